"""The halfshaft: ψ(θ) and γ(θ) from the residual pair 2.9.1–2.9.3 (seed §2.9).

With the far end of the shaft fixed at the fixed joint's pivot H (g = 0), the
output angle ψ and the instantaneous articulation angle γ follow from

    F1 = h sin Δ − e(γ) sin 3ψ                  = 0      (2.9.1)
    F2 = h cos Δ + l sin γ + e(γ) cos γ cos 3ψ  = 0      (2.9.2)
    h  = −l sin γ0 − (R/2)(1 − cos γ0)                   (2.9.3)

with Δ = θ − ψ. The pair is degenerate at γ0 = 0 (h = e = 0, so F1 ≡ 0) and,
written in ψ and γ, loses digits in float32 because Δ and γ − γ0 are O(10⁻³).
The solver therefore works with the small unknowns

    Δ = θ − ψ   and   v = (γ − γ0)/γ0     (γ = γ0 (1 + v)),

and with the pair divided by 2 l sin(γ0/2), every difference of nearly equal
terms rewritten as a product of sines (see :func:`scaled_residual`). The
scaled Jacobian tends to diag(−1, 1) as γ0 → 0, so the solve stays regular at
γ0 = 0, where the solution is ψ = θ, γ = 0 exactly.

Derivatives of the solution (w.r.t. θ, R, l, γ0, any order) come from the
implicit function theorem through ``jax.lax.custom_root``; the Newton
iterations are never differentiated.
"""

import functools

import jax
import jax.numpy as jnp

from tripodjax._pytree import pytree_dataclass

DEFAULT_MAX_STEPS = 24
_RTOL_EPS_MULTIPLE = 32.0


def _sinc(x):
    """sin(x)/x, smooth (with exact derivatives) at x = 0."""
    return jnp.sinc(x / jnp.pi)


def _scaled_terms(R, l, gamma0, theta, x):
    """Shared intermediate quantities of the scaled residual and its Jacobian."""
    delta, v = x[..., 0], x[..., 1]
    half0 = 0.5 * gamma0  # γ0/2
    k = R / (2.0 * l)
    h_scaled = jnp.cos(half0) + k * jnp.sin(half0)  # −h / (2 l sin(γ0/2))
    half_gamma = half0 * (1.0 + v)  # γ/2
    gamma = 2.0 * half_gamma
    sinc0 = _sinc(half0)
    # rho = sin(γ/2)/sin(γ0/2), sigma = sin((γ−γ0)/2)/sin(γ0/2), both regular at γ0 = 0
    rho = (1.0 + v) * _sinc(half_gamma) / sinc0
    sigma = v * _sinc(half0 * v) / sinc0
    three_psi = 3.0 * (theta - delta)
    return dict(
        delta=delta, v=v, half0=half0, k=k, h_scaled=h_scaled, half_gamma=half_gamma,
        gamma=gamma, sinc0=sinc0, rho=rho, sigma=sigma, three_psi=three_psi,
        mid=half0 * (2.0 + v),  # (γ + γ0)/2
        q=jnp.sin(half_gamma) * rho,  # sin²(γ/2)/sin(γ0/2)
    )


def scaled_residual(R, l, gamma0, theta, x):
    """The pair 2.9.1–2.9.2 divided by 2 l sin(γ0/2), in x = (Δ, v). Dimensionless.

    With k = R/(2l), H = cos(γ0/2) + k sin(γ0/2) (so h = −2 l sin(γ0/2) H),
    q = sin²(γ/2)/sin(γ0/2), σ = sin((γ−γ0)/2)/sin(γ0/2), m = (γ+γ0)/2:

        g1 = −H sin Δ − k q sin 3ψ / cos γ                         (2.9.1)
        g2 = 2H sin²(Δ/2) + σ (cos m + k sin m) − 2k q sin²(3ψ/2)   (2.9.2 − 2.9.3)

    g2 is F2 after subtracting the θ = 0 identity 2.9.3 term by term, so no
    two large terms cancel. Returns an array of shape (..., 2).
    """
    t = _scaled_terms(R, l, gamma0, theta, x)
    g1 = -t["h_scaled"] * jnp.sin(t["delta"]) - t["k"] * t["q"] * jnp.sin(t["three_psi"]) / jnp.cos(
        t["gamma"]
    )
    g2 = (
        2.0 * t["h_scaled"] * jnp.sin(0.5 * t["delta"]) ** 2
        + t["sigma"] * (jnp.cos(t["mid"]) + t["k"] * jnp.sin(t["mid"]))
        - 2.0 * t["k"] * t["q"] * jnp.sin(0.5 * t["three_psi"]) ** 2
    )
    return jnp.stack([g1, g2], axis=-1)


def scaled_jacobian(R, l, gamma0, theta, x):
    """Closed-form Jacobian ∂(g1, g2)/∂(Δ, v) of :func:`scaled_residual`, (..., 2, 2)."""
    t = _scaled_terms(R, l, gamma0, theta, x)
    k, q, H, half0 = t["k"], t["q"], t["h_scaled"], t["half0"]
    s3, c3 = jnp.sin(t["three_psi"]), jnp.cos(t["three_psi"])
    cg, sg = jnp.cos(t["gamma"]), jnp.sin(t["gamma"])
    dq_dv = 2.0 * half0 * t["rho"] * jnp.cos(t["half_gamma"])
    dsigma_dv = jnp.cos(half0 * t["v"]) / t["sinc0"]
    mid = t["mid"]
    j11 = -H * jnp.cos(t["delta"]) + 3.0 * k * q * c3 / cg
    j12 = -k * s3 * (dq_dv / cg + q * 2.0 * half0 * sg / cg**2)
    j21 = H * jnp.sin(t["delta"]) + 3.0 * k * q * s3
    j22 = (
        dsigma_dv * (jnp.cos(mid) + k * jnp.sin(mid))
        + t["sigma"] * half0 * (-jnp.sin(mid) + k * jnp.cos(mid))
        - 2.0 * k * jnp.sin(0.5 * t["three_psi"]) ** 2 * dq_dv
    )
    return jnp.stack([jnp.stack([j11, j12], -1), jnp.stack([j21, j22], -1)], -2)


def _solve_2x2(j, b):
    """Solve j @ x = b for one 2×2 system by Cramer's rule."""
    det = j[0, 0] * j[1, 1] - j[0, 1] * j[1, 0]
    return jnp.stack(
        [(b[0] * j[1, 1] - j[0, 1] * b[1]) / det, (j[0, 0] * b[1] - b[0] * j[1, 0]) / det]
    )


def default_rtol(dtype):
    """Default step tolerance of the Newton solve: 32 machine epsilons of ``dtype``."""
    return _RTOL_EPS_MULTIPLE * float(jnp.finfo(dtype).eps)


def _newton(R, l, gamma0, theta, rtol, max_steps):
    """Newton iterations from Δ = v = 0 for one θ; returns (x, (residual, steps, converged))."""
    dtype = jnp.result_type(theta)
    # Typical size of the unknowns: the first-order amplitude e(γ0)/|h| of Δ (§2.11),
    # which is also the floor of their rounding error; 0 at γ0 = 0 (exact zeros).
    half0 = 0.5 * gamma0
    k = R / (2.0 * l)
    scale = k * jnp.sin(half0) / (jnp.cos(gamma0) * (jnp.cos(half0) + k * jnp.sin(half0)))
    tiny = jnp.finfo(dtype).tiny

    def step(x):
        g = scaled_residual(R, l, gamma0, theta, x)
        return -_solve_2x2(scaled_jacobian(R, l, gamma0, theta, x), g)

    def cond(carry):
        _, n, done = carry
        return jnp.logical_and(n < max_steps, jnp.logical_not(done))

    def body(carry):
        x, n, _ = carry
        dx = step(x)
        x_new = x + dx
        small = jnp.max(jnp.abs(dx)) <= rtol * (jnp.max(jnp.abs(x_new)) + scale) + tiny
        return x_new, n + 1, small

    x0 = jnp.zeros(2, dtype)
    x, steps, done = jax.lax.while_loop(cond, body, (x0, jnp.int32(0), jnp.bool_(False)))
    residual = scaled_residual(R, l, gamma0, theta, x)
    converged = jnp.logical_and(done, jnp.all(jnp.isfinite(residual)))
    # custom_root gives its aux outputs float tangents: carry the counters as floats.
    return x, (residual, steps.astype(dtype), converged.astype(dtype))


def _tangent_solve(linear_map, rhs):
    """Solve the linearised residual (the IFT step) for a 2-vector right-hand side."""
    e0 = jnp.array([1.0, 0.0], rhs.dtype)
    e1 = jnp.array([0.0, 1.0], rhs.dtype)
    j = jnp.stack([linear_map(e0), linear_map(e1)], axis=1)
    return _solve_2x2(j, rhs)


def _solve_point(R, l, gamma0, theta, rtol, max_steps):
    """Solve one θ; x = (Δ, v) differentiable by the implicit function theorem."""
    residual = functools.partial(scaled_residual, R, l, gamma0, theta)
    solve = lambda f, x0: _newton(R, l, gamma0, theta, rtol, max_steps)  # noqa: E731
    x0 = jnp.zeros(2, jnp.result_type(theta))
    x, (res, steps, converged) = jax.lax.custom_root(
        residual, x0, solve, _tangent_solve, has_aux=True
    )
    return x, res, steps.astype(jnp.int32), converged > 0.5


@pytree_dataclass
class HalfshaftSolution:
    """Solution of the halfshaft equations at each input angle θ.

    Attributes:
        theta: input (pot) angle θ [rad].
        psi: output (spider) angle ψ [rad].
        gamma: instantaneous articulation angle γ [rad].
        delta: input–output difference Δ = θ − ψ [rad], solved for directly.
        delta_gamma: γ − γ0 [rad], solved for directly (as γ0 · v).
        residual: scaled residual pair (g1, g2) at the solution,
            dimensionless (the pair 2.9.1–2.9.2 divided by 2 l sin(γ0/2)),
            shape (..., 2). Diagnostic only: not differentiated.
        converged: True where the Newton step met the tolerance within the
            iteration cap and the residual is finite.
        iterations: Newton steps taken.
    """

    theta: jax.Array
    psi: jax.Array
    gamma: jax.Array
    delta: jax.Array
    delta_gamma: jax.Array
    residual: jax.Array
    converged: jax.Array
    iterations: jax.Array


@functools.partial(jax.jit, static_argnames=("max_steps",))
def solve_halfshaft(layout, theta, *, rtol=None, max_steps=DEFAULT_MAX_STEPS):
    """Solve ψ(θ) and γ(θ) of a halfshaft for every input angle in ``theta``.

    Args:
        layout: a :class:`~tripodjax.Layout` (scalar fields, or fields that
            broadcast against ``theta``).
        theta: input angles θ [rad], any shape.
        rtol: Newton stops when the largest step is at most
            ``rtol · (max(|Δ|, |v|) + e(γ0)/|h|)``, the last term being the
            first-order amplitude of Δ; default :func:`default_rtol` of the
            working dtype (32 ε: 7e-15 in float64, 4e-6 in float32; the last
            step is applied, so the error is far below that).
        max_steps: iteration cap; points that hit it report ``converged=False``.

    Returns:
        :class:`HalfshaftSolution` with arrays of the broadcast shape.

    Jit-compiled (``max_steps`` is static). Every float field is
    differentiable (``jax.jvp``/``jax.grad``, any order) w.r.t. θ and the layout; derivatives come from the implicit function
    theorem, not from the iterations. Works in float32 and float64: the
    working dtype is that of ``theta`` and the layout combined.
    """
    dtype = jnp.result_type(layout.R, layout.l, layout.gamma0, theta, 0.0)
    if not jnp.issubdtype(dtype, jnp.floating):
        dtype = jnp.result_type(float)
    R, l, gamma0, theta = (
        jnp.asarray(a, dtype) for a in (layout.R, layout.l, layout.gamma0, theta)
    )
    if rtol is None:
        rtol = default_rtol(dtype)
    solve = functools.partial(_solve_point, rtol=rtol, max_steps=max_steps)
    x, residual, steps, converged = jnp.vectorize(solve, signature="(),(),(),()->(2),(2),(),()")(
        R, l, gamma0, theta
    )
    delta = x[..., 0]
    delta_gamma = gamma0 * x[..., 1]
    theta = jnp.broadcast_to(theta, delta.shape)
    return HalfshaftSolution(
        theta=theta,
        psi=theta - delta,
        gamma=gamma0 + delta_gamma,
        delta=delta,
        delta_gamma=delta_gamma,
        residual=residual,
        converged=converged,
        iterations=steps,
    )
