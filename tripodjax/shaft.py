"""The halfshaft's sections, statically and in fatigue (the company workbook, seed §4.3, sheets 5–7).

Every section that carries the torque (the shaft's cross-sections A-A, B-B,
C-C and both joints' stems; seed fig. 4.3.5) is a solid or hollow circle of
outer diameter Øe and inner diameter Øi (0 for a round bar), induction-hardened
to a depth h with a transition of depth t below it. Units: mm, N·m, MPa.

**Strength profile** (seed §4.3, sheet 6, fig. 4.3.6). At the depth δ = Øe/2 − r
the ultimate strength falls linearly from the surface value σ_R,s (from the
micro-hardness) to (1 − Δ) σ_R,s at δ = h (Δ the "% UTS reduction at max depth",
10 % in the workbook), then linearly to the core's σ_R,c at δ = h + t, and
stays there. Its kinks are at r_o = Øe/2, r_o − h and r_TR = r_o − h − t, the
end of the transformed layer.

**Static check** (fig. 4.3.6). The shear τ = T r / J (J = π(Øe⁴ − Øi⁴)/32) is
linear in r and the allowed shear τ_adm(r) = σ_R(r) / (C_s √3) piecewise linear,
so their ratio is monotonic between the kinks: the safety S(r) = τ_adm(r)/τ(r)
is taken at the three kink radii (its minimum over the section is the smallest
of the three; the workbook's 1817 and 1049 MPa at the surface, 575 and 332 MPa
in the core are σ_R/C_s and σ_R/(C_s √3)). The torque is the largest working
torque with the shock factor k_s (seed §4.3, sheet 6: "la coppia massima
aumentata del fattore di shock"), forward and backward, i.e.
`LoadCycles.M_max_forward` and `M_max_backward` (1154 and 750 N·m for the
workbook's vehicle). The sheet prints no number here; the engine-side torque
(8015 N·m in 1st gear) is not a torque the wheel can react.

**Fatigue check** (fig. 4.3.7), at r_o and r_TR. For each driving mode m, gear
g and engine condition c (`tripodjax.vehicle.ENGINE_CONDITIONS`) one row:

- the load torque: the working torque T_w[m, g, c] (adhesion-limited, with k_s)
  for mean torque, maximum torque and maximum power; the engine brake torque
  T_eb[g] = T_brake · i_g without k_s (the working torque of the brake
  condition over k_s); each cycle runs from the load to the engine brake, the
  brake rows from the gear's maximum-torque load;
- stresses σ = √3 τ (pure torsion), σ_m = (σ_load + σ_eb)/2, σ_a = (σ_load −
  σ_eb)/2, the ratio r = σ_a/σ_m;
- the allowed amplitude at 10⁶ cycles on the constant-ratio line of Goodman's
  diagram, σ_lim = 1 / (1/σ_f + |σ_m|/(σ_a σ_R)), σ_f = σ_R / q with q the
  UTS / fatigue-limit ratio (1.6 or 2 in the workbook);
- cycles to failure on the semi-log line from (10³, σ_R) to (10⁶, σ_lim),
  log₁₀ N = 3 + 3 (σ_R − σ_a)/(σ_R − σ_lim), without an endurance limit;
- cycle counts n = w_m N_rev u[m, g, c] p(ω): mode weight × the mileage's
  revolutions × the relative use × the event rate p(ω) = 10^(a + b ω) at the
  shaft speed ω [rad/s], the line through (10 rad/s, 5 %) and (250 rad/s, 0.2 %)
  (`EventRate`, fig. 4.3.5). The engine brake's use of a gear is its own plus
  the revolutions that no condition claims, shared in proportion to the
  gear's driving use (the sheet's share(g) · (1 − Σ u)/Σ u);
- Miner's sum D = Σ n/N per radius; the section passes when D < 1.

**Readings** (``reading="consistent"``, the default, or ``"workbook"``) where the
sheet is silent or inconsistent:

- *the 1st gear's engine-brake counts.* ``consistent``: with the event rate like
  every row. ``workbook``: the revolutions without p(ω) (the sheet's 164 176
  cycles against 6 813 with it, seed fig. 4.3.7);
- *the strength at r_TR in fatigue.* ``consistent``: the profile's value
  there, the core's σ_R,c (690 MPa). ``workbook``: σ_R,c (1 + Δ) = 759 MPa,
  the sheet's number (its rule is not printed; this one reproduces it).

Both readings keep the sheet's engine-brake sign: a torque reversal (T_eb < 0)
in 1st gear only, a same-sign unload in the other gears and reverse (the sheet's
means and amplitudes). An engine brake drags the wheels in every gear, but under
the sheet's S–N line (anchored at σ_a = σ_R at 10³ cycles whatever the ratio) a
reversal *lowers* the damage (the constant-ratio line's σ_lim rises faster than
σ_a): with a reversal in every gear the workbook's outboard stem would get 0.010
and 0.028 instead of about 0.08 and 0.12. Until the S–N anchor is settled the
sheet's, more conservative, signs stay.

Where the sheet's 2nd gear sport rows take 1154 N·m (the 1st gear's adhesion
limit, also in its fig. 4.3.4), this module takes the chain's 1103 N·m, as the
sheet's own intercity and city rows do. The inboard stem's 20.44 mm (sheet 5)
fails both checks at that size although the sheet says "Positive"; it is read
as a typing error, not a reading (28.44 mm passes).

Every number is a pytree leaf: ``jit``, ``vmap`` (over sections, materials or
vehicles) and ``grad`` through all of them. Inputs are checked at the Python
boundary (one line naming the field, the value and the allowed range);
inside ``jit`` an input outside its domain gives NaN, never a plausible number.
"""

import functools
import math
from collections.abc import Mapping
from types import MappingProxyType

import jax
import jax.numpy as jnp
import numpy as np
from jax.typing import ArrayLike

from tripodjax._checks import (
    _at_most,
    check,
    check_choice,
    check_instance,
    check_non_negative,
    check_positive,
    check_range,
    check_real,
    check_shapes,
    checked_pytree_dataclass,
)
from tripodjax._compile import latency_bound_at_top_level
from tripodjax._pytree import pytree_dataclass
from tripodjax.hertz import _nan_unless
from tripodjax.results import RESULTS, code_where
from tripodjax.vehicle import DrivingModes, LoadCycles

__all__ = [
    "READINGS",
    "WORKBOOK_SECTIONS",
    "EventRate",
    "FatigueCheck",
    "FatigueCycles",
    "Material",
    "Section",
    "StaticCheck",
    "check_material_strength",
    "check_section_fits",
    "fatigue_check",
    "fatigue_cycles",
    "polar_moment",
    "static_check",
    "strength_profile",
]

READINGS = ("consistent", "workbook")
SQRT3 = math.sqrt(3.0)
RPM_TO_RAD_S = 2.0 * math.pi / 60.0


def _concrete(*values):
    """The values as NumPy arrays, or None when any is traced (relations are then not checked)."""
    arrays = [check_real("value", v) for v in values]
    return None if any(a is None for a in arrays) else arrays


def _shape(obj):
    """The shape of a Section's, Material's or EventRate's fields, which broadcast together
    and are not empty (else a ValueError naming each field's shape)."""
    name = type(obj).__name__
    shapes = {f: jnp.shape(getattr(obj, f)) for f in obj.__dataclass_fields__}
    return check_shapes(shapes, prefix=f"{name}.")


def _check_batch(section, material, **values):
    """The section, the material and ``values`` (e.g. the torque) broadcast together."""
    shapes = {"section": _shape(section), "material": _shape(material)}
    shapes.update({k: jnp.shape(v) for k, v in values.items()})
    check_shapes(
        shapes,
        allowed="shapes that broadcast together (e.g. a torque[:, None] against sections of "
        "shape (n,), or jax.vmap over the sections)",
    )


@checked_pytree_dataclass
class Section:
    """One cross-section that carries the torque (seed fig. 4.3.5), with its hardened layer.

    Attributes:
        outer_diameter: Øe [mm], > 0 (at a spline, its root).
        hardened_depth: h [mm], ≥ 0 (0: not quenched).
        transition_depth: t [mm], ≥ 0; h + t ≤ (Øe − Øi)/2.
        inner_diameter: Øi [mm], 0 ≤ Øi < Øe (0, the default: a round bar).
    """

    outer_diameter: ArrayLike
    hardened_depth: ArrayLike
    transition_depth: ArrayLike
    inner_diameter: ArrayLike = 0.0

    def __post_init__(self) -> None:
        check_positive(**{"Section.outer_diameter": self.outer_diameter})
        for k in ("hardened_depth", "transition_depth", "inner_diameter"):
            check_non_negative(f"Section.{k}", getattr(self, k), " mm")
        _shape(self)
        check_section_fits(
            self.outer_diameter, self.hardened_depth, self.transition_depth, self.inner_diameter
        )


SECTION_NAMES = (
    "Section.outer_diameter",
    "Section.hardened_depth",
    "Section.transition_depth",
    "Section.inner_diameter",
)


def check_section_fits(
    outer_diameter: ArrayLike,
    hardened_depth: ArrayLike,
    transition_depth: ArrayLike,
    inner_diameter: ArrayLike = 0.0,
    names: tuple = SECTION_NAMES,
) -> None:
    """A section's dimensions [mm] fit together: Øi < Øe and h + t ≤ the wall (Øe − Øi)/2, for
    concrete values (traced ones are not checked). ``names`` name Øe, h, t and Øi in the
    error (default: `Section`'s fields; the spec gives its keys)."""
    arrays = _concrete(outer_diameter, inner_diameter, hardened_depth, transition_depth)
    if arrays is None:
        return
    outer, inner, h, t = np.broadcast_arrays(*arrays)
    fields = names == SECTION_NAMES  # the fields' own messages, "h + t ≤ the wall (Øe − Øi)/2"
    short = [n.removeprefix("Section.") for n in names] if fields else list(names)
    number = repr if fields else "{:g}".format  # a caller's keys: its numbers as a file's
    check(
        names[3],
        inner,
        lambda a: a < outer,
        f"0 ≤ {short[3]} < {short[0]} (= {number(_first(outer, a=inner >= outer))} mm)",
    )
    wall = (outer - inner) / 2.0
    # on the wall up to rounding: 1e-12 of it, or a few ulps of a float32 section's dtype
    beyond = (h + t > wall * (1.0 + 1e-12)) & ~_at_most(h + t, wall, *arrays)
    rule = "h + t ≤ the wall (Øe − Øi)/2" if fields else f"≤ the wall ({short[0]} − {short[3]})/2"
    check(
        f"{names[1]} + {short[2]}",
        h + t,
        lambda a: ~beyond,
        f"{rule} (= {number(_first(wall, a=beyond))} mm)",
    )


def _first(values, a):
    """The first value where the mask ``a`` holds (for an error message), as a float."""
    return float(values[tuple(np.argwhere(a)[0])] if values.ndim else values) if np.any(a) else 0.0


@checked_pytree_dataclass
class Material:
    """A section's steel and the strength of its induction-hardened layer (seed fig. 4.3.5).

    Attributes:
        core_uts: σ_R,c, the core's ultimate strength [MPa], > 0 (690 for C53 and 42CrMo4).
        surface_uts: σ_R,s, the surface's, from the micro-hardness [MPa]; (1 − Δ) σ_R,s ≥ σ_R,c.
        depth_drop: Δ, the strength lost from the surface to the depth h [–], 0 ≤ Δ < 1.
        fatigue_ratio: q = σ_R / σ_f, UTS over the fatigue limit [–], > 1 (1.6 or 2).
        safety: C_s, the safety coefficient on the static limits [–], ≥ 1 (1.2).
    """

    core_uts: ArrayLike
    surface_uts: ArrayLike
    depth_drop: ArrayLike
    fatigue_ratio: ArrayLike
    safety: ArrayLike

    def __post_init__(self) -> None:
        check_positive(
            **{"Material.core_uts": self.core_uts, "Material.surface_uts": self.surface_uts}
        )
        check_range("Material.depth_drop", self.depth_drop, 0.0, 1.0, high_open=True)
        check_range("Material.fatigue_ratio", self.fatigue_ratio, 1.0, low_open=True)
        check_range("Material.safety", self.safety, 1.0)
        _shape(self)
        check_material_strength(self.core_uts, self.surface_uts, self.depth_drop)


MATERIAL_NAMES = ("Material.core_uts", "Material.surface_uts", "Material.depth_drop")


def check_material_strength(
    core_uts: ArrayLike,
    surface_uts: ArrayLike,
    depth_drop: ArrayLike,
    names: tuple = MATERIAL_NAMES,
) -> None:
    """The hardened layer is no weaker than the core at its depth: σ_R,s (1 − Δ) ≥ σ_R,c [MPa],
    for concrete values (traced ones are not checked). ``names`` name σ_R,c, σ_R,s and Δ in the
    error (default: `Material`'s fields; the spec gives its keys)."""
    arrays = _concrete(core_uts, surface_uts, depth_drop)
    if arrays is None:
        return
    core, surface, drop = np.broadcast_arrays(*arrays)
    weak = surface * (1.0 - drop) < core
    fields = names == MATERIAL_NAMES
    short = [n.removeprefix("Material.") for n in names] if fields else names
    number = repr if fields else "{:g}".format  # a caller's keys: its numbers as a file's
    check(
        names[1],
        surface,
        lambda a: ~weak,
        f"{short[1]} (1 − {short[2]}) ≥ {short[0]} (= {number(_first(core, a=weak))} MPa)",
    )


def _workbook_material(fatigue_ratio: float, safety: float) -> Material:
    return Material(
        core_uts=690.0,
        surface_uts=2180.0,
        depth_drop=0.10,
        fatigue_ratio=fatigue_ratio,
        safety=safety,
    )


WORKBOOK_SECTIONS: Mapping[str, tuple[Section, Material]] = MappingProxyType(
    {
        "A-A": (Section(26.0, 5.6, 3.5), _workbook_material(1.6, 1.2)),
        "B-B": (Section(27.5, 5.6, 3.5), _workbook_material(1.6, 1.2)),
        "C-C": (Section(25.8, 5.6, 3.5), _workbook_material(1.6, 1.2)),
        "outboard stem": (Section(30.685, 2.5, 3.5), _workbook_material(1.6, 1.3)),
        "inboard stem": (Section(28.44, 1.2, 1.1), _workbook_material(1.6, 1.2)),
    }
)
"""The workbook's rear halfshaft, section by section (seed fig. 4.3.5, sheet 5): name → (Section, Material).

The shaft's cross-sections A-A, B-B, C-C (42CrMo4: Øe 26, 27.5 and 25.8 mm, h 5.6,
t 3.5 mm, safety coefficient 1.2), the outboard joint's stem ("Fixed FR", bell C53:
Øe 30.685 mm — printed 30.69, the sheet's J = 87 037 mm⁴ needs 30.685 —, h 2.5, t 3.5,
safety coefficient 1.3) and the inboard tripod's stem (h 1.2, t 1.1 mm, the rear's;
safety coefficient 1.2). Every section: core σ_R,c 690 MPa, surface σ_R,s 2180 MPa (from
the micro-hardness), Δ = 10 % at the depth h, the rear's UTS / fatigue ratio q = 1.6.
The inboard stem's printed 20.44 mm fails both checks where the sheet says "Positive":
it is read as a typing error for 28.44 mm (see the module docstring). The front axle
is "no DS" (rear-wheel drive): its sections are not listed.
"""


@checked_pytree_dataclass
class EventRate:
    """The share of the revolutions that are fatigue events, p(ω), a line in log p (fig. 4.3.5).

    p(ω) = p_low (p_high/p_low)^((ω − ω_low)/(ω_high − ω_low)) at the shaft speed ω
    [rad/s], not clipped outside [ω_low, ω_high]. The workbook's line goes through
    (10 rad/s, 5 %) and (250 rad/s, 0.2 %): log₁₀ p[%] = 0.75722 − 0.0058248 ω.

    Attributes:
        speed_low, speed_high: ω_low < ω_high [rad/s], > 0.
        rate_low, rate_high: p at them [–], in (0, 1].
    """

    speed_low: ArrayLike = 10.0
    rate_low: ArrayLike = 0.05
    speed_high: ArrayLike = 250.0
    rate_high: ArrayLike = 0.002

    def __post_init__(self) -> None:
        check_positive(
            **{"EventRate.speed_low": self.speed_low, "EventRate.speed_high": self.speed_high}
        )
        for k in ("rate_low", "rate_high"):
            check_range(f"EventRate.{k}", getattr(self, k), 0.0, 1.0, low_open=True)
        _shape(self)
        arrays = _concrete(self.speed_low, self.speed_high)
        if arrays is None:
            return
        low, high = np.broadcast_arrays(*arrays)
        check(
            "EventRate.speed_high",
            high,
            lambda a: a > low,
            f"speed_high > speed_low (= {_first(low, a=high <= low)} rad/s)",
        )

    def __call__(self, omega: ArrayLike) -> jax.Array:
        """p(ω) [–] at the shaft speed ω [rad/s]."""
        low, high = jnp.asarray(self.speed_low), jnp.asarray(self.speed_high)
        p_low, p_high = jnp.asarray(self.rate_low), jnp.asarray(self.rate_high)
        x = (jnp.asarray(omega) - low) / (high - low)
        return p_low * jnp.exp(x * jnp.log(p_high / p_low))


def polar_moment(section: Section) -> jax.Array:
    """J = π(Øe⁴ − Øi⁴)/32 [mm⁴]."""
    outer, inner = jnp.asarray(section.outer_diameter), jnp.asarray(section.inner_diameter)
    return math.pi * (outer**4 - inner**4) / 32.0


def _valid(section, material):
    """Elementwise: the section and material inside their domains (NaN elsewhere under ``jit``)."""
    s, m = section, material
    wall = (s.outer_diameter - s.inner_diameter) / 2.0
    ok = (s.outer_diameter > 0) & (s.inner_diameter >= 0) & (wall > 0)
    ok = ok & (s.hardened_depth >= 0) & (s.transition_depth >= 0)
    ok = ok & (s.hardened_depth + s.transition_depth <= wall * (1.0 + 1e-6))
    ok = ok & (m.core_uts > 0) & (m.depth_drop >= 0) & (m.depth_drop < 1)
    ok = ok & (m.surface_uts * (1.0 - m.depth_drop) >= m.core_uts * (1.0 - 1e-6))
    ok = ok & (m.fatigue_ratio > 1) & (m.safety >= 1)
    finite = [jnp.isfinite(jnp.asarray(x)) for x in (*jax.tree.leaves(s), *jax.tree.leaves(m))]
    for f in finite:
        ok = ok & f
    return ok


def _kinks(section, material):
    """The profile's kink radii (r_o, r_o − h, r_TR) and strengths there, each shape (..., 3)."""
    s, m = section, material
    r_o = jnp.asarray(s.outer_diameter) / 2.0
    r_h = r_o - s.hardened_depth
    r_tr = r_h - s.transition_depth
    radius = jnp.stack(jnp.broadcast_arrays(r_o, r_h, r_tr), axis=-1)
    surface = jnp.asarray(m.surface_uts)
    uts = jnp.stack(
        jnp.broadcast_arrays(surface, surface * (1.0 - m.depth_drop), m.core_uts), axis=-1
    )
    return radius, uts


def strength_profile(section: Section, material: Material, radius: ArrayLike) -> jax.Array:
    """σ_R(r) [MPa] at the radius r [mm] (Øi/2 ≤ r ≤ Øe/2): the piecewise-linear layer profile.

    Linear from σ_R,s at the surface to (1 − Δ) σ_R,s at the depth h, then to σ_R,c
    at h + t; σ_R,c below. Where h or t is 0 the profile steps there (the value
    below the step). Differentiable in r and every field between the kinks.
    """
    check_instance("section", section, Section, "a shaft.Section")
    check_instance("material", material, Material, "a shaft.Material")
    check_real("radius", radius)
    _check_batch(section, material, radius=radius)
    arrays = _concrete(radius, section.outer_diameter, section.inner_diameter)
    if arrays is not None:
        r, outer, inner = np.broadcast_arrays(*arrays)
        outside = ~((r >= inner / 2.0) & (r <= outer / 2.0))
        check(
            "radius",
            r,
            lambda a: ~outside,
            f"Øi/2 ≤ radius ≤ Øe/2 (= {_first(inner / 2.0, a=outside)}–"
            f"{_first(outer / 2.0, a=outside)} mm)",
        )
    s, m = section, material
    depth = jnp.asarray(s.outer_diameter) / 2.0 - jnp.asarray(radius)
    h, t = jnp.asarray(s.hardened_depth), jnp.asarray(s.transition_depth)
    surface, core = jnp.asarray(m.surface_uts), jnp.asarray(m.core_uts)
    at_h = surface * (1.0 - m.depth_drop)
    in_layer = depth < h
    in_transition = depth < h + t
    layer = surface - (surface - at_h) * depth / jnp.where(in_layer, h, 1.0)
    transition = at_h - (at_h - core) * (depth - h) / jnp.where(in_transition, t, 1.0)
    uts = jnp.where(in_layer, layer, jnp.where(in_transition, transition, core))
    ok = _valid(s, m) & (depth >= 0) & (depth <= s.outer_diameter / 2.0 - s.inner_diameter / 2.0)
    return _nan_unless(ok, uts)


@pytree_dataclass
class StaticCheck:
    """The static check of a section at the kinks of its strength profile (fig. 4.3.6).

    The last axis is the radius (r_o, r_o − h, r_TR); a leading axis of the torque
    (e.g. forward and backward) comes first.

    Attributes:
        radius: the kink radii [mm].
        uts: σ_R there [MPa].
        allowed_shear: τ_adm = σ_R / (C_s √3) [MPa].
        shear: τ = T r / J under the torque [MPa].
        safety: τ_adm / τ [–] at each radius (+∞ at r_TR = 0, the unstressed centre of a
            solid section hardened through); the section's is their minimum.
        passed: every safety ≥ 1 (bool; False where a safety is NaN).
        result: code (int32, [`RESULTS`][tripodjax.results.RESULTS]): ``successful``,
            or ``nonfinite`` where an input is outside its domain or not finite inside
            ``jit`` (the safeties are then NaN).
    """

    radius: jax.Array
    uts: jax.Array
    allowed_shear: jax.Array
    shear: jax.Array
    safety: jax.Array
    passed: jax.Array
    result: jax.Array


def static_check(section: Section, material: Material, torque: ArrayLike) -> StaticCheck:
    """Static safety of ``section`` under the torque T [N·m] (> 0) at every kink radius.

    ``torque`` may be an array (e.g. ``[cycles.M_max_forward, cycles.M_max_backward]``):
    the results then carry its shape before the radius axis. See the module docstring.
    """
    check_instance("section", section, Section, "a shaft.Section")
    check_instance("material", material, Material, "a shaft.Material")
    check_positive(torque=torque)
    _check_batch(section, material, torque=torque)
    return _static_check(section, material, torque)


@functools.partial(latency_bound_at_top_level, small_inputs=True)
def _static_check(section, material, torque):
    radius, uts = _kinks(section, material)
    allowed = uts / (jnp.asarray(material.safety)[..., None] * SQRT3)
    J = polar_moment(section)[..., None]
    torque = jnp.asarray(torque)[..., None]
    shear = 1000.0 * torque * radius / J
    # +∞ where no shear: the centre of a solid section hardened through (r_TR = 0), with
    # derivatives 0 there (not ∞ · 0)
    stressed = radius > 0
    safety = jnp.where(stressed, allowed / jnp.where(stressed, shear, 1.0), jnp.inf)
    # a torque ≤ 0 (checked where concrete, here where traced) is outside the check's domain
    ok = _valid(section, material)[..., None] & jnp.isfinite(torque) & (torque > 0)
    safety = _nan_unless(ok, safety)
    return StaticCheck(
        radius=radius,
        uts=uts,
        allowed_shear=allowed,
        shear=_nan_unless(ok, shear),
        safety=safety,
        passed=jnp.all(safety >= 1.0, axis=-1),
        # the section's safety, the least over the kinks, is finite: +∞ at the centre of a
        # solid section hardened through (r_TR = 0, no shear there) is no failure
        result=_code(jnp.min(safety, axis=-1, keepdims=True), axis=-1),
    )


def _code(value, axis):
    """``successful`` where every value along ``axis`` is finite, else ``nonfinite``."""
    finite = jnp.all(jnp.isfinite(value), axis=axis)
    return code_where(finite, RESULTS.successful, RESULTS.nonfinite)


@pytree_dataclass
class FatigueCycles:
    """The fatigue rows of one halfshaft, shape (modes, gears + 1, 4) each (fig. 4.3.7).

    The gear axis holds the forward gears then reverse; the last axis the engine
    conditions (`tripodjax.vehicle.ENGINE_CONDITIONS`), the brake last.

    Attributes:
        torque: the row's torque, the load or the (signed) engine brake [N·m].
        load: the cycle's upper torque [N·m].
        brake: the cycle's lower torque, the signed engine brake [N·m].
        speed: shaft speed ω [rad/s].
        event_rate: p(ω) applied to the row's revolutions [–] (1 where the
            workbook reading counts without it).
        count: cycles n over the required mileage [–].
    """

    torque: jax.Array
    load: jax.Array
    brake: jax.Array
    speed: jax.Array
    event_rate: jax.Array
    count: jax.Array


def fatigue_cycles(
    cycles: LoadCycles,
    modes: DrivingModes,
    event_rate: EventRate | None = None,
    *,
    reading: str = "consistent",
) -> FatigueCycles:
    """The load → engine-brake cycles of fig. 4.3.7 from the vehicle's load cycles.

    ``cycles`` from [`load_cycles`][tripodjax.vehicle.load_cycles] of the same
    ``modes``; ``event_rate`` the p(ω) line (default the workbook's);
    ``reading`` ``"consistent"`` or ``"workbook"`` (see the module docstring).
    Differentiable in every number of the inputs; vmap over them.
    """
    check_instance("cycles", cycles, LoadCycles, "a vehicle.LoadCycles")
    check_instance("modes", modes, DrivingModes, "a vehicle.DrivingModes")
    event_rate = EventRate() if event_rate is None else event_rate
    check_instance("event_rate", event_rate, EventRate, "a shaft.EventRate")
    check_choice("reading", reading, READINGS)
    if np.shape(modes.use) != np.shape(cycles.working_torque):
        raise ValueError(
            f"modes.use has shape {np.shape(modes.use)}; the cycles have "
            f"{np.shape(cycles.working_torque)}: build the cycles from the same modes"
        )
    return _fatigue_cycles(cycles, modes, event_rate, reading == "workbook")


@functools.partial(latency_bound_at_top_level, small_inputs=True, static_argnums=3)
def _fatigue_cycles(cycles, modes, event_rate, workbook):
    use = jnp.asarray(modes.use)
    weight = jnp.asarray(modes.weight)
    drive = jnp.sum(use[..., :3], axis=-1)  # (M, G+1)
    drive_total = jnp.sum(drive, axis=-1, keepdims=True)
    unclaimed = 1.0 - jnp.sum(use, axis=(-2, -1))[..., None]
    spread = jnp.where(drive_total > 0, unclaimed / jnp.where(drive_total > 0, drive_total, 1.0), 0)
    row_use = jnp.concatenate([use[..., :3], (use[..., 3] + drive * spread)[..., None]], axis=-1)
    speed = cycles.shaft_speed * RPM_TO_RAD_S
    rate = event_rate(speed)
    n_gears = use.shape[-2]
    if workbook:  # the 1st gear's engine-brake rows without p(ω)
        first_brake = (jnp.arange(n_gears) == 0)[:, None] & (jnp.arange(4) == 3)[None, :]
        rate = jnp.where(first_brake, 1.0, rate)
    sign = jnp.where(jnp.arange(n_gears) == 0, -1.0, 1.0)  # the sheet's: a reversal in 1st only
    count = weight[:, None, None] * cycles.total_revolutions * row_use * rate
    brake_torque = sign * cycles.working_torque[..., 3] / cycles.shock_factor  # (M, G+1)
    load = jnp.concatenate([cycles.working_torque[..., :3], cycles.working_torque[..., 1:2]], -1)
    brake = jnp.broadcast_to(brake_torque[..., None], load.shape)
    is_brake = jnp.arange(4) == 3
    return FatigueCycles(
        torque=jnp.where(is_brake, brake, load),
        load=load,
        brake=brake,
        speed=speed,
        event_rate=rate,
        count=count,
    )


@pytree_dataclass
class FatigueCheck:
    """The fatigue check of a section at r_o and r_TR (fig. 4.3.7).

    The first axis is the radius (outer, end of the transformed layer); per-row
    fields then have the rows' shape (modes, gears + 1, 4).

    Attributes:
        radius: r_o and r_TR [mm].
        uts: σ_R there [MPa] (at r_o the profile's, below a step where h or t is 0; per
            the reading at r_TR).
        fatigue_limit: σ_f = σ_R / q [MPa].
        shear: τ = T r / J of the row's torque [MPa].
        stress: σ = √3 τ [MPa].
        mean, amplitude: σ_m, σ_a of the row's cycle [MPa].
        ratio: r = σ_a / σ_m [–] (0 for a row without torque: no cycle).
        allowed_amplitude: σ_lim, Goodman on the constant-ratio line at 10⁶ cycles [MPa]
            (σ_f for a row without torque, which does no damage).
        cycles_to_failure: N [–].
        damage_per_row: n / N [–].
        damage: Miner's sum Σ n/N per radius [–].
        passed: damage < 1 at both radii (bool; False where a damage is NaN).
        result: code (int32, [`RESULTS`][tripodjax.results.RESULTS]): ``successful``,
            or ``nonfinite`` where an input is outside its domain or not finite inside
            ``jit`` (the damage is then NaN).
    """

    radius: jax.Array
    uts: jax.Array
    fatigue_limit: jax.Array
    shear: jax.Array
    stress: jax.Array
    mean: jax.Array
    amplitude: jax.Array
    ratio: jax.Array
    allowed_amplitude: jax.Array
    cycles_to_failure: jax.Array
    damage_per_row: jax.Array
    damage: jax.Array
    passed: jax.Array
    result: jax.Array


def fatigue_check(
    section: Section, material: Material, rows: FatigueCycles, *, reading: str = "consistent"
) -> FatigueCheck:
    """Goodman, the semi-log S–N line and Miner's sum of ``section`` under ``rows``.

    ``rows`` from [`fatigue_cycles`][tripodjax.shaft.fatigue_cycles]; ``reading``
    sets σ_R at r_TR (see the module docstring). Scalar section and material
    fields (``vmap`` over sections); differentiable in every number.
    """
    check_instance("section", section, Section, "a shaft.Section")
    check_instance("material", material, Material, "a shaft.Material")
    check_instance("rows", rows, FatigueCycles, "a shaft.FatigueCycles")
    check_choice("reading", reading, READINGS)
    s, m = section, material
    if any(jnp.ndim(x) for x in (*jax.tree.leaves(s), *jax.tree.leaves(m))):
        raise ValueError(
            "fatigue_check takes one section and one material (scalar fields); vmap over several"
        )
    return _fatigue_check(s, m, rows, reading == "workbook")


@functools.partial(latency_bound_at_top_level, small_inputs=True, static_argnums=3)
def _fatigue_check(s, m, rows, workbook):
    r_o = jnp.asarray(s.outer_diameter) / 2.0
    r_tr = r_o - s.hardened_depth - s.transition_depth
    core = jnp.asarray(m.core_uts) * (1.0 + m.depth_drop if workbook else 1.0)
    radius = jnp.stack(jnp.broadcast_arrays(r_o, r_tr))
    # σ_R at r_o is the profile's there, below a step: (1 − Δ) σ_R,s without a hardened depth,
    # the core's without a layer (an unhardened section)
    surface = jnp.asarray(m.surface_uts, core.dtype)
    h, t = jnp.asarray(s.hardened_depth), jnp.asarray(s.transition_depth)
    at_h = surface * (1.0 - m.depth_drop)
    outer = jnp.where(h > 0, surface, jnp.where(t > 0, at_h, core))
    uts = jnp.stack(jnp.broadcast_arrays(outer, core))
    fatigue_limit = uts / m.fatigue_ratio
    per_mm = 1000.0 * SQRT3 * radius / polar_moment(s)  # σ per N·m at each radius

    def at(x):
        return x[:, None, None, None]

    stress = at(per_mm) * rows.torque
    upper, lower = at(per_mm) * rows.load, at(per_mm) * rows.brake
    mean, amplitude = (upper + lower) / 2.0, (upper - lower) / 2.0
    sigma_R, sigma_f = at(uts), at(fatigue_limit)
    # σ_lim = σ_f σ_R σ_a / (σ_R σ_a + σ_f |σ_m|) depends on the cycle's ratio, not on the
    # stress's scale: written with the torques it is the same number, and finite where the
    # stress is 0 (the centre of a solid section hardened through, r_TR = 0) instead of 0/0
    mean_torque, amplitude_torque = (rows.load + rows.brake) / 2.0, (rows.load - rows.brake) / 2.0
    # A row without torque (a gear whose wheel carries none, e.g. a reverse whose load transfer
    # unloads the axle) is no stress cycle and does no damage, where σ_lim would be 0/0; where no
    # row has torque the damage is NaN (below).
    idle = (rows.load == 0) & (rows.brake == 0)
    cycle = jnp.where(idle, 1.0, amplitude_torque)  # σ_lim of a pure alternation there: σ_f
    allowed = sigma_f * sigma_R * cycle / (sigma_R * cycle + sigma_f * jnp.abs(mean_torque))
    log_n = 3.0 + 3.0 * (sigma_R - amplitude) / (sigma_R - allowed)
    n_fail = jnp.power(10.0, log_n)
    per_row = jnp.where(idle, 0.0, rows.count / n_fail)
    damage = jnp.sum(per_row, axis=(1, 2, 3))
    # A section no row loads (a vehicle without torque) is not checked: NaN, not a pass.
    ok = _valid(s, m) & jnp.any(~idle)
    damage = _nan_unless(ok, damage)
    return FatigueCheck(
        radius=radius,
        uts=uts,
        fatigue_limit=fatigue_limit,
        shear=stress / SQRT3,
        stress=stress,
        mean=mean,
        amplitude=amplitude,
        ratio=jnp.broadcast_to(
            jnp.where(idle, 0.0, amplitude_torque / jnp.where(idle, 1.0, mean_torque)), mean.shape
        ),
        allowed_amplitude=_nan_unless(ok, allowed),
        cycles_to_failure=_nan_unless(ok, n_fail),
        damage_per_row=_nan_unless(ok, per_row),
        damage=damage,
        passed=jnp.all(damage < 1.0),
        result=_code(damage, axis=0),
    )
