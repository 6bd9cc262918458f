"""The joint-design problem: design variables → quantities, objective and constraint margins.

The design vector holds the free variables of the spec (any of R, d_roller,
l, γ0, conformity, λ, μ_slp, and [shaft] entries such as ``shaft.outer_diameter_mm[C-C]``;
internal units: mm, rad, –); the others stay at their spec values. For each design the halfshaft is solved over a revolution
(seed §2.9, implicit derivatives), the Hertz capacities and life come from
§4.2 and the GAF from §3.2, but only the quantities the objective and the
constraints use are computed. Everything is differentiable in the design and
in every number of the spec.

Objective (dimensionless): f = Σ_q w_q · q / q_ref over the spec's terms.

Constraint margins, ≥ 0 when satisfied, as logarithmic ratios (0.01 = 1 % to spare):

    static_capacity   ln(M_s / (shock_factor · M_max))        (always)
    life              ln(L_km / required_km)                   (always)
    shaft_static[s]   ln(S_s), S_s the static safety of [shaft] section s       (with a vehicle)
    shaft_fatigue[s]  ln(allowed_damage / D_s), D_s its damage (the larger radius's)  (")
    outboard_static   ln(M_s,outboard / (shock_factor · M_max))                 (")
    outboard_life     ln(L_km,outboard / required_km)                           (")
    max_<q>           ln(limit / q)
    min_<q>           ln(q / limit)

then each chance constraint of the spec (``max_failure_probability_<q>``,
``min_reliability_index_<q>``): the requirement's margin at its inverse-FORM point
(performance-measure approach, [`chance_margins`][tripodjax.optimize.problem.chance_margins]);
and, in [`evaluate`][tripodjax.optimize.evaluate], the bounds of the free
variables, (x − lo)/(hi − lo) and (hi − x)/(hi − lo).
"""

import contextlib
import dataclasses
import functools
import math
from collections.abc import Mapping

import jax
import jax.numpy as jnp
import numpy as np
from jax.custom_derivatives import SymbolicZero
from jax.scipy.special import ndtri

from tripodjax import forces, friction, hertz, life, vehicle
from tripodjax._checks import check_instance, check_layout_domain, real_scalar
from tripodjax.kinematics import MIN_N_THETA_ORDERS, metrics_from, revolution
from tripodjax.layout import Layout
from tripodjax.optimize import uncertainty
from tripodjax.optimize._compiled import call, latency_bound_jit, rows_per_call
from tripodjax.optimize.spec import (
    FORCE_QUANTITIES,
    GAF_QUANTITIES,
    HALFSHAFT_QUANTITIES,
    KINEMATIC_QUANTITIES,
    QUANTITIES,
    REVOLUTION_QUANTITIES,
    SHAFT_VARIABLES,
    VARIABLES,
    Spec,
    quantity_unit,
    shaft_variable,
    shaft_variable_name,
    variable_domain,
)
from tripodjax.results import RESULTS, worst

MARGIN_FLOOR = 1e-12  # q is floored at this fraction of its limit inside ln(limit/q)


def halfshaft_constraint_names(structure):
    """The rest of the halfshaft's requirements (with a vehicle): each [shaft] section's static
    and fatigue checks, then the outboard joint's static safety and life."""
    if not structure.halfshaft:
        return ()
    sections = tuple(
        f"shaft_{check}[{name}]"
        for name in structure.shaft_sections
        for check in ("static", "fatigue")
    )
    return sections + ("outboard_static", "outboard_life")


def fixed_constraints(structure):
    """The halfshaft constraints that no free variable changes: a [shaft] section's checks when
    none of its entries is free, and the outboard joint's (no design variable enters it)."""
    free = {shaft_variable(v)[1] for v in structure.free if shaft_variable(v)}
    return tuple(
        name
        for name in halfshaft_constraint_names(structure)
        if not any(name.endswith(f"[{section}]") for section in free)
    )


def constraint_names(structure):
    """The constraints in margin order: the two Hertz requirements, the rest of the halfshaft's,
    then the spec's."""
    names = ("static_capacity", "life") + halfshaft_constraint_names(structure)
    names += tuple(name for name, _, _ in structure.constraints)
    return names + tuple(
        key if len(requirements) == 1 else f"{key}:{name}"
        for key, _, requirements in structure.chance
        for name in requirements
    )


def bounds(structure, values, xp=jnp):
    """(lower, upper) arrays of the free variables, internal units.

    ``xp=np`` for concrete float64 values outside ``jit`` (jnp would round them to float32
    unless x64 is on).
    """
    b = values["bounds"]
    lower = xp.stack([xp.asarray(b[k])[..., 0] for k in structure.free], axis=-1)
    upper = xp.stack([xp.asarray(b[k])[..., 1] for k in structure.free], axis=-1)
    return lower, upper


def full_design(structure, values, x):
    """Every design variable (internal names and units) with the free ones taken from x."""
    design = {name: values[section][key] for name, (section, key, _, _) in VARIABLES.items()}
    for i, name in enumerate(structure.free):  # a [shaft] entry only when free
        design[name] = x[..., i]
    return design


def quantities(structure, values, design):
    """The quantities the spec uses (see ``spec.QUANTITIES``), and two result codes.

    The codes (``RESULTS``) are the worst of the halfshaft solve, the GAF and the
    finiteness of the quantities, and the worst of the Hertz ellipse (κ) solves.
    """
    needs = structure.needs
    R, d = design["R"], design["d_roller"]
    layout = Layout(R, design["l"], design["gamma0_deg"])
    h, loads = values["hertz"], values["loads"]
    q, codes, hertz_codes = {}, [], []
    if needs & set(REVOLUTION_QUANTITIES):
        # dΔ/dθ and dγ/dθ only for the quantities that use them (irregularity, GAF, forces).
        with_rates = bool(needs & {"irregularity", *GAF_QUANTITIES, *FORCE_QUANTITIES})
        sol, rates = revolution(
            layout, structure.n_theta, structure.fidelity, with_rates=with_rates
        )
        # Metrics from the small unknowns (float32-accurate, one-sided slopes at γ0 = 0).
        names = {
            "irregularity": "irregularity",
            "eccentricity": "ecc_max",
            "gamma_ripple": "gamma_pp",
            "roller_stroke": "roller_axial_stroke",
        }
        wanted = [k for k in KINEMATIC_QUANTITIES if k in needs]
        metrics = metrics_from(layout, sol, rates, [names[k] for k in wanted] + ["result"])
        codes.append(metrics["result"])
        for k in wanted:
            q[k] = metrics[names[k]]
        if "gamma_ripple" in q:
            q["gamma_ripple"] = jnp.degrees(q["gamma_ripple"])
        params = friction.GREASE_A.replace(lam=design["lam"], mu_slp=design["mu_slp"])
        from_forces = {k: n for k, n in FORCE_QUANTITIES.items() if k in needs}
        if structure.gaf_model == "forces":
            from_forces.update({k: k for k in GAF_QUANTITIES if k in needs})
        elif needs & set(GAF_QUANTITIES):
            inputs = friction.GAFInputs(loads["gaf_torque"], params, structure.gaf_model)
            gaf = friction.gaf_from_revolution(layout, sol, rates, inputs)
            codes.append(gaf.result)
            q.update(gaf_rms=gaf.rms, gaf_peak=gaf.peak, gaf_third_order=gaf.third_order)
        if from_forces:
            out = forces.force_quantities(
                layout, sol, rates, force_inputs(values, params), (*from_forces.values(), "result")
            )
            codes.append(out["result"])
            q.update({k: out[n] for k, n in from_forces.items()})
    if needs & {"static_capacity", "M_d", "M_sd"}:
        caps = hertz.capacities(
            d,
            R,
            conformity=design["conformity"],
            P_s=h["P_s"],
            P_d=h["P_d"],
            P_sd=h["P_sd"],
            C_s=h["C_s"],
            n_rollers=structure.n_rollers,
            gamma=design["gamma0_deg"],
            domain_flags=False,  # the spec's ranges (and the bounds) keep them inside
        )
        q.update(static_capacity=caps.M_s, M_d=caps.M_d, M_sd=caps.M_sd)
        hertz_codes.append(caps.result)
    life_result = joint_life(structure, values, design)
    q["life_km"] = life_result.km
    hertz_codes.append(life_result.result)
    q["outer_diameter"] = 2.0 * R + d
    q["R_over_d"] = R / d
    sections = {}
    if structure.halfshaft:
        from tripodjax.optimize.structural import halfshaft_quantities

        hq, sections, halfshaft_codes = halfshaft_quantities(structure, values, design)
        q.update(hq)
        codes.append(halfshaft_codes[0])
        hertz_codes.append(halfshaft_codes[1])
    q = {k: q[k] for k in QUANTITIES if k in q and k in needs} | sections
    finite = jnp.all(jnp.stack([jnp.isfinite(v) for v in q.values()]))
    codes.append(jnp.where(finite, RESULTS.successful, RESULTS.nonfinite))
    return q, jnp.stack([worst(*codes), worst(*hertz_codes)])


def force_inputs(values, params):
    """The spec's [`ForceInputs`][tripodjax.forces.ForceInputs]: its [forces] section at
    loads.gaf_torque with the design's friction ``params``."""
    f = values["forces"]
    rpm = math.pi / 30.0  # rad/s per rpm
    return forces.ForceInputs(
        values["loads"]["gaf_torque"],
        params,
        mu_trunnion=f["mu_trunnion"],
        contact_angle=f["contact_angle"],
        speed=f["speed_rpm"] * rpm,
        plunge_speed=f["plunge_speed_mm_s"],
        lts_speed=f["lts_speed_rpm"] * rpm,
    )


def load_cycles(structure, values):
    """The vehicle's [`LoadCycles`][tripodjax.vehicle.LoadCycles] (the spec's [vehicle] and its k_s)."""
    v, gears = values["vehicle"], values["vehicle.gears"]
    car = vehicle.Vehicle(
        mass=v["mass_kg"],
        front_share=v["front_share"],
        wheelbase=v["wheelbase_m"],
        cg_height=v["cg_height_m"],
        tyre_radius=v["tyre_radius_m"],
        adhesion=v["adhesion"],
        rear_torque_share=v["rear_torque_share"],
        engine_torque=v["engine_torque_Nm"],
        engine_speed=v["engine_speed_rpm"],
        shock_factor=values["loads"]["shock_factor"],
        ratios=gears["ratios"],
        reverse_ratio=gears["reverse"],
        load_transfer_per_ratio=v["load_transfer_per_ratio_N"],
        reverse_load_transfer=v["reverse_load_transfer_N"],
        differential_locking=v["differential_locking"],
    )
    return vehicle.load_cycles(
        car,
        driving_modes(structure, values),
        values["life"]["required_km"],
        axle=structure.axle,
        domain_flags=False,  # the spec's ranges lie inside the vehicle's domains
    )


def driving_modes(structure, values):
    """The vehicle's [`DrivingModes`][tripodjax.vehicle.DrivingModes] (the spec's [vehicle.modes])."""
    modes = values["vehicle.modes"]
    shape = (len(structure.vehicle_modes), -1)  # the spec keeps them flat, mode-major
    use = [
        jnp.reshape(jnp.asarray(modes[f"use_{c}_pct"]), shape) / 100.0
        for c in vehicle.ENGINE_CONDITIONS
    ]
    return vehicle.DrivingModes(weight=modes["weight"], use=jnp.stack(use, axis=-1))


def m_max(structure, values, cycles=None):
    """M_max [N·m]: ``loads.M_max``, or the vehicle's largest forward working torque
    (``cycles``: the vehicle's load cycles where the caller formed them, not traced again)."""
    if structure.m_max_from_vehicle:
        return (load_cycles(structure, values) if cycles is None else cycles).M_max_forward
    return values["loads"]["M_max"]


def joint_torque(structure, values, cycles=None):
    """The torque [N·m] of the joints' static checks (M_s ≥ k_s · it): `m_max`, and where the
    spec has a vehicle the larger of it and the vehicle's largest backward working torque (a
    joint's static capacity holds in either direction; a front-driven car's reverse may carry
    the most). The shaft sections are checked at both torques (``halfshaft_checks``)."""
    forward = m_max(structure, values, cycles)
    if not structure.vehicle_modes:
        return forward
    cycles = load_cycles(structure, values) if cycles is None else cycles
    return jnp.maximum(forward, cycles.M_max_backward)


_joint_torque = latency_bound_jit(joint_torque, static_argnums=0)


def load_spectrum(structure, values):
    """The life's [`LoadSpectrum`][tripodjax.life.LoadSpectrum]: the vehicle's, or the [life] lists."""
    v = values["life"]
    if structure.spectrum_from_vehicle:
        return vehicle.load_spectrum(load_cycles(structure, values))
    return life.LoadSpectrum(
        torque=v["torque"], speed=v["speed"], vehicle_speed=v["vehicle_speed"], share=v["share"]
    )


def joint_life(structure, values, design):
    """The [`Life`][tripodjax.life.Life] of the design under the spec's spectrum and conditions."""
    v = values["life"]
    conditions = life.WorkingConditions(angle=v["condition_angle"], share=v["condition_share"])
    return life.joint_life(
        design["d_roller"],
        design["R"],
        load_spectrum(structure, values),
        conditions,
        conformity=design["conformity"],
        P_d=values["hertz"]["P_d"],
        C_s=values["hertz"]["C_s"],
        n_rollers=structure.n_rollers,
        angle_law=structure.angle_law,
        domain_flags=False,  # the spec's ranges (and the bounds) keep the inputs inside
    )


def objective_and_margins(structure, values, x):
    """(objective, margins, quantities, result code) of the free-variable vector x.

    The margins of the spec's chance constraints follow the deterministic ones (see
    [`chance_margins`][tripodjax.optimize.problem.chance_margins]).
    """
    q, code = quantities(structure, values, full_design(structure, values, x))
    o = values["objective"]
    objective = sum(o[f"w_{k}"] * q[k] / o[f"{k}_ref"] for k in structure.objective)
    margins = requirement_margins(structure, values, q)
    if structure.chance:
        chance, chance_code = chance_margins(structure, values, x)
        margins = jnp.concatenate([margins, chance])
        code = jnp.maximum(code, chance_code)
    objective = jnp.asarray(objective)
    # Finite quantities can still give an infinite objective or margin (a weight of 1e300 over
    # a reference of 1e-300, an M_max of 5e-324): that is a non-finite problem, not a solve's.
    finite = jnp.isfinite(objective) & jnp.all(jnp.isfinite(margins))
    code = code.at[0].max(jnp.where(finite, RESULTS.successful, RESULTS.nonfinite))
    return objective, margins, q, code


def requirement_structure(structure):
    """The structure of the requirements alone: no objective terms, no chance constraints."""
    return dataclasses.replace(structure, objective=(), chance=())


def limit_state(structure, values, x, u):
    """(margins, code) of the requirements with the uncertain numbers at standard normal ``u``.

    A margin < 0 is a miss; ``structure`` is a
    [`requirement_structure`][tripodjax.optimize.problem.requirement_structure].
    """
    values, x = uncertainty.perturb(structure, values, x, u)
    q, code = quantities(structure, values, full_design(structure, values, x))
    return requirement_margins(structure, values, q), code


PMA_STEPS = 12  # hybrid-mean-value steps to the inverse-FORM point (fixed: traced)


def chance_margins(structure, values, x):
    """Margins of the chance constraints by the performance-measure approach (PMA).

    For a target index β_t (−Φ⁻¹(P_max) for ``max_failure_probability_<q>``) the margin is
    the requirement's margin at the inverse-FORM point, min g(u) over |u| = β_t; it is ≥ 0
    when the FORM probability of missing is ≤ P_max. The point comes from ``PMA_STEPS``
    hybrid-mean-value steps from the mean (Youn, Choi & Park 2003): the advanced-mean-value
    step u ← β_t n(u), n = −∇g/|∇g|, while g is convex along the iterates, the conjugate step
    u ← β_t (n_k + n_{k−1} + n_{k−2})/|…| where it is concave (AMV alone cycles there); the
    lowest margin seen is kept. A point of the sphere without a finite margin (a tail of an
    input where the model overflows) leaves the minimum undefined: that margin is NaN with the
    code ``nonfinite``, never the lowest finite point's or the mean's. The point is held fixed
    in the derivatives: at the minimiser ∂g/∂x is the margin's total derivative
    (``_pma_margin``). Returns (margins, worst code).
    """
    rs = chance_target_structure(structure)
    names = constraint_names(rs)
    targets, betas = [], []
    for key, kind, requirements in structure.chance:
        number = values["constraints"][key]
        beta = -ndtri(number) if kind == "probability" else number
        for name in requirements:
            targets.append(names.index(name))
            betas.append(beta)
    one = len(targets) == 1  # the usual case: no batch of one to trace
    targets = jnp.asarray(targets, jnp.int32)
    betas = jax.lax.stop_gradient(jnp.stack(betas).astype(x.dtype))  # the point held fixed
    if one:
        margin, code = _pma_margin(rs, values, x, targets[0], betas[0])
        return margin[None], code
    margins, codes = jax.vmap(lambda j, beta: _pma_margin(rs, values, x, j, beta))(targets, betas)
    return margins, jnp.max(codes, axis=0)


def _requirement(rs, values, x, j, u):
    """(margin of requirement j of ``rs``, the code) with the uncertain numbers at u."""
    margins, code = limit_state(rs, values, x, u)
    return margins[j], code


def _pma_search(rs, values, x, j, beta):
    """The PMA steps of requirement j (see ``chance_margins``) at fixed (values, x): (the margin
    at the point, its code, the margin's x-gradient there, the point u).

    Each step evaluates the margin with its derivatives along u and along x (forward mode, one
    linearisation), and the step that finds the lowest margin keeps all three: the margin at
    the point and its Jacobian in x come out of the loop, and the program holds the
    requirement's model once (evaluated again at the point, it was one more copy in the
    solve's program; see docs/speed-accuracy.md).
    """
    values, x = jax.lax.stop_gradient((values, x))
    n = len(rs.uncertainty)
    basis = jnp.eye(n + x.shape[-1], dtype=x.dtype)

    def g(w):  # w = (u, x)
        return _requirement(rs, values, w[n:], j, w[:n])

    def step(k, s):
        w = jnp.concatenate([s["u"], x])
        value, slopes, code = jax.vmap(
            lambda t: jax.jvp(g, (w,), (t,), has_aux=True), out_axes=(None, 0, None)
        )(basis)
        grad = slopes[:n]
        # The lowest margin on the sphere (the mean, k = 0, is not on it). A point of the
        # sphere without a finite margin (an input's tail where the model overflows, or the
        # mean's own margin not finite, which sends every step to NaN) leaves the minimum
        # undefined: neither the lowest finite point nor the mean stands in for it.
        better = (value < s["best"]) & (k >= 1)
        keep = better | (k == 0)
        answer = (value, code, slopes[n:], s["u"])
        answer = jax.tree_util.tree_map(lambda a, b: jnp.where(keep, a, b), answer, s["answer"])
        best = jnp.where(better, value, s["best"])
        undefined = s["undefined"] | ((k >= 1) & ~jnp.isfinite(value))
        norm = jnp.linalg.norm(grad)
        normal = -grad / jnp.where(norm > 0, norm, 1.0)
        zeta = jnp.dot(normal - s["n1"], s["n1"] - s["n2"])
        conjugate = s["n1"] + s["n2"] + normal
        conjugate = conjugate / jnp.maximum(jnp.linalg.norm(conjugate), 1e-300)
        direction = jnp.where((k >= 2) & (zeta < 0), conjugate, normal)
        return dict(
            u=beta * direction, n1=normal, n2=s["n1"], best=best, answer=answer, undefined=undefined
        )

    zero = jnp.zeros(n, x.dtype)
    inf = jnp.asarray(jnp.inf, x.dtype)
    # (margin, code, x-gradient, u): the code is quantities' pair (kinematics and forces, Hertz).
    answer = (inf, jnp.zeros(2, jnp.int32), jnp.zeros_like(x), zero)
    init = dict(u=zero, n1=zero, n2=zero, best=inf, answer=answer, undefined=jnp.bool_(False))
    out = jax.lax.fori_loop(0, PMA_STEPS + 1, step, init)  # the last pass only scores
    margin, code, slope, u = out["answer"]
    undefined = out["undefined"]  # NaN and a nonfinite code: the solve says so, names the key
    code = code.at[0].max(jnp.where(undefined, RESULTS.nonfinite, RESULTS.successful))
    nan = jnp.asarray(jnp.nan, x.dtype)
    return jnp.where(undefined, nan, margin), code, jnp.where(undefined, nan, slope), u


def _instantiate(tangent):
    """A symbolic zero tangent as an array of zeros (float0 for an integer primal)."""
    if not isinstance(tangent, SymbolicZero):
        return tangent
    shape, dtype = tangent.aval.shape, tangent.aval.dtype
    return np.zeros(shape, dtype) if dtype == jax.dtypes.float0 else jnp.zeros(shape, dtype)


def _is_zero(tangents):
    return all(
        isinstance(t, SymbolicZero)
        for t in jax.tree_util.tree_leaves(tangents, is_leaf=lambda t: isinstance(t, SymbolicZero))
    )


@functools.partial(jax.custom_jvp, nondiff_argnums=(0,))
def _pma_margin(rs, values, x, j, beta):
    """(margin, code) of requirement j at its inverse-FORM point (``_pma_search``).

    Derivatives at the point held fixed: along x from the search's own gradient (no second
    evaluation of the model: the solve differentiates along x alone), along the spec's numbers
    by a forward pass at the point (only where they move: the sensitivities' reverse pass).
    """
    margin, code, _, _ = _pma_search(rs, values, x, j, beta)
    return margin, code


@functools.partial(_pma_margin.defjvp, symbolic_zeros=True)
def _pma_margin_jvp(rs, primals, tangents):
    values, x, j, beta = primals
    d_values, d_x, _, _ = tangents
    margin, code, slope, u = _pma_search(rs, values, x, j, beta)
    tangent = jnp.zeros_like(margin)
    if not _is_zero(d_x):
        tangent += jnp.dot(_pma_slope(rs, values, x, j, u, slope), _instantiate(d_x))
    if not _is_zero(d_values):
        d_values = jax.tree_util.tree_map(
            _instantiate, d_values, is_leaf=lambda t: isinstance(t, SymbolicZero)
        )
        along = jax.jvp(lambda v: _requirement(rs, v, x, j, u)[0], (values,), (d_values,))
        tangent += along[1]
    return (margin, code), (tangent, np.zeros(code.shape, jax.dtypes.float0))


@functools.partial(jax.custom_jvp, nondiff_argnums=(0,))
def _pma_slope(rs, values, x, j, u, slope):
    """∂g/∂x at the point u, ``slope`` (from ``_pma_search``); its derivatives (a reverse pass
    through the solve's Jacobian) by forward mode over the model at u."""
    return slope


@functools.partial(_pma_slope.defjvp, symbolic_zeros=True)
def _pma_slope_jvp(rs, primals, tangents):
    values, x, j, u, slope = primals
    d_values, d_x = tangents[:2]
    if _is_zero((d_values, d_x)):
        return slope, jnp.zeros_like(slope)
    d_values, d_x = jax.tree_util.tree_map(
        _instantiate, (d_values, d_x), is_leaf=lambda t: isinstance(t, SymbolicZero)
    )

    def gradient(v, y):
        return jax.jacfwd(lambda z: _requirement(rs, v, z, j, u)[0])(y)

    return slope, jax.jvp(gradient, (values, x), (d_values, d_x))[1]


def chance_target_structure(structure):
    """The requirements the chance constraints hold with a probability, alone: no objective, no
    chance constraints, of the spec's constraints only those a chance constraint names, the
    halfshaft's quantities only for a halfshaft quantity's constraint among them.

    Its margins and codes are those of the same requirements in the whole requirement
    structure; the PMA steps and the margins at the inverse-FORM points compute only what the
    targets need (they evaluated every requirement: with one chance constraint on the life,
    the solve's program 2958 → 2341 kB, its trace 3.9 → 2.6 s, ``python -m tripodjax.bench
    --latency``).
    """
    named = {name for _, _, requirements in structure.chance for name in requirements}
    constraints = tuple(c for c in structure.constraints if c[0] in named)
    halfshaft = any(q in HALFSHAFT_QUANTITIES for _, q, _ in constraints)
    return dataclasses.replace(
        structure, objective=(), chance=(), constraints=constraints, halfshaft_checked=halfshaft
    )


def requirement_margins(structure, values, q):
    """The deterministic margins (static capacity, life, the spec's constraints) from quantities."""
    loads = values["loads"]
    required_km = values["life"]["required_km"]
    margins = [
        jnp.log(q["static_capacity"] / (loads["shock_factor"] * joint_torque(structure, values))),
        jnp.log(q["life_km"] / required_km),
    ]
    if structure.halfshaft:
        for name in structure.shaft_sections:
            margins.append(jnp.log(q[f"shaft_static_safety[{name}]"]))
            margins.append(jnp.log(values["shaft"]["allowed_damage"] / q[f"shaft_damage[{name}]"]))
        margins.append(jnp.log(q["outboard_static_safety"] / loads["shock_factor"]))
        margins.append(jnp.log(q["outboard_life_km"] / required_km))
    for name, k, sense in structure.constraints:
        limit = values["constraints"][name]
        value = jnp.maximum(q[k], MARGIN_FLOOR * limit)
        margins.append(jnp.log(limit / value) if sense == "max" else jnp.log(value / limit))
    return jnp.stack(margins)


def limits(structure, values):
    """name → (quantity, limit, sense, unit) of each constraint, for reports."""
    loads = values["loads"]
    with jax.enable_x64(True):  # the vehicle's M_max in float64, as the solve
        # compiled (and, in the command, exported): op by op it took ~0.2 s a call
        torque = float(call(_joint_torque, structure, values))
    out = {
        "static_capacity": (
            "static_capacity",
            float(loads["shock_factor"] * torque),
            "≥",
            "N·m",
        ),
        "life": ("life_km", float(values["life"]["required_km"]), "≥", "km"),
    }
    if structure.halfshaft:
        for name in structure.shaft_sections:
            out[f"shaft_static[{name}]"] = (f"shaft_static_safety[{name}]", 1.0, "≥", "–")
            allowed = float(values["shaft"]["allowed_damage"])
            out[f"shaft_fatigue[{name}]"] = (f"shaft_damage[{name}]", allowed, "≤", "–")
        shock = float(loads["shock_factor"])
        out["outboard_static"] = ("outboard_static_safety", shock, "≥", "–")
        out["outboard_life"] = ("outboard_life_km", out["life"][1], "≥", "km")
    for name, k, sense in structure.constraints:
        out[name] = (
            k,
            float(values["constraints"][name]),
            "≤" if sense == "max" else "≥",
            quantity_unit(k),
        )
    # A chance constraint: its requirement's quantity and limit (value: at the nominal design;
    # margin: at the inverse-FORM point).
    for key, _, requirements in structure.chance:
        for name in requirements:
            out[key if len(requirements) == 1 else f"{key}:{name}"] = out[name]
    return out


def fixed_design(values):
    """Every design variable of ``VARIABLES`` at its spec value, in spec units (γ0 in degrees)."""
    return {
        name: to_spec_units(name, values[section][key])
        for name, (section, key, _, _) in VARIABLES.items()
    }


def spec_design(structure, values):
    """The free variables at their spec values ([shaft] entries too), in spec units."""
    fixed = fixed_design(values)
    design = {}
    for name in structure.free:
        entry = shaft_variable(name)
        if entry is None:
            design[name] = fixed[name]
        else:
            key, section = entry
            design[name] = float(values["shaft"][key][structure.shaft_sections.index(section)])
    return design


def to_spec_units(name, value):
    """A design variable's internal value in its spec unit (γ0: rad → deg)."""
    return math.degrees(value) if name == "gamma0_deg" else float(value)


def from_spec_units(name, value):
    return math.radians(value) if name == "gamma0_deg" else float(value)


@functools.partial(latency_bound_jit, static_argnums=0)
def _evaluate(structure, values, x):
    return objective_and_margins(structure, values, x)


def check_spec(spec, name="spec"):
    """``TypeError`` naming ``name`` unless ``spec`` is a checked [`Spec`][tripodjax.optimize.Spec]."""
    return check_instance(name, spec, Spec, "a Spec (tripodjax.optimize.load_spec())")


def check_result(spec, result, name="result"):
    """``TypeError`` naming ``name`` unless ``result`` is a Result of a solve of ``spec``'s structure.

    A Result knows its free variables and constraints; another spec's Result (other free
    variables or constraints) would be read against the wrong numbers.
    """
    from tripodjax.optimize.solver import Result

    check_spec(spec)
    check_instance(name, result, Result, "the Result of tripodjax.optimize.solve(spec)")
    free = tuple(result.starts[0]["design"]) if result.starts else ()
    names = constraint_names(spec.structure)
    if free != spec.structure.free or tuple(result.multipliers) != names:
        raise TypeError(
            f"{name} is the Result of another spec (free variables {', '.join(free) or 'none'}; "
            f"constraints {', '.join(result.multipliers)}); allowed: the Result of "
            f"solve(spec) for this spec (free variables {', '.join(spec.structure.free)}; "
            f"constraints {', '.join(names)})"
        )
    return result


def check_design(structure, values, design):
    """Check a ``{variable: value}`` design (spec units, any mapping); returns it as floats."""
    if not isinstance(design, Mapping):
        raise TypeError(
            f"design = {design!r:.60} is not allowed; allowed: a mapping {{variable: value}} "
            f"(got a {type(design).__name__})"
        )
    shaft_entries = [
        shaft_variable_name(k, n) for n in structure.shaft_sections for k in SHAFT_VARIABLES
    ]
    unknown = sorted(set(design) - set(VARIABLES) - set(shaft_entries))
    if unknown:
        raise ValueError(
            f"design keys {unknown} not allowed; allowed: {', '.join(VARIABLES)}, or a [shaft] "
            f'entry "shaft.<list>[<section>]" ({shaft_entries[0] if shaft_entries else "none"}, …)'
        )
    missing = [k for k in structure.free if k not in design]
    if missing:
        raise ValueError(
            f"design lacks the free variables {missing} (spec units: {', '.join(f'{k} [{variable_domain(k)[0]}]' for k in missing)})"
        )
    out = {}
    for key, value in design.items():
        unit, (low, high, low_open) = variable_domain(key)
        value = real_scalar(f"design[{key!r}]", value, f"a real number [{unit}]")
        ok = math.isfinite(value) and (value > low if low_open else value >= low)
        ok = ok and (high is None or value <= high)
        if not ok:
            allowed = f"{'>' if low_open else '≥'} {low:g}" + (
                f" and ≤ {high:g}" if high is not None else ""
            )
            raise ValueError(
                f"design[{key!r}] = {value!r} is outside the allowed range: a finite number {allowed} {unit}"
            )
        out[key] = value
    _check_shaft_sections(structure, values, out)
    check_layout_domain(  # the one layout-domain rule of the package
        R=out.get("R", float(values["design"]["R"])),
        l=out.get("l", float(values["layout"]["l"])),
        gamma0=out.get("gamma0_deg"),
        names={"R": "design['R']", "l": "design['l']", "gamma0": "design['gamma0_deg']"},
        degrees=True,
    )
    return out


def _with_shaft_entries(structure, lists, design):
    """The [shaft] lists (NumPy copies) with the design's [shaft] entries in them."""
    lists = {k: np.array(v, np.float64) for k, v in lists.items()}
    for name, value in design.items():
        entry = shaft_variable(name)
        if entry is not None:
            lists[entry[0]][structure.shaft_sections.index(entry[1])] = value
    return lists


def _check_shaft_sections(structure, values, design):
    """ValueError naming the section when the design's [shaft] entries leave it outside its
    domain (Øi < Øe, h + t within the wall)."""
    from tripodjax import shaft

    lists = _with_shaft_entries(structure, values["shaft"], design)
    touched = {shaft_variable(k)[1] for k in design if shaft_variable(k)}
    for name in touched:
        i = structure.shaft_sections.index(name)
        try:
            shaft.Section(*(float(lists[k][i]) for k in SECTION_FIELDS))
        except ValueError as error:
            raise ValueError(f"design: shaft section {name!r}: {error}") from None


# The Section fields' [shaft] lists, in its argument order.
SECTION_FIELDS = (
    "outer_diameter_mm",
    "hardened_depth_mm",
    "transition_depth_mm",
    "inner_diameter_mm",
)


def design_values(spec, design):
    """(values, x) of a checked ``{variable: value}`` design (spec units): the numbers with the
    given fixed variables overridden, and the free-variable vector (internal units)."""
    structure = spec.structure
    design = check_design(structure, spec.values, design)
    values = jax.tree_util.tree_map(np.asarray, spec.values)
    fixed = {k: v for k, v in design.items() if k not in structure.free}
    values["shaft"] = dict(
        values["shaft"], **_with_shaft_entries(structure, values["shaft"], fixed)
    )
    for key, value in fixed.items():
        if not shaft_variable(key):
            section, name = VARIABLES[key][:2]
            values[section] = dict(
                values[section], **{name: np.asarray(from_spec_units(key, value))}
            )
    return values, np.array([from_spec_units(k, design[k]) for k in structure.free])


def evaluate(spec: Spec, design: Mapping[str, float]) -> dict:
    """Objective, constraint margins and quantities of one design.

    Args:
        spec: a [`Spec`][tripodjax.optimize.Spec] (``optimize.load_spec()``).
        design: ``{variable: value}`` in spec units (``R``, ``d_roller``, ``l`` [mm],
            ``gamma0_deg`` [deg], ``conformity``, ``lam``, ``mu_slp``). Every free
            variable is required; a fixed one given here overrides its spec value.

    Returns:
        ``{"objective": float, "constraints": {name: margin}, "quantities": {name: value},
        "result": RESULTS name, "life": the life and its damage shares}`` — a margin ≥ 0
        means satisfied (see the module docstring), the bounds of the free variables
        included; "life" as [`life_report`][tripodjax.optimize.life_report]. Jit-compiled once per
        spec structure; runs in float64 (inside ``jax.enable_x64``, scoped to the call).

    Examples:
        >>> from tripodjax import optimize
        >>> spec = optimize.load_spec()
        >>> out = optimize.evaluate(spec, {"R": 21.3, "d_roller": 27.8})
        >>> round(out["quantities"]["outer_diameter"], 1)
        70.4
    """
    structure = check_spec(spec).structure
    values, x = design_values(spec, design)
    with jax.enable_x64(True):  # the design problem runs in float64; scoped to this call
        out = call(_evaluate, structure, values, np.asarray(x))
        objective, margins, q, code = jax.tree_util.tree_map(np.asarray, out)
        objective, margins = float(objective), [float(m) for m in margins]
        q = {k: float(v) for k, v in q.items()}
        life_shares = _life_report(structure, values, x)
    result = dict(zip(constraint_names(structure), margins, strict=True))
    lower, upper = bounds(structure, values, np)
    span = upper - lower
    for i, name in enumerate(structure.free):
        result[f"{name}_lower_bound"] = float((x[i] - lower[i]) / span[i])
        result[f"{name}_upper_bound"] = float((upper[i] - x[i]) / span[i])
    return {
        "objective": objective,
        "constraints": result,
        "quantities": q,
        "result": RESULTS(int(np.max(code))).name,
        "life": life_shares,
    }


@functools.partial(latency_bound_jit, static_argnums=0)
def _life(structure, values, x):
    result = joint_life(structure, values, full_design(structure, values, x))
    forward = backward = jnp.nan
    if structure.m_max_from_vehicle or structure.spectrum_from_vehicle:
        cycles = load_cycles(structure, values)
        forward, backward = cycles.M_max_forward, cycles.M_max_backward
    if not structure.m_max_from_vehicle:
        forward = values["loads"]["M_max"]
    return result, forward, backward


def gear_names(values):
    """The gear labels of the spec's vehicle: "1" … "G", then "R"."""
    return [str(i + 1) for i in range(len(values["vehicle.gears"]["ratios"]))] + ["R"]


# The spec's sections only the solve reads (its box, terms, limits, controls, tolerances).
_SOLVE_SECTIONS = ("bounds", "constraints", "objective", "solver", "uncertainty")


def report_arguments(structure, values, level=False):
    """(structure, values) for a report's program that reads nothing only the solve reads: the
    structure with no objective, constraints, chance constraints or uncertain inputs, one start
    and one iteration, and newton at 360 angles unless ``level`` (its own level and grid kept);
    the values without the solve's sections. The life's, the halfshaft's (``level`` False) and
    the forces' (``level`` True) report programs take these: specs that differ only there share
    them (a cold ``optimize-joint`` compiled the life's twice, for the spec and its full-fidelity
    check; a spec with a chance constraint loads the default run's three from the command's cache).
    """
    kept = {} if level else {"fidelity": "newton", "n_theta": 360}
    structure = dataclasses.replace(
        structure,
        objective=(),
        constraints=(),
        chance=(),
        uncertainty=(),
        starts=1,
        **kept,
    )
    return structure, {k: v for k, v in values.items() if k not in _SOLVE_SECTIONS}


def _life_report(structure, values, x):
    """The life of design x, its damage shares and M_max (the ``life`` section of the report)."""
    out = call(_life, *report_arguments(structure, values), np.asarray(x))
    result, forward, backward = jax.tree_util.tree_map(np.asarray, out)
    v = values["life"]
    conditions = [
        {
            "name": name,
            "angle_deg": math.degrees(float(angle)),
            "share": float(share),
            "life_km": float(km),
            "damage_share": float(damage),
        }
        for name, angle, share, km, damage in zip(
            structure.condition_names,
            v["condition_angle"],
            v["condition_share"],
            result.km_per_condition,
            result.damage_per_condition,
            strict=True,
        )
    ]
    damage = np.asarray(result.damage_per_case)
    if structure.spectrum_from_vehicle:
        gears = gear_names(values)
        shape = (len(structure.vehicle_modes), len(gears), len(vehicle.ENGINE_CONDITIONS))
        grid = damage[:-1].reshape(shape)  # the last case: revolutions that do no damage
        cases = [
            {
                "mode": mode,
                "gear": gear,
                "engine_condition": condition,
                "damage_share": float(grid[m, g, c]),
            }
            for m, mode in enumerate(structure.vehicle_modes)
            for g, gear in enumerate(gears)
            for c, condition in enumerate(vehicle.ENGINE_CONDITIONS)
        ]
    else:
        cases = [
            {
                "mode": None,
                "gear": None,
                "engine_condition": None,
                "case": i,
                "damage_share": float(d),
            }
            for i, d in enumerate(damage)
        ]
    return {
        "km": float(result.km),
        "hours": float(result.hours),
        "required_km": float(v["required_km"]),
        "angle_law": structure.angle_law,
        "M_max_forward_Nm": float(forward),
        "M_max_backward_Nm": float(backward),
        "conditions": conditions,
        "damage_by_case": cases,
    }


def life_report(spec: Spec, design: Mapping[str, float]) -> dict:
    """The ``life`` section of the report for a design (spec units, as [`evaluate`][tripodjax.optimize.evaluate]).

    ``{"km", "hours", "required_km", "angle_law", "M_max_forward_Nm", "M_max_backward_Nm",
    "conditions": [{"name", "angle_deg", "share", "life_km", "damage_share"}],
    "damage_by_case": [{"mode", "gear", "engine_condition", "damage_share"}]}``; the damage
    shares sum to 1 (0 everywhere for a spectrum that does no damage). With an explicit
    spectrum the cases carry their index ``case`` and ``None`` for mode, gear and engine
    condition; without a vehicle M_max_backward_Nm is NaN.
    """
    values, x = design_values(check_spec(spec), design)
    with jax.enable_x64(True):
        return _life_report(spec.structure, values, x)


# The forces section: quantity of tripodjax.forces → its report key (unit in the name).
FORCE_REPORT_KEYS = {
    "gaf_rms": "gaf_rms_N",
    "gaf_peak": "gaf_peak_N",
    "gaf_third_order": "gaf_third_order_N",
    "gaf_sixth_order": "gaf_sixth_order_N",
    "gaf_ninth_order": "gaf_ninth_order_N",
    "lts_mean": "lts_mean_N",
    "lts_ripple": "lts_ripple_N",
    "complementary_torque_steady": "complementary_torque_steady_Nm",
    "complementary_torque_third_order": "complementary_torque_third_order_Nm",
    "complementary_torque_sixth_order": "complementary_torque_sixth_order_Nm",
    "roller_load_ratio": "roller_load_ratio",
    "friction_power": "friction_power_W",
}


@functools.partial(latency_bound_jit, static_argnums=0)
def _forces_report(structure, values, x):
    design = full_design(structure, values, x)
    layout = Layout(design["R"], design["l"], design["gamma0_deg"])
    params = friction.GREASE_A.replace(lam=design["lam"], mu_slp=design["mu_slp"])
    # At least the force model's minimum of angles (the fewest that tell its orders apart); the
    # spec's own grid otherwise, as its quantities (a constraint's value the same number here).
    n_theta = max(structure.n_theta, MIN_N_THETA_ORDERS)
    sol, rates = revolution(layout, n_theta, structure.fidelity, with_rates=True)
    names = (*FORCE_REPORT_KEYS, "result")
    return forces.force_quantities(layout, sol, rates, force_inputs(values, params), names)


def forces_report(spec: Spec, design: Mapping[str, float]) -> dict:
    """The ``forces`` section of the report for a design (spec units, as [`evaluate`][tripodjax.optimize.evaluate]).

    The force model ([`tripodjax.forces`][tripodjax.forces], seed §3.1) of the design's
    halfshaft over a revolution at ``loads.gaf_torque``, with the spec's ``[forces]`` and
    friction, at the spec's solver level: ``{"torque_Nm", "nominal_roller_load_N"`` (T/3R),
    ``"speed_rpm", "plunge_speed_mm_s", "lts_speed_rpm", "mu_trunnion", "contact_angle_deg"``, the
    GAF (``gaf_rms_N``, ``gaf_peak_N``, ``gaf_third_order_N``, ``gaf_sixth_order_N``,
    ``gaf_ninth_order_N``), the LTS (``lts_mean_N``, ``lts_ripple_N``), the complementary
    torque (``complementary_torque_steady_Nm``, ``..._third_order_Nm``,
    ``..._sixth_order_Nm``), ``roller_load_ratio``, ``friction_power_W`` and ``result`` (a
    RESULTS name)}``. The revolution has at least ``tripodjax.kinematics.MIN_N_THETA_ORDERS`` angles.
    """
    structure = check_spec(spec).structure
    values, x = design_values(spec, design)
    with jax.enable_x64(True):
        out = call(_forces_report, *report_arguments(structure, values, level=True), x)
        torque = float(values["loads"]["gaf_torque"])
        R = float(full_design(structure, values, x)["R"])
        f = values["forces"]
        return {
            "torque_Nm": torque,
            "nominal_roller_load_N": 1000.0 * torque / (3.0 * R),
            "speed_rpm": float(f["speed_rpm"]),
            "plunge_speed_mm_s": float(f["plunge_speed_mm_s"]),
            "lts_speed_rpm": float(f["lts_speed_rpm"]),
            "mu_trunnion": float(f["mu_trunnion"]),
            "contact_angle_deg": math.degrees(float(f["contact_angle"])),
            **{key: float(out[name]) for name, key in FORCE_REPORT_KEYS.items()},
            "result": RESULTS(int(out["result"])).name,
        }


OWN_PROGRAM_ROWS = 128  # rows per call when the catalogue's structure is not the spec's


def _evaluate_sizes(spec, sizes):
    """(objective, margins, quantities) for (R, d) pairs, every other variable at its spec value.

    Through the solve's program when R and d_roller are free in the spec (the catalogue's
    problem is then the spec's own); the bounds of R and d do not apply.
    """
    from tripodjax.optimize.solver import SAFETY, evaluate_points

    unbounded = _unbounded(spec)
    shared = unbounded.structure == spec.structure
    spec, structure = unbounded, unbounded.structure
    fixed = fixed_design(spec.values)
    rows = [
        [from_spec_units(k, dict(fixed, R=R, d_roller=d)[k]) for k in structure.free]
        for R, d in sizes
    ]
    batch = jax.tree_util.tree_map(lambda a: np.stack([np.asarray(a)] * len(rows)), spec.values)
    # R and d fixed in the spec: no solve of this structure ran, so use larger blocks.
    with contextlib.nullcontext() if shared else rows_per_call(OWN_PROGRAM_ROWS):
        f, c, _, _, q, _ = evaluate_points(structure, batch, np.asarray(rows, float))
    offset = SAFETY * float(spec.values["solver"]["tolerance"])
    return f, c + offset, q, constraint_names(structure)


def evaluate_catalogue(spec: Spec) -> tuple[list[dict], dict | None]:
    """Every GE and GI catalogue size (seed §1.1.2) under the spec, and the best feasible one.

    R and d come from the catalogue, every other variable stays at its fixed spec
    value; the bounds of the design variables do not apply. Returns
    ``(entries, choice)``: entries ``{"family", "size", "R_mm", "d_roller_mm",
    "feasible", "objective", "margins", "quantities"}`` with the margins that
    [`evaluate`][tripodjax.optimize.evaluate] gives (bounds left out), and the feasible
    entry with the lowest objective (None when no size is feasible).
    """
    from tripodjax import catalogue

    fixed = fixed_design(check_spec(spec).values)
    sizes, entries = [], []
    for family, table in (("GE", catalogue.GE), ("GI", catalogue.GI)):
        for size, row in table.items():
            entry = {"family": family, "size": size, "R_mm": row["R"], "d_roller_mm": row["d"]}
            entries.append(entry)
            try:
                check_layout_domain(R=row["R"], l=fixed["l"], names={"R": f"{family} {size} R"})
            except ValueError as error:  # outside the halfshaft domain (R/l > 0.2)
                entry.update(
                    feasible=False, objective=None, margins={}, quantities={}, note=str(error)
                )
                continue
            sizes.append(entry)
    f, c, q, names = _evaluate_sizes(spec, [(e["R_mm"], e["d_roller_mm"]) for e in sizes])
    for i, entry in enumerate(sizes):
        margins = {n: float(m) for n, m in zip(names, c[i], strict=True)}
        entry.update(
            feasible=bool(all(m >= 0 for m in margins.values())),
            objective=float(f[i]),
            margins=margins,
            quantities={k: float(v[i]) for k, v in q.items()},
        )
    feasible = [e for e in entries if e["feasible"] and math.isfinite(e["objective"])]
    choice = min(feasible, key=lambda e: e["objective"]) if feasible else None
    return entries, choice


def constraint_landscape(spec: Spec, R: np.ndarray, d: np.ndarray) -> dict:
    """Objective and margins over the (R, d) grid ``R × d`` [mm], the rest at its spec values.

    Returns ``{"R", "d", "objective" (len R × len d), "margins": {name: array}}``, for
    plots of the constraint landscape (the catalogue figure of the report).
    """
    check_spec(spec)
    R, d = np.asarray(R, float), np.asarray(d, float)
    RR, DD = np.meshgrid(R, d, indexing="ij")
    f, c, _, names = _evaluate_sizes(spec, list(zip(RR.ravel(), DD.ravel(), strict=True)))
    shape = RR.shape
    return {
        "R": R,
        "d": d,
        "objective": f.reshape(shape),
        "margins": {n: c[:, i].reshape(shape) for i, n in enumerate(names)},
    }


def _unbounded(spec):
    """The spec with R and d_roller free over a box wide enough for any catalogue size."""
    structure = spec.structure
    free = tuple(k for k in VARIABLES if k in structure.free or k in ("R", "d_roller"))
    b = dict(spec.values["bounds"])
    b.setdefault("R", np.array([1.0, 1000.0]))
    b.setdefault("d_roller", np.array([1.0, 1000.0]))
    values = dict(spec.values, bounds=b)
    return dataclasses.replace(
        spec, structure=dataclasses.replace(structure, free=free), values=values
    )
