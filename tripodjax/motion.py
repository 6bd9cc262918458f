"""Positions, velocities and accelerations of the spider and roller centres (seed §2.11).

Exact motion: the positions are functions of θ through the implicit solution
ψ(θ), γ(θ); their θ-derivatives come from forward-mode AD through the solver
(implicit function theorem), and with θ̇, θ̈

    velocity     = p'(θ) θ̇
    acceleration = p''(θ) θ̇² + p'(θ) θ̈.

First-order motion: the seed's approximations 2.11.1–2.11.2, with ψ ≈ θ and
γ ≈ γ0 constant.

Lengths in mm, velocities in mm/s, accelerations in mm/s² (the seed quotes
m/s²: divide by 1000).
"""

import functools

import jax
import jax.numpy as jnp
import numpy as np
from jax.typing import ArrayLike

from tripodjax import joint
from tripodjax._checks import as_array, check_real, check_shapes
from tripodjax._compile import latency_bound_at_top_level
from tripodjax._pytree import pytree_dataclass
from tripodjax.halfshaft import solve_halfshaft
from tripodjax.layout import Layout, check_layout


@pytree_dataclass
class JointMotion:
    """Motion of the spider centre and the three roller centres.

    Attributes:
        spider_position, spider_velocity, spider_acceleration: shape (..., 3),
            components (a, b, Z*) — a, b in the fixed frame (2.5.13) and the
            axial position Z* = c + (Z* − c) (2.6.2), with c0 = 0.
        roller_position, roller_velocity, roller_acceleration: shape
            (..., 3 rollers, 3), components (X̃_i, Ỹ_i, Z_i): X̃_i, Ỹ_i in the
            intermediate frame (2.6.3), Z_i along the pot axis (2.6.2).
    """

    spider_position: jax.Array
    spider_velocity: jax.Array
    spider_acceleration: jax.Array
    roller_position: jax.Array
    roller_velocity: jax.Array
    roller_acceleration: jax.Array


def _positions(R, theta, gamma, psi, offset):
    """Spider (…, 3) and roller (…, 3, 3) positions for given ψ, γ and spider offset c."""
    a, b, z_rel = joint._spider_centre(R, gamma, theta, psi)
    spider = jnp.stack([a, b, offset + z_rel], axis=-1)
    x, y, z_i = joint._roller_centres(R, gamma, psi)
    rollers = jnp.stack([x, y, offset[..., None] + z_i], axis=-1)
    return spider, rollers


def _motion(positions, theta, theta_dot, theta_ddot):
    """JointMotion from a position function θ ↦ (spider, rollers) by nested forward-mode AD."""

    def first_derivative(t):
        return jax.jvp(positions, (t,), (jnp.ones_like(t),))

    (p, dp), (_, d2p) = jax.jvp(first_derivative, (theta,), (jnp.ones_like(theta),))
    fields = []
    for position, slope, curvature, extra_axes in zip(p, dp, d2p, (1, 2), strict=False):
        w = theta_dot.reshape(theta_dot.shape + (1,) * extra_axes)
        alpha = theta_ddot.reshape(theta_ddot.shape + (1,) * extra_axes)
        fields += [position, slope * w, curvature * w**2 + slope * alpha]
    return JointMotion(*fields)


def _prepare(
    layout: Layout, theta: ArrayLike, theta_dot: ArrayLike, theta_ddot: ArrayLike
) -> tuple[tuple[jax.Array, ...], list[jax.Array]]:
    """Broadcast θ, θ̇, θ̈ and cast them and the layout to the working dtype."""
    dtype = jnp.result_type(layout.R, layout.l, layout.gamma0, theta, 0.0)
    rates = jnp.broadcast_arrays(*(jnp.asarray(a, dtype) for a in (theta, theta_dot, theta_ddot)))
    fields = tuple(jnp.asarray(a, dtype) for a in (layout.R, layout.l, layout.gamma0))
    return fields, rates


def _check_motion(layout, theta, theta_dot, theta_ddot):
    """One layout (scalar fields) and real θ, θ̇, θ̈ whose shapes broadcast together (a NaN
    angle is answered with NaN, as by the solve); returns θ, θ̇, θ̈ (lists as arrays)."""
    check_layout(layout, one=True)
    rates = {"theta": theta, "theta_dot": theta_dot, "theta_ddot": theta_ddot}
    for name, value in rates.items():
        check_real(name, value)
    check_shapes({name: np.shape(value) for name, value in rates.items()})
    return tuple(as_array(value) for value in rates.values())


def halfshaft_motion(
    layout: Layout, theta: ArrayLike, theta_dot: ArrayLike, theta_ddot: ArrayLike = 0.0
) -> JointMotion:
    """Exact motion of the spider and roller centres at input angles ``theta``.

    Args:
        layout: [`Layout`][tripodjax.layout.Layout] with scalar fields.
        theta: input angle θ [rad]; theta_dot θ̇ [rad/s]; theta_ddot θ̈
            [rad/s²]. Broadcast together.

    Returns:
        [`JointMotion`][tripodjax.motion.JointMotion] in mm, mm/s, mm/s².
    """
    theta, theta_dot, theta_ddot = _check_motion(layout, theta, theta_dot, theta_ddot)
    return _halfshaft_motion(layout, theta, theta_dot, theta_ddot)


@functools.partial(latency_bound_at_top_level, small_inputs=True)
def _halfshaft_motion(layout, theta, theta_dot, theta_ddot):
    (R, l, gamma0), (theta, theta_dot, theta_ddot) = _prepare(layout, theta, theta_dot, theta_ddot)

    def positions(t):
        sol = solve_halfshaft(layout, t)
        offset = joint._spider_offset(l, gamma0, sol.gamma)
        return _positions(R, t, sol.gamma, sol.psi, offset)

    return _motion(positions, theta, theta_dot, theta_ddot)


def first_order_motion(
    layout: Layout, theta: ArrayLike, theta_dot: ArrayLike, theta_ddot: ArrayLike = 0.0
) -> JointMotion:
    """The seed's first-order motion (2.11.1, 2.11.2): ψ ≈ θ, γ ≈ γ0 constant.

    Same arguments and units as [`halfshaft_motion`][tripodjax.motion.halfshaft_motion]. With γ constant the
    spider offset c is constant (taken as 0), so the axial components are
    Z* − c and Z_i − c.
    """
    theta, theta_dot, theta_ddot = _check_motion(layout, theta, theta_dot, theta_ddot)
    return _first_order_motion(layout, theta, theta_dot, theta_ddot)


@functools.partial(latency_bound_at_top_level, small_inputs=True)
def _first_order_motion(layout, theta, theta_dot, theta_ddot):
    (R, _, gamma0), (theta, theta_dot, theta_ddot) = _prepare(layout, theta, theta_dot, theta_ddot)
    gamma = jnp.broadcast_to(gamma0, theta.shape)

    # The exact relations at ψ = θ, γ = γ0 are sums of sin/cos of θ and 3θ;
    # their θ-derivatives are 2.11.1–2.11.2 term by term.
    def positions(t):
        return _positions(R, t, gamma, t, jnp.zeros_like(t))

    return _motion(positions, theta, theta_dot, theta_ddot)
