"""Augmented-Lagrangian optimiser for the joint-design problem, on optax's L-BFGS.

Bounds are handled by reparametrisation, x = lo + (hi − lo)·sigmoid(z), which
also scales every variable to the width of its bounds (mm, rad and unitless
constants converge alike); the inequality constraints c_i(x) ≥ 0 by the
augmented Lagrangian

    L(z; λ, ρ) = f(x) + Σ_i [max(0, λ_i − ρ c_i)² − λ_i²] / (2ρ),

minimised over z by ``optax.lbfgs`` (backtracking line search; where the decrease it asks
for is below L's roundoff, the slope at the trial point decides) for at most
``inner_steps`` iterations (fewer once the projected gradient of L w.r.t. x, scaled by
the bound widths as in the KKT residual below, is ≤ tolerance/10, or once a line search
finds no step; where L-BFGS offers no descent direction, a steepest-descent step of unit
length in z), after which λ_i ← max(0, λ_i − ρ c_i) and ρ grows
while the constraints stay violated. Each outer iteration evaluates the
objective, the margins and their Jacobian once (forward mode through the
implicit halfshaft solve) and stops a problem when its KKT residual — the
largest of the projected gradient of the Lagrangian f − Σ λ_i c_i w.r.t. x
scaled by the bound widths, the constraint violation and the complementarity
|λ_i c_i| — is below ``solver.tolerance``. The solver asks for margins
≥ 2·tolerance, so the proposed design is strictly feasible when re-evaluated.

Every problem of a call — each start of each scenario (the spec's own, the
members of a layout family, the weights of a Pareto sweep) — is one entry of a
single flat batch: one ``vmap`` over a ``while_loop``, compiled once per spec
*structure* and batch size. The spec's numbers are traced, so solving a spec
that differs only in its numbers reuses the compiled code.
"""

import dataclasses
import functools
import math
from collections.abc import Sequence

import jax
import jax.numpy as jnp
import numpy as np
import optax

from tripodjax._checks import check_layout_domain
from tripodjax.optimize._compiled import batch_rows, call, latency_bound_jit
from tripodjax.optimize.problem import (
    bounds,
    check_spec,
    constraint_names,
    fixed_design,
    limits,
    objective_and_margins,
    to_spec_units,
)
from tripodjax.optimize.spec import MAX_OUTER_ITERATIONS, Spec, Structure
from tripodjax.progress import ProgressMeter, resolve
from tripodjax.results import RESULTS

RHO_START = 10.0
RHO_GROWTH = 4.0
RHO_MAX = 1e6
ARMIJO = 1e-4  # sufficient-decrease constant of the backtracking search
# Relative size of L's roundoff as the line search judges it: where the decrease Armijo asks
# for is below this, the slope at the trial point decides (Hager & Zhang's approximate Wolfe).
VALUE_NOISE = 1e-12
BACKTRACK = 0.5  # step reduction per backtrack
MAX_BACKTRACKS = 30
INNER_FRACTION = 0.1  # an inner run stops at a projected, width-scaled |∂L/∂x| ≤ this · tolerance
# The solver asks for margins ≥ SAFETY · tolerance, so the design is strictly feasible (by at
# least one tolerance once the KKT criterion holds) and moves by ~2·tolerance relative at most.
SAFETY = 2.0
# A start that did not converge but whose KKT residual and violation are within this many
# tolerances ranks with the feasible starts (Ipopt's acceptable_tol / tol, 1e-6 / 1e-8).
ACCEPTABLE = 100.0
# The constraints a least-squares multiplier estimate may use: margins within this many
# tolerances of zero (the augmented Lagrangian keeps its active ones within one).
NEAR_ACTIVE = 10.0
_PRIMES = (2, 3, 5, 7, 11, 13, 17)


def start_points(structure):
    """Deterministic starts in z-space: a grid (≤ 2 free variables) or a Halton set over the bounds."""
    n, k = len(structure.free), structure.starts
    if n <= 2:
        per_axis = max(1, math.ceil(k ** (1.0 / n)))
        fractions = (np.arange(per_axis) + 0.5) / per_axis
        grid = np.stack(np.meshgrid(*[fractions] * n, indexing="ij"), -1).reshape(-1, n)[:k]
    else:
        grid = np.full((k, n), 0.5)
        for i in range(1, k):  # the box centre first, then Halton points
            for j in range(n):
                f, r, m = 1.0, 0.0, i
                while m:
                    f /= _PRIMES[j]
                    r += f * (m % _PRIMES[j])
                    m //= _PRIMES[j]
                grid[i, j] = 0.05 + 0.9 * r
    return np.log(grid / (1.0 - grid))


def _evaluation(structure, values):
    """Functions of one problem: x(z), and (f, c, ∇f, J, q, code) at x by forward mode."""
    lower, upper = bounds(structure, values)

    def to_x(z):
        return lower + (upper - lower) * jax.nn.sigmoid(z)

    def with_jacobian(x):
        return _linearised(structure, values, x)

    return lower, upper, to_x, with_jacobian


@functools.partial(jax.jit, static_argnums=0)
def _linearised(structure, values, x):
    """(f, c − offset, ∇f, J, q, code) at x, the Jacobian by forward mode over every direction.

    A jitted function of the structure and the problem's arrays, not a closure: its trace is
    cached by their shapes, so the loop's first carry (`_zero_evaluation`) and the loop's
    body share one trace of the model (a closure made anew by each of `_problem`'s pieces
    was traced twice: 4.3 s of the chance-constrained solve's 11.9 s of tracing, measured).
    """
    offset = SAFETY * values["solver"]["tolerance"]

    def vector(x):
        f, c, q, code = objective_and_margins(structure, values, x)
        return jnp.concatenate([f[None], c - offset]), (q, code)

    def directional(t):
        return jax.jvp(vector, (x,), (t,), has_aux=True)

    basis = jnp.eye(x.shape[0], dtype=x.dtype)
    value, jac, (q, code) = jax.vmap(directional, out_axes=(None, 0, None))(basis)
    return value[0], value[1:], jac[:, 0], jac[:, 1:].T, q, code


def _zero_evaluation(with_jacobian, x):
    """Zeros shaped as ``with_jacobian(x)`` (the loop's first carry), from its shapes alone
    (the trace that gives them is the one the loop's body reuses)."""
    shapes = jax.eval_shape(with_jacobian, x)
    return jax.tree_util.tree_map(lambda a: jnp.zeros(a.shape, a.dtype), shapes)


def _stationarity(x, g, lower, upper):
    """The projected-gradient step ‖x − P(x − g)‖∞ with x and g scaled by the bound widths
    (P the projection on the box, Conn, Gould & Toint 1988): a component pushing a variable
    out of its box counts up to the variable's distance to that bound, so a variable that
    has come within the tolerance of its bound is stationary there however steep its slope."""
    width = upper - lower
    g = g * width
    towards_lower = jnp.minimum(g, (x - lower) / width)
    towards_upper = jnp.minimum(-g, (upper - x) / width)
    return jnp.max(jnp.where(g > 0, towards_lower, towards_upper))


def _kkt(x, lam, c, grad_f, jac, lower, upper):
    """KKT residual (stationarity scaled by the bound widths, feasibility, complementarity)."""
    stationarity = _stationarity(x, grad_f - jac.T @ lam, lower, upper)
    feasibility = jnp.max(jnp.maximum(0.0, -c))
    complementarity = jnp.max(jnp.abs(lam * c))
    return jnp.maximum(stationarity, jnp.maximum(feasibility, complementarity))


def _fitted_multipliers(x, c, grad_f, jac, lower, upper, tolerance):
    """First-order multiplier estimate: λ ≥ 0 minimising ‖(∇f − Jᵀλ) ⊙ width‖ over the
    variables off their bounds, with λ_i = 0 unless c_i ≤ NEAR_ACTIVE · tolerance; a column
    whose estimate is negative is dropped and the rest refitted once.

    At a vertex of the constraints, the augmented Lagrangian's update λ − ρ c recovers the
    multipliers only as fast as c settles within 1/ρ of zero, and the design is there long
    before (Nocedal & Wright, Numerical Optimization, §17.3; the least-squares estimate
    of §18.3).
    """
    width = upper - lower
    off_bound = jnp.minimum(x - lower, upper - x) > tolerance * width
    rows = jnp.where(off_bound[:, None], jac.T * width[:, None], 0.0)
    target = jnp.where(off_bound, grad_f * width, 0.0)
    keep = c <= NEAR_ACTIVE * tolerance
    for _ in range(2):
        a = jnp.where(keep[None, :], rows, 0.0)
        normal = a.T @ a
        # a dropped column's row of the normal equations is λ_i = 0; a tiny ridge on the
        # kept ones for constraints whose gradients coincide
        ridge = jnp.where(keep, 1e-12 * jnp.trace(normal), 1.0)
        lam = jnp.linalg.solve(normal + jnp.diag(ridge), a.T @ target)
        keep = keep & (lam > 0)
    return jnp.where(keep, lam, 0.0)


def _problem(structure, values, z0, x_eval, evaluate_only):
    """The optimisation of one problem from start z0: ``(initial, iterate, answer)``.

    ``initial()`` is the loop's first state, ``iterate(state)`` one iteration, ``answer(state)``
    the dict of arrays [`solve_batch`][tripodjax.optimize.solver.solve_batch] returns. Each
    iteration evaluates the model once (with its Jacobian, forward mode) at a trial point and
    then plays the role that point has: a line-search trial of the inner L-BFGS run, the end
    of that run (multiplier and penalty update, KKT check), or the start; ``state["done"]``
    ends it. One copy of the model in the compiled program keeps tracing and compilation short.

    With ``evaluate_only`` (traced) the loop stops after its first evaluation, made at
    ``x_eval`` (internal units, not bound to the box) instead of x(z0): the same compiled
    program then serves [`evaluate_points`][tripodjax.optimize.solver.evaluate_points].
    """
    lower, upper, to_x, with_jacobian = _evaluation(structure, values)
    tolerance = values["solver"]["tolerance"]
    offset = SAFETY * tolerance
    dtype = z0.dtype
    lbfgs = optax.scale_by_lbfgs()

    def augmented(z, lam, rho, f, c, grad_f, jac):
        """L(z; λ, ρ), ∂L/∂z and the projected stationarity of L in x (see ``_stationarity``)
        from an evaluation at x(z)."""
        sig = jax.nn.sigmoid(z)
        active = jnp.maximum(0.0, lam - rho * c)
        value = f + jnp.sum(active**2 - lam**2) / (2.0 * rho)
        grad_x = grad_f - jac.T @ active
        grad = grad_x * (upper - lower) * sig * (1.0 - sig)
        stationarity = _stationarity(to_x(z), grad_x, lower, upper)
        return jnp.where(jnp.isfinite(value), value, jnp.inf), grad, stationarity

    def pick(flag, new, old):
        return jax.tree_util.tree_map(lambda a, b: jnp.where(flag, a, b), new, old)

    def initial():
        evaluation = _zero_evaluation(with_jacobian, to_x(z0))
        # One entry per outer iteration, for any solver.max_outer (a number, not structure).
        nan_history = jnp.full((MAX_OUTER_ITERATIONS + 1,), jnp.nan, dtype)
        return dict(
            start=jnp.bool_(True),
            done=jnp.bool_(False),
            k=jnp.int32(0),  # outer iterations finished
            i=jnp.int32(0),  # accepted steps of the current inner run
            j=jnp.int32(0),  # backtracks of the current line search
            inner_iterations=jnp.int32(0),
            z=z0,
            evaluation=evaluation,
            lam=jnp.zeros_like(evaluation[1]),
            multipliers=jnp.zeros_like(evaluation[1]),  # those of the KKT residual in "kkt"
            rho=jnp.asarray(RHO_START, dtype),
            kkt=jnp.asarray(jnp.inf, dtype),
            value=jnp.asarray(jnp.inf, dtype),
            grad=jnp.zeros_like(z0),
            direction=jnp.zeros_like(z0),
            slope=jnp.asarray(0.0, dtype),
            alpha=jnp.asarray(0.0, dtype),
            memory=lbfgs.init(z0),
            history_objective=nan_history,
            history_kkt=nan_history,
        )

    x_eval = to_x(z0) if x_eval is None else x_eval

    def iterate(s):
        y = s["z"] + s["alpha"] * s["direction"]
        trial = with_jacobian(jnp.where(s["start"] & evaluate_only, x_eval, to_x(y)))
        f, c, grad_f, jac = trial[:4]
        value, grad, stationarity = augmented(y, s["lam"], s["rho"], f, c, grad_f, jac)
        armijo = value <= s["value"] + ARMIJO * s["alpha"] * s["slope"]
        # Near a solution the decrease Armijo asks for falls below L's roundoff and the search
        # would stall on noise; there the exact slope decides: φ'(α) ≤ (2·ARMIJO − 1)·φ'(0),
        # which on a quadratic is the Armijo condition itself (Hager & Zhang 2005).
        flat = value <= s["value"] + VALUE_NOISE * jnp.abs(s["value"])
        approximate = flat & (jnp.dot(grad, s["direction"]) <= (2 * ARMIJO - 1) * s["slope"])
        accepted = s["start"] | armijo | approximate
        j = jnp.where(accepted, 0, s["j"] + 1)
        stalled = jnp.logical_and(jnp.logical_not(accepted), j >= MAX_BACKTRACKS)
        z = jnp.where(accepted, y, s["z"])
        current = pick(accepted, trial, s["evaluation"])
        value = jnp.where(accepted, value, s["value"])
        grad = jnp.where(accepted, grad, s["grad"])
        step = jnp.logical_and(accepted, jnp.logical_not(s["start"]))
        i = s["i"] + step.astype(jnp.int32)
        # Measured in x as the KKT residual measures it, not in z: in z a variable driven
        # onto its bound would be pushed on into the sigmoid's flat tail (σ' ~ 1e-12 at
        # tolerance 1e-8), from which no later run could bring it back.
        small = stationarity <= INNER_FRACTION * tolerance
        run_over = jnp.logical_or(i >= values["solver"]["inner_steps"], small)
        inner_over = s["start"] | stalled | (step & run_over)
        # The end of an inner run: multipliers, penalty, KKT residual (no update at the start).
        f, c, grad_f, jac = current[:4]
        first = s["k"] == 0
        lam_new = jnp.where(first, s["lam"], jnp.maximum(0.0, s["lam"] - s["rho"] * c))
        violated = jnp.max(jnp.maximum(0.0, -c)) > tolerance
        grow = jnp.logical_and(jnp.logical_not(first), violated)
        rho_new = jnp.where(grow, jnp.minimum(s["rho"] * RHO_GROWTH, RHO_MAX), s["rho"])
        kkt = _kkt(to_x(z), lam_new, c, grad_f, jac, lower, upper)
        # the KKT test also with the multipliers fitted at z (see _fitted_multipliers)
        fitted = _fitted_multipliers(to_x(z), c, grad_f, jac, lower, upper, tolerance)
        kkt_fitted = _kkt(to_x(z), fitted, c, grad_f, jac, lower, upper)
        better = kkt_fitted < kkt
        multipliers = jnp.where(better, fitted, lam_new)
        kkt = jnp.where(better, kkt_fitted, kkt)
        kkt = jnp.where(jnp.isfinite(kkt), kkt, jnp.inf)
        done = inner_over & ((kkt <= tolerance) | (s["k"] >= values["solver"]["max_outer"]))
        done = done | evaluate_only
        lam = jnp.where(inner_over, lam_new, s["lam"])
        rho = jnp.where(inner_over, rho_new, s["rho"])
        # A new inner run starts from z on the updated Lagrangian.
        restart_value, restart_grad, _ = augmented(z, lam, rho, f, c, grad_f, jac)
        value = jnp.where(inner_over, restart_value, value)
        grad = jnp.where(inner_over, restart_grad, grad)
        memory = pick(inner_over, lbfgs.init(z), s["memory"])
        # A new direction after an accepted step or a restart; else halve the step.
        fresh = accepted | inner_over
        direction, new_memory = lbfgs.update(grad, memory, z)
        direction = -direction
        slope = jnp.dot(grad, direction)
        # Not a descent direction (negative curvature in the memory, as where sigmoid(z) bends
        # towards a bound): steepest descent of unit length in z, so that the line search
        # starts at a step of the sigmoid's own scale however small the gradient.
        descent = slope < 0
        norm = jnp.sqrt(jnp.dot(grad, grad))
        unit = -grad / jnp.where(norm > 0, norm, 1.0)
        direction = jnp.where(descent, direction, unit)
        slope = jnp.where(descent, slope, -norm)
        k = s["k"]
        return dict(
            start=jnp.bool_(False),
            done=done,
            k=k + inner_over.astype(jnp.int32),
            i=jnp.where(inner_over, 0, i),
            j=jnp.where(inner_over, 0, j),  # a new run, a new line search
            inner_iterations=s["inner_iterations"] + step.astype(jnp.int32),
            z=z,
            evaluation=current,
            lam=lam,
            rho=rho,
            kkt=jnp.where(inner_over, kkt, s["kkt"]),
            multipliers=jnp.where(inner_over, multipliers, s["multipliers"]),
            value=value,
            grad=grad,
            direction=jnp.where(fresh, direction, s["direction"]),
            slope=jnp.where(fresh, slope, s["slope"]),
            alpha=jnp.where(fresh, 1.0, s["alpha"] * BACKTRACK),
            memory=pick(fresh, new_memory, memory),
            history_objective=jnp.where(
                inner_over, s["history_objective"].at[k].set(f), s["history_objective"]
            ),
            history_kkt=jnp.where(inner_over, s["history_kkt"].at[k].set(kkt), s["history_kkt"]),
        )

    def answer(s):
        f, c, grad_f, jac, q, code = s["evaluation"]
        return dict(
            gradient=grad_f,
            jacobian=jac,
            x=to_x(s["z"]),
            lam=s["multipliers"],
            objective=f,
            margins=c + offset,
            kkt=s["kkt"],
            code=code,
            outer_iterations=s["k"] - 1,
            inner_iterations=s["inner_iterations"],
            quantities=q,
            history_objective=s["history_objective"],
            history_kkt=s["history_kkt"],
        )

    return initial, iterate, answer


def evaluate_points(structure, values, x):
    """(f, c − offset, ∇f, J, quantities, codes) at each row of a batch of (values, x).

    ``values`` has a leading row axis on every leaf, ``x`` is (rows, free variables) in
    internal units (not bound to the box); forward mode, exact in x. The rows go
    through the compiled program of [`solve_batch`][tripodjax.optimize.solver.solve_batch]
    in its evaluate-only mode, in blocks of ``_compiled.rows_per_call``
    (the spec's starts unless set; the last block padded): the catalogue, the constraint
    landscape and the sensitivities reuse the solve's program instead of compiling one.
    """
    rows = x.shape[0]
    block = batch_rows() or structure.starts
    padded = -(-rows // block) * block

    def pad(a):
        a = np.asarray(a)
        return np.concatenate([a, np.repeat(a[:1], padded - rows, axis=0)])

    values, x = jax.tree_util.tree_map(pad, values), pad(x)
    offset = SAFETY * np.asarray(values["solver"]["tolerance"])[:, None]
    z0 = np.zeros(x.shape)
    only = np.ones(block, bool)
    blocks = []
    with jax.enable_x64(True):  # float64, scoped to this call
        for start in range(0, padded, block):
            rows_of_block = slice(start, start + block)
            out = call(
                solve_batch,
                structure,
                jax.tree_util.tree_map(lambda a, b=rows_of_block: a[b], values),
                z0[rows_of_block],
                x[rows_of_block],
                only,
            )
            keep = ("objective", "margins", "gradient", "jacobian", "quantities", "code")
            blocks.append({k: jax.tree_util.tree_map(np.asarray, out[k]) for k in keep})
    out = jax.tree_util.tree_map(lambda *a: np.concatenate(a)[:rows], *blocks)
    return (
        out["objective"],
        out["margins"] - offset[:rows],
        out["gradient"],
        out["jacobian"],
        out["quantities"],
        out["code"],
    )


@functools.partial(latency_bound_jit, static_argnums=0)
def solve_batch(structure, values, z0, x_eval, evaluate_only):
    """Every problem of a flat batch: every argument carries a leading batch axis.

    Rows with ``evaluate_only`` are evaluated at ``x_eval`` instead (see ``_problem``).
    One ``while_loop`` over the batch, each iteration the problems' ``iterate`` under
    ``vmap`` (a finished row keeps its state), until every row is done: what ``vmap`` of
    each problem's loop computes, traced once, where batching a traced loop took as long
    again as tracing it (its body's jaxpr batched two or three times over, measured).
    """
    problems = (values, z0, x_eval, evaluate_only)

    def each(piece, *state):  # one of _problem's pieces, on every row
        return jax.vmap(lambda p, *s: _problem(structure, *p)[piece](*s))(problems, *state)

    def step(s):
        done = s["done"]
        return jax.tree_util.tree_map(
            lambda new, old: jnp.where(done.reshape(done.shape + (1,) * (old.ndim - 1)), old, new),
            each(1, s),
            s,
        )

    return each(2, jax.lax.while_loop(lambda s: jnp.any(~s["done"]), step, each(0)))


@dataclasses.dataclass
class Result:
    """Outcome of an optimisation (one scenario).

    Attributes:
        design: the proposed design ``{variable: value}`` in spec units (free and fixed).
        objective: its objective [–].
        constraints: name → {"value", "limit", "sense", "unit", "margin"}.
        quantities: every quantity the spec uses, in the units of ``spec.QUANTITIES``.
        kkt_residual: KKT residual at the design.
        kkt_converged: the KKT criterion was met within ``max_outer`` iterations.
        halfshaft_converged: every halfshaft point (and every other inner solve) at the
            design returned ``RESULTS.successful``.
        hertz_converged: the Hertz ellipse solve converged at the design.
        converged: all three.
        feasible: every margin ≥ 0 (up to the tolerance).
        result: the worst inner result code at the design (a ``RESULTS`` name).
        multipliers: the constraints' Lagrange multipliers.
        history: per outer iteration, the objective and the KKT residual of the chosen start.
        starts: per start, its final design, objective, KKT residual and feasibility.
        fidelity: the halfshaft fidelity the optimiser ran at.
        sensitivities: ``None`` unless asked for: ``solve(spec, sensitivities=True)`` fills it
            with [`sensitivities`][tripodjax.optimize.sensitivities]``(spec, result)`` when the
            solve converged (derivatives of an unfinished point would be wrong).
        structure, values: the spec's structure and the numbers it was solved for
            (``spec.values``, or a scenario's): what identifies its spec, e.g. to
            [`write_report`][tripodjax.optimize.write_report].
    """

    design: dict
    objective: float
    constraints: dict
    quantities: dict
    kkt_residual: float
    kkt_converged: bool
    halfshaft_converged: bool
    hertz_converged: bool
    converged: bool
    feasible: bool
    result: str
    multipliers: dict
    history: dict
    starts: list
    fidelity: str
    x: np.ndarray = dataclasses.field(repr=False, default=None)
    sensitivities: dict = None
    structure: Structure = dataclasses.field(repr=False, default=None, compare=False)
    values: dict = dataclasses.field(repr=False, default=None, compare=False)


def _stack(values_list):
    return jax.tree_util.tree_map(lambda *a: np.stack([np.asarray(x) for x in a]), *values_list)


def run(
    spec: Spec,
    scenarios: Sequence[dict],
    progress: bool | ProgressMeter | None = None,
    *,
    starts: np.ndarray | None = None,
) -> list[Result]:
    """Optimise each scenario (a values pytree each) from every start; one Result per scenario.

    ``starts`` overrides the spec's start points (z-space rows) for every scenario.
    """
    structure = spec.structure
    z0 = start_points(structure) if starts is None else np.asarray(starts)
    n_starts = z0.shape[0]
    batch_values = _stack([v for v in scenarios for _ in range(n_starts)])
    batch_z0 = np.concatenate([z0] * len(scenarios))
    meter = resolve(progress).start(total=1, desc="optimize", unit="solve")
    with jax.enable_x64(True):  # the design problem runs in float64; scoped to this call
        rows = batch_z0.shape[0]
        out = call(
            solve_batch,
            structure,
            batch_values,
            np.asarray(batch_z0, float),
            np.zeros(batch_z0.shape),
            np.zeros(rows, bool),
        )
        out = jax.tree_util.tree_map(np.asarray, out)
    meter.update(1)
    meter.close()
    out = jax.tree_util.tree_map(lambda a: a.reshape((len(scenarios), n_starts) + a.shape[1:]), out)
    return [
        _result(structure, values, jax.tree_util.tree_map(lambda a, i=i: a[i], out))
        for i, values in enumerate(scenarios)
    ]


def _choose(out, tolerance):
    """The start to report: converged first, then feasible or acceptable, each by objective.

    A start is acceptable when its KKT residual and its violation are both within
    ``ACCEPTABLE · tolerance`` (Ipopt's acceptable level, 1e-6 for its tolerance 1e-8): one
    that ran out of iterations just outside a limit is a near-solution, and ranks with the
    feasible starts by its objective instead of behind a feasible start that stalled far from
    any (a margin is a log ratio, so the violation is relative, as the tolerance is). Then
    the least violation.
    """
    violation = np.nan_to_num(np.maximum(0.0, -np.min(out["margins"], axis=-1)), nan=np.inf)
    feasible = violation <= tolerance
    converged = feasible & (out["kkt"] <= tolerance)
    acceptable = (violation <= ACCEPTABLE * tolerance) & (out["kkt"] <= ACCEPTABLE * tolerance)
    ranked = feasible | acceptable
    objective = np.where(np.isfinite(out["objective"]), out["objective"], np.inf)
    # Converged first (a feasible start that stopped short may sit lower within the
    # tolerance), then feasible or acceptable, each by objective; then the least violation.
    order = np.lexsort((violation, np.where(ranked, objective, np.inf), ~ranked, ~converged))
    return int(order[0])


def _design_dict(structure, x):
    return {name: to_spec_units(name, x[i]) for i, name in enumerate(structure.free)}


def _result(structure, values, out):
    tolerance = float(values["solver"]["tolerance"])
    best = _choose(out, tolerance)
    names = constraint_names(structure)
    table_limits = limits(structure, values)
    q = {k: float(v[best]) for k, v in out["quantities"].items()}
    constraints = {}
    for name, margin in zip(names, out["margins"][best], strict=True):
        quantity, limit, sense, unit = table_limits[name]
        constraints[name] = {
            "value": q[quantity],
            "limit": limit,
            "sense": sense,
            "unit": unit,
            "margin": float(margin),
        }
    design = fixed_design(values) | _design_dict(structure, out["x"][best])
    halfshaft_code, hertz_code = (RESULTS(int(c)) for c in out["code"][best])
    code = max(halfshaft_code, hertz_code)
    kkt = float(out["kkt"][best])
    kkt_ok = bool(kkt <= tolerance)
    inner_ok = code == RESULTS.successful
    feasible = bool(np.min(out["margins"][best]) >= -tolerance)
    n_outer = int(out["outer_iterations"][best]) + 1
    starts = []
    for s in range(out["x"].shape[0]):
        starts.append(
            {
                "design": _design_dict(structure, out["x"][s]),
                "objective": float(out["objective"][s]),
                "kkt_residual": float(out["kkt"][s]),
                "feasible": bool(np.min(out["margins"][s]) >= -tolerance),
                "result": RESULTS(int(np.max(out["code"][s]))).name,
            }
        )
    return Result(
        design=design,
        objective=float(out["objective"][best]),
        constraints=constraints,
        quantities=q,
        kkt_residual=kkt,
        kkt_converged=kkt_ok,
        halfshaft_converged=halfshaft_code == RESULTS.successful,
        hertz_converged=hertz_code == RESULTS.successful,
        converged=bool(kkt_ok and inner_ok),
        feasible=feasible,
        result=code.name,
        multipliers={n: float(v) for n, v in zip(names, out["lam"][best], strict=True)},
        history={
            "objective": [float(v) for v in out["history_objective"][best][:n_outer]],
            "kkt_residual": [float(v) for v in out["history_kkt"][best][:n_outer]],
        },
        starts=starts,
        fidelity=structure.fidelity,
        x=np.asarray(out["x"][best]),
        structure=structure,
        values=values,
    )


def solve(
    spec: Spec, progress: bool | ProgressMeter | None = None, *, sensitivities: bool = False
) -> Result:
    """Propose the joint design for a spec: the best of all starts. Returns a [`Result`][tripodjax.optimize.Result].

    ``progress``: ``None`` (a bar when standard error is a terminal), True/False, or a
    ``tripodjax.progress.ProgressMeter``. Deterministic for a given spec. Runs in
    float64 (scoped to the call). Compiled once per spec structure: solving a spec that
    differs only in its numbers does not retrace. With ``sensitivities=True`` a converged
    result carries [`sensitivities`][tripodjax.optimize.sensitivities] of the optimum in
    ``result.sensitivities`` (else that stays ``None``).

    Examples:
        >>> from tripodjax import optimize
        >>> result = optimize.solve(optimize.load_spec(), progress=False)
        >>> round(result.design["R"], 1), round(result.design["d_roller"], 1), result.converged
        (26.1, 41.4, True)
    """
    check_spec(spec)
    result = run(spec, [spec.values], progress)[0]
    if sensitivities and result.converged:
        from tripodjax.optimize.sensitivity import sensitivities as derivatives

        result.sensitivities = derivatives(spec, result)
    return result


def _with(values, section, **changes):
    out = dict(values)
    out[section] = dict(
        values[section], **{k: np.asarray(v, np.float64) for k, v in changes.items()}
    )
    return out


def solve_family(
    spec: Spec,
    *,
    gamma0_deg: Sequence[float] | None = None,
    l: Sequence[float] | None = None,
    progress: bool | ProgressMeter | None = None,
) -> list[Result]:
    """The proposed design for each member of a layout family, optimised together (one batch).

    Give ``gamma0_deg`` (a sequence of layout angles [deg]) or ``l`` (shaft
    lengths [mm]); the other layout value comes from the spec. The family's variable
    must be fixed in the spec (not in ``[bounds]``). Returns a list of
    [`Result`][tripodjax.optimize.Result], one per member.
    """
    check_spec(spec)
    if (gamma0_deg is None) == (l is None):
        raise ValueError("solve_family needs exactly one of gamma0_deg=[...] or l=[...]")
    name = "gamma0_deg" if gamma0_deg is not None else "l"
    if name in spec.structure.free:
        raise ValueError(
            f"solve_family over {name}: {name} is a free variable of this spec; fix it (remove it from [bounds])"
        )
    members = np.asarray(gamma0_deg if gamma0_deg is not None else l, float).ravel()
    if members.size == 0 or not np.all(np.isfinite(members)):
        raise ValueError(
            f"{name} = {members.tolist()!r} must be a non-empty sequence of finite numbers"
        )
    r_max = (
        float(np.max(spec.values["bounds"]["R"]))
        if "R" in spec.structure.free
        else float(spec.values["design"]["R"])
    )
    if name == "gamma0_deg":
        check_layout_domain(gamma0=members, names={"gamma0": "gamma0_deg"}, degrees=True)
        scenarios = [_with(spec.values, "layout", gamma0=math.radians(v)) for v in members]
    else:  # R/l ≤ 0.2 with the largest R the spec allows
        check_layout_domain(R=r_max, l=members, names={"R": "the largest R of the spec", "l": "l"})
        scenarios = [_with(spec.values, "layout", l=v) for v in members]
    return run(spec, scenarios, progress)


def pareto_front(
    spec: Spec, gaf_weights: Sequence[float], progress: bool | ProgressMeter | None = None
) -> list[Result]:
    """Designs minimising the objective with ``w_gaf_rms`` set to each weight (other weights from the spec).

    Returns a list of [`Result`][tripodjax.optimize.Result]; their GAF RMS and outer
    diameter trace the front of GAF against joint size. The spec's objective must have
    a ``gaf_rms`` term.
    """
    check_spec(spec)
    if "gaf_rms" not in spec.structure.objective:
        raise ValueError(
            "pareto_front sweeps objective.w_gaf_rms; the spec's objective has no gaf_rms term"
        )
    weights = np.asarray(gaf_weights, float).ravel()
    if weights.size == 0 or not np.all(np.isfinite(weights)):
        raise ValueError(
            f"gaf_weights = {weights.tolist()!r} must be a non-empty sequence of finite numbers"
        )
    scenarios = [_with(spec.values, "objective", w_gaf_rms=w) for w in weights]
    return run(spec, scenarios, progress)
