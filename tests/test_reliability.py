"""Uncertain spec numbers and the reliability of a design: FORM, SORM, Monte Carlo, importance
sampling, chance constraints; OpenTURNS as the peer on a limit state both evaluate."""

import copy
import dataclasses
import importlib
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy import stats

from tripodjax import optimize
from tripodjax.optimize import uncertainty
from tripodjax.optimize.problem import (
    full_design,
    quantities,
    requirement_margins,
    requirement_structure,
)

rel = importlib.import_module(
    "tripodjax.optimize.reliability"
)  # the module (its function shares the name)

# The case: normal tolerances on R and d (σ 0.01 mm), the workbook's conformity range,
# a 5 % scatter of P_d.
TOLERANCES = uncertainty.DEFAULT_TOLERANCES_TOML


def row(result, name):
    return next(r for r in result["requirements"] if r["name"] == name)


# --------------------------------------------------------------------------- the spec section


@pytest.mark.parametrize(
    ("text", "names"),
    [
        ('R = { distribution = "gauss", sd = 0.01 }', ("uncertainty.R.distribution", "'normal'")),
        ('R = { distribution = "normal", sd = -0.01 }', ("uncertainty.R.sd", "> 0")),
        ('R = { distribution = "normal" }', ("uncertainty.R", "sd or cov")),
        ('R = { distribution = "normal", sd = 0.1, cov = 0.1 }', ("uncertainty.R", "sd or cov")),
        ('R = { distribution = "normal", sd = 0.1, width = 2 }', ("uncertainty.R", "width")),
        (
            'conformity = { distribution = "uniform", low = 0.99, high = 1.01 }',
            ("uncertainty.conformity", "1.0005"),
        ),
        (
            'conformity = { distribution = "uniform", low = 1.008, high = 1.002 }',
            ("uncertainty.conformity", "low < high"),
        ),
        ('hertz.P_x = { distribution = "normal", cov = 0.05 }', ("uncertainty.hertz.P_x",)),
        (
            'solver.tolerance = { distribution = "normal", cov = 0.05 }',
            ("uncertainty.solver.tolerance", "[solver] holds no number of the model"),
        ),
        (
            'vehicle.engine_torque_Nm = { distribution = "normal", cov = 0.05 }',
            ("vehicle.engine_torque_Nm", "list"),
        ),
        (
            'hertz.P_d = { distribution = "uniform", low = 1.0, half_width = 0.1 }',
            ("uncertainty.hertz.P_d", "not both"),
        ),
        ("R = 0.01", ("uncertainty.R", "table")),
        (
            'R = { distribution = "normal", sd = 0.01 }\n'
            'd_roller = { distribution = "normal", sd = 0.01 }\n'
            'correlation = [["R", "d_roller", 1.2]]',
            ("uncertainty.correlation[0]", "1.2"),
        ),
        (
            'R = { distribution = "normal", sd = 0.01 }\ncorrelation = [["R", "l", 0.2]]',
            ("uncertainty.correlation[0]", "'l'"),
        ),
        (
            'R = { distribution = "normal", sd = 0.01 }\n'
            'd_roller = { distribution = "normal", sd = 0.01 }\n'
            'correlation = [["R", "d_roller", 0.3], ["d_roller", "R", -0.3]]',
            ("uncertainty.correlation[1]", "uncertainty.correlation[0]", "each pair once"),
        ),
        (
            'hertz.P_d = { distribution = "normal", cov = 0.05 }\n'
            '"hertz.P_d" = { distribution = "normal", cov = 0.05 }',
            ("uncertainty.hertz.P_d", "twice"),
        ),
        # A distribution's values within the number's own rule (the spec's check of that key).
        (
            'hertz.P_d = { distribution = "uniform", low = -2000.0, high = 2000.0 }',
            ("uncertainty.hertz.P_d.low = -2000.0 is not allowed: hertz.P_d takes", "≥ 100 MPa"),
        ),
        (
            'vehicle.mass_kg = { distribution = "uniform", low = -100.0, high = 2000.0 }',
            ("uncertainty.vehicle.mass_kg.low = -100.0", "vehicle.mass_kg takes", "≥ 50 kg"),
        ),
        (
            'outboard.pressure_angle_deg = { distribution = "uniform", low = 10.0, high = 100.0 }',
            ("uncertainty.outboard.pressure_angle_deg.high = 100.0", "> 0° and < 90°"),
        ),
        (
            'loads.shock_factor = { distribution = "uniform", low = 0.0, high = 2.0 }',
            (
                "uncertainty.loads.shock_factor.low = 0.0",
                "loads.shock_factor takes",
                "≥ 1 and ≤ 10",
            ),
        ),
        (
            'hertz.P_d = { distribution = "normal", cov = 0.4, low = -5.0 }',
            ("uncertainty.hertz.P_d.low = -5.0", "≥ 100 MPa"),
        ),
        (
            'conformity = { distribution = "normal", sd = 0.01, low = 1.0 }',
            ("uncertainty.conformity.low = 1.0", "≥ 1.0005"),
        ),
        (
            'layout.gamma0_deg = { distribution = "normal", sd = 3.0, high = 50.0 }',
            ("uncertainty.layout.gamma0_deg.high = 50.0", "≤ 45°"),
        ),
        (
            'R = { distribution = "uniform", half_width = 16.0 }',  # R's bounds [15, 40] mm
            ("uncertainty.R.half_width = 16.0", "around the bounds: -1", "≥ 1 mm"),
        ),
        # A spread whose variance overflows.
        (
            'hertz.P_d = { distribution = "normal", sd = 1e300 }',
            ("hertz.P_d.sd = 1e+300", "≤ 1.341e+154"),
        ),
        (
            'hertz.P_d = { distribution = "normal", cov = 1e300 }',
            ("hertz.P_d.cov = 1e+300", "≤ 9.954e+150"),
        ),
        (
            'hertz.P_d = { distribution = "lognormal", cov = 1e300 }',
            ("hertz.P_d.cov = 1e+300", "≤ 1.341e+154"),
        ),
        (
            'loads.gaf_torque = { distribution = "normal", cov = 0.1 }\n[loads]\ngaf_torque = 0.0',
            ("uncertainty.loads.gaf_torque.cov = 0.1", "give sd"),
        ),
    ],
)
def test_bad_uncertainty_is_one_line_naming_key_and_value(text, names):
    with pytest.raises(optimize.SpecError) as error:
        optimize.parse_spec("[uncertainty]\n" + text.replace("\\n", "\n"))
    message = str(error.value)
    assert "\n" not in message
    for name in names:
        assert name in message


@pytest.mark.parametrize(
    ("text", "where"),
    [
        ("R = { sd = 0.01 }", "uncertainty.R"),
        ("d_roller = {}", "uncertainty.d_roller"),
        ("hertz.P_d = { cov = 0.05 }", "uncertainty.hertz.P_d"),
        ('"hertz.P_d" = { cov = 0.05 }', "uncertainty.hertz.P_d"),
        ("hertz = { P_d = { cov = 0.05 } }", "uncertainty.hertz.P_d"),
    ],
)
def test_an_entry_without_a_distribution_says_so(text, where):
    """Not "unknown key uncertainty.R.sd": the entry's distribution key is missing."""
    with pytest.raises(optimize.SpecError) as error:
        optimize.parse_spec("[uncertainty]\n" + text)
    message = str(error.value)
    assert message.startswith(f"{where} has no distribution key") and "\n" not in message
    assert all(repr(kind) in message for kind in uncertainty.KINDS)


def test_a_quoted_dotted_key_is_the_nested_one():
    """The form the messages suggest, section.key, is accepted quoted as well."""
    entry = '{ distribution = "normal", cov = 0.05 }'
    quoted = optimize.parse_spec(f'[uncertainty]\n"hertz.P_d" = {entry}\n')
    nested = optimize.parse_spec(f"[uncertainty]\nhertz.P_d = {entry}\n")
    assert quoted.structure == nested.structure
    assert quoted.values["uncertainty"] == nested.values["uncertainty"]
    (one,) = quoted.structure.uncertainty
    assert (one.name, one.section, one.key) == ("hertz.P_d", "hertz", "P_d")


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("max_failure_probability_life = 1e-3", "needs uncertain numbers"),
        ("max_failure_probability_life = 0.7", "≤ 0.5"),
        ("min_reliability_index_life = -1", "≥ 0"),
        # One rule for both forms: β_t ≤ 8, P ≥ Φ(−8) ≈ 6.2e-16 (1e-300 was β ≈ 37).
        ("min_reliability_index_life = 8.5", "= 8.5 is not allowed: a finite number ≥ 0 and ≤ 8"),
        ("max_failure_probability_life = 1e-300", "= 1e-300 is not allowed: .* ≥ 6.22096e-16 and"),
        ("max_failure_probability_life = 6.2e-16", "≥ 6.22096e-16 and ≤ 0.5"),
        ("max_failure_probability_eccentricity = 1e-3", "no constraint"),
        ("max_failure_probability_colour = 1e-3", "unknown key constraints."),
    ],
)
def test_bad_chance_constraint(text, expected):
    unc = "" if "needs" in expected else TOLERANCES
    with pytest.raises(optimize.SpecError, match=expected) as error:
        optimize.parse_spec(unc + "[constraints]\n" + text)
    assert "\n" not in str(error.value)


def test_chance_targets_at_the_ends_of_their_one_range():
    """β_t = 8 and its probability Φ(−8) are both allowed: the same target."""
    p = optimize.spec.CHANCE_RANGES["probability"][0]
    assert p == pytest.approx(stats.norm.sf(8.0), rel=1e-12)
    for text in ("min_reliability_index_life = 8.0", f"max_failure_probability_life = {p!r}"):
        optimize.parse_spec(TOLERANCES + "[constraints]\n" + text)


def test_uncertain_numbers_are_traced_and_kinds_are_structure():
    a = optimize.parse_spec(TOLERANCES)
    b = optimize.parse_spec(TOLERANCES.replace("sd = 0.01", "sd = 0.02"))
    c = optimize.parse_spec(TOLERANCES.replace('"normal", cov', '"lognormal", cov'))
    assert a.structure == b.structure
    assert a.structure != c.structure
    assert float(b.values["uncertainty"]["R"]["spread"]) == 0.02
    leaves = jax.tree_util.tree_leaves(a.values["uncertainty"])
    assert leaves and all(isinstance(v, np.ndarray) for v in leaves)


def test_distributions_against_scipy():
    """realize(u) is each distribution's inverse CDF at Φ(u), tails included."""
    spec = optimize.parse_spec(
        "[loads]\nM_max = 1154.0\n"  # an explicit M_max (the default takes the vehicle's)
        "[uncertainty]\n"
        'R = { distribution = "normal", sd = 0.5, low = 24.0, high = 26.5 }\n'
        'hertz.P_d = { distribution = "lognormal", cov = 0.2 }\n'
        'conformity = { distribution = "uniform", low = 1.002, high = 1.008 }\n'
        'loads.M_max = { distribution = "normal", cov = 0.1 }\n'
        'layout.gamma0_deg = { distribution = "uniform", half_width = 2.0 }\n'
    )
    inputs, numbers = spec.structure.uncertainty, spec.values["uncertainty"]
    means = [25.55, 1347.0, 1.005, 1154.0, math.radians(20.0)]
    u = np.array([-30.0, -6.0, -1.3, 0.0, 0.7, 5.0, 30.0])
    with jax.enable_x64(True):
        out = np.asarray(uncertainty.realize(inputs, numbers, means, np.stack([u] * 5, -1)))
    p = stats.norm.cdf(u)
    a, b = (24.0 - 25.55) / 0.5, (26.5 - 25.55) / 0.5
    truncated = stats.truncnorm(a, b, loc=25.55, scale=0.5)
    # scipy's ppf from the upper tail where p rounds to 1
    expected_r = np.where(u < 0, truncated.ppf(p), truncated.isf(stats.norm.sf(u)))
    np.testing.assert_allclose(out[:, 0], expected_r, rtol=1e-12, atol=1e-9)
    s = math.sqrt(math.log1p(0.2**2))
    lognormal = stats.lognorm(s, scale=1347.0 * math.exp(-0.5 * s * s))
    np.testing.assert_allclose(out[2:5, 1], lognormal.ppf(p[2:5]), rtol=1e-12)
    np.testing.assert_allclose(out[:, 2], stats.uniform(1.002, 0.006).ppf(p), rtol=1e-14)
    # M_max ≥ 1 N·m (spec.RANGES): its normal is truncated there (10 sd below the mean: seen
    # at u = −30 alone, which gave M_max = −2308 N·m before).
    np.testing.assert_allclose(out[1:, 3], 1154.0 * (1 + 0.1 * u[1:]), rtol=1e-14)
    assert out[0, 3] == 1.0  # the bound: Φ(−30) is below the cut mass Φ(−10)
    np.testing.assert_allclose(
        out[:, 4], math.radians(20.0) + math.radians(2.0) * (2 * p - 1), rtol=1e-14
    )
    assert np.all(np.isfinite(out)) and np.all(np.diff(out[:, 0]) > 0)


def test_a_normal_design_variable_is_truncated_at_its_physical_bound():
    """conformity ≥ 1.0005 (hertz.MIN_CONFORMITY) for every u, however wide the normal (and
    ≤ 2, the spec's upper limit, 99.8 sd away: no mass cut off there)."""
    spec = optimize.parse_spec(
        '[uncertainty]\nconformity = { distribution = "normal", sd = 0.01 }\n'
    )
    (entry,) = spec.structure.uncertainty
    assert entry.truncate_low and entry.truncate_high
    u = np.linspace(-35.0, 35.0, 141)[:, None]
    with jax.enable_x64(True):
        out = np.asarray(uncertainty.realize((entry,), spec.values["uncertainty"], [1.002], u))
    assert np.all(out >= 1.0005) and np.all(np.diff(out[:, 0]) >= 0)
    truncated = stats.truncnorm((1.0005 - 1.002) / 0.01, np.inf, loc=1.002, scale=0.01)
    np.testing.assert_allclose(
        out[60:81, 0], truncated.ppf(stats.norm.cdf(u[60:81, 0])), rtol=1e-12
    )


def test_a_normal_or_lognormal_is_truncated_at_its_numbers_range():
    """The spec's rule for the number (spec.RANGES) bounds a distribution as a design variable's
    does: P_d in [100, 10 000] MPa (CoV 0.4: 1 % of the plain normal below 100), front_share in
    [0, 1]; a lognormal M_max in [1, 50 000] N·m, in log space (its upper end 8 of its sd
    away: the plain lognormal there to roundoff, and never past the end)."""
    spec = optimize.parse_spec(
        "[loads]\nM_max = 1154.0\n"
        "[uncertainty]\n"
        'hertz.P_d = { distribution = "normal", cov = 0.4 }\n'
        'vehicle.front_share = { distribution = "normal", sd = 0.3 }\n'
        'loads.M_max = { distribution = "lognormal", cov = 0.5 }\n'
    )
    p_d, share, torque = spec.structure.uncertainty
    for x in (p_d, share, torque):
        assert (x.truncate_low, x.truncate_high) == (True, True)
    numbers = spec.values["uncertainty"]
    ranges = optimize.spec.RANGES
    assert float(numbers["hertz.P_d"]["low"]) == ranges["hertz.P_d"].low == 100.0
    assert float(numbers["vehicle.front_share"]["high"]) == 1.0
    assert float(numbers["loads.M_max"]["high"]) == ranges["loads.M_max"].high
    u = np.linspace(-35.0, 35.0, 141)
    means = [1347.0, float(spec.values["vehicle"]["front_share"]), 1154.0]
    with jax.enable_x64(True):
        out = np.asarray(
            uncertainty.realize(spec.structure.uncertainty, numbers, means, np.stack([u] * 3, -1))
        )
    assert np.all((out[:, 0] >= 100.0) & (out[:, 0] <= 1e4)) and np.all(np.diff(out[:, 0]) >= 0)
    assert np.all((out[:, 1] >= 0.0) & (out[:, 1] <= 1.0))
    assert np.all((out[:, 2] >= 1.0) & (out[:, 2] <= 5e4)) and np.all(np.diff(out[:, 2]) >= 0)
    sd = 0.4 * 1347.0
    truncated = stats.truncnorm((100.0 - 1347.0) / sd, (1e4 - 1347.0) / sd, loc=1347.0, scale=sd)
    middle = slice(60, 81)  # |u| ≤ 5
    np.testing.assert_allclose(out[middle, 0], truncated.ppf(stats.norm.cdf(u[middle])), rtol=1e-10)
    s2 = math.log1p(0.5**2)
    plain = stats.lognorm(math.sqrt(s2), scale=1154.0 * math.exp(-0.5 * s2))
    np.testing.assert_allclose(out[middle, 2], plain.ppf(stats.norm.cdf(u[middle])), rtol=1e-10)


def test_correlation_is_that_of_the_underlying_normals():
    spec = optimize.parse_spec(
        "[uncertainty]\n"
        'R = { distribution = "normal", sd = 0.01 }\n'
        'd_roller = { distribution = "normal", sd = 0.02 }\n'
        'correlation = [["R", "d_roller", -0.6]]\n'
    )
    z = np.random.default_rng(1).standard_normal((200_000, 2))
    with jax.enable_x64(True):
        out = np.asarray(
            uncertainty.realize(
                spec.structure.uncertainty, spec.values["uncertainty"], [25.55, 43.5], z
            )
        )
    assert abs(np.corrcoef(out.T)[0, 1] + 0.6) < 0.01
    np.testing.assert_allclose(np.std(out, axis=0), [0.01, 0.02], rtol=0.01)


# --------------------------------------------------------------------------- reliability


def test_wilson_interval():
    assert rel.wilson(0.0, 1000) == [0.0, pytest.approx(3.84 / 1003.84, rel=1e-3)]
    lo, hi = rel.wilson(0.5, 10_000)
    assert lo == pytest.approx(0.5 - 1.96 * 0.005, abs=1e-4) and hi == pytest.approx(1 - lo)


def test_reliability_errors():
    with pytest.raises(ValueError, match="no \\[uncertainty\\]"):
        optimize.reliability(optimize.load_spec())
    spec = optimize.parse_spec(TOLERANCES)
    with pytest.raises(ValueError, match="method = 'sorm'"):
        optimize.reliability(spec, method="sorm")
    with pytest.raises(ValueError, match="samples = 0"):
        optimize.reliability(spec, method="mc", samples=0)


@pytest.mark.parametrize(
    ("argument", "value", "error", "expected"),
    [
        (
            "seed",
            2**70,
            ValueError,
            "seed = 1180591620717411303424 .* 0 ≤ seed ≤ 9223372036854775807",
        ),
        ("seed", 2**63, ValueError, "0 ≤ seed ≤ 9223372036854775807"),
        ("seed", -1, ValueError, "seed = -1"),
        ("samples", 10**9 + 1, ValueError, "2 ≤ samples ≤ 1000000000"),
        ("is_samples", 10**12, ValueError, "2 ≤ is_samples ≤ 1000000000"),
        ("chunk", 2**20 + 1, ValueError, "1 ≤ chunk ≤ 1048576"),
        ("chunk", 0, ValueError, "chunk = 0"),
        ("chunk", 2.0, TypeError, "chunk = 2.0"),
        ("samples", True, TypeError, "samples = True"),
        ("seed", np.array([1, 2]), TypeError, "seed = array"),
    ],
)
def test_reliability_arguments_have_ranges(argument, value, error, expected):
    """Each count and the seed in one range, checked before anything compiles; one line."""
    spec = optimize.parse_spec(TOLERANCES)
    with pytest.raises(error, match=expected) as raised:
        optimize.reliability(spec, method="mc", **{argument: value})
    assert "\n" not in str(raised.value)


def _life_margin_batch(spec):
    """The life margin of a design as a function of the physical (R, d, Ψ, P_d): the peer's
    limit state (through the problem's quantities, independent of the uncertainty module)."""
    structure = requirement_structure(spec.structure)
    values = jax.tree_util.tree_map(jnp.asarray, spec.values)
    names = optimize.problem.constraint_names(structure)

    def one(row):
        v = dict(values, hertz=dict(values["hertz"], P_d=row[3]))
        design = full_design(structure, v, jnp.zeros(len(structure.free)))
        design.update(R=row[0], d_roller=row[1], conformity=row[2])
        q, _ = quantities(structure, v, design)
        return requirement_margins(structure, v, q)[names.index("life")]

    batch = jax.jit(jax.vmap(one))

    def g(x):
        with jax.enable_x64(True):
            return np.asarray(batch(jnp.asarray(np.asarray(x, float))))

    return g


@pytest.fixture(scope="module")
def default_case():
    """The issue's Done-when case at the default design (the workbook joint), 10⁶ samples."""
    spec = optimize.parse_spec(TOLERANCES)
    return spec, optimize.reliability(spec, None, "all", samples=1_000_000, chunk=2**16)


# On the vehicle chain the workbook joint lives ~128 000 km only at the nominal conformity 1.002,
# the best end of the tolerance range; at its middle (1.005, u = 0) the life is already short of
# 100 000 km, so P ≈ 0.92 and β < 0 (SORM of the safe domain). The agreement of FORM, SORM,
# Monte Carlo and OpenTURNS with the origin safe (β > 0) is checked on the same joint, the same
# tolerances, against a required life of 5 000 km (P ≈ 5·10⁻³; the margin g = ln(L/L_req) only
# shifts by a constant, the limit state keeps its shape: conformity and P_d still share the
# importance). A 10⁶-sample Monte Carlo resolves that P to ±3 % (95 %).
RESOLVABLE_KM = 5000.0


@pytest.fixture(scope="module")
def resolvable_case():
    """The Done-when tolerances at the workbook joint, P of missing the life ≈ 5·10⁻³."""
    spec = optimize.parse_spec(TOLERANCES).replace_values(life={"required_km": RESOLVABLE_KM})
    return spec, optimize.reliability(spec, None, "all", samples=1_000_000, chunk=2**16)


def _common_checks(result):
    """What holds of every reliability result: statuses, system bounds, notes."""
    life = row(result, "life")
    assert math.isclose(sum(life["importance"].values()), 1.0, rel_tol=1e-9)
    assert result["status"]["mc_failed_solves"] == 0
    assert result["status"]["mc_nonfinite_samples"] == 0
    system = result["system_probability_mc"]
    probabilities = [r["probability_mc"] for r in result["requirements"]]
    assert max(probabilities) <= system <= min(1.0, sum(probabilities)) + 1e-12
    form = [r["probability_form"] for r in result["requirements"]]
    assert result["system_bounds_form"] == [max(form), min(1.0, sum(form))]
    assert result["disagree"] == [r["name"] for r in result["requirements"] if not r["agree"]]
    for r in result["requirements"]:  # a FORM that did not converge says so in words
        assert ("form_note" in r) == (not r["form_converged"])
        basis = "sorm" if r["probability_sorm"] is not None else "form"
        lo, hi = r["mc_interval_95"]
        assert r["agree_basis"] == basis
        assert r["agree"] == (lo <= r[f"probability_{basis}"] <= hi)


def test_form_sorm_and_monte_carlo_agree_at_the_default_design(resolvable_case):
    _, result = resolvable_case
    life = row(result, "life")
    assert life["form_converged"] and life["samples"] == 1_000_000
    lo, hi = life["mc_interval_95"]
    assert 1e-3 < life["probability_mc"] < 2e-2  # the regime the required life was set for
    assert life["beta_form"] > 0
    assert lo <= life["probability_sorm"] <= hi
    assert life["agree"] and life["agree_basis"] == "sorm"
    # The uniform conformity curves the limit state: first order overestimates, SORM corrects.
    assert life["probability_form"] > hi
    assert life["importance"]["conformity"] > 0.1 and life["importance"]["hertz.P_d"] > 0.5
    _common_checks(result)


def test_the_done_when_case_at_the_workbook_joint(default_case):
    """The issue's Done-when case: the default tolerances at the workbook joint, 10⁶ samples.

    The conformity's range, not its nominal 1.002, decides the life: the mean of the inputs
    misses it, β < 0, and SORM applies to the safe domain (P = 1 − P_SORM(safe)). OpenTURNS
    gives the same β, the same SORM probabilities (formula by formula) and a Monte Carlo
    probability within the combined interval. The Done-when's "within the Monte Carlo
    interval" does NOT hold for any SORM formula here (measured: MC 0.92265, interval
    0.92212–0.92317; Tvedt 0.92064, Hohenbichler–Rackwitz 0.92012, Breitung 0.91757, FORM
    0.90865, OpenTURNS' Breitung 0.91753 and Tvedt 0.92058): the safe domain is no paraboloid
    (the uniform conformity saturates at 1.002, where the boundary flattens out), so SORM is
    about 0.2 % (P_safe about 3 %) off, 5–8 standard errors of 10⁶ samples. The test asserts
    that, and that SORM is nearer than FORM; ``agree`` is False and says so in the report."""
    spec, result = default_case
    life = row(result, "life")
    assert life["form_converged"] and life["samples"] == 1_000_000
    lo, hi = life["mc_interval_95"]
    assert 0.5 < life["probability_mc"] < 1.0 and hi - lo < 2e-3  # resolved by 10⁶ samples
    assert life["beta_form"] < 0 and life["probability_form"] > 0.5
    assert life["agree_basis"] == "sorm"
    sorm = life["probability_sorm"]
    assert sorm == life["probability_sorm_hohenbichler_rackwitz"]
    # The Done-when, measured: SORM outside the 10⁶-sample interval (below it), nearer than FORM.
    assert not life["agree"] and "life" in result["disagree"]
    assert sorm < lo and hi - sorm < 4e-3
    mc = life["probability_mc"]
    assert abs(sorm - mc) < 0.25 * abs(life["probability_form"] - mc)
    tvedt, breitung = life["probability_sorm_tvedt"], life["probability_sorm_breitung"]
    assert life["probability_form"] < breitung < sorm < tvedt < lo
    assert life["importance"]["conformity"] > 0.5  # the range dominates
    # The deterministic margin at the nominal design is positive (the workbook joint meets its
    # 100 000 km at conformity 1.002): the miss comes from the tolerance range alone.
    assert optimize.evaluate(spec, {"R": 25.55, "d_roller": 43.5})["constraints"]["life"] > 0
    _common_checks(result)
    # The peer on the same limit state: the origin in the failure domain, SORM of the complement.
    peer = _openturns(spec, monte_carlo=True)
    assert peer["origin_in_failure"]
    assert -life["beta_form"] == pytest.approx(peer["beta"], rel=0.01)
    for formula in rel.SORM_FORMULAS:  # the safe probabilities 1 − P within 2 %
        ours = 1.0 - life[f"probability_sorm_{formula}"]
        assert ours == pytest.approx(1.0 - peer[formula], rel=0.02), formula
    spread = 1.96 * math.hypot(peer["mc_standard_error"], life["mc_standard_error"])
    assert abs(peer["mc"] - mc) <= spread
    assert not lo <= peer["hohenbichler_rackwitz"] <= hi  # OpenTURNS' SORM misses it alike


def test_design_point_is_on_the_limit_state_nearest_the_origin(default_case):
    """At u* the margin is 0 and u* is parallel to −∇g (the FORM optimality conditions)."""
    spec, result = default_case
    life = row(result, "life")
    g = _life_margin_batch(spec)
    point = np.array(
        [[life["design_point"][k] for k in ("R", "d_roller", "conformity", "hertz.P_d")]]
    )
    assert abs(g(point)[0]) < 1e-9


def _openturns(spec, monte_carlo=False):
    """OpenTURNS' FORM/SORM (and Monte Carlo, 262 144 samples) on the life margin of the
    workbook joint under the Done-when tolerances, a Python callback of the margin."""
    import openturns as ot  # the peer: a test dependency (the test extra), never skipped

    g = _life_margin_batch(spec)
    model = ot.PythonFunction(
        4, 1, func=lambda x: [float(g([x])[0])], func_sample=lambda xs: g(xs)[:, None]
    )
    marginals = [
        ot.Normal(25.55, 0.01),
        ot.Normal(43.5, 0.01),
        ot.Uniform(1.002, 1.008),
        ot.Normal(1347.0, 0.05 * 1347.0),
    ]
    joint = getattr(ot, "JointDistribution", None) or ot.ComposedDistribution  # renamed in 1.24
    distribution = joint(marginals)
    event = ot.ThresholdEvent(
        ot.CompositeRandomVector(model, ot.RandomVector(distribution)), ot.Less(), 0.0
    )
    solver = ot.AbdoRackwitz()
    solver.setMaximumIterationNumber(200)
    sorm = ot.SORM(solver, event, distribution.getMean())
    sorm.run()
    result = sorm.getResult()
    out = dict(
        beta=result.getHasoferReliabilityIndex(),
        origin_in_failure=result.getIsStandardPointOriginInFailureSpace(),
        breitung=result.getEventProbabilityBreitung(),
        hohenbichler_rackwitz=result.getEventProbabilityHohenbichler(),
        tvedt=result.getEventProbabilityTvedt(),
    )
    if monte_carlo:
        ot.RandomGenerator.SetSeed(7)
        mc = ot.ProbabilitySimulationAlgorithm(event, ot.MonteCarloExperiment())
        mc.setBlockSize(2**15)
        mc.setMaximumOuterSampling(8)  # 262 144 samples
        mc.setMaximumCoefficientOfVariation(-1.0)
        mc.run()
        out["mc"] = mc.getResult().getProbabilityEstimate()
        out["mc_standard_error"] = mc.getResult().getStandardDeviation()
    return out


def test_openturns_peer(resolvable_case):
    """FORM β within 1 % of OpenTURNS', each SORM formula within 2 %, Monte Carlo P within the
    interval (β > 0: the Done-when tolerances, the required life at P ≈ 5·10⁻³)."""
    spec, result = resolvable_case
    life = row(result, "life")
    peer = _openturns(spec, monte_carlo=True)
    assert not peer["origin_in_failure"]
    assert life["beta_form"] == pytest.approx(peer["beta"], rel=0.01)
    for formula in rel.SORM_FORMULAS:
        assert life[f"probability_sorm_{formula}"] == pytest.approx(peer[formula], rel=0.02)
    # Two independent estimates: their difference within its 95 % interval.
    spread = 1.96 * math.hypot(peer["mc_standard_error"], life["mc_standard_error"])
    assert abs(peer["mc"] - life["probability_mc"]) <= spread
    lo, hi = life["mc_interval_95"]
    assert lo <= peer["hohenbichler_rackwitz"] <= hi


def test_importance_sampling_reaches_small_probabilities():
    """A linear limit state in u (lognormal P_d only: ln L is linear in ln P_d) with P ≈ 1e-6:
    FORM is exact there, and 2·10⁴ importance samples estimate it to a few per cent."""
    text = '[uncertainty]\nhertz.P_d = { distribution = "lognormal", cov = 0.05 }\n'
    spec = optimize.parse_spec(text)
    first = row(optimize.reliability(spec, None, "form"), "life")
    # Move the required life so that β = 4.75 (P ≈ 1.0e-6): g = a + b·u is linear.
    required = float(spec.values["life"]["required_km"])
    g0 = _margin_at_mean(spec)
    slope = g0 / first["beta_form"]  # |∂g/∂u|
    target = 4.75
    spec = spec.replace_values(life={"required_km": required * math.exp(g0 - target * slope)})
    result = optimize.reliability(spec, None, "is", is_samples=20_000)
    life = row(result, "life")
    assert life["beta_form"] == pytest.approx(target, rel=1e-6)
    assert life["probability_is"] == pytest.approx(stats.norm.sf(target), rel=0.05)
    assert life["is_standard_error"] / life["probability_is"] < 0.02
    assert life["is_interval_95"][0] <= life["probability_form"] <= life["is_interval_95"][1]


def _margin_at_mean(spec):
    """The life margin with every uncertain number at its median (u = 0)."""
    structure = requirement_structure(spec.structure)
    values, x = optimize.problem.design_values(spec, optimize.problem.fixed_design(spec.values))
    with jax.enable_x64(True):
        m, _ = optimize.problem.limit_state(
            structure, jax.tree_util.tree_map(jnp.asarray, values), jnp.asarray(x), jnp.zeros(1)
        )
    return float(m[1])


def _without_the_range_of_p_d(spec):
    """``spec`` with the truncation of its P_d lognormal widened from P_d's range (100–10 000 MPa,
    spec.RANGES, which keeps the model finite) to 1e-300–1e300 MPa: in the numbers, not the file
    (which refuses it), so that the model overflows at tiny P_d as these tests need."""
    values = copy.deepcopy(spec.values)
    values["uncertainty"]["hertz.P_d"].update(low=np.asarray(1e-300), high=np.asarray(1e300))
    return dataclasses.replace(spec, values=values)


def test_non_finite_samples_count_as_misses():
    """Samples where the model gives no finite margin are counted, never dropped, and each is a
    miss (an infinite margin too). P_d lognormal, CoV 1e30: P_d is 1e-27 MPa at the median,
    and below about u = −1 the life overflows (its margin is +inf, result nonfinite); the
    fraction of samples with no finite margin is Φ(u*), u* the edge of the finite margins found
    on a grid of u through the limit state, and the life is missed below u ≈ 5.8. (A normal on P_d, which gave P_d < 0 here before,
    is now truncated at P_d's bound.)"""
    text = '[uncertainty]\nhertz.P_d = { distribution = "lognormal", cov = 1e30 }\n'
    spec = _without_the_range_of_p_d(optimize.parse_spec(text))
    structure = requirement_structure(spec.structure)
    values, x = optimize.problem.design_values(spec, optimize.problem.fixed_design(spec.values))
    grid = np.linspace(-4.0, 8.0, 12001)
    with jax.enable_x64(True):
        margins = jax.jit(
            jax.vmap(
                lambda u: optimize.problem.limit_state(structure, values, jnp.asarray(x), u)[0]
            )
        )(jnp.asarray(grid[:, None]))
    finite = np.all(np.isfinite(np.asarray(margins)), axis=1)
    edge = grid[np.argmax(finite)]  # finite from here up, none below
    assert 0.05 < stats.norm.cdf(edge) < 0.5 and np.all(finite[grid >= edge])
    life = np.asarray(margins)[:, 1]
    met = grid[np.argmax(finite & (life >= 0))]  # the life is met from here up (u ≈ 5.8)
    assert np.all(life[finite & (grid < met)] < 0)
    result = optimize.reliability(spec, None, "mc", samples=20_000, chunk=4096)
    status = result["status"]
    assert status["mc_nonfinite_samples"] / 20_000 == pytest.approx(stats.norm.cdf(edge), abs=0.01)
    # Every sample below u ≈ 5.8 misses: the non-finite ones too (they counted as met before).
    assert row(result, "life")["probability_mc"] == pytest.approx(stats.norm.cdf(met), abs=1e-3)


def test_form_without_a_finite_margin_at_the_mean_gives_no_probability():
    """A margin (or gradient) that is not finite at the mean of the inputs is no requirement
    independent of them: FORM has not converged, β and P are None (never 0 or 1), the note says
    why (before: β = +∞, P = 0, converged). P_d lognormal, CoV 1e40: P_d is 1e-37 MPa at the
    median, where the life overflows. One FORM program with the importance-sampling test's."""
    spec = _without_the_range_of_p_d(
        optimize.parse_spec(
            '[uncertainty]\nhertz.P_d = { distribution = "lognormal", cov = 1e40 }\n'
        )
    )
    result = optimize.reliability(spec, None, "form")
    life = row(result, "life")
    assert life["beta_form"] is None and life["probability_form"] is None
    assert life["probability_sorm"] is None and not life["form_converged"]
    assert life["form_result"] == "nonfinite" and "not finite at the mean" in life["form_note"]
    assert result["status"]["form_converged"] is False
    assert result["system_bounds_form"][1] is None  # an unknown P_i: no upper bound


def test_chance_constraint_design_meets_its_probability_and_no_more():
    """The Done-when: the default tolerances, the default 100 000 km, max_failure_probability_life
    = 1e-3: the design's Monte Carlo probability (10⁵ samples) is ≤ 1e-3 with its whole 95 %
    interval, and the FORM constraint is active (margin 0, multiplier > 0, β = −Φ⁻¹(1e-3)).

    Measured: R 38.9 mm, d 61.8 mm (R/d at its minimum 0.63), outer diameter 139.7 mm against
    93.5 mm for the deterministic optimum (R 26.05, d 41.35 mm), which misses the life with
    P ≈ 0.96 under these tolerances. FORM's 1e-3 is conservative here: SORM ≈ 6.2·10⁻⁴ and the
    Monte Carlo 6.5·10⁻⁴."""
    spec = optimize.parse_spec(TOLERANCES + "[constraints]\nmax_failure_probability_life = 1e-3\n")
    result = optimize.solve(spec, progress=False)
    assert result.converged and result.feasible
    pma = result.constraints["max_failure_probability_life"]
    assert abs(pma["margin"]) < 1e-3 and result.multipliers["max_failure_probability_life"] > 0
    assert result.design["d_roller"] > 50.0  # a roller the former default box (d ≤ 50 mm) lacked
    design = {k: result.design[k] for k in spec.structure.free}
    check = optimize.reliability(spec, design, "all", samples=100_000)
    life = row(check, "life")
    assert life["samples"] >= 100_000 and life["form_converged"]
    assert life["beta_form"] == pytest.approx(-stats.norm.ppf(1e-3), rel=0.01)
    assert life["probability_mc"] <= 1e-3 and life["mc_interval_95"][1] <= 1e-3
    assert life["agree"]  # SORM within the Monte Carlo interval
    # Larger than the deterministic optimum, which misses the life most of the time (it meets it
    # only near the nominal conformity 1.002, the best end of the range).
    # (The tolerances change no deterministic number: the default spec's solve, compiled already.)
    deterministic = optimize.solve(optimize.load_spec(), progress=False)
    assert abs(deterministic.constraints["life"]["margin"]) < 1e-3  # life-bound
    assert result.quantities["outer_diameter"] > deterministic.quantities["outer_diameter"]
    at_optimum = optimize.reliability(
        spec, {k: deterministic.design[k] for k in spec.structure.free}, "form"
    )
    assert row(at_optimum, "life")["probability_form"] > 0.5


def test_form_converges_where_the_limit_state_is_curved_by_one_over_beta():
    """At R 40, d 55 mm the life's limit state is curved by κβ ≈ 1: full HL-RF steps alternate
    across the design point, each a little lower in merit (100 steps, not converged, before
    the Armijo rule); with it the step halves and HL-RF converges. β against an independent
    search (scipy SLSQP on min |u|² subject to g(u) = 0, the margin as the peer's callback)."""
    from scipy import optimize as scipy_optimize

    spec = optimize.parse_spec(TOLERANCES)
    design = {"R": 40.0, "d_roller": 55.0}
    life = row(optimize.reliability(spec, design, "form"), "life")
    assert life["form_converged"] and life["form_iterations"] < 30
    g = _life_margin_batch(spec)

    def physical(u):
        return [
            40.0 + 0.01 * u[0],
            55.0 + 0.01 * u[1],
            1.002 + 0.006 * stats.norm.cdf(u[2]),
            1347.0 * (1.0 + 0.05 * u[3]),
        ]

    def gradient(u, h=1e-5):  # central differences, one batch
        steps = np.concatenate([np.eye(4), -np.eye(4)]) * h
        values = g([physical(u + e) for e in steps])
        return (values[:4] - values[4:]) / (2 * h)

    point = [life["design_point"][k] for k in ("R", "d_roller", "conformity", "hertz.P_d")]
    assert abs(g([point])[0]) < 1e-9
    search = scipy_optimize.minimize(
        lambda u: 0.5 * float(u @ u),
        np.array([0.0, 0.0, 1.0, -1.7]),
        jac=lambda u: u,
        constraints=[{"type": "eq", "fun": lambda u: g([physical(u)])[0], "jac": gradient}],
        method="SLSQP",
        options={"ftol": 1e-9, "maxiter": 200},
    )
    assert search.success
    assert life["beta_form"] == pytest.approx(np.linalg.norm(search.x), rel=1e-5)


@pytest.mark.usefixtures("default_report")  # its programs compiled once, not by two at once
def test_cli_reliability_table_with_the_default_tolerances(tmp_path):
    from command import run_cli
    from test_optimize_cli import strict_json

    out = tmp_path / "report"
    result = run_cli("--reliability", "--out", str(out), "--progress", "off")
    assert result.returncode == 0, result.stderr
    table = strict_json(out / "report.json")["reliability"]
    assert table["tolerances"].startswith("default")
    assert set(table["inputs"]) == {"R", "d_roller", "conformity", "hertz.P_d"}
    names = [r["name"] for r in table["requirements"]]
    assert names[:2] == ["static_capacity", "life"]
    for r in table["requirements"]:
        assert r["samples"] >= 100_000 and isinstance(r["agree"], bool)
        lo, hi = r["mc_interval_95"]
        assert lo <= r["probability_mc"] <= hi
    assert (out / "importance.png").stat().st_size > 0


@pytest.mark.usefixtures("default_report")  # its programs compiled once, not by two at once
@pytest.mark.parametrize(
    ("extra", "flags"),
    [("", ()), ("[constraints]\nmax_failure_probability_life = 1e-3\n", ("--reliability",))],
    ids=["own-uncertainty", "chance-constraint-and-flag"],
)
def test_cli_spec_with_its_own_uncertainty(tmp_path, extra, flags):
    """A spec's own [uncertainty] (issue 36: a TypeError after the solve, exit 1, no report):
    exit 0 and its reliability table, with a chance constraint and --reliability too. The
    sensitivities are derivatives w.r.t. the model's numbers, none of the uncertainty tables."""
    from command import run_cli
    from reference import reference_default_design
    from test_optimize_cli import strict_json

    spec, out = tmp_path / "spec.toml", tmp_path / "report"
    spec.write_text(TOLERANCES + extra, encoding="utf-8")
    result = run_cli(str(spec), *flags, "--out", str(out), "--progress", "off")
    assert result.returncode == 0, result.stderr
    report = strict_json(out / "report.json")
    table = report["reliability"]
    assert table["tolerances"] == "spec"
    assert set(table["inputs"]) == {"R", "d_roller", "conformity", "hertz.P_d"}
    assert (out / "importance.png").stat().st_size > 0
    assert report["sensitivities"] and not any(
        k.startswith("uncertainty") for k in report["sensitivities"]
    )
    assert report["spec"]["uncertainty"]["hertz"]["P_d"]["distribution"] == "normal"
    life = row(table, "life")
    if extra:  # the chance constraint is active: FORM's β at the design is −Φ⁻¹(1e-3)
        assert report["multipliers"]["max_failure_probability_life"] > 0
        assert life["beta_form"] == pytest.approx(-stats.norm.ppf(1e-3), rel=0.01)
    else:  # the tolerances alone change no deterministic number: the workbook chain's design
        R, d = reference_default_design()
        assert report["design"]["R_mm"] == pytest.approx(R, rel=2e-3)
        assert report["design"]["d_roller_mm"] == pytest.approx(d, rel=2e-3)


def test_reliability_index_and_probability_forms_are_one_constraint():
    """min_reliability_index_life = β and max_failure_probability_life = Φ(−β) give one margin."""
    beta = 2.5
    by_index = optimize.parse_spec(
        TOLERANCES + f"[constraints]\nmin_reliability_index_life = {beta}\n"
    )
    by_p = optimize.parse_spec(
        TOLERANCES
        + f"[constraints]\nmax_failure_probability_life = {float(stats.norm.sf(beta))!r}\n"
    )
    assert (
        by_index.structure.chance[0][1] == "index" and by_p.structure.chance[0][1] == "probability"
    )
    design = {"R": 25.55, "d_roller": 43.5}
    a = optimize.evaluate(by_index, design)["constraints"]["min_reliability_index_life"]
    b = optimize.evaluate(by_p, design)["constraints"]["max_failure_probability_life"]
    assert a == pytest.approx(b, abs=1e-9)
    # At the design, FORM's β is above 2.5 exactly when the PMA margin is positive.
    form = row(optimize.reliability(by_index, design, "form"), "life")
    assert (form["beta_form"] > beta) == (a > 0)


def test_each_chance_margin_is_its_requirements_lowest_margin_on_the_sphere():
    """The chance margins are computed from their own requirements alone
    (``chance_target_structure``; a chance on the life computes Hertz and life, nothing of the
    halfshaft or the objective). Each is the PMA's lowest margin on |u| = β of that requirement
    *of the whole requirement structure*: at least the sphere's minimum found by an independent
    search (scipy SLSQP from ±e_i, the margins through ``limit_state`` of every requirement), and
    within the 12 PMA steps' reach of it: to roundoff where the margin is linear in u (R/d, the
    capacity's power law, a shaft area no uncertain number moves), 1e-4 (log margin) for the
    curved life. Targets: Hertz, life, a spec constraint's pair, a halfshaft quantity's."""
    from scipy import optimize as scipy_optimize

    life_only = optimize.parse_spec(
        TOLERANCES + "[constraints]\nmax_failure_probability_life = 1e-3\n"
    )
    alone = optimize.problem.chance_target_structure(life_only.structure)
    assert alone.needs == {"static_capacity", "life_km"} and life_only.structure.halfshaft
    extra = (
        "[constraints]\nmax_failure_probability_life = 1e-3\n"
        "min_reliability_index_static_capacity = 2.0\n"
        "max_failure_probability_R_over_d = 0.01\n"
        "max_shaft_area = 2000.0\nmax_failure_probability_shaft_area = 0.01\n"
    )
    spec = optimize.parse_spec(TOLERANCES + extra)
    design = {"R": 25.55, "d_roller": 43.5}
    margins = optimize.evaluate(spec, design)["constraints"]
    structure = requirement_structure(spec.structure)
    names = optimize.problem.constraint_names(structure)
    values, x = optimize.problem.design_values(spec, design)
    values = jax.tree_util.tree_map(jnp.asarray, values)
    with jax.enable_x64(True):
        x = jnp.asarray(x)

        def margins_at(u):
            return optimize.problem.limit_state(structure, values, x, u)[0]

        every = jax.jit(lambda u: (margins_at(u), jax.jacfwd(margins_at)(u)))  # one program
        checked = 0
        for key, kind, requirements in spec.structure.chance:
            number = spec.values["constraints"][key]
            beta = -stats.norm.ppf(number) if kind == "probability" else number
            for name in requirements:
                i = names.index(name)

                def g(u, i=i):
                    return [np.asarray(a)[i] for a in every(jnp.asarray(u))]

                searches = [
                    scipy_optimize.minimize(
                        g,
                        beta * start,
                        jac=True,
                        constraints=[
                            {
                                "type": "eq",
                                "fun": lambda u, b=beta: u @ u - b * b,
                                "jac": lambda u: 2 * u,
                            }
                        ],
                        method="SLSQP",
                        options={"ftol": 1e-14, "maxiter": 300},
                    )
                    for start in np.vstack([np.eye(4), -np.eye(4)])
                ]
                lowest = min(r.fun for r in searches if r.success)
                pma = margins[key if len(requirements) == 1 else f"{key}:{name}"]
                tolerance = 1e-4 if name == "life" else 1e-12
                assert lowest - 1e-12 <= pma <= lowest + tolerance, (name, pma, lowest)
                checked += 1
    assert checked == 5
    # One chance constraint alone (no batch of targets): the same margin.
    single = optimize.evaluate(life_only, design)["constraints"]["max_failure_probability_life"]
    assert single == pytest.approx(margins["max_failure_probability_life"], abs=1e-12)


def test_a_chance_margin_with_a_non_finite_point_on_its_sphere_is_undefined():
    """A point of the PMA sphere whose margin is not finite leaves the minimum undefined: the
    chance margin is NaN with a nonfinite code, never the lowest finite point's nor the mean's
    (the nominal margin, which the solve took as the chance constraint's, 'converged').
    P_d lognormal, CoV 1e12 (σ_ln 7.4): P_d is 1.3e-9 MPa at the mean (a finite life margin,
    −248), 2e-35 MPa at u = −8 (the life overflows: no finite margin) and 1e17 MPa at u = +8.
    One program, the cases vmapped over the traced CoV and β_t: CoV 1e12 at β_t 8 (the sphere
    {−8, +8} half undefined) and at β_t 0 (the sphere is the mean: finite), CoV 0.05 at β_t 5
    (finite everywhere: the lower point, below the mean's margin)."""
    from tripodjax.optimize import problem
    from tripodjax.results import RESULTS

    spec = _without_the_range_of_p_d(
        optimize.parse_spec(
            '[uncertainty]\nhertz.P_d = { distribution = "lognormal", cov = 1e12 }\n'
            "[constraints]\nmin_reliability_index_life = 8.0\n"
        )
    )
    cov = jnp.asarray([1e12, 1e12, 0.05])
    beta = jnp.asarray([8.0, 0.0, 5.0])
    with jax.enable_x64(True):
        values, x = problem.design_values(spec, {"R": 25.55, "d_roller": 43.5})
        values = jax.tree_util.tree_map(jnp.asarray, values)

        def case(c, b):
            v = {
                **values,
                "uncertainty": {"hertz.P_d": {**values["uncertainty"]["hertz.P_d"], "spread": c}},
                "constraints": {**values["constraints"], "min_reliability_index_life": b},
            }
            (margin,), code = problem.chance_margins(spec.structure, v, jnp.asarray(x))
            at_mean = problem.limit_state(
                problem.requirement_structure(spec.structure), v, jnp.asarray(x), jnp.zeros(1)
            )[0][1]
            return margin, code, at_mean

        margin, code, at_mean = map(np.asarray, jax.jit(jax.vmap(case))(cov, beta))
    assert np.all(np.isfinite(at_mean))  # the mean's (nominal) life margin is finite
    assert np.isnan(margin[0]) and code[0, 0] == RESULTS.nonfinite
    assert margin[1] == at_mean[1] and np.all(code[1] == RESULTS.successful)
    assert np.isfinite(margin[2]) and margin[2] < at_mean[2]
    assert np.all(code[2] == RESULTS.successful)


def test_a_non_finite_chance_margin_is_named_in_the_verdict():
    """The command's verdict names the chance constraint whose margin is not finite."""
    import types

    from tripodjax.optimize.cli import EXIT_NOT_CONVERGED, _verdict

    result = types.SimpleNamespace(
        result="nonfinite",
        feasible=False,
        constraints={"life": {"margin": 0.2}, "min_reliability_index_life": {"margin": math.nan}},
    )
    message, status = _verdict(result)
    assert status == EXIT_NOT_CONVERGED and "\n" not in message
    assert message.startswith("not converged: the margin of min_reliability_index_life is not")
    assert "inverse-FORM" in message


def test_chance_margin_derivatives_are_those_at_the_point_held_fixed():
    """The chance margin's derivatives come from the PMA search's own linearisation (along x,
    as the solve takes them) and from a forward pass at the point (along a spec number, and the
    x-gradient's own derivative, as the sensitivities take them): each equals the derivative
    of the requirement's margin with the inverse-FORM point held fixed, which agrees with
    central differences. The number: R's standard deviation (it moves the point's R, so the
    margin's x-gradient depends on it). A reverse pass through the κ solve's derivatives is
    test_hertz's."""
    from jax.scipy.special import ndtri

    from tripodjax._compile import latency_bound_jit
    from tripodjax.optimize import problem

    spec = optimize.parse_spec(TOLERANCES + "[constraints]\nmax_failure_probability_life = 1e-3\n")
    with jax.enable_x64(True):
        values, x = problem.design_values(spec, {"R": 25.55, "d_roller": 43.5})
        values = jax.tree_util.tree_map(jnp.asarray, values)
        x = jnp.asarray(x)
        rs = problem.chance_target_structure(spec.structure)
        j = problem.constraint_names(rs).index("life")
        search = latency_bound_jit(lambda v, x: problem._pma_search(rs, v, x, j, -ndtri(1e-3)))
        u = search(values, x)[3]
        assert float(jnp.linalg.norm(u)) == pytest.approx(-stats.norm.ppf(1e-3), rel=1e-12)

        def with_sd(sd):
            table = values["uncertainty"]
            return {**values, "uncertainty": {**table, "R": {**table["R"], "spread": sd}}}

        def chance(sd, x):
            return problem.chance_margins(spec.structure, with_sd(sd), x)[0][0]

        def held(sd, x):
            return problem._requirement(rs, with_sd(sd), x, j, u)[0]

        @latency_bound_jit
        def derivatives(sd, x):  # value, along the sd, along x, the x-gradient along the sd
            return (
                chance(sd, x),
                jax.jacfwd(chance, 0)(sd, x),
                jax.jacrev(chance, 1)(sd, x),
                jax.jacfwd(jax.jacfwd(chance, 1), 0)(sd, x),
            )

        # The held margin: its value and x-gradient, and its derivative along the sd.
        value_and_gradient = latency_bound_jit(jax.value_and_grad(held, 1))
        along_sd = latency_bound_jit(jax.jacfwd(held, 0))
        sd = values["uncertainty"]["R"]["spread"]
        value, d_sd, gradient, mixed = derivatives(sd, x)
        reference, reference_gradient = value_and_gradient(sd, x)
        assert float(value) == pytest.approx(float(reference), abs=1e-12)
        assert float(d_sd) == pytest.approx(float(along_sd(sd, x)), rel=1e-12)
        np.testing.assert_allclose(gradient, reference_gradient, rtol=1e-12)
        # Against central differences of the held margin and of its exact x-gradient.
        step = 1e-6 * np.asarray(x)
        for i in range(x.shape[0]):
            e = jnp.zeros_like(x).at[i].set(step[i])
            difference = value_and_gradient(sd, x + e)[0] - value_and_gradient(sd, x - e)[0]
            assert float(gradient[i]) == pytest.approx(float(difference) / (2 * step[i]), rel=1e-6)
        h = 1e-3 * float(sd)
        difference = (value_and_gradient(sd + h, x)[1] - value_and_gradient(sd - h, x)[1]) / (2 * h)
        scale = float(np.max(np.abs(mixed)))  # d_roller's entry is 0
        assert scale > 0
        np.testing.assert_allclose(mixed, difference, rtol=1e-6, atol=1e-6 * scale)


def test_bench_monte_carlo_rate_runs_small():
    """The benchmark line's function end to end at a small size (figures measured, not asserted)."""
    from tripodjax.optimize.bench import monte_carlo_rate

    out = monte_carlo_rate(samples=4096, sweep_layouts=256)
    rates = (
        "hertz_life_samples_per_s",
        "kinematics_hertz_life_samples_per_s",
        "sweep_layouts_per_s",
    )
    assert all(out[k] > 0 and math.isfinite(out[k]) for k in rates)


def test_correlated_inputs_form_against_monte_carlo_and_importance():
    """A lognormal M_max correlated with P_d: the life does not use M_max, so its importance for
    the life is 0 (the correlated part is P_d's); SORM within the Monte Carlo interval (the
    required life at RESOLVABLE_KM, where β > 0; 2·10⁵ samples resolve its
    P ≈ 5·10⁻³ to ±6 %)."""
    text = TOLERANCES.replace(
        "[uncertainty]\n",
        "[uncertainty]\n"
        'loads.M_max = { distribution = "lognormal", cov = 0.1 }\n'
        'correlation = [["loads.M_max", "hertz.P_d", -0.5]]\n',
    )
    text = "[loads]\nM_max = 1154.0\n" + text  # an explicit M_max: the life does not use it
    spec = optimize.parse_spec(text).replace_values(life={"required_km": RESOLVABLE_KM})
    result = optimize.reliability(spec, None, "all", samples=200_000)
    life, static = row(result, "life"), row(result, "static_capacity")
    assert life["beta_form"] > 0 and life["agree_basis"] == "sorm"
    assert life["importance"]["loads.M_max"] < 1e-12
    assert static["importance"]["hertz.P_d"] < 1e-12 and static["importance"]["loads.M_max"] > 0.01
    lo, hi = life["mc_interval_95"]
    assert lo <= life["probability_sorm"] <= hi
