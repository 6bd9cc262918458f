"""``python -m tripodjax``: the kinematics report."""

import re
import subprocess
import sys


def run(*args):
    return subprocess.run(
        [sys.executable, "-m", "tripodjax", *args], capture_output=True, text=True, timeout=300
    )


def test_default_report_is_case_N():
    result = run()
    assert result.returncode == 0, result.stderr
    assert "seed case N" in result.stdout
    # The seed's §2.11.3: Δ amplitude 4.7e-3 rad, irregularity 2.82 % (2.83 % in the brief's check).
    amplitude = float(
        re.search(r"Δ amplitude \(delta_pp/2\)\s+([0-9.e+-]+) rad", result.stdout).group(1)
    )
    irregularity = float(re.search(r"irregularity\s+([0-9.]+) %", result.stdout).group(1))
    assert abs(amplitude - 4.7e-3) < 0.05e-3 and 2.82 <= irregularity <= 2.83


def test_bad_layout_exits_2_with_a_one_line_message():
    result = run("--gamma0", "60")
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    # The message names the command's own option (--gamma0, in degrees), not the Layout field.
    assert len(lines) == 1 and "--gamma0 = 60.0" in lines[0] and "45°" in lines[0]
    # the same prefix and ending as the parser's own argument errors
    assert lines[0].startswith("python -m tripodjax: --gamma0") and lines[0].endswith("--help)")


def test_an_argument_argparse_rejects_is_one_line_too():
    """A value of the wrong type or an unknown choice: argparse's message in one line (no usage
    block), exit status 2, as for every command (tripodjax._cli.ArgumentParser)."""
    for args, says in (
        (("--l", "abc"), "argument --l: invalid float value: 'abc'"),
        (("--solver", "fast"), "argument --solver: invalid choice: 'fast'"),
        (
            ("--n-theta", "100"),
            "argument --n-theta: '100' is not allowed; allowed: an integer ≥ 6, a multiple of 6",
        ),
    ):
        result = run(*args)
        assert result.returncode == 2
        assert result.stderr.startswith(f"python -m tripodjax: {says}")
        assert result.stderr.count("\n") == 1 and result.stderr.endswith("(see --help)\n")


def test_a_reader_that_left_early_ends_the_report_quietly():
    """``python -m tripodjax | head -1``: the pipe's reader gone before the report is printed
    ends the command with 141 (128 + SIGPIPE) and no traceback."""
    import os

    read, write = os.pipe()
    os.close(read)  # the reader has left
    try:
        result = subprocess.run(
            [sys.executable, "-m", "tripodjax", "--n-theta", "36"],
            stdout=write,
            stderr=subprocess.PIPE,
            text=True,
            timeout=300,
        )
    finally:
        os.close(write)
    assert result.returncode == 141, result.stderr
    assert result.stderr == ""
