"""Friction and GAF (seed §3.2): the seed's facts, an independent evaluation, limits, gradients."""

import math
import re

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import reference
from scipy.optimize import brentq

from tripodjax import Layout, catalogue, friction, seed_case, solvers
from tripodjax._compile import latency_bound_jit
from tripodjax.kinematics import period_grid

PARAMS_EXAMPLE = friction.GREASE_A.replace(mu_slp=0.04, lam=0.007)  # the seed's GAF example
THETA = np.linspace(0, 2 * np.pi, 721)


def printed_gaf(theta_roller1, gamma_deg, torque, R_mm, mu_slp, lam):
    """3.2.11–3.2.15 as printed, in degrees, plain NumPy (independent of the library)."""
    Cd1, Cd2, Rs = 0.4, 8.4e-3, 0.585
    total = 0.0
    for i in range(3):
        th = np.asarray(theta_roller1) + np.radians(120 * i)
        mu_sr = Rs * np.radians(gamma_deg) * mu_slp + (1 - Rs * np.radians(gamma_deg)) * lam
        mu_dyn = gamma_deg / 15 * (Cd1 * mu_slp - Cd2) * np.abs(np.sin(th)) + mu_sr
        total = total + np.sign(np.sin(th + np.radians(90))) * np.abs(mu_dyn)
    return 2 * torque / (3 * R_mm / 1000) * total


def test_three_roller_mean_of_mu_avg_is_constant():
    """§3.2.5: at γ 15°, 160 N·m, grease A the combined mean friction is constant (0.1445)."""
    theta = np.linspace(0, 2 * np.pi, 97)
    rollers = theta[:, None] + np.array([0, 2, 4]) * np.pi / 3
    each = np.asarray(friction.mu_avg(rollers, math.radians(15), 160.0, friction.GREASE_A))
    np.testing.assert_allclose(each.mean(axis=1), 0.1445, atol=5e-4)
    assert np.ptp(each.mean(axis=1)) < 1e-12
    assert each.min() == pytest.approx(0.102, abs=5e-4) and each.max() == pytest.approx(
        0.187, abs=5e-4
    )


def test_static_friction_limits():
    g = math.radians(15)
    assert float(friction.mu_sta(g, 0.0)) == pytest.approx(3.86e-2, rel=1e-14)
    assert float(friction.mu_sta(g, 1e5)) == pytest.approx(
        3.86e-2 + 1.34e-1 + 4.5e-3 * 15, rel=1e-12
    )


def test_dynamic_friction_inward_and_outward_are_opposite():
    theta = np.linspace(0, 2 * np.pi, 13)  # holds θ = 90°
    g = math.radians(15)
    inward = friction.mu_dyn(theta, g, stroke="in")
    np.testing.assert_allclose(friction.mu_dyn(theta, g, stroke="out"), -inward, rtol=1e-15)
    # Over θ the inward coefficient swings by (γ°/15)(C_d1 μ_slp − C_d2) above μ_S/R.
    assert float(jnp.min(inward)) == pytest.approx(
        0.585 * g * 0.06 + (1 - 0.585 * g) * 0.007, rel=1e-12
    )
    assert float(jnp.max(inward) - jnp.min(inward)) == pytest.approx(0.4 * 0.06 - 8.4e-3, rel=1e-12)


@pytest.mark.parametrize("gamma_deg", [0.0, 7.5, 20.0, 45.0])
def test_printed_gaf_equals_independent_evaluation(gamma_deg):
    ours = friction.gaf(
        THETA, math.radians(gamma_deg), 1000.0, 25.0, PARAMS_EXAMPLE, factor="printed"
    )
    theirs = printed_gaf(THETA, gamma_deg, 1000.0, 25.0, 0.04, 0.007)
    np.testing.assert_allclose(ours, theirs, rtol=1e-12, atol=1e-9)


def test_printed_gaf_is_a_third_order_square_wave_linear_in_torque_and_inverse_in_R():
    g = math.radians(20)
    base = np.asarray(friction.gaf(THETA, g, 1000.0, 25.0))
    np.testing.assert_allclose(
        friction.gaf(THETA + 2 * np.pi / 3, g, 1000.0, 25.0), base, rtol=1e-9, atol=1e-9
    )
    np.testing.assert_allclose(
        friction.gaf(THETA + np.pi / 3, g, 1000.0, 25.0), -base, rtol=1e-9, atol=1e-9
    )
    np.testing.assert_allclose(friction.gaf(THETA, g, 250.0, 25.0), 0.25 * base, rtol=1e-14)
    np.testing.assert_allclose(friction.gaf(THETA, g, 1000.0, 50.0), 0.5 * base, rtol=1e-14)
    sign_changes = np.count_nonzero(np.diff(np.sign(base[:-1])))
    assert sign_changes == 6  # six reversals per revolution: third order


def test_printed_model_keeps_a_lambda_square_wave_at_zero_angle():
    force = np.asarray(friction.gaf(THETA, 0.0, 1000.0, 25.0, PARAMS_EXAMPLE, factor="printed"))
    level = 2000.0 * 1000.0 / (3 * 25.0) * 0.007
    np.testing.assert_allclose(np.abs(force[np.abs(force) > 0]), level, rtol=1e-12)


def test_stroke_model_vanishes_at_zero_angle_and_decreases_towards_it():
    gammas = np.radians([20.0, 10.0, 5.0, 2.0, 1.0, 0.5, 0.2, 0.05, 0.0])
    rms = [
        float(jnp.sqrt(jnp.mean(friction.gaf(THETA, g, 1000.0, 25.0, model="stroke") ** 2)))
        for g in gammas
    ]
    assert all(a > b for a, b in zip(rms, rms[1:], strict=False))
    assert rms[-1] == 0.0
    dgaf = jax.grad(lambda g: jnp.sum(friction.gaf(THETA, g, 1000.0, 25.0, model="stroke")))(0.0)
    assert np.isfinite(float(dgaf))


def test_stroke_model_tends_to_the_printed_one_away_from_zero_angle():
    g = math.radians(20)
    theta = THETA + 1e-3  # off the reversal points, where the printed sign is 0
    printed = np.asarray(friction.gaf(theta, g, 1000.0, 25.0))
    for width, tol in ((1e-2, 0.02), (1e-4, 2e-4)):
        stroke = np.asarray(friction.gaf(theta, g, 1000.0, 25.0, model="stroke", width=width))
        rms_printed, rms_stroke = np.sqrt(np.mean(printed**2)), np.sqrt(np.mean(stroke**2))
        assert rms_stroke == pytest.approx(rms_printed, rel=tol)


def test_halfshaft_gaf_is_the_printed_model_on_the_independent_kinematics():
    layout = seed_case("N")
    result = friction.gaf_halfshaft(layout, 1000.0, PARAMS_EXAMPLE, n_theta=360, factor="printed")
    theta = np.asarray(period_grid(360, jnp.float64))
    psi, gamma = reference.solve(theta, layout.R, layout.l, layout.gamma0)
    # Lee's roller angle is ψ_i + 90°; γ varies per θ.
    expected = np.array(
        [
            printed_gaf(p + np.pi / 2, math.degrees(g), 1000.0, layout.R, 0.04, 0.007)
            for p, g in zip(psi, gamma, strict=False)
        ]
    )
    np.testing.assert_allclose(result.force, expected, rtol=1e-9, atol=1e-8)
    assert float(result.rms) == pytest.approx(np.sqrt(np.mean(expected**2)), rel=1e-9)
    assert float(result.peak) == pytest.approx(np.abs(expected).max(), rel=1e-12)
    fft = np.fft.rfft(expected) / len(expected)
    assert float(result.third_order) == pytest.approx(
        2 * np.abs(fft[1]), rel=1e-9
    )  # one period = order 3


def test_halfshaft_stroke_model_at_zero_layout_angle():
    result = friction.gaf_halfshaft(Layout(25.0, 500.0, 0.0), 1000.0, model="stroke")
    assert float(result.rms) == 0.0 and float(result.peak) == 0.0
    grads = jax.grad(lambda lay: friction.gaf_halfshaft(lay, 1000.0, model="stroke").rms)(
        Layout(25.0, 500.0, 0.0)
    )
    assert all(np.isfinite(float(v)) for v in jax.tree_util.tree_leaves(grads))


def test_zero_torque_gives_zero_force():
    assert float(friction.gaf_halfshaft(seed_case("N"), 0.0).rms) == 0.0


def central_difference(f, x, step):
    return (f(x + step) - f(x - step)) / (2 * step)


@pytest.mark.parametrize("model", ["stroke", "printed"])
def test_gradients_of_halfshaft_gaf_rms_match_finite_differences(model):
    layout = Layout.from_degrees(28.0, 450.0, 18.0)
    params = friction.GREASE_A

    def rms(lay, torque, p):
        return friction.gaf_halfshaft(lay, torque, p, model=model).rms

    # One gradient program for every argument (each argnums compiles its own).
    g_layout, g_torque, g_params = jax.grad(rms, argnums=(0, 1, 2))(layout, 900.0, params)
    for name in params.__dataclass_fields__:
        value = getattr(params, name)
        step = 1e-5 * abs(value)
        fd = central_difference(
            lambda v, name=name: float(rms(layout, 900.0, params.replace(**{name: v}))), value, step
        )
        assert float(getattr(g_params, name)) == pytest.approx(fd, rel=1e-4, abs=1e-9), name
    assert float(g_torque) == pytest.approx(float(rms(layout, 900.0, params)) / 900.0, rel=1e-12)
    for name in ("R", "l", "gamma0"):
        base = getattr(layout, name)
        step = 1e-6 * base
        fields = {"R": layout.R, "l": layout.l, "gamma0": layout.gamma0}

        def moved(v, fields=fields, name=name):
            return float(rms(Layout(**{**fields, name: v}), 900.0, params))

        assert float(getattr(g_layout, name)) == pytest.approx(
            central_difference(moved, base, step), rel=1e-4
        ), name


@pytest.mark.parametrize("model", ["stroke", "printed"])
def test_an_eager_gaf_derivative_runs_the_jacobian_program_and_equals_reverse_mode(model):
    """jax.grad and jax.jacfwd of the halfshaft GAF answer from one program of the values and
    their Jacobian, compiled at top level for latency: equal to reverse mode through the
    revolution."""
    layout, params = Layout.from_degrees(28.0, 450.0, 18.0), friction.GREASE_A.replace(lam=0.01)

    def gaf(lay, torque, p):
        return friction.gaf_halfshaft(lay, torque, p, 60, model=model)

    def plain(lay, torque, p):  # the function itself, reverse mode through the solve
        inputs = friction.GAFInputs(torque, p, model)
        out = friction._gaf_over_revolution(
            lay, inputs, n_theta=60, solver=solvers.resolve("newton")
        )
        return out.third_order, out.force

    program = friction._gaf_halfshaft.with_jacobian.latency_bound
    before = program._cache_size()
    got = jax.grad(lambda *a: gaf(*a).third_order, argnums=(0, 1, 2))(layout, 900.0, params)
    forward = jax.jacfwd(lambda *a: gaf(*a).force, argnums=(0, 1, 2))(layout, 900.0, params)
    # One program for both (none where another test of this worker compiled it already).
    assert program._cache_size() - before <= 1
    want = latency_bound_jit(jax.jacrev(plain, argnums=(0, 1, 2)))(layout, 900.0, params)
    for got_, want_ in ((got, want[0]), (forward, want[1])):
        for g, w in zip(*(jax.tree_util.tree_leaves(x) for x in (got_, want_)), strict=True):
            np.testing.assert_allclose(g, w, rtol=1e-11, atol=1e-11 * np.abs(w).max() + 1e-300)


def test_a_gaf_derivative_under_jit_equals_the_eager_one():
    """Under a user's jit the rule's Jacobian joins the caller's program (its traced path)."""
    layout, params = Layout.from_degrees(28.0, 450.0, 18.0), friction.GREASE_A

    def third(lay, torque, p):
        return friction.gaf_halfshaft(lay, torque, p, 60).third_order

    eager = jax.grad(third, argnums=(0, 1, 2))(layout, 900.0, params)
    traced = jax.jit(jax.grad(third, argnums=(0, 1, 2)))(layout, 900.0, params)
    for g, w in zip(*(jax.tree_util.tree_leaves(x) for x in (traced, eager)), strict=True):
        assert float(g) == pytest.approx(float(w), rel=1e-12, abs=1e-300)


def test_float32_gaf_close_to_float64(float32_default):
    rms32 = friction.gaf_halfshaft(seed_case("N"), 1000.0, model="stroke").rms
    assert rms32.dtype == jnp.float32
    with jax.enable_x64(True):
        rms64 = float(friction.gaf_halfshaft(seed_case("N"), 1000.0, model="stroke").rms)
    assert float(rms32) == pytest.approx(rms64, rel=1e-5)


def test_rolling_resistance_utilities():
    assert float(
        friction.rolling_resistance_hysteresis(0.3, 20.0, 0.1, contact="line")
    ) == pytest.approx(0.1 * 0.6 / (3 * math.pi * 20))
    assert float(friction.rolling_resistance_hysteresis(0.3, 20.0, 0.1)) == pytest.approx(
        0.1 * 0.9 / (16 * 20)
    )
    assert float(friction.rolling_resistance_microslip(2.0, 20.0, 0.06)) == pytest.approx(
        0.08 * 0.06 * 0.01
    )


def test_friction_from_trunnion_force_recovers_a_known_coefficient():
    """Forces built from a normal N and a friction P along the formula's (orthonormal) directions."""
    rng = np.random.default_rng(5)
    for _ in range(20):
        theta, gamma = rng.uniform(0, 2 * np.pi), rng.uniform(0, 0.8)
        st, ct, sg, cg = np.sin(theta), np.cos(theta), np.sin(gamma), np.cos(gamma)
        normal_dir = np.array([st**2 + cg * ct**2, ct * sg, -st * ct * (cg - 1)])
        friction_dir = np.array([-ct * sg, cg, st * sg])
        assert (
            np.linalg.norm(normal_dir) == pytest.approx(1, rel=1e-14)
            and abs(normal_dir @ friction_dir) < 1e-15
        )
        N, mu = rng.uniform(500, 5000), rng.uniform(0.02, 0.3)
        F = N * normal_dir + mu * N * friction_dir
        assert float(friction.friction_from_trunnion_force(*F, theta, gamma)) == pytest.approx(
            mu, rel=1e-12
        )


@pytest.mark.parametrize(
    "call, message",
    [
        (
            lambda: friction.gaf(0.0, 0.3, -5.0, 25.0),
            "torque = -5.0 is outside the allowed range: torque ≥ 0 N·m",
        ),
        (lambda: friction.gaf(0.0, 0.3, 100.0, 0.0), "R = 0.0 is outside the allowed range: R > 0"),
        (
            lambda: friction.gaf(0.0, 0.3, 100.0, 25.0, model="smooth"),
            "model = 'smooth' is not allowed; allowed: 'printed', 'stroke'",
        ),
        (
            lambda: friction.gaf_halfshaft(seed_case("N"), -1.0),
            "torque = -1.0 is outside the allowed range",
        ),
        (
            lambda: friction.mu_dyn(0.0, 0.3, stroke="up"),
            "stroke = 'up' is not allowed; allowed: 'in', 'out'",
        ),
        (
            lambda: friction.FrictionParams(mu_slp=-0.1),
            "FrictionParams.mu_slp = -0.1 is outside the allowed range: mu_slp ≥ 0",
        ),
        (
            lambda: friction.FrictionParams(lam=float("nan")),
            "FrictionParams.lam = nan is outside the allowed range: lam ≥ 0",
        ),
        (
            lambda: friction.FrictionParams(C_s4=float("inf")),
            "FrictionParams.C_s4 = inf is outside the allowed range",
        ),
        (
            lambda: friction.GREASE_A.replace(C_d2=-1e-3),
            "FrictionParams.C_d2 = -0.001 is outside the allowed range: C_d2 ≥ 0",
        ),
        (
            lambda: friction.FrictionParams(mu_slp=np.float32(-0.5)),
            "FrictionParams.mu_slp = -0.5 is outside",
        ),
        (
            lambda: friction.rolling_resistance_hysteresis(0.3, 20.0, 0.1, contact="point"),
            "contact = 'point' is not allowed",
        ),
        # The GAF's inputs one number each: an array lined up with the rollers or the angles.
        (
            lambda: friction.gaf_halfshaft(seed_case("N"), np.array([1000.0, 2000.0])),
            "torque has shape (2,); allowed: one number (jax.vmap over the inputs for a batch)",
        ),
        (
            lambda: friction.gaf_halfshaft(seed_case("N"), [1000.0, 2000.0]),
            "torque has shape (2,); allowed: one number",
        ),
        # ... traced too: under jit (no vmap) a shape-(2,) torque is two numbers as well
        (
            lambda: jax.jit(friction.gaf_halfshaft, static_argnums=0)(
                seed_case("N"), jnp.array([1000.0, 2000.0])
            ),
            "torque has shape (2,); allowed: one number",
        ),
        (
            lambda: friction.gaf_halfshaft(
                seed_case("N"), 1000.0, friction.FrictionParams(mu_slp=np.array([0.1, 0.2, 0.3]))
            ),
            "params.mu_slp has shape (3,); allowed: one number",
        ),
        (
            lambda: friction.gaf(
                0.3, 0.3, 1000.0, 25.0, friction.FrictionParams(lam=np.array([0.01, 0.02, 0.03]))
            ),
            "params.lam has shape (3,); allowed: one number",
        ),
        (
            lambda: friction.gaf(0.3, 0.3, 1000.0, 25.0, model="stroke", width=np.full(3, 0.01)),
            "width has shape (3,); allowed: one number",
        ),
        (
            lambda: friction.FrictionParams(mu_slp=np.zeros(0)),
            "FrictionParams.mu_slp is empty (shape (0,)); allowed: a number or a non-empty array",
        ),
        (lambda: friction.GAFInputs(np.zeros(0)), "torque is empty (shape (0,))"),
        # Shapes that do not broadcast, and empty arrays, in one line naming the arguments.
        (
            lambda: friction.gaf(np.zeros(3), np.full(2, 0.3), 1000.0, 25.0),
            "the arguments have shapes theta (3,), gamma (2,); allowed: numbers, or arrays",
        ),
        (
            lambda: friction.mu_sta(np.full(3, 0.3), np.full(2, 100.0)),
            "the arguments have shapes gamma (3,), torque (2,)",
        ),
        (
            lambda: friction.mu_avg(np.zeros(3), np.full(2, 0.3), 100.0),
            "the arguments have shapes theta (3,), gamma (2,)",
        ),
        (
            lambda: friction.mu_avg(
                np.zeros(3), 0.3, 100.0, friction.FrictionParams(mu_slp=np.array([0.05, 0.06]))
            ),
            "the arguments have shapes theta (3,), params.mu_slp (2,)",
        ),
        (
            lambda: friction.rolling_resistance_hysteresis(np.full(3, 0.3), np.full(2, 20.0), 0.1),
            "the arguments have shapes a (3,), rolling_radius (2,)",
        ),
        (lambda: friction.mu_sta(np.zeros(0), 100.0), "gamma is empty (shape (0,))"),
        # The trunnion-force measurement: finite forces, a working angle in rad.
        (
            lambda: friction.friction_from_trunnion_force(1000.0, 100.0, 0.0, 0.3, 20.0),
            "gamma = 20.0 is outside the allowed range: 0 ≤ gamma < π/2 rad",
        ),
        (
            lambda: friction.friction_from_trunnion_force(float("nan"), 100.0, 0.0, 0.3, 0.2),
            "F_x = nan is outside the allowed range: F_x finite N",
        ),
        (
            lambda: friction.friction_from_trunnion_force(
                1000.0, [1.0, 2.0], np.zeros(3), 0.3, 0.2
            ),
            "the arguments have shapes F_y (2,), F_z (3,)",
        ),
    ],
)
def test_bad_inputs_raise_clear_errors(call, message):
    with pytest.raises(ValueError) as info:
        call()
    assert message in str(info.value) and "\n" not in str(info.value)


@pytest.mark.parametrize("force", [True, "1000", None])
def test_trunnion_force_of_a_wrong_type_is_a_type_error_naming_it(force):
    with pytest.raises(TypeError, match="^F_z = .* is not allowed; allowed: a real number"):
        friction.friction_from_trunnion_force(1000.0, 100.0, force, 0.3, 0.2)


def test_trunnion_force_without_a_normal_component_gives_nan_not_inf():
    """μ = tangential / normal is undefined where the normal component vanishes (no force, or a
    purely tangential one: (0, F_y, 0) at γ = 0); a normal one still gives its coefficient."""
    mu = friction.friction_from_trunnion_force(
        [0.0, 0.0, 1000.0], [100.0, 0.0, 100.0], 0.0, 0.3, [0.0, 0.2, 0.0]
    )
    assert np.isnan(mu[0]) and np.isnan(mu[1]) and float(mu[2]) == pytest.approx(0.1)


def test_lists_are_arrays_and_array_constants_broadcast():
    """Lists as their arrays (they failed inside JAX); a FrictionParams array field broadcasts in
    the elementwise coefficients like a batch of FrictionParams."""
    gammas = [0.1, 0.2]
    np.testing.assert_allclose(
        friction.mu_sta(gammas, 100.0), friction.mu_sta(np.array(gammas), 100.0), rtol=1e-15
    )
    np.testing.assert_allclose(
        friction.gaf([0.1, 0.2], 0.3, [1000.0, 500.0], 25.0),
        friction.gaf(np.array([0.1, 0.2]), 0.3, np.array([1000.0, 500.0]), 25.0),
        rtol=1e-15,
    )
    assert float(friction.rolling_resistance_microslip([2.0], 20.0, 0.06)[0]) == pytest.approx(
        0.08 * 0.06 * 0.01
    )
    greases = [friction.FrictionParams(mu_slp=mu) for mu in (0.05, 0.09)]
    batched = friction.mu_avg(0.5, 0.3, 100.0, friction.FrictionParams(mu_slp=[0.05, 0.09]))
    one_by_one = [float(friction.mu_avg(0.5, 0.3, 100.0, grease)) for grease in greases]
    np.testing.assert_allclose(batched, one_by_one, rtol=1e-14)


def test_a_traced_gaf_input_outside_its_domain_is_flagged_not_successful():
    """Inside jit, a negative torque, a width ≤ 0 or a negative friction constant (each refused
    at the boundary) gave a plausible GAF marked successful; NaN stays nonfinite."""
    from tripodjax.results import RESULTS

    def gaf(torque, width, mu_slp, C_s4):
        params = friction.GREASE_A.replace(mu_slp=mu_slp, C_s4=C_s4)
        return friction.gaf_halfshaft(seed_case("N"), torque, params, 24, "stroke", width).result

    cases = np.array(
        [  # torque, width, mu_slp, C_s4
            [1000.0, 0.01, 0.06, 0.0235],
            [-1000.0, 0.01, 0.06, 0.0235],
            [1000.0, -0.01, 0.06, 0.0235],
            [1000.0, 0.0, 0.06, 0.0235],
            [1000.0, 0.01, -0.5, 0.0235],
            [1000.0, 0.01, 0.06, -0.01],
            [float("nan"), 0.01, 0.06, 0.0235],
        ]
    )
    codes = jax.jit(jax.vmap(gaf))(*cases.T)
    ok, out, nonfinite = RESULTS.successful, RESULTS.outside_validity, RESULTS.nonfinite
    assert codes.tolist() == [ok, out, out, out, out, out, nonfinite]


def test_float32_single_joint_stroke_gaf_at_small_angles(float32_default):
    """The stroke model's three terms cancel at first order: summed from the small stroke rates,
    float32 holds float64 down to γ = 1e-9 (4 % off at 1e-6 before) and the γ-derivative at 0
    is 0 (0.0029 before)."""
    theta = np.linspace(0.0, 2.0 * np.pi / 3.0, 12, endpoint=False) + 0.05

    @jax.jit
    def values_and_slope(gammas):  # at γ = 1e-9 and 1e-6, and the γ-derivative at 0
        def gaf(gamma):
            return friction.gaf(theta, gamma, 1000.0, 25.0, model="stroke")

        return jax.vmap(gaf)(gammas), jax.jacfwd(gaf)(jnp.zeros_like(gammas[0]))

    value32, slope32 = values_and_slope(np.array([1e-9, 1e-6], np.float32))
    assert value32.dtype == np.float32
    with jax.enable_x64(True):
        value64, slope64 = values_and_slope(np.array([1e-9, 1e-6]))
    value32, value64 = np.asarray(value32), np.asarray(value64)
    error = np.abs(value32 - value64).max(axis=1) / np.abs(value64).max(axis=1)
    assert np.all(error < 1e-4), error
    assert np.abs(slope32).max() < 1e-12 and np.abs(slope64).max() < 1e-12


def test_friction_params_accept_traced_values_and_gradients():
    layout = seed_case("N")

    def rms(lam, mu):
        params = friction.GREASE_A.replace(lam=lam, mu_slp=mu)
        return friction.gaf_halfshaft(layout, 800.0, params, 60, "stroke").rms

    grads = jax.jit(jax.grad(rms, argnums=(0, 1)))(0.007, 0.06)
    assert all(np.isfinite(float(g)) for g in grads)
    # A gradient w.r.t. the params is a FrictionParams whose entries may be negative.
    g = jax.grad(lambda p: friction.gaf_halfshaft(layout, 800.0, p, 60).rms)(friction.GREASE_A)
    assert isinstance(g, friction.FrictionParams)


def test_gaf_result_carries_the_kinematic_status():
    from tripodjax.results import RESULTS
    from tripodjax.solvers import Newton

    ok = friction.gaf_halfshaft(seed_case("N"), 800.0, n_theta=60)
    assert int(ok.result) == RESULTS.successful
    capped = friction.gaf_halfshaft(seed_case("g25"), 800.0, n_theta=60, solver=Newton(max_steps=1))
    assert int(capped.result) == RESULTS.max_steps_reached


def _log_uniform_layouts(n, seed, dtype):
    """R/l log-uniform 1e-5…0.2, l 1…1e5 mm, γ0 log-uniform 1e-9…π/4 rad (the metrics' edge set)."""
    rng = np.random.default_rng(seed)
    ratio = np.exp(rng.uniform(np.log(1e-5), np.log(0.2), n))
    gamma0 = np.exp(rng.uniform(np.log(1e-9), np.log(np.pi / 4), n))
    l = np.exp(rng.uniform(np.log(1.0), np.log(1e5), n))
    ratio[0], gamma0[0], gamma0[1] = 0.2, np.pi / 4, 1e-9
    return [np.asarray(a, dtype) for a in (ratio * l, l, gamma0)]


@pytest.mark.parametrize(
    "params",
    [friction.GREASE_A, friction.GREASE_A.replace(mu_slp=0.01, lam=0.0)],  # C_d1 μ_slp < C_d2 too
)
def test_float32_gaf_within_1e_3_of_float64_down_to_gamma0_1e_9(float32_default, params):
    """Stroke model from the small unknowns (its three terms cancel at first order), printed model too."""
    from tripodjax import GAFInputs, sweep

    names = ("gaf_rms", "gaf_peak", "gaf_third_order")
    R, l, gamma0 = _log_uniform_layouts(200, seed=21, dtype=np.float32)
    for model in ("stroke", "printed"):
        gaf = GAFInputs(500.0, params, model)
        out32 = sweep(Layout(R, l, gamma0), n_theta=120, outputs=names, gaf=gaf)
        assert out32["gaf_rms"].dtype == np.float32
        with jax.enable_x64(True):
            # float32's roundings of the bounds: clipped onto them for float64 (a ~1e-7 change)
            R64, l64, g64 = (np.asarray(a, np.float64) for a in (R, l, gamma0))
            layouts64 = Layout(np.minimum(R64, 0.2 * l64), l64, np.minimum(g64, np.pi / 4))
            out64 = sweep(layouts64, n_theta=120, outputs=names, gaf=gaf)
        for name in names:
            error = np.abs(out32[name] / out64[name] - 1)
            assert error.max() < 1e-3, (model, name, float(error.max()))
        assert np.all(out64["gaf_rms"] > 0)


def test_stroke_gaf_vanishes_like_gamma0_squared():
    """GAF ∝ γ0² at small γ0 (the first order cancels between the rollers), in float32 as in float64."""
    for dtype in (np.float64, np.float32):
        rms = [
            float(
                friction.gaf_halfshaft(
                    Layout(*np.asarray([25.0, 500.0, g], dtype)), 500.0, model="stroke", n_theta=60
                ).rms
            )
            for g in (1e-8, 1e-7)
        ]
        assert rms[1] / rms[0] == pytest.approx(100.0, rel=1e-3), dtype


def test_seed_gaf_example_fits_the_printed_factor_with_a_diameter():
    """The seed's example (1000 N·m, μ_slp 0.04, λ 0.007: peak 386.4 N, RMS 344.9 N): the printed
    3.2.15 fits it at γ ≈ 21.8° only with R ≈ 57.7 mm, no tripod's pitch-circle radius (the
    catalogue's largest is below 40 mm) but a plausible diameter; the statics factor (the default)
    gives the same numbers with the radius R/2 ≈ 28.9 mm, beside the GI 720's 28.15 mm."""
    grid = np.arange(7200) * (2 * np.pi / 3 / 7200) + 1e-5  # one period, off the reversals

    def peak_rms(gamma, R, factor):
        g = np.asarray(friction.gaf(grid, gamma, 1000.0, R, PARAMS_EXAMPLE, factor=factor))
        return np.abs(g).max(), np.sqrt(np.mean(g**2))

    ratio = 386.4 / 344.9
    gamma = brentq(lambda g: np.divide(*peak_rms(g, 1.0, "printed")) - ratio, 0.2, 0.6, xtol=1e-12)
    R_printed = peak_rms(gamma, 1.0, "printed")[1] / 344.9
    assert math.degrees(gamma) == pytest.approx(21.8, abs=0.05)
    assert R_printed == pytest.approx(57.7, abs=0.05)
    for R, factor in ((R_printed, "printed"), (R_printed / 2, "statics")):
        peak, rms = peak_rms(gamma, R, factor)
        assert peak == pytest.approx(386.4, abs=0.05) and rms == pytest.approx(344.9, abs=0.05)
    radii = [size["R"] for table in (catalogue.GE, catalogue.GI) for size in table.values()]
    assert max(radii) < 40.0 < R_printed and min(radii) < R_printed / 2 < max(radii)


def test_the_gaf_needs_enough_angles_for_its_orders():
    """At 6 angles a turn the stroke model's GAF was 5e-12 N (623 N at 360), at 12 its third
    order the peak: at least 24 (8 a period), in one line."""
    layout = Layout(25.0, 500.0, math.radians(20.0))
    with pytest.raises(
        ValueError, match=re.escape("n_theta = 12 is not allowed for the GAF: at least 24")
    ):
        friction.gaf_halfshaft(layout, 1000.0, n_theta=12, model="stroke")
