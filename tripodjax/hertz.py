"""Hertz contact of roller on track, joint capacities, minimum size and life (seed §4.2).

Roller of diameter d in a track of groove radius R_g, conformity Ψ = 2 R_g / d.
The seed reads the Hertz product μν from a book table; here it follows from
Hertz theory: for the contact-ellipse ratio κ = a/b ≥ 1, with m = 1 − 1/κ² and
the complete elliptic integrals K(m), E(m),

    cos τ = ((κ² + 1) E − 2K) / ((κ² − 1) E),
    μ = (2κ² E / π)^(1/3),   ν = (2E / (πκ))^(1/3).

For steel (E = 208 GPa, Poisson 0.3) p_max = (858/(μν)) (Q (Σρ)²)^(1/3) [MPa,
N, 1/mm], hence the conformity coefficient C_p = (858/(μν)) (dΣρ)^(2/3) and
the torque a joint carries at the contact pressure p (physics brief §4):

    M(p) = ½(1 + cos γ) n_R (p / (C_s C_p))³ d² R sin ε cos ζ     [N·mm]

Units: lengths mm, pressures MPa, loads N, torques N·m at the API, speeds rpm,
angles rad.
"""

import math

import jax
import jax.numpy as jnp
import numpy as np

from tripodjax._checks import check, check_non_negative, check_positive, check_shares
from tripodjax._pytree import pytree_dataclass

YOUNG_MODULUS_STEEL = 208_000.0  # MPa
POISSON_STEEL = 0.3
HERTZ_STEEL = 858.0  # MPa·N^(-1/3)·mm^(2/3): the seed's constant, = (3/2π)(E/(3(1−ν²)))^(2/3)
_AGM_STEPS = 12
_KAPPA_MAX_STEPS = 40


# --------------------------------------------------------------------------- elliptic integrals


def _elliptic_agm(m, m1):
    """K(m), E(m) and D(m) = (K − E)/m by the arithmetic–geometric mean.

    Takes the parameter m and its complement m1 = 1 − m separately so that
    neither loses digits near its end of [0, 1). The AGM differences
    c_n = (a_{n−1} − b_{n−1})/2 are carried as s_n = c_n²/m through the
    cancellation-free recursion c_{n+1} = c_n²/(4 a_{n+1}), so D is accurate
    at m → 0 and everything is smooth (differentiable) there.
    """
    a = jnp.ones_like(m)
    b = jnp.sqrt(m1)
    s = jnp.ones_like(m)  # s_0 = c_0²/m with c_0² = m
    weighted = 0.5 * s  # Σ 2^(n−1) s_n
    weight = 0.5
    for _ in range(_AGM_STEPS):
        a, b = 0.5 * (a + b), jnp.sqrt(a * b)
        s = s * s * m / (16.0 * a * a)
        weight *= 2.0
        weighted = weighted + weight * s
    K = jnp.pi / (2.0 * a)
    return K, K * (1.0 - m * weighted), K * weighted


def elliptic_integrals(m):
    """Complete elliptic integrals of the first and second kind, (K(m), E(m)), 0 ≤ m < 1.

    Parameter convention m = k² (as SciPy's ``ellipk``/``ellipe``). Computed by
    the arithmetic–geometric mean in JAX; differentiable; any dtype.
    """
    m = jnp.asarray(m, jnp.result_type(m, 0.0))
    K, E, _ = _elliptic_agm(m, 1.0 - m)
    return K, E


# --------------------------------------------------------------------------- ellipse ratio


def _log_ratio_residual(t, log1m_cos_tau):
    """log(1 − cos τ(κ)) − log(1 − cos τ) with κ = e^t.

    1 − cos τ = 2 m1 (K − E)/(m E) = 2 m1 D / E, a product of positive,
    cancellation-free factors; log(1 − cos τ) is nearly linear in log κ over
    the whole range, so Newton converges in a few steps from any start.
    """
    m1 = jnp.exp(-2.0 * t)
    m = -jnp.expm1(-2.0 * t)
    _, E, D = _elliptic_agm(m, m1)
    return jnp.log(2.0 * D / E) - 2.0 * t - log1m_cos_tau


def _newton_log_kappa(log1m_cos_tau, cos_tau):
    dtype = jnp.result_type(cos_tau)
    tol = 8.0 * float(jnp.finfo(dtype).eps)
    # Start from the usual power-law fit κ ≈ (R_x/R_y)^(2/π).
    t0 = (2.0 / jnp.pi) * (jnp.log1p(cos_tau) - log1m_cos_tau)
    slope = jax.grad(_log_ratio_residual)

    def body(carry):
        t, n, _ = carry
        step = -_log_ratio_residual(t, log1m_cos_tau) / slope(t, log1m_cos_tau)
        t_new = jnp.maximum(t + step, 0.0)
        return t_new, n + 1, jnp.abs(t_new - t) <= tol * (1.0 + t_new)

    def cond(carry):
        _, n, done = carry
        return jnp.logical_and(n < _KAPPA_MAX_STEPS, jnp.logical_not(done))

    t, _, _ = jax.lax.while_loop(cond, body, (t0, jnp.int32(0), jnp.bool_(False)))
    return t


def _log_kappa(cos_tau):
    """log κ for one |cos τ| in [0, 1), by Newton with implicit derivatives."""
    log1m = jnp.log1p(-cos_tau)
    return jax.lax.custom_root(
        lambda t: _log_ratio_residual(t, log1m),
        jnp.zeros_like(cos_tau),
        lambda f, t0: _newton_log_kappa(log1m, cos_tau),
        lambda g, y: y / g(jnp.ones_like(y)),
    )


@pytree_dataclass
class HertzCoefficients:
    """Hertz's ellipse ratio and coefficients for one curvature function cos τ.

    Attributes:
        kappa: ellipse ratio κ = a/b ≥ 1 [–].
        mu, nu: coefficients of the semi-axes a = μ·k, b = ν·k [–].
        mu_nu: the product μν used by the seed's conformity coefficient [–].
    """

    kappa: jax.Array
    mu: jax.Array
    nu: jax.Array
    mu_nu: jax.Array


@jax.jit
def hertz_coefficients(cos_tau):
    """κ, μ, ν and μν from the curvature function cos τ (its magnitude is used), |cos τ| < 1.

    Exact Hertz theory: the ellipse ratio solves the cos τ(κ) relation above by
    Newton (derivatives from the implicit function theorem); no lookup table.
    cos τ = 0 gives κ = μ = ν = 1; values approach infinity as |cos τ| → 1.
    """
    c = jnp.abs(jnp.asarray(cos_tau, jnp.result_type(cos_tau, 0.0)))
    t = jnp.vectorize(_log_kappa)(c)
    kappa = jnp.exp(t)
    _, E, _ = _elliptic_agm(-jnp.expm1(-2.0 * t), jnp.exp(-2.0 * t))
    mu = jnp.cbrt(2.0 * kappa**2 * E / jnp.pi)
    nu = jnp.cbrt(2.0 * E / (jnp.pi * kappa))
    return HertzCoefficients(kappa=kappa, mu=mu, nu=nu, mu_nu=mu * nu)


def mu_nu(cos_tau):
    """The Hertz product μν for the curvature function cos τ (see :func:`hertz_coefficients`)."""
    return hertz_coefficients(cos_tau).mu_nu


# --------------------------------------------------------------------------- contact geometry


@pytree_dataclass
class ContactGeometry:
    """Roller–track contact geometry from the conformity Ψ (seed §4.2).

    Attributes:
        chi_q: transverse conformity χ_q = −1/Ψ [–].
        chi_l: longitudinal conformity χ_l = 0 (straight tracks) [–].
        d_sum_rho: Hertz factor dΣρ = 2(2 + χ_q + χ_l) [–] (curvature sum × d).
        cos_tau: curvature function |χ_q − χ_l| / (2 + χ_q + χ_l) [–].
    """

    chi_q: jax.Array
    chi_l: jax.Array
    d_sum_rho: jax.Array
    cos_tau: jax.Array


def contact_geometry(conformity):
    """Contact geometry of a roller in a straight track of conformity Ψ = 2 R_g / d > 1."""
    check("conformity", conformity, lambda a: np.isfinite(a) & (a > 1), "conformity Ψ > 1")
    conformity = jnp.asarray(conformity, jnp.result_type(conformity, 0.0))
    chi_q = -1.0 / conformity
    chi_l = jnp.zeros_like(chi_q)
    denominator = 2.0 + chi_q + chi_l
    return ContactGeometry(
        chi_q=chi_q,
        chi_l=chi_l,
        d_sum_rho=2.0 * denominator,
        cos_tau=jnp.abs(chi_q - chi_l) / denominator,
    )


def conformity_coefficient(conformity):
    """C_p = (858/(μν)) (dΣρ)^(2/3) [MPa·N^(-1/3)·mm^(2/3)] for steel on steel."""
    geometry = contact_geometry(conformity)
    return HERTZ_STEEL / mu_nu(geometry.cos_tau) * geometry.d_sum_rho ** (2.0 / 3.0)


@pytree_dataclass
class Contact:
    """Hertz contact of one roller on its track under a normal load.

    Attributes:
        p_max: maximum contact pressure [MPa].
        a: semi-axis of the contact ellipse across the track, in the
            conformal groove direction [mm].
        b: semi-axis along the track, in the rolling direction [mm].
    """

    p_max: jax.Array
    a: jax.Array
    b: jax.Array


def roller_contact(
    load, d, *, conformity, young_modulus=YOUNG_MODULUS_STEEL, poisson=POISSON_STEEL
):
    """Contact pressure and ellipse semi-axes for a roller load Q [N] on a roller of diameter d [mm].

    a = μ k, b = ν k with k = (3 Q (1 − ν_P²) / (E Σρ))^(1/3), Σρ = dΣρ / d, and
    p_max = 3Q / (2π a b); for steel this is the seed's 858/(μν) (Q Σρ²)^(1/3).
    """
    check_non_negative("load", load, " N")
    check_positive(d=d, young_modulus=young_modulus)
    geometry = contact_geometry(conformity)
    coefficients = hertz_coefficients(geometry.cos_tau)
    sum_rho = geometry.d_sum_rho / d
    k = jnp.cbrt(3.0 * load * (1.0 - poisson**2) / (young_modulus * sum_rho))
    a, b = coefficients.mu * k, coefficients.nu * k
    area = jnp.where(a * b > 0, a * b, 1.0)
    return Contact(p_max=jnp.where(a * b > 0, 1.5 * load / (jnp.pi * area), 0.0), a=a, b=b)


# --------------------------------------------------------------------------- capacities and sizing


def torque_at_pressure(
    pressure, d, R, *, C_p, C_s, n_rollers=3, pressure_angle=math.pi / 2, helix_angle=0.0, gamma=0.0
):
    """M(p) = ½(1 + cos γ) n_R (p/(C_s C_p))³ d² R sin ε cos ζ, returned in N·m."""
    load_factor = (pressure / (C_s * C_p)) ** 3
    torque_nmm = (
        0.5
        * (1.0 + jnp.cos(gamma))
        * n_rollers
        * load_factor
        * d**2
        * R
        * jnp.sin(pressure_angle)
        * jnp.cos(helix_angle)
    )
    return torque_nmm / 1000.0


@pytree_dataclass
class Capacities:
    """Torque capacities of a tripod joint from its Hertz contact (seed §4.2).

    Attributes:
        M_s: static capacity at P_s, γ = 0 [N·m].
        M_d: long-lasting dynamic capacity at P_d and the working angle [N·m]
            (the torque for 500 h at 730 rpm).
        M_sd: short-lasting dynamic capacity at P_sd and the working angle [N·m].
        C_p: conformity coefficient [MPa·N^(-1/3)·mm^(2/3)].
        mu_nu: Hertz product μν [–].
    """

    M_s: jax.Array
    M_d: jax.Array
    M_sd: jax.Array
    C_p: jax.Array
    mu_nu: jax.Array


def capacities(
    d,
    R,
    *,
    conformity,
    P_s,
    P_d,
    P_sd,
    C_s,
    n_rollers=3,
    pressure_angle=math.pi / 2,
    helix_angle=0.0,
    gamma=0.0,
):
    """Static and dynamic torque capacities of a joint with roller diameter d and PCR R [mm].

    Args:
        d: roller diameter [mm]; R: track pitch-circle radius [mm].
        conformity: Ψ = 2 R_g / d > 1 (experience range 1.002–1.008).
        P_s, P_d, P_sd: allowed static, long-lasting and short-lasting
            dynamic contact pressures [MPa].
        C_s: safety coefficient on the pressure [–].
        n_rollers: 3 for a tripod; pressure_angle ε [rad] (π/2 for a tripod);
        helix_angle ζ [rad] (0); gamma: working angle [rad] for M_d and M_sd.

    Differentiable w.r.t. d, R, the conformity and the pressures; any dtype.
    """
    check_positive(d=d, R=R, P_s=P_s, P_d=P_d, P_sd=P_sd, C_s=C_s)
    geometry = contact_geometry(conformity)
    product = mu_nu(geometry.cos_tau)
    C_p = HERTZ_STEEL / product * geometry.d_sum_rho ** (2.0 / 3.0)
    common = dict(
        C_p=C_p,
        C_s=C_s,
        n_rollers=n_rollers,
        pressure_angle=pressure_angle,
        helix_angle=helix_angle,
    )
    return Capacities(
        M_s=torque_at_pressure(P_s, d, R, gamma=0.0, **common),
        M_d=torque_at_pressure(P_d, d, R, gamma=gamma, **common),
        M_sd=torque_at_pressure(P_sd, d, R, gamma=gamma, **common),
        C_p=C_p,
        mu_nu=product,
    )


SIZING_RULES = ("consistent", "workbook")


def min_roller_diameter(
    M_max,
    *,
    R_over_d,
    conformity,
    P_s,
    C_s,
    n_rollers=3,
    pressure_angle=math.pi / 2,
    helix_angle=0.0,
    rule="consistent",
):
    """Smallest roller diameter and pitch-circle radius [mm] for a maximum torque M_max [N·m].

    ``rule="consistent"``: the static capacity equals M_max,
    d³ = M_max / (n_R (R/d) (P_s/(C_s C_p))³ sin ε cos ζ) — Hertz's cube law.

    ``rule="workbook"``: the company workbook's rule (seed §4.2–4.3),
    d³ = (C_p C_s / P_s)² M_max / (n_R (R/d) sin ε cos ζ) with M_max in N·mm.
    It reproduces the workbook's 37.654 mm but is dimensionally inconsistent
    (pressure to the power 2 where Hertz gives 3); kept for reproduction only.

    Returns:
        (d_min, R_min) with R_min = (R/d)·d_min.
    """
    if rule not in SIZING_RULES:
        raise ValueError(f"rule = {rule!r} is not allowed; allowed: {', '.join(SIZING_RULES)}")
    check_positive(M_max=M_max, R_over_d=R_over_d, P_s=P_s, C_s=C_s)
    C_p = conformity_coefficient(conformity)
    geometry_factor = n_rollers * R_over_d * jnp.sin(pressure_angle) * jnp.cos(helix_angle)
    torque_nmm = 1000.0 * M_max
    if rule == "consistent":
        d3 = torque_nmm / (geometry_factor * (P_s / (C_s * C_p)) ** 3)
    else:
        d3 = (C_p * C_s / P_s) ** 2 * torque_nmm / geometry_factor
    d_min = jnp.cbrt(d3)
    return d_min, R_over_d * d_min


# --------------------------------------------------------------------------- life (Palmgren–Miner)

RATING_HOURS_RPM = 365_000.0  # 500 h at 730 rpm at M = M_d, the catalogues' rating (4.2.2)


def life_hours(M_d, torque, speed, share):
    """Palmgren–Miner life in hours over a load spectrum (4.2.1, 4.2.2).

    L_h,i = (365000 / n_i) (M_d / M_i)³ and 1/L_h = Σ a_i / L_h,i, over the
    last axis of ``torque`` [N·m], ``speed`` n [rpm] and ``share`` a [–];
    ``M_d`` [N·m] may carry leading axes (one life per entry). A case with zero
    torque or speed does no damage.
    """
    M_d = jnp.asarray(M_d)[..., None]
    torque, speed, share = (
        jnp.atleast_1d(jnp.asarray(x, M_d.dtype)) for x in (torque, speed, share)
    )
    damage_rate = share * speed * (torque / M_d) ** 3 / RATING_HOURS_RPM
    return 1.0 / jnp.sum(damage_rate, axis=-1)


@pytree_dataclass
class LoadSpectrum:
    """A load spectrum: each case is a torque applied at a speed for a share of the time.

    Attributes (1-D arrays of one length):
        torque: joint torque M_i [N·m].
        speed: joint speed n_i [rpm].
        vehicle_speed: vehicle speed V_i [km/h] (for the life in km, 4.2.3).
        share: share a_i of the running time [–], summing to 1.
    """

    torque: jax.Array
    speed: jax.Array
    vehicle_speed: jax.Array
    share: jax.Array

    def __post_init__(self):
        check_non_negative("LoadSpectrum.torque", self.torque, " N·m")
        check_non_negative("LoadSpectrum.speed", self.speed, " rpm")
        check_non_negative("LoadSpectrum.vehicle_speed", self.vehicle_speed, " km/h")
        check_shares("LoadSpectrum.share", self.share)


@pytree_dataclass
class WorkingConditions:
    """Working conditions of the joint (e.g. static, steer left/right, bound, rebound).

    Attributes (1-D arrays of one length):
        angle: working articulation angle γ_j [rad]; it enters through M_d(γ).
        share: share w_j of the mileage spent in the condition [–], summing to 1.
    """

    angle: jax.Array
    share: jax.Array

    def __post_init__(self):
        check(
            "WorkingConditions.angle",
            self.angle,
            lambda a: np.isfinite(a) & (a >= 0) & (a < math.pi / 2),
            "0 ≤ angle < π/2 rad",
        )
        check_shares("WorkingConditions.share", self.share)


@pytree_dataclass
class Life:
    """Rolling-contact life of a joint under a spectrum and working conditions.

    Attributes:
        hours: combined life L_h [h].
        km: combined life in kilometres L_s = L_h · V_m (4.2.3) [km].
        hours_per_condition: life L_h,j if the joint ran in condition j only [h].
        M_d_per_condition: long-lasting capacity M_d(γ_j) [N·m].
    """

    hours: jax.Array
    km: jax.Array
    hours_per_condition: jax.Array
    M_d_per_condition: jax.Array


def joint_life(
    d,
    R,
    spectrum,
    conditions,
    *,
    conformity,
    P_d,
    C_s,
    n_rollers=3,
    pressure_angle=math.pi / 2,
    helix_angle=0.0,
):
    """Palmgren–Miner life of a joint in hours and km (4.2.1–4.2.3).

    For each working condition j the capacity M_d(γ_j) gives the spectrum's
    life L_h,j (4.2.2, 4.2.1); the conditions combine by Miner's rule on their
    shares, 1/L_h = Σ w_j / L_h,j, and L_s = L_h · V_m with V_m = Σ a_i V_i.
    Differentiable w.r.t. d, R, the conformity and P_d.
    """
    check_positive(d=d, R=R, P_d=P_d, C_s=C_s)
    C_p = conformity_coefficient(conformity)
    M_d = torque_at_pressure(
        P_d,
        d,
        R,
        C_p=C_p,
        C_s=C_s,
        n_rollers=n_rollers,
        pressure_angle=pressure_angle,
        helix_angle=helix_angle,
        gamma=jnp.asarray(conditions.angle),
    )
    per_condition = life_hours(M_d, spectrum.torque, spectrum.speed, spectrum.share)
    hours = 1.0 / jnp.sum(jnp.asarray(conditions.share) / per_condition)
    mean_speed = jnp.sum(jnp.asarray(spectrum.share) * jnp.asarray(spectrum.vehicle_speed))
    return Life(
        hours=hours, km=hours * mean_speed, hours_per_condition=per_condition, M_d_per_condition=M_d
    )
