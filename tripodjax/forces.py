"""Forces inside the joint: the rollers' contact forces from quasi-static equilibrium (seed §3.1).

The seed names three disturbances of an articulated tripod (§3.1): the generated
axial force (GAF), the load-to-stroke resistance (LTS) and the complementary
torque. This module computes all three from one quasi-static model on the exact
kinematics that [`tripodjax.halfshaft`][tripodjax.halfshaft] solves, instead of
from the empirical friction of [`tripodjax.friction`][tripodjax.friction].

Geometry, in the fixed frame XYZ (the pot turns by θ about Z; seed §2.3–2.6):
track k lies at θ_k = θ + k·2π/3 with radial and tangential unit vectors e_r,k,
e_t,k; the roller centre is C_k = (R e_r,k, Z_k) with Z_k of 2.6.2 (spider
plunge c included); the trunnion axis is â_k = −(cos ψ_k X' + sin ψ_k Y') with
X', Y' the columns of the direction cosines 2.3.5 at τ = θ − ψ (2.4.21); the
roller centre moves relative to the pot along Z only, at Ż_k = θ̇ dZ_k/dθ, and
relative to its trunnion at d|r_k|/dt (2.6.4).

Assumptions: rigid parts, inertia neglected (seed §3.1); each roller touches
one flank, normal n_k = cos α e_t,k + sin α e_r,k (contact angle α); it spins
freely on its trunnion, so it rolls along t_k = â_k × n_k / |â_k × n_k| and
slides only along b_k = n_k × t_k; the contact point is taken at the roller
centre (the roller radius times the spider's angular velocity relative to the
pot adds a slip of second order in γ, neglected). With the roller's velocity
relative to the pot v_k = (Ż_k + v_p) e_Z (v_p an imposed plunge speed), the
force of the pot on roller k is

    P_k = N_k [n_k − μ σ(v_k·b_k) b_k − λ σ(v_k·t_k) t_k] + Q_k e_r,k,

σ a smooth sign (tanh of the velocity over ``width`` times the reference speed
R|θ̇| + |v_p|, as the stroke model of [`tripodjax.friction`][tripodjax.friction];
the slip's as that of the stroke times tanh(sin β_k / width), β_k the slip angle,
so that the friction saturates beyond a slip-to-roll ratio of about ``width``),
μ the sliding coefficient (``FrictionParams.mu_slp``), λ the rolling resistance
(``FrictionParams.lam``), Q_k the radial reaction of the conforming track. The
unknowns (N_k, Q_k) follow from six linear equations per angle: each roller's
balance along its trunnion, P_k·â_k = μ_t N_k σ(d|r_k|/dt) (μ_t the trunnion
friction), the torque Σ (C_k × P_k)·e_Z = T, and the spider's balance across
the pot axis, Σ P_k·e_X = F_x, Σ P_k·e_Y = F_y (zero by default: the shaft
carries no transverse force). The trunnion equations give Q_k in closed form;
the other three are a 3×3 solve by Cramer's rule: no iteration, differentiable
everywhere, elementwise over angles and layouts.

Out of it: GAF = Σ P_k·e_Z (the axial force of the pot on the spider) at
v_p = 0; the LTS, the axial force that opposes an imposed plunge; the
complementary torque M = Σ C_k × P_k about the pot axis, its components normal
to Z (the bending moment the rollers put on the housing, with the opposite
sign); the friction power. Torque in N·m, lengths in mm, forces in N, moments
in N·m, speeds in rad/s and mm/s, power in W.
"""

import dataclasses
import functools
import math
from collections.abc import Iterable
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax.typing import ArrayLike

from tripodjax import joint, solvers
from tripodjax._checks import (
    check_choice,
    check_finite,
    check_instance,
    check_non_negative,
    check_nonzero,
    check_one_number,
    check_positive,
    check_range,
    check_real,
    checked_pytree_dataclass,
)
from tripodjax._compile import latency_bound_at_top_level
from tripodjax._derivatives import differentiated_by_jacobian
from tripodjax._pytree import pytree_dataclass
from tripodjax.friction import DEFAULT_STROKE_WIDTH, GREASE_A, FrictionParams
from tripodjax.halfshaft import HalfshaftSolution, half_angle_sincos, solve_halfshaft
from tripodjax.kinematics import _check_n_theta, revolution
from tripodjax.layout import Layout, check_layout
from tripodjax.results import RESULTS, code_where, worst

CASES = ("running", "lts")
RUNNING_QUANTITIES = (
    "gaf_rms",
    "gaf_peak",
    "gaf_third_order",
    "gaf_sixth_order",
    "gaf_ninth_order",
    "complementary_torque_steady",
    "complementary_torque_third_order",
    "complementary_torque_sixth_order",
    "roller_load_ratio",
    "friction_power",
)
LTS_QUANTITIES = ("lts_mean", "lts_ripple")
QUANTITIES = RUNNING_QUANTITIES + LTS_QUANTITIES
MAX_CONTACT_ANGLE = 0.5 * math.pi


@checked_pytree_dataclass
class ForceInputs:
    """The load, friction and motion of the force model, as one object.

    Attributes:
        torque: torque T transmitted by the pot about its axis [N·m], ≥ 0.
        params: [`FrictionParams`][tripodjax.friction.FrictionParams]; the force
            model uses ``mu_slp`` (sliding μ at the track) and ``lam`` (rolling
            resistance λ) only.
        mu_trunnion: sliding friction μ_t between roller and trunnion [–], ≥ 0
            (default 0: needle bearings).
        contact_angle: contact angle α of the roller on its flank [rad],
            0 ≤ α < π/2 (0: flat flanks).
        speed: θ̇ of the running case [rad/s], finite, not 0 (GAF, complementary
            torque, roller loads, friction power; only the power depends on its
            size, the forces on its sign).
        plunge_speed: v_p of the LTS test [mm/s], finite, not 0: the spider pushed
            into the pot (> 0, along +Z) or pulled out (< 0).
        lts_speed: θ̇ during the LTS test [rad/s], finite (default 0: the joint
            held still under torque and stroked, the idle case; a speed gives
            the idle case between LTS and GAF).
        width: width of the smooth signs, in units of the reference speed
            R|θ̇| + |v_p| [–], > 0 (default that of the stroke model).
        transverse_x: force of the pot on the spider across the pot axis, along
            the fixed X [N], finite (default 0).
        transverse_y: the same along the fixed Y [N], finite (default 0).

    A pytree: every field is a leaf (traced, differentiable); each is one number
    for one layout (``jax.vmap`` over a batch). Concrete fields are checked at
    construction; the error names the field, the value and the range.
    """

    torque: ArrayLike
    params: FrictionParams = GREASE_A
    mu_trunnion: ArrayLike = 0.0
    contact_angle: ArrayLike = 0.0
    speed: ArrayLike = 100.0
    plunge_speed: ArrayLike = 10.0
    lts_speed: ArrayLike = 0.0
    width: ArrayLike = DEFAULT_STROKE_WIDTH
    transverse_x: ArrayLike = 0.0
    transverse_y: ArrayLike = 0.0

    def __post_init__(self) -> None:
        check_non_negative("torque", self.torque, " N·m")
        check_instance("params", self.params, FrictionParams, "a FrictionParams, e.g. GREASE_A")
        check_non_negative("mu_trunnion", self.mu_trunnion)
        check_range("contact_angle", self.contact_angle, 0.0, MAX_CONTACT_ANGLE, high_open=True)
        check_nonzero("speed", self.speed, " rad/s", "the running case needs a direction")
        check_nonzero("plunge_speed", self.plunge_speed, " mm/s", "the LTS opposes a plunge")
        check_finite("lts_speed", self.lts_speed, " rad/s")
        check_positive(width=self.width)
        check_finite("transverse_x", self.transverse_x, " N")
        check_finite("transverse_y", self.transverse_y, " N")

    def replace(self, **changes: Any) -> "ForceInputs":
        """A copy with some fields changed, e.g. ``inputs.replace(mu_trunnion=0.05)``."""
        fields = {name: getattr(self, name) for name in self.__dataclass_fields__}
        fields.update(changes)
        return ForceInputs(**fields)


@pytree_dataclass
class RollerForces:
    """The force model at each input angle (trailing axis of 3: the rollers).

    Attributes:
        normal: N_k, the normal force of the pot on each roller [N], (..., 3).
        radial: Q_k, the radial reaction of the track [N], (..., 3).
        force: P_k, the whole force of the pot on each roller, fixed frame [N], (..., 3, 3).
        axial: Σ P_k·e_Z, the axial force of the pot on the spider [N], (...).
        moment: Σ C_k × P_k about the pot centre, fixed frame [N·m], (..., 3); its
            X and Y components are the complementary torque, its Z component T.
        power: power dissipated by friction at the tracks and trunnions [W], (...).
        slip: each roller's sliding speed at its track, v_k·b_k [mm/s], (..., 3).
        rolling: each roller's rolling speed, v_k·t_k [mm/s], (..., 3).
        result: [`RESULTS`][tripodjax.results.RESULTS] code at each angle, (...): the
            kinematics' solve, ``nonfinite`` where a force is not finite, and
            ``outside_validity`` where a roller is not pressed onto its track (N_k < 0:
            the rollers lift off, or friction locks the joint) or an input lies outside
            its domain (see [`ForceInputs`][tripodjax.forces.ForceInputs]; checked where
            traced).
    """

    normal: jax.Array
    radial: jax.Array
    force: jax.Array
    axial: jax.Array
    moment: jax.Array
    power: jax.Array
    slip: jax.Array
    rolling: jax.Array
    result: jax.Array


# A roller's quantities have shape (3, ...): the rollers first, then the batch, elementwise
# arithmetic on whole arrays that XLA vectorises along the batch's layouts (neither a trailing
# axis of 3 rollers nor one of 3 components would be). Its vectors are in its track's frame
# (e_r,k, e_t,k, e_Z), where the trunnion axis and the contact directions are a few products of
# cos ψ_k, sin ψ_k and γ (``_contact``); the 3 × 3 solve's columns are tuples of their entries.


def _cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _each_roller(cos, sin):
    """cos and sin of angle + k·2π/3 (2.4.7), (3, ...), from those of ``angle`` alone."""
    offsets = np.asarray(joint.ROLLER_OFFSETS, np.float64).reshape((3,) + (1,) * jnp.ndim(cos))
    cos_k, sin_k = (jnp.asarray(f(offsets), cos.dtype) for f in (np.cos, np.sin))
    return cos * cos_k - sin * sin_k, sin * cos_k + cos * sin_k


def _angles(cos_theta, sin_theta, delta, delta_gamma):
    """(cos θ, sin θ, cos Δ, sin Δ, cos h, sin h), h = (γ − γ0)/2, from cos θ, sin θ, Δ, γ − γ0.

    The small angles' by polynomials (``half_angle_sincos``: exact to roundoff, NaN beyond |Δ|,
    |γ − γ0| = 2 rad): a transcendental costs ten times the arithmetic on a CPU.
    """
    s, c = half_angle_sincos(jnp, 0.5 * delta)
    sin_h, cos_h = half_angle_sincos(jnp, 0.5 * delta_gamma)
    return cos_theta, sin_theta, 1.0 - 2.0 * s * s, 2.0 * s * c, cos_h, sin_h


def _angles_and_rates(cos_theta, sin_theta, delta, delta_gamma, d_delta, d_delta_gamma):
    """``_angles`` and their θ-derivatives, from dΔ/dθ and d(γ − γ0)/dθ."""
    tangents = (-sin_theta, cos_theta, d_delta, d_delta_gamma)
    return jax.jvp(_angles, (cos_theta, sin_theta, delta, delta_gamma), tangents)


def _layout_angles(gamma0):
    """(sin γ0, cos γ0, sin γ0/2, cos γ0/2) by polynomials (``half_angle_sincos``)."""
    sin_h0, cos_h0 = half_angle_sincos(jnp, 0.5 * gamma0)
    return 2.0 * sin_h0 * cos_h0, 1.0 - 2.0 * sin_h0 * sin_h0, sin_h0, cos_h0


def _pose(R, l, layout_angles, cos_theta, sin_theta, cos_t, sin_t, cos_h, sin_h):
    """The spider's pose at an angle, from ``_angles``: (cos ψ, sin ψ), (sin γ, 1 − cos γ), the
    roller centres' Z_k = P + Q cos ψ_k as (P, Q), and the eccentricity e.

    Arithmetic only: ψ = θ − Δ and γ = γ0 + 2h by the angle sums; γ0's from ``_layout_angles``.
    """
    sin_g0, cos_g0, sin_h0, cos_h0 = layout_angles
    sin_dg, cos_dg = 2.0 * sin_h * cos_h, 1.0 - 2.0 * sin_h * sin_h
    cos_psi = cos_theta * cos_t + sin_theta * sin_t  # ψ = θ − Δ
    sin_psi = sin_theta * cos_t - cos_theta * sin_t
    cos_g = cos_g0 * cos_dg - sin_g0 * sin_dg
    sin_g = sin_g0 * cos_dg + cos_g0 * sin_dg
    sin_half_g = sin_h0 * cos_h + cos_h0 * sin_h  # γ/2 = γ0/2 + h
    versine = 2.0 * sin_half_g * sin_half_g  # 1 − cos γ
    # Z_k = c − (R/2) tan γ (2 cos ψ_k + (1 − cos γ) cos 3ψ) (2.6.2, as joint.roller_centres;
    # cos 3ψ_k = cos 3ψ = 4 cos³ψ − 3 cos ψ), c = l (cos γ0 − cos γ) = 2 l sin(γ0 + h) sin h.
    secant = 1.0 / cos_g  # one division: XLA forms each in a pass of its own
    tan_g = sin_g * secant
    plunge = 2.0 * l * (sin_g0 * cos_h + cos_g0 * sin_h) * sin_h
    z_common = versine * cos_psi * (4.0 * cos_psi * cos_psi - 3.0)
    centres = (plunge - 0.5 * R * tan_g * z_common, -R * tan_g)
    # e = R sin²(γ/2)/cos γ (joint.eccentricity).
    return (cos_psi, sin_psi), (sin_g, versine), centres, 0.5 * R * versine * secant


def _pose_and_rates(R, l, layout_angles, angles, rates):
    """(cos θ, sin θ), ``_pose`` and its θ-derivative, from ``_angles_and_rates``."""
    pose = functools.partial(_pose, R, l, layout_angles)
    return angles[:2], *jax.jvp(pose, angles, rates)


def _smooth_sign(x, scale):
    """σ(x) = tanh(x · scale), ``scale`` = 1/width (of a speed: 1/(width · reference speed)), one
    number a layout: a multiplication, where a division by the width would cost one an element."""
    return jnp.tanh(x * scale)


def _kinematics(track_angle, pose, rates):
    """Per roller, from ``_pose_and_rates``: the track angle's (cos θ_k, sin θ_k), the trunnion's
    (cos ψ_k, sin ψ_k), (sin γ, 1 − cos γ), Z_k and the θ-rates dZ_k/dθ, d|r_k|/dθ.

    |r_k| = R + e (1 + 2 cos 2ψ_k) = R + e (4 cos²ψ_k − 1) (joint.roller_radial_distance).
    """
    (cos_psi, sin_psi), tilt, (p, q), e = pose
    (d_cos_psi, d_sin_psi), _, (d_p, d_q), d_e = rates
    cos_k, sin_k = _each_roller(cos_psi, sin_psi)
    d_cos_k = _each_roller(d_cos_psi, d_sin_psi)[0]  # the rotation by k·2π/3 is linear
    z = p + q * cos_k
    d_z = d_p + d_q * cos_k + q * d_cos_k
    d_distance = d_e * (4.0 * cos_k * cos_k - 1.0) + 8.0 * e * cos_k * d_cos_k
    return _each_roller(*track_angle), (cos_k, sin_k), tilt, z, d_z, d_distance


def _contact(kinematics, inputs):
    """Each roller's contact, from ``_kinematics``: its trunnion axis and rolling and sliding
    directions in the track's frame (e_r,k, e_t,k, e_Z), as far as the force model uses them.

    â_k = −(cos ψ_k X' + sin ψ_k Y'), X' = (−cos γ cos Δ, −cos γ sin Δ, sin γ), Y' = (sin Δ,
    −cos Δ, 0) the columns of the direction cosines 2.3.5 at τ = Δ; with θ_k − ψ_k = Δ its
    components are â·e_r = 1 − (1 − cos γ) cos²ψ_k, â·e_t = (1 − cos γ) cos ψ_k sin ψ_k and
    â·e_Z = −sin γ cos ψ_k. With n = sin α e_r + cos α e_t, â × n = (−â_Z cos α, â_Z sin α, w),
    w = â_r cos α − â_t sin α: t_k = (â × n)/|â × n| and b_k = n × t_k = (w cos α, −w sin α,
    â_Z)/|â × n| (n × (â × n) = â − (â·n) n).
    """
    _, (cos_k, sin_k), (sin_g, versine), _, _, _ = kinematics
    alpha, width = (jnp.asarray(x, cos_k.dtype) for x in (inputs.contact_angle, inputs.width))
    cos_a, sin_a = jnp.cos(alpha), jnp.sin(alpha)
    a_r = 1.0 - versine * cos_k * cos_k
    a_t = versine * cos_k * sin_k
    a_z = -sin_g * cos_k
    w = a_r * cos_a - a_t * sin_a
    length = jnp.sqrt(a_z * a_z + w * w)  # |â × n|
    t_z, b_z = w / length, a_z / length
    along = a_r * sin_a + a_t * cos_a  # â·n
    # e_Z lies in the tangent plane (e_Z ⊥ n_k): v_k = (Ż_k + v_p)(cos β t_k + sin β b_k), β the
    # slip angle, sin β = b_Z. The slip's sign is the stroke's times sin β's, each smoothed over
    # the width: the friction saturates beyond a slip-to-roll ratio of about the width, at any
    # stroke speed.
    sign_angle = _smooth_sign(b_z, 1.0 / width)
    return (cos_a, sin_a), a_r, along, length, (t_z, b_z), sign_angle


def _solve(R, kinematics, contact, inputs, speed, plunge):
    """The force model at every angle of ``kinematics`` (``_kinematics``) for θ̇ = speed, v_p = plunge.

    The rollers on the leading axis of every ``RollerForces`` field; ``contact`` from ``_contact``.
    """
    (cos_k, sin_k), _, _, z, stroke_rate, distance_rate = kinematics
    (cos_a, sin_a), a_r, along, length, (t_z, b_z), sign_angle = contact
    dtype = cos_k.dtype
    speed, plunge = (jnp.asarray(x, dtype) for x in (speed, plunge))
    mu, lam, mu_t = (
        jnp.asarray(x, dtype) for x in (inputs.params.mu_slp, inputs.params.lam, inputs.mu_trunnion)
    )
    width = jnp.asarray(inputs.width, dtype)
    reference = R * jnp.abs(speed) + jnp.abs(plunge)
    inverse = jnp.where(reference > 0, 1.0 / jnp.where(reference > 0, reference, 1.0), 0.0)
    scale = inverse / width
    axial_speed = stroke_rate * speed + plunge  # Ż_k + v_p [mm/s]
    trunnion_speed = distance_rate * speed  # d|r_k|/dt [mm/s]
    rolling = axial_speed * t_z  # v_k·t_k
    slip = axial_speed * b_z  # v_k·b_k
    sliding = mu * _smooth_sign(axial_speed, scale) * sign_angle  # μ σ(v_k·b_k)
    resisting = lam * _smooth_sign(rolling, scale)  # λ σ(v_k·t_k)
    trunnion = mu_t * _smooth_sign(trunnion_speed, scale)  # μ_t σ(ṙ_k)
    # P_k / N_k = n − μσ b − λσ t + (Q_k / N_k) e_r in the track's frame (``_contact``).
    q = sliding * t_z - resisting * b_z
    g_t = cos_a + sin_a * q
    g_z = -(sliding * b_z + resisting * t_z)
    # Roller balance along its trunnion: P_k·â_k = μ_t N_k σ(ṙ_k), with t·â = 0 and b·â = |â × n|,
    # gives Q_k = −κ_k N_k.
    kappa = (along - sliding * length - trunnion) / a_r
    g_r = sin_a - cos_a * q - kappa
    g_x, g_y = g_r * cos_k - g_t * sin_k, g_r * sin_k + g_t * cos_k  # P_k = N_k g_k
    # Torque about Z (N·mm) and the spider's balance across Z: three equations in N_k, whose
    # column k is roller k's (R g_k·e_t,k, g_k,x, g_k,y).
    torque_arm = R * g_t
    columns = tuple((torque_arm[k], g_x[k], g_y[k]) for k in range(3))
    shape = cos_k.shape[1:]
    rhs = tuple(
        jnp.broadcast_to(jnp.asarray(value, dtype), shape)
        for value in (1000.0 * inputs.torque, inputs.transverse_x, inputs.transverse_y)
    )
    # Behind a barrier, XLA forms each roller's N_k once: else, for a max over the rollers, it
    # fuses the solve into the reduction and forms every column again for each roller
    # (roller_load_ratio alone 2.2× as costly, measured).
    normal = jax.lax.optimization_barrier(jnp.stack(_cramer(columns, rhs)))

    def total(x):  # Σ_k N_k x_k
        return jnp.sum(normal * x, axis=0)

    # C_k × P_k, C_k = R e_r + Z_k e_Z: N_k (−Z_k g_t e_r + (Z_k g_r − R g_z) e_t + R g_t e_Z).
    m_r, m_t = -z * g_t, z * g_r - R * g_z
    moment = tuple(
        total(m) / 1000.0
        for m in (m_r * cos_k - m_t * sin_k, m_r * sin_k + m_t * cos_k, torque_arm)
    )
    loss = sliding * slip + resisting * rolling + trunnion * trunnion_speed
    finite = jnp.all(jnp.isfinite(normal), axis=0)
    lifted = jnp.any(normal < 0, axis=0)
    return RollerForces(
        normal=normal,
        radial=-kappa * normal,
        force=jnp.stack([normal * g for g in (g_x, g_y, g_z)], axis=-1),
        axial=total(g_z),
        moment=jnp.stack(moment, axis=-1),
        power=total(loss) / 1000.0,
        slip=slip,
        rolling=rolling,
        result=worst(
            code_where(lifted, RESULTS.outside_validity, RESULTS.successful),
            code_where(~finite, RESULTS.nonfinite, RESULTS.successful),
        ),
    )


def _cramer(columns, rhs):
    """x of a x = b by Cramer's rule, elementwise: ``columns`` the matrix's three columns (one per
    unknown, a roller), each a tuple of the three equations' coefficients; ``rhs`` the right side."""
    c0, c1, c2 = columns
    cross12, cross20, cross01 = _cross(c1, c2), _cross(c2, c0), _cross(c0, c1)
    det = _dot(c0, cross12)
    return tuple(_dot(rhs, c) / det for c in (cross12, cross20, cross01))


def _case_motion(inputs, case):
    if case == "running":
        return inputs.speed, 0.0
    return inputs.lts_speed, inputs.plunge_speed


def _check_inputs(inputs, *, one_number=True):
    check_instance("inputs", inputs, ForceInputs, "a ForceInputs, e.g. ForceInputs(torque=500.0)")
    if one_number:
        allowed = "one number (jax.vmap over the layouts and the inputs for a batch)"
        check_one_number("inputs", inputs, allowed)


def _outside_domain(inputs, cases, dtype):
    """Whether a field of ``inputs`` the ``cases`` use lies outside its domain (the ranges
    `ForceInputs` checks where its fields are concrete; here, where they are traced)."""
    value = {
        name: jnp.asarray(getattr(inputs, name), dtype)
        for name in ("torque", "mu_trunnion", "contact_angle", "width")
    }
    mu, lam = (jnp.asarray(x, dtype) for x in (inputs.params.mu_slp, inputs.params.lam))
    # Comparisons false for NaN: a NaN input is ``nonfinite``, not outside the domain.
    outside = (
        (value["torque"] < 0)
        | (value["mu_trunnion"] < 0)
        | (value["contact_angle"] < 0)
        | (value["contact_angle"] >= MAX_CONTACT_ANGLE)
        | (value["width"] <= 0)
        | (mu < 0)
        | (lam < 0)
    )
    for case in cases:
        speed, plunge = _case_motion(inputs, case)
        moving = speed if case == "running" else plunge
        outside |= jnp.asarray(moving, dtype) == 0
    return outside


def roller_forces(
    layout: Layout,
    theta: ArrayLike,
    inputs: ForceInputs,
    solver: solvers.SolverLike = "newton",
    *,
    case: str = "running",
) -> RollerForces:
    """The force model at input angles ``theta`` [rad] of a halfshaft (see the module).

    Args:
        layout: a [`Layout`][tripodjax.layout.Layout] (scalar fields, or fields that
            broadcast against ``theta``).
        theta: input angles θ [rad], any shape.
        inputs: [`ForceInputs`][tripodjax.forces.ForceInputs].
        solver: the kinematics' level (see [`tripodjax.solvers`][tripodjax.solvers]).
        case: ``"running"`` — θ̇ = ``inputs.speed``, no plunge (GAF); ``"lts"`` —
            θ̇ = ``inputs.lts_speed``, v_p = ``inputs.plunge_speed``.

    The kinematics and their θ-rates come from
    [`solve_halfshaft`][tripodjax.halfshaft.solve_halfshaft] (forward mode through the
    solve, implicit for Newton). Differentiable w.r.t. the layout and every input.
    """
    check_layout(layout)
    check_real("theta", theta)
    theta = jnp.asarray(theta)
    fields = (layout.R, layout.l, layout.gamma0)
    shapes = {"layout": jnp.broadcast_shapes(*(jnp.shape(f) for f in fields)), "theta": theta.shape}
    try:
        jnp.broadcast_shapes(*shapes.values())
    except ValueError:
        raise ValueError(
            f"the layout's fields (shape {shapes['layout']}) and theta (shape {shapes['theta']}) "
            "do not broadcast together; allowed: a layout of one halfshaft (scalar fields) with "
            "any theta, or fields that broadcast against theta"
        ) from None
    _check_inputs(inputs)
    check_choice("case", case, CASES)
    return _roller_forces(layout, theta, inputs, solver=solvers.resolve(solver), case=case)


@functools.partial(
    latency_bound_at_top_level, small_inputs=True, static_argnames=("solver", "case")
)
def _roller_forces(layout, theta, inputs, *, solver, case):
    dtype = jnp.result_type(layout.R, layout.l, layout.gamma0, theta, 0.0)
    fields = [jnp.asarray(a, dtype) for a in (layout.R, layout.l, layout.gamma0, theta)]
    shape = jnp.broadcast_shapes(*(a.shape for a in fields))
    flat = [jnp.broadcast_to(a, shape).reshape(-1) for a in fields]
    outside = code_where(
        _outside_domain(inputs, (case,), dtype), RESULTS.outside_validity, RESULTS.successful
    )

    def at(R, l, gamma0, t):  # one layout at one angle: the layout's fields may vary with θ
        sol, rates = jax.jvp(
            lambda u: solve_halfshaft(Layout(R, l, gamma0), u, solver), (t,), (jnp.ones_like(t),)
        )
        angles = _angles_and_rates(
            jnp.cos(t), jnp.sin(t), sol.delta, sol.delta_gamma, rates.delta, rates.delta_gamma
        )
        kinematics = _kinematics(*_pose_and_rates(R, l, _layout_angles(gamma0), *angles))
        contact = _contact(kinematics, inputs)
        f = _solve(R, kinematics, contact, inputs, *_case_motion(inputs, case))
        return dataclasses.replace(f, result=worst(f.result, sol.result, outside))

    out = jax.vmap(at)(*flat)
    return jax.tree_util.tree_map(lambda x: x.reshape(shape + x.shape[1:]), out)


def _rollers_last(f):
    """``RollerForces`` from ``_solve`` (the rollers on the leading axis) with the rollers last."""
    return dataclasses.replace(
        f,
        normal=jnp.moveaxis(f.normal, 0, -1),
        radial=jnp.moveaxis(f.radial, 0, -1),
        force=jnp.moveaxis(f.force, 0, -2),
        slip=jnp.moveaxis(f.slip, 0, -1),
        rolling=jnp.moveaxis(f.rolling, 0, -1),
    )


def _series(case, f, checked):
    """The series over the angles a case's quantities use, from its ``RollerForces`` at an angle;
    with ``checked`` its result codes too."""
    series = {"axial": f.axial, **({"result": f.result} if checked else {})}
    if case == "lts":
        return series
    return {
        **series,
        "moment_x": f.moment[..., 0],
        "moment_y": f.moment[..., 1],
        "normal_max": jnp.max(f.normal, 0),
        "power": f.power,
    }


def _over_angles(R, l, gamma0, sol, rates, inputs, cases, full, checked):
    """For each named case: its ``_series`` at every angle of ``sol`` (last axis; with ``checked``
    the codes too), and with ``full`` its ``RollerForces`` (else None); one angle at a time.

    A loop over the angles, each step the whole batch at one angle: its few dozen intermediate
    arrays stay in the CPU's cache, where over every angle at once XLA writes each to memory. The
    steps return only the series the quantities use (the per-angle ``RollerForces`` with
    ``full``): stacking every roller's forces costs more. The spider's pose and its θ-rates come
    from a first loop: XLA fuses a chain of arithmetic into each of its consumers, and the pose's
    feeds most of the second loop's fused passes, each on 3 rollers (measured, every force
    quantity of 20 000 layouts × 360 angles at newton, 2-core AMD EPYC: 12 % less CPU time than
    the pose computed in the one loop).
    """
    batch = sol.theta.ndim - 1
    # The angles' sines and cosines before the loop, at every angle at once: computed once (in
    # the loop XLA would evaluate them again in each of its fusions: 36 times, measured).
    angles = _angles_and_rates(
        jnp.cos(sol.theta),
        jnp.sin(sol.theta),
        sol.delta,
        sol.delta_gamma,
        rates.delta,
        rates.delta_gamma,
    )
    angles = jax.tree_util.tree_map(lambda x: jnp.moveaxis(x, -1, 0), angles)
    layout_angles = _layout_angles(gamma0)  # loop invariants, computed once

    def pose_at(carry, x):  # the pose stored for each angle, computed once
        return carry, _pose_and_rates(R, l, layout_angles, *x)

    _, poses = jax.lax.scan(pose_at, None, angles)

    def at_angle(carry, pose):
        kinematics = _kinematics(*pose)
        contact = _contact(kinematics, inputs)
        out = {}
        for case in cases:
            f = _solve(R, kinematics, contact, inputs, *_case_motion(inputs, case))
            out[case] = (_series(case, f, checked), _rollers_last(f) if full else None)
        return carry, out

    _, out = jax.lax.scan(at_angle, None, poses)
    return jax.tree_util.tree_map(lambda x: jnp.moveaxis(x, 0, batch), out)


def _safe_sqrt(x):
    """√x with a zero (not NaN) derivative where x = 0; NaN stays NaN."""
    positive = x > 0
    return jnp.where(positive, jnp.sqrt(jnp.where(positive, x, 1.0)), x)


def _harmonic(signal, order):
    """(cosine, sine) amplitudes of the harmonic of ``order`` cycles over the samples (last axis)."""
    n = signal.shape[-1]
    phase = 2.0 * np.pi * order * np.arange(n) / n
    cos, sin = (jnp.asarray(f(phase), signal.dtype) for f in (np.cos, np.sin))
    return 2.0 / n * jnp.sum(signal * cos, -1), 2.0 / n * jnp.sum(signal * sin, -1)


def _amplitude(*signals, order):
    """Amplitude of a harmonic of one signal, or of a vector of signals (the norm of theirs)."""
    return _safe_sqrt(sum(c * c + s * s for x in signals for c, s in [_harmonic(x, order)]))


def _running_quantity(name, f, torque, R):
    """A running-case quantity over one period (every quantity has period 2π/3 in θ)."""
    gaf, mx, my = f["axial"], f["moment_x"], f["moment_y"]
    if name == "gaf_rms":
        return _safe_sqrt(jnp.mean(gaf * gaf, -1))
    if name == "gaf_peak":
        return jnp.max(jnp.abs(gaf), -1)
    orders = {"third": 1, "sixth": 2, "ninth": 3}  # harmonics of the period: orders 3, 6, 9
    if name.startswith("gaf_"):
        return _amplitude(gaf, order=orders[name.split("_")[1]])
    if name == "complementary_torque_steady":
        return _safe_sqrt(jnp.mean(mx, -1) ** 2 + jnp.mean(my, -1) ** 2)
    if name.startswith("complementary_torque_"):
        return _amplitude(mx, my, order=orders[name.split("_")[2]])
    if name == "roller_load_ratio":
        nominal = 1000.0 * torque / (3.0 * R)
        return jnp.max(f["normal_max"], -1) / nominal
    return jnp.mean(f["power"], -1)  # friction_power


def force_quantities(
    layout: Layout,
    sol: HalfshaftSolution,
    rates: HalfshaftSolution,
    inputs: ForceInputs,
    names: Iterable[str] = QUANTITIES,
) -> dict[str, jax.Array]:
    """The named force quantities over a revolution, from a [`revolution`][tripodjax.kinematics.revolution].

    ``sol, rates`` from ``revolution(layout, n_theta, solver, with_rates=True)``
    (one period; every force quantity has period 2π/3 in θ, the rollers taking
    each other's places). Only the cases the names need are solved (the running
    case for the GAF, complementary torque, roller loads and power; the LTS case
    for ``lts_*``). Names, see [`ForceResult`][tripodjax.forces.ForceResult]:
    ``gaf_rms``, ``gaf_peak``, ``gaf_third_order``, ``gaf_sixth_order``,
    ``gaf_ninth_order`` [N]; ``lts_mean``, ``lts_ripple`` [N];
    ``complementary_torque_steady``, ``complementary_torque_third_order``,
    ``complementary_torque_sixth_order`` [N·m]; ``roller_load_ratio`` [–];
    ``friction_power`` [W]; ``result`` (the worst RESULTS code). Elementwise: a
    batch of layouts (fields of shape (N,), the revolution's (N, n)) gives each
    quantity of shape (N,), faster than ``jax.vmap`` over the layouts (the batch,
    not the rollers, on the arrays' last axis). The names and the type of ``inputs`` are
    checked; the numbers are not (it runs inside jit; ``result`` flags them).
    """
    if isinstance(names, str):
        raise TypeError(
            f"names = {names!r} is one string; allowed: a sequence of names, e.g. ({names!r},)"
        )
    names = tuple(names)
    unknown = [name for name in names if name not in QUANTITIES + ("result",)]
    if unknown:
        raise ValueError(
            f"force quantities {unknown} are not known; allowed: {', '.join(QUANTITIES)}, result"
        )
    _check_inputs(inputs, one_number=False)
    return _evaluate(layout, sol, rates, inputs, names)[0]


def _evaluate(layout, sol, rates, inputs, names, full=False):
    dtype = sol.theta.dtype
    R, l, gamma0 = (jnp.asarray(a, dtype) for a in (layout.R, layout.l, layout.gamma0))
    torque = jnp.asarray(inputs.torque, dtype)
    out, cases = {}, {}
    wanted = [
        case
        for case, group in (("running", RUNNING_QUANTITIES), ("lts", LTS_QUANTITIES))
        if set(names) & set(group)
    ]
    checked = "result" in names
    if wanted:
        cases = _over_angles(R, l, gamma0, sol, rates, inputs, wanted, full, checked)
    series = {case: s for case, (s, _) in cases.items()}
    outside = code_where(
        _outside_domain(inputs, wanted, dtype), RESULTS.outside_validity, RESULTS.successful
    )
    for name in names:
        if name in RUNNING_QUANTITIES:
            out[name] = _running_quantity(name, series["running"], torque, R)
    if "lts" in series:
        resistance = -jnp.sign(jnp.asarray(inputs.plunge_speed, dtype)) * series["lts"]["axial"]
        if "lts_mean" in names:
            out["lts_mean"] = jnp.mean(resistance, -1)
        if "lts_ripple" in names:
            out["lts_ripple"] = 0.5 * (jnp.max(resistance, -1) - jnp.min(resistance, -1))
    if "result" in names:
        # Without torque the load ratio N_k / (T/3R) is 0/0: NaN, and no failure of the solve.
        defined = {k: v for k, v in out.items() if k != "roller_load_ratio"}
        ratio = out.get("roller_load_ratio")
        finite = jnp.ones(sol.theta.shape[:-1], bool)
        for value in defined.values():
            finite &= jnp.isfinite(value)
        if ratio is not None:
            finite &= jnp.isfinite(ratio) | (torque == 0)
        # Each case's forces at every angle (N_k < 0: outside the model), and the inputs' domain.
        codes = [jnp.max(s["result"], -1) for s in series.values()]
        out["result"] = worst(
            jnp.max(sol.result, -1),
            code_where(~finite, RESULTS.nonfinite, RESULTS.successful),
            outside,
            *codes,
        )
    full_forces = {}  # each case's per-angle codes with the kinematics' and its own inputs' domain
    for case, (_, f) in cases.items():
        if f is not None:
            domain = _outside_domain(inputs, (case,), dtype)
            code = code_where(domain, RESULTS.outside_validity, RESULTS.successful)
            f = dataclasses.replace(f, result=worst(f.result, sol.result, code))
        full_forces[case] = f
    return out, full_forces


@pytree_dataclass
class ForceResult:
    """The force model over one revolution of a halfshaft (one period, 2π/3, of the input).

    Attributes:
        theta: input angles of the period [rad], (n,).
        running: [`RollerForces`][tripodjax.forces.RollerForces] of the running case at each angle.
        lts: [`RollerForces`][tripodjax.forces.RollerForces] of the LTS case at each angle.
        gaf_rms: RMS of the running case's GAF [N].
        gaf_peak: largest |GAF| of the running case [N].
        gaf_third_order: GAF amplitude of the order 3 of the rotation [N] (only
            multiples of 3 exist: the period is 2π/3).
        gaf_sixth_order: GAF amplitude of the order 6 [N].
        gaf_ninth_order: GAF amplitude of the order 9 [N].
        lts_mean: mean axial force opposing the imposed plunge [N].
        lts_ripple: half its peak-to-peak over a revolution (the ± about the mean) [N].
        complementary_torque_steady: magnitude of the mean of the moment's X, Y
            components [N·m].
        complementary_torque_third_order: amplitude of their order 3 (the norm over
            X and Y) [N·m].
        complementary_torque_sixth_order: amplitude of their order 6 [N·m].
        roller_load_ratio: the largest N_k over the revolution over T/(3R) [–]
            (NaN without torque: 0/0).
        friction_power: mean power dissipated by friction [W], running case.
        result: worst [`RESULTS`][tripodjax.results.RESULTS] code over the revolution:
            the kinematics', ``nonfinite`` where a quantity is not finite,
            ``outside_validity`` where a roller's N_k < 0 at some angle (lift-off or
            self-locking friction) or a traced input lies outside its domain.

    The RMS, peak and order amplitudes and the steady couple are norms of series that vanish at
    T = 0 and at γ0 = 0 (the couple ∝ T tan(γ/2)): there a norm has a kink, its one-sided slope
    (the steady couple's 150 N·m/rad in γ0 for case N's R and l at 1000 N·m) not a linear function
    of the direction, which reverse mode needs. 0 is returned there (finite, a subgradient), the
    exact derivative everywhere else (q/T w.r.t. the torque). An optimiser's bound at γ0 = 0 sees
    a zero slope of these quantities there.
    """

    theta: jax.Array
    running: RollerForces
    lts: RollerForces
    gaf_rms: jax.Array
    gaf_peak: jax.Array
    gaf_third_order: jax.Array
    gaf_sixth_order: jax.Array
    gaf_ninth_order: jax.Array
    lts_mean: jax.Array
    lts_ripple: jax.Array
    complementary_torque_steady: jax.Array
    complementary_torque_third_order: jax.Array
    complementary_torque_sixth_order: jax.Array
    roller_load_ratio: jax.Array
    friction_power: jax.Array
    result: jax.Array


def forces_from_revolution(
    layout: Layout, sol: HalfshaftSolution, rates: HalfshaftSolution, inputs: ForceInputs
) -> ForceResult:
    """Every force quantity and both cases' per-angle forces, from a revolution (nothing checked)."""
    out, cases = _evaluate(layout, sol, rates, inputs, QUANTITIES + ("result",), full=True)
    return ForceResult(theta=sol.theta, running=cases["running"], lts=cases["lts"], **out)


def forces_halfshaft(
    layout: Layout,
    inputs: ForceInputs,
    n_theta: int = 360,
    solver: solvers.SolverLike = "newton",
) -> ForceResult:
    """The force model of a halfshaft over a revolution (n_theta angles a turn, one period solved).

    Args:
        layout: a [`Layout`][tripodjax.layout.Layout] with scalar fields (``jax.vmap``
            over layouts for batches).
        inputs: [`ForceInputs`][tripodjax.forces.ForceInputs].
        n_theta: angles per revolution, a multiple of 6, at least 24
            (`tripodjax.kinematics.MIN_N_THETA_ORDERS`).
        solver: any level of [`tripodjax.solvers`][tripodjax.solvers]; the kinematics
            over the revolution come from [`revolution`][tripodjax.kinematics.revolution].

    Returns a [`ForceResult`][tripodjax.forces.ForceResult]; differentiable w.r.t. the
    layout and every field of ``inputs``: a derivative (``jax.grad``, ``jax.jacfwd``) runs
    one program of the values and their Jacobian, compiled once for every quantity.
    """
    check_layout(layout, one=True)
    _check_inputs(inputs)
    n_theta = _check_n_theta(n_theta, orders="the force quantities")
    return _forces_halfshaft(layout, inputs, n_theta=n_theta, solver=solvers.resolve(solver))


def _forces_over_revolution(layout, inputs, *, n_theta, solver):
    sol, rates = revolution(layout, n_theta, solver, with_rates=True)
    return forces_from_revolution(layout, sol, rates, inputs)


# Derivatives from the Jacobian w.r.t. the layout and the inputs' numbers
# (``tripodjax._derivatives``): an eager ``jax.grad`` of the seed's case N compiles one program
# for latency, 16.7 → 5.1 s, where reverse mode through the revolution compiled two with XLA's
# defaults (2-core AMD EPYC, fresh processes).
_forces_halfshaft = differentiated_by_jacobian(_forces_over_revolution, ("n_theta", "solver"))
