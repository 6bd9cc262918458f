"""Rolling-contact life of a joint: load spectrum, working conditions, Miner's rule (seed §4.2).

Palmgren–Miner over a load spectrum (4.2.1, 4.2.2), with the catalogues' rating
of 500 h at 730 rpm at M = M_d:

    L_h,i = (365000 / n_i) (M_d / M_i)³,    1/L_h = Σ a_i / L_h,i,

and the life in kilometres L_s = L_h · V_m with V_m = Σ a_i V_i (4.2.3). The
shares a_i are shares of the running *time*.

Working conditions (static trim, steering, suspension shock…) each run the
spectrum at an articulation angle γ_j for a share w_j of the mileage and
combine by Miner's rule, 1/L = Σ w_j / L_j. The life at an angle is the life at
0° times a derating g(γ) (``angle_law``):

- ``"workbook"`` (default): g(γ) = exp(−(a γ + b γ²)), γ in rad, with
  a = `WORKBOOK_ANGLE_A`, b = `WORKBOOK_ANGLE_B`. **Fitted to the company
  workbook** (seed fig. 4.3.10, the tripod column): the seed does not print the
  macro's law; this smooth form with g(0) = 1 passes exactly through its two
  readable points, 6.5° → 164 088 km and 12.8° → 99 204 km from 244 574 km at
  0° (error 0 at both by construction). It implies 8.0° for the unreadable
  "shock +" condition (from the combined life; its "P" entry is then 58.2 %,
  printed 58 %), the "P" row 44.7 / 58.2 / 86.3 % (printed 45 / 58 / 86) and the
  combined 129 265 km against the printed 129 277 km (−0.01 %). Outside 0–12.8°
  it is an extrapolation.
- ``"seed"``: the seed's printed factor ½(1 + cos γ) in M_d, i.e.
  g(γ) = (½(1 + cos γ))³ (0.990 at 6.5°, 0.963 at 12.8°): about 1.5× and
  2.4× the workbook's lives there.

Damage shares: condition j takes w_j / L_j of the damage rate 1/L; spectrum case
i takes a_i n_i M_i³ / Σ a_k n_k M_k³ (the same in every condition).

A spectrum that does no damage (every case with zero torque, speed or share)
lives for ever: ``life_hours`` and ``joint_life`` give ``inf`` hours and km with
``result = successful`` and damage shares 0. Units: N·m, rpm, km/h, h, km, rad.
"""

import csv
import functools
import math
import os

import jax
import jax.numpy as jnp
import numpy as np
from jax.typing import ArrayLike

from tripodjax._checks import (
    Domain,
    as_array,
    check_broadcast,
    check_choice,
    check_domains,
    check_flag,
    check_real,
    check_shares,
    check_working_angle,
    checked_pytree_dataclass,
    outside_domains,
    outside_shares,
)
from tripodjax._compile import latency_bound_at_top_level
from tripodjax._pytree import pytree_dataclass
from tripodjax.hertz import DOMAINS as HERTZ_DOMAINS
from tripodjax.hertz import (
    _all_finite,
    _checked,
    _code,
    _conformity_coefficient,
    _finite,
    _nan_unless,
    _torque_at_pressure,
)
from tripodjax.hertz import _outside as _outside_hertz

__all__ = [
    "ANGLE_LAWS",
    "RATING_HOURS_RPM",
    "WORKBOOK_ANGLE_A",
    "WORKBOOK_ANGLE_B",
    "Life",
    "LoadSpectrum",
    "WorkingConditions",
    "angle_factor",
    "joint_life",
    "life_hours",
    "read_spectrum_csv",
    "read_spectrum_rows",
]

RATING_HOURS_RPM = 365_000.0  # 500 h at 730 rpm at M = M_d, the catalogues' rating (4.2.2)
ANGLE_LAWS = ("workbook", "seed")
# g(γ) = exp(−(a γ + b γ²)) through the workbook's 164088/244574 at 6.5° and 99204/244574 at 12.8°.
WORKBOOK_ANGLE_A = 2.9805657453896677  # 1/rad
WORKBOOK_ANGLE_B = 4.738165269969751  # 1/rad²

DOMAINS = {
    "M_d": Domain(0.0, low_open=True),
    "torque": Domain(0.0, unit=" N·m"),
    "speed": Domain(0.0, unit=" rpm"),
    "vehicle_speed": Domain(0.0, unit=" km/h"),
    "angle": HERTZ_DOMAINS["gamma"],  # a working angle, 0 ≤ γ < π/2 rad
}
"""The spectrum's and conditions' domains (one rule for the concrete check and the traced
flag); the shares lie in [0, 1] and, where concrete, sum to 1 (`check_shares`; traced,
`outside_shares` flags a share outside [0, 1]: a derivative moves one share alone)."""


def _angle_factor(gamma, law):
    if law == "seed":
        return (0.5 * (1.0 + jnp.cos(gamma))) ** 3
    return jnp.exp(-(WORKBOOK_ANGLE_A * gamma + WORKBOOK_ANGLE_B * gamma**2))


def angle_factor(gamma: ArrayLike, law: str = "workbook") -> jax.Array:
    """Life at the working angle γ over the life at 0°, g(γ) [–] (g(0) = 1).

    ``law="workbook"``: exp(−(a γ + b γ²)), fitted to the company workbook (see the
    module docstring); ``"seed"``: (½(1 + cos γ))³. γ in [0, π/2) rad, finite.
    """
    check_choice("law", law, ANGLE_LAWS)
    check_working_angle("gamma", gamma)
    return _angle_factor(jnp.asarray(gamma), law)


def _damage_rate(M_d, torque, speed, share):
    """Σ a_i n_i (M_i / M_d)³ / 365000 [1/h] over the last axis, and its per-case terms."""
    M_d = jnp.asarray(M_d)[..., None]
    torque, speed, share = (
        jnp.atleast_1d(jnp.asarray(x, M_d.dtype)) for x in (torque, speed, share)
    )
    terms = share * speed * (torque / M_d) ** 3 / RATING_HOURS_RPM
    return jnp.sum(terms, axis=-1), terms


def _hours(rate):
    """1 / damage rate, ``inf`` for a rate of 0 (no division warning, no NaN gradient)."""
    safe = jnp.where(rate > 0, rate, 1.0)
    return jnp.where(rate > 0, 1.0 / safe, jnp.inf)


def life_hours(M_d: ArrayLike, torque: ArrayLike, speed: ArrayLike, share: ArrayLike) -> jax.Array:
    """Palmgren–Miner life in hours over a load spectrum (4.2.1, 4.2.2).

    L_h,i = (365000 / n_i) (M_d / M_i)³ and 1/L_h = Σ a_i / L_h,i, over the
    last axis of ``torque`` [N·m], ``speed`` n [rpm] and ``share`` a [–];
    ``M_d`` [N·m] may carry leading axes (one life per entry). A case with zero
    torque or speed does no damage; a spectrum that does none lives for ever
    (``inf``). M_d > 0, torque ≥ 0, speed ≥ 0, shares ≥ 0 summing to 1, all
    finite; numbers or non-empty arrays (lists too). Inside ``jit`` a non-finite
    input gives NaN, as does one outside its domain (a negative torque, a share
    outside [0, 1]): this function has no result code.
    """
    check_domains(DOMAINS, M_d=M_d, torque=torque, speed=speed)
    check_broadcast(M_d=M_d)  # not empty
    check_broadcast(torque=torque, speed=speed, share=share)  # the cases, on the last axis
    check_shares("share", share)
    M_d, torque, speed, share = (as_array(x) for x in (M_d, torque, speed, share))
    return _life_hours(M_d, torque, speed, share)


def _spectrum_outside(torque, speed, share, vehicle_speed=0.0):
    """Traced: per spectrum (over the last axis) a case outside its domain or shares off 1."""
    cases = outside_domains(DOMAINS, torque=torque, speed=speed, vehicle_speed=vehicle_speed)
    return jnp.any(jnp.atleast_1d(cases), axis=-1) | outside_shares(share)


@functools.partial(latency_bound_at_top_level, small_inputs=True)
def _life_hours(M_d, torque, speed, share):
    """`life_hours` past its checks: one compiled program."""
    rate, _ = _damage_rate(M_d, torque, speed, share)
    ok = jnp.all(_all_finite(M_d, torque, speed, share))
    outside = outside_domains(DOMAINS, M_d=M_d) | _spectrum_outside(torque, speed, share)
    return _nan_unless(ok & ~outside, _hours(rate))


def _check_vectors(owner, fields):
    """Concrete fields: 1-D, non-empty, of one length."""
    shapes = {}
    for name, value in fields.items():
        if isinstance(value, jax.core.Tracer):
            continue
        shape = np.shape(value)
        if len(shape) != 1 or shape[0] == 0:
            raise ValueError(
                f"{owner}.{name} has shape {shape}; allowed: a non-empty 1-D array "
                "(one entry per case), the same length for every field"
            )
        shapes[name] = shape
    if len(set(shapes.values())) > 1:
        shown = ", ".join(f"{name} {shape}" for name, shape in shapes.items())
        raise ValueError(
            f"{owner} needs fields of one shape (1-D arrays of one length); got {shown}"
        )


@checked_pytree_dataclass
class LoadSpectrum:
    """A load spectrum: each case is a torque applied at a speed for a share of the time.

    Attributes (non-empty 1-D arrays of one length):
        torque: joint torque M_i [N·m], ≥ 0.
        speed: joint speed n_i [rpm], ≥ 0.
        vehicle_speed: vehicle speed V_i [km/h] (for the life in km, 4.2.3), ≥ 0.
        share: share a_i of the running time [–], ≥ 0, summing to 1.

    All finite real numbers; checked when built from concrete values (not
    when JAX rebuilds one, nor for traced fields). Batch spectra with ``vmap``.
    """

    torque: ArrayLike
    speed: ArrayLike
    vehicle_speed: ArrayLike
    share: ArrayLike

    def __post_init__(self) -> None:
        check_domains(
            DOMAINS,
            **{f"LoadSpectrum.{k}": getattr(self, k) for k in ("torque", "speed", "vehicle_speed")},
        )
        check_real("LoadSpectrum.share", self.share)
        _check_vectors(  # the shape before the shares: the share rule is that of one spectrum
            "LoadSpectrum",
            {name: getattr(self, name) for name in ("torque", "speed", "vehicle_speed", "share")},
        )
        check_shares("LoadSpectrum.share", self.share)


@checked_pytree_dataclass
class WorkingConditions:
    """Working conditions of the joint (e.g. static trim, steering ±, shock ±).

    Attributes (non-empty 1-D arrays of one length):
        angle: working articulation angle γ_j [rad], 0 ≤ γ_j < π/2; it derates
            the life by the ``angle_law`` of [`joint_life`][tripodjax.life.joint_life].
        share: share w_j of the mileage spent in the condition [–], ≥ 0,
            summing to 1.

    All finite real numbers; checked when built from concrete values.
    """

    angle: ArrayLike
    share: ArrayLike

    def __post_init__(self) -> None:
        check_domains(DOMAINS, **{"WorkingConditions.angle": self.angle})
        check_real("WorkingConditions.share", self.share)
        _check_vectors("WorkingConditions", {"angle": self.angle, "share": self.share})
        check_shares("WorkingConditions.share", self.share)


@pytree_dataclass
class Life:
    """Rolling-contact life of a joint under a spectrum and working conditions.

    Attributes:
        hours: combined life L_h [h].
        km: combined life in kilometres L_s = L_h · V_m (4.2.3) [km].
        hours_per_condition: life L_h,j if the joint ran in condition j only [h].
        km_per_condition: the same in km [km].
        M_d: long-lasting capacity M_d at 0° [N·m].
        damage_per_condition: share of the damage done in each condition [–] (sums to 1).
        damage_per_case: share of the damage done by each spectrum case [–] (sums to 1).
        result: code (int32, [`RESULTS`][tripodjax.results.RESULTS]), per joint: the κ
            solve's, ``nonfinite`` where an input or the life is NaN, ``outside_validity``
            where a (traced) input lies outside its domain (a negative size or torque,
            an angle ≥ π/2, a share outside [0, 1]; the lives are then NaN; that concrete
            shares sum to 1 is checked at the call). A spectrum that does no damage gives an infinite life, damage
            shares 0 and ``successful``.
    """

    hours: jax.Array
    km: jax.Array
    hours_per_condition: jax.Array
    km_per_condition: jax.Array
    M_d: jax.Array
    damage_per_condition: jax.Array
    damage_per_case: jax.Array
    result: jax.Array


def joint_life(
    d: ArrayLike,
    R: ArrayLike,
    spectrum: LoadSpectrum,
    conditions: WorkingConditions,
    *,
    conformity: ArrayLike,
    P_d: ArrayLike,
    C_s: ArrayLike,
    n_rollers: int = 3,
    pressure_angle: ArrayLike = math.pi / 2,
    helix_angle: ArrayLike = 0.0,
    angle_law: str = "workbook",
    longitudinal_conformity: ArrayLike = 0.0,
    domain_flags: bool = True,
) -> Life:
    """Palmgren–Miner life of a joint in hours and km (4.2.1–4.2.3).

    The capacity M_d at 0° gives the spectrum's life L_h,0 (4.2.2, 4.2.1); in
    condition j it is L_h,0 · g(γ_j) (``angle_law``, see
    [`angle_factor`][tripodjax.life.angle_factor]); the conditions combine by
    Miner's rule on their shares, 1/L_h = Σ w_j / L_h,j, and L_s = L_h · V_m with
    V_m = Σ a_i V_i.

    Args: d, R > 0 [mm]; ``spectrum`` a
    [`LoadSpectrum`][tripodjax.life.LoadSpectrum]; ``conditions`` a
    [`WorkingConditions`][tripodjax.life.WorkingConditions]; conformity Ψ ≥ 1.0005;
    P_d > 0 [MPa]; C_s > 0; n_rollers an integer ≥ 1; angles as
    [`capacities`][tripodjax.hertz.capacities], as is ``longitudinal_conformity``
    (0 for straight tracks; a ball joint's curved tracks); ``angle_law`` ``"workbook"`` or
    ``"seed"``; ``domain_flags`` as [`capacities`][tripodjax.hertz.capacities]' (False: no
    traced domain flags, for a caller that keeps its inputs inside their domains itself).

    Shapes: d, R, conformity, P_d, C_s, n_rollers, the angles and
    ``longitudinal_conformity`` are numbers or non-empty arrays (lists too) that
    broadcast together, one joint per element: ``hours``, ``km``, ``M_d`` and
    ``result`` take their broadcast shape, the per-condition and per-case fields
    one axis more. One spectrum and one set of conditions (1-D fields) serve
    every joint; ``vmap`` over several spectra.

    Inside ``jit`` a non-finite input gives a NaN life and ``result =
    nonfinite``, a finite one outside its domain a NaN life and
    ``outside_validity``. Differentiable w.r.t. d, R, the conformity, P_d and
    every spectrum and condition number.
    """
    arguments = dict(locals())  # the parameters, as given
    check_flag("domain_flags", domain_flags)
    if not isinstance(spectrum, LoadSpectrum):
        raise TypeError(
            f"spectrum = {spectrum!r} ({type(spectrum).__name__}) is not allowed; "
            "allowed: a life.LoadSpectrum"
        )
    if not isinstance(conditions, WorkingConditions):
        raise TypeError(
            f"conditions = {conditions!r} ({type(conditions).__name__}) is not allowed; "
            "allowed: a life.WorkingConditions"
        )
    check_choice("angle_law", angle_law, ANGLE_LAWS)
    joint = {k: v for k, v in arguments.items() if k in HERTZ_DOMAINS}
    return _joint_life(**{**arguments, **dict(zip(joint, _checked(**joint), strict=True))})


@functools.partial(
    latency_bound_at_top_level, small_inputs=True, static_argnames=("angle_law", "domain_flags")
)
def _joint_life(
    d,
    R,
    spectrum,
    conditions,
    conformity,
    P_d,
    C_s,
    n_rollers,
    pressure_angle,
    helix_angle,
    angle_law,
    longitudinal_conformity,
    domain_flags,
):
    """`joint_life` past its checks: one compiled program (its operations one by one compiled
    each on a first call)."""
    joint = {k: v for k, v in locals().items() if k in HERTZ_DOMAINS}
    C_p, _, kappa_code = _conformity_coefficient(conformity, longitudinal_conformity)
    M_d = _torque_at_pressure(P_d, d, R, C_p, C_s, n_rollers, pressure_angle, helix_angle, 0.0)
    rate0, terms = _damage_rate(M_d, spectrum.torque, spectrum.speed, spectrum.share)
    angle, w = jnp.asarray(conditions.angle), jnp.asarray(conditions.share)
    g = _angle_factor(angle, angle_law)
    condition_rate = w * rate0[..., None] / g  # w_j / L_h,j
    rate = jnp.sum(condition_rate, axis=-1)
    mean_speed = jnp.sum(jnp.asarray(spectrum.share) * jnp.asarray(spectrum.vehicle_speed))
    hours0 = _hours(rate0)
    per_condition = hours0[..., None] * g
    damaged = rate > 0
    scale = jnp.where(damaged, rate, 1.0)
    case_total = jnp.sum(terms, axis=-1, keepdims=True)
    # Per joint: finite, and every input inside its domain (checked where concrete).
    finite = _finite(M_d) & _all_finite(
        angle, g, w, spectrum.torque, spectrum.speed, spectrum.share, spectrum.vehicle_speed
    )
    outside = jnp.zeros((), bool)
    if domain_flags:
        outside = (
            _outside_hertz(**joint)
            | _spectrum_outside(
                spectrum.torque, spectrum.speed, spectrum.share, spectrum.vehicle_speed
            )
            | jnp.any(outside_domains(DOMAINS, angle=angle))
            | outside_shares(w)
        )
    ok = finite & ~outside
    each = ok[..., None]  # per condition, per case
    hours = _hours(rate)
    km = jnp.where(damaged, hours * mean_speed, jnp.inf)
    return Life(
        hours=_nan_unless(ok, hours),
        km=_nan_unless(ok, km),
        hours_per_condition=_nan_unless(each, per_condition),
        km_per_condition=_nan_unless(
            each, jnp.where(damaged[..., None], per_condition * mean_speed, jnp.inf)
        ),
        M_d=M_d,
        damage_per_condition=_nan_unless(
            each, jnp.where(damaged[..., None], condition_rate / scale[..., None], 0.0)
        ),
        damage_per_case=_nan_unless(
            each,
            jnp.where(case_total > 0, terms / jnp.where(case_total > 0, case_total, 1.0), 0.0),
        ),
        result=_code(finite, outside, kappa_code),
    )


# --------------------------------------------------------------------------- measured spectra

SPECTRUM_COLUMNS = ("torque_Nm", "speed_rpm", "vehicle_speed_kmh")
SPECTRUM_AMOUNTS = ("revolutions", "hours")


def read_spectrum_rows(path: str | os.PathLike) -> dict[str, list[float]]:
    """The columns of a spectrum CSV as lists: ``torque``, ``speed``, ``vehicle_speed``, ``share``.

    The file (UTF-8, comma-separated, a header row; lines starting with ``#`` are
    comments) has the columns ``torque_Nm``, ``speed_rpm``, ``vehicle_speed_kmh``
    and one of ``revolutions`` or ``hours`` per level, as load-measurement
    software exports. Time shares follow: hours_i / Σ hours, or (revolutions_i /
    n_i) / Σ (revolutions / n). A bad row raises ``ValueError`` naming the file,
    its line and the column.
    """
    try:
        with open(path, encoding="utf-8-sig", newline="") as f:
            lines = [
                (i, line) for i, line in enumerate(f, start=1) if not line.lstrip().startswith("#")
            ]
    except (OSError, UnicodeDecodeError) as error:
        raise ValueError(
            f"cannot read spectrum file {path}: {getattr(error, 'strerror', None) or error}"
        ) from None
    rows = [
        (i, row)
        for i, row in zip((i for i, _ in lines), csv.reader(line for _, line in lines), strict=True)
        if any(c.strip() for c in row)
    ]
    if not rows:
        raise ValueError(
            f"spectrum file {path} is empty; it needs a header row and at least one level"
        )
    header_line, header = rows[0]
    header = [h.strip() for h in header]
    twice = next((h for h in (*SPECTRUM_COLUMNS, *SPECTRUM_AMOUNTS) if header.count(h) > 1), None)
    if twice is not None:
        raise ValueError(
            f"spectrum file {path} line {header_line}: the column {twice} is given twice in the "
            f"header {header}; give each column once"
        )
    amounts = [a for a in SPECTRUM_AMOUNTS if a in header]
    missing = [c for c in SPECTRUM_COLUMNS if c not in header]
    if missing or len(amounts) != 1:
        raise ValueError(
            f"spectrum file {path} line {header_line}: header {header} needs the columns "
            f"{', '.join(SPECTRUM_COLUMNS)} and one of {' or '.join(SPECTRUM_AMOUNTS)}"
        )
    amount = amounts[0]
    index = {name: header.index(name) for name in (*SPECTRUM_COLUMNS, amount)}
    columns: dict[str, list[float]] = {name: [] for name in index}
    for line, row in rows[1:]:
        if len(row) != len(header):
            raise ValueError(
                f"spectrum file {path} line {line}: {len(row)} fields, the header has {len(header)}"
            )
        for name, i in index.items():
            text = row[i].strip()
            try:
                value = float(text)
            except ValueError:
                raise ValueError(
                    f"spectrum file {path} line {line}: {name} = {text!r} is not a number"
                ) from None
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(
                    f"spectrum file {path} line {line}: {name} = {text} is not allowed: a finite number ≥ 0"
                )
            columns[name].append(value)
        if (
            amount == "revolutions"
            and columns["revolutions"][-1] > 0
            and columns["speed_rpm"][-1] == 0
        ):
            raise ValueError(f"spectrum file {path} line {line}: revolutions > 0 at speed_rpm = 0")
    if not columns["torque_Nm"]:
        raise ValueError(f"spectrum file {path} has a header but no levels")
    speed = columns["speed_rpm"]
    if amount == "hours":
        time = columns["hours"]
    else:
        time = [r / n if r > 0 else 0.0 for r, n in zip(columns["revolutions"], speed, strict=True)]
    total = sum(time)
    if not total > 0:
        raise ValueError(
            f"spectrum file {path}: every level has zero {amount}; the shares need a total > 0"
        )
    return {
        "torque": columns["torque_Nm"],
        "speed": speed,
        "vehicle_speed": columns["vehicle_speed_kmh"],
        "share": [t / total for t in time],
    }


def read_spectrum_csv(path: str | os.PathLike) -> LoadSpectrum:
    """A [`LoadSpectrum`][tripodjax.life.LoadSpectrum] from a measured-spectrum CSV.

    See [`read_spectrum_rows`][tripodjax.life.read_spectrum_rows] for the columns;
    bad rows are named by line.
    """
    return LoadSpectrum(**{k: np.asarray(v) for k, v in read_spectrum_rows(path).items()})
