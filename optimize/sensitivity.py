"""Post-optimal sensitivities: how the proposed design moves when a number of the spec changes.

At the optimum x* with multipliers λ* the KKT conditions of the active set hold,

    ∇ₓf − Σ_{i∈A} λ_i ∇ₓc_i = 0   (free variables off their bounds),   c_A(x) = offset,

and the implicit function theorem on them gives dx*/dp and dλ*/dp for every
number p of the spec (the solution is differentiated, not the iterations):

    [ H   −J_Aᵀ ] [dx/dp]     [ ∂ₚ∇ₓL ]
    [ J_A   0   ] [dλ/dp] = − [ ∂ₚc_A  ],     L = f − λ·c,

solved here directly. The optimal
objective's derivative is ∂ₚL at (x*, λ*) (the envelope theorem). Variables on a
bound stay there. A constraint that is about to switch — active with a multiplier
near zero, or inactive with a margin near zero — makes the derivative one-sided;
it is named in ``near_switch`` instead of being trusted silently.
"""

import math

import jax
import numpy as np

from tripodjax.optimize.problem import bounds, check_result, constraint_names
from tripodjax.optimize.solver import BOUND_TOLERANCE, Result, evaluate_points
from tripodjax.optimize.spec import Spec

ACTIVE_MULTIPLIER = 1e-6  # λ above this: the constraint is active
SWITCH_MULTIPLIER = 1e-4  # active with λ below this: about to leave the active set
SWITCH_MARGIN = 1e-3  # inactive with a margin below this: about to enter it
MAX_CONDITION = 1e12  # a KKT matrix worse than this is singular: a free variable has no effect


def _ravel(tree):
    """(flat NumPy vector, unravel) for a pytree of NumPy arrays; unravel takes a leading batch."""
    leaves, treedef = jax.tree_util.tree_flatten(tree)
    shapes = [np.shape(a) for a in leaves]
    sizes = [int(np.prod(s)) for s in shapes]
    flat = np.concatenate([np.ravel(a) for a in leaves])

    def unravel(rows):
        rows = np.asarray(rows)
        parts = np.split(rows, np.cumsum(sizes)[:-1], axis=-1)
        lead = rows.shape[:-1]
        return treedef.unflatten([p.reshape(lead + s) for p, s in zip(parts, shapes, strict=True)])

    return flat, unravel


def _perturbations(values, x):
    """Rows (values, x): the base point, ± a step in each variable, ± a step in each number."""
    flat, unravel = _ravel(values)
    skip, _ = _ravel(
        {
            k: jax.tree_util.tree_map(
                lambda a, k=k: np.full(np.shape(a), k in ("bounds", "solver")), v
            )
            for k, v in values.items()
        }
    )
    params = [i for i in range(flat.size) if not skip[i]]
    hx = 1e-6 * np.maximum(np.abs(x), 1.0)
    hp = 1e-6 * np.maximum(np.abs(flat[params]), 1e-3)
    rows_x, rows_p = [x], [flat]
    for i, h in enumerate(hx):
        for sign in (1.0, -1.0):
            rows_x.append(x + sign * h * np.eye(x.size)[i])
            rows_p.append(flat)
    for i, h in zip(params, hp, strict=True):
        for sign in (1.0, -1.0):
            rows_x.append(x)
            rows_p.append(flat + sign * h * np.eye(flat.size)[i])
    return unravel(np.stack(rows_p)), np.stack(rows_x), hx, hp, params, flat.size, unravel


def _derivatives(structure, values, x, lam, free_mask, active_mask):
    """(dF*/dp, dx*/dp, cond K) with dp over the flattened numbers of the spec.

    The KKT pieces are exact in x (forward mode through the implicit solve); their
    partial derivatives in x and in each number of the spec are central differences of
    those exact first derivatives (a second-order forward pass through the implicit
    solve takes minutes to compile, this one seconds).
    """
    batch, xs, hx, hp, params, size, unravel = _perturbations(values, x)
    f, c, grad_f, jac, _, _ = evaluate_points(structure, batch, xs)
    n, m = x.size, lam.size
    L = f - c @ lam
    grad_L = grad_f - np.einsum("bmn,m->bn", jac, lam)
    G = np.concatenate([grad_L, c], 1)
    H = np.stack([(grad_L[1 + 2 * i] - grad_L[2 + 2 * i]) / (2 * hx[i]) for i in range(n)], 1)
    J = jac[0]
    base = 1 + 2 * n
    Gp = np.zeros((n + m, size))
    dL = np.zeros(size)
    for k, (i, h) in enumerate(zip(params, hp, strict=True)):
        plus, minus = base + 2 * k, base + 2 * k + 1
        Gp[:, i] = (G[plus] - G[minus]) / (2 * h)
        dL[i] = (L[plus] - L[minus]) / (2 * h)
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
        return None, None, cond
    du = -np.linalg.solve(K, np.concatenate([fm, am])[:, None] * Gp)
    return unravel(dL), unravel(du[:n]), cond


# Internal value path → (spec key, factor from per-internal-unit to per-spec-unit).
def _spec_key(section, key):
    if section == "layout" and key == "gamma0":
        return "layout.gamma0_deg", math.pi / 180.0
    if section == "life" and key == "condition_angle":
        return "life.conditions.angle_deg", math.pi / 180.0
    if section == "life" and key == "condition_share":
        return "life.conditions.share", 1.0
    return f"{section}.{key}", 1.0


def sensitivities(spec: Spec, result: Result) -> dict:
    """Derivatives of the optimal objective and of each free variable w.r.t. every fixed number.

    Args:
        spec: the [`Spec`][tripodjax.optimize.Spec] that was solved.
        result: its [`Result`][tripodjax.optimize.Result].

    Returns:
        ``{"derivatives": {"<section>.<key>": {"objective": …, "<variable>": …}},
        "elasticities": {…same keys…}, "active": [...], "near_switch": [...],
        "condition_number": float}``, and ``"unavailable"`` (a sentence) with empty
        derivatives when the KKT matrix is singular: per unit of the spec's own unit (per degree for
        ``*_deg`` keys; list entries as ``key[i]``); the free variables in spec units.
        Elasticities are (p / y)·dy/dp; for the conformity Ψ, p is the clearance Ψ − 1
        (a relative change of Ψ itself would read as a huge number).
    """
    check_result(spec, result)
    structure, values = spec.structure, spec.values
    names = constraint_names(structure)
    lam = np.array([result.multipliers[n] for n in names])
    margins = np.array([result.constraints[n]["margin"] for n in names])
    x = np.asarray(result.x)
    lower, upper = bounds(structure, values, np)
    width = upper - lower
    on_bound = (x - lower <= 10 * BOUND_TOLERANCE * width) | (
        upper - x <= 10 * BOUND_TOLERANCE * width
    )
    active = lam > ACTIVE_MULTIPLIER
    near_switch = [
        n
        for n, a, lm, mg in zip(names, active, lam, margins, strict=True)
        if (a and lm < SWITCH_MULTIPLIER) or (not a and mg < SWITCH_MARGIN)
    ]
    dF, dx, cond = _derivatives(structure, values, x, lam, ~on_bound, active)
    notes = {
        "active": [n for n, a in zip(names, active, strict=True) if a],
        "on_bound": [v for v, b in zip(structure.free, on_bound, strict=True) if b],
        "near_switch": near_switch,
        "condition_number": cond,
    }
    if dF is None:  # no derivative exists: say so instead of printing numbers
        unused = [v for v, b in zip(structure.free, on_bound, strict=True) if not b]
        notes["unavailable"] = (
            f"the KKT matrix is singular (condition number {cond:.3g}): one of the free "
            f"variables off their bounds ({', '.join(unused)}) has no effect on the objective or "
            "the active constraints"
        )
        return {"derivatives": {}, "elasticities": {}, **notes}
    derivatives, elasticities = {}, {}
    optimum = {v: result.design[v] for v in structure.free}
    for section, entries in values.items():
        if section in ("bounds", "solver"):
            continue
        for key, value in entries.items():
            if section == "design" and key in structure.free:
                continue
            if section == "layout" and {"l": "l", "gamma0": "gamma0_deg"}[key] in structure.free:
                continue
            if section in ("hertz", "friction") and key in structure.free:
                continue
            spec_key, factor = _spec_key(section, key)
            value = np.asarray(value)
            indices = [()] if value.ndim == 0 else [(i,) for i in range(value.shape[0])]
            for idx in indices:
                label = spec_key if not idx else f"{spec_key}[{idx[0]}]"
                row = {"objective": float(dF[section][key][idx]) * factor}
                for v, variable in enumerate(structure.free):
                    d = float(dx[section][key][(v,) + idx]) * factor
                    row[variable] = d * (180.0 / math.pi if variable == "gamma0_deg" else 1.0)
                p_spec = math.degrees(float(value[idx])) if factor != 1.0 else float(value[idx])
                if label == "hertz.conformity":  # per relative change of the clearance Ψ − 1
                    p_spec -= 1.0
                derivatives[label] = row
                elasticities[label] = {
                    k: (p_spec * d / y if y != 0 else float("nan"))
                    for k, d, y in (
                        (k, d, result.objective if k == "objective" else optimum[k])
                        for k, d in row.items()
                    )
                }
    return {"derivatives": derivatives, "elasticities": elasticities, **notes}
