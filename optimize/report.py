"""The report of an optimisation: strict JSON and PNG plots, written atomically.

The figures use fixed margins rather than ``tight_layout`` (which cost as much as the
rest of a warm run together).

Plots draw on ``matplotlib.figure.Figure`` objects (no pyplot state, no backend
switch): importing this module changes nothing in the process.
"""

import io
import json
import math
import os
import platform
import tempfile

import numpy as np

from tripodjax.optimize.spec import QUANTITIES, REPORT_KEYS


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


def strict(value, path="", notes=None):
    """``value`` with every non-finite float replaced by None (noted in ``notes``): strict JSON."""
    if isinstance(value, dict):
        return {
            str(k): strict(v, f"{path}.{k}" if path else str(k), notes) for k, v in value.items()
        }
    if isinstance(value, (list, tuple)):
        return [strict(v, f"{path}[{i}]", notes) for i, v in enumerate(value)]
    if hasattr(value, "item") and not isinstance(value, (str, bytes)):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        if notes is not None:
            notes.append(f"{path} = {value!r} is not finite; written as null")
        return None
    return value


def design_keys(design):
    return {REPORT_KEYS[k]: v for k, v in design.items()}


def report_dict(
    result,
    spec,
    *,
    pareto=(),
    catalogue=None,
    choice=None,
    full_fidelity=None,
    source="default",
    life=None,
    reliability=None,
):
    """Everything a reader needs: design, status, constraints, sensitivities, catalogue, spec.

    ``reliability``: the [`reliability`][tripodjax.optimize.reliability] answer at the
    design, written as the report's ``reliability`` section when given.
    """
    report = {
        "design": design_keys(result.design),
        "free_variables": list(spec.structure.free),
        "objective": result.objective,
        "converged": result.converged,
        "status": {
            "kkt_converged": result.kkt_converged,
            "halfshaft_converged": result.halfshaft_converged,
            "hertz_converged": result.hertz_converged,
            "feasible": result.feasible,
            "result": result.result,
        },
        "kkt_residual": result.kkt_residual,
        "tolerance": float(spec.values["solver"]["tolerance"]),
        "fidelity": {"solver": result.fidelity, "n_theta": spec.structure.n_theta},
        "constraints": result.constraints,
        "quantities": result.quantities,
        "units": {q: QUANTITIES[q][0] for q in result.quantities},
        "multipliers": result.multipliers,
        "history": result.history,
        "starts": result.starts,
    }
    if full_fidelity is not None:
        report["full_fidelity"] = full_fidelity
    if life is not None:  # optimize.life_report of the design
        report["life"] = life
    if result.sensitivities is not None:
        sens = result.sensitivities
        keys = ("active", "on_bound", "near_switch", "withheld", "switch_distance", "switch_step")
        notes = {k: sens[k] for k in (*keys, "condition_number", "unavailable") if k in sens}
        # An input with a switch within switch_step has no derivative (it would hold on one
        # side only): it is absent from "sensitivities" and listed under "withheld".
        report["sensitivities"] = sens["derivatives"]
        report["sensitivity_notes"] = notes
    if catalogue is not None:
        report["catalogue"] = catalogue
        report["catalogue_choice"] = choice
    report["pareto_front"] = [
        {
            "w_gaf_rms": w,
            **design_keys(r.design),
            "gaf_rms_N": r.quantities.get("gaf_rms"),
            "outer_diameter_mm": r.quantities.get("outer_diameter"),
            "irregularity": r.quantities.get("irregularity"),
            "converged": r.converged,
        }
        for w, r in pareto
    ]
    if reliability is not None:
        report["reliability"] = reliability
    report["spec_source"] = source
    report["spec"] = spec.resolved
    report["versions"] = versions()
    notes = []
    report = strict(report, notes=notes)
    if notes:
        report["nonfinite_notes"] = notes
    return report


def _figure(**kw):
    from matplotlib.figure import Figure

    return Figure(**kw)


def figure_convergence(result):
    fig = _figure(figsize=(11, 4))
    ax0, ax1 = fig.subplots(1, 2)
    it = range(len(result.history["objective"]))
    ax0.plot(it, result.history["objective"], "o-")
    ax0.set(
        title="objective of the chosen start", xlabel="outer iteration [–]", ylabel="objective [–]"
    )
    ax1.semilogy(it, result.history["kkt_residual"], "o-")
    ax1.set(title="KKT residual", xlabel="outer iteration [–]", ylabel="KKT residual [–]")
    for ax in (ax0, ax1):
        ax.grid(alpha=0.3, which="both")
    fig.subplots_adjust(left=0.07, right=0.98, bottom=0.14, top=0.9, wspace=0.25)
    return fig


def figure_margins(result):
    fig = _figure(figsize=(8, 4))
    ax = fig.subplots()
    names = list(result.constraints)
    margins = [result.constraints[n]["margin"] for n in names]
    ax.barh(names, margins, color=["C2" if m >= 0 else "C3" for m in margins])
    for y, m in enumerate(margins):
        label = f"{m:+.2e}" + (" (active)" if abs(m) < 1e-3 else "")
        ax.annotate(
            label,
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
    fig.subplots_adjust(left=0.2, right=0.95, bottom=0.14, top=0.9)
    return fig


def figure_pareto(result, pareto):
    fig = _figure(figsize=(7, 5))
    ax = fig.subplots()
    size = [r.quantities["outer_diameter"] for _, r in pareto]
    gaf = [r.quantities["gaf_rms"] for _, r in pareto]
    ax.plot(size, gaf, "o-", label="Pareto front (GAF weight swept)")
    labels = {}  # weights that land on the same design share one label
    for (w, _), s, g in zip(pareto, size, gaf, strict=True):
        labels.setdefault((round(s, 3), round(g, 1)), []).append(f"{w:g}")
    for (s, g), ws in labels.items():
        ax.annotate(
            "w_gaf_rms = " + ", ".join(ws),
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
    fig.subplots_adjust(left=0.12, right=0.97, bottom=0.11, top=0.93)
    return fig


def figure_tornado(result, count=12):
    """The largest elasticities of the optimal objective and design (d ln y / d ln p)."""
    el = result.sensitivities["elasticities"]
    outputs = list(next(iter(el.values()))) if el else ["objective"]
    rows = sorted(
        el,
        key=lambda k: -max((abs(v) for v in el[k].values() if v == v), default=0.0),
    )[:count][::-1]
    fig = _figure(figsize=(9, 0.45 * len(rows) + 1.8))
    ax = fig.subplots()
    height = 0.8 / len(outputs)
    for j, out in enumerate(outputs):
        values = [el[k].get(out, 0.0) for k in rows]
        ax.barh([i + j * height for i in range(len(rows))], values, height=height, label=out)
    ax.set_yticks([i + 0.4 - height / 2 for i in range(len(rows))], rows, fontsize=8)
    ax.axvline(0, color="k", lw=0.8)
    ax.set(
        title="sensitivities of the optimum: elasticities (p/y)·dy/dp",
        xlabel="elasticity [–] (% change of y per % change of p)",
    )
    ax.grid(alpha=0.3, axis="x")
    ax.legend(fontsize=8)
    fig.subplots_adjust(
        left=0.3, right=0.97, bottom=0.6 / fig.get_figheight(), top=1 - 0.45 / fig.get_figheight()
    )
    return fig


def figure_catalogue(result, catalogue, choice, landscape=None):
    """Catalogue sizes on the (R, d) plane over the constraint landscape, with the ad hoc optimum."""
    fig = _figure(figsize=(7, 5.5))
    ax = fig.subplots()
    if landscape is not None:
        R, d = landscape["R"], landscape["d"]
        worst = np.min(np.stack(list(landscape["margins"].values())), axis=0)
        ax.contourf(R, d, (worst < 0).T.astype(float), levels=[0.5, 1.5], colors="0.85")
        for k, (name, margin) in enumerate(landscape["margins"].items()):
            ax.contour(R, d, margin.T, levels=[0.0], colors=f"C{k % 10}", linewidths=1.2)
            ax.plot([], [], color=f"C{k % 10}", lw=1.2, label=f"{name} = 0")
    for family, marker in (("GE", "s"), ("GI", "^")):
        for feasible, color in ((True, "C2"), (False, "C3")):
            pts = [e for e in catalogue if e["family"] == family and e["feasible"] == feasible]
            if pts:
                ax.scatter(
                    [e["R_mm"] for e in pts],
                    [e["d_roller_mm"] for e in pts],
                    marker=marker,
                    color=color,
                    label=f"{family} {'feasible' if feasible else 'infeasible'}",
                )
            for e in pts:
                ax.annotate(
                    e["size"],
                    (e["R_mm"], e["d_roller_mm"]),
                    xytext=(3, 3),
                    textcoords="offset points",
                    fontsize=7,
                )
    if choice is not None:
        ax.scatter(
            [choice["R_mm"]],
            [choice["d_roller_mm"]],
            s=200,
            facecolors="none",
            edgecolors="k",
            label=f"catalogue choice {choice['family']} {choice['size']}",
        )
    ax.plot([result.design["R"]], [result.design["d_roller"]], "r*", ms=15, label="ad hoc optimum")
    ax.set(
        title="catalogue sizes over the constraint landscape (grey: infeasible)",
        xlabel="pitch-circle radius R [mm]",
        ylabel="roller diameter d [mm]",
    )
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.subplots_adjust(left=0.11, right=0.97, bottom=0.1, top=0.94)
    return fig


def figure_damage(life):
    """What eats the joint: damage share by gear (stacked by mode) and by working condition.

    ``life``: [`life_report`][tripodjax.optimize.life_report] of the design.
    """
    fig = _figure(figsize=(11, 4))
    ax0, ax1 = fig.subplots(1, 2, gridspec_kw={"width_ratios": [3, 2]})
    cases = life["damage_by_case"]
    if cases and cases[0]["gear"] is not None:
        gears = list(dict.fromkeys(c["gear"] for c in cases))
        modes = list(dict.fromkeys(c["mode"] for c in cases))
        bottom = np.zeros(len(gears))
        for mode in modes:
            share = np.array(
                [
                    sum(c["damage_share"] for c in cases if c["mode"] == mode and c["gear"] == g)
                    for g in gears
                ]
            )
            ax0.bar(gears, 100 * share, bottom=100 * bottom, label=mode)
            bottom += share
        ax0.legend(fontsize=8)
        ax0.set(title="damage by gear and driving mode", xlabel="gear")
    else:
        ax0.bar([str(c["case"]) for c in cases], [100 * c["damage_share"] for c in cases])
        ax0.set(title="damage by spectrum case", xlabel="case")
    ax0.set(ylabel="share of the damage [%]")
    names = [c["name"] for c in life["conditions"]]
    ax1.bar(names, [100 * c["damage_share"] for c in life["conditions"]], color="C3")
    ax1.set(
        title=f"damage by working condition (life {life['km']:,.0f} km)",
        ylabel="share of the damage [%]",
    )
    ax1.tick_params(axis="x", labelrotation=30, labelsize=8)
    for ax in (ax0, ax1):
        ax.grid(alpha=0.3, axis="y")
    fig.subplots_adjust(left=0.07, right=0.98, bottom=0.22, top=0.9, wspace=0.25)
    return fig


def figure_importance(reliability):
    """The FORM importance factors α² of the uncertain inputs, one stacked bar per requirement."""
    rows = [r for r in reliability["requirements"] if r.get("importance")]
    inputs = list(reliability["inputs"])
    fig = _figure(figsize=(9, 0.5 * len(rows) + 2.2))
    ax = fig.subplots()
    left = np.zeros(len(rows))
    for i, key in enumerate(inputs):
        share = np.array([r["importance"][key] for r in rows])
        ax.barh(range(len(rows)), share, left=left, color=f"C{i % 10}", label=key)
        left += share
    labels = []
    for r in rows:
        beta, p = r.get("beta_form"), r.get("probability_form")
        beta = "β = ∞" if beta is None else f"β = {beta:.2f}"
        note = "" if r.get("form_converged") else ", FORM not converged"
        labels.append(f"{r['name']}\n{beta}, P = {p:.2g}{note}")
    ax.set_yticks(range(len(rows)), labels, fontsize=8)
    ax.set(
        xlim=(0, 1),
        title="which tolerance matters: FORM importance factors α² per requirement",
        xlabel="share of the variance of the linearised margin at the design point [–]",
    )
    ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.18), ncol=min(4, len(inputs)))
    ax.grid(alpha=0.3, axis="x")
    fig.subplots_adjust(left=0.3, right=0.97, bottom=0.32, top=0.9)
    return fig


def write(out_dir, report, figures, documents=None, *, with_json=True):
    """Write report.json, the figures ``{name: Figure}`` (as PNG) and the ``documents``
    ``{name: writer(path, pngs)}`` (``pngs``: the figures' PNG bytes by name) into out_dir,
    atomically.

    Every file is written under a temporary name in out_dir and renamed into place
    only when all of them are complete, report.json last: a reader never sees a
    half-written report, and a failure leaves the older report intact.
    """
    os.makedirs(out_dir, exist_ok=True)
    staged = []
    umask = os.umask(0)
    os.umask(umask)

    def stage(name):
        fd, tmp = tempfile.mkstemp(prefix=f".{name}.", dir=out_dir)
        staged.append((tmp, name))
        return fd, tmp

    try:
        pngs = {}
        for name, fig in figures.items():
            buffer = io.BytesIO()
            fig.savefig(buffer, format="png", dpi=110)
            pngs[name] = buffer.getvalue()
            fd, tmp = stage(name)
            with os.fdopen(fd, "wb") as f:
                f.write(pngs[name])
        for name, writer in (documents or {}).items():
            fd, tmp = stage(name)
            os.close(fd)
            writer(tmp, pngs)
        if with_json:
            fd, tmp = stage("report.json")
            with os.fdopen(fd, "w", encoding="utf-8") as f:
                json.dump(report, f, indent=2, ensure_ascii=False, allow_nan=False)
        while staged:
            tmp, name = staged[0]
            os.chmod(tmp, 0o666 & ~umask)  # mkstemp creates 0600 files
            os.replace(tmp, os.path.join(out_dir, name))
            staged.pop(0)
    finally:
        for tmp, _ in staged:  # whatever was not renamed into place
            if os.path.exists(tmp):
                os.remove(tmp)
