"""Post-optimal sensitivities: how the proposed design moves when a number of the spec changes.

At the optimum x* with multipliers λ* the KKT conditions of the active set hold,

    ∇ₓf − Σ_{i∈A} λ_i ∇ₓc_i = 0   (free variables off their bounds),   c_A(x) = offset,

and the implicit function theorem on them gives dx*/dp and dλ*/dp for every
number p of the spec's model sections (the solution is differentiated, not the
iterations; the ``[uncertainty]`` section's distribution parameters are not among them):

    [ H   −J_Aᵀ ] [dx/dp]     [ ∂ₚ∇ₓL ]
    [ J_A   0   ] [dλ/dp] = − [ ∂ₚc_A  ],     L = f − λ·c,

solved here directly. The optimal objective's derivative is ∂ₚL at (x*, λ*) (the
envelope theorem). Variables on a bound stay there.

The right-hand side costs O(sections), not O(numbers): the scalar numbers of the spec
(a fixed set of keys) by central differences of the exact first derivatives, through
the solve's own compiled program; the list entries (a load spectrum of up to a thousand
cases) by one reverse pass, ``jax.vjp`` of (f, c, ∇ₓf, Jₓc) w.r.t. every list at once
pulled back along the n + m rows of the KKT system, once they outnumber
``REVERSE_FROM`` (a few entries cost less by differences than a second program).

A derivative holds only while the active set does. A constraint switches where its
multiplier (active) or its margin (inactive) reaches zero; from dλ/dp and the total
dc/dp the linearised change of each input at which that happens is
``switch_distance`` (relative to the input). A variable reaching or leaving a bound
switches likewise. Every input with a switch within ``SWITCH_STEP`` (1 %) of itself
has its derivatives withheld (``withheld``: the input and the constraints that switch),
since they would hold on one side only.
"""

import functools
import math

import jax
import numpy as np

from tripodjax.optimize._compiled import call, latency_bound_jit
from tripodjax.optimize.problem import bounds, check_result, check_spec, constraint_names
from tripodjax.optimize.solver import Result, _evaluation, evaluate_points
from tripodjax.optimize.spec import _SPEC_UNITS, VARIABLES, Spec, number_domain, shaft_variable

ACTIVE_MULTIPLIER = 1e-6  # λ above this: the constraint is active
SWITCH_STEP = 0.01  # relative change of an input within which a switch withholds its derivatives
SWITCH_REPORTED = 1.0  # switch distances up to this relative change are reported
MAX_CONDITION = 1e12  # a KKT matrix worse than this is singular: a free variable has no effect
REVERSE_FROM = 64  # list entries from which one reverse pass is cheaper than differences
# Sections that are not numbers of the model: the bounds, the solver's settings, and the
# [uncertainty] tables (distribution parameters and a correlation matrix, which enter only the
# chance constraints' margins; their derivatives are not given).
SKIPPED = ("bounds", "solver", "uncertainty")


def _inputs(structure, values):
    """The spec's numbers that enter the model: {(section, key): array}, free variables' own values
    left out (a free [shaft] entry's list stays: its other entries are inputs; see ``_free_entries``)."""
    free = {VARIABLES[v][:2] for v in structure.free if not shaft_variable(v)}
    return {
        (section, key): np.asarray(value, np.float64)
        for section, entries in values.items()
        if section not in SKIPPED
        for key, value in entries.items()
        if (section, key) not in free
    }


@functools.partial(latency_bound_jit, static_argnums=0)
def _pullback(structure, values, x, lists, cotangents):
    """For each cotangent row, the gradient w.r.t. ``lists`` of ⟨row, (f, c, ∇ₓf, Jₓc)⟩ at x.

    ``lists`` is ``{section: {key: 1-D array}}``, replacing those values; one reverse pass
    (``jax.vjp``) through the forward-mode Jacobian of the model serves every row.
    """

    def model(lists):
        merged = {s: dict(values[s], **lists.get(s, {})) for s in values}
        f, c, grad_f, jac, _, _ = _evaluation(structure, merged)[-1](x)
        return f, c, grad_f, jac

    _, pull = jax.vjp(model, lists)
    return jax.vmap(pull)(cotangents)[0]


def _difference_rows(values, x, entries):
    """Rows (values, x): the base point, ± a step in each variable and in each entry; and the
    steps (hx of the variables, the entries' spans: plus minus minus).

    ``entries`` are ((section, key), index) with index None for a scalar. An entry on an end of
    its number's allowed range (`spec.RANGES`: a working angle of 0, a share of 0 or 1) steps
    inward alone, a one-sided difference: past the end the model is NaN (its domain).
    """
    hx = 1e-6 * np.maximum(np.abs(x), 1.0)
    rows, spans = [(values, x)], []
    for i, h in enumerate(hx):
        for sign in (1.0, -1.0):
            rows.append((values, x + sign * h * np.eye(x.size)[i]))
    for (section, key), index in entries:
        value = np.asarray(values[section][key], np.float64)
        at = float(value if index is None else value[index])
        h = 1e-6 * max(abs(at), 1e-3)
        domain = number_domain(section, key, None)
        steps = [h, -h]
        if domain is not None and any(_inside(domain, at + step) for step in steps):
            steps = [step if _inside(domain, at + step) else 0.0 for step in steps]
        spans.append(steps[0] - steps[1])
        for step in steps:
            changed = np.array(value)
            changed[() if index is None else index] += step
            rows.append((dict(values, **{section: dict(values[section], **{key: changed})}), x))
    batch = jax.tree_util.tree_map(
        lambda *a: np.stack([np.asarray(v, np.float64) for v in a]), *[r[0] for r in rows]
    )
    return batch, np.stack([r[1] for r in rows]), hx, np.asarray(spans)


def _inside(domain, value):
    """Whether ``value`` lies in a number's allowed values (an `uncertainty.Domain`)."""
    low = domain.low is None or (value > domain.low if domain.low_open else value >= domain.low)
    return low and (
        domain.high is None or (value < domain.high if domain.high_open else value <= domain.high)
    )


def _reversed_keys(inputs):
    """The inputs whose columns come from the reverse pass: every list, when they hold
    ``REVERSE_FROM`` entries or more in all."""
    entries = sum(v.size for v in inputs.values() if v.ndim > 0)
    return [k for k, v in inputs.items() if v.ndim > 0 and entries >= REVERSE_FROM]


def _reverse_pass(structure, values, x, lam, inputs, reversed_keys):
    """``_pullback`` of the rows `_right_hand_side` needs, w.r.t. the ``reversed_keys`` lists."""
    n, m = x.size, lam.size
    # Cotangents of (f, c, ∇ₓf, J): row r < n pulls back ∂(∇ₓL)_r = ∂(∇ₓf − Jᵀλ)_r,
    # the next m rows ∂c_i, the last ∂L = ∂(f − λ·c).
    eye_n = np.eye(n)
    cotangents = (
        np.concatenate([np.zeros(n + m), [1.0]]),
        np.concatenate([np.zeros((n, m)), np.eye(m), -lam[None]]),
        np.concatenate([eye_n, np.zeros((m + 1, n))]),
        np.concatenate([-lam[None, :, None] * eye_n[:, None, :], np.zeros((m + 1, m, n))]),
    )
    lists = {}
    for section, key in reversed_keys:
        lists.setdefault(section, {})[key] = inputs[section, key]
    with jax.enable_x64(True):  # float64, scoped to this call
        return call(_pullback, structure, values, x, lists, cotangents)


def compile_reverse_pass(spec: Spec) -> None:
    """Run the reverse pass [`sensitivities`][tripodjax.optimize.sensitivities] of ``spec``
    needs (if any) once, at the middle of the box: its compiled program (its shapes are any
    design's) is then ready for the optimum's (``optimize-joint`` compiles it beside the solve).
    """
    structure, values = check_spec(spec).structure, spec.values
    inputs = _inputs(structure, values)
    reversed_keys = _reversed_keys(inputs)
    if reversed_keys:
        lower, upper = bounds(structure, values, np)
        lam = np.zeros(len(constraint_names(structure)))
        _reverse_pass(structure, values, 0.5 * (lower + upper), lam, inputs, reversed_keys)


def _right_hand_side(structure, values, x, lam, inputs):
    """(H, J, G = (∇ₓL, c) at x, the columns ∂G/∂p and ∂L/∂p of every input entry).

    ``inputs`` maps (section, key) to its array; the columns come in that order, a list
    one column per entry. Scalars and short lists by central differences, long lists by
    one reverse pass (see the module docstring).
    """
    n, m = x.size, lam.size
    reversed_keys = _reversed_keys(inputs)
    differenced = [
        (k, None if v.ndim == 0 else i)
        for k, v in inputs.items()
        if k not in reversed_keys
        for i in range(v.size)
    ]
    batch, xs, hx, spans = _difference_rows(values, x, differenced)
    f, c, grad_f, jac, _, _ = evaluate_points(structure, batch, xs)
    L = f - c @ lam
    grad_L = grad_f - np.einsum("bmn,m->bn", jac, lam)
    G = np.concatenate([grad_L, c], 1)
    H = np.stack([(grad_L[1 + 2 * i] - grad_L[2 + 2 * i]) / (2 * hx[i]) for i in range(n)], 1)
    base = 1 + 2 * n
    dG = (G[base::2] - G[base + 1 :: 2]).T / spans
    dL = (L[base::2] - L[base + 1 :: 2]) / spans
    columns, start = {}, 0
    for key, value in inputs.items():
        if key not in reversed_keys:
            columns[key] = (dG[:, start : start + value.size], dL[start : start + value.size])
            start += value.size
    if reversed_keys:
        pulled = _reverse_pass(structure, values, x, lam, inputs, reversed_keys)
        for section, key in reversed_keys:
            rows = np.asarray(pulled[section][key])  # (n + m + 1, entries)
            columns[section, key] = (rows[: n + m], rows[n + m])
    Gp = np.concatenate([columns[k][0] for k in inputs], 1)
    dL = np.concatenate([columns[k][1] for k in inputs])
    return H, jac[0], G[0], Gp, dL


def _kkt_solve(H, J, Gp, free_mask, active_mask):
    """(du = (dx, dλ)/dp for every column of Gp, cond K); du None when K is singular."""
    fm, am = free_mask.astype(float), active_mask.astype(float)
    # Rows of variables on a bound and of inactive constraints become identities (no change).
    K = np.block(
        [
            [fm[:, None] * H * fm[None, :] + np.diag(1.0 - fm), -(fm[:, None] * J.T * am[None, :])],
            [am[:, None] * J * fm[None, :], np.diag(1.0 - am)],
        ]
    )
    cond = float(np.linalg.cond(K))
    if not np.isfinite(cond) or cond > MAX_CONDITION:
        return None, cond
    return -np.linalg.solve(K, np.concatenate([fm, am])[:, None] * Gp), cond


def _switches(names, lam, margins, active, free, x, lower, upper, side, G0, H, J, Gp, du):
    """{name: d(name's switching quantity)/dp and its value}: each crosses zero at a switch.

    Constraints: λ_i (active) or the margin c_i (inactive, with its total derivative
    ∂c_i/∂p + J_i·dx/dp). Variables: the distance to the nearer bound (off a bound) or the
    bound's multiplier, the reduced gradient (∇ₓL)_v (on a bound; ``side`` is +1 on the lower
    bound, −1 on the upper, 0 off both).
    """
    n = x.size
    dx, dlam = du[:n], du[n:]
    dc = Gp[n:] + J @ dx
    out = {}
    for i, name in enumerate(names):
        out[name] = (lam[i], dlam[i]) if active[i] else (margins[i], dc[i])
    dgrad = Gp[:n] + H @ dx - J.T @ dlam
    for v, variable in enumerate(free):
        if side[v]:  # leaves the bound when its multiplier ±(∇ₓL)_v reaches 0
            sign = side[v]  # ∇ₓL_v ≥ 0 on a lower bound (+1), ≤ 0 on an upper (−1)
            bound = "lower" if side[v] > 0 else "upper"
            out[f"{variable}_{bound}_bound"] = (sign * G0[v], sign * dgrad[v])
        else:  # reaches whichever bound it moves towards
            out[f"{variable}_lower_bound"] = (x[v] - lower[v], dx[v])
            out[f"{variable}_upper_bound"] = (upper[v] - x[v], -dx[v])
    return out


def _spec_key(section, key):
    """Internal value path → (spec key, factor from per-internal-unit to per-spec-unit): an
    angle held in radians is a ``*_deg`` key of the file (``spec._SPEC_UNITS``)."""
    name, unit = _SPEC_UNITS.get((section, key), (key, None))
    name = ".".join(name) if isinstance(name, tuple) else name
    return f"{section}.{name}", (math.pi / 180.0 if unit == "deg" else 1.0)


def _free_entries(structure):
    """The labels (``shaft.<list>[i]``) of the list entries that are free variables."""
    out = set()
    for name in structure.free:
        entry = shaft_variable(name)
        if entry is not None:
            out.add(f"shaft.{entry[0]}[{structure.shaft_sections.index(entry[1])}]")
    return out


CONFORMITIES = ("hertz.conformity", "outboard.conformity")  # read as their clearance Ψ − 1


def _labels(inputs):
    """Per column: (label, factor to spec units, the spec-unit value a relative change is of)."""
    out = []
    for (section, key), value in inputs.items():
        spec_key, factor = _spec_key(section, key)
        for i, p in enumerate(np.ravel(value)):
            label = spec_key if value.ndim == 0 else f"{spec_key}[{i}]"
            p_spec = math.degrees(float(p)) if factor != 1.0 else float(p)
            # A conformity Ψ (the tripod's, the outboard joint's): per relative change of the
            # clearance Ψ − 1 (a relative change of Ψ itself would read as a huge number, and
            # a switch within 1 % of Ψ would put Ψ below 1, where no spec may go).
            relative_of = p_spec - 1.0 if label in CONFORMITIES else p_spec
            out.append((label, factor, relative_of))
    return out


def sensitivities(spec: Spec, result: Result) -> dict:
    """Derivatives of the optimal objective and of each free variable w.r.t. every fixed number.

    Args:
        spec: the [`Spec`][tripodjax.optimize.Spec] that was solved.
        result: its [`Result`][tripodjax.optimize.Result] (``solve(spec, sensitivities=True)``
            fills ``result.sensitivities`` with this).

    Returns:
        ``{"derivatives": {"<section>.<key>": {"objective": …, "<variable>": …}},
        "elasticities": {…same keys…}, "active": [...], "on_bound": [...],
        "near_switch": [...], "withheld": {key: [names]}, "switch_distance":
        {name: {key: r}}, "switch_step": SWITCH_STEP, "condition_number": float}``, and
        ``"unavailable"`` (a sentence) with empty derivatives when the KKT matrix is
        singular. Derivatives are per unit of the spec's own unit (per degree for ``*_deg``
        keys; list entries as ``key[i]``); the free variables in spec units. Elasticities
        are (p / y)·dy/dp; for the conformity Ψ, p is the clearance Ψ − 1 (a relative change
        of Ψ itself would read as a huge number).

        ``switch_distance[name][key]`` is the relative change r of the input (Δp = r·p; of
        Ψ − 1 for the conformity) at which, linearised, the constraint ``name`` (or the bound
        ``<variable>_lower_bound`` / ``_upper_bound``) switches: an active one's multiplier
        or an inactive one's margin reaches zero. Given for |r| ≤ ``SWITCH_REPORTED``; an
        input that is zero has no relative change and none. Every input with a switch at
        |r| ≤ ``switch_step`` is left out of the derivatives and listed in ``withheld`` with
        the names that switch; ``near_switch`` lists those names.
    """
    check_result(spec, result)
    structure, values = spec.structure, spec.values
    names = constraint_names(structure)
    lam = np.array([result.multipliers[n] for n in names])
    x = np.asarray(result.x)
    lower, upper = bounds(structure, values, np)
    width = upper - lower
    # on a bound within the solver's tolerance: its KKT residual (the projected step, scaled by
    # the widths) lets a variable stop that close to a bound it pushes against
    near = float(values["solver"]["tolerance"]) * width
    side = np.where(x - lower <= near, 1.0, np.where(upper - x <= near, -1.0, 0.0))
    on_bound = side != 0
    active = lam > ACTIVE_MULTIPLIER
    inputs = _inputs(structure, values)
    H, J, G0, Gp, dL = _right_hand_side(structure, values, x, lam, inputs)
    du, cond = _kkt_solve(H, J, Gp, ~on_bound, active)
    notes = {
        "active": [n for n, a in zip(names, active, strict=True) if a],
        "on_bound": [v for v, b in zip(structure.free, on_bound, strict=True) if b],
        "near_switch": [],
        "withheld": {},
        "switch_distance": {},
        "switch_step": SWITCH_STEP,
        "condition_number": cond,
    }
    if du is None:  # no derivative exists: say so instead of printing numbers
        unused = [v for v, b in zip(structure.free, on_bound, strict=True) if not b]
        notes["unavailable"] = (
            f"the KKT matrix is singular (condition number {cond:.3g}): one of the free "
            f"variables off their bounds ({', '.join(unused)}) has no effect on the objective or "
            "the active constraints"
        )
        return {"derivatives": {}, "elasticities": {}, **notes}
    margins = G0[x.size :]  # c − offset: zero on the solver's active set
    switches = _switches(
        names, lam, margins, active, structure.free, x, lower, upper, side, G0, H, J, Gp, du
    )
    labels = _labels(inputs)
    derivatives, elasticities = {}, {}
    optimum = {v: result.design[v] for v in structure.free}
    free_entries = _free_entries(structure)
    for j, (label, factor, relative_of) in enumerate(labels):
        if label in free_entries:  # a free variable's own spec value: not an input
            continue
        switching = []
        for name, (level, slope) in switches.items():
            # level + slope·Δp = 0 at Δp = −level / slope (internal units); relative to p.
            step = slope[j] * factor * relative_of  # change of the level per unit r
            if relative_of == 0 or step == 0 or not np.isfinite(step):
                continue
            r = float(-max(level, 0.0) / step)
            if abs(r) <= SWITCH_REPORTED:
                notes["switch_distance"].setdefault(name, {})[label] = r
            if abs(r) <= SWITCH_STEP:
                switching.append(name)
        if switching:
            notes["withheld"][label] = switching
            continue
        row = {"objective": float(dL[j]) * factor}
        for v, variable in enumerate(structure.free):
            d = float(du[v, j]) * factor
            row[variable] = d * (180.0 / math.pi if variable == "gamma0_deg" else 1.0)
        derivatives[label] = row
        elasticities[label] = {
            k: (relative_of * d / y if y != 0 else float("nan"))
            for k, d, y in (
                (k, d, result.objective if k == "objective" else optimum[k]) for k, d in row.items()
            )
        }
    switching = {n for names_ in notes["withheld"].values() for n in names_}
    notes["near_switch"] = [n for n in switches if n in switching]
    return {"derivatives": derivatives, "elasticities": elasticities, **notes}
