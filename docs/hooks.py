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
  A4 print and report.xlsx): taken from `$TRIPODJAX_REPORT_EXAMPLE` (default build/report-example/; the browser
  test tests/test_report_html.py leaves them there) when newer than the package sources, and
  made here otherwise (the command on the default spec, then headless Chromium's --screenshot).
"""

from __future__ import annotations

import contextlib
import importlib
import io
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

REPORT_FILES = ("report.html", "report.png", "report.pdf", "report.xlsx")
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


def spec_entries(text: str):
    """Sections of a spec TOML as (section, notes, rows); rows are (key, default, unit, meaning).

    A commented-out assignment (`# key = value  # meaning`) is an optional key, not set by default.
    """
    sections = []
    notes, rows = [], []
    section = None
    lines = iter(text.splitlines())
    for raw in lines:
        line = raw.strip()
        if not line:
            continue
        header = re.match(r"^\[([^\[\]]+)\]\s*(#.*)?$", line)
        if header:
            if section is not None or rows or notes:
                sections.append((section, notes, rows))
            section, notes, rows = header.group(1).strip(), [], []
            continue
        optional = False
        if line.startswith("#"):
            body = line.lstrip("#").strip()
            if _KEY.match(body) and section is not None:
                line, optional = body, True
            else:
                notes.append(body)
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
        unit = _UNIT.search(comment)
        meaning = _UNIT.sub("", comment, count=1).strip() if unit else comment
        meaning = re.sub(r"\s+", " ", meaning).strip(" ,;")
        if unit:
            unit = unit.group(1)
        elif key.endswith("_deg"):
            unit = "deg"
        else:
            unit = "–"
        if optional:
            value = f"not set (e.g. `{value}`)"
            meaning = f"optional: {meaning}" if meaning else "optional"
        else:
            value = f"`{value}`"
        rows.append((key, value, unit, meaning, optional))
    sections.append((section, notes, rows))
    return sections


def _leaves(table, prefix=()):
    for key, value in table.items():
        if isinstance(value, dict):
            yield from _leaves(value, (*prefix, key))
        else:
            yield ".".join((*prefix, key))


def spec_reference_markdown(text: str) -> str:
    try:
        import tomllib
    except ModuleNotFoundError:  # Python 3.10
        import tomli as tomllib

    sections = spec_entries(text)
    listed = {f"{s}.{r[0]}" for s, _, rows in sections for r in rows if not r[4]}
    parsed = set(_leaves(tomllib.loads(text)))
    if listed != parsed:
        raise ValueError(
            f"spec reference out of step with DEFAULT_SPEC_TOML: {sorted(listed ^ parsed)}"
        )
    out = []
    for section, notes, rows in sections:
        if section is None:
            out += [" ".join(notes), ""]
            continue
        out += [f"### `[{section}]`", ""]
        if notes:
            out += [" ".join(notes), ""]
        if rows:
            out += ["| key | default | unit | meaning |", "| --- | --- | --- | --- |"]
            for key, value, unit, meaning, _ in rows:
                cells = [c.replace("|", "\\|") for c in (value, unit, meaning)]
                out.append(f"| `{key}` | " + " | ".join(cells) + " |")
            out.append("")
    return "\n".join(out)


def _help(module: str) -> str:
    main = importlib.import_module(module).main
    buffer = io.StringIO()
    columns = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = "96"
    try:
        with contextlib.redirect_stdout(buffer), contextlib.suppress(SystemExit):
            main(["--help"])
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


def on_page_markdown(markdown, page, config, files):
    if "<!-- spec-reference -->" in markdown:
        from tripodjax.optimize import DEFAULT_SPEC_TOML

        markdown = markdown.replace(
            "<!-- spec-reference -->", spec_reference_markdown(DEFAULT_SPEC_TOML)
        )
    modules = ("tripodjax.optimize.cli", "tripodjax.optimize.compare")
    for module in (*modules, "tripodjax.__main__", "tripodjax.bench"):
        marker = f"<!-- help {module} -->"
        if marker in markdown:
            markdown = markdown.replace(marker, _help(module))
    if "<!-- report-example -->" in markdown:
        markdown = markdown.replace("<!-- report-example -->", report_example_markdown(files))
    if "<!-- equation-map -->" in markdown:
        markdown = markdown.replace("<!-- equation-map -->", equation_map_markdown(config))
    return markdown
