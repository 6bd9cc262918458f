"""The design-problem specification: a TOML file, checked, with an embedded default.

Every number carries its unit in its name or comment; angles are in degrees in
the file (``*_deg``) and in radians inside. :func:`load_spec` returns a
:class:`Spec`; any problem in the file raises :class:`SpecError` with one line
naming the key, the value and what is allowed.
"""

import copy
import dataclasses
import math

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

DEFAULT_SPEC_TOML = """\
# The company validation workbook's tripod (seed §4.3) on the seed's nominal halfshaft,
# case N of Table 2.1 (§2.10). Units in the key names and comments.

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
lam = 0.007            # rolling resistance λ
gaf_model = "stroke"   # "stroke" (no GAF at γ = 0) or "printed" (the seed's 3.2.14)

[objective]
# Dimensionless: Σ w · quantity / reference. The references are the seed's case N with the
# workbook's joint (R 25.55 mm, d 43.5 mm), so the objective is about 3 there.
w_irregularity = 1.0
w_gaf = 1.0
w_size = 1.0
irregularity_ref = 0.0283  # transmission irregularity of case N [–] (§2.11.3)
gaf_rms_ref = 1250.0       # GAF RMS of case N at gaf_torque, grease A, stroke model [N]
size_ref = 94.6            # outer-diameter proxy 2R + d of the workbook joint [mm]

[bounds]
R = [15.0, 40.0]         # track pitch-circle radius [mm]
d_roller = [20.0, 50.0]  # roller diameter [mm]

[constraints]
R_over_d = [0.63, 0.83]  # experience range for tripods (workbook)
# max_outer_diameter = 100.0  # optional envelope on 2R + d [mm]

[solver]
n_theta = 120          # input angles per revolution for the kinematics (multiple of 6)
starts = 4             # multi-start points (a deterministic grid over the bounds)
max_outer = 25         # augmented-Lagrangian outer iterations
inner_steps = 30       # L-BFGS iterations per outer iteration
tolerance = 1e-5       # KKT residual (projected gradient, feasibility, complementarity)
"""


class SpecError(ValueError):
    """A problem in a design specification: the message names the key and what is allowed."""


@dataclasses.dataclass(frozen=True)
class Spec:
    """A checked design specification (see ``DEFAULT_SPEC_TOML`` for every key and unit).

    ``values`` holds the resolved numbers (angles in rad under ``*_rad`` keys);
    ``resolved`` is the full specification as a plain dict, for reports.
    """

    values: dict
    resolved: dict

    def __getitem__(self, section):
        return self.values[section]


def _get(table, path, kind=float):
    key = ".".join(path)
    node = table
    for part in path:
        if not isinstance(node, dict) or part not in node:
            raise SpecError(f"missing key {key}")
        node = node[part]
    if kind is float:
        if isinstance(node, bool) or not isinstance(node, (int, float)) or not math.isfinite(node):
            raise SpecError(f"{key} = {node!r} must be a finite number")
        return float(node)
    if kind is int:
        if isinstance(node, bool) or not isinstance(node, int):
            raise SpecError(f"{key} = {node!r} must be an integer")
        return node
    if kind is list:
        if (
            not isinstance(node, list)
            or not node
            or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in node)
        ):
            raise SpecError(f"{key} = {node!r} must be a non-empty list of numbers")
        return [float(v) for v in node]
    if kind is str:
        if not isinstance(node, str):
            raise SpecError(f"{key} = {node!r} must be a string")
        return node
    raise TypeError(kind)


def _require(ok, key, value, allowed):
    if not ok:
        raise SpecError(f"{key} = {value!r} is not allowed: {allowed}")


def _interval(table, path, positive=True):
    key = ".".join(path)
    values = _get(table, path, list)
    _require(len(values) == 2, key, values, "a pair [lo, hi]")
    lo, hi = values
    _require(lo < hi and (lo > 0 or not positive), key, values, "[lo, hi] with 0 < lo < hi")
    return lo, hi


def _merge(default, override, path=()):
    """Deep-merge ``override`` into ``default``, rejecting keys the default does not have."""
    merged = copy.deepcopy(default)
    for key, value in override.items():
        where = ".".join(path + (key,))
        if key not in default:
            if path == ("constraints",) and key == "max_outer_diameter":
                merged[key] = value
                continue
            raise SpecError(f"unknown key {where}; allowed here: {', '.join(sorted(default))}")
        if isinstance(default[key], dict):
            if not isinstance(value, dict):
                raise SpecError(f"{where} must be a table")
            merged[key] = _merge(default[key], value, path + (key,))
        else:
            merged[key] = value
    return merged


def parse_spec(text, source="spec"):
    """Check a TOML text (merged over the default: a file need only hold what it changes)."""
    try:
        given = tomllib.loads(text)
    except tomllib.TOMLDecodeError as error:
        raise SpecError(f"{source} is not valid TOML: {error}") from None
    table = _merge(tomllib.loads(DEFAULT_SPEC_TOML), given)
    v = {}
    v["layout"] = {
        "l": _get(table, ("layout", "l")),
        "gamma0_rad": math.radians(_get(table, ("layout", "gamma0_deg"))),
    }
    _require(v["layout"]["l"] > 0, "layout.l", v["layout"]["l"], "l > 0 mm")
    _require(
        0 <= v["layout"]["gamma0_rad"] <= math.pi / 4,
        "layout.gamma0_deg",
        table["layout"]["gamma0_deg"],
        "0 ≤ gamma0_deg ≤ 45",
    )
    loads = {k: _get(table, ("loads", k)) for k in ("M_max", "shock_factor", "gaf_torque")}
    for k, value in loads.items():
        _require(
            value > 0 if k != "gaf_torque" else value >= 0,
            f"loads.{k}",
            value,
            "> 0" if k != "gaf_torque" else "≥ 0 N·m",
        )
    v["loads"] = loads
    hertz = {k: _get(table, ("hertz", k)) for k in ("P_s", "P_d", "P_sd", "C_s", "conformity")}
    for k in ("P_s", "P_d", "P_sd", "C_s"):
        _require(hertz[k] > 0, f"hertz.{k}", hertz[k], "> 0")
    _require(
        hertz["conformity"] > 1,
        "hertz.conformity",
        hertz["conformity"],
        "conformity Ψ > 1 (workbook range 1.002–1.008)",
    )
    hertz["n_rollers"] = _get(table, ("hertz", "n_rollers"), int)
    _require(hertz["n_rollers"] >= 1, "hertz.n_rollers", hertz["n_rollers"], "≥ 1")
    v["hertz"] = hertz
    life = {"required_km": _get(table, ("life", "required_km"))}
    _require(life["required_km"] > 0, "life.required_km", life["required_km"], "> 0 km")
    spectrum = {
        k: _get(table, ("life", k), list) for k in ("torque", "speed", "vehicle_speed", "share")
    }
    lengths = {k: len(x) for k, x in spectrum.items()}
    _require(
        len(set(lengths.values())) == 1,
        "life",
        lengths,
        "torque, speed, vehicle_speed and share of one length",
    )
    for k in ("torque", "speed", "vehicle_speed", "share"):
        _require(all(x >= 0 for x in spectrum[k]), f"life.{k}", spectrum[k], "values ≥ 0")
    _require(
        abs(sum(spectrum["share"]) - 1) < 1e-6,
        "life.share",
        spectrum["share"],
        "shares summing to 1",
    )
    life["spectrum"] = spectrum
    angles = _get(table, ("life", "conditions", "angle_deg"), list)
    shares = _get(table, ("life", "conditions", "share"), list)
    names = table["life"]["conditions"].get(
        "names", [f"condition {i + 1}" for i in range(len(angles))]
    )
    _require(
        len(angles) == len(shares) == len(names),
        "life.conditions",
        {"angle_deg": len(angles), "share": len(shares), "names": len(names)},
        "lists of one length",
    )
    _require(
        all(0 <= a < 90 for a in angles), "life.conditions.angle_deg", angles, "0 ≤ angle < 90"
    )
    _require(
        all(s >= 0 for s in shares) and abs(sum(shares) - 1) < 1e-6,
        "life.conditions.share",
        shares,
        "shares ≥ 0 summing to 1",
    )
    life["conditions"] = {
        "names": [str(n) for n in names],
        "angle_rad": [math.radians(a) for a in angles],
        "share": shares,
    }
    v["life"] = life
    friction = {
        "grease": _get(table, ("friction", "grease"), str),
        "lam": _get(table, ("friction", "lam")),
        "gaf_model": _get(table, ("friction", "gaf_model"), str),
    }
    _require(
        friction["grease"] in ("A", "B", "dry"),
        "friction.grease",
        friction["grease"],
        'one of "A", "B", "dry"',
    )
    _require(friction["lam"] >= 0, "friction.lam", friction["lam"], "λ ≥ 0")
    _require(
        friction["gaf_model"] in ("stroke", "printed"),
        "friction.gaf_model",
        friction["gaf_model"],
        'one of "stroke", "printed"',
    )
    v["friction"] = friction
    objective = {
        k: _get(table, ("objective", k))
        for k in (
            "w_irregularity",
            "w_gaf",
            "w_size",
            "irregularity_ref",
            "gaf_rms_ref",
            "size_ref",
        )
    }
    for k, value in objective.items():
        _require(
            value >= 0 if k.startswith("w_") else value > 0,
            f"objective.{k}",
            value,
            "≥ 0" if k.startswith("w_") else "> 0",
        )
    _require(
        sum(objective[k] for k in ("w_irregularity", "w_gaf", "w_size")) > 0,
        "objective",
        "all weights 0",
        "at least one weight > 0",
    )
    v["objective"] = objective
    v["bounds"] = {
        "R": _interval(table, ("bounds", "R")),
        "d_roller": _interval(table, ("bounds", "d_roller")),
    }
    constraints = {"R_over_d": _interval(table, ("constraints", "R_over_d"))}
    if "max_outer_diameter" in table["constraints"]:
        constraints["max_outer_diameter"] = _get(table, ("constraints", "max_outer_diameter"))
        _require(
            constraints["max_outer_diameter"] > 0,
            "constraints.max_outer_diameter",
            constraints["max_outer_diameter"],
            "> 0 mm",
        )
    v["constraints"] = constraints
    r_lo, r_hi = v["bounds"]["R"]
    _require(
        r_hi / v["layout"]["l"] <= 0.2,
        "bounds.R",
        [r_lo, r_hi],
        f"R/l ≤ 0.2 with layout.l = {v['layout']['l']:g} mm, so R ≤ {0.2 * v['layout']['l']:g}",
    )
    solver = {
        k: _get(table, ("solver", k), int)
        for k in ("n_theta", "starts", "max_outer", "inner_steps")
    }
    solver["tolerance"] = _get(table, ("solver", "tolerance"))
    _require(
        solver["n_theta"] >= 6 and solver["n_theta"] % 6 == 0,
        "solver.n_theta",
        solver["n_theta"],
        "a positive multiple of 6",
    )
    for k in ("starts", "max_outer", "inner_steps"):
        _require(solver[k] >= 1, f"solver.{k}", solver[k], "≥ 1")
    _require(solver["tolerance"] > 0, "solver.tolerance", solver["tolerance"], "> 0")
    v["solver"] = solver
    return Spec(values=v, resolved=table)


def load_spec(path=None):
    """The specification in the TOML file at ``path``, or the embedded default when None."""
    if path is None:
        return parse_spec(DEFAULT_SPEC_TOML, "the default spec")
    try:
        with open(path, encoding="utf-8") as f:
            text = f.read()
    except OSError as error:
        raise SpecError(f"cannot read spec file {path}: {error.strerror}") from None
    return parse_spec(text, str(path))
