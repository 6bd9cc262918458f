"""The design-problem specification: a TOML file, checked, with an embedded default.

Every number carries its unit in its name or comment; angles are in degrees in
the file (``*_deg``) and in radians inside. [`load_spec`][tripodjax.optimize.load_spec]
returns a [`Spec`][tripodjax.optimize.Spec]: a frozen pytree whose *numbers* are
leaves (traced by ``jit``: a new value never recompiles) and whose *structure*
(which variables are free, which objective terms and constraints exist, list
lengths, ``n_theta``, the number of starts, the fidelity, iteration counts) is
static. Any problem in the file raises [`SpecError`][tripodjax.optimize.SpecError]
with one line naming the key, the value and what is allowed.
"""

import copy
import dataclasses
import math
import os
import tomllib

import jax
import numpy as np

from tripodjax._checks import MAX_GAMMA0, check_layout_domain
from tripodjax.hertz import MIN_CONFORMITY

MAX_GAMMA0_DEG = math.degrees(MAX_GAMMA0)

DEFAULT_SPEC_TOML = """\
# The company validation workbook's tripod (seed §4.3) on the seed's nominal halfshaft,
# case N of Table 2.1 (§2.10). Units in the key names and comments.

[design]
# Values of the joint-size variables when they are not free (see [bounds]): the workbook's joint.
R = 25.55              # track pitch-circle radius [mm]
d_roller = 43.5        # roller diameter [mm]

[layout]
l = 500.0              # shaft length, spider centre to the fixed joint's pivot [mm]
gamma0_deg = 20.0      # layout articulation angle [deg]

[loads]
M_max = 1154.0         # maximum forward torque [N·m] (workbook)
shock_factor = 1.1     # static check at shock_factor · M_max (workbook; seed Table 4.1)
gaf_torque = 1000.0    # torque at which GAF is judged [N·m] (the seed's GAF example, §3.2)

[hertz]
P_s = 2350.0           # allowed static contact pressure [MPa] (workbook)
P_d = 1347.0           # allowed long-lasting dynamic pressure [MPa]
P_sd = 2005.0          # allowed short-lasting dynamic pressure [MPa]
C_s = 1.2              # safety coefficient on the pressure (workbook)
conformity = 1.002     # Ψ = 2 R_groove / d (workbook range 1.002–1.008)
n_rollers = 3

[life]
required_km = 100000.0 # required life [km] (workbook)
# Load spectrum: each case's joint torque [N·m], joint speed [rpm], vehicle speed [km/h] and
# share of the running time. An illustrative passenger-car spectrum with the workbook's
# M_max as its first-gear peak; replace it with the vehicle's own.
torque = [1154.0, 700.0, 350.0, 150.0]
speed = [230.0, 400.0, 700.0, 1000.0]
vehicle_speed = [28.0, 50.0, 90.0, 130.0]
share = [0.02, 0.18, 0.45, 0.35]

[life.conditions]
# Working conditions: main articulation, straight running and suspension shock, with the
# workbook's angles (6.5°, 0°, 12.8°) and shares of the mileage.
names = ["main", "straight", "shock"]
angle_deg = [6.5, 0.0, 12.8]
share = [0.45, 0.20, 0.35]

[friction]
grease = "A"           # "A" (μ_slp 0.06), "B" (0.09) or "dry" (0.30) (seed §3.2.3)
# mu_slp = 0.06        # pure-sliding coefficient; when absent it comes from the grease
lam = 0.007            # rolling resistance λ
gaf_model = "stroke"   # "stroke" (no GAF at γ = 0) or "printed" (the seed's 3.2.14)

[objective]
# Dimensionless: Σ w_<q> · <q> / <q>_ref over any quantity q (see the quantity table in the
# docs). The references are the seed's case N with the workbook's joint (R 25.55 mm,
# d 43.5 mm), so the objective is about 3 there.
w_irregularity = 1.0
w_gaf_rms = 1.0
w_outer_diameter = 1.0
irregularity_ref = 0.0283  # transmission irregularity of case N [–] (§2.11.3)
gaf_rms_ref = 1250.0       # GAF RMS of case N at gaf_torque, grease A, stroke model [N]
outer_diameter_ref = 94.6  # outer-diameter proxy 2R + d of the workbook joint [mm]

[bounds]
# A variable is free when it has an interval here, else fixed at its value in its own
# section ([design], [layout], [hertz], [friction]). Free-able: R, d_roller [mm], l [mm],
# gamma0_deg [deg], conformity, lam, mu_slp. "fixed" removes a default interval.
R = [15.0, 40.0]         # track pitch-circle radius [mm]
d_roller = [20.0, 50.0]  # roller diameter [mm]

[constraints]
# max_<q> / min_<q> for any quantity q; the Hertz static capacity (≥ shock_factor · M_max)
# and the life (≥ required_km) are always required.
min_R_over_d = 0.63      # experience range for tripods (workbook)
max_R_over_d = 0.83
# max_outer_diameter = 100.0  # optional envelope on 2R + d [mm]
# max_eccentricity = 0.5      # spider-centre eccentricity [mm]

[uncertainty]
# Distributions on any spec number (design variables: a tolerance around the design), e.g.
#   R = { distribution = "normal", sd = 0.01 }                      [mm]
#   conformity = { distribution = "uniform", low = 1.002, high = 1.008 }
#   hertz.P_d = { distribution = "normal", cov = 0.05 }
#   correlation = [["R", "d_roller", 0.3]]
# Kinds: normal (sd or cov; low/high truncate), lognormal (sd or cov), uniform (low and high,
# or half_width). With any entry the report gives the probability of missing each requirement,
# and [constraints] accepts max_failure_probability_<q> / min_reliability_index_<q>.

[solver]
# Among the cheapest settings (first solve: trace, compile and run) whose design lies within 0.1 %
# of the newton / n_theta = 360 answer (python -m tripodjax.optimize.bench; analytic at 360 angles
# costs the same and lands within 1e-9 of it); optimize-joint re-checks the design at full fidelity.
fidelity = "newton"    # halfshaft kinematics: "newton" (exact) or "analytic" (cheap)
n_theta = 168          # input angles per revolution for the kinematics (multiple of 6)
starts = 4             # multi-start points (a deterministic grid over the bounds)
max_outer = 25         # augmented-Lagrangian outer iterations
inner_steps = 30       # L-BFGS iterations per outer iteration
tolerance = 1e-5       # KKT residual (projected gradient, feasibility, complementarity)
"""

# Quantity → (unit, what). Every one can be an objective term or a constraint.
QUANTITIES = {
    "irregularity": ("–", "transmission irregularity (Ω2max − Ω2min)/Ω1 (§2.11.3)"),
    "eccentricity": ("mm", "maximum spider-centre eccentricity over a revolution (2.5.9)"),
    "gamma_ripple": ("deg", "peak-to-peak articulation angle over a revolution"),
    "roller_stroke": (
        "mm",
        "peak-to-peak axial roller travel along its track (2.6.2, with the spider plunge)",
    ),
    "gaf_rms": ("N", "RMS of the generated axial force at loads.gaf_torque (§3.2)"),
    "gaf_peak": ("N", "peak |GAF| at loads.gaf_torque"),
    "gaf_third_order": ("N", "third-order GAF amplitude at loads.gaf_torque"),
    "outer_diameter": ("mm", "outer-diameter proxy 2R + d"),
    "static_capacity": ("N·m", "static torque capacity M_s at P_s (§4.2)"),
    "M_d": ("N·m", "long-lasting dynamic capacity at P_d and γ0 (§4.2)"),
    "M_sd": ("N·m", "short-lasting dynamic capacity at P_sd and γ0 (§4.2)"),
    "life_km": ("km", "Palmgren–Miner life under the spectrum (4.2.1–4.2.3)"),
    "R_over_d": ("–", "R / d"),
}
KINEMATIC_QUANTITIES = ("irregularity", "eccentricity", "gamma_ripple", "roller_stroke")
GAF_QUANTITIES = ("gaf_rms", "gaf_peak", "gaf_third_order")

# Design variable → (section, its value's key inside (γ0 in rad), unit, domain (low, high, low
# open)). Its key in the file is the variable's own name (gamma0_deg in degrees); report keys add
# the unit suffix.
VARIABLES = {
    "R": ("design", "R", "mm", (0.0, None, True)),
    "d_roller": ("design", "d_roller", "mm", (0.0, None, True)),
    "l": ("layout", "l", "mm", (0.0, None, True)),
    "gamma0_deg": ("layout", "gamma0", "deg", (0.0, MAX_GAMMA0_DEG, False)),
    "conformity": ("hertz", "conformity", "–", (MIN_CONFORMITY, None, False)),
    "lam": ("friction", "lam", "–", (0.0, None, False)),
    "mu_slp": ("friction", "mu_slp", "–", (0.0, None, False)),
}
REPORT_KEYS = {
    "R": "R_mm",
    "d_roller": "d_roller_mm",
    "l": "l_mm",
    "gamma0_deg": "gamma0_deg",
    "conformity": "conformity",
    "lam": "lam",
    "mu_slp": "mu_slp",
}
GREASE_MU_SLP = {"A": 0.06, "B": 0.09, "dry": 0.30}  # seed §3.2.3
FIDELITIES = ("newton", "analytic")
GAF_MODELS = ("stroke", "printed")
# Integer solver sizes: upper limits that keep a solve within memory and minutes.
INTEGER_LIMITS = {
    "n_theta": (6, 3600, "a multiple of 6"),
    "starts": (1, 64, ""),
    "max_outer": (1, 200, ""),
    "inner_steps": (1, 200, ""),
}
MAX_LIST_LENGTH = 1000
# Legacy keys that keep working (old name → new name).
LEGACY_OBJECTIVE = {
    "w_gaf": "w_gaf_rms",
    "w_size": "w_outer_diameter",
    "size_ref": "outer_diameter_ref",
}


class SpecError(ValueError):
    """A problem in a design specification: the message names the key and what is allowed."""


@dataclasses.dataclass(frozen=True)
class Structure:
    """The static part of a spec: what is free, which terms and constraints exist, the sizes.

    Two specs with equal structures share one compiled optimiser.
    """

    free: tuple  # free design variables, in VARIABLES order
    objective: tuple  # quantities with a weight
    constraints: tuple  # (name, quantity, sense) with sense "max" or "min"
    condition_names: tuple
    n_rollers: int
    gaf_model: str
    fidelity: str
    n_theta: int
    starts: int
    max_outer: int
    inner_steps: int
    uncertainty: tuple = ()  # uncertainty.Input per uncertain number
    chance: tuple = ()  # (key, "probability" or "index", constrained requirement names)

    @property
    def needs(self):
        """The quantities the objective and constraints use (computed; nothing else is)."""
        used = set(self.objective) | {q for _, q, _ in self.constraints}
        return used | {"static_capacity", "life_km"}


def _flatten_spec(spec):
    return (spec.values,), spec.structure


def _unflatten_spec(structure, children):
    return Spec(structure=structure, values=children[0], resolved=None)


@dataclasses.dataclass(frozen=True)
class Spec:
    """A checked design specification (see ``DEFAULT_SPEC_TOML`` for every key and unit).

    Attributes:
        structure: the static [`Structure`][tripodjax.optimize.spec.Structure].
        values: the numbers, ``{section: {key: float or 1-D array}}``, in internal
            units (angles in rad under ``gamma0``, ``angle``; lengths in mm). A
            pytree leaf each: ``jit`` traces them.
        resolved: the full specification as a plain dict (the file merged over
            the default), for reports; not part of the pytree.
    """

    structure: Structure
    values: dict
    resolved: dict = dataclasses.field(default=None, compare=False)

    def __getitem__(self, section):
        return self.values[section]

    def replace_values(self, **sections: dict) -> "Spec":
        """A copy with some numbers changed, e.g. ``spec.replace_values(loads={"M_max": 1200.0})``.

        Checked like the file: an unknown section or key is an error, and the new numbers go
        through the same rules.
        """
        return _check(_merge(self.resolved, _legacy(copy.deepcopy(sections))))


jax.tree_util.register_pytree_node(Spec, _flatten_spec, _unflatten_spec)


# --------------------------------------------------------------------------- checking


def _is_number(value):
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _number(table, section, key, low=None, high=None, *, low_open=False, unit=""):
    """A finite number in [low, high] (low excluded when low_open)."""
    where = f"{section}.{key}"
    value = table[section][key]
    if not _is_number(value):
        raise SpecError(f"{where} = {value!r} must be a number")
    return _in_range(where, float(value), low, high, low_open, unit)


def _in_range(where, value, low, high, low_open, unit):
    ok = math.isfinite(value)
    ok = ok and (low is None or (value > low if low_open else value >= low))
    ok = ok and (high is None or value <= high)
    if not ok:
        parts = []
        if low is not None:
            parts.append(f"{'>' if low_open else '≥'} {low:g}{unit}")
        if high is not None:
            parts.append(f"≤ {high:g}{unit}")
        allowed = "a finite number " + " and ".join(parts) if parts else "a finite number"
        raise SpecError(f"{where} = {value!r} is not allowed: {allowed}")
    return value


def _numbers(table, section, key, low=None, high=None, *, low_open=False, unit=""):
    """A non-empty list of finite numbers, each in range; errors name the index."""
    where = f"{section}.{key}"
    node = table
    for part in section.split("."):
        node = node[part]
    values = node[key]
    if not isinstance(values, list) or not values:
        raise SpecError(f"{where} = {values!r} must be a non-empty list of numbers")
    if len(values) > MAX_LIST_LENGTH:
        raise SpecError(f"{where} has {len(values)} entries; at most {MAX_LIST_LENGTH} allowed")
    out = []
    for i, value in enumerate(values):
        if not _is_number(value):
            raise SpecError(f"{where}[{i}] = {value!r} must be a number")
        out.append(_in_range(f"{where}[{i}]", float(value), low, high, low_open, unit))
    return out


def _string(table, section, key, allowed):
    where = f"{section}.{key}"
    value = table[section][key]
    if not isinstance(value, str) or value not in allowed:
        raise SpecError(
            f"{where} = {value!r} is not allowed; allowed: {', '.join(repr(a) for a in allowed)}"
        )
    return value


def _integer(table, key):
    low, high, extra = INTEGER_LIMITS[key]
    value = table["solver"][key]
    where = f"solver.{key}"
    if isinstance(value, float) and value.is_integer() and abs(value) < 2**53:
        value = int(value)
    if not isinstance(value, int) or isinstance(value, bool):
        raise SpecError(f"{where} = {value!r} must be an integer")
    if not low <= value <= high or (key == "n_theta" and value % 6):
        limits = f"an integer from {low} to {high}" + (f", {extra}" if extra else "")
        raise SpecError(f"{where} = {value!r} is not allowed: {limits}")
    return value


def _shares(where, shares):
    total = sum(shares)
    if abs(total - 1.0) > 1e-6:
        raise SpecError(
            f"{where} = {shares!r} is not allowed: shares summing to 1 (sum {total:.6g})"
        )


def _merge(default, override, path=()):
    """Deep-merge ``override`` into ``default``, rejecting keys the default does not know."""
    merged = copy.deepcopy(default)
    for key, value in override.items():
        where = ".".join(path + (key,))
        section = path[0] if path else None
        if key not in default and section not in (
            "objective",
            "constraints",
            "bounds",
            "friction",
            "uncertainty",
        ):
            raise SpecError(f"unknown key {where}; allowed here: {', '.join(sorted(default))}")
        if isinstance(default.get(key), dict):
            if not isinstance(value, dict):
                raise SpecError(f"{where} must be a table")
            merged[key] = _merge(default[key], value, path + (key,))
        else:
            merged[key] = value
    return merged


def _quantity_key(section, key, prefixes):
    """The quantity named by an objective/constraint key, e.g. 'w_gaf_rms' → 'gaf_rms'."""
    for prefix, suffix in prefixes:
        if key.startswith(prefix) and key.endswith(suffix):
            name = key[len(prefix) : len(key) - len(suffix)]
            if name in QUANTITIES:
                return prefix, name
    forms = " / ".join(f"{p}<q>{s}" for p, s in prefixes)
    raise SpecError(
        f"unknown key {section}.{key}; allowed: {forms} with <q> one of {', '.join(QUANTITIES)}"
    )


def _legacy(given):
    """Today's earlier keys, renamed in the file's own table before it meets the default."""
    objective = given.get("objective")
    if isinstance(objective, dict):
        for old, new in LEGACY_OBJECTIVE.items():
            if old in objective:
                if new in objective:
                    raise SpecError(
                        f"objective.{old} and objective.{new} are the same key; give one"
                    )
                objective[new] = objective.pop(old)
    constraints = given.get("constraints")
    if isinstance(constraints, dict) and "R_over_d" in constraints:
        pair = constraints.pop("R_over_d")
        if not isinstance(pair, list) or len(pair) != 2:
            raise SpecError(f"constraints.R_over_d = {pair!r} must be a pair [lo, hi]")
        constraints["min_R_over_d"], constraints["max_R_over_d"] = pair
    return given


def _objective(table):
    given = dict(table["objective"])
    weights, refs = {}, {}
    for key, value in given.items():
        prefix, q = _quantity_key("objective", key, (("w_", ""), ("", "_ref")))
        tab = {"objective": {key: value}}
        if prefix == "w_":
            weights[q] = _number(tab, "objective", key)
        else:
            refs[q] = _number(tab, "objective", key, 0.0, low_open=True)
    terms = tuple(q for q in QUANTITIES if q in weights)
    if not any(weights[q] != 0 for q in terms):
        raise SpecError("objective has no non-zero weight w_<q>; give at least one")
    for q in terms:
        if q not in refs:
            raise SpecError(f"objective.w_{q} needs objective.{q}_ref (> 0, in {QUANTITIES[q][0]})")
    values = {f"w_{q}": weights[q] for q in terms} | {f"{q}_ref": refs[q] for q in terms}
    return terms, values


CHANCE_PREFIXES = {"max_failure_probability_": "probability", "min_reliability_index_": "index"}


def _chance(key, value):
    """A chance constraint's (kind, quantity, number) from its key, or None for another key."""
    for prefix, kind in CHANCE_PREFIXES.items():
        if key.startswith(prefix):
            q = key[len(prefix) :]
            if q not in (*QUANTITIES, "life"):
                raise SpecError(
                    f"unknown key constraints.{key}; allowed: {prefix}<q> with <q> life, static_capacity "
                    "or a quantity with a max_<q> / min_<q> constraint"
                )
            tab = {"constraints": {key: value}}
            if kind == "probability":  # β = −Φ⁻¹(P) from 0 to 8
                number = _number(tab, "constraints", key, 0.0, 0.5, low_open=True)
            else:
                number = _number(tab, "constraints", key, 0.0, 8.0)
            return kind, "life_km" if q == "life" else q, number
    return None


def _chance_constraints(chances, names, uncertainty):
    """(key, kind, requirement names) of each chance constraint; needs [uncertainty]."""
    out = []
    for key, (kind, q) in chances.items():
        if not uncertainty:
            raise SpecError(
                f"constraints.{key} needs uncertain numbers: give at least one [uncertainty] entry"
            )
        targets = [n for n, k, _ in names if k == q]
        targets = {"life_km": ["life"], "static_capacity": ["static_capacity"]}.get(q, targets)
        if not targets:
            raise SpecError(
                f"constraints.{key}: {q} has no constraint to hold with a probability; "
                f"give constraints.max_{q} or constraints.min_{q}"
            )
        out.append((key, kind, tuple(targets)))
    return tuple(out)


def _constraints(table):
    given = dict(table["constraints"])
    names, values, chances = [], {}, {}
    for key, value in given.items():
        chance = _chance(key, value)
        if chance is not None:
            chances[key] = chance[:2]
            values[key] = chance[2]
            continue
        prefix, q = _quantity_key("constraints", key, (("max_", ""), ("min_", "")))
        values[key] = _number({"constraints": {key: value}}, "constraints", key, 0.0, low_open=True)
        names.append((key, q, prefix[:-1]))
    order = {q: i for i, q in enumerate(QUANTITIES)}
    names.sort(key=lambda c: (order[c[1]], c[2]))
    for key, q, sense in names:
        if sense == "min" and f"max_{q}" in values and values[f"max_{q}"] < values[key]:
            raise SpecError(
                f"constraints.min_{q} = {values[key]:g} is above constraints.max_{q} = "
                f"{values[f'max_{q}']:g}: no design can meet both"
            )
    return tuple(names), values, chances


def _bounds(table, fixed):
    given = table["bounds"]
    bounds = {}
    for key, value in given.items():
        if key not in VARIABLES:
            raise SpecError(f"unknown key bounds.{key}; allowed: {', '.join(VARIABLES)}")
        if value == "fixed":
            continue
        if not isinstance(value, list) or len(value) != 2:
            raise SpecError(f'bounds.{key} = {value!r} must be a pair [lo, hi] or "fixed"')
        _, _, unit, (low, high, low_open) = VARIABLES[key]
        unit = "°" if unit == "deg" else ("" if unit == "–" else f" {unit}")
        lo, hi = _numbers(
            {"bounds": {key: value}}, "bounds", key, low, high, low_open=low_open, unit=unit
        )
        if not lo < hi:
            raise SpecError(f"bounds.{key} = {value!r} is not allowed: [lo, hi] with lo < hi")
        bounds[key] = (lo, hi)
    # R/l ≤ 0.2 at every corner of the box (and at the fixed values).
    r_hi = bounds["R"][1] if "R" in bounds else fixed["R"]
    l_lo = bounds["l"][0] if "l" in bounds else fixed["l"]
    names = {"R": "bounds.R[1]" if "R" in bounds else "design.R"}
    names["l"] = "bounds.l[0]" if "l" in bounds else "layout.l"
    try:  # the one layout-domain rule of the package
        check_layout_domain(R=r_hi, l=l_lo, names=names)
    except ValueError as error:
        raise SpecError(f"{error} (at the corner of the bounds with the largest R/l)") from None
    return bounds


def _check(table):
    """Check a merged table; returns the Spec."""
    v = {}
    fixed = {
        "R": _number(table, "design", "R", 0.0, low_open=True, unit=" mm"),
        "d_roller": _number(table, "design", "d_roller", 0.0, low_open=True, unit=" mm"),
        "l": _number(table, "layout", "l", 0.0, low_open=True, unit=" mm"),
        "gamma0_deg": _number(table, "layout", "gamma0_deg", 0.0, MAX_GAMMA0_DEG, unit="°"),
        "conformity": _number(table, "hertz", "conformity", MIN_CONFORMITY),
    }
    v["design"] = {"R": fixed["R"], "d_roller": fixed["d_roller"]}
    v["layout"] = {"l": fixed["l"], "gamma0": math.radians(fixed["gamma0_deg"])}
    v["loads"] = {
        "M_max": _number(table, "loads", "M_max", 0.0, low_open=True, unit=" N·m"),
        "shock_factor": _number(table, "loads", "shock_factor", 0.0, low_open=True),
        "gaf_torque": _number(table, "loads", "gaf_torque", 0.0, unit=" N·m"),
    }
    hertz = {
        k: _number(table, "hertz", k, 0.0, low_open=True, unit=" MPa")
        for k in ("P_s", "P_d", "P_sd")
    }
    hertz["C_s"] = _number(table, "hertz", "C_s", 0.0, low_open=True)
    hertz["conformity"] = fixed["conformity"]
    n_rollers = table["hertz"]["n_rollers"]
    if not isinstance(n_rollers, int) or isinstance(n_rollers, bool) or not 1 <= n_rollers <= 12:
        raise SpecError(f"hertz.n_rollers = {n_rollers!r} is not allowed: an integer from 1 to 12")
    v["hertz"] = hertz
    life = {"required_km": _number(table, "life", "required_km", 0.0, low_open=True, unit=" km")}
    units = {"torque": " N·m", "speed": " rpm", "vehicle_speed": " km/h", "share": ""}
    spectrum = {k: _numbers(table, "life", k, 0.0, unit=u) for k, u in units.items()}
    lengths = {k: len(x) for k, x in spectrum.items()}
    if len(set(lengths.values())) != 1:
        raise SpecError(
            f"life lists have lengths {lengths}; torque, speed, vehicle_speed and share must have one length"
        )
    _shares("life.share", spectrum["share"])
    if not any(
        s > 0 and n > 0 and t > 0
        for s, n, t in zip(spectrum["share"], spectrum["speed"], spectrum["torque"], strict=True)
    ):
        raise SpecError(
            "life spectrum has no case with torque, speed and share > 0: the life would be infinite"
        )
    conditions = table["life"]["conditions"]
    angles = _numbers(table, "life.conditions", "angle_deg", 0.0, 89.999, unit="°")
    shares = _numbers(table, "life.conditions", "share", 0.0)
    _shares("life.conditions.share", shares)
    names = conditions.get("names", [f"condition {i + 1}" for i in range(len(angles))])
    if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
        raise SpecError(f"life.conditions.names = {names!r} must be a list of strings")
    if not len(angles) == len(shares) == len(names):
        raise SpecError(
            f"life.conditions lists have lengths angle_deg {len(angles)}, share {len(shares)}, "
            f"names {len(names)}; they must have one length"
        )
    life.update({k: np.asarray(x) for k, x in spectrum.items()})
    life["condition_angle"] = np.radians(np.asarray(angles))
    life["condition_share"] = np.asarray(shares)
    v["life"] = life
    grease = _string(table, "friction", "grease", tuple(GREASE_MU_SLP))
    for key in table["friction"]:
        if key not in ("grease", "lam", "gaf_model", "mu_slp"):
            raise SpecError(
                f"unknown key friction.{key}; allowed here: gaf_model, grease, lam, mu_slp"
            )
    if "mu_slp" in table["friction"]:
        mu_slp = _number(table, "friction", "mu_slp", 0.0)
    else:
        mu_slp = GREASE_MU_SLP[grease]
    v["friction"] = {"lam": _number(table, "friction", "lam", 0.0), "mu_slp": mu_slp}
    fixed.update(v["friction"])
    gaf_model = _string(table, "friction", "gaf_model", GAF_MODELS)
    terms, v["objective"] = _objective(table)
    constraints, v["constraints"], chances = _constraints(table)
    bounds = _bounds(table, fixed)
    v["bounds"] = {
        k: (math.radians(lo), math.radians(hi)) if k == "gamma0_deg" else (lo, hi)
        for k, (lo, hi) in bounds.items()
    }
    v["bounds"] = {k: np.asarray(pair) for k, pair in v["bounds"].items()}
    for key in table["solver"]:
        if key not in (*INTEGER_LIMITS, "tolerance", "fidelity"):
            raise SpecError(
                f"unknown key solver.{key}; allowed here: {', '.join((*INTEGER_LIMITS, 'fidelity', 'tolerance'))}"
            )
    sizes = {k: _integer(table, k) for k in INTEGER_LIMITS}
    inputs, v["uncertainty"] = _uncertainty(table, v, tuple(k for k in VARIABLES if k in bounds))
    v["solver"] = {"tolerance": _number(table, "solver", "tolerance", 1e-12, 1e-1)}
    structure = Structure(
        free=tuple(k for k in VARIABLES if k in bounds),
        objective=terms,
        constraints=constraints,
        condition_names=tuple(names),
        n_rollers=n_rollers,
        gaf_model=gaf_model,
        fidelity=_string(table, "solver", "fidelity", FIDELITIES),
        **sizes,
        uncertainty=inputs,
        chance=_chance_constraints(chances, constraints, inputs),
    )
    if not structure.free:
        raise SpecError(
            f"bounds gives no free variable; give an interval for at least one of {', '.join(VARIABLES)}"
        )
    values = jax.tree_util.tree_map(lambda x: np.asarray(x, np.float64), v)
    return Spec(structure=structure, values=values, resolved=table)


def _uncertainty(table, values, free):
    """The [uncertainty] section: (inputs, their numbers); see tripodjax.optimize.uncertainty."""
    from tripodjax.optimize import uncertainty

    section = table["uncertainty"]
    if not isinstance(section, dict):
        raise SpecError("uncertainty must be a table")
    numbers = jax.tree_util.tree_map(np.asarray, values)
    numbers["bounds"] = {k: np.asarray(b) for k, b in values["bounds"].items()}
    return uncertainty.parse(section, numbers, VARIABLES, free)


def parse_spec(text: str, source: str = "spec") -> Spec:
    """Check a TOML text (merged over the default: a file need only hold what it changes)."""
    if text.startswith("\ufeff"):  # a UTF-8 byte-order mark, as Windows editors write
        text = text[1:]
    try:
        given = tomllib.loads(text)
    except tomllib.TOMLDecodeError as error:
        raise SpecError(f"{source} is not valid TOML: {error}") from None
    return _check(_merge(tomllib.loads(DEFAULT_SPEC_TOML), _legacy(given)))


def load_spec(path: str | os.PathLike | None = None) -> Spec:
    """The specification in the TOML file at ``path``, or the embedded default when None."""
    if path is None:
        return parse_spec(DEFAULT_SPEC_TOML, "the default spec")
    try:
        with open(path, "rb") as f:
            data = f.read()
    except IsADirectoryError:
        raise SpecError(f"spec file {path} is a directory, not a TOML file") from None
    except OSError as error:
        raise SpecError(f"cannot read spec file {path}: {error.strerror or error}") from None
    if b"\x00" in data:
        raise SpecError(f"spec file {path} is a binary file, not a TOML text")
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as error:
        raise SpecError(
            f"spec file {path} is not UTF-8 text (byte {error.start}: {data[error.start : error.start + 1]!r}); "
            "save it as UTF-8"
        ) from None
    return parse_spec(text, str(path))
