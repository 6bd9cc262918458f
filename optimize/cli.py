"""``optimize-joint [SPEC] --out DIR``: propose a tripod-joint size for a design specification."""

import argparse
import os
import sys

EXIT_OK, EXIT_NOT_CONVERGED, EXIT_BAD_INPUT = 0, 1, 2
PARETO_FACTORS = (0.25, 0.5, 1.0, 2.0, 4.0)


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one line, no usage block
        self.exit(EXIT_BAD_INPUT, f"{self.prog}: {message} (see --help)\n")


def _parse(argv):
    parser = _Parser(
        prog="optimize-joint",
        description=(
            "Propose the track pitch-circle radius R and roller diameter d of a tripod joint that meet "
            "the Hertz static-capacity and life requirements and the R/d range, while keeping the "
            "transmission irregularity, the generated axial force (GAF) and the joint size low. "
            "Writes DIR/report.json and PNG plots (convergence, constraint margins, Pareto front)."
        ),
        epilog=(
            "Exit status: 0 converged; 1 did not converge (the report says so); 2 bad specification or arguments. "
            "Compiled code is cached in $TRIPODJAX_CACHE_DIR (default ~/.cache/tripodjax/jax), which makes later runs faster."
        ),
    )
    parser.add_argument(
        "spec",
        nargs="?",
        help="TOML design specification (default: the embedded one, `optimize.DEFAULT_SPEC_TOML`)",
    )
    parser.add_argument(
        "--out", required=True, metavar="DIR", help="directory for report.json and the plots"
    )
    parser.add_argument(
        "--progress",
        choices=("auto", "on", "off"),
        default="auto",
        help="progress bar on standard error (default: on a terminal)",
    )
    return parser.parse_args(argv)


def main(argv=None):
    args = _parse(argv)
    if os.path.exists(args.out) and not os.path.isdir(args.out):
        print(f"optimize-joint: --out {args.out} exists and is not a directory", file=sys.stderr)
        return EXIT_BAD_INPUT
    import jax

    jax.config.update("jax_enable_x64", True)  # the command's own choice
    # Compiling the optimiser takes most of a first run; keep the executables for the next one.
    cache = os.environ.get("TRIPODJAX_CACHE_DIR") or os.path.join(
        os.environ.get("XDG_CACHE_HOME") or os.path.expanduser("~/.cache"), "tripodjax", "jax"
    )
    jax.config.update("jax_compilation_cache_dir", cache)
    from tripodjax.optimize import report
    from tripodjax.optimize.solver import pareto_front
    from tripodjax.optimize.spec import SpecError, load_spec

    try:
        spec = load_spec(args.spec)
    except SpecError as error:
        print(f"optimize-joint: {error}", file=sys.stderr)
        return EXIT_BAD_INPUT
    progress = {"auto": None, "on": True, "off": False}[args.progress]
    weight = spec["objective"]["w_gaf"]
    weights = [weight * f for f in PARETO_FACTORS] if weight > 0 else [0.0, 0.5, 1.0, 2.0, 4.0]
    # One batched solve gives the proposed design (the spec's own weight) and the Pareto front.
    results = pareto_front(spec, weights, progress=progress)
    main_result = results[PARETO_FACTORS.index(1.0)] if weight > 0 else results[0]
    report.write(
        args.out,
        main_result,
        spec,
        list(zip(weights, results, strict=False)),
        source=args.spec or "default",
    )
    d = main_result.design
    status = "converged" if main_result.converged else "NOT converged"
    print(
        f"optimize-joint: R = {d['R']:.3f} mm, d_roller = {d['d_roller']:.3f} mm, objective {main_result.objective:.5f}, "
        f"KKT residual {main_result.kkt_residual:.2e} ({status}); report in {os.path.join(args.out, 'report.json')}"
    )
    if not main_result.converged:
        violated = [
            f"{name} (margin {c['margin']:+.3g})"
            for name, c in main_result.constraints.items()
            if c["margin"] < 0
        ]
        reason = (
            "violated: " + ", ".join(violated)
            if violated
            else "the KKT residual is above solver.tolerance"
        )
        print(
            f"optimize-joint: no converged design within solver.max_outer iterations; {reason}",
            file=sys.stderr,
        )
        return EXIT_NOT_CONVERGED
    return EXIT_OK


if __name__ == "__main__":
    sys.exit(main())
