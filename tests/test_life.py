"""The life (seed 4.2.1–4.2.3, fig. 4.3.10): Miner's rule, the angle derating, damage shares, CSV spectra."""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from tripodjax import hertz, life

WORKBOOK = dict(conformity=1 / 0.998, P_d=1347.0, C_s=1.2)
# Fig. 4.3.10, tripod column: 0° life and the five working conditions (shock + at the 8.0°
# that the workbook law implies from its "P" entry, see tripodjax.life).
L0_KM = 244_574.0
SHEET_ANGLES_DEG = np.array([6.5, 0.0, 0.0, 8.0, 12.8])
SHEET_SHARES = np.array([0.30, 0.0, 0.0, 0.35, 0.35])


def test_life_rating_500_hours_at_730_rpm():
    assert float(life.life_hours(1505.0, 1505.0, 730.0, 1.0)) == pytest.approx(500.0, rel=1e-14)
    # Cube law and Miner's rule over two equal halves.
    assert float(life.life_hours(1000.0, 500.0, 730.0, 1.0)) == pytest.approx(4000.0, rel=1e-14)
    two = float(
        life.life_hours(
            1000.0, np.array([1000.0, 500.0]), np.array([730.0, 730.0]), np.array([0.5, 0.5])
        )
    )
    assert two == pytest.approx(1 / (0.5 / 500 + 0.5 / 4000), rel=1e-14)


def spectrum_and_conditions():
    spectrum = life.LoadSpectrum(
        torque=np.array([900.0, 400.0, 150.0]),
        speed=np.array([300.0, 800.0, 1200.0]),
        vehicle_speed=np.array([40.0, 90.0, 130.0]),
        share=np.array([0.1, 0.5, 0.4]),
    )
    conditions = life.WorkingConditions(
        angle=np.radians([6.5, 0.0, 0.0, 12.8, 2.0]), share=np.array([0.45, 0.05, 0.05, 0.3, 0.15])
    )
    return spectrum, conditions


def _by_hand(spectrum, conditions, M_d_of_angle):
    per = np.array(
        [
            1
            / np.sum(
                spectrum.share * spectrum.speed * (spectrum.torque / M_d_of_angle(a)) ** 3 / 365000
            )
            for a in conditions.angle
        ]
    )
    hours = 1 / np.sum(conditions.share / per)
    return per, hours, hours * np.sum(spectrum.share * spectrum.vehicle_speed)


def test_seed_law_is_the_cosine_factor_in_M_d():
    spectrum, conditions = spectrum_and_conditions()
    out = life.joint_life(43.5, 25.55, spectrum, conditions, angle_law="seed", **WORKBOOK)
    C_p = hertz.conformity_coefficient(WORKBOOK["conformity"])

    def M_d(angle):
        return float(hertz.torque_at_pressure(1347.0, 43.5, 25.55, C_p=C_p, C_s=1.2, gamma=angle))

    per, hours, km = _by_hand(spectrum, conditions, M_d)
    np.testing.assert_allclose(out.hours_per_condition, per, rtol=1e-12)
    assert float(out.hours) == pytest.approx(hours, rel=1e-12)
    assert float(out.km) == pytest.approx(km, rel=1e-12)


def test_workbook_law_reproduces_fig_4_3_10_from_its_0_degree_life():
    g = np.asarray(life.angle_factor(np.radians(SHEET_ANGLES_DEG)))
    km = L0_KM * g
    assert km[0] == pytest.approx(164_088.0, rel=1e-3)
    assert km[4] == pytest.approx(99_204.0, rel=1e-3)
    assert km[1] == km[2] == L0_KM
    combined = 1 / np.sum(SHEET_SHARES / km)  # Miner over the mileage shares
    assert combined == pytest.approx(129_277.0, rel=1e-3)
    P = SHEET_SHARES * L0_KM / km  # the sheet's "P" row
    np.testing.assert_allclose(np.round(100 * P[[0, 3, 4]]), [45, 58, 86])
    # A weighted mean of lives (not Miner) would be far off.
    assert np.sum(SHEET_SHARES * km) > 1.04 * 129_277.0
    # The seed's law over-predicts by about 48 % and 137 % there.
    seed = np.asarray(life.angle_factor(np.radians([6.5, 12.8]), "seed"))
    np.testing.assert_allclose(seed, ((1 + np.cos(np.radians([6.5, 12.8]))) / 2) ** 3, rtol=1e-12)
    assert seed[0] * L0_KM / 164_088 - 1 == pytest.approx(0.48, abs=0.01)
    assert seed[1] * L0_KM / 99_204 - 1 == pytest.approx(1.37, abs=0.01)


def test_workbook_law_is_smooth_with_g0_one_and_decreasing():
    gamma = np.linspace(0.0, math.radians(30), 301)
    g = np.asarray(life.angle_factor(gamma))
    assert g[0] == 1.0 and np.all(np.diff(g) < 0)
    slope = jax.grad(lambda x: life.angle_factor(x))(0.1)
    fd = (float(life.angle_factor(0.1 + 1e-6)) - float(life.angle_factor(0.1 - 1e-6))) / 2e-6
    assert float(slope) == pytest.approx(fd, rel=1e-6)


def test_joint_life_workbook_law_scales_the_0_degree_life():
    spectrum, conditions = spectrum_and_conditions()
    out = life.joint_life(43.5, 25.55, spectrum, conditions, **WORKBOOK)
    C_p = hertz.conformity_coefficient(WORKBOOK["conformity"])
    M_d0 = float(hertz.torque_at_pressure(1347.0, 43.5, 25.55, C_p=C_p, C_s=1.2))
    per0, _, _ = _by_hand(spectrum, life.WorkingConditions(np.zeros(1), np.ones(1)), lambda a: M_d0)
    g = np.exp(
        -(life.WORKBOOK_ANGLE_A * conditions.angle + life.WORKBOOK_ANGLE_B * conditions.angle**2)
    )
    np.testing.assert_allclose(out.hours_per_condition, per0[0] * g, rtol=1e-12)
    assert float(out.hours) == pytest.approx(
        1 / np.sum(conditions.share / (per0[0] * g)), rel=1e-12
    )
    assert float(out.M_d) == pytest.approx(M_d0, rel=1e-12)


def test_damage_shares_sum_to_one_and_follow_the_terms():
    spectrum, conditions = spectrum_and_conditions()
    out = life.joint_life(43.5, 25.55, spectrum, conditions, **WORKBOOK)
    w_over_L = conditions.share / np.asarray(out.hours_per_condition)
    np.testing.assert_allclose(out.damage_per_condition, w_over_L / w_over_L.sum(), rtol=1e-12)
    terms = spectrum.share * spectrum.speed * spectrum.torque**3
    np.testing.assert_allclose(out.damage_per_case, terms / terms.sum(), rtol=1e-12)
    assert float(jnp.sum(out.damage_per_condition)) == pytest.approx(1.0, rel=1e-12)


@pytest.mark.parametrize("jit", [False, True])
def test_a_spectrum_that_does_no_damage_lives_for_ever(jit):
    """One rule in life_hours and joint_life: infinite life, successful, damage shares 0."""
    _, conditions = spectrum_and_conditions()
    for torque, speed in ((np.zeros(3), np.ones(3)), (np.ones(3), np.zeros(3))):
        spectrum = life.LoadSpectrum(torque, speed, np.full(3, 50.0), np.full(3, 1 / 3))

        def run(s):
            return life.joint_life(43.5, 25.55, s, conditions, **WORKBOOK)

        out = (jax.jit(run) if jit else run)(spectrum)
        assert float(out.hours) == math.inf and float(out.km) == math.inf
        assert int(out.result) == int(hertz.RESULTS.successful)
        assert np.all(np.asarray(out.damage_per_condition) == 0)
        assert np.all(np.asarray(out.hours_per_condition) == math.inf)
        hours = life.life_hours(1500.0, torque, speed, np.full(3, 1 / 3))
        assert float(hours) == math.inf


def test_gradients_match_central_differences():
    spectrum, conditions = spectrum_and_conditions()

    def life_km(d, R, conformity, P_d):
        return life.joint_life(
            d, R, spectrum, conditions, conformity=conformity, P_d=P_d, C_s=1.2
        ).km

    x = (43.5, 25.55, 1.004, 1500.0)
    grads = jax.grad(life_km, argnums=(0, 1, 2, 3))(*x)
    for i, g in enumerate(grads):
        step = 1e-6 * x[i]
        plus, minus = list(x), list(x)
        plus[i] += step
        minus[i] -= step
        fd = (float(life_km(*plus)) - float(life_km(*minus))) / (2 * step)
        assert float(g) == pytest.approx(fd, rel=1e-6), i


@pytest.mark.parametrize(
    "call, message",
    [
        (
            lambda: life.LoadSpectrum(
                np.array([1.0, 2.0]),
                np.array([100.0, -5.0]),
                np.array([50.0, 60.0]),
                np.array([0.5, 0.5]),
            ),
            "LoadSpectrum.speed[1] = -5.0 is outside the allowed range: speed ≥ 0 rpm",
        ),
        (
            lambda: life.LoadSpectrum(
                np.array([1.0, 2.0]),
                np.array([100.0, 5.0]),
                np.array([50.0, 60.0]),
                np.array([0.5, 0.6]),
            ),
            "LoadSpectrum.share sums to 1.1",
        ),
        (
            lambda: life.WorkingConditions(np.array([0.1, 0.2]), np.array([0.7, 0.2])),
            "WorkingConditions.share sums to 0.9",
        ),
        (
            lambda: life.LoadSpectrum(
                np.ones((2, 2)), np.ones((2, 2)), np.ones((2, 2)), np.full((2, 2), 0.5)
            ),
            "LoadSpectrum.torque has shape (2, 2); allowed: a non-empty 1-D array",
        ),
        (  # shares summing to 1 over the whole 2-D field: the shape is what is wrong
            lambda: life.LoadSpectrum(
                np.ones((2, 2)), np.ones((2, 2)), np.ones((2, 2)), np.full((2, 2), 0.25)
            ),
            "LoadSpectrum.torque has shape (2, 2); allowed: a non-empty 1-D array",
        ),
        (
            lambda: life.WorkingConditions(np.zeros(4), np.full((2, 2), 0.25)),
            "WorkingConditions.share has shape (2, 2)",
        ),
        (  # a batch of spectra: the row that does not sum to 1 is named
            lambda: life.life_hours(
                100.0, np.ones((2, 2)), np.ones((2, 2)), np.array([[0.5, 0.5], [0.25, 0.25]])
            ),
            "share[1, :] sums to 0.5",
        ),
        (
            lambda: life.LoadSpectrum(1.0, 1.0, 1.0, 1.0),
            "LoadSpectrum.torque has shape (); allowed: a non-empty 1-D array",
        ),
        (
            lambda: life.WorkingConditions(np.zeros((1, 1)), np.ones((1, 1))),
            "WorkingConditions.angle has shape (1, 1)",
        ),
        (
            lambda: life.angle_factor(0.1, "cosine"),
            "law = 'cosine' is not allowed; allowed: 'workbook', 'seed'",
        ),
    ],
)
def test_bad_inputs_raise_clear_errors(call, message):
    with pytest.raises(ValueError) as info:
        call()
    assert message in str(info.value)


def test_spectrum_and_conditions_check_types_and_shapes():
    with pytest.raises(TypeError, match="LoadSpectrum.torque = None"):
        life.LoadSpectrum(None, [1.0], [1.0], [1.0])
    with pytest.raises(TypeError, match="LoadSpectrum.speed = 'fast'"):
        life.LoadSpectrum([1.0], "fast", [1.0], [1.0])
    with pytest.raises(ValueError, match="one shape"):
        life.LoadSpectrum(np.ones(2), np.ones(3), np.ones(2), np.array([0.5, 0.5]))
    with pytest.raises(ValueError, match=r"WorkingConditions.angle\[0\] = nan"):
        life.WorkingConditions(np.array([np.nan]), np.array([1.0]))
    with pytest.raises(TypeError, match="allowed: a life.LoadSpectrum"):
        life.joint_life(43.5, 25.55, {"torque": 1.0}, None, **WORKBOOK)
    spectrum, conditions = spectrum_and_conditions()
    with pytest.raises(ValueError, match="angle_law = 'x' is not allowed"):
        life.joint_life(43.5, 25.55, spectrum, conditions, angle_law="x", **WORKBOOK)
    # JAX rebuilds them without the checks: tree_map to None, negative cotangents.
    assert jax.tree.map(lambda x: None, spectrum).torque is None
    assert float(jax.tree.map(lambda x: -x, spectrum).torque[0]) == -900.0


def test_non_finite_inputs_inside_jit_give_nan_and_a_nonfinite_code():
    spectrum, conditions = spectrum_and_conditions()

    @jax.jit
    def run(d, torque0, angle0):
        s = life.LoadSpectrum(
            jnp.asarray(spectrum.torque).at[0].set(torque0),
            spectrum.speed,
            spectrum.vehicle_speed,
            spectrum.share,
        )
        c = life.WorkingConditions(
            jnp.asarray(conditions.angle).at[0].set(angle0), conditions.share
        )
        return life.joint_life(d, 25.55, s, c, conformity=1.002, P_d=1347.0, C_s=1.2)

    assert run(43.5, 900.0, 0.1).result == hertz.RESULTS.successful
    for args in [
        (np.nan, 900.0, 0.1),
        (43.5, np.inf, 0.1),
        (43.5, np.nan, 0.1),
        (43.5, 900.0, np.nan),
    ]:
        out = run(*args)
        assert np.isnan(float(out.km)) and out.result == hertz.RESULTS.nonfinite, args
    hours = jax.jit(life.life_hours)
    assert np.isnan(float(hours(1505.0, np.inf, 730.0, 1.0)))
    assert np.isnan(float(hours(np.nan, 1505.0, 730.0, 1.0)))


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_result_is_successful_in_both_dtypes(dtype):
    spectrum, conditions = spectrum_and_conditions()
    out = life.joint_life(
        dtype(43.5), dtype(25.55), spectrum, conditions, conformity=1.002, P_d=1347.0, C_s=1.2
    )
    assert out.result == hertz.RESULTS.successful and np.isfinite(float(out.km))


def test_spectrum_csv_from_revolutions_and_hours(tmp_path):
    revs = tmp_path / "revs.csv"
    revs.write_text(
        "# measured on the test track\ntorque_Nm,speed_rpm,vehicle_speed_kmh,revolutions\n"
        "900,300,40,3000\n400,800,90,16000\n\n150,1200,130,0\n"
    )
    s = life.read_spectrum_csv(revs)
    time = np.array([3000 / 300, 16000 / 800, 0.0])
    np.testing.assert_allclose(s.share, time / time.sum(), rtol=1e-15)
    np.testing.assert_allclose(s.torque, [900, 400, 150])
    hours = tmp_path / "hours.csv"
    hours.write_text("hours,torque_Nm,speed_rpm,vehicle_speed_kmh\n1,900,300,40\n3,400,800,90\n")
    h = life.read_spectrum_csv(hours)
    np.testing.assert_allclose(h.share, [0.25, 0.75]) and np.testing.assert_allclose(
        h.speed, [300, 800]
    )


@pytest.mark.parametrize(
    "text, message",
    [
        (
            "torque_Nm,speed_rpm,vehicle_speed_kmh,revolutions\n900,300,40,1\n900,fast,40,1\n",
            "line 3: speed_rpm = 'fast' is not a number",
        ),
        (
            "torque_Nm,speed_rpm,vehicle_speed_kmh,revolutions\n900,300,40,1\n-5,300,40,1\n",
            "line 3: torque_Nm = -5 is not allowed",
        ),
        (
            "torque_Nm,speed_rpm,vehicle_speed_kmh,revolutions\n900,300,40\n",
            "line 2: 3 fields, the header has 4",
        ),
        (
            "torque_Nm,speed_rpm,vehicle_speed_kmh,revolutions\n900,0,40,10\n",
            "line 2: revolutions > 0 at speed_rpm = 0",
        ),
        ("torque_Nm,speed_rpm,revolutions\n900,300,10\n", "line 1: header"),
        (
            "torque_Nm,speed_rpm,vehicle_speed_kmh,hours,revolutions\n1,1,1,1,1\n",
            "one of revolutions or hours",
        ),
        ("torque_Nm,speed_rpm,vehicle_speed_kmh,hours\n", "has a header but no levels"),
        ("torque_Nm,speed_rpm,vehicle_speed_kmh,hours\n5,5,5,0\n", "every level has zero hours"),
        (
            "torque_Nm,speed_rpm,vehicle_speed_kmh,hours\n5,5,5,nan\n",
            "line 2: hours = nan is not allowed",
        ),
        (  # which column would count? (the first did, silently)
            "torque_Nm,speed_rpm,vehicle_speed_kmh,hours,hours\n5,5,5,1,2\n",
            "s.csv line 1: the column hours is given twice",
        ),
        (
            "torque_Nm,speed_rpm,torque_Nm,vehicle_speed_kmh,hours\n5,5,6,5,1\n",
            "s.csv line 1: the column torque_Nm is given twice",
        ),
    ],
)
def test_spectrum_csv_names_the_bad_line(tmp_path, text, message):
    path = tmp_path / "s.csv"
    path.write_text(text)
    with pytest.raises(ValueError) as info:
        life.read_spectrum_csv(path)
    assert message in str(info.value)


# --------------------------------------------------------------------------- in the spec


def test_spec_spectrum_file_is_read_relative_to_the_spec_folder(tmp_path, monkeypatch):
    from tripodjax import optimize

    folder = tmp_path / "job"
    (folder / "data").mkdir(parents=True)
    (folder / "data" / "measured.csv").write_text(
        "torque_Nm,speed_rpm,vehicle_speed_kmh,hours\n1000,300,40,1\n400,800,100,3\n"
    )
    (folder / "spec.toml").write_text('[life]\nspectrum_file = "data/measured.csv"\n')
    monkeypatch.chdir(tmp_path)  # not the spec's folder
    spec = optimize.load_spec(folder / "spec.toml")
    assert not spec.structure.spectrum_from_vehicle and spec.structure.m_max_from_vehicle
    np.testing.assert_allclose(spec.values["life"]["share"], [0.25, 0.75])
    out = optimize.life_report(spec, {"R": 25.55, "d_roller": 43.5})
    expected = life.joint_life(
        43.5,
        25.55,
        life.read_spectrum_csv(folder / "data" / "measured.csv"),
        life.WorkingConditions(
            spec.values["life"]["condition_angle"], spec.values["life"]["condition_share"]
        ),
        conformity=1.002,
        P_d=1347.0,
        C_s=1.2,
    )
    assert out["km"] == pytest.approx(float(expected.km), rel=1e-12)
    assert [c["case"] for c in out["damage_by_case"]] == [0, 1]
    (folder / "bad.toml").write_text('[life]\nspectrum_file = "data/bad.csv"\n')
    (folder / "data" / "bad.csv").write_text(
        "torque_Nm,speed_rpm,vehicle_speed_kmh,hours\n1000,300,40,1\n400,x,100,3\n"
    )
    with pytest.raises(
        optimize.SpecError, match=r"bad.csv line 3: speed_rpm = 'x' is not a number"
    ):
        optimize.load_spec(folder / "bad.toml")
    # A file's levels within the [life] lists' ranges (1e300 N·m gave a plausible life before).
    (folder / "data" / "bad.csv").write_text(
        "torque_Nm,speed_rpm,vehicle_speed_kmh,hours\n1000,300,40,1\n1e300,800,100,3\n"
    )
    with pytest.raises(
        optimize.SpecError,
        match=r"bad.csv level 2: torque_Nm = 1e\+300 is not allowed: a finite number ≥ 0 N·m "
        r"and ≤ 50000 N·m$",
    ):
        optimize.load_spec(folder / "bad.toml")


def test_evaluate_gives_the_damage_by_condition_gear_and_mode():
    from tripodjax import optimize

    spec = optimize.load_spec()
    out = optimize.evaluate(spec, {"R": 25.55, "d_roller": 43.5})["life"]
    assert out["angle_law"] == "workbook" and out["required_km"] == 100_000.0
    cases = out["damage_by_case"]
    assert len(cases) == 3 * 7 * 4  # modes × (6 gears + reverse) × engine conditions
    assert sum(c["damage_share"] for c in cases) == pytest.approx(1.0, rel=1e-12)
    assert all(
        c["damage_share"] == 0 for c in cases if c["engine_condition"] in ("T_mean", "brake")
    )
    # By hand: each case's r_i M_i³ (revolution share × torque³) over the sum.
    from tripodjax.optimize.problem import load_cycles

    cycles = load_cycles(spec.structure, spec.values)
    terms = np.asarray(cycles.share) * np.asarray(cycles.working_torque) ** 3
    sport_1st_T_max = [
        c for c in cases if (c["mode"], c["gear"], c["engine_condition"]) == ("sport", "1", "T_max")
    ][0]
    assert sport_1st_T_max["damage_share"] == pytest.approx(terms[0, 0, 1] / terms.sum(), rel=1e-6)
    shares = [c["damage_share"] for c in out["conditions"]]
    assert sum(shares) == pytest.approx(1.0) and shares[1] == shares[2] == 0.0
    km = [c["life_km"] for c in out["conditions"]]
    assert 1 / sum(
        c["share"] / k for c, k in zip(out["conditions"], km, strict=True)
    ) == pytest.approx(out["km"], rel=1e-12)


def test_a_first_call_compiles_one_program_not_each_operation(caplog):
    """The chain's public functions check their arguments, then run one compiled program: a
    first call compiled each operation alone (50–150 programs; `vehicle.load_cycles` 1.1 s,
    `life.joint_life` 2.4 s, against 0.3 and 0.8 s). Shapes no other test uses: nothing is
    compiled already."""
    from test_vehicle import workbook_modes, workbook_vehicle

    from tripodjax import vehicle

    n = 11  # spectrum rows
    spectrum = life.LoadSpectrum(
        np.linspace(100.0, 1100.0, n), np.full(n, 500.0), np.full(n, 60.0), np.full(n, 1 / n)
    )
    conditions = life.WorkingConditions(np.radians([3.0, 7.0, 9.0]), np.array([0.2, 0.3, 0.5]))
    modes = workbook_modes()
    calls = {
        "life.joint_life": lambda: life.joint_life(43.5, 25.55, spectrum, conditions, **WORKBOOK),
        "life.life_hours": lambda: life.life_hours(
            1000.0, spectrum.torque, spectrum.speed, spectrum.share
        ),
        "hertz.capacities": lambda: hertz.capacities(
            np.full(n, 43.5), 25.55, P_s=4000.0, P_sd=2500.0, **WORKBOOK
        ),
        "vehicle.load_cycles": lambda: vehicle.load_cycles(
            workbook_vehicle(), modes, np.full((1, 1, 1), 1e5)
        ),
    }
    for name, call in calls.items():
        caplog.clear()
        with jax.log_compiles(True), caplog.at_level("WARNING"):
            jax.block_until_ready(call())
        compiled = [r for r in caplog.records if "Finished XLA compilation" in r.getMessage()]
        assert len(compiled) <= 2, (name, [r.getMessage() for r in compiled])


def test_a_spectrum_whose_lists_differ_in_length_is_named():
    with pytest.raises(ValueError, match=r"torque \(3,\), speed \(2,\), share \(2,\)"):
        life.life_hours(1500.0, [500.0, 800.0, 900.0], [1000.0, 2000.0], [0.5, 0.5])
    # M_d with leading axes: one life per entry, as documented
    hours = life.life_hours(np.array([[1500.0], [1600.0]]), [500.0, 800.0], [1e3, 2e3], [0.5, 0.5])
    assert np.shape(hours) == (2, 1) and float(hours[1, 0]) > float(hours[0, 0])


def test_life_of_small_inputs_compiles_for_latency_and_of_large_ones_for_throughput():
    """A library program called at top level is compiled with the latency options where no
    input holds more than SMALL_INPUT elements, with XLA's defaults beyond (a throughput
    program), and inside a caller's trace as part of the caller's program; the answers agree."""
    from tripodjax._compile import SMALL_INPUT

    program = life._life_hours
    # Seven cases: a signature no other test compiles, so that each call compiles anew.
    torque = np.array([1000.0, 800.0, 700.0, 500.0, 400.0, 300.0, 0.0])
    speed = np.array([100.0, 150.0, 200.0, 300.0, 400.0, 500.0, 600.0])
    spectrum = (torque, speed, np.full(7, 1.0 / 7.0))
    many = np.full((SMALL_INPUT + 1, 1), 1733.0)  # one M_d a row

    def grown(*args):
        before = [p._cache_size() for p in (program.latency_bound, program.plain)]
        value = life.life_hours(*args)
        after = [p._cache_size() for p in (program.latency_bound, program.plain)]
        return value, [a - b for a, b in zip(after, before, strict=True)]

    one, small = grown(np.float64(1733.0), *spectrum)
    row, large = grown(many, *spectrum)
    assert small == [1, 0] and large == [0, 1]
    nested = jax.jit(lambda m: life.life_hours(m, *spectrum))(1733.0)
    np.testing.assert_allclose(row, float(one), rtol=1e-12)
    assert float(nested) == pytest.approx(float(one), rel=1e-12)


@jax.jit
@jax.vmap
def _life_cases(x):
    spectrum = life.LoadSpectrum(
        torque=jnp.stack([x["torque0"], 400.0]),
        speed=jnp.array([300.0, 800.0]),
        vehicle_speed=jnp.array([40.0, 90.0]),
        share=jnp.stack([x["share0"], x["share1"]]),
    )
    conditions = life.WorkingConditions(
        angle=jnp.stack([x["angle0"], 0.1]), share=jnp.stack([x["w0"], x["w1"]])
    )
    out = life.joint_life(
        x["d"], x["R"], spectrum, conditions, conformity=1.004, P_d=x["P_d"], C_s=1.2
    )
    hours = life.life_hours(x["P_d"], spectrum.torque, spectrum.speed, spectrum.share)
    return out.km, out.result, hours


def test_traced_inputs_outside_their_domain_give_a_nan_life_and_outside_validity():
    """Before: a negative d gave the life of +d, R or P_d < 0 an infinite one, an angle of 2 rad
    1.7e-17 km, shares of [−0.5, 1.5] a plausible one, all ``successful``. (That shares sum to
    1 is checked where they are concrete: traced, a derivative moves one share alone.)"""
    good = dict(d=20.0, R=25.0, P_d=2400.0, torque0=900.0, share0=0.5, share1=0.5)
    good.update(angle0=0.2, w0=0.5, w1=0.5)
    bad = [
        {"d": -20.0},
        {"R": -25.0},
        {"P_d": -2400.0},
        {"torque0": -900.0},
        {"share0": -0.5, "share1": 1.5},
        {"angle0": 2.0},
        {"w0": -0.5, "w1": 1.5},
    ]
    rows = [good] + [{**good, **b} for b in bad] + [{**good, "torque0": np.nan}]
    km, result, hours = jax.device_get(
        _life_cases({k: np.array([r[k] for r in rows]) for k in good})
    )
    assert np.isfinite(km[0]) and result[0] == hertz.RESULTS.successful and np.isfinite(hours[0])
    assert np.all(np.isnan(km[1:]))
    assert np.all(result[1:-1] == hertz.RESULTS.outside_validity), result
    assert result[-1] == hertz.RESULTS.nonfinite
    # life_hours (no code): NaN for its own inputs outside (P_d, a torque, the shares)
    assert np.all(np.isnan(hours[[3, 4, 5, -1]])) and np.all(np.isfinite(hours[[1, 2, 6]]))


def test_joint_life_takes_arrays_that_broadcast_and_names_those_that_do_not():
    spectrum, conditions = spectrum_and_conditions()
    d = np.array([43.5, 45.0])
    both = life.joint_life(d, 25.55, spectrum, conditions, **WORKBOOK)
    assert both.km.shape == (2,) and both.hours_per_condition.shape == (2, 5)
    assert both.damage_per_case.shape == (2, 3) and both.result.shape == (2,)
    for i in range(2):
        one = life.joint_life(d[i], 25.55, spectrum, conditions, **WORKBOOK)
        assert float(both.km[i]) == pytest.approx(float(one.km), rel=1e-12)
        np.testing.assert_allclose(both.damage_per_condition[i], one.damage_per_condition)
    with pytest.raises(ValueError, match=r"^the arguments have shapes d \(2,\), R \(3,\); "):
        life.joint_life(d, np.full(3, 25.55), spectrum, conditions, **WORKBOOK)
    with pytest.raises(ValueError, match=r"^torque is empty \(shape \(0,\)\)"):
        life.life_hours(1000.0, [], [], [])
    assert float(life.life_hours(1505.0, [1505.0], [730.0], [1.0])) == pytest.approx(500.0)
