"""Augmented-Lagrangian optimiser for the joint-design problem, on optax's L-BFGS.

Bounds are handled by reparametrisation, x = lo + (hi − lo)·sigmoid(z); the
inequality constraints c_i(x) ≥ 0 by the augmented Lagrangian

    L(z; λ, ρ) = f(x) + Σ_i [max(0, λ_i − ρ c_i)² − λ_i²] / (2ρ),

minimised over z by ``optax.lbfgs`` (zoom line search) for ``inner_steps``
iterations, after which λ_i ← max(0, λ_i − ρ c_i) and ρ grows while the
constraints stay violated. Gradients come from the implicit solver and the
differentiable Hertz and GAF models. Several starts (a deterministic grid over
the bounds) run at once through ``vmap``; so do the members of a layout family
and the weights of a Pareto sweep.

The solver asks for margins ≥ 10·tolerance, so the proposed design is
strictly feasible when re-evaluated. Stopping: the KKT residual — the largest of the projected gradient of the
Lagrangian f − Σ λ_i c_i w.r.t. x scaled by the bound widths, the constraint
violation and the complementarity |λ_i c_i| — below ``solver.tolerance``.
"""

import dataclasses
import functools
import math
import sys
import time

import jax
import jax.numpy as jnp
import numpy as np
import optax

from tripodjax.optimize.problem import (
    VARIABLES,
    bounds,
    compiled,
    constraint_names,
    limits,
    objective_and_margins,
    scenario,
)

RHO_START = 10.0
RHO_GROWTH = 4.0
RHO_MAX = 1e6
BOUND_TOLERANCE = 1e-6  # a variable this close (relative to its bound width) counts as on the bound
SAFETY = (
    10.0  # the solver asks for margins ≥ SAFETY · tolerance, so the design is strictly feasible
)


def start_points(spec):
    """Deterministic starts in z-space: a grid over the interior of the bounds."""
    n = spec["solver"]["starts"]
    per_axis = max(1, math.ceil(math.sqrt(n)))
    fractions = (np.arange(per_axis) + 0.5) / per_axis
    grid = np.array([(a, b) for a in fractions for b in fractions])[:n]
    return jnp.asarray(np.log(grid / (1 - grid)))


def _to_x(z, lower, upper):
    return lower + (upper - lower) * jax.nn.sigmoid(z)


def _kkt(spec, x, lam, params, lower, upper, offset):
    """KKT residual at x with multipliers λ (stationarity, feasibility, complementarity)."""

    def lagrangian(x):
        f, c, _ = objective_and_margins(spec, x, params)
        return f - jnp.dot(lam, c - offset)

    g = jax.grad(lagrangian)(x) * (upper - lower)
    at_lower = (x - lower) <= BOUND_TOLERANCE * (upper - lower)
    at_upper = (upper - x) <= BOUND_TOLERANCE * (upper - lower)
    g = jnp.where(at_lower & (g > 0), 0.0, g)
    g = jnp.where(at_upper & (g < 0), 0.0, g)
    _, c, _ = objective_and_margins(spec, x, params)
    c = c - offset
    stationarity = jnp.max(jnp.abs(g))
    feasibility = jnp.max(jnp.maximum(0.0, -c))
    complementarity = jnp.max(jnp.abs(lam * c))
    return jnp.maximum(stationarity, jnp.maximum(feasibility, complementarity))


def _outer_step(spec, z, lam, rho, params, lower, upper):
    """One augmented-Lagrangian iteration for one start: L-BFGS on z, then λ and ρ updates."""

    offset = SAFETY * spec["solver"]["tolerance"]

    def augmented(z):
        f, c, _ = objective_and_margins(spec, _to_x(z, lower, upper), params)
        c = c - offset
        return f + jnp.sum(jnp.maximum(0.0, lam - rho * c) ** 2 - lam**2) / (2.0 * rho)

    opt = optax.lbfgs(
        linesearch=optax.scale_by_backtracking_linesearch(
            max_backtracking_steps=20, store_grad=True
        )
    )
    value_and_grad = optax.value_and_grad_from_state(augmented)

    def inner(carry, _):
        z, state = carry
        value, grad = value_and_grad(z, state=state)
        updates, state = opt.update(grad, state, z, value=value, grad=grad, value_fn=augmented)
        return (optax.apply_updates(z, updates), state), None

    (z, _), _ = jax.lax.scan(inner, (z, opt.init(z)), None, length=spec["solver"]["inner_steps"])
    x = _to_x(z, lower, upper)
    f, c, _ = objective_and_margins(spec, x, params)
    c = c - offset
    new_lam = jnp.maximum(0.0, lam - rho * c)
    violation = jnp.max(jnp.maximum(0.0, -c))
    new_rho = jnp.where(
        violation > spec["solver"]["tolerance"], jnp.minimum(rho * RHO_GROWTH, RHO_MAX), rho
    )
    kkt = _kkt(spec, x, new_lam, params, lower, upper, offset)
    return z, new_lam, new_rho, f, c, kkt


_STEPS = {}


def _compiled_step(spec):
    """The jit-compiled outer step, vmapped over starts and then over scenarios (kept per Spec)."""
    key = id(spec)
    if key not in _STEPS:
        step = functools.partial(_outer_step, spec)
        per_start = jax.vmap(step, in_axes=(0, 0, 0, None, None, None))
        _STEPS[key] = (spec, jax.jit(jax.vmap(per_start, in_axes=(0, 0, 0, 0, None, None))))
    return _STEPS[key][1]


@dataclasses.dataclass
class Result:
    """Outcome of an optimisation (one scenario).

    Attributes:
        design: the proposed design {"R": mm, "d_roller": mm}.
        objective: its objective [–].
        constraints: name → {"value", "limit", "sense", "unit", "margin"}.
        kkt_residual: KKT residual at the design; converged when ≤ tolerance.
        converged: the KKT criterion was met within ``max_outer`` iterations.
        quantities: irregularity, GAF RMS [N], outer diameter [mm], static
            capacity [N·m], life [km], R/d of the design.
        history: per outer iteration, the best feasible objective and the KKT
            residual of the chosen start.
        starts: per start, its final design, objective, KKT residual and feasibility.
    """

    design: dict
    objective: float
    constraints: dict
    kkt_residual: float
    converged: bool
    quantities: dict
    history: dict
    starts: list
    multipliers: dict


class _Progress:
    def __init__(self, total, enabled):
        self.total, self.enabled, self.start = total, enabled, time.perf_counter()

    def update(self, i, kkt):
        if self.enabled:
            bar = "#" * int(30 * i / self.total)
            sys.stderr.write(
                f"\roptimize [{bar:<30}] outer {i}/{self.total}, KKT {kkt:.2e}, {time.perf_counter() - self.start:.1f} s"
            )
            sys.stderr.flush()

    def close(self):
        if self.enabled:
            sys.stderr.write("\n")
            sys.stderr.flush()


def _run(spec, scenarios, progress):
    """Optimise every scenario (dict of arrays with a leading axis) from every start."""
    step = _compiled_step(spec)
    lower, upper = (jnp.asarray(a) for a in bounds(spec))
    n_scenarios = next(iter(scenarios.values())).shape[0]
    z0 = start_points(spec)
    n_starts, n_constraints = z0.shape[0], len(constraint_names(spec))
    z = jnp.broadcast_to(z0, (n_scenarios,) + z0.shape)
    lam = jnp.zeros((n_scenarios, n_starts, n_constraints))
    rho = jnp.full((n_scenarios, n_starts), RHO_START)
    tolerance = spec["solver"]["tolerance"]
    history = {"objective": [], "kkt_residual": []}
    bar = _Progress(spec["solver"]["max_outer"], progress)
    done = np.zeros((n_scenarios, n_starts), bool)
    f = c = kkt = None
    for i in range(spec["solver"]["max_outer"]):
        state = (z, lam, rho)
        stepped = step(z, lam, rho, scenarios, lower, upper)
        if f is None:
            z, lam, rho, f, c, kkt = (np.asarray(a) for a in stepped)
        else:
            # A start that has met the KKT criterion stays where it is.
            keep = lambda old, new: np.where(
                done.reshape(done.shape + (1,) * (np.ndim(new) - 2)), old, new
            )  # noqa: E731
            z, lam, rho = (
                keep(np.asarray(o), np.asarray(n)) for o, n in zip(state, stepped[:3], strict=False)
            )
            f, c, kkt = (
                keep(o, np.asarray(n)) for o, n in zip((f, c, kkt), stepped[3:], strict=False)
            )
        done |= kkt <= tolerance
        best = _choose(f, c, kkt, tolerance)
        history["objective"].append(np.take_along_axis(f, best[:, None], 1)[:, 0])
        history["kkt_residual"].append(np.take_along_axis(kkt, best[:, None], 1)[:, 0])
        bar.update(i + 1, float(np.max(history["kkt_residual"][-1])))
        # Stop once each scenario's chosen start has converged and no other start can still beat it.
        best_f = np.take_along_axis(f, best[:, None], 1)
        settled = done | (f >= best_f - tolerance)
        if np.all(np.take_along_axis(done, best[:, None], 1)) and settled.all():
            break
    bar.close()
    z, lam = jnp.asarray(z), jnp.asarray(lam)
    x = np.asarray(jax.vmap(jax.vmap(lambda zz: _to_x(zz, lower, upper)))(z))
    return x, np.asarray(lam), np.asarray(f), np.asarray(c), np.asarray(kkt), history


def _choose(f, c, kkt, tolerance):
    """Per scenario, the start to report: feasible and converged first, then the lowest objective."""
    feasible = np.min(c, axis=-1) >= -tolerance
    score = np.where(feasible, f, np.inf) + np.where(kkt <= tolerance, 0.0, 1e-9)
    score = np.where(np.isfinite(score), score, f + 1e6 * np.maximum(0, -np.min(c, axis=-1)))
    return np.argmin(score, axis=-1)


def _results(spec, scenarios, outcome):
    x, lam, f, c, kkt, history = outcome
    best = _choose(f, c, kkt, spec["solver"]["tolerance"])
    names = constraint_names(spec)
    evaluate = compiled(spec)
    out = []
    for k, b in enumerate(best):
        params = {name: value[k] for name, value in scenarios.items()}
        objective, margins, q = evaluate(jnp.asarray(x[k, b]), params)
        quantities = {name: float(v) for name, v in q.items()}
        table = {}
        for name, m in zip(names, np.asarray(margins), strict=False):
            quantity, limit, sense, unit = limits(spec)[name]
            table[name] = {
                "value": quantities[quantity],
                "limit": limit,
                "sense": sense,
                "unit": unit,
                "margin": float(m),
            }
        out.append(
            Result(
                design={name: float(v) for name, v in zip(VARIABLES, x[k, b], strict=False)},
                objective=float(objective),
                constraints=table,
                kkt_residual=float(kkt[k, b]),
                converged=bool(kkt[k, b] <= spec["solver"]["tolerance"]),
                quantities=quantities,
                history={key: [float(v[k]) for v in values] for key, values in history.items()},
                starts=[
                    {
                        "design": {n: float(v) for n, v in zip(VARIABLES, x[k, s], strict=False)},
                        "objective": float(f[k, s]),
                        "kkt_residual": float(kkt[k, s]),
                        "feasible": bool(np.min(c[k, s]) >= -spec["solver"]["tolerance"]),
                    }
                    for s in range(x.shape[1])
                ],
                multipliers={name: float(v) for name, v in zip(names, lam[k, b], strict=False)},
            )
        )
    return out


def solve(spec, progress=None):
    """Propose the joint size (R, d_roller) for a spec: the best of all starts. Returns a :class:`Result`.

    ``progress``: a progress bar on standard error (default: when it is a terminal).
    Deterministic for a given spec. Runs in float64 (scoped to the call).
    """
    with jax.enable_x64(True):
        scenarios = {k: v[None] for k, v in scenario(spec).items()}
        outcome = _run(spec, scenarios, sys.stderr.isatty() if progress is None else progress)
        return _results(spec, scenarios, outcome)[0]


def solve_family(spec, *, gamma0_deg=None, l=None, progress=None):
    """The proposed size for each member of a layout family, optimised together (vmap).

    Give ``gamma0_deg`` (a sequence of layout angles [deg]) or ``l`` (shaft
    lengths [mm]); the other layout value comes from the spec. Returns a list
    of :class:`Result`, one per member.
    """
    if (gamma0_deg is None) == (l is None):
        raise ValueError("solve_family needs exactly one of gamma0_deg=[...] or l=[...]")
    with jax.enable_x64(True):
        base = scenario(spec)
        values = (
            np.radians(np.asarray(gamma0_deg, float))
            if gamma0_deg is not None
            else np.asarray(l, float)
        )
        name = "gamma0" if gamma0_deg is not None else "l"
        scenarios = {k: jnp.broadcast_to(v, values.shape) for k, v in base.items()}
        scenarios[name] = jnp.asarray(values)
        outcome = _run(spec, scenarios, sys.stderr.isatty() if progress is None else progress)
        return _results(spec, scenarios, outcome)


def pareto_front(spec, gaf_weights, progress=None):
    """Designs minimising w_gaf · GAF + w_size · size for each GAF weight (irregularity weight from the spec).

    Returns a list of :class:`Result`; their GAF RMS and outer diameter trace
    the front of GAF against joint size.
    """
    with jax.enable_x64(True):
        weights = jnp.asarray(np.asarray(gaf_weights, float))
        base = scenario(spec)
        scenarios = {k: jnp.broadcast_to(v, weights.shape) for k, v in base.items()}
        scenarios["w_gaf"] = weights
        outcome = _run(spec, scenarios, sys.stderr.isatty() if progress is None else progress)
        return _results(spec, scenarios, outcome)
