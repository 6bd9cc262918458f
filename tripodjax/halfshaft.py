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
terms rewritten as a product of sines (see [`scaled_residual`][tripodjax.halfshaft.scaled_residual]). The
scaled Jacobian tends to diag(−1, 1) as γ0 → 0, so the solve stays regular at
γ0 = 0, where the solution is ψ = θ, γ = 0 exactly.

Two solver levels ([`tripodjax.solvers`][tripodjax.solvers]): [`Newton`][tripodjax.solvers.Newton]
iterates to the dtype's tolerance, and its derivatives (w.r.t. θ, R, l, γ0,
any order) come from the implicit function theorem, in a ``jax.custom_jvp``
rule that solves with the closed-form Jacobian at the solution (the iterations
are never differentiated); [`Analytic`][tripodjax.solvers.Analytic] is the closed
form plus a fixed number of Newton corrections in plain arithmetic,
differentiated as written, and over a revolution it solves at a few angles
of the period and interpolates
([`trigonometric_interpolation`][tripodjax.halfshaft.trigonometric_interpolation]).
Every point carries a result code ([`RESULTS`][tripodjax.results.RESULTS])
and an error estimate. The solve works
elementwise on arrays of any shape.
"""

import dataclasses
import functools
from types import ModuleType
from typing import Any, TypeAlias

import jax
import jax.numpy as jnp
import numpy as np
from jax.custom_derivatives import SymbolicZero
from jax.typing import ArrayLike, DTypeLike

from tripodjax import solvers
from tripodjax._checks import (
    as_array,
    check_broadcast,
    check_flag,
    check_integer,
    check_real,
    outside_layout_domain,
)
from tripodjax._compile import latency_bound_at_top_level
from tripodjax._pytree import pytree_dataclass
from tripodjax.layout import Layout, check_layout
from tripodjax.results import RESULTS, code_where, worst
from tripodjax.solvers import DEFAULT_MAX_STEPS, Analytic, Newton, SolverError  # noqa: F401

_RTOL_EPS_MULTIPLE = 32.0

XpArray: TypeAlias = Any
"""An array (or number) of the array module ``xp`` of the generic helpers: NumPy or jax.numpy."""


def _traced_once(*static_argnames):
    """Trace an ``xp``-generic kernel once per signature when ``xp`` is jax.numpy.

    Each call of the kernel inside a trace is then one call of a cached program (``jax.jit``;
    its derivatives and batches are cached with it) instead of its hundred jax.numpy calls
    traced again: the halfshaft's kernels are called at every level of a solve and of its
    derivatives, and retracing them was most of a first solve's trace time. With NumPy
    (``xp`` = numpy) the kernel runs as written.
    """

    def wrap(kernel):
        jitted = jax.jit(kernel, static_argnames=("xp", *static_argnames))

        @functools.wraps(kernel)
        def call(xp, *args, **kwargs):
            return (jitted if xp is jnp else kernel)(xp, *args, **kwargs)

        return call

    return wrap


def _sinc(xp, y, sin_y):
    """sin(y)/y from y and sin(y); a Taylor branch near 0 keeps values and derivatives exact."""
    small = xp.abs(y) < 1e-4
    safe = xp.where(small, 1.0, y)
    return xp.where(small, 1.0 - y * y / 6.0, sin_y / safe)


# |γ0|/2 up to which half_angle_sincos equals the sine and cosine to roundoff (γ0 ≤ 2 rad).
HALF_ANGLE_LIMIT = 1.0


@_traced_once()
def half_angle_sincos(xp: ModuleType, x: XpArray) -> tuple[XpArray, XpArray]:
    """(sin x, cos x) of the half articulation angle x = γ0/2 by Taylor polynomials to x¹⁹, x¹⁸.

    Exact to roundoff for |x| ≤ ``HALF_ANGLE_LIMIT`` (the first omitted terms, x²¹/21!
    and x²⁰/20!, are below 1e-18 there; the layout domain has x ≤ π/8), and NaN beyond,
    never an inaccurate number. Pure arithmetic: XLA fuses it into every consumer of a
    layout's constants, where a transcendental function would be evaluated again in each.
    """
    x2 = x * x
    sin, cos = 1.0, 1.0
    for n in range(18, 0, -2):  # Horner in x²: sin x = x(1 − x²/(2·3)(1 − x²/(4·5)(…)))
        sin = 1.0 - x2 / (n * (n + 1)) * sin
        cos = 1.0 - x2 / (n * (n - 1)) * cos
    outside = xp.abs(x) > HALF_ANGLE_LIMIT
    return xp.where(outside, xp.nan, x * sin), xp.where(outside, xp.nan, cos)


def _working_arrays(layout, theta):
    """R, l, γ0 and θ as arrays of the working dtype (that of the inputs combined), unbroadcast."""
    dtype = jnp.result_type(layout.R, layout.l, layout.gamma0, theta, 0.0)
    return tuple(jnp.asarray(a, dtype) for a in (layout.R, layout.l, layout.gamma0, theta))


@_traced_once()
def layout_constants(
    xp: ModuleType, R: XpArray, l: XpArray, gamma0: XpArray, theta: XpArray
) -> dict[str, XpArray]:
    """The loop invariants of the scaled pair for array module ``xp`` (jax.numpy or numpy)."""
    half0 = 0.5 * gamma0
    s0, c0 = half_angle_sincos(xp, half0)
    k = R / (2.0 * l)
    return dict(
        half0=half0,
        s0=s0,
        c0=c0,
        k=k,
        H=c0 + k * s0,  # −h / (2 l sin(γ0/2)), 2.9.3
        sinc0=_sinc(xp, half0, s0),
        inv_sinc0=1.0 / _sinc(xp, half0, s0),
        sin_g0=2.0 * s0 * c0,
        cos_g0=1.0 - 2.0 * s0**2,
        sin_15t=xp.sin(1.5 * theta),
        cos_15t=xp.cos(1.5 * theta),
    )


@_traced_once("small_angles", "row_scaled", "with_theta")
def scaled_system(
    xp: ModuleType,
    consts: dict[str, XpArray],
    delta: XpArray,
    v: XpArray,
    small_angles: bool = False,
    row_scaled: bool = False,
    with_theta: bool = False,
) -> Any:
    """Scaled residual (g1, g2) and closed-form Jacobian of the pair at (Δ, v).

    Every angle is built from two sine–cosine pairs, of Δ/2 and of
    (γ − γ0)/2 = (γ0/2)·v, and the loop invariants of [`layout_constants`][tripodjax.halfshaft.layout_constants]
    (angle-addition and triple-angle identities), so an iteration costs four
    transcendental functions. Returns ``(g1, g2), ((j11, j12), (j21, j22))``.

    With ``small_angles`` the sines and cosines of the small angles Δ/2 and
    (γ − γ0)/2 are Taylor polynomials ([`small_angle_sincos`][tripodjax.halfshaft.small_angle_sincos]), and an
    iteration is pure arithmetic (for |Δ|/2, |γ − γ0|/2 ≤ ``POLYNOMIAL_LIMIT`` only).
    With ``row_scaled`` the first row (g1, j11, j12) is returned multiplied by
    cos²γ: the same Newton step, with no division left but the determinant's
    (XLA then fuses a whole step into one loop). With ``with_theta`` a third pair
    follows: (∂g1/∂θ, ∂g2/∂θ) at fixed (Δ, v), in closed form (θ enters only through
    3ψ/2 = 3(θ − Δ)/2, so ∂(sin 3ψ)/∂θ = 3 cos 3ψ and ∂(sin²(3ψ/2))/∂θ = (3/2) sin 3ψ).
    """
    half0, s0, c0, k, H = (consts[n] for n in ("half0", "s0", "c0", "k", "H"))
    y = half0 * v
    inv_sinc0 = consts["inv_sinc0"]
    if small_angles:
        sd, cd = small_angle_sincos(0.5 * delta)
        sinc_y = _small_angle_sinc(y * y)
        sy, cy = small_angle_sincos(y)
    else:
        sd, cd = xp.sin(0.5 * delta), xp.cos(0.5 * delta)
        sy, cy = xp.sin(y), xp.cos(y)
        sinc_y = _sinc(xp, y, sy)
    sigma = v * sinc_y * inv_sinc0  # sin((γ−γ0)/2)/sin(γ0/2)
    rho = cy + c0 * sigma  # sin(γ/2)/sin(γ0/2)
    sin_half_gamma = s0 * cy + c0 * sy
    cos_half_gamma = c0 * cy - s0 * sy
    q = sin_half_gamma * rho  # sin²(γ/2)/sin(γ0/2)
    cos_g = 1.0 - 2.0 * sin_half_gamma**2
    sin_g = 2.0 * sin_half_gamma * cos_half_gamma
    sin_mid = consts["sin_g0"] * cy + consts["cos_g0"] * sy  # m = (γ + γ0)/2
    cos_mid = consts["cos_g0"] * cy - consts["sin_g0"] * sy
    s3d, c3d = sd * (3.0 - 4.0 * sd**2), cd * (4.0 * cd**2 - 3.0)  # sin, cos of 3Δ/2
    sp = consts["sin_15t"] * c3d - consts["cos_15t"] * s3d  # sin(3ψ/2), ψ = θ − Δ
    cp = consts["cos_15t"] * c3d + consts["sin_15t"] * s3d
    sin3, cos3 = 2.0 * sp * cp, 1.0 - 2.0 * sp**2
    sin_delta, cos_delta = 2.0 * sd * cd, 1.0 - 2.0 * sd**2
    kq = k * q
    dq_dv = 2.0 * half0 * rho * cos_half_gamma
    g2 = 2.0 * H * sd**2 + sigma * (cos_mid + k * sin_mid) - 2.0 * kq * sp**2
    j21 = H * sin_delta + 3.0 * kq * sin3
    j22 = (
        cy * inv_sinc0 * (cos_mid + k * sin_mid)
        + sigma * half0 * (k * cos_mid - sin_mid)
        - 2.0 * k * sp**2 * dq_dv
    )
    if row_scaled:  # row 1 × cos²γ
        cos2_g = cos_g * cos_g
        g1 = -H * sin_delta * cos2_g - kq * sin3 * cos_g
        j11 = -H * cos_delta * cos2_g + 3.0 * kq * cos3 * cos_g
        j12 = -k * sin3 * (dq_dv * cos_g + q * 2.0 * half0 * sin_g)
        g1_theta = -3.0 * kq * cos3 * cos_g
    else:
        kq_cg = kq / cos_g
        g1 = -H * sin_delta - kq_cg * sin3
        j11 = -H * cos_delta + 3.0 * kq_cg * cos3
        j12 = -k * sin3 / cos_g * (dq_dv + q * 2.0 * half0 * sin_g / cos_g)
        g1_theta = -3.0 * kq_cg * cos3
    if with_theta:
        return (g1, g2), ((j11, j12), (j21, j22)), (g1_theta, -3.0 * kq * sin3)
    return (g1, g2), ((j11, j12), (j21, j22))


def newton_step(
    residual: tuple[XpArray, XpArray],
    jacobian: tuple[tuple[XpArray, XpArray], tuple[XpArray, XpArray]],
) -> tuple[XpArray, XpArray]:
    """The Newton step −J⁻¹ g of a 2×2 system by Cramer's rule, elementwise."""
    (g1, g2), ((j11, j12), (j21, j22)) = residual, jacobian
    inv_det = 1.0 / (j11 * j22 - j12 * j21)
    return -(g1 * j22 - j12 * g2) * inv_det, -(j11 * g2 - g1 * j21) * inv_det


def first_order_amplitude(consts: dict[str, XpArray]) -> XpArray:
    """e(γ0)/|h|, the first-order amplitude of Δ (§2.11): the unknowns' typical size."""
    return consts["k"] * consts["s0"] / (consts["cos_g0"] * consts["H"])


def scaled_residual(
    R: ArrayLike, l: ArrayLike, gamma0: ArrayLike, theta: ArrayLike, x: jax.Array
) -> jax.Array:
    """The pair 2.9.1–2.9.2 divided by 2 l sin(γ0/2), in x = (Δ, v). Dimensionless, (..., 2).

    With k = R/(2l), H = cos(γ0/2) + k sin(γ0/2) (so h = −2 l sin(γ0/2) H),
    q = sin²(γ/2)/sin(γ0/2), σ = sin((γ−γ0)/2)/sin(γ0/2), m = (γ+γ0)/2:

        g1 = −H sin Δ − k q sin 3ψ / cos γ                         (2.9.1)
        g2 = 2H sin²(Δ/2) + σ (cos m + k sin m) − 2k q sin²(3ψ/2)   (2.9.2 − 2.9.3)

    g2 is F2 after subtracting the θ = 0 identity 2.9.3 term by term, so no
    two large terms cancel.
    """
    consts = layout_constants(jnp, R, l, gamma0, theta)
    (g1, g2), _ = scaled_system(jnp, consts, x[..., 0], x[..., 1])
    return jnp.stack([g1, g2], axis=-1)


def scaled_jacobian(
    R: ArrayLike, l: ArrayLike, gamma0: ArrayLike, theta: ArrayLike, x: jax.Array
) -> jax.Array:
    """Closed-form Jacobian ∂(g1, g2)/∂(Δ, v) of [`scaled_residual`][tripodjax.halfshaft.scaled_residual], (..., 2, 2)."""
    consts = layout_constants(jnp, R, l, gamma0, theta)
    _, ((j11, j12), (j21, j22)) = scaled_system(jnp, consts, x[..., 0], x[..., 1])
    return jnp.stack([jnp.stack([j11, j12], -1), jnp.stack([j21, j22], -1)], -2)


def default_rtol(dtype: DTypeLike) -> float:
    """Default step tolerance of the Newton solve: 32 machine epsilons of ``dtype``."""
    return _RTOL_EPS_MULTIPLE * float(jnp.finfo(dtype).eps)


def _small_angle_sinc(x2: XpArray) -> XpArray:
    """sin(x)/x from x² by its Taylor polynomial to x¹⁰ (exact to roundoff for |x| ≤ ``POLYNOMIAL_LIMIT``)."""
    return 1.0 - x2 / 6.0 * (
        1.0 - x2 / 20.0 * (1.0 - x2 / 42.0 * (1.0 - x2 / 72.0 * (1.0 - x2 / 110.0)))
    )


def small_angle_sincos(x: XpArray) -> tuple[XpArray, XpArray]:
    """(sin x, cos x) by Taylor polynomials to x¹¹ and x¹²: exact to roundoff for |x| ≤ 0.25.

    The first omitted terms, x¹³/13! and x¹⁴/14!, are below 1e-17 of sin x and cos x
    there (``POLYNOMIAL_LIMIT``), and so are those of the polynomials' derivatives. Used by
    the Newton steps and the corrections of [`Analytic`][tripodjax.solvers.Analytic], where
    the arguments are Δ/2 and (γ − γ0)/2 (|Δ| ≤ 0.06 over the layout domain).
    """
    x2 = x * x
    cos = 1.0 - x2 / 2.0 * (
        1.0
        - x2 / 12.0 * (1.0 - x2 / 30.0 * (1.0 - x2 / 56.0 * (1.0 - x2 / 90.0 * (1.0 - x2 / 132.0))))
    )
    return x * _small_angle_sinc(x2), cos


def analytic_unknowns(
    xp: ModuleType, consts: dict[str, XpArray], theta: XpArray
) -> tuple[XpArray, XpArray]:
    """(Δ, v) of the closed form of [`analytic_halfshaft`][tripodjax.halfshaft.analytic_halfshaft]; θ enters through sin 3θ, cos 3θ."""
    k, s0, c0, H, half0 = (consts[n] for n in ("k", "s0", "c0", "H", "half0"))
    sin3, cos3 = xp.sin(3.0 * theta), xp.cos(3.0 * theta)
    delta1 = -first_order_amplitude(consts) * sin3
    one_minus_cos3psi1 = (1.0 - cos3) - 3.0 * delta1 * sin3  # 2 sin²(3ψ1/2), first order in Δ1
    v = (
        consts["sinc0"]
        * (k * s0 * one_minus_cos3psi1 - 0.5 * H * delta1**2)
        / (consts["cos_g0"] + k * consts["sin_g0"])
    )
    q = s0 + 2.0 * half0 * c0 * v  # sin²(γ/2)/sin(γ0/2), first order in v
    cos_gamma = consts["cos_g0"] - 2.0 * half0 * consts["sin_g0"] * v
    z = -k / H * q * (sin3 - 3.0 * delta1 * cos3) / cos_gamma
    return z * (1.0 + z * z / 6.0), v


def _nonfinite_inputs(R, l, gamma0, theta):
    bad = ~(jnp.isfinite(R) & jnp.isfinite(l) & jnp.isfinite(gamma0) & jnp.isfinite(theta))
    return jnp.broadcast_to(
        bad, jnp.broadcast_shapes(*(jnp.shape(a) for a in (R, l, gamma0, theta)))
    )


# The polynomial sines of small_angle_sincos are exact to float64 roundoff for |x| ≤ 0.25 (the
# first omitted terms are below 1e-17 of the functions there); over the domain |Δ/2| ≤ 0.03.
POLYNOMIAL_LIMIT = 0.25
# Polynomial steps from the closed form before the tested one; with 4 the fifth step confirms
# every point of the domain (measured).
POLYNOMIAL_STEPS = 4


def _in_polynomial_range(consts, delta, v):
    """Where the small angles Δ/2 and (γ − γ0)/2 = (γ0/2)·v are within ``POLYNOMIAL_LIMIT``."""
    return (jnp.abs(0.5 * delta) <= POLYNOMIAL_LIMIT) & (
        jnp.abs(consts["half0"] * v) <= POLYNOMIAL_LIMIT
    )


def _step_is_small(old, new, rtol, scale):
    """The stopping test of every Newton stage: max(|dΔ|, |dv|) ≤ rtol · (max(|Δ|, |v|) + scale)."""
    (d0, v0), (d1, v1) = old, new
    step = jnp.maximum(jnp.abs(d1 - d0), jnp.abs(v1 - v0))
    tiny = jnp.finfo(step.dtype).tiny
    return step <= rtol * (jnp.maximum(jnp.abs(d1), jnp.abs(v1)) + scale) + tiny


def _pair(z):
    """(Δ, v) of z = Δ + iv."""
    return jnp.real(z), jnp.imag(z)


def _polynomial_steps(consts, z, count):
    """``count`` Newton steps with the polynomial sines from z = Δ + iv; the last two iterates.

    Δ and v travel as one complex number through a ``fori_loop``: a step then has a single
    output, so XLA evaluates it in one fused pass, shared subexpressions once (with two
    outputs, or unrolled, it splits each step into several passes that recompute them). The
    first row of the pair is scaled by cos²γ (``row_scaled``): no division but 1/det.
    """

    def step(_, pair):
        z = pair[1]
        delta, v = _pair(z)
        d_delta, d_v = newton_step(*scaled_system(jnp, consts, delta, v, True, row_scaled=True))
        return z, jax.lax.complex(delta + d_delta, v + d_v)

    return jax.lax.fori_loop(0, count, step, (z, z))


def _iterate(consts, scale, rtol, z, steps, max_steps, done):
    """Newton steps with the exact sines on z = Δ + iv for the points not yet ``done``, until
    each point's step is small or its ``steps`` reach ``max_steps``; returns (z, steps, done,
    singular). The loop runs only while some point is active: not at all where the polynomial
    stage settled every point."""

    def active_of(steps, done):
        return jnp.logical_not(done) & (steps < max_steps)

    def cond(carry):
        n, _, steps, done, _ = carry
        return jnp.logical_and(n < max_steps, jnp.any(active_of(steps, done)))

    def body(carry):
        n, z, steps, done, singular = carry
        old = _pair(z)
        d_delta, d_v = newton_step(*scaled_system(jnp, consts, *old))
        new = (old[0] + d_delta, old[1] + d_v)
        small = _step_is_small(old, new, rtol, scale)
        # A non-finite step ends the point: a singular Jacobian (finite iterate), or NaN input.
        broken = ~(jnp.isfinite(new[0]) & jnp.isfinite(new[1]))
        active = active_of(steps, done)
        return (
            n + 1,
            jnp.where(active, jax.lax.complex(*new), z),
            steps + active.astype(jnp.int32),
            done | (active & (small | broken)),
            singular | (active & broken & jnp.isfinite(z)),
        )

    start = (jnp.int32(0), z, steps, done, jnp.zeros(done.shape, bool))
    _, z, steps, done, singular = jax.lax.while_loop(cond, body, start)
    return z, steps, done, singular


def _newton(R, l, gamma0, theta, rtol, max_steps):
    """Newton iterations from the closed form, elementwise; returns Δ, v, steps, result.

    Two stages within ``max_steps`` steps in all. First ``POLYNOMIAL_STEPS + 1`` Newton steps
    (or ``max_steps`` if fewer) on the pair with the polynomial sines of
    [`small_angle_sincos`][tripodjax.halfshaft.small_angle_sincos], pure arithmetic: where the
    last step starts inside the polynomials' range (|Δ/2|, |γ − γ0|/2 ≤ ``POLYNOMIAL_LIMIT``,
    where they equal the exact sines to roundoff) and is below tolerance, the point is solved:
    over the layout domain every point is. The other points go on with Newton on the exact
    sines (a loop that does not run when there are none): from there if still in range and
    finite, else from the closed form again.
    """
    consts = layout_constants(jnp, R, l, gamma0, theta)
    scale = first_order_amplitude(consts)
    bad_input = _nonfinite_inputs(R, l, gamma0, theta)
    guess = jnp.broadcast_arrays(*analytic_unknowns(jnp, consts, theta), bad_input)[:2]
    guess = jax.lax.complex(*guess)
    polynomial_steps = min(POLYNOMIAL_STEPS + 1, max_steps)
    before, z = _polynomial_steps(consts, guess, polynomial_steps)
    before, after = _pair(before), _pair(z)
    keep = _in_polynomial_range(consts, *before) & jnp.isfinite(z)
    done = keep & _step_is_small(before, after, rtol, scale)
    keep = keep & _in_polynomial_range(consts, *after)
    z = jnp.where(keep, z, guess)
    steps = jnp.where(keep, jnp.int32(polynomial_steps), jnp.int32(0))
    z, steps, done, singular = _iterate(consts, scale, rtol, z, steps, max_steps, done)
    result = code_where(done, RESULTS.successful, RESULTS.max_steps_reached)
    result = code_where(singular & ~bad_input, RESULTS.singular_jacobian, result)
    nonfinite = bad_input | ~jnp.isfinite(z)
    result = code_where(nonfinite & ~(singular & ~bad_input), RESULTS.nonfinite, result)
    delta, v = _pair(z)
    return delta, v, steps, result


def _implicit_solver(rtol, max_steps):
    """Newton solve whose derivatives come from the implicit function theorem (``_implicit``)."""
    return _implicit(lambda R, l, gamma0, theta: _newton(R, l, gamma0, theta, rtol, max_steps))


def _implicit(primal):
    """``primal(R, l, gamma0, theta, *known)`` → (Δ, v, steps, result) at the solution of the pair,
    with derivatives from the implicit function theorem.

    The JVP rule solves J·dx = −(∂g/∂(R, l, γ0, θ))·d(R, l, γ0, θ) with the
    closed-form Jacobian J at the solution; the iterations are never
    differentiated. The rule is itself differentiable, so derivatives of any
    order (and reverse mode, by transposition) follow. ``known`` (``_at_solution``'s:
    the solution itself) has no derivative of its own: it is the solution at
    (R, l, γ0, θ), whose derivatives the rule gives.
    """

    @jax.custom_jvp
    def solve(R, l, gamma0, theta, *known):
        return primal(R, l, gamma0, theta, *known)

    def solve_jvp(primals, tangents):
        out = solve(*primals)
        primals, tangents = primals[:4], tangents[:4]
        delta, v = out[:2]
        # Only the layout's fields being differentiated enter the JVP (the others carry
        # symbolic zeros); θ's part is the closed-form ∂g/∂θ, so that the θ-rates (every
        # revolution's) differentiate the pair once, and their layout derivatives twice
        # (a JVP of a JVP of the pair was most of the programs that need them).
        active = [i for i, t in enumerate(tangents[:3]) if not isinstance(t, SymbolicZero)]

        def system_at_solution(*moving):
            args = list(primals)
            for i, value in zip(active, moving, strict=False):
                args[i] = value
            consts = layout_constants(jnp, *args)
            return scaled_system(jnp, consts, delta, v, True, row_scaled=True, with_theta=True)

        if active:
            (_, jacobian, g_theta), (dg, _, _) = jax.jvp(
                system_at_solution,
                tuple(primals[i] for i in active),
                tuple(tangents[i] for i in active),
            )
        else:
            _, jacobian, g_theta = system_at_solution()
            dg = (0.0, 0.0)
        d_theta = tangents[3]
        if not isinstance(d_theta, SymbolicZero):
            dg = tuple(d + g * d_theta for d, g in zip(dg, g_theta, strict=True))
        # The polynomial sines hold inside their range, which holds every solution of the layout
        # domain (|Δ/2| ≤ 0.03 there): beyond it the derivatives are NaN, never a wrong number.
        valid = _in_polynomial_range(layout_constants(jnp, *primals), delta, v)
        dx = [jnp.where(valid, d, jnp.nan) for d in newton_step(dg, jacobian)]
        no_tangent = [np.zeros(a.shape, jax.dtypes.float0) for a in out[2:]]
        return out, (*(jnp.broadcast_to(d, delta.shape) for d in dx), *no_tangent)

    solve.defjvp(solve_jvp, symbolic_zeros=True)
    return solve


_at_solution = _implicit(lambda R, l, gamma0, theta, *known: known)


@jax.jit
def _known_solution(layout, theta, sol):
    """Newton's solution ``sol`` at angles ``theta`` of ``layout``, differentiable without solving again.

    ``sol`` is ``solve_halfshaft``'s answer (Newton's) at these
    angles (e.g. picked from a revolution's); its derivatives w.r.t. the layout and θ come
    from the implicit function theorem at it, as those of the Newton solve itself (the
    values are ``sol``'s, not computed again). For a derivative at a few angles of a solved
    grid (``kinematics._metrics_and_jacobian``).
    """
    R, l, gamma0, theta = _working_arrays(layout, theta)
    delta, v, steps, result = _at_solution(
        R, l, gamma0, theta, sol.delta, sol.v, sol.iterations, sol.result
    )
    diagnostics = (sol.residual, sol.error_estimate)  # not differentiated: the grid's
    return _finish(R, l, gamma0, theta, delta, v, result, steps, diagnostics)


def _analytic(R, l, gamma0, theta, corrections):
    """The closed form plus ``corrections`` Newton steps with polynomial sines; (Δ, v)."""
    consts = layout_constants(jnp, R, l, gamma0, theta)
    guess = jax.lax.complex(*jnp.broadcast_arrays(*analytic_unknowns(jnp, consts, theta)))
    return _pair(_polynomial_steps(consts, guess, corrections)[1])


def _diagnostics(R, l, gamma0, theta, delta, v, small_angles=False):
    """Scaled residual (…, 2) and error estimate at (Δ, v), not differentiated.

    The estimate is the next Newton step, max(|dΔ|, |dv|), relative to the
    first-order amplitude e(γ0)/|h| of Δ: the relative error of the small
    unknowns, to first order in it. With ``small_angles`` the step uses the
    polynomial sines (no transcendental function; equal to the exact step to
    roundoff while |Δ/2| and |γ − γ0|/2 are at most ``POLYNOMIAL_LIMIT``, and
    an infinite estimate where they are not).
    """
    delta, v = jax.lax.stop_gradient(delta), jax.lax.stop_gradient(v)
    R, l, gamma0, theta = (jax.lax.stop_gradient(a) for a in (R, l, gamma0, theta))
    consts = layout_constants(jnp, R, l, gamma0, theta)
    residual, _ = scaled_system(jnp, consts, delta, v, small_angles)  # formed only if used
    d_delta, d_v = newton_step(*scaled_system(jnp, consts, delta, v, small_angles, True))
    scale = jnp.maximum(first_order_amplitude(consts), jnp.finfo(delta.dtype).tiny)
    estimate = jnp.maximum(jnp.abs(d_delta), jnp.abs(d_v)) / scale
    if small_angles:
        outside = ~_in_polynomial_range(consts, delta, v)
        estimate = jnp.where(outside, jnp.inf, estimate)
    estimate = jnp.where(jnp.isfinite(d_delta) & jnp.isfinite(d_v), estimate, jnp.nan)
    return jnp.stack(jnp.broadcast_arrays(*residual), axis=-1), estimate


@pytree_dataclass
class HalfshaftSolution:
    """Solution of the halfshaft equations at each input angle θ.

    Attributes:
        theta: input (pot) angle θ [rad].
        psi: output (spider) angle ψ [rad].
        gamma: instantaneous articulation angle γ [rad].
        delta: input–output difference Δ = θ − ψ [rad], solved for directly.
        delta_gamma: γ − γ0 [rad], solved for directly (as γ0 · v).
        v: (γ − γ0)/γ0 [–], the unknown solved for beside Δ (0 at γ0 = 0, where
            γ − γ0 vanishes like γ0²).
        residual: scaled residual pair (g1, g2) at the solution,
            dimensionless (the pair 2.9.1–2.9.2 divided by 2 l sin(γ0/2)),
            shape (..., 2). Diagnostic only: not differentiated.
        error_estimate: the next Newton step at the answer, relative to the
            first-order amplitude e(γ0)/|h| of Δ [–]: roundoff (≲ 1e-13 in
            float64) for Newton, the truncation error for Analytic. Not
            differentiated.
        result: [`RESULTS`][tripodjax.results.RESULTS] code per point (int32).
        converged: ``result == RESULTS.successful``.
        iterations: Newton steps taken (the fixed corrections for Analytic).
        series: for a level that solves at nodes and interpolates (Analytic over a
            revolution), Δ and v as their [`PeriodSeries`][tripodjax.halfshaft.PeriodSeries]
            in 3θ; None otherwise.
    """

    theta: jax.Array
    psi: jax.Array
    gamma: jax.Array
    delta: jax.Array
    delta_gamma: jax.Array
    v: jax.Array
    residual: jax.Array
    error_estimate: jax.Array
    result: jax.Array
    converged: jax.Array
    iterations: jax.Array
    series: "PeriodSeries | None" = None


@pytree_dataclass
class PeriodSeries:
    """Δ and v over a revolution as trigonometric series in 3θ, from an interpolating level's nodes.

    The pair 2.9.1–2.9.2 is unchanged under θ → −θ, ψ → −ψ with γ kept, so Δ is odd
    and v even in θ, and the trigonometric interpolant of M equispaced node values
    of one period is

        Δ(θ) = Σ_{m=1}^{M/2−1} b_m sin 3mθ,    v(θ) = Σ_{m=0}^{M/2} a_m cos 3mθ

    (the node data's other parts are roundoff). Extremes over a grid of the period
    then need half the grid and a few terms per angle
    ([`tripodjax.kinematics`][tripodjax.kinematics] uses it for the peak-to-peak metrics).

    Attributes:
        delta_sin: b_m [rad], m = 1 … M/2 − 1, shape (…, M/2 − 1).
        v_cos: a_m [–], m = 0 … M/2, shape (…, M/2 + 1).
        result: the worst [`RESULTS`][tripodjax.results.RESULTS] code over the period (int32).
        error_estimate: the largest error estimate over the period [–].
    """

    delta_sin: jax.Array
    v_cos: jax.Array
    result: jax.Array
    error_estimate: jax.Array


def _series_of_nodes(delta, v):
    """Δ's sine and v's cosine coefficients (b_m, a_m) from the nodes of half the period.

    ``delta``, ``v``: (…, M/2) values at 3θ_k = 2πk/M, k = 1 … M/2, of M equispaced
    nodes. The others follow: node 0 (θ = 0) holds Δ = v = 0 exactly, and node M − k
    holds −Δ_k, v_k (Δ odd, v even), so the M-node discrete Fourier sums fold onto these.
    Returns (b_m, m = 1 … M/2 − 1; a_m, m = 0 … M/2).
    """
    nodes = 2 * delta.shape[-1]
    k = np.arange(1, nodes // 2 + 1)[:, None]
    m = np.arange(nodes // 2 + 1)
    phase = 2.0 * np.pi * k * m / nodes
    mirrored = np.where(k == nodes // 2, 1.0, 2.0)  # an inner node stands for its mirror too
    weight = mirrored * np.where((m == 0) | (m == nodes // 2), 1.0, 2.0) / nodes
    return _product(delta, (np.sin(phase) * weight)[:, 1:-1]), _product(v, np.cos(phase) * weight)


# A product with a constant table of at most this many entries is summed term by term: on a
# CPU that is faster than a dot call, and the same to the bit however many rows the batch has,
# which a small dot's kernels are not (measured; the sweep's shards would differ in the last bit).
_TERM_BY_TERM = 20


_REDUCTIONS: dict[Any, Any] = {jnp.maximum: jnp.max, jnp.minimum: jnp.min, jnp.add: jnp.sum}


def _reduce_last(op, x: jax.Array) -> jax.Array:
    """``op`` (``jnp.maximum``, ``jnp.minimum`` or ``jnp.add``) over the last axis of ``x``.

    A short axis (at most ``_TERM_BY_TERM`` entries) term by term: XLA fuses that with its
    neighbours, where a reduction is a pass of its own on a CPU (measured: a few tenths of
    a millisecond each at 20 000 layouts).
    """
    if not 0 < x.shape[-1] <= _TERM_BY_TERM:  # an empty sum is 0 (e.g. no higher harmonic)
        return _REDUCTIONS[op](x, axis=-1)
    return functools.reduce(op, [x[..., k] for k in range(x.shape[-1])])


def _product(x: jax.Array, table: np.ndarray) -> jax.Array:
    """x (…, K) @ table (K, J), a NumPy constant, at full precision on every backend.

    A float32 dot may otherwise run in TF32/bfloat16 on accelerators; a small table
    (``_TERM_BY_TERM``) is summed term by term.
    """
    if table.size > _TERM_BY_TERM:
        constant = jnp.asarray(table, x.dtype)
        return jnp.matmul(x, constant, precision=jax.lax.Precision.HIGHEST)
    total = x[..., :1] * jnp.asarray(table[0], x.dtype)
    for k in range(1, table.shape[0]):
        total = total + x[..., k : k + 1] * jnp.asarray(table[k], x.dtype)
    return total


def _series_on(coefficients: jax.Array, first_order: int, phase: np.ndarray, trig) -> jax.Array:
    """Σ_m c_m · trig(m·x) at the phases x = 3θ (a NumPy array), m = first_order, first_order + 1, ….

    ``trig``: ``np.sin`` or ``np.cos``; ``coefficients`` (…, M). One matrix product with a
    constant table. Evaluates a [`PeriodSeries`][tripodjax.halfshaft.PeriodSeries]
    (``delta_sin`` from order 1 with sines, ``v_cos`` from order 0 with cosines).
    """
    orders = first_order + np.arange(coefficients.shape[-1])
    return _product(coefficients, trig(np.outer(orders, phase)))


def solve_halfshaft(
    layout: Layout,
    theta: ArrayLike,
    solver: solvers.SolverLike = "newton",
    *,
    throw: bool = False,
    rtol: float | None | solvers._Unset = solvers._UNSET,
    max_steps: int | solvers._Unset = solvers._UNSET,
) -> HalfshaftSolution:
    """Solve ψ(θ) and γ(θ) of a halfshaft for every input angle in ``theta``.

    Args:
        layout: a [`Layout`][tripodjax.layout.Layout] (scalar fields, or fields that
            broadcast against ``theta``).
        theta: input angles θ [rad], any shape.
        solver: [`Newton`][tripodjax.solvers.Newton] (default, ``"newton"``),
            [`Analytic`][tripodjax.solvers.Analytic] (``"analytic"``) or
            ``"closed_form"``; see [`tripodjax.solvers`][tripodjax.solvers].
        throw: raise [`SolverError`][tripodjax.solvers.SolverError] naming the first
            point (index and θ) whose result is not successful. Needs concrete
            values: works outside ``jax.jit`` only (inside, read ``result``).
        rtol, max_steps: older spelling of ``solver=Newton(rtol, max_steps)``.

    Returns:
        [`HalfshaftSolution`][tripodjax.halfshaft.HalfshaftSolution] with arrays of the broadcast shape.

    Jit-compiled (the solver is static). Newton starts from the closed form
    and takes 5 steps (polynomial sines, the last one the stopping test) at
    every point of the domain, in float64 and float32.
    Every float field is differentiable (``jax.jvp``/``jax.grad``, any order)
    w.r.t. θ and the layout. Works in float32 and float64: the working dtype
    is that of ``theta`` and the layout combined. Non-finite input gives NaN
    and ``RESULTS.nonfinite`` at that point, never a finite answer.
    """
    check_layout(layout)
    check_real("theta", theta)  # the type only: a NaN θ is answered with NaN and a code
    theta = as_array(theta)
    check_broadcast(
        **{f"layout.{name}": getattr(layout, name) for name in ("R", "l", "gamma0")}, theta=theta
    )
    check_flag("throw", throw)
    solver = solvers.resolve_legacy(solver, rtol=rtol, max_steps=max_steps)
    sol = _solve(layout, theta, solver)
    if throw:
        raise_first_failure(sol.result, sol.theta, "solve_halfshaft")
    return sol


@functools.partial(latency_bound_at_top_level, small_inputs=True, static_argnames=("solver",))
def _solve(layout, theta, solver):
    R, l, gamma0, theta = _working_arrays(layout, theta)
    if isinstance(solver, Newton):
        rtol = default_rtol(theta.dtype) if solver.rtol is None else solver.rtol
        delta, v, steps, result = _implicit_solver(rtol, solver.max_steps)(R, l, gamma0, theta)
        return _finish(R, l, gamma0, theta, delta, v, result, steps)
    delta, v = _analytic(R, l, gamma0, theta, solver.corrections)
    return _finish_analytic(R, l, gamma0, theta, delta, v, solver)


@functools.partial(jax.jit, static_argnames=("solver",))
def _solve_period(layout, theta, solver):
    """``_solve`` for one layout on a 1-D grid θ; Analytic from its ``nodes`` by interpolation.

    Δ and v are smooth and 2π/3-periodic in θ, their harmonics falling by
    about 50× each (at R/l = 0.2, γ0 = 45°), so the analytic answer at
    ``solver.nodes`` equispaced angles of one period, carried to θ by
    trigonometric interpolation, differs from the answer at θ by < 3e-5
    relative over the domain (measured), at a fraction of the cost.
    """
    nodes = solver.nodes if isinstance(solver, Analytic) else None
    if nodes is None or jnp.ndim(theta) != 1 or jnp.shape(theta)[0] <= nodes:
        return _solve(layout, theta, solver)
    R, l, gamma0, theta = _working_arrays(layout, theta)
    if any(jnp.ndim(a) for a in (R, l, gamma0)):
        return _solve(layout, theta, solver)
    # Solved at the nodes k = 1 … M/2 of half the period (3θ_k = 2πk/M): at θ = 0 the answer
    # is Δ = v = 0 exactly (ψ = 0 and γ = γ0 there, 2.9.3), and node M − k mirrors node k
    # (Δ odd, v even in θ). M/2 angles, a multiple of the CPU's vector width at the default 8.
    half = nodes // 2
    node_theta = np.arange(1, half + 1) * (2.0 * np.pi / 3.0 / nodes)
    solved = _analytic(R, l, gamma0, jnp.asarray(node_theta, theta.dtype), solver.corrections)
    zero = jnp.zeros(1, theta.dtype)
    at_nodes = (
        jnp.concatenate([zero, solved[0], -solved[0][half - 2 :: -1]]),
        jnp.concatenate([zero, solved[1], solved[1][half - 2 :: -1]]),
    )

    def interpolate(to):
        # Full precision on every backend (a float32 dot may run in TF32/bfloat16 on accelerators).
        weights = trigonometric_interpolation(to, nodes)
        return (jnp.matmul(weights, u, precision=jax.lax.Precision.HIGHEST) for u in at_nodes)

    delta, v = interpolate(theta)
    delta_sin, v_cos = _series_of_nodes(*solved)
    # The error estimate where the answer is formed and where the interpolation errs most: at
    # the nodes and midway between them on the half period (Δ odd, v even: the other half
    # mirrors it), from the series; not at θ = 0, where the answer is exact.
    sample_phase = np.arange(1, nodes + 1) * (np.pi / nodes)  # 3θ
    _, estimate = _diagnostics(
        R,
        l,
        gamma0,
        jnp.asarray(sample_phase / 3.0, theta.dtype),
        _series_on(delta_sin, 1, sample_phase, np.sin),
        _series_on(v_cos, 0, sample_phase, np.cos),
        small_angles=True,
    )
    # The residual at every angle is computed only where it is used (max_residual).
    residual, _ = _diagnostics(R, l, gamma0, theta, delta, v)
    # The interpolated answer is finite wherever the node values are.
    finite = jnp.all(jnp.isfinite(solved[0]) & jnp.isfinite(solved[1]))
    # A reduction, not term by term: that would fuse the samples' Newton step into the
    # maximum, which XLA then forms with the layout's constants again for every sample.
    estimate = jnp.max(estimate)
    # The worst code of the angles, formed per layout (the codes of _finish_analytic, reduced).
    bad_layout = ~(jnp.isfinite(R) & jnp.isfinite(l) & jnp.isfinite(gamma0) & finite)
    good_theta = jnp.isfinite(theta)
    code = code_where(bad_layout | ~jnp.all(good_theta), RESULTS.nonfinite, RESULTS.successful)
    flagged = ~bad_layout & jnp.any(good_theta) & (estimate > solver.validity)
    flagged |= outside_layout_domain(R, l, gamma0)
    code = code_where(flagged, RESULTS.outside_validity, code)
    series = PeriodSeries(delta_sin, v_cos, result=code, error_estimate=estimate)
    return _finish_analytic(
        R, l, gamma0, theta, delta, v, solver, (residual, estimate), finite, series
    )


def trigonometric_interpolation(theta: ArrayLike, nodes: int) -> jax.Array:
    """Weights (θ.shape + (nodes,)) carrying values at θ_j = j·2π/(3·nodes) to θ (2π/3-periodic).

    The Dirichlet kernel of an even number M of nodes, in x = 3(θ − θ_j),
    written as its cosine sum

        D(x) = (1 + 2 Σ_{k=1}^{M/2−1} cos kx + cos(Mx/2)) / M,

    1 at x = 0 and 0 at the other nodes: exact for the harmonics of 3θ below
    M/2, for any θ (the kernel is periodic). The sum has no 0/0 near a node,
    so its θ-derivative (the θ-rates of an interpolated answer) keeps full
    precision in float32 too. ``nodes``: an even integer ≥ 2; θ [rad] of any
    shape (integers are promoted to the default float dtype).
    """
    nodes = check_integer("nodes", nodes, minimum=2)
    if nodes % 2:
        raise ValueError(f"nodes = {nodes} is not allowed; allowed: an even integer ≥ 2")
    theta = jnp.asarray(theta)
    theta = theta.astype(jnp.result_type(theta, 0.0))
    node_theta = np.arange(nodes) * (2.0 * np.pi / 3.0 / nodes)
    x = 3.0 * (theta[..., None] - jnp.asarray(node_theta, theta.dtype))
    total = 1.0 + jnp.cos(0.5 * nodes * x)
    for k in range(1, nodes // 2):
        total = total + 2.0 * jnp.cos(k * x)
    return total / nodes


def _finish_analytic(
    R, l, gamma0, theta, delta, v, solver, diagnostics=None, finite=None, series=None
):
    """The HalfshaftSolution of an Analytic answer (Δ, v): codes from its error estimate.

    ``diagnostics``: (residual, estimate) when already formed (the estimate may be
    one number for the whole grid), ``finite``: whether (Δ, v) is finite when
    already known; by default both at every point. ``series``: the node series, if any.
    """
    delta, v = jnp.broadcast_arrays(delta, v)
    steps = jnp.full(delta.shape, solver.corrections, jnp.int32)
    if diagnostics is None:
        diagnostics = _diagnostics(R, l, gamma0, theta, delta, v)
    if finite is None:
        finite = jnp.isfinite(delta) & jnp.isfinite(v)
    bad = _nonfinite_inputs(R, l, gamma0, theta) | ~finite
    result = code_where(diagnostics[1] > solver.validity, RESULTS.outside_validity, 0)
    result = code_where(bad, RESULTS.nonfinite, result)
    return _finish(R, l, gamma0, theta, delta, v, result, steps, diagnostics, series)


def _finish(R, l, gamma0, theta, delta, v, result, steps, diagnostics=None, series=None):
    """The HalfshaftSolution of (Δ, v): diagnostics, and NaN wherever an input is not finite."""
    bad_input = _nonfinite_inputs(R, l, gamma0, theta)
    if diagnostics is None:
        diagnostics = _diagnostics(R, l, gamma0, theta, delta, v)
    residual, estimate = diagnostics
    # Non-finite input gives NaN, never a finite answer (e.g. l = ±inf makes the pair
    # trivially solvable): a factor NaN/1, so the θ- and layout-derivatives are NaN there too.
    nan_where_bad = jnp.where(bad_input, jnp.nan, 1.0).astype(delta.dtype)
    delta, v = delta * nan_where_bad, v * nan_where_bad
    # A traced layout outside the documented domain (a concrete one is refused by Layout).
    outside = outside_layout_domain(R, l, gamma0)
    result = worst(result, code_where(outside, RESULTS.outside_validity, RESULTS.successful))
    if series is not None:  # one layout (scalar inputs): its coefficients alike
        bad_layout = _nonfinite_inputs(R, l, gamma0, 0.0) | ~jnp.all(jnp.isfinite(theta))
        nan_if_bad = jnp.where(bad_layout, jnp.nan, 1.0).astype(delta.dtype)
        series = dataclasses.replace(
            series, delta_sin=series.delta_sin * nan_if_bad, v_cos=series.v_cos * nan_if_bad
        )
    return _solution(theta, gamma0, delta, v, residual, estimate, result, steps, series)


def analytic_halfshaft(layout: Layout, theta: ArrayLike, corrections: int = 2) -> HalfshaftSolution:
    """The [`Analytic`][tripodjax.solvers.Analytic] level (``corrections=0``: the closed form alone).

    The closed form of [`analytic_unknowns`][tripodjax.halfshaft.analytic_unknowns] — the seed's first order
    (§2.11) plus the γ ripple — then ``corrections`` Newton steps whose sines
    of small angles are Taylor polynomials. See
    [`Analytic`][tripodjax.solvers.Analytic] for the measured accuracy.
    """
    return solve_halfshaft(layout, theta, Analytic(corrections=corrections))


def raise_first_failure(
    result: ArrayLike, theta: ArrayLike, what: str, index_prefix: str = ""
) -> None:
    """Raise SolverError naming the first point whose ``result`` is not successful (concrete only)."""
    if isinstance(result, jax.core.Tracer):
        raise TypeError(f"{what}: throw=True needs concrete values; it works outside jax.jit only")
    codes = np.asarray(result)
    bad = np.flatnonzero(codes != RESULTS.successful)
    if not bad.size:
        return
    index = np.unravel_index(int(bad[0]), codes.shape)
    theta_at = np.broadcast_to(np.asarray(theta), codes.shape)[index]
    code = RESULTS(int(codes[index]))
    where = ", ".join(str(int(i)) for i in index)
    raise SolverError(
        f"{what}: {index_prefix}point [{where}] at θ = {float(theta_at):.6g} rad: "
        f"{code.name} ({code.describe()}); {bad.size} of {codes.size} points not successful"
    )


def _solution(theta, gamma0, delta, v, residual, estimate, result, iterations, series=None):
    """A HalfshaftSolution from the unknowns (Δ, v), every field of the broadcast shape."""
    theta, gamma0 = jnp.broadcast_to(theta, delta.shape), jnp.broadcast_to(gamma0, delta.shape)
    delta_gamma = gamma0 * v
    return HalfshaftSolution(
        theta=theta,
        psi=theta - delta,
        gamma=gamma0 + delta_gamma,
        delta=delta,
        delta_gamma=delta_gamma,
        v=jnp.broadcast_to(v, delta.shape),
        residual=jnp.broadcast_to(residual, delta.shape + (2,)),
        error_estimate=jnp.broadcast_to(estimate, delta.shape),
        result=jnp.broadcast_to(result, delta.shape),
        converged=jnp.broadcast_to(result == RESULTS.successful, delta.shape),
        iterations=jnp.broadcast_to(iterations, delta.shape),
        series=series,
    )
