"""Kinematic metrics of a halfshaft over one revolution (seed §2.10, §2.11.3).

Every metric that is a small difference is formed from the solver's small
unknowns, never from O(1) numbers: the irregularity as ptp(−dΔ/dθ) (not
ptp(dψ/dθ) = ptp(1 − dΔ/dθ)), the γ ripple as ptp(γ − γ0) with γ − γ0 = γ0 v
solved for directly, the roller stroke without the pitch radius R. float32
then keeps them within 1e-6 … 1e-4 relative of float64 over the whole domain,
down to (R/l)·γ0 ~ 1e-13.

Metrics that grow linearly from γ0 = 0 (delta_pp → (R/(2l))·γ0, irregularity
→ 1.5·(R/l)·γ0, roller_axial_stroke → 2R·γ0) are formed as a smooth scale
times the peak-to-peak of a shape that has a finite limit at γ0 = 0, e.g.
delta_pp = A·ptp(Δ/A) with A = e(γ0)/|h|. ``jax.grad`` at γ0 = 0 then returns
the one-sided derivative instead of the 0 that max − min over tying samples
gives.
"""

import functools
import numbers
from collections.abc import Iterable

import jax
import jax.numpy as jnp
import numpy as np
from jax.typing import ArrayLike, DTypeLike

from tripodjax import joint, solvers
from tripodjax._checks import check_flag
from tripodjax._compile import latency_bound_at_top_level
from tripodjax._derivatives import differentiable, jvp_from_jacobian, values_and_jacobian
from tripodjax._pytree import pytree_dataclass
from tripodjax.halfshaft import (
    HalfshaftSolution,
    _known_solution,
    _reduce_last,
    _series_on,
    _sinc,
    _solve_period,
    first_order_amplitude,
    layout_constants,
    raise_first_failure,
)
from tripodjax.layout import Layout, check_layout
from tripodjax.results import RESULTS


@pytree_dataclass
class KinematicMetrics:
    """Peak-to-peak and extreme values over one revolution of the input.

    Attributes:
        delta_pp: peak-to-peak input–output difference Δ = θ − ψ [rad]
            (seed figures 2.10.2–2.10.4; Δ ≈ −(delta_pp/2) sin 3θ).
        irregularity: transmission irregularity (Ω2max − Ω2min)/Ω1 [–] from
            the exact dψ/dθ (§2.11.3), as ptp(dΔ/dθ).
        gamma_pp: peak-to-peak instantaneous articulation angle [rad]
            (figure 2.10.5), as ptp(γ − γ0).
        gamma_max: largest instantaneous articulation angle [rad]
            (figure 2.10.6, the pot-clearance check).
        ecc_max: largest spider-centre eccentricity e(γ) [mm] (2.5.9, figure 2.10.13).
        roller_stroke: radial stroke of a roller, max − min of its distance
            |r_i| = R + e(1 + 2 cos 2ψ_i) from the spider centre [mm]
            (2.6.4, figure 2.10.9); vanishes like γ0².
        roller_radial_max: largest roller-centre distance |r_i| [mm].
        roller_axial_stroke: axial travel of a roller along its track,
            max − min over a revolution of Z_i = c − (R/2) tan γ
            [2 cos ψ_i + (1 − cos γ) cos 3ψ] (2.6.2, with the spider plunge
            c = l(cos γ0 − cos γ)) [mm]; ≈ 2R tan γ0 (the plunge the track
            must allow).
        spider_orbit_x, spider_orbit_y: peak-to-peak of the spider centre's
            fixed-frame coordinates a and b [mm] (2.5.13).
        spider_orbit_z: peak-to-peak of Z* − c, the spider's axial
            oscillation relative to its frame [mm] (2.6.2).
        converged: every angle's solve succeeded (``result == successful``).
        max_residual: largest scaled residual over the revolution [–].
        error_estimate: largest per-angle error estimate over the revolution
            [–] (see [`HalfshaftSolution`][tripodjax.halfshaft.HalfshaftSolution]): the relative
            error of Δ and γ − γ0, roundoff for Newton.
        result: worst [`RESULTS`][tripodjax.results.RESULTS] code over the revolution (int32).
    """

    delta_pp: jax.Array
    irregularity: jax.Array
    gamma_pp: jax.Array
    gamma_max: jax.Array
    ecc_max: jax.Array
    roller_stroke: jax.Array
    roller_radial_max: jax.Array
    roller_axial_stroke: jax.Array
    spider_orbit_x: jax.Array
    spider_orbit_y: jax.Array
    spider_orbit_z: jax.Array
    converged: jax.Array
    max_residual: jax.Array
    error_estimate: jax.Array
    result: jax.Array


MIN_N_THETA_ORDERS = 24
"""Angles per revolution at least of the quantities with orders, the GAF's and the force model's:
8 a period (2π/3), the fewest on which the orders 3, 6 and 9 (the period's harmonics 1–3) are three
distinct harmonics (at 6 a turn the stroke model's GAF came out as 5e-12 N against 623 N, at 12
the 9th order equal to the 3rd). A minimum, not an accuracy: the force model's nearly square GAF
folds its orders n ∓ 9 onto the 9th (62 % low at 24 angles, 0.3 % at 168; docs/physics.md)."""


def _check_n_theta(n_theta, name="n_theta", orders=None):
    """The grid's angles per revolution as a Python int: an integer (NumPy's too), a positive
    multiple of 6, and for ``orders`` (what is computed, e.g. "the GAF") at least
    `MIN_N_THETA_ORDERS`; else one ValueError naming ``name`` (a command names its option)."""
    integer = isinstance(n_theta, numbers.Integral) and not isinstance(n_theta, (bool, np.bool_))
    if not integer or n_theta < 6 or n_theta % 6:
        raise ValueError(
            f"{name} = {n_theta!r} is not allowed: it must be a positive multiple of 6 "
            "(so the grid holds the accuracy points θ = kπ/3 where dψ/dθ peaks), e.g. 360"
        )
    if orders is not None and n_theta < MIN_N_THETA_ORDERS:
        raise ValueError(
            f"{name} = {n_theta} is not allowed for {orders}: at least {MIN_N_THETA_ORDERS} "
            "(8 angles a period, the fewest that tell the orders 3, 6 and 9 apart), e.g. 360"
        )
    return int(n_theta)


def period_grid(n_theta: int, dtype: DTypeLike) -> jax.Array:
    """The n_theta/3 input angles [rad] of one period 0 ≤ θ < 2π/3 of a grid of n_theta per turn.

    Every halfshaft quantity has period 2π/3 in θ (§2.10), and roller i at θ
    is roller 1 at θ + (i − 1)·2π/3, so one period with all three rollers
    covers a whole revolution.
    """
    n_theta = _check_n_theta(n_theta)
    n = n_theta // 3
    # Built in NumPy: a compile-time constant, so XLA folds the functions of θ alone.
    return jnp.asarray(np.arange(n) * (2.0 * np.pi / 3.0 / n), dtype)


@functools.partial(jax.custom_jvp, nondiff_argnums=(1,))
def _extreme_value(x, kind):
    """max (``kind`` "max") or min of every element of x; its derivative that of the first
    extreme element (the tangent there).

    JAX's own rule for ``jnp.max`` averages the tangents of the elements equal to the
    maximum, found by comparing x with it: where XLA forms x in two fusions with different
    roundoff (seen compiled for latency, -O0), no element compares equal and the derivative
    is 0/0, NaN (``roller_axial_stroke``'s w.r.t. γ0 at domain layouts).
    """
    return jnp.max(x) if kind == "max" else jnp.min(x)


@_extreme_value.defjvp
def _extreme_value_jvp(kind, primals, tangents):
    (x,), (t,) = primals, tangents
    position = jnp.argmax(x) if kind == "max" else jnp.argmin(x)
    return _extreme_value(x, kind), jnp.ravel(t)[position]


# Half-width [rad of 3θ] of the window about 3θ = π/2 that holds the peak of |Δ| over the half
# period whenever Δ's first harmonic dominates as it does over the layout domain (the largest
# share of the others there, Σ m|b_m|/|b_1| ≈ 0.036 at R/l = 0.2, γ0 = 45°, is a third of sin of it).
PEAK_WINDOW = 0.1


def _half_period(n: int) -> np.ndarray:
    """The phases 3θ_j = 2πj/n, j = 0 … n/2, of the half period of a grid of n angles a period."""
    return 2.0 * np.pi * np.arange(n // 2 + 1) / n


def _extremes_on(shapes, phases):
    """max |Δ/A|, max and min of (dΔ/dθ)/A, max and min of γ − γ0, each series at its phases."""
    (delta, rate, delta_gamma), (at_delta, at_rate, at_delta_gamma) = shapes, phases
    delta = jnp.abs(_series_on(delta, 1, at_delta, np.sin))
    rate = _series_on(rate, 1, at_rate, np.cos)
    delta_gamma = _series_on(delta_gamma, 0, at_delta_gamma, np.cos)
    return (
        _reduce_last(jnp.maximum, delta),
        _reduce_last(jnp.maximum, rate),
        _reduce_last(jnp.minimum, rate),
        _reduce_last(jnp.maximum, delta_gamma),
        _reduce_last(jnp.minimum, delta_gamma),
    )


def _grid_extremes(shapes, n):
    """The extremes of ``_extremes_on`` over every angle of the grid's half period."""
    x = _half_period(n)
    return _extremes_on(shapes, (x, x, x))


def _window_extremes(shapes, n):
    """The same extremes from a few angles of the half period, where ``_window_holds``.

    |Δ| at the angles within ``PEAK_WINDOW`` + one spacing of 3θ = π/2; the cosine
    series dΔ/dθ and γ − γ0 at the ends 3θ = 0 and π.
    """
    x = _half_period(n)
    near_peak = x[np.abs(x - 0.5 * np.pi) <= PEAK_WINDOW + 2.0 * np.pi / n]
    ends = x[[0, -1]]
    return _extremes_on(shapes, (near_peak, ends, ends))


def _first_harmonic_dominates(c, first_order, bound):
    """``bound(|c_1|, (Σ_{m≥2} m|c_m|, Σ_{m≥2} m²|c_m|))`` of a series of orders first_order, …."""
    orders = first_order + np.arange(c.shape[-1])
    first = jnp.abs(c[..., 1 - first_order])
    higher = jnp.abs(c[..., 2 - first_order :])
    weighted = tuple(
        _reduce_last(jnp.add, higher * jnp.asarray(orders[2 - first_order :] ** p, c.dtype))
        for p in (1, 2)
    )
    return bound(first, weighted)


def _window_holds(shapes):
    """Whether ``_window_extremes`` equals ``_grid_extremes`` for these series (per layout).

    A cosine series f = Σ c_m cos mx has f(0) and f(π) for its extremes when
    Σ_{m≥2} m²|c_m| ≤ |c_1| (1 − cos mx ≤ m²(1 − cos x)). For Δ = Σ b_m sin mx: where
    E1 = Σ_{m≥2} m|b_m| ≤ |b_1| sin w and E2 = Σ_{m≥2} m²|b_m| < |b_1| cos w, dΔ/dx
    vanishes only within w of π/2 and falls strictly there, so |Δ| rises to one peak
    and falls on the half period, and the grid's largest |Δ| is at one of the two
    angles about the peak, both within w + one spacing of π/2.
    """
    delta, rate, delta_gamma = shapes
    sin_w, cos_w = np.sin(PEAK_WINDOW), np.cos(PEAK_WINDOW)
    peak_in_window = _first_harmonic_dominates(
        delta, 1, lambda b1, e: (e[0] <= b1 * sin_w) & (e[1] < b1 * cos_w)
    )
    ends = [
        _first_harmonic_dominates(c, k, lambda c1, e: e[1] <= c1)
        for c, k in ((rate, 1), (delta_gamma, 0))
    ]
    return peak_in_window & ends[0] & ends[1]


def revolution(
    layout: Layout, n_theta: int, solver: solvers.SolverLike = "newton", *, with_rates: bool
) -> tuple[HalfshaftSolution, HalfshaftSolution | None]:
    """The halfshaft solution over one period of an n_theta grid, and its θ-derivative.

    Args:
        layout: a [`Layout`][tripodjax.layout.Layout] with scalar fields.
        n_theta: angles per revolution, a multiple of 6 (see [`period_grid`][tripodjax.kinematics.period_grid]).
        solver: a solver object or shorthand ([`tripodjax.solvers`][tripodjax.solvers]).
        with_rates: also return the θ-derivatives.

    Returns ``(solution, rates)``: two [`HalfshaftSolution`][tripodjax.halfshaft.HalfshaftSolution],
    the second holding d(field)/dθ (forward-mode AD through the solve, so
    implicit for Newton), or None when ``with_rates`` is False. Form metrics
    from them with [`metrics_from`][tripodjax.kinematics.metrics_from]; ``solution.result`` carries the status.
    A batch of layouts goes through ``jax.vmap`` (as [`sweep`][tripodjax.sweep.sweep] does).
    """
    check_layout(layout, one=True)
    check_flag("with_rates", with_rates)
    solver = solvers.resolve(solver)
    dtype = jnp.result_type(layout.R, layout.l, layout.gamma0, 0.0)
    theta = period_grid(n_theta, dtype)
    solve = functools.partial(_solve_period, layout, solver=solver)
    if not with_rates:
        return solve(theta), None
    return jax.jvp(solve, (theta,), (jnp.ones_like(theta),))


def _shape_of(x, scale, limit):
    """x / scale, with its γ0 → 0 limit where the scale vanishes (or underflows).

    A NaN x (non-finite input) stays NaN in the limit branch too (``0 · x``).
    """
    ok = scale > jnp.sqrt(jnp.finfo(x.dtype).tiny)
    return jnp.where(ok, x * (1.0 / jnp.where(ok, scale, 1.0)), limit + 0.0 * x)


class _Revolution:
    """Quantities shared by several metrics, each built once and only when asked for.

    Where the solution carries its [`PeriodSeries`][tripodjax.halfshaft.PeriodSeries]
    (Analytic over a revolution), the extremes of Δ, dΔ/dθ and γ − γ0 over the grid are
    those of the half period (Δ is odd and γ even in θ, so the other half repeats the
    values, Δ with its sign changed), taken per ``extremes``: ``"grid"`` at every angle
    of it, ``"window"`` at the few angles where they lie when ``_window_holds`` (the
    caller's promise), ``"auto"`` the window where it holds, else the grid
    (``lax.cond``; under ``vmap`` both are evaluated).
    """

    def __init__(self, layout, sol, rates, extremes="auto", *, record=False, picks=None):
        self.sol, self.rates, self.extremes = sol, rates, extremes
        # The extremes over the grid's angles (``extreme``): each the array's largest or
        # smallest value, with ``record`` its position appended to ``positions``; with ``picks``
        # (the ``positions`` of a revolution on the whole grid), the solution is at those
        # angles only, the j-th extreme the value at pick j.
        self.picks = picks
        self.positions = [] if record or picks is not None else None
        dtype = sol.theta.dtype
        self.R, self.l, self.gamma0 = (
            jnp.asarray(a, dtype) for a in (layout.R, layout.l, layout.gamma0)
        )

    def extreme(self, x, kind):
        """max (``kind`` "max") or min of x over its angles (axis 0) and rollers (axis 1, if any).

        The position (angle, roller) of the first extreme value is kept in ``positions``; with
        ``picks`` the value at the next pick (see ``__init__``). A derivative of an extreme
        over the grid is that of its value at that position (Danskin; the first one where
        several angles tie), so ``_metrics_and_jacobian`` forms it from those angles alone.
        """
        if self.picks is not None:
            j = len(self.positions)
            roller = self.picks[j][1]
            self.positions.append(self.picks[j])
            return x[j] if roller is None else x[j, roller]
        if self.positions is not None:
            position = jnp.argmax(x) if kind == "max" else jnp.argmin(x)
            if x.ndim == 1:
                self.positions.append((position, None))
            else:
                self.positions.append(jnp.unravel_index(position, x.shape))
        return _extreme_value(x, kind)

    def ptp(self, x):
        """Peak to peak of x over its angles (and rollers): ``extreme`` max − min."""
        return self.extreme(x, "max") - self.extreme(x, "min")

    @functools.cached_property
    def amplitude(self):
        """A = e(γ0)/|h|, the first-order amplitude of Δ (0 at γ0 = 0, slope R/(4l))."""
        return first_order_amplitude(layout_constants(jnp, self.R, self.l, self.gamma0, 0.0))

    def _first_harmonic(self, coefficients, first):
        """The γ0 → 0 limit of a shape series: ``first`` in the first harmonic, 0 beyond."""
        return jnp.zeros(coefficients.shape[-1], coefficients.dtype).at[0].set(first)

    @functools.cached_property
    def _shapes(self):
        """The series of Δ/A, (dΔ/dθ)/A (dΔ/dθ = Σ 3m b_m cos 3mθ) and γ − γ0 = γ0 v."""
        b = self.sol.series.delta_sin
        rate = 3.0 * jnp.arange(1, b.shape[-1] + 1, dtype=b.dtype) * b
        return (
            _shape_of(b, self.amplitude, self._first_harmonic(b, -1.0)),
            _shape_of(rate, self.amplitude, self._first_harmonic(b, -3.0)),
            self.gamma0 * self.sol.series.v_cos,
        )

    @functools.cached_property
    def series_extremes(self):
        """max |Δ/A|, max and min of (dΔ/dθ)/A and of γ − γ0 over the grid (see the class)."""
        n = self.sol.theta.shape[-1]
        grid = functools.partial(_grid_extremes, n=n)
        window = functools.partial(_window_extremes, n=n)
        if self.extremes == "grid":
            return grid(self._shapes)
        if self.extremes == "window":
            return window(self._shapes)
        return jax.lax.cond(_window_holds(self._shapes), window, grid, self._shapes)

    def window_holds(self):
        """``_window_holds`` of the series; None where no series extreme was formed."""
        if "series_extremes" not in vars(self):
            return None
        return _window_holds(self._shapes)

    @functools.cached_property
    def spider(self):
        s = self.sol
        return joint._spider_centre(self.R, s.gamma, s.theta, s.psi)

    @functools.cached_property
    def roller_radial_excess(self):
        """|r_i| − R = e (1 + 2 cos 2ψ_i) [mm], without the large R."""
        s = self.sol
        e = joint._eccentricity(self.R, s.gamma)[..., None]
        return e * (1.0 + 2.0 * jnp.cos(2.0 * joint._roller_angles(s.psi)))

    def delta_pp(self):
        if self.sol.series is not None:  # Δ odd: ptp = 2 max |Δ| over the half period
            return self.amplitude * 2.0 * self.series_extremes[0]
        limit = -jnp.sin(3.0 * self.sol.theta)
        return self.amplitude * self.ptp(_shape_of(self.sol.delta, self.amplitude, limit))

    def irregularity(self):
        if self.sol.series is not None:
            return self.amplitude * (self.series_extremes[1] - self.series_extremes[2])
        limit = -3.0 * jnp.cos(3.0 * self.sol.theta)
        return self.amplitude * self.ptp(_shape_of(self.rates.delta, self.amplitude, limit))

    def worst_result(self):
        """The worst result code over the revolution (from the series' own when present)."""
        if self.sol.series is not None:
            return self.sol.series.result.astype(jnp.int32)
        return jnp.max(self.sol.result).astype(jnp.int32)

    def delta_gamma_max(self):
        if self.sol.series is not None:
            return self.series_extremes[3]
        return self.extreme(self.sol.delta_gamma, "max")

    def gamma_pp(self):
        if self.sol.series is not None:
            return self.series_extremes[3] - self.series_extremes[4]
        return self.ptp(self.sol.delta_gamma)

    def roller_axial_stroke(self):
        """R tan γ0 · ptp(Z_i / (R tan γ0)), the shape regular at γ0 = 0 (→ −cos ψ_i)."""
        s, R, l, g0 = self.sol, self.R, self.l, self.gamma0
        tiny = jnp.sqrt(jnp.finfo(g0.dtype).tiny)
        v = jnp.where(g0 > tiny, s.delta_gamma / jnp.where(g0 > tiny, g0, 1.0), 0.0)
        gamma = s.gamma
        sinc_g0 = _sinc(jnp, g0, jnp.sin(g0))
        # tan γ / tan γ0 = (γ/γ0)(sinc γ / sinc γ0)(cos γ0 / cos γ)
        tan_ratio = (1.0 + v) * _sinc(jnp, gamma, jnp.sin(gamma)) / sinc_g0
        tan_ratio = tan_ratio * jnp.cos(g0) / jnp.cos(gamma)
        half_dg = 0.5 * s.delta_gamma
        # c / (R tan γ0) = (l/R) sin((γ+γ0)/2) · v · sinc((γ−γ0)/2) · cos γ0 / sinc γ0
        plunge = (
            (l / R)
            * jnp.sin(0.5 * (gamma + g0))
            * v
            * _sinc(jnp, half_dg, jnp.sin(half_dg))
            * jnp.cos(g0)
            / sinc_g0
        )
        psi_i = joint._roller_angles(s.psi)
        bracket = (
            2.0 * jnp.cos(psi_i)
            + 2.0 * (jnp.sin(0.5 * gamma) ** 2 * jnp.cos(3.0 * s.psi))[..., None]
        )
        shape = plunge[..., None] - 0.5 * tan_ratio[..., None] * bracket
        return R * jnp.tan(g0) * self.ptp(shape)


_METRICS = {
    "delta_pp": _Revolution.delta_pp,
    "irregularity": _Revolution.irregularity,
    "gamma_pp": _Revolution.gamma_pp,
    "gamma_max": lambda r: r.gamma0 + r.delta_gamma_max(),
    # e(γ) grows with γ on 0 ≤ γ < π/2: its largest value is e at the largest γ.
    "ecc_max": lambda r: joint._eccentricity(r.R, r.gamma0 + r.delta_gamma_max()),
    "roller_stroke": lambda r: r.ptp(r.roller_radial_excess),
    "roller_radial_max": lambda r: r.R + r.extreme(r.roller_radial_excess, "max"),
    "roller_axial_stroke": _Revolution.roller_axial_stroke,
    "spider_orbit_x": lambda r: r.ptp(r.spider[0]),
    "spider_orbit_y": lambda r: r.ptp(r.spider[1]),
    "spider_orbit_z": lambda r: r.ptp(r.spider[2]),
    "converged": lambda r: r.worst_result() == RESULTS.successful,
    "max_residual": lambda r: r.extreme(jnp.abs(r.sol.residual), "max"),
    "error_estimate": lambda r: (
        r.sol.series.error_estimate
        if r.sol.series is not None
        else r.extreme(r.sol.error_estimate, "max")
    ),
    "result": lambda r: r.worst_result(),
}
NEEDS_RATES = ("irregularity",)
METRICS = tuple(_METRICS)
# Formed from the PeriodSeries where the solution carries one (no array over the grid's angles).
FROM_SERIES = (
    "delta_pp",
    "irregularity",
    "gamma_pp",
    "gamma_max",
    "ecc_max",
    "converged",
    "error_estimate",
    "result",
)


def metrics_from(
    layout: Layout,
    sol: HalfshaftSolution,
    rates: HalfshaftSolution | None,
    names: Iterable[str],
) -> dict[str, jax.Array]:
    """The named kinematic metrics (KinematicMetrics field names) from a [`revolution`][tripodjax.kinematics.revolution].

    Only the metrics named are built (``rates`` may be None unless
    ``"irregularity"`` is asked for). Returns a dict name → scalar array;
    differentiable like [`kinematic_metrics`][tripodjax.kinematics.kinematic_metrics]. E.g. for an optimiser::

        sol, rates = revolution(layout, 120, "newton", with_rates=True)
        m = metrics_from(layout, sol, rates, ("irregularity", "ecc_max", "gamma_pp",
                                              "roller_axial_stroke", "result"))
    """
    return metrics_and_window(layout, sol, rates, names, "auto")[0]


def metrics_and_window(
    layout: Layout,
    sol: HalfshaftSolution,
    rates: HalfshaftSolution | None,
    names: Iterable[str],
    extremes: str,
) -> tuple[dict[str, jax.Array], jax.Array | None]:
    """[`metrics_from`][tripodjax.kinematics.metrics_from] with the series' extremes taken per ``extremes``.

    ``extremes``: ``"grid"``, ``"window"`` or ``"auto"`` (see ``_Revolution``). Returns the
    metrics and whether the window holds the grid's extremes (per layout; None where
    no extreme of a [`PeriodSeries`][tripodjax.halfshaft.PeriodSeries] was formed). A batch
    evaluation takes ``"window"`` for every layout, and ``"grid"`` for the batch unless
    the window holds for all of it (e.g. [`sweep`][tripodjax.sweep.sweep]): ``"auto"``
    under ``vmap`` evaluates both.
    """
    r = _Revolution(layout, sol, rates, extremes)
    metrics = {name: _METRICS[name](r) for name in names}
    return metrics, r.window_holds()


def kinematic_metrics(
    layout: Layout,
    n_theta: int = 360,
    solver: solvers.SolverLike = "newton",
    *,
    throw: bool = False,
    fidelity: str | None | solvers._Unset = solvers._UNSET,
) -> KinematicMetrics:
    """Kinematic metrics of a halfshaft layout over one revolution.

    Args:
        layout: a [`Layout`][tripodjax.layout.Layout] with scalar fields (vmap over
            layouts for batches, or use [`tripodjax.sweep`][tripodjax.sweep.sweep]).
        n_theta: input angles per revolution, a multiple of 6; only the
            first period (n_theta/3 angles) is solved, see [`period_grid`][tripodjax.kinematics.period_grid].
        solver: [`Newton`][tripodjax.solvers.Newton] (``"newton"``, default) —
            the implicit solve converged to the dtype's tolerance;
            [`Analytic`][tripodjax.solvers.Analytic] (``"analytic"``) — the closed
            form plus two Newton corrections in plain arithmetic at 8 angles
            per period, interpolated to the grid; over the whole domain
            within 1.3e-5 (irregularity), 5e-6 (delta_pp), 4e-7 (ecc_max),
            1.1e-6 (gamma_pp), and an order of magnitude faster than newton
            in sweeps with the default outputs (the documentation's "Speed
            and accuracy" page gives the measured ratios; one layout at
            a time the call's own overhead dominates);
            ``"closed_form"`` — the closed form alone (see [`tripodjax.solvers`][tripodjax.solvers]).
        throw: raise [`SolverError`][tripodjax.solvers.SolverError] naming the first
            angle θ whose solve did not succeed. Outside ``jax.jit`` only.
        fidelity: older spelling of ``solver`` (a shorthand string).

    Returns:
        [`KinematicMetrics`][tripodjax.kinematics.KinematicMetrics]. Jit-compiled (``n_theta`` and ``solver``
        are static). Every float field is differentiable (``jax.grad``,
        ``jax.jacfwd``) w.r.t. every Layout field, and at γ0 = 0 ``jax.grad``
        gives the one-sided derivative (irregularity 1.5 R/l, delta_pp
        R/(2l), roller_axial_stroke 2R per radian of γ0). A metric is an
        extreme over the grid (or a difference of two): its derivative is that
        at the extreme's angle, the first of them where several tie;
        ``max_residual`` and ``error_estimate`` are not differentiated (0).
    """
    check_layout(layout, one=True)
    check_flag("throw", throw)
    solver = solvers.resolve_legacy(solver, fidelity)
    n_theta = _check_n_theta(n_theta)
    metrics = _metrics_of_layout(layout, n_theta, solver)
    if throw:
        raise_failure_of_revolution(metrics.result, layout, n_theta, solver, "kinematic_metrics")
    return metrics


def _every_metric(layout, n_theta, solver):
    sol, rates = revolution(layout, n_theta, solver, with_rates=True)
    return KinematicMetrics(**metrics_from(layout, sol, rates, METRICS))


@functools.partial(latency_bound_at_top_level, static_argnames=("n_theta", "solver"))
def _metrics_and_jacobian(layout, *, n_theta, solver):
    """Every metric of one layout and its Jacobian w.r.t. the layout's floating-point fields.

    One program: a plain call and a derivative (``jax.grad``, ``jax.jacfwd``) of the same
    layout run this same compiled program, where a forward program and a JVP program were
    compiled before (the README's first example paid both; see docs/speed-accuracy.md).
    Under ``jax.jit`` of a plain call, the unused Jacobian is removed by the compiler.

    Each metric is an extreme (or a difference of two) over the grid's angles and rollers,
    and its derivative that of its value at the extreme's position (Danskin's theorem;
    ``_Revolution.extreme``): the Jacobian is a linearisation (forward mode, one direction
    per field) of the revolution at those few angles, not at the grid's n_theta/3. An
    interpolating level's series extremes linearise the revolution at every angle.
    """
    leaves, tree = jax.tree_util.tree_flatten(layout)
    moving = differentiable(leaves)

    def with_fields(fields):
        args = list(leaves)
        for i, value in zip(moving, fields, strict=True):
            args[i] = value
        return tree.unflatten(args)

    def metrics_of(r):
        return KinematicMetrics(**{name: _METRICS[name](r) for name in METRICS})

    fields = [leaves[i] for i in moving]
    sol, rates = revolution(layout, n_theta, solver, with_rates=True)
    if not fields:
        return metrics_of(_Revolution(layout, sol, rates)), None
    dtype = jnp.result_type(*fields)
    basis = jnp.eye(len(fields), dtype=dtype)

    def directions(e):
        return tuple(e[k].astype(f.dtype) for k, f in enumerate(fields))

    if sol.series is not None:
        return values_and_jacobian(lambda lay: _every_metric(lay, n_theta, solver), layout)
    values, columns, recorded = {}, {}, []
    for group in _JACOBIAN_GROUPS:
        grid = _Revolution(layout, sol, rates, record=True)
        values.update({name: _METRICS[name](grid) for name in group})
        recorded.append(grid.positions)
    # Every group's angles padded to one count (with its first): one trace of the solve.
    count = max(len(picks) for picks in recorded)
    for group, picks in zip(_JACOBIAN_GROUPS, recorded, strict=True):
        angles = [angle for angle, _ in picks]
        index = jnp.stack(angles + angles[:1] * (count - len(angles)))
        theta = sol.theta[index]
        # Newton's solution at those angles, differentiated there (implicit function theorem)
        # without solving again; another level's answer is its own function of the layout.
        known = jax.tree_util.tree_map(lambda a, index=index: a[index], sol)

        def at_picks(*fields, group=group, picks=picks, theta=theta, known=known):
            picked = with_fields(fields)
            if isinstance(solver, solvers.Newton):
                solve = functools.partial(_known_solution, picked, sol=known)
            else:
                solve = functools.partial(_solve_period, picked, solver=solver)
            solved = jax.jvp(solve, (theta,), (jnp.ones_like(theta),))
            r = _Revolution(picked, *solved, picks=picks)
            return {name: _METRICS[name](r) for name in group}

        columns.update(
            jax.vmap(lambda e, f=at_picks: jax.jvp(f, tuple(fields), directions(e))[1])(basis)
        )
    codes = _Revolution(layout, sol, rates)
    for name in METRICS:  # the result codes and diagnostics: not differentiated (halfshaft)
        if name not in values:
            values[name] = _METRICS[name](codes)
            columns[name] = jnp.zeros(len(fields), dtype)
    return KinematicMetrics(**values), KinematicMetrics(**columns)


# The metrics whose Jacobian comes from one linearisation of the revolution at their extremes'
# angles (``_metrics_and_jacobian``), grouped by the cost of the series that find those angles:
# a derivative of one metric (under ``jax.jit``, the others' removed) costs its group's series.
# The others are result codes and diagnostics (max_residual, error_estimate), not differentiated.
_JACOBIAN_GROUPS = (
    ("delta_pp", "irregularity", "gamma_pp", "gamma_max", "ecc_max"),
    (
        "roller_stroke",
        "roller_radial_max",
        "roller_axial_stroke",
        "spider_orbit_x",
        "spider_orbit_y",
        "spider_orbit_z",
    ),
)


@functools.partial(jax.custom_jvp, nondiff_argnums=(1, 2))
def _metrics_of_layout(layout, n_theta, solver):
    """Every metric of one layout; derivatives from its Jacobian w.r.t. the layout's fields.

    The JVP rule answers a tangent with the product of the Jacobian that
    ``_metrics_and_jacobian`` forms beside the metrics: a gradient (``jax.grad``, reverse
    mode) then transposes that small product alone, where transposing the revolution itself
    keeps some 170 arrays of the angle grid for its reverse pass, in a second and larger
    program. Derivatives of any order follow: the rule is itself differentiable.
    """
    return _metrics_and_jacobian(layout, n_theta=n_theta, solver=solver)[0]


def _metrics_of_layout_jvp(n_theta, solver, primals, tangents):
    return jvp_from_jacobian(
        lambda lay: _every_metric(lay, n_theta, solver),
        functools.partial(_metrics_and_jacobian, n_theta=n_theta, solver=solver),
        primals,
        tangents,
    )


_metrics_of_layout.defjvp(_metrics_of_layout_jvp, symbolic_zeros=True)


def raise_failure_of_revolution(
    result: ArrayLike,
    layout: Layout,
    n_theta: int,
    solver: solvers.SolverLike,
    what: str,
    index: int | None = None,
) -> None:
    """Raise SolverError for a revolution whose worst code is not successful, naming the angle.

    Solves the revolution again (concrete values, outside jit) to find the
    first failing θ; ``index`` names the layout in a batch.
    """
    if isinstance(result, jax.core.Tracer):
        raise TypeError(f"{what}: throw=True needs concrete values; it works outside jax.jit only")
    if int(np.max(np.asarray(result))) == RESULTS.successful:
        return
    sol, _ = revolution(layout, n_theta, solver, with_rates=False)
    prefix = f"layout {index}, " if index is not None else ""
    raise_first_failure(sol.result, sol.theta, what, index_prefix=prefix)
