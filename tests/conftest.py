"""Test configuration: the suite runs with float64 available.

Enabling x64 here is the test suite's choice (float32 is still tested by
passing float32 inputs or inside ``jax.enable_x64(False)``); the library
itself never changes JAX's configuration.
"""

import contextlib
import json
import os
import pathlib
import shutil
import subprocess
import sys
import tempfile

import jax
import pytest

try:
    import fcntl
except ImportError:  # not POSIX: each worker makes the run-wide results itself
    fcntl = None

# Test the installed package, not the source folders: `python -m pytest` puts the repository
# root first on sys.path, where tripodjax/ lacks the optimiser (installed as tripodjax.optimize
# from the top-level optimize/ folder).
_ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path[:] = [p for p in sys.path if os.path.abspath(p or os.curdir) != _ROOT]
for _name in [m for m in sys.modules if m == "tripodjax" or m.startswith("tripodjax.")]:
    del sys.modules[_name]

jax.config.update("jax_enable_x64", True)

_JAX_CACHE = "JAX_COMPILATION_CACHE_DIR"
_JAX_CACHE_MIN_SECONDS = "JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS"
_cache_key = pytest.StashKey[str]()
_COMMAND_CACHE = "TRIPODJAX_CACHE_DIR"
_command_cache_key = pytest.StashKey[str]()


def pytest_configure(config):
    """One persistent compilation cache for the run: the xdist workers, the notebooks' kernels
    and the Python subprocesses compile a program another process compiled once (the
    controller makes it before the workers start; they inherit it). Likewise one cache of
    `optimize-joint` (TRIPODJAX_CACHE_DIR) for the run, out of the user's home: every run of
    the command with a structure that one ran before loads its programs."""
    if not hasattr(config, "workerinput"):
        if _JAX_CACHE not in os.environ:
            config.stash[_cache_key] = os.environ[_JAX_CACHE] = tempfile.mkdtemp(
                prefix="tripodjax-tests-jax-cache-"
            )
            os.environ[_JAX_CACHE_MIN_SECONDS] = "0.2"
        config.stash[_command_cache_key] = os.environ[_COMMAND_CACHE] = tempfile.mkdtemp(
            prefix="tripodjax-tests-command-cache-"
        )
    if _JAX_CACHE in os.environ:
        jax.config.update("jax_compilation_cache_dir", os.environ[_JAX_CACHE])
        seconds = float(os.environ.get(_JAX_CACHE_MIN_SECONDS, 1.0))
        jax.config.update("jax_persistent_cache_min_compile_time_secs", seconds)


def pytest_unconfigure(config):
    for key, names in (
        (_cache_key, (_JAX_CACHE, _JAX_CACHE_MIN_SECONDS)),
        (_command_cache_key, (_COMMAND_CACHE,)),
    ):
        directory = config.stash.get(key, None)
        if directory:
            shutil.rmtree(directory, ignore_errors=True)
            for name in names:
                os.environ.pop(name, None)


def pytest_collection_modifyitems(config, items):
    """The notebooks first, then test_reliability.py: the modules of the longest tests (a kernel
    each and its compiles; the chance-constrained solves), so that none of them starts last
    and leaves one worker alone at the end (measured on 2 cores: the suite 692 s → 626 s, the
    two workers finishing 14 s apart instead of 44 s, when test_reliability.py came last but
    two). And where notebook 08 finishes before test_reliability.py's chance-constraint test
    starts, that test finds the chance-constrained solve in the run's compilation cache
    (measured 32 s then, 76–94 s when both compile it at once). Every worker collects the same
    order, as pytest-xdist requires."""
    first = ("test_notebooks.py", "test_reliability.py")

    def rank(item):
        return first.index(item.path.name) if item.path.name in first else len(first)

    items.sort(key=rank)


@pytest.fixture
def float32_default():
    """Run the body with JAX's default float32 configuration."""
    with jax.enable_x64(False):
        yield


@contextlib.contextmanager
def _run_wide(tmp_path_factory, name):
    """A folder shared by the run's processes (pytest-xdist's workers), held exclusively in the
    block: the first worker makes what it holds, the others wait and find it made. Without
    file locks (not POSIX) each worker has a folder of its own."""
    root = tmp_path_factory.getbasetemp()
    if "PYTEST_XDIST_WORKER" in os.environ and fcntl is not None:
        root = root.parent  # the workers' base folders sit in the run's
    folder = root / name
    folder.mkdir(exist_ok=True)
    with open(root / f"{name}.lock", "w") as lock:
        if fcntl is not None:
            fcntl.flock(lock, fcntl.LOCK_EX)
        yield folder


@pytest.fixture(scope="session")
def default_report(tmp_path_factory):
    """``optimize-joint --out DIR --progress off`` (the default spec), run once for the whole
    run: ``(completed process, DIR)``. Read only: a test that changes a report writes its own."""
    from command import run_cli

    with _run_wide(tmp_path_factory, "default-report") as folder:
        out, record = folder / "out", folder / "process.json"
        if not record.exists():
            done = run_cli("--out", str(out), "--progress", "off")
            fields = {"args": done.args, "returncode": done.returncode}
            fields |= {"stdout": done.stdout, "stderr": done.stderr}
            record.write_text(json.dumps(fields), encoding="utf-8")
            # The executables in the run's cache now: the default run's own (the tests that run
            # the command with another structure wait for this fixture).
            executables = pathlib.Path(os.environ[_COMMAND_CACHE]) / "executables"
            entries = sorted(p.name for p in executables.glob("*.jaxexec"))
            (folder / "entries.json").write_text(json.dumps(entries), encoding="utf-8")
        done = subprocess.CompletedProcess(**json.loads(record.read_text(encoding="utf-8")))
    return done, out


@pytest.fixture(scope="session")
def default_report_entries(default_report):
    """The names of the executables the default run wrote in the run's command cache (the
    tests that run the command with another structure wait for the default run first)."""
    _, out = default_report
    return json.loads((out.parent / "entries.json").read_text(encoding="utf-8"))
