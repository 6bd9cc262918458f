"""The report of an optimisation: JSON and PNG plots, written atomically."""

import json
import os
import platform
import tempfile

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def versions():
    import jax
    import numpy
    import optax

    import tripodjax

    return {
        "tripodjax": tripodjax.__version__,
        "jax": jax.__version__,
        "optax": optax.__version__,
        "numpy": numpy.__version__,
        "python": platform.python_version(),
    }


def report_dict(result, spec, pareto=(), source="default"):
    """Everything a reader needs: design, objective, constraints, KKT residual, spec, versions."""
    return {
        "design": {"R_mm": result.design["R"], "d_roller_mm": result.design["d_roller"]},
        "objective": result.objective,
        "converged": result.converged,
        "kkt_residual": result.kkt_residual,
        "tolerance": spec["solver"]["tolerance"],
        "constraints": result.constraints,
        "quantities": result.quantities,
        "multipliers": result.multipliers,
        "history": result.history,
        "starts": result.starts,
        "pareto_front": [
            {
                "w_gaf": w,
                "R_mm": r.design["R"],
                "d_roller_mm": r.design["d_roller"],
                "gaf_rms_N": r.quantities["gaf_rms"],
                "outer_diameter_mm": r.quantities["outer_diameter"],
                "irregularity": r.quantities["irregularity"],
                "converged": r.converged,
            }
            for w, r in pareto
        ],
        "spec_source": source,
        "spec": spec.resolved,
        "versions": versions(),
    }


def _figure_convergence(result):
    fig, (ax0, ax1) = plt.subplots(1, 2, figsize=(11, 4))
    it = range(1, len(result.history["objective"]) + 1)
    ax0.plot(it, result.history["objective"], "o-")
    ax0.set(
        title="objective of the chosen start", xlabel="outer iteration [–]", ylabel="objective [–]"
    )
    ax1.semilogy(it, result.history["kkt_residual"], "o-")
    ax1.set(title="KKT residual", xlabel="outer iteration [–]", ylabel="KKT residual [–]")
    for ax in (ax0, ax1):
        ax.grid(alpha=0.3, which="both")
    fig.tight_layout()
    return fig


def _figure_margins(result):
    fig, ax = plt.subplots(figsize=(8, 4))
    names = list(result.constraints)
    margins = [result.constraints[n]["margin"] for n in names]
    ax.barh(names, margins, color=["C2" if m >= 0 else "C3" for m in margins])
    for y, m in enumerate(margins):
        ax.annotate(
            f"{m:+.2e}" + (" (active)" if abs(m) < 1e-3 else ""),
            (max(m, 0), y),
            xytext=(4, 0),
            textcoords="offset points",
            va="center",
            fontsize=8,
        )
    ax.axvline(0, color="k", lw=0.8)
    ax.set(
        title="constraint margins at the proposed design (≥ 0: satisfied)",
        xlabel="margin ln(value/limit) [–]",
    )
    ax.grid(alpha=0.3, axis="x")
    fig.tight_layout()
    return fig


def _figure_pareto(result, pareto):
    fig, ax = plt.subplots(figsize=(7, 5))
    if pareto:
        size = [r.quantities["outer_diameter"] for _, r in pareto]
        gaf = [r.quantities["gaf_rms"] for _, r in pareto]
        ax.plot(size, gaf, "o-", label="Pareto front (GAF weight swept)")
        labels = {}  # weights that land on the same design share one label
        for (w, _), s, g in zip(pareto, size, gaf, strict=False):
            labels.setdefault((round(s, 3), round(g, 1)), []).append(f"{w:g}")
        for (s, g), ws in labels.items():
            ax.annotate(
                "w_gaf = " + ", ".join(ws),
                (s, g),
                textcoords="offset points",
                xytext=(5, 5),
                fontsize=8,
            )
    ax.plot(
        [result.quantities["outer_diameter"]],
        [result.quantities["gaf_rms"]],
        "r*",
        ms=14,
        label="proposed design",
    )
    ax.set(
        title="GAF against joint size",
        xlabel="outer-diameter proxy 2R + d [mm]",
        ylabel="GAF RMS [N]",
    )
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    return fig


def write(out_dir, result, spec, pareto=(), source="default"):
    """Write report.json, convergence.png, constraint_margins.png and pareto_front.png into out_dir.

    Every file is written under a temporary name in out_dir and renamed into
    place only when all of them are complete, report.json last: a reader never
    sees a half-written report.
    """
    os.makedirs(out_dir, exist_ok=True)
    staged = []
    try:
        for name, make in (
            ("convergence.png", lambda: _figure_convergence(result)),
            ("constraint_margins.png", lambda: _figure_margins(result)),
            ("pareto_front.png", lambda: _figure_pareto(result, list(pareto))),
        ):
            fig = make()
            fd, tmp = tempfile.mkstemp(prefix=f".{name}.", dir=out_dir)
            os.close(fd)
            staged.append((tmp, name))
            fig.savefig(tmp, format="png", dpi=110)
            plt.close(fig)
        fd, tmp = tempfile.mkstemp(prefix=".report.json.", dir=out_dir)
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            json.dump(report_dict(result, spec, pareto, source), f, indent=2, ensure_ascii=False)
        staged.append((tmp, "report.json"))
    except BaseException:
        for tmp, _ in staged:
            if os.path.exists(tmp):
                os.remove(tmp)
        raise
    umask = os.umask(0)
    os.umask(umask)
    for tmp, name in staged:
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp creates 0600 files
        os.replace(tmp, os.path.join(out_dir, name))
