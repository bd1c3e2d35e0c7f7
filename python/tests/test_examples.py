"""The example scripts run (headless), and the fan-out pattern gives what the in-process
Monte Carlo gives."""

import concurrent.futures
import os
import subprocess
import sys
from pathlib import Path

import pytest

import dmech

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


@pytest.mark.parametrize("script, output", [
    ("plan_track_eight.py", "eight_tracking.png"),
    ("diagnose_log.py", "diagnosis_residuals.png"),
])
def test_example_runs_and_plots(script, output, tmp_path):
    env = dict(os.environ, MPLBACKEND="Agg")
    r = subprocess.run([sys.executable, str(EXAMPLES / script), str(tmp_path)],
                       capture_output=True, text=True, env=env)
    assert r.returncode == 0, r.stderr
    assert (tmp_path / output).stat().st_size > 10_000


def test_fan_out_over_processes_is_the_monte_carlo():
    sys.path.insert(0, str(EXAMPLES))
    try:
        import fan_out
    finally:
        sys.path.pop(0)
    plan = dmech.wip.plan("eight")
    with concurrent.futures.ProcessPoolExecutor(max_workers=2) as pool:
        figures = fan_out.monte_carlo(plan, [1, 2, 3], pool)
    mc = dmech.wip.track(plan, monte_carlo=3)
    assert sorted(figures) == [1, 2, 3]
    for s, r in zip((1, 2, 3), mc.runs):
        assert {k: figures[s][k] for k in r} == r  # the same run, figure for figure
