"""Checks of inputs at the Python boundary: concrete values only, never traced ones.

One rule per domain, written once and called by every layer with its own names:

- `check_real` — the type rule (real numbers or arrays of them; never a
  ``str``, ``bool``, ``None``, complex number or object);
- `real_scalar` — the type rule for one real number (a Python, NumPy or JAX
  scalar, a 0-d array; never a ``bool``), as a Python float, also beyond the
  float range (a huge Python ``int``);
- `check_instance` — the type rule for object arguments (a Layout, a
  FrictionParams…);
- `check`, `check_finite`, `check_positive`, `check_non_negative`,
  `check_shares`, `check_integer` — value rules;
- `check_layout_domain` — the halfshaft layout domain (R, l, γ0), used by
  [`Layout`][tripodjax.layout.Layout], [`sweep`][tripodjax.sweep.sweep] and the optimiser's spec;
- `check_choice` — every mode/choice argument;
- `check_shapes` — fields that broadcast together and are not empty (a Layout's;
  `check_not_empty` one field);
  `check_sweep_batch`, `check_devices` — what a sweep's torque and devices must be beside its layouts.

Every error is a ``ValueError`` (or ``TypeError`` for a wrong type) that names
the argument, the offending value (with its index inside an array) and what is
allowed. Traced values (inside ``jit``/``vmap``/``grad``) are never value-checked:
there the functions propagate NaN and/or a result code instead. Every
concrete value is: a Python or NumPy number, a NumPy array or a concrete JAX
array, 0-d or not, element by element (the error names the first bad index).
Shapes are checked for traced values too (they are static).
"""

import dataclasses
import math
import numbers
import sys
import typing

import jax
import jax.numpy as jnp
import numpy as np

# --------------------------------------------------------------------------- domains

MAX_GAMMA0 = math.pi / 4  # rad: the documented layout domain ends at γ0 = 45°
MAX_R_OVER_L = 0.2  # the documented layout domain ends at R/l = 0.2
TOLERANCE_ULPS = 4  # closed upper bounds of the layout domain admit a few ulps of the value's dtype


def _at_most(array, top, *sources):
    """``array ≤ top`` up to `TOLERANCE_ULPS` ulps of ``top`` in the values' own dtype.

    float32(π/4) and float32(R)/float32(l) at R/l = 0.2 round to just above
    the float64 bound; a value on the bound in its own precision is on it.
    The dtype is the coarsest floating dtype among ``sources`` (default the
    array itself), e.g. float32 for a float32 R over a float64 l.
    """
    floats = [a.dtype for a in (sources or (array,)) if a.dtype.kind == "f"]
    dtype = max(floats, key=lambda d: np.finfo(d).eps) if floats else np.dtype(np.float64)
    top = np.asarray(top, dtype)
    return array <= top + TOLERANCE_ULPS * np.spacing(top)


# --------------------------------------------------------------------------- types


def concrete(value):
    """``value`` as a NumPy array when it is a concrete number or array, else None.

    Traced values (inside jit/vmap/grad) and the placeholders JAX puts in
    pytrees while it rebuilds them are not checked. No type errors: use
    `check_real` at a public boundary.
    """
    if isinstance(value, jax.core.Tracer):
        return None
    try:
        array = np.asarray(value)
    except Exception:  # a placeholder object that is no number
        return None
    return array if array.dtype.kind in "fiu" else None


def _type_name(value):
    return type(value).__name__


def _not_allowed(name, value, allowed):
    """The one wording of a type error: ``"x = 'a' is not allowed; allowed: … (got a str)"``."""
    return f"{name} = {_show(value)} is not allowed; allowed: {allowed} (got a {_type_name(value)})"


def check_real(name, value, *, allowed="a real number or an array of real numbers"):
    """The type rule: ``value`` as a NumPy array of real numbers, or None when it is traced.

    Raises ``TypeError`` naming ``name`` for ``str``/``bytes``, ``bool`` (Python,
    NumPy or a boolean array), ``None``, complex numbers, objects that are not
    numbers, and lists that do not form a rectangular array of real numbers.
    Integers are accepted (they are real numbers); the caller checks values.
    Floats are float32 or float64: a float16 value raises ``TypeError`` too.
    """
    if isinstance(value, jax.core.Tracer):
        if not np.issubdtype(value.dtype, np.integer) and not np.issubdtype(
            value.dtype, np.floating
        ):
            raise TypeError(f"{name} has dtype {value.dtype}; allowed: {allowed}")
        _check_precision(name, value.dtype)
        return None
    if value is None or isinstance(value, (str, bytes, bool, np.bool_, complex, dict, set)):
        raise TypeError(_not_allowed(name, value, allowed))
    if _beyond_float_range(value):
        raise _beyond(name, value)
    if isinstance(value, (list, tuple)):
        flat = list(_flatten(value))
        bad = [v for v in flat if not _is_real_scalar(v)]
        if bad:
            raise TypeError(
                f"{name} = {_show(value)} holds {_show(bad[0])} ({_type_name(bad[0])}); allowed: {allowed}"
            )
        for i, v in enumerate(flat):
            if _beyond_float_range(v):
                raise _beyond(f"{name}[{i}]" if np.ndim(value) == 1 else name, v)
    try:
        array = np.asarray(value)
    except Exception:
        raise TypeError(_not_allowed(name, value, allowed)) from None
    if array.dtype.kind not in "fiu":
        raise TypeError(f"{name} = {_show(value)} has dtype {array.dtype}; allowed: {allowed}")
    _check_precision(name, array.dtype)
    return array


def as_array(value):
    """A list or tuple of numbers as its NumPy array (JAX takes no list for an array), anything
    else as it is: for arguments ``check_real`` accepted."""
    return np.asarray(value) if isinstance(value, (list, tuple)) else value


def _check_precision(name, dtype):
    """The one precision rule: floats are float32 or float64 (float16 has no complex type, nor
    the resolution of the solves; it is refused rather than silently widened)."""
    if dtype.kind == "f" and dtype.itemsize < 4:
        raise TypeError(
            f"{name} has dtype {dtype}; allowed: float32 or float64 (e.g. x.astype(np.float32))"
        )


FLOAT_MAX = sys.float_info.max


def _beyond_float_range(value):
    """True for a Python ``int`` too large for a float (e.g. a TOML integer of 400 digits)."""
    return isinstance(value, int) and not isinstance(value, bool) and abs(value) > FLOAT_MAX


def _show_int(value):
    digits = int(value.bit_length() * math.log10(2)) + 1
    return f"{'-' if value < 0 else ''}an integer of about {digits} digits"


def _beyond(name, value):
    return ValueError(
        f"{name} = {_show_int(value)} is beyond the float range: |{_short(name)}| ≤ {FLOAT_MAX:.4g}"
    )


def real_scalar(name, value, allowed="a real number"):
    """The type rule for one real number: ``value`` as a Python ``float``.

    Accepts Python ``int``/``float``, any ``numbers.Real`` (NumPy scalars such as
    ``np.float32``), and 0-d arrays of a real dtype from any array library (NumPy,
    concrete JAX arrays). ``TypeError`` naming ``name`` for ``bool``, ``None``,
    strings, complex numbers, arrays of another shape or dtype, tracers and other
    objects; ``ValueError`` for an integer beyond the float range. Values are not
    range-checked (see `check_range`).
    """
    if isinstance(value, jax.core.Tracer):
        raise TypeError(f"{name} is a traced value; allowed: {allowed} (a concrete value)")
    if isinstance(value, (bool, np.bool_)) or value is None or isinstance(value, (str, bytes)):
        raise TypeError(_not_allowed(name, value, allowed))
    if _beyond_float_range(value):
        raise _beyond(name, value)
    if isinstance(value, numbers.Real):
        return float(value)
    try:
        array = np.asarray(value)
    except Exception:
        raise TypeError(_not_allowed(name, value, allowed)) from None
    if array.dtype.kind not in "fiu":
        raise TypeError(_not_allowed(name, value, allowed))
    if array.ndim:
        raise TypeError(
            f"{name} = {_show(value)} has shape {array.shape}; allowed: {allowed} (one value, shape ())"
        )
    return float(array)


def _flatten(items):
    for item in items:
        if isinstance(item, (list, tuple)):
            yield from _flatten(item)
        else:
            yield item


def _is_real_scalar(value):
    if isinstance(value, (bool, np.bool_)):
        return False
    if isinstance(value, numbers.Real):
        return True
    return isinstance(value, (np.ndarray, jax.Array)) and np.asarray(value).dtype.kind in "fiu"


def _show(value):
    text = repr(value)
    return text if len(text) <= 80 else text[:77] + "..."


def _scalar(x):
    """A NumPy scalar as a Python number for the message (ints stay ints)."""
    return int(x) if np.asarray(x).dtype.kind in "iu" else float(x)


def check_instance(name, value, cls, allowed):
    """The type rule for an object argument: ``TypeError`` naming ``name`` unless ``value`` is a ``cls``.

    E.g. ``check_instance("layout", layout, Layout, "a Layout")``. Returns ``value``.
    """
    if not isinstance(value, cls):
        raise TypeError(_not_allowed(name, value, allowed))
    return value


def check_flag(name, value):
    """A switch: True or False (NumPy's bool too), not a truthy string or number."""
    return check_instance(name, value, (bool, np.bool_), "True or False")


# --------------------------------------------------------------------------- values


def check(name, value, ok, allowed):
    """Raise unless ``ok(array)`` holds everywhere for the concrete ``value``.

    ``ok`` maps a NumPy array to a boolean array. The error names ``name`` (with
    the index of the first offending element for an array), the value and
    ``allowed``: ``"d[2] = -1.0 is outside the allowed range: d > 0"``. A wrong
    type raises ``TypeError`` (`check_real`). Returns the concrete array,
    or None when ``value`` is traced.
    """
    array = check_real(name, value)
    if array is None:
        return None
    good = np.broadcast_to(np.asarray(ok(array), bool), array.shape)
    if not np.all(good):
        if array.ndim:
            index = tuple(int(i) for i in np.argwhere(~good)[0])
            where = ",".join(str(i) for i in index)
            shown = f"{name}[{where}] = {_scalar(array[index])!r}"
        else:
            shown = f"{name} = {_scalar(array)!r}"
        raise ValueError(f"{shown} is outside the allowed range: {allowed}")
    return array


def _short(name):
    return name.split(".")[-1]


def check_positive(**values):
    """Each value finite and > 0, e.g. ``check_positive(d=d, R=R)``."""
    for name, value in values.items():
        check(name, value, lambda a: np.isfinite(a) & (a > 0), f"{_short(name)} > 0 (finite)")


def check_finite(name, value, unit=""):
    """A finite real number (or array of them), of any sign."""
    check(name, value, np.isfinite, f"{_short(name)} finite{unit}")


def check_nonzero(name, value, unit="", why=""):
    """A finite value, not 0 (a speed that must have a direction); ``why`` ends the message."""
    allowed = f"{_short(name)} finite{unit}, not 0" + (f" ({why})" if why else "")
    check(name, value, lambda a: np.isfinite(a) & (a != 0), allowed)


def check_non_negative(name, value, unit=""):
    """A finite value ≥ 0 (``unit`` is appended to the allowed range, e.g. ``" N·m"``)."""
    check(name, value, lambda a: np.isfinite(a) & (a >= 0), f"{_short(name)} ≥ 0{unit} (finite)")


def check_range(
    name, value, low=-math.inf, high=math.inf, *, low_open=False, high_open=False, unit=""
):
    """A finite value in the interval from ``low`` to ``high`` (closed unless ``*_open``)."""
    short = _short(name)

    def ok(a):
        above = a > low if low_open else a >= low
        below = a < high if high_open else a <= high
        return np.isfinite(a) & above & below

    parts = []
    if low > -math.inf:
        parts.append(f"{low:g} {'<' if low_open else '≤'} ")
    parts.append(short)
    if high < math.inf:
        parts.append(f" {'<' if high_open else '≤'} {high:g}")
    return check(name, value, ok, "".join(parts) + unit + " (finite)")


def check_working_angle(name, value):
    """A working (articulation) angle γ [rad]: finite, 0 ≤ γ < π/2. The one rule of every public
    function that takes one (Hertz capacities, life, friction): γ = 20 (degrees given for
    radians) is refused, not answered with a plausible number."""
    return check(
        name,
        value,
        lambda a: np.isfinite(a) & (a >= 0) & (a < math.pi / 2),
        f"0 ≤ {_short(name)} < π/2 rad (finite)",
    )


SHARE_TOLERANCE = 1e-6
"""Concrete shares sum to 1 within this (`check_shares`)."""


def check_shares(name, share, axis=-1):
    """Non-negative finite shares that sum to 1 (along ``axis`` for an array; the error names
    the first slice that does not, e.g. ``share[1, :]``)."""
    array = check_real(name, share)
    if array is None:
        return
    check_non_negative(name, share)
    total = np.sum(array, axis=axis) if array.ndim else array
    bad = np.abs(total - 1.0) > SHARE_TOLERANCE
    if np.any(bad):
        if np.ndim(total):  # name the slice along ``axis`` that does not sum to 1
            index = [str(int(i)) for i in np.argwhere(bad)[0]]
            index.insert(axis % array.ndim, ":")
            name = f"{name}[{', '.join(index)}]"
        shown = float(np.asarray(total)[bad].flat[0]) if np.ndim(total) else float(total)
        raise ValueError(f"{name} sums to {shown:.6g}; the shares must sum to 1")


def check_integer(name, value, minimum=None, maximum=None):
    """An integer (Python ``int``, NumPy integer or integer array; never bool or float) in range.

    Returns the value; a traced integer passes unchecked. ``TypeError`` for a
    float such as 2.5 or 3.0, a bool or a string; ``ValueError`` below
    ``minimum`` or above ``maximum``.
    """
    short = _short(name)
    if minimum is not None and maximum is not None:
        rule = f"an integer {minimum} ≤ {short} ≤ {maximum}"
    elif minimum is not None:
        rule = f"an integer ≥ {minimum}"
    elif maximum is not None:
        rule = f"an integer ≤ {maximum}"
    else:
        rule = "an integer"
    if isinstance(value, jax.core.Tracer):
        if not np.issubdtype(value.dtype, np.integer):
            raise TypeError(f"{name} has dtype {value.dtype}; allowed: {rule}")
        return value
    is_int = isinstance(value, (numbers.Integral, np.ndarray, jax.Array)) and not isinstance(
        value, (bool, np.bool_)
    )
    lo = -math.inf if minimum is None else minimum
    hi = math.inf if maximum is None else maximum
    if is_int and isinstance(value, int) and not lo <= value <= hi:  # any size: out of range
        shown = _show_int(value) if abs(value) > 10**30 else repr(value)
        raise ValueError(f"{name} = {shown} is outside the allowed range: {rule}")
    if not is_int or np.asarray(value).dtype.kind not in "iu":
        raise TypeError(_not_allowed(name, value, rule))
    check(name, value, lambda a: (a >= lo) & (a <= hi), rule)
    return value


def check_choice(name, value, allowed):
    """Raise ValueError unless ``value`` is one of ``allowed`` (the one rule for every mode argument)."""
    if not isinstance(value, str) or value not in allowed:
        raise ValueError(
            f"{name} = {value!r} is not allowed; allowed: {', '.join(repr(a) for a in allowed)}"
        )
    return value


# --------------------------------------------------------------------------- shapes


def check_shapes(shapes, prefix="", allowed="numbers, or arrays whose shapes broadcast together"):
    """``ValueError`` unless the shapes ``{name: shape}`` broadcast together and none is empty.

    E.g. ``check_shapes({"R": (3,), "l": (2,), "gamma0": ()}, prefix="Layout.")`` raises
    ``"Layout fields have shapes R (3,), l (2,), gamma0 (); allowed: …"``. Returns the
    broadcast shape.
    """
    _check_not_empty(shapes, prefix)
    return _broadcast(shapes, f"{prefix.rstrip('.') or 'the'} fields", allowed)


def _check_not_empty(shapes, prefix=""):
    for name, shape in shapes.items():
        check_not_empty(prefix + name, shape)


def check_not_empty(name, shape):
    """``ValueError`` for an empty array (shape with a 0), as a Layout's fields: a number or a
    non-empty array, never one without values."""
    if math.prod(shape) == 0:
        raise ValueError(
            f"{name} is empty (shape {tuple(shape)}); allowed: a number or a non-empty array"
        )


def check_broadcast(**values):
    """``ValueError`` unless the arguments ``{name: value}`` broadcast together and none is
    empty, e.g. ``"the arguments have shapes d (3,), R (2,); allowed: …"`` or ``"d is empty
    (shape (0,)); …"`` (the rule of `check_shapes`); returns the broadcast shape."""
    shapes = {name: np.shape(value) for name, value in values.items()}
    _check_not_empty(shapes)
    arrays = {name: shape for name, shape in shapes.items() if shape}  # numbers fit any shape
    return _broadcast(arrays, "the arguments", "numbers, or arrays whose shapes broadcast together")


def _broadcast(shapes, owner, allowed):
    try:
        return np.broadcast_shapes(*shapes.values())
    except ValueError:
        listed = ", ".join(f"{name} {tuple(shape)}" for name, shape in shapes.items())
        raise ValueError(f"{owner} have shapes {listed}; allowed: {allowed}") from None


def check_devices(devices):
    """``devices``: None (every visible device) or a non-empty sequence of ``jax.Device``.

    Returns the devices as a list.
    """
    if devices is None:
        return jax.devices()
    if isinstance(devices, (str, bytes)) or not isinstance(devices, typing.Iterable):
        raise TypeError(_not_allowed("devices", devices, "a non-empty sequence of jax.Device"))
    devices = list(devices)
    if not devices:
        raise ValueError(
            "devices = [] is empty; allowed: a non-empty sequence of jax.Device, or None for "
            "every visible device"
        )
    bad = [d for d in devices if not isinstance(d, jax.Device)]
    if bad:
        raise TypeError(
            f"devices holds {_show(bad[0])} ({_type_name(bad[0])}); allowed: a non-empty "
            "sequence of jax.Device (e.g. jax.devices())"
        )
    return devices


def check_sweep_batch(n, torque, devices):
    """A sweep of ``n`` layouts: at least one, one ``torque`` for all, and
    `check_devices`. Returns the devices as a list.

    ``torque`` (None or a number [N·m]) must have shape (): the same torque for every layout.
    """
    if n < 1:
        raise ValueError("layouts is empty (0 layouts); allowed: a Layout of at least one layout")
    if torque is not None and not isinstance(torque, jax.core.Tracer) and np.ndim(torque) != 0:
        raise ValueError(
            f"torque has shape {np.shape(torque)}; allowed: one torque [N·m] for every layout "
            "(a number, shape ())"
        )
    return check_devices(devices)


# --------------------------------------------------------------------------- the layout domain


def check_layout_domain(R=None, l=None, gamma0=None, *, names=None, prefix="", degrees=False):
    """The one rule for the halfshaft layout domain (seed §2.9; see [`Layout`][tripodjax.layout.Layout]).

    ``R > 0`` mm, ``l > 0`` mm, ``R/l ≤ 0.2`` (`MAX_R_OVER_L`) and
    ``0 ≤ γ0 ≤ π/4`` rad = 45° (`MAX_GAMMA0`), every value finite and real
    (``str``, ``bool``, ``None``… raise ``TypeError``). The two upper bounds
    hold up to `TOLERANCE_ULPS` ulps of the value's own dtype, so the
    float32 roundings of π/4 and of R/l = 0.2 are inside.

    Args:
        R, l, gamma0: Python numbers or concrete arrays (broadcast together,
            e.g. one element per layout of a sweep); ``None`` skips a field
            (and the R/l rule unless both R and l are given). Traced values are
            not checked.
        names: display names of the fields, a mapping with any of the keys
            ``"R"``, ``"l"``, ``"gamma0"``; default the key itself. E.g.
            ``{"gamma0": "layout.gamma0_deg"}`` or ``{"R": "bounds.R"}``.
        prefix: put before every display name, e.g. ``"layouts."`` for a
            sweep (an array element is named ``layouts.R[3]``) or ``"Layout."``.
        degrees: ``gamma0`` is in degrees (0 ≤ γ0 ≤ 45), as at the user edge.

    Raises:
        TypeError: a value that is not a real number (or array of them).
        ValueError: naming the field (and index), the value and the allowed
            range, e.g. ``"layouts.gamma0[2] = 0.9 is outside the allowed
            range: 0 ≤ gamma0 ≤ π/4 = 0.785398 rad (45°), finite; got 51.57°"``.
    """
    shown = {"R": "R", "l": "l", "gamma0": "gamma0", **(names or {})}
    shown = {key: prefix + value for key, value in shown.items()}
    arrays = {}
    if R is not None:
        arrays["R"] = check(
            shown["R"],
            R,
            lambda a: np.isfinite(a) & (a > 0),
            f"{_short(shown['R'])} > 0 mm (finite)",
        )
    if l is not None:
        arrays["l"] = check(
            shown["l"],
            l,
            lambda a: np.isfinite(a) & (a > 0),
            f"{_short(shown['l'])} > 0 mm (finite)",
        )
    if gamma0 is not None:
        name = shown["gamma0"]
        array = check_real(name, gamma0)
        if array is not None:
            top = 45.0 if degrees else MAX_GAMMA0
            good = np.isfinite(array) & (array >= 0) & _at_most(array, top)
            if not np.all(good):
                index = (
                    tuple(int(i) for i in np.argwhere(~np.atleast_1d(good))[0])
                    if array.ndim
                    else ()
                )
                value = float(array[index]) if array.ndim else float(array)
                label = f"{name}[{','.join(map(str, index))}]" if array.ndim else name
                if degrees:
                    allowed = f"0 ≤ {_short(name)} ≤ 45°, finite"
                else:
                    allowed = f"0 ≤ {_short(name)} ≤ π/4 = {MAX_GAMMA0:.6f} rad (45°), finite"
                    if math.isfinite(value):
                        allowed += f"; got {math.degrees(value):.10g}°"
                raise ValueError(f"{label} = {value!r} is outside the allowed range: {allowed}")
    if arrays.get("R") is not None and arrays.get("l") is not None:
        R_array, l_array = np.broadcast_arrays(arrays["R"], arrays["l"])
        with np.errstate(over="ignore", divide="ignore", invalid="ignore"):  # 1e300 / 1e-300
            ratio = R_array / l_array
        bad = ~_at_most(ratio, MAX_R_OVER_L, arrays["R"], arrays["l"])
        if np.any(bad):
            if ratio.ndim:
                index = tuple(int(i) for i in np.argwhere(bad)[0])
                at = f"[{','.join(map(str, index))}]"
            else:
                index, at = (), ""
            r_name = shown["R"] + (at if np.ndim(arrays["R"]) else "")
            l_name = shown["l"] + (at if np.ndim(arrays["l"]) else "")
            R_value, l_value = float(R_array[index]), float(l_array[index])
            raise ValueError(
                f"{r_name} / {l_name} = {float(ratio[index]):.4g} is outside the allowed range: "
                f"R/l ≤ {MAX_R_OVER_L} (R = {R_value!r} mm, l = {l_value!r} mm, "
                f"so R ≤ {MAX_R_OVER_L * l_value:g} mm)"
            )


def outside_layout_domain(R, l, gamma0):
    """Where traced layout fields lie outside `check_layout_domain`'s domain (the same rule, the
    same tolerance of `TOLERANCE_ULPS` ulps of the fields' dtype): R ≤ 0, l ≤ 0, γ0 < 0,
    γ0 > π/4 or R/l > 0.2, as a boolean array of the broadcast shape. Comparisons are false
    for NaN: a NaN field is ``nonfinite``, not outside the domain."""
    dtype = np.dtype(jnp.result_type(R, l, gamma0, 0.0))

    def top(bound):
        bound = np.asarray(bound, dtype)
        return bound + TOLERANCE_ULPS * np.spacing(bound)

    return (
        (R <= 0)
        | (l <= 0)
        | (gamma0 < 0)
        | (gamma0 > top(MAX_GAMMA0))
        | (R / l > top(MAX_R_OVER_L))
    )


# --------------------------------------------------------------------------- hertz domain

MIN_CONFORMITY = 1.0005
"""Smallest conformity Ψ = 2 R_g/d accepted (Ψ − 1 ≥ 5·10⁻⁴), see `check_conformity`."""


def check_conformity(value, name="conformity"):
    """The Hertz conformity rule: Ψ = 2 R_g/d finite and ≥ `MIN_CONFORMITY` (1.0005).

    Ψ − 1 ≥ 5·10⁻⁴: a quarter of the lower end of the workbook's experience range
    (1.002–1.008). Below it the groove-to-roller radius clearance R_g − d/2 =
    (Ψ − 1)·d/2 is under 10 µm on a 40 mm roller, the order of the grinding
    tolerance of the track, so the conformity is not made nor held; and the
    capacities grow without bound as Ψ → 1 (M ∝ (μν)³ with κ ≈ 100 at 1.0005,
    cos τ = 1/(2Ψ − 1) ≈ 0.999, the end of the usual tables of μ, ν).
    """
    return check(
        name,
        value,
        lambda a: np.isfinite(a) & (a >= MIN_CONFORMITY),
        f"{_short(name)} Ψ ≥ {MIN_CONFORMITY} (Ψ − 1 ≥ 5e-4; workbook range 1.002–1.008)",
    )


# --------------------------------------------------------------------------- pytrees


_T = typing.TypeVar("_T")


@typing.dataclass_transform(frozen_default=True)
def checked_pytree_dataclass(cls: type[_T]) -> type[_T]:
    """A frozen dataclass registered as a pytree whose ``__post_init__`` checks run on user calls only.

    Unlike `tripodjax._pytree.pytree_dataclass`, JAX rebuilds instances
    (after ``jit``/``vmap``/``grad``, ``tree_map`` with ``None`` leaves,
    cotangents that are negative…) without calling ``__init__``, so the
    checks can be strict: a ``None``, ``str`` or ``bool`` field raises
    ``TypeError`` instead of being taken for a JAX placeholder.
    """
    cls = dataclasses.dataclass(frozen=True)(cls)
    names = tuple(f.name for f in dataclasses.fields(cls))  # type: ignore[arg-type]  # a dataclass now
    keys = tuple(jax.tree_util.GetAttrKey(name) for name in names)

    def flatten_with_keys(obj):
        return tuple(zip(keys, (getattr(obj, name) for name in names), strict=True)), None

    def flatten(obj):
        return tuple(getattr(obj, name) for name in names), None

    def unflatten(_, children):
        obj = object.__new__(cls)
        for name, child in zip(names, children, strict=True):
            object.__setattr__(obj, name, child)
        return obj

    jax.tree_util.register_pytree_with_keys(cls, flatten_with_keys, unflatten, flatten)
    return cls


def check_one_number(name: str, inputs: object, allowed: str) -> None:
    """Every field of ``inputs`` (a pytree) one number (shape ()); else one ValueError naming
    the field and its shape, with ``allowed`` saying what to do instead. A traced field's shape
    is known too (under ``vmap`` that of one element)."""
    for path, leaf in jax.tree_util.tree_leaves_with_path(inputs):
        if np.ndim(leaf) != 0:
            within = jax.tree_util.keystr(path, simple=True, separator=".")
            field = f"{name}.{within}" if within else name  # ``inputs`` a field itself
            raise ValueError(f"{field} has shape {np.shape(leaf)}; allowed: {allowed}")


# --------------------------------------------------------------------------- domains, traced too


@dataclasses.dataclass(frozen=True)
class Domain:
    """One input's domain, written once for both sides of the rule: the interval that the
    concrete check refuses values outside of at the Python boundary (`Domain.check`) and that
    flags traced values inside ``jit`` (`Domain.outside`).

    ``wording``: None words the boundary's error as `check_positive` (0 < x),
    `check_non_negative` (0 ≤ x) or `check_range`; else a callable ``(name, value)``, an
    existing rule of this module (e.g. `check_conformity`) that refuses exactly the values
    outside the interval and the non-finite ones.
    """

    low: float = -math.inf
    high: float = math.inf
    low_open: bool = False
    high_open: bool = False
    unit: str = ""
    wording: typing.Callable[[str, typing.Any], object] | None = None

    def check(self, name, value):
        """A concrete ``value`` (any shape) finite and inside; a traced one passes unchecked."""
        if self.wording is not None:
            self.wording(name, value)
        elif self.low == 0 and self.high == math.inf and self.low_open:
            check_positive(**{name: value})
        elif self.low == 0 and self.high == math.inf:
            check_non_negative(name, value, self.unit)
        else:
            check_range(
                name,
                value,
                self.low,
                self.high,
                low_open=self.low_open,
                high_open=self.high_open,
                unit=self.unit,
            )

    def outside(self, value):
        """Where a finite (traced) ``value`` lies outside, elementwise (a JAX bool array). NaN
        and ±inf are not outside: they are non-finite (``nonfinite``, not ``outside_validity``)."""
        x = jnp.asarray(value)
        below = x <= self.low if self.low_open else x < self.low
        above = x >= self.high if self.high_open else x > self.high
        return jnp.isfinite(x) & (below | above)


def check_domains(domains, **values):
    """Each concrete value inside the domain ``domains[short name]`` (e.g. the key ``d`` for
    ``FixedJoint.d``); the error names the full name."""
    for name, value in values.items():
        domains[_short(name)].check(name, value)


def outside_domains(domains, **values):
    """Where any (traced) value lies outside its domain ``domains[name]``, broadcast together."""
    flag = jnp.bool_(False)
    for name, value in values.items():
        flag = flag | domains[name].outside(value)
    return flag


def outside_shares(share, axis=-1):
    """Traced shares, per slice along ``axis``: some finite share outside [0, 1]. Non-finite
    shares are not outside (they are ``nonfinite``). That they sum to 1 is a relation between
    numbers, checked where they are concrete (`check_shares`); traced, a derivative moves one
    share alone (a sensitivity, the optimiser's derivatives w.r.t. one entry of a list), so
    only each share's own domain is flagged."""
    share = jnp.asarray(share)
    if not share.ndim:
        share = share[None]
    return jnp.any(jnp.isfinite(share) & ((share < 0) | (share > 1)), axis=axis)
