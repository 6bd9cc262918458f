"""Fuzzing the specification: a bad value for any key, or any list element, is one clear line.

Every key of the embedded default (and every element of its lists) gets values of the wrong
type, non-finite numbers and out-of-range numbers. The checker must either accept the value
(when it is allowed) or raise SpecError with one line naming the key — never another
exception, never a multi-line message. The command turns a SpecError into exit 2 (tested in
test_optimize_cli.py), so this covers what the CLI would print for each case.
"""

import math
import tomllib

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


def _spec_text(path, value):
    return f"[{'.'.join(path[:-1])}]\n{path[-1]} = {_toml_value(value)}\n"


def _never_allowed(default, value):
    """A value no key accepts in place of ``default``: non-finite, or of the wrong kind."""
    if isinstance(value, float) and not math.isfinite(value):
        return True
    number = isinstance(default, (int, float)) and not isinstance(default, bool)
    if number:
        return isinstance(value, (str, bool, list))
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
        _check(_spec_text(path, value), ".".join(path), _never_allowed(DEFAULTS[path], value))


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
                must_fail = _never_allowed(default[index], value)
                _check(_spec_text(path, bad), f"{'.'.join(path)}[{index}]", must_fail)
            except TypeError:  # TOML arrays of mixed types are valid TOML; a list value is not
                continue


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    path=st.sampled_from(PATHS),
    value=st.one_of(
        st.floats(allow_nan=True, allow_infinity=True),
        st.integers(min_value=-(2**63), max_value=2**63 - 1),
        st.text(max_size=8),
        st.booleans(),
        st.lists(st.floats(allow_nan=True, allow_infinity=True), max_size=5),
    ),
)
def test_random_values_never_escape_as_other_errors(path, value):
    _check(_spec_text(path, value), ".".join(path), _never_allowed(DEFAULTS[path], value))


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
