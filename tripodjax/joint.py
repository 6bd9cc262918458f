"""Single-joint kinematics of the tripod joint (seed §2.3–2.6).

Pure functions of the joint size ``R`` [mm], the instantaneous articulation
angle ``gamma`` [rad], the input (pot) angle ``theta`` [rad] and the output
(spider) angle ``psi`` [rad]. Every function broadcasts over its arguments. Concrete
arguments are checked (``R``, ``l`` > 0; ``gamma``, ``gamma0`` working angles,
0 ≤ γ < π/2; the angles θ, ψ, τ real numbers, a NaN answered with NaN), the error
naming the argument; traced ones (inside ``jit``) are not. The library's own code calls the
unchecked kernels (``_eccentricity``, …), which answer NaN with NaN.
Roller quantities carry the roller index i = 1, 2, 3 on a trailing axis of
length 3, with ``psi_i = psi + (i − 1)·2π/3``.
"""

import jax
import jax.numpy as jnp
from jax.typing import ArrayLike

from tripodjax._checks import as_array, check_positive, check_real, check_working_angle

ROLLER_OFFSETS = (0.0, 2.0 * jnp.pi / 3.0, 4.0 * jnp.pi / 3.0)


def _check(**arguments):
    """The joint's rules for each argument given, by its name (see the module); returns the
    arguments in order, a list of numbers as an array."""
    for name, value in arguments.items():
        if name in ("R", "l"):
            check_positive(**{name: value})
        elif name in ("gamma", "gamma0"):
            check_working_angle(name, value)
        else:  # an angle θ, ψ or τ
            check_real(name, value)
    values = tuple(as_array(value) for value in arguments.values())
    return values if len(values) > 1 else values[0]


def roller_angles(psi: ArrayLike) -> jax.Array:
    """ψ_i = ψ + (i − 1)·2π/3 [rad] on a trailing axis of length 3 (2.4.7)."""
    psi = _check(psi=psi)
    return _roller_angles(psi)


def _roller_angles(psi):
    psi = jnp.asarray(psi)
    return psi[..., None] + jnp.asarray(ROLLER_OFFSETS, dtype=psi.dtype)


def direction_cosines(gamma: ArrayLike, tau: ArrayLike) -> jax.Array:
    """Direction-cosine matrix between pot XYZ and spider X'Y'Z' (2.3.5); γ, τ in rad.

    Rows are X, Y, Z; columns are X', Y', Z' (entries l_j, m_j, n_j), so the
    last column is the spider axis Z' in the pot frame. Shape ``(..., 3, 3)``.
    """
    gamma, tau = _check(gamma=gamma, tau=tau)
    gamma, tau = jnp.broadcast_arrays(gamma, tau)
    cg, sg, ct, st = jnp.cos(gamma), jnp.sin(gamma), jnp.cos(tau), jnp.sin(tau)
    zero = jnp.zeros_like(gamma)
    rows = (
        (-cg * ct, st, sg * ct),
        (-cg * st, -ct, sg * st),
        (sg, zero, cg),
    )
    return jnp.stack([jnp.stack(row, axis=-1) for row in rows], axis=-2)


def eccentricity(R: ArrayLike, gamma: ArrayLike) -> jax.Array:
    """Spider-centre eccentricity e = (R/2)(1 − cos γ)/cos γ [mm] (2.5.9).

    Evaluated as R sin²(γ/2)/cos γ, which keeps full relative accuracy at
    small γ (no cancellation in 1 − cos γ).
    """
    R, gamma = _check(R=R, gamma=gamma)
    return _eccentricity(R, gamma)


def _eccentricity(R, gamma):
    R = jnp.asarray(R)
    return R * jnp.sin(0.5 * gamma) ** 2 / jnp.cos(gamma)


def eccentricity_components(
    R: ArrayLike, gamma: ArrayLike, psi: ArrayLike
) -> tuple[jax.Array, jax.Array]:
    """Eccentricity components (e_x, e_y) = e (cos 3ψ, sin 3ψ) [mm] (2.5.8)."""
    R, gamma, psi = _check(R=R, gamma=gamma, psi=psi)
    e = _eccentricity(R, gamma)
    return e * jnp.cos(3.0 * psi), e * jnp.sin(3.0 * psi)


def spider_offset(l: ArrayLike, gamma0: ArrayLike, gamma: ArrayLike) -> jax.Array:
    """Axial offset of the spider frame c − c0 = l (cos γ0 − cos γ) [mm] (§2.6.2).

    The constant c0 is taken as 0: positions are measured from where the
    spider sits at θ = 0. Written as 2 l sin((γ+γ0)/2) sin((γ−γ0)/2).
    """
    l, gamma0, gamma = _check(l=l, gamma0=gamma0, gamma=gamma)
    return _spider_offset(l, gamma0, gamma)


def _spider_offset(l, gamma0, gamma):
    half_sum = 0.5 * (gamma + gamma0)
    half_diff = 0.5 * (gamma - gamma0)
    return 2.0 * jnp.asarray(l) * jnp.sin(half_sum) * jnp.sin(half_diff)


def spider_centre(
    R: ArrayLike, gamma: ArrayLike, theta: ArrayLike, psi: ArrayLike
) -> tuple[jax.Array, jax.Array, jax.Array]:
    """Spider centre relative to the spider frame origin: (a, b, Z* − c) [mm].

    a, b: 2.5.13 (fixed frame, X and Y); Z* − c = −e sin γ cos 3ψ (2.6.2,
    which fixes the sign of 2.5.15). Returns a tuple of three arrays.
    """
    R, gamma, theta, psi = _check(R=R, gamma=gamma, theta=theta, psi=psi)
    return _spider_centre(R, gamma, theta, psi)


def _spider_centre(R, gamma, theta, psi):
    e = _eccentricity(R, gamma)
    delta = theta - psi
    s3, c3 = jnp.sin(3.0 * psi), jnp.cos(3.0 * psi)
    cg = jnp.cos(gamma)
    a = e * (s3 * jnp.sin(delta) - cg * c3 * jnp.cos(delta))
    b = e * (-s3 * jnp.cos(delta) - cg * c3 * jnp.sin(delta))
    z = -e * jnp.sin(gamma) * c3
    return a, b, z


def roller_centres(
    R: ArrayLike, gamma: ArrayLike, psi: ArrayLike
) -> tuple[jax.Array, jax.Array, jax.Array]:
    """Roller centres (X̃_i, Ỹ_i, Z_i − c) [mm], each of shape (..., 3).

    X̃_i = −(R/cos γ) cos ψ_i, Ỹ_i = −R sin ψ_i in the intermediate frame
    (2.6.3, an ellipse); Z_i − c = −(R/2) tan γ [2 cos ψ_i + (1 − cos γ) cos 3ψ]
    along the pot axis (2.6.2).
    """
    R, gamma, psi = _check(R=R, gamma=gamma, psi=psi)
    return _roller_centres(R, gamma, psi)


def _roller_centres(R, gamma, psi):
    R, gamma = jnp.asarray(R), jnp.asarray(gamma)[..., None]
    psi_i = _roller_angles(psi)
    c3 = jnp.cos(3.0 * jnp.asarray(psi))[..., None]
    x = -R / jnp.cos(gamma) * jnp.cos(psi_i)
    y = -R * jnp.sin(psi_i)
    z = -0.5 * R * jnp.tan(gamma) * (2.0 * jnp.cos(psi_i) + 2.0 * jnp.sin(0.5 * gamma) ** 2 * c3)
    return x, y, z


def roller_radial_distance(R: ArrayLike, gamma: ArrayLike, psi: ArrayLike) -> jax.Array:
    """Distance |r_i| from the spider centre to each roller centre [mm], (..., 3).

    The seed's 2.6.4, r_i = −R − e sin 3ψ / sin ψ_i, has a removable
    singularity at sin ψ_i = 0; since sin 3ψ = sin 3ψ_i and
    sin 3x / sin x = 1 + 2 cos 2x, the stable form is
    |r_i| = R + e (1 + 2 cos 2ψ_i), which ranges over R − e … R + 3e.
    """
    R, gamma, psi = _check(R=R, gamma=gamma, psi=psi)
    e = _eccentricity(R, gamma)[..., None]
    R = jnp.asarray(R)
    return R + e * (1.0 + 2.0 * jnp.cos(2.0 * _roller_angles(psi)))


def roller_path_semi_axes(R: ArrayLike, gamma: ArrayLike) -> tuple[jax.Array, jax.Array]:
    """Semi-axes (R / cos γ, R) [mm] of the elliptical roller-centre path (2.6.3)."""
    R, gamma = _check(R=R, gamma=gamma)
    R = jnp.asarray(R)
    return R / jnp.cos(gamma), R * jnp.ones_like(gamma)
