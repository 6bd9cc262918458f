"""report.html and report.xlsx: read as a person would (headless Chromium), and read back."""

import copy
import json
import math
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
import tomllib
import types
from pathlib import Path

import numpy as np
import pytest
from browser import Page, executable
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.text import Text

from tripodjax import optimize
from tripodjax.optimize import document, report

ROOT = Path(__file__).resolve().parent.parent
# The example report and its screenshot, for the docs page (docs/hooks.py reads them).
EXAMPLE = Path(os.environ.get("TRIPODJAX_REPORT_EXAMPLE") or ROOT / "build" / "report-example")
CHROMIUM = executable()
# Skipped only outside CI where no Chromium can be had; in CI (.ci/run installs it) a missing
# browser fails the browser tests instead of skipping them.
needs_chromium = pytest.mark.skipif(
    CHROMIUM is None and not os.environ.get("CI"),
    reason="no Chromium on PATH (.ci/run installs it: apt-get install chromium, as root)",
)

LIFE = {
    "km": 123456.0,
    "hours": 2345.5,
    "required_km": 100000.0,
    "angle_law": "workbook",
    "M_max_forward_Nm": 1154.0,
    "M_max_backward_Nm": 577.0,
    "conditions": [
        {"name": "main", "angle_deg": 6.5, "share": 0.45, "life_km": 150000.0, "damage_share": 0.4},
        {
            "name": "straight",
            "angle_deg": 0.0,
            "share": 0.2,
            "life_km": 410000.0,
            "damage_share": 0.1,
        },
        {
            "name": "shock",
            "angle_deg": 12.8,
            "share": 0.35,
            "life_km": 87654.3,
            "damage_share": 0.5,
        },
    ],
    "damage_by_case": [
        {"mode": "forward", "gear": "1", "engine_condition": "full load", "damage_share": 0.75},
        {"mode": "backward", "gear": "R", "engine_condition": "full load", "damage_share": 0.25},
    ],
}
RELIABILITY = {
    "method": "FORM and Monte Carlo",
    "inputs": {"loads.M_max": "normal, 5 % coefficient of variation"},
    "requirements": [
        {
            "name": "life",
            "beta_form": 2.345,
            "probability_form": 0.00951,
            "probability_mc": 0.0102,
            "mc_interval_95": [0.0085, 0.0121],
            "samples": 20000,
            "agree": True,
            "importance": {"loads.M_max": 0.98},
        }
    ],
    "system_probability_mc": 0.0117,
    "system_interval_95": [0.0099, 0.0137],
    "status": {"converged": True},
}
SWITCH = {"life": {"loads.M_max": 0.0123, "hertz.P_d": -0.0456}}


@pytest.fixture
def run(default_report):
    done, out = default_report
    assert done.returncode == 0, done.stderr
    return out, json.loads((out / "report.json").read_text())


def without_sections(body):
    body = {
        k: copy.deepcopy(v)
        for k, v in body.items()
        if k not in ("life", "forces", "halfshaft", "reliability")
    }
    body["sensitivity_notes"].pop("switch_distance", None)
    return body


def with_sections(body):
    body = copy.deepcopy(body)
    body["life"] = LIFE
    body["reliability"] = RELIABILITY
    body["sensitivity_notes"]["switch_distance"] = SWITCH
    body["sensitivity_notes"]["switch_step"] = 0.01
    return body


def test_cli_writes_a_self_contained_html_and_a_workbook_beside_the_json(run):
    out, body = run
    assert {"report.json", "report.html", "validation.html", "report.xlsx"} <= set(os.listdir(out))
    assert not [n for n in os.listdir(out) if n.startswith(".")]  # nothing staged is left
    html = (out / "report.html").read_text(encoding="utf-8")
    assert "<script" not in html.lower()
    # Every image and link is embedded: nothing for a browser to fetch.
    references = re.findall(r"""(?:src|href)\s*=\s*["']([^"']*)""", html)
    assert references and all(r.startswith("data:") for r in references)
    assert "@page { size: A4" in html
    assert body["written"]["command"].startswith("optimize-joint")
    for name in ("Summary", "Requirements", "Quantities", "Sensitivities", "Catalogue"):
        assert f"<h2>{name}" in html
    # The contents in the reader's order.
    order = [html.index(f'id="{t}"') for t in document.tables(body)] + [html.index('id="spec"')]
    assert order == sorted(order)


@needs_chromium
def test_report_opens_offline_in_chromium_with_the_reports_numbers(run):
    out, body = run
    with Page(CHROMIUM) as page:
        page.open((out / "report.html").as_uri())
        assert page.console_errors() == []
        assert [u for u in page.requests() if not u.startswith(("file:", "data:"))] == []
        cells = page.evaluate(
            """Object.fromEntries(["summary", "requirements", "quantities"].map(name => [name,
               [...document.querySelectorAll(`table[data-table="${name}"] tbody tr`)].map(tr =>
               [...tr.cells].map(td => [td.textContent.trim(), td.dataset.value ?? null]))]))"""
        )
        images = page.evaluate(
            "[...document.images].map(i => [i.complete && i.naturalWidth > 0, i.alt])"
        )
        EXAMPLE.mkdir(parents=True, exist_ok=True)
        page.screenshot(EXAMPLE / "report.png", height=1500)
        page.pdf(EXAMPLE / "report.pdf")
        # Printed: on the width of an A4 page within the page margins (186 mm), every table fits.
        page.send("Emulation.setEmulatedMedia", session=True, media="print")
        page.send(
            "Emulation.setDeviceMetricsOverride",
            session=True,
            width=round(186 / 25.4 * 96),
            height=1000,
            deviceScaleFactor=1,
            mobile=False,
        )
        overflow = page.evaluate(
            """[...document.querySelectorAll("table, img")].filter(e =>
               e.getBoundingClientRect().right > document.documentElement.clientWidth + 1)
               .map(e => e.dataset.table || e.alt)"""
        )
        # and no number is broken over two lines (at its exponent's minus sign, say)
        broken = page.evaluate(
            """[...document.querySelectorAll("td.num")].filter(td => {
               const range = document.createRange(); range.selectNodeContents(td.firstChild);
               return new Set([...range.getClientRects()].map(r => Math.round(r.top))).size > 1;
               }).map(td => td.textContent.trim())"""
        )
    assert overflow == []
    assert broken == []
    pdf = (EXAMPLE / "report.pdf").read_bytes()
    boxes = {tuple(map(float, b.split())) for b in re.findall(rb"/MediaBox\s*\[([^\]]*)\]", pdf)}
    assert len(boxes) == 1  # every page A4: 210 × 297 mm = 595.3 × 841.9 pt
    assert next(iter(boxes)) == pytest.approx((0, 0, 595.3, 841.9), abs=1.5)
    for name in ("report.html", "report.xlsx"):
        (EXAMPLE / name).write_bytes((out / name).read_bytes())
    assert (EXAMPLE / "report.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert pdf[:5] == b"%PDF-"
    pngs = [n for n in os.listdir(out) if n.endswith(".png")]
    assert len(images) == len(pngs) and all(ok for ok, _ in images), images

    def value(text_and_value):
        text, exact = text_and_value
        assert exact is not None, text
        number = float(exact)
        shown = float(text.split()[0])  # the text shows the number rounded (5 digits)
        assert shown == pytest.approx(number, rel=1e-4, abs=1e-12)
        return number

    summary = {row[0][0]: row for row in cells["summary"]}
    assert value(summary["R"][2]) == body["design"]["R_mm"]
    assert value(summary["d_roller"][2]) == body["design"]["d_roller_mm"]
    assert value(summary["objective"][2]) == body["objective"]
    choice = body["catalogue_choice"]
    if choice is not None:
        assert value(summary["objective"][3]) == choice["objective"]
        assert summary["design"][3][0] == f"{choice['family']} {choice['size']}"
    else:  # the default vehicle's joint is larger than every catalogue size
        assert "not available" in summary["objective"][3][0].lower()
    for name, c in body["constraints"].items():
        row = summary[f"margin {name}"]
        assert value(row[2]) == c["margin"]
        if choice is not None:
            assert value(row[3]) == choice["margins"][name]
        assert ("✓ met" in row[2][0]) == (c["margin"] >= 0)  # not by colour alone
    requirements = {row[0][0]: row for row in cells["requirements"]}
    assert set(requirements) == set(body["constraints"])
    for name, c in body["constraints"].items():
        row = requirements[name]
        assert row[1][0] == c["sense"] and row[4][0] == c["unit"]
        assert [value(row[j]) for j in (2, 3, 5, 6)] == [
            c["value"],
            c["limit"],
            c["margin"],
            body["multipliers"][name],
        ]
        assert row[7][0] == ("yes" if name in body["sensitivity_notes"]["active"] else "no")
    quantities = {row[0][0]: row for row in cells["quantities"]}
    for name, q in body["quantities"].items():
        assert value(quantities[name][2]) == q
        assert quantities[name][1][0] == body["units"][name]


@needs_chromium
def test_optional_sections_render_in_chromium_and_say_why_when_absent(run, tmp_path):
    out, body = run
    page_with = tmp_path / "with.html"
    page_with.write_text(document.render_html(with_sections(body)), encoding="utf-8")
    with Page(CHROMIUM) as page:
        page.open(page_with.as_uri())
        assert page.console_errors() == []
        life = page.evaluate(
            """[...document.querySelectorAll('table[data-table="life"] tbody tr')].map(tr =>
               [...tr.cells].map(td => td.dataset.value ?? td.textContent))"""
        )
        text = page.evaluate("document.body.innerText")
    assert [row[0] for row in life] == ["main", "straight", "shock"]
    assert [float(row[3]) for row in life] == [c["life_km"] for c in LIFE["conditions"]]
    assert (
        "Not available" not in text.split("Life per working condition")[1].split("Sensitivities")[0]
    )
    body = without_sections(body)  # the default run has a life section and switch distances
    absent = document.render_html(body)
    assert "Not available: the report has no life section" in absent
    assert "Not available: the spec has no uncertainty" in absent
    assert "Not available: the report has no forces section" in absent
    assert "Not available: the report has no halfshaft section" in absent
    assert "Not available: the report has no switch distances" in absent


def test_optional_sections_synthetic_tables_hold_their_numbers(run):
    _, body = run
    tables = document.tables(with_sections(body))
    assert [r[4] for r in tables["life"].rows] == [c["damage_share"] for c in LIFE["conditions"]]
    assert [r[3] for r in tables["damage"].rows] == [0.75, 0.25]
    # An explicit spectrum's cases: their index, no "None" for mode, gear or engine condition.
    explicit = dict(
        LIFE,
        damage_by_case=[
            {"mode": None, "gear": None, "engine_condition": None, "case": i, "damage_share": d}
            for i, d in enumerate((0.6, 0.4))
        ],
    )
    body_explicit = dict(with_sections(body), life=explicit)
    rows = document.tables(body_explicit)["damage"].rows
    assert [r[:3] for r in rows] == [["case 0", "", ""], ["case 1", "", ""]]
    row = tables["reliability"].rows[0]
    assert row[:7] == ["life", 2.345, 0.00951, 0.0102, 0.0085, 0.0121, 20000.0]
    assert "loads.M_max (0.98)" in row[8]
    assert sorted(r[2] for r in tables["switch"].rows) == [-0.0456, 0.0123]
    assert "0.01" in tables["switch"].notes[0]
    body = without_sections(body)
    for name in ("life", "damage", "forces", "reliability", "switch"):
        assert document.tables(body)[name].unavailable  # absent: a reason, not a blank


def read_sheets(path):
    import openpyxl  # the report extra, part of the test extra: a missing one fails

    book = openpyxl.load_workbook(path)
    sheets = {}
    for sheet in book.worksheets:
        rows = [list(r) for r in sheet.iter_rows(values_only=True)]
        assert sheet.freeze_panes == "A2" or len(rows) == 1
        header, body = rows[0], []
        for r in rows[1:]:
            if all(v is None for v in r):
                break  # the notes follow an empty row
            body.append(dict(zip(header, r, strict=True)))
        sheets[sheet.title] = body
    return sheets


def same(from_xlsx, from_json):
    """Equal, floats to the 16 significant digits openpyxl writes ("%.16g")."""
    assert len(from_xlsx) == len(from_json)
    for x, j in zip(from_xlsx, from_json, strict=True):
        if isinstance(j, float) and not isinstance(j, bool):
            # "%.16g" writes 0.0 as 0: read back as an int, still a number
            assert isinstance(x, (int, float)) and x == pytest.approx(j, rel=1e-15, abs=0), (x, j)
        else:
            assert x == j
    return True


def test_xlsx_round_trips_every_number_of_the_json(run):
    out, body = run
    sheets = read_sheets(out / "report.xlsx")
    assert {
        "summary",
        "requirements",
        "quantities",
        "life",
        "sensitivities",
        "catalogue",
        "pareto_front",
    } <= set(sheets)
    requirements = {r["requirement"]: r for r in sheets["requirements"]}
    assert set(requirements) == set(body["constraints"])
    full = body["full_fidelity"]
    for name, c in body["constraints"].items():
        r = requirements[name]
        columns = ("value", "limit", "margin ln(value/limit) [–]", "multiplier [–]")
        assert same(
            [r[k] for k in columns] + [r["at full fidelity: margin [–]"]],
            [
                c["value"],
                c["limit"],
                c["margin"],
                body["multipliers"][name],
                full["constraints"][name],
            ],
        )
    quantities = {r["quantity"]: r for r in sheets["quantities"]}
    assert set(quantities) == set(body["quantities"])
    for name, q in body["quantities"].items():
        r = quantities[name]
        assert same(
            [r["unit"], r["proposed design"], r["catalogue choice"], r["at full fidelity"]],
            [
                body["units"][name],
                q,
                (body["catalogue_choice"] or {})
                .get("quantities", {})
                .get(name, r["catalogue choice"]),
                full["quantities"][name],
            ],
        )
    summary = {r["item"]: r for r in sheets["summary"]}
    choice = body["catalogue_choice"]
    assert same(
        [summary[k]["proposed design"] for k in ("R", "d_roller", "objective")],
        [body["design"]["R_mm"], body["design"]["d_roller_mm"], body["objective"]],
    )
    if choice is None:  # no catalogue size is feasible: those cells are not numbers
        assert not any(
            isinstance(r.get("catalogue choice"), (int, float)) for r in summary.values()
        )
    else:
        assert same(
            [summary[k]["catalogue choice"] for k in ("R", "d_roller", "objective")],
            [choice["R_mm"], choice["d_roller_mm"], choice["objective"]],
        )
    for name, c in body["constraints"].items():
        row = summary[f"margin {name}"]
        assert same(
            [row["proposed design"]] + ([row["catalogue choice"]] if choice else []),
            [c["margin"]] + ([choice["margins"][name]] if choice else []),
        )
    catalogue = sheets["catalogue"]
    assert len(catalogue) == len(body["catalogue"])
    for r, e in zip(catalogue, body["catalogue"], strict=True):
        assert same(
            [r[k] for k in ("family", "size", "R [mm]", "d [mm]", "feasible", "objective [–]")],
            [e["family"], e["size"], e["R_mm"], e["d_roller_mm"], e["feasible"], e["objective"]],
        )
        assert same([r["binding margin [–]"]], [min(e["margins"].values())])
    columns = {
        "w_gaf_rms [–]": "w_gaf_rms",
        "R [mm]": "R_mm",
        "d_roller [mm]": "d_roller_mm",
        "GAF RMS [N]": "gaf_rms_N",
        "outer diameter 2R + d [mm]": "outer_diameter_mm",
        "irregularity [–]": "irregularity",
        "converged": "converged",
    }
    for x, j in columns.items():
        assert same([r[x] for r in sheets["pareto_front"]], [p[j] for p in body["pareto_front"]])
    history = body["history"]
    assert same([r["objective [–]"] for r in sheets["convergence"]], history["objective"])
    assert same([r["KKT residual [–]"] for r in sheets["convergence"]], history["kkt_residual"])
    sensitivities = {r["spec key"]: r for r in sheets["sensitivities"]}
    assert len(sensitivities) == min(len(body["sensitivities"]), document.SENSITIVITY_ROWS)
    for key, r in sensitivities.items():
        d = body["sensitivities"][key]
        assert same(
            [r["d objective / d p [– per unit of p]"], r["d R / d p [mm per unit of p]"]],
            [d["objective"], d["R"]],
        )
        assert same([r["d d_roller / d p [mm per unit of p]"]], [d["d_roller"]])
    # Numbers are numbers, not text.
    assert all(isinstance(r["value"], (int, float)) for r in sheets["requirements"])
    # The life chain's section, every number as in report.json.
    for r, c in zip(sheets["life"], body["life"]["conditions"], strict=True):
        assert same(
            [r["condition"], r["angle [deg]"], r["share of the mileage [–]"], r["life [km]"]],
            [c["name"], c["angle_deg"], c["share"], c["life_km"]],
        )
    # The forces inside the joint, every number as in report.json.
    forces = {r["quantity"]: r["value"] for r in sheets["forces"]}
    assert same(list(forces.values()), [body["forces"][k] for k, _, _ in document._FORCE_ROWS])
    assert list(forces) == [name for _, name, _ in document._FORCE_ROWS]
    # The rest of the halfshaft: each section's static safety and damage, the outboard joint.
    halfshaft = body["halfshaft"]
    values = [r["value"] for r in sheets["halfshaft"]]
    expected = [x for s in halfshaft["sections"] for x in (s["static_safety"], s["damage"])]
    outboard = halfshaft["outboard"]
    assert same(values, expected + [outboard["static_safety"], outboard["life_km"]])
    assert same(
        [r["life [km]"] for r in sheets["outboard_life"]],
        [c["life_km"] for c in outboard["conditions"]],
    )
    assert same(
        [r["damage [–]"] for r in sheets["shaft_damage"]],
        [g["damage"] for s in halfshaft["sections"] for g in s["damage_by_gear"]],
    )
    # The optional section absent from this run: a sheet that says why, no rows.
    assert sheets["reliability"] == []


def test_xlsx_of_the_optional_sections(run, tmp_path):
    _, body = run
    document.write_xlsx(with_sections(body), tmp_path / "r.xlsx")
    sheets = read_sheets(tmp_path / "r.xlsx")
    assert [r["life [km]"] for r in sheets["life"]] == [c["life_km"] for c in LIFE["conditions"]]
    assert [r["share of the damage [–]"] for r in sheets["damage"]] == [0.75, 0.25]
    assert sheets["reliability"][0]["β (FORM) [–]"] == 2.345


def test_without_openpyxl_one_line_names_the_extra_and_the_rest_is_written(
    run, tmp_path, monkeypatch
):
    _, body = run
    monkeypatch.setitem(sys.modules, "openpyxl", None)  # import openpyxl raises ImportError
    writers, messages = document.documents(body, {})
    assert set(writers) == {"report.html", "validation.html"}
    assert len(messages) == 1 and "\n" not in messages[0] and "tripodjax[report]" in messages[0]
    report.write(tmp_path, body, {}, writers)
    assert sorted(os.listdir(tmp_path)) == ["report.html", "report.json", "validation.html"]


def test_bad_input_renders_not_available_with_its_reason(run):
    _, body = run
    old = copy.deepcopy(body)
    old["versions"]["tripodjax"] = "0.0.1"
    del old["constraints"]
    old["quantities"]["gaf_rms"] = math.nan
    old["quantities"]["life_km"] = None
    old["catalogue"] = "not a list"
    html = document.render_html(old)
    assert "written by tripodjax 0.0.1" in html
    assert "Not available: the report has no constraints" in html
    assert 'not available <span class="reason">(nan is not finite)</span>' in html
    assert "(null in the report (not finite when computed))" in html
    assert "Not available: the report&#39;s catalogue cannot be read" in html
    tables = document.tables(old)
    assert tables["quantities"].rows and tables["requirements"].unavailable
    for broken in (None, [], {}, {"versions": None, "design": 3}):
        page = document.render_html(broken)
        assert page.count("Not available:") >= len(document.SECTIONS) - 1
    # Bad input to the xlsx writer: the sheets say why instead of failing.
    with tempfile.TemporaryDirectory() as tmp:
        document.write_xlsx(old, os.path.join(tmp, "r.xlsx"))
        assert read_sheets(os.path.join(tmp, "r.xlsx"))["requirements"] == []


def test_text_is_escaped_and_the_spec_is_valid_toml(run):
    _, body = run
    hostile = copy.deepcopy(body)
    hostile["spec_source"] = "<script>alert(1)</script>"
    html = document.render_html(hostile)
    assert "<script>" not in html and "&lt;script&gt;" in html
    assert tomllib.loads(document.spec_toml(body["spec"])) == body["spec"]
    hostile["spec"]["bounds"]["R"] = [15.0, None]  # a non-finite bound, written as null
    assert "not available" in document.spec_toml(hostile["spec"])


def test_write_report_from_python(tmp_path):
    spec = optimize.load_spec().replace_values(
        solver={"fidelity": "analytic", "n_theta": 24, "starts": 1, "max_outer": 3}
    )
    result = optimize.solve(spec, progress=False)
    body, messages = optimize.write_report(result, spec, tmp_path / "all")
    assert messages == []
    assert {"report.json", "report.html", "report.xlsx", "convergence.png"} <= set(
        os.listdir(tmp_path / "all")
    )
    assert json.loads((tmp_path / "all" / "report.json").read_text()) == body
    optimize.write_report(result, spec, tmp_path / "html", formats=("html",))
    assert "report.json" not in os.listdir(tmp_path / "html")
    assert "report.html" in os.listdir(tmp_path / "html")
    with pytest.raises(ValueError, match="pdf"):
        optimize.write_report(result, spec, tmp_path / "bad", formats=("pdf",))
    # A report pairs a design with the spec it was solved for, or it is refused in one line.
    other = spec.replace_values(hertz={"P_d": 1.01 * float(spec.values["hertz"]["P_d"])})
    refusals = (
        (None, spec, TypeError, r"result = None is not allowed; allowed: the Result of"),
        (result, other, ValueError, r"another spec: hertz.P_d = .* there, .* in this spec"),
        (result, optimize.load_spec(), TypeError, "the Result of another spec"),
    )
    for res, paired, error, message in refusals:
        with pytest.raises(error, match=message) as info:
            optimize.write_report(res, paired, tmp_path / "refused")
        assert "\n" not in str(info.value)
    assert not (tmp_path / "refused").exists()
    # Figures given as matplotlib Figures are embedded as SVG.
    page = document.render_html(body, {"convergence.png": report.figure_convergence(result)})
    assert "data:image/svg+xml;base64," in page


# --------------------------------------------------------------------------- the figures


def _result_of_report(body):
    """What the figures read of a Result, from the report (no solve)."""
    design = {"R": body["design"]["R_mm"], "d_roller": body["design"]["d_roller_mm"]}
    return types.SimpleNamespace(
        design=design,
        constraints=body["constraints"],
        history=body["history"],
        quantities=body["quantities"],
        sensitivities={"elasticities": body["elasticities"]},
    )


def _pareto_of_report(body):
    members = []
    for p in body["pareto_front"]:
        member = types.SimpleNamespace(
            design={"R": p["R_mm"], "d_roller": p["d_roller_mm"]},
            quantities={"outer_diameter": p["outer_diameter_mm"], "gaf_rms": p["gaf_rms_N"]},
        )
        members += [(w, member) for w in p.get("same_design_w_gaf_rms", [p["w_gaf_rms"]])]
    return members


def _drawn(fig):
    """Draw ``fig`` (its layout done as when it is written) and return the renderer."""
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    return canvas.get_renderer()


def _texts(fig, renderer):
    """The texts drawn: (text, its box in pixels); tick labels of ticks outside the view are not."""
    hidden = set()
    for ax in fig.axes:
        for axis in (ax.xaxis, ax.yaxis):
            low, high = sorted(axis.get_view_interval())
            for tick in axis.get_major_ticks() + axis.get_minor_ticks():
                if not low - 1e-9 * (high - low) <= tick.get_loc() <= high + 1e-9 * (high - low):
                    hidden.update({id(tick.label1), id(tick.label2)})
    return [
        (t.get_text(), t.get_window_extent(renderer))
        for t in fig.findobj(Text)
        if t.get_visible() and t.get_text().strip() and id(t) not in hidden
    ]


def _apart(boxes):
    return [(a, b) for i, (a, x) in enumerate(boxes) for b, y in boxes[i + 1 :] if x.overlaps(y)]


def _assert_readable(fig):
    """Every text inside the figure; no two tick labels of an axis, nor two annotations, overlap."""
    renderer = _drawn(fig)
    outside = [
        text
        for text, box in _texts(fig, renderer)
        if box.x0 < -0.5
        or box.y0 < -0.5
        or box.x1 > fig.bbox.x1 + 0.5
        or box.y1 > fig.bbox.y1 + 0.5
    ]
    assert outside == [], outside
    assert _apart(_texts(fig, renderer)) == []  # titles, labels, legends, annotations
    return renderer


def test_figures_keep_every_label_inside_and_apart(run):
    out, body = run
    result = _result_of_report(body)
    figures = {
        "convergence": report.figure_convergence(result),
        "margins": report.figure_margins(result),
        "pareto": report.figure_pareto(result, _pareto_of_report(body)),
        "tornado": report.figure_tornado(result),
        "catalogue": report.figure_catalogue(result, body["catalogue"], body["catalogue_choice"]),
        "damage": report.figure_damage(body["life"]),
        "importance": report.figure_importance(RELIABILITY),
        "life_conditions": report.figure_life_conditions(body["life"], body["halfshaft"]),
        "life_conditions of the tripod": report.figure_life_conditions(body["life"]),
        "shaft_damage": report.figure_shaft_damage(body["halfshaft"]),
    }
    for name, fig in figures.items():
        try:
            _assert_readable(fig)
        except AssertionError as error:
            raise AssertionError(f"{name}: {error}") from None
    # Iterations are whole numbers: no tick between them.
    for ax in figures["convergence"].axes:
        ticks = ax.get_xticks()
        assert len(ticks) and all(float(t).is_integer() for t in ticks), ticks
    # The catalogue's legend covers no point: it lies outside the axes.
    catalogue = figures["catalogue"]
    renderer = _drawn(catalogue)
    ax = catalogue.axes[0]
    points = ax.transData.transform([(e["R_mm"], e["d_roller_mm"]) for e in body["catalogue"]])
    for legend in [*catalogue.legends, *(a.get_legend() for a in catalogue.axes)]:
        if legend is not None:
            box = legend.get_window_extent(renderer)
            assert not any(box.contains(x, y) for x, y in points)
    # One label per catalogue size, at its point.
    assert sorted(t.get_text() for t in ax.texts) == sorted(e["size"] for e in body["catalogue"])
    # Each sensitivity row's label sits at the middle of that row's bars, one bar or three.
    tornado = figures["tornado"].axes[0]
    centres = {}
    for bar in tornado.patches:
        centres.setdefault(round(bar.get_y() + bar.get_height() / 2), []).append(
            bar.get_y() + bar.get_height() / 2
        )
    for tick in tornado.get_yticks():
        mid = (min(centres[round(tick)]) + max(centres[round(tick)])) / 2
        assert mid == pytest.approx(tick, abs=1e-9)
    # The Pareto front: one point per distinct design.
    line = figures["pareto"].axes[0].lines[0]
    assert len(line.get_xdata()) == len(body["pareto_front"])


def test_the_sensitivity_table_ranks_as_the_chart(run):
    _, body = run
    table = document.tables(body)["sensitivities"]
    chart = report.figure_tornado(_result_of_report(body))
    labels = [t.get_text() for t in chart.axes[0].get_yticklabels()][::-1]
    assert [row[0] for row in table.rows] == labels
    assert f"The {len(labels)} largest of {len(body['sensitivities'])}" in table.notes[0]
    # The summary's count of switches is the near-switch section's, and "none" is said only
    # of the inputs whose derivatives are withheld.
    notes = body["sensitivity_notes"]
    switches = document.tables(body)["switch"]
    assert f"{len(switches.rows)} (the near-switch notes)" in table.notes[1]
    assert f"{len(switches.rows)} switches" in switches.notes[0]
    near = ", ".join(notes["near_switch"]) or "none"
    assert f"(derivatives withheld): {near};" in table.notes[1]
    assert f"(near a switch: {near})" in switches.notes[0]
    # every listed key has its value and unit: a grease's μ_slp, angles in degrees, a unit
    # from the key's name (mass_kg), none left "not available"
    for key, unit, value, *_ in table.rows:
        assert isinstance(value, float), (key, value)
        assert not any(key.endswith(s) for s in ("_kg", "_mm", "_m", "_MPa")) or unit != "–", key
    assert next(row[2] for row in table.rows if row[0] == "friction.mu_slp") == 0.06  # grease A
    grease_b = {**body["spec"], "friction": {"grease": "B", "lam": 0.007}}
    rows = document.tables({**body, "spec": grease_b})["sensitivities"].rows
    assert next(row[2] for row in rows if row[0] == "friction.mu_slp") == 0.09


def test_the_pareto_front_lists_each_design_once(run):
    _, body = run
    front = body["pareto_front"]
    designs = [(p["R_mm"], p["d_roller_mm"]) for p in front]
    for i, a in enumerate(designs):
        for b in designs[i + 1 :]:
            assert (
                max(abs(x - y) / max(1.0, abs(x)) for x, y in zip(a, b, strict=True))
                > report.SAME_DESIGN
            )
    weights = [w for p in front for w in p["same_design_w_gaf_rms"]]
    assert weights == sorted(weights) and len(weights) == 5  # the five weights swept
    table = document.tables(body)["pareto_front"]
    assert f"5 weights swept, {len(front)} distinct designs" in table.notes[0]
    assert [row[1] for row in table.rows] == [
        ", ".join(f"{w:g}" for w in p["same_design_w_gaf_rms"]) for p in front
    ]


def test_a_long_name_is_drawn_short_and_fast():
    life = copy.deepcopy(LIFE)
    life["conditions"][0]["name"] = "x" * 1_000_000  # a 1 MB name, as a spec may hold
    start = time.perf_counter()
    fig = report.figure_damage(life)
    _assert_readable(fig)
    assert time.perf_counter() - start < 10  # 100 s before
    names = [t.get_text() for t in fig.axes[1].get_xticklabels()]
    assert names[0].endswith("…") and set(names[0][:-1]) == {"x"} and len(names[0]) <= 40
    assert names[1:] == ["straight", "shock"]


@needs_chromium
def test_the_browser_starts_without_forking_this_process(tmp_path):
    """A fork of this (JAX-threaded) process would warn of a deadlock: none is made."""
    forks = []
    os.register_at_fork(before=lambda: forks.append(1))
    page = tmp_path / "page.html"
    page.write_text("<p>tripodjax</p>", encoding="utf-8")
    with Page(CHROMIUM) as browser:
        browser.open(page.as_uri())
        assert browser.evaluate("document.body.innerText") == "tripodjax"
    assert forks == []


# --------------------------------------------------------------------------- validation.html


def expected_verdicts(body):
    """Each check's verdict from the report's own numbers and flags, in the table's order."""
    words = {True: "passes", False: "fails"}
    life = body["life"]
    verdicts = [
        words[body["constraints"]["static_capacity"]["margin"] >= 0],
        words[life["km"] >= life["required_km"]],
    ]
    if "halfshaft" in body:
        outboard = body["halfshaft"]["outboard"]
        verdicts += [words[outboard["static_passed"]], words[outboard["life_passed"]]]
        for s in body["halfshaft"]["sections"]:
            verdicts += [words[s["static_passed"]], words[s["fatigue_passed"]]]
    verdicts += [words[c["margin"] >= 0] for c in spec_constraints(body).values()]
    return verdicts


def spec_constraints(body):
    """The spec's own [constraints] in report.json (the verdict table's last rows)."""
    given = body["spec"]["constraints"]
    return {name: c for name, c in body["constraints"].items() if name in given}


def without_halfshaft(body):
    body = {k: copy.deepcopy(v) for k, v in body.items() if k != "halfshaft"}
    body["validation"] = document.validation_section(body)
    return body


def pdf_pages(pdf):
    """The number of pages of a PDF: its page objects (``/Type /Page``, not ``/Pages``)."""
    return len(re.findall(rb"/Type\s*/Page(?![a-zA-Z])", pdf))


def test_the_verdict_table_is_the_same_in_json_xlsx_and_html(run):
    out, body = run
    rows = body["validation"]["rows"]
    # report.json's section is the table the pages show, recomputed from the rest of the report.
    assert body["validation"] == document.validation_section(
        {k: v for k, v in body.items() if k != "validation"}
    )
    assert [r[-1] for r in rows] == expected_verdicts(body)
    assert len(rows) == 4 + 2 * len(body["halfshaft"]["sections"]) + len(spec_constraints(body))
    assert spec_constraints(body)  # the default spec's R/d limits: rows of the table too
    sheet = read_sheets(out / "report.xlsx")["validation"]
    assert [list(r) for r in sheet] == [body["validation"]["columns"]] * len(rows)
    for r, j in zip(sheet, rows, strict=True):
        assert same(list(r.values()), j)
    html = (out / "report.html").read_text(encoding="utf-8")
    assert 'data-table="validation"' in html  # the engineer's report shows it too
    assert body["validation"]["notes"][0] == "Every check passes."  # the default halfshaft


def test_a_failing_check_is_named_in_the_verdict(run):
    _, body = run
    failing = copy.deepcopy(body)
    failing["halfshaft"]["sections"][0]["fatigue_passed"] = False
    failing["life"]["km"] = 0.5 * failing["life"]["required_km"]
    table = document.tables(failing, document.VALIDATION_SECTIONS)["validation"]
    assert [r[-1] for r in table.rows] == expected_verdicts(failing)
    assert table.rows[1][5] == pytest.approx(2.0)  # damage over the required mileage L_req/L
    name = failing["halfshaft"]["sections"][0]["name"]
    assert table.notes[0].startswith("Not validated: inboard tripod: life over the working")
    assert f"{name} (Øe" in table.notes[0] and "fatigue damage" in table.notes[0]
    page = document.render_validation(failing)
    assert 'class="verdict fail"' in page and "Every check passes." not in page


def test_the_validation_document_says_why_a_part_is_missing(run):
    _, body = run
    absent = without_halfshaft(body)
    table = document.tables(absent, document.VALIDATION_SECTIONS)["validation"]
    n = len(spec_constraints(absent))
    assert [r[0] for r in table.rows] == ["inboard tripod"] * 2 + ["design (spec)"] * n
    assert "the report has no halfshaft section" in table.notes[1]
    page = document.render_validation(absent)
    assert "shaft sections are not checked: the report has no halfshaft section" in page
    assert table.notes[0].startswith("Not validated: the inboard tripod passes;")
    assert "Figure not available: the report has no halfshaft section" in page
    assert "Rev. 0" in page  # written before revisions were recorded: the first
    revised = dict(body, written=dict(body["written"], revision="B"))
    assert '<td id="revision">Rev. B</td>' in document.render_validation(revised)
    for broken in (None, [], {}, {"spec": 3, "versions": None}):
        assert "Not available:" in document.render_validation(broken)


def printed_margins(pdf_path, pages, body):
    """Each printed page of validation.html says its page of the pages, the document and its
    revision (CSS @page margin boxes; read back with pdftotext where it is installed, else the
    CSS that prints them is checked)."""
    revision = f"Rev. {body['written'].get('revision', '0')}"
    html = document.render_validation(body)
    assert '@bottom-right { content: "page " counter(page) " of " counter(pages);' in html
    if shutil.which("pdftotext") is None:
        assert f"@top-right {{ content: {document.css_string(revision)[:-1]}" in html
        return
    for page in range(1, pages + 1):
        done = subprocess.run(
            ["pdftotext", "-f", str(page), "-l", str(page), str(pdf_path), "-"],
            capture_output=True,
            text=True,
            check=True,
        )
        text = " ".join(done.stdout.split())
        assert f"page {page} of {pages}" in text, text[-200:]
        assert f"Halfshaft validation, {revision}" in text
        assert f"Halfshaft validation: {body['spec_source']}" in text


@needs_chromium
def test_validation_prints_on_at_most_4_a4_pages_with_the_reports_verdicts(run, tmp_path):
    out, body = run
    html = (out / "validation.html").read_text(encoding="utf-8")
    assert "<script" not in html.lower() and "@page { size: A4" in html
    assert '<td id="revision">Rev. 0</td>' in html  # the command's default revision
    references = re.findall(r"""(?:src|href)\s*=\s*["']([^"']*)""", html)
    assert len(references) == 2 and all(r.startswith("data:image/png") for r in references)
    # The same document without the halfshaft's checks (a spec without [vehicle]).
    absent = tmp_path / "absent.html"
    figures = {"life_conditions.png": report.figure_life_conditions(body["life"])}
    absent.write_text(document.render_validation(without_halfshaft(body), figures), "utf-8")
    EXAMPLE.mkdir(parents=True, exist_ok=True)
    for page_path, expected, pdf_path in (
        (out / "validation.html", body, EXAMPLE / "validation.pdf"),
        (absent, without_halfshaft(body), tmp_path / "absent.pdf"),
    ):
        with Page(CHROMIUM) as page:
            page.open(page_path.as_uri())
            assert page.console_errors() == []
            assert [u for u in page.requests() if not u.startswith(("file:", "data:"))] == []
            cells = page.evaluate(
                """[...document.querySelectorAll('table[data-table="validation"] tbody tr')]
                   .map(tr => [...tr.cells].map(td => td.dataset.value ?? td.textContent.trim()))"""
            )
            overall = page.evaluate("document.querySelector('p.verdict').textContent.trim()")
            images = page.evaluate(
                "[...document.images].map(i => i.complete && i.naturalWidth > 0)"
            )
            page.pdf(pdf_path)
            page.send("Emulation.setEmulatedMedia", session=True, media="print")
            page.send(
                "Emulation.setDeviceMetricsOverride",
                session=True,
                width=round(182 / 25.4 * 96),  # A4 within the document's 14 mm margins
                height=1000,
                deviceScaleFactor=1,
                mobile=False,
            )
            overflow = page.evaluate(
                """[...document.querySelectorAll("table, img, p, li")].filter(e =>
                   e.getBoundingClientRect().right > document.documentElement.clientWidth + 1)
                   .map(e => e.dataset.table || e.alt || e.textContent.slice(0, 40))"""
            )
        assert overflow == []
        assert images and all(images)
        rows = expected["validation"]["rows"]
        assert [r[-1] for r in cells] == [r[-1] for r in rows] == expected_verdicts(expected)
        for shown, row in zip(cells, rows, strict=True):  # every cell, numbers to the last digit
            assert [
                float(c) if isinstance(v, float) else c for c, v in zip(shown, row, strict=True)
            ] == row
        assert overall == expected["validation"]["notes"][0]
        pdf = pdf_path.read_bytes()
        assert pdf[:5] == b"%PDF-" and 1 <= pdf_pages(pdf) <= 4, pdf_pages(pdf)
        printed_margins(pdf_path, pdf_pages(pdf), expected)
        boxes = {
            tuple(map(float, b.split())) for b in re.findall(rb"/MediaBox\s*\[([^\]]*)\]", pdf)
        }
        assert len(boxes) == 1 and next(iter(boxes)) == pytest.approx((0, 0, 595.3, 841.9), abs=1.5)
    (EXAMPLE / "validation.html").write_bytes(html.encode("utf-8"))


def test_every_constraint_boundary_of_the_catalogue_figure_is_drawn_its_own_way():
    """Beyond the colour cycle's 10 colours the boundaries change line style: each legend entry
    of a landscape with 23 margins is a different (colour, line style)."""
    R, d = np.linspace(20.0, 30.0, 5), np.linspace(30.0, 45.0, 6)
    margins = {f"c{k}": np.add.outer(R - 20.0 - k / 3.0, 0.0 * d) for k in range(23)}
    margins["met everywhere"] = np.ones((5, 6))  # no zero line on the grid: not in the legend
    margins["missed everywhere"] = -np.ones((5, 6))
    margins["not computed"] = np.full((5, 6), np.nan)  # no line, and no warning
    result = types.SimpleNamespace(design={"R": 25.0, "d_roller": 40.0})
    fig = report.figure_catalogue(result, [], None, {"R": R, "d": d, "margins": margins})
    lines = [h for h in fig.legends[0].legend_handles if h.get_label().endswith(" = 0")]
    assert [h.get_label() for h in lines] == [f"c{k} = 0" for k in range(23)]
    styles = {(h.get_color(), h.get_linestyle()) for h in lines}
    assert len(styles) == 23


def test_without_a_vehicle_the_validation_method_lists_only_the_steps_taken(run):
    """A report without the halfshaft section (a spec without [vehicle]): the method says the
    loads are the spec's and lists no shaft step; with it, the vehicle's loads and both shaft
    steps."""
    _, body = run
    with_vehicle = document.render_validation(body)
    without = document.render_validation({k: v for k, v in body.items() if k != "halfshaft"})
    for html, vehicle in ((with_vehicle, True), (without, False)):
        method = html[html.index('id="method"') : html.index('id="results"')]
        assert ("From the vehicle" in method) == vehicle
        assert ("without a vehicle" in method) == (not vehicle)
        assert method.count("<strong>Shaft sections") == (2 if vehicle else 0)


def test_the_forces_table_says_which_model_gives_the_objectives_gaf(run):
    """Two GAF RMS in one report (the force model's table, the quantities' from Lee's model):
    the forces table names the other one and its model."""
    _, body = run
    notes = document.tables(body)["forces"].notes
    assert body["spec"]["friction"]["gaf_model"] == "stroke"
    assert f"gaf_rms ({document.fmt(body['quantities']['gaf_rms'])} N)" in notes[-1]
    assert 'friction.gaf_model = "stroke"' in notes[-1]
    forces_model = {**body, "spec": {**body["spec"], "friction": {"gaf_model": "forces"}}}
    assert len(document.tables(forces_model)["forces"].notes) == len(notes) - 1


def test_each_joints_static_requirement_names_its_capacity_limit(run):
    """The verdict table's static rows say M_s ≥ k_s · M_max in N·m for both joints."""
    _, body = run
    rows = {(r[0], r[1]): r[2] for r in document.tables(body)["validation"].rows}
    static = "Hertz static capacity M_s; safety M_s/M_max"
    k_s = body["halfshaft"]["outboard"]["required_static_safety"]
    forward = body["halfshaft"]["static_torque_Nm"]["forward"]
    limit = document.fmt(k_s * forward)
    assert (
        rows[("outboard joint", static)] == f"M_s/M_max ≥ {document.fmt(k_s)} (M_s ≥ {limit} N·m)"
    )
    assert rows[("inboard tripod", static)].endswith(f"(M_s ≥ {limit} N·m)")  # one M_max for both


def test_xlsx_writes_a_name_that_looks_like_a_formula_as_text(run, tmp_path):
    """A condition named "=1+2" is its name in the workbook, not a formula the customer's
    spreadsheet evaluates."""
    _, body = run
    named = with_sections(body)
    named["life"] = copy.deepcopy(named["life"])
    named["life"]["conditions"][0]["name"] = "=1+2"
    document.write_xlsx(named, tmp_path / "r.xlsx")
    from openpyxl import load_workbook

    cell = load_workbook(tmp_path / "r.xlsx")["life"]["A2"]
    assert (cell.value, cell.data_type) == ("=1+2", "s")


def test_the_validation_verdict_counts_the_spec_constraints_and_the_run():
    """validation.html said "Every check passes." for an infeasible, unconverged run whose
    spec constraints (an envelope, R/d) failed: they are rows now, and the run's status a
    reason of the verdict. A margin is log(value/limit): its exponential the row's safety."""
    from tripodjax.optimize import document

    report = {
        "converged": False,
        "status": {"feasible": False},
        "spec": {"constraints": {"max_outer_diameter": 85.0, "min_R_over_d": 0.63}},
        "constraints": {
            "static_capacity": {"value": 9.0, "limit": 1.0, "sense": "≥", "margin": 2.2},
            "shaft_static[C-C]": {"value": 0.9, "limit": 1.0, "sense": "≥", "margin": -0.1},
            "max_outer_diameter": {
                "value": 92.945,
                "limit": 85.0,
                "sense": "≤",
                "unit": "mm",
                "margin": math.log(85.0 / 92.945),
            },
            "min_R_over_d": {
                "value": 0.64,
                "limit": 0.63,
                "sense": "≥",
                "unit": "–",
                "margin": math.log(0.64 / 0.63),
            },
        },
    }
    rows = document._spec_requirement_checks(report)
    assert [r[1] for r in rows] == ["constraints.max_outer_diameter", "constraints.min_R_over_d"]
    envelope, ratio = rows
    assert envelope[2] == "≤ 85 mm" and envelope[3] == 92.945 and envelope[6] == "fails"
    assert envelope[5] == pytest.approx(85.0 / 92.945, rel=1e-12)
    assert ratio[2] == "≥ 0.63" and ratio[6] == "passes"
    assert document._run_problems(report) == [
        "the optimisation found no design meeting every requirement",
        "the optimisation did not converge (the design is not its answer)",
    ]
    assert document._run_problems({"converged": True, "status": {"feasible": True}}) == []
    assert document.fmt(99999.7) == "100000"  # not "1e+05" beside "≥ 100000 km"


def test_the_margins_chart_marks_active_by_multiplier_and_never_a_violated_one():
    """The chart said "(active)" for a margin of −2.2e-4 whose requirement was NOT met and whose
    multiplier was 0 in the table; it follows the table now."""
    from tripodjax.optimize import report

    result = types.SimpleNamespace(
        constraints={
            "life": {"margin": 0.0},
            "shaft_static[C-C]": {"margin": -2.24e-4},
            "max_R_over_d": {"margin": 0.27},
            "min_R_over_d": {"margin": 2e-5},
        },
        multipliers={"life": 0.8, "shaft_static[C-C]": 0.0, "max_R_over_d": 0.0},
    )
    fig = report.figure_margins(result)
    texts = [t.get_text() for t in fig.axes[0].texts]
    assert texts == ["+0.00e+00 (active)", "-2.24e-04 (NOT met)", "+2.70e-01", "+2.00e-05"]


def test_a_front_of_one_design_keeps_readable_axes_and_its_label_inside():
    """Every GAF weight gave one design, the proposed one 5e-13 mm beside it: the axes spanned
    roundoff (no tick labels), the label sat off the right edge, and an unconverged front was
    called a Pareto front."""
    from tripodjax.optimize import report

    def design(size, converged=True):
        return types.SimpleNamespace(
            design={"R": 26.0, "d_roller": 41.0},
            quantities={"outer_diameter": size, "gaf_rms": 452.0},
            converged=converged,
        )

    pareto = [(w, design(92.945, converged=False)) for w in (0.25, 0.5, 1.0, 2.0, 4.0)]
    fig = report.figure_pareto(design(92.945 + 5e-13), pareto)
    ax = fig.axes[0]
    for low, high in (ax.get_xlim(), ax.get_ylim()):
        assert high - low >= 0.01 * abs(high)  # at least ±1 % of the values
    (label,) = ax.texts
    assert label.get_text() == "w_gaf_rms = 0.25, 0.5, 1, 2, 4" and label.get_ha() == "center"
    legend = [t.get_text() for t in ax.get_legend().get_texts()]
    assert legend[0].startswith("designs per GAF weight (not every solve converged")
    fig.canvas.draw()
    box = label.get_window_extent()
    assert 0 <= box.x0 and box.x1 <= fig.bbox.width  # inside the figure


def test_shaft_fatigue_at_the_allowed_damage_passes_in_both_documents(run):
    """report.html wrote "≤ 1" (the optimiser's margin ln(allowed/D) ≥ 0, met at 0) and
    validation.html "< 1" with a failing verdict at D = allowed: one rule now, D ≤ allowed, in
    report.json's halfshaft section (its flag and words), both documents and the verdict. The
    allowed damage (one for every section) is set to the largest section damage, so that
    D = allowed exactly there and the other sections stay below it."""
    from tripodjax.optimize import structural

    _, body = run
    index, worst = max(enumerate(body["halfshaft"]["sections"]), key=lambda p: p[1]["damage"])
    name, damage = worst["name"], worst["damage"]

    def with_allowed(allowed):
        spec = optimize.parse_spec(f"[shaft]\nallowed_damage = {allowed!r}\n")
        report = copy.deepcopy(body)
        report["halfshaft"] = optimize.halfshaft_report(spec)
        return report

    at = with_allowed(damage)
    section = at["halfshaft"]["sections"][index]
    assert section["damage"] == section["allowed_damage"] == damage
    assert section["fatigue_passed"] and "damage" in section["result"]
    assert structural.summary(at["halfshaft"]).startswith("halfshaft: 5 sections")
    sense = body["constraints"][f"shaft_fatigue[{name}]"]["sense"]
    assert sense == "≤" and math.log(damage / section["damage"]) >= 0  # the optimiser's margin
    requirement = f"{sense} {document.fmt(damage)}"

    def fatigue_rows(report):
        validation = document.tables(report, document.VALIDATION_SECTIONS)["validation"]
        halfshaft = document.tables(report)["halfshaft"]
        return (
            [r for r in validation.rows if r[0].startswith(f"{name} (") and "fatigue" in r[1]][0],
            [r for r in halfshaft.rows if r[0] == name and "fatigue" in r[1]][0],
            validation.notes[0],
        )

    validation, halfshaft, verdict = fatigue_rows(at)
    assert validation[2] == halfshaft[2] == requirement
    assert validation[6] == halfshaft[4] == "passes"
    assert verdict == "Every check passes."  # the default halfshaft's other checks pass
    assert f"<td>{requirement}</td>" in document.render_validation(at)
    assert f"<td>{requirement}</td>" in document.render_html(at)
    below = with_allowed(damage * (1 - 1e-12))  # D just above what is allowed: it fails
    assert not below["halfshaft"]["sections"][index]["fatigue_passed"]
    validation, halfshaft, verdict = fatigue_rows(below)
    assert validation[6] == halfshaft[4] == "fails" and verdict.startswith("Not validated")


def test_a_reliability_check_no_uncertain_input_affects_says_so():
    """A check whose margin no uncertain input moves (FORM's β = ±∞, null in report.json, every
    importance 0) showed "β not available (null …)", "largest importance R (0)" and "FORM and
    MC agree: yes"; it says it is not affected now, and claims no agreement."""
    flat = {
        "name": "shaft_static[A-A]",
        "beta_form": None,
        "probability_form": 0.0,
        "probability_sorm": None,
        "importance": {"R": 0.0, "hertz.P_d": 0.0},
        "form_converged": True,
        "probability_mc": 0.0,
        "mc_interval_95": [0.0, 3.8e-05],
        "samples": 100000,
        "agree": True,
        "agree_basis": "form",
    }
    missed = dict(flat, name="outboard_life", probability_form=1.0, probability_mc=1.0)
    unknown = dict(flat, name="life", probability_form=None, importance={"R": None})
    rel = copy.deepcopy(RELIABILITY)
    rel["requirements"] += [flat, missed, unknown]
    rows = {r[0]: r for r in document.tables({"reliability": rel})["reliability"].rows[1:]}
    affected = document.tables({"reliability": RELIABILITY})["reliability"].rows[0]
    assert affected[7] is True and affected[8] == "loads.M_max (0.98)"  # as before
    assert rows["shaft_static[A-A]"][1] == "+∞: not affected by the uncertain inputs"
    assert rows["outboard_life"][1].startswith("−∞: not affected by the uncertain inputs")
    for name in ("shaft_static[A-A]", "outboard_life"):
        row = rows[name]
        assert row[7] == "not compared (β infinite)" and row[8] == "none (every importance is 0)"
    # A β that is null because FORM could not compute it keeps its reason.
    assert isinstance(rows["life"][1], document.NotAvailable)
    html = document.render_html({"reliability": rel})
    table = html[html.index('data-table="reliability"') :].split("</table>")[0]
    assert "(0)" not in table and table.count("not affected by the uncertain inputs") == 2


def test_the_validation_document_identifies_the_halfshaft(run):
    """validation.html named neither the outboard joint's geometry and Hertz inputs, nor each
    shaft section's Øi, t, materials and C_s, nor the tripod's Hertz inputs, nor the vehicle's
    load transfers and gear-use tables: its tables hold them now, each number with a unit, as
    report.json's spec and halfshaft sections give them."""
    _, body = run
    spec, design = body["spec"], body["design"]
    tables = document.tables(body, document.VALIDATION_SECTIONS)
    hertz, outboard = spec["hertz"], spec["outboard"]
    pressures = ("P_s", "P_d", "P_sd", "C_s")
    assert tables["joints"].rows == [
        ["inboard tripod", hertz["n_rollers"], design["d_roller_mm"], design["R_mm"]]
        + [design["conformity"], *(hertz[k] for k in pressures)],
        ["outboard joint", outboard["n_balls"], outboard["ball_diameter_mm"], outboard["pcr_mm"]]
        + [outboard["conformity"], *(outboard[k] for k in pressures)],
    ]
    shaft = spec["shaft"]
    expected = []
    for s in body["halfshaft"]["sections"]:
        i = shaft["names"].index(s["name"])
        geometry = [s[k] for k in ("outer_diameter_mm", "inner_diameter_mm", "hardened_depth_mm")]
        expected.append([s["name"], *geometry, shaft["transition_depth_mm"][i], shaft["safety"][i]])
    assert tables["sections"].rows == expected
    assert 1.3 in shaft["safety"]  # the outboard stem's, hidden by "≥ 1" before
    material = tables["sections"].notes[0]
    for key, unit in (("core_uts_MPa", "MPa"), ("surface_uts_MPa", "MPa")):
        assert f"{document.fmt(shaft[key])} {unit}" in material
    for key in ("depth_drop", "fatigue_ratio", "allowed_damage"):
        assert f"{document.fmt(shaft[key])} –" in material
    for name in ("joints", "sections"):  # a unit on every number
        assert all(c.unit for c in tables[name].columns[1:])
    inputs = {r[0]: r[1:] for r in tables["inputs"].rows}
    vehicle = spec["vehicle"]
    assert inputs["wheel-load transfer per unit overall ratio"] == [
        vehicle["load_transfer_per_ratio_N"],
        "N",
    ]
    assert inputs["wheel-load transfer in reverse"] == [vehicle["reverse_load_transfer_N"], "N"]
    use = {k: v for k, v in inputs.items() if k.startswith("gear use")}
    assert len(use) == 4 and all(unit == "%" for _, unit in use.values())
    for key in ("use_T_mean_pct", "use_T_max_pct", "use_P_max_pct", "use_brake_pct"):
        (shown,) = [v for k, (v, _) in use.items() if k.endswith(f"({key})")]
        assert shown == ", ".join(document.fmt(float(x)) for x in vehicle["modes"][key])
    assert all(unit for _, value, unit in tables["inputs"].rows if isinstance(value, float))
    # The verdict rows say the C_s inside τ_adm.
    static = [r[2] for r in tables["validation"].rows if r[1].startswith("static safety τ_adm")]
    assert static == [f"≥ 1 (C_s {document.fmt(c)} in τ_adm)" for c in shaft["safety"]]
    page = document.render_validation(body)
    for name in ("joints", "sections", "inputs"):
        assert f'data-table="{name}"' in page
    assert f'data-value="{outboard["pcr_mm"]!r}"' in page


def test_the_validation_sheet_names_its_revision_date_and_spec(run, tmp_path):
    """report.xlsx's validation sheet carried no revision, date or spec name (validation.html
    does): they follow its notes, and its printed header and footer carry them too."""
    _, body = run
    revised = dict(body, written=dict(body["written"], revision="B & <x>"))
    document.write_xlsx(revised, tmp_path / "r.xlsx")
    from openpyxl import load_workbook

    sheet = load_workbook(tmp_path / "r.xlsx")["validation"]
    rows = [r[:2] for r in sheet.iter_rows(values_only=True)]
    identity = dict(rows[-5:])
    assert identity == {
        "document": identity["document"],
        "revision": "Rev. B & <x>",
        "date": body["written"]["date"],
        "specification": body["spec_source"],
        "computed with": f"tripodjax {body['versions']['tripodjax']}, jax {body['versions']['jax']}",
    }
    assert identity["document"].startswith("Halfshaft validation")
    page = document.render_validation(revised)  # the same words as the document's header
    assert '<td id="revision">Rev. B &amp; &lt;x&gt;</td>' in page
    assert sheet.oddHeader.left.text == f"Halfshaft validation: {body['spec_source']}"
    assert sheet.oddHeader.right.text == f"Rev. B && <x>, {body['written']['date']}"
    assert sheet.oddFooter.right.text == "page &P of &N"
    assert read_sheets(tmp_path / "r.xlsx")["validation"]  # the table above, read as before


def test_an_unconverged_run_says_so_in_the_switch_notes(run):
    """For a run that did not converge (no sensitivities, no notes) the near-switch section
    said the report "has no switch distances", as if an older version had written it; it
    gives the sensitivities' reason now."""
    _, body = run
    unfinished = {k: v for k, v in body.items() if k not in ("sensitivities", "sensitivity_notes")}
    table = document.tables(unfinished)["switch"]
    assert table.unavailable == (
        "the run did not converge: no switch distances of an unfinished optimum"
    )
    assert document.tables(unfinished)["sensitivities"].unavailable.startswith(
        "the run did not converge"
    )
