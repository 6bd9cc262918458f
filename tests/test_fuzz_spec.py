"""Fuzzing the specification: a bad value for any key, or any list element, is one clear line.

Every key of the embedded default (and every element of its lists) gets values of the wrong
type, non-finite numbers and out-of-range numbers. The checker must either accept the value
(when it is allowed) or raise SpecError with one line naming the key — never another
exception, never a multi-line message. The command turns a SpecError into exit 2 (tested in
test_optimize_cli.py), so this covers what the CLI would print for each case.
"""

import math
import sys
import tomllib
import types

import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tripodjax import optimize

DEFAULT = tomllib.loads(optimize.DEFAULT_SPEC_TOML)


def _paths(table, prefix=()):
    for key, value in table.items():
        if isinstance(value, dict):
            yield from _paths(value, prefix + (key,))
        else:
            yield prefix + (key,), value


PATHS = [path for path, _ in _paths(DEFAULT)]
BAD_SCALARS = [
    float("nan"),
    float("inf"),
    float("-inf"),
    -1.0,
    0.0,
    -1e300,
    1e300,
    1e20,
    "x",
    True,
    [],
    2.5,
    10**400,  # a valid TOML integer beyond the float range
    -(10**400),
]


def _toml_value(value):
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return repr(value)
    if isinstance(value, int):
        return str(value)
    if isinstance(value, str):
        escaped = (
            f"\\u{ord(c):04x}" if ord(c) < 0x20 or ord(c) == 0x7F or c in '"\\' else c
            for c in value
        )
        return '"' + "".join(escaped) + '"'
    if isinstance(value, list):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    raise TypeError(value)


def _is_number(value):
    if isinstance(value, list):
        return bool(value) and all(_is_number(v) for v in value)
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _spec_text(path, value):
    return f"[{'.'.join(path[:-1])}]\n{path[-1]} = {_toml_value(value)}\n"


# Sections whose keys the file names freely (any quantity): weights, references, limits.
FREE_SECTIONS = ("objective", "constraints")


def _never_allowed(default, value, path):
    """A value no key accepts in place of ``default``: non-finite, or of the wrong kind, or (for
    a number of a halfshaft, outside FREE_SECTIONS) a size of 1e20 or more: no mass, length,
    speed, torque, pressure or ratio of a car's halfshaft comes near it."""
    if isinstance(value, float) and not math.isfinite(value):
        return True
    if isinstance(value, int) and not isinstance(value, bool) and abs(value) > sys.float_info.max:
        return True
    number = isinstance(default, (int, float)) and not isinstance(default, bool)
    if number:
        if isinstance(value, (str, bool, list)):
            return True
        return abs(value) >= 1e20 and path[0] not in FREE_SECTIONS
    if isinstance(default, str):
        return not isinstance(value, str)
    return False


def _check(text, key, must_fail=False):
    try:
        optimize.parse_spec(text)
        assert not must_fail, f"{key}: accepted {text!r}"
    except optimize.SpecError as error:
        message = str(error)
        assert "\n" not in message.strip(), message
        assert key.split(".")[0] in message or "life" in message or "objective" in message, (
            key,
            message,
        )
    # any other exception type fails the test


DEFAULTS = dict(_paths(DEFAULT))


@pytest.mark.parametrize("path", PATHS, ids=lambda p: ".".join(p))
def test_every_key_with_bad_scalars(path):
    for value in BAD_SCALARS:
        _check(_spec_text(path, value), ".".join(path), _never_allowed(DEFAULTS[path], value, path))


LIST_PATHS = [(p, v) for p, v in _paths(DEFAULT) if isinstance(v, list)]


@pytest.mark.parametrize(
    "path, default", LIST_PATHS, ids=lambda p: ".".join(p) if isinstance(p, tuple) else ""
)
def test_every_list_element_with_bad_values(path, default):
    for index in range(len(default)):
        for value in BAD_SCALARS:
            if isinstance(default[0], str) and isinstance(value, str):
                continue
            bad = list(default)
            bad[index] = value
            try:
                must_fail = _never_allowed(default[index], value, path)
                _check(_spec_text(path, bad), f"{'.'.join(path)}[{index}]", must_fail)
            except TypeError:  # TOML arrays of mixed types are valid TOML; a list value is not
                continue


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    path=st.sampled_from(PATHS),
    value=st.one_of(
        st.floats(allow_nan=True, allow_infinity=True),
        st.integers(min_value=-(2**63), max_value=2**63 - 1),
        st.integers(min_value=2**1024, max_value=10**500).map(lambda i: i * (-1) ** (i % 2)),
        st.text(max_size=8),
        st.booleans(),
        st.lists(st.floats(allow_nan=True, allow_infinity=True), max_size=5),
    ),
)
def test_random_values_never_escape_as_other_errors(path, value):
    _check(_spec_text(path, value), ".".join(path), _never_allowed(DEFAULTS[path], value, path))


@pytest.mark.parametrize(
    "text",
    [
        "[objective]\nw_nonsense = 1.0",
        "[constraints]\nmax_nonsense = 1.0",
        "[bounds]\nnonsense = [1.0, 2.0]",
        "[nonsense]\nx = 1",
        "[solver]\nnonsense = 1",
        "[friction]\nnonsense = 1",
        "layout = 5",
        "[bounds]\nR = [1.0]",
        '[bounds]\nR = "free"',
    ],
)
def test_unknown_or_malformed_keys_are_one_line(text):
    with pytest.raises(optimize.SpecError) as info:
        optimize.parse_spec(text)
    assert "\n" not in str(info.value).strip()


# --------------------------------------------------------------------------- finite but extreme


def test_every_number_of_the_spec_has_a_finite_range():
    """Each number a file can hold (the default's and the optional ones) has its one range in
    spec.RANGES, finite at both ends, and the default lies in it; the keys the file names
    freely (objective weights and references, constraint limits) are the exceptions."""
    keys = [".".join(p) for p, v in _paths(DEFAULT) if _is_number(v)]
    keys = [k for k in keys if k.split(".")[0] not in (*FREE_SECTIONS, "bounds", "solver")]
    keys += ["loads.M_max", "friction.mu_slp", "life.torque", "life.speed", "life.vehicle_speed"]
    keys += ["solver.tolerance", "life.share"]
    counts = ("hertz.n_rollers", "outboard.n_balls")
    for key in keys:
        if key in counts:
            assert key in optimize.spec.COUNT_LIMITS, key
            continue
        rule = optimize.spec.RANGES[key]
        assert math.isfinite(rule.low) and math.isfinite(rule.high) and rule.low < rule.high, key
        default = DEFAULTS.get(tuple(key.split(".")))
        for value in default if isinstance(default, list) else [] if default is None else [default]:
            assert rule.holds(value), (key, value)


# Every number of the spec that is a float (the solver's sizes change the structure: left out).
FLOAT_PATHS = [
    path
    for path, value in _paths(DEFAULT)
    if isinstance(value, float) or (isinstance(value, list) and isinstance(value[0], float))
    if path[0] not in ("solver",)
]
EXTREME = [5e-324, 1e-300, 1e-30, 1e30, 1e300, 1.7976931348623157e308]
DESIGN = {"R": 21.3, "d_roller": 27.8}


def _finite_result(out):
    return math.isfinite(out["objective"]) and all(
        math.isfinite(m) for m in out["constraints"].values()
    )


@pytest.mark.parametrize("path", FLOAT_PATHS, ids=lambda p: ".".join(p))
def test_extreme_finite_numbers_are_rejected_or_reported_nonfinite(path):
    """A finite number that makes the problem non-finite: a SpecError, or result ``nonfinite``.

    Never "successful" beside an infinite objective or margin (a weight of 1e300 over a
    reference of 1e-300, a limit of 5e-324 …).
    """
    default = DEFAULTS[path]
    for value in EXTREME:
        given = [value] * len(default) if isinstance(default, list) else value
        try:
            spec = optimize.parse_spec(_spec_text(path, given))
        except optimize.SpecError as error:
            assert "\n" not in str(error).strip()
            continue
        design = {k: v for k, v in DESIGN.items() if k in spec.structure.free}
        try:
            out = optimize.evaluate(spec, design)
        except ValueError as error:  # the design is outside the domain this spec makes
            assert "design" in str(error), error
            continue
        if out["result"] == "successful":
            assert _finite_result(out), (path, value, out)


@pytest.mark.parametrize(
    "text, fragment",
    [
        ("[objective]\nw_irregularity = 1e300\nirregularity_ref = 1e-300", "overflows"),
        ("[objective]\nirregularity_ref = 5e-324", "overflows"),
    ],
)
def test_an_overflowing_weight_over_reference_is_a_spec_error(text, fragment):
    with pytest.raises(optimize.SpecError, match=fragment):
        optimize.parse_spec(text)


def test_a_non_finite_margin_is_result_nonfinite_not_successful():
    # loads.M_max = 5e-324 is refused at parse (below 1 N·m); the vehicle's engine torques
    # may be that small (0 is allowed), and M_max is then ~1e-322 N·m: ln(M_s / M_max) overflows.
    spec = optimize.parse_spec("[vehicle]\nengine_torque_Nm = [5e-324, 5e-324, 5e-324, 5e-324]")
    out = optimize.evaluate(spec, DESIGN)
    assert out["result"] == "nonfinite" and not _finite_result(out)


# --------------------------------------------------------------------------- contradictions


@settings(max_examples=30, deadline=None, derandomize=True)
@given(
    weights=st.lists(
        st.floats(max_value=0.0, allow_nan=False, allow_infinity=False, min_value=-1e6),
        min_size=3,
        max_size=3,
    ).filter(any)
)
def test_objective_without_a_positive_weight_is_a_spec_error(weights):
    names = ("w_irregularity", "w_gaf_rms", "w_outer_diameter")
    text = "[objective]\n" + "\n".join(f"{n} = {w!r}" for n, w in zip(names, weights, strict=True))
    with pytest.raises(optimize.SpecError, match="positive weight"):
        optimize.parse_spec(text)


# --------------------------------------------------------------------------- types the API promises


SPEC = optimize.load_spec()


@pytest.mark.parametrize(
    "convert",
    [
        np.float32,
        np.float64,
        np.int64,
        jnp.asarray,
        lambda v: np.asarray(v),
        lambda v: jnp.asarray(v, jnp.float32),
    ],
)
def test_replace_values_takes_real_scalars_of_any_array_library(convert):
    changed = SPEC.replace_values(
        hertz=types.MappingProxyType({"P_d": convert(1300)}),
        layout={"gamma0_deg": convert(22)},
        vehicle={"engine_torque_Nm": (convert(555), 555.0, 517.4, 50.0)},
        bounds={"R": np.array([convert(15), 40.0])},
    )
    expected = SPEC.replace_values(
        hertz={"P_d": 1300.0},
        layout={"gamma0_deg": 22.0},
        vehicle={"engine_torque_Nm": [555.0, 555.0, 517.4, 50.0]},
        bounds={"R": [15.0, 40.0]},
    )
    assert changed.structure == expected.structure
    for section in expected.values:
        for key, value in expected.values[section].items():
            np.testing.assert_allclose(changed.values[section][key], value, rtol=1e-7)


@pytest.mark.parametrize(
    "call, name",
    [
        (lambda: optimize.parse_spec(b"[loads]\nM_max = 1000.0"), "text"),
        (lambda: optimize.parse_spec(None), "text"),
        (lambda: optimize.parse_spec("", source=3), "source"),
        (lambda: optimize.load_spec(12345), "path"),  # not read as a file descriptor
        (lambda: optimize.load_spec(3.5), "path"),
        (lambda: optimize.load_spec(["a.toml"]), "path"),
    ],
)
def test_parse_and_load_name_an_argument_of_the_wrong_type(call, name):
    with pytest.raises(TypeError, match=f"^{name} = "):
        call()


@pytest.mark.parametrize(
    "sections",
    [{"loads": 5}, {"loads": ["M_max"]}, {"bounds": {"R": {"lo": 1}}}, {"life": {5: 1.0}}],
)
def test_replace_values_with_a_malformed_section_is_one_line(sections):
    with pytest.raises(optimize.SpecError) as info:
        SPEC.replace_values(**sections)
    assert "\n" not in str(info.value)


# --------------------------------------------------------------------------- free text

LONG = optimize.spec.MAX_TEXT_LENGTH + 1
CONDITIONS = '[life.conditions]\nnames = ["a", "b", "c", "d", "{}"]\n'


@pytest.mark.parametrize(
    ("text", "where", "length", "limit"),
    [
        (CONDITIONS.format("x" * 10**6), "life.conditions.names[4]", 10**6, "80"),
        ('[vehicle.modes]\nnames = ["a", "b", "{}"]\n'.format("m" * LONG), "names[2]", LONG, "80"),
        ('[friction]\ngrease = "{}"\n'.format("g" * LONG), "friction.grease", LONG, "80"),
        ('[uncertainty]\n"{}" = 1\n'.format("k" * LONG), "in uncertainty", LONG, "80"),
        ('[life]\nspectrum_file = "{}"\n'.format("p" * 5000), "life.spectrum_file", 5000, "4096"),
    ],
)
def test_texts_longer_than_their_limit_are_one_line_at_load(tmp_path, text, where, length, limit):
    """Names are labels of the report's figures (a 1 MB one took 100 s to draw): refused at load,
    the message naming the key, the length and the limit, not repeating the text."""
    path = tmp_path / "spec.toml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(optimize.SpecError) as info:
        optimize.load_spec(path)
    message = str(info.value)
    assert "\n" not in message and len(message) < 200
    assert where in message and f"{length} characters" in message and f"at most {limit}" in message


def test_texts_at_their_limit_are_accepted_and_replace_values_is_bounded_too():
    name = "n" * optimize.spec.MAX_TEXT_LENGTH
    spec = optimize.parse_spec(CONDITIONS.format(name))
    assert spec.structure.condition_names[4] == name
    with pytest.raises(optimize.SpecError, match=r"names\[0\] is 81 characters long; at most 80"):
        SPEC.replace_values(life={"conditions": {"names": [name + "n"] + ["a"] * 4}})
