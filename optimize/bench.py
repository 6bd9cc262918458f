"""``python -m tripodjax.optimize.bench``: the optimiser's latency and its speed/accuracy trade.

Every figure is measured in the same run against a peer, and reported as a ratio
(these machines are shared and noisy):

- the command ``optimize-joint --out DIR``, cold (empty caches) and warm, against the
  floor of a bare ``python -c "import jax, matplotlib.pyplot"``, for the default spec and
  for one with the conformity free;
- in one process, after one ``solve``, a ``solve`` of a spec that differs in a number
  (``vehicle.adhesion``, which moves M_max and the life), against SciPy's SLSQP over the same ``evaluate`` with
  finite-difference gradients, and the distance between their designs;
- a spec with a 1000-case life spectrum: its first solve, its sensitivities (O(sections): one
  reverse pass for the lists) and the whole command, cold;
- for each ``[solver] fidelity`` and ``n_theta``, the first solve (trace, compile and run:
  what a fresh process waits for), a re-solve, and the distance of the design and objective
  from the newton / float64 / n_theta = 360 answer;
- for each structure of `STRUCTURES` (which variables are free), the first solve and a
  re-solve, and the command's cold and warm run with the conformity free (its warm run
  loads that structure's executables from the command's cache).
- the time report.html and report.xlsx add to writing report.json and the PNGs.
- Monte Carlo samples per second of the reliability's requirement chain, against the plain
  sweep's layouts per second (``monte_carlo_rate``).

The per-program breakdown of the first answers (trace, compile and run of each program, the
first solve of each structure and the command cold and warm) is ``python -m tripodjax.bench
--latency`` (``tripodjax.bench.latency``), which shares this module's structures and floor.

Needs SciPy (the ``bench`` extra: ``pip install "tripodjax[bench]"``).
"""

import os
import subprocess
import sys
import tempfile
import time

from tripodjax._cli import ArgumentParser, output_file, write_json
from tripodjax.bench import COMMAND_FLOOR

PROG = "python -m tripodjax.optimize.bench"

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


# Spec structures (free variables) whose first solve the bench measures: the default and the
# ones a study frees most often. Each is a new structure: traced and compiled on its first solve.
STRUCTURES = {
    "R, d_roller (default)": "",
    "R, d_roller, conformity": "[bounds]\nconformity = [1.002, 1.008]\n",
    "R, d_roller, lam, mu_slp": "[bounds]\nlam = [0.004, 0.01]\nmu_slp = [0.04, 0.09]\n",
    "R, d_roller, l, gamma0_deg": "[bounds]\nl = [450.0, 550.0]\ngamma0_deg = [15.0, 25.0]\n",
}


def command_latency(repeats=2, spec_text=None):
    """Cold and warm ``optimize-joint`` against the import floor [s] and their ratios.

    ``spec_text``: a TOML spec to run instead of the default (e.g. one of `STRUCTURES`: its
    warm run loads the structure's executables from the command's cache).
    """
    floor = _seconds([sys.executable, "-c", COMMAND_FLOOR], repeats=3)
    cli = [sys.executable, "-P", "-m", "tripodjax.optimize.cli"]  # -P: the installed package
    with tempfile.TemporaryDirectory() as tmp:
        env = dict(os.environ, TRIPODJAX_CACHE_DIR=os.path.join(tmp, "cache"))
        out = os.path.join(tmp, "out")
        if spec_text is not None:
            path = os.path.join(tmp, "spec.toml")
            with open(path, "w", encoding="utf-8") as f:
                f.write(spec_text)
            cli = cli + [path]
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
    changed = spec.replace_values(vehicle={"adhesion": 0.95}, hertz={"P_d": 1300.0})
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


def first_solve_by_structure(structures=STRUCTURES, compiled=None):
    """Per structure: its free variables, the first solve in this process (trace, compile and
    run) and a re-solve [s]. ``compiled``: ``{structure: seconds}`` measured already."""
    from tripodjax import optimize

    rows = []
    for name, text in structures.items():
        spec = optimize.parse_spec(text)
        start = time.perf_counter()
        result = optimize.solve(spec, progress=False)
        first = (compiled or {}).get(spec.structure, time.perf_counter() - start)
        start = time.perf_counter()
        optimize.solve(spec, progress=False)
        rows.append(
            {
                "structure": name,
                "free": len(spec.structure.free),
                "first_solve_s": first,
                "solve_s": time.perf_counter() - start,
                "converged": result.converged,
            }
        )
    return rows


def report_writing(repeats=3):
    """The time report.html and report.xlsx add to ``optimize-joint`` [s].

    - ``command_added_s``: a warm ``optimize-joint`` against the same command with the two
      documents switched off (``document.documents`` returning none), best of ``repeats``;
    - in one process, writing the default run's report with the documents against report.json
      and the PNGs alone: ``added_cold_s`` the first time (importing Jinja2 and openpyxl and
      compiling the template: what the command does in a thread beside the solve),
      ``added_s`` once they are loaded (what the command waits for).
    """
    cli = "from tripodjax.optimize.cli import command; command()"
    off = "from tripodjax.optimize import document; document.documents = lambda *a: ({}, []); "
    figures = {}
    with tempfile.TemporaryDirectory() as tmp:
        env = dict(os.environ, TRIPODJAX_CACHE_DIR=os.path.join(tmp, "cache"))
        out = os.path.join(tmp, "out")
        args = ["--out", out, "--progress", "off"]
        _seconds([sys.executable, "-P", "-c", cli, *args], env)  # fills the caches
        with_documents = _seconds([sys.executable, "-P", "-c", cli, *args], env, repeats)
        without = _seconds([sys.executable, "-P", "-c", off + cli, *args], env, repeats)
    figures.update(command_s=with_documents, command_without_s=without)
    figures["command_added_s"] = with_documents - without

    from tripodjax import optimize
    from tripodjax.optimize import document, report

    spec = optimize.load_spec()
    result = optimize.solve(spec, progress=False)
    result.sensitivities = optimize.sensitivities(spec, result)
    catalogue, choice = optimize.evaluate_catalogue(spec)
    body = report.report_dict(result, spec, catalogue=catalogue, choice=choice)
    drawn = {
        "convergence.png": report.figure_convergence(result),
        "constraint_margins.png": report.figure_margins(result),
        "catalogue.png": report.figure_catalogue(result, catalogue, choice),
        "sensitivities.png": report.figure_tornado(result),
    }

    def seconds(with_documents):
        with tempfile.TemporaryDirectory() as out:
            start = time.perf_counter()
            writers = document.documents(body, drawn)[0] if with_documents else None
            report.write(out, body, drawn, writers)
            return time.perf_counter() - start

    seconds(False)  # matplotlib's first PNG (fonts, Agg) is not the documents' cost
    figures["added_cold_s"] = seconds(True) - seconds(False)
    base = min(seconds(False) for _ in range(repeats))
    figures["json_png_s"] = base
    figures["added_s"] = min(seconds(True) for _ in range(repeats)) - base
    return figures


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
        floor = _seconds([sys.executable, "-c", COMMAND_FLOOR], repeats=3)
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
    parser = ArgumentParser(prog=PROG, description=__doc__.split("\n")[0])
    parser.add_argument(
        "--skip-command", action="store_true", help="skip the cold/warm command timings"
    )
    parser.add_argument(
        "--json", metavar="FILE", type=output_file, help="also write the figures as JSON"
    )
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
        _write(args.json, figures)
        return
    if not args.skip_command:
        figures["command"] = command_latency()
        c = figures["command"]
        print(
            f"optimize-joint: floor {c['floor_s']:.2f} s; cold {c['cold_s']:.2f} s "
            f"({c['cold_over_floor']:.1f}× floor); warm {c['warm_s']:.2f} s ({c['warm_over_floor']:.1f}× floor)"
        )
        conformity = STRUCTURES["R, d_roller, conformity"]
        figures["command_conformity_free"] = c = command_latency(spec_text=conformity)
        print(
            f"optimize-joint, conformity free: cold {c['cold_s']:.2f} s "
            f"({c['cold_over_floor']:.1f}× floor {c['floor_s']:.2f} s); warm {c['warm_s']:.2f} s "
            f"({c['warm_over_floor']:.1f}× floor)"
        )
    with jax.enable_x64(True):
        figures["resolve"] = r = resolve_latency()
        print(
            f"re-solve with a changed adhesion and P_d: {r['resolve_s'] * 1e3:.0f} ms; SLSQP peer "
            f"{r['slsqp_s'] * 1e3:.0f} ms (ratio {r['resolve_over_slsqp']:.2f}); designs "
            f"{r['design_distance_rel']:.1e} apart (first solve {r['first_solve_s']:.1f} s)"
        )
        default = optimize_default_structure()
        figures["fidelity"] = rows = fidelity_trade(compiled={default: r["first_solve_s"]})
        figures["report"] = w = report_writing()
        print(
            f"report.html and report.xlsx: warm optimize-joint {w['command_s']:.2f} s, without them "
            f"{w['command_without_s']:.2f} s (added {w['command_added_s']:+.2f} s); writing them "
            f"adds {w['added_s']:.2f} s ({w['added_cold_s']:.2f} s with the imports) to the "
            f"{w['json_png_s']:.2f} s of report.json and the PNGs"
        )
    print(
        "fidelity  n_theta  first solve [s]  re-solve [ms]  design vs reference  objective vs reference"
    )
    for row in rows:
        print(
            f"{row['fidelity']:<9} {row['n_theta']:>7}  {row['first_solve_s']:>15.2f}  {row['solve_s'] * 1e3:>13.1f}  "
            f"{row['design_distance_rel']:>19.1e}  {row['objective_distance_rel']:>22.1e}"
        )
    with jax.enable_x64(True):
        figures["structures"] = rows = first_solve_by_structure(
            compiled={default: r["first_solve_s"]}
        )
    print("free variables                 first solve [s]  re-solve [ms]  converged")
    for row in rows:
        print(
            f"{row['structure']:<30} {row['first_solve_s']:>15.2f}  {row['solve_s'] * 1e3:>13.1f}  "
            f"{row['converged']}"
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
    _write(args.json, figures)


def _write(path, figures):
    if path:
        from tripodjax.bench import measured_on

        figures["measured_on"] = measured_on()
        if not write_json(PROG, path, figures):
            sys.exit(1)


if __name__ == "__main__":
    main()
