"""The report as documents a person reads: one self-contained HTML page and a spreadsheet.

Both are built from the dict that [`report_dict`][tripodjax.optimize.report.report_dict]
returns (the content of ``report.json``), through one table model
([`tables`][tripodjax.optimize.document.tables]): the page and the workbook hold the same
numbers. A section the report lacks (an optional one, or a report written by another
version) and a number that is not finite are shown as "not available" with the reason.

- ``report.html``: the template ``templates/report.html.j2`` (Jinja2, autoescaped); figures
  embedded as SVG data URIs; no script, no fetch; print styles for A4.
- ``validation.html``: the document the company sends the customer (the workbook's sheets 7
  and 8), ``templates/validation.html.j2``: the customer's inputs, the method, each joint's and
  shaft section's requirement, value and verdict (the report's ``validation`` table, also in
  report.json and a sheet of report.xlsx), the readings chosen, the revision and approval block;
  at most 4 A4 pages printed.
- ``report.xlsx``: a sheet per table, units in the headers, numbers as numbers, frozen
  header rows. Needs openpyxl (the ``report`` extra); without it the other files are written
  and one line says what to install.
"""

import base64
import dataclasses
import datetime
import functools
import io
import json
import math
import os
import re
import shlex
import sys

XLSX_EXTRA = 'pip install "tripodjax[report]"'
FORMATS = ("json", "html", "xlsx")
SENSITIVITY_ROWS = 12  # the largest sensitivities listed: the rows of the sensitivity chart
# Units of spec keys whose comment in the embedded spec does not carry one.
_LIST_UNITS = {
    "life.torque": "N·m",
    "life.speed": "rpm",
    "life.vehicle_speed": "km/h",
    "life.share": "–",
    "life.conditions.share": "–",
}


class NotAvailable(Exception):
    """A section or number the report cannot give; the message is the reason."""


@dataclasses.dataclass
class Column:
    header: str
    unit: str = ""
    kind: str = ""  # "margin": a pass/fail mark beside the number; "text": never a number;
    # "verdict": "passes" or "fails" (shown as a pass or a fail)

    @property
    def label(self):
        return f"{self.header} [{self.unit}]" if self.unit else self.header


@dataclasses.dataclass
class Table:
    """One table of the report: the same rows on the page and in the workbook."""

    name: str  # the sheet's name
    title: str
    columns: list = dataclasses.field(default_factory=list)
    rows: list = dataclasses.field(default_factory=list)
    notes: list = dataclasses.field(default_factory=list)  # sentences shown under the table
    unavailable: str | None = None  # the reason the table is not available
    margin_rows: bool = False  # rows named "margin …" hold margins (the summary)

    def mark(self, row, j):
        """ "pass" or "fail" when cell j of ``row`` is a margin, else None."""
        value = row[j]
        if isinstance(value, bool) or not isinstance(value, float):
            return None
        named = self.margin_rows and j >= 2 and str(row[0]).startswith("margin ")
        if self.columns[j].kind == "margin" or named:
            return "pass" if value >= 0 else "fail"
        return None


# ---------------------------------------------------------------------------------------------
# reading the report defensively


def _get(report, *path):
    """``report[path[0]][path[1]]…``, or NotAvailable naming the missing key."""
    value = report
    for i, key in enumerate(path):
        try:
            value = value[key]
        except (KeyError, IndexError, TypeError):
            where = ".".join(str(k) for k in path[: i + 1])
            raise NotAvailable(f"the report has no {where}") from None
        if value is None:
            where = ".".join(str(k) for k in path[: i + 1])
            raise NotAvailable(f"{where} is null in the report")
    return value


def number(value):
    """``value`` as a finite float, or NotAvailable saying why not."""
    if value is None:
        raise NotAvailable("null in the report (not finite when computed)")
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise NotAvailable(f"{value!r} is not a number")
    if not math.isfinite(value):
        raise NotAvailable(f"{value!r} is not finite")
    return float(value)


def cell(value):
    """A table cell: a finite number, a string, a bool, or NotAvailable (the reason)."""
    if isinstance(value, (str, bool, NotAvailable)):
        return value
    try:
        return number(value)
    except NotAvailable as reason:
        return reason


def fmt(value, digits=5):
    """The text of a cell (numbers to ``digits`` significant figures)."""
    if isinstance(value, NotAvailable):
        return f"not available ({value})"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float):
        if value == 0.0:
            return "0"
        if 10**digits <= abs(value) < 1e9:
            return f"{value:.0f}"
        if 1e-3 <= abs(value) < 10**digits:
            text = f"{value:.{digits}g}"  # 99999.7 rounds up to "1e+05": written out instead
            return f"{value:.0f}" if "e" in text else text
        return f"{value:.{digits - 1}e}"
    return str(value)


def _section(title, name, build, report):
    try:
        return build(report)
    except NotAvailable as reason:
        return Table(name, title, unavailable=str(reason))
    except (KeyError, IndexError, TypeError, ValueError, AttributeError) as error:
        # A report of another layout (another version): say so rather than crash.
        return Table(name, title, unavailable=f"the report's {name} cannot be read ({error!r})")


# ---------------------------------------------------------------------------------------------
# the tables


def _summary(report):
    design = _get(report, "design")
    choice = report.get("catalogue_choice") if isinstance(report, dict) else None
    columns = [
        Column("item", kind="text"),
        Column("unit", kind="text"),
        Column("proposed design"),
        Column("catalogue choice"),
    ]
    rows = []
    name = (
        f"{choice['family']} {choice['size']}"
        if choice
        else NotAvailable(
            "no catalogue size is feasible"
            if "catalogue" in report
            else "no catalogue in the report"
        )
    )
    rows.append(["design", "", "ad hoc optimum", name])
    from tripodjax.optimize.spec import REPORT_KEYS, VARIABLES, shaft_variable, variable_domain

    free = [REPORT_KEYS.get(v, v) for v in report.get("free_variables", [])]
    spec = report.get("spec") or {}
    for key in ["R_mm", "d_roller_mm", *[k for k in free if k not in ("R_mm", "d_roller_mm")]]:
        variable = next((v for v, k in REPORT_KEYS.items() if k == key), key)
        unit = variable_domain(variable)[0]
        if not choice:
            other = name
        elif key in choice:
            other = cell(choice[key])
        elif (entry := shaft_variable(variable)) is not None:  # the spec's [shaft] entry
            shaft = spec.get("shaft", {})
            names = shaft.get("names", [])
            i = names.index(entry[1]) if entry[1] in names else None
            other = cell(shaft.get(entry[0], [])[i]) if i is not None else ""
        else:  # the catalogue keeps every variable but R and d at the spec's value
            other = cell(spec.get(VARIABLES[variable][0], {}).get(variable))
        rows.append([key.removesuffix(f"_{unit}"), unit, cell(design.get(key)), other])
    rows.append(
        [
            "objective",
            "–",
            cell(report.get("objective")),
            cell(choice["objective"]) if choice else name,
        ]
    )
    for constraint, c in _get(report, "constraints").items():
        rows.append(
            [
                f"margin {constraint}",
                "–",
                cell(c.get("margin")),
                cell(choice["margins"].get(constraint)) if choice else name,
            ]
        )
    return Table(
        "summary", "Summary", columns, rows, notes=[status_words(report)], margin_rows=True
    )


def status_words(report):
    """The status of the run in one sentence."""
    status = report.get("status") or {}
    parts = [
        "converged" if report.get("converged") else "NOT converged",
        "feasible" if status.get("feasible") else "NOT feasible",
    ]
    try:
        parts.append(
            f"KKT residual {fmt(number(report['kkt_residual']), 3)} (tolerance {fmt(number(report['tolerance']), 3)})"
        )
    except (KeyError, NotAvailable):
        parts.append("KKT residual not available")
    fidelity = report.get("fidelity") or {}
    if fidelity:
        parts.append(
            f"solved at fidelity {fidelity.get('solver')} / n_theta {fidelity.get('n_theta')}"
        )
    full = report.get("full_fidelity")
    if isinstance(full, dict) and isinstance(full.get("constraints"), dict):
        names = report.get("constraints") or full["constraints"]  # the bounds left out
        margins = [full["constraints"].get(n) for n in names]
        margins = [m for m in margins if isinstance(m, (int, float))]
        worst = min(margins) if margins else float("nan")
        parts.append(
            f"re-checked at {full.get('solver')} / n_theta {full.get('n_theta')}: smallest margin "
            f"{fmt(cell(worst), 3)}, objective {fmt(cell(full.get('objective')))}"
        )
    elif (fidelity.get("solver"), fidelity.get("n_theta")) == ("newton", 360):
        parts.append("solved at full fidelity (no re-check needed)")
    else:
        parts.append("not re-checked at full fidelity (newton / n_theta 360)")
    sentence = "; ".join(parts) + "."
    if report.get("message"):
        sentence += f" {report['message'][0].upper()}{report['message'][1:]}."
    return sentence


def _active(report):
    notes = report.get("sensitivity_notes")
    if isinstance(notes, dict) and isinstance(notes.get("active"), list):
        return set(notes["active"])
    return {
        k
        for k, v in (report.get("multipliers") or {}).items()
        if isinstance(v, (int, float)) and v > 0
    }


def _requirements(report):
    active = _active(report)
    full = (report.get("full_fidelity") or {}).get("constraints") or {}
    columns = [
        Column("requirement", kind="text"),
        Column("sense", kind="text"),
        Column("value"),
        Column("limit"),
        Column("unit", kind="text"),
        Column("margin ln(value/limit)", "–", kind="margin"),
        Column("multiplier", "–"),
        Column("active"),
        Column("at full fidelity: margin", "–", kind="margin"),
    ]
    rows = []
    for name, c in _get(report, "constraints").items():
        rows.append(
            [
                name,
                c.get("sense", ""),
                cell(c.get("value")),
                cell(c.get("limit")),
                c.get("unit", ""),
                cell(c.get("margin")),
                cell((report.get("multipliers") or {}).get(name)),
                name in active,
                cell(full[name]) if name in full else NotAvailable("no full-fidelity re-check"),
            ]
        )
    return Table(
        "requirements",
        "Requirements",
        columns,
        rows,
        notes=[
            "A requirement is met when its margin is ≥ 0 (✓ met, ✗ NOT met); active: its multiplier is positive, it holds the design."
        ],
    )


def _quantities(report):
    units = report.get("units") or {}
    choice = report.get("catalogue_choice") or {}
    full = (report.get("full_fidelity") or {}).get("quantities") or {}
    columns = [
        Column("quantity", kind="text"),
        Column("unit", kind="text"),
        Column("proposed design"),
        Column("catalogue choice"),
        Column("at full fidelity"),
    ]
    rows = [
        [
            name,
            units.get(name, ""),
            cell(value),
            cell(choice["quantities"].get(name))
            if "quantities" in choice
            else NotAvailable("no catalogue choice"),
            cell(full[name]) if name in full else NotAvailable("no full-fidelity re-check"),
        ]
        for name, value in _get(report, "quantities").items()
    ]
    return Table("quantities", "Quantities", columns, rows)


_ABSENT = {
    "life": "the report has no life section (the life chain of this version does not give the life per working condition)",
    "reliability": "the spec has no uncertainty (no reliability section in the report)",
    "halfshaft": "the report has no halfshaft section (the spec has no [vehicle] to give the shaft's load cycles, or the report was written by a version without it)",
    "forces": "the report has no forces section (written by a version without the force model, or the design is outside the layout domain)",
}


def _conditions(conditions):
    """Columns and rows of a joint's life per working condition (the tripod's, the outboard's)."""
    columns = [
        Column("condition", kind="text"),
        Column("angle", "deg"),
        Column("share of the mileage", "–"),
        Column("life", "km"),
        Column("share of the damage", "–"),
    ]
    keys = ("angle_deg", "share", "life_km", "damage_share")
    return columns, [[c["name"], *(cell(c.get(k)) for k in keys)] for c in conditions]


def _life(report):
    life = report.get("life")
    if life is None:
        raise NotAvailable(_ABSENT["life"])
    columns, rows = _conditions(_get(life, "conditions"))
    notes = [
        f"Life {fmt(cell(life.get('km')))} km ({fmt(cell(life.get('hours')))} h) against "
        f"{fmt(cell(life.get('required_km')))} km required; angle law {life.get('angle_law', 'not given')}; "
        f"M_max forward {fmt(cell(life.get('M_max_forward_Nm')))} N·m, backward {fmt(cell(life.get('M_max_backward_Nm')))} N·m."
    ]
    return Table("life", "Life per working condition", columns, rows, notes)


def _passes(passed):
    """The verdict in words of a check: ``passed`` a bool, or NotAvailable (the reason)."""
    if isinstance(passed, NotAvailable):
        return passed
    return "passes" if passed else "fails"


# The sense of a shaft section's fatigue requirement, as the requirements table's
# shaft_fatigue rows write it (problem: ln(allowed/D) ≥ 0).
FATIGUE_SENSE = "≤"


def _halfshaft_section(report):
    halfshaft = report.get("halfshaft")
    if halfshaft is None:
        raise NotAvailable(_ABSENT["halfshaft"])
    return halfshaft


def _halfshaft(report):
    h = _halfshaft_section(report)
    columns = [
        Column("part", kind="text"),
        Column("check", kind="text"),
        Column("required", kind="text"),
        Column("value"),
        Column("verdict", kind="text"),
    ]
    rows = []
    for s in _get(h, "sections"):
        safety, damage = cell(s.get("static_safety")), cell(s.get("damage"))
        rows.append(
            [
                s["name"],
                "static safety τ_adm/τ",
                f"≥ {fmt(cell(s.get('required_static_safety')))}",
                safety,
                _passes(bool(s.get("static_passed"))),
            ]
        )
        rows.append(
            [
                s["name"],
                "fatigue damage (Miner)",
                f"{FATIGUE_SENSE} {fmt(cell(s.get('allowed_damage')))}",
                damage,
                _passes(bool(s.get("fatigue_passed"))),
            ]
        )
    o = _get(h, "outboard")
    rows.append(
        [
            "outboard joint",
            "static safety M_s/M_max",
            f"≥ {fmt(cell(o.get('required_static_safety')))}",
            cell(o.get("static_safety")),
            _passes(bool(o.get("static_passed"))),
        ]
    )
    rows.append(
        [
            "outboard joint",
            "life [km]",
            f"≥ {fmt(cell(o.get('required_km')))}",
            cell(o.get("life_km")),
            _passes(bool(o.get("life_passed"))),
        ]
    )
    torque = _get(h, "static_torque_Nm")
    notes = [
        f"The halfshaft {'passes' if h.get('passed') else 'does NOT pass'}. Sections checked "
        f"statically at M_max {fmt(cell(torque.get('forward')))} N·m forward and "
        f"{fmt(cell(torque.get('backward')))} N·m backward and in fatigue under the vehicle's "
        f"load → engine-brake cycles (reading {h.get('reading', 'not given')}); the outboard "
        f"joint ({o.get('n_balls')} balls of {fmt(cell(o.get('ball_diameter_mm')))} mm on a "
        f"{fmt(cell(o.get('pcr_mm')))} mm PCR: M_s {fmt(cell(o.get('M_s_Nm')))}, M_d "
        f"{fmt(cell(o.get('M_d_Nm')))}, M_sd {fmt(cell(o.get('M_sd_Nm')))} N·m)."
    ]
    return Table("halfshaft", "The rest of the halfshaft", columns, rows, notes)


def _outboard_life(report):
    o = _get(_halfshaft_section(report), "outboard")
    columns, rows = _conditions(_get(o, "conditions"))
    return Table("outboard_life", "Outboard joint: life per working condition", columns, rows)


def _shaft_damage(report):
    sections = _get(_halfshaft_section(report), "sections")
    columns = [Column("section", kind="text"), Column("gear", kind="text"), Column("damage", "–")]
    rows = [
        [s["name"], g["gear"], cell(g.get("damage"))] for s in sections for g in s["damage_by_gear"]
    ]
    notes = [
        "Each section's damage by gear at its critical radius, summed over the driving modes and engine conditions."
    ]
    return Table("shaft_damage", "Shaft sections: damage by gear", columns, rows, notes)


def _quotient(a, b):
    """``a / b`` as a cell; a cell that is not a number stays the reason."""
    for x in (a, b):
        if isinstance(x, NotAvailable):
            return x
    if b == 0:
        return NotAvailable("divided by 0")
    return cell(a / b)


def _at_least(value, limit):
    """``value ≥ limit`` of two cells, or the reason one is not a number."""
    for x in (value, limit):
        if isinstance(x, NotAvailable):
            return x
    return value >= limit


def _spec_requirement_checks(report):
    """The verdict table's rows of the spec's own [constraints] (an envelope, R/d, a kinematic
    limit, a chance constraint): a design requirement as binding as the joints' checks."""
    from tripodjax.optimize.spec import CHANCE_PREFIXES

    spec = report.get("spec") if isinstance(report.get("spec"), dict) else {}
    given = spec.get("constraints") if isinstance(spec.get("constraints"), dict) else {}
    rows = []
    for name, c in (report.get("constraints") or {}).items():
        if name.split(":")[0] not in given:  # a chance constraint on several: "key:requirement"
            continue
        c = c if isinstance(c, dict) else {}
        limit, value, margin = (cell(c.get(k)) for k in ("limit", "value", "margin"))
        unit = c.get("unit") or "–"
        requirement = f"{c.get('sense', '')} {fmt(limit)}" + ("" if unit == "–" else f" {unit}")
        # The margin is log(value/limit) (≥) or log(limit/value) (≤): its exponential is the
        # requirement's safety, ≥ 1 where met, as the joints' safeties.
        safety = margin if isinstance(margin, NotAvailable) else math.exp(margin)
        if name.startswith(tuple(CHANCE_PREFIXES)):
            safety = NotAvailable("a probability requirement: the reliability section gives it")
        rows.append(
            [
                "design (spec)",
                f"constraints.{name}",
                requirement,
                value,
                unit,
                safety,
                _passes(margin if isinstance(margin, NotAvailable) else margin >= 0),
            ]
        )
    return rows


def _run_problems(report):
    """What keeps a run's answer from being validated whatever its checks show: an optimisation
    that did not converge or found no feasible design."""
    status = report.get("status") or {}
    problems = []
    if status.get("feasible") is False:
        problems.append("the optimisation found no design meeting every requirement")
    if report.get("converged") is False:
        problems.append("the optimisation did not converge (the design is not its answer)")
    return problems


def _tripod_checks(report):
    """The verdict table's rows of the inboard tripod: its Hertz static capacity and its life."""
    k_s = cell(_get(report, "spec", "loads", "shock_factor"))
    c = _get(report, "constraints", "static_capacity")
    M_s, limit = cell(c.get("value")), cell(c.get("limit"))
    M_max = _quotient(limit, k_s)
    margin = cell(c.get("margin"))
    rows = [
        [
            "inboard tripod",
            "Hertz static capacity M_s; safety M_s/M_max",
            f"M_s/M_max ≥ k_s = {fmt(k_s)} (M_s ≥ {fmt(limit)} N·m)",
            M_s,
            "N·m",
            _quotient(M_s, M_max),
            _passes(margin if isinstance(margin, NotAvailable) else margin >= 0),
        ]
    ]
    life = report.get("life")
    if life is None:
        km = required = NotAvailable(_ABSENT["life"])
    else:
        km, required = cell(life.get("km")), cell(life.get("required_km"))
    rows.append(
        [
            "inboard tripod",
            "life over the working conditions; damage L_req/L (Miner)",
            f"≥ {fmt(required)} km",
            km,
            "km",
            _quotient(required, km),
            _passes(_at_least(km, required)),
        ]
    )
    return rows


def _halfshaft_checks(halfshaft, spec=None):
    """The verdict table's rows of the outboard joint and of each shaft section (``spec``: the
    report's, for each section's safety coefficient C_s)."""
    shaft = (spec or {}).get("shaft") if isinstance(spec, dict) else None
    shaft = shaft if isinstance(shaft, dict) else {}
    names, safeties = shaft.get("names") or [], shaft.get("safety") or []
    o = _get(halfshaft, "outboard")
    required = cell(o.get("required_km"))
    km = cell(o.get("life_km"))
    k_s = cell(o.get("required_static_safety"))
    torques = halfshaft.get("static_torque_Nm") or {}
    # The joints' static checks take the larger of the two directions (problem.joint_torque).
    largest = [cell(torques.get(k)) for k in ("forward", "backward")]
    largest = [t for t in largest if isinstance(t, float)]
    static = f"M_s/M_max ≥ {fmt(k_s)}"
    if isinstance(k_s, float) and largest:  # as the tripod's row says it
        static += f" (M_s ≥ {fmt(k_s * max(largest))} N·m)"
    rows = [
        [
            "outboard joint",
            "Hertz static capacity M_s; safety M_s/M_max",
            static,
            cell(o.get("M_s_Nm")),
            "N·m",
            cell(o.get("static_safety")),
            _passes(bool(o.get("static_passed"))),
        ],
        [
            "outboard joint",
            "life over the working conditions; damage L_req/L (Miner)",
            f"≥ {fmt(required)} km",
            km,
            "km",
            _quotient(required, km),
            _passes(bool(o.get("life_passed"))),
        ],
    ]
    for s in _get(halfshaft, "sections"):
        part = (
            f"{s['name']} (Øe {fmt(cell(s.get('outer_diameter_mm')))}, "
            f"h {fmt(cell(s.get('hardened_depth_mm')))} mm)"
        )
        safety, damage = cell(s.get("static_safety")), cell(s.get("damage"))
        static = f"≥ {fmt(cell(s.get('required_static_safety')))}"
        if s["name"] in names and len(safeties) == len(names):  # the coefficient inside τ_adm
            static += f" (C_s {fmt(cell(safeties[names.index(s['name'])]))} in τ_adm)"
        rows.append(
            [
                part,
                "static safety τ_adm/τ, through the hardened layer",
                static,
                safety,
                "–",
                safety,
                _passes(bool(s.get("static_passed"))),
            ]
        )
        rows.append(
            [
                part,
                "fatigue damage (Goodman, semi-log S–N, Miner)",
                f"{FATIGUE_SENSE} {fmt(cell(s.get('allowed_damage')))}",
                damage,
                "–",
                damage,
                _passes(bool(s.get("fatigue_passed"))),
            ]
        )
    return rows


def _validation(report):
    """The verdict table of the validation document: each joint's and section's requirement,
    computed value, safety or damage and verdict."""
    columns = [
        Column("part", kind="text"),
        Column("check", kind="text"),
        Column("requirement", kind="text"),
        Column("computed value"),
        Column("unit", kind="text"),
        Column("safety or damage", "–"),
        Column("verdict", kind="verdict"),
    ]
    rows = _tripod_checks(report)
    halfshaft = report.get("halfshaft")
    notes = []
    if halfshaft is None:
        notes.append(
            f"The outboard joint and the shaft sections are not checked: {_ABSENT['halfshaft']}."
        )
    else:
        rows += _halfshaft_checks(halfshaft, report.get("spec"))
        torque = _get(halfshaft, "static_torque_Nm")
        notes.append(
            f"Static checks at M_max {fmt(cell(torque.get('forward')))} N·m forward and "
            f"{fmt(cell(torque.get('backward')))} N·m backward, the largest working torques with "
            "the shock factor k_s: the sections at both, the joints at the larger (a joint's "
            "capacity holds in either direction); fatigue and life over the required mileage."
        )
    rows += _spec_requirement_checks(report)
    failed = [f"{r[0]}: {r[1].split(';')[0]}" for r in rows if r[6] != "passes"]
    unfinished = _run_problems(report)
    if failed or unfinished:
        verdict = (
            "Not validated: "
            + "; ".join(
                unfinished
                + (
                    [f"{'; '.join(failed)} {'does' if len(failed) == 1 else 'do'} not pass"]
                    if failed
                    else []
                )
            )
            + "."
        )
    elif halfshaft is None:
        verdict = "Not validated: the inboard tripod passes; the outboard joint and the shaft sections are not checked."
    else:
        verdict = "Every check passes."
    return Table(
        "validation", "Validation: requirements and verdicts", columns, rows, [verdict, *notes]
    )


def _damage(report):
    life = report.get("life")
    if life is None:
        raise NotAvailable(_ABSENT["life"])
    columns = [
        Column("mode", kind="text"),
        Column("gear", kind="text"),
        Column("engine condition", kind="text"),
        Column("share of the damage", "–"),
    ]

    def text(value):  # an explicit spectrum's cases have no mode, gear or engine condition
        return "" if value is None else str(value)

    rows = [
        [
            text(d.get("mode")) if "case" not in d else f"case {d['case']}",
            text(d.get("gear")),
            text(d.get("engine_condition")),
            cell(d.get("damage_share")),
        ]
        for d in _get(life, "damage_by_case")
    ]
    return Table("damage", "Damage shares by load case", columns, rows)


# The forces table's rows: (report key, quantity, unit).
_FORCE_ROWS = (
    ("gaf_rms_N", "GAF, RMS", "N"),
    ("gaf_peak_N", "GAF, peak", "N"),
    ("gaf_third_order_N", "GAF, 3rd order", "N"),
    ("gaf_sixth_order_N", "GAF, 6th order", "N"),
    ("gaf_ninth_order_N", "GAF, 9th order", "N"),
    ("lts_mean_N", "LTS, mean", "N"),
    ("lts_ripple_N", "LTS, ripple (± about the mean)", "N"),
    ("complementary_torque_steady_Nm", "complementary torque, steady", "N·m"),
    ("complementary_torque_third_order_Nm", "complementary torque, 3rd order", "N·m"),
    ("complementary_torque_sixth_order_Nm", "complementary torque, 6th order", "N·m"),
    ("roller_load_ratio", "largest roller load / (T/3R)", "–"),
    ("friction_power_W", "friction power (running case)", "W"),
)


def _forces(report):
    forces = report.get("forces")
    if forces is None:
        raise NotAvailable(_ABSENT["forces"])
    columns = [Column("quantity", kind="text"), Column("unit", kind="text"), Column("value")]
    rows = [[name, unit, cell(forces.get(key))] for key, name, unit in _FORCE_ROWS]
    notes = [
        f"The force model (quasi-static roller forces on the exact kinematics, seed §3.1) at "
        f"T = {fmt(cell(forces.get('torque_Nm')))} N·m (T/3R = "
        f"{fmt(cell(forces.get('nominal_roller_load_N')))} N per roller), running at "
        f"{fmt(cell(forces.get('speed_rpm')))} rpm; LTS at a plunge of "
        f"{fmt(cell(forces.get('plunge_speed_mm_s')))} mm/s and "
        f"{fmt(cell(forces.get('lts_speed_rpm')))} rpm; trunnion μ "
        f"{fmt(cell(forces.get('mu_trunnion')))}, contact angle "
        f"{fmt(cell(forces.get('contact_angle_deg')))}°; result {forces.get('result', 'not given')}."
    ]
    model = ((report.get("spec") or {}).get("friction") or {}).get("gaf_model")
    if model in ("stroke", "printed"):  # the quantities' gaf_rms comes from another model
        notes.append(
            f"The quantities' gaf_rms ({fmt(cell((report.get('quantities') or {}).get('gaf_rms')))} "
            f'N) is Lee\'s empirical friction model (friction.gaf_model = "{model}"), not this '
            "statics: the two differ (the physics docs compare them); friction.gaf_model = "
            '"forces" makes the optimiser use the force model\'s.'
        )
    return Table("forces", "Forces inside the joint", columns, rows, notes)


UNAFFECTED = "not affected by the uncertain inputs"


def _unaffected(requirement):
    """β's text, +∞ or −∞, for a reliability requirement that no uncertain input affects
    (its margin's gradient is 0 at the mean: FORM's β is ±∞, null in report.json, its
    probability exactly 0 or 1 and every importance 0), else None (a β that is null because it
    could not be computed keeps its reason)."""
    importance = requirement.get("importance")
    p = requirement.get("probability_form")
    if requirement.get("beta_form") is not None or not isinstance(importance, dict):
        return None
    if not importance or any(v != 0 for v in importance.values()):
        return None
    if isinstance(p, bool) or p not in (0, 1) or requirement.get("form_converged") is False:
        return None
    if p == 0:
        return f"+∞: {UNAFFECTED}"
    return f"−∞: {UNAFFECTED} (always missed)"


def _reliability(report):
    rel = report.get("reliability")
    if rel is None:
        raise NotAvailable(_ABSENT["reliability"])
    columns = [
        Column("requirement", kind="text"),
        Column("β (FORM)", "–"),
        Column("P failure (FORM)", "–"),
        Column("P failure (Monte Carlo)", "–"),
        Column("95 % interval low", "–"),
        Column("95 % interval high", "–"),
        Column("samples", "–"),
        Column("FORM and MC agree"),
        Column("largest importance", kind="text"),
    ]
    rows = []
    for r in _get(rel, "requirements"):
        interval = r.get("mc_interval_95") or [None, None]
        importance = r.get("importance") or {}
        top = max(importance, key=lambda k: abs(importance[k] or 0.0), default=None)
        beta, agree = cell(r.get("beta_form")), bool(r.get("agree"))
        largest = f"{top} ({fmt(cell(importance[top]), 3)})" if top else "–"
        if top and importance[top] == 0:  # no input moves the margin: none is the largest
            largest = "none (every importance is 0)"
        unaffected = _unaffected(r)
        if unaffected is not None:  # β = ±∞ (null in the JSON): no FORM estimate to agree with
            beta, agree = unaffected, "not compared (β infinite)"
        rows.append(
            [
                r["name"],
                beta,
                cell(r.get("probability_form")),
                cell(r.get("probability_mc")),
                cell(interval[0]),
                cell(interval[1]),
                cell(r.get("samples")),
                agree,
                largest,
            ]
        )
    interval = rel.get("system_interval_95") or [None, None]
    inputs = rel.get("inputs") or {}
    notes = [
        f"Method {rel.get('method', 'not given')}; system probability of failure (Monte Carlo) "
        f"{fmt(cell(rel.get('system_probability_mc')), 3)}, 95 % interval "
        f"[{fmt(cell(interval[0]), 3)}, {fmt(cell(interval[1]), 3)}].",
        "Uncertain inputs: "
        + ("; ".join(f"{k}: {v}" for k, v in inputs.items()) or "none listed")
        + ".",
    ]
    return Table("reliability", "Reliability", columns, rows, notes)


# A key's name ending → its unit (`mass_kg`, `tyre_radius_m`, `core_uts_MPa`, …).
_SUFFIX_UNITS = {
    "_deg": "deg",
    "_mm": "mm",
    "_m": "m",
    "_kg": "kg",
    "_MPa": "MPa",
    "_Nm": "N·m",
    "_N": "N",
    "_km": "km",
    "_rpm": "rpm",
    "_pct": "%",
    "_mm_s": "mm/s",
    "_kmh": "km/h",
}


def spec_unit(key):
    """The unit of a spec key (``section.key`` or ``section.key[i]``), from the embedded spec."""
    from tripodjax.optimize.spec import DEFAULT_SPEC_TOML, QUANTITIES

    base = key.split("[")[0]
    section, _, name = base.rpartition(".")
    if base in _LIST_UNITS:
        return _LIST_UNITS[base]
    for suffix, unit in _SUFFIX_UNITS.items():  # the unit a key's name ends with
        if name.endswith(suffix):
            return unit
    if section == "constraints" and name[4:] in QUANTITIES:
        return QUANTITIES[name[4:]][0]
    if section == "objective":
        if name.endswith("_ref") and name[:-4] in QUANTITIES:
            return QUANTITIES[name[:-4]][0]
        return "–"
    current = None
    for line in DEFAULT_SPEC_TOML.splitlines():
        header = re.match(r"^\[([\w.]+)\]", line)
        if header:
            current = header.group(1)
        match = re.match(r"^#?\s*(\w+)\s*=[^#]*#.*?\[([^\[\]]{1,16})\]", line)
        if match and current == section and match.group(1) == name:
            return match.group(2)
    return "–"


def _spec_value(spec, key):
    from tripodjax.optimize.spec import GREASE_MU_SLP

    base, _, index = key.partition("[")
    if base == "friction.mu_slp" and "mu_slp" not in spec.get("friction", {}):
        return GREASE_MU_SLP[spec["friction"]["grease"]]  # the grease's, where not given
    value = spec
    for part in base.split("."):
        value = value[part]
    if index:
        value = value[int(index.rstrip("]"))]
    return float(value)


def _sensitivities(report):
    notes_in = report.get("sensitivity_notes")
    derivatives = report.get("sensitivities")
    if notes_in is None and derivatives is None:
        raise NotAvailable("the run did not converge: no sensitivities of an unfinished optimum")
    notes_in = notes_in or {}
    if notes_in.get("unavailable"):
        raise NotAvailable(notes_in["unavailable"])
    if not derivatives:
        raise NotAvailable("the report lists no sensitivities")
    from tripodjax.optimize.spec import variable_domain

    elasticities = report.get("elasticities")
    if elasticities is None:
        raise NotAvailable(
            "the report has no elasticities (written by an earlier version): the inputs that "
            "matter most cannot be ranked"
        )
    from tripodjax.optimize.report import ranked_sensitivities
    from tripodjax.optimize.sensitivity import SWITCH_REPORTED

    outputs = list(next(iter(derivatives.values())))
    spec = report.get("spec") or {}
    # The ranking of the sensitivity chart (figure_tornado): one rule, the same rows.
    ranked = ranked_sensitivities({k: elasticities[k] for k in derivatives}, SENSITIVITY_ROWS)
    columns = [Column("spec key", kind="text"), Column("unit", kind="text"), Column("value")]
    for out in outputs:
        unit = "–" if out == "objective" else variable_domain(out)[0]
        columns.append(Column(f"d {out} / d p", f"{unit} per unit of p"))
    columns += [
        Column("elasticity of the objective" if out == "objective" else f"elasticity of {out}", "–")
        for out in outputs
    ]
    rows = []
    for key in ranked:
        try:
            value = cell(_spec_value(spec, key))
        except (KeyError, IndexError, TypeError, ValueError):
            value = NotAvailable("not in the report's spec")
        rows.append(
            [
                key,
                spec_unit(key),
                value,
                *(cell(derivatives[key].get(o)) for o in outputs),
                *(cell(elasticities[key].get(o)) for o in outputs),
            ]
        )
    step = notes_in.get("switch_step")
    switches = sum(len(v) for v in (notes_in.get("switch_distance") or {}).values())
    notes = [
        f"The {len(rows)} largest of {len(derivatives)} by |elasticity| (p/y)·dy/dp, the "
        "largest of the objective's and the free variables' (for the conformity Ψ, p is "
        "Ψ − 1): the rows of the sensitivity chart. Derivatives per unit of the spec key's "
        "own unit.",
        "Active constraints: "
        + (", ".join(notes_in.get("active") or []) or "none")
        + "; variables on a bound: "
        + (", ".join(notes_in.get("on_bound") or []) or "none")
        + f"; switching within a relative change of {fmt(cell(step), 3)} (derivatives "
        "withheld): "
        + (", ".join(notes_in.get("near_switch") or []) or "none")
        + f"; switches within a relative change of {SWITCH_REPORTED:g}: {switches} (the "
        "near-switch notes)"
        + f"; KKT condition number {fmt(cell(notes_in.get('condition_number')), 3)}.",
    ]
    return Table("sensitivities", "Sensitivities", columns, rows, notes)


def _switch(report):
    from tripodjax.optimize.sensitivity import SWITCH_REPORTED

    if report.get("sensitivity_notes") is None and report.get("sensitivities") is None:
        raise NotAvailable("the run did not converge: no switch distances of an unfinished optimum")
    notes = report.get("sensitivity_notes") or {}
    if notes.get("unavailable"):
        raise NotAvailable(notes["unavailable"])
    distance = notes.get("switch_distance")
    if distance is None:
        raise NotAvailable(
            "the report has no switch distances (sensitivity_notes.switch_distance): "
            "how far each input may move before a constraint switches is not given"
        )
    columns = [
        Column("constraint", kind="text"),
        Column("spec key", kind="text"),
        Column("relative change at which it switches", "–"),
    ]
    rows = [[c, k, cell(v)] for c, per_key in distance.items() for k, v in per_key.items()]
    step = notes.get("switch_step")
    return Table(
        "switch",
        "Near-switch notes",
        columns,
        rows,
        notes=[
            f"{len(rows)} switches: the relative change of an input at which, linearised, a "
            f"constraint or bound switches (active ↔ inactive), up to {SWITCH_REPORTED:g}. "
            "Within "
            + (fmt(cell(step), 3) if step is not None else "the tested change (not given)")
            + " the input's derivatives are withheld (near a switch: "
            + (", ".join(notes.get("near_switch") or []) or "none")
            + ")."
        ],
    )


def _catalogue(report):
    catalogue = report.get("catalogue")
    if catalogue is None:
        raise NotAvailable("the run evaluated no catalogue")
    columns = [
        Column("family", kind="text"),
        Column("size", kind="text"),
        Column("R", "mm"),
        Column("d", "mm"),
        Column("feasible"),
        Column("objective", "–"),
        Column("binding margin", "–", kind="margin"),
        Column("binding requirement", kind="text"),
    ]
    rows = []
    for e in catalogue:
        margins = {k: v for k, v in (e.get("margins") or {}).items() if isinstance(v, (int, float))}
        binding = min(margins, key=margins.get) if margins else None
        rows.append(
            [
                e["family"],
                str(e["size"]),
                cell(e.get("R_mm")),
                cell(e.get("d_roller_mm")),
                bool(e.get("feasible")),
                cell(e.get("objective"))
                if e.get("objective") is not None
                else NotAvailable(e.get("note", "not evaluated")),
                cell(margins[binding]) if binding else NotAvailable(e.get("note", "not evaluated")),
                binding or "–",
            ]
        )
    choice = report.get("catalogue_choice")
    note = (
        f"Choice: {choice['family']} {choice['size']}, the feasible size of lowest objective."
        if choice
        else "No size is feasible."
    )
    return Table("catalogue", "Catalogue (GE/GI sizes)", columns, rows, [note])


def _pareto(report):
    front = _get(report, "pareto_front")
    if not front:
        raise NotAvailable("the objective has no GAF term: no Pareto front was swept")
    free = report.get("free_variables") or []
    from tripodjax.optimize.report import SAME_DESIGN
    from tripodjax.optimize.spec import REPORT_KEYS, variable_domain

    keys = [REPORT_KEYS.get(v, v) for v in free]  # a [shaft] entry: its own name
    units = [variable_domain(v)[0] for v in free]
    columns = [Column("w_gaf_rms", "–"), Column("weights giving this design", kind="text")]
    columns += [
        Column(k.removesuffix(f"_{unit}"), unit) for k, unit in zip(keys, units, strict=True)
    ]
    columns += [
        Column("GAF RMS", "N"),
        Column("outer diameter 2R + d", "mm"),
        Column("irregularity", "–"),
        Column("converged"),
    ]
    rows = [
        [
            cell(p.get("w_gaf_rms")),
            ", ".join(f"{w:g}" for w in p.get("same_design_w_gaf_rms") or [p.get("w_gaf_rms")]),
            *(cell(p.get(k)) for k in keys),
            cell(p.get("gaf_rms_N")),
            cell(p.get("outer_diameter_mm")),
            cell(p.get("irregularity")),
            bool(p.get("converged")),
        ]
        for p in front
    ]
    weights = sum(len(p.get("same_design_w_gaf_rms") or [0]) for p in front)
    note = (
        f"{weights} weights swept, {len(front)} distinct designs: weights whose designs agree "
        f"within a relative {SAME_DESIGN:g} are one design, listed once."
    )
    return Table("pareto_front", "Pareto front", columns, rows, [note])


def _history(report):
    history = _get(report, "history")
    columns = [
        Column("outer iteration", "–"),
        Column("objective", "–"),
        Column("KKT residual", "–"),
    ]
    rows = [
        [float(i), cell(f), cell(k)]
        for i, (f, k) in enumerate(zip(history["objective"], history["kkt_residual"], strict=True))
    ]
    return Table("convergence", "Convergence history (chosen start)", columns, rows)


_VALIDATION = ("validation", "Validation: requirements and verdicts", _validation)
SECTIONS = (
    ("summary", "Summary", _summary),
    ("requirements", "Requirements", _requirements),
    ("quantities", "Quantities", _quantities),
    ("life", "Life per working condition", _life),
    ("damage", "Damage shares by load case", _damage),
    ("forces", "Forces inside the joint", _forces),
    ("halfshaft", "The rest of the halfshaft", _halfshaft),
    ("outboard_life", "Outboard joint: life per working condition", _outboard_life),
    ("shaft_damage", "Shaft sections: damage by gear", _shaft_damage),
    _VALIDATION,
    ("reliability", "Reliability", _reliability),
    ("sensitivities", "Sensitivities", _sensitivities),
    ("switch", "Near-switch notes", _switch),
    ("catalogue", "Catalogue (GE/GI sizes)", _catalogue),
    ("pareto_front", "Pareto front", _pareto),
    ("convergence", "Convergence history (chosen start)", _history),
)


# ---------------------------------------------------------------------------------------------
# the validation document (validation.html): the customer's inputs and the readings beside the
# verdict table (SECTIONS' "validation")

# The customer's inputs: (path in the resolved spec, what it is, unit).
_VEHICLE_INPUTS = (
    (("vehicle", "axle"), "axle of the halfshaft", ""),
    (("vehicle", "mass_kg"), "gross vehicle mass", "kg"),
    (("vehicle", "front_share"), "share of the mass on the front axle", "–"),
    (("vehicle", "wheelbase_m"), "wheelbase", "m"),
    (("vehicle", "cg_height_m"), "centre-of-gravity height", "m"),
    (("vehicle", "tyre_radius_m"), "static loaded tyre radius", "m"),
    (("vehicle", "adhesion"), "tyre–road adhesion coefficient", "–"),
    (("vehicle", "rear_torque_share"), "share of the engine torque to the rear axle", "–"),
    (("vehicle", "differential_locking"), "differential locking", "–"),
    (
        ("vehicle", "engine_torque_Nm"),
        "engine torque at mean torque, maximum torque, maximum power, engine brake",
        "N·m",
    ),
    (("vehicle", "engine_speed_rpm"), "engine speed at the same conditions", "rpm"),
    (("vehicle", "gears", "ratios"), "overall ratios (gear × final drive), 1st gear first", "–"),
    (("vehicle", "gears", "reverse"), "overall ratio in reverse", "–"),
    (("vehicle", "load_transfer_per_ratio_N"), "wheel-load transfer per unit overall ratio", "N"),
    (("vehicle", "reverse_load_transfer_N"), "wheel-load transfer in reverse", "N"),
)
# The gear-use tables of [vehicle.modes]: (key, engine condition).
_USE_TABLES = (
    ("use_T_mean_pct", "mean torque"),
    ("use_T_max_pct", "maximum torque"),
    ("use_P_max_pct", "maximum power"),
    ("use_brake_pct", "engine brake"),
)
_USE_INPUTS = (
    (("loads", "M_max"), "largest forward torque on the shaft, as given", "N·m"),
    (("loads", "shock_factor"), "shock factor k_s", "–"),
    (("life", "required_km"), "required mileage", "km"),
)


def _listed(value):
    return ", ".join(fmt(cell(v)) for v in value) if isinstance(value, list) else cell(value)


def _shares(names, shares):
    return ", ".join(f"{n} {fmt(cell(100 * w), 3)} %" for n, w in zip(names, shares, strict=True))


def _conditions_text(conditions):
    return ", ".join(
        f"{n} {fmt(cell(a), 3)}° {fmt(cell(100 * w), 3)} %"
        for n, a, w in zip(
            conditions["names"], conditions["angle_deg"], conditions["share"], strict=True
        )
    )


def _use_text(names, use):
    """A gear-use table: one list for every mode, or a list per mode (named)."""
    if isinstance(use, list) and use and all(isinstance(u, list) for u in use):
        return "; ".join(f"{n}: {_listed(u)}" for n, u in zip(names, use, strict=False))
    return _listed(use)


def _spec_cell(spec, *path):
    """The spec's value at ``path`` as a cell (a list as its text), or the reason it is not
    there (a report of an earlier version): one missing input never hides the others."""
    try:
        return _listed(_get(spec, *path))
    except NotAvailable as reason:
        return reason


def _inputs(report):
    spec = _get(report, "spec")
    columns = [Column("input", kind="text"), Column("value"), Column("unit", kind="text")]
    from tripodjax.optimize.spec import LIFE_LISTS

    rows = []
    notes = []
    life = _get(spec, "life")
    explicit = [k for k in (*LIFE_LISTS, "spectrum_file") if k in life]
    # The resolved spec keeps the default [vehicle]; it is used unless M_max and the spectrum
    # are both given (optimize.spec).
    if "vehicle" in spec and ("M_max" not in _get(spec, "loads") or not explicit):
        for path, name, unit in _VEHICLE_INPUTS:
            rows.append([name, _spec_cell(spec, *path), unit])
        modes = _get(spec, "vehicle", "modes")
        rows.append(
            [
                "use: driving modes, share of the mileage",
                _shares(modes["names"], modes["weight"]),
                "",
            ]
        )
        for key, condition in _USE_TABLES:
            use = modes.get(key)
            rows.append(
                [
                    f"gear use at {condition}: % of the mode's revolutions, 1st gear first, "
                    f"reverse last ({key})",
                    NotAvailable(f"the report has no spec.vehicle.modes.{key}")
                    if use is None
                    else _use_text(modes["names"], use),
                    "%",
                ]
            )
    else:
        notes.append(
            "No vehicle is used: the spec gives the largest torque (loads.M_max) and the load "
            "spectrum directly."
        )
    for path, name, unit in _USE_INPUTS:
        if path[-1] in spec.get(path[0], {}):
            rows.append([name, cell(_get(spec, *path)), unit])
    for key in explicit:
        unit = "" if key == "spectrum_file" else spec_unit(f"life.{key}")
        rows.append([f"load spectrum: life.{key}", _listed(life[key]), unit])
    rows.append(
        [
            "working conditions of the inboard tripod: angle, share of the mileage",
            _conditions_text(_get(spec, "life", "conditions")),
            "",
        ]
    )
    if report.get("halfshaft") is not None:
        rows.append(
            [
                "working conditions of the outboard joint: angle, share of the mileage",
                _conditions_text(_get(spec, "outboard", "conditions")),
                "",
            ]
        )
    return Table("inputs", "Vehicle, loads and use", columns, rows, notes)


def _design_or_spec(report, key, *path):
    """A joint's input at the design (``report["design"][key]``, where the optimiser moves it)
    or the spec's (``path``), as a cell."""
    design = report.get("design")
    if isinstance(design, dict) and key in design:
        return cell(design[key])
    return _spec_cell(_get(report, "spec"), *path)


def _joints(report):
    """The joints' Hertz inputs: the tripod's (its design R, d, Ψ and the [hertz] pressures)
    and, with the halfshaft's checks, the outboard ball joint's ([outboard])."""
    spec = _get(report, "spec")
    columns = [
        Column("joint", kind="text"),
        Column("n", "–"),
        Column("d", "mm"),
        Column("R or PCR", "mm"),
        Column("Ψ", "–"),
        Column("P_s", "MPa"),
        Column("P_d", "MPa"),
        Column("P_sd", "MPa"),
        Column("C_s", "–"),
    ]
    pressures = ("P_s", "P_d", "P_sd", "C_s")
    rows = [
        [
            "inboard tripod",
            _spec_cell(spec, "hertz", "n_rollers"),
            _design_or_spec(report, "d_roller_mm", "design", "d_roller"),
            _design_or_spec(report, "R_mm", "design", "R"),
            _design_or_spec(report, "conformity", "hertz", "conformity"),
            *(_spec_cell(spec, "hertz", k) for k in pressures),
        ]
    ]
    notes = [
        "n rollers or balls of diameter d on the track radius R (tripod) or pitch-centre radius "
        "PCR (outboard); conformity Ψ = 2R_g/d; allowed contact pressures static P_s, "
        "long-lasting dynamic P_d, short-lasting dynamic P_sd; safety coefficient C_s on the "
        "pressure."
    ]
    if isinstance(report.get("halfshaft"), dict):
        rows.append(
            [
                "outboard joint",
                *(
                    _spec_cell(spec, "outboard", k)
                    for k in ("n_balls", "ball_diameter_mm", "pcr_mm", "conformity", *pressures)
                ),
            ]
        )

        def value(key, unit):
            return f"{fmt(_spec_cell(spec, 'outboard', key))} {unit}"

        notes.append(
            f"Outboard joint: pressure angle ε {value('pressure_angle_deg', 'deg')}, oblique "
            f"angle ζ {value('oblique_angle_deg', 'deg')}, longitudinal conformity χ_l "
            f"{value('longitudinal_conformity', '–')}, life tolerance "
            f"{value('tolerance', '–')}."
        )
    return Table("joints", "The joints' Hertz inputs", columns, rows, notes)


def _sections(report):
    """Each shaft section's geometry and safety coefficient as checked, and the material."""
    spec = _get(report, "spec")
    shaft = _get(spec, "shaft")
    names = shaft.get("names") or []
    design = report.get("design") if isinstance(report.get("design"), dict) else {}
    columns = [
        Column("section", kind="text"),
        Column("Øe", "mm"),
        Column("Øi", "mm"),
        Column("hardened depth h", "mm"),
        Column("transition t", "mm"),
        Column("safety coefficient C_s", "–"),
    ]

    def entry(key, name):  # the design's where the optimiser moves it, else the spec's
        free = f"shaft.{key}[{name}]"
        if free in design:
            return cell(design[free])
        if name in names and isinstance(shaft.get(key), list):
            return cell(shaft[key][names.index(name)])
        return NotAvailable(f"the report's spec has no shaft.{key} of {name}")

    rows = [
        [
            s["name"],
            cell(s.get("outer_diameter_mm")),
            cell(s.get("inner_diameter_mm")),
            cell(s.get("hardened_depth_mm")),
            entry("transition_depth_mm", s["name"]),
            entry("safety", s["name"]),
        ]
        for s in _get(_halfshaft_section(report), "sections")
    ]

    def value(key, unit):
        return f"{fmt(_spec_cell(spec, 'shaft', key))}{unit}"

    notes = [
        f"Material of every section: core strength σ_R,c {value('core_uts_MPa', ' MPa')}, "
        f"surface strength σ_R,s {value('surface_uts_MPa', ' MPa')}, strength lost from the "
        f"surface to the depth h Δ {value('depth_drop', ' –')}, fatigue ratio q = σ_R/σ_f "
        f"{value('fatigue_ratio', ' –')}; allowed damage {value('allowed_damage', ' –')}. C_s "
        "is inside τ_adm = σ_R/(C_s√3): the requirement τ_adm/τ ≥ 1 includes it."
    ]
    return Table("sections", "Shaft sections", columns, rows, notes)


# Where the workbook is silent: (spec key, what it concerns, {reading: what it means}).
READINGS = (
    (
        ("shaft", "reading"),
        "shaft sections in fatigue",
        {
            "consistent": "the 1st gear's engine-brake cycles counted with the event rate p(ω) "
            "like every other row; the strength at the end of the hardened layer r_TR is the "
            "strength profile's there (the core's σ_R,c)",
            "workbook": "the sheet's numbers: the 1st gear's engine-brake cycles counted as "
            "revolutions without p(ω); the strength at r_TR taken as σ_R,c (1 + Δ) (759 MPa "
            "for a 690 MPa core)",
        },
    ),
    (
        ("outboard", "reading"),
        "outboard joint's Hertz coefficient μν and life in km",
        {
            "consistent": "μν from exact Hertz theory (elliptic integrals); km = hours × the "
            "time-weighted mean vehicle speed, the distance the spectrum's revolutions roll",
            "workbook": "μν from the sheet's table at cos τ truncated to 10⁻³ (reproduces the "
            "sheet's M_s, M_d, M_sd within 0.3 %; the exact μν gives 3.8 % more); km = hours × "
            "the revolution-weighted mean vehicle speed, the sheet's V_ave (its km per working "
            "condition and combined within 0.3 %)",
        },
    ),
    (
        ("life", "angle_law"),
        "life against the working angle (both joints)",
        {
            "workbook": "g(γ) = exp(−(aγ + bγ²)), fitted through the workbook's two readable "
            "points (6.5° and 12.8°, fig. 4.3.10): the sheet's macro is not printed",
            "seed": "the seed's printed factor ½(1 + cos γ) in M_d, g(γ) = (½(1 + cos γ))³",
        },
    ),
)


def _readings(report):
    spec = _get(report, "spec")
    columns = [
        Column("item", kind="text"),
        Column("reading chosen", kind="text"),
        Column("what it means", kind="text"),
        Column("the other reading", kind="text"),
    ]
    rows = []
    for path, item, meanings in READINGS:
        chosen = _get(spec, *path)
        others = "; ".join(f"{k}: {v}" for k, v in meanings.items() if k != chosen)
        rows.append(
            [item, chosen, meanings.get(chosen, f"{chosen!r} is not a known reading"), others]
        )
    return Table(
        "readings",
        "Readings where the workbook is silent",
        columns,
        rows,
        notes=["Spec keys: " + ", ".join(".".join(p) for p, _, _ in READINGS) + "."],
    )


def table_dict(table) -> dict:
    """A table as strict JSON: column labels, rows (a cell that is not available as its text),
    notes, and the reason when the whole table is not available (else null)."""
    return {
        "title": table.title,
        "columns": [c.label for c in table.columns],
        "rows": [[fmt(v) if isinstance(v, NotAvailable) else v for v in r] for r in table.rows],
        "notes": list(table.notes),
        "unavailable": table.unavailable,
    }


# The validation document's tables: the customer's inputs, the verdict table (the report's
# "validation" table, as in report.json and report.xlsx) and the readings where the sheet is silent.
VALIDATION_SECTIONS = (
    ("inputs", "Vehicle, loads and use", _inputs),
    ("joints", "The joints' Hertz inputs", _joints),
    ("sections", "Shaft sections", _sections),
    _VALIDATION,
    ("readings", "Readings where the workbook is silent", _readings),
)


def validation_section(report) -> dict:
    """The report's ``validation`` section (report.json): the verdict table as `table_dict`,
    the table validation.html, report.html and report.xlsx show."""
    return table_dict(tables(report, (_VALIDATION,))["validation"])


def tables(report, sections=SECTIONS) -> dict:
    """The report's tables ``{name: Table}``, in reading order; a table it cannot give says why.
    ``sections``: `SECTIONS` (report.html, report.xlsx) or `VALIDATION_SECTIONS`
    (validation.html)."""
    if not isinstance(report, dict):
        report = {}
    return {name: _section(title, name, build, report) for name, title, build in sections}


# ---------------------------------------------------------------------------------------------
# the resolved spec as TOML


def _toml_value(value):
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False)
    if isinstance(value, (int, float)):
        return (
            repr(value)
            if math.isfinite(value)
            else ("inf" if value > 0 else "-inf" if value < 0 else "nan")
        )
    if isinstance(value, list):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    if value is None:
        raise NotAvailable("null")
    raise NotAvailable(f"{value!r} has no TOML form")


def spec_toml(spec, prefix=()):
    """A resolved spec (nested dicts) as TOML text; a null (non-finite) value as a comment."""
    lines, tables_ = [], []
    for key, value in spec.items():
        if isinstance(value, dict):
            tables_.append((key, value))
            continue
        try:
            lines.append(f"{key} = {_toml_value(value)}")
        except NotAvailable as reason:
            lines.append(f"# {key}: not available ({reason}: not finite when written)")
    out = []
    if prefix and (lines or not tables_):  # an empty table keeps its header
        out.append(f"[{'.'.join(prefix)}]")
    out += lines
    for key, value in tables_:
        sub = spec_toml(value, (*prefix, key))
        if sub:
            out += ([""] if out else []) + [sub]
    return "\n".join(out)


# ---------------------------------------------------------------------------------------------
# the page


def image_uri(figure):
    """A figure as a data URI: PNG bytes as they are (what ``optimize-joint`` wrote already,
    no second rendering), a matplotlib Figure as SVG (text kept as text)."""
    if isinstance(figure, bytes):
        return "data:image/png;base64," + base64.b64encode(figure).decode("ascii")
    import matplotlib

    buffer = io.BytesIO()
    with matplotlib.rc_context({"svg.fonttype": "none", "svg.hashsalt": "tripodjax"}):
        figure.savefig(buffer, format="svg")
    return "data:image/svg+xml;base64," + base64.b64encode(buffer.getvalue()).decode("ascii")


FIGURES = {  # the figure beside each table, by the name the CLI gives it
    "requirements": ("constraint_margins.png", "Constraint margins at the proposed design"),
    "damage": ("damage.png", "Damage shares"),
    "reliability": ("importance.png", "Importance factors"),
    "sensitivities": ("sensitivities.png", "Tornado chart of the largest elasticities"),
    "life": ("life_conditions.png", "Life per working condition of each joint"),
    "shaft_damage": ("shaft_damage.png", "Fatigue damage of the shaft sections by gear"),
    "catalogue": ("catalogue.png", "Catalogue sizes over the constraint landscape"),
    "pareto_front": ("pareto_front.png", "Pareto front: GAF against joint size"),
    "convergence": ("convergence.png", "Convergence of the chosen start"),
}


# The validation document's figures: {place: (file name, caption)}.
VALIDATION_FIGURES = {
    "life": ("life_conditions.png", "Life per working condition of each joint"),
    "damage": ("shaft_damage.png", "Fatigue damage of the shaft sections by gear"),
}


def _images(figures, wanted):
    """``{place: (data URI or NotAvailable, caption)}`` of the ``wanted`` figures that are drawn."""
    images = {}
    for place, (name, caption) in wanted.items():
        if name in figures:
            try:
                images[place] = (image_uri(figures[name]), caption)
            except (ValueError, RuntimeError, OverflowError) as error:  # a figure of bad numbers
                images[place] = (NotAvailable(f"the figure could not be drawn: {error}"), caption)
    return images


def css_string(text):
    """``text`` as a CSS string literal (for ``content:`` in a style element): every character
    but letters, digits and plain punctuation as a hex escape, so that no quote, backslash,
    ``<`` or line end of a spec name or revision ends the string or the style element (the
    space after each escape is the escape's own)."""
    import markupsafe

    safe = set(" .,:;-_()/+#")
    body = "".join(
        ch if (ch.isascii() and ch.isalnum()) or ch in safe else f"\\{ord(ch):06x} "
        for ch in str(text)
    )
    return markupsafe.Markup(f'"{body}"')


@functools.cache
def _environment():
    import jinja2

    env = jinja2.Environment(
        loader=jinja2.PackageLoader("tripodjax.optimize", "templates"),
        autoescape=jinja2.select_autoescape(["html", "j2"], default=True),
        undefined=jinja2.StrictUndefined,
        trim_blocks=True,
        lstrip_blocks=True,
    )
    env.filters["fmt"] = fmt
    env.filters["exact"] = repr  # full precision in data-value: what a reader can check
    env.filters["css_string"] = css_string
    env.tests["unavailable"] = lambda v: isinstance(v, NotAvailable)
    return env


def _current_version():
    import tripodjax

    return tripodjax.__version__


def version_note(report):
    """A sentence when the report was written by another tripodjax version, else None."""
    written = (
        ((report or {}).get("versions") or {}).get("tripodjax")
        if isinstance(report, dict)
        else None
    )
    current = _current_version()
    if written != current:
        return (
            f"This report was written by tripodjax {written or 'of an unknown version'}; this page "
            f'was rendered by tripodjax {current}: sections it cannot read say "not available".'
        )
    return None


def render_html(report, figures=None) -> str:
    """The report as one self-contained HTML page.

    ``figures``: ``{file name: matplotlib Figure or PNG bytes}`` under the names the CLI
    gives them (``FIGURES``), each shown beside its table.
    """
    figures = figures or {}
    safe = report if isinstance(report, dict) else {}
    images = _images(figures, FIGURES)
    try:
        toml = spec_toml(_get(safe, "spec"))
    except (NotAvailable, AttributeError) as reason:
        toml = NotAvailable(str(reason))
    written = safe.get("written") or {}
    return (
        _environment()
        .get_template("report.html.j2")
        .render(
            title=f"tripodjax design report: {safe.get('spec_source', 'spec not named')}",
            tables=tables(report),
            images=images,
            version_note=version_note(report),
            versions=safe.get("versions") or {},
            date=written.get("date", NotAvailable("not recorded")),
            command=written.get("command", NotAvailable("not recorded")),
            spec_toml=toml,
            nonfinite=safe.get("nonfinite_notes") or [],
        )
    )


def render_validation(report, figures=None) -> str:
    """The validation document the customer signs off (validation.html): the inputs, the method,
    each joint's and shaft section's requirement, value and verdict, the life per working
    condition and the damage by gear, the readings chosen, the revision and approval block.

    ``figures``: as for `render_html` (`VALIDATION_FIGURES` are shown).
    """
    safe = report if isinstance(report, dict) else {}
    written = safe.get("written") or {}
    versions = safe.get("versions") or {}
    design = safe.get("design") if isinstance(safe.get("design"), dict) else {}
    spec = safe.get("spec") if isinstance(safe.get("spec"), dict) else {}
    return (
        _environment()
        .get_template("validation.html.j2")
        .render(
            title=VALIDATION_TITLE,
            source=safe.get("spec_source", "spec not named"),
            tables=tables(report, VALIDATION_SECTIONS),
            images=_images(figures or {}, VALIDATION_FIGURES),
            version_note=version_note(report),
            versions={
                name: versions.get(name, NotAvailable("not recorded"))
                for name in ("tripodjax", "jax")
            },
            date=written.get("date", NotAvailable("not recorded")),
            revision=written.get("revision", "0"),
            R=cell(design.get("R_mm")),
            d=cell(design.get("d_roller_mm")),
            status=status_words(safe),
            shock_factor=cell((spec.get("loads") or {}).get("shock_factor")),
            halfshaft_absent=None
            if isinstance(safe.get("halfshaft"), dict)
            else _ABSENT["halfshaft"],
            life_absent=None if isinstance(safe.get("life"), dict) else _ABSENT["life"],
        )
    )


# ---------------------------------------------------------------------------------------------
# the workbook


def prepare():
    """Import Matplotlib's figure and PNG writer, Jinja2 and openpyxl and compile the templates
    now (``optimize-joint`` does it in a thread beside the solve, so that drawing and writing the
    report later waits for none of them)."""
    import matplotlib.backends.backend_agg  # noqa: F401
    import matplotlib.figure  # noqa: F401

    env = _environment()
    for name in ("report.html.j2", "validation.html.j2", "compare.html.j2"):
        env.get_template(name)
    xlsx_missing()


def xlsx_missing():
    """The one line to print when openpyxl is not installed, else None."""
    try:
        import openpyxl  # noqa: F401
    except ImportError:
        return f"report.xlsx not written: it needs openpyxl ({XLSX_EXTRA})"
    return None


def _append(sheet, values):
    """A row of the workbook, its text as text: a name such as "=1+2" is no formula."""
    sheet.append(values)
    for cell in sheet[sheet.max_row]:
        if isinstance(cell.value, str):
            cell.data_type = "s"


VALIDATION_TITLE = "Halfshaft validation"


def validation_identity(report) -> dict:
    """What identifies the validation document (validation.html's header, report.xlsx's
    validation sheet): ``{"document", "revision", "date", "specification", "computed with"}``
    as text."""
    safe = report if isinstance(report, dict) else {}
    written = safe.get("written") if isinstance(safe.get("written"), dict) else {}
    versions = safe.get("versions") if isinstance(safe.get("versions"), dict) else {}
    return {
        "document": f"{VALIDATION_TITLE} (validation.html): the halfshaft and its joints "
        "(the workbook's sheets 7 and 8)",
        "revision": f"Rev. {written.get('revision', '0')}",
        "date": fmt(written.get("date", NotAvailable("not recorded"))),
        "specification": str(safe.get("spec_source", "spec not named")),
        "computed with": ", ".join(
            f"{name} {fmt(versions.get(name, NotAvailable('not recorded')))}"
            for name in ("tripodjax", "jax")
        ),
    }


def _header_text(text):
    """``text`` in a sheet's printed header or footer, its "&" not a code."""
    return str(text).replace("&", "&&")


def write_xlsx(report, path):
    """The report's tables as a workbook at ``path``: a sheet per table, header row frozen.
    The validation sheet names its document, revision, date and spec below its notes and in
    its printed header and footer (with the page of the pages)."""
    from openpyxl import Workbook
    from openpyxl.styles import Font

    book = Workbook()
    book.remove(book.active)
    identity = validation_identity(report)
    for table in tables(report).values():
        sheet = book.create_sheet(table.name[:31])
        if table.name == "validation":
            sheet.oddHeader.left.text = _header_text(
                f"{VALIDATION_TITLE}: {identity['specification']}"
            )
            sheet.oddHeader.right.text = _header_text(f"{identity['revision']}, {identity['date']}")
            sheet.oddFooter.right.text = "page &P of &N"
        if table.unavailable:
            _append(sheet, [f"{table.title}: not available ({table.unavailable})"])
            continue
        _append(sheet, [c.label for c in table.columns])
        for c in sheet[1]:
            c.font = Font(bold=True)
        for row in table.rows:
            _append(sheet, [fmt(v) if isinstance(v, NotAvailable) else v for v in row])
        sheet.freeze_panes = "A2"
        for note in table.notes:
            sheet.append([])
            _append(sheet, [note])
        if table.name == "validation":
            sheet.append([])
            for key, value in identity.items():
                _append(sheet, [key, value])
        for i, column in enumerate(table.columns):
            width = (
                max(len(column.label), *(len(fmt(r[i])) for r in table.rows))
                if table.rows
                else len(column.label)
            )
            sheet.column_dimensions[sheet.cell(1, i + 1).column_letter].width = min(width + 2, 60)
    book.save(path)


# ---------------------------------------------------------------------------------------------
# writing


def written_info(command=None, revision="0"):
    """The date (UTC), the command line (default: this process's) and the validation
    document's revision (``optimize-joint --revision``), for the colophon."""
    if command is None:
        command = [os.path.basename(sys.argv[0]) or "python", *sys.argv[1:]]
    return {
        "date": datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M UTC"),
        "command": shlex.join(command),
        "revision": revision,
    }


def documents(report, figures, formats=FORMATS):
    """``({file name: writer(path)}, messages)`` for the html (report.html and validation.html)
    and xlsx among ``formats``."""
    unknown = set(formats) - set(FORMATS)
    if unknown:
        raise ValueError(f"formats {sorted(unknown)} unknown; allowed: {', '.join(FORMATS)}")
    writers, messages = {}, []
    if "html" in formats:  # the design report and the customer's validation document

        def page(render):
            def write(path, pngs):
                with open(path, "w", encoding="utf-8") as f:
                    f.write(render(report, {**figures, **pngs}))

            return write

        writers["report.html"] = page(render_html)
        writers["validation.html"] = page(render_validation)
    if "xlsx" in formats:
        missing = xlsx_missing()
        if missing:
            messages.append(missing)
        else:
            writers["report.xlsx"] = lambda path, pngs: write_xlsx(report, path)
    return writers, messages


def write_report(
    result,
    spec,
    out_dir,
    formats=FORMATS,
    *,
    pareto=(),
    catalogue=None,
    choice=None,
    full_fidelity=None,
    figures=None,
    source="python",
):
    """Write the report of ``result`` (a [`Result`][tripodjax.optimize.Result] of ``spec``) into
    ``out_dir``, atomically: ``report.json``, ``report.html``, ``report.xlsx`` as ``formats`` says,
    and the PNG figures.

    Args:
        result: the solved design (``result.sensitivities`` filled in for the sensitivity table).
        spec: its [`Spec`][tripodjax.optimize.Spec]: the one it was solved for (``TypeError``
            for ``None`` or another spec's Result, ``ValueError`` for a spec of other numbers;
            nothing is written).
        out_dir: the folder (created when absent).
        formats: any of ``"json"``, ``"html"``, ``"xlsx"``.
        pareto, catalogue, choice, full_fidelity: as ``optimize-joint`` computes them (optional).
        figures: ``{file name: matplotlib Figure}``; by default the convergence, margins,
            tornado, Pareto and catalogue figures that the inputs allow.
        source: how the spec is named in the report.

    Returns:
        ``(report dict, messages)``: messages are one-line notes (e.g. openpyxl missing: the
        workbook was not written, the other files were).
    """
    from tripodjax.optimize import report as _report

    body = _report.report_dict(
        result,
        spec,
        pareto=pareto,
        catalogue=catalogue,
        choice=choice,
        full_fidelity=full_fidelity,
        source=source,
    )
    body["written"] = written_info()
    if figures is None:
        figures = {
            "convergence.png": _report.figure_convergence(result),
            "constraint_margins.png": _report.figure_margins(result),
        }
        if catalogue is not None:
            figures["catalogue.png"] = _report.figure_catalogue(result, catalogue, choice)
        if pareto:
            figures["pareto_front.png"] = _report.figure_pareto(result, list(pareto))
        if result.sensitivities is not None and result.sensitivities["elasticities"]:
            figures["sensitivities.png"] = _report.figure_tornado(result)
    writers, messages = documents(body, figures, formats)
    _report.write(out_dir, body, figures, writers, with_json="json" in formats)
    return body, messages
