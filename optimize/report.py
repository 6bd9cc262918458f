"""The report of an optimisation: strict JSON and PNG plots, written atomically.

The figures are laid out by Matplotlib's constrained layout (every label inside the
figure; a fraction of a second a figure); text from the spec (names of working conditions, modes,
inputs) is shortened to `LABEL_CHARS` characters with an ellipsis when drawn, so a long
name costs no time and covers nothing.

Plots draw on ``matplotlib.figure.Figure`` objects (no pyplot state, no backend
switch): importing this module changes nothing in the process.
"""

import dataclasses
import errno
import io
import json
import math
import os
import platform
import shutil
import tempfile

import numpy as np

from tripodjax.optimize.spec import REPORT_KEYS, quantity_unit


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


LABEL_CHARS = 40  # the most characters of a name drawn on a figure (an ellipsis beyond)
SAME_DESIGN = 1e-4  # Pareto members whose free variables agree to this relative change: one design


def label(text, chars=LABEL_CHARS):
    """``text`` as drawn on a figure: at most ``chars`` characters, one line, … when shortened."""
    text = " ".join(str(text)[: 4 * chars].split())
    return text if len(text) <= chars else text[: chars - 1] + "…"


def pareto_groups(pareto):
    """The Pareto front ``[(w_gaf_rms, Result)]`` as ``[(weights, Result)]``, one per design.

    Weights whose designs agree within `SAME_DESIGN` (relative, on every free variable) are
    one design (the GAF term too weak to move it): listed once, with every weight that gave it.
    """
    groups = []
    for w, r in pareto:
        for weights, first in groups:
            same = all(
                abs(r.design[k] - first.design[k]) <= SAME_DESIGN * max(1.0, abs(first.design[k]))
                for k in first.design
            )
            if same:
                weights.append(w)
                break
        else:
            groups.append(([w], r))
    return groups


def ranked_sensitivities(elasticities, count):
    """The ``count`` inputs of largest |elasticity| (the largest over the objective and the
    free variables), largest first: the one ranking of the sensitivity table and chart."""

    def size(key):
        return max(
            (abs(v) for v in elasticities[key].values() if v is not None and v == v), default=0.0
        )

    return sorted(elasticities, key=lambda key: -size(key))[:count]


def design_keys(design):
    return {REPORT_KEYS.get(k, k): v for k, v in design.items()}  # a [shaft] entry: its name


def check_pairing(result, spec):
    """``result`` is the Result of ``spec``: its structure (`check_result`) and, when the
    Result carries them, the very numbers it was solved for. A report pairs one design with
    one spec; another spec's numbers beside it would be a report of a design never solved."""
    import jax

    from tripodjax.optimize.problem import check_result

    check_result(spec, result)
    if result.values is None:  # a Result built by hand: only its variables and constraints
        return
    if result.structure != spec.structure and result.structure == spec.deterministic().structure:
        spec = spec.deterministic()  # solved without the [uncertainty] that only the report uses
    if result.structure != spec.structure:
        differ = [
            f.name
            for f in dataclasses.fields(spec.structure)
            if getattr(result.structure, f.name) != getattr(spec.structure, f.name)
        ]
        raise TypeError(
            f"result is the Result of another spec (its {', '.join(differ)} differ); "
            "allowed: the Result of solve(spec) for this spec"
        )
    solved = jax.tree_util.tree_flatten_with_path(result.values)
    given = jax.tree_util.tree_flatten_with_path(spec.values)
    if solved[1] != given[1]:
        raise ValueError(
            "result is the Result of another spec (other sections or keys); allowed: the "
            "Result of solve(spec) for this spec"
        )
    for (path, a), (_, b) in zip(solved[0], given[0], strict=True):
        if not np.array_equal(np.asarray(a), np.asarray(b), equal_nan=True):
            key = ".".join(str(getattr(k, "key", k)) for k in path)
            raise ValueError(
                f"result is the Result of another spec: {key} = {_short(a)} there, "
                f"{_short(b)} in this spec; allowed: the Result of solve(spec) for this spec"
            )


def _short(value):
    text = " ".join(np.array2string(np.asarray(value), threshold=6, precision=6).split())
    return text if len(text) <= 60 else text[:57] + "..."


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
    forces=None,
    halfshaft=None,
    reliability=None,
):
    """Everything a reader needs: design, status, constraints, sensitivities, catalogue, spec.

    ``reliability``: the [`reliability`][tripodjax.optimize.reliability] answer at the
    design, written as the report's ``reliability`` section when given; ``life`` and
    ``forces`` those of [`life_report`][tripodjax.optimize.life_report] and
    [`forces_report`][tripodjax.optimize.forces_report], ``halfshaft`` that of
    [`halfshaft_report`][tripodjax.optimize.halfshaft_report]. ``result`` must be
    the Result of ``spec`` (`check_pairing`).
    """
    check_pairing(result, spec)
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
        "units": {q: quantity_unit(q) for q in result.quantities},
        "multipliers": result.multipliers,
        "history": result.history,
        "starts": result.starts,
    }
    if full_fidelity is not None:
        report["full_fidelity"] = full_fidelity
    if life is not None:  # optimize.life_report of the design
        report["life"] = life
    if forces is not None:  # optimize.forces_report of the design
        report["forces"] = forces
    if halfshaft is not None:  # optimize.halfshaft_report of the spec
        report["halfshaft"] = halfshaft
    if result.sensitivities is not None:
        sens = result.sensitivities
        report["elasticities"] = sens["elasticities"]
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
            "w_gaf_rms": weights[0],
            "same_design_w_gaf_rms": weights,
            **design_keys(r.design),
            "gaf_rms_N": r.quantities.get("gaf_rms"),
            "outer_diameter_mm": r.quantities.get("outer_diameter"),
            "irregularity": r.quantities.get("irregularity"),
            "converged": r.converged,
        }
        for weights, r in pareto_groups(pareto)
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
    from tripodjax.optimize.document import validation_section

    report["validation"] = validation_section(report)  # the verdict table, as on the pages
    return report


def _figure(**kw):
    from matplotlib.figure import Figure

    return Figure(layout="constrained", **kw)


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
    from matplotlib.ticker import MaxNLocator

    for ax in (ax0, ax1):
        ax.grid(alpha=0.3, which="both")
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))  # iterations are whole
    return fig


def figure_margins(result):
    fig = _figure(figsize=(8, 4))
    ax = fig.subplots()
    names = list(result.constraints)
    margins = [result.constraints[n]["margin"] for n in names]
    ax.barh([label(n) for n in names], margins, color=["C2" if m >= 0 else "C3" for m in margins])
    multipliers = getattr(result, "multipliers", None) or {}
    for y, (name, m) in enumerate(zip(names, margins, strict=True)):
        # As the report's table: active where the multiplier is positive (the requirement holds
        # the design), NOT met where the margin is negative, whatever its size.
        active = multipliers.get(name, 0.0) > 0
        text = f"{m:+.2e}" + (" (NOT met)" if m < 0 else " (active)" if active else "")
        ax.annotate(
            text,
            (max(m, 0), y),
            xytext=(4, 0),
            textcoords="offset points",
            va="center",
            fontsize=8,
        )
    # Room right of the longest bar for its number (the layout keeps the axes in the figure,
    # not an annotation beyond its limits); a non-finite margin (a nonfinite solve) has no bar.
    finite = [m for m in margins if math.isfinite(m)]
    low, high = min(finite + [0.0]), max(finite + [0.0])
    ax.set_xlim(low - 0.05 * (high - low), high + 0.3 * (high - low or 1.0))
    ax.axvline(0, color="k", lw=0.8)
    ax.set(
        title="constraint margins at the proposed design (≥ 0: satisfied)",
        xlabel="margin ln(value/limit) [–]",
    )
    ax.grid(alpha=0.3, axis="x")
    return fig


def figure_pareto(result, pareto):
    fig = _figure(figsize=(7, 5))
    ax = fig.subplots()
    groups = pareto_groups(pareto)  # weights that land on one design: one point, one label
    size = [r.quantities["outer_diameter"] for _, r in groups]
    gaf = [r.quantities["gaf_rms"] for _, r in groups]
    # A front only where every weight's solve converged; else the designs the solves ended at.
    converged = all(getattr(r, "converged", True) for _, r in groups)
    ax.plot(
        size,
        gaf,
        "o-",
        label="Pareto front (GAF weight swept)"
        if converged
        else "designs per GAF weight (not every solve converged: no front)",
    )
    star = (result.quantities["outer_diameter"], result.quantities["gaf_rms"])
    low, high = min(size + [star[0]]), max(size + [star[0]])
    middle = (low + high) / 2
    one_size = high - low <= 1e-6 * max(abs(high), 1.0)  # every weight gave one design
    for (weights, _), s, g in zip(groups, size, gaf, strict=True):
        right = s > middle  # a label toward the middle of the plot, never off its edge
        ax.annotate(
            "w_gaf_rms = " + ", ".join(f"{w:g}" for w in weights),
            (s, g),
            textcoords="offset points",
            xytext=(0, 8) if one_size else (-6 if right else 6, 6),
            ha="center" if one_size else "right" if right else "left",
            fontsize=8,
        )
    ax.plot(*([v] for v in star), "r*", ms=14, label="proposed design")
    # Spans of roundoff (a front of one design, the star 5e-13 mm beside it) are no scale:
    # at least ±1 % of the values, so the axes keep readable ticks.
    for values, limits in ((size + [star[0]], ax.set_xlim), (gaf + [star[1]], ax.set_ylim)):
        lo, hi = min(values), max(values)
        pad = 0.01 * max(abs(lo), abs(hi), 1e-9)
        if hi - lo < pad:
            limits(lo - pad, hi + pad)
    ax.set(
        title="GAF against joint size",
        xlabel="outer-diameter proxy 2R + d [mm]",
        ylabel="GAF RMS [N]",
    )
    ax.grid(alpha=0.3)
    ax.margins(x=0.08, y=0.1)
    ax.legend(loc="best")
    return fig


def figure_tornado(result, count=12):
    """The largest elasticities of the optimal objective and design (d ln y / d ln p)."""
    el = result.sensitivities["elasticities"]
    outputs = list(next(iter(el.values()))) if el else ["objective"]
    rows = ranked_sensitivities(el, count)[::-1]  # the table's ranking, the largest on top
    fig = _figure(figsize=(9, 0.45 * len(rows) + 1.8))
    ax = fig.subplots()
    height = 0.8 / len(outputs)
    for i, key in enumerate(rows):
        # Only the bars that are there, centred on the row's label (a zero draws no bar).
        values = [el[key].get(out) for out in outputs]
        drawn = [j for j, v in enumerate(values) if v is not None and v == v and v != 0.0]
        for m, j in enumerate(drawn):
            y = i + (m - (len(drawn) - 1) / 2) * height
            ax.barh(y, values[j], height=height, color=f"C{j % 10}")
    ax.set_yticks(range(len(rows)), [label(k) for k in rows], fontsize=8)
    ax.axvline(0, color="k", lw=0.8)
    ax.set(
        title="sensitivities of the optimum: elasticities (p/y)·dy/dp",
        xlabel="elasticity [–] (% change of y per % change of p)",
    )
    ax.grid(alpha=0.3, axis="x")
    from matplotlib.patches import Patch

    handles = [Patch(color=f"C{j % 10}", label=out) for j, out in enumerate(outputs)]
    fig.legend(handles=handles, fontsize=8, loc="outside lower center", ncol=len(outputs))
    return fig


# Line styles of the constraint boundaries beyond the colour cycle's 10 colours.
LINE_STYLES = ("solid", "dashed", "dotted", "dashdot")


def figure_catalogue(result, catalogue, choice, landscape=None):
    """Catalogue sizes on the (R, d) plane over the constraint landscape, with the ad hoc optimum."""
    fig = _figure(figsize=(7, 6.5))
    ax = fig.subplots()
    if landscape is not None:
        R, d = landscape["R"], landscape["d"]
        worst = np.min(np.stack(list(landscape["margins"].values())), axis=0)
        ax.contourf(R, d, (worst < 0).T.astype(float), levels=[0.5, 1.5], colors="0.85")
        # The boundaries on the grid: a margin of one sign over it (a requirement that R and d
        # do not move, or one met or missed everywhere) has no zero line to draw or name.
        crossing = {
            name: margin
            for name, margin in landscape["margins"].items()
            if _crosses_zero(np.asarray(margin))
        }
        for k, (name, margin) in enumerate(crossing.items()):
            # 10 colours, then the next 10 dashed, …: no two boundaries drawn alike
            style = dict(color=f"C{k % 10}", linestyle=LINE_STYLES[k // 10 % len(LINE_STYLES)])
            ax.contour(
                R,
                d,
                margin.T,
                levels=[0.0],
                colors=style["color"],
                linestyles=style["linestyle"],
                linewidths=1.2,
            )
            ax.plot([], [], lw=1.2, label=f"{name} = 0", **style)
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
    # The legend below the plot, not over its points; the layout is fixed before the labels
    # are placed (their places are found in display coordinates).
    fig.legend(fontsize=8, loc="outside lower center", ncol=3)
    _place_labels(
        fig,
        ax,
        [(e["R_mm"], e["d_roller_mm"]) for e in catalogue],
        [label(e["size"], 12) for e in catalogue],
    )
    return fig


def _crosses_zero(values):
    """Some finite value ≤ 0 and some ≥ 0 (a zero line to draw); NaN ignored, without warnings."""
    finite = values[np.isfinite(values)]
    return finite.size > 0 and finite.min() <= 0.0 <= finite.max()


def _renderer(fig):
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    canvas = fig.canvas if isinstance(fig.canvas, FigureCanvasAgg) else FigureCanvasAgg(fig)
    return canvas.get_renderer()


# Where a point's label may go, in points from the point: right-up first, then around it.
LABEL_OFFSETS = ((3, 3), (3, -9), (-3, 3), (-3, -9), (3, 10), (-3, 10), (3, -16), (-3, -16))


def _place_labels(fig, ax, points, texts):
    """Annotate ``points`` with ``texts``, each at the first of `LABEL_OFFSETS` where it overlaps
    no label placed before it, no marker and stays in the axes (else where it overlaps least)."""
    fig.draw_without_rendering()  # the constrained layout: the axes' place is final
    renderer = _renderer(fig)
    inside = ax.get_window_extent(renderer)
    centres = ax.transData.transform(points) if len(points) else np.zeros((0, 2))
    marker = 4.0 * fig.dpi / 72  # half a marker's width [px]
    placed = []
    for (x, y), text, centre in zip(points, texts, centres, strict=True):
        best = None
        for dx, dy in LABEL_OFFSETS:
            note = ax.annotate(
                text,
                (x, y),
                xytext=(dx, dy),
                textcoords="offset points",
                ha="left" if dx > 0 else "right",
                fontsize=7,
            )
            box = note.get_window_extent(renderer)
            cost = sum(_overlap(box, other) for other in placed)
            cost += sum(
                _overlap(box, _square(c, marker)) for c in centres if not np.array_equal(c, centre)
            )
            cost += box.width * box.height - _overlap(box, inside)
            if best is None or cost < best[0]:
                if best is not None:
                    best[1].remove()
                best = (cost, note, box)
            else:
                note.remove()
            if cost == 0:
                break
        placed.append(best[2])
    fig.set_layout_engine("none")  # the labels were placed for this layout: keep it


def _square(centre, half):
    from matplotlib.transforms import Bbox

    return Bbox.from_extents(centre[0] - half, centre[1] - half, centre[0] + half, centre[1] + half)


def _overlap(a, b):
    """The area [px²] two boxes share."""
    width = min(a.x1, b.x1) - max(a.x0, b.x0)
    height = min(a.y1, b.y1) - max(a.y0, b.y0)
    return max(width, 0.0) * max(height, 0.0)


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
            ax0.bar(range(len(gears)), 100 * share, bottom=100 * bottom, label=label(mode))
            bottom += share
        ax0.set_xticks(range(len(gears)), [label(g) for g in gears])
        ax0.legend(fontsize=8)
        ax0.set(title="damage by gear and driving mode", xlabel="gear")
    else:
        ax0.bar(range(len(cases)), [100 * c["damage_share"] for c in cases])
        ax0.set_xticks(range(len(cases)), [label(c["case"]) for c in cases])
        ax0.set(title="damage by spectrum case", xlabel="case")
    ax0.set(ylabel="share of the damage [%]")
    conditions = life["conditions"]
    ax1.bar(range(len(conditions)), [100 * c["damage_share"] for c in conditions], color="C3")
    ax1.set_xticks(
        range(len(conditions)),
        [label(c["name"], 24) for c in conditions],
        rotation=30,
        ha="right",
        rotation_mode="anchor",  # each label ends under its bar
        fontsize=8,
    )
    ax1.set(
        title=f"damage by condition (life {life['km']:,.0f} km)",
        ylabel="share of the damage [%]",
    )
    for ax in (ax0, ax1):
        ax.grid(alpha=0.3, axis="y")
    return fig


def figure_life_conditions(life=None, halfshaft=None):
    """The life of each joint per working condition [km], with its combined life and the
    required mileage: the inboard tripod's (``life``, of
    [`life_report`][tripodjax.optimize.life_report]) and the outboard joint's (``halfshaft``, of
    [`halfshaft_report`][tripodjax.optimize.halfshaft_report]), whichever is given."""
    joints = []
    if life is not None:
        joints.append(("inboard tripod", life["conditions"], life["km"], life["required_km"]))
    if halfshaft is not None:
        o = halfshaft["outboard"]
        joints.append(("outboard joint", o["conditions"], o["life_km"], o["required_km"]))
    if not joints:
        raise ValueError("figure_life_conditions needs the tripod's life or the halfshaft's")
    fig = _figure(figsize=(11, 4))
    axes = np.atleast_1d(fig.subplots(1, len(joints), sharey=True))
    for ax, (name, conditions, km, required) in zip(axes, joints, strict=True):
        ax.bar(range(len(conditions)), [c["life_km"] for c in conditions], color="C0")
        ax.set_xticks(
            range(len(conditions)),
            [
                f"{label(c['name'], 16)}\n{c['angle_deg']:.1f}°, {100 * c['share']:.0f} %"
                for c in conditions
            ],
            fontsize=8,
        )
        ax.axhline(km, color="C2", lw=1.5)
        ax.axhline(required, color="C3", lw=1.2, ls="--")
        ax.set_title(f"{name}\n{km:,.0f} km combined, {required:,.0f} km required", fontsize=10)
        ax.set(xlabel="working condition: angle, share of the mileage")
        ax.grid(alpha=0.3, axis="y")
    axes[0].set(ylabel="life [km]")
    from matplotlib.lines import Line2D

    handles = [
        Line2D([], [], color="C2", lw=1.5, label="combined life (Miner's rule over the shares)"),
        Line2D([], [], color="C3", lw=1.2, ls="--", label="required mileage"),
    ]
    fig.legend(handles=handles, fontsize=8, loc="outside lower center", ncol=2)
    return fig


def figure_shaft_damage(halfshaft):
    """Each shaft section's fatigue damage (Miner's sum over the required mileage) by gear, at
    its critical radius (``halfshaft``: of [`halfshaft_report`][tripodjax.optimize.halfshaft_report])."""
    sections = halfshaft["sections"]
    gears = [g["gear"] for g in sections[0]["damage_by_gear"]]
    fig = _figure(figsize=(11, 4))
    ax = fig.subplots()
    width = 0.8 / len(sections)
    for k, s in enumerate(sections):
        x = np.arange(len(gears)) + (k - (len(sections) - 1) / 2) * width
        damage = [g["damage"] for g in s["damage_by_gear"]]
        ax.bar(
            x,
            damage,
            width,
            color=f"C{k % 10}",
            label=f"{label(s['name'], 20)} (Σ {s['damage']:.3g})",
        )
    ax.set_xticks(range(len(gears)), [label(g, 8) for g in gears])
    ax.set(
        title="shaft sections: fatigue damage by gear (Miner's sum over the required mileage; "
        f"allowed total ≤ {sections[0]['allowed_damage']:g})",
        xlabel="gear",
        ylabel="damage [–]",
    )
    fig.legend(fontsize=8, loc="outside lower center", ncol=min(len(sections), 5))
    ax.grid(alpha=0.3, axis="y")
    return fig


def figure_importance(reliability):
    """The FORM importance factors α² of the uncertain inputs, one stacked bar per requirement."""
    rows = [r for r in reliability["requirements"] if r.get("importance")]
    inputs = list(reliability["inputs"])
    fig = _figure(figsize=(9, 0.5 * len(rows) + 2.2))
    ax = fig.subplots()
    left = np.zeros(len(rows))
    for i, key in enumerate(inputs):
        share = np.nan_to_num([r["importance"][key] for r in rows])  # NaN: no FORM estimate
        ax.barh(range(len(rows)), share, left=left, color=f"C{i % 10}", label=label(key))
        left += share
    labels = []
    for r in rows:
        beta, p = r.get("beta_form"), r.get("probability_form")
        beta = "β = ∞" if beta is None else f"β = {beta:.2f}"
        note = "" if r.get("form_converged") else ", FORM not converged"
        estimate = "FORM: no estimate (margin not finite)" if p is None else f"{beta}, P = {p:.2g}"
        labels.append(f"{label(r['name'])}\n{estimate}{note if p is not None else ''}")
    ax.set_yticks(range(len(rows)), labels, fontsize=8)
    ax.set(
        xlim=(0, 1),
        title="which tolerance matters: FORM importance factors α² per requirement",
        xlabel="share of the variance of the linearised margin at the design point [–]",
    )
    fig.legend(fontsize=8, loc="outside lower center", ncol=min(4, len(inputs)))
    ax.grid(alpha=0.3, axis="x")
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
        for tmp, _ in staged:
            os.chmod(tmp, 0o666 & ~umask)  # mkstemp creates 0600 files
        _commit(out_dir, staged)
    finally:
        for tmp, _ in staged:  # whatever was not renamed into place
            if os.path.exists(tmp):
                os.remove(tmp)


def _commit(out_dir, staged):
    """Rename every staged ``(temporary, name)`` into place, all or none: where one rename fails,
    the files already renamed are put back as they were (an older file restored from its
    hard link, a new name removed) and the error is raised. ``staged`` is emptied as its files
    are renamed, so that what is left in it is the caller's to remove."""
    kept, placed = [], []  # (path, link to the older file or None); the paths renamed into place
    try:
        for _, name in staged:
            path = os.path.join(out_dir, name)
            if os.path.lexists(path) and not os.path.isfile(path):
                raise IsADirectoryError(errno.EISDIR, f"{name} there is not a file", path)
            older = None
            if os.path.lexists(path):
                older = os.path.join(out_dir, f".{name}.{os.getpid()}.older")
                try:  # the older file stays in place until it is replaced
                    os.link(path, older, follow_symlinks=False)
                except OSError:  # a file system without hard links
                    shutil.copy2(path, older, follow_symlinks=False)
            kept.append((path, older))
        while staged:
            tmp, name = staged[0]
            path = os.path.join(out_dir, name)
            os.replace(tmp, path)
            placed.append(path)
            staged.pop(0)
    except BaseException:
        for path, older in kept:
            if path in placed:
                if older is None:
                    os.remove(path)
                else:
                    os.replace(older, path)
        raise
    finally:
        for _, older in kept:
            if older is not None and os.path.lexists(older):
                os.remove(older)
