"""The shaft's sections as design variables and the rest of the halfshaft as constraints.

The smallest passing diameter the optimiser finds is checked against a root found by scipy's
brentq on the margins computed by tripodjax.shaft directly, on the vehicle built by hand
(tests/test_vehicle.py), and the model's derivatives of the damage and the static safety
against central differences of tripodjax.shaft through the same load cycles.
"""

import dataclasses
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.optimize import brentq
from test_vehicle import workbook_modes, workbook_vehicle

from tripodjax import optimize, shaft, vehicle
from tripodjax.optimize import problem, structural

STEM = "outboard stem"
FREE = f"shaft.outer_diameter_mm[{STEM}]"
SPEC_TEXT = f"""
[bounds]
"{FREE}" = [14.0, 34.0]
[objective]
w_shaft_area = 1.0
shaft_area_ref = 3000.0
"""
# The fatigue case: a low allowed damage, the inboard stem (not free) thickened to pass it.
FATIGUE = {"allowed_damage": 0.15, "outer_diameter_mm": [26.0, 27.5, 25.8, 30.685, 34.0]}


@pytest.fixture(scope="module")
def spec():
    return optimize.parse_spec(SPEC_TEXT)


@pytest.fixture(scope="module")
def by_hand():
    """(rows, torque) of the fatigue and static checks, from the vehicle built by hand."""
    with jax.enable_x64(True):
        modes = workbook_modes()
        cycles = vehicle.load_cycles(workbook_vehicle(front_share=0.328), modes, 100_000.0)
        rows = shaft.fatigue_cycles(cycles, modes)
        torque = jnp.stack([cycles.M_max_forward, cycles.M_max_backward])
    return rows, torque


def stem(diameter):
    section, material = shaft.WORKBOOK_SECTIONS[STEM]
    return shaft.Section(diameter, section.hardened_depth, section.transition_depth), material


def safety(diameter, torque):
    section, material = stem(diameter)
    return float(jnp.min(shaft.static_check(section, material, torque).safety))


def damage(diameter, rows):
    section, material = stem(diameter)
    return float(jnp.max(shaft.fatigue_check(section, material, rows).damage))


def smallest(margin):
    """The smallest diameter [mm] at which ``margin`` (increasing in it) is zero: brentq."""
    return brentq(margin, 13.0, 34.0, xtol=1e-13, rtol=1e-15)


@pytest.mark.parametrize("case", ["static", "fatigue"])
def test_the_smallest_passing_diameter_and_its_binding_check(spec, by_hand, case):
    rows, torque = by_hand
    if case == "fatigue":
        spec = spec.replace_values(shaft=FATIGUE)
    allowed = float(spec.values["shaft"]["allowed_damage"])
    with jax.enable_x64(True):
        roots = {
            "static": smallest(lambda d: math.log(safety(d, torque))),
            "fatigue": smallest(lambda d: math.log(allowed / damage(d, rows))),
        }
    binding = max(roots, key=roots.get)
    assert binding == case  # the two cases bind differently
    result = optimize.solve(spec, progress=False)
    assert result.converged and result.feasible
    diameter = result.design[FREE]
    # the solver keeps every margin ≥ 2·tolerance: just above the root, never below it
    assert roots[case] < diameter < roots[case] * (1 + 1e-4)
    # the binding check is named: the one active shaft or outboard constraint
    halfshaft = problem.halfshaft_constraint_names(spec.structure)
    active = [n for n in halfshaft if result.multipliers[n] > 1e-6]
    assert active == [f"shaft_{case}[{STEM}]"]
    row = result.constraints[f"shaft_{case}[{STEM}]"]
    assert row["margin"] == pytest.approx(0.0, abs=1e-4)
    if case == "static":
        assert row["value"] == pytest.approx(1.0, abs=1e-4) and row["sense"] == "≥"
    else:
        assert row["value"] == pytest.approx(allowed, rel=1e-4) and row["sense"] == "≤"
    # the R, d optimum of the default spec is untouched (the shaft does not depend on them)
    default = optimize.solve(optimize.load_spec(), progress=False)
    for k in ("R", "d_roller"):
        assert result.design[k] == pytest.approx(default.design[k], rel=1e-4)
    # the report checks the design's diameter, and it passes
    report = optimize.halfshaft_report(spec, result.design)
    section = {s["name"]: s for s in report["sections"]}[STEM]
    assert section["outer_diameter_mm"] == diameter
    assert section["static_passed"] and section["fatigue_passed"] and report["passed"]
    # just below the optimum it fails the binding check (the optimum is the smallest)
    below = optimize.halfshaft_report(spec, dict(result.design, **{FREE: roots[case] * 0.999}))
    section = {s["name"]: s for s in below["sections"]}[STEM]
    assert not section["static_passed" if case == "static" else "fatigue_passed"]


@pytest.mark.parametrize("x64", [True, False], ids=["float64", "float32"])
def test_the_damage_and_safety_derivatives_equal_central_differences(spec, by_hand, x64):
    rows, torque = by_hand
    structure, values = spec.structure, spec.values
    d0 = 21.0

    def model(x):
        design = problem.full_design(structure, values, x)
        _, sections, _ = structural.halfshaft_quantities(structure, values, design)
        return sections[f"shaft_damage[{STEM}]"], sections[f"shaft_static_safety[{STEM}]"]

    with jax.enable_x64(x64):
        dtype = jnp.float64 if x64 else jnp.float32
        x = jnp.asarray([26.05, 41.35, d0], dtype)
        # one program (each operation compiled alone took 150 compilations)
        out, tangent = jax.jit(lambda x: jax.jvp(model, (x,), (jnp.eye(3, dtype=dtype)[2],)))(x)
        assert out[0].dtype == dtype
        value, slope = np.asarray(out, np.float64), np.asarray(tangent, np.float64)
    with jax.enable_x64(True):
        h = 1e-4
        central = [
            (damage(d0 + h, rows) - damage(d0 - h, rows)) / (2 * h),
            (safety(d0 + h, torque) - safety(d0 - h, torque)) / (2 * h),
        ]
        expected = [damage(d0, rows), safety(d0, torque)]
    rtol = 1e-7 if x64 else 2e-4
    np.testing.assert_allclose(value, expected, rtol=1e-12 if x64 else 1e-5)
    np.testing.assert_allclose(slope, central, rtol=rtol)
    assert slope[0] < 0 < slope[1]  # a thicker section: less damage, more safety


def test_the_default_spec_checks_the_halfshaft_by_default():
    spec = optimize.load_spec()
    names = problem.constraint_names(spec.structure)
    assert names[:4] == ("static_capacity", "life", "shaft_static[A-A]", "shaft_fatigue[A-A]")
    assert names[-4:-2] == ("outboard_static", "outboard_life")
    out = optimize.evaluate(spec, {"R": 26.05, "d_roller": 41.35})
    report = optimize.halfshaft_report(spec)
    for s in report["sections"]:
        margin = out["constraints"][f"shaft_static[{s['name']}]"]
        assert margin == pytest.approx(math.log(s["static_safety"]), rel=1e-12)
        margin = out["constraints"][f"shaft_fatigue[{s['name']}]"]
        assert margin == pytest.approx(math.log(1.0 / s["damage"]), rel=1e-12)
        assert out["quantities"][f"shaft_damage[{s['name']}]"] == pytest.approx(s["damage"])
    joint = report["outboard"]
    assert out["constraints"]["outboard_static"] == pytest.approx(
        math.log(joint["static_safety"] / 1.1), rel=1e-12
    )
    assert out["constraints"]["outboard_life"] == pytest.approx(
        math.log(joint["life_km"] / 100_000.0), rel=1e-12
    )
    # Two programs (the solve's and the report's) agree to roundoff, not bit for bit.
    largest = max(s["damage"] for s in report["sections"])
    assert out["quantities"]["shaft_damage"] == pytest.approx(largest, rel=1e-12)
    assert out["quantities"]["shaft_area"] == pytest.approx(
        sum(math.pi / 4 * s["outer_diameter_mm"] ** 2 for s in report["sections"]), rel=1e-12
    )


def test_the_constraints_no_free_variable_changes_are_named(spec):
    from types import SimpleNamespace

    from tripodjax.optimize.cli import _verdict

    default = optimize.load_spec().structure
    halfshaft = problem.halfshaft_constraint_names(default)
    assert problem.fixed_constraints(default) == halfshaft  # no [shaft] entry free
    fixed = problem.fixed_constraints(spec.structure)  # the outboard stem's diameter free
    assert f"shaft_static[{STEM}]" not in fixed and f"shaft_fatigue[{STEM}]" not in fixed
    assert set(fixed) == set(halfshaft) - {f"shaft_static[{STEM}]", f"shaft_fatigue[{STEM}]"}
    # An infeasible run names a violated constraint that no free variable changes (the
    # outboard's 117 001 km with the workbook reading against a required 120 000 km: ln = -0.0253).
    margins = {"life": 0.1, "outboard_life": -0.0253, f"shaft_fatigue[{STEM}]": -0.01}
    result = SimpleNamespace(
        result="successful",
        feasible=False,
        constraints={k: {"margin": m} for k, m in margins.items()},
        starts=[{"feasible": False}],
        structure=spec.structure,
    )
    message, _ = _verdict(result)
    assert message == (
        "infeasible: no start reached feasibility; largest violations: outboard_life (margin "
        f"-0.0253; no free variable changes it), shaft_fatigue[{STEM}] (margin -0.01)"
    )


def test_the_report_tables_give_a_shaft_variable_its_unit_and_spec_value():
    from tripodjax.optimize import document

    body = {
        "free_variables": ["R", "d_roller", FREE],
        "design": {"R_mm": 26.0, "d_roller_mm": 41.0, FREE: 21.5},
        "objective": 1.0,
        "constraints": {},
        "catalogue_choice": {
            "family": "GE",
            "size": "86",
            "R_mm": 24.0,
            "d_roller_mm": 38.0,
            "objective": 1.1,
        },
        "spec": {"shaft": {"names": ["A-A", STEM], "outer_diameter_mm": [26.0, 24.5]}},
        "pareto_front": [
            {"w_gaf_rms": 1.0, "R_mm": 26.0, "d_roller_mm": 41.0, FREE: 21.5, "converged": True}
        ],
    }
    tables = document.tables(body)
    pareto = tables["pareto_front"]
    column = [c.label for c in pareto.columns].index(f"{FREE} [mm]")
    assert pareto.rows[0][column] == 21.5
    row = next(r for r in tables["summary"].rows if r[0] == FREE)
    assert row[1:] == ["mm", 21.5, 24.5]  # the catalogue keeps the spec's diameter


LISTS = (
    "[loads]\nM_max = 1154.0\n[life]\ntorque = [1154.0, 350.0]\nspeed = [100.0, 1000.0]\n"
    "vehicle_speed = [28.0, 90.0]\nshare = [0.55, 0.45]\n"
)


def test_without_a_vehicle_the_halfshaft_is_not_a_constraint():
    spec = optimize.parse_spec(LISTS)
    assert problem.constraint_names(spec.structure)[2:4] == ("max_R_over_d", "min_R_over_d")


@pytest.mark.parametrize(
    "text, message",
    [
        (
            f'[bounds]\n"{FREE}" = [11.0, 34.0]',
            f"bounds of shaft section '{STEM}': shaft.hardened_depth_mm[3] + "
            f"shaft.transition_depth_mm[3] = 6.0 is outside the allowed range: ≤ the wall "
            f'(bounds."{FREE}"[0] − shaft.inner_diameter_mm[3])/2 (= 5.5 mm)',
        ),
        (
            '[bounds]\n"shaft.outer_diameter_mm[D-D]" = [20.0, 30.0]',
            "unknown key bounds.shaft.outer_diameter_mm[D-D]; allowed: R, d_roller, l, "
            'gamma0_deg, conformity, lam, mu_slp, or "shaft.<list>[<section>]"',
        ),
        ('[bounds]\n"shaft.safety[C-C]" = [1.0, 2.0]', "unknown key bounds.shaft.safety[C-C]"),
        (
            '[bounds]\n"shaft.inner_diameter_mm[C-C]" = [-1.0, 2.0]',
            'bounds."shaft.inner_diameter_mm[C-C]"[0] = -1.0 is not allowed: a finite number '
            "≥ 0 mm and ≤ 200 mm",
        ),
        (
            '[bounds]\n"shaft.inner_diameter_mm[C-C]" = [2.0, 1.0]',
            'bounds."shaft.inner_diameter_mm[C-C]" = [2.0, 1.0] is not allowed: [lo, hi] with lo < hi',
        ),
        (
            '[bounds]\n"shaft.hardened_depth_mm[C-C]" = [1.0, 10.0]',
            "bounds of shaft section 'C-C': bounds.\"shaft.hardened_depth_mm[C-C]\"[1] + "
            "shaft.transition_depth_mm[2] = 13.5 is outside the allowed range",
        ),
        (
            '[bounds]\nshaft.outer_diameter_mm."C-C" = [20.0, 30.0]',
            "bounds.shaft is a table; give each [shaft] entry as one quoted key, e.g. "
            '"shaft.outer_diameter_mm[C-C]" = [18.5, 30.0]',
        ),
        (
            LISTS + f'[bounds]\n"{FREE}" = [20.0, 34.0]',
            f"bounds.{FREE} needs the spec's [vehicle]",
        ),
        (
            LISTS + "[constraints]\nmax_shaft_damage = 0.5",
            "constraints.max_shaft_damage needs the spec's [vehicle]",
        ),
    ],
)
def test_bad_shaft_bounds_are_refused_in_one_line(text, message):
    with pytest.raises(optimize.SpecError) as error:
        optimize.parse_spec(text)
    assert str(error.value).startswith(message) and "\n" not in str(error.value)


def test_a_design_outside_a_sections_domain_is_refused(spec):
    with pytest.raises(ValueError, match=f"design: shaft section '{STEM}': Section.hardened_depth"):
        optimize.evaluate(spec, {"R": 26.0, "d_roller": 41.0, FREE: 11.0})
    with pytest.raises(ValueError, match=r"design\['shaft.inner_diameter_mm\[C-C\]'\] = -1.0"):
        optimize.evaluate(
            spec, {"R": 26.0, "d_roller": 41.0, FREE: 20.0, "shaft.inner_diameter_mm[C-C]": -1.0}
        )
    with pytest.raises(ValueError, match="design keys .'shaft.outer_diameter_mm.D-D.'. not"):
        optimize.evaluate(
            spec, {"R": 26.0, "d_roller": 41.0, FREE: 20.0, "shaft.outer_diameter_mm[D-D]": 9.0}
        )


def test_the_diameters_sensitivity_equals_differences_of_the_root(spec, by_hand):
    """d Øe*/d σ_R,c by the KKT system of the solve against central differences of the brentq
    root: the stem's binding static check is at the end of its layer, in the core."""
    rows, torque = by_hand
    result = optimize.solve(spec, progress=False, sensitivities=True)
    derivatives = result.sensitivities["derivatives"]
    section, material = stem(20.0)

    def root(core):
        steel = dataclasses.replace(material, core_uts=core)

        def margin(d):
            layer = shaft.Section(d, section.hardened_depth, section.transition_depth)
            return math.log(float(jnp.min(shaft.static_check(layer, steel, torque).safety)))

        return smallest(margin)

    with jax.enable_x64(True):
        h = 1e-3 * 690.0
        central = (root(690.0 + h) - root(690.0 - h)) / (2 * h)
    # the KKT system takes its Hessian by differences of exact gradients: ~1e-5 relative
    assert derivatives["shaft.core_uts_MPa"][FREE] == pytest.approx(central, rel=1e-4)
    # the free entry's own spec value is not an input; the other sections' diameters are
    index = spec.structure.shaft_sections.index(STEM)
    assert f"shaft.outer_diameter_mm[{index}]" not in derivatives
    assert derivatives["shaft.outer_diameter_mm[2]"][FREE] == 0.0
