"""``python -m tripodjax.bench`` end to end at a small size (figures are measured, never asserted)."""

import json
import subprocess
import sys

import pytest


def test_bench_writes_its_figures(tmp_path):
    # notebooks/04_speed_accuracy.ipynb's sizes: its programs in the run's compilation cache
    # (the notebooks run first), the cost table small.
    out = tmp_path / "bench.json"
    result = subprocess.run(
        [
            sys.executable,
            "-m",
            "tripodjax.bench",
            "--layouts",
            "3000",
            "--fsolve-layouts",
            "3",
            "--repeats",
            "2",
            "--gradient-layouts",
            "500",
            "--domain-layouts",
            "500",
            "--cost-layouts",
            "60",
            "--cost-outputs",
            "delta_pp,result,gaf_rms",
            "--json",
            str(out),
        ],
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert result.returncode == 0, result.stderr
    figures = json.loads(out.read_text())
    # Where and when: the docs' tables name the CPU and the date under each table.
    machine = figures["measured_on"]
    assert machine["cpu"] and machine["cpu_count"] >= 1 and machine["date"].endswith(" UTC")
    assert set(figures["variants"]) == {
        f"{solver}/{dtype}"
        for solver in ("newton", "analytic", "closed_form")
        for dtype in ("float64", "float32")
    }
    for entry in [*figures["variants"].values(), figures["numpy_newton"], figures["fsolve_loop"]]:
        assert entry["points_per_s"] > 0 and set(entry["errors_vs_newton_float64"]) == {
            "delta_pp",
            "irregularity",
            "gamma_pp",
            "ecc_max",
        }
    # Accuracy is checked (timings are not): the peers and float64 Newton agree; the analytic level is within 2 %.
    assert figures["numpy_newton"]["errors_vs_newton_float64"]["irregularity"] < 1e-10
    assert figures["fsolve_loop"]["errors_vs_newton_float64"]["irregularity"] < 1e-6
    analytic = figures["variants"]["analytic/float64"]
    assert analytic["errors_vs_newton_float64"]["irregularity"] < 0.01
    assert analytic["domain_errors_vs_newton_float64"]["gamma_pp"] < 0.05
    assert analytic["domain_max_error_estimate"] < 0.01
    limit = figures["machine_limit"]
    assert limit["sines_per_s"] > 0 and limit["polynomial_steps_per_s"] > 0
    # Over the design range every angle is settled by the polynomial steps: no exact-sine
    # iteration, so no transcendental function per solved angle.
    assert limit["newton_loop_iterations"] == limit["polynomial_iterations"]
    assert limit["exact_iterations"] == 0 and limit["transcendentals_per_solved_angle"] == 0
    assert limit["steps_per_solved_angle"] == limit["polynomial_iterations"] + 1
    assert figures["gradient_to_forward"]["layouts"] == 500  # --gradient-layouts
    costs = figures["output_costs"]
    for level in ("newton", "analytic", "closed_form"):
        assert costs[level]["default"] > 0
        assert set(costs[level]["outputs"]) == {"delta_pp", "result", "gaf_rms"}
    assert "cost of each output alone" in result.stdout and "*delta_pp" in result.stdout
    assert (
        "× newton" in result.stdout
        and "× NumPy" in result.stdout
        and "gradient (R, l, γ0) / forward cost" in result.stdout
        and "newton/float64 reaches" in result.stdout
    )


def test_latency_table_of_one_entry(tmp_path):
    """``--latency`` on its cheapest entry: the wall time of a fresh process is split into
    import, trace, lowering, compile and run, each program named with its compile time and
    size, and set against the floor measured in the same run."""
    out = tmp_path / "latency.json"
    result = subprocess.run(
        [
            sys.executable,
            "-m",
            "tripodjax.bench",
            "--latency",
            "--repeats",
            "1",
            "--entries",
            "sweep",
            "--gradient-layouts",
            "",
            "--json",
            str(out),
        ],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert result.returncode == 0, result.stderr
    figures = json.loads(out.read_text())
    assert figures["measured_on"]["cpu"] and figures["floors"]["library_s"] > 0
    (name,) = figures["entries"]
    entry = figures["entries"][name]
    parts = ("import_s", "trace_s", "lower_s", "compile_s", "run_s")
    # The parts cover the wall time (they overlap only where threads compile at once).
    assert sum(entry[p] for p in parts) >= entry["wall_s"] - 1e-6
    assert all(entry[p] >= 0 for p in parts) and entry["compile_s"] > 0
    assert abs(entry["over_floor"] - entry["wall_s"] / figures["floors"]["library_s"]) < 1e-9
    program = max(entry["programs"], key=lambda p: p["compile_s"])
    assert "_evaluate_chunk" in program["name"] and program["kb"] > 0 and program["ops"] > 0
    assert sum(p["compile_s"] for p in entry["programs"]) <= entry["compile_s"] + 1e-6
    assert "compile latency" in result.stdout and figures["measured_on"]["cpu"] in result.stdout


@pytest.mark.parametrize(
    "argv, says",
    [
        (["--layouts", "-5"], "argument --layouts: '-5' is not allowed; allowed: an integer ≥ 1"),
        (["--layouts", "2.5"], "argument --layouts: '2.5' is not allowed"),
        (["--n-theta", "100"], "allowed: an integer ≥ 6, a multiple of 6"),
        (["--repeats", "0"], "argument --repeats: '0' is not allowed"),
        (["--gradient-layouts", "0"], "argument --gradient-layouts: '0' is not allowed"),
        (["--cost-layouts", "-1"], "allowed: an integer ≥ 0"),
        (
            ["--cost-outputs", "delta_pp,foo"],
            "argument --cost-outputs: foo unknown; allowed: delta_pp,",
        ),
        (["--latency", "--repeats", "0"], "argument --repeats: '0' is not allowed"),
        (  # an empty name: not every entry (minutes), nor a blank in the error
            ["--latency", "--entries", ""],
            "argument --entries: '' has an empty name; allowed: comma-separated names of readme,",
        ),
        (
            ["--latency", "--entries", "readme,,solve"],
            "argument --entries: 'readme,,solve' has an empty name",
        ),
        (
            ["--latency", "--entries", "solve,foo"],
            "argument --entries: foo unknown; allowed: readme,",
        ),
        (
            ["--latency", "--gradient-layouts", "1,x"],
            "argument --gradient-layouts: 'x' is not allowed",
        ),
        (
            ["--json", "/nonexistent/folder/x.json"],
            "argument --json: '/nonexistent/folder/x.json' is not allowed (the folder "
            "/nonexistent/folder does not exist)",
        ),
        (["--json", "."], "argument --json: '.' is not allowed (it is a folder)"),
        (["--latency", "--json", ""], "argument --json: '' is not allowed (it is empty)"),
    ],
)
def test_bad_arguments_exit_2_with_one_line(argv, says, capsys):
    """A bad argument stops the bench before anything is measured: exit status 2 and one line
    naming the argument, the value and what is allowed (no usage block, no traceback)."""
    from tripodjax import bench

    with pytest.raises(SystemExit) as stopped:
        bench.main(argv)
    assert stopped.value.code == 2
    err = capsys.readouterr().err
    assert says in err and err.count("\n") == 1 and err.endswith("(see --help)\n")


def test_the_optimiser_bench_checks_its_json_file_first(capsys):
    from tripodjax.optimize import bench

    with pytest.raises(SystemExit) as stopped:
        bench.main(["--json", "/nonexistent/folder/x.json"])
    assert stopped.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "the folder /nonexistent/folder does not exist" in err


def test_figures_that_cannot_be_written_are_one_line_and_leave_nothing(tmp_path, capsys):
    from tripodjax._cli import write_json

    folder = tmp_path / "figures"
    folder.mkdir()
    assert write_json("bench", str(folder / "a.json"), {"x": 1.5})
    assert json.loads((folder / "a.json").read_text()) == {"x": 1.5}
    (folder / "b.json").mkdir()  # in the way
    assert not write_json("bench", str(folder / "b.json"), {"x": 1.5})
    err = capsys.readouterr().err
    assert err.startswith("bench: cannot write ") and err.count("\n") == 1
    assert sorted(p.name for p in folder.iterdir()) == ["a.json", "b.json"]  # no temporary file


def test_the_help_names_the_latency_mode_and_its_help_its_options(capsys):
    """``--help`` says the latency mode exists; ``--latency --help`` lists its options once
    each, with their defaults (the switch itself is not offered again)."""
    from tripodjax import bench

    for argv in (["--help"], ["--latency", "--help"]):
        with pytest.raises(SystemExit) as stopped:
            bench.main(argv)
        assert stopped.value.code == 0
    main_help, latency_help = capsys.readouterr().out.split("usage: ")[1:]
    assert "python -m tripodjax.bench --latency [--help]" in " ".join(main_help.split())
    usage = latency_help.splitlines()[0]
    assert usage.count("--latency") == 1 and "--repeats N" in usage
    assert "(default 3)" in " ".join(latency_help.split())
