"""The design problem, the optimiser and the optimize-joint command."""

import json
import math
import os
import subprocess
import sys
import tempfile

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from tripodjax import Layout, friction, hertz, kinematic_metrics, optimize
from tripodjax.optimize.problem import compiled, scenario

SPEC = optimize.load_spec()


def run_cli(*args, cwd=None):
    command = [
        sys.executable,
        "-c",
        "import sys; from tripodjax.optimize.cli import main; sys.exit(main())",
        *args,
    ]
    # The command caches compiled code; keep the tests' cache out of the user's home.
    env = dict(
        os.environ, TRIPODJAX_CACHE_DIR=os.path.join(tempfile.gettempdir(), "tripodjax-test-cache")
    )
    return subprocess.run(command, capture_output=True, text=True, timeout=900, cwd=cwd, env=env)


def test_default_spec_is_grounded_in_the_seed():
    assert SPEC["loads"]["M_max"] == 1154.0 and SPEC["loads"]["shock_factor"] == 1.1
    assert SPEC["hertz"]["conformity"] == 1.002 and SPEC["constraints"]["R_over_d"] == (0.63, 0.83)
    assert SPEC["life"]["required_km"] == 100000.0
    assert SPEC["layout"]["l"] == 500.0 and SPEC["layout"]["gamma0_rad"] == pytest.approx(
        math.radians(20)
    )


def test_evaluate_against_the_physics_computed_independently():
    design = {"R": 25.55, "d_roller": 43.5}
    out = optimize.evaluate(SPEC, design)
    with jax.enable_x64(True):
        layout = Layout(25.55, 500.0, math.radians(20))
        irr = float(kinematic_metrics(layout, n_theta=120).irregularity)
        gaf = float(
            friction.gaf_halfshaft(
                layout, 1000.0, friction.GREASE_A, n_theta=120, model="stroke"
            ).rms
        )
        caps = hertz.capacities(
            43.5, 25.55, conformity=1.002, P_s=2350.0, P_d=1347.0, P_sd=2005.0, C_s=1.2
        )
    expected = irr / 0.0283 + gaf / 1250.0 + (2 * 25.55 + 43.5) / 94.6
    assert out["objective"] == pytest.approx(expected, rel=1e-10)
    assert out["constraints"]["static_capacity"] == pytest.approx(
        math.log(float(caps.M_s) / (1.1 * 1154)), rel=1e-10
    )
    assert out["constraints"]["R_over_d_min"] == pytest.approx(
        math.log(25.55 / 43.5 / 0.63), rel=1e-12
    )
    assert (
        out["constraints"]["R_over_d_min"] < 0
    )  # the workbook joint sits below the R/d experience range
    assert out["constraints"]["R_lower_bound"] == pytest.approx((25.55 - 15) / 25, rel=1e-12)


def test_evaluate_on_another_layout_and_bad_design_keys():
    steeper = optimize.evaluate(SPEC, {"R": 25.0, "d_roller": 33.0, "gamma0_deg": 30.0})
    nominal = optimize.evaluate(SPEC, {"R": 25.0, "d_roller": 33.0})
    assert steeper["objective"] > nominal["objective"]
    with pytest.raises(ValueError, match="need R and d_roller"):
        optimize.evaluate(SPEC, {"R": 25.0})


@pytest.mark.parametrize(
    "text, message",
    [
        ("[hertz\nP_s = 1", "is not valid TOML"),
        ("[hertz]\nconformity = 0.99", "hertz.conformity = 0.99 is not allowed: conformity Ψ > 1"),
        ("[hertz]\nPs = 2000.0", "unknown key hertz.Ps; allowed here:"),
        (
            "[bounds]\nR = [30.0, 20.0]",
            "bounds.R = [30.0, 20.0] is not allowed: [lo, hi] with 0 < lo < hi",
        ),
        ("[bounds]\nR = [15.0, 150.0]", "R/l ≤ 0.2"),
        ("[life]\nshare = [0.5, 0.5, 0.5, 0.5]", "life.share"),
        ("[life.conditions]\nshare = [0.5, 0.2, 0.2]", "shares ≥ 0 summing to 1"),
        ('[loads]\nM_max = "big"', "loads.M_max = 'big' must be a finite number"),
        (
            "[solver]\nn_theta = 100",
            "solver.n_theta = 100 is not allowed: a positive multiple of 6",
        ),
        (
            '[friction]\ngrease = "C"',
            'friction.grease = \'C\' is not allowed: one of "A", "B", "dry"',
        ),
    ],
)
def test_bad_specs_name_the_key(text, message):
    with pytest.raises(optimize.SpecError) as info:
        optimize.parse_spec(text)
    assert message in str(info.value) and "\n" not in str(info.value).strip()


def test_optional_envelope_constraint():
    spec = optimize.parse_spec("[constraints]\nmax_outer_diameter = 80.0")
    out = optimize.evaluate(spec, {"R": 25.0, "d_roller": 35.0})
    assert out["constraints"]["outer_diameter"] == pytest.approx(math.log(80.0 / 85.0), rel=1e-12)


@pytest.fixture(scope="module")
def cli_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("report")
    result = run_cli("--out", str(out), "--progress", "off")
    return result, out


def test_cli_default_exits_0_and_writes_the_report(cli_run):
    result, out = cli_run
    assert result.returncode == 0, result.stderr
    assert sorted(os.listdir(out)) == [
        "constraint_margins.png",
        "convergence.png",
        "pareto_front.png",
        "report.json",
    ]
    report = json.loads((out / "report.json").read_text())
    for key in (
        "design",
        "objective",
        "constraints",
        "kkt_residual",
        "spec",
        "versions",
        "pareto_front",
    ):
        assert key in report
    assert report["converged"] and report["kkt_residual"] <= report["tolerance"]
    for entry in report["constraints"].values():
        assert {"value", "limit", "margin"} <= set(entry)


def test_cli_design_is_feasible_and_no_grid_point_is_better(cli_run):
    """Acceptance: every constraint holds when re-evaluated, and no feasible point of a 60×60 grid
    over the bounds has an objective more than 0.5 % lower."""
    _, out = cli_run
    report = json.loads((out / "report.json").read_text())
    design = {"R": report["design"]["R_mm"], "d_roller": report["design"]["d_roller_mm"]}
    check = optimize.evaluate(SPEC, design)
    assert min(check["constraints"].values()) >= 0.0
    assert check["objective"] == pytest.approx(report["objective"], rel=1e-12)
    with jax.enable_x64(True):
        R, d = np.meshgrid(np.linspace(15, 40, 60), np.linspace(20, 50, 60), indexing="ij")
        x = jnp.asarray(np.stack([R.ravel(), d.ravel()], axis=1))
        f, c, _ = jax.jit(jax.vmap(compiled(SPEC), in_axes=(0, None)))(x, scenario(SPEC))
    feasible = np.asarray(c).min(axis=1) >= 0
    assert feasible.any()
    assert np.asarray(f)[feasible].min() >= check["objective"] * (1 - 0.005)


def test_cli_malformed_spec_exits_2_with_one_line_and_no_report(tmp_path):
    spec = tmp_path / "bad.toml"
    spec.write_text("[hertz]\nconformity = 0.9\n")
    out = tmp_path / "out"
    result = run_cli(str(spec), "--out", str(out))
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "hertz.conformity" in lines[0] and "Traceback" not in result.stderr
    assert not (out / "report.json").exists()
    missing = run_cli(str(tmp_path / "none.toml"), "--out", str(out))
    assert missing.returncode == 2 and "cannot read spec file" in missing.stderr
    bad_args = run_cli("--out")
    assert bad_args.returncode == 2 and len(bad_args.stderr.strip().splitlines()) == 1


def test_cli_infeasible_spec_exits_1_with_a_complete_report(tmp_path):
    spec = tmp_path / "small.toml"
    spec.write_text(
        "[bounds]\nR = [15.0, 17.0]\nd_roller = [20.0, 22.0]\n[solver]\nmax_outer = 3\n"
    )
    result = run_cli(str(spec), "--out", str(tmp_path / "out"), "--progress", "off")
    assert result.returncode == 1, result.stderr
    assert "violated: life" in result.stderr
    report = json.loads((tmp_path / "out" / "report.json").read_text())
    assert report["converged"] is False and report["constraints"]["life"]["margin"] < 0


def test_cli_help():
    result = run_cli("--help")
    assert (
        result.returncode == 0 and "--out DIR" in result.stdout and "Exit status" in result.stdout
    )


def test_solve_is_deterministic_and_matches_the_cli(cli_run):
    _, out = cli_run
    report = json.loads((out / "report.json").read_text())
    first, second = optimize.solve(SPEC, progress=False), optimize.solve(SPEC, progress=False)
    assert first.design == second.design
    assert first.design["R"] == pytest.approx(report["design"]["R_mm"], rel=1e-6)
    assert first.converged and min(v["margin"] for v in first.constraints.values()) >= 0


def test_pareto_front_trades_gaf_against_size(cli_run):
    _, out = cli_run
    front = json.loads((out / "report.json").read_text())["pareto_front"]
    gaf = [p["gaf_rms_N"] for p in front]
    size = [p["outer_diameter_mm"] for p in front]
    assert all(p["converged"] for p in front)
    assert all(
        a >= b - 1e-6 for a, b in zip(gaf, gaf[1:], strict=False)
    )  # more weight on GAF: less GAF
    assert all(
        a <= b + 1e-6 for a, b in zip(size, size[1:], strict=False)
    )  # ... and a bigger joint
    assert gaf[0] > gaf[-1] and size[0] < size[-1]


def test_layout_family():
    results = optimize.solve_family(SPEC, gamma0_deg=[10.0, 20.0, 30.0], progress=False)
    assert all(
        r.converged and min(v["margin"] for v in r.constraints.values()) >= 0 for r in results
    )
    # Steeper layouts raise irregularity and GAF alike; each member is its own optimum.
    irregularity = [r.quantities["irregularity"] for r in results]
    assert irregularity[0] < irregularity[1] < irregularity[2]
    single = optimize.evaluate(SPEC, {**results[2].design, "gamma0_deg": 30.0})
    assert single["objective"] == pytest.approx(results[2].objective, rel=1e-10)
    with pytest.raises(ValueError, match="exactly one of"):
        optimize.solve_family(SPEC)
