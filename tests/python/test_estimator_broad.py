"""The attitude estimator on real IMU data (BROAD), beside VQF in the same run.

Runs tools/bench_estimator.py: `autopilot replay` with the tilt/heading filter (ATT_MODE 1) and
with Castillo's observer (ATT_MODE 0), and VQF (pinned), over the twelve shared trials, scored by
the benchmark's own scorer. The replay is deterministic, so the figures reached are asserted.
The same run replays every trial from the middle of its motion and measures how long the
estimators take to converge.
"""
import json
import subprocess
import sys
from pathlib import Path

from conftest import ROOT, binary

TRIALS = ROOT.parent / "shared" / "benchmarks" / "broad"
# The mean total RMSE the tilt/heading filter reached (2.02°), with room for rounding only.
MEAN_REACHED_DEG = 2.05
# From the middle of the motion, half the starts converge within this (measured: the
# inclination in 2.5 s, the whole attitude in 3.1 s; VQF 2.4 s and 2.6 s).
MEDIAN_CONVERGENCE_S = 4.0


def test_tilt_heading_filter_beats_vqf_on_broad(tmp_path):
    assert TRIALS.is_dir(), f"{TRIALS}: the shared BROAD trials are missing"
    out = tmp_path / "bench.json"
    run = subprocess.run(
        [sys.executable, str(ROOT / "tools" / "bench_estimator.py"), "--autopilot",
         str(binary("autopilot")), "--trials", str(TRIALS), "--json", str(out)],
        capture_output=True, text=True, timeout=600)
    print(run.stdout)
    assert run.returncode == 0, run.stderr
    figures = json.loads(out.read_text())
    trials, mean = figures["trials"], figures["mean"]
    assert len(trials) == 12
    ours, vqf = mean["tilt_heading"]["total"], mean["vqf"]["total"]
    # VQF's published figure on these files, reproduced in this run.
    assert abs(vqf - 2.87) < 0.01, vqf
    assert ours < vqf, (ours, vqf)
    assert ours <= MEAN_REACHED_DEG, ours
    for t in trials:
        assert t["tilt_heading"]["total"] <= 2 * t["vqf"]["total"], t
    # The paper's observer, for scale: the tilt/heading filter is its replacement.
    assert mean["castillo"]["total"] > 5 * ours
    # A log that does not start at rest: converged within seconds.
    settle = figures["convergence_s"]["tilt_heading"]
    for k in ("inclination", "total"):
        assert settle[k]["median"] <= MEDIAN_CONVERGENCE_S, (k, settle[k])
