"""The outboard fixed ball joint ("Fixed FR", seed fig. 4.3.10, second column).

The workbook sizes and gives a life to both joints of a halfshaft by one
method (seed §4.2, §4.3 sheet 8): this module runs the tripod's contact model of
[`tripodjax.hertz`][tripodjax.hertz] and [`tripodjax.life`][tripodjax.life]
with a ball joint's numbers — n balls (6), the pressure angle ε = 45° (the
workbook: "only 45"), the transverse conformity Ψ = 2 R_g/d and the
longitudinal conformity χ_l of its curved tracks (Hertz's dΣρ = 2(2 + χ_q + χ_l),
cos τ = |χ_q − χ_l|/(2 + χ_q + χ_l) with χ_q = −1/Ψ), its allowed pressures P_s,
P_d, P_sd and safety coefficient C_s:

    M(p) = ½(1 + cos γ) n (p / (C_s C_p))³ d² R sin ε cos ζ,

ζ the track's oblique angle (YZ; the tripod's helix angle, 0 in the workbook).
The track inclination in XZ (0 in the workbook, "it can vary") is not modelled:
the seed prints no relation for it.

The life at 0° from the load spectrum (4.2.1–4.2.3) is multiplied by 1 + tol,
the workbook's "tolerance on calculation spread" (15 %: 1547 h → 1779 h); the
working conditions derate it by the same angle law as the tripod's and combine
by Miner's rule on their mileage shares.

Decoded from fig. 4.3.10 (second column): n = 6 (the digit is illegible; 6
gives the printed capacities), P_s = 3750, P_d = 2150, P_sd = 3200 MPa,
C_s = 1.1 on the capacities (1.35 on the suggested size), Ψ = 1.003 (χ_q =
−0.997), χ_l = 0.268, dΣρ = 2.543, μν = 2.540, C_p = 629, PCR/d = 1.65;
d = 18.256 mm, PCR = 29.958 mm → M_s = 6734, M_d = 1269, M_sd = 4183 N·m; static
safety 5.833 forward (M_s / 1154 N·m). Life: 1547 h at 0°, 1779 h with the
tolerance, 202 617 km; static trim 6.0° (the angle is illegible; the workbook
law gives 6.0° from its 140 772 km), shock + 8.0° (as the tripod's), shock −
10.5° (100 128 km); shares 30 / 0 / 0 / 35 / 35 %; combined 117 671 km.

The sheet's 1547 h is not the tripod's 2148 h scaled by (M_d/M_d,tripod)³
(that gives 1282 h, 17 % less): the sheet's rating for a ball joint is not
printed. Here one rating (500 h at 730 rpm) serves both joints. The chain's
reading of 4.2.1–4.2.3 (time shares, the unclaimed revolutions at the mean
speed) gives this joint 1520 h at 0° (−1.7 %). The two readings of its km
(``reading`` of [`joint_life`][tripodjax.outboard.joint_life]):

- ``"consistent"``: km = hours × the time-weighted mean vehicle speed Σ a_i V_i
  (4.2.3), the distance the spectrum's revolutions roll (revolutions × 2π r),
  and the exact μν: 184 266 km at 0° (−9.1 %; 166 250 km, −18.0 %, with the
  table's μν);
- ``"workbook"``: km = hours × the revolution-weighted mean vehicle speed V_ave =
  Σ a_i n_i V_i / Σ a_i n_i ([`revolution_mean_speed`][tripodjax.outboard.revolution_mean_speed];
  the sheet's 113.9 km/h, 115.6 here): 202 143 km at 0° (−0.2 %), every printed
  working condition and the combined life within 0.3 % (the hours' −1.7 % and the
  speed's +1.5 % nearly cancel).

The same conversion puts the tripod's column at +19 %, whose km the chain's own
reading gives within 1.8 %: the sheet's two columns are not computed the same
way (docs/physics.md), and the workbook reading here is the outboard column's.
"""

import dataclasses
import math

import jax
import jax.numpy as jnp
import numpy as np
from jax.typing import ArrayLike

from tripodjax import hertz, life
from tripodjax._checks import (
    Domain,
    check,
    check_choice,
    check_domains,
    check_flag,
    check_instance,
    check_integer,
    check_real,
    check_shapes,
    checked_pytree_dataclass,
    outside_domains,
)
from tripodjax.hertz import _nan_unless
from tripodjax.results import RESULTS, code_where, worst

__all__ = [
    "READINGS",
    "FixedJoint",
    "capacities",
    "check_balls_fit",
    "joint_life",
    "min_ball_diameter",
    "revolution_mean_speed",
    "static_safety",
]


@checked_pytree_dataclass
class FixedJoint:
    """A fixed ball joint's contact geometry, allowed pressures and safety (fig. 4.3.10).

    Attributes:
        d: ball diameter [mm], > 0.
        R: pitch-centre radius PCR [mm], > 0.
        conformity: transverse conformity Ψ = 2 R_g/d [–], ≥ 1.0005 (workbook 1.003–1.005).
        longitudinal_conformity: χ_l [–] in (−1, 1] (workbook 0.268).
        P_s, P_d, P_sd: allowed static, long-lasting and short-lasting dynamic
            pressures [MPa], > 0.
        C_s: safety coefficient on the pressure [–], > 0 (workbook 1.1).
        pressure_angle: ε [rad] in (0, π/2) (π/4, the workbook's 45°; at π/2 the ball
            would touch its track on the pitch circle, the groove as deep as the ball's radius
            in both races: no ball joint).
        oblique_angle: the tracks' oblique angle ζ (YZ) [rad] in [0, π/2) (0).
        tolerance: the tolerance on the life's calculation spread [–], ≥ 0 (0.15).

    Every field a finite number, or a non-empty array, the arrays broadcasting together
    (checked when built from concrete values; traced fields outside their domain give NaN
    and ``outside_validity`` in the functions that use them).
    """

    d: ArrayLike
    R: ArrayLike
    conformity: ArrayLike
    longitudinal_conformity: ArrayLike
    P_s: ArrayLike
    P_d: ArrayLike
    P_sd: ArrayLike
    C_s: ArrayLike
    pressure_angle: ArrayLike = math.pi / 4
    oblique_angle: ArrayLike = 0.0
    tolerance: ArrayLike = 0.15

    def __post_init__(self) -> None:
        fields = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        check_domains(DOMAINS, **{f"FixedJoint.{k}": v for k, v in fields.items()})
        check_shapes({k: np.shape(v) for k, v in fields.items()}, prefix="FixedJoint.")


READINGS = ("consistent", "workbook")
MIN_BALLS = 3
"""The fewest balls of a fixed joint: three hold the inner race on the joint's centre."""
DOMAINS = {
    **{k: hertz.DOMAINS[k] for k in ("d", "R", "P_s", "P_d", "P_sd", "C_s", "conformity")},
    "longitudinal_conformity": hertz.DOMAINS["longitudinal_conformity"],
    # (0, π/2) open: at π/2 the groove would be as deep as the ball's radius (no ball joint)
    "pressure_angle": Domain(0.0, math.pi / 2, low_open=True, high_open=True, unit=" rad"),
    "oblique_angle": hertz.DOMAINS["helix_angle"],
    "tolerance": Domain(0.0),
    "M_max": hertz.DOMAINS["M_max"],
}
"""A fixed joint's fields' domains (and M_max's): one rule for the check of a concrete value
and the flag of a traced one."""


def _balls_fit(d, R, n_balls):
    """The one fit rule: d < 2 R sin(π/n) [mm] (adjacent ball centres more than a ball apart)."""
    return d < 2.0 * R * math.sin(math.pi / n_balls)


def _outside(joint, n_balls, *, tolerance=False, domain_flags=True):
    """Traced: where the joint's finite fields lie outside what its functions' hertz checks do
    not cover: overlapping balls, a pressure angle of π/2 (and with ``tolerance`` its own).
    Without ``domain_flags`` only the balls' fit (a relation between two fields)."""
    d, R = jnp.asarray(joint.d), jnp.asarray(joint.R)
    overlap = jnp.isfinite(d) & jnp.isfinite(R) & ~_balls_fit(d, R, n_balls)
    if not domain_flags:
        return overlap
    fields = {"pressure_angle": joint.pressure_angle}
    if tolerance:
        fields["tolerance"] = joint.tolerance
    return overlap | outside_domains(DOMAINS, **fields)


def _flagged(outside, code):
    """``code``, ``outside_validity`` where ``outside``."""
    return worst(code, code_where(outside, RESULTS.outside_validity, RESULTS.successful))


def _check_n_balls(n_balls, name="n_balls"):
    """The ball count rule: an integer ≥ `MIN_BALLS` (3; not a bool, nor a float such as 6.0)."""
    return check_integer(name, n_balls, minimum=MIN_BALLS)


def check_balls_fit(d, R, n_balls, names=("FixedJoint.d", "FixedJoint.R", "n_balls")):
    """The balls fit on their pitch circle: adjacent centres, 2 R sin(π/n) apart, are more
    than a ball's diameter apart (else neighbours overlap), for concrete ``d`` and ``R`` [mm];
    ``names`` name d, R and the count in the error (the spec gives its keys)."""
    arrays = [check_real(name, value) for name, value in zip(names[:2], (d, R), strict=True)]
    if any(a is None for a in arrays):
        return
    shapes = [a.shape for a in arrays]
    d, R = np.broadcast_arrays(*arrays)
    with np.errstate(over="ignore"):  # a spacing beyond the dtype's range is inf: any d fits
        spacing = 2.0 * R * math.sin(math.pi / n_balls)
        overlap = ~_balls_fit(d, R, n_balls)
    if np.any(overlap):
        i = tuple(int(j) for j in np.argwhere(overlap)[0])
        # each array's own index of the first overlap (a broadcast axis at 0)
        own = [
            [j if n > 1 else 0 for j, n in zip(i[len(i) - len(s) :], s, strict=True)]
            for s in shapes
        ]
        at = [f"[{','.join(map(str, k))}]" if k else "" for k in own]
        raise ValueError(
            f"{names[0]}{at[0]} = {float(d[i])!r} mm is not allowed for {n_balls} balls on "
            f"{names[1]}{at[1]} = {float(R[i])!r} mm: {names[0]} < 2·{names[1]}·sin(π/{names[2]}) "
            f"= {float(spacing[i]):.6g} mm (neighbouring balls would overlap)"
        )


def _common(joint, n_balls):
    _check_n_balls(n_balls)
    return dict(
        conformity=joint.conformity,
        longitudinal_conformity=joint.longitudinal_conformity,
        C_s=joint.C_s,
        n_rollers=n_balls,
        pressure_angle=joint.pressure_angle,
        helix_angle=joint.oblique_angle,
    )


def _check_fit(joint, n_balls):
    """The joint's d and R against its ball count (`check_balls_fit`)."""
    _check_n_balls(n_balls)
    check_balls_fit(joint.d, joint.R, n_balls)


def _table_factor(joint, reading):
    """M_workbook / M_exact = (μν at cos τ truncated to 10⁻³ / exact μν)³ (1 when consistent)."""
    check_choice("reading", reading, READINGS)
    if reading == "consistent":
        return 1.0
    cos_tau = hertz.contact_geometry(joint.conformity, joint.longitudinal_conformity).cos_tau
    table = hertz.mu_nu(jnp.floor(1000.0 * cos_tau) / 1000.0)
    return (table / hertz.mu_nu(cos_tau)) ** 3


def capacities(
    joint: FixedJoint,
    *,
    n_balls: int = 6,
    gamma: ArrayLike = 0.0,
    reading: str = "consistent",
    domain_flags: bool = True,
) -> hertz.Capacities:
    """M_s, M_d, M_sd [N·m] of the joint ([`hertz.capacities`][tripodjax.hertz.capacities]).

    ``n_balls`` an integer ≥ 3 whose balls fit on the pitch circle (d < 2 R sin(π/n_balls),
    `check_balls_fit`); ``gamma`` the working angle [rad] for M_d and
    M_sd; ``reading`` ``"consistent"`` (exact Hertz μν) or ``"workbook"`` (μν
    at cos τ truncated to 10⁻³, the book table's step: the sheet's 2.540 and
    2.650; see the module docstring). The workbook reading is for reproducing the
    sheet: its μν steps with cos τ, so its derivatives hold the table's value fixed.
    ``domain_flags`` as [`hertz.capacities`][tripodjax.hertz.capacities]' (False: no traced
    flags of each field's own domain; the balls' fit, a relation between d and R, stays).
    """
    check_instance("joint", joint, FixedJoint, "an outboard.FixedJoint")
    check_flag("domain_flags", domain_flags)
    _check_fit(joint, n_balls)
    factor = _table_factor(joint, reading)
    exact = hertz.capacities(
        joint.d,
        joint.R,
        P_s=joint.P_s,
        P_d=joint.P_d,
        P_sd=joint.P_sd,
        gamma=gamma,
        **_common(joint, n_balls),
        domain_flags=domain_flags,
    )
    # The balls' fit where d and R are traced (checked above where concrete): NaN and
    # ``outside_validity`` where neighbours would overlap, never a plausible capacity.
    inside = ~_outside(joint, n_balls, domain_flags=domain_flags)
    return dataclasses.replace(
        exact,
        M_s=_nan_unless(inside, exact.M_s * factor),
        M_d=_nan_unless(inside, exact.M_d * factor),
        M_sd=_nan_unless(inside, exact.M_sd * factor),
        C_p=exact.C_p / factor ** (1.0 / 3.0),
        mu_nu=exact.mu_nu * factor ** (1.0 / 3.0),
        result=_flagged(~inside, exact.result),
    )


def static_safety(
    joint: FixedJoint, M_max: ArrayLike, *, n_balls: int = 6, reading: str = "consistent"
) -> jax.Array:
    """S_o = M_s / M_max [–] for the largest working torque M_max [N·m] (> 0), forward or backward.

    Inside ``jit`` a traced M_max ≤ 0 (or a joint outside its domain) gives NaN.
    """
    check_domains(DOMAINS, M_max=M_max)
    M_max = jnp.asarray(M_max)
    safety = capacities(joint, n_balls=n_balls, reading=reading).M_s / M_max
    return _nan_unless(~outside_domains(DOMAINS, M_max=M_max), safety)


def min_ball_diameter(
    joint: FixedJoint,
    M_max: ArrayLike,
    *,
    R_over_d: ArrayLike,
    C_s: ArrayLike,
    n_balls: int = 6,
    reading: str = "consistent",
) -> tuple[jax.Array, jax.Array]:
    """Suggested smallest ball diameter and PCR [mm] for M_max [N·m] (Hertz's cube law).

    [`hertz.min_roller_diameter`][tripodjax.hertz.min_roller_diameter] with
    ``rule="consistent"`` and the joint's P_s and contact geometry; ``C_s`` the
    sizing safety coefficient (the workbook's 1.35), ``R_over_d`` the PCR/d
    (1.65) with room for the balls: R_over_d > 1/(2 sin(π/n_balls)) (1.0 for 6 balls, else
    neighbours would overlap); ``reading`` as [`capacities`][tripodjax.outboard.capacities].
    With the workbook reading it gives the sheet's 12.424 and 20.499 mm within 0.2 %.
    Inside ``jit`` a traced input outside its domain gives NaN.
    """
    check_instance("joint", joint, FixedJoint, "an outboard.FixedJoint")
    common = {**_common(joint, n_balls), "C_s": C_s}
    lowest = 1.0 / (2.0 * math.sin(math.pi / n_balls))
    check(
        "R_over_d",
        R_over_d,
        lambda a: np.isfinite(a) & _balls_fit(1.0, a, n_balls),
        f"R_over_d > 1/(2·sin(π/n_balls)) = {lowest:.6g} for {n_balls} balls (finite; "
        "neighbouring balls would overlap)",
    )
    scale = _table_factor(joint, reading) ** (-1.0 / 3.0)  # d_min ∝ C_p ∝ 1/μν
    d_min, R_min = hertz.min_roller_diameter(M_max, R_over_d=R_over_d, P_s=joint.P_s, **common)
    fits = _balls_fit(1.0, jnp.asarray(R_over_d), n_balls)
    return _nan_unless(fits, d_min * scale), _nan_unless(fits, R_min * scale)


def joint_life(
    joint: FixedJoint,
    spectrum: life.LoadSpectrum,
    conditions: life.WorkingConditions,
    *,
    n_balls: int = 6,
    angle_law: str = "workbook",
    reading: str = "consistent",
    domain_flags: bool = True,
) -> life.Life:
    """The joint's life (hours and km), ×(1 + tol), under the spectrum and its working conditions.

    [`life.joint_life`][tripodjax.life.joint_life] with the joint's numbers (one joint:
    scalar fields; ``vmap`` over several); every life (combined and per condition) is multiplied by 1 + tolerance.
    ``reading``:

    - ``"consistent"`` (default): exact Hertz μν, and km = hours × V_m with
      V_m = Σ a_i V_i the time-weighted mean vehicle speed of 4.2.3 (a_i the
      spectrum's time shares), i.e. the distance the spectrum's revolutions roll
      (revolutions × 2π r for a spectrum built from the vehicle);
    - ``"workbook"``: the sheet's (fig. 4.3.10, second column): μν at cos τ
      truncated to 10⁻³, so every life × (M_d/M_d,exact)³, and km = hours ×
      V_ave with V_ave = Σ a_i n_i V_i / Σ a_i n_i the *revolution*-weighted mean
      vehicle speed (4.2.3 with revolution shares; 115.6 km/h for the workbook's
      vehicle, the sheet prints 113.9). It gives the sheet's km per working
      condition and combined within 0.3 % from the vehicle's inputs; the hours
      stay the chain's (1.7 % under the sheet's 1547 h at 0°). The tripod column of
      the same sheet is not this reading (docs/physics.md).

    ``domain_flags`` as [`capacities`][tripodjax.outboard.capacities]'.
    """
    check_instance("joint", joint, FixedJoint, "an outboard.FixedJoint")
    check_flag("domain_flags", domain_flags)
    _check_fit(joint, n_balls)
    for field in dataclasses.fields(joint):
        shape = jnp.shape(getattr(joint, field.name))
        if shape:
            raise ValueError(
                f"joint.{field.name} has shape {shape}; allowed: one joint (a number in every "
                "field, shape ()): jax.vmap(joint_life) over several"
            )
    table = _table_factor(joint, reading)
    outside = _outside(joint, n_balls, tolerance=True, domain_flags=domain_flags)
    out = life.joint_life(
        joint.d,
        joint.R,
        spectrum,
        conditions,
        P_d=joint.P_d,
        angle_law=angle_law,
        **_common(joint, n_balls),
        domain_flags=domain_flags,
    )
    factor = (1.0 + jnp.asarray(joint.tolerance)) * table**3
    hours = out.hours * factor
    hours_per_condition = out.hours_per_condition * factor
    if reading == "consistent":
        km, km_per_condition = out.km * factor, out.km_per_condition * factor
    else:
        v_ave = revolution_mean_speed(spectrum)
        km = _in_km(hours, out.km, v_ave)
        km_per_condition = _in_km(hours_per_condition, out.km_per_condition, v_ave)
    lives = dict(
        hours=hours,
        km=km,
        hours_per_condition=hours_per_condition,
        km_per_condition=km_per_condition,
    )  # NaN where a traced field lies outside (a negative tolerance, overlapping balls)
    lives = {name: _nan_unless(~outside, value) for name, value in lives.items()}
    return dataclasses.replace(out, **lives, result=_flagged(outside, out.result))


def revolution_mean_speed(spectrum: life.LoadSpectrum) -> jax.Array:
    """V_ave = Σ a_i n_i V_i / Σ a_i n_i [km/h]: the spectrum's revolution-weighted mean vehicle speed.

    The workbook's average speed (fig. 4.3.10: 113.9 km/h; 115.6 for the workbook's
    vehicle), by which ``joint_life(..., reading="workbook")`` converts hours into km:
    4.2.3's V_m = Σ a_i V_i with the revolution shares a_i n_i / Σ a_k n_k in place of
    the time shares a_i. Always ≥ the time-weighted mean where the vehicle speed rises
    with the joint's (95.1 km/h for the same vehicle). A spectrum whose joint never
    turns (Σ a_i n_i = 0) gives the time-weighted mean Σ a_i V_i.
    """
    check_instance("spectrum", spectrum, life.LoadSpectrum, "a life.LoadSpectrum")
    a, n, V = (jnp.asarray(x) for x in (spectrum.share, spectrum.speed, spectrum.vehicle_speed))
    revolutions = jnp.sum(a * n, axis=-1)
    turning = revolutions > 0
    by_revolutions = jnp.sum(a * n * V, axis=-1) / jnp.where(turning, revolutions, 1.0)
    return jnp.where(turning, by_revolutions, jnp.sum(a * V, axis=-1))


def _in_km(hours, km, speed):
    """hours × speed where the life is finite; the chain's km (∞, or NaN) where it is not."""
    finite = jnp.isfinite(hours)
    return jnp.where(finite, jnp.where(finite, hours, 0.0) * speed, km)
