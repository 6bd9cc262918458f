"""The shaft's sections against the workbook's fatigue sheet (seed fig. 4.3.7) and by hand.

Expected numbers are the sheet's printed ones (the outboard joint's stem, "OCVJ stem":
Øe 30.685 mm, h 2.5 mm, t 3.5 mm, core 690 MPa, surface 2180 MPa, −10 % at h, q 1.6),
computed from the vehicle inputs alone (tests/test_vehicle.py's workbook vehicle and the
sheet's modes of fig. 4.3.4, whose sport column also runs reverse at T_ave).
"""

import dataclasses
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from test_vehicle import workbook_modes, workbook_vehicle

from tripodjax import shaft, vehicle
from tripodjax.results import RESULTS

STEM = dict(outer_diameter=30.685, hardened_depth=2.5, transition_depth=3.5)
MATERIAL = dict(core_uts=690.0, surface_uts=2180.0, depth_drop=0.10, fatigue_ratio=1.6, safety=1.2)

# Fig. 4.3.7 per gear (1st–6th, reverse), intercity/city rows: load torque [N·m], at the outer
# radius τ, σ of the load, σ_m, σ_a, σ_lim, N [10⁶]; at r_TR τ, σ, σ_m, σ_a, σ_lim, N [10⁶].
SHEET_LOAD = [1154, 1103, 1051, 1026, 1009, 998, 750]
SHEET_OUTER = [
    (203, 352, 76, 276, 1162.67, 411),
    (195, 337, 229, 108, 585.71, 8),
    (185, 321, 201, 119, 663.43, 12),
    (181, 313, 189, 125, 700.62, 15),
    (178, 308, 180, 129, 727.62, 17),
    (176, 305, 174, 131, 745.39, 19),
    (132, 229, 218, 11, 99.61, 1),
]
SHEET_INNER = [
    (124, 215, 46, 168, 404.80, 101),
    (118, 205, 139, 66, 203.92, 6),
    (113, 195, 123, 73, 230.98, 8),
    (110, 191, 115, 76, 243.93, 10),
    (108, 188, 109, 78, 253.33, 11),
    (107, 186, 106, 80, 259.52, 12),
    (80, 139, 133, 7, 34.68, 1),
]
# Engine-brake rows: torque (signed as printed) and σ at both radii.
SHEET_BRAKE = [
    (-656, -200, -122),
    (397, 121, 74),
    (268, 82, 50),
    (209, 64, 39),
    (167, 51, 31),
    (139, 43, 26),
    (679, 207, 126),
]
# Legible cycle counts [thousands] as (mode, gear, condition, count): modes sport 0,
# intercity 1, city 2; conditions T_ave 0, T_max 1, P_max 2, brake 3 (the OCR's row labels
# are often shifted; a row is placed by its torque, its event rate and its count). Left out,
# with the reason: the 1st and 2nd gears' P_max rows (0.14 and 1.23 % are rounded: 1.8 % and
# 0.4 % off) and 5th gear city brake (reads 20.375 for 20.7). The sport rows of the brake and
# reverse's sport T_ave row ("*,337": its first digit is illegible; fig. 4.3.4 prints 0.40 %,
# 103 thousand revolutions) need the sheet's sport column (tests/test_vehicle.py).
SHEET_COUNTS = [
    (0, 0, 3, 164.176),
    (0, 1, 3, 18.132),
    (0, 2, 3, 37.758),
    (0, 4, 3, 25.375),
    (0, 5, 3, 15.979),
    (0, 6, 3, 3.329),
    (0, 6, 0, 4.337),
    (1, 0, 1, 3.465),
    (2, 0, 1, 13.858),
    (1, 0, 3, 33.513),
    (2, 0, 3, 134.050),
    (0, 1, 1, 39.548),
    (1, 1, 1, 7.910),
    (2, 1, 3, 14.805),
    (0, 2, 1, 74.178),
    (1, 2, 1, 14.836),
    (2, 2, 1, 59.343),
    (0, 2, 2, 15.775),
    (2, 2, 2, 12.620),
    (1, 2, 3, 7.707),
    (2, 2, 3, 30.830),
    (0, 3, 1, 64.361),
    (1, 3, 1, 12.872),
    (0, 3, 2, 16.983),
    (1, 3, 2, 3.397),
    (2, 3, 2, 13.587),
    (1, 3, 3, 7.646),
    (2, 3, 3, 30.585),
    (0, 4, 1, 40.140),
    (1, 4, 1, 8.028),
    (2, 4, 1, 32.112),
    (1, 4, 2, 2.102),
    (2, 4, 2, 8.407),
    (1, 5, 1, 4.587),
    (2, 5, 1, 18.349),
    (0, 5, 2, 6.042),
    (2, 5, 2, 4.834),
    (1, 5, 3, 3.262),
    (2, 5, 3, 13.047),
    (0, 6, 1, 4.337),
    (1, 6, 1, 0.867),
    (0, 6, 2, 0.419),
    (1, 6, 2, 0.084),
    (2, 6, 2, 0.335),
    (2, 6, 3, 1.439),
]
SHEET_DAMAGE = (0.0835, 0.122)


@pytest.fixture(scope="module")
def chain():
    modes = workbook_modes(sheet=True)
    cycles = vehicle.load_cycles(workbook_vehicle(), modes, 100_000.0)
    return cycles, modes


@pytest.fixture(scope="module")
def sheet(chain):
    rows = shaft.fatigue_cycles(*chain, reading="workbook")
    check = shaft.fatigue_check(
        shaft.Section(**STEM), shaft.Material(**MATERIAL), rows, reading="workbook"
    )
    return rows, check


def test_geometry_and_strengths_of_the_stem():
    section = shaft.Section(**STEM)
    assert float(shaft.polar_moment(section)) == pytest.approx(87_037.0, rel=1e-4)
    material = shaft.Material(**MATERIAL)
    radius = np.array([15.3425, 12.8425, 9.3425])
    np.testing.assert_allclose(
        shaft.strength_profile(section, material, radius), [2180, 1962, 690], rtol=1e-3
    )
    # Linear in between: the middle of the transition.
    mid = float(shaft.strength_profile(section, material, 15.3425 - 2.5 - 1.75))
    assert mid == pytest.approx((1962 + 690) / 2, rel=1e-9)
    # Sheet 5's static limits: 2180/1.2 = 1817 normal, 1049 shear; the core's 575 and 332.
    static = shaft.static_check(section, material, 1154.0)
    np.testing.assert_allclose(np.asarray(static.allowed_shear)[[0, 2]], [1049, 332], atol=0.6)


def test_fig_4_3_7_stresses_goodman_and_cycles_to_failure(sheet):
    rows, check = sheet
    assert np.asarray(check.radius) == pytest.approx([15.343, 9.343], abs=1e-3)
    np.testing.assert_allclose(check.uts, [2180, 759], rtol=1e-9)
    np.testing.assert_allclose(check.fatigue_limit, [1363, 474], atol=0.7)
    city = 2  # the sport rows of 2nd gear take 1154 N·m in the sheet (see the module docstring)
    for g in range(7):
        assert float(rows.load[city, g, 1]) == pytest.approx(SHEET_LOAD[g], abs=1.0), g
        torque, s_outer, s_inner = SHEET_BRAKE[g]
        assert float(rows.brake[city, g, 3]) == pytest.approx(torque, abs=1.0), g
        for k, printed in enumerate((SHEET_OUTER[g], SHEET_INNER[g])):
            tau, sigma, mean, amp, allowed, n_fail = printed
            assert float(check.shear[k, city, g, 1]) == pytest.approx(tau, abs=0.6), (g, k)
            assert float(check.stress[k, city, g, 1]) == pytest.approx(sigma, abs=0.6), (g, k)
            assert float(check.stress[k, city, g, 3]) == pytest.approx(
                (s_outer, s_inner)[k], abs=0.6
            )
            assert float(check.mean[k, city, g, 1]) == pytest.approx(mean, abs=0.6), (g, k)
            assert float(check.amplitude[k, city, g, 1]) == pytest.approx(amp, abs=0.6), (g, k)
            # Every row of the gear shares the cycle (the brake rows too).
            assert float(check.amplitude[k, city, g, 3]) == pytest.approx(amp, abs=0.6)
            # σ_lim within 0.05 % (reverse 0.35 %: a small amplitude from 750 − 679 N·m).
            rel = 3.5e-3 if g == 6 else 5e-4
            assert float(check.allowed_amplitude[k, city, g, 1]) == pytest.approx(allowed, rel=rel)
            assert float(check.cycles_to_failure[k, city, g, 1]) / 1e6 == pytest.approx(
                n_fail,
                rel=6e-3,
                abs=0.5,  # rounded to 10⁶; 409.9 for 411, 100.5 for 101
            ), (g, k)
    assert round(float(check.ratio[0, city, 0, 1])) == 4  # the sheet's "Ratio" column
    assert round(float(check.ratio[0, city, 1, 1])) == 0


def test_fig_4_3_7_cycle_counts(sheet):
    rows, _ = sheet
    for mode, gear, condition, printed in SHEET_COUNTS:
        count = float(rows.count[mode, gear, condition]) / 1e3
        assert count == pytest.approx(printed, rel=5e-3), (mode, gear, condition)
    # The event rate column: p at 3000 rpm in 1st gear (4.15 %) and at 5500 rpm (3.17 %).
    assert float(rows.event_rate[0, 0, 1]) == pytest.approx(0.0415, rel=2e-3)
    assert float(rows.event_rate[0, 0, 2]) == pytest.approx(0.0317, rel=2e-3)
    # The sheet's 1st-gear brake rows count revolutions without p(ω); the consistent reading does not.
    assert float(rows.event_rate[2, 0, 3]) == 1.0
    assert float(rows.event_rate[2, 1, 3]) == pytest.approx(0.0336, rel=2e-3)


def test_fig_4_3_7_damage_sums(sheet):
    """Miner's sums 0.0826 and 0.1202 against the printed 0.0835 and 0.122: −1.1 % and −1.5 %.

    The remaining gap is not in the legible rows (every count within 0.5 %, every N within its
    printing). Not closed by: the sheet's 1154 N·m in the 2nd gear's sport rows (−1.5 %,
    −1.5 %: a larger mean raises σ_lim more than σ_a), every N rounded to its printed 10⁶
    (+4.2 %, −0.4 %), reverse's N = 10⁶ as printed (+4.7 %, +2.2 %; the line gives 1.35 and
    1.31·10⁶).
    """
    _, check = sheet
    damage = np.asarray(check.damage)
    np.testing.assert_allclose(damage, SHEET_DAMAGE, rtol=0.02)
    np.testing.assert_allclose(damage / SHEET_DAMAGE - 1, [-0.011, -0.015], atol=0.001)
    assert bool(check.passed)
    by_hand = np.sum(np.asarray(check.damage_per_row), axis=(1, 2, 3))
    np.testing.assert_allclose(damage, by_hand, rtol=1e-12)


def test_without_the_sport_reverse_rows_the_sums_fall_short(sheet):
    """With one gear-use table for all modes (no sport T_ave in reverse): −6.1 % and −4.8 %.

    The sport column's 0.40 % in reverse at T_ave adds 4.337 thousand cycles of 750 ↔ 679 N·m
    and raises the sport brake rows' share of reverse (3.329 thousand, was 1.797); its larger
    total (73.46 %) lowers every other sport brake row 2.1 %, as the sheet prints them.
    """
    _, check = sheet
    modes = workbook_modes()
    cycles = vehicle.load_cycles(workbook_vehicle(), modes, 100_000.0)
    rows = shaft.fatigue_cycles(cycles, modes, reading="workbook")
    one_table = shaft.fatigue_check(
        shaft.Section(**STEM), shaft.Material(**MATERIAL), rows, reading="workbook"
    )
    np.testing.assert_allclose(
        np.asarray(one_table.damage) / SHEET_DAMAGE - 1, [-0.061, -0.048], atol=0.001
    )
    assert float(rows.count[0, 6, 3]) / 1e3 == pytest.approx(1.797, rel=2e-3)
    assert float(rows.count[0, 2, 3]) / 1e3 == pytest.approx(37.758 * 1.0198, rel=2e-3)
    # The reverse rows alone make the difference at both radii.
    extra = np.asarray(check.damage) - np.asarray(one_table.damage)
    reverse = np.sum(
        np.asarray(check.damage_per_row)[:, :, 6] - np.asarray(one_table.damage_per_row)[:, :, 6],
        axis=(1, 2),
    )
    assert np.all(reverse > extra) and np.all(extra > 0)


def test_consistent_reading_differs_only_where_stated(chain, sheet):
    rows_wb, check_wb = sheet
    rows = shaft.fatigue_cycles(*chain)
    check = shaft.fatigue_check(shaft.Section(**STEM), shaft.Material(**MATERIAL), rows)
    first_brake = np.zeros(rows.count.shape, bool)
    first_brake[:, 0, 3] = True
    np.testing.assert_allclose(
        np.asarray(rows.count)[~first_brake], np.asarray(rows_wb.count)[~first_brake], rtol=1e-12
    )
    ratio = np.asarray(rows_wb.count)[first_brake] / np.asarray(rows.count)[first_brake]
    np.testing.assert_allclose(ratio, 1 / np.asarray(rows.event_rate)[first_brake], rtol=1e-12)
    np.testing.assert_allclose(check.uts, [2180, 690], rtol=1e-12)
    assert float(check.damage[0]) < float(check_wb.damage[0])  # fewer 1st-gear brake cycles
    assert float(check.damage[1]) > float(check_wb.damage[1])  # the core's strength at r_TR


def test_static_check_by_hand_and_the_inboard_stem():
    material = shaft.Material(**MATERIAL)
    static = shaft.static_check(shaft.Section(**STEM), material, np.array([1154.0, 750.0]))
    J = math.pi * 30.685**4 / 32
    radius = np.array([15.3425, 12.8425, 9.3425])
    allowed = np.array([2180, 1962, 690]) / (1.2 * math.sqrt(3))
    expected = allowed / (1154e3 * radius / J)
    np.testing.assert_allclose(static.safety[0], expected, rtol=1e-9)
    np.testing.assert_allclose(static.safety[1], expected * 1154 / 750, rtol=1e-9)
    assert static.safety.shape == (2, 3) and bool(np.all(static.passed))
    # The inboard stem as read (20.44 mm, h 1.2, t 1.1) fails; 28.44 mm passes.
    inboard = dict(hardened_depth=1.2, transition_depth=1.1)
    small = shaft.static_check(shaft.Section(20.44, **inboard), material, 1154.0)
    large = shaft.static_check(shaft.Section(28.44, **inboard), material, 1154.0)
    assert not bool(small.passed) and bool(large.passed)


def test_hollow_section():
    section = shaft.Section(40.0, 2.0, 1.0, inner_diameter=20.0)
    assert float(shaft.polar_moment(section)) == pytest.approx(
        math.pi * (40**4 - 20**4) / 32, rel=1e-12
    )
    static = shaft.static_check(section, shaft.Material(**MATERIAL), 2000.0)
    assert np.asarray(static.radius) == pytest.approx([20, 18, 17])


@jax.jit
def _damage_and_safety(outer, depth, chain_rows):
    section = shaft.Section(outer, depth, 3.5)
    material = shaft.Material(**MATERIAL)
    check = shaft.fatigue_check(section, material, chain_rows, reading="workbook")
    static = shaft.static_check(section, material, 1154.0)
    return jnp.concatenate([check.damage, static.safety])


def test_derivatives_agree_with_finite_differences(sheet):
    rows, _ = sheet
    x = (30.685, 2.5)
    jac = jax.jacfwd(_damage_and_safety, argnums=(0, 1))(*x, rows)
    for i, h in enumerate((1e-5, 1e-6)):
        plus, minus = list(x), list(x)
        plus[i] += h
        minus[i] -= h
        fd = (
            np.asarray(_damage_and_safety(*plus, rows))
            - np.asarray(_damage_and_safety(*minus, rows))
        ) / (2 * h)
        np.testing.assert_allclose(np.asarray(jac[i]), fd, rtol=1e-5, atol=1e-10)


def test_float32_and_vmap_over_sections(chain):
    cycles, modes = chain
    rows = shaft.fatigue_cycles(
        *jax.tree.map(lambda a: jnp.asarray(a, jnp.float32), (cycles, modes))
    )
    f32 = jnp.float32
    sections = shaft.Section(
        jnp.array([30.685, 26.0, 27.5], f32), jnp.array([2.5, 5.6, 5.6], f32), jnp.array(3.5, f32)
    )
    material = jax.tree.map(lambda a: jnp.asarray(a, f32), shaft.Material(**MATERIAL))

    def one(s):
        return shaft.fatigue_check(s, material, rows).damage

    damage = jax.jit(jax.vmap(one))(jax.tree.map(lambda a: jnp.broadcast_to(a, (3,)), sections))
    assert damage.dtype == jnp.float32 and damage.shape == (3, 2)
    rows64 = shaft.fatigue_cycles(cycles, modes)
    expected = shaft.fatigue_check(shaft.Section(**STEM), shaft.Material(**MATERIAL), rows64)
    np.testing.assert_allclose(damage[0], expected.damage, rtol=1e-4)
    assert bool(jnp.all(jnp.isfinite(damage)))
    safety = jax.jit(jax.vmap(lambda s: shaft.static_check(s, material, f32(1154.0)).safety))(
        jax.tree.map(lambda a: jnp.broadcast_to(a, (3,)), sections)
    )
    assert safety.dtype == jnp.float32 and safety.shape == (3, 3)
    np.testing.assert_allclose(
        safety[0],
        shaft.static_check(shaft.Section(**STEM), shaft.Material(**MATERIAL), 1154.0).safety,
        rtol=1e-5,
    )


@pytest.mark.parametrize(
    "build, message",
    [
        (
            lambda: shaft.Section(20.0, 1.0, 1.0, inner_diameter=20.0),
            "Section.inner_diameter = 20.0 is outside the allowed range: "
            "0 ≤ inner_diameter < outer_diameter (= 20.0 mm)",
        ),
        (
            lambda: shaft.Section(20.0, 6.0, 5.0),
            "Section.hardened_depth + transition_depth = 11.0 is outside the allowed range: "
            "h + t ≤ the wall (Øe − Øi)/2 (= 10.0 mm)",
        ),
        (
            lambda: shaft.Section(20.0, -1.0, 1.0),
            "Section.hardened_depth = -1.0 is outside the allowed range: hardened_depth ≥ 0 mm",
        ),
        (
            lambda: shaft.Material(**{**MATERIAL, "core_uts": 0.0}),
            "Material.core_uts = 0.0 is outside the allowed range: core_uts > 0",
        ),
        (
            lambda: shaft.Material(**{**MATERIAL, "fatigue_ratio": 1.0}),
            "Material.fatigue_ratio = 1.0 is outside the allowed range: 1 < fatigue_ratio",
        ),
        (
            lambda: shaft.Material(**{**MATERIAL, "surface_uts": 700.0}),
            "Material.surface_uts = 700.0 is outside the allowed range: "
            "surface_uts (1 − depth_drop) ≥ core_uts (= 690.0 MPa)",
        ),
        (
            lambda: shaft.Material(**{**MATERIAL, "safety": 0.9}),
            "Material.safety = 0.9 is outside the allowed range: 1 ≤ safety",
        ),
        (
            lambda: shaft.EventRate(speed_low=300.0),
            "EventRate.speed_high = 250.0 is outside the allowed range: speed_high > speed_low",
        ),
        (
            lambda: shaft.Section(np.array([20.0, 30.0]), np.array([6.0, 1.0]), 5.0),
            "Section.hardened_depth + transition_depth[0] = 11.0 is outside the allowed range: "
            "h + t ≤ the wall (Øe − Øi)/2 (= 10.0 mm)",
        ),
        (
            lambda: shaft.strength_profile(
                shaft.Section(**STEM), shaft.Material(**MATERIAL), np.array([15.0, 16.0])
            ),
            "radius[1] = 16.0 is outside the allowed range: Øi/2 ≤ radius ≤ Øe/2 (= 0.0–15.3425 mm)",
        ),
        (
            lambda: shaft.static_check(shaft.Section(**STEM), shaft.Material(**MATERIAL), -5.0),
            "torque = -5.0 is outside the allowed range: torque > 0",
        ),
    ],
)
def test_bad_input_names_key_value_and_range(build, message):
    with pytest.raises(ValueError) as info:
        build()
    assert message in str(info.value)
    assert "\n" not in str(info.value)


def test_reading_and_types_are_checked(chain):
    with pytest.raises(ValueError, match="reading = 'sheet' is not allowed"):
        shaft.fatigue_cycles(*chain, reading="sheet")
    with pytest.raises(TypeError, match="allowed: a shaft.Section"):
        shaft.static_check({"outer_diameter": 30.0}, shaft.Material(**MATERIAL), 100.0)


def test_traced_bad_input_gives_nan(sheet):
    rows, _ = sheet

    @jax.jit
    def damage(inner):
        section = shaft.Section(30.0, 2.5, 3.5, inner_diameter=inner)
        return shaft.fatigue_check(section, shaft.Material(**MATERIAL), rows)

    good, bad = damage(5.0), damage(40.0)
    assert bool(jnp.all(jnp.isfinite(good.damage))) and int(good.result) == 0
    assert bool(jnp.all(jnp.isnan(bad.damage))) and not bool(bad.passed)
    assert int(bad.result) == int(RESULTS.nonfinite)


def test_workbook_sections_are_sheet_5s_and_every_rear_verdict_is_positive(chain):
    """Sheet 5's rear sections (shared/docs/workbook.md, fig. 4.3.5); sheet 7: all "Positive"."""
    # name: (Øe, h, t, q, safety coefficient) as workbook.md states them.
    stated = {
        "A-A": (26.0, 5.6, 3.5, 1.6, 1.2),
        "B-B": (27.5, 5.6, 3.5, 1.6, 1.2),
        "C-C": (25.8, 5.6, 3.5, 1.6, 1.2),
        "outboard stem": (30.685, 2.5, 3.5, 1.6, 1.3),
        "inboard stem": (28.44, 1.2, 1.1, 1.6, 1.2),  # printed 20.44, read as a typing error
    }
    assert set(shaft.WORKBOOK_SECTIONS) == set(stated)
    cycles, modes = chain
    rows = shaft.fatigue_cycles(cycles, modes)
    torque = np.array([float(cycles.M_max_forward), float(cycles.M_max_backward)])
    for name, (section, material) in shaft.WORKBOOK_SECTIONS.items():
        outer, h, t, q, safety = stated[name]
        got = (section.outer_diameter, section.hardened_depth, section.transition_depth)
        assert got == (outer, h, t) and section.inner_diameter == 0.0, name
        assert (material.fatigue_ratio, material.safety) == (q, safety), name
        assert (material.core_uts, material.surface_uts, material.depth_drop) == (690, 2180, 0.1)
        assert bool(np.all(shaft.static_check(section, material, torque).passed)), name
        assert bool(shaft.fatigue_check(section, material, rows).passed), name
    stem = shaft.WORKBOOK_SECTIONS["outboard stem"][0]
    assert float(shaft.polar_moment(stem)) == pytest.approx(87_037.0, rel=1e-4)
    # 2180/1.2 = 1817 normal and 1049 shear at the surface (sheet 5's static limits).
    section, material = shaft.WORKBOOK_SECTIONS["A-A"]
    allowed = shaft.static_check(section, material, 1154.0).allowed_shear
    assert float(allowed[0]) == pytest.approx(1049.0, abs=0.6)


def test_a_float32_section_hardened_through_its_wall_is_accepted():
    """h + t on the wall (Øe − Øi)/2 in float32: the rounding of the sum is no violation."""
    f32 = np.float32
    for outer, depth, inner in [(16.1, 0.5, 0.0), (25.8, 5.6, 0.0), (30.685, 2.5, 12.3)]:
        wall = (f32(outer) - f32(inner)) / f32(2)
        section = shaft.Section(f32(outer), f32(depth), wall - f32(depth), f32(inner))
        static = shaft.static_check(section, shaft.Material(**MATERIAL), f32(1154.0))
        assert int(static.result) == int(RESULTS.successful)
    with pytest.raises(ValueError, match=r"hardened_depth \+ transition_depth"):
        shaft.Section(f32(16.1), f32(0.5), f32(7.6))  # 0.05 mm beyond


@pytest.mark.parametrize(
    "build, message",
    [
        (
            lambda: shaft.Section(np.array([26.0, 27.5]), np.array([5.6, 5.6, 2.5]), 3.5),
            "Section fields have shapes outer_diameter (2,), hardened_depth (3,), "
            "transition_depth (), inner_diameter (); allowed: numbers, or arrays whose shapes "
            "broadcast together",
        ),
        (
            lambda: shaft.Material(**{**MATERIAL, "safety": np.array([])}),
            "Material.safety is empty (shape (0,)); allowed: a number or a non-empty array",
        ),
        (
            lambda: shaft.static_check(
                shaft.Section(np.array([26.0, 27.5, 25.8]), 5.6, 3.5),
                shaft.Material(**MATERIAL),
                np.array([1154.0, 750.0]),
            ),
            "the fields have shapes section (3,), material (), torque (2,); allowed: shapes "
            "that broadcast together",
        ),
        (
            lambda: shaft.strength_profile(
                shaft.Section(np.array([26.0, 27.5, 25.8]), 5.6, 3.5),
                shaft.Material(**MATERIAL),
                np.array([12.0, 11.0]),
            ),
            "the fields have shapes section (3,), material (), radius (2,)",
        ),
    ],
)
def test_shapes_that_do_not_broadcast_are_named(build, message):
    with pytest.raises(ValueError) as info:
        build()
    assert message in str(info.value) and "\n" not in str(info.value)
    # the same torques against each section: torque[:, None]
    sections = shaft.Section(np.array([26.0, 27.5, 25.8]), 5.6, 3.5)
    static = shaft.static_check(sections, shaft.Material(**MATERIAL), np.array([[1154.0], [750.0]]))
    assert static.safety.shape == (2, 3, 3)


def test_stresses_and_limits_against_an_independent_computation():
    """τ = 16 T/(π Øe³) solid, 16 T Øe/(π (Øe⁴ − Øi⁴)) hollow at the surface; Øi → 0 is the
    solid section; doubling the torque halves the static safety and raises the damage; a
    deeper hardened layer never lowers the section's static safety nor the surface strength."""
    material = shaft.Material(**MATERIAL)
    T = 1154.0
    solid = shaft.static_check(shaft.Section(26.0, 5.6, 3.5), material, T)
    assert float(solid.shear[0]) == pytest.approx(16 * T * 1e3 / (math.pi * 26.0**3), rel=1e-12)
    hollow = shaft.static_check(shaft.Section(26.0, 2.0, 1.0, 14.0), material, T)
    assert float(hollow.shear[0]) == pytest.approx(
        16 * T * 1e3 * 26.0 / (math.pi * (26.0**4 - 14.0**4)), rel=1e-12
    )
    for inner in (1e-2, 1e-4):
        near = shaft.static_check(shaft.Section(26.0, 5.6, 3.5, inner), material, T)
        np.testing.assert_allclose(near.safety, solid.safety, rtol=inner**4 / 26.0**4 * 10)
    double = shaft.static_check(shaft.Section(26.0, 5.6, 3.5), material, 2 * T)
    np.testing.assert_allclose(double.safety, solid.safety / 2, rtol=1e-12)
    safeties = [
        float(jnp.min(shaft.static_check(shaft.Section(26.0, h, 3.5), material, T).safety))
        for h in np.linspace(0.0, 9.5, 20)
    ]
    assert np.all(np.diff(safeties) >= -1e-12)
    surface = [
        float(shaft.strength_profile(shaft.Section(26.0, h, 3.5), material, 13.0))
        for h in np.linspace(0.1, 9.5, 20)
    ]
    assert surface == pytest.approx([2180.0] * 20)


def test_a_solid_section_hardened_to_its_centre(sheet):
    """h + t = Øe/2 (r_TR = 0, no stress there): the static safety there is +∞ and the
    section's the least of the others, the damage there the limit of r_TR → 0, every result
    successful and every derivative finite (they were ∞, NaN and nonfinite)."""
    rows, _ = sheet
    material = shaft.Material(**MATERIAL)

    def checks(outer, depth, transition):
        section = shaft.Section(outer, depth, transition)
        static = shaft.static_check(section, material, 1154.0)
        fatigue = shaft.fatigue_check(section, material, rows)
        return jnp.min(static.safety), fatigue.damage[1], static.result, fatigue.result

    through = checks(26.0, 5.6, 7.4)
    near = checks(26.0, 5.6, 7.4 - 1e-7)
    assert int(through[2]) == int(through[3]) == int(RESULTS.successful)
    assert float(through[0]) == pytest.approx(float(near[0]), rel=1e-12)
    assert float(through[1]) == pytest.approx(float(near[1]), rel=1e-6)
    ratio = shaft.fatigue_check(shaft.Section(26.0, 13.0, 0.0), material, rows).ratio
    assert bool(jnp.all(jnp.isfinite(ratio)))
    for i in range(2):
        grads = jax.grad(lambda *x, i=i: checks(*x)[i], argnums=(0, 1, 2))(26.0, 5.6, 7.4)
        h = 1e-6  # one-sided in t: the wall bounds it
        below = (float(checks(26.0, 5.6, 7.4)[i]) - float(checks(26.0, 5.6, 7.4 - h)[i])) / h
        assert all(np.isfinite(float(g)) for g in grads), i
        assert float(grads[2]) == pytest.approx(below, rel=1e-4, abs=1e-9), i


@pytest.mark.parametrize("h, t", [(2.5, 3.5), (0.0, 3.5), (2.5, 0.0), (0.0, 0.0)])
def test_the_outer_fibres_strength_is_the_profiles_below_a_step(chain, h, t):
    """σ_R at r_o in fatigue is strength_profile's at r_o (the value below a step where h or t
    is 0): an unhardened section (h = t = 0, r_o = r_TR) is the core's at both radii, with
    equal damage; it took the surface's 2180 MPa at r_o."""
    rows = shaft.fatigue_cycles(*chain)
    section = shaft.Section(30.685, h, t)
    material = shaft.Material(**MATERIAL)
    check = shaft.fatigue_check(section, material, rows)
    r_o = 30.685 / 2
    profile = float(shaft.strength_profile(section, material, r_o))
    assert float(check.uts[0]) == pytest.approx(profile, rel=1e-12)
    if h == t == 0.0:
        assert profile == MATERIAL["core_uts"]
        assert float(check.damage[0]) == pytest.approx(float(check.damage[1]), rel=1e-12)


def test_a_row_without_torque_does_no_damage(chain):
    """A gear whose wheel carries no torque (a reverse whose load transfer unloads the axle):
    load = brake = 0 is no stress cycle, 0 damage, where Goodman's σ_lim was 0/0 and made every
    radius's damage NaN."""
    rows = shaft.fatigue_cycles(*chain)
    idle = np.zeros(rows.load.shape, bool)
    idle[:, -1, :] = True  # the reverse rows
    unloaded = dataclasses.replace(
        rows,
        load=jnp.where(idle, 0.0, rows.load),
        brake=jnp.where(idle, 0.0, rows.brake),
        torque=jnp.where(idle, 0.0, rows.torque),
    )
    section, material = shaft.Section(**STEM), shaft.Material(**MATERIAL)
    check = shaft.fatigue_check(section, material, unloaded)
    full = shaft.fatigue_check(section, material, rows)
    assert int(check.result) == RESULTS.successful
    np.testing.assert_array_equal(np.asarray(check.damage_per_row)[:, idle], 0.0)
    forward = np.sum(np.where(idle, 0.0, np.asarray(full.damage_per_row)), axis=(1, 2, 3))
    np.testing.assert_allclose(check.damage, forward, rtol=1e-12)
    gradient = jax.grad(lambda s: shaft.fatigue_check(s, material, unloaded).damage[0])(section)
    assert np.isfinite(float(gradient.outer_diameter))


def test_a_torque_outside_its_domain_inside_jit_is_no_safety():
    section, material = shaft.Section(**STEM), shaft.Material(**MATERIAL)
    check = jax.jit(lambda T: shaft.static_check(section, material, T))
    for torque in (-1154.0, 0.0):
        out = check(torque)
        assert np.all(np.isnan(np.asarray(out.safety))) and not bool(out.passed)
        assert int(out.result) == RESULTS.nonfinite
    assert int(check(1154.0).result) == RESULTS.successful
