"""The rest of the halfshaft, as the company validates it (seed §4.3, sheets 5–8): the shaft's
sections and stems statically and in fatigue, and the outboard fixed ball joint.

[`halfshaft_report`][tripodjax.optimize.halfshaft_report] checks the spec's ``[shaft]`` sections
([`tripodjax.shaft`][tripodjax.shaft]) and its ``[outboard]`` joint
([`tripodjax.outboard`][tripodjax.outboard]) under the spec's vehicle, with a verdict for each;
``optimize-joint`` writes it as the report's ``halfshaft`` section beside the tripod's life.
Requirements:

- a section's static safety τ_adm/τ (its safety coefficient inside τ_adm) ≥ 1 at every kink of
  its strength profile, under M_max forward and backward (the vehicle's largest working torques,
  with the shock factor);
- a section's fatigue damage (Miner's sum, at the outer radius and at the end of the hardened
  layer) below ``shaft.allowed_damage`` (1);
- the outboard joint's static safety M_s / M_max ≥ ``loads.shock_factor`` (the tripod's rule,
  M_s ≥ k_s M_max) and its life ≥ ``life.required_km`` under its own working conditions.
"""

import functools
import math
from collections.abc import Mapping

import jax
import jax.numpy as jnp
import numpy as np

from tripodjax import life, outboard, shaft
from tripodjax.optimize._compiled import call, latency_bound_jit
from tripodjax.optimize.problem import (
    check_spec,
    design_values,
    driving_modes,
    full_design,
    gear_names,
    load_cycles,
    load_spectrum,
    m_max,
    report_arguments,
    spec_design,
)
from tripodjax.optimize.spec import SHAFT_VARIABLES, Spec, shaft_variable
from tripodjax.results import RESULTS, code_where, worst


def shaft_lists(structure, values, design):
    """The [shaft] geometry lists (``SHAFT_VARIABLES``) with the design's free entries in them."""
    lists = {k: jnp.asarray(values["shaft"][k]) for k in SHAFT_VARIABLES}
    for name in structure.free:
        entry = shaft_variable(name)
        if entry is not None:
            key, section = entry
            i = structure.shaft_sections.index(section)
            lists[key] = lists[key].at[i].set(design[name])
    return lists


def _sections(structure, values, design):
    """The [shaft] sections and their materials, batched over the sections (leading axis)."""
    s = values["shaft"]
    lists = shaft_lists(structure, values, design)
    n = jnp.shape(lists["outer_diameter_mm"])[0]

    def each(x):
        return jnp.broadcast_to(jnp.asarray(x), (n,))

    sections = shaft.Section(
        lists["outer_diameter_mm"],
        lists["hardened_depth_mm"],
        lists["transition_depth_mm"],
        lists["inner_diameter_mm"],
    )
    materials = shaft.Material(
        each(s["core_uts_MPa"]),
        each(s["surface_uts_MPa"]),
        each(s["depth_drop"]),
        each(s["fatigue_ratio"]),
        s["safety"],
    )
    return sections, materials


def outboard_joint(values):
    """The spec's [`FixedJoint`][tripodjax.outboard.FixedJoint] (its [outboard] section)."""
    o = values["outboard"]
    return outboard.FixedJoint(
        d=o["ball_diameter_mm"],
        R=o["pcr_mm"],
        conformity=o["conformity"],
        longitudinal_conformity=o["longitudinal_conformity"],
        P_s=o["P_s"],
        P_d=o["P_d"],
        P_sd=o["P_sd"],
        C_s=o["C_s"],
        pressure_angle=o["pressure_angle"],
        oblique_angle=o["oblique_angle"],
        tolerance=o["tolerance"],
    )


def halfshaft_checks(structure, values, design):
    """Every check of the rest of the halfshaft for a design (``problem.full_design``): JAX,
    differentiable in the design's [shaft] entries and in every number of the spec.

    The one computation behind the report ([`halfshaft_report`][tripodjax.optimize.halfshaft_report])
    and the optimiser's quantities and constraints (``problem.quantities``).
    """
    cycles = load_cycles(structure, values)
    # The parts carry the same torque in series: forward the M_max of the tripod's check
    # (loads.M_max where the spec gives it, else the vehicle's), backward the vehicle's.
    torque = jnp.stack([m_max(structure, values, cycles), cycles.M_max_backward])
    # A direction without torque (a reverse whose load transfer lifts the wheel) is no check
    # (checked at 1 N·m and left out: finite derivatives); a vehicle without any is not computed.
    loaded = torque > 0
    rows = shaft.fatigue_cycles(
        cycles, driving_modes(structure, values), reading=structure.shaft_reading
    )
    sections, materials = _sections(structure, values, design)
    static = jax.vmap(lambda s, m: shaft.static_check(s, m, jnp.where(loaded, torque, 1.0)))(
        sections, materials
    )
    unchecked = code_where(jnp.any(loaded), RESULTS.successful, RESULTS.nonfinite)
    fatigue = jax.vmap(
        lambda s, m: shaft.fatigue_check(s, m, rows, reading=structure.shaft_reading)
    )(sections, materials)
    joint = outboard_joint(values)
    o = values["outboard"]
    caps = outboard.capacities(
        joint,
        n_balls=structure.outboard_balls,
        reading=structure.outboard_reading,
        domain_flags=False,  # the spec's ranges lie inside its domains; the balls' fit stays
    )
    joint_life = outboard.joint_life(
        joint,
        load_spectrum(structure, values),
        life.WorkingConditions(o["condition_angle"], o["condition_share"]),
        n_balls=structure.outboard_balls,
        angle_law=structure.angle_law,
        reading=structure.outboard_reading,
        domain_flags=False,
    )
    outer, inner = sections.outer_diameter, sections.inner_diameter
    return {
        "torque": torque,
        "sections": sections,
        "area": jnp.sum(jnp.pi / 4.0 * (outer**2 - inner**2)),
        "static_safety": jnp.where(
            jnp.any(loaded),
            jnp.min(jnp.where(loaded[:, None], static.safety, jnp.inf), axis=(-2, -1)),
            jnp.nan,
        ),
        "static_result": worst(jnp.where(loaded, static.result, RESULTS.successful), unchecked),
        "damage": fatigue.damage,  # (section, radius)
        # damage per gear at each radius: summed over the modes and engine conditions
        "damage_by_gear": jnp.sum(fatigue.damage_per_row, axis=(2, 4)),
        "fatigue_result": fatigue.result,
        "M_s": caps.M_s,
        "M_d": caps.M_d,
        "M_sd": caps.M_sd,
        "hertz_result": caps.result,
        "life_km": joint_life.km,
        "km_per_condition": joint_life.km_per_condition,
        "damage_per_condition": joint_life.damage_per_condition,
        "life_result": joint_life.result,
    }


def halfshaft_quantities(structure, values, design):
    """The optimiser's quantities of the rest of the halfshaft (``spec.HALFSHAFT_QUANTITIES``):
    (quantities, the per-section ones ``shaft_static_safety[<name>]`` and ``shaft_damage[<name>]``,
    (the sections' result code, the outboard joint's)).

    A section's static safety is the smallest over its profile's kinks and both torques, its
    damage the larger of its two radii's (as the report's); the outboard joint's static safety
    is M_s over the larger of the two torques (``problem.joint_torque``).
    """
    out = halfshaft_checks(structure, values, design)
    damage = jnp.max(out["damage"], axis=-1)
    q = {
        "shaft_area": out["area"],
        "shaft_static_safety": jnp.min(out["static_safety"]),
        "shaft_damage": jnp.max(damage),
        "outboard_static_safety": out["M_s"] / jnp.max(out["torque"]),  # either direction
        "outboard_life_km": out["life_km"],
    }
    sections = {}
    for i, name in enumerate(structure.shaft_sections):
        sections[f"shaft_static_safety[{name}]"] = out["static_safety"][i]
        sections[f"shaft_damage[{name}]"] = damage[i]
    shaft_code = jnp.maximum(jnp.max(out["static_result"]), jnp.max(out["fatigue_result"]))
    joint_code = jnp.maximum(jnp.max(out["hertz_result"]), jnp.max(out["life_result"]))
    return q, sections, (shaft_code, joint_code)


@functools.partial(latency_bound_jit, static_argnums=0)
def _halfshaft(structure, values, x):
    return halfshaft_checks(structure, values, full_design(structure, values, x))


def _requirement(name, value, relation, limit, unit=""):
    """(passed, words) of ``value relation limit`` (``relation`` "≥" or "≤"), the numbers as
    `_apart` writes them (never "1 < 1" for a safety of 0.9998, nor "100000 km < 100000 km"). A
    value that is not finite passes nothing: the words say it is not finite."""
    if not math.isfinite(value):
        return False, f"{name} not finite ({value!r})"
    passed = {"≥": value >= limit, "≤": value <= limit}[relation]
    opposite = {"≥": "<", "≤": ">"}[relation]
    shown, bound = _apart(value, limit, "f" if unit == " km" else "g")
    return passed, f"{name} {shown}{unit} {relation if passed else opposite} {bound}{unit}"


def _apart(value, limit, style):
    """``value`` and ``limit`` as text: ``style`` "g" to 3 significant figures, "f" to whole
    units (a life in km), with more digits where those round them to the same text (distinct
    floats are told apart)."""
    start = 3 if style == "g" else 0
    for n in range(start, start + 18):
        shown, bound = f"{value:.{n}{style}}", f"{limit:.{n}{style}}"
        if shown != bound or value == limit:
            break
    return shown, bound


def _verdict(checks, code=RESULTS.successful):
    """ "passes: …" or "fails: …" from (passed, text) pairs, the failing ones named first;
    a result code other than successful fails the verdict, in words."""
    if code != RESULTS.successful:
        return f"fails: not computed ({RESULTS(code).describe()})"
    failed = [text for ok, text in checks if not ok]
    return f"fails: {'; '.join(failed)}" if failed else f"passes: {'; '.join(t for _, t in checks)}"


def summary(report: dict) -> str:
    """One line for the command's output: the halfshaft's verdict, naming what fails."""
    failed = [f"{x['name']} {x['result']}" for x in report["sections"] if "fails" in x["result"]]
    if "fails" in report["outboard"]["result"]:
        failed.append(f"outboard joint {report['outboard']['result']}")
    if not failed:
        return f"halfshaft: {len(report['sections'])} sections and the outboard joint pass"
    return "halfshaft: " + "; ".join(failed)


def halfshaft_report(spec: Spec, design: Mapping[str, float] | None = None) -> dict:
    """The ``halfshaft`` section of the report: every [shaft] section and the outboard joint.

    ``design``: a design ``{variable: value}`` (spec units, as [`evaluate`][tripodjax.optimize.evaluate],
    e.g. ``result.design``) whose free [shaft] entries (``"shaft.outer_diameter_mm[C-C]"``) are
    checked; None: the spec's own [shaft] numbers.

    Needs the spec's ``[vehicle]`` (its load cycles: the working torques, the gears and the
    driving modes); a spec that gives ``loads.M_max`` and the ``[life]`` lists instead raises
    ValueError saying so. Returns (plain floats, strict JSON)::

        {"reading", "static_torque_Nm": {"forward", "backward"},
         "sections": [{"name", "outer_diameter_mm", "inner_diameter_mm", "hardened_depth_mm",
            "static_safety", "required_static_safety", "static_passed", "damage",
            "damage_outer", "damage_core", "allowed_damage", "fatigue_passed",
            "damage_by_gear": [{"gear", "damage"}], "result"}],
         "outboard": {"n_balls", "ball_diameter_mm", "pcr_mm", "M_s_Nm", "M_d_Nm", "M_sd_Nm",
            "static_safety", "required_static_safety", "static_passed", "life_km",
            "required_km", "life_passed",
            "conditions": [{"name", "angle_deg", "share", "life_km", "damage_share"}], "result"},
         "passed"}

    ``damage`` is the larger of the two radii's (the outer one and the end of the hardened
    layer, ``damage_core``); ``damage_by_gear`` is at that radius, summed over the driving modes
    and engine conditions; ``result`` is the verdict in words. Runs in float64 (scoped to the
    call); compiled once per spec structure.
    """
    structure = check_spec(spec).structure
    if not structure.vehicle_modes:
        raise ValueError(
            "the halfshaft check needs the spec's [vehicle] (its gears and driving modes give "
            "the sections' fatigue cycles); this spec gives loads.M_max and the load spectrum "
            "instead"
        )
    values, x = design_values(
        spec, spec_design(structure, spec.values) if design is None else design
    )
    with jax.enable_x64(True):  # float64, scoped to this call
        out = jax.tree_util.tree_map(
            np.asarray, call(_halfshaft, *report_arguments(structure, values), x)
        )
    s, o, geometry = values["shaft"], values["outboard"], out["sections"]
    forward, backward = map(float, out["torque"])
    gears = gear_names(values)
    sections = []
    for i, name in enumerate(structure.shaft_sections):
        outer, core = map(float, out["damage"][i])
        critical = int(np.argmax(out["damage"][i]))
        safety, allowed = float(out["static_safety"][i]), float(s["allowed_damage"])
        damage = max(outer, core)
        code = int(max(np.max(out["static_result"][i]), np.max(out["fatigue_result"][i])))
        static = _requirement("static safety", safety, "≥", 1.0)
        fatigue = _requirement("damage", damage, "≤", allowed)  # the optimiser's ln(allowed/D) ≥ 0
        sections.append(
            {
                "name": name,
                "outer_diameter_mm": float(geometry.outer_diameter[i]),
                "inner_diameter_mm": float(geometry.inner_diameter[i]),
                "hardened_depth_mm": float(geometry.hardened_depth[i]),
                "static_safety": safety,
                "required_static_safety": 1.0,
                "static_passed": static[0] and code == RESULTS.successful,
                "damage": damage,
                "damage_outer": outer,
                "damage_core": core,
                "allowed_damage": allowed,
                "fatigue_passed": fatigue[0] and code == RESULTS.successful,
                "damage_by_gear": [
                    {"gear": gear, "damage": float(d)}
                    for gear, d in zip(gears, out["damage_by_gear"][i, critical], strict=True)
                ],
                "status": RESULTS(code).name,
                "result": _verdict([static, fatigue], code),
            }
        )
    shock = float(values["loads"]["shock_factor"])
    required_km = float(values["life"]["required_km"])
    with np.errstate(divide="ignore", invalid="ignore"):  # no torque: no finite safety
        safety = float(np.float64(out["M_s"]) / np.float64(max(forward, backward)))
    km = float(out["life_km"])
    code = int(max(np.max(out["hertz_result"]), np.max(out["life_result"])))
    static = _requirement("static safety", safety, "≥", shock)
    life_check = _requirement("life", km, "≥", required_km, " km")
    static_ok = static[0] and code == RESULTS.successful
    life_ok = life_check[0] and code == RESULTS.successful
    conditions = [
        {
            "name": name,
            "angle_deg": math.degrees(float(angle)),
            "share": float(share),
            "life_km": float(condition_km),
            "damage_share": float(damage),
        }
        for name, angle, share, condition_km, damage in zip(
            structure.outboard_conditions,
            o["condition_angle"],
            o["condition_share"],
            out["km_per_condition"],
            out["damage_per_condition"],
            strict=True,
        )
    ]
    joint = {
        "n_balls": structure.outboard_balls,
        "ball_diameter_mm": float(o["ball_diameter_mm"]),
        "pcr_mm": float(o["pcr_mm"]),
        "M_s_Nm": float(out["M_s"]),
        "M_d_Nm": float(out["M_d"]),
        "M_sd_Nm": float(out["M_sd"]),
        "static_safety": safety,
        "required_static_safety": shock,
        "static_passed": bool(static_ok),
        "life_km": km,
        "required_km": required_km,
        "life_passed": bool(life_ok),
        "conditions": conditions,
        "status": RESULTS(code).name,
        "result": _verdict([static, life_check], code),
    }
    passed = all(x["static_passed"] and x["fatigue_passed"] for x in sections)
    return {
        "reading": structure.shaft_reading,
        "outboard_reading": structure.outboard_reading,
        "static_torque_Nm": {"forward": forward, "backward": backward},
        "sections": sections,
        "outboard": joint,
        "passed": bool(passed and static_ok and life_ok),
    }
