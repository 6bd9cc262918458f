"""Roller friction and the generated axial force, GAF (seed §3.2, the Lee–Polycarpou model).

The empirical fits take the articulation angle γ in **degrees** (μ_sta, μ_avg
and the factor γ/15) and in **radians** in the slip-to-roll ratio
S/R = R_s γ (3.2.5); the API takes γ in rad everywhere and converts inside.
The roller angle θ of the fits is the Lee model's: a roller moves inward for
90° < θ < 270° and outward otherwise (§3.2.5, figure 3.2.7).

    μ_sta = C_s1 + (C_s2 + C_s3 γ°)(1 − exp(−C_s4 T_d))                          (3.2.9)
    μ_avg = μ_sta (1 + (C_s5 μ_slp − C_s6) γ°) + C_s7 μ_slp − C_s8
            + (γ°/15) C_s9 (sin θ − 1)                                          (3.2.10)
    μ_dyn = ±(γ°/15)(C_d1 μ_slp − C_d2)|sin θ| ± μ_S/R   (+ inward, − outward)  (3.2.11)
    μ_S/R = R_s γ μ_slp + (1 − R_s γ) λ                                         (3.2.12)
    μ_GAF,i = sgn(sin(θ_i + 90°)) |μ_dyn(θ_i)|                                  (3.2.14)
    GAF = (2 T_d / (3R)) Σ_i μ_GAF,i                                            (3.2.15)

The factor of 3.2.15 (``factor``): statics gives each roller the normal force
T_d/(3R) (R the pitch-circle radius; [`tripodjax.forces`][tripodjax.forces]
solves it on the exact kinematics), so a friction coefficient μ_i per roller
makes GAF = (T_d/(3R)) Σ_i μ_i: ``factor="statics"``, the default. The printed
2 T_d/(3R) is twice that; it reproduces the seed's example (386.4 N peak,
344.9 N RMS) at γ ≈ 21.8° with R ≈ 57.7 mm, a plausible pitch-circle *diameter*:
3.2.15 reads right with R the diameter. ``factor="printed"`` keeps it, for
reproduction.

Units: torque N·m, R mm (GAF = 1000 T_d Σ μ / (3 R) in N; twice that printed), angles rad.
"""

import dataclasses
import math
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax.typing import ArrayLike

from tripodjax import joint, solvers
from tripodjax._checks import (
    as_array,
    check_broadcast,
    check_choice,
    check_finite,
    check_instance,
    check_non_negative,
    check_not_empty,
    check_one_number,
    check_positive,
    check_working_angle,
    checked_pytree_dataclass,
)
from tripodjax._derivatives import differentiated_by_jacobian
from tripodjax._pytree import pytree_dataclass
from tripodjax.halfshaft import HalfshaftSolution
from tripodjax.kinematics import _check_n_theta, revolution
from tripodjax.layout import Layout, check_layout
from tripodjax.results import RESULTS, code_where, worst

GAF_MODELS = ("printed", "stroke")
FACTORS = ("statics", "printed")
STROKES = ("in", "out")
DEFAULT_STROKE_WIDTH = 0.01  # [–] width of the smooth stroke sign, in units of tan γ · cos θ


@checked_pytree_dataclass
class FrictionParams:
    """Constants of the Lee–Polycarpou friction model (defaults: the seed's, grease A).

    Attributes:
        C_s1 … C_s9: constants of μ_sta and μ_avg (3.2.9, 3.2.10) [–, per degree
            for C_s3, C_s5, C_s6 terms as printed, C_s4 per N·m].
        C_d1, C_d2: constants of μ_dyn (3.2.11) [–].
        R_s: slip-to-roll factor, S/R = R_s γ with γ in rad (3.2.5) [–].
        mu_slp: pure-sliding friction coefficient μ_slp (pin-on-disk) [–].
        lam: rolling resistance λ [–] (see [`rolling_resistance_hysteresis`][tripodjax.friction.rolling_resistance_hysteresis],
            [`rolling_resistance_microslip`][tripodjax.friction.rolling_resistance_microslip]).

    A pytree: every field is differentiable (``jax.grad`` returns a FrictionParams)
    and may be traced (e.g. ``params.replace(lam=x)`` inside ``jit``). Concrete
    fields (Python or NumPy numbers, concrete arrays) are checked at
    construction: each must be a finite real number ≥ 0 (every constant of
    the model is non-negative), or a non-empty array of them (a batch for
    ``jax.vmap``, or for the elementwise [`mu_sta`][tripodjax.friction.mu_sta],
    [`mu_avg`][tripodjax.friction.mu_avg], [`mu_dyn`][tripodjax.friction.mu_dyn]), else
    ``ValueError`` (``TypeError`` for a string, bool or None) naming the field,
    the value and the allowed range. The GAF ([`gaf`][tripodjax.friction.gaf],
    [`gaf_halfshaft`][tripodjax.friction.gaf_halfshaft], the sweep's) takes one number
    per field. Traced fields are not checked; inside ``jit`` a NaN constant gives
    a NaN GAF (``nonfinite``), a negative one a GAF marked ``outside_validity``.
    """

    C_s1: float = 3.86e-2
    C_s2: float = 1.34e-1
    C_s3: float = 4.50e-3
    C_s4: float = 2.35e-2
    C_s5: float = 3.33e-2
    C_s6: float = 1.04e-2
    C_s7: float = 1.00e-1
    C_s8: float = 2.47e-2
    C_s9: float = 4.25e-2
    C_d1: float = 4.00e-1
    C_d2: float = 8.40e-3
    R_s: float = 0.585
    mu_slp: float = 0.06
    lam: float = 0.007

    def __post_init__(self) -> None:
        for name in self.__dataclass_fields__:
            value = getattr(self, name)
            check_non_negative(f"FrictionParams.{name}", value)  # the domain (`_params_outside`)
            check_not_empty(f"FrictionParams.{name}", np.shape(value))
            object.__setattr__(self, name, as_array(value))  # a list: one leaf, an array

    def replace(self, **changes: Any) -> "FrictionParams":
        """A copy with some fields changed, e.g. ``params.replace(mu_slp=0.04)``."""
        fields = {name: getattr(self, name) for name in self.__dataclass_fields__}
        fields.update(changes)
        return FrictionParams(**fields)


def _params_outside(params, dtype):
    """Whether a (traced) field of ``params`` lies outside the domain that
    `FrictionParams` checks at construction: every constant ≥ 0. False for NaN (``nonfinite``)."""
    outside = jnp.asarray(False)
    for name in params.__dataclass_fields__:
        outside = outside | (jnp.asarray(getattr(params, name), dtype) < 0)
    return outside


GREASE_A = FrictionParams(mu_slp=0.06)
"""The seed's grease A: pure-sliding coefficient μ_slp = 0.06 [–], the other constants
`FrictionParams`' defaults (seed §3.2.3)."""
GREASE_B = FrictionParams(mu_slp=0.09)
"""The seed's grease B: μ_slp = 0.09 [–], the other constants as `GREASE_A` (seed §3.2.3)."""
DRY = FrictionParams(mu_slp=0.30)
"""Dry contact: μ_slp = 0.30 [–], the other constants as `GREASE_A` (seed §3.2.3)."""


def _degrees(gamma):
    return gamma * (180.0 / math.pi)


def _arrays(**values):
    """The checked arguments as arrays (a list too), once none is empty (as a Layout's fields)
    and their shapes broadcast together (``ValueError`` naming the arguments' shapes)."""
    for name, value in values.items():
        check_not_empty(name, np.shape(value))
    check_broadcast(**values)
    return tuple(jnp.asarray(value) for value in values.values())


def _check_coefficient_inputs(params, **values):
    """The friction coefficients' arguments (those given): θ finite, γ a working angle, T_d ≥ 0,
    their shapes and the arrays of ``params`` broadcast together. Returns them as arrays."""
    if "theta" in values:
        check_finite("theta", values["theta"], " [rad]")
    check_working_angle("gamma", values["gamma"])
    if "torque" in values:
        check_non_negative("torque", values["torque"], " N·m")
    _check_params(params)
    batched = {
        f"params.{name}": getattr(params, name)
        for name in params.__dataclass_fields__
        if np.ndim(getattr(params, name))
    }
    return _arrays(**values, **batched)[: len(values)]


def mu_sta(gamma: ArrayLike, torque: ArrayLike, params: FrictionParams = GREASE_A) -> jax.Array:
    """Static friction coefficient μ_sta [–] (3.2.9) at articulation γ [rad], 0 ≤ γ < π/2, and
    torque T_d [N·m], ≥ 0."""
    gamma, torque = _check_coefficient_inputs(params, gamma=gamma, torque=torque)
    return _mu_sta(gamma, torque, params)


def _mu_sta(gamma, torque, params):
    g = _degrees(gamma)
    return params.C_s1 + (params.C_s2 + params.C_s3 * g) * (1.0 - jnp.exp(-params.C_s4 * torque))


def mu_avg(
    theta: ArrayLike, gamma: ArrayLike, torque: ArrayLike, params: FrictionParams = GREASE_A
) -> jax.Array:
    """Mean friction coefficient of a roller at its angle θ [rad] (3.2.10); γ [rad] and T_d
    [N·m] as [`mu_sta`][tripodjax.friction.mu_sta]."""
    theta, gamma, torque = _check_coefficient_inputs(
        params, theta=theta, gamma=gamma, torque=torque
    )
    g = _degrees(gamma)
    static = _mu_sta(gamma, torque, params)
    return (
        static * (1.0 + (params.C_s5 * params.mu_slp - params.C_s6) * g)
        + params.C_s7 * params.mu_slp
        - params.C_s8
        + g / 15.0 * params.C_s9 * (jnp.sin(theta) - 1.0)
    )


def mu_slip_to_roll(gamma: ArrayLike, params: FrictionParams = GREASE_A) -> ArrayLike:
    """Combined sliding–rolling coefficient μ_S/R = R_s γ μ_slp + (1 − R_s γ) λ (3.2.12), γ in
    rad, 0 ≤ γ < π/2."""
    (gamma,) = _check_coefficient_inputs(params, gamma=gamma)
    return _mu_slip_to_roll(gamma, params)


def _mu_slip_to_roll(gamma, params):
    slip = params.R_s * gamma
    return slip * params.mu_slp + (1.0 - slip) * params.lam


def mu_dyn(
    theta: ArrayLike, gamma: ArrayLike, params: FrictionParams = GREASE_A, stroke: str = "in"
) -> jax.Array:
    """Dynamic friction coefficient (3.2.11) at roller angle θ [rad] and articulation γ [rad],
    0 ≤ γ < π/2, for the inward (+) or outward (−) stroke."""
    check_choice("stroke", stroke, STROKES)
    theta, gamma = _check_coefficient_inputs(params, theta=theta, gamma=gamma)
    return _mu_dyn(theta, gamma, params, stroke)


def _mu_dyn(theta, gamma, params, stroke):
    sign = 1.0 if stroke == "in" else -1.0
    g = _degrees(gamma)
    return sign * (
        g / 15.0 * (params.C_d1 * params.mu_slp - params.C_d2) * jnp.abs(jnp.sin(theta))
        + _mu_slip_to_roll(gamma, params)
    )


CONTACTS = ("line", "elliptical")


def rolling_resistance_hysteresis(
    a: ArrayLike, rolling_radius: ArrayLike, loss_factor: ArrayLike, contact: str = "elliptical"
) -> ArrayLike:
    """Rolling resistance λ [–] from elastic hysteresis (3.2.6, 3.2.7).

    λ = α · 2a/(3π R) for a line contact, α · 3a/(16 R) for an elliptical one,
    with a the contact half-width in the rolling direction [mm] (e.g.
    ``hertz.roller_contact(...).b``), R the rolling radius [mm] and α the
    hysteresis loss factor [–].
    """
    check_choice("contact", contact, CONTACTS)
    check_positive(rolling_radius=rolling_radius)
    check_non_negative("a", a, " mm")
    check_non_negative("loss_factor", loss_factor)
    a, rolling_radius, loss_factor = _arrays(
        a=a, rolling_radius=rolling_radius, loss_factor=loss_factor
    )
    factor = 2.0 / (3.0 * math.pi) if contact == "line" else 3.0 / 16.0
    return loss_factor * factor * a / rolling_radius


def rolling_resistance_microslip(
    b: ArrayLike, rolling_radius: ArrayLike, mu: ArrayLike
) -> ArrayLike:
    """Rolling resistance λ = 0.08 μ b²/R² [–] from micro-slip (Heathcote, 3.2.8).

    b: half of the larger width of the contact ellipse [mm]; R: rolling
    radius [mm]; μ: sliding friction coefficient [–].
    """
    check_positive(rolling_radius=rolling_radius)
    check_non_negative("b", b, " mm")
    check_non_negative("mu", mu)
    b, rolling_radius, mu = _arrays(b=b, rolling_radius=rolling_radius, mu=mu)
    return 0.08 * mu * (b / rolling_radius) ** 2


def friction_from_trunnion_force(
    F_x: ArrayLike, F_y: ArrayLike, F_z: ArrayLike, theta: ArrayLike, gamma: ArrayLike
) -> jax.Array:
    """Friction coefficient from a triaxial trunnion force measurement (3.2.4).

    μ = [−cos θ sin γ F_x + cos γ F_y + sin θ sin γ F_z]
        / [(sin²θ + cos γ cos²θ) F_x + cos θ sin γ F_y − sin θ cos θ (cos γ − 1) F_z],

    the friction (tangential) over the normal component of the measured force
    (F_x, F_y, F_z) [N, finite] at roller angle θ [rad, finite] and articulation
    γ [rad], 0 ≤ γ < π/2; at γ = 0 it is F_y / F_x. The arguments broadcast
    together. Where the normal component is 0 (no force, or a purely
    tangential one) no coefficient is defined: NaN, not ±inf.
    """
    for name, force in (("F_x", F_x), ("F_y", F_y), ("F_z", F_z)):
        check_finite(name, force, " N")
    check_finite("theta", theta, " [rad]")
    check_working_angle("gamma", gamma)
    F_x, F_y, F_z, theta, gamma = _arrays(F_x=F_x, F_y=F_y, F_z=F_z, theta=theta, gamma=gamma)
    sg, cg, st, ct = jnp.sin(gamma), jnp.cos(gamma), jnp.sin(theta), jnp.cos(theta)
    tangential = -ct * sg * F_x + cg * F_y + st * sg * F_z
    normal = (st**2 + cg * ct**2) * F_x + ct * sg * F_y - st * ct * (cg - 1.0) * F_z
    loaded = normal != 0
    return jnp.where(loaded, tangential / jnp.where(loaded, normal, 1.0), jnp.nan)


def _load_per_roller(torque, R, factor):
    """The normal load of a roller by which 3.2.15 multiplies Σ μ_i [N]: T/(3R), or 2T/(3R) printed."""
    return (2000.0 if factor == "printed" else 1000.0) * torque / (3.0 * R)


def _gaf_from_sum(total, torque, R, width, factor):
    """GAF [N] from Σ_i μ_GAF,i (3.2.15).

    A non-finite R or width (inside jit, where nothing is checked) gives NaN,
    not the 0 that 1/R → 0 or tanh(s/width) → 0 would make of it.
    """
    force = _load_per_roller(torque, R, factor) * total
    return jnp.where(jnp.isfinite(R) & jnp.isfinite(width), force, jnp.nan)


def _printed_sum(theta_i, gamma, params):
    """Σ_i sgn(sin(θ_i + 90°)) |μ_dyn(θ_i)| (3.2.14) of the roller angles θ_i (…, 3), γ (…)."""
    magnitude = jnp.abs(_mu_dyn(theta_i, gamma[..., None], params, "in"))
    return jnp.sum(jnp.sign(jnp.cos(theta_i)) * magnitude, axis=-1)


def _stroke_sum(a, c, gamma, u, params, width):
    """Σ_i tanh(s_i/width) |μ_dyn,i| of the stroke model, s_i = a_i + c, from the small unknowns.

    ``a`` (…, 3): the part of the rollers' stroke rates whose three terms sum
    to zero exactly (Σ_i a_i = 0 analytically; it is not formed); ``c`` (…):
    their common part; ``u`` (…, 3): |sin θ_i|; ``gamma`` (…). At first order
    the three terms cancel (GAF ∝ γ²), so where every |s_i|/width < 1 the sum
    is formed as

        (c Σ m_i + Σ a_i (m_i − |m_0|) + Σ s_i h_i m_i) / width,

    with m_i = |m_0 + d u_i|, m_0 = μ_S/R, d = (γ°/15)(C_d1 μ_slp − C_d2)
    (3.2.11) and tanh x = x (1 + h(x)): every term a product of small
    quantities, no difference of nearly equal ones (float32 keeps it at
    γ ~ 1e-9); elsewhere as Σ tanh(s_i/width) m_i directly.
    """
    gamma = gamma[..., None]
    m0 = _mu_slip_to_roll(gamma, params)
    d = _degrees(gamma) / 15.0 * (params.C_d1 * params.mu_slp - params.C_d2)
    inner = m0 + d * u  # μ_dyn of the inward stroke (3.2.11)
    m = jnp.abs(inner)
    sign0 = jnp.where(m0 >= 0.0, 1.0, -1.0)
    dm = jnp.where(inner * sign0 >= 0.0, sign0 * d * u, m - jnp.abs(m0))  # m_i − |m_0|
    s = a + c[..., None]
    x = s / width
    tanh = jnp.tanh(x)
    x2 = x * x
    series = x2 * (-1.0 / 3.0 + x2 * (2.0 / 15.0 - x2 * (17.0 / 315.0)))  # tanh(x)/x − 1
    small_x = jnp.abs(x) < 1e-2
    h = jnp.where(small_x, series, tanh / jnp.where(small_x, 1.0, x) - 1.0)
    split = (
        c * jnp.sum(m, axis=-1) + jnp.sum(a * dm, axis=-1) + jnp.sum(s * h * m, axis=-1)
    ) / width
    direct = jnp.sum(tanh * m, axis=-1)
    return jnp.where(jnp.max(jnp.abs(x), axis=-1) < 1.0, split, direct)


def _halfshaft_stroke_sum(sol, rates, R, l, gamma0, params, width):
    """`_stroke_sum` over a revolution, from the small unknowns of the kinematics.

    The rollers' stroke rates s_i = −(1/R) dZ_i/dθ (2.6.2) split into a part
    whose three terms sum to zero exactly, a_i = d(tan γ cos ψ_i)/dθ, and a
    common part c = d(tan γ sin²(γ/2) cos 3ψ − c_plunge/R)/dθ of second order;
    |sin θ_i| = |cos ψ_i| (θ_i = ψ_i + 90°).
    """

    offsets = np.asarray(joint.ROLLER_OFFSETS)
    cos_k, sin_k = (jnp.asarray(f(offsets), sol.psi.dtype) for f in (np.cos, np.sin))

    def cos_rollers(psi):  # cos ψ_i = cos(ψ + k·2π/3) from one sine–cosine pair
        c, s = jnp.cos(psi)[..., None], jnp.sin(psi)[..., None]
        return c * cos_k - s * sin_k

    def zero_sum(psi, gamma):  # Σ_i cos ψ_i = 0 for three rollers 120° apart
        return jnp.tan(gamma)[..., None] * cos_rollers(psi)

    def common(psi, delta_gamma):
        gamma, half = gamma0 + delta_gamma, 0.5 * delta_gamma
        plunge = 2.0 * l * jnp.sin(gamma0 + half) * jnp.sin(half)  # l (cos γ0 − cos γ)
        cos_psi = jnp.cos(psi)
        cos_3psi = cos_psi * (4.0 * cos_psi**2 - 3.0)
        return jnp.tan(gamma) * jnp.sin(0.5 * gamma) ** 2 * cos_3psi - plunge / R

    _, a = jax.jvp(zero_sum, (sol.psi, sol.gamma), (rates.psi, rates.gamma))
    _, c = jax.jvp(common, (sol.psi, sol.delta_gamma), (rates.psi, rates.delta_gamma))
    return _stroke_sum(a, c, sol.gamma, jnp.abs(cos_rollers(sol.psi)), params, width)


def _check_model(model, width, factor):
    check_choice("model", model, GAF_MODELS)
    check_positive(width=width)
    check_choice("factor", factor, FACTORS)


def _check_load(torque, R):
    check_non_negative("torque", torque, " N·m")
    check_positive(R=R)


def _check_params(params, name="params"):
    check_instance(name, params, FrictionParams, "a FrictionParams, e.g. friction.GREASE_A")


def _check_one_number(**inputs):
    """The GAF's inputs (its friction constants, width, a halfshaft's torque) one number each:
    an array would line up with the three rollers or the angles, not with a batch."""
    for name, value in inputs.items():
        check_one_number(name, as_array(value), "one number (jax.vmap over the inputs for a batch)")


def gaf(
    theta: ArrayLike,
    gamma: ArrayLike,
    torque: ArrayLike,
    R: ArrayLike,
    params: FrictionParams = GREASE_A,
    model: str = "printed",
    width: float = DEFAULT_STROKE_WIDTH,
    factor: str = "statics",
) -> jax.Array:
    """Generated axial force [N] at roller-1 angle θ [rad] (3.2.14–3.2.15).

    Args:
        theta: angle of roller 1 in the Lee model's convention [rad]; the
            others are at θ + 120° and θ + 240°.
        gamma: articulation angle [rad], 0 ≤ γ < π/2 (constant: the single joint).
        torque: joint torque T_d [N·m], ≥ 0.
        R: track pitch-circle radius [mm], > 0.
        params: [`FrictionParams`][tripodjax.friction.FrictionParams], one number a field.
        model: ``"printed"`` — the seed's 3.2.14–3.2.15 exactly (a ±λ square
            wave survives at γ = 0); ``"stroke"`` — each roller's sign is
            replaced by tanh(s_i / width), where s_i = tan γ · cos θ_i is the
            roller's stroke velocity normalised by R θ̇ (first order, §2.11),
            so GAF → 0 as γ → 0 and derivatives exist everywhere. For
            γ ≫ width the two models differ only where |cos θ_i| < width/tan γ,
            i.e. within about width/tan γ rad of each stroke reversal.
        width: smoothing width of the stroke model [–], one number > 0 (default
            0.01: at γ = 20° the sign ramps over ±1.6° of roller angle).
        factor: ``"statics"`` (default) — GAF = (T_d/(3R)) Σ μ_GAF,i, each
            roller loaded by T_d/(3R) as statics gives; ``"printed"`` — the
            seed's 3.2.15 as printed, 2 T_d/(3R), twice as large (right if its R
            is the pitch-circle diameter; see the module).

    ``theta``, ``gamma``, ``torque`` and ``R`` are numbers or non-empty arrays
    (lists too) that broadcast together. Differentiable w.r.t. γ, torque, R and
    every FrictionParams field. The stroke model's sum is formed from the small
    stroke rates as on the halfshaft, so float32 keeps it at small γ (within
    1e-4 of float64's peak down to γ = 1e-9 rad, its γ-derivative 0 at γ = 0).
    """
    check_finite("theta", theta, " [rad]")
    check_working_angle("gamma", gamma)
    _check_load(torque, R)
    _check_params(params)
    _check_model(model, width, factor)
    _check_one_number(params=params, width=width)
    theta, gamma, torque, R = _arrays(theta=theta, gamma=gamma, torque=torque, R=R)
    theta_i = joint._roller_angles(jnp.asarray(theta, jnp.result_type(theta, gamma, 0.0)))
    gamma = jnp.broadcast_to(jnp.asarray(gamma, theta_i.dtype), theta_i.shape[:-1])
    if model == "printed":
        total = _printed_sum(theta_i, gamma, params)
    else:  # s_i = tan γ cos θ_i: all of it sums to zero over the rollers, no common part
        a = jnp.tan(gamma)[..., None] * jnp.cos(theta_i)
        u = jnp.abs(jnp.sin(theta_i))
        total = _stroke_sum(a, jnp.zeros_like(gamma), gamma, u, params, width)
    return _gaf_from_sum(total, torque, R, width, factor)


def _safe_rms(x, axis=-1):
    """Root mean square with a finite (zero) derivative where it vanishes; NaN stays NaN."""
    mean_square = jnp.mean(x**2, axis=axis)
    positive = mean_square > 0
    # Where not positive the mean square is 0 (value and derivative 0) or NaN (kept).
    return jnp.where(positive, jnp.sqrt(jnp.where(positive, mean_square, 1.0)), mean_square)


def harmonic_amplitude(signal: jax.Array, order_per_sample_period: ArrayLike) -> jax.Array:
    """Amplitude of the harmonic that completes ``order_per_sample_period`` cycles over the samples."""
    n = signal.shape[-1]
    phase = 2.0 * jnp.pi * order_per_sample_period * jnp.arange(n) / n
    c = jnp.sum(signal * jnp.cos(phase), axis=-1)
    s = jnp.sum(signal * jnp.sin(phase), axis=-1)
    return 2.0 / n * jnp.sqrt(c**2 + s**2)


@pytree_dataclass
class GAFResult:
    """Generated axial force of a halfshaft over one revolution.

    Attributes:
        theta: input angles of one period 0 ≤ θ < 2π/3 [rad] (GAF has period 2π/3).
        force: GAF at those angles [N].
        rms: root mean square over a revolution [N].
        peak: largest |GAF| [N].
        third_order: amplitude of the third rotating order [N].
        result: worst [`RESULTS`][tripodjax.results.RESULTS] code of the kinematics over
            the revolution, or ``nonfinite`` where the force is not finite
            (e.g. a NaN torque or friction constant inside ``jit``: the RMS
            is then NaN, never 0), or ``outside_validity`` where a traced
            input lies outside the domain its construction checks (a
            negative torque or friction constant, a width ≤ 0).
    """

    theta: jax.Array
    force: jax.Array
    rms: jax.Array
    peak: jax.Array
    third_order: jax.Array
    result: jax.Array


@dataclasses.dataclass(frozen=True)
class GAFInputs:
    """What a GAF over a revolution needs besides the kinematics, as one object (for [`sweep`][tripodjax.sweep.sweep]).

    Attributes:
        torque: joint torque T_d [N·m], finite and ≥ 0: one number (for every
            layout of a [`sweep`][tripodjax.sweep.sweep]; for a batch of torques,
            ``jax.vmap`` over [`gaf_halfshaft`][tripodjax.friction.gaf_halfshaft]).
        params: [`FrictionParams`][tripodjax.friction.FrictionParams] (default grease A).
        model: ``"stroke"`` (default) or ``"printed"``, see [`gaf`][tripodjax.friction.gaf].
        width: smoothing width of the stroke model [–], one number > 0.
        factor: ``"statics"`` (default) or ``"printed"`` (the seed's 2 T_d/(3R)),
            see [`gaf`][tripodjax.friction.gaf].

    A pytree: ``torque``, ``params`` and ``width`` are leaves (traced,
    differentiable), ``model`` and ``factor`` are static. Checked at construction (the error
    names the field; an array field may be a batch that ``jax.vmap`` maps over, never empty;
    [`sweep`][tripodjax.sweep.sweep] and [`gaf_halfshaft`][tripodjax.friction.gaf_halfshaft]
    take one number a field); JAX's own rebuilding skips the checks.
    """

    torque: ArrayLike
    params: FrictionParams = GREASE_A
    model: str = "stroke"
    width: ArrayLike = DEFAULT_STROKE_WIDTH
    factor: str = "statics"

    def __post_init__(self) -> None:
        check_non_negative("torque", self.torque, " N·m")
        _check_params(self.params)
        _check_model(self.model, self.width, self.factor)
        for name in ("torque", "width"):
            value = getattr(self, name)
            check_not_empty(name, np.shape(value))
            object.__setattr__(self, name, as_array(value))  # a list: one leaf, an array


_GAF_INPUT_KEYS = tuple(jax.tree_util.GetAttrKey(name) for name in ("torque", "params", "width"))


def _flatten_gaf_inputs(g):
    return (g.torque, g.params, g.width), (g.model, g.factor)


def _flatten_gaf_inputs_with_keys(g):
    children, static = _flatten_gaf_inputs(g)
    return tuple(zip(_GAF_INPUT_KEYS, children, strict=True)), static


def _unflatten_gaf_inputs(static, children):
    obj = object.__new__(GAFInputs)  # no checks: JAX rebuilds with tracers and placeholders
    for name, child in zip(("torque", "params", "width"), children, strict=True):
        object.__setattr__(obj, name, child)
    object.__setattr__(obj, "model", static[0])
    object.__setattr__(obj, "factor", static[1])
    return obj


jax.tree_util.register_pytree_with_keys(
    GAFInputs, _flatten_gaf_inputs_with_keys, _unflatten_gaf_inputs, _flatten_gaf_inputs
)


def _inputs_outside(inputs, dtype):
    """Whether a (traced) field of ``inputs`` lies outside the domain that `GAFInputs` and
    `FrictionParams` check at construction: torque ≥ 0, width > 0, every constant ≥ 0.
    False for NaN (``nonfinite``)."""
    torque, width = (jnp.asarray(x, dtype) for x in (inputs.torque, inputs.width))
    return (torque < 0) | (width <= 0) | _params_outside(inputs.params, dtype)


def gaf_from_revolution(
    layout: Layout,
    sol: HalfshaftSolution,
    rates: HalfshaftSolution,
    inputs: GAFInputs,
) -> GAFResult:
    """GAF over a revolution from a halfshaft solution and its θ-rates (see [`gaf_halfshaft`][tripodjax.friction.gaf_halfshaft]).

    ``sol, rates`` come from [`revolution`][tripodjax.kinematics.revolution] with
    ``with_rates=True``; ``inputs``: a [`GAFInputs`][tripodjax.friction.GAFInputs]
    (torque, friction constants, model, width), one number a field. Nothing is
    checked here (it runs inside jit): a field outside its domain makes ``result``
    ``outside_validity``, a NaN one ``nonfinite``.
    """
    torque, params, model, width = inputs.torque, inputs.params, inputs.model, inputs.width
    factor = inputs.factor
    dtype = sol.theta.dtype
    R, l, gamma0 = (jnp.asarray(a, dtype) for a in (layout.R, layout.l, layout.gamma0))
    if model == "printed":
        theta_lee = joint._roller_angles(sol.psi) + 0.5 * jnp.pi
        total = _printed_sum(theta_lee, sol.gamma, params)
    else:
        total = _halfshaft_stroke_sum(sol, rates, R, l, gamma0, params, width)
    force = _gaf_from_sum(total, torque, R, width, factor)
    rms = _safe_rms(force)
    outside = _inputs_outside(inputs, dtype)
    return GAFResult(
        theta=sol.theta,
        force=force,
        rms=rms,
        peak=jnp.max(jnp.abs(force)),
        third_order=harmonic_amplitude(force, 1),
        result=worst(
            jnp.max(sol.result),
            code_where(~jnp.isfinite(rms), RESULTS.nonfinite, RESULTS.successful),
            code_where(outside, RESULTS.outside_validity, RESULTS.successful),
        ),
    )


def gaf_halfshaft(
    layout: Layout,
    torque: ArrayLike,
    params: FrictionParams = GREASE_A,
    n_theta: int = 360,
    model: str = "printed",
    width: float = DEFAULT_STROKE_WIDTH,
    solver: solvers.SolverLike = "newton",
    *,
    fidelity: str | None | solvers._Unset = solvers._UNSET,
    factor: str = "statics",
) -> GAFResult:
    """GAF of a halfshaft over a revolution, from the instantaneous γ(θ) and roller angles.

    The Lee model's roller angle is θ_L,i = ψ_i + 90°: the kinematics measure
    ψ_i from the articulation plane, where a roller is at the end of its
    stroke, the Lee model from mid-stroke. The stroke model's rate is the
    exact s_i = −(1/R) dZ_i/dθ of each roller's axial position (2.6.2, with
    the spider plunge c), by forward-mode AD through the solve; at first
    order it is tan γ cos θ_L,i, as in [`gaf`][tripodjax.friction.gaf]. ``solver`` picks the
    kinematics (a [`tripodjax.solvers`][tripodjax.solvers] object or shorthand, see
    [`kinematic_metrics`][tripodjax.kinematics.kinematic_metrics]); ``result`` carries its status.

    Differentiable w.r.t. the layout (R, l, γ0), the torque and every
    FrictionParams field, with derivatives of the solve from the implicit
    function theorem; a derivative (``jax.grad``, ``jax.jacfwd``) runs one
    program of the values and their Jacobian, compiled once. ``factor``:
    ``"statics"`` (default) or ``"printed"``, see [`gaf`][tripodjax.friction.gaf].

    ``torque``, ``width`` and every field of ``params`` are one number each (for a
    batch, ``jax.vmap`` over them). Inside ``jit`` a traced input outside its
    domain (a negative torque or friction constant, a width ≤ 0) makes
    ``result`` ``outside_validity``, a NaN one ``nonfinite``.
    """
    check_layout(layout, one=True)
    _check_load(torque, layout.R)
    _check_params(params)
    _check_model(model, width, factor)
    _check_one_number(torque=torque, params=params, width=width)
    solver = solvers.resolve_legacy(solver, fidelity)  # fidelity: the older spelling
    n_theta = _check_n_theta(n_theta, orders="the GAF")
    inputs = GAFInputs(torque, params, model, width, factor)
    return _gaf_halfshaft(layout, inputs, n_theta=n_theta, solver=solver)


def _gaf_over_revolution(layout, inputs, *, n_theta, solver):
    sol, rates = revolution(layout, n_theta, solver, with_rates=True)
    return gaf_from_revolution(layout, sol, rates, inputs)


# Derivatives from the Jacobian w.r.t. the layout and the inputs' numbers
# (``tripodjax._derivatives``): an eager ``jax.grad`` compiles one program for latency, where
# reverse mode through the revolution compiled two with XLA's defaults (notebook 02's
# elasticities: 6.3–6.9 → 2.1–2.5 s, 2-core AMD EPYC).
_gaf_halfshaft = differentiated_by_jacobian(_gaf_over_revolution, ("n_theta", "solver"))
