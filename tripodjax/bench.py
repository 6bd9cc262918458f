"""``python -m tripodjax.bench``: throughput and accuracy of the solver levels, side by side.

Measures, in one process on the current machine, each solver level
([`tripodjax.solvers`][tripodjax.solvers]: newton, analytic, closed_form) and dtype of
[`tripodjax.sweep`][tripodjax.sweep.sweep] against two peers solving the same equations on the
same grid (one period of ``n_theta`` angles per layout):

- a vectorised NumPy Newton of the scaled residual pair (same closed-form
  Jacobian, same tolerance, dψ/dθ by the implicit function theorem);
- a per-point ``scipy.optimize.fsolve`` loop on the printed pair, the seed's
  own workflow, on a subsample (SciPy: the ``bench`` extra, ``pip install "tripodjax[bench]"``).

It prints points/s (layouts × angles solved per second, ``sweep`` with its
default outputs), the ratios to newton in the same dtype and to the peers,
the machine's limit for the Newton sweep (XLA's rate for one polynomial Newton
step and for sines, measured in the same run), the cost of each output, the
cost of a gradient relative to the forward pass, and the error of delta_pp,
irregularity, gamma_pp and ecc_max
against converged float64 — over the seed's design range (the timed set) and
over the whole domain (R/l log-uniform 1e-3…0.2, γ0 uniform 0…45°, plus the
corner R/l = 0.2, γ0 = 45°); and writes the figures as JSON. Absolute times
do not transfer between machines; the ratios measured in one run do.
"""

import argparse
import datetime
import json
import os
import platform
import re
import subprocess
import sys
import time
from collections.abc import Sequence
from typing import Any

import numpy as np

from tripodjax._cli import ArgumentParser, count, counts, finish, output_file, write_json

COMPARED = ("delta_pp", "irregularity", "gamma_pp", "ecc_max")
SOLVERS = ("newton", "analytic", "closed_form")


def measured_on() -> dict[str, Any]:
    """Where and when a bench ran, written beside its figures (the docs' tables name it).

    The CPU's model name (Linux's /proc/cpuinfo, else what `platform` knows), its core count,
    the load average as the figures are written (a shared machine's noise), the UTC date and the
    versions that produced the figures.
    """
    import jax

    import tripodjax

    return {
        "cpu": cpu_model(),
        "cpu_count": os.cpu_count(),
        "load_average": [round(x, 2) for x in os.getloadavg()]
        if hasattr(os, "getloadavg")
        else None,
        "date": datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M UTC"),
        "python": platform.python_version(),
        "jax": jax.__version__,
        "backend": jax.default_backend(),
        "tripodjax": tripodjax.__version__,
    }


def random_layouts(n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Layouts drawn uniformly over R 18–42 mm, l 300–800 mm, γ0 5–25° (the seed's design range)."""
    rng = np.random.default_rng(seed)
    return rng.uniform(18, 42, n), rng.uniform(300, 800, n), np.radians(rng.uniform(5, 25, n))


def domain_layouts(n: int, seed: int = 1) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Layouts over the whole domain: R/l log-uniform 1e-3…0.2, γ0 uniform 0…45°, l 50–2000 mm.

    The first eighth sits on the edges R/l = 0.2 or γ0 = 45°, the corner included.
    """
    rng = np.random.default_rng(seed)
    top = 0.2  # the bound itself: the domain check allows float32's rounding of it
    ratio = np.exp(rng.uniform(np.log(1e-3), np.log(top), n))
    gamma0 = rng.uniform(0.0, np.pi / 4, n)
    edge = max(n // 16, 1)
    ratio[:edge], gamma0[edge : 2 * edge] = top, np.pi / 4
    ratio[0], gamma0[0] = top, np.pi / 4
    l = np.exp(rng.uniform(np.log(50.0), np.log(2000.0), n))
    return ratio * l, l, gamma0


# --------------------------------------------------------------------------- NumPy peer


NUMPY_RTOL = 32 * np.finfo(float).eps


def numpy_newton_metrics(
    R: np.ndarray,
    l: np.ndarray,
    gamma0: np.ndarray,
    n_theta: int,
    rtol: float = NUMPY_RTOL,
    max_steps: int = 24,
) -> dict[str, Any]:
    """delta_pp, irregularity, gamma_pp by a vectorised NumPy Newton of the same scaled pair.

    The residual and closed-form Jacobian are the library's own
    ([`scaled_system`][tripodjax.halfshaft.scaled_system] with NumPy as the array
    module), with the same start, tolerance and implicit dψ/dθ: the peer
    differs only in running on NumPy.
    """
    from tripodjax.halfshaft import (
        analytic_unknowns,
        first_order_amplitude,
        layout_constants,
        newton_step,
        scaled_system,
    )

    n_period = n_theta // 3
    theta = np.arange(n_period) * (2 * np.pi / 3 / n_period)
    R, l, g0 = (np.asarray(a, float)[:, None] for a in (R, l, gamma0))
    theta = np.broadcast_to(theta, (R.shape[0], n_period))
    consts = layout_constants(np, R, l, g0, theta)
    scale = first_order_amplitude(consts)
    delta, v = analytic_unknowns(np, consts, theta)
    for _ in range(max_steps):
        d_delta, d_v = newton_step(*scaled_system(np, consts, delta, v))
        delta, v = delta + d_delta, v + d_v
        if np.all(
            np.maximum(np.abs(d_delta), np.abs(d_v))
            <= rtol * (np.maximum(np.abs(delta), np.abs(v)) + scale)
        ):
            break
    # dψ/dθ = 1 − dΔ/dθ by the implicit function theorem, J·d(Δ, v)/dθ = −∂g/∂θ. g depends on θ
    # only through 3ψ = 3(θ − Δ), so −∂g/∂θ is the Δ-column of J less its direct Δ terms
    # (−H cos Δ in j11, H sin Δ in j21); newton_step(b, J) = −J⁻¹b then gives −dΔ/dθ.
    _, jacobian = scaled_system(np, consts, delta, v)
    (j11, _), (j21, _) = jacobian
    H = consts["H"]
    minus_d_delta = newton_step((j11 + H * np.cos(delta), j21 - H * np.sin(delta)), jacobian)[0]
    gamma = g0 * (1 + v)
    return {
        "delta_pp": np.ptp(delta, axis=1),
        "irregularity": np.ptp(1 + minus_d_delta, axis=1),
        "gamma_pp": np.ptp(g0 * v, axis=1),
        "ecc_max": np.max(R * np.sin(gamma / 2) ** 2 / np.cos(gamma), axis=1),
    }


# --------------------------------------------------------------------------- fsolve peer


def _printed_pair(x, theta, R, l, gamma0):
    psi, gamma = x
    h = -l * np.sin(gamma0) - 0.5 * R * (1 - np.cos(gamma0))
    e = 0.5 * R * (1 - np.cos(gamma)) / np.cos(gamma)
    return [
        h * np.sin(theta - psi) - e * np.sin(3 * psi),
        h * np.cos(theta - psi) + l * np.sin(gamma) + e * np.cos(gamma) * np.cos(3 * psi),
    ]


def fsolve_metrics(
    R: np.ndarray, l: np.ndarray, gamma0: np.ndarray, n_theta: int
) -> dict[str, np.ndarray]:
    """The seed's workflow: fsolve per angle on the printed pair, dψ/dθ by central differences."""
    import warnings

    from scipy.optimize import fsolve

    n_period = n_theta // 3
    theta = np.arange(n_period) * (2 * np.pi / 3 / n_period)
    out: dict[str, list[float]] = {name: [] for name in COMPARED}
    step = 1e-6
    warnings.filterwarnings("ignore", "The iteration is not making good progress", RuntimeWarning)
    for Ri, li, gi in zip(R, l, gamma0, strict=False):
        psi, gamma, slope = [], [], []
        for t in theta:
            x = fsolve(_printed_pair, [t, gi], args=(t, Ri, li, gi), xtol=1e-13)
            xp = fsolve(_printed_pair, x, args=(t + step, Ri, li, gi), xtol=1e-13)
            xm = fsolve(_printed_pair, x, args=(t - step, Ri, li, gi), xtol=1e-13)
            psi.append(x[0])
            gamma.append(x[1])
            slope.append((xp[0] - xm[0]) / (2 * step))
        out["delta_pp"].append(np.ptp(theta - np.array(psi)))
        out["irregularity"].append(np.ptp(slope))
        out["gamma_pp"].append(np.ptp(gamma))
        out["ecc_max"].append(np.max(0.5 * Ri * (1 - np.cos(gamma)) / np.cos(gamma)))
    return {name: np.array(values) for name, values in out.items()}


# --------------------------------------------------------------------------- the machine's limit

# Transcendental functions per exact-sine Newton iteration of one angle: the sine and cosine of
# Δ/2 and of (γ − γ0)/2 (scaled_system). The polynomial steps, the θ-rate by the implicit
# function theorem and the metrics need none over the layout domain.
TRANSCENDENTALS_PER_EXACT_ITERATION = 4


def sine_rate(dtype: Any = np.float64, n: int = 2**18, repeats: int = 5) -> float:
    """XLA's float64 sines per second on this machine: jnp.sin over a cache-sized array (a sweep chunk)."""
    import jax
    import jax.numpy as jnp

    x = jax.device_put(np.linspace(-3.0, 3.0, n).astype(dtype))
    sine = jax.jit(jnp.sin)
    seconds = _best_time(lambda: jax.block_until_ready(sine(x)), repeats)
    return n / seconds


def newton_step_rate(n_theta: int = 360, n_points: int = 2**18, repeats: int = 5) -> float:
    """Polynomial Newton steps per second (float64) over a sweep chunk, as XLA compiles them here.

    The marginal cost of a step: ``halfshaft._polynomial_steps`` with 10 steps less with 2,
    over the angles of a chunk (2^18 points), so the start and the loop's setup cancel.
    """
    import jax
    import jax.numpy as jnp

    from tripodjax.halfshaft import _polynomial_steps, analytic_unknowns, layout_constants
    from tripodjax.kinematics import period_grid

    theta = period_grid(n_theta, np.float64)
    n_layouts = max(1, n_points // theta.shape[0])
    R, l, g0 = (jnp.asarray(a)[:, None] for a in random_layouts(n_layouts))

    def steps(count):
        def run(R, l, g0):
            consts = layout_constants(jnp, R, l, g0, theta)
            guess = jnp.broadcast_arrays(*analytic_unknowns(jnp, consts, theta))
            return _polynomial_steps(consts, jax.lax.complex(*guess), count)[1]

        run = jax.jit(run)
        return _best_time(lambda: jax.block_until_ready(run(R, l, g0)), repeats)

    few, many = steps(2), steps(10)
    return 8 * n_layouts * theta.shape[0] / max(many - few, 1e-9)


def newton_loop_iterations(layouts: Any, n_theta: int) -> int:
    """Iterations the Newton loop runs for a chunk: the largest any angle of the set needs."""
    import jax
    import jax.numpy as jnp

    from tripodjax.kinematics import revolution

    def most(layout):
        return jnp.max(revolution(layout, n_theta, "newton", with_rates=False)[0].iterations)

    return int(jnp.max(jax.jit(jax.vmap(most))(layouts)))


# --------------------------------------------------------------------------- measurements


def _best_time(f, repeats):
    f()  # warm-up: compilation
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        f()
        times.append(time.perf_counter() - start)
    return min(times)


def _relative_error(values, reference):
    keep = reference != 0  # γ0 = 0: every metric is 0 exactly at every level
    return float(np.max(np.abs(values[keep] / reference[keep] - 1), initial=0.0))


def run(
    n_layouts: int = 20000,
    n_theta: int = 360,
    fsolve_layouts: int = 20,
    repeats: int = 3,
    gradient_layouts: int = 2000,
    domain_n: int = 2000,
) -> dict[str, Any]:
    import jax

    import tripodjax as tj

    R, l, g0 = random_layouts(n_layouts)
    points = n_layouts * (n_theta // 3)
    results: dict[str, Any] = {
        "machine": platform.machine(),
        "processor": platform.processor(),
        "cpu_count": os.cpu_count(),
        "jax": jax.__version__,
        "backend": jax.default_backend(),
        "devices": len(jax.devices()),
        "n_layouts": n_layouts,
        "n_theta": n_theta,
        "angles_solved_per_layout": n_theta // 3,
        "domain_layouts": domain_n,
        "variants": {},
    }

    def layouts(dtype, R=R, l=l, g0=g0):
        return tj.Layout(*(np.asarray(a, dtype) for a in (R, l, g0)))

    reference = tj.sweep(layouts(np.float64), n_theta=n_theta, outputs=COMPARED)
    dR, dl, dg = domain_layouts(domain_n)
    domain_reference = tj.sweep(
        layouts(np.float64, dR, dl, dg), n_theta=n_theta, outputs=(*COMPARED, "error_estimate")
    )
    for solver in SOLVERS:
        for dtype in (np.float64, np.float32):
            batch = layouts(dtype)
            holder: dict[str, Any] = {}

            def call(holder=holder, batch=batch, solver=solver):  # the default outputs
                holder["r"] = tj.sweep(batch, n_theta=n_theta, solver=solver)

            seconds = _best_time(call, repeats)
            domain = tj.sweep(
                layouts(dtype, dR, dl, dg),
                n_theta=n_theta,
                solver=solver,
                outputs=(*COMPARED, "error_estimate"),
            )
            name = f"{solver}/{np.dtype(dtype).name}"
            results["variants"][name] = {
                "seconds": seconds,
                "points_per_s": points / seconds,
                "errors_vs_newton_float64": {
                    k: _relative_error(holder["r"][k].astype(float), reference[k]) for k in COMPARED
                },
                "domain_errors_vs_newton_float64": {
                    k: _relative_error(domain[k].astype(float), domain_reference[k])
                    for k in COMPARED
                },
                "domain_max_error_estimate": float(np.max(domain["error_estimate"])),
            }
    for name, entry in results["variants"].items():
        newton = results["variants"]["newton/" + name.split("/")[1]]
        entry["speedup_vs_newton_same_dtype"] = newton["seconds"] / entry["seconds"]

    from tripodjax.halfshaft import POLYNOMIAL_STEPS

    iterations = newton_loop_iterations(layouts(np.float64), n_theta)
    exact = max(0, iterations - (POLYNOMIAL_STEPS + 1))
    newton_rate = results["variants"]["newton/float64"]["points_per_s"]
    step_rate = newton_step_rate(n_theta)
    # A solved angle: its polynomial steps, and one more Jacobian solve for dψ/dθ.
    steps_per_angle = POLYNOMIAL_STEPS + 2
    results["machine_limit"] = {
        "sines_per_s": sine_rate(),
        "newton_loop_iterations": iterations,
        "polynomial_iterations": POLYNOMIAL_STEPS + 1,
        "exact_iterations": exact,
        "transcendentals_per_solved_angle": TRANSCENDENTALS_PER_EXACT_ITERATION * exact,
        "polynomial_steps_per_s": step_rate,
        "steps_per_solved_angle": steps_per_angle,
        "limit_points_per_s": step_rate / steps_per_angle,
        "newton_fraction_of_limit": newton_rate * steps_per_angle / step_rate,
    }

    holder = {}
    numpy_seconds = _best_time(
        lambda: holder.update(r=numpy_newton_metrics(R, l, g0, n_theta)), repeats
    )
    results["numpy_newton"] = {
        "seconds": numpy_seconds,
        "points_per_s": points / numpy_seconds,
        "errors_vs_newton_float64": {
            k: _relative_error(holder["r"][k], reference[k]) for k in COMPARED
        },
    }
    sub = slice(0, fsolve_layouts)
    start = time.perf_counter()
    fs = fsolve_metrics(R[sub], l[sub], g0[sub], n_theta)
    fsolve_seconds = time.perf_counter() - start
    fsolve_points = fsolve_layouts * (n_theta // 3)
    results["fsolve_loop"] = {
        "layouts": fsolve_layouts,
        "seconds": fsolve_seconds,
        "points_per_s": fsolve_points / fsolve_seconds,
        "errors_vs_newton_float64": {
            k: _relative_error(fs[k], reference[k][sub]) for k in COMPARED
        },
    }
    results["fsolve_loop"]["max_abs_irregularity_difference"] = float(
        np.max(np.abs(fs["irregularity"] - reference["irregularity"][sub]))
    )

    results["gradient_to_forward"] = gradient_to_forward(
        layouts(np.float64, R[:gradient_layouts], l[:gradient_layouts], g0[:gradient_layouts]),
        n_theta,
        repeats,
    )
    return results


def gradient_to_forward(batch: Any, n_theta: int = 360, repeats: int = 3) -> dict[str, Any]:
    """Seconds of the gradient of a batch's summed irregularity w.r.t. every layout field
    (R, l, γ0; newton) against its forward pass, both compiled: the best call of ``repeats``
    rounds (10 at the least), each round three forward calls then three gradient calls, so that
    a shared machine's busy moments fall on both (a call takes milliseconds: timed in two
    separate series, the ratio of 2000 layouts ranged 2.8–6.5 on a shared 2-core AMD EPYC)."""
    import jax
    import jax.numpy as jnp

    import tripodjax as tj

    def total(b):
        return jnp.sum(jax.vmap(lambda lay: tj.kinematic_metrics(lay, n_theta).irregularity)(b))

    forward, gradient = jax.jit(total), jax.jit(jax.grad(total))
    calls = (lambda: forward(batch), lambda: gradient(batch))
    for call in calls:  # compile
        jax.block_until_ready(call())
    times: list[list[float]] = [[], []]
    for _ in range(max(repeats, 10)):
        for call, kept in zip(calls, times, strict=True):
            for _ in range(3):  # back to back: the later calls find the CPU's caches warm
                start = time.perf_counter()
                jax.block_until_ready(call())
                kept.append(time.perf_counter() - start)
    t_forward, t_gradient = (min(t) for t in times)
    return {
        "layouts": int(np.shape(batch.R)[0]),
        "forward_s": t_forward,
        "gradient_s": t_gradient,
        "ratio": t_gradient / t_forward,
    }


FORCES_ROW = "every force quantity"  # output_costs' row of the force model's whole set


def output_costs(
    n_layouts: int = 20000,
    n_theta: int = 360,
    repeats: int = 3,
    outputs: Sequence[str] | None = None,
) -> dict[str, Any]:
    """Seconds of ``sweep`` per level (float64) for the default outputs and for each output alone.

    Returns {level: {"default": s, "outputs": {name: s}}}; an output's share of the
    default set is its time alone over the default set's time. The GAF outputs come from
    Lee's friction (``gaf=``), the force model's from ``forces=``; without ``outputs`` a
    last row, ``FORCES_ROW``, times every quantity of the force model in one sweep (the
    running and the LTS case over the revolution; issue 35's target: ≤ 3× the default set).
    """
    import tripodjax as tj
    from tripodjax.sweep import DEFAULT_OUTPUTS, FORCE_ONLY_OUTPUTS, FORCE_OUTPUTS, OUTPUTS

    layouts = tj.Layout(*random_layouts(n_layouts))
    gaf, forces = tj.GAFInputs(500.0), tj.ForceInputs(500.0)
    names = tuple(outputs) if outputs is not None else OUTPUTS
    costs: dict[str, Any] = {"layouts": n_layouts, "default_outputs": list(DEFAULT_OUTPUTS)}
    for solver in SOLVERS:

        def timed(selected, solver=solver, with_forces=False):
            with_forces = with_forces or any(name in FORCE_ONLY_OUTPUTS for name in selected)
            inputs = {"forces": forces} if with_forces else {"gaf": gaf}
            return _best_time(
                lambda: tj.sweep(layouts, n_theta, solver, selected, **inputs), repeats
            )

        costs[solver] = {
            "default": timed(DEFAULT_OUTPUTS),
            "outputs": {name: timed((name,)) for name in names},
        }
        if outputs is None:
            costs[solver]["outputs"][FORCES_ROW] = timed(FORCE_OUTPUTS, with_forces=True)
    return costs


def memory_of_sweep(n_layouts: int, n_theta: int = 360) -> dict[str, Any]:
    """Peak resident memory [MB] a fresh process adds by sweeping n_layouts (newton, float64)."""
    code = (
        "import resource, jax, numpy as np; jax.config.update('jax_enable_x64', True);"
        "import tripodjax as tj; from tripodjax.bench import random_layouts;"
        f"R, l, g = random_layouts({n_layouts}); lay = tj.Layout(R, l, g);"
        "small = tj.Layout(R[:8], l[:8], g[:8]); tj.sweep(small);"
        "before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss;"
        f"tj.sweep(lay, n_theta={n_theta});"
        "after = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss;"
        "print(before / 1024, after / 1024)"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    ).stdout.split()
    before, after = float(out[0]), float(out[1])
    return {
        "layouts": n_layouts,
        "peak_rss_before_mb": before,
        "peak_rss_after_mb": after,
        "added_mb": after - before,
    }


def report(results: dict[str, Any]) -> str:
    lines = [
        f"tripodjax bench — {results['n_layouts']} layouts × {results['angles_solved_per_layout']} angles "
        f"(one period of {results['n_theta']}), backend {results['backend']}, {results['cpu_count']} CPU cores",
        f"{'variant':<26} {'points/s':>10} {'× newton':>9} {'× NumPy':>8} {'× fsolve':>9} "
        f"{'err delta_pp':>13} {'err Irr':>9} {'err gamma_pp':>13} {'err ecc_max':>12}",
    ]
    numpy_rate = results["numpy_newton"]["points_per_s"]
    fsolve_rate = results["fsolve_loop"]["points_per_s"]
    rows = list(results["variants"].items()) + [
        ("numpy Newton (peer)", results["numpy_newton"]),
        (f"fsolve loop ({results['fsolve_loop']['layouts']} layouts)", results["fsolve_loop"]),
    ]
    for name, r in rows:
        e = r["errors_vs_newton_float64"]
        speedup = r.get("speedup_vs_newton_same_dtype")
        speedup = f"{speedup:>9.1f}" if speedup is not None else f"{'':>9}"
        lines.append(
            f"{name:<26} {r['points_per_s']:>10.3g} {speedup} {r['points_per_s'] / numpy_rate:>8.2f} "
            f"{r['points_per_s'] / fsolve_rate:>9.1f} {e['delta_pp']:>13.1e} "
            f"{e['irregularity']:>9.1e} {e['gamma_pp']:>13.1e} {e['ecc_max']:>12.1e}"
        )
    lines.append(
        f"whole domain ({results['domain_layouts']} layouts, R/l ≤ 0.2, γ0 ≤ 45°, corner included):"
    )
    for name, r in results["variants"].items():
        e = r["domain_errors_vs_newton_float64"]
        lines.append(
            f"  {name:<24} err delta_pp {e['delta_pp']:.1e}  Irr {e['irregularity']:.1e}  "
            f"gamma_pp {e['gamma_pp']:.1e}  ecc_max {e['ecc_max']:.1e}  "
            f"largest error estimate {r['domain_max_error_estimate']:.1e}"
        )
    t = results["machine_limit"]
    lines.append(
        f"limit: a polynomial Newton step runs at {t['polynomial_steps_per_s']:.3g} points/s "
        f"here; a newton angle takes {t['steps_per_solved_angle']} ({t['polynomial_iterations']} "
        f"steps + the Jacobian solve for dψ/dθ; exact-sine iterations {t['exact_iterations']}, "
        f"transcendentals per angle {t['transcendentals_per_solved_angle']}; XLA float64 sines "
        f"{t['sines_per_s']:.3g}/s): limit {t['limit_points_per_s']:.3g} points/s, "
        f"newton/float64 reaches {100 * t['newton_fraction_of_limit']:.0f} %"
    )
    if "output_costs" in results:
        lines.extend(cost_table(results["output_costs"], results["n_theta"]))
    g = results["gradient_to_forward"]
    lines.append(
        f"gradient (R, l, γ0) / forward cost, newton float64, {g['layouts']} layouts: {g['ratio']:.2f}"
    )
    if "memory" in results:
        m = results["memory"]
        lines.append(
            f"a {m['layouts']}-layout sweep added {m['added_mb']:.0f} MB to the peak resident memory"
        )
    lines.append(
        "errors: largest relative difference from newton/float64 over the layouts "
        "(the timed set: R 18–42 mm, l 300–800 mm, γ0 5–25°)"
    )
    return "\n".join(lines)


def cost_table(costs: dict[str, Any], n_theta: int) -> list[str]:
    """The per-output cost table: ms per sweep, and the share of the default set, per level."""
    levels = [level for level in SOLVERS if level in costs]
    head = f"{'output (sweep, float64)':<24}" + "".join(
        f" {level + ' ms':>15} {'share':>6}" for level in levels
    )
    lines = [
        f"cost of each output alone, {costs['layouts']} layouts × {n_theta} angles "
        "(share: of the default set's time)",
        head,
    ]
    default = {level: costs[level]["default"] for level in levels}
    row = f"{'default outputs':<24}" + "".join(
        f" {1e3 * default[level]:>15.1f} {'1':>6}" for level in levels
    )
    lines.append(row)
    for name in costs[levels[0]]["outputs"]:
        cells = "".join(
            f" {1e3 * costs[level]['outputs'][name]:>15.1f} "
            f"{costs[level]['outputs'][name] / default[level]:>6.2f}"
            for level in levels
        )
        mark = "*" if name in costs["default_outputs"] else " "
        lines.append(f"{mark}{name:<23}{cells}")
    ratios = "; ".join(
        f"{level} {default['newton'] / default[level]:.1f}× newton"
        for level in levels
        if level != "newton"
    )
    lines.append(f"default outputs (* in the default set): {ratios}")
    return lines


# --------------------------------------------------------------------------- compile latency

# What a user does first, each run in a fresh process with empty caches: (name, what, code).
# The code runs after ``import jax, tripodjax`` (the library floor) and may use the names of
# `_LATENCY_PRELUDE`; a command entry is run as ``optimize-joint`` with the arguments given.
_LATENCY_PRELUDE = "import jax\nimport tripodjax as tj\n"
_CHANCE_SPEC = (
    "from tripodjax.optimize.uncertainty import DEFAULT_TOLERANCES_TOML as T\n"
    "spec = optimize.parse_spec(T + '[constraints]\\nmax_failure_probability_life = 1e-3\\n')\n"
)
LATENCY_ENTRIES: tuple[tuple[str, str, str], ...] = (
    (
        "readme",
        "README's first example: kinematic_metrics of case N, then jax.grad of its irregularity",
        "layout = tj.Layout.from_degrees(R=25.0, l=500.0, gamma0_deg=20.0)\n"
        "m = tj.kinematic_metrics(layout)\n"
        "g = jax.grad(lambda lay: tj.kinematic_metrics(lay).irregularity)(layout)\n"
        "jax.block_until_ready((m, g))\n",
    ),
    (
        "sweep",
        "sweep of 1000 layouts, analytic",
        "from tripodjax.bench import random_layouts\n"
        "tj.sweep(tj.Layout(*random_layouts(1000)), solver='analytic', progress=False)\n",
    ),
    (
        "solve",
        "optimize.solve(load_spec())",
        "from tripodjax import optimize\noptimize.solve(optimize.load_spec(), progress=False)\n",
    ),
    (
        "solve_l_gamma0",
        "optimize.solve, l and γ0 free",
        "from tripodjax import optimize\nfrom tripodjax.optimize.bench import STRUCTURES\n"
        "spec = optimize.parse_spec(STRUCTURES['R, d_roller, l, gamma0_deg'])\n"
        "optimize.solve(spec, progress=False)\n",
    ),
    (
        "solve_conformity",
        "optimize.solve, conformity free",
        "from tripodjax import optimize\nfrom tripodjax.optimize.bench import STRUCTURES\n"
        "spec = optimize.parse_spec(STRUCTURES['R, d_roller, conformity'])\n"
        "optimize.solve(spec, progress=False)\n",
    ),
    (
        "solve_chance",
        "optimize.solve, max_failure_probability_life = 1e-3, documented tolerances",
        "from tripodjax import optimize\n"
        + _CHANCE_SPEC
        + "optimize.solve(spec, progress=False)\n",
    ),
    ("command_cold", "optimize-joint --out DIR, cold", "command"),
    (
        "command_warm",
        "optimize-joint --out DIR, warm (its cache filled by the cold run)",
        "command",
    ),
)
LIBRARY_FLOOR = "import jax, tripodjax"
COMMAND_FLOOR = "import jax, matplotlib.pyplot"  # the command's floor (optimize.bench too)

# The child: records JAX's trace, lowering and compile spans (jax.monitoring: the program's
# name with each) and the time its imports took, runs the entry and prints them as JSON.
_CHILD = """\
import time
start = time.time()
import json, sys
import jax.monitoring
spans = []
jax.monitoring.register_event_time_span_listener(
    lambda event, s, e, **kw: spans.append((event.rsplit('/', 1)[-1], s, e, kw.get('fun_name', '')))
)
{prelude}
imported = time.time()
{code}
print('\\nLATENCY ' + json.dumps({{'start': start, 'imported': imported, 'end': time.time(), 'spans': spans}}))
"""
_COMMAND_CODE = (
    "from tripodjax.optimize.cli import command\n"
    "sys.argv = ['optimize-joint', '--out', {out!r}, '--progress', 'off']\n"
    "try:\n    command()\nexcept SystemExit as e:\n    assert not e.code, e.code\n"
)


def cpu_model() -> str:
    """The CPU's model name (/proc/cpuinfo), or the platform's processor string."""
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def _union(intervals: list[tuple[float, float]]) -> float:
    """Seconds covered by the union of (start, end) intervals (nested spans counted once)."""
    total, reach = 0.0, -np.inf
    for s, e in sorted(intervals):
        if e > reach:
            total += e - max(s, reach)
            reach = e
    return total


def _fresh_process(code: str, env: dict[str, str]) -> tuple[float, dict[str, Any] | None]:
    """Wall seconds of ``python -c code`` and the child's LATENCY record, if it printed one."""
    start = time.perf_counter()
    done = subprocess.run(
        [sys.executable, "-P", "-c", code], capture_output=True, text=True, env=env
    )
    wall = time.perf_counter() - start
    if done.returncode:
        raise RuntimeError(f"latency entry failed: {done.stderr.strip()[-800:]}")
    records = [line for line in done.stdout.splitlines() if line.startswith("LATENCY ")]
    return wall, json.loads(records[-1][8:]) if records else None


def _programs_of(record: dict[str, Any], ir_dir: str) -> list[dict[str, Any]]:
    """Each compiled program: its name, compile seconds and StableHLO size (the dump's kB and ops).

    JAX dumps one ``jax_ir<N>_<name>_compile.mlir`` per compiled program; each compile span
    takes the first dump not yet taken whose name is its program's (``jit(f)`` → ``jit_f``):
    programs compiled in threads (the command's) may finish out of order.
    """
    dumps = sorted(f for f in os.listdir(ir_dir) if f.endswith("_compile.mlir"))
    compiles = sorted(
        (s, e, name) for event, s, e, name in record["spans"] if event.startswith("backend_compile")
    )
    programs = []
    for s, e, name in compiles:
        stem = re.sub(r"\W", "_", name.replace(")", ""))
        dump = next((d for d in dumps if d.split("_", 2)[2] == f"{stem}_compile.mlir"), None)
        size = {"kb": 0.0, "ops": 0}
        if dump is not None:
            dumps.remove(dump)
            with open(os.path.join(ir_dir, dump), encoding="utf-8") as f:
                text = f.read()
            ops = sum(1 for line in text.splitlines() if " = " in line)
            size = {"kb": len(text) / 1e3, "ops": ops}
        programs.append({"name": name, "compile_s": e - s, **size})
    return programs


def _breakdown(wall: float, record: dict[str, Any]) -> dict[str, float]:
    """Wall seconds split into import, trace, lowering, compile and the rest (running, Python)."""
    spans = record["spans"]

    def covered(prefix):
        return _union([(s, e) for event, s, e, _ in spans if event.startswith(prefix)])

    parts = {
        "import_s": record["imported"]
        - record["start"]
        + (wall - (record["end"] - record["start"])),
        "trace_s": covered("jaxpr_trace"),
        "lower_s": covered("jaxpr_to_mlir"),
        "compile_s": covered("backend_compile"),
    }
    # The rest: running and Python. Threads (the command's) may trace, lower and compile at
    # once: the parts then overlap, and the rest is what no span covers.
    busy = _union([(s, e) for _, s, e, _ in spans])
    parts["run_s"] = max(wall - parts["import_s"] - busy, 0.0)
    return parts


def latency(repeats: int = 3, names: Sequence[str] | None = None) -> dict[str, Any]:
    """Each entry of `LATENCY_ENTRIES` (or those ``names``) in fresh processes with empty caches.

    Per repeat, the floors (``python -c "import jax, tripodjax"``, and for the command
    ``import jax, matplotlib.pyplot``) run just before the entries (interleaved: the machine
    may be shared); the figures are medians over the repeats, the programs those of the
    median run. Returns {"measured_on", "repeats", "floors", "entries": {name: {...}}}.
    """
    import tempfile

    selected = [e for e in LATENCY_ENTRIES if names is None or e[0] in names]
    unknown = set(names or ()) - {e[0] for e in LATENCY_ENTRIES}
    if unknown:
        raise ValueError(
            f"latency entries {sorted(unknown)} are not known; allowed: {[e[0] for e in LATENCY_ENTRIES]}"
        )
    floors: dict[str, list[float]] = {"library": [], "command": []}
    runs: dict[str, list[dict[str, Any]]] = {name: [] for name, _, _ in selected}
    base = {k: v for k, v in os.environ.items() if not k.startswith("JAX_COMPILATION_CACHE")}
    for _ in range(repeats):
        floors["library"].append(_fresh_process(LIBRARY_FLOOR, base)[0])
        if any(code == "command" for _, _, code in selected):
            floors["command"].append(_fresh_process(COMMAND_FLOOR, base)[0])
        with tempfile.TemporaryDirectory() as tmp:
            out, cache = os.path.join(tmp, "out"), os.path.join(tmp, "cache")
            for i, (name, _, code) in enumerate(selected):
                ir_dir = os.path.join(tmp, f"ir{i}")
                env = dict(base, TRIPODJAX_CACHE_DIR=cache, JAX_DUMP_IR_TO=ir_dir)
                if code == "command":
                    prelude, code = "", _COMMAND_CODE.format(out=out)
                else:
                    prelude = _LATENCY_PRELUDE
                wall, record = _fresh_process(_CHILD.format(prelude=prelude, code=code), env)
                assert record is not None
                os.makedirs(ir_dir, exist_ok=True)
                runs[name].append(
                    {
                        "wall_s": wall,
                        **_breakdown(wall, record),
                        "programs": _programs_of(record, ir_dir),
                    }
                )
    library = float(np.median(floors["library"]))
    command = float(np.median(floors["command"])) if floors["command"] else library
    entries = {}
    for name, what, code in selected:
        ordered = sorted(runs[name], key=lambda r: r["wall_s"])
        median = ordered[len(ordered) // 2]
        figures = {
            k: float(np.median([r[k] for r in runs[name]])) for k in median if k.endswith("_s")
        }
        floor = command if code == "command" else library
        entries[name] = {
            "what": what,
            **figures,
            "over_floor": figures["wall_s"] / floor,
            "over_library_floor": figures["wall_s"] / library,
            "programs": median["programs"],
        }
    return {
        "measured_on": measured_on(),
        "repeats": repeats,
        # The command floor is the library's when no command entry ran.
        "floors": {"library_s": library, "command_s": command},
        "entries": entries,
    }


def latency_report(results: dict[str, Any], programs: int = 4) -> str:
    """The latency table: per entry, wall seconds and its ratio to the floor, split into import,
    trace, lowering, compile and run, and its largest programs (compile s, StableHLO kB)."""
    f, machine = results["floors"], results["measured_on"]
    lines = [
        f"compile latency — {machine['cpu']}, {machine['cpu_count']} cores; fresh process, empty "
        f"caches, medians of {results['repeats']}; floor `{LIBRARY_FLOOR}` {f['library_s']:.2f} s"
        + f", command floor `{COMMAND_FLOOR}` {f['command_s']:.2f} s",
        f"{'entry':<17} {'wall s':>7} {'× floor':>8} {'import':>7} {'trace':>6} {'lower':>6} "
        f"{'compile':>8} {'run':>6}  largest programs (compile s, StableHLO kB)",
    ]
    for name, e in results["entries"].items():
        largest = sorted(e["programs"], key=lambda p: -p["compile_s"])[:programs]
        named = ", ".join(f"{p['name']} {p['compile_s']:.2f} s {p['kb']:.0f} kB" for p in largest)
        lines.append(
            f"{name:<17} {e['wall_s']:>7.2f} {e['over_floor']:>8.2f} {e['import_s']:>7.2f} "
            f"{e['trace_s']:>6.2f} {e['lower_s']:>6.2f} {e['compile_s']:>8.2f} {e['run_s']:>6.2f}  "
            f"[{len(e['programs'])} programs] {named}"
        )
    lines.append(
        "× floor: the command's entries against the command floor, the others against the library's"
    )
    return "\n".join(lines)


def _names(parser: argparse.ArgumentParser, flag: str, text: str | None, allowed: Sequence[str]):
    """The comma-separated names of ``flag`` (None where not given); an unknown one is the
    parser's one-line error."""
    if text is None:
        return None
    names = text.split(",")
    if not all(names):
        parser.error(
            f"argument {flag}: {text!r} has an empty name; allowed: comma-separated names of "
            f"{', '.join(allowed)}"
        )
    unknown = [name for name in names if name not in allowed]
    if unknown:
        parser.error(
            f"argument {flag}: {', '.join(unknown)} unknown; allowed: {', '.join(allowed)}"
        )
    return names


def main(argv: Sequence[str] | None = None) -> int:
    if argv is None:
        argv = sys.argv[1:]
    if "--latency" in argv:
        return latency_main(argv)
    try:
        import scipy.optimize  # noqa: F401  (the fsolve peer)
    except ModuleNotFoundError:
        print(
            "python -m tripodjax.bench needs SciPy for its fsolve peer: "
            'pip install "tripodjax[bench]"',
            file=sys.stderr,
        )
        return 2
    parser = ArgumentParser(
        prog="python -m tripodjax.bench",
        description=__doc__.split("\n\n")[0],
        epilog="python -m tripodjax.bench --latency [--help]: the compile-latency table instead "
        "(trace, lowering, compile and run time of each first answer, in fresh processes)",
    )
    parser.add_argument(
        "--layouts", type=count(1), default=20000, help="layouts per variant (default 20000)"
    )
    parser.add_argument(
        "--n-theta", type=count(6, 6), default=360, help="angles per revolution (default 360)"
    )
    parser.add_argument(
        "--fsolve-layouts",
        type=count(1),
        default=20,
        help="layouts in the fsolve subsample (default 20)",
    )
    parser.add_argument(
        "--repeats", type=count(1), default=3, help="timed repeats, best kept (default 3)"
    )
    parser.add_argument(
        "--gradient-layouts",
        type=count(1),
        default=2000,
        help="layouts of the gradient-to-forward cost ratio (default 2000)",
    )
    parser.add_argument(
        "--domain-layouts",
        type=count(1),
        default=2000,
        help="layouts of the whole-domain accuracy check (default 2000)",
    )
    parser.add_argument(
        "--cost-layouts",
        type=count(0),
        default=None,
        metavar="N",
        help="layouts of the per-output cost table (default: --layouts; 0 skips it)",
    )
    parser.add_argument(
        "--cost-outputs",
        default=None,
        metavar="NAMES",
        help="comma-separated outputs of the cost table (default: every sweep output)",
    )
    parser.add_argument(
        "--memory",
        type=count(0),
        default=0,
        metavar="N",
        help="also measure the peak memory a sweep of N layouts adds",
    )
    parser.add_argument(
        "--json",
        type=output_file,
        default="tripodjax-bench.json",
        help="where to write the figures (default tripodjax-bench.json)",
    )
    args = parser.parse_args(argv)
    from tripodjax.sweep import OUTPUTS

    cost_outputs = _names(parser, "--cost-outputs", args.cost_outputs, OUTPUTS)
    import jax

    jax.config.update(
        "jax_enable_x64", True
    )  # the command's own choice: float64 variants and reference
    results = run(
        args.layouts,
        args.n_theta,
        args.fsolve_layouts,
        args.repeats,
        gradient_layouts=args.gradient_layouts,
        domain_n=args.domain_layouts,
    )
    cost_layouts = args.layouts if args.cost_layouts is None else args.cost_layouts
    if cost_layouts:
        results["output_costs"] = output_costs(
            cost_layouts, args.n_theta, args.repeats, cost_outputs
        )
    if args.memory:
        results["memory"] = memory_of_sweep(args.memory, args.n_theta)
    print(report(results))
    results["measured_on"] = measured_on()
    if not write_json(parser.prog, args.json, results):
        return 1
    print(f"figures written to {args.json}")
    return 0


def latency_main(argv: Sequence[str]) -> int:
    """``python -m tripodjax.bench --latency``: the compile-latency table (see `latency`)."""
    parser = ArgumentParser(
        prog="python -m tripodjax.bench --latency",
        usage="%(prog)s [-h] [--repeats N] [--entries NAMES] [--gradient-layouts NS] [--json JSON]",
        description="trace, lowering, compile and run time of each first answer, in fresh "
        "processes with empty caches, against the floor of the same run",
    )
    parser.add_argument(
        "--latency", action="store_true", required=True, help=argparse.SUPPRESS
    )  # the mode's switch, taken by ``main``
    parser.add_argument(
        "--repeats",
        type=count(1),
        default=3,
        metavar="N",
        help="fresh runs per entry, the median kept (default 3)",
    )
    parser.add_argument(
        "--entries",
        default=None,
        metavar="NAMES",
        help="comma-separated entries (default all: "
        + ",".join(e[0] for e in LATENCY_ENTRIES)
        + ")",
    )
    parser.add_argument(
        "--gradient-layouts",
        type=counts,
        default=[1, 2000],
        metavar="NS",
        help="batch sizes of the gradient/forward ratio (default 1,2000; empty skips it)",
    )
    parser.add_argument(
        "--json",
        type=output_file,
        default="tripodjax-latency.json",
        help="where to write the figures (default tripodjax-latency.json)",
    )
    args = parser.parse_args(argv)
    names = _names(parser, "--entries", args.entries, [entry[0] for entry in LATENCY_ENTRIES])
    results = latency(args.repeats, names)
    print(latency_report(results))
    sizes = args.gradient_layouts
    if sizes:
        import jax

        import tripodjax as tj

        results["gradient_to_forward"] = []
        with jax.enable_x64(True):
            for n in sizes:
                g = gradient_to_forward(tj.Layout(*random_layouts(n)), repeats=max(args.repeats, 3))
                results["gradient_to_forward"].append(g)
                print(
                    f"gradient (R, l, γ0) / forward cost of the summed irregularity, newton "
                    f"float64, {n} layouts: {g['ratio']:.2f}"
                )
    results["measured_on"] = measured_on()  # the load average as the figures are written
    if not write_json(parser.prog, args.json, results):
        return 1
    print(f"figures written to {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(finish(main))
