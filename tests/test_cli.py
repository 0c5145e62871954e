"""The command line runs the built-in examples and reports their reference errors."""

import subprocess
import sys

from flexmbd.cli import main


def test_examples_are_listed(capsys):
    assert main(["examples"]) == 0
    out = capsys.readouterr().out
    assert "four-bar" in out and "pendulum" in out


def test_run_pendulum_reports_the_reference_errors(capsys):
    assert main(["run", "pendulum", "--end", "1.0", "--step", "1e-3"]) == 0
    out = capsys.readouterr().out
    assert "position error at t = 0.5 s" in out and "steps" in out


def test_python_dash_m_runs_the_default_example():
    run = subprocess.run(
        [sys.executable, "-m", "flexmbd", "run", "--end", "0.5", "--step", "1e-3"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert run.returncode == 0, run.stderr
    assert "IFToMM A02" in run.stdout
