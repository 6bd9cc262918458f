"""How likely a design is to miss each requirement, given the spec's ``[uncertainty]``.

The requirements are the constraints of the spec (the static capacity and the life
always, then every ``max_<q>`` / ``min_<q>``); requirement i is missed where its
margin g_i(u) < 0, u the independent standard normal variables behind the uncertain
numbers ([`perturb`][tripodjax.optimize.uncertainty.perturb] maps u to the numbers).

- FORM: the Hasofer–Lind index β = ±|u*| of the design point u* (the point of g = 0
  nearest the origin), by HL-RF iterations with a safeguarded step (the merit
  ½|u|² + c|g| of Zhang & Der Kiureghian must decrease by ARMIJO of its linear prediction;
  the step halves until it does),
  exact gradients from JAX (forward mode through the implicit solves). P ≈ Φ(−β); the
  importance factors α_i² = (∂g/∂u_i)²/|∇g|² at u* (summing to 1) say which inputs
  matter (with a correlation, the same of the gradient w.r.t. the inputs' correlated
  standard normals y = L u, so that an input the margin does not depend on gets 0).
- SORM from the curvatures κ_j at u* (central differences of the JAX gradient, 2n more
  evaluations): Breitung, Hohenbichler–Rackwitz and Tvedt, all three reported;
  ``probability_sorm`` is Hohenbichler–Rackwitz, P ≈ Φ(−β) Π (1 + ρ κ_j)^(−½) with
  ρ = φ(β)/Φ(−β) (Breitung's asymptotic β replaced by the inverse Mills ratio; within the
  10⁶-sample Monte Carlo interval on the tests' β ≈ 2.4 case, where Tvedt is not, and
  nearer the Monte Carlo than Breitung at β ≈ −1.3). Where β < 0 (the mean of the inputs
  misses) the formulas apply to the safe domain: P = 1 − P_SORM(safe), as in OpenTURNS.
- Monte Carlo: seeded (``jax.random``), in chunks of fixed size (bounded memory, one
  compiled program); the estimate, its standard error and the 95 % Wilson interval; the
  system probability of missing any requirement.
- Importance sampling: u ~ N(u*, I) around each FORM design point, weights φ(u)/φ(u − u*);
  its error depends on how well FORM describes the limit state, not on 1/P, so
  probabilities down to 1e-6 and below cost the same few 10⁴ samples.

Samples whose inner solves (halfshaft, GAF, Hertz κ) did not return ``successful`` are
counted in ``status``; a sample with a non-finite margin counts as a miss (never dropped).
"""

import functools
import math
from collections.abc import Mapping

import jax
import jax.numpy as jnp
import numpy as np
from jax.scipy.special import log_ndtr, ndtr

from tripodjax._checks import check_integer
from tripodjax.optimize import uncertainty
from tripodjax.optimize._compiled import call, latency_bound_jit
from tripodjax.optimize.problem import (
    check_spec,
    constraint_names,
    design_values,
    fixed_design,
    limit_state,
    requirement_structure,
)
from tripodjax.optimize.spec import REVOLUTION_QUANTITIES, Spec
from tripodjax.results import RESULTS

METHODS = ("form", "mc", "is", "all")
MAX_ITERATIONS = 100  # HL-RF iterations (accepted steps)
MAX_EVALUATIONS = 400  # model evaluations of one FORM search, backtracks included
ARMIJO = 0.1  # sufficient decrease of the HL-RF merit, a fraction of its linear prediction
TOLERANCE = 1e-6  # HL-RF stops when |u_HL − u| ≤ TOLERANCE · (1 + |u|)
SORM_STEP = 1e-4  # central-difference step of the curvatures in u
Z95 = 1.959963984540054  # Φ⁻¹(0.975)
DEFAULT_SAMPLES = 100_000
DEFAULT_IS_SAMPLES = 20_000
# Samples per compiled call: Hertz and life alone 2^15; with the kinematics (n_theta angles per
# sample) 2^11, which keeps a chunk's arrays near the sweep's 2^18 points (measured: 1.5× faster
# than 2^15 samples at n_theta 168).
DEFAULT_CHUNK = 2**15
DEFAULT_CHUNK_KINEMATIC = 2**11
SORM_FORMULAS = ("breitung", "hohenbichler_rackwitz", "tvedt")
IS_BELOW = 1e-3  # method "all": importance sampling where the FORM probability is below this
# Allowed ranges of the arguments (low, high), each checked in one line by `_check`: at most
# 10⁹ draws (about 20 min of the Hertz and life chain at its measured 8.4·10⁵ samples/s); a
# chunk of at most 2^20 samples (the Hertz and life chain holds about 430 bytes a sample:
# 0.45 GB; a chain with the kinematics n_theta times more, keep it near the default 2^11);
# a seed that jax.random.PRNGKey takes (an int64 ≥ 0).
MAX_SAMPLES = 10**9
MAX_CHUNK = 2**20
MAX_SEED = 2**63 - 1
ARGUMENT_RANGES = {
    "samples": (2, MAX_SAMPLES),
    "is_samples": (2, MAX_SAMPLES),
    "chunk": (1, MAX_CHUNK),
    "seed": (0, MAX_SEED),
}


def _value_and_gradient(structure, values, x, u):
    """(margins, ∂margins/∂u, code) at one u: forward mode, one pass per input."""

    def margins(v):
        m, code = limit_state(structure, values, x, v)
        return m, code

    basis = jnp.eye(u.shape[0], dtype=u.dtype)
    value, jac, code = jax.vmap(
        lambda t: jax.jvp(margins, (u,), (t,), has_aux=True), out_axes=(None, 0, None)
    )(basis)
    return value, jac.T, code


def _hlrf(structure, values, x, j):
    """HL-RF with a safeguarded step for requirement j, then the SORM curvatures.

    One flat ``while_loop`` with one model evaluation per iteration (one copy of the model
    in the compiled program): the mean first, then the HL-RF trials, then the 2n points
    u* ± h e_i of the curvature differences. Returns a dict of arrays.
    """
    n = len(structure.uncertainty)
    dtype = values["hertz"]["P_d"].dtype
    eye = jnp.eye(n, dtype=dtype)

    def at(u):
        m, jac, code = _value_and_gradient(structure, values, x, u)
        return m[j], jac[j], jnp.max(code)

    def direction(u, g, grad):
        """The HL-RF step to the linearised surface's nearest point, and the merit weight."""
        norm2 = jnp.dot(grad, grad)
        safe = jnp.where(norm2 > 0, norm2, 1.0)
        target = (jnp.dot(grad, u) - g) / safe * grad
        c = (2.0 * jnp.linalg.norm(target) + 1.0) / jnp.sqrt(safe)
        return target - u, c

    def merit(u, g, c):
        value = 0.5 * jnp.dot(u, u) + c * jnp.abs(g)
        return jnp.where(jnp.isfinite(value), value, jnp.inf)

    zero = jnp.zeros(n, dtype)
    state = dict(
        start=jnp.bool_(True),
        search=jnp.bool_(True),  # False: the curvature points
        i=jnp.int32(0),  # curvature point
        u=zero,
        g=jnp.asarray(0.0, dtype),
        g0=jnp.asarray(0.0, dtype),
        grad=zero,
        code=jnp.int32(0),
        d=zero,
        c=jnp.asarray(0.0, dtype),
        merit=jnp.asarray(jnp.inf, dtype),
        slope=jnp.asarray(0.0, dtype),
        step=jnp.asarray(0.0, dtype),
        k=jnp.int32(0),
        evaluations=jnp.int32(0),
        converged=jnp.bool_(False),
        flat=jnp.bool_(False),
        nonfinite=jnp.bool_(False),
        hessian=jnp.zeros((n, n), dtype),
        done=jnp.bool_(False),
    )

    def iterate(s):
        sign = jnp.where(s["i"] % 2 == 0, 1.0, -1.0)
        offset = sign * SORM_STEP * eye[jnp.minimum(s["i"] // 2, n - 1)]
        y = jnp.where(s["search"], s["u"] + s["step"] * s["d"], s["u"] + offset)
        g, grad, code = at(y)
        # HL-RF: accept a trial when the merit decreases by ARMIJO × the linear prediction
        # (always at the mean); a plain decrease lets HL-RF oscillate across a limit state
        # curved by κβ ≈ 1, each full step a little lower than the last.
        trial = merit(y, g, s["c"])
        accepted = s["search"] & (
            s["start"]
            | (
                (trial < s["merit"])
                & (trial <= s["merit"] + ARMIJO * s["step"] * s["slope"])
                & jnp.all(jnp.isfinite(grad))
            )
        )
        d, c = direction(y, g, grad)
        slope = jnp.minimum(jnp.dot(y + c * jnp.sign(g) * grad, d), 0.0)  # ∇merit · d
        small = jnp.linalg.norm(d) <= TOLERANCE * (1.0 + jnp.linalg.norm(y))
        # At the mean: a margin or gradient that is not finite leaves FORM without a start (not
        # converged, β NaN); a finite zero gradient: g does not depend on u (β = ±∞).
        nonfinite = s["start"] & ~(jnp.isfinite(g) & jnp.all(jnp.isfinite(grad)))
        flat = s["start"] & ~nonfinite & (jnp.dot(grad, grad) == 0)
        converged = (s["converged"] | (accepted & small) | flat) & ~nonfinite
        k = s["k"] + (accepted & ~s["start"]).astype(jnp.int32)
        evaluations = s["evaluations"] + 1
        stalled = s["search"] & ~accepted & (s["step"] < 1e-12)
        over = (k >= MAX_ITERATIONS) | (evaluations >= MAX_EVALUATIONS)
        search_over = s["search"] & (converged | stalled | over | nonfinite)

        def keep(new, old):
            return jnp.where(accepted, new, old)

        # The curvature points: row i//2 of the Hessian by central differences of ∇g.
        row = jnp.where(s["search"], 0.0, sign * grad / (2.0 * SORM_STEP))
        hessian = s["hessian"].at[jnp.minimum(s["i"] // 2, n - 1)].add(row)
        i = s["i"] + (~s["search"]).astype(jnp.int32)
        return dict(
            start=jnp.bool_(False),
            search=s["search"] & ~search_over,
            i=i,
            u=keep(y, s["u"]),
            g=keep(g, s["g"]),
            g0=jnp.where(s["start"], g, s["g0"]),
            grad=keep(grad, s["grad"]),
            code=jnp.maximum(s["code"], code),
            d=keep(d, s["d"]),
            c=keep(c, s["c"]),
            merit=keep(merit(y, g, c), s["merit"]),
            slope=keep(slope, s["slope"]),
            step=jnp.where(accepted, 1.0, 0.5 * s["step"]),
            k=k,
            evaluations=evaluations,
            converged=converged,
            flat=s["flat"] | flat,
            nonfinite=s["nonfinite"] | nonfinite,
            hessian=hessian,
            done=(search_over & (flat | nonfinite)) | (~s["search"] & (i >= 2 * n)),
        )

    s = jax.lax.while_loop(lambda s: ~s["done"], iterate, state)
    u, grad, flat, nonfinite = s["u"], s["grad"], s["flat"], s["nonfinite"]
    norm = jnp.linalg.norm(grad)
    sign = jnp.where(s["g0"] >= 0, 1.0, -1.0)
    beta = jnp.where(flat, sign * jnp.inf, sign * jnp.linalg.norm(u))
    beta = jnp.where(nonfinite, jnp.nan, beta)  # never a probability of 0 or 1
    # SORM: the curvatures are the eigenvalues of the tangential Hessian / |∇g|.
    hessian = 0.5 * (s["hessian"] + s["hessian"].T)
    normal = grad / jnp.where(norm > 0, norm, 1.0)
    tangent = eye - jnp.outer(normal, normal)
    kappa = jnp.linalg.eigvalsh(tangent @ hessian @ tangent / jnp.where(norm > 0, norm, 1.0))
    sorm = _sorm(beta, kappa)
    # Importance: the squared direction cosines of the margin's gradient w.r.t. the inputs'
    # (correlated) standard normal variables y = L u; with no correlation these are α².
    cosines = grad
    if "correlation" in values["uncertainty"]:
        cholesky = jnp.linalg.cholesky(values["uncertainty"]["correlation"])
        cosines = jax.scipy.linalg.solve_triangular(cholesky.T, grad, lower=False)
    importance = cosines**2 / jnp.where(norm > 0, jnp.dot(cosines, cosines), 1.0)
    return dict(
        beta=beta,
        probability=ndtr(-beta),
        probability_sorm=sorm["hohenbichler_rackwitz"],
        probability_sorm_breitung=sorm["breitung"],
        probability_sorm_hohenbichler_rackwitz=sorm["hohenbichler_rackwitz"],
        probability_sorm_tvedt=sorm["tvedt"],
        design_point=u,
        importance=jnp.where(flat, 0.0, jnp.where(nonfinite, jnp.nan, importance)),
        converged=s["converged"],
        nonfinite=nonfinite,
        iterations=s["k"],
        evaluations=s["evaluations"],
        g_at_point=s["g"],
        step_left=jnp.linalg.norm(s["d"]),
        code=jnp.maximum(s["code"], jnp.where(nonfinite, RESULTS.nonfinite, RESULTS.successful)),
        curvatures=kappa,
    )


def _sorm(beta, kappa):
    """The SORM probabilities of g < 0 from the FORM index β and the curvatures κ at u*.

    Where β ≥ 0 (the origin safe) the paraboloid through u* bounds the failure domain;
    where β < 0 (the origin fails) it bounds the safe one, so the formulas give the safe
    probability, from |β| and the curvatures of the complement (−κ: g's curvatures seen
    from the other side), and P = 1 − that (as OpenTURNS' ``SORMResult`` does; the
    Breitung factors 1 + |β|(−κ) = 1 + βκ are the same either way). Breitung
    Φ(−b) Π (1 + bκ)^(−½), Hohenbichler–Rackwitz Φ(−b) Π (1 + ρκ)^(−½) with the inverse
    Mills ratio ρ = φ(b)/Φ(−b), and Tvedt's three-term formula (exact for the paraboloid).
    NaN where a factor is ≤ 0, β is not finite or the result leaves [0, 1].
    """
    side = jnp.where(beta >= 0, 1.0, -1.0)
    b = jnp.abs(beta)
    k = side * kappa
    tail = ndtr(-b)
    density = jnp.exp(-0.5 * b * b) / math.sqrt(2.0 * math.pi)
    mills = jnp.exp(-0.5 * b * b - 0.5 * math.log(2.0 * math.pi) - log_ndtr(-b))

    def product(factors):
        ok = jnp.all(factors > 0)
        return jnp.where(ok, jnp.prod(1.0 / jnp.sqrt(jnp.where(ok, factors, 1.0))), jnp.nan)

    first = product(1.0 + b * k)
    breitung = tail * first
    hohenbichler = tail * product(1.0 + mills * k)
    # Tvedt (1990): A1 + A2 + A3, A1 Breitung's; the complex root is the principal one.
    rho = b * tail - density
    second = product(1.0 + (1.0 + b) * k)
    third = jnp.prod(1.0 / jnp.sqrt(1.0 + (b + 1j) * k)).real
    tvedt = breitung + rho * (first - second) + (b + 1.0) * rho * (first - third)

    def event(p):
        p = jnp.where(beta >= 0, p, 1.0 - p)
        return jnp.where(jnp.isfinite(beta) & (p >= 0) & (p <= 1), p, jnp.nan)

    return dict(
        breitung=event(breitung), hohenbichler_rackwitz=event(hohenbichler), tvedt=event(tvedt)
    )


@functools.partial(latency_bound_jit, static_argnums=0)
def _form(structure, values, x):
    count = len(constraint_names(structure))
    return jax.vmap(lambda j: _hlrf(structure, values, x, j))(jnp.arange(count))


@functools.partial(jax.jit, static_argnums=0)
def _sample_chunk(static, values, x, key, index, shift, valid):
    """Weighted miss sums of one chunk of ``size`` samples u = shift + z, z ~ N(0, I).

    Returns (Σ w·miss, Σ (w·miss)² per requirement, Σ w·(any miss), Σ (w·any)²,
    samples with a failed inner solve, samples with a non-finite margin); only the first
    ``valid`` rows count (the last chunk is padded).
    """
    structure, size = static
    n = len(structure.uncertainty)
    z = jax.random.normal(jax.random.fold_in(key, index), (size, n), shift.dtype)
    u = shift + z
    weight = jnp.exp(-u @ shift + 0.5 * jnp.dot(shift, shift))  # φ(u)/φ(u − shift)
    margins, codes = jax.vmap(lambda v: limit_state(structure, values, x, v))(u)
    live = jnp.arange(size) < valid
    # A margin that is not finite (NaN, or an infinity the model overflowed to) is a miss.
    miss = ~(jnp.isfinite(margins) & (margins >= 0)) & live[:, None]
    wm = jnp.where(miss, weight[:, None], 0.0)
    system = jnp.where(jnp.any(miss, axis=1), weight, 0.0)
    failed = jnp.sum((jnp.max(codes, axis=1) != RESULTS.successful) & live)
    nonfinite = jnp.sum(~jnp.all(jnp.isfinite(margins), axis=1) & live)
    return (
        jnp.sum(wm, 0),
        jnp.sum(wm**2, 0),
        jnp.sum(system),
        jnp.sum(system**2),
        failed,
        nonfinite,
    )


def _sample(structure, values, x, samples, seed, chunk, shift):
    """Sums over ``samples`` draws in chunks of ``chunk``: estimates and their variances."""
    key = jax.random.PRNGKey(seed)
    totals = None
    for index, start in enumerate(range(0, samples, chunk)):
        valid = min(chunk, samples - start)
        out = call(
            _sample_chunk,
            (structure, chunk),
            values,
            x,
            key,
            np.int32(index),
            shift,
            np.int64(valid),
        )
        out = [np.asarray(a, np.float64) for a in out]
        totals = out if totals is None else [t + a for t, a in zip(totals, out, strict=True)]
    s1, s2, sys1, sys2, failed, nonfinite = totals
    mean, system = s1 / samples, sys1 / samples
    se = np.sqrt(np.maximum(s2 / samples - mean**2, 0.0) / max(samples - 1, 1))
    system_se = math.sqrt(max(sys2 / samples - system**2, 0.0) / max(samples - 1, 1))
    return mean, se, system, system_se, int(failed), int(nonfinite)


def wilson(probability, samples, z=Z95):
    """The Wilson score interval of a Monte Carlo proportion (exact at 0 and 1 hits)."""
    centre = (probability + z * z / (2 * samples)) / (1 + z * z / samples)
    half = (
        z
        / (1 + z * z / samples)
        * math.sqrt(probability * (1 - probability) / samples + z * z / (4 * samples**2))
    )
    low = 0.0 if probability <= 0.0 else max(0.0, centre - half)  # no rounding above 0 hits
    high = 1.0 if probability >= 1.0 else min(1.0, centre + half)
    return [low, high]


def _float(value):
    value = float(value)
    return value if math.isfinite(value) else None


def _check(spec, design, method, samples, is_samples, chunk, seed):
    check_spec(spec)
    if not spec.structure.uncertainty:
        raise ValueError(
            "the spec has no [uncertainty] entry: give distributions on its numbers "
            "(e.g. uncertainty.DEFAULT_TOLERANCES_TOML)"
        )
    if method not in METHODS:
        raise ValueError(f"method = {method!r} is not allowed; allowed: {', '.join(METHODS)}")
    given = {"samples": samples, "is_samples": is_samples, "chunk": chunk, "seed": seed}
    for name, (low, high) in ARGUMENT_RANGES.items():
        value = given[name]
        if np.ndim(value) != 0:  # an array of integers is no count
            raise TypeError(f"{name} = {value!r:.60} is not allowed; allowed: one integer")
        if value is not None or name != "chunk":  # chunk None: the default
            check_integer(name, value, low, high)
    if design is None:
        design = fixed_design(spec.values)
    return design


def reliability(
    spec: Spec,
    design: Mapping[str, float] | None = None,
    method: str = "all",
    *,
    samples: int = DEFAULT_SAMPLES,
    is_samples: int = DEFAULT_IS_SAMPLES,
    seed: int = 0,
    chunk: int | None = None,
) -> dict:
    """The probability of missing each requirement of the spec at a design.

    Args:
        spec: a [`Spec`][tripodjax.optimize.Spec] with an ``[uncertainty]`` section.
        design: ``{variable: value}`` in spec units, as for
            [`evaluate`][tripodjax.optimize.evaluate] (every free variable; the uncertain
            design variables vary around these values). None: the spec's own values.
        method: ``"form"`` (FORM and SORM), ``"mc"`` (Monte Carlo, ``samples`` draws),
            ``"is"`` (FORM, then importance sampling at each design point,
            ``is_samples`` draws), ``"all"`` (FORM, Monte Carlo, and importance sampling
            where the FORM probability is below 1e-3).
        samples, is_samples, seed, chunk: Monte Carlo draws, importance-sampling draws
            per requirement (each 2 to 10⁹), the seed of ``jax.random`` (0 to 2⁶³ − 1), draws
            per compiled call (1 to 2^20, bounding its memory: about 430 bytes a sample for
            the Hertz and life chain, n_theta times more with the kinematics; None: 2^15, or
            2^11 when a requirement needs the kinematics).

    Returns:
        ``{"method", "inputs": {key: description}, "requirements": [{"name",
        "beta_form", "probability_form", "probability_sorm", "probability_mc",
        "mc_standard_error", "mc_interval_95", "samples", "probability_is",
        "is_standard_error", "is_interval_95", "agree", "agree_basis",
        "importance": {key: α²},
        "design_point": {key: value}, "form_converged", "form_iterations", "form_note"
        (only where FORM did not converge)}],
        "disagree": [names], "system_probability_mc", "system_interval_95",
        "system_bounds_form", "status": {...}}``; besides ``probability_sorm``
        (Hohenbichler–Rackwitz) each requirement has ``probability_sorm_breitung``,
        ``probability_sorm_hohenbichler_rackwitz`` and ``probability_sorm_tvedt`` (for
        β < 0 each the complement of the safe domain's). ``agree``: the SORM probability
        (the FORM one where SORM does not apply: β not finite or a curvature factor ≤ 0;
        ``agree_basis`` says which) lies within the Monte Carlo 95 % interval; absent
        without both. Non-finite numbers are None. Runs in float64 (scoped to the call);
        compiled once per spec structure and chunk size.
    """
    design = _check(spec, design, method, samples, is_samples, chunk, seed)
    structure = requirement_structure(spec.structure)
    if chunk is None:
        kinematic = structure.needs & set(REVOLUTION_QUANTITIES)
        chunk = DEFAULT_CHUNK_KINEMATIC if kinematic else DEFAULT_CHUNK
    values, x = design_values(spec, design)
    names = constraint_names(structure)
    inputs = structure.uncertainty
    keys = [i.name for i in inputs]
    out = {
        "method": method,
        "inputs": {i.name: uncertainty.describe(i, values["uncertainty"][i.name]) for i in inputs},
        "requirements": [{"name": name} for name in names],
    }
    status = {"form_converged": None, "mc_failed_solves": 0, "mc_nonfinite_samples": 0}
    with jax.enable_x64(True):  # float64, scoped to this call
        values = jax.tree_util.tree_map(lambda a: jnp.asarray(a, jnp.float64), values)
        x = jnp.asarray(x, jnp.float64)
        zero = np.zeros(len(inputs))
        form = None
        if method != "mc":
            form = jax.tree_util.tree_map(np.asarray, call(_form, structure, values, x))
            mean = uncertainty.nominal(structure, values, x)
            point = np.asarray(
                uncertainty.realize(inputs, values["uncertainty"], mean, form["design_point"])
            )
            degrees = np.array(
                [180.0 / math.pi if i.variable == "gamma0_deg" else 1.0 for i in inputs]
            )
            point = point * degrees
            status["form_converged"] = bool(np.all(form["converged"]))
            for j, row in enumerate(out["requirements"]):
                row.update(
                    beta_form=_float(form["beta"][j]),
                    probability_form=_float(form["probability"][j]),
                    probability_sorm=_float(form["probability_sorm"][j]),
                    **{
                        f"probability_sorm_{formula}": _float(
                            form[f"probability_sorm_{formula}"][j]
                        )
                        for formula in SORM_FORMULAS
                    },
                    importance=dict(zip(keys, map(float, form["importance"][j]), strict=True)),
                    design_point=dict(zip(keys, map(float, point[j]), strict=True)),
                    form_converged=bool(form["converged"][j]),
                    form_iterations=int(form["iterations"][j]),
                    form_result=RESULTS(int(form["code"][j])).name,
                )
                if form["nonfinite"][j]:
                    row["form_note"] = (
                        "the margin or its gradient is not finite at the mean of the inputs "
                        f"(result {row['form_result']}): FORM has no start, no probability"
                    )
                elif not row["form_converged"]:
                    row["form_note"] = (
                        f"HL-RF stopped after {int(form['iterations'][j])} steps without reaching "
                        f"the limit state (margin {float(form['g_at_point'][j]):.3g} at its last "
                        "point), e.g. where a bounded input saturates before the margin reaches 0; "
                        "the FORM figures are not an estimate, the Monte Carlo one is"
                    )
            p = np.asarray(form["probability"], float)
            known = p[np.isfinite(p)]  # an unknown P_i leaves the upper bound unknown
            out["system_bounds_form"] = [
                float(np.max(known)) if known.size else None,
                float(min(1.0, np.sum(p))) if known.size == p.size else None,
            ]
        if method in ("mc", "all"):
            mean, se, system, system_se, failed, nonfinite = _sample(
                structure, values, x, samples, seed, chunk, jnp.asarray(zero)
            )
            status.update(mc_failed_solves=failed, mc_nonfinite_samples=nonfinite)
            for j, row in enumerate(out["requirements"]):
                row.update(
                    probability_mc=float(mean[j]),
                    mc_standard_error=float(se[j]),
                    mc_interval_95=wilson(float(mean[j]), samples),
                    samples=samples,
                )
                if form is not None and row["probability_form"] is not None:  # SORM or FORM
                    lo, hi = row["mc_interval_95"]
                    basis = "sorm" if row["probability_sorm"] is not None else "form"
                    row["agree"] = bool(lo <= row[f"probability_{basis}"] <= hi)
                    row["agree_basis"] = basis
            out["disagree"] = [r["name"] for r in out["requirements"] if r.get("agree") is False]
            out["system_probability_mc"] = float(system)
            out["system_standard_error"] = system_se
            out["system_interval_95"] = wilson(float(system), samples)
        if form is not None and method in ("is", "all"):
            status.update(is_failed_solves=0, is_nonfinite_samples=0)
            for j, row in enumerate(out["requirements"]):
                if not np.isfinite(form["beta"][j]):
                    continue  # no design point: g does not depend on u, or no FORM
                if method == "all" and not row["probability_form"] < IS_BELOW:
                    continue
                shift = jnp.asarray(form["design_point"][j])
                mean, se, _, _, failed, nonfinite = _sample(
                    structure, values, x, is_samples, (seed + 1 + j) % (MAX_SEED + 1), chunk, shift
                )
                row.update(
                    probability_is=float(mean[j]),
                    is_standard_error=float(se[j]),
                    is_interval_95=[
                        float(max(0.0, mean[j] - Z95 * se[j])),
                        float(mean[j] + Z95 * se[j]),
                    ],
                    is_samples=is_samples,
                )
                status["is_failed_solves"] += failed
                status["is_nonfinite_samples"] += nonfinite
    out["status"] = status
    return out


REPORT_SAMPLES = 100_000  # the report's Monte Carlo check


def with_default_tolerances(spec: Spec) -> Spec:
    """The spec with ``uncertainty.DEFAULT_TOLERANCES_TOML`` as its [uncertainty] section."""
    import tomllib

    check_spec(spec)
    return spec.replace_values(**tomllib.loads(uncertainty.DEFAULT_TOLERANCES_TOML))


def report_reliability(spec: Spec, design: Mapping[str, float], default_tolerances: bool = False):
    """The report's reliability section at a design (FORM, SORM and a 10⁵-sample Monte Carlo
    check, importance sampling below 1e-3), or None when the spec has no [uncertainty] and
    ``default_tolerances`` is off (then the default tolerances apply)."""
    check_spec(spec)
    source = "spec"
    if not spec.structure.uncertainty:
        if not default_tolerances:
            return None
        spec, source = with_default_tolerances(spec), "default (docs/reliability.md)"
    out = reliability(spec, design, "all", samples=REPORT_SAMPLES)
    out["tolerances"] = source
    return out
