"""Hertz contact of roller on track, joint capacities and minimum size (seed §4.2).

The life under a load spectrum is in [`tripodjax.life`][tripodjax.life].

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

Inputs are checked at the Python boundary (concrete values only): a
``TypeError`` or ``ValueError`` names the argument, the value and what is
allowed. The conformity must be at least `MIN_CONFORMITY` = 1.0005
(see `tripodjax._checks.check_conformity`), ``n_rollers`` an integer ≥ 1.
Inside ``jit`` nothing can raise: a non-finite or out-of-range input gives NaN,
and the results that depend on the Hertz ellipse-ratio solve carry a per-point
``result`` code ([`tripodjax.results.RESULTS`][tripodjax.results.RESULTS]).
"""

import functools
import math

import jax
import jax.numpy as jnp
import numpy as np
from jax.typing import ArrayLike

from tripodjax._checks import (
    MIN_CONFORMITY,  # re-exported: hertz.MIN_CONFORMITY
    Domain,
    as_array,
    check_broadcast,
    check_choice,
    check_conformity,
    check_domains,
    check_flag,
    check_integer,
    check_working_angle,
    outside_domains,
)
from tripodjax._compile import latency_bound_at_top_level
from tripodjax._pytree import pytree_dataclass
from tripodjax.results import RESULTS, code_where, worst

__all__ = [
    "MIN_CONFORMITY",
    "Capacities",
    "Contact",
    "ContactGeometry",
    "HertzCoefficients",
    "RESULTS",
    "capacities",
    "conformity_coefficient",
    "contact_geometry",
    "elliptic_integrals",
    "hertz_coefficients",
    "min_roller_diameter",
    "mu_nu",
    "roller_contact",
    "torque_at_pressure",
]

YOUNG_MODULUS_STEEL = 208_000.0  # MPa
POISSON_STEEL = 0.3
HERTZ_STEEL = 858.0  # MPa·N^(-1/3)·mm^(2/3): the seed's constant, = (3/2π)(E/(3(1−ν²)))^(2/3)
_AGM_STEPS = 12
_KAPPA_MAX_STEPS = 40

_POSITIVE = Domain(0.0, low_open=True)
_UNIT_INTERVAL = Domain(0.0, 1.0, high_open=True)
DOMAINS = {
    **dict.fromkeys(
        ("d", "R", "C_p", "C_s", "P_s", "P_d", "P_sd", "M_max", "R_over_d", "young_modulus"),
        _POSITIVE,
    ),
    "load": Domain(0.0, unit=" N"),
    "pressure": Domain(0.0, unit=" MPa"),
    "conformity": Domain(MIN_CONFORMITY, wording=lambda name, value: check_conformity(value, name)),
    "longitudinal_conformity": Domain(-1.0, 1.0, low_open=True),
    "poisson": Domain(-1.0, 0.5, low_open=True, high_open=True),
    "n_rollers": Domain(1, wording=lambda name, value: check_integer(name, value, minimum=1)),
    "pressure_angle": Domain(0.0, math.pi / 2, low_open=True, unit=" rad"),
    "helix_angle": Domain(0.0, math.pi / 2, high_open=True, unit=" rad"),
    "gamma": Domain(0.0, math.pi / 2, high_open=True, wording=check_working_angle),
    "cos_tau": _UNIT_INTERVAL,
    "m": _UNIT_INTERVAL,
}
"""Each input's domain, one rule for the concrete check at the boundary (``ValueError``) and
for the traced flag inside ``jit`` (NaN and ``outside_validity``)."""


def _checked(**values):
    """The arguments at the boundary: each concrete one inside its domain (`DOMAINS`), the
    arrays broadcasting together and none empty; returned in order, lists as arrays."""
    check_domains(DOMAINS, **values)
    check_broadcast(**values)
    return [as_array(v) for v in values.values()]


def _outside(**values):
    """Where a traced (finite) argument lies outside its domain (`DOMAINS`)."""
    return outside_domains(DOMAINS, **values)


def _code(finite, outside, *codes):
    """The worst of ``codes``, ``nonfinite`` where not ``finite``, ``outside_validity`` where
    ``outside`` (a NaN input is ``nonfinite``, a finite one outside its domain ``outside_validity``)."""
    return worst(
        *codes,
        code_where(finite, RESULTS.successful, RESULTS.nonfinite),
        code_where(outside, RESULTS.outside_validity, RESULTS.successful),
    )


# --------------------------------------------------------------------------- elliptic integrals


def _elliptic_agm(m, m1):
    """K(m), E(m) and D(m) = (K − E)/m by the arithmetic–geometric mean.

    Takes the parameter m and its complement m1 = 1 − m separately so that
    neither loses digits near its end of [0, 1). The AGM differences
    c_n = (a_{n−1} − b_{n−1})/2 are carried as s_n = c_n²/m through the
    cancellation-free recursion c_{n+1} = c_n²/(4 a_{n+1}), so D is accurate
    at m → 0 and everything is smooth (differentiable) there.
    """
    m, m1 = jnp.broadcast_arrays(m, m1)

    def step(_, carry):
        a, b, s, weight, weighted = carry
        a, b = 0.5 * (a + b), jnp.sqrt(a * b)
        s = s * s * m / (16.0 * a * a)
        weight = 2.0 * weight
        return a, b, s, weight, weighted + weight * s

    one = jnp.ones_like(m)  # a_0 = 1, and s_0 = c_0²/m with c_0² = m
    # Σ 2^(n−1) s_n; one loop body in the program, however many steps (and derivatives) it takes.
    a, _, _, _, weighted = jax.lax.fori_loop(
        0, _AGM_STEPS, step, (one, jnp.sqrt(m1), one, 0.5 * one, 0.5 * one)
    )
    K = jnp.pi / (2.0 * a)
    return K, K * (1.0 - m * weighted), K * weighted


def _nan_unless(ok: ArrayLike, value: ArrayLike) -> jax.Array:
    """``value`` where ``ok``, NaN elsewhere (NaN, not a plausible number, for bad traced input)."""
    value = jnp.asarray(value)
    return jnp.where(ok, value, jnp.asarray(jnp.nan, value.dtype))


def _finite(*values):
    """Elementwise: every value finite (broadcast together)."""
    ok = jnp.bool_(True)
    for value in values:
        ok = ok & jnp.isfinite(value)
    return ok


def _all_finite(*values):
    """One flag: every element of every value finite."""
    ok = jnp.bool_(True)
    for value in values:
        ok = ok & jnp.all(jnp.isfinite(jnp.asarray(value)))
    return ok


def elliptic_integrals(m: ArrayLike) -> tuple[jax.Array, jax.Array]:
    """Complete elliptic integrals of the first and second kind, (K(m), E(m)), 0 ≤ m < 1.

    Parameter convention m = k² (as SciPy's ``ellipk``/``ellipe``). Computed by
    the arithmetic–geometric mean in JAX; differentiable; any dtype. A concrete
    m outside [0, 1) raises ``ValueError``; a traced one gives NaN.
    """
    (m,) = _checked(m=m)
    m = jnp.asarray(m, jnp.result_type(m, 0.0))
    m = _nan_unless((m >= 0) & (m < 1), m)
    K, E, _ = _elliptic_agm(m, 1.0 - m)
    return K, E


# --------------------------------------------------------------------------- ellipse ratio


def _ratio_log(t):
    """log(1 − cos τ(κ)) at κ = e^t, its t-slope, E(m) and dE/dt (m = 1 − 1/κ²).

    1 − cos τ = 2 m1 (K − E)/(m E) = 2 m1 D / E, a product of positive,
    cancellation-free factors; log(1 − cos τ) is nearly linear in log κ over
    the whole range, so Newton converges in a few steps from any start. The
    t-derivatives come from the same AGM loop as the values (forward mode: one
    loop, not a loop and its reverse).
    """

    def integrals(t):
        _, E, D = _elliptic_agm(-jnp.expm1(-2.0 * t), jnp.exp(-2.0 * t))
        return E, D

    (E, D), (dE, dD) = jax.jvp(integrals, (t,), (jnp.ones_like(t),))
    return jnp.log(2.0 * D / E) - 2.0 * t, dD / D - dE / E - 2.0, E, dE


def _newton_log_kappa(log1m_cos_tau, cos_tau):
    """Newton on log κ: (t, ∂r/∂t, E(m), dE/dt, result code).

    The loop stops when a step is below 8 ε (1 + t). The terms come from the last step's
    evaluation, one step before the returned t: E moved to it to first order (its error is of
    the step's square, below roundoff); the slope and dE/dt, which only the derivatives use,
    as they are. No evaluation after the loop. The code is successful, max_steps_reached or
    nonfinite.
    """
    dtype = jnp.result_type(cos_tau)
    tol = 8.0 * float(jnp.finfo(dtype).eps)
    # Start from the usual power-law fit κ ≈ (R_x/R_y)^(2/π).
    t0 = (2.0 / jnp.pi) * (jnp.log1p(cos_tau) - log1m_cos_tau)

    def body(carry):
        _, t, n, _, _ = carry
        value, slope, E, dE = _ratio_log(t)
        t_new = jnp.maximum(t - (value - log1m_cos_tau) / slope, 0.0)
        met = jnp.abs(t_new - t) <= tol * (1.0 + t_new)
        # A non-finite iterate ends the loop too (it is flagged below, not iterated on).
        return (t, slope, E, dE), t_new, n + 1, met | ~jnp.isfinite(t_new), ~met

    def cond(carry):
        _, _, n, done, _ = carry
        return jnp.logical_and(n < _KAPPA_MAX_STEPS, jnp.logical_not(done))

    nan = jnp.full_like(t0, jnp.nan)
    start = ((nan, nan, nan, nan), t0, jnp.int32(0), ~jnp.isfinite(t0), jnp.bool_(True))
    (t, slope, E, dE), t_new, _, _, unmet = jax.lax.while_loop(cond, body, start)
    code = code_where(unmet, RESULTS.max_steps_reached, RESULTS.successful)
    E = E + dE * (t_new - t)
    code = code_where(jnp.isfinite(t_new) & jnp.isfinite(E), code, RESULTS.nonfinite)
    return t_new, slope, E, dE, code


@jax.custom_jvp
def _log_kappa(cos_tau):
    """(log κ, ∂r/∂t, E(m), dE/dt, result code) for one cos τ in [0, 1), by Newton.

    The derivatives are the implicit function theorem's at the answer, from terms the solve
    computes anyway: dt/d(cos τ) = −(∂r/∂cos τ)/(∂r/∂t) with ∂r/∂cos τ = 1/(1 − cos τ)
    (r = ``_ratio_log``(t) − log(1 − cos τ)), dE = (dE/dt) dt; no loop is differentiated.
    The slope and dE/dt are outputs too, so that a derivative of second order (a reverse
    pass through a Jacobian) has theirs: from the AGM at the answer, in forward mode.
    """
    return _newton_log_kappa(jnp.log1p(-cos_tau), cos_tau)


@_log_kappa.defjvp
def _log_kappa_jvp(primals, tangents):
    (cos_tau,), (d_cos_tau,) = primals, tangents
    t, slope, E, dE, code = _log_kappa(cos_tau)
    dt = -d_cos_tau / ((1.0 - cos_tau) * slope)
    # The slope's and dE/dt's own tangents: unused (and removed by the compiler) unless a
    # derivative of second order asks for them.
    _, (_, d_slope, _, d_dE) = jax.jvp(_ratio_log, (t,), (dt,))
    tangent = (dt, d_slope, dE * dt, d_dE, np.zeros(jnp.shape(code), jax.dtypes.float0))
    return (t, slope, E, dE, code), tangent


@pytree_dataclass
class HertzCoefficients:
    """Hertz's ellipse ratio and coefficients for one curvature function cos τ.

    Attributes:
        kappa: ellipse ratio κ = a/b ≥ 1 [–].
        mu, nu: coefficients of the semi-axes a = μ·k, b = ν·k [–].
        mu_nu: the product μν used by the seed's conformity coefficient [–].
        result: per-point code of the κ solve (int32,
            [`RESULTS`][tripodjax.results.RESULTS]): ``successful``,
            ``max_steps_reached``, ``outside_validity`` (cos τ outside [0, 1) inside
            ``jit``) or ``nonfinite`` (cos τ non-finite); the coefficients are then NaN.
    """

    kappa: jax.Array
    mu: jax.Array
    nu: jax.Array
    mu_nu: jax.Array
    result: jax.Array


@functools.partial(latency_bound_at_top_level, small_inputs=True)
def _hertz_coefficients(cos_tau):
    c = jnp.asarray(cos_tau, jnp.result_type(cos_tau, 0.0))
    outside = _outside(cos_tau=c)
    c = _nan_unless((c >= 0) & (c < 1), c)
    t, _, E, _, code = jnp.vectorize(_log_kappa)(c)
    code = worst(code, code_where(outside, RESULTS.outside_validity, RESULTS.successful))
    kappa = jnp.exp(t)
    mu = jnp.cbrt(2.0 * kappa**2 * E / jnp.pi)
    nu = jnp.cbrt(2.0 * E / (jnp.pi * kappa))
    return HertzCoefficients(kappa=kappa, mu=mu, nu=nu, mu_nu=mu * nu, result=code)


def hertz_coefficients(cos_tau: ArrayLike) -> HertzCoefficients:
    """κ, μ, ν and μν from the curvature function cos τ, 0 ≤ cos τ < 1.

    Exact Hertz theory: the ellipse ratio solves the cos τ(κ) relation above by
    Newton (derivatives from the implicit function theorem); no lookup table.
    cos τ = 0 gives κ = μ = ν = 1; values approach infinity as cos τ → 1.
    A concrete cos τ outside [0, 1) (or non-finite) raises ``ValueError``; a
    traced one gives NaN coefficients and ``result = RESULTS.outside_validity``
    (``nonfinite`` for a NaN or infinite one). A number or a non-empty array (a list too).
    Jit-compiled.
    """
    (cos_tau,) = _checked(cos_tau=cos_tau)
    return _hertz_coefficients(cos_tau)


def mu_nu(cos_tau: ArrayLike) -> jax.Array:
    """The Hertz product μν for the curvature function cos τ in [0, 1) (see [`hertz_coefficients`][tripodjax.hertz.hertz_coefficients])."""
    return hertz_coefficients(cos_tau).mu_nu


# --------------------------------------------------------------------------- contact geometry


@pytree_dataclass
class ContactGeometry:
    """Roller–track contact geometry from the conformity Ψ (seed §4.2).

    Attributes:
        chi_q: transverse conformity χ_q = −1/Ψ [–].
        chi_l: longitudinal conformity χ_l [–]: 0 for straight tracks (a tripod), d/(2ρ_l)
            for a track of longitudinal radius ρ_l (> 0 convex, < 0 concave; a ball joint).
        d_sum_rho: Hertz factor dΣρ = 2(2 + χ_q + χ_l) [–] (curvature sum × d).
        cos_tau: curvature function |χ_q − χ_l| / (2 + χ_q + χ_l) [–].
    """

    chi_q: jax.Array
    chi_l: jax.Array
    d_sum_rho: jax.Array
    cos_tau: jax.Array


def contact_geometry(
    conformity: ArrayLike, longitudinal_conformity: ArrayLike = 0.0
) -> ContactGeometry:
    """Contact geometry of a roller or ball in a track of conformity Ψ = 2 R_g / d.

    ``longitudinal_conformity`` χ_l in (−1, 1]: 0 (the default) for a straight
    track; a ball joint's curved track has χ_l ≠ 0 (fig. 4.3.10: 0.268).

    Ψ ≥ `MIN_CONFORMITY` = 1.0005 (Ψ − 1 ≥ 5·10⁻⁴; the workbook's
    experience range is 1.002–1.008; see
    `tripodjax._checks.check_conformity` for why). A concrete Ψ below it
    or non-finite raises ``ValueError`` (as does a χ_l outside (−1, 1]); inside
    ``jit`` a non-finite Ψ or χ_l, or one outside its domain, gives NaN. Numbers or
    non-empty arrays (lists too) that broadcast together.
    """
    conformity, longitudinal_conformity = _checked(
        conformity=conformity, longitudinal_conformity=longitudinal_conformity
    )
    conformity = jnp.asarray(conformity, jnp.result_type(conformity, 0.0))
    longitudinal = jnp.asarray(longitudinal_conformity, conformity.dtype)
    inside = ~_outside(conformity=conformity, longitudinal_conformity=longitudinal)
    return _geometry(conformity, longitudinal, inside)


def _geometry(conformity, longitudinal, inside=True):
    """`contact_geometry` past its checks; ``inside``: where the inputs lie in their domains
    (its callers inside the library flag their inputs themselves). NaN where they do not or
    are not finite."""
    conformity = jnp.asarray(conformity, jnp.result_type(conformity, 0.0))
    longitudinal = jnp.asarray(longitudinal, conformity.dtype)
    ok = inside & jnp.isfinite(conformity) & jnp.isfinite(longitudinal)
    chi_q = -1.0 / _nan_unless(ok, conformity)
    chi_l = _nan_unless(ok, longitudinal)
    chi_q, chi_l = jnp.broadcast_arrays(chi_q, chi_l)
    denominator = 2.0 + chi_q + chi_l
    return ContactGeometry(
        chi_q=chi_q,
        chi_l=chi_l,
        d_sum_rho=2.0 * denominator,
        cos_tau=jnp.abs(chi_q - chi_l) / denominator,
    )


def _conformity_coefficient(conformity, longitudinal_conformity=0.0):
    """(C_p, μν, κ-solve code) from a checked conformity (and longitudinal conformity χ_l); its
    callers flag a traced input outside its domain."""
    geometry = _geometry(conformity, longitudinal_conformity)
    coefficients = _hertz_coefficients(geometry.cos_tau)
    C_p = HERTZ_STEEL / coefficients.mu_nu * geometry.d_sum_rho ** (2.0 / 3.0)
    return C_p, coefficients.mu_nu, coefficients.result


def conformity_coefficient(conformity: ArrayLike) -> jax.Array:
    """C_p = (858/(μν)) (dΣρ)^(2/3) [MPa·N^(-1/3)·mm^(2/3)] for steel on steel (Ψ ≥ 1.0005)."""
    (conformity,) = _checked(conformity=conformity)
    return _nan_unless(~_outside(conformity=conformity), _conformity_coefficient(conformity)[0])


@pytree_dataclass
class Contact:
    """Hertz contact of one roller on its track under a normal load.

    Attributes:
        p_max: maximum contact pressure [MPa].
        a: semi-axis of the contact ellipse across the track, in the
            conformal groove direction [mm].
        b: semi-axis along the track, in the rolling direction [mm].
        result: per-point code (int32, [`RESULTS`][tripodjax.results.RESULTS]):
            the κ solve's, ``nonfinite`` where an input or the answer is not
            finite, ``outside_validity`` where a (traced) input lies outside its
            domain (the fields are then NaN).
    """

    p_max: jax.Array
    a: jax.Array
    b: jax.Array
    result: jax.Array


def roller_contact(
    load: ArrayLike,
    d: ArrayLike,
    *,
    conformity: ArrayLike,
    young_modulus: ArrayLike = YOUNG_MODULUS_STEEL,
    poisson: ArrayLike = POISSON_STEEL,
) -> Contact:
    """Contact pressure and ellipse semi-axes for a roller load Q [N] on a roller of diameter d [mm].

    a = μ k, b = ν k with k = (3 Q (1 − ν_P²) / (E Σρ))^(1/3), Σρ = dΣρ / d, and
    p_max = 3Q / (2π a b); for steel this is the seed's 858/(μν) (Q Σρ²)^(1/3).

    Args: load Q ≥ 0 [N]; d > 0 [mm]; conformity Ψ ≥ 1.0005; young_modulus
    E > 0 [MPa]; poisson ν_P in (−1, 0.5) [–]. All finite; numbers or non-empty
    arrays (lists too) that broadcast together. Concrete values outside raise
    ``ValueError``; traced ones give NaN and ``outside_validity`` (``nonfinite``
    for a NaN or infinite input).

    At Q = 0 the pressure and semi-axes are 0 and their derivatives with respect to Q
    are +∞ (p_max ∝ Q^(1/3)): the true slope, not NaN.
    """
    load, d, conformity, young_modulus, poisson = _checked(
        load=load, d=d, conformity=conformity, young_modulus=young_modulus, poisson=poisson
    )
    geometry = _geometry(conformity, 0.0)  # flagged below with the other inputs
    coefficients = _hertz_coefficients(geometry.cos_tau)
    sum_rho = geometry.d_sum_rho / d
    compliance = 3.0 * (1.0 - poisson**2) / (young_modulus * sum_rho)  # k³/Q [mm³/N]
    k = jnp.cbrt(load * compliance)
    a, b = coefficients.mu * k, coefficients.nu * k
    # p_max = 3Q/(2π a b) = 3 Q^(1/3) / (2π μν (k³/Q)^(2/3)): 0 at Q = 0 with the slope +∞
    p_max = 1.5 * jnp.cbrt(load) / (jnp.pi * coefficients.mu_nu * jnp.cbrt(compliance) ** 2)
    outside = _outside(
        load=load, d=d, conformity=conformity, young_modulus=young_modulus, poisson=poisson
    )
    finite = _finite(load, d, young_modulus, poisson, p_max, a, b)
    ok = finite & ~outside
    return Contact(
        p_max=_nan_unless(ok, p_max),
        a=_nan_unless(ok, a),
        b=_nan_unless(ok, b),
        result=_code(finite, outside, coefficients.result),
    )


# --------------------------------------------------------------------------- capacities and sizing


def _torque_at_pressure(pressure, d, R, C_p, C_s, n_rollers, pressure_angle, helix_angle, gamma):
    """M(p) [N·m] past the checks, NaN where an input is not finite (its callers flag a traced
    input outside its domain)."""
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
    ok = _finite(pressure, d, R, C_p, C_s, n_rollers, pressure_angle, helix_angle, gamma)
    return _nan_unless(ok, torque_nmm / 1000.0)


def torque_at_pressure(
    pressure: ArrayLike,
    d: ArrayLike,
    R: ArrayLike,
    *,
    C_p: ArrayLike,
    C_s: ArrayLike,
    n_rollers: int = 3,
    pressure_angle: ArrayLike = math.pi / 2,
    helix_angle: ArrayLike = 0.0,
    gamma: ArrayLike = 0.0,
) -> jax.Array:
    """M(p) = ½(1 + cos γ) n_R (p/(C_s C_p))³ d² R sin ε cos ζ, returned in N·m.

    Args: pressure p ≥ 0 [MPa]; d, R > 0 [mm]; C_p > 0
    [MPa·N^(-1/3)·mm^(2/3)]; C_s > 0 [–]; n_rollers an integer ≥ 1;
    pressure_angle ε in (0, π/2], helix_angle ζ in [0, π/2), gamma in
    [0, π/2) [rad]. All finite; numbers or non-empty arrays (lists too) that
    broadcast together. Inside ``jit`` a non-finite input, or one outside its
    domain, gives NaN.
    """
    arguments = dict(zip(locals(), _checked(**locals()), strict=True))  # in order
    return _nan_unless(~_outside(**arguments), _torque_at_pressure(**arguments))


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
        result: per-point code (int32, [`RESULTS`][tripodjax.results.RESULTS]):
            the κ solve's, ``nonfinite`` where an input or a capacity is not
            finite (that capacity is then NaN), ``outside_validity`` where a
            (traced) input lies outside its domain (the capacities are then NaN).
    """

    M_s: jax.Array
    M_d: jax.Array
    M_sd: jax.Array
    C_p: jax.Array
    mu_nu: jax.Array
    result: jax.Array


def capacities(
    d: ArrayLike,
    R: ArrayLike,
    *,
    conformity: ArrayLike,
    P_s: ArrayLike,
    P_d: ArrayLike,
    P_sd: ArrayLike,
    C_s: ArrayLike,
    n_rollers: int = 3,
    pressure_angle: ArrayLike = math.pi / 2,
    helix_angle: ArrayLike = 0.0,
    gamma: ArrayLike = 0.0,
    longitudinal_conformity: ArrayLike = 0.0,
    domain_flags: bool = True,
) -> Capacities:
    """Static and dynamic torque capacities of a joint with roller diameter d and PCR R [mm].

    Args:
        d: roller diameter [mm]; R: track pitch-circle radius [mm]; both > 0.
        conformity: Ψ = 2 R_g / d ≥ 1.0005 (experience range 1.002–1.008;
            `MIN_CONFORMITY`).
        P_s, P_d, P_sd: allowed static, long-lasting and short-lasting
            dynamic contact pressures [MPa], > 0.
        C_s: safety coefficient on the pressure [–], > 0.
        n_rollers: an integer ≥ 1, 3 for a tripod; pressure_angle ε in
            (0, π/2] [rad] (π/2 for a tripod); helix_angle ζ in [0, π/2)
            [rad] (0); gamma: working angle in [0, π/2) [rad] for M_d and M_sd.
        longitudinal_conformity: χ_l in (−1, 1] (0 for straight tracks; see
            [`contact_geometry`][tripodjax.hertz.contact_geometry]).
        domain_flags: False leaves out the traced inputs' domain flags below, for a
            caller that keeps them inside their domains itself (the optimiser: its
            spec's ranges lie inside them); a non-finite input still gives NaN.

    Every value finite; numbers or non-empty arrays (lists too) that broadcast
    together; concrete values are checked (``ValueError`` / ``TypeError`` naming
    the argument). Inside ``jit`` a non-finite input gives NaN capacities and
    ``result = RESULTS.nonfinite``, a finite one outside its domain NaN and
    ``outside_validity``.
    Differentiable w.r.t. d, R, the conformity and the pressures; any dtype.
    """
    arguments = dict(locals())  # the parameters, as given
    flags = check_flag("domain_flags", arguments.pop("domain_flags"))
    checked = dict(zip(arguments, _checked(**arguments), strict=True))
    return _capacities(**checked, domain_flags=flags)


@functools.partial(latency_bound_at_top_level, small_inputs=True, static_argnames=("domain_flags",))
def _capacities(
    d,
    R,
    conformity,
    P_s,
    P_d,
    P_sd,
    C_s,
    n_rollers,
    pressure_angle,
    helix_angle,
    gamma,
    longitudinal_conformity,
    *,
    domain_flags=True,
):
    """`capacities` past its checks: one compiled program (its operations one by one compiled
    each on a first call)."""
    arguments = {k: v for k, v in locals().items() if k != "domain_flags"}  # each in DOMAINS
    C_p, product, kappa_code = _conformity_coefficient(conformity, longitudinal_conformity)
    common = (C_p, C_s, n_rollers, pressure_angle, helix_angle)
    M_s = _torque_at_pressure(P_s, d, R, *common, 0.0)
    M_d = _torque_at_pressure(P_d, d, R, *common, gamma)
    M_sd = _torque_at_pressure(P_sd, d, R, *common, gamma)
    finite = _finite(M_s, M_d, M_sd)
    outside = jnp.zeros((), bool)
    if domain_flags:  # every input inside its domain (checked where concrete; traced: NaN)
        outside = _outside(**arguments)
        M_s, M_d, M_sd = (_nan_unless(~outside, M) for M in (M_s, M_d, M_sd))
    return Capacities(
        M_s=M_s,
        M_d=M_d,
        M_sd=M_sd,
        C_p=C_p,
        mu_nu=product,
        result=_code(finite, outside, kappa_code),
    )


SIZING_RULES = ("consistent", "workbook")


def min_roller_diameter(
    M_max: ArrayLike,
    *,
    R_over_d: ArrayLike,
    conformity: ArrayLike,
    P_s: ArrayLike,
    C_s: ArrayLike,
    n_rollers: int = 3,
    pressure_angle: ArrayLike = math.pi / 2,
    helix_angle: ArrayLike = 0.0,
    rule: str = "consistent",
    longitudinal_conformity: ArrayLike = 0.0,
) -> tuple[jax.Array, jax.Array]:
    """Smallest roller diameter and pitch-circle radius [mm] for a maximum torque M_max [N·m].

    ``rule="consistent"``: the static capacity equals M_max,
    d³ = M_max / (n_R (R/d) (P_s/(C_s C_p))³ sin ε cos ζ) — Hertz's cube law.

    ``rule="workbook"``: the company workbook's rule (seed §4.2–4.3),
    d³ = (C_p C_s / P_s)² M_max / (n_R (R/d) sin ε cos ζ) with M_max in N·mm.
    It reproduces the workbook's 37.654 mm but is dimensionally inconsistent
    (pressure to the power 2 where Hertz gives 3); kept for reproduction only.

    Args: M_max, R_over_d, P_s, C_s > 0; conformity Ψ ≥ 1.0005; n_rollers an
    integer ≥ 1; angles and longitudinal_conformity as
    [`capacities`][tripodjax.hertz.capacities]; all finite; numbers or non-empty
    arrays (lists too) that broadcast together. Inside ``jit`` a non-finite input,
    or one outside its domain, gives NaN (this function has no result code).

    Returns:
        (d_min, R_min) with R_min = (R/d)·d_min.
    """
    check_choice("rule", rule, SIZING_RULES)
    arguments = dict(
        M_max=M_max,
        R_over_d=R_over_d,
        conformity=conformity,
        P_s=P_s,
        C_s=C_s,
        n_rollers=n_rollers,
        pressure_angle=pressure_angle,
        helix_angle=helix_angle,
        longitudinal_conformity=longitudinal_conformity,
    )
    M_max, R_over_d, conformity, P_s, C_s, n_rollers, pressure_angle, helix_angle, _ = _checked(
        **arguments
    )
    outside = _outside(**arguments)
    C_p = _conformity_coefficient(conformity, longitudinal_conformity)[0]
    geometry_factor = n_rollers * R_over_d * jnp.sin(pressure_angle) * jnp.cos(helix_angle)
    torque_nmm = 1000.0 * M_max
    if rule == "consistent":
        d3 = torque_nmm / (geometry_factor * (P_s / (C_s * C_p)) ** 3)
    else:
        d3 = (C_p * C_s / P_s) ** 2 * torque_nmm / geometry_factor
    ok = _finite(M_max, R_over_d, P_s, C_s, C_p, n_rollers, pressure_angle, helix_angle, d3)
    d_min = _nan_unless(ok & ~outside, jnp.cbrt(d3))
    return d_min, d_min * R_over_d  # (R/d)·d_min
