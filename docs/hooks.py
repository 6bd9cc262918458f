"""mkdocs hooks of the tripodjax site (mkdocs.yml `hooks:`; not a page of the site).

- The API reference reads the sources with griffe. The optimiser's source lives in the top-level
  optimize/ folder and installs as `tripodjax.optimize` (setuptools package-dir), a layout griffe
  cannot follow, so the hook stages `build/docs-src/tripodjax/` (links to tripodjax/* plus
  optimize/ as its `optimize` subpackage) and mkdocs.yml points mkdocstrings there.
- The CLI and spec reference is generated from the embedded default spec
  (`tripodjax.optimize.DEFAULT_SPEC_TOML`) and the commands' own `--help`, so it cannot drift.
- The physics page's map from the seed's equation numbers to the code is generated from the
  docstrings of the objects the API reference renders.
- The notebooks are rendered with their outputs: executed copies are taken from
  `$TRIPODJAX_NOTEBOOK_OUTPUTS` (default build/notebooks/; tests/test_notebooks.py can leave
  them there) when they are newer than the package sources and hold the same cells, and are
  executed here otherwise.
- The report page shows an example `optimize-joint` report (report.html, its screenshot, its
  A4 print, report.xlsx, validation.html and its A4 print): taken from
  `$TRIPODJAX_REPORT_EXAMPLE` (default build/report-example/; the browser
  test tests/test_report_html.py leaves them there) when newer than the package sources, and
  made here otherwise (the command on the default spec, then headless Chromium's --screenshot).
- The measured tables of the speed page (`<!-- bench:NAME -->`) are rendered from the benches'
  JSON committed in docs/bench/ (`python -m tripodjax.bench --json …`, `python -m
  tripodjax.optimize.bench --json …`), each under a line naming the CPU, date and versions it was
  measured with; a missing file or figure fails the build.
"""

from __future__ import annotations

import contextlib
import html
import importlib
import io
import itertools
import json
import logging
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

from mkdocs.plugins import event_priority
from mkdocs.structure.files import File

ROOT = Path(__file__).resolve().parent.parent
BUILD = ROOT / "build"
STAGED = BUILD / "docs-src"
NOTEBOOKS = ROOT / "notebooks"
log = logging.getLogger("mkdocs.hooks.tripodjax")

# Document the installed package (the repository root's tripodjax/ lacks tripodjax.optimize).
sys.path[:] = [p for p in sys.path if Path(p or os.curdir).resolve() != ROOT]


# ---------------------------------------------------------------------------------------------
# sources for griffe


def _stage_sources() -> None:
    target = STAGED / "tripodjax"
    if STAGED.exists():
        shutil.rmtree(STAGED)
    target.mkdir(parents=True)
    entries = [(p, target / p.name) for p in (ROOT / "tripodjax").iterdir()]
    entries.append((ROOT / "optimize", target / "optimize"))
    for source, link in entries:
        if source.name == "__pycache__" or link.exists():
            continue
        try:
            link.symlink_to(source, target_is_directory=source.is_dir())
        except OSError:  # no symlinks on this file system: copy
            (shutil.copytree if source.is_dir() else shutil.copy2)(source, link)


@event_priority(100)  # before mkdocstrings reads its handler's paths
def on_config(config):
    _stage_sources()
    return config


# ---------------------------------------------------------------------------------------------
# notebooks, rendered with their outputs


def _cells(notebook):
    return [(c["cell_type"], "".join(c["source"])) for c in notebook["cells"]]


def _executed(path: Path) -> Path:
    import nbformat

    outputs = Path(os.environ.get("TRIPODJAX_NOTEBOOK_OUTPUTS") or BUILD / "notebooks")
    executed = outputs / path.name
    sources = [*ROOT.glob("tripodjax/*.py"), *ROOT.glob("optimize/*.py"), path]
    newest = max(p.stat().st_mtime for p in sources)
    notebook = nbformat.read(path, as_version=4)
    if executed.is_file() and executed.stat().st_mtime >= newest:
        if _cells(nbformat.read(executed, as_version=4)) == _cells(notebook):
            log.info("notebook %s: executed copy %s", path.name, executed)
            return executed
    import nbclient

    log.info("notebook %s: executing (no fresh executed copy in %s)", path.name, outputs)
    env = os.environ.pop("MPLBACKEND", None)  # the kernel's inline backend draws the figures
    try:
        nbclient.NotebookClient(
            notebook,
            timeout=900,
            kernel_name="python3",
            resources={"metadata": {"path": str(path.parent)}},
        ).execute()
    finally:
        if env is not None:
            os.environ["MPLBACKEND"] = env
    outputs.mkdir(parents=True, exist_ok=True)
    nbformat.write(notebook, executed)
    return executed


@event_priority(100)  # before mkdocs-jupyter wraps the notebook files
def on_files(files, config):
    for path in sorted(NOTEBOOKS.glob("*.ipynb")):
        executed = _executed(path)
        # mkdocs-jupyter reads the notebook from disk: a copy under a src_dir of its own.
        copy = BUILD / "docs-notebooks" / "notebooks" / path.name
        copy.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(executed, copy)
        files.append(
            File(
                f"notebooks/{path.name}",
                src_dir=str(copy.parent.parent),
                dest_dir=config.site_dir,
                use_directory_urls=config.use_directory_urls,
            )
        )
    _add_report_example(files, config)
    return files


# ---------------------------------------------------------------------------------------------
# the example report

REPORT_FILES = (
    "report.html",
    "report.png",
    "report.pdf",
    "report.xlsx",
    "validation.html",
    "validation.pdf",
)
CHROMIUM = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")


def _report_example() -> Path:
    """A folder with a fresh example report.html (and report.png where Chromium is available)."""
    example = Path(os.environ.get("TRIPODJAX_REPORT_EXAMPLE") or BUILD / "report-example")
    sources = [*ROOT.glob("tripodjax/*.py"), *ROOT.glob("optimize/*.py")]
    sources += ROOT.glob("optimize/templates/*")
    newest = max(p.stat().st_mtime for p in sources)
    html, png = example / "report.html", example / "report.png"
    if all(p.is_file() and p.stat().st_mtime >= newest for p in (html, png)):
        log.info("report example: %s", example)
        return example
    log.info("report example: running optimize-joint (no fresh example in %s)", example)
    example.mkdir(parents=True, exist_ok=True)
    for name in REPORT_FILES:
        (example / name).unlink(missing_ok=True)
    command = [sys.executable, "-P", "-m", "tripodjax.optimize.cli"]
    subprocess.run([*command, "--out", str(example), "--progress", "off"], check=True)
    chromium = next((p for p in map(shutil.which, CHROMIUM) if p), None)
    if chromium is None:
        log.info("report example: no Chromium on PATH, so no screenshot")
        return example
    profile = BUILD / "chromium-profile"
    subprocess.run(
        [
            chromium,
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            f"--user-data-dir={profile}",
            "--window-size=1200,1500",
            f"--screenshot={png}",
            html.as_uri(),
        ],
        check=True,
        capture_output=True,
        timeout=120,
    )
    return example


def _add_report_example(files, config):
    example = _report_example()
    # A src_dir of its own, as for the notebooks: the files are copied into the site.
    staged = BUILD / "docs-report" / "report-example"
    if staged.exists():
        shutil.rmtree(staged)
    staged.mkdir(parents=True)
    for name in REPORT_FILES:
        if (example / name).is_file():
            shutil.copyfile(example / name, staged / name)
            files.append(
                File(
                    f"report-example/{name}",
                    src_dir=str(staged.parent),
                    dest_dir=config.site_dir,
                    use_directory_urls=config.use_directory_urls,
                )
            )


def report_example_markdown(files) -> str:
    have = {
        f.src_uri.removeprefix("report-example/")
        for f in files
        if f.src_uri.startswith("report-example/")
    }
    out = []
    if "report.png" in have:
        out.append(
            "[![The top of the example report: summary and requirements]"
            "(report-example/report.png)](report-example/report.html)"
        )
    else:
        out.append("*(No screenshot: the site was built without Chromium.)*")
    links = ["[the page itself](report-example/report.html)"]
    if "report.pdf" in have:
        links.append("[its A4 print](report-example/report.pdf)")
    if "report.xlsx" in have:
        links.append("[the workbook](report-example/report.xlsx)")
    if "validation.html" in have:
        links.append("[the validation document](report-example/validation.html)")
    if "validation.pdf" in have:
        links.append("[its print](report-example/validation.pdf)")
    out += ["", "Open " + ", ".join(links) + "."]
    return "\n".join(out)


# ---------------------------------------------------------------------------------------------
# the CLI and spec reference


def _split_comment(line: str) -> tuple[str, str]:
    """Split a TOML line at its comment (a `#` outside a string)."""
    quote = None
    for i, ch in enumerate(line):
        if quote:
            if ch == quote:
                quote = None
        elif ch in "\"'":
            quote = ch
        elif ch == "#":
            return line[:i].rstrip(), line[i + 1 :].strip()
    return line.rstrip(), ""


_UNIT = re.compile(r"\[([^\[\]]{1,16})\]")
_KEY = re.compile(r"^([A-Za-z_][A-Za-z0-9_]*)\s*=\s*(.*)$")
_EXAMPLE = re.compile(r"^#\s{2,}\S")  # "#   R = { … }": an example of a section's notes
_SAME_UNIT = {"deg": "°"}  # a comment's unit → the unit of its key's range (spec.RANGES)


def spec_entries(text: str):
    """Sections of a spec TOML as (section, notes, rows); rows are (key, default, unit, meaning,
    optional), notes the section's comment lines (an indented example line, ``#   x = …``, keeps
    four spaces of indentation).

    A commented-out assignment (`# key = value  # meaning`) is an optional key, not set by
    default. A comment line indented under a key's line continues that key's comment. The unit
    is the one in the key's comment (``[mm]``), "–" for none; `spec_reference_markdown` checks
    it against the key's range.
    """
    sections = []
    notes: list[str] = []
    rows: list[list] = []
    section = None
    last = None  # the row an indented comment line continues
    lines = iter(text.splitlines())
    for raw in lines:
        line = raw.strip()
        if not line:
            last = None
            continue
        header = re.match(r"^\[([^\[\]]+)\]\s*(#.*)?$", line)
        if header:
            if section is not None or rows or notes:
                sections.append((section, notes, rows))
            section, notes, rows, last = header.group(1).strip(), [], [], None
            continue
        optional = False
        if line.startswith("#"):
            body = line[1:].strip()
            if raw[:1].isspace() and last is not None:  # the comment of the row above, continued
                last[3] = f"{last[3]} {body}"
                continue
            if _EXAMPLE.match(line):
                notes.append("    " + body)
                last = None
                continue
            if _KEY.match(body) and section is not None:
                line, optional = body, True
            else:
                notes.append(body)
                last = None
                continue
        code, comment = _split_comment(line)
        match = _KEY.match(code)
        if not match:
            raise ValueError(f"unexpected line in the spec: {raw!r}")
        key, value = match.groups()
        while value.count("[") > value.count("]"):  # a multi-line array
            more, extra = _split_comment(next(lines).strip())
            value += " " + more
            comment = " ".join(c for c in (comment, extra) if c)
        last = [key, value, None, comment, optional]
        rows.append(last)
    sections.append((section, notes, rows))
    out = []
    for section, notes, rows in sections:
        entries = []
        for key, value, _, comment, optional in rows:
            unit = _UNIT.search(comment)
            meaning = _UNIT.sub("", comment, count=1) if unit else comment
            meaning = re.sub(r"\s+", " ", meaning).strip(" ,;")
            if optional:
                value = f"not set (e.g. `{value}`)"
                meaning = f"optional: {meaning}" if meaning else "optional"
            else:
                value = f"`{value}`"
            entries.append((key, value, unit.group(1) if unit else "–", meaning, optional))
        out.append((section, notes, entries))
    return out


def _leaves_with_values(table, prefix=()):
    for key, value in table.items():
        if isinstance(value, dict):
            yield from _leaves_with_values(value, (*prefix, key))
        else:
            yield ".".join((*prefix, key)), value


def _is_number(value):
    if isinstance(value, list):
        return bool(value) and all(_is_number(v) for v in value)
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _text(markdown: str) -> str:
    """A comment's text as Markdown that shows it: ``<q>`` stays ``<q>``, not an HTML tag."""
    return html.escape(markdown, quote=False).replace("|", "\\|")


def _notes_markdown(notes: list[str]) -> list[str]:
    """A section's notes: prose lines as one paragraph each run, example lines as TOML code."""
    out: list[str] = []
    for example, group in itertools.groupby(notes, key=lambda n: n.startswith("    ")):
        group = list(group)
        if example:
            out += ["```toml", *(n[4:] for n in group), "```", ""]
        else:
            out += [_text(" ".join(group)), ""]
    return out


def spec_reference_markdown(text: str) -> str:
    try:
        import tomllib
    except ModuleNotFoundError:  # Python 3.10
        import tomli as tomllib

    from tripodjax.optimize.spec import accepted_keys, allowed_text, unit_text

    sections = spec_entries(text)
    listed = {f"{s}.{r[0]}" for s, _, rows in sections for r in rows if not r[4]}
    parsed = {k for k, _ in _leaves_with_values(tomllib.loads(text))}
    if listed != parsed:
        raise ValueError(
            f"spec reference out of step with DEFAULT_SPEC_TOML: {sorted(listed ^ parsed)}"
        )
    names = [s for s, _, _ in sections if s is not None]
    for section, _, rows in sections:  # a row for every key a section accepts (spec.py)
        accepted = section and accepted_keys(tuple(section.split(".")))
        if accepted:
            tables = {s.rpartition(".")[2] for s in names if s.rpartition(".")[0] == section}
            shown = {r[0] for r in rows} | tables
            if shown != set(accepted):
                raise ValueError(
                    f"spec reference: [{section}] accepts {sorted(accepted)}, rows for "
                    f"{sorted(shown)} (a key the default leaves out: a commented-out line)"
                )
    numbers = {k for k, v in _leaves_with_values(tomllib.loads(text)) if _is_number(v)}
    unranged = sorted(k for k in numbers if allowed_text(k) is None)
    if unranged:  # every number of the spec has its range in spec.RANGES
        raise ValueError(f"spec reference: no allowed range for {unranged} (spec.RANGES)")
    out = []
    for section, notes, rows in sections:
        if section is None:
            out += _notes_markdown(notes)
            continue
        out += [f"### `[{section}]`", ""]
        out += _notes_markdown(notes)
        if rows:
            out += [
                "| key | default | unit | allowed | meaning |",
                "| --- | --- | --- | --- | --- |",
            ]
            for key, value, written, meaning, _ in rows:
                unit = unit_text(f"{section}.{key}")  # its range's, as the allowed column's
                if written != "–" and _SAME_UNIT.get(written, written) != unit:
                    raise ValueError(
                        f"spec reference: {section}.{key}'s comment says [{written}], its unit "
                        f"is {unit} (spec.unit_text)"
                    )
                allowed = allowed_text(f"{section}.{key}") or "–"
                cells = [value.replace("|", "\\|"), unit, allowed, _text(meaning)]
                out.append(f"| `{key}` | " + " | ".join(cells) + " |")
            out.append("")
    return "\n".join(out)


def _help(module: str, *args: str) -> str:
    """A command's ``--help`` (after ``args``, e.g. a mode's flag) as a text block."""
    main = importlib.import_module(module).main
    buffer = io.StringIO()
    columns = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = "96"
    try:
        with contextlib.redirect_stdout(buffer), contextlib.suppress(SystemExit):
            main([*args, "--help"])
    finally:
        if columns is None:
            os.environ.pop("COLUMNS")
        else:
            os.environ["COLUMNS"] = columns
    return f"```text\n{buffer.getvalue().rstrip()}\n```"


# ---------------------------------------------------------------------------------------------
# the seed's equation numbers → the code

_REFERENCE = re.compile(
    r"(?:§\s?\d+(?:\.\d+)*"
    r"|\b(?:[Tt]able|[Ff]igures?|[Ff]ig\.)\s\d+\.\d+(?:\.\d+)?"
    r"|(?<![\d.])\d\.\d{1,2}\.\d{1,2}(?:[–-]\d\.\d{1,2}\.\d{1,2})?(?![\d.]))"
)


def _sort_key(reference: str):
    kind = 0 if reference[0].isdigit() else 1 if reference.startswith("§") else 2
    numbers = [int(n) for n in re.findall(r"\d+", reference.split("–")[0])]
    return (numbers, kind, reference)


def _documented_identifiers(config) -> list[str]:
    docs = Path(config.docs_dir)
    found = []
    for page in sorted(docs.rglob("*.md")):
        found += re.findall(r"^::: ([\w.]+)", page.read_text(encoding="utf-8"), flags=re.M)
    return found


def equation_map_markdown(config) -> str:
    import griffe

    package = griffe.load(
        "tripodjax", search_paths=[str(STAGED)], try_relative_path=False, resolve_aliases=False
    )
    rendered = _documented_identifiers(config)
    where: dict[str, set[str]] = {}

    def visit(obj, depth):
        if obj.is_alias or obj.name.startswith("_") and depth:
            return
        if obj.docstring:
            for reference in _REFERENCE.findall(obj.docstring.value):
                reference = reference.replace("§ ", "§").replace("-", "–")
                reference = re.sub(r"^(fig\.|figures?)", "Figure", reference, flags=re.I)
                reference = re.sub(r"^table", "Table", reference)
                where.setdefault(reference, set()).add(obj.path)
        if obj.is_module or obj.is_class:
            for member in obj.members.values():
                if not member.is_alias and (obj.is_class or not member.is_module):
                    visit(member, depth + 1)

    for identifier in rendered:
        obj = package if identifier == "tripodjax" else package[identifier.split(".", 1)[1]]
        if not obj.is_module:
            continue
        visit(obj, 0)
    out = [
        "| seed | where it is used (function, class or module docstring) |",
        "| --- | --- |",
    ]
    for reference in sorted(where, key=_sort_key):
        links = ", ".join(
            f"[`{p.removeprefix('tripodjax.')}`][{p}]" for p in sorted(where[reference])
        )
        out.append(f"| {reference} | {links} |")
    return "\n".join(out)


# ---------------------------------------------------------------------------------------------
# the benches' tables

BENCH = ROOT / "docs" / "bench"
SWEEP_BENCH = "tripodjax-bench.json"
OPTIMISER_BENCH = "optimize-bench.json"
LATENCY_BENCH = "tripodjax-latency.json"
# Issue 33's targets for each first answer, as multiples of the floor of the same run.
LATENCY_TARGETS = {
    "readme": "≤ 2",
    "solve": "≤ 4",
    "solve_l_gamma0": "≤ 4",
    "solve_conformity": "≤ 4",
    "solve_chance": "≤ 8",
    "command_cold": "≤ 6",
    "command_warm": "≤ 2",
}
COMPARED = ("delta_pp", "irregularity", "gamma_pp", "ecc_max")


def _g(x: float, digits: int = 3) -> str:
    """A figure to ``digits`` significant digits (``1.46e+07``, ``24.9``)."""
    return f"{x:.{digits}g}"


def _n(x: float) -> str:
    """A time or ratio: 3 significant digits, no exponent (``1499``, ``24.9``, ``0.0079``)."""
    return f"{x:.0f}" if abs(x) >= 1000 else _g(x)


def _e(x: float) -> str:
    return "0" if x == 0 else f"{x:.1e}"


def _table(head: list[str], rows: list[list[str]], right: int = 1) -> list[str]:
    """A Markdown table; columns from ``right`` on are right-aligned."""
    align = ["---" if i < right else "---:" for i in range(len(head))]
    return [
        "| " + " | ".join(head) + " |",
        "| " + " | ".join(align) + " |",
        *("| " + " | ".join(row) + " |" for row in rows),
    ]


def measured_on_markdown(name: str, command: str, machine: dict) -> str:
    """The line under a bench table: which command, on which CPU, when, with what."""
    load = machine.get("load_average")
    load = f", load average {load[0]:g}" if load else ""
    return (
        f"*Measured by `{command}` on {machine['cpu']} ({machine['cpu_count']} cores{load}), "
        f"{machine['date']}; JAX {machine['jax']} ({machine['backend']}), tripodjax "
        f"{machine['tripodjax']}, Python {machine['python']}. "
        f"Figures: [docs/bench/{name}](bench/{name}).*"
    )


def sweep_tables(figures: dict) -> dict[str, list[str]]:
    """The tables of ``python -m tripodjax.bench``'s JSON, by marker name."""
    variants = figures["variants"]
    numpy_rate = figures["numpy_newton"]["points_per_s"]
    fsolve = figures["fsolve_loop"]
    peers = [
        ("NumPy Newton (peer)", figures["numpy_newton"]),
        (f"SciPy fsolve loop (peer, {fsolve['layouts']} layouts)", fsolve),
    ]
    rows = []
    for name, entry in [*((n.replace("/", " / "), v) for n, v in variants.items()), *peers]:
        rate = entry["points_per_s"]
        speedup = entry.get("speedup_vs_newton_same_dtype")
        errors = entry["errors_vs_newton_float64"]
        rows.append(
            [
                name,
                _g(rate),
                "" if speedup is None else _g(speedup),
                _g(rate / numpy_rate),
                _n(rate / fsolve["points_per_s"]),
                *(_e(errors[k]) for k in COMPARED),
            ]
        )
    head = ["variant", "angles/s", "× newton", "× NumPy", "× fsolve"]
    tables = {"sweep": _table([*head, *(f"error {k}" for k in COMPARED)], rows)}
    tables["sweep"].insert(
        0,
        f"{figures['n_layouts']} layouts × {figures['n_theta']} angles "
        f"({figures['angles_solved_per_layout']} solved per layout, the rest by symmetry):",
    )
    tables["sweep"].insert(1, "")
    domain = [
        [
            name.replace("/", " / "),
            *(_e(v["domain_errors_vs_newton_float64"][k]) for k in COMPARED),
            _e(v["domain_max_error_estimate"]),
        ]
        for name, v in variants.items()
    ]
    tables["domain"] = [
        f"{figures['domain_layouts']} layouts:",
        "",
        *_table(["variant", *COMPARED, "largest error estimate"], domain),
    ]
    t, g = figures["machine_limit"], figures["gradient_to_forward"]
    limit = [
        ["one polynomial Newton step", f"{_g(t['polynomial_steps_per_s'])} angles/s"],
        [
            "steps per solved angle",
            f"{t['steps_per_solved_angle']} ({t['polynomial_iterations']} polynomial steps, "
            f"{t['exact_iterations']} exact-sine iterations, and the Jacobian solve for dψ/dθ)",
        ],
        ["the limit for newton", f"{_g(t['limit_points_per_s'])} angles/s"],
        [
            "newton / float64 reaches",
            f"{100 * t['newton_fraction_of_limit']:.0f} % of it (the status, the metrics and "
            "the chunking are the rest)",
        ],
        [
            "XLA's float64 sine",
            f"{_g(t['sines_per_s'])}/s: the 8 transcendental functions per angle of the previous "
            f"solver would cap a sweep at "
            f"{_g(t['sines_per_s'] / 8)} angles/s",
        ],
        [
            f"gradient of the irregularity w.r.t. (R, l, γ0), {g['layouts']} layouts",
            f"{g['ratio']:.1f}× the forward pass",
        ],
    ]
    tables["limit"] = _table(["what", "measured"], limit, right=2)
    costs = figures["output_costs"]
    levels = [level for level in ("newton", "analytic", "closed_form") if level in costs]
    head = ["output"]
    for level in levels:
        head += [f"{level} ms", "share"]
    default = {level: costs[level]["default"] for level in levels}
    rows = [["default outputs", *[c for level in levels for c in (_n(1e3 * default[level]), "1")]]]
    for name in costs[levels[0]]["outputs"]:
        mark = "\\* " if name in costs["default_outputs"] else ""
        cells = []
        for level in levels:
            seconds = costs[level]["outputs"][name]
            cells += [_n(1e3 * seconds), f"{seconds / default[level]:.2f}"]
        rows.append([mark + name, *cells])
    ratios = "; ".join(
        f"`{level}` {default['newton'] / default[level]:.1f}× newton"
        for level in levels
        if level != "newton"
    )
    tables["output-costs"] = [
        f"{costs['layouts']} layouts × {figures['n_theta']} angles:",
        "",
        *_table(head, rows),
        "",
        f"With the default outputs in this table: {ratios}.",
    ]
    return tables


def optimiser_tables(figures: dict, default_solver: tuple[str, int]) -> dict[str, list[str]]:
    """The tables of ``python -m tripodjax.optimize.bench``'s JSON, by marker name."""
    tables: dict[str, list[str]] = {}
    rows = []
    command = figures.get("command")
    if command:
        floor = command["floor_s"]
        rows += [
            ['floor: `python -c "import jax, matplotlib.pyplot"`', f"{floor:.2f} s", "1"],
            [
                "`optimize-joint --out DIR`, cold (empty caches)",
                f"{command['cold_s']:.1f} s",
                f"{command['cold_over_floor']:.1f}× floor",
            ],
            [
                "`optimize-joint --out DIR`, warm (compiled code cached)",
                f"{command['warm_s']:.1f} s",
                f"{command['warm_over_floor']:.1f}× floor",
            ],
        ]
    free = figures.get("command_conformity_free")
    if free:
        for state in ("cold", "warm"):
            rows.append(
                [
                    f"the same with the conformity free, {state} (floor {free['floor_s']:.2f} s)",
                    f"{free[f'{state}_s']:.1f} s",
                    f"{free[f'{state}_over_floor']:.1f}× floor",
                ]
            )
    r = figures["resolve"]
    rows += [
        [
            "`solve` of a spec that differs in the adhesion and P_d, after one `solve`",
            f"{1e3 * r['resolve_s']:.0f} ms",
            f"{r['resolve_over_slsqp']:.2f}× SLSQP",
        ],
        [
            "SciPy SLSQP over `evaluate`, finite-difference gradients (peer)",
            f"{1e3 * r['slsqp_s']:.0f} ms",
            "1",
        ],
    ]
    s = figures["long_spectrum"]
    rows += [
        [
            f"{s['cases']}-case life spectrum: first `solve` (trace, compile, run)",
            f"{s['first_solve_s']:.1f} s",
            "1",
        ],
        [
            f"its `sensitivities`, {s['inputs']} inputs (one reverse pass compiled and run)",
            f"{s['sensitivities_s']:.1f} s",
            f"{s['sensitivities_over_solve']:.2f}× its solve",
        ],
    ]
    if "command_cold_s" in s:
        rows.append(
            [
                f"`optimize-joint` on it, cold (floor {s['floor_s']:.2f} s in that call)",
                f"{s['command_cold_s']:.1f} s",
                f"{s['command_cold_over_floor']:.1f}× floor",
            ]
        )
    w = figures["report"]
    rows += [
        [
            "warm `optimize-joint` with report.html and report.xlsx, against without them",
            f"{w['command_s']:.1f} s",
            f"{w['command_added_s']:+.2f} s",
        ],
        [
            "in one process: writing report.json and the PNGs",
            f"{w['json_png_s']:.2f} s",
            "1",
        ],
        [
            "… and report.html and report.xlsx as well (with their imports the first time)",
            f"{w['json_png_s'] + w['added_s']:.2f} s",
            f"{w['added_s']:+.2f} s ({w['added_cold_s']:+.2f} s)",
        ],
    ]
    tables["optimiser"] = [
        *_table(["what", "time", "ratio"], rows),
        "",
        f"The re-solve and the SLSQP peer's designs are {_e(r['design_distance_rel'])} apart "
        f"(relative); the first `solve` in that process took {r['first_solve_s']:.1f} s.",
    ]
    rows = [
        [
            row["structure"],
            f"{row['first_solve_s']:.1f}",
            f"{1e3 * row['solve_s']:.1f}",
            "yes" if row["converged"] else "**no**",
        ]
        for row in figures["structures"]
    ]
    tables["structures"] = _table(
        ["free variables", "first solve [s]", "re-solve [ms]", "converged"], rows
    )
    rows = []
    for row in figures["fidelity"]:
        cells = [
            row["fidelity"],
            str(row["n_theta"]),
            f"{row['first_solve_s']:.1f}",
            f"{1e3 * row['solve_s']:.1f}",
            _e(row["design_distance_rel"]),
            _e(row["objective_distance_rel"]),
        ]
        if (row["fidelity"], row["n_theta"]) == default_solver:
            cells = [f"**{c}**" for c in cells]
        rows.append(cells)
    tables["fidelity"] = _table(
        [
            "fidelity",
            "n_theta",
            "first solve [s]",
            "re-solve [ms]",
            "design vs newton/360",
            "objective vs newton/360",
        ],
        rows,
    )
    m = figures["monte_carlo"]
    tables["monte-carlo"] = _table(
        ["chain", "per second", "ratio"],
        [
            [
                "Hertz + life (the default spec's requirements)",
                f"{_g(m['hertz_life_samples_per_s'])} samples",
                "",
            ],
            [
                "analytic kinematics (n_theta 168) + Hertz + life",
                f"{_g(m['kinematics_hertz_life_samples_per_s'])} samples",
                f"{m['kinematic_mc_over_sweep']:.2f}× the sweep",
            ],
            [
                "plain `sweep`, analytic, n_theta 168 (peer)",
                f"{_g(m['sweep_layouts_per_s'])} layouts",
                "1",
            ],
        ],
    )
    return tables


def latency_tables(figures: dict) -> dict[str, list[str]]:
    """The tables of ``python -m tripodjax.bench --latency``'s JSON, by marker name."""
    rows = []
    for name, e in figures["entries"].items():
        largest = max(e["programs"], key=lambda p: p["compile_s"], default=None)
        program = (
            f"`{largest['name']}`, {largest['compile_s']:.1f} s, {largest['kb']:.0f} kB"
            if largest
            else "–"
        )
        rows.append(
            [
                e["what"],
                f"{e['wall_s']:.1f}",
                f"{e['over_floor']:.1f}",
                f"{e['import_s']:.1f}",
                f"{e['trace_s']:.1f}",
                f"{e['lower_s']:.1f}",
                f"{e['compile_s']:.1f}",
                f"{e['run_s']:.1f}",
                str(len(e["programs"])),
                program,
                LATENCY_TARGETS.get(name, "–"),
            ]
        )
    floors = figures["floors"]
    tables = {
        "latency": [
            *_table(
                [
                    "first answer",
                    "wall s",
                    "× floor",
                    "import s",
                    "trace s",
                    "lowering s",
                    "compile s",
                    "run s",
                    "programs",
                    "longest compile (s, StableHLO kB)",
                    "target × floor",
                ],
                rows,
            ),
            "",
            f"Floors of the same run: `import jax, tripodjax` {floors['library_s']:.2f} s, "
            f"`import jax, matplotlib.pyplot` (the command's) {floors['command_s']:.2f} s; "
            f"medians of {figures['repeats']} run(s).",
        ]
    }
    gradient = figures.get("gradient_to_forward") or []
    tables["gradient"] = _table(
        ["layouts", "forward s", "gradient s", "gradient / forward"],
        [
            [str(g["layouts"]), _e(g["forward_s"]), _e(g["gradient_s"]), f"{g['ratio']:.2f}"]
            for g in gradient
        ],
        right=0,
    )
    return tables


def bench_markdown(markdown: str) -> str:
    """Replace each ``<!-- bench:NAME -->`` with its table from docs/bench/ and its provenance."""
    markers = set(re.findall(r"<!-- bench:([\w-]+) -->", markdown))
    if not markers:
        return markdown
    import tomllib

    from tripodjax.optimize import DEFAULT_SPEC_TOML

    solver = tomllib.loads(DEFAULT_SPEC_TOML)["solver"]
    sources = {
        SWEEP_BENCH: ("python -m tripodjax.bench", sweep_tables),
        OPTIMISER_BENCH: (
            "python -m tripodjax.optimize.bench",
            lambda f: optimiser_tables(f, (solver["fidelity"], solver["n_theta"])),
        ),
        LATENCY_BENCH: ("python -m tripodjax.bench --latency", latency_tables),
    }
    for name, (command, render) in sources.items():
        figures = json.loads((BENCH / name).read_text(encoding="utf-8"))
        caption = measured_on_markdown(name, command, figures["measured_on"])
        for marker, lines in render(figures).items():
            if marker in markers:
                markers.discard(marker)
                block = "\n".join([*lines, "", caption])
                markdown = markdown.replace(f"<!-- bench:{marker} -->", block)
    if markers:
        raise ValueError(f"no bench table named {sorted(markers)} (docs/hooks.py)")
    return markdown


# ---------------------------------------------------------------------------------------------


# ``<!-- help MODULE ARGS -->`` markers: the command's ``--help`` after ARGS.
HELP_MARKERS = (
    ("tripodjax.optimize.cli", ()),
    ("tripodjax.optimize.compare", ()),
    ("tripodjax.__main__", ()),
    ("tripodjax.bench", ()),
    ("tripodjax.bench", ("--latency",)),
)


def on_page_markdown(markdown, page, config, files):
    if "<!-- spec-reference -->" in markdown:
        from tripodjax.optimize import DEFAULT_SPEC_TOML

        markdown = markdown.replace(
            "<!-- spec-reference -->", spec_reference_markdown(DEFAULT_SPEC_TOML)
        )
    for module, args in HELP_MARKERS:
        marker = f"<!-- help {' '.join((module, *args))} -->"
        if marker in markdown:
            markdown = markdown.replace(marker, _help(module, *args))
    if "<!-- report-example -->" in markdown:
        markdown = markdown.replace("<!-- report-example -->", report_example_markdown(files))
    if "<!-- equation-map -->" in markdown:
        markdown = markdown.replace("<!-- equation-map -->", equation_map_markdown(config))
    return bench_markdown(markdown)
