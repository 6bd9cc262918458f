"""``optimize-joint [SPEC] --out DIR``: propose a tripod-joint design for a design specification.

Exit status (also in ``--help``):

- 0: converged to a feasible design;
- 1: not converged, or infeasible (no start reached feasibility; the message says
  "infeasible" and names the largest violations); the report is written either way;
- 2: bad specification, arguments or output folder (one line, nothing computed);
- 3: the report could not be written (the design is printed; an older report is left intact);
- 130: interrupted (Ctrl-C, SIGINT); 143: terminated (SIGTERM); one line, no partial files;
- 141: the reader of its output left early (``| head``; the report is written), no traceback.

The command handles SIGINT and SIGTERM from its first instruction: ``tripodjax`` and
this module import nothing heavy, so ``--help`` and argument errors answer before JAX
is imported. The computation runs in a worker thread while the main thread waits, so a
signal is handled at once, not after a compilation ends; the main thread stages the
report and leaves on a signal only when no staged file remains in ``--out``.
"""

import contextlib
import gc
import math
import os
import signal
import sys
import tempfile
import threading
import warnings

from tripodjax._cli import ArgumentParser, finish
from tripodjax.optimize._texts import label_problem

EXIT_OK, EXIT_NOT_CONVERGED, EXIT_BAD_INPUT, EXIT_WRITE_FAILED, EXIT_INTERRUPTED = 0, 1, 2, 3, 130
EXIT_TERMINATED = 143  # 128 + SIGTERM
PARETO_FACTORS = (0.25, 0.5, 1.0, 2.0, 4.0)
SIGNALS = {"SIGINT": (EXIT_INTERRUPTED, "interrupted"), "SIGTERM": (EXIT_TERMINATED, "terminated")}


# --------------------------------------------------------------------------- signals


class _Signals:
    """What a signal does now: leave at once (one line, ``os._exit``), or after a staging block.

    A handler that raised an exception would depend on where the main thread is (an
    exception raised inside a garbage-collector callback of XLA is printed and dropped);
    this one leaves the process itself, except inside ``staging``,
    where it only records the signal.
    """

    def __init__(self):
        self.staging_depth = 0
        self.pending = None
        self.detail = "no report written"

    def handle(self, signum, frame):
        if self.staging_depth:
            self.pending = self.pending or signum
            return
        self.leave(signum)

    def leave(self, signum):
        code, what = SIGNALS[signal.Signals(signum).name]
        # os.write: no Python stream whose lock the interrupted code may hold.
        os.write(2, f"optimize-joint: {what}; {self.detail}\n".encode())
        os._exit(code)  # no teardown racing XLA's compiler threads

    @contextlib.contextmanager
    def staging(self):
        """Within the block a signal waits: files staged in ``--out`` are renamed or removed first."""
        self.staging_depth += 1
        try:
            yield
        finally:
            self.staging_depth -= 1
            if not self.staging_depth and self.pending is not None:
                self.leave(self.pending)


_SIGNALS = _Signals()


def _install_handlers():
    for name in SIGNALS:
        signal.signal(getattr(signal, name), _SIGNALS.handle)


def _in_worker(function, *args):
    """``function(*args)`` in a worker thread while this (the main) thread waits on it.

    Signal handlers run in the main thread between its bytecodes; waiting on a thread
    (``join``) lets them run at once, where a compilation on the main thread would
    delay them until it returns.
    """
    box = {}

    def target():
        try:
            box["value"] = function(*args)
        except BaseException as error:  # re-raised in the main thread
            box["error"] = error

    worker = threading.Thread(target=target, name="optimize-joint", daemon=True)
    worker.start()
    worker.join()
    if "error" in box:
        raise box["error"]
    return box["value"]


# --------------------------------------------------------------------------- arguments


def _parse(argv):
    parser = ArgumentParser(
        prog="optimize-joint",
        description=(
            "Propose a tripod joint design (any of R, d, l, γ0, conformity, λ, μ_slp free, as the "
            "spec's [bounds] say) that meets the Hertz static-capacity and life requirements and the "
            "spec's constraints at the lowest objective. Writes DIR/report.json (strict JSON: design, "
            "status, margins, sensitivities, the GE/GI catalogue choice, Pareto front), PNG plots, "
            "report.html (the report to read or print), validation.html (the customer's "
            "validation document: requirements, values and verdicts of both joints and the shaft "
            "sections, with a revision and approval block) and report.xlsx (its tables). "
            "`optimize-joint compare DIR_A DIR_B` sets two reports side by side."
        ),
        epilog=(
            "Exit status: 0 converged and feasible; 1 not converged or infeasible (the report says "
            "which); 2 bad specification, arguments or --out; 3 the report could not be written; "
            "130 interrupted (SIGINT), 143 terminated (SIGTERM), 141 the output's reader left. Compiled code is cached in $TRIPODJAX_CACHE_DIR (default "
            "~/.cache/tripodjax/jax), which makes later runs faster."
        ),
    )
    parser.add_argument(
        "spec",
        nargs="?",
        help="TOML design specification (default: the embedded one, tripodjax.optimize.DEFAULT_SPEC_TOML)",
    )
    parser.add_argument(
        "--out", required=True, metavar="DIR", help="directory for report.json and the plots"
    )
    parser.add_argument(
        "--reliability",
        action="store_true",
        help="add the reliability table (FORM, SORM, 10^5-sample Monte Carlo) with the default "
        "tolerances of the docs when the spec has no [uncertainty] (with one, it is always added)",
    )
    parser.add_argument(
        "--revision",
        default="0",
        metavar="REV",
        help="the revision of validation.html, the customer's validation document (default 0: "
        '"Rev. 0"; at most 80 printable characters)',
    )
    parser.add_argument(
        "--progress",
        choices=("auto", "on", "off"),
        default="auto",
        help="progress bar on standard error (default: on a terminal)",
    )
    return parser.parse_args(argv)


def _out_named(path):
    """--out names a directory or a place for one (checked before the spec is read, without
    importing JAX; `_check_out` creates it after). Returns an error line or None."""
    if not path or not path.strip():
        return "--out is empty; give a directory"
    if os.path.exists(path) and not os.path.isdir(path):
        return f"--out {path} exists and is not a directory"
    return None


def _check_out(path):
    """Create --out if absent; it must be a writable directory. Returns an error line or None."""
    problem = _out_named(path)
    if problem:
        return problem
    try:
        os.makedirs(path, exist_ok=True)
    except FileExistsError:
        return f"--out {path} exists and is not a directory"
    except OSError as error:
        return f"--out {path} cannot be created: {error.strerror or error}"
    if not os.path.isdir(path):
        return f"--out {path} is not a directory"
    try:
        with _SIGNALS.staging():  # the probe never stays behind
            fd, probe = tempfile.mkstemp(prefix=".write-test.", dir=path)
            os.close(fd)
            os.remove(probe)
    except OSError as error:
        return f"--out {path} is not writable: {error.strerror or error}"
    return None


def _cache_dir():
    return os.environ.get("TRIPODJAX_CACHE_DIR") or os.path.join(
        os.environ.get("XDG_CACHE_HOME") or os.path.expanduser("~/.cache"), "tripodjax", "jax"
    )


def _landscape_axes(spec, catalogue):
    """R and d axes [mm] covering the catalogue sizes and the bounds, within R/l ≤ 0.2."""
    import numpy as np

    bounds = spec.resolved["bounds"]

    def span(key, sizes):
        given = bounds.get(key)
        return sizes + (list(given) if isinstance(given, list) else [])

    R = span("R", [e["R_mm"] for e in catalogue])
    d = span("d_roller", [e["d_roller_mm"] for e in catalogue])
    r_max = min(1.05 * max(R), 0.2 * float(spec.values["layout"]["l"]))
    r_min = min(0.95 * min(R), 0.5 * r_max)
    return np.linspace(r_min, r_max, 28), np.linspace(0.95 * min(d), 1.05 * max(d), 28)


def _reports(spec, design):
    """The life, forces and halfshaft sections of the report for a design (None where absent)."""
    from tripodjax.optimize import structural
    from tripodjax.optimize.problem import forces_report, life_report

    try:
        life, forces = life_report(spec, design), forces_report(spec, design)
    except ValueError:  # a design outside the domain (a failed solve): no life, no forces
        life = forces = None
    try:
        halfshaft = structural.halfshaft_report(spec, design)
    except ValueError:  # no [vehicle] (the report's halfshaft section says why it is absent) or
        # a design outside the domain (a failed solve)
        halfshaft = None
    return life, forces, halfshaft


def _compile_ahead(spec, design):
    """The sensitivities' reverse pass and `_reports` run at ``design`` for their compiled
    programs only: whatever they raise, the optimum's raise again where it applies to them."""
    from tripodjax.optimize.sensitivity import compile_reverse_pass

    with contextlib.suppress(Exception):
        compile_reverse_pass(spec)
    with contextlib.suppress(Exception):
        _reports(spec, design)


def _mid_box(spec):
    """The middle of the box of the free variables, in spec units (a design inside the domain)."""
    import numpy as np

    from tripodjax.optimize.problem import bounds, to_spec_units

    lower, upper = bounds(spec.structure, spec.values, np)
    return {
        k: to_spec_units(k, 0.5 * (lo + hi))
        for k, lo, hi in zip(spec.structure.free, lower, upper, strict=True)
    }


def main(argv=None):
    """The command: parse, check, compute (in a worker thread), write. Returns the exit status."""
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ["compare"]:
        from tripodjax.optimize.compare import main as compare

        return compare(argv[1:])
    try:
        return _main(argv)
    except KeyboardInterrupt:  # main() called without command()'s handlers
        print("optimize-joint: interrupted; no report written", file=sys.stderr)
        return EXIT_INTERRUPTED


def _summary(result):
    from tripodjax.optimize.spec import variable_domain

    d = result.design

    def with_unit(name):  # "R = 26.05 mm", "gamma0_deg = 20 deg", "conformity = 1.002"
        unit = variable_domain(name)[0]
        return f"{name} = {d[name]:.4g}" + ("" if unit == "–" else f" {unit}")

    free = ", ".join(with_unit(k) for k in result.starts[0]["design"])
    return f"{free} (objective {result.objective:.5f})"


def _main(argv):
    args = _parse(argv)
    problem = label_problem("--revision", args.revision) or _out_named(args.out)
    if problem is None:
        from tripodjax.optimize.spec import SpecError, load_spec

        try:
            spec = load_spec(args.spec)
        except SpecError as error:
            problem = str(error)
    if problem is None:  # --out created only for a spec that can run
        problem = _check_out(args.out)
    if problem:
        print(f"optimize-joint: {problem}", file=sys.stderr)
        return EXIT_BAD_INPUT
    with warnings.catch_warnings():
        # A non-finite margin plots as a gap; matplotlib's warning about it is no message.
        warnings.filterwarnings("ignore", category=RuntimeWarning, module="matplotlib")
        outcome = _in_worker(_compute, args, spec, ["optimize-joint", *argv])
        return _write(args, outcome)


def _compute(args, given, command_line):
    """Everything the report holds (`_contents`), JAX's persistent cache off meanwhile.

    The command keeps its programs' executables itself (`executable_cache`); JAX's persistent
    cache (on where JAX_COMPILATION_CACHE_DIR is set) would trace and lower each program again,
    and an executable it returns cannot be kept (see `_compiled`). The setting is restored
    afterwards: a notebook that calls `main` keeps its own.
    """
    import jax

    previous = jax.config.jax_enable_compilation_cache
    jax.config.update("jax_enable_compilation_cache", False)
    try:
        return _contents(args, given, command_line)
    finally:
        jax.config.update("jax_enable_compilation_cache", previous)


def _contents(args, given, command_line):
    """Everything the report holds: solve, catalogue, landscape, sensitivities, figures.

    ``given`` is the spec as loaded (its reliability table and the report's spec); the
    solve and the evaluations run on its deterministic problem (`Spec.deterministic`).
    """
    import contextvars
    from concurrent.futures import ThreadPoolExecutor

    from tripodjax.optimize import document, report, structural
    from tripodjax.optimize._compiled import executable_cache, rows_per_call
    from tripodjax.optimize.problem import (
        constraint_landscape,
        evaluate,
        evaluate_catalogue,
    )
    from tripodjax.optimize.reliability import report_reliability
    from tripodjax.optimize.sensitivity import sensitivities
    from tripodjax.optimize.solver import _with, run

    spec = given.deterministic()
    progress = {"auto": None, "on": True, "off": False}[args.progress]
    pareto_weights, weight = [], None
    if "gaf_rms" in spec.structure.objective:
        weight = float(spec.values["objective"]["w_gaf_rms"])
        pareto_weights = (
            [weight * f for f in PARETO_FACTORS] if weight > 0 else [0.0, 0.5, 1.0, 2.0, 4.0]
        )
    # One batch: the spec's own problem and the Pareto members other than the spec's own weight
    # (that member is the spec's own result).
    members = [w for w in pareto_weights if w != weight]
    scenarios = [spec.values] + [_with(spec.values, "objective", w_gaf_rms=w) for w in members]
    # The catalogue, the landscape and the sensitivities evaluate points through the solve's
    # own compiled program (evaluate-only rows of the same batch size): one program, not two.
    # The full-fidelity check is a second, smaller program: on a cold cache it compiles in a
    # second thread beside the solve, at a design inside the box.
    full_reference = None
    if spec.structure.fidelity != "newton" or spec.structure.n_theta != 360:
        full_reference = spec.replace_values(
            solver={"fidelity": "newton", "n_theta": 360}
        ).deterministic()
    # Matplotlib, Jinja2, openpyxl and the report templates load beside the solve.
    threading.Thread(target=document.prepare, daemon=True).start()
    pool = ThreadPoolExecutor(max_workers=1)
    rows = len(scenarios) * spec.structure.starts
    try:
        with executable_cache(os.path.join(_cache_dir(), "executables")), rows_per_call(rows):
            run_in_context = contextvars.copy_context().run
            warm = None
            if full_reference is not None:
                warm = pool.submit(run_in_context, evaluate, full_reference, _mid_box(spec))
            # The sensitivities' reverse pass and the reports' programs compile there too, at
            # the same design, while the solve compiles and runs (their executables serve the
            # proposed design: the same shapes).
            ahead = pool.submit(run_in_context, _compile_ahead, spec, _mid_box(spec))
            results = run(spec, scenarios, progress)
            result, by_weight = results[0], dict(zip(members, results[1:], strict=True))
            pareto = [(w, by_weight.get(w, result)) for w in pareto_weights]
            catalogue, choice = evaluate_catalogue(spec)
            landscape = constraint_landscape(spec, *_landscape_axes(spec, catalogue))
            ahead.result()
            if result.converged:  # derivatives of an optimum, not of an unfinished point
                result.sensitivities = sensitivities(spec, result)
            reliability = report_reliability(given, result.design, args.reliability)
            full = None
            if full_reference is not None:
                warm.result()
                design = {k: result.design[k] for k in spec.structure.free}
                full = {"solver": "newton", "n_theta": 360, **evaluate(full_reference, design)}
            life, forces, halfshaft = _reports(spec, result.design)
    finally:
        pool.shutdown(wait=False, cancel_futures=True)
    figures = {
        "convergence.png": report.figure_convergence(result),
        "constraint_margins.png": report.figure_margins(result),
        "catalogue.png": report.figure_catalogue(result, catalogue, choice, landscape),
    }
    if pareto:
        figures["pareto_front.png"] = report.figure_pareto(result, pareto)
    if result.sensitivities is not None and result.sensitivities["elasticities"]:
        figures["sensitivities.png"] = report.figure_tornado(result)
    if life is not None:
        figures["damage.png"] = report.figure_damage(life)
    if life is not None or halfshaft is not None:
        figures["life_conditions.png"] = report.figure_life_conditions(life, halfshaft)
    if halfshaft is not None:
        figures["shaft_damage.png"] = report.figure_shaft_damage(halfshaft)
    if reliability is not None:
        figures["importance.png"] = report.figure_importance(reliability)
    body = report.report_dict(
        result,
        given,
        pareto=pareto,
        catalogue=catalogue,
        choice=choice,
        full_fidelity=full,
        source=args.spec or "default",
        life=life,
        forces=forces,
        halfshaft=halfshaft,
        reliability=reliability,
    )
    message, code = _verdict(result)
    body["message"] = message
    body["written"] = document.written_info(command_line, args.revision)
    documents, notes = document.documents(body, figures)
    cat = (
        f"{choice['family']} {choice['size']} (objective {choice['objective']:.5f})"
        if choice
        else "none feasible"
    )
    status = "converged" if result.converged else "NOT converged"
    return {
        "body": body,
        "figures": figures,
        "documents": documents,
        "notes": notes,
        "message": message,
        "code": code,
        "designs": f"catalogue: {cat}; ad hoc: {_summary(result)}",
        "halfshaft": structural.summary(halfshaft) if halfshaft else None,
        "status": f"KKT residual {result.kkt_residual:.2e} ({status})",
    }


def _verdict(result):
    """(message, exit status) of a result."""
    if result.result == "nonfinite":
        from tripodjax.optimize.spec import CHANCE_PREFIXES

        names = [n for n, c in result.constraints.items() if not math.isfinite(c["margin"])]
        chance = [n for n in names if n.startswith(tuple(CHANCE_PREFIXES))]
        which = (
            f"the margin of {', '.join(names[:3])}"
            if names
            else "the objective or a constraint margin"
        )
        why = (
            f"{chance[0]}'s requirement has no finite margin at a point of its inverse-FORM "
            "search (|u| = β_t): an uncertain number's distribution reaches values where the "
            "model overflows; narrow that distribution or lower the target"
            if chance
            else "some numbers of the spec overflow together, e.g. a weight w_<q> over its "
            "reference <q>_ref, or a limit or load near 0"
        )
        return (
            f"not converged: {which} is not finite at the design (result nonfinite): {why}",
            EXIT_NOT_CONVERGED,
        )
    if not result.feasible:
        worst = sorted(
            (c["margin"], name) for name, c in result.constraints.items() if c["margin"] < 0
        )
        from tripodjax.optimize.problem import fixed_constraints

        fixed = fixed_constraints(result.structure) if result.structure else ()
        listed = ", ".join(
            f"{name} (margin {m:+.3g}{'; no free variable changes it' if name in fixed else ''})"
            for m, name in worst[:3]
        )
        # The solver may report a start within its acceptable level of feasibility, for its far
        # better objective, beside another that was feasible (solver.ACCEPTABLE).
        others = sum(start["feasible"] for start in result.starts)
        which = (
            f"the proposed design is just outside its limits ({others} other start(s) feasible "
            "with a worse objective)"
            if others
            else "no start reached feasibility"
        )
        more = f" ({len(worst)} in all)" if len(worst) > 3 else ""
        return (f"infeasible: {which}; largest violations{more}: {listed}", EXIT_NOT_CONVERGED)
    if not result.converged:
        reasons = []
        if not result.kkt_converged:
            reasons.append(
                "the KKT residual is above solver.tolerance within solver.max_outer iterations"
            )
        if not result.halfshaft_converged:
            reasons.append(
                f"the halfshaft or GAF evaluation at the design returned {result.result}"
            )
        if not result.hertz_converged:
            reasons.append(f"the Hertz ellipse (κ) solve at the design returned {result.result}")
        return f"not converged: {'; '.join(reasons)}", EXIT_NOT_CONVERGED
    return "converged to a feasible design", EXIT_OK


def _write(args, outcome):
    """Write the report (the main thread: a signal waits until no staged file is left)."""
    from tripodjax.optimize import report

    with _SIGNALS.staging():
        try:
            report.write(args.out, outcome["body"], outcome["figures"], outcome["documents"])
        except OSError as error:
            print(f"optimize-joint: {outcome['designs']}", file=sys.stderr)
            print(
                f"optimize-joint: cannot write the report in {args.out}: {error.strerror or error}",
                file=sys.stderr,
            )
            return EXIT_WRITE_FAILED
        _SIGNALS.detail = f"the report in {args.out} was complete before the signal"
    print(
        f"optimize-joint: {outcome['designs']}, {outcome['status']}; "
        f"report in {os.path.join(args.out, 'report.json')}"
    )
    if outcome["halfshaft"]:
        print(f"optimize-joint: {outcome['halfshaft']}")
    for note in outcome["notes"]:  # e.g. report.xlsx not written: openpyxl missing
        print(f"optimize-joint: {note}", file=sys.stderr)
    if outcome["code"] != EXIT_OK:
        print(f"optimize-joint: {outcome['message']}", file=sys.stderr)
    return outcome["code"]


def command():
    """The ``optimize-joint`` console script: ``main()`` as the process's exit status.

    Its first instruction installs the SIGINT and SIGTERM handlers (nothing heavy is
    imported before it). A signal prints one line and leaves at once (``os._exit``:
    an interpreter teardown racing XLA's compiler threads can crash) with 130 / 143;
    while the report is being staged in ``--out`` it waits until every staged file is
    renamed into place or removed.

    Python's cyclic garbage collector is off for the process: tracing and compiling make
    millions of short-lived objects and almost no cycles, so its passes found nothing and
    took ~1 s of a cold run (7 %; the peak memory grows 1 % without them, measured).
    """
    _install_handlers()
    gc.disable()
    code = finish(main)
    sys.stderr.flush()
    if code == EXIT_INTERRUPTED:
        os._exit(code)
    sys.exit(code)


if __name__ == "__main__":
    command()
