"""The optimize-joint command: report, exit codes, bad input, interruption."""

import json
import os
import signal
import subprocess
import sys
import tempfile
import time

import pytest
from reference import reference_default_design

from tripodjax import optimize

SPEC = optimize.load_spec()


def run_cli(*args, cwd=None, **popen):
    command = [
        sys.executable,
        "-P",  # the installed package, not the source folders of the repository root
        "-c",
        "from tripodjax.optimize.cli import command; command()",
        *args,
    ]
    # The command caches compiled code; keep the tests' cache out of the user's home.
    env = dict(
        os.environ, TRIPODJAX_CACHE_DIR=os.path.join(tempfile.gettempdir(), "tripodjax-test-cache")
    )
    return subprocess.run(command, capture_output=True, text=True, timeout=900, cwd=cwd, env=env)


def strict_json(path):
    def refuse(token):
        raise ValueError(f"non-strict JSON token {token}")

    return json.loads(path.read_text(), parse_constant=refuse)


@pytest.fixture(scope="module")
def cli_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("report")
    return run_cli("--out", str(out), "--progress", "off"), out


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
    # The cheap default (n_theta 120) is re-checked at full fidelity.
    assert report["full_fidelity"]["n_theta"] == 360
    assert min(report["full_fidelity"]["constraints"].values()) > -1e-4


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
        (
            "[life]\ntorque = [1154.0, inf]\nspeed = [1.0, 1.0]\nvehicle_speed = [1.0, 1.0]\n"
            "share = [0.5, 0.5]\n",
            "life.torque[1] = inf",
        ),
        ("[loads]\nM_max = 1.0\n[vehicle]\nadhesion = 1.0\n", "loads.M_max and [vehicle]"),
        ("[constraints]\nmax_life_km = 1.0\n", "below life.required_km"),
        ("[solver]\nn_theta = 9999996\n", "solver.n_theta"),
        ("[life.conditions]\nnames = 5\n", "life.conditions.names"),
    ],
)
def test_cli_bad_spec_exits_2_with_one_line_and_no_report(tmp_path, content, fragment):
    spec = tmp_path / "bad.toml"
    spec.write_text(content)
    out = tmp_path / "out"
    result = run_cli(str(spec), "--out", str(out))
    assert result.returncode == 2, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and fragment in lines[0] and "Traceback" not in result.stderr
    assert not (out / "report.json").exists()


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
    ):
        result = run_cli(*args)
        assert result.returncode == 2, (args, result.stderr)
        assert len(result.stderr.strip().splitlines()) == 1 and fragment in result.stderr
        assert not (tmp_path / "o" / "report.json").exists()  # stopped before any optimisation


def test_cli_infeasible_spec_says_so_with_a_strict_report(tmp_path):
    spec = tmp_path / "small.toml"
    spec.write_text("[constraints]\nmax_outer_diameter = 50.0\n")
    out = tmp_path / "out"
    result = run_cli(str(spec), "--out", str(out), "--progress", "off")
    assert result.returncode == 1, result.stderr
    assert "infeasible" in result.stderr and "Traceback" not in result.stderr
    report = strict_json(out / "report.json")
    assert "infeasible" in report["message"] and report["status"]["feasible"] is False


def test_cli_ctrl_c_prints_one_line_and_exits_130(tmp_path):
    out = tmp_path / "out"
    env = dict(os.environ, TRIPODJAX_CACHE_DIR=str(tmp_path / "cache"))
    command = [
        sys.executable,
        "-P",  # the installed package, not the source folders of the repository root
        "-c",
        "from tripodjax.optimize.cli import command; command()",
        "--out",
        str(out),
        "--progress",
        "off",
    ]
    process = subprocess.Popen(
        command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env
    )
    time.sleep(4.0)  # inside the (cold) compilation
    process.send_signal(signal.SIGINT)
    _, stderr = process.communicate(timeout=120)
    assert process.returncode == 130, stderr
    assert len(stderr.strip().splitlines()) == 1 and "interrupted" in stderr
    assert not out.exists() or not any(
        p.name.startswith(".") or p.name == "report.json" for p in out.iterdir()
    )


def test_cli_help():
    result = run_cli("--help")
    assert (
        result.returncode == 0 and "--out DIR" in result.stdout and "Exit status" in result.stdout
    )


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
