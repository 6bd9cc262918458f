"""The halfshaft solve (seed §2.9) against an independent fsolve, identities and limits."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import reference

from tripodjax import Layout, halfshaft, seed_case, solve_halfshaft, solvers
from tripodjax.halfshaft import scaled_jacobian, scaled_residual
from tripodjax.results import RESULTS
from tripodjax.solvers import Analytic, Newton, SolverError

THETA = np.linspace(0.0, 2 * np.pi, 97)


def unscaled_pair(R, l, gamma0, theta, delta, gamma):
    h = -l * np.sin(gamma0) - 0.5 * R * (1 - np.cos(gamma0))
    e = 0.5 * R * (1 - np.cos(gamma)) / np.cos(gamma)
    psi = theta - delta
    f1 = h * np.sin(delta) - e * np.sin(3 * psi)
    f2 = h * np.cos(delta) + l * np.sin(gamma) + e * np.cos(gamma) * np.cos(3 * psi)
    return np.stack([f1, f2], -1)


def test_scaled_residual_is_the_printed_pair_divided_by_2l_sin_half_gamma0():
    rng = np.random.default_rng(1)
    for _ in range(20):
        R, l, g0 = rng.uniform(15, 45), rng.uniform(250, 900), rng.uniform(0.05, 0.78)
        theta, delta, v = (
            rng.uniform(0, 2 * np.pi),
            rng.uniform(-0.02, 0.02),
            rng.uniform(-0.05, 0.05),
        )
        scaled = np.asarray(scaled_residual(R, l, g0, theta, jnp.array([delta, v])))
        printed = unscaled_pair(R, l, g0, theta, delta, g0 * (1 + v)) / (2 * l * np.sin(g0 / 2))
        np.testing.assert_allclose(scaled, printed, rtol=1e-9, atol=1e-13)


@pytest.mark.parametrize("gamma0", [0.0, 1e-8, 0.35, 0.785])
def test_closed_form_jacobian_matches_autodiff(gamma0):
    rng = np.random.default_rng(2)
    for _ in range(10):
        theta, x = rng.uniform(0, 2 * np.pi), jnp.asarray(rng.uniform(-0.03, 0.03, 2))
        closed = scaled_jacobian(40.0, 200.0, gamma0, theta, x)
        auto = jax.jacfwd(lambda y, theta=theta: scaled_residual(40.0, 200.0, gamma0, theta, y))(x)
        np.testing.assert_allclose(closed, auto, rtol=1e-12, atol=1e-15)


def assert_matches_fsolve(layout, theta=THETA, atol=1e-12):
    sol = solve_halfshaft(layout, jnp.asarray(theta))
    assert bool(jnp.all(sol.converged))
    psi, gamma = reference.solve(theta, layout.R, layout.l, layout.gamma0)
    np.testing.assert_allclose(sol.psi, psi, rtol=0, atol=atol)
    np.testing.assert_allclose(sol.gamma, gamma, rtol=0, atol=atol)


@pytest.mark.parametrize(
    "code", ["N", "L3", "L4", "L7", "R2", "R3", "R4", "g5", "g10", "g15", "g25"]
)
def test_table_2_1_pointwise_against_fsolve(code):
    assert_matches_fsolve(seed_case(code))


def test_random_layouts_pointwise_against_fsolve():
    rng = np.random.default_rng(3)
    for _ in range(12):
        layout = Layout.from_degrees(rng.uniform(15, 45), rng.uniform(250, 900), rng.uniform(1, 40))
        assert_matches_fsolve(layout, theta=THETA[::4])


@pytest.mark.parametrize(
    "layout", [Layout.from_degrees(25.0, 500.0, 45.0), Layout.from_degrees(40.0, 200.0, 45.0)]
)
def test_extremes_45_degrees_and_R_over_l_0_2(layout):
    assert_matches_fsolve(layout)


def test_identities_period_zeros_and_symmetry():
    layout = seed_case("N")
    theta = np.linspace(0, 2 * np.pi / 3, 41)
    base = solve_halfshaft(layout, theta)
    shifted = solve_halfshaft(layout, theta + 2 * np.pi / 3)
    np.testing.assert_allclose(shifted.delta, base.delta, atol=1e-14)  # period 2π/3
    np.testing.assert_allclose(shifted.gamma, base.gamma, atol=1e-14)
    mirrored = solve_halfshaft(layout, -theta)
    np.testing.assert_allclose(mirrored.delta, -base.delta, atol=1e-14)  # Δ odd in θ
    zeros = solve_halfshaft(layout, np.arange(7) * np.pi / 3)
    np.testing.assert_allclose(zeros.delta, 0.0, atol=1e-14)  # accuracy points θ = kπ/3 (2.8.10)
    start = solve_halfshaft(layout, 0.0)
    assert float(start.psi) == 0.0 and float(start.gamma) == pytest.approx(layout.gamma0, abs=1e-15)


def test_gamma0_zero_is_homokinetic_with_finite_derivatives():
    layout = Layout(25.0, 500.0, 0.0)
    sol = solve_halfshaft(layout, THETA)
    assert bool(jnp.all(sol.converged))
    np.testing.assert_allclose(sol.psi, THETA, rtol=0, atol=1e-12)
    np.testing.assert_allclose(sol.gamma, 0.0, rtol=0, atol=1e-12)

    def delta_at(lay):
        return jnp.sum(solve_halfshaft(lay, jnp.asarray(THETA)).delta)

    grads = jax.grad(delta_at)(layout)
    assert all(np.isfinite(g) for g in jax.tree_util.tree_leaves(grads))
    # dγ/dγ0 = 1 at γ0 = 0 (γ ≈ γ0 + O(γ0²)).
    dgamma = jax.grad(lambda g0: solve_halfshaft(Layout(25.0, 500.0, g0), 0.7).gamma)(0.0)
    assert float(dgamma) == pytest.approx(1.0, abs=1e-12)


def test_v_is_the_scaled_gamma_ripple_and_vanishes_like_gamma0():
    """v = (γ − γ0)/γ0, solved beside Δ: γ − γ0 = O(γ0²), so v/γ0 has a finite limit as
    γ0 → 0 (equal at 1e-6 and 1e-3 to the first order of γ0) and v = 0 at γ0 = 0."""
    sol = solve_halfshaft(seed_case("N"), THETA)
    np.testing.assert_allclose(sol.v * seed_case("N").gamma0, sol.delta_gamma, rtol=1e-15)
    slopes = [solve_halfshaft(Layout(25.0, 500.0, g), THETA).v / g for g in (1e-6, 1e-3)]
    assert float(jnp.max(jnp.abs(slopes[0]))) > 1e-3
    np.testing.assert_allclose(slopes[1], slopes[0], rtol=1e-3, atol=1e-9)
    np.testing.assert_array_equal(solve_halfshaft(Layout(25.0, 500.0, 0.0), THETA).v, 0.0)


def test_tiny_gamma0_converges_in_float32_and_float64():
    for dtype in (jnp.float32, jnp.float64):
        layout = Layout(
            jnp.asarray(25.0, dtype), jnp.asarray(500.0, dtype), jnp.asarray(1e-8, dtype)
        )
        sol = solve_halfshaft(layout, jnp.asarray(THETA, dtype))
        assert sol.psi.dtype == dtype
        assert bool(jnp.all(sol.converged)) and bool(jnp.all(jnp.isfinite(sol.psi)))
        # Δ ≈ −(e/|h|) sin 3θ with e/|h| ≈ R γ0 / (4 l)
        np.testing.assert_allclose(
            sol.delta, -25.0e-8 / 2000 * np.sin(3 * THETA), rtol=0, atol=1e-15
        )


def test_non_convergence_is_reported_per_point():
    sol = solve_halfshaft(seed_case("g25"), np.array([0.0, 0.3, 0.5]), Newton(max_steps=1))
    # θ = 0 is solved exactly by the first step; the others need more than one.
    np.testing.assert_array_equal(sol.converged, [True, False, False])
    np.testing.assert_array_equal(
        sol.result, [RESULTS.successful, RESULTS.max_steps_reached, RESULTS.max_steps_reached]
    )
    assert np.all(np.asarray(sol.iterations) == 1)
    assert np.all(np.isfinite(sol.residual)) and float(jnp.max(jnp.abs(sol.residual))) > 1e-12
    with pytest.raises(SolverError, match=r"point \[1\] at θ = 0.3 rad: max_steps_reached"):
        solve_halfshaft(
            seed_case("g25"), np.array([0.0, 0.3, 0.5]), Newton(max_steps=1), throw=True
        )


@pytest.mark.parametrize("solver", ["newton", "analytic", "closed_form"])
def test_nonfinite_input_gives_nan_and_a_nonfinite_code(solver):
    theta = np.array([0.2, np.nan, np.inf, 0.4])
    sol = solve_halfshaft(seed_case("N"), theta, solver)
    np.testing.assert_array_equal(
        sol.result, [RESULTS.successful, RESULTS.nonfinite, RESULTS.nonfinite, RESULTS.successful]
    )
    assert (
        np.isnan(sol.delta[1])
        and np.isnan(sol.psi[2])
        and np.isfinite(np.asarray(sol.delta)[[0, 3]]).all()
    )
    assert not bool(sol.converged[1])
    # Inside jit too, and for a NaN layout field: NaN everywhere, never a plausible number.
    jitted = jax.jit(lambda g0: solve_halfshaft(Layout(25.0, 500.0, g0), THETA, solver))(jnp.nan)
    assert np.isnan(jitted.gamma).all() and (np.asarray(jitted.result) == RESULTS.nonfinite).all()
    with pytest.raises(SolverError, match=r"point \[1\] at θ = nan rad: nonfinite"):
        solve_halfshaft(seed_case("N"), theta, solver, throw=True)


@pytest.mark.parametrize("solver", ["newton", "analytic"])
def test_a_traced_layout_outside_the_domain_is_outside_validity(solver):
    """Layout refuses a concrete field outside its domain; a traced one (inside jit) cannot be
    refused, and its solve says so at every point: the same rule (and ulps) as Layout's."""
    R = np.array([25.0, 250.0, 0.0, -25.0, 25.0, 25.0, 100.0, 25.0, 25.0])
    gamma0 = np.array([0.3, 0.3, 0.3, 0.3, 1.0, -0.1, 0.3, np.pi / 4, np.nan])
    for dtype in (np.float64, np.float32):

        def code(R, g0, theta):
            return solve_halfshaft(Layout(R, 500.0, g0), theta, solver).result

        at = (R.astype(dtype), gamma0.astype(dtype), THETA.astype(dtype))
        codes = jax.jit(jax.vmap(code, in_axes=(0, 0, None)))(*at)
        expected = [0, 4, 4, 4, 4, 4, 0, 0, 3]  # R/l = 0.2 and γ0 = π/4 (rounded) are inside
        np.testing.assert_array_equal(np.asarray(codes), np.repeat([expected], THETA.size, 0).T)


def test_newton_iterations_stay_few_over_the_domain():
    rng = np.random.default_rng(8)
    ratio, g0 = rng.uniform(0, 0.2, 60), rng.uniform(0, np.pi / 4, 60)
    ratio[0], g0[0] = 0.2, np.pi / 4
    layout = Layout(100.0 * ratio[:, None], 100.0, g0[:, None])
    for dtype in (np.float64, np.float32):
        theta = np.linspace(0, 2 * np.pi / 3, 40, dtype=dtype)
        lay = Layout(*(np.asarray(a, dtype) for a in (layout.R, layout.l, layout.gamma0)))
        sol = solve_halfshaft(lay, theta)
        assert (np.asarray(sol.result) == RESULTS.successful).all()
        # Five polynomial steps, the last one the stopping test, settle every point.
        assert int(np.max(sol.iterations)) == halfshaft.POLYNOMIAL_STEPS + 1


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_polynomial_stage_changes_no_digit_and_falls_back_outside_its_range(dtype):
    """The answer equals Newton with the exact sines alone (to roundoff) inside the domain, and
    a point whose small angles leave the polynomials' range (R/l = 0.2, γ0 = 70°: outside the
    layout domain's 45°, where the larger of |Δ/2| and |γ − γ0|/2 reaches 0.42) restarts from the
    closed form and still solves the exact pair, with the exact Newton's own steps. (Not
    R/l ≈ 0.5 at 45°: there Newton wanders near a singular Jacobian before it settles, and
    in float32 whether it meets the tolerance depends on how the constants were rounded.)"""
    rng = np.random.default_rng(3)
    R = np.concatenate([100.0 * rng.uniform(0, 0.2, 30), [20.0]]).astype(dtype)[:, None]
    g0 = np.concatenate([rng.uniform(0, np.pi / 4, 30), [np.radians(70.0)]]).astype(dtype)[:, None]
    l = np.asarray(100.0, dtype)
    theta = np.linspace(0, 2 * np.pi / 3, 24, dtype=dtype)[None, :]
    rtol = halfshaft.default_rtol(dtype)
    delta, v, steps, result = halfshaft._newton(R, l, g0, theta, rtol, 24)
    consts = halfshaft.layout_constants(jnp, R, l, g0, theta)
    guess = jnp.broadcast_arrays(*halfshaft.analytic_unknowns(jnp, consts, theta))
    guess = jax.lax.complex(*guess)
    scale = halfshaft.first_order_amplitude(consts)
    zero = jnp.zeros(guess.shape, jnp.int32)
    exact, exact_steps, done, _ = halfshaft._iterate(consts, scale, rtol, guess, zero, 24, zero > 0)
    assert bool(jnp.all(done)) and (np.asarray(result) == RESULTS.successful).all()
    far = jnp.maximum(jnp.abs(0.5 * delta[-1]), jnp.abs(consts["half0"][-1] * v[-1]))
    assert float(jnp.max(far)) > halfshaft.POLYNOMIAL_LIMIT
    out = np.asarray(far > halfshaft.POLYNOMIAL_LIMIT)  # restarted: the exact Newton's own steps
    np.testing.assert_array_equal(np.asarray(steps[-1])[out], np.asarray(exact_steps[-1])[out])
    # Both stop once a step is below rtol · (max(|Δ|, |v|) + scale): they agree within that.
    exact = (jnp.real(exact), jnp.imag(exact))
    tolerance = rtol * (max(float(jnp.max(jnp.abs(e))) for e in exact) + float(jnp.max(scale)))
    for ours, theirs in zip((delta, v), exact, strict=True):
        np.testing.assert_allclose(ours, theirs, rtol=0, atol=tolerance)


@pytest.mark.parametrize(
    "make, error, message",
    [
        (lambda: Newton(rtol=-1.0), ValueError, "rtol = -1.0 is outside the allowed range"),
        (lambda: Newton(rtol=0.0), ValueError, "0 < rtol < 1"),
        (lambda: Newton(rtol="tight"), TypeError, "rtol = 'tight' is not allowed"),
        (lambda: Newton(max_steps=-5), ValueError, "max_steps = -5 is outside the allowed range"),
        (lambda: Newton(max_steps=0), ValueError, "1 ≤ max_steps ≤ 1000"),
        (lambda: Newton(max_steps=2.5), TypeError, "max_steps = 2.5 is not allowed"),
        (lambda: Newton(max_steps=True), TypeError, "max_steps = True is not allowed"),
        (lambda: Analytic(corrections=-1), ValueError, "corrections = -1 is outside"),
        (lambda: Analytic(validity=0.0), ValueError, "validity = 0.0 is outside"),
        (
            lambda: Analytic(nodes=7),
            ValueError,
            "nodes = 7 is not allowed; allowed: None or an even",
        ),
        (lambda: Analytic(nodes=2), ValueError, "nodes = 2 is outside the allowed range"),
        (lambda: Analytic(nodes=62), ValueError, "4 ≤ nodes ≤ 60"),
        (lambda: Analytic(nodes=8.0), TypeError, "nodes = 8.0 is not allowed"),
        (lambda: solvers.resolve("exact"), ValueError, "solver = 'exact' is not allowed"),
        (lambda: solvers.resolve(3), TypeError, "solver = 3 is not allowed"),
        (
            lambda: solve_halfshaft(Layout(np.array([25.0, 26.0]), 500.0, 0.3), np.zeros(3)),
            ValueError,
            "the arguments have shapes layout.R (2,), theta (3,); allowed: numbers, or arrays",
        ),
    ],
)
def test_solver_options_are_validated_at_construction(make, error, message):
    with pytest.raises(error) as info:
        make()
    assert message in str(info.value)


def test_solver_objects_are_hashable_and_shorthands_resolve_to_defaults():
    assert solvers.resolve("newton") == Newton() and hash(Newton(rtol=1e-10)) == hash(
        Newton(rtol=1e-10)
    )
    assert solvers.resolve("analytic") == Analytic()
    assert solvers.resolve("closed_form") == Analytic(
        corrections=0, validity=solvers.ClosedForm().validity, nodes=8
    )
    a = solve_halfshaft(seed_case("N"), THETA, Newton(rtol=1e-10, max_steps=30))
    b = solve_halfshaft(seed_case("N"), THETA)
    np.testing.assert_allclose(a.delta, b.delta, rtol=0, atol=1e-15)


def test_converged_residual_is_at_rounding_level_and_steps_are_few():
    sol = solve_halfshaft(seed_case("R4"), THETA)
    assert float(jnp.max(jnp.abs(sol.residual))) < 1e-15
    assert int(jnp.max(sol.iterations)) <= 6


def test_second_theta_derivative_by_implicit_differentiation_matches_differences():
    layout = seed_case("N")
    theta0, step = 0.4, 1e-4

    def dpsi(t):
        return jax.jvp(lambda u: solve_halfshaft(layout, u).psi, (t,), (1.0,))[1]

    d2 = jax.jvp(dpsi, (theta0,), (1.0,))[1]
    psi = [
        reference.solve(np.array([theta0 + k * step]), layout.R, layout.l, layout.gamma0)[0][0]
        for k in (-1, 0, 1)
    ]
    fd2 = (psi[2] - 2 * psi[1] + psi[0]) / step**2
    assert float(d2) == pytest.approx(fd2, rel=1e-4)
    assert float(dpsi(theta0)) == pytest.approx((psi[2] - psi[0]) / (2 * step), rel=1e-9)


def test_parameter_derivatives_match_central_differences():
    theta = 0.45
    base = dict(R=30.0, l=450.0, gamma0=0.3)

    def delta(**kw):
        return solve_halfshaft(Layout(**kw), theta).delta

    grads = jax.grad(lambda lay: delta(R=lay.R, l=lay.l, gamma0=lay.gamma0))(Layout(**base))
    for name in ("R", "l", "gamma0"):
        step = 1e-6 * base[name]
        plus, minus = dict(base), dict(base)
        plus[name] += step
        minus[name] -= step
        fd = (float(delta(**plus)) - float(delta(**minus))) / (2 * step)
        assert float(getattr(grads, name)) == pytest.approx(fd, rel=1e-6)


def test_float32_keeps_the_small_unknowns_accurate(float32_default):
    layout = seed_case("N")
    sol32 = solve_halfshaft(layout, jnp.asarray(THETA, jnp.float32))
    assert sol32.delta.dtype == jnp.float32
    with jax.enable_x64(True):
        sol64 = solve_halfshaft(layout, jnp.asarray(THETA, jnp.float64))
        delta64 = np.asarray(sol64.delta)
    amplitude = np.abs(delta64).max()
    # Δ is solved for directly: its float32 error is a few ε of Δ's own size,
    # not ε·θ as it would be from θ − ψ.
    assert np.abs(np.asarray(sol32.delta, np.float64) - delta64).max() < 2e-5 * amplitude


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_error_estimate_from_polynomial_sines_equals_the_exact_one(dtype):
    """Analytic's status comes from an estimate formed with the polynomial sines (no
    transcendental function): over the domain it is the exact-sine estimate to roundoff, and
    infinite (outside validity) where the small angles leave the polynomials' range."""
    rng = np.random.default_rng(5)
    R = (100.0 * rng.uniform(0, 0.2, 40)).astype(dtype)[:, None]
    g0 = rng.uniform(0, np.pi / 4, 40).astype(dtype)[:, None]
    R[0, 0], g0[0, 0] = 20.0, np.pi / 4  # the corner
    l = np.asarray(100.0, dtype)
    theta = np.linspace(0, 2 * np.pi / 3, 16, dtype=dtype)[None, :]
    delta, v = halfshaft._analytic(R, l, g0, theta, 1)  # errors of ~1e-6: a step to measure
    _, exact = halfshaft._diagnostics(R, l, g0, theta, delta, v)
    _, polynomial = halfshaft._diagnostics(R, l, g0, theta, delta, v, small_angles=True)
    # The estimate is a step relative to the amplitude: roundoff of the dtype in those units
    # (measured: 2.7 eps in float64, 3.9 eps in float32, estimates up to 8e-3 at the corner).
    assert float(jnp.max(exact)) > 1e-3
    np.testing.assert_allclose(polynomial, exact, rtol=0, atol=8 * np.finfo(dtype).eps)
    far = jnp.full_like(delta, 0.6)  # |Δ/2| = 0.3 > POLYNOMIAL_LIMIT
    _, outside = halfshaft._diagnostics(R, l, g0, theta, far, v, small_angles=True)
    assert bool(jnp.all(jnp.isinf(outside)))


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_half_angle_sines_are_the_sines_to_roundoff_within_their_limit(dtype):
    """The layout's sin and cos of γ0/2 are Taylor polynomials: equal to mpmath's to a few
    ulps for |γ0/2| ≤ HALF_ANGLE_LIMIT (γ0 up to 2 rad, the domain's 45° well inside), their
    derivatives each other's, and NaN beyond the limit, never an inaccurate number."""
    mpmath = pytest.importorskip("mpmath")
    x = np.concatenate([np.linspace(-1.0, 1.0, 401), [np.pi / 8, 1e-30, 0.0]]).astype(dtype)
    sin, cos = (np.asarray(a) for a in halfshaft.half_angle_sincos(jnp, jnp.asarray(x)))
    exact_sin = np.array([float(mpmath.sin(mpmath.mpf(float(t)))) for t in x])
    exact_cos = np.array([float(mpmath.cos(mpmath.mpf(float(t)))) for t in x])
    eps = np.finfo(dtype).eps
    np.testing.assert_allclose(sin, exact_sin, rtol=4 * eps, atol=0)
    np.testing.assert_allclose(cos, exact_cos, rtol=4 * eps, atol=0)
    slope = jax.vmap(jax.grad(lambda t: halfshaft.half_angle_sincos(jnp, t)[0]))(jnp.asarray(x))
    np.testing.assert_allclose(slope, exact_cos, rtol=8 * eps, atol=0)
    limit = halfshaft.HALF_ANGLE_LIMIT
    beyond = jnp.asarray([np.nextafter(dtype(limit), dtype(2)), -1.5, np.inf, np.nan], dtype)
    assert np.all(np.isnan(np.asarray(halfshaft.half_angle_sincos(jnp, beyond))))
