"""The halfshaft layout: joint size, shaft length and layout articulation angle."""

import math
import numbers

from tripodjax._pytree import pytree_dataclass

MAX_GAMMA0 = math.pi / 4  # rad; the validated domain ends at 45°
MAX_R_OVER_L = 0.2


def _is_python_number(value):
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def _describe(field, value, allowed):
    return f"Layout.{field} = {value!r} is outside the allowed range: {allowed}"


@pytree_dataclass
class Layout:
    """Layout of a halfshaft with a tripod joint (seed §2.9, figure 2.9.1).

    Attributes:
        R: track pitch-circle radius of the pot [mm] — the joint size.
        l: shaft length from the spider centre to the fixed joint's pivot
            point H [mm].
        gamma0: layout articulation angle [rad], the joint angle at θ = 0.

    An immutable pytree: it can be passed through ``jax.jit``, ``jax.vmap``
    and differentiated with ``jax.grad`` (gradients come back as a Layout).
    Built from Python numbers it checks its documented domain
    ``R > 0``, ``l > 0``, ``R/l ≤ 0.2``, ``0 ≤ gamma0 ≤ π/4`` (45°) and
    raises ``ValueError`` naming the field, the value and the allowed range.
    Array or traced fields are not checked (that would break ``jit``).

    Use :meth:`from_degrees` to give ``gamma0`` in degrees.
    """

    R: float
    l: float
    gamma0: float

    def __post_init__(self):
        values = {"R": self.R, "l": self.l, "gamma0": self.gamma0}
        for name, value in values.items():
            if _is_python_number(value) and not math.isfinite(value):
                raise ValueError(_describe(name, value, "a finite number"))
        if _is_python_number(self.R) and not self.R > 0:
            raise ValueError(_describe("R", self.R, "R > 0 mm"))
        if _is_python_number(self.l) and not self.l > 0:
            raise ValueError(_describe("l", self.l, "l > 0 mm"))
        if _is_python_number(self.gamma0) and not 0 <= self.gamma0 <= MAX_GAMMA0:
            raise ValueError(
                _describe(
                    "gamma0",
                    self.gamma0,
                    f"0 ≤ gamma0 ≤ {MAX_GAMMA0:.6f} rad (45°); "
                    f"got {math.degrees(self.gamma0):.4g}°",
                )
            )
        if _is_python_number(self.R) and _is_python_number(self.l):
            if self.R / self.l > MAX_R_OVER_L:
                raise ValueError(
                    f"Layout.R / Layout.l = {self.R!r} / {self.l!r} = "
                    f"{self.R / self.l:.4g} is outside the allowed range: "
                    f"R/l ≤ {MAX_R_OVER_L}"
                )

    @classmethod
    def from_degrees(cls, R, l, gamma0_deg):
        """Build a Layout with the layout articulation angle in degrees."""
        if _is_python_number(gamma0_deg):
            return cls(R, l, math.radians(gamma0_deg))
        return cls(R, l, gamma0_deg * (math.pi / 180.0))


# The seed's Table 2.1 cases (§2.10): code → (l [mm], R [mm], γ0 [deg]).
TABLE_2_1 = {
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


def seed_case(code):
    """The Layout of one of the seed's Table 2.1 cases, e.g. ``seed_case("N")``."""
    try:
        l, R, gamma0_deg = TABLE_2_1[code]
    except KeyError:
        raise ValueError(
            f"unknown Table 2.1 case {code!r}; allowed: {', '.join(TABLE_2_1)}"
        ) from None
    return Layout.from_degrees(R, l, gamma0_deg)
