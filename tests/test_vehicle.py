"""Vehicle → load cycles against the workbook's printed numbers (seed figs. 4.3.1–4.3.4, 4.3.11)."""

import math

import jax
import numpy as np
import pytest

from tripodjax import life, vehicle

RATIOS = [13.128, 7.931, 5.367, 4.181, 3.336, 2.788]
T_MAX_USE = [1.62, 4.55, 11.00, 11.93, 9.60, 7.04, 0.40]  # % of revolutions, 1st–6th, reverse
P_MAX_USE = [0.14, 1.23, 4.50, 7.29, 7.20, 6.53, 0.05]
SPORT_REVERSE_T_AVE_USE = 0.40  # % of the sport revolutions, fig. 4.3.4's sport column only


def workbook_vehicle(**changes):
    fields = dict(
        mass=937.0,
        front_share=307.34 / 937.0,
        wheelbase=2.475,
        cg_height=0.42,
        tyre_radius=0.30773,
        adhesion=0.9,
        rear_torque_share=1.0,
        engine_torque=np.array([555.0, 555.0, 517.4, 50.0]),
        engine_speed=np.array([3000.0, 3000.0, 5500.0, 3000.0]),
        shock_factor=1.1,
        ratios=np.array(RATIOS),
        reverse_ratio=13.584,
        load_transfer_per_ratio=67.45,
        reverse_load_transfer=627.0,
    )
    return vehicle.Vehicle(**{**fields, **changes})


def workbook_modes(sheet=False):
    """Sport, intercity, city (50/10/40 %), with one gear-use table for all three (fig. 4.3.11).

    ``sheet=True``: the sheet's own modes as fig. 4.3.4 prints them, where the sport column
    also runs reverse at T_ave for 0.40 % of its revolutions ("C_ave 750 0,40% 0,20% 103":
    relative use, absolute use, thousands of revolutions), so that its reverse gear is used
    0.85 % (intercity and city 0.45 %) and its total 73.46 % (73.06 %). Fig. 4.3.7 counts
    those cycles (tests/test_shaft.py).
    """
    use = np.zeros((3, 7, 4))
    use[:, :, 1] = np.array(T_MAX_USE) / 100
    use[:, :, 2] = np.array(P_MAX_USE) / 100
    if sheet:
        use[0, -1, 0] = SPORT_REVERSE_T_AVE_USE / 100
    return vehicle.DrivingModes(weight=np.array([0.5, 0.1, 0.4]), use=use)


@pytest.fixture(scope="module")
def cycles():
    return vehicle.load_cycles(workbook_vehicle(), workbook_modes(), 100_000.0)


def test_the_chain_reproduces_the_printed_numbers(cycles):
    c = cycles
    assert float(c.total_revolutions) == pytest.approx(51_719_021, rel=5e-3)
    assert float(c.shaft_speed[0, 0, 1]) == pytest.approx(228.5, rel=5e-3)  # 1st at 3000 rpm
    assert float(c.vehicle_speed[0, 0, 1]) == pytest.approx(26.5, rel=5e-3)
    assert float(c.engine_torque[0, 0, 1]) == pytest.approx(8015.0, rel=5e-3)
    np.testing.assert_allclose(
        c.adhesion_limit[0, :5, 1], [1154, 1103, 1051, 1026, 1009], rtol=5e-3
    )
    np.testing.assert_allclose(c.wheel_load[:5], [3789, 3622, 3449, 3369, 3312], rtol=5e-3)
    assert float(c.wheel_load[-1]) == pytest.approx(2461.0, rel=5e-3)
    assert float(c.adhesion_limit[0, 5, 1]) == pytest.approx(998.0, rel=5e-3)  # 6th (ratio 2.788)
    assert float(c.share[0, 0, 1]) == pytest.approx(0.0081, rel=5e-3)  # sport 1st T_max: 0.81 %
    assert float(c.revolutions[0, 0, 1]) == pytest.approx(0.0081 * 51_719_021, rel=5e-3)
    assert float(c.M_max_forward) == pytest.approx(1154.0, rel=5e-3)
    assert float(c.M_max_backward) == pytest.approx(750.0, rel=5e-3)
    # Working torque: the adhesion limit wherever the engine can give more (every case here).
    np.testing.assert_allclose(c.working_torque[..., 1:3], c.adhesion_limit[..., 1:3], rtol=1e-12)


def test_the_sheets_sport_column_runs_reverse_at_the_mean_torque():
    """Fig. 4.3.4, sport column, reverse: "C_ave 750 0,40% 0,20% 103", gear use 0.85 %.

    The other columns print 0.00 % there and 0.45 % for the gear; the totals are 73.46 % for
    sport and 73.06 % for intercity and city (the tables as read sum to 73.48 % and 73.08 %).
    """
    modes = workbook_modes(sheet=True)
    c = vehicle.load_cycles(workbook_vehicle(), modes, 100_000.0)
    assert float(c.working_torque[0, -1, 0]) == pytest.approx(750.0, rel=5e-3)
    assert float(c.share[0, -1, 0]) == pytest.approx(0.0020, rel=1e-9)  # absolute use 0.20 %
    assert float(c.revolutions[0, -1, 0]) / 1e3 == pytest.approx(103.0, abs=0.5)
    use = np.asarray(modes.use)
    np.testing.assert_allclose(100 * use[:, -1, :3].sum(axis=-1), [0.85, 0.45, 0.45], rtol=1e-9)
    np.testing.assert_allclose(100 * use.sum(axis=(1, 2)), [73.46, 73.06, 73.06], atol=0.03)
    # Only that cell differs from the one-table modes.
    differs = use != np.asarray(workbook_modes().use)
    assert differs.sum() == 1 and differs[0, -1, 0]


def test_relations_by_hand(cycles):
    """Independent of the module: each printed relation written out."""
    g = vehicle.GRAVITY
    rear_static = 629.66 * g / 2
    transfer = [min(67.45 * i, 0.9 * 937 * g * 0.42 / (2 * 2.475)) for i in RATIOS]
    wheel = np.array([rear_static + t for t in transfer] + [rear_static - 627.0])
    np.testing.assert_allclose(cycles.wheel_load, wheel, rtol=1e-9)
    np.testing.assert_allclose(
        cycles.adhesion_limit[0, :, 0], 0.9 * wheel * 0.30773 * 1.1, rtol=1e-9
    )
    speed = 5500 / np.array(RATIOS + [13.584])
    np.testing.assert_allclose(cycles.shaft_speed[2, :, 2], speed, rtol=1e-12)
    np.testing.assert_allclose(
        cycles.vehicle_speed[1, :, 2], speed * 2 * math.pi * 0.30773 * 0.06, rtol=1e-12
    )
    brake = 50 * 1.1 * np.array(RATIOS + [13.584])  # locked differential, below adhesion
    np.testing.assert_allclose(cycles.working_torque[0, :, 3], brake, rtol=1e-12)


def test_the_0_degree_life_against_the_sheet(cycles):
    """244 574 km at M_d = 1507 N·m (fig. 4.3.10): the revolutions reading gets within 2 %."""
    s = vehicle.load_spectrum(cycles)
    hours = float(life.life_hours(1507.0, s.torque, s.speed, s.share))
    km = hours * float(np.sum(s.share * s.vehicle_speed))
    assert km == pytest.approx(244_574.0, rel=0.02)
    assert km == pytest.approx(240_311.0, rel=1e-5)  # the figure tripodjax.vehicle's docs quote
    # Independently: revolutions of the whole mileage at each working torque without the shock.
    r = np.asarray(cycles.share).ravel()
    M = np.asarray(cycles.working_torque).ravel() / 1.1
    revolutions = 365000 * 60 / np.sum(r * (M / 1507.0) ** 3)
    assert km == pytest.approx(revolutions * 2 * math.pi * 0.30773 / 1000, rel=1e-9)
    # The sheet's 2148 h: revolution shares read as time shares in 4.2.1.
    n = np.asarray(cycles.shaft_speed).ravel()
    assert 365000 / np.sum(r * n * (M / 1507.0) ** 3) == pytest.approx(2148.0, rel=0.01)
    # The sheet's V_ave 113.9 km/h is the revolution-weighted mean of the case speeds.
    v = np.asarray(cycles.vehicle_speed).ravel()
    assert np.sum(r * v) / np.sum(r) == pytest.approx(113.9, rel=0.02)
    assert float(np.sum(s.share)) == pytest.approx(1.0, rel=1e-12)


def test_front_axle_and_all_wheel_drive():
    c = vehicle.load_cycles(
        workbook_vehicle(rear_torque_share=0.6, differential_locking=0.5),
        workbook_modes(),
        100_000.0,
        axle="front",
    )
    g = vehicle.GRAVITY
    front_static = 307.34 * g / 2
    assert float(c.wheel_load[1]) == pytest.approx(front_static - 67.45 * 7.931, rel=1e-9)
    assert float(c.wheel_load[-1]) == pytest.approx(front_static + 627.0, rel=1e-9)
    engine = 555 * 1.1 * 2.788 * 0.4 * (1 + 0.5) / 2
    assert float(c.working_torque[0, 5, 1]) == pytest.approx(
        min(engine, float(c.adhesion_limit[0, 5, 1]))
    )


def test_differentiable_and_vmappable_in_every_continuous_input():
    modes = workbook_modes()

    def m_max(radius, adhesion):
        return vehicle.load_cycles(
            workbook_vehicle(tyre_radius=radius, adhesion=adhesion), modes, 100_000.0
        ).M_max_forward

    g = jax.grad(m_max, argnums=(0, 1))(0.30773, 0.9)
    for i, x in enumerate((0.30773, 0.9)):
        args = [0.30773, 0.9]
        args[i] = x * (1 + 1e-6)
        plus = float(m_max(*args))
        args[i] = x * (1 - 1e-6)
        minus = float(m_max(*args))
        assert float(g[i]) == pytest.approx((plus - minus) / (2e-6 * x), rel=1e-5)
    radii = np.array([0.29, 0.30773, 0.32])
    batch = jax.vmap(lambda r: m_max(r, 0.9))(radii)
    np.testing.assert_allclose(batch, [float(m_max(r, 0.9)) for r in radii], rtol=1e-12)


@pytest.mark.parametrize(
    "build, message",
    [
        (lambda: workbook_vehicle(mass=-1.0), "Vehicle.mass = -1.0 is outside the allowed range"),
        (lambda: workbook_vehicle(front_share=1.2), "Vehicle.front_share = 1.2"),
        (
            lambda: workbook_vehicle(engine_torque=np.ones(3)),
            "Vehicle.engine_torque has shape (3,)",
        ),
        (lambda: workbook_vehicle(ratios=np.ones(12)), "Vehicle.ratios has shape (12,)"),
        (
            lambda: vehicle.DrivingModes(weight=np.array([0.5, 0.6]), use=np.zeros((2, 7, 4))),
            "DrivingModes.weight sums to 1.1",
        ),
        (
            lambda: vehicle.DrivingModes(weight=np.array([1.0]), use=np.full((1, 7, 4), 0.1)),
            "a sum over gears and conditions ≤ 1",
        ),
        (
            lambda: vehicle.DrivingModes(weight=np.array([1.0]), use=np.zeros((2, 7, 4))),
            "DrivingModes.use has 2 modes and weight 1",
        ),
        (
            lambda: vehicle.load_cycles(
                workbook_vehicle(),
                vehicle.DrivingModes(weight=np.array([1.0]), use=np.zeros((1, 5, 4))),
                1e5,
            ),
            "DrivingModes.use has 5 gears; the vehicle has 6 forward gears",
        ),
        (
            lambda: vehicle.load_cycles(workbook_vehicle(), workbook_modes(), 1e5, axle="left"),
            "axle = 'left' is not allowed",
        ),
    ],
)
def test_bad_inputs_name_the_field(build, message):
    with pytest.raises(ValueError) as info:
        build()
    assert message in str(info.value)


def test_a_traced_vehicle_outside_its_domain_gives_nan_load_cycles():
    """Before: a mass of −937 kg gave M_max_forward = 0.0 inside jit."""
    modes = workbook_modes()

    @jax.jit
    @jax.vmap
    def run(mass, required_km):
        cycles = vehicle.load_cycles(workbook_vehicle(mass=mass), modes, required_km)
        return cycles.M_max_forward, cycles.revolutions

    forward, revolutions = run(np.array([937.0, -937.0, 937.0]), np.array([1e5, 1e5, -1e5]))
    assert np.isfinite(forward[0]) and np.all(np.isfinite(revolutions[0]))
    assert np.all(np.isnan(forward[1:])) and np.all(np.isnan(revolutions[1:]))


def test_domain_flags_off_gives_the_same_cycles_without_the_flags():
    """``domain_flags=False`` (the optimiser, whose spec keeps the vehicle inside): every
    field equal inside the domain; a traced mass ≤ 0 is the caller's to keep out."""
    modes = workbook_modes()

    def run(flags):
        return jax.jit(
            jax.vmap(
                lambda m: vehicle.load_cycles(
                    workbook_vehicle(mass=m), modes, 1e5, domain_flags=flags
                )
            )
        )(np.array([937.0, -937.0]))

    on, off = run(True), run(False)
    for a, b in zip(jax.tree_util.tree_leaves(on), jax.tree_util.tree_leaves(off), strict=True):
        np.testing.assert_array_equal(a[0], b[0])
        assert np.all(np.isnan(a[1]))
    assert not np.isnan(off.revolutions[1]).any()
    with pytest.raises(TypeError, match="domain_flags = 'off' is not allowed"):
        vehicle.load_cycles(workbook_vehicle(), modes, 1e5, domain_flags="off")


@pytest.mark.parametrize(
    "build, message",
    [
        (lambda: workbook_vehicle(cg_height=np.array([])), "Vehicle.cg_height has shape (0,)"),
        (
            lambda: workbook_vehicle(mass=np.array([937.0, 1000.0])),
            "Vehicle.mass has shape (2,); allowed: one number (shape ())",
        ),
        (
            lambda: workbook_vehicle(reverse_ratio=np.ones(2)),
            "Vehicle.reverse_ratio has shape (2,)",
        ),
        (
            lambda: vehicle.load_cycles(workbook_vehicle(), workbook_modes(), np.array([1e5, 2e5])),
            "required_km has shape (2,); allowed: one number [km] (shape ()), or an array that "
            "broadcasts against the cycles' shape (modes, gears + 1, 4) = (3, 7, 4)",
        ),
        (
            lambda: vehicle.load_cycles(workbook_vehicle(), workbook_modes(), np.array([])),
            "required_km is empty (shape (0,))",
        ),
    ],
)
def test_one_vehicle_has_one_number_per_field(build, message):
    with pytest.raises(ValueError) as info:
        build()
    assert message in str(info.value) and "\n" not in str(info.value)
