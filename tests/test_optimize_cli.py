"""The optimize-joint command: report, exit codes, bad input, interruption."""

import contextlib
import json
import math
import os
import pathlib
import re
import shutil
import signal
import subprocess
import sys
import time

import jax
import pytest
from command import COMMAND, run_cli
from reference import reference_default_design

from tripodjax import Layout, forces, optimize

SPEC = optimize.load_spec()


def strict_json(path):
    def refuse(token):
        raise ValueError(f"non-strict JSON token {token}")

    return json.loads(path.read_text(), parse_constant=refuse)


@pytest.fixture
def cli_run(default_report):
    return default_report


def copy_of_the_runs_cache(destination):
    """A copy of the run's cache (conftest), made after ``cli_run``: it holds every program of
    the default run, and only executables of the installed source. Entries another worker
    writes meanwhile may be missing from it (a file named in the listing and gone)."""

    def copy_present(source, target):
        with contextlib.suppress(FileNotFoundError):
            shutil.copy2(source, target)

    shutil.copytree(os.environ["TRIPODJAX_CACHE_DIR"], destination, copy_function=copy_present)
    return destination


def test_cli_default_exits_0_and_writes_a_strict_report(cli_run):
    result, out = cli_run
    assert result.returncode == 0, result.stderr
    assert {
        "report.json",
        "convergence.png",
        "constraint_margins.png",
        "pareto_front.png",
        "catalogue.png",
        "sensitivities.png",
    } <= set(os.listdir(out))
    report = strict_json(out / "report.json")
    assert report["converged"] and report["kkt_residual"] <= report["tolerance"]
    assert set(report["status"]) >= {"kkt_converged", "halfshaft_converged", "hertz_converged"}
    R, d = reference_default_design()  # the workbook's chain, independently (test_optimize.py)
    assert report["design"]["R_mm"] == pytest.approx(R, rel=2e-3)
    assert report["design"]["d_roller_mm"] == pytest.approx(d, rel=2e-3)
    assert "catalogue:" in result.stdout and "ad hoc:" in result.stdout
    # the printed design with its units, the report's numbers
    printed = f"R = {report['design']['R_mm']:.4g} mm, d_roller = {report['design']['d_roller_mm']:.4g} mm"
    assert printed in result.stdout
    # No catalogue size lives 100 000 km in the workbook's vehicle (test_optimize.py).
    assert report["catalogue_choice"] is None and not any(
        e["feasible"] for e in report["catalogue"]
    )
    assert "catalogue: none feasible" in result.stdout
    assert "layout.gamma0_deg" in report["sensitivities"]
    for key in ("vehicle.tyre_radius_m", "vehicle.adhesion"):
        assert report["sensitivities"][key]["d_roller"] != 0, key
    life = report["life"]
    assert life["M_max_forward_Nm"] == pytest.approx(1154.0, rel=5e-3)
    assert life["M_max_backward_Nm"] == pytest.approx(750.0, rel=5e-3)
    assert life["km"] == pytest.approx(100_000.0, rel=1e-3)  # active
    assert [c["name"] for c in life["conditions"]] == [
        "static trim",
        "steering +",
        "steering -",
        "shock +",
        "shock -",
    ]
    assert sum(c["damage_share"] for c in life["conditions"]) == pytest.approx(1.0)
    assert sum(c["damage_share"] for c in life["damage_by_case"]) == pytest.approx(1.0)
    assert "damage.png" in os.listdir(out)
    forces_section = report["forces"]  # the force model at the design, beside Lee's GAF
    with jax.enable_x64(True):
        one = forces.forces_halfshaft(
            Layout(report["design"]["R_mm"], 500.0, math.radians(20.0)),
            forces.ForceInputs(1000.0),
            n_theta=optimize.load_spec().structure.n_theta,
        )
    for name in ("gaf_rms", "gaf_third_order", "lts_mean", "lts_ripple"):
        assert forces_section[f"{name}_N"] == pytest.approx(float(getattr(one, name)), rel=1e-9)
    steady = forces_section["complementary_torque_steady_Nm"]
    assert steady == pytest.approx(float(one.complementary_torque_steady), rel=1e-9)
    assert forces_section["nominal_roller_load_N"] == pytest.approx(
        1e6 / (3 * report["design"]["R_mm"]), rel=1e-12
    )
    assert forces_section["result"] == "successful"
    # The rest of the halfshaft (tests/test_structural.py checks its numbers).
    halfshaft = report["halfshaft"]
    assert [s["name"] for s in halfshaft["sections"]] == [
        "A-A",
        "B-B",
        "C-C",
        "outboard stem",
        "inboard stem",
    ]
    assert halfshaft["passed"] and halfshaft["outboard"]["life_passed"]
    assert "halfshaft: 5 sections and the outboard joint pass" in result.stdout
    # The cheap default (n_theta 120) is re-checked at full fidelity.
    assert report["full_fidelity"]["n_theta"] == 360
    assert min(report["full_fidelity"]["constraints"].values()) > -1e-4


def test_cli_default_writes_every_document_the_readme_lists(cli_run):
    """The README's main command (with the report extra, as the tests have it) writes exactly the
    files its set-up paragraph lists."""
    readme = (pathlib.Path(__file__).resolve().parent.parent / "README.md").read_text("utf-8")
    setup = readme[readme.index("[start:setup]") : readme.index("[end:setup]")]
    listed = set(re.findall(r"`([\w.]+\.(?:json|html|xlsx|png))`", setup))
    result, out = cli_run
    assert result.returncode == 0, result.stderr
    assert listed == set(os.listdir(out))


def test_cli_design_is_feasible_under_evaluate(cli_run):
    _, out = cli_run
    report = strict_json(out / "report.json")
    design = {"R": report["design"]["R_mm"], "d_roller": report["design"]["d_roller_mm"]}
    check = optimize.evaluate(SPEC, design)
    assert min(check["constraints"].values()) >= 0.0
    assert check["objective"] == pytest.approx(report["objective"], rel=1e-12)


@pytest.mark.parametrize(
    "content, fragment",
    [
        ("[hertz]\nconformity = 0.9\n", "hertz.conformity"),
        ("[bounds]\nd_roller = [20.0, inf]\n", "bounds.d_roller[1] = inf"),
        (  # accepted before: a 78 s solve, then "NOT converged … overflow"
            '[bounds]\n"shaft.outer_diameter_mm[C-C]" = [18.5, 1e300]\n'
            "[objective]\nw_shaft_area = 1.0\nshaft_area_ref = 3000.0\n",
            'bounds."shaft.outer_diameter_mm[C-C]"[1] = 1e+300 is not allowed: a finite number '
            "≥ 1 mm and ≤ 200 mm",
        ),
        (
            "[life]\ntorque = [1154.0, inf]\nspeed = [1.0, 1.0]\nvehicle_speed = [1.0, 1.0]\n"
            "share = [0.5, 0.5]\n",
            "life.torque[1] = inf",
        ),
        ("[loads]\nM_max = 1.0\n[vehicle]\nadhesion = 1.0\n", "loads.M_max and [vehicle]"),
        ("[constraints]\nmax_life_km = 1.0\n", "below life.required_km"),
        ("[solver]\nn_theta = 9999996\n", "solver.n_theta"),
        ("[life.conditions]\nnames = 5\n", "life.conditions.names"),
        ("[outboard]\nn_balls = 2\n", "outboard.n_balls = 2 is not allowed"),
    ],
)
def test_cli_bad_spec_exits_2_with_one_line_and_no_report(tmp_path, capsys, content, fragment):
    """The command's main() in this process (the spec is refused before anything is computed);
    the next test runs one such case as a process of its own."""
    from tripodjax.optimize import cli

    spec = tmp_path / "bad.toml"
    spec.write_text(content)
    out = tmp_path / "out"
    assert cli.main([str(spec), "--out", str(out)]) == 2
    stdout, stderr = capsys.readouterr()
    lines = stderr.strip().splitlines()
    assert len(lines) == 1 and fragment in lines[0] and not stdout, stderr
    assert not out.exists()  # --out is made only for a spec that can run


def test_cli_bad_spec_in_a_process_of_its_own_exits_2_with_one_line(tmp_path):
    spec = tmp_path / "bad.toml"
    spec.write_text("[hertz]\nconformity = 0.9\n")
    result = run_cli(str(spec), "--out", str(tmp_path / "out"))
    assert result.returncode == 2, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "hertz.conformity" in lines[0] and "Traceback" not in result.stderr
    assert not result.stdout and not (tmp_path / "out" / "report.json").exists()


def test_cli_bad_files_and_out_exit_2_before_computing(tmp_path):
    latin = tmp_path / "latin.toml"
    latin.write_bytes("# réglé\n".encode("latin-1"))
    regular = tmp_path / "file"
    regular.write_text("x")
    for args, fragment in (
        ((str(tmp_path / "none.toml"), "--out", str(tmp_path / "o")), "cannot read spec file"),
        ((str(latin), "--out", str(tmp_path / "o")), "not UTF-8"),
        (("--out", str(regular / "sub")), "--out"),
        (("--out", ""), "--out"),
        (("--out",), "--out"),
        (("--revision", " ", "--out", str(tmp_path / "o")), "--revision"),
        (("--revision", "1\n2", "--out", str(tmp_path / "o")), "printable characters"),
        (("--revision", "r" * 5000, "--out", str(tmp_path / "o")), "at most 80 allowed"),
    ):
        result = run_cli(*args)
        assert result.returncode == 2, (args, result.stderr)
        assert len(result.stderr.strip().splitlines()) == 1 and fragment in result.stderr
        assert not (tmp_path / "o").exists()  # stopped before any optimisation, --out not made


@pytest.mark.usefixtures("default_report")  # its programs compiled once, not by two at once
def test_cli_infeasible_spec_says_so_with_a_strict_report(tmp_path):
    spec = tmp_path / "long_life.toml"
    # No joint within the bounds lasts 1e7 km (life.required_km's upper limit; the largest joint
    # with R/d ≥ 0.63, R 40 mm and d 63.4 mm, lasts 4.7e6 km). A number of the default spec: its
    # programs reused.
    spec.write_text("[life]\nrequired_km = 1e7\n")
    out = tmp_path / "out"
    result = run_cli(str(spec), "--out", str(out), "--progress", "off")
    assert result.returncode == 1, result.stderr
    assert "infeasible" in result.stderr and "Traceback" not in result.stderr
    report = strict_json(out / "report.json")
    assert "infeasible" in report["message"] and report["status"]["feasible"] is False
    assert "life" in report["message"]


def test_cli_non_finite_problem_says_nonfinite_not_successful(tmp_path, cli_run):
    spec = tmp_path / "tiny.toml"
    # Finite, but M_max (the vehicle's largest working torque) is then ~1e-322 N·m and
    # ln(M_s / M_max) overflows. The default spec's structure: its compiled programs are reused.
    torques = ", ".join(["5e-324"] * len(SPEC["vehicle"]["engine_torque_Nm"]))
    spec.write_text(f"[vehicle]\nengine_torque_Nm = [{torques}]\n")
    out = tmp_path / "out"
    # In a copy of the run's cache, at another path, every program is found: no entry of
    # JAX's compilation cache names the folder (before, 25 s and two new entries; now 8 s).
    cache = copy_of_the_runs_cache(tmp_path / "cache")
    compiled = sorted(p.name for p in cache.glob("*-cache"))
    result = run_cli(str(spec), "--out", str(out), "--progress", "off", cache=cache)
    assert sorted(p.name for p in cache.glob("*-cache")) == compiled
    assert result.returncode == 1, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "nonfinite" in lines[0] and "KKT" not in lines[0], lines
    report = strict_json(out / "report.json")
    assert report["status"]["result"] == "nonfinite" and not report["converged"]


def _popen_cli(out, cache):
    env = dict(os.environ, TRIPODJAX_CACHE_DIR=str(cache))
    command = [*COMMAND, "--out", str(out), "--progress", "off"]
    return subprocess.Popen(
        command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env
    )


def _handlers_installed(pid):
    """True once the process catches SIGTERM (/proc/PID/status SigCgt): command() has begun.

    Python itself catches SIGINT from start-up; SIGTERM only the command's handler does. Where
    /proc is absent the caller falls back to a pause.
    """
    try:
        with open(f"/proc/{pid}/status") as f:
            fields = dict(line.split(":", 1) for line in f if ":" in line)
    except OSError:
        return None
    return bool(int(fields["SigCgt"].strip(), 16) >> (signal.SIGTERM - 1) & 1)


# Delays after command()'s first instruction: in the imports of JAX and the spec reader, in
# tracing and in the (cold) compilation.
@pytest.mark.parametrize(
    "signum, code, word", [(signal.SIGINT, 130, "interrupted"), (signal.SIGTERM, 143, "terminated")]
)
@pytest.mark.parametrize("delay", [0.0, 0.3, 1.5, 5.0])
def test_cli_signal_at_any_moment_prints_one_line_and_exits(tmp_path, signum, code, word, delay):
    out = tmp_path / "out"
    process = _popen_cli(out, tmp_path / "cache")
    deadline = time.monotonic() + 60
    while _handlers_installed(process.pid) is False and time.monotonic() < deadline:
        time.sleep(0.005)
    if _handlers_installed(process.pid) is None:  # no /proc: past the start-up by then
        time.sleep(1.0)
    time.sleep(delay)
    process.send_signal(signum)
    stdout, stderr = process.communicate(timeout=120)
    assert process.returncode == code, stderr
    lines = stderr.strip().splitlines()
    assert len(lines) == 1 and word in lines[0] and "Traceback" not in stderr, stderr
    assert stdout == ""
    assert not out.exists() or not list(out.iterdir())  # no staged, no partial file


def test_cli_signal_while_staging_waits_until_no_staged_file_is_left(tmp_path):
    """SIGTERM in the middle of writing the report: every staged file is renamed or removed."""
    out = tmp_path / "out"
    script = f"""
import os, signal
from matplotlib.figure import Figure
from tripodjax.optimize import cli

class Interrupting:  # a figure whose saving is interrupted while a.png is staged
    def savefig(self, target, **kw):
        os.kill(os.getpid(), signal.SIGTERM)
        Figure().savefig(target, **kw)

cli._install_handlers()
outcome = dict(body={{"a": 1}}, figures={{"a.png": Figure(), "b.png": Interrupting()}},
               documents={{}}, notes=[], message="m", code=0, designs="d", status="s")
cli._write(type("A", (), {{"out": {str(out)!r}}}), outcome)
print("not reached")
"""
    result = subprocess.run(
        [sys.executable, "-P", "-c", script], capture_output=True, text=True, timeout=300
    )
    assert result.returncode == 143, result.stderr
    assert "not reached" not in result.stdout
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "terminated" in lines[0] and "complete" in lines[0]
    assert sorted(p.name for p in out.iterdir()) == ["a.png", "b.png", "report.json"]


def test_cli_help_and_argument_errors_answer_without_importing_jax():
    script = """
import sys
from tripodjax.optimize import cli
for argv in (["--help"], ["--bogus"], ["--out", ""]):
    try:
        cli.main(argv)
    except SystemExit:
        pass
print(sorted(m for m in ("jax", "numpy", "matplotlib", "tripodjax.layout") if m in sys.modules))
"""
    result = subprocess.run(
        [sys.executable, "-P", "-c", script], capture_output=True, text=True, timeout=300
    )
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip().splitlines()[-1] == "[]"


def test_cli_help_answers_within_a_second():
    # The best of three runs: the machine is shared, and one slow start says nothing about the
    # command (the structural test above shows that --help imports nothing heavy).
    seconds = []
    for _ in range(3):
        start = time.perf_counter()
        result = run_cli("--help")
        seconds.append(time.perf_counter() - start)
        assert result.returncode == 0
    assert min(seconds) <= 1.0, seconds
    assert "--out DIR" in result.stdout and "Exit status" in result.stdout
    assert "143" in result.stdout


@pytest.mark.usefixtures("default_report")  # its programs compiled once, not by two at once
def test_cli_report_write_failure_exits_3_and_prints_the_design(tmp_path):
    out = tmp_path / "out"
    (out / "report.json").mkdir(parents=True)  # the report cannot replace a folder
    (out / "report.json" / "keep").write_text("older")
    result = run_cli("--out", str(out), "--progress", "off")
    assert result.returncode == 3, result.stderr
    assert "ad hoc:" in result.stderr and "cannot write the report" in result.stderr
    assert "Traceback" not in result.stderr
    assert (out / "report.json" / "keep").read_text() == "older"
    assert not any(p.name.startswith(".") for p in out.iterdir())  # no temporary files left


def _older_report(out):
    out.mkdir()
    for name in ("a.png", "report.json"):
        (out / name).write_text(f"older {name}")


def test_a_report_that_cannot_be_written_leaves_every_older_file_as_it_was(tmp_path):
    from matplotlib.figure import Figure

    from tripodjax.optimize import report

    out = tmp_path / "out"
    _older_report(out)
    (out / "b.png").mkdir()  # in the way of the second figure: found before anything is renamed
    with pytest.raises(IsADirectoryError, match="b.png"):
        report.write(out, {"new": 1}, {"a.png": Figure(), "b.png": Figure()})
    assert sorted(p.name for p in out.iterdir()) == ["a.png", "b.png", "report.json"]
    assert (out / "a.png").read_text() == "older a.png"
    assert (out / "report.json").read_text() == "older report.json"


def test_a_rename_that_fails_puts_back_the_files_renamed_before_it(tmp_path, monkeypatch):
    from matplotlib.figure import Figure

    from tripodjax.optimize import report

    out = tmp_path / "out"
    _older_report(out)
    replace = os.replace

    def failing(source, target):  # the second figure's rename fails (a full disk, say)
        if os.path.basename(str(target)) == "b.png" and ".b.png." in str(source):
            raise OSError(28, "No space left on device")
        replace(source, target)

    monkeypatch.setattr(report.os, "replace", failing)
    with pytest.raises(OSError, match="No space"):
        report.write(out, {"new": 1}, {"a.png": Figure(), "b.png": Figure(), "c.png": Figure()})
    # a.png was renamed into place, then put back; b.png and c.png never appear
    assert sorted(p.name for p in out.iterdir()) == ["a.png", "report.json"]
    assert (out / "a.png").read_text() == "older a.png"
    assert (out / "report.json").read_text() == "older report.json"


def _swap_entries(executables, names=None):
    """Swap the contents of the two largest entries (valid executables under wrong keys), of
    those ``names`` where given."""
    entries = [p for p in executables.glob("*.jaxexec") if names is None or p.name in names]
    entries = sorted(entries, key=lambda p: p.stat().st_size)[-2:]
    assert len(entries) == 2, list(executables.iterdir())
    first, second = (p.read_bytes() for p in entries)
    entries[0].write_bytes(second)
    entries[1].write_bytes(first)
    return entries


def _entries_hold_their_keys(executables):
    return all(
        p.read_bytes().startswith(f"tripodjax-executable 1 {p.stem}\n".encode())
        for p in executables.glob("*.jaxexec")
    )


def test_executable_cache_replaces_a_swapped_or_corrupt_entry(tmp_path):
    import functools

    import jax
    import jax.numpy as jnp

    from tripodjax.optimize._compiled import call, executable_cache

    @functools.partial(jax.jit, static_argnums=0)
    def scaled(factor, x):
        return {"y": factor * x}

    @functools.partial(jax.jit, static_argnums=0)
    def summed(n, x, y):
        return x.sum() + n * y

    def calls():
        return (
            float(call(scaled, 3.0, jnp.arange(4.0))["y"][1]),
            float(call(summed, 2, jnp.arange(3.0), jnp.float32(1.0))),
        )

    with executable_cache(tmp_path):
        assert calls() == (3.0, 5.0)
    _swap_entries(tmp_path)
    with executable_cache(tmp_path):  # a new cache (process): it loads the swapped files
        assert calls() == (3.0, 5.0)
    assert _entries_hold_their_keys(tmp_path)
    for path in tmp_path.glob("*.jaxexec"):  # truncated entries
        path.write_bytes(path.read_bytes()[:100])
    with executable_cache(tmp_path):
        assert calls() == (3.0, 5.0)
    assert _entries_hold_their_keys(tmp_path)


def test_executable_cache_removes_the_least_recently_used_entries(tmp_path, monkeypatch):
    import functools

    import jax
    import jax.numpy as jnp

    from tripodjax.optimize import _compiled

    @functools.partial(jax.jit, static_argnums=0)
    def scaled(factor, x):
        return factor * x

    def entry(factor):
        with _compiled.executable_cache(tmp_path):
            assert float(_compiled.call(scaled, factor, jnp.ones(2))[0]) == factor
        return max(tmp_path.glob("*.jaxexec"), key=lambda p: p.stat().st_mtime_ns)

    paths = {}
    for i, factor in enumerate((1.0, 2.0, 3.0)):
        paths[factor] = entry(factor)
        os.utime(paths[factor], (100.0 + i, 100.0 + i))  # used in this order, 1 s apart
    sizes = [p.stat().st_size for p in paths.values()]
    monkeypatch.setattr(_compiled, "MAX_CACHE_BYTES", sum(sizes) + min(sizes) // 2)  # 3 fit
    entry(1.0)  # loaded: now the most recently used
    assert paths[1.0].stat().st_mtime > 200.0
    newest = entry(4.0)  # written: the cache is over its size, the oldest entry goes
    assert {p.name for p in tmp_path.glob("*.jaxexec")} == {
        paths[1.0].name,
        paths[3.0].name,
        newest.name,
    }


_LOADS_AN_LU = """
import functools, sys
import jax, jax.numpy as jnp, jax.monitoring
from tripodjax.optimize._compiled import call, executable_cache
compiled = []
jax.monitoring.register_event_time_span_listener(
    lambda event, *_, **kw: compiled.append(kw.get("fun_name")) if "backend_compile" in event else None
)
@functools.partial(jax.jit, static_argnums=0)
def solved(n, a, b):
    return jnp.linalg.solve(a + n * jnp.eye(3), b)
with executable_cache(sys.argv[1]):
    x = call(solved, 1.0, jnp.diag(jnp.arange(3.0)), jnp.ones(3))
print(*map(float, x), "solved" in str(compiled))
"""


def test_a_process_that_only_loads_an_executable_runs_its_lapack_kernels(tmp_path):
    """The second process loads the LU's executable and lowers nothing: JAX has not loaded its
    LAPACK kernels for it (without ``_linear_algebra_ready``: a segmentation fault)."""
    command = [sys.executable, "-P", "-c", _LOADS_AN_LU, str(tmp_path)]
    first, second = (
        subprocess.run(command, capture_output=True, text=True, timeout=300) for _ in range(2)
    )
    for done, compiles in ((first, "True"), (second, "False")):
        assert done.returncode == 0, done.stderr
        *x, compiled = done.stdout.split()
        # (diag(0, 1, 2) + I) x = 1: x = 1/(1 + i), in float32 or float64 as JAX runs
        assert [float(v) for v in x] == pytest.approx([1.0, 0.5, 1.0 / 3.0], rel=1e-6)
        assert compiled == compiles


_WITH_JAX_CACHE = """
import functools, sys
import jax, jax.numpy as jnp
from tripodjax._compile import latency_bound_jit
from tripodjax.optimize._compiled import call, executable_cache
jax.config.update("jax_compilation_cache_dir", sys.argv[1])
jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
@functools.partial(latency_bound_jit, static_argnums=0)
def f(n, a, b):
    return jnp.where(a > 0, b / a, n * b).sum() + jnp.sin(a).prod()
args = (2.0, jnp.arange(1.0, 4.0), jnp.ones(3))
if sys.argv[3] == "plain":
    print(float(f(*args)))
else:
    with executable_cache(sys.argv[2]):
        print(float(call(f, *args)))
"""


def test_an_executable_from_jaxs_persistent_cache_is_not_kept(tmp_path):
    """JAX's persistent cache answers the second process's compile: that executable is not
    stored (serialized again it lacks its kernels: "Function ... not found" when loaded)."""
    jax_cache, executables = tmp_path / "jax", tmp_path / "executables"

    def run(mode):
        command = [sys.executable, "-P", "-c", _WITH_JAX_CACHE, str(jax_cache), str(executables)]
        done = subprocess.run(command + [mode], capture_output=True, text=True, timeout=300)
        assert done.returncode == 0, done.stderr
        return done.stdout.strip()

    expected = run("plain")
    assert run("cached") == expected
    assert not list(executables.glob("*.jaxexec"))
    assert run("cached") == expected


def test_cli_with_a_swapped_cache_entry_runs_normally_and_repairs_it(
    default_report_entries, tmp_path
):
    cache = copy_of_the_runs_cache(tmp_path / "cache")  # entries the run below loads, all of them
    # Two that the default run loads (the run's cache may hold other structures' too).
    _swap_entries(cache / "executables", default_report_entries)
    out = tmp_path / "out"
    env = dict(os.environ, TRIPODJAX_CACHE_DIR=str(cache))
    command = [sys.executable, "-P", "-m", "tripodjax.optimize.cli", "--out", str(out)]
    result = subprocess.run(
        command + ["--progress", "off"], capture_output=True, text=True, env=env, timeout=900
    )
    assert result.returncode == 0, result.stderr
    assert "Traceback" not in result.stderr
    assert _entries_hold_their_keys(cache / "executables")
    assert strict_json(out / "report.json")["converged"]


def test_an_infeasible_verdict_says_whether_another_start_was_feasible():
    """The solver may report a start just outside its limits for its far better objective
    (solver.ACCEPTABLE) beside a feasible one: "no start reached feasibility" would be untrue."""
    import types

    from tripodjax.optimize.cli import EXIT_NOT_CONVERGED, _verdict

    def result(*feasible_starts):
        return types.SimpleNamespace(
            result="successful",
            feasible=False,
            constraints={"life": {"margin": -3e-7}, "min_R_over_d": {"margin": 0.1}},
            starts=[{"feasible": f} for f in feasible_starts],
            structure=None,
        )

    message, status = _verdict(result(False, False))
    assert status == EXIT_NOT_CONVERGED
    assert message.startswith("infeasible: no start reached feasibility") and "life" in message
    message, status = _verdict(result(False, True, True))
    assert status == EXIT_NOT_CONVERGED and "no start reached" not in message
    assert "2 other start(s) feasible" in message and "life (margin -3e-07)" in message


@pytest.mark.parametrize("failing", [False, True])
def test_the_command_restores_jaxs_persistent_cache_setting(monkeypatch, failing):
    """The command turns JAX's persistent cache off while it computes (it keeps executables
    itself) and gives the caller's setting back afterwards, also when the computation fails:
    a notebook that calls `cli.main` keeps its own cache."""
    from tripodjax.optimize import cli

    seen = []

    def contents(args, given, command_line):
        seen.append(jax.config.jax_enable_compilation_cache)
        if failing:
            raise RuntimeError("failed")
        return "report"

    monkeypatch.setattr(cli, "_contents", contents)
    before = jax.config.jax_enable_compilation_cache
    try:
        jax.config.update("jax_enable_compilation_cache", True)
        with pytest.raises(RuntimeError) if failing else contextlib.nullcontext():
            assert cli._compute(None, None, []) == "report"
        assert seen == [False]
        assert jax.config.jax_enable_compilation_cache is True
    finally:
        jax.config.update("jax_enable_compilation_cache", before)
