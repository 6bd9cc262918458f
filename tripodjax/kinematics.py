"""Kinematic metrics of a halfshaft over one revolution (seed §2.10, §2.11.3)."""

import functools

import jax
import jax.numpy as jnp
import numpy as np

from tripodjax import joint
from tripodjax._pytree import pytree_dataclass
from tripodjax.halfshaft import DEFAULT_MAX_STEPS, analytic_halfshaft, solve_halfshaft

FIDELITIES = ("newton", "analytic")


@pytree_dataclass
class KinematicMetrics:
    """Peak-to-peak and extreme values over one revolution of the input.

    Attributes:
        delta_pp: peak-to-peak input–output difference Δ = θ − ψ [rad]
            (seed figures 2.10.2–2.10.4; Δ ≈ −(delta_pp/2) sin 3θ).
        irregularity: transmission irregularity (Ω2max − Ω2min)/Ω1 [–] from
            the exact dψ/dθ (§2.11.3).
        gamma_pp: peak-to-peak instantaneous articulation angle [rad]
            (figure 2.10.5).
        gamma_max: largest instantaneous articulation angle [rad]
            (figure 2.10.6, the pot-clearance check).
        ecc_max: largest spider-centre eccentricity e(γ) [mm] (figure 2.10.13).
        roller_stroke: radial stroke of a roller, max − min of its distance
            from the spider centre [mm] (figure 2.10.9).
        roller_radial_max: largest roller-centre distance |r_i| [mm].
        spider_orbit_x, spider_orbit_y: peak-to-peak of the spider centre's
            fixed-frame coordinates a and b [mm] (2.5.13).
        spider_orbit_z: peak-to-peak of Z* − c, the spider's axial
            oscillation relative to its frame [mm] (2.6.2).
        converged: every angle's Newton solve met its tolerance.
        max_residual: largest scaled residual over the revolution [–].
    """

    delta_pp: jax.Array
    irregularity: jax.Array
    gamma_pp: jax.Array
    gamma_max: jax.Array
    ecc_max: jax.Array
    roller_stroke: jax.Array
    roller_radial_max: jax.Array
    spider_orbit_x: jax.Array
    spider_orbit_y: jax.Array
    spider_orbit_z: jax.Array
    converged: jax.Array
    max_residual: jax.Array


def _check_n_theta(n_theta):
    if not isinstance(n_theta, int) or isinstance(n_theta, bool) or n_theta < 6 or n_theta % 6:
        raise ValueError(
            f"n_theta = {n_theta!r} is not allowed: it must be a positive multiple of 6 "
            "(so the grid holds the accuracy points θ = kπ/3 where dψ/dθ peaks), e.g. 360"
        )


def period_grid(n_theta, dtype):
    """The n_theta/3 input angles [rad] of one period 0 ≤ θ < 2π/3 of a grid of n_theta per turn.

    Every halfshaft quantity has period 2π/3 in θ (§2.10), and roller i at θ
    is roller 1 at θ + (i − 1)·2π/3, so one period with all three rollers
    covers a whole revolution.
    """
    _check_n_theta(n_theta)
    n = n_theta // 3
    # Built in NumPy: a compile-time constant, so XLA folds the functions of θ alone.
    return jnp.asarray(np.arange(n) * (2.0 * np.pi / 3.0 / n), dtype)


def _ptp(x, axis=None):
    return jnp.max(x, axis=axis) - jnp.min(x, axis=axis)


def check_fidelity(fidelity):
    if fidelity not in FIDELITIES:
        raise ValueError(
            f"fidelity = {fidelity!r} is not allowed; allowed: {', '.join(FIDELITIES)}"
        )


def revolution(layout, n_theta, fidelity, *, with_rates, rtol=None, max_steps=DEFAULT_MAX_STEPS):
    """The halfshaft solution over one period of an n_theta grid, and its θ-derivative.

    Returns ``(solution, rates)``: two :class:`HalfshaftSolution`, the second
    holding d(field)/dθ (forward-mode AD through the solve, so implicit for
    ``"newton"``), or None when ``with_rates`` is False.
    """
    check_fidelity(fidelity)
    dtype = jnp.result_type(layout.R, layout.l, layout.gamma0, 0.0)
    theta = period_grid(n_theta, dtype)
    if fidelity == "newton":
        solve = functools.partial(solve_halfshaft, layout, rtol=rtol, max_steps=max_steps)
    else:
        solve = functools.partial(analytic_halfshaft, layout)
    if not with_rates:
        return solve(theta), None
    return jax.jvp(solve, (theta,), (jnp.ones_like(theta),))


# Each metric from (R, solution, rates); only those asked for are built.
def _spider(R, sol):
    return joint.spider_centre(R, sol.gamma, sol.theta, sol.psi)


_METRICS = {
    "delta_pp": lambda R, sol, rates: _ptp(sol.delta),
    "irregularity": lambda R, sol, rates: _ptp(rates.psi),
    "gamma_pp": lambda R, sol, rates: _ptp(sol.gamma),
    "gamma_max": lambda R, sol, rates: jnp.max(sol.gamma),
    "ecc_max": lambda R, sol, rates: jnp.max(joint.eccentricity(R, sol.gamma)),
    "roller_stroke": lambda R, sol, rates: _ptp(
        joint.roller_radial_distance(R, sol.gamma, sol.psi)
    ),
    "roller_radial_max": lambda R, sol, rates: jnp.max(
        joint.roller_radial_distance(R, sol.gamma, sol.psi)
    ),
    "spider_orbit_x": lambda R, sol, rates: _ptp(_spider(R, sol)[0]),
    "spider_orbit_y": lambda R, sol, rates: _ptp(_spider(R, sol)[1]),
    "spider_orbit_z": lambda R, sol, rates: _ptp(_spider(R, sol)[2]),
    "converged": lambda R, sol, rates: jnp.all(sol.converged),
    "max_residual": lambda R, sol, rates: jnp.max(jnp.abs(sol.residual)),
}
NEEDS_RATES = ("irregularity",)


def metrics_from(layout, sol, rates, names):
    """The named kinematic metrics (KinematicMetrics field names) from a revolution."""
    R = jnp.asarray(layout.R, sol.theta.dtype)
    return {name: _METRICS[name](R, sol, rates) for name in names}


@functools.partial(jax.jit, static_argnames=("n_theta", "fidelity", "max_steps"))
def kinematic_metrics(
    layout, n_theta=360, fidelity="newton", *, rtol=None, max_steps=DEFAULT_MAX_STEPS
):
    """Kinematic metrics of a halfshaft layout over one revolution.

    Args:
        layout: a :class:`~tripodjax.Layout` with scalar fields (vmap over
            layouts for batches, or use :func:`tripodjax.sweep`).
        n_theta: input angles per revolution, a multiple of 6; only the
            first period (n_theta/3 angles) is solved, see :func:`period_grid`.
        fidelity: ``"newton"`` — the implicit solve converged to the dtype's
            tolerance (default); ``"analytic"`` — the closed form of
            :func:`~tripodjax.halfshaft.analytic_halfshaft`, no iteration,
            an order of magnitude cheaper, irregularity within 0.4 %.
        rtol, max_steps: Newton tolerance and iteration cap (``"newton"``
            only), see :func:`~tripodjax.solve_halfshaft`.

    Returns:
        :class:`KinematicMetrics`. Jit-compiled (``n_theta``, ``fidelity`` and
        ``max_steps`` are static). Every float field is differentiable
        (``jax.grad``, ``jax.jacfwd``) w.r.t. every Layout field.
    """
    sol, rates = revolution(
        layout, n_theta, fidelity, with_rates=True, rtol=rtol, max_steps=max_steps
    )
    return KinematicMetrics(
        **metrics_from(layout, sol, rates, KinematicMetrics.__dataclass_fields__)
    )
