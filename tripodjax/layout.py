"""The halfshaft layout: joint size, shaft length and layout articulation angle."""

import math
import numbers
import types
from collections.abc import Mapping
from typing import TypeGuard

import numpy as np
from jax.typing import ArrayLike

from tripodjax._checks import (
    MAX_GAMMA0,
    MAX_R_OVER_L,
    as_array,
    check_choice,
    check_instance,
    check_layout_domain,
    check_real,
    check_shapes,
    checked_pytree_dataclass,
    concrete,
)

__all__ = ["MAX_GAMMA0", "MAX_R_OVER_L", "TABLE_2_1", "Layout", "check_layout", "seed_case"]


def _is_scalar(value: object) -> TypeGuard[numbers.Real | np.ndarray]:
    """A concrete real scalar: a Python/NumPy number (not bool) or a 0-d NumPy array."""
    if isinstance(value, numbers.Real) and not isinstance(value, (bool, np.bool_)):
        return True
    return isinstance(value, np.ndarray) and value.ndim == 0


@checked_pytree_dataclass
class Layout:
    """Layout of a halfshaft with a tripod joint (seed §2.9, figure 2.9.1).

    Attributes:
        R: track pitch-circle radius of the pot [mm] — the joint size.
        l: shaft length from the spider centre to the fixed joint's pivot
            point H [mm].
        gamma0: layout articulation angle [rad], the joint angle at θ = 0.

    An immutable pytree: it can be passed through ``jax.jit``, ``jax.vmap``
    and differentiated with ``jax.grad`` (gradients come back as a Layout;
    JAX rebuilds instances without re-running the checks).

    Fields are real numbers or arrays of real numbers (a Python list or tuple
    of numbers is taken as a NumPy array): a ``str``, ``bool``,
    ``None``, complex number or list of those raises ``TypeError``. Their
    shapes must broadcast together (numbers, or arrays of one shape, e.g. a
    batch for [`sweep`][tripodjax.sweep.sweep]) and none may be empty. Every
    concrete field — a Python or NumPy number, a NumPy array, a concrete JAX
    array, 0-d or not — is checked element by element against the documented
    domain ``R > 0`` mm, ``l > 0`` mm, ``R/l ≤ 0.2``, ``0 ≤ gamma0 ≤ π/4``
    (45°), all finite — the one rule of
    `tripodjax._checks.check_layout_domain` — and raises ``ValueError``
    naming the field (and the first bad index), the value and the allowed
    range. Traced fields (inside ``jit``/``vmap``/``grad``) cannot be refused:
    there a field outside the domain gives the solve's result code
    ``outside_validity`` at every point (`tripodjax._checks.outside_layout_domain`,
    the same rule), and a NaN field NaN with the code ``nonfinite``.

    Use [`from_degrees`][tripodjax.layout.Layout.from_degrees] to give ``gamma0`` in degrees.
    """

    R: ArrayLike
    l: ArrayLike
    gamma0: ArrayLike

    def __post_init__(self) -> None:
        values = {"R": self.R, "l": self.l, "gamma0": self.gamma0}
        for name, value in values.items():
            check_real(f"Layout.{name}", value)
            if isinstance(value, (list, tuple)):  # a NumPy array at the boundary, not a pytree node
                values[name] = as_array(value)
                object.__setattr__(self, name, values[name])
        check_shapes({name: np.shape(value) for name, value in values.items()}, "Layout.")
        check_layout_domain(
            **{name: value for name, value in values.items() if concrete(value) is not None},
            prefix="Layout.",
        )

    @classmethod
    def from_degrees(cls, R: ArrayLike, l: ArrayLike, gamma0_deg: ArrayLike) -> "Layout":
        """Build a Layout with the layout articulation angle in degrees (0 ≤ gamma0_deg ≤ 45)."""
        check_real("gamma0_deg", gamma0_deg)
        gamma0_deg = as_array(gamma0_deg)
        if concrete(gamma0_deg) is not None:
            check_layout_domain(gamma0=gamma0_deg, names={"gamma0": "gamma0_deg"}, degrees=True)
        if _is_scalar(gamma0_deg):
            return cls(R, l, math.radians(gamma0_deg))
        return cls(R, l, gamma0_deg * (math.pi / 180.0))


def check_layout(
    layout: object,
    name: str = "layout",
    allowed: str = "a Layout, e.g. Layout(25.0, 500.0, 0.35)",
    *,
    one: bool = False,
) -> Layout:
    """``TypeError`` naming ``name`` unless ``layout`` is a [`Layout`][tripodjax.layout.Layout] (its fields were checked).

    The one type rule of every function that takes a layout
    ([`solve_halfshaft`][tripodjax.halfshaft.solve_halfshaft], [`kinematic_metrics`][tripodjax.kinematics.kinematic_metrics],
    [`gaf_halfshaft`][tripodjax.friction.gaf_halfshaft], [`sweep`][tripodjax.sweep.sweep]).
    With ``one`` (a function of one layout over a revolution), ``ValueError`` unless every field
    is a number (shape ()): a batch goes through ``jax.vmap`` or ``sweep``. Returns ``layout``.
    """
    checked: Layout = check_instance(name, layout, Layout, allowed)
    if one:
        shapes = {field: np.shape(getattr(checked, field)) for field in ("R", "l", "gamma0")}
        if any(shapes.values()):
            listed = ", ".join(f"{field} {shape}" for field, shape in shapes.items())
            raise ValueError(
                f"{name} has fields of shapes {listed}; allowed: one layout (every field a "
                "number): for a batch, jax.vmap over the layouts or tripodjax.sweep"
            )
    return checked


TABLE_2_1: Mapping[str, tuple[float, float, float]] = types.MappingProxyType(
    {
        "N": (500.0, 25.0, 20.0),
        "L3": (300.0, 25.0, 20.0),
        "L4": (400.0, 25.0, 20.0),
        "L7": (700.0, 25.0, 20.0),
        "R2": (500.0, 20.0, 20.0),
        "R3": (500.0, 30.0, 20.0),
        "R4": (500.0, 40.0, 20.0),
        "g5": (500.0, 25.0, 5.0),
        "g10": (500.0, 25.0, 10.0),
        "g15": (500.0, 25.0, 15.0),
        "g25": (500.0, 25.0, 25.0),
    }
)
"""The seed's Table 2.1 cases (§2.10): code → (l [mm], R [mm], γ0 [deg]), read-only;
`seed_case` gives one as a `Layout`."""


def seed_case(code: str) -> Layout:
    """The Layout of one of the seed's Table 2.1 cases, e.g. ``seed_case("N")``."""
    if not isinstance(code, str):
        raise TypeError(
            f"code = {code!r} ({type(code).__name__}) is not allowed; "
            f"allowed: a Table 2.1 case name, one of {', '.join(TABLE_2_1)}"
        )
    if code not in TABLE_2_1:
        check_choice("code", code, tuple(TABLE_2_1))
    l, R, gamma0_deg = TABLE_2_1[code]
    return Layout.from_degrees(R, l, gamma0_deg)
