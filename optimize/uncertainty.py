"""Uncertain spec numbers: the ``[uncertainty]`` section, read once, and its map from standard normal space.

Any scalar number of the spec can carry a distribution, design variables included (then a
tolerance around the design's value). An entry is an inline table:

    [uncertainty]
    R = { distribution = "normal", sd = 0.01 }                       # [mm], around the design
    d_roller = { distribution = "normal", sd = 0.01 }
    conformity = { distribution = "uniform", low = 1.002, high = 1.008 }
    hertz.P_d = { distribution = "normal", cov = 0.05 }              # any section.key of the spec
    loads.M_max = { distribution = "lognormal", cov = 0.1 }
    correlation = [["R", "d_roller", 0.3]]                           # optional

Kinds (the mean or centre is the spec's value, or the design's for a design variable):

- ``normal``: ``sd`` (in the number's unit) or ``cov`` (sd / |mean|); optional ``low`` /
  ``high`` truncate it. Any number with a bounded domain is always truncated at its bounds
  (the spec's own rule for the number, `spec.RANGES`: ``conformity`` 1.0005–2, ``hertz.P_d``
  100–10 000 MPa, …), and a ``low`` / ``high`` outside the domain is refused.
- ``lognormal``: ``sd`` or ``cov`` of the number itself (mean > 0); truncated at its domain's
  bounds as a normal is (a low ≤ 0 cuts nothing: its values are > 0).
- ``uniform``: ``low`` and ``high`` (absolute) or ``half_width`` around the mean; the interval
  must lie within the number's domain (for ``half_width`` around a free variable, at every
  design within its bounds).

A spread whose variance overflows (sd above `MAX_SPREAD` ≈ 1.34e154) is refused.

Inputs are independent unless ``correlation`` lists ``[key_a, key_b, ρ]`` triples: ρ is
the correlation of the underlying standard normal variables (a Gaussian copula; for
untruncated normal inputs, the inputs' own correlation).

The distribution parameters are spec numbers (leaves of ``Spec.values["uncertainty"]``,
traced); which keys are uncertain and their kinds are structure
([`Input`][tripodjax.optimize.uncertainty.Input] tuples in ``Structure.uncertainty``).
"""

import dataclasses
import math
import sys
import typing

import jax.numpy as jnp
import numpy as np
from jax.scipy.special import ndtr, ndtri

KINDS = ("normal", "lognormal", "uniform")
# Keys an entry may hold, per kind.
ENTRY_KEYS = {
    "normal": ("sd", "cov", "low", "high"),
    "lognormal": ("sd", "cov"),
    "uniform": ("low", "high", "half_width"),
}
DEFAULT_TOLERANCES_TOML = """\
[uncertainty]
R = { distribution = "normal", sd = 0.01 }
d_roller = { distribution = "normal", sd = 0.01 }
conformity = { distribution = "uniform", low = 1.002, high = 1.008 }
hertz.P_d = { distribution = "normal", cov = 0.05 }
"""
"""The default tolerances of ``optimize-joint --reliability``, an ``[uncertainty]`` section
(TOML; docs/reliability.md gives the sources): manufacturing tolerances on R and
d_roller (normal, σ 0.01 mm), the workbook's conformity range (uniform on 1.002–1.008 [–],
seed fig. 4.3.10) and a 5 % scatter (CoV) of the allowed dynamic pressure hertz.P_d [MPa]."""


# A spread whose square (the variance; the lognormal's log-variance ln(1 + CoV²)) overflows is
# refused: sd ≤ √(float max) ≈ 1.34e154 (a normal's CoV times |mean|), a lognormal's CoV too.
MAX_SPREAD = math.sqrt(sys.float_info.max)


class Domain(typing.NamedTuple):
    """The allowed values of an uncertain number (the spec's own rule for it), internal units.

    ``low`` / ``high`` (None: unbounded), each excluded when ``low_open`` / ``high_open``;
    ``name`` is the number's key in the file, ``allowed`` the rule in words and file units.
    """

    low: float | None
    high: float | None
    low_open: bool
    high_open: bool
    name: str
    allowed: str


@dataclasses.dataclass(frozen=True)
class Input:
    """The static part of one uncertain number.

    Attributes:
        name: its key as written in ``[uncertainty]`` (``R``, ``hertz.P_d``).
        section, key: where its value lives in ``Spec.values``.
        kind: ``normal``, ``lognormal`` or ``uniform``.
        spread: ``sd``, ``cov`` (normal, lognormal), ``interval`` or ``half_width`` (uniform).
        truncate_low, truncate_high: a normal or lognormal input truncated below / above.
        variable: the design variable it is (``R``, ``conformity``), or None.
    """

    name: str
    section: str
    key: str
    kind: str
    spread: str
    truncate_low: bool = False
    truncate_high: bool = False
    variable: str | None = None


def _error(message):
    from tripodjax.optimize.spec import SpecError

    return SpecError(message)


def _is_number(value):
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _entries(table, variables, prefix=()):
    """(path, entry) for every distribution of the section.

    A dotted key is a nested table (``hertz.P_d = {…}``) or one quoted key
    (``"hertz.P_d" = {…}``): both give the path (hertz, P_d). A table is a nested one
    when it is not a design variable's entry, holds no ``distribution`` and holds only
    tables; any other value is an entry (one without ``distribution`` is refused by
    ``parse``, naming that key).
    """
    for key, value in table.items():
        path = prefix + tuple(key.split("."))
        if not prefix and key == "correlation":
            continue
        nested = (
            isinstance(value, dict)
            and value
            and "distribution" not in value
            and all(isinstance(v, dict) for v in value.values())
            and path not in {(v,) for v in variables}
        )
        if nested:
            yield from _entries(value, variables, path)
        else:
            yield path, value


def _locate(path, values, variables):
    """(section, key in values, design variable or None, degrees) of an uncertain key."""
    where = "uncertainty." + ".".join(path)
    if len(path) == 1 and path[0] in variables:
        section, key = variables[path[0]][:2]
        return section, key, path[0], path[0] == "gamma0_deg"
    if len(path) != 2:
        allowed = ", ".join(variables)
        raise _error(
            f"unknown key {where}; allowed: a design variable ({allowed}) or section.key of a number of the spec"
        )
    section, key = path
    degrees = False
    if section in values and key not in values[section] and key.endswith("_deg"):
        key, degrees = key[: -len("_deg")], True
    if section not in values:
        raise _error(
            f"unknown key {where}: [{section}] holds no number of the model (the solver's "
            "settings cannot be uncertain); allowed: a design variable or section.key of a "
            "number of the model, e.g. hertz.P_d"
        )
    if key not in values[section]:
        raise _error(f"unknown key {where}: the spec has no number {'.'.join(path)}")
    if np.ndim(values[section][key]) != 0:
        raise _error(f"{where}: {'.'.join(path)} is a list; only a single number can be uncertain")
    variable = next((v for v, (s, k, _, _) in variables.items() if (s, k) == (section, key)), None)
    return section, key, variable, degrees


def _positive(where, entry, name):
    value = entry[name]
    if not _is_number(value) or not math.isfinite(value) or value <= 0:
        raise _error(f"{where}.{name} = {value!r} is not allowed: a finite number > 0")
    return float(value)


def _finite(where, entry, name):
    value = entry[name]
    if not _is_number(value) or not math.isfinite(value):
        raise _error(f"{where}.{name} = {value!r} is not allowed: a finite number")
    return float(value)


def _outside(domain, value, side, support):
    """Whether ``value`` (internal units), the low (side 0) or high (side 1) end of a
    distribution's values, leaves the domain; ``support``: the end is a value the input takes
    (a uniform's), else a truncation point (a normal's, never reached: an open bound allowed)."""
    bound = (domain.low, domain.high)[side]
    if bound is None:
        return False
    strict = support and (domain.low_open, domain.high_open)[side]
    return (
        (value <= bound if strict else value < bound)
        if side == 0
        else (value >= bound if strict else value > bound)
    )


def parse(table, values, variables, free, domain_of=None):
    """The ``[uncertainty]`` table → (tuple of Input, numbers for ``values["uncertainty"]``).

    ``values`` are the spec's checked numbers (internal units), ``variables`` the spec's
    ``VARIABLES``, ``free`` the free design variables, ``domain_of(section, key, variable)``
    the number's allowed values, a `Domain` or None (unbounded). A distribution must keep to
    them: a uniform's interval (over every design in the bounds, for ``half_width`` around a
    free variable) and a normal's truncation points within them, a normal or lognormal
    truncated at them where it gives none. Raises SpecError on a bad entry.
    """
    inputs, numbers, seen = [], {}, {}
    for path, entry in _entries(table, variables):
        where = "uncertainty." + ".".join(path)
        section, key, variable, degrees = _locate(path, values, variables)
        if (section, key) in seen:
            first = seen[(section, key)]
            again = "is given twice (quoted and not)" if first == where else f"repeats {first}"
            raise _error(f"{where} {again}: give one distribution per number")
        if not isinstance(entry, dict):
            raise _error(
                f'{where} = {entry!r} must be a table, e.g. {{ distribution = "normal", sd = 0.01 }}'
            )
        if "distribution" not in entry:
            raise _error(
                f"{where} has no distribution key; give distribution = one of "
                f'{", ".join(map(repr, KINDS))}, e.g. {{ distribution = "normal", sd = 0.01 }}'
            )
        kind = entry["distribution"]
        if kind not in KINDS:
            raise _error(
                f"{where}.distribution = {kind!r} is not allowed; allowed: {', '.join(map(repr, KINDS))}"
            )
        unknown = sorted(set(entry) - {"distribution", *ENTRY_KEYS[kind]})
        if unknown:
            raise _error(
                f"{where}: unknown key {unknown[0]} for a {kind} distribution; allowed: {', '.join(ENTRY_KEYS[kind])}"
            )
        scale = math.pi / 180.0 if degrees else 1.0  # file units (deg) → internal (rad)
        nominal = float(values[section][key])
        # A free variable's mean is the design's, anywhere in its bounds: (lowest, highest).
        means = tuple(map(float, values["bounds"][variable])) if variable in free else (nominal,)
        domain = None if domain_of is None else domain_of(section, key, variable)
        number = {}
        truncate = [False, False]
        if kind in ("normal", "lognormal"):
            given = [k for k in ("sd", "cov") if k in entry]
            if len(given) != 1:
                raise _error(f"{where}: a {kind} distribution needs one of sd or cov (got {given})")
            spread = given[0]
            number["spread"] = _positive(where, entry, spread) * (scale if spread == "sd" else 1.0)
            if kind == "lognormal" and not min(means) > 0:
                raise _error(
                    f"{where}: a lognormal distribution needs a mean > 0; {'.'.join(path)} = {min(means):g}"
                )
            # The largest sd (normal) or CoV (lognormal) over the means; its square must be finite.
            size = max(map(abs, means)) if kind == "normal" else 1.0 / min(means)
            if kind == "normal" and spread == "cov" and size == 0:
                raise _error(
                    f"{where}.cov = {entry['cov']!r} is not allowed: {'.'.join(path)} = 0 has no "
                    "coefficient of variation; give sd"
                )
            factor = 1.0 if (kind == "normal") == (spread == "sd") else size
            if not number["spread"] * factor <= MAX_SPREAD:
                top = MAX_SPREAD / factor / (scale if spread == "sd" else 1.0)
                raise _error(
                    f"{where}.{spread} = {entry[spread]!r} is not allowed: a finite number > 0 "
                    f"and ≤ {top:.4g} (a larger spread's variance overflows)"
                )
            if kind == "lognormal" and domain is not None:  # truncated at the domain's bounds
                if domain.low is not None and domain.low > 0:
                    truncate[0], number["low"] = True, domain.low
                if domain.high is not None:
                    truncate[1], number["high"] = True, domain.high
            if kind == "normal":
                low = _finite(where, entry, "low") * scale if "low" in entry else None
                high = _finite(where, entry, "high") * scale if "high" in entry else None
                for side, end in enumerate(("low", "high")):
                    at = (low, high)[side]
                    if domain is not None and at is not None and _outside(domain, at, side, False):
                        raise _error(
                            f"{where}.{end} = {entry[end]!r} is not allowed: {domain.name} "
                            f"takes {domain.allowed}"
                        )
                if domain is not None and domain.low is not None and low is None:
                    low = domain.low  # truncated at the number's bound, as a design variable's
                if domain is not None and domain.high is not None and high is None:
                    high = domain.high
                if low is not None and high is not None and not low < high:
                    raise _error(
                        f"{where}: truncation [low, high] = [{low / scale:g}, {high / scale:g}] is not allowed: low < high"
                    )
                for i, bound in enumerate((low, high)):
                    if bound is not None:
                        truncate[i] = True
                        number["low" if i == 0 else "high"] = bound
        else:
            if "half_width" in entry:
                if "low" in entry or "high" in entry:
                    raise _error(f"{where}: give low and high, or half_width, not both")
                spread = "half_width"
                number["spread"] = _positive(where, entry, "half_width") * scale
                low, high = min(means) - number["spread"], max(means) + number["spread"]
            else:
                if "low" not in entry or "high" not in entry:
                    raise _error(
                        f"{where}: a uniform distribution needs low and high (or half_width)"
                    )
                spread = "interval"
                low = _finite(where, entry, "low") * scale
                high = _finite(where, entry, "high") * scale
                if not low < high:
                    raise _error(
                        f"{where}: [low, high] = [{entry['low']!r}, {entry['high']!r}] is not allowed: low < high"
                    )
                number["low"], number["high"] = low, high
            for side, end in enumerate(("low", "high")):
                at = (low, high)[side]
                if domain is not None and _outside(domain, at, side, True):
                    if spread == "half_width":
                        around = "the bounds" if variable in free else "the mean"
                        shown = f"half_width = {entry[spread]!r} (around {around}: {at / scale:g})"
                    else:
                        shown = f"{end} = {entry[end]!r}"
                    raise _error(
                        f"{where}.{shown} is not allowed: {domain.name} takes {domain.allowed}"
                    )
        seen[(section, key)] = where
        inputs.append(
            Input(
                name=".".join(path),
                section=section,
                key=key,
                kind=kind,
                spread=spread,
                truncate_low=truncate[0],
                truncate_high=truncate[1],
                variable=variable,
            )
        )
        numbers[".".join(path)] = number
    correlation = _correlation(table.get("correlation"), [i.name for i in inputs])
    if correlation is not None:
        numbers["correlation"] = correlation
    return tuple(inputs), numbers


def _correlation(triples, names):
    """The correlation matrix of the underlying normals from [key_a, key_b, ρ] triples, or None."""
    if triples is None:
        return None
    where = "uncertainty.correlation"
    if not isinstance(triples, list) or not triples:
        raise _error(f"{where} = {triples!r} must be a non-empty list of [key_a, key_b, ρ] triples")
    matrix = np.eye(len(names))
    given = {}  # each pair once, in either order
    for i, triple in enumerate(triples):
        ok = isinstance(triple, list) and len(triple) == 3 and _is_number(triple[2])
        if not ok or triple[0] not in names or triple[1] not in names or triple[0] == triple[1]:
            raise _error(
                f"{where}[{i}] = {triple!r} is not allowed: [key_a, key_b, ρ] with two different uncertain keys "
                f"({', '.join(names) or 'none given'}) and a number ρ"
            )
        rho = float(triple[2])
        if not -1.0 < rho < 1.0:
            raise _error(f"{where}[{i}] ρ = {rho!r} is not allowed: −1 < ρ < 1")
        pair = frozenset(triple[:2])
        if pair in given:
            raise _error(
                f"{where}[{i}] = {triple!r} gives the pair of {where}[{given[pair]}] again; "
                "give each pair once"
            )
        given[pair] = i
        a, b = names.index(triple[0]), names.index(triple[1])
        matrix[a, b] = matrix[b, a] = rho
    if np.min(np.linalg.eigvalsh(matrix)) <= 1e-10:
        raise _error(
            f"{where} = {triples!r} is not allowed: the correlation matrix must be positive definite"
        )
    return matrix


def realize(inputs, numbers, nominal, u):
    """The uncertain numbers at standard normal point(s) ``u`` (last axis: the inputs).

    ``nominal[i]`` is input i's mean (the spec's value or the design's). Traced; one
    function per kind, written once: normal (optionally truncated), lognormal, uniform.
    """
    if "correlation" in numbers:
        u = u @ jnp.linalg.cholesky(numbers["correlation"]).T
    out = []
    for i, spec in enumerate(inputs):
        p = numbers[spec.name]
        mean, z = nominal[i], u[..., i]
        if spec.kind == "uniform":
            if spec.spread == "half_width":
                low, high = mean - p["spread"], mean + p["spread"]
            else:
                low, high = p["low"], p["high"]
            out.append(low + (high - low) * ndtr(z))
            continue
        sd = p["spread"] if spec.spread == "sd" else p["spread"] * jnp.abs(mean)
        low = p["low"] if spec.truncate_low else None
        high = p["high"] if spec.truncate_high else None
        if spec.kind == "lognormal":  # a normal of ln x, truncated at ln low, ln high
            s2 = jnp.log1p((sd / mean) ** 2)
            bounds = [None if b is None else jnp.log(b) for b in (low, high)]
            log_value = _truncated_normal(jnp.log(mean) - 0.5 * s2, jnp.sqrt(s2), *bounds, z)
            value = jnp.exp(log_value)
        else:
            value = _truncated_normal(mean, sd, low, high, z)
        # Never past a bound by rounding (mean + sd·(a − ε) with a = (low − mean)/sd).
        value = value if low is None else jnp.maximum(value, low)
        out.append(value if high is None else jnp.minimum(value, high))
    return jnp.stack(out, axis=-1)


def _truncated_normal(mean, sd, low, high, z):
    """The normal of ``mean``, ``sd`` truncated at ``low`` / ``high`` (None: not cut) at the
    standard normal point ``z``: its inverse CDF at Φ(z)."""
    if low is None and high is None:
        return mean + sd * z
    below = ndtr((low - mean) / sd) if low is not None else 0.0  # the mass cut off
    above = ndtr((mean - high) / sd) if high is not None else 0.0
    kept = 1.0 - below - above
    # Each tail from its own side, so that ndtr never rounds to 1; where the cut mass
    # underflows (a bound many sd away) the input is the plain normal, for any z.
    cut = (below > 0) | (above > 0)
    t = jnp.where(cut, z, 0.0)
    lower = ndtri(below + kept * ndtr(jnp.minimum(t, 0.0)))
    upper = -ndtri(above + kept * ndtr(-jnp.maximum(t, 0.0)))
    return mean + sd * jnp.where(cut, jnp.where(t < 0.0, lower, upper), z)


def nominal(structure, values, x):
    """The mean (or centre) of each uncertain input: the design's value for a free variable."""
    return [
        x[..., structure.free.index(i.variable)]
        if i.variable in structure.free
        else values[i.section][i.key]
        for i in structure.uncertainty
    ]


def perturb(structure, values, x, u):
    """(values, x) with every uncertain number at the standard normal point ``u``.

    An uncertain design variable that is free varies around its value in the design
    vector ``x``; every other uncertain number around its spec value.
    """
    inputs = structure.uncertainty
    realized = realize(inputs, values["uncertainty"], nominal(structure, values, x), u)
    values = dict(values)
    for n, i in enumerate(inputs):
        if i.variable in structure.free:
            x = x.at[..., structure.free.index(i.variable)].set(realized[..., n])
        else:
            values[i.section] = dict(values[i.section], **{i.key: realized[..., n]})
    return values, x


def describe(spec, number):
    """A one-line description of an input for reports, in file units."""
    scale = 180.0 / math.pi if spec.variable == "gamma0_deg" else 1.0
    if spec.kind == "uniform":
        if spec.spread == "half_width":
            return f"uniform, ± {float(number['spread']) * scale:g} around the design"
        return f"uniform on [{float(number['low']) * scale:g}, {float(number['high']) * scale:g}]"
    spread = (
        f"sd {float(number['spread']) * scale:g}"
        if spec.spread == "sd"
        else f"CoV {float(number['spread']):g}"
    )
    text = f"{spec.kind}, {spread}"
    bounds = [
        f"{name} {float(number[name]) * scale:g}"
        for name, on in (("low", spec.truncate_low), ("high", spec.truncate_high))
        if on
    ]
    return text + (f", truncated at {' and '.join(bounds)}" if bounds else "")
