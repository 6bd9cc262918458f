"""Solver options for the halfshaft pair, as objects (in the manner of Optimistix's ``Newton``).

Every layer that solves the halfshaft ([`solve_halfshaft`][tripodjax.halfshaft.solve_halfshaft],
[`revolution`][tripodjax.kinematics.revolution], [`kinematic_metrics`][tripodjax.kinematics.kinematic_metrics],
the GAF functions of [`tripodjax.friction`][tripodjax.friction], [`sweep`][tripodjax.sweep.sweep] and the
bench) takes one ``solver=`` argument: an instance of

- [`Newton`][tripodjax.solvers.Newton] — the implicit-differentiated Newton solve, converged to a
  relative step tolerance (the reference level);
- [`Analytic`][tripodjax.solvers.Analytic] — the closed form plus a fixed number of Newton corrections
  in plain arithmetic, over a revolution at a few angles and interpolated:
  cheap, and accurate over the whole domain (see its docstring for the
  measured errors);
- [`ClosedForm`][tripodjax.solvers.ClosedForm] — the closed form alone (the seed's first order plus the
  γ ripple), kept for reproduction and as the cheapest level;

or one of the strings ``"newton"``, ``"analytic"``, ``"closed_form"`` as
shorthands for their defaults, resolved by [`resolve`][tripodjax.solvers.resolve] (the one place).

The objects are frozen and hashable, so they are static arguments of
``jax.jit``; they validate their settings once, at construction.
"""

import dataclasses
import enum
from collections.abc import Callable
from typing import Final, TypeAlias

import numpy as np

from tripodjax._checks import check_choice, check_integer, check_range, check_real

DEFAULT_MAX_STEPS = 24
MAX_MAX_STEPS = 1000
MIN_NODES, MAX_NODES = 4, 60


class SolverError(RuntimeError):
    """Raised by ``throw=True`` when a solve did not succeed; names the layout index and θ."""


def _check_rtol(rtol):
    if rtol is None:
        return None
    check_real("rtol", rtol, allowed="None or a real number 0 < rtol < 1")
    if np.ndim(rtol):
        raise TypeError(f"rtol = {rtol!r} is not allowed; allowed: None or a real number")
    return float(check_range("rtol", rtol, 0.0, 1.0, low_open=True, high_open=True))


def _check_steps(name, value, low, high):
    return int(check_integer(name, value, minimum=low, maximum=high))


@dataclasses.dataclass(frozen=True)
class Newton:
    """Newton iterations on the scaled pair, from the closed form, with implicit derivatives.

    Attributes:
        rtol: relative step tolerance: a point is done when the largest Newton
            step is at most ``rtol · (max(|Δ|, |v|) + e(γ0)/|h|)``. None (the
            default) means 32 machine epsilons of the working dtype (7e-15 in
            float64, 4e-6 in float32; the last step is applied, so the error
            is far below that). Must be in (0, 1).
        max_steps: iteration cap, an integer 1 … 1000; points that reach it
            report ``RESULTS.max_steps_reached``.

    The first 5 iterations (or ``max_steps`` if fewer) use polynomial sines of
    the small angles, exact to roundoff in their range, and the last of them is
    the stopping test; any point not settled then goes on with the exact sines
    until the step is below tolerance (see ``halfshaft._newton``). Measured over
    the whole domain (R/l ≤ 0.2, γ0 ≤ 45°): 5 iterations in all, none with the
    exact sines, in float32 and float64; metrics exact to roundoff.
    """

    rtol: float | None = None
    max_steps: int = DEFAULT_MAX_STEPS

    def __post_init__(self) -> None:
        object.__setattr__(self, "rtol", _check_rtol(self.rtol))
        object.__setattr__(
            self, "max_steps", _check_steps("max_steps", self.max_steps, 1, MAX_MAX_STEPS)
        )


@dataclasses.dataclass(frozen=True)
class Analytic:
    """The closed form plus ``corrections`` Newton steps in plain arithmetic (no loop, no check).

    The sines and cosines of the small angles Δ/2 and (γ − γ0)/2 in the
    corrections are odd/even Taylor polynomials (exact to < 1e-12 relative
    for the |Δ| ≤ 0.06 of the domain), so a correction costs only
    multiplications. Derivatives are forward-mode AD through the arithmetic.
    Over a revolution the level solves at ``nodes`` angles per period only
    and interpolates (see ``nodes``).

    Accuracy, measured against converged float64 Newton over the whole domain
    (2000 layouts, R/l ≤ 0.2, 0 ≤ γ0 ≤ 45°, worst at R/l = 0.2, γ0 = 45°),
    float32 or float64 alike, with the defaults (two corrections, 8 nodes):
    irregularity 1.3e-5, delta_pp 5e-6, gamma_pp 1.1e-6, ecc_max 4e-7
    (the interpolation's share; at every angle, ``nodes=None``: below 2e-6).
    One correction: irregularity 1.2e-3, delta_pp 3e-4, gamma_pp 3.8e-3,
    ecc_max 1.2e-3; the closed form alone: 4.2 %, 0.6 %, 23 %, 7.3 %.
    Speed (``python -m tripodjax.bench``): an order of magnitude faster than newton with
    [`sweep`][tripodjax.sweep.sweep]'s default outputs (newton itself solves with no
    transcendental function); the documentation's "Speed and accuracy" page gives the
    measured ratios per dtype, and each output's cost, with the CPU they were measured on.

    Every point carries an error estimate (the next Newton step with exact
    sines, relative to the first-order amplitude e(γ0)/|h|; over a revolution
    formed at the nodes and midway between them, see ``nodes``), and points
    whose estimate exceeds ``validity`` report ``RESULTS.outside_validity``.

    Attributes:
        corrections: Newton corrections after the closed form, an integer 0 … 4
            (0 is [`ClosedForm`][tripodjax.solvers.ClosedForm]).
        validity: largest accepted error estimate [–], in (0, 1); default 1e-2.
        nodes: over a revolution ([`revolution`][tripodjax.kinematics.revolution]: kinematic
            metrics, GAF, sweeps, the optimiser), solve at this many
            equispaced angles of one period and carry the answer to the grid
            by trigonometric interpolation
            ([`trigonometric_interpolation`][tripodjax.halfshaft.trigonometric_interpolation]):
            an even integer 4 … 60, default 8, or None to solve at every
            angle. Δ and v are smooth in θ (each harmonic about 50× below the
            one before at R/l = 0.2, γ0 = 45°), so 8 nodes add < 3e-5 relative
            to the errors above (measured over the domain) and make the level
            many times faster. Only nodes/2 of them are solved: at θ = 0 the
            answer is exact, and Δ is odd and v even in θ, so the other half
            of the period mirrors the first. The error estimate and result
            codes are formed at the nodes and midway between them (where the
            interpolation errs most) on half the period, ``nodes`` angles (θ = 0
            is exact), so they include the interpolation at a fraction of the
            cost of forming them at every grid angle; over such a revolution
            the estimate is one number (the largest), reported at every angle.
            The peak-to-peak metrics come from the nodes' sine and cosine
            series on half the period, at the few angles where their extremes
            provably lie (see [`metrics_and_window`][tripodjax.kinematics.metrics_and_window]),
            not from every angle.
    """

    corrections: int = 2
    validity: float = 1e-2
    nodes: int | None = 8

    def __post_init__(self) -> None:
        object.__setattr__(self, "corrections", _check_steps("corrections", self.corrections, 0, 4))
        validity = check_range("validity", self.validity, 0.0, 1.0, low_open=True, high_open=True)
        object.__setattr__(self, "validity", float(validity))
        if self.nodes is not None:
            nodes = _check_steps("nodes", self.nodes, MIN_NODES, MAX_NODES)
            if nodes % 2:
                raise ValueError(
                    f"nodes = {nodes} is not allowed; allowed: None or an even integer "
                    f"{MIN_NODES} ≤ nodes ≤ {MAX_NODES}"
                )
            object.__setattr__(self, "nodes", nodes)


def ClosedForm(validity: float = 1.0 - 1e-9, nodes: int | None = 8) -> "Analytic":  # noqa: N802 — a solver "class" like the others
    """The closed form alone: [`Analytic`][tripodjax.solvers.Analytic] with no correction.

    The seed's first order (§2.11) plus the γ ripple; over the whole domain it
    is off by up to 4.2 % (irregularity), 0.6 % (delta_pp), 7.3 % (ecc_max)
    and 23 % (gamma_pp) at R/l = 0.2, γ0 = 45°; within 0.4 % in irregularity
    for R 18–42 mm, l 300–800 mm, γ0 5–25°. Its error estimate is reported, and
    by default never flags ``outside_validity``. At given angles
    ([`solve_halfshaft`][tripodjax.halfshaft.solve_halfshaft]) it is the
    printed formula at each angle; over a revolution it is evaluated at
    ``nodes`` angles per period and interpolated as ``Analytic`` is (the
    interpolation's < 3e-5 relative is far below the level's own error), so its
    error estimate costs ``nodes`` evaluations per period, not one per angle.
    """
    return Analytic(corrections=0, validity=validity, nodes=nodes)


Solver: TypeAlias = Newton | Analytic
"""A solver object: [`Newton`][tripodjax.solvers.Newton] or [`Analytic`][tripodjax.solvers.Analytic] (incl. ``ClosedForm()``)."""

SolverLike: TypeAlias = Newton | Analytic | str
"""What a ``solver=`` argument takes: a solver object or a shorthand string."""

SHORTHANDS: Final[dict[str, Callable[[], Solver]]] = {
    "newton": Newton,
    "analytic": Analytic,
    "closed_form": ClosedForm,
}


def resolve(solver: SolverLike) -> Solver:
    """The solver object for a ``solver=`` argument: an instance, or a shorthand string."""
    if isinstance(solver, Newton | Analytic):
        return solver
    if isinstance(solver, str):
        return SHORTHANDS[check_choice("solver", solver, tuple(SHORTHANDS))]()
    raise TypeError(
        f"solver = {solver!r} is not allowed; allowed: a Newton(...) or Analytic(...) "
        f"instance, or one of {', '.join(repr(s) for s in SHORTHANDS)}"
    )


def name(solver: Solver) -> str:
    """A short label: ``"newton"``, ``"analytic"`` or ``"closed_form"``."""
    if isinstance(solver, Newton):
        return "newton"
    return "closed_form" if solver.corrections == 0 else "analytic"


class _Unset(enum.Enum):
    """The type of `_UNSET`: the default of an older keyword that was not given."""

    UNSET = enum.auto()

    def __repr__(self) -> str:
        return "_UNSET"


_UNSET: Final = _Unset.UNSET


def resolve_legacy(
    solver: SolverLike,
    fidelity: str | None | _Unset = _UNSET,
    rtol: float | None | _Unset = _UNSET,
    max_steps: int | _Unset = _UNSET,
) -> Solver:
    """[`resolve`][tripodjax.solvers.resolve], also honouring the older keywords ``fidelity=``, ``rtol=``, ``max_steps=``.

    ``fidelity`` is a shorthand string (as ``solver``; when given, even as
    None, it is checked like any choice and replaces ``solver``);
    ``rtol``/``max_steps`` build a [`Newton`][tripodjax.solvers.Newton] (validated by it;
    ``rtol=None`` is its default tolerance). Kept for compatibility: prefer
    one ``solver=`` object.
    """
    if fidelity is not _UNSET:
        solver = SHORTHANDS[check_choice("fidelity", fidelity, tuple(SHORTHANDS))]()
    solver = resolve(solver)
    if rtol is _UNSET and max_steps is _UNSET:
        return solver
    if not isinstance(solver, Newton):
        raise ValueError(
            "rtol and max_steps apply to the Newton solver only; pass solver=Newton(...)"
        )
    return Newton(
        rtol=solver.rtol if rtol is _UNSET else rtol,
        max_steps=solver.max_steps if max_steps is _UNSET else max_steps,
    )
