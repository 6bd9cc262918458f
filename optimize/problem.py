"""The joint-design problem: design variables → objective and constraint margins.

Design variables: the track pitch-circle radius R and the roller diameter d
[mm]. For each design the halfshaft (layout l, γ0 from the spec) is solved
over a revolution by the implicit-differentiated Newton solve; the
irregularity and the GAF RMS come from it, the static capacity and the life
from the Hertz contact (seed §4.2). Everything is differentiable in (R, d).

Objective (dimensionless):

    f = w_irr · Irr / Irr_ref + w_gaf · GAF_rms / GAF_ref + w_size · (2R + d) / D_ref,

with 2R + d the outer diameter swept by the rollers, a proxy for the joint's size.

Constraint margins, ≥ 0 when satisfied, as logarithmic ratios (0.01 = 1 % to spare):

    static_capacity   ln(M_s / (shock · M_max))
    life              ln(L_km / required_km)
    R_over_d_min      ln((R/d) / lo),   R_over_d_max   ln(hi / (R/d))
    outer_diameter    ln(D_max / (2R + d))             (when the spec sets one)

and the bounds on R and d, (x − lo)/(hi − lo) and (hi − x)/(hi − lo).
"""

import functools

import jax
import jax.numpy as jnp
import numpy as np

from tripodjax import friction, hertz
from tripodjax.kinematics import revolution
from tripodjax.layout import Layout

GREASES = {"A": friction.GREASE_A, "B": friction.GREASE_B, "dry": friction.DRY}
VARIABLES = ("R", "d_roller")


def scenario(spec, **overrides):
    """The traced parameters of a solve: layout and objective weights (overridable per family member)."""
    values = {
        "l": spec["layout"]["l"],
        "gamma0": spec["layout"]["gamma0_rad"],
        "w_irregularity": spec["objective"]["w_irregularity"],
        "w_gaf": spec["objective"]["w_gaf"],
        "w_size": spec["objective"]["w_size"],
    }
    values.update(overrides)
    return {k: jnp.asarray(v, jnp.float64) for k, v in values.items()}


def constraint_names(spec):
    names = ["static_capacity", "life", "R_over_d_min", "R_over_d_max"]
    if "max_outer_diameter" in spec["constraints"]:
        names.append("outer_diameter")
    return tuple(names)


def quantities(spec, x, params):
    """Physical quantities of the design x = (R, d) [mm] under scenario ``params``."""
    R, d = x[0], x[1]
    h, fr, loads = spec["hertz"], spec["friction"], spec["loads"]
    layout = Layout(R, params["l"], params["gamma0"])
    sol, rates = revolution(layout, spec["solver"]["n_theta"], "newton", with_rates=True)
    friction_params = GREASES[fr["grease"]].replace(lam=fr["lam"])
    gaf = friction.gaf_from_revolution(
        layout,
        sol,
        rates,
        loads["gaf_torque"],
        friction_params,
        fr["gaf_model"],
        friction.DEFAULT_STROKE_WIDTH,
    )
    caps = hertz.capacities(
        d,
        R,
        conformity=h["conformity"],
        P_s=h["P_s"],
        P_d=h["P_d"],
        P_sd=h["P_sd"],
        C_s=h["C_s"],
        n_rollers=h["n_rollers"],
    )
    life_spec = spec["life"]
    spectrum = hertz.LoadSpectrum(
        **{
            k: jnp.asarray(life_spec["spectrum"][k])
            for k in ("torque", "speed", "vehicle_speed", "share")
        }
    )
    conditions = hertz.WorkingConditions(
        angle=jnp.asarray(life_spec["conditions"]["angle_rad"]),
        share=jnp.asarray(life_spec["conditions"]["share"]),
    )
    life = hertz.joint_life(
        d,
        R,
        spectrum,
        conditions,
        conformity=h["conformity"],
        P_d=h["P_d"],
        C_s=h["C_s"],
        n_rollers=h["n_rollers"],
    )
    return {
        "irregularity": jnp.max(rates.psi) - jnp.min(rates.psi),
        "gaf_rms": gaf.rms,
        "outer_diameter": 2.0 * R + d,
        "static_capacity": caps.M_s,
        "life_km": life.km,
        "R_over_d": R / d,
        "converged": jnp.all(sol.converged),
    }


def objective_and_margins(spec, x, params):
    """(objective, margins, quantities) of design x under ``params``; margins in constraint_names order."""
    q = quantities(spec, x, params)
    o = spec["objective"]
    objective = (
        params["w_irregularity"] * q["irregularity"] / o["irregularity_ref"]
        + params["w_gaf"] * q["gaf_rms"] / o["gaf_rms_ref"]
        + params["w_size"] * q["outer_diameter"] / o["size_ref"]
    )
    lo, hi = spec["constraints"]["R_over_d"]
    loads = spec["loads"]
    margins = [
        jnp.log(q["static_capacity"] / (loads["shock_factor"] * loads["M_max"])),
        jnp.log(q["life_km"] / spec["life"]["required_km"]),
        jnp.log(q["R_over_d"] / lo),
        jnp.log(hi / q["R_over_d"]),
    ]
    if "max_outer_diameter" in spec["constraints"]:
        margins.append(jnp.log(spec["constraints"]["max_outer_diameter"] / q["outer_diameter"]))
    return objective, jnp.stack(margins), q


def limits(spec):
    """The limit each constraint compares its value with, for reports."""
    loads = spec["loads"]
    lo, hi = spec["constraints"]["R_over_d"]
    out = {
        "static_capacity": ("static_capacity", loads["shock_factor"] * loads["M_max"], "≥", "N·m"),
        "life": ("life_km", spec["life"]["required_km"], "≥", "km"),
        "R_over_d_min": ("R_over_d", lo, "≥", "–"),
        "R_over_d_max": ("R_over_d", hi, "≤", "–"),
    }
    if "max_outer_diameter" in spec["constraints"]:
        out["outer_diameter"] = (
            "outer_diameter",
            spec["constraints"]["max_outer_diameter"],
            "≤",
            "mm",
        )
    return out


def bounds(spec):
    """(lower, upper) arrays of the design variables [mm]."""
    b = spec["bounds"]
    return np.array([b["R"][0], b["d_roller"][0]]), np.array([b["R"][1], b["d_roller"][1]])


_EVALUATORS = {}


def compiled(spec):
    """The jit-compiled ``objective_and_margins`` of a spec (kept per Spec object)."""
    key = id(spec)
    if key not in _EVALUATORS:
        _EVALUATORS[key] = (spec, jax.jit(functools.partial(objective_and_margins, spec)))
    return _EVALUATORS[key][1]


def evaluate(spec, design):
    """Objective and constraint margins of one design.

    Args:
        spec: a :class:`~optimize.spec.Spec` (``optimize.load_spec()``).
        design: ``{"R": mm, "d_roller": mm}``; optionally ``"l"`` [mm] and
            ``"gamma0_deg"`` to evaluate on another layout.

    Returns:
        ``{"objective": float, "constraints": {name: margin}}`` — a margin ≥ 0
        means satisfied (see the module docstring), the bounds included.
        Jit-compiled: after the first call with a spec, a call costs milliseconds.
        Runs in float64 (inside ``jax.enable_x64``, scoped to the call).
    """
    unknown = set(design) - {"R", "d_roller", "l", "gamma0_deg"}
    if unknown or not {"R", "d_roller"} <= set(design):
        raise ValueError(
            f"design keys {sorted(design)} not allowed: need R and d_roller [mm], optionally l [mm] and gamma0_deg"
        )
    overrides = {}
    if "l" in design:
        overrides["l"] = float(design["l"])
    if "gamma0_deg" in design:
        overrides["gamma0"] = np.radians(float(design["gamma0_deg"]))
    x = np.array([float(design["R"]), float(design["d_roller"])])
    with jax.enable_x64(True):  # the design problem runs in float64; scoped to this call
        objective, margins, _ = compiled(spec)(jnp.asarray(x), scenario(spec, **overrides))
        objective, margins = float(objective), [float(m) for m in margins]
    lower, upper = bounds(spec)
    span = upper - lower
    result = dict(zip(constraint_names(spec), margins, strict=False))
    for i, name in enumerate(VARIABLES):
        result[f"{name}_lower_bound"] = float((x[i] - lower[i]) / span[i])
        result[f"{name}_upper_bound"] = float((upper[i] - x[i]) / span[i])
    return {"objective": objective, "constraints": result}
