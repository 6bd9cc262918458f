"""Hertz contact, capacities and sizing (seed §4.2–4.3) against SciPy, the workbook and identities."""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.optimize import brentq
from scipy.special import ellipe, ellipk

from tripodjax import catalogue, hertz

WORKBOOK = dict(conformity=1 / 0.998, P_s=2350.0, P_d=1347.0, P_sd=2005.0, C_s=1.2)


def scipy_mu_nu(cos_tau):
    """Independent: κ from cos τ(κ) by Brent's method on SciPy's K, E; then μν."""

    def cos_tau_of(kappa):
        m = 1 - 1 / kappa**2
        K, E = ellipk(m), ellipe(m)
        return ((kappa**2 + 1) * E - 2 * K) / ((kappa**2 - 1) * E)

    kappa = brentq(lambda k: cos_tau_of(k) - cos_tau, 1 + 1e-9, 1e5, xtol=1e-14, rtol=1e-15)
    E = ellipe(1 - 1 / kappa**2)
    return kappa, (2 * kappa**2 * E / np.pi) ** (1 / 3) * (2 * E / (np.pi * kappa)) ** (1 / 3)


def test_elliptic_integrals_match_scipy():
    m = np.concatenate([[0.0, 1e-12, 1e-6], np.linspace(0.01, 0.99, 50), [0.999, 1 - 1e-6]])
    K, E = hertz.elliptic_integrals(m)
    np.testing.assert_allclose(K, ellipk(m), rtol=1e-13)
    np.testing.assert_allclose(E, ellipe(m), rtol=1e-13)


def test_elliptic_integrals_float32():
    m = np.linspace(0.0, 0.99, 23)
    K, E = hertz.elliptic_integrals(m.astype(np.float32))
    assert K.dtype == jnp.float32
    np.testing.assert_allclose(K, ellipk(m), rtol=1e-6)
    np.testing.assert_allclose(E, ellipe(m), rtol=1e-6)


def test_mu_nu_matches_independent_scipy_evaluation():
    cos_tau = np.concatenate(
        [np.linspace(1e-3, 0.99, 60), [0.995, 0.996008, 0.999, 0.9995, 0.9999]]
    )
    ours = hertz.hertz_coefficients(cos_tau)
    reference = np.array([scipy_mu_nu(c) for c in cos_tau])
    np.testing.assert_allclose(ours.kappa, reference[:, 0], rtol=1e-8)
    np.testing.assert_allclose(ours.mu_nu, reference[:, 1], rtol=1e-10)


def test_limits_of_the_hertz_coefficients():
    at_zero = hertz.hertz_coefficients(0.0)
    for name in ("kappa", "mu", "nu", "mu_nu"):
        assert float(getattr(at_zero, name)) == pytest.approx(1.0, abs=1e-14)
    near_zero = hertz.hertz_coefficients(1e-9)
    assert float(near_zero.mu) == pytest.approx(1.0, abs=1e-8) and float(
        near_zero.nu
    ) == pytest.approx(1.0, abs=1e-8)
    near_one = hertz.hertz_coefficients(np.array([0.9999, 0.99999, 0.999999]))
    assert np.all(np.isfinite(near_one.mu_nu)) and np.all(np.diff(near_one.mu_nu) > 0)
    assert np.all(near_one.result == hertz.RESULTS.successful)


def test_mu_nu_float32_close_to_float64():
    cos_tau = np.array([0.0, 0.3, 0.9, 0.996, 0.9999], np.float32)
    mu_nu32 = hertz.mu_nu(cos_tau)
    assert mu_nu32.dtype == jnp.float32
    # Against float64 at the same (float32-rounded) inputs: a few float32 ε.
    np.testing.assert_allclose(mu_nu32, hertz.mu_nu(cos_tau.astype(np.float64)), rtol=2e-6)


def test_mu_nu_derivative_matches_differences_and_is_finite_at_zero():
    c, step = 0.996, 1e-7
    grad = float(jax.grad(hertz.mu_nu)(c))
    assert grad == pytest.approx(
        (float(hertz.mu_nu(c + step)) - float(hertz.mu_nu(c - step))) / (2 * step), rel=1e-6
    )
    assert np.isfinite(float(jax.grad(hertz.mu_nu)(0.0)))


@pytest.mark.parametrize("c", [0.3, 0.996, 0.9999])
def test_mu_nu_second_derivative_in_either_mode_matches_differences(c):
    """A reverse pass through a Jacobian (the sensitivities' second order) goes through the κ
    solve's implicit derivatives, never through its loop: forward over forward and reverse
    over forward agree, and with central differences of the first derivative."""
    first = jax.grad(hertz.mu_nu)
    step = 1e-6 * (1.0 - c)
    difference = (float(first(c + step)) - float(first(c - step))) / (2 * step)
    for second in (jax.jacfwd(jax.jacfwd(hertz.mu_nu)), jax.jacrev(jax.jacfwd(hertz.mu_nu))):
        assert float(second(c)) == pytest.approx(difference, rel=1e-6)


def test_steel_constant_858_follows_from_the_elastic_constants():
    E, nu = hertz.YOUNG_MODULUS_STEEL, hertz.POISSON_STEEL
    assert 3 / (2 * math.pi) * (E / (3 * (1 - nu**2))) ** (2 / 3) == pytest.approx(
        hertz.HERTZ_STEEL, rel=2e-4
    )


def test_workbook_example_capacities():
    """Brief §4 (seed §4.3, tripod AAR): values within 0.3 %."""
    result = hertz.capacities(43.5, 25.55, **WORKBOOK)
    geometry = hertz.contact_geometry(WORKBOOK["conformity"])
    assert float(geometry.chi_q) == pytest.approx(-0.998, abs=1e-12)
    assert float(geometry.d_sum_rho) == pytest.approx(2.004, abs=1e-12)
    assert float(result.mu_nu) == pytest.approx(2.652, rel=3e-3)
    assert float(result.C_p) == pytest.approx(514.6, rel=3e-3)
    assert float(result.M_s) == pytest.approx(7991, rel=3e-3)
    assert float(result.M_d) == pytest.approx(1505, rel=3e-3)
    assert float(result.M_sd) == pytest.approx(4963, rel=3e-3)
    assert float(result.M_s) / 1154 == pytest.approx(
        6.923, rel=3e-3
    )  # the sheet's static safety at M_max


def test_workbook_and_consistent_minimum_sizes():
    common = dict(R_over_d=0.63, conformity=WORKBOOK["conformity"], P_s=2350.0, C_s=1.35)
    d_wb, R_wb = hertz.min_roller_diameter(1154.0, rule="workbook", **common)
    # The sheet's μν comes from a table (2.650 against the exact 2.6521): 0.1 %.
    assert float(d_wb) == pytest.approx(37.654, rel=1e-3) and float(R_wb) == pytest.approx(
        23.722, rel=1e-3
    )
    d_min, R_min = hertz.min_roller_diameter(1154.0, **common)
    assert float(d_min) == pytest.approx(25.1, abs=0.05)
    # The consistent rule is the inverse of the static capacity.
    check = hertz.capacities(
        d_min, R_min, conformity=common["conformity"], P_s=2350.0, P_d=1.0, P_sd=1.0, C_s=1.35
    )
    assert float(check.M_s) == pytest.approx(1154.0, rel=1e-12)


def test_torque_law_scaling_and_working_angle():
    base = hertz.capacities(40.0, 25.0, **WORKBOOK)
    bigger = hertz.capacities(80.0, 50.0, **WORKBOOK)
    assert float(bigger.M_s) == pytest.approx(8 * float(base.M_s), rel=1e-12)  # d² R
    angled = hertz.capacities(40.0, 25.0, gamma=0.4, **WORKBOOK)
    assert float(angled.M_d) == pytest.approx(
        float(base.M_d) * 0.5 * (1 + math.cos(0.4)), rel=1e-12
    )
    assert float(angled.M_s) == float(base.M_s)  # static capacity at γ = 0


def test_roller_contact_pressure_and_semi_axes():
    load, d = 12000.0, 43.5
    contact = hertz.roller_contact(load, d, conformity=1.002)
    C_p = float(hertz.conformity_coefficient(1.002))
    # p_max = C_p (Q/d²)^(1/3), the seed's 858/(μν)(QΣρ²)^(1/3) with Σρ = dΣρ/d
    assert float(contact.p_max) == pytest.approx(C_p * (load / d**2) ** (1 / 3), rel=2e-4)
    assert float(contact.p_max) == pytest.approx(
        1.5 * load / (math.pi * float(contact.a) * float(contact.b)), rel=1e-12
    )
    coeffs = hertz.hertz_coefficients(hertz.contact_geometry(1.002).cos_tau)
    assert float(contact.a) / float(contact.b) == pytest.approx(float(coeffs.kappa), rel=1e-12)
    assert float(hertz.roller_contact(0.0, d, conformity=1.002).p_max) == 0.0


def test_gradients_match_central_differences():
    def static(d, R, conformity, P_s):
        return hertz.capacities(
            d, R, conformity=conformity, P_s=P_s, P_d=1347.0, P_sd=2005.0, C_s=1.2
        ).M_s

    x = (43.5, 25.55, 1.004, 1500.0)
    for f in (static,):
        grads = jax.grad(f, argnums=(0, 1, 2, 3))(*x)
        for i, g in enumerate(grads):
            step = 1e-6 * x[i]
            plus, minus = list(x), list(x)
            plus[i] += step
            minus[i] -= step
            fd = (float(f(*plus)) - float(f(*minus))) / (2 * step)
            assert float(g) == pytest.approx(fd, rel=1e-6), (f.__name__, i)


@pytest.mark.parametrize(
    "call, message",
    [
        (
            lambda: hertz.contact_geometry(1.0),
            "conformity = 1.0 is outside the allowed range: conformity Ψ ≥ 1.0005",
        ),
        (
            lambda: hertz.capacities(-1.0, 25.0, **WORKBOOK),
            "d = -1.0 is outside the allowed range: d > 0",
        ),
        (
            lambda: hertz.capacities(43.5, 25.0, **{**WORKBOOK, "P_d": 0.0}),
            "P_d = 0.0 is outside the allowed range: P_d > 0",
        ),
        (
            lambda: hertz.min_roller_diameter(
                1154.0, R_over_d=0.63, conformity=1.002, P_s=2350.0, C_s=1.35, rule="book"
            ),
            "rule = 'book' is not allowed; allowed: 'consistent', 'workbook'",
        ),
        (
            lambda: hertz.roller_contact(-10.0, 43.5, conformity=1.002),
            "load = -10.0 is outside the allowed range: load ≥ 0 N",
        ),
    ],
)
def test_bad_inputs_raise_clear_errors(call, message):
    with pytest.raises(ValueError) as info:
        call()
    assert message in str(info.value)


@pytest.mark.parametrize("cos_tau", [1.0, 1.5, -0.5, -1e-300, np.nan, np.inf, -np.inf])
def test_mu_nu_rejects_cos_tau_outside_zero_one(cos_tau):
    for f in (hertz.mu_nu, hertz.hertz_coefficients):
        with pytest.raises(
            ValueError, match=r"cos_tau.* is outside the allowed range: 0 ≤ cos_tau < 1"
        ):
            f(cos_tau)
    with pytest.raises(ValueError, match=r"cos_tau\[1\]"):
        hertz.mu_nu(np.array([0.5, cos_tau]))


def test_mu_nu_inside_jit_gives_nan_and_a_code_for_bad_cos_tau():
    bad = np.array([0.5, 1.0, 1.5, -0.5, np.nan, np.inf])
    c = jax.jit(hertz.hertz_coefficients)(bad)
    assert np.isfinite(c.mu_nu[0]) and c.result[0] == hertz.RESULTS.successful
    assert np.all(np.isnan(c.mu_nu[1:])) and np.all(np.isnan(c.kappa[1:]))
    # a finite cos τ outside [0, 1) is outside the domain; NaN and inf are non-finite
    assert np.all(c.result[1:4] == hertz.RESULTS.outside_validity)
    assert np.all(c.result[4:] == hertz.RESULTS.nonfinite)
    assert c.result.dtype == jnp.int32


def test_kappa_solve_reports_the_iteration_cap(monkeypatch):
    monkeypatch.setattr(hertz, "_KAPPA_MAX_STEPS", 1)
    for c in (0.9, 0.999):
        c = jnp.asarray(c)
        code = hertz._newton_log_kappa(jnp.log1p(-c), c)[-1]
        assert code == hertz.RESULTS.max_steps_reached


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_result_codes_are_successful_on_the_workbook_example(dtype):
    caps = hertz.capacities(dtype(43.5), dtype(25.55), **WORKBOOK)
    assert caps.result == hertz.RESULTS.successful
    contact = hertz.roller_contact(dtype(12000.0), dtype(43.5), conformity=1.002)
    assert contact.result == hertz.RESULTS.successful


@pytest.mark.parametrize("n_rollers", [-3, 0])
def test_capacities_reject_fewer_than_one_roller(n_rollers):
    with pytest.raises(
        ValueError, match=rf"n_rollers = {n_rollers} is outside the allowed range: an integer ≥ 1"
    ):
        hertz.capacities(43.5, 25.55, n_rollers=n_rollers, **WORKBOOK)


@pytest.mark.parametrize("n_rollers", [2.5, 3.0, True, "3", None, [3]])
def test_capacities_reject_a_non_integer_roller_count(n_rollers):
    with pytest.raises(TypeError, match="n_rollers = .* is not allowed; allowed: an integer ≥ 1"):
        hertz.capacities(43.5, 25.55, n_rollers=n_rollers, **WORKBOOK)


def test_n_rollers_accepts_python_and_numpy_integers():
    three = hertz.capacities(43.5, 25.55, **WORKBOOK)
    for n in (3, np.int32(3), np.int64(3)):
        assert float(hertz.capacities(43.5, 25.55, n_rollers=n, **WORKBOOK).M_s) == float(three.M_s)


@pytest.mark.parametrize("conformity", [1.0 + 1e-15, 1.0004, 1.0, 0.99, np.nan, np.inf])
def test_conformity_has_a_physical_lower_limit(conformity):
    kwargs = {**WORKBOOK, "conformity": conformity}
    with pytest.raises(ValueError, match=r"conformity = .* conformity Ψ ≥ 1.0005"):
        hertz.capacities(43.5, 25.55, **kwargs)
    with pytest.raises(ValueError, match=r"conformity Ψ ≥ 1.0005"):
        hertz.conformity_coefficient(conformity)


def test_conformity_limit_itself_is_allowed():
    assert hertz.MIN_CONFORMITY == 1.0005
    caps = hertz.capacities(43.5, 25.55, **{**WORKBOOK, "conformity": hertz.MIN_CONFORMITY})
    assert np.isfinite(float(caps.M_s)) and caps.result == hertz.RESULTS.successful


def test_non_finite_inputs_inside_jit_give_nan_and_a_nonfinite_code():
    def caps(d, R, conformity, P_s):
        return hertz.capacities(
            d, R, conformity=conformity, P_s=P_s, P_d=1347.0, P_sd=2005.0, C_s=1.2
        )

    f = jax.jit(caps)
    good = f(43.5, 25.55, 1.002, 2350.0)
    assert good.result == hertz.RESULTS.successful and np.isfinite(float(good.M_s))
    for args in [
        (np.nan, 25.55, 1.002, 2350.0),
        (np.inf, 25.55, 1.002, 2350.0),
        (43.5, -np.inf, 1.002, 2350.0),
        (43.5, 25.55, np.inf, 2350.0),
        (43.5, 25.55, np.nan, 2350.0),
        (43.5, 25.55, 1.002, np.inf),
    ]:
        out = f(*args)
        assert np.isnan(float(out.M_s)), args
        assert out.result == hertz.RESULTS.nonfinite, args

    torque = jax.jit(lambda p: hertz.torque_at_pressure(p, 43.5, 25.55, C_p=514.6, C_s=1.2))
    assert np.isnan(float(torque(np.inf))) and np.isnan(float(torque(np.nan)))
    d_min = jax.jit(
        lambda m: hertz.min_roller_diameter(
            m, R_over_d=0.63, conformity=1.002, P_s=2350.0, C_s=1.35
        )[0]
    )
    assert np.isnan(float(d_min(np.inf))) and np.isfinite(float(d_min(1154.0)))
    contact = jax.jit(lambda q: hertz.roller_contact(q, 43.5, conformity=1.002))(np.inf)
    assert np.isnan(float(contact.p_max)) and contact.result == hertz.RESULTS.nonfinite
    K, E = jax.jit(hertz.elliptic_integrals)(jnp.array([np.nan, 1.5, -0.5]))
    assert np.all(np.isnan(K)) and np.all(np.isnan(E))


def test_traced_n_rollers_and_gradients_still_work():
    def static(d, n):
        return hertz.capacities(d, 25.55, n_rollers=n, **WORKBOOK).M_s

    g3 = jax.grad(static)(43.5, 3)
    gj = jax.jit(jax.grad(static))(43.5, 3)
    assert float(g3) == pytest.approx(float(gj), rel=1e-12)
    assert float(g3) == pytest.approx(2 * float(static(43.5, 3)) / 43.5, rel=1e-10)  # M ∝ d²


def test_capacity_law_calibrated_on_one_catalogue_size_predicts_the_others():
    """GE catalogue (seed §1.1.2): M_d ∝ d² R, one constant calibrated on the GE 86."""
    ref = catalogue.GE["86"]
    k = ref["M_d"] / (ref["d"] ** 2 * ref["R"])
    errors = [k * s["d"] ** 2 * s["R"] / s["M_d"] - 1 for s in catalogue.GE.values()]
    assert max(abs(e) for e in errors) < 0.1


def test_arguments_whose_shapes_do_not_broadcast_are_named():
    d, R = np.array([40.0, 41.0, 42.0]), np.array([25.0, 26.0])
    calls = (
        lambda: hertz.capacities(
            d, R, conformity=1.002, P_s=2350.0, P_d=1347.0, P_sd=2005.0, C_s=1.2
        ),
        lambda: hertz.torque_at_pressure(1347.0, d, R, C_p=514.6, C_s=1.2),
        lambda: hertz.roller_contact(np.ones(2) * 1e4, d, conformity=1.002),
        lambda: hertz.min_roller_diameter(
            np.array([900.0, 1000.0]), R_over_d=d / 60.0, conformity=1.002, P_s=2350.0, C_s=1.2
        ),
    )
    for call in calls:
        with pytest.raises(
            ValueError, match=r"^the arguments have shapes \w+ \(\d,\), \w+ \(\d,\)"
        ):
            call()
    # shapes that broadcast keep working: one capacity per (d, R) pair
    pairs = hertz.capacities(
        d[:2], R, conformity=1.002, P_s=2350.0, P_d=1347.0, P_sd=2005.0, C_s=1.2
    )
    assert np.shape(pairs.M_s) == (2,)


def test_sizes_outside_their_domain_inside_jit_give_nan_and_a_code():
    """Concrete values are refused at the call; traced ones outside the domain (a negative
    diameter or pressure) give NaN capacities and ``outside_validity``, never a plausible
    number."""
    from tripodjax.results import RESULTS

    def of(d, P_s):
        return hertz.capacities(d, 25.55, **{**WORKBOOK, "P_s": P_s})

    for d, P_s in ((-43.5, WORKBOOK["P_s"]), (43.5, -1.0)):
        out = jax.jit(of)(d, P_s)
        assert math.isnan(float(out.M_s)) and int(out.result) == RESULTS.outside_validity
    assert int(jax.jit(of)(43.5, WORKBOOK["P_s"]).result) == RESULTS.successful


# Good values of every input of the traced domain check below, and one bad value per row.
_GOOD = dict(
    d=43.5,
    R=25.55,
    conformity=1.004,
    P_s=2350.0,
    C_s=1.2,
    gamma=0.1,
    helix_angle=0.0,
    pressure_angle=math.pi / 2,
    n_rollers=3,
    longitudinal_conformity=0.0,
    load=5000.0,
    poisson=0.3,
    young_modulus=208_000.0,
    M_max=1000.0,
    R_over_d=0.6,
    pressure=1347.0,
)
_BAD = [
    ("d", -20.0),
    ("R", -25.0),
    ("conformity", 1.0002),  # above 1 but below MIN_CONFORMITY
    ("P_s", -4000.0),
    ("C_s", -1.2),
    ("gamma", 2.0),  # ≥ π/2
    ("helix_angle", 2.0),
    ("pressure_angle", 2.0),
    ("n_rollers", -3),
    ("longitudinal_conformity", 1.5),
    ("load", -5000.0),
    ("poisson", 0.7),
    ("poisson", -1.5),
    ("young_modulus", -208_000.0),
    ("M_max", -1000.0),
    ("R_over_d", -0.6),
    ("pressure", -1347.0),
]
# The inputs each output uses: an output outside them stays finite and successful.
_USES = {
    "caps": {"d", "R", "conformity", "P_s", "C_s", "gamma", "helix_angle", "pressure_angle"}
    | {"n_rollers", "longitudinal_conformity"},
    "contact": {"load", "d", "conformity", "poisson", "young_modulus"},
    "d_min": {"M_max", "R_over_d", "conformity", "P_s", "C_s", "n_rollers", "pressure_angle"}
    | {"helix_angle", "longitudinal_conformity"},
    "torque": {"pressure", "d", "R", "C_s", "n_rollers", "pressure_angle", "helix_angle", "gamma"},
}


@jax.jit
@jax.vmap
def _every_hertz_function(x):
    angles = dict(pressure_angle=x["pressure_angle"], helix_angle=x["helix_angle"])
    common = dict(C_s=x["C_s"], n_rollers=x["n_rollers"], **angles)
    caps = hertz.capacities(
        x["d"],
        x["R"],
        conformity=x["conformity"],
        P_s=x["P_s"],
        P_d=0.6 * x["P_s"],
        P_sd=0.85 * x["P_s"],
        gamma=x["gamma"],
        longitudinal_conformity=x["longitudinal_conformity"],
        **common,
    )
    contact = hertz.roller_contact(
        x["load"],
        x["d"],
        conformity=x["conformity"],
        young_modulus=x["young_modulus"],
        poisson=x["poisson"],
    )
    d_min, _ = hertz.min_roller_diameter(
        x["M_max"],
        R_over_d=x["R_over_d"],
        conformity=x["conformity"],
        P_s=x["P_s"],
        rule="workbook",
        longitudinal_conformity=x["longitudinal_conformity"],
        **common,
    )
    torque = hertz.torque_at_pressure(
        x["pressure"], x["d"], x["R"], C_p=514.6, gamma=x["gamma"], **common
    )
    return {
        "caps": (caps.M_d, caps.result),
        "contact": (contact.p_max, contact.result),
        "d_min": (d_min, None),
        "torque": (torque, None),
    }


def test_traced_inputs_outside_their_domain_give_nan_and_outside_validity():
    """Inside jit every hertz function flags a finite input outside its domain: NaN, and
    ``outside_validity`` where it returns a code (a NaN input stays ``nonfinite``); before, a
    negative d or P_s, γ or ζ ≥ π/2, ν_P = 0.7… gave the plausible number, result 0."""
    rows = [dict(_GOOD)] + [{**_GOOD, name: value} for name, value in _BAD]
    rows.append({**_GOOD, "d": np.nan})
    batch = {k: np.array([row[k] for row in rows]) for k in _GOOD}
    out = jax.device_get(_every_hertz_function(batch))
    for i, bad in enumerate([None, *(name for name, _ in _BAD), "nan d"]):
        for output, (value, code) in out.items():
            if bad is None or (bad not in _USES[output] and bad != "nan d"):
                assert np.isfinite(value[i]), (bad, output)
                assert code is None or code[i] == hertz.RESULTS.successful, (bad, output)
            elif bad == "nan d":
                if "d" in _USES[output]:
                    assert np.isnan(value[i]), output
                    assert code is None or code[i] == hertz.RESULTS.nonfinite, output
            else:
                assert np.isnan(value[i]), (bad, output, value[i])
                assert code is None or code[i] == hertz.RESULTS.outside_validity, (bad, output)


@pytest.mark.parametrize(
    "call, message",
    [
        (lambda: hertz.roller_contact(100.0, 20.0, conformity=1.004, poisson=0.7), "poisson"),
        (lambda: hertz.roller_contact(100.0, 20.0, conformity=1.004, young_modulus=-1.0), "young"),
        (lambda: hertz.capacities(43.5, 25.55, gamma=2.0, **WORKBOOK), "0 ≤ gamma < π/2"),
        (
            lambda: hertz.torque_at_pressure(1347.0, -43.5, 25.55, C_p=514.6, C_s=1.2),
            "d = -43.5 is outside the allowed range: d > 0",
        ),
        (
            lambda: hertz.min_roller_diameter(
                1000.0, R_over_d=0.6, conformity=1.004, P_s=-4000.0, C_s=1.2, rule="workbook"
            ),
            "P_s = -4000.0 is outside the allowed range: P_s > 0",
        ),
        (lambda: hertz.contact_geometry(1.004, 1.5), "longitudinal_conformity = 1.5"),
        (lambda: hertz.hertz_coefficients([]), "cos_tau is empty (shape (0,))"),
        (lambda: hertz.capacities([], 25.55, **WORKBOOK), "d is empty (shape (0,))"),
        (lambda: hertz.roller_contact([], 43.5, conformity=1.002), "load is empty"),
        (lambda: hertz.elliptic_integrals(np.zeros((2, 0))), "m is empty (shape (2, 0))"),
    ],
)
def test_concrete_inputs_outside_their_domain_or_empty_are_refused_in_one_line(call, message):
    with pytest.raises(ValueError) as info:
        call()
    assert message in str(info.value) and "\n" not in str(info.value)


def test_lists_work_as_arrays():
    caps = hertz.capacities([43.5, 44.0], 25.55, **WORKBOOK)
    np.testing.assert_allclose(
        caps.M_s, [float(hertz.capacities(d, 25.55, **WORKBOOK).M_s) for d in (43.5, 44.0)]
    )
    cos_tau = hertz.contact_geometry([1.004, 1.005]).cos_tau
    np.testing.assert_allclose(cos_tau, [1 / (2 * c - 1) for c in (1.004, 1.005)], rtol=1e-12)
    p = hertz.roller_contact([100.0, 800.0], 20.0, conformity=1.004).p_max
    assert float(p[1]) == pytest.approx(2 * float(p[0]), rel=1e-12)  # p ∝ Q^(1/3)
    np.testing.assert_allclose(hertz.hertz_coefficients([0.0]).kappa, [1.0])
    d_min, _ = hertz.min_roller_diameter([900.0], R_over_d=0.6, conformity=1.004, P_s=2350, C_s=1)
    assert np.shape(d_min) == (1,)


def test_the_pressure_rises_with_an_infinite_slope_from_zero_load():
    """p_max ∝ Q^(1/3): its slope at Q = 0 is +∞ (NaN before); 0 beside it for the size."""
    contact = jax.jacfwd(lambda q: hertz.roller_contact(q, 20.0, conformity=1.004))(0.0)
    assert contact.p_max == np.inf and contact.a == np.inf and contact.b == np.inf
    assert jax.grad(lambda q: hertz.roller_contact(q, 20.0, conformity=1.004).p_max)(0.0) == np.inf
    by_d = jax.grad(lambda d: hertz.roller_contact(0.0, d, conformity=1.004).p_max)(20.0)
    assert float(by_d) == 0.0


def test_domain_flags_off_leaves_the_values_and_only_the_flags_out():
    """``domain_flags=False`` (the optimiser, whose spec keeps its inputs inside): the same
    capacities and life inside the domain; outside, no flag (the caller's promise)."""
    from tripodjax import life

    spectrum = life.LoadSpectrum(
        torque=[600.0, 900.0], speed=[700.0, 300.0], share=[0.6, 0.4], vehicle_speed=[50.0, 90.0]
    )
    conditions = life.WorkingConditions(angle=[0.1, 0.2], share=[0.5, 0.5])

    def both(P_s, flags):
        caps = hertz.capacities(20.0, 25.0, **{**WORKBOOK, "P_s": P_s}, domain_flags=flags)
        hours = life.joint_life(
            20.0, 25.0, spectrum, conditions, conformity=1.004, P_d=P_s, C_s=1.2, domain_flags=flags
        )
        return caps.M_s, caps.result, hours.km, hours.result

    on, off = (
        jax.jit(jax.vmap(lambda p, f=f: both(p, f)))(jnp.array([2350.0, -2350.0]))
        for f in (True, False)
    )
    for a, b in zip(on, off, strict=True):
        np.testing.assert_array_equal(np.asarray(a)[0], np.asarray(b)[0])
    assert np.isnan(on[0][1]) and on[1][1] == hertz.RESULTS.outside_validity
    assert np.isnan(on[2][1]) and on[3][1] == hertz.RESULTS.outside_validity
    with pytest.raises(
        TypeError, match="domain_flags = 'no' is not allowed; allowed: True or False"
    ):
        hertz.capacities(20.0, 25.0, **WORKBOOK, domain_flags="no")
