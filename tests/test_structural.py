"""The rest of the halfshaft in the optimiser's spec and report (tripodjax.optimize.structural).

The spec's [shaft] and [outboard] defaults are the workbook's rear halfshaft (its vehicle with
the spec's front share 0.328 for 307.34/937); the report's
numbers are checked against tripodjax.shaft and tripodjax.outboard called directly on the
vehicle built by hand (tests/test_vehicle.py), and against the sheet's printed numbers.
"""

import math

import jax
import numpy as np
import pytest
from test_outboard import ANGLES_DEG, JOINT, SHARES
from test_vehicle import workbook_modes, workbook_vehicle

from tripodjax import life, optimize, outboard, shaft, vehicle
from tripodjax.optimize import document
from tripodjax.optimize.report import strict

SPEC = optimize.load_spec()
LISTS = (
    "[loads]\nM_max = 1154.0\n[life]\ntorque = [1154.0, 350.0]\nspeed = [100.0, 1000.0]\n"
    "vehicle_speed = [28.0, 90.0]\nshare = [0.55, 0.45]\n"
)


@pytest.fixture(scope="module")
def reports():
    return {
        reading: optimize.halfshaft_report(
            optimize.parse_spec(
                f'[shaft]\nreading = "{reading}"\n[outboard]\nreading = "{reading}"'
            )
        )
        for reading in shaft.READINGS
    }


@pytest.mark.parametrize("reading", shaft.READINGS)
def test_sections_equal_the_shaft_module_on_the_hand_built_vehicle(reports, reading):
    report = reports[reading]
    with jax.enable_x64(True):
        modes = workbook_modes()
        cycles = vehicle.load_cycles(workbook_vehicle(front_share=0.328), modes, 100_000.0)
        rows = shaft.fatigue_cycles(cycles, modes, reading=reading)
        torque = np.array([float(cycles.M_max_forward), float(cycles.M_max_backward)])
        assert [report["static_torque_Nm"][k] for k in ("forward", "backward")] == pytest.approx(
            torque, rel=1e-12
        )
        assert list(shaft.WORKBOOK_SECTIONS) == [s["name"] for s in report["sections"]]
        for row, (section, material) in zip(
            report["sections"], shaft.WORKBOOK_SECTIONS.values(), strict=True
        ):
            static = shaft.static_check(section, material, torque)
            fatigue = shaft.fatigue_check(section, material, rows, reading=reading)
            assert row["static_safety"] == pytest.approx(float(np.min(static.safety)), rel=1e-12)
            outer, core = map(float, fatigue.damage)
            assert row["damage_outer"] == pytest.approx(outer, rel=1e-12)
            assert row["damage_core"] == pytest.approx(core, rel=1e-12)
            assert row["damage"] == max(row["damage_outer"], row["damage_core"])
            by_gear = [g["damage"] for g in row["damage_by_gear"]]
            assert [g["gear"] for g in row["damage_by_gear"]] == ["1", "2", "3", "4", "5", "6", "R"]
            assert sum(by_gear) == pytest.approx(row["damage"], rel=1e-12)
            assert row["static_passed"] and row["fatigue_passed"]
            assert row["result"].startswith("passes")
    # The outboard's combined life passes the 100 000 km under both readings: the workbook's
    # (km = hours × the revolution-weighted V_ave, test_outboard.py) 117 001 km against the
    # sheet's 117 671 (−0.6 % with this spec's one gear-use table), the consistent one's
    # (km = the distance the revolutions roll) 107 096 km.
    km = {"consistent": 107_096.0, "workbook": 117_001.0}[reading]
    assert report["outboard"]["life_km"] == pytest.approx(km, rel=1e-4)
    assert report["outboard"]["life_passed"] and report["passed"]


@pytest.mark.parametrize("reading", outboard.READINGS)
def test_a_mileage_the_outboard_joint_does_not_reach_fails_it(reading):
    """120 000 km required: the outboard life fails under both readings, and says by how much."""
    report = optimize.halfshaft_report(
        optimize.parse_spec(f'[life]\nrequired_km = 120000.0\n[outboard]\nreading = "{reading}"')
    )
    joint = report["outboard"]
    assert joint["required_km"] == 120_000.0 and joint["static_passed"]
    assert not joint["life_passed"] and not report["passed"]
    assert joint["life_km"] < 120_000.0
    assert f"life {joint['life_km']:.0f} km < 120000 km" in joint["result"]
    assert "outboard joint fails" in optimize.structural.summary(report)


def test_the_workbook_reading_gives_the_sheets_stem_damage_and_outboard_capacities(reports):
    report = reports["workbook"]
    stem = {s["name"]: s for s in report["sections"]}["outboard stem"]
    # fig. 4.3.7 prints 0.0835 and 0.122; its legible rows give these (docs/physics.md's gap)
    assert stem["damage_outer"] == pytest.approx(0.0784, abs=5e-4)
    assert stem["damage_core"] == pytest.approx(0.1161, abs=5e-4)
    joint = report["outboard"]
    # fig. 4.3.10, second column: M_s 6734, M_d 1269, M_sd 4183 N·m; static safety 5.833
    for key, printed in (("M_s_Nm", 6734.0), ("M_d_Nm", 1269.0), ("M_sd_Nm", 4183.0)):
        assert joint[key] == pytest.approx(printed, rel=5e-3), key
    assert joint["static_safety"] == pytest.approx(5.833, rel=5e-3)


@pytest.mark.parametrize("reading", outboard.READINGS)
def test_outboard_equals_the_outboard_module(reports, reading):
    joint = reports[reading]["outboard"]
    with jax.enable_x64(True):
        fixed = outboard.FixedJoint(**JOINT)
        cycles = vehicle.load_cycles(
            workbook_vehicle(front_share=0.328), workbook_modes(), 100_000.0
        )
        caps = outboard.capacities(fixed, reading=reading)
        out = outboard.joint_life(
            fixed,
            vehicle.load_spectrum(cycles),
            life.WorkingConditions(np.radians(ANGLES_DEG), SHARES),
            reading=reading,
        )
        M_max = float(cycles.M_max_forward)
    assert joint["M_s_Nm"] == pytest.approx(float(caps.M_s), rel=1e-12)
    assert joint["static_safety"] == pytest.approx(float(caps.M_s) / M_max, rel=1e-12)
    assert joint["required_static_safety"] == 1.1  # the tripod's rule: M_s ≥ k_s M_max
    assert joint["life_km"] == pytest.approx(float(out.km), rel=1e-12)
    assert [c["life_km"] for c in joint["conditions"]] == pytest.approx(
        np.asarray(out.km_per_condition), rel=1e-12
    )
    assert [c["angle_deg"] for c in joint["conditions"]] == pytest.approx(ANGLES_DEG, rel=1e-12)
    assert joint["life_passed"] == (joint["life_km"] >= 100_000.0)


def test_a_given_m_max_is_the_forward_torque_of_every_part(reports):
    """loads.M_max with the default [vehicle] (for the spectrum): the shaft sections and the
    outboard joint are checked statically at that M_max forward, as the tripod is (the parts
    carry the same torque in series); backward stays the vehicle's reverse-gear torque."""
    given = optimize.halfshaft_report(optimize.parse_spec("[loads]\nM_max = 1300.0"))
    vehicle_only = reports["consistent"]
    assert given["static_torque_Nm"]["forward"] == 1300.0
    assert given["static_torque_Nm"]["backward"] == vehicle_only["static_torque_Nm"]["backward"]
    assert vehicle_only["static_torque_Nm"]["forward"] != 1300.0
    joint = given["outboard"]
    assert joint["static_safety"] == pytest.approx(joint["M_s_Nm"] / 1300.0, rel=1e-12)


def test_a_failing_section_is_named_with_its_check():
    thin = optimize.parse_spec(
        "[shaft]\nouter_diameter_mm = [26.0, 27.5, 16.0, 30.685, 28.44]\n"
        "hardened_depth_mm = [5.6, 5.6, 3.0, 2.5, 1.2]\n"
        "transition_depth_mm = [3.5, 3.5, 2.0, 3.5, 1.1]"
    )
    report = optimize.halfshaft_report(thin)
    c_c = report["sections"][2]
    assert not c_c["fatigue_passed"] and c_c["damage"] > 1
    assert c_c["result"] == (
        f"fails: static safety {c_c['static_safety']:.3g} < 1; damage {c_c['damage']:.3g} > 1"
    )
    assert not report["passed"]
    from tripodjax.optimize import structural

    assert structural.summary(report) == f"halfshaft: C-C {c_c['result']}"
    # the report's table says so in words, beside the number
    table = document.tables({"halfshaft": report})["halfshaft"]
    fatigue = [r for r in table.rows if r[0] == "C-C" and r[1].startswith("fatigue")][0]
    assert fatigue[3] == c_c["damage"] and fatigue[4] == "fails"
    assert "does NOT pass" in table.notes[0]


def test_a_vehicle_without_torque_passes_nothing_and_says_why():
    """Working torques of 5e-324 N·m: no static safety, no damage is finite; nothing passes."""
    torques = ", ".join(["5e-324"] * len(SPEC.values["vehicle"]["engine_torque_Nm"]))
    report = optimize.halfshaft_report(
        optimize.parse_spec(f"[vehicle]\nengine_torque_Nm = [{torques}]")
    )
    assert not report["passed"]
    for s in report["sections"]:
        assert not (s["static_passed"] or s["fatigue_passed"])
        assert s["status"] == "nonfinite" and s["result"].startswith("fails: not computed (")
    joint = report["outboard"]
    assert not (joint["static_passed"] or joint["life_passed"])
    assert "static safety not finite" in joint["result"]
    notes = []
    report_strict = strict(report, notes=notes)
    assert notes and report_strict["sections"][0]["damage"] is None


def test_without_a_vehicle_the_check_says_why():
    spec = optimize.parse_spec(LISTS)
    with pytest.raises(ValueError, match=r"needs the spec's \[vehicle\]"):
        optimize.halfshaft_report(spec)
    tables = document.tables({})
    for name in ("halfshaft", "outboard_life", "shaft_damage"):
        assert "no halfshaft section" in tables[name].unavailable


def test_tables_hold_the_reports_numbers(reports):
    report = reports["consistent"]
    tables = document.tables({"halfshaft": report})
    rows = tables["halfshaft"].rows
    assert len(rows) == 2 * len(report["sections"]) + 2
    for s in report["sections"]:
        mine = [r for r in rows if r[0] == s["name"]]
        assert [r[3] for r in mine] == [s["static_safety"], s["damage"]]
    life_rows = tables["outboard_life"].rows
    assert [r[3] for r in life_rows] == [c["life_km"] for c in report["outboard"]["conditions"]]
    damage = tables["shaft_damage"].rows
    assert len(damage) == 7 * len(report["sections"])
    assert math.fsum(r[2] for r in damage if r[0] == "A-A") == pytest.approx(
        report["sections"][0]["damage"], rel=1e-12
    )


@pytest.mark.parametrize(
    "text, message",
    [
        (
            "[outboard]\nn_balls = 2",
            "outboard.n_balls = 2 is not allowed: an integer from 3 to 24",
        ),
        (
            "[outboard]\nn_balls = 11",  # 2 R sin(π/11) = 16.880 mm < d: neighbours overlap
            "outboard.ball_diameter_mm = 18.256 mm is not allowed for 11 balls on outboard.pcr_mm "
            "= 29.958 mm: outboard.ball_diameter_mm < 2·outboard.pcr_mm·sin(π/outboard.n_balls) "
            "= 16.8803 mm (neighbouring balls would overlap)",
        ),
        (
            "[outboard]\npressure_angle_deg = 90.0",
            "outboard.pressure_angle_deg = 90.0 is not allowed: a finite number > 0° and < 90°",
        ),
        (
            "[shaft]\ndepth_drop = 1.0",
            "shaft.depth_drop = 1.0 is not allowed: a finite number ≥ 0 and < 1",
        ),
        (
            "[shaft]\ndepth_drop = -0.1",
            "shaft.depth_drop = -0.1 is not allowed: a finite number ≥ 0 and < 1",
        ),
    ],
)
def test_the_specs_ranges_are_the_librarys(text, message):
    """A key's allowed range in the spec's message is the library's, open ends included."""
    with pytest.raises(optimize.SpecError) as info:
        optimize.parse_spec(text)
    assert str(info.value) == message


def test_a_reverse_that_lifts_the_wheel_is_checked_forward_alone():
    """A reverse load transfer above the rear wheel's static load (4000 N against 3087 N) leaves
    no backward torque: the reverse rows do no damage and there is no backward static check
    (both were NaN at every section: "nonfinite", and the command exited 1)."""
    lifted = optimize.halfshaft_report(
        optimize.parse_spec("[vehicle]\nreverse_load_transfer_N = 4000.0\n")
    )
    default = optimize.halfshaft_report(SPEC)
    assert lifted["static_torque_Nm"]["backward"] == 0.0
    for mine, theirs in zip(lifted["sections"], default["sections"], strict=True):
        assert mine["status"] == "successful"
        assert 0.0 < mine["damage"] < theirs["damage"]  # the default's reverse rows do damage
        reverse = [g["damage"] for g in mine["damage_by_gear"] if g["gear"] == "R"]
        assert reverse == [0.0]
        # the forward torque is the same, and it gives the default's smaller safety here
        assert mine["static_safety"] >= theirs["static_safety"]


@pytest.mark.parametrize(
    "args, words",
    [
        (("static safety", 0.99978, "≥", 1.0), (False, "static safety 0.9998 < 1")),
        (("static safety", 1.549, "≥", 1.1), (True, "static safety 1.55 ≥ 1.1")),
        (("life", 99999.6, "≥", 1e5, " km"), (False, "life 99999.6 km < 100000.0 km")),
        (("life", 65811.3, "≥", 1e5, " km"), (False, "life 65811 km < 100000 km")),
        (("damage", 1.0, "≤", 1.0), (True, "damage 1 ≤ 1")),  # the limit itself is met
        (("damage", 1.0000001, "≤", 1.0), (False, "damage 1.0000001 > 1")),
    ],
)
def test_a_verdicts_words_never_round_the_value_onto_its_limit(args, words):
    """The console line and report.json's words of a check: "1 < 1" was printed for a safety
    of 0.99978; the numbers get the digits that tell them apart."""
    from tripodjax.optimize import structural

    assert structural._requirement(*args) == words


def test_the_joints_static_checks_take_the_larger_direction():
    """A front-driven car whose reverse carries more than any forward gear (1491 against
    1214 N·m): the tripod's and the outboard joint's M_s ≥ k_s · M_max take the backward torque
    (they took the forward one while the document said both); the default rear-driven
    vehicle's forward torque stays the larger."""
    from tripodjax.optimize import problem

    front = optimize.parse_spec(
        '[vehicle]\naxle = "front"\nmass_kg = 1450.0\nfront_share = 0.60\n'
        "rear_torque_share = 0.0\nengine_torque_Nm = [300.0, 320.0, 290.0, 40.0]\n"
        "engine_speed_rpm = [2500.0, 3500.0, 6000.0, 3000.0]\n"
    )
    for spec in (front, optimize.load_spec()):
        structure, values = spec.structure, spec.values
        cycles = problem.load_cycles(structure, values)
        forward, backward = float(cycles.M_max_forward), float(cycles.M_max_backward)
        assert float(problem.joint_torque(structure, values)) == max(forward, backward)
        k_s = float(values["loads"]["shock_factor"])
        limit = problem.limits(structure, values)["static_capacity"][1]
        assert limit == pytest.approx(k_s * max(forward, backward), rel=1e-12)
    assert backward < forward  # the default: forward governs, results unchanged
    report = optimize.halfshaft_report(front)
    outboard = report["outboard"]
    torque = report["static_torque_Nm"]
    assert torque["backward"] > torque["forward"]
    assert outboard["static_safety"] == pytest.approx(
        outboard["M_s_Nm"] / torque["backward"], rel=1e-12
    )
