"""optimize-joint compare: two runs (the default and C_s = 1.35) side by side."""

import json

import pytest
from browser import Page, executable
from command import run_cli
from test_report_html import needs_chromium

from tripodjax.optimize import compare

CHROMIUM = executable()


@pytest.fixture(scope="module")
def runs(tmp_path_factory, default_report):
    root = tmp_path_factory.mktemp("compare")
    done, default = default_report
    assert done.returncode == 0, done.stderr
    # A number of the default spec, not its structure: this run reuses the default's programs.
    spec = root / "cs135.toml"
    spec.write_text("[hertz]\nC_s = 1.35\n")
    done = run_cli(str(spec), "--out", str(root / "cs135"), "--progress", "off")
    assert done.returncode == 0, done.stderr
    return root, [default, root / "cs135"]


def margins_on_page(html):
    import re

    rows = re.findall(
        r'<tr><td>([^<]+)</td><td class="num (?:pass|fail)" data-value="([^"]+)">.*?'
        r'<td class="num (?:pass|fail)" data-value="([^"]+)">',
        html.split('id="margins"')[1].split("</table>")[0],
    )
    return {name: (float(a), float(b)) for name, a, b in rows}


def test_compare_shows_the_changed_margins_and_the_spec_key(runs):
    root, (a, b) = runs
    page = root / "page.html"
    done = run_cli("compare", str(a), str(b), "--out", str(page))
    assert done.returncode == 0, done.stderr
    assert "hertz.C_s" in done.stdout
    html = page.read_text(encoding="utf-8")
    report_a = json.loads((a / "report.json").read_text())
    report_b = json.loads((b / "report.json").read_text())
    spec_rows = html.split('data-table="spec"')[1].split("</table>")[0]
    assert "<td>hertz.C_s</td>" in spec_rows and spec_rows.count("<tr>") == 2  # header + C_s
    shown = margins_on_page(html)
    assert set(shown) == set(report_a["constraints"])
    for name in shown:
        assert shown[name] == (
            report_a["constraints"][name]["margin"],
            report_b["constraints"][name]["margin"],
        )
    # A larger safety coefficient lowers every capacity by (1.2/1.35)³ (M ∝ (p/(C_s C_p))³ d² R):
    # the life-bound design grows until its dynamic capacity is back, so its R/d margins change
    # and the static margin ln(M_s / (shock · M_max)) returns to where it was.
    changed = [n for n, (ma, mb) in shown.items() if abs(mb - ma) > 1e-6]
    assert {"min_R_over_d", "max_R_over_d"} <= set(changed)
    assert shown["static_capacity"][1] == pytest.approx(shown["static_capacity"][0], abs=1e-4)
    rows = compare.comparison(report_a, report_b)
    (objective,) = rows["objective"]
    assert objective[4] == pytest.approx(report_b["objective"] - report_a["objective"], abs=0)
    assert "<script" not in html.lower()


@needs_chromium
def test_compare_page_opens_offline_in_chromium(runs):
    root, (a, b) = runs
    page_path = root / "page-browser.html"
    assert compare.main([str(a), str(b), "--out", str(page_path)]) == 0
    with Page(CHROMIUM) as page:
        page.open(page_path.as_uri())
        assert page.console_errors() == []
        assert [u for u in page.requests() if not u.startswith(("file:", "data:"))] == []
        tables = page.evaluate(
            "[...document.querySelectorAll('table[data-table]')].map(t => t.dataset.table)"
        )
    assert tables == ["spec", "design", "objective", "margins", "quantities"]


def test_compare_bad_folders_exit_2_with_one_line(tmp_path, runs):
    _, (a, _) = runs
    (tmp_path / "broken").mkdir()
    (tmp_path / "broken" / "report.json").write_text('{"objective": NaN}')
    # Another program's JSON object, even one with a converged flag, and a JSON list.
    (tmp_path / "foreign").mkdir()
    (tmp_path / "foreign" / "report.json").write_text('{"name": "other", "converged": true}')
    (tmp_path / "list").mkdir()
    (tmp_path / "list" / "report.json").write_text("[1, 2]")
    for args, fragment in (
        ([str(a), str(tmp_path / "none")], "cannot read"),
        ([str(a), str(tmp_path / "broken")], "not a strict-JSON report"),
        ([str(tmp_path / "foreign"), str(a)], "not a tripodjax report.json"),
        ([str(a), str(tmp_path / "list")], "not a tripodjax report.json"),
        ([str(a)], "DIR_B"),
    ):
        done = run_cli("compare", *args, "--out", str(tmp_path / "page.html"))
        assert done.returncode == 2, done.stderr
        assert len(done.stderr.strip().splitlines()) == 1 and fragment in done.stderr
        assert "Traceback" not in done.stderr
    assert not (tmp_path / "page.html").exists()


def test_compare_of_reports_with_missing_parts_says_not_available(runs):
    _, (a, _) = runs
    report_a = json.loads((a / "report.json").read_text())
    other = {"versions": {"tripodjax": "0.0.1"}, "constraints": {"life": {"margin": None}}}
    html = compare.render(report_a, other)
    assert "written by tripodjax 0.0.1" in html
    assert "not available" in html and "null in the report" in html


def test_units_and_relative_changes_of_near_zero_numbers():
    """Every design row has its unit; a relative change is given only where A is not zero on
    its scale (1 for a margin, a log ratio; max(|A|, |B|) otherwise): an active constraint's
    margin of a few tolerances moving by another few is noise in relative terms."""
    versions = {"versions": {"tripodjax": "x"}, "converged": True}
    a = {
        **versions,
        "design": {"R_mm": 25.0, "gamma0_deg": 20.0, "conformity": 1.002},
        "constraints": {"life": {"margin": 2.0e-5}, "max_R_over_d": {"margin": 0.25}},
        "quantities": {"eccentricity": 1e-9},
        "units": {"eccentricity": "mm"},
    }
    b = {
        **versions,
        "design": {"R_mm": 26.0, "gamma0_deg": 20.0, "conformity": 1.004},
        "constraints": {"life": {"margin": 3.0e-5}, "max_R_over_d": {"margin": 0.2}},
        "quantities": {"eccentricity": 0.5},
        "units": {"eccentricity": "mm"},
    }
    rows = compare.comparison(a, b)
    units = {key.split("/")[-1]: unit for key, unit, *_ in rows["design"]}
    assert units == {"R_mm": "mm", "gamma0_deg": "deg", "conformity": "–"}
    (_, _, _, _, change, relative), *_ = rows["design"]
    assert (change, relative) == (1.0, 1.0 / 25.0)
    margins = {name: (change, relative) for name, _, _, change, relative, _, _ in rows["margins"]}
    assert margins["life"][0] == pytest.approx(1.0e-5, rel=1e-12)
    assert isinstance(margins["life"][1], compare.NotAvailable)  # not +50 %
    assert margins["max_R_over_d"][1] == pytest.approx(-0.2, rel=1e-12)
    (_, unit, _, _, change, relative), *_ = rows["quantities"]
    assert unit == "mm" and change == pytest.approx(0.5)
    assert isinstance(relative, compare.NotAvailable)  # 1e-9 is 0 next to 0.5
    html = compare.render(a, b)
    design = html.split('data-table="design"')[1].split("</table>")[0]
    assert "<td>R_mm</td><td>mm</td>" in design and "<td>conformity</td><td>–</td>" in design
    margins_html = html.split('data-table="margins"')[1].split("</table>")[0]
    assert "near 0" in margins_html


def test_a_difference_of_roundoff_is_no_change():
    """Two runs of one design differ in the last digits only: the page shows no change."""
    assert compare._change(26.051335186072663, 26.05133518607263) == (0.0, 0.0)
    assert compare._change(0.0, 0.0) == (0.0, 0.0)
    change, relative = compare._change(26.05, 26.06)
    assert change == pytest.approx(0.01) and relative == pytest.approx(0.01 / 26.05)
