"""Numerics at the edges of the domain (issue #12): small values, float32, γ0 = 0, status, NaN.

Oracles: float64 against a 50-digit mpmath solve of the printed pair 2.9.1–2.9.2
(test-only dependency), float32 against float64, and the first-order limits
(irregularity → 1.5 (R/l) γ0, delta_pp → (R/(2l)) γ0, axial stroke → 2 R γ0).
"""

import jax
import jax.numpy as jnp
import mpmath
import numpy as np
import pytest

from tripodjax import Layout, friction, kinematic_metrics, sweep
from tripodjax._compile import latency_bound_jit
from tripodjax.kinematics import metrics_from, period_grid, revolution
from tripodjax.results import RESULTS
from tripodjax.solvers import Analytic

SMALL_DIFFERENCES = ("delta_pp", "irregularity", "gamma_pp", "ecc_max", "roller_stroke")
N_THETA = 36


def log_uniform_layouts(n, seed, low_gamma0=1e-6, dtype=np.float64):
    rng = np.random.default_rng(seed)
    ratio = np.exp(rng.uniform(np.log(1e-5), np.log(0.2), n))
    gamma0 = np.exp(rng.uniform(np.log(low_gamma0), np.log(np.pi / 4), n))
    l = np.exp(rng.uniform(np.log(1.0), np.log(1e5), n))
    ratio[0], gamma0[0] = 0.2, np.pi / 4  # the corner (float32's rounding of it is inside)
    return Layout(*(np.asarray(a, dtype) for a in (ratio * l, l, gamma0)))


def test_float32_metrics_within_1e_3_of_float64_over_the_log_uniform_edge_set(float32_default):
    names = (*SMALL_DIFFERENCES, "roller_axial_stroke", "result")
    layouts = log_uniform_layouts(300, seed=5, dtype=np.float32)
    out32 = sweep(layouts, n_theta=N_THETA, outputs=names)
    assert out32["irregularity"].dtype == np.float32
    assert out32.result_counts["successful"] == 300
    with jax.enable_x64(True):
        R, l, gamma0 = (np.asarray(getattr(layouts, f), np.float64) for f in ("R", "l", "gamma0"))
        # float32's roundings of the bounds (the corner) lie a few float32 ulps above them,
        # which float64 does not allow: clip the reference onto the bounds (a ~1e-7 change).
        layouts64 = Layout(np.minimum(R, 0.2 * l), l, np.minimum(gamma0, np.pi / 4))
        out64 = sweep(layouts64, n_theta=N_THETA, outputs=names)
    for name in names[:-1]:
        error = np.abs(out32[name] / out64[name] - 1)
        assert error.max() < 1e-3, (name, error.max())


def _mp_solution(R, l, gamma0, theta):
    """ψ, γ, dψ/dθ at θ by a 50-digit Newton on the printed pair and the implicit function theorem."""
    R, l, g0, t = (mpmath.mpf(float(x)) for x in (R, l, gamma0, theta))
    h = -l * mpmath.sin(g0) - R / 2 * (1 - mpmath.cos(g0))

    def pair(psi, gamma, t=t):
        e = R / 2 * (1 - mpmath.cos(gamma)) / mpmath.cos(gamma)
        return (
            h * mpmath.sin(t - psi) - e * mpmath.sin(3 * psi),
            h * mpmath.cos(t - psi)
            + l * mpmath.sin(gamma)
            + e * mpmath.cos(gamma) * mpmath.cos(3 * psi),
        )

    psi, gamma = mpmath.findroot(pair, (t, g0), tol=mpmath.mpf(10) ** -45)
    J = mpmath.matrix(2, 2)
    for j, f in enumerate((lambda p: pair(p, gamma), lambda g: pair(psi, g))):
        column = mpmath.diff(lambda x, f=f: mpmath.matrix(f(x)), psi if j == 0 else gamma)
        J[0, j], J[1, j] = column[0], column[1]
    dF = mpmath.diff(lambda x: mpmath.matrix(pair(psi, gamma, x)), t)
    dx = -(J**-1) * dF
    return psi, gamma, dx[0]


@pytest.mark.parametrize(
    "R, l, gamma0",
    [(25.0, 500.0, 0.349), (2e-3, 200.0, 1e-7), (40.0, 200.0, np.pi / 4), (0.5, 1e4, 0.05)],
)
def test_float64_metrics_to_roundoff_against_a_50_digit_solve(R, l, gamma0):
    mpmath.mp.dps = 50
    theta = np.asarray(period_grid(N_THETA, jnp.float64))
    rows = [_mp_solution(R, l, gamma0, t) for t in theta]
    delta = [mpmath.mpf(float(t)) - p for t, (p, _, _) in zip(theta, rows, strict=True)]
    expected = {
        "delta_pp": max(delta) - min(delta),
        "irregularity": max(r[2] for r in rows) - min(r[2] for r in rows),
        "gamma_pp": max(r[1] for r in rows) - min(r[1] for r in rows),
    }
    ours = kinematic_metrics(Layout(R, l, gamma0), n_theta=N_THETA)
    assert int(ours.result) == RESULTS.successful
    for name, value in expected.items():
        assert float(getattr(ours, name)) == pytest.approx(float(value), rel=1e-12), name


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_tiny_values_follow_the_first_order_limits(dtype):
    with jax.enable_x64(dtype == np.float64):
        for ratio, gamma0 in ((1e-5, 1e-6), (0.1, 1e-6), (0.2, 1e-4), (1e-3, 1e-3)):
            layout = Layout(*(np.asarray(x, dtype) for x in (ratio * 300.0, 300.0, gamma0)))
            m = kinematic_metrics(layout, n_theta=N_THETA)
            rel = 5e-4 + 2 * ratio * gamma0 + gamma0
            assert float(m.irregularity) == pytest.approx(1.5 * ratio * gamma0, rel=rel)
            assert float(m.delta_pp) == pytest.approx(0.5 * ratio * gamma0, rel=rel)
            assert float(m.roller_axial_stroke) == pytest.approx(
                2 * ratio * 300.0 * gamma0, rel=rel
            )


@pytest.mark.parametrize("solver", ["newton", "analytic"])
@pytest.mark.parametrize("ratio", [0.2])
def test_grad_at_gamma0_zero_is_the_one_sided_derivative(solver, ratio):
    l = 400.0
    expected = {
        "irregularity": 1.5 * ratio,
        "delta_pp": 0.5 * ratio,
        "roller_axial_stroke": 2 * ratio * l,
        "gamma_pp": 0.0,
        "ecc_max": 0.0,
        "roller_stroke": 0.0,
    }

    def metrics(g0):
        layout = Layout(ratio * l, l, g0)
        sol, rates = revolution(layout, N_THETA, solver, with_rates=True)
        return metrics_from(layout, sol, rates, tuple(expected))

    # One compiled program each (op by op, every primitive of the solve and its transpose
    # compiles alone: 37 s), compiled for latency: the same arithmetic, to roundoff.
    grads = latency_bound_jit(jax.jacrev(metrics))(0.0)  # reverse mode, as jax.grad of each
    step = 1e-7
    at_step = latency_bound_jit(metrics)(step)  # the values at γ0 = 0 are 0
    for name, slope in expected.items():
        grad, forward = float(grads[name]), float(at_step[name]) / step
        assert grad == pytest.approx(slope, rel=1e-12, abs=1e-300), name
        if slope:
            assert grad == pytest.approx(forward, rel=1e-5), name
        else:  # the metric grows like γ0²: its forward difference is O(step)
            assert abs(forward) < 10 * l * step, name
    public = jax.grad(lambda g0: kinematic_metrics(Layout(ratio * l, l, g0), 12).irregularity)
    assert float(public(0.0)) == pytest.approx(1.5 * ratio, rel=1e-12)


def test_nan_torque_or_friction_constant_inside_jit_gives_nan_gaf():
    layout = Layout(25.0, 500.0, 0.35)

    @jax.jit
    def rms(torque, lam):
        return friction.gaf_halfshaft(layout, torque, friction.GREASE_A.replace(lam=lam), 60).rms

    assert np.isnan(float(rms(jnp.nan, 0.007))) and np.isnan(float(rms(500.0, jnp.nan)))
    assert np.isfinite(float(rms(500.0, 0.007)))
    result = jax.jit(lambda t: friction.gaf_halfshaft(layout, t, n_theta=60).result)(jnp.nan)
    assert int(result) == RESULTS.nonfinite


def test_analytic_error_estimate_bounds_its_error_over_the_domain():
    """The per-layout estimate is a sweep output and within ~1× of the metrics' worst error."""
    layouts = log_uniform_layouts(200, seed=9, low_gamma0=1e-3)
    names = ("delta_pp", "irregularity", "gamma_pp", "ecc_max", "error_estimate", "result")
    newton = sweep(layouts, n_theta=N_THETA, outputs=names)
    analytic = sweep(layouts, n_theta=N_THETA, solver="analytic", outputs=names)
    worst = np.max([np.abs(analytic[n] / newton[n] - 1) for n in names[:4]], axis=0)
    assert np.all(worst <= 1.5 * analytic["error_estimate"] + 1e-12)
    assert newton["error_estimate"].max() < 1e-12
    validity = float(np.quantile(analytic["error_estimate"], 0.9))  # flags a tenth of them
    strict = sweep(
        layouts, n_theta=N_THETA, solver=Analytic(validity=validity), outputs=("result",)
    )
    flagged = strict["result"] == RESULTS.outside_validity
    np.testing.assert_array_equal(flagged, analytic["error_estimate"] > validity)
    assert strict.result_counts["outside_validity"] == int(flagged.sum()) > 0
