"""Every ```python block of README.md and docs/*.md runs.

The blocks of one file run in order in one namespace, in a fresh interpreter (JAX's default
float32 configuration, as a reader has it; not the suite's float64) whose working directory is a
temporary folder, so that a snippet that writes files leaves nothing behind. A failure names the
file and the line of the snippet.
"""

import json
import os
import pathlib
import re
import subprocess
import sys
import textwrap

import pytest

ROOT = pathlib.Path(__file__).resolve().parent.parent
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("**/*.md"))]
FENCE = re.compile(
    r"^(?P<indent>[ \t]*)```+\s*python[^\n]*\n(?P<code>.*?)^(?P=indent)```+\s*$", re.M | re.S
)

RUNNER = """
import json, sys
blocks = json.loads(sys.argv[1])
namespace = {"__name__": "__main__"}
for name, line, code in blocks:
    # Pad so that a traceback's line numbers are those of the Markdown file.
    exec(compile("\\n" * (line - 1) + code, name, "exec"), namespace)
"""


JAX_CACHE = ("JAX_COMPILATION_CACHE_DIR", "JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS")


def python_blocks(path):
    """(first line, code) of each ```python block of a Markdown file."""
    text = path.read_text(encoding="utf-8")
    return [
        (text.count("\n", 0, m.start("code")) + 1, textwrap.dedent(m.group("code")))
        for m in FENCE.finditer(text)
    ]


def test_the_readme_has_snippets():
    assert python_blocks(ROOT / "README.md")


@pytest.mark.parametrize(
    "path",
    [p for p in PAGES if python_blocks(p)],
    ids=lambda p: str(p.relative_to(ROOT)),
)
def test_snippets_run(path, tmp_path):
    name = str(path.relative_to(ROOT))
    blocks = [(name, line, code) for line, code in python_blocks(path)]
    # A reader's JAX configuration; only the run's compilation cache is kept (it changes no result).
    env = {k: v for k, v in os.environ.items() if not k.startswith("JAX_") or k in JAX_CACHE}
    env["MPLBACKEND"] = "Agg"
    env["TRIPODJAX_CACHE_DIR"] = str(tmp_path / "cache")
    done = subprocess.run(
        [sys.executable, "-c", RUNNER, json.dumps(blocks)],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode == 0, f"a snippet of {name} failed:\n{done.stderr[-4000:]}"


def _section(text, name):
    """The text between a README's ``--8<-- [start:name]`` and ``[end:name]`` markers."""
    start = text.index(f"<!-- --8<-- [start:{name}] -->")
    return text[start : text.index(f"<!-- --8<-- [end:{name}] -->", start)]


NUMBER = re.compile(r"\d+(?:\.\d+)?")


def test_the_setup_paragraph_quotes_only_figures_of_the_latency_table():
    """Every figure of the set-up paragraph is one that the optimiser bench put in its table."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    setup = FENCE.sub("", re.sub(r"```.*?```", "", _section(text, "setup"), flags=re.S))
    setup = re.sub(r"<!--.*?-->", "", setup)
    prose = re.sub(r"Python ≥ \d+\.\d+|\d+-core", "", setup)  # a requirement, a machine
    prose = re.sub(r"`[^`]*`", "", prose)  # commands, paths and options
    table = "\n".join(
        line for line in _section(text, "optimiser-speed").splitlines() if line.startswith("|")
    )
    measured = set(NUMBER.findall(table))
    quoted = NUMBER.findall(prose)
    assert quoted, "the set-up paragraph states no timing"
    assert set(quoted) <= measured, f"figures not in the latency table: {set(quoted) - measured}"
    # A duration in words ("about a minute") is a figure no bench measured.
    assert not re.search(r"\b(minutes?|hours?|seconds)\b", prose), prose
