"""Checks of inputs at the Python boundary: concrete values only, never traced ones."""

import jax
import numpy as np


def concrete(value):
    """``value`` as a NumPy array when it is a concrete number or array, else None.

    Traced values (inside jit/vmap/grad) and the placeholders JAX puts in
    pytrees while it rebuilds them are not checked.
    """
    if isinstance(value, jax.core.Tracer):
        return None
    try:
        array = np.asarray(value)
    except Exception:  # a placeholder object that is no number
        return None
    return array if array.dtype.kind in "fiu" else None


def check(name, value, ok, allowed):
    """Raise ValueError naming ``name``, the offending value and ``allowed`` unless ``ok`` holds."""
    array = concrete(value)
    if array is not None and not np.all(ok(array)):
        shown = array[~ok(array)].flat[0] if array.ndim else array
        raise ValueError(f"{name} = {float(shown)!r} is outside the allowed range: {allowed}")


def check_positive(**values):
    """Each value finite and > 0."""
    for name, value in values.items():
        check(name, value, lambda a: np.isfinite(a) & (a > 0), f"{name} > 0")


def check_non_negative(name, value, unit=""):
    """A finite value ≥ 0."""
    check(name, value, lambda a: np.isfinite(a) & (a >= 0), f"{name.split('.')[-1]} ≥ 0{unit}")


def check_shares(name, share):
    """Non-negative shares that sum to 1."""
    array = concrete(share)
    if array is None:
        return
    check_non_negative(name, share)
    total = float(np.sum(array))
    if abs(total - 1.0) > 1e-6:
        raise ValueError(f"{name} sums to {total:.6g}; the shares must sum to 1")


def check_choice(name, value, allowed):
    """Raise ValueError unless ``value`` is one of ``allowed`` (the one rule for every mode argument)."""
    if not isinstance(value, str) or value not in allowed:
        raise ValueError(
            f"{name} = {value!r} is not allowed; allowed: {', '.join(repr(a) for a in allowed)}"
        )
    return value
