"""``python -m tripodjax.optimize.bench``: the optimiser's latency and its speed/accuracy trade.

Every figure is measured in the same run against a peer, and reported as a ratio
(these machines are shared and noisy):

- the command ``optimize-joint --out DIR``, cold (empty caches) and warm, against the
  floor of a bare ``python -c "import jax, matplotlib.pyplot"``;
- in one process, after one ``solve``, a ``solve`` of a spec that differs in a number
  (``loads.M_max``), against SciPy's SLSQP over the same ``evaluate`` with
  finite-difference gradients, and the distance between their designs;
- a spec with a 1000-case life spectrum: its first solve, its sensitivities (O(sections): one
  reverse pass for the lists) and the whole command, cold;
- for each ``[solver] fidelity`` and ``n_theta``, the first solve (trace, compile and run:
  what a fresh process waits for), a re-solve, and the distance of the design and objective
  from the newton / float64 / n_theta = 360 answer.

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


def long_spectrum_spec_text(cases=1000, seed=0):
    """A spec whose life spectrum has ``cases`` load cases (the largest list a spec may hold)."""
    import numpy as np

    rng = np.random.default_rng(seed)
    lists = {
        "torque": np.round(rng.uniform(100.0, 1154.0, cases), 1),
        "speed": np.round(rng.uniform(200.0, 1000.0, cases), 1),
        "vehicle_speed": np.round(rng.uniform(20.0, 130.0, cases), 1),
        "share": np.full(cases, 1.0 / cases),
    }
    return "[life]\n" + "".join(f"{k} = {v.tolist()}\n" for k, v in lists.items())


def long_spectrum(cases=1000, command=True):
    """The ``cases``-entry spectrum: in one process the first solve and the sensitivities
    (their reverse pass compiled on first use) [s], and the whole ``optimize-joint`` run,
    cold, against the import floor."""
    from tripodjax import optimize

    text = long_spectrum_spec_text(cases)
    spec = optimize.parse_spec(text)
    start = time.perf_counter()
    result = optimize.solve(spec, progress=False)
    solve_s = time.perf_counter() - start
    start = time.perf_counter()
    sens = optimize.sensitivities(spec, result)
    sensitivities_s = time.perf_counter() - start
    start = time.perf_counter()
    optimize.sensitivities(spec, result)
    again_s = time.perf_counter() - start
    out = {
        "cases": cases,
        "inputs": len(sens["derivatives"]) + len(sens["withheld"]),
        "first_solve_s": solve_s,
        "sensitivities_s": sensitivities_s,
        "sensitivities_again_s": again_s,
        "sensitivities_over_solve": sensitivities_s / solve_s,
    }
    if command:
        floor = _seconds([sys.executable, "-c", "import jax, matplotlib.pyplot"], repeats=3)
        with tempfile.TemporaryDirectory() as tmp:
            path = os.path.join(tmp, "long.toml")
            with open(path, "w", encoding="utf-8") as f:
                f.write(text)
            env = dict(os.environ, TRIPODJAX_CACHE_DIR=os.path.join(tmp, "cache"))
            cli = [sys.executable, "-P", "-m", "tripodjax.optimize.cli", path, "--progress", "off"]
            out["command_cold_s"] = _seconds(cli + ["--out", os.path.join(tmp, "out")], env)
        out["floor_s"] = floor
        out["command_cold_over_floor"] = out["command_cold_s"] / floor
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
    args = parser.parse_args(argv)
    _require_scipy()
    import jax

    figures = {}
    if not args.skip_command:
        figures["command"] = command_latency()
        c = figures["command"]
        print(
            f"optimize-joint: floor {c['floor_s']:.2f} s; cold {c['cold_s']:.2f} s "
            f"({c['cold_over_floor']:.1f}× floor); warm {c['warm_s']:.2f} s ({c['warm_over_floor']:.1f}× floor)"
        )
    with jax.enable_x64(True):
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
    figures["long_spectrum"] = g = long_spectrum(command=not args.skip_command)
    print(
        f"{g['cases']}-case spectrum ({g['inputs']} inputs): first solve {g['first_solve_s']:.1f} s, "
        f"sensitivities {g['sensitivities_s']:.1f} s ({g['sensitivities_over_solve']:.2f}× the solve; "
        f"{g['sensitivities_again_s']:.2f} s once compiled)"
        + (
            f"; optimize-joint cold {g['command_cold_s']:.1f} s ({g['command_cold_over_floor']:.1f}× floor)"
            if "command_cold_s" in g
            else ""
        )
    )
    if args.json:
        with open(args.json, "w", encoding="utf-8") as f:
            json.dump(figures, f, indent=2)


if __name__ == "__main__":
    main()
