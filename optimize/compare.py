"""``optimize-joint compare DIR_A DIR_B``: two reports side by side on one HTML page.

The page sets the designs, the objectives, each requirement's margin (met or not) and each
quantity next to each other with the change from A to B, and lists the spec keys whose values
differ. Exit status: 0 written; 2 a folder without a readable report.json (or one that
optimize-joint did not write), or bad arguments; 3 the page could not be written.
"""

import json
import os
import sys

from tripodjax._cli import ArgumentParser, write_text
from tripodjax.optimize.document import NotAvailable, cell, fmt, version_note

EXIT_OK, EXIT_BAD_INPUT, EXIT_WRITE_FAILED = 0, 2, 3
# What every report.json optimize-joint has written holds, beside versions.tripodjax.
REQUIRED = {"design": dict, "converged": bool, "constraints": dict}
# A relative change (B − A)/|A| is shown where |A| is at least this share of its scale: 1 for a
# margin ln(value/limit) (itself relative), max(|A|, |B|) for any other number. Below it, A is
# zero up to the solve (an active constraint's margin is of the order of the solver's tolerance)
# and the relative change is noise: the page gives the change B − A alone.
NEAR_ZERO = 1e-3
# Relative to the larger of A and B, a difference below ROUNDOFF is the arithmetic's, not a
# change (the solve is converged to 1e-8): the page shows 0, where it showed e.g. −3.6e-15.
ROUNDOFF = 1e-12


def load(folder):
    """The strict-JSON report.json of an optimize-joint output folder (ValueError: why not)."""
    path = os.path.join(folder, "report.json")

    def refuse(token):
        raise ValueError(f"non-strict JSON token {token}")

    try:
        with open(path, encoding="utf-8") as f:
            report = json.load(f, parse_constant=refuse)
    except OSError as error:
        raise ValueError(f"cannot read {path}: {error.strerror or error}") from None
    except (ValueError, UnicodeDecodeError) as error:
        raise ValueError(f"{path} is not a strict-JSON report: {error}") from None
    versions = report.get("versions") if isinstance(report, dict) else None
    written = versions.get("tripodjax") if isinstance(versions, dict) else None
    if not isinstance(written, str) or not all(
        isinstance(report.get(k), t) for k, t in REQUIRED.items()
    ):
        raise ValueError(
            f"{path} is not a tripodjax report.json (written by optimize-joint: it has "
            f"versions.tripodjax, {', '.join(REQUIRED)})"
        )
    return report


def _flat(table, prefix=""):
    out = {}
    for key, value in (table or {}).items():
        name = f"{prefix}.{key}" if prefix else str(key)
        if isinstance(value, dict):
            out.update(_flat(value, name))
        else:
            out[name] = value
    return out


def _change(a, b, scale=None):
    """(B − A, (B − A)/|A|) for two numbers, NotAvailable where either is not one.

    ``scale``: the size against which A is near zero (``NEAR_ZERO``); max(|A|, |B|) when None.
    """
    if not (isinstance(a, float) and isinstance(b, float)):
        reason = a if isinstance(a, NotAvailable) else b if isinstance(b, NotAvailable) else None
        return (NotAvailable(str(reason) if reason else "not a number"),) * 2
    if abs(b - a) <= ROUNDOFF * max(abs(a), abs(b)):
        return 0.0, 0.0
    scale = max(abs(a), abs(b)) if scale is None else scale
    if a == 0 or abs(a) < NEAR_ZERO * scale:
        return b - a, NotAvailable(f"A is near 0 (|A| < {NEAR_ZERO:g} of its scale); see B − A")
    return b - a, (b - a) / abs(a)


def _rows(a, b, keys):
    rows = []
    for key, unit in keys:
        va, vb = cell(_pick(a, key)), cell(_pick(b, key))
        rows.append((key, unit, va, vb, *_change(va, vb)))
    return rows


def _design_unit(key):
    """The unit of a design key of a report: its suffix (R_mm, gamma0_deg), else – (conformity)."""
    return next((u for u in ("mm", "deg") if key.endswith(f"_{u}")), "–")


def _pick(report, path):
    value = report
    for part in path.split("/"):
        if not isinstance(value, dict) or part not in value:
            return NotAvailable("not in this report")
        value = value[part]
    return value


def comparison(a, b):
    """The rows of the comparison page: design, objective, margins, quantities, spec keys."""
    design = list(dict.fromkeys([*(a.get("design") or {}), *(b.get("design") or {})]))
    constraints = list(
        dict.fromkeys([*(a.get("constraints") or {}), *(b.get("constraints") or {})])
    )
    quantities = list(dict.fromkeys([*(a.get("quantities") or {}), *(b.get("quantities") or {})]))
    units = {**(a.get("units") or {}), **(b.get("units") or {})}
    margins = []
    for name in constraints:
        va = cell(_pick(a, f"constraints/{name}/margin"))
        vb = cell(_pick(b, f"constraints/{name}/margin"))
        limit_a = cell(_pick(a, f"constraints/{name}/limit"))
        limit_b = cell(_pick(b, f"constraints/{name}/limit"))
        margins.append((name, va, vb, *_change(va, vb, scale=1.0), limit_a, limit_b))
    spec_a, spec_b = _flat(a.get("spec")), _flat(b.get("spec"))
    differ = [
        (key, spec_a.get(key, NotAvailable("not set")), spec_b.get(key, NotAvailable("not set")))
        for key in sorted(set(spec_a) | set(spec_b))
        if spec_a.get(key, KeyError) != spec_b.get(key, KeyError)
    ]
    return {
        "design": _rows(a, b, [(f"design/{k}", _design_unit(k)) for k in design]),
        "objective": _rows(a, b, [("objective", "–")]),
        "margins": margins,
        "quantities": _rows(a, b, [(f"quantities/{q}", units.get(q, "")) for q in quantities]),
        "spec": differ,
    }


def render(a, b, name_a="A", name_b="B"):
    """The comparison of reports ``a`` and ``b`` (dicts) as one self-contained HTML page."""
    from tripodjax.optimize.document import _environment

    notes = [n for n in (version_note(a), version_note(b)) if n]
    return (
        _environment()
        .get_template("compare.html.j2")
        .render(
            name_a=name_a,
            name_b=name_b,
            rows=comparison(a, b),
            notes=notes,
            status={
                "A": "converged" if a.get("converged") else "NOT converged",
                "B": "converged" if b.get("converged") else "NOT converged",
            },
            fmt=fmt,
        )
    )


def main(argv=None):
    parser = ArgumentParser(
        prog="optimize-joint compare",
        description=(
            "Set two optimize-joint reports side by side: designs, objectives, each requirement's "
            "margin and each quantity with the change from A to B, and the spec keys that differ."
        ),
        epilog=(
            "Exit status: 0 written; 2 a folder without a readable report.json of optimize-joint; "
            "3 the page could not be written."
        ),
    )
    parser.add_argument("dir_a", metavar="DIR_A", help="output folder of the first run (A)")
    parser.add_argument("dir_b", metavar="DIR_B", help="output folder of the second run (B)")
    parser.add_argument(
        "--out",
        metavar="FILE",
        default="compare.html",
        help="the page to write (default: compare.html in the current folder)",
    )
    args = parser.parse_args(argv)
    try:
        a, b = load(args.dir_a), load(args.dir_b)
    except ValueError as error:
        print(f"optimize-joint compare: {error}", file=sys.stderr)
        return EXIT_BAD_INPUT
    try:
        write_text(args.out, render(a, b, args.dir_a, args.dir_b))
    except OSError as error:
        print(
            f"optimize-joint compare: cannot write {args.out}: {error.strerror or error}",
            file=sys.stderr,
        )
        return EXIT_WRITE_FAILED
    changed = [row[0] for row in comparison(a, b)["spec"]]
    print(
        f"optimize-joint compare: {args.out} written; "
        + (f"the specs differ in {', '.join(changed)}" if changed else "the specs are the same")
    )
    return EXIT_OK
