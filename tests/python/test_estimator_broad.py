"""The attitude estimator on real IMU data (BROAD), beside VQF in the same run.

Runs tools/bench_estimator.py: `autopilot replay` with the tilt/heading filter (ATT_MODE 1) and
with Castillo's observer (ATT_MODE 0), and VQF (pinned), over the twelve trials, scored as the
benchmark defines its errors. The replay is deterministic, so the figures reached are asserted.
The same run replays every trial from the middle of its motion and measures how long the
estimators take to converge, how long they take to recover from a gyro glitch at rest, how far
the heading drifts without the magnetometer, and how fast synthetic flights started in motion
with a biased gyro converge (tools/synthetic_flight.py).

The data is not in the repository: tools/broad.py finds it (or fetches it). Without it the test is
skipped, saying how to fetch it; with AUTOPILOT_REQUIRE_BROAD=1 (CI) it fails instead.
"""
import json
import os
import subprocess
import sys

import pytest

from conftest import ROOT, binary

sys.path.insert(0, str(ROOT / "tools"))
import broad  # noqa: E402
# The mean total RMSE the tilt/heading filter reached (2.02°), with room for rounding only.
MEAN_REACHED_DEG = 2.05
# From the middle of the motion, half the starts converge within this (measured: the
# inclination in 2.5 s, the whole attitude in 3.1 s; VQF 2.4 s and 2.6 s).
MEDIAN_CONVERGENCE_S = 4.0


def broad_trials():
    """The trials' folder, checked against their pinned checksums; skips (or, where CI requires
    the data, fails) when there is none."""
    trials = broad.trials_dir()
    if trials is None:
        if os.environ.get(broad.ENV_REQUIRED) == "1":
            pytest.fail(f"{broad.ENV_REQUIRED}=1 and {broad.why_none()}")
        pytest.skip(broad.why_none())
    problems = broad.verify(trials)
    assert not problems, "\n".join(problems)
    return trials


def test_tilt_heading_filter_beats_vqf_on_broad(tmp_path):
    trials = broad_trials()
    out = tmp_path / "bench.json"
    run = subprocess.run(
        [sys.executable, str(ROOT / "tools" / "bench_estimator.py"), "--autopilot",
         str(binary("autopilot")), "--trials", str(trials), "--json", str(out)],
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
    # Knocked off at rest by up to 179°: the tilt within 2° in 2 s on every trial (VQF takes
    # 5-12 s), and the whole attitude within 5° in the median no later than VQF.
    glitch = figures["glitch_s"]
    for deg, ours in glitch["tilt_heading"].items():
        assert max(ours["inclination"]) <= 2.0, (deg, ours)
        median = sorted(ours["total"])[len(ours["total"]) // 2]
        vqf = sorted(glitch["vqf"][deg]["total"])[len(ours["total"]) // 2]
        assert median <= vqf, (deg, median, vqf)
    # Without the magnetometer: the heading drifts no more than VQF's 6-axis estimate's, the
    # tilt as with it (measured: 6.2° against 6.3° of mean drift, 0.69° inclination both).
    no_mag = figures["no_mag"]
    assert no_mag["tilt_heading"]["drift_deg"] <= no_mag["vqf"]["drift_deg"] + 0.1, no_mag
    assert no_mag["tilt_heading"]["inclination_rms_deg"] <= mean["tilt_heading"]["inclination"] + 0.05
    # A start in motion with a 1.2°/s gyro bias on the synthetic flights in a clean field: within
    # 3° from 5 s on every seed (measured up to 2.75°; VQF 4.6-8.0°), and from 10 s on no worse
    # than VQF (0.26° RMS against 8.0°).
    synthetic = figures["synthetic_start"]
    assert max(synthetic["tilt_heading"]["worst_5_10_deg"]) <= 3.0, synthetic
    for ours, vqf in zip(synthetic["tilt_heading"]["rms_10_deg"], synthetic["vqf"]["rms_10_deg"]):
        assert ours <= vqf, synthetic
