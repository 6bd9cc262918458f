"""``python -m tripodjax.optimize.bench``: the optimiser's latency and its speed/accuracy trade.

Every figure is measured in the same run against a peer, and reported as a ratio
(these machines are shared and noisy):

- the command ``optimize-joint --out DIR``, cold (empty caches) and warm, against the
  floor of a bare ``python -c "import jax, matplotlib.pyplot"``;
- in one process, after one ``solve``, a ``solve`` of a spec that differs in a number
  (``loads.M_max``), against SciPy's SLSQP over the same ``evaluate`` with
  finite-difference gradients, and the distance between their designs;
- for each ``[solver] fidelity`` and ``n_theta``, the first solve (trace, compile and run:
  what a fresh process waits for), a re-solve, and the distance of the design and objective
  from the newton / float64 / n_theta = 360 answer;
- Monte Carlo samples per second of the reliability's requirement chain, against the plain
  sweep's layouts per second (``monte_carlo_rate``).

Needs SciPy (the ``bench`` extra: ``pip install "tripodjax[bench]"``).
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

FIDELITY_SETTINGS = (
    ("newton", 360),
    ("newton", 180),
    ("newton", 168),
    ("newton", 120),
    ("analytic", 360),
    ("analytic", 168),
    ("analytic", 120),
)


def _require_scipy():
    try:
        import scipy.optimize  # noqa: F401
    except ImportError:
        sys.exit(
            "python -m tripodjax.optimize.bench needs SciPy for its SLSQP peer: "
            'pip install "tripodjax[bench]"'
        )


def _seconds(command, env=None, repeats=1):
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        done = subprocess.run(command, capture_output=True, text=True, env=env)
        best = min(best, time.perf_counter() - start)
        if done.returncode not in (0,):
            raise RuntimeError(f"{command} failed: {done.stderr.strip()[-500:]}")
    return best


def command_latency(repeats=2):
    """Cold and warm ``optimize-joint`` against the import floor [s] and their ratios."""
    floor = _seconds([sys.executable, "-c", "import jax, matplotlib.pyplot"], repeats=3)
    cli = [sys.executable, "-P", "-m", "tripodjax.optimize.cli"]  # -P: the installed package
    with tempfile.TemporaryDirectory() as tmp:
        env = dict(os.environ, TRIPODJAX_CACHE_DIR=os.path.join(tmp, "cache"))
        out = os.path.join(tmp, "out")
        cold = _seconds(cli + ["--out", out, "--progress", "off"], env)
        warm = _seconds(cli + ["--out", out, "--progress", "off"], env, repeats)
    return {
        "floor_s": floor,
        "cold_s": cold,
        "warm_s": warm,
        "cold_over_floor": cold / floor,
        "warm_over_floor": warm / floor,
    }


def slsqp(spec, x0):
    """The peer: SLSQP over ``evaluate`` with finite-difference gradients."""
    import numpy as np
    from scipy.optimize import minimize

    from tripodjax import optimize

    free = spec.structure.free
    lower = [spec.resolved["bounds"][k][0] for k in free]
    upper = [spec.resolved["bounds"][k][1] for k in free]

    def design(x):
        return dict(zip(free, (float(v) for v in x), strict=True))

    def margins(x):
        c = optimize.evaluate(spec, design(x))["constraints"]
        return np.array([v for k, v in c.items() if not k.endswith("_bound")])

    out = minimize(
        lambda x: optimize.evaluate(spec, design(x))["objective"],
        x0,
        method="SLSQP",
        bounds=list(zip(lower, upper, strict=True)),
        constraints=[{"type": "ineq", "fun": margins}],
        options={"ftol": 1e-12, "maxiter": 200},
    )
    return design(out.x), float(out.fun)


def resolve_latency():
    """A re-solve with a changed number against the SLSQP peer on the same spec."""
    from tripodjax import optimize

    spec = optimize.load_spec()
    start = time.perf_counter()
    first = optimize.solve(spec, progress=False)
    first_s = time.perf_counter() - start
    changed = spec.replace_values(loads={"M_max": 1250.0}, hertz={"P_d": 1300.0})
    start = time.perf_counter()
    ours = optimize.solve(changed, progress=False)
    ours_s = time.perf_counter() - start
    x0 = [first.design[k] for k in spec.structure.free]
    slsqp(changed, x0)  # the peer's own first call compiles evaluate
    start = time.perf_counter()
    peer, peer_objective = slsqp(changed, x0)
    peer_s = time.perf_counter() - start
    distance = max(abs(ours.design[k] - peer[k]) / abs(peer[k]) for k in peer)
    return {
        "first_solve_s": first_s,
        "resolve_s": ours_s,
        "slsqp_s": peer_s,
        "resolve_over_slsqp": ours_s / peer_s,
        "design_distance_rel": distance,
        "objective_ours": ours.objective,
        "objective_slsqp": peer_objective,
    }


def fidelity_trade(settings=FIDELITY_SETTINGS, compiled=None):
    """Per setting: the first solve (trace, compile, run: what a fresh process waits for), a
    re-solve, and the distance of design and objective from the newton / n_theta 360 answer.

    ``compiled``: ``{structure: first-solve seconds}`` for structures this process has
    compiled already (their first solve was measured then).
    """
    from tripodjax import optimize

    base = optimize.load_spec()
    rows, reference = [], None
    for fidelity, n_theta in settings:
        spec = base.replace_values(solver={"fidelity": fidelity, "n_theta": n_theta})
        start = time.perf_counter()
        optimize.solve(spec, progress=False)  # a new structure: traced and compiled here
        first = (compiled or {}).get(spec.structure, time.perf_counter() - start)
        start = time.perf_counter()
        result = optimize.solve(spec, progress=False)
        seconds = time.perf_counter() - start
        if reference is None:
            reference = result
        distance = max(
            abs(result.design[k] - reference.design[k]) / abs(reference.design[k])
            for k in spec.structure.free
        )
        rows.append(
            {
                "fidelity": fidelity,
                "n_theta": n_theta,
                "first_solve_s": first,
                "solve_s": seconds,
                "design_distance_rel": distance,
                "objective_distance_rel": abs(result.objective - reference.objective)
                / abs(reference.objective),
                "converged": result.converged,
            }
        )
    return rows


def monte_carlo_rate(samples=1_000_000, sweep_layouts=65_536):
    """Monte Carlo samples per second of the requirements' whole chain, against the plain sweep.

    At the default design with the default tolerances: (a) the default spec, whose
    requirements need the Hertz capacities and the life (no kinematics); (b) the same with
    a kinematic requirement (``max_eccentricity``) at ``fidelity = "analytic"``,
    ``n_theta = 168``: kinematics, Hertz and life per sample. Against
    ``tripodjax.sweep.sweep`` of random layouts at the same fidelity (layouts per second).
    Compilation is excluded (a warm-up call of the same chunk size first).
    """
    import numpy as np

    from tripodjax import optimize
    from tripodjax.layout import Layout
    from tripodjax.optimize.reliability import reliability, with_default_tolerances
    from tripodjax.sweep import sweep

    base = with_default_tolerances(optimize.load_spec())
    kinematic = optimize.parse_spec(
        "[solver]\nfidelity = 'analytic'\nn_theta = 168\n[constraints]\nmax_eccentricity = 1.0\n"
    )
    kinematic = with_default_tolerances(kinematic)
    out = {}
    for name, spec in (("hertz_life", base), ("kinematics_hertz_life", kinematic)):
        reliability(spec, None, "mc", samples=2**15)  # compile
        start = time.perf_counter()
        reliability(spec, None, "mc", samples=samples)
        out[f"{name}_samples_per_s"] = samples / (time.perf_counter() - start)
    rng = np.random.default_rng(0)
    layouts = Layout(
        R=rng.uniform(20.0, 30.0, sweep_layouts),
        l=np.full(sweep_layouts, 500.0),
        gamma0=np.radians(rng.uniform(5.0, 25.0, sweep_layouts)),
    )
    kwargs = dict(n_theta=168, solver="analytic", outputs=("ecc_max", "result"), progress=False)
    sweep(layouts, **kwargs)  # compile
    start = time.perf_counter()
    sweep(layouts, **kwargs)
    out["sweep_layouts_per_s"] = sweep_layouts / (time.perf_counter() - start)
    out["kinematic_mc_over_sweep"] = (
        out["kinematics_hertz_life_samples_per_s"] / out["sweep_layouts_per_s"]
    )
    out["samples"] = samples
    return out


def optimize_default_structure():
    from tripodjax import optimize

    return optimize.load_spec().structure


def main(argv=None):
    parser = argparse.ArgumentParser(
        prog="python -m tripodjax.optimize.bench", description=__doc__.split("\n")[0]
    )
    parser.add_argument(
        "--skip-command", action="store_true", help="skip the cold/warm command timings"
    )
    parser.add_argument("--json", metavar="FILE", help="also write the figures as JSON")
    parser.add_argument(
        "--reliability-only",
        action="store_true",
        help="only the Monte Carlo rate of the reliability (samples/s against the sweep)",
    )
    args = parser.parse_args(argv)
    _require_scipy()
    import jax

    figures = {}
    figures["monte_carlo"] = m = monte_carlo_rate()
    print(
        f"Monte Carlo of the requirements, {m['samples']:.0e} samples: Hertz + life "
        f"{m['hertz_life_samples_per_s']:.3g} samples/s; analytic kinematics + Hertz + life "
        f"{m['kinematics_hertz_life_samples_per_s']:.3g} samples/s; plain sweep (analytic, 168) "
        f"{m['sweep_layouts_per_s']:.3g} layouts/s (ratio {m['kinematic_mc_over_sweep']:.2f})"
    )
    if args.reliability_only:
        args.skip_command = True
    if not args.skip_command:
        figures["command"] = command_latency()
        c = figures["command"]
        print(
            f"optimize-joint: floor {c['floor_s']:.2f} s; cold {c['cold_s']:.2f} s "
            f"({c['cold_over_floor']:.1f}× floor); warm {c['warm_s']:.2f} s ({c['warm_over_floor']:.1f}× floor)"
        )
    with jax.enable_x64(True):
        if args.reliability_only:
            _write(args.json, figures)
            return
        figures["resolve"] = r = resolve_latency()
        print(
            f"re-solve with a changed M_max: {r['resolve_s'] * 1e3:.0f} ms; SLSQP peer "
            f"{r['slsqp_s'] * 1e3:.0f} ms (ratio {r['resolve_over_slsqp']:.2f}); designs "
            f"{r['design_distance_rel']:.1e} apart (first solve {r['first_solve_s']:.1f} s)"
        )
        default = optimize_default_structure()
        figures["fidelity"] = rows = fidelity_trade(compiled={default: r["first_solve_s"]})
    print(
        "fidelity  n_theta  first solve [s]  re-solve [ms]  design vs reference  objective vs reference"
    )
    for row in rows:
        print(
            f"{row['fidelity']:<9} {row['n_theta']:>7}  {row['first_solve_s']:>15.2f}  {row['solve_s'] * 1e3:>13.1f}  "
            f"{row['design_distance_rel']:>19.1e}  {row['objective_distance_rel']:>22.1e}"
        )
    _write(args.json, figures)


def _write(path, figures):
    if path:
        with open(path, "w", encoding="utf-8") as f:
            json.dump(figures, f, indent=2)


if __name__ == "__main__":
    main()
