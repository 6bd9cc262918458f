"""``python -m tripodjax``: the kinematics report."""

import subprocess
import sys


def run(*args):
    return subprocess.run([sys.executable, "-m", "tripodjax", *args], capture_output=True, text=True, timeout=300)


def test_default_report_is_case_N():
    result = run()
    assert result.returncode == 0, result.stderr
    assert "seed case N" in result.stdout
    assert "2.830 %" in result.stdout and "4.7159e-03 rad" in result.stdout


def test_bad_layout_exits_2_with_a_one_line_message():
    result = run("--gamma0", "60")
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "Layout.gamma0" in lines[0] and "45°" in lines[0]
