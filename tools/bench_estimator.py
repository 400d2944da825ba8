#!/usr/bin/env python3
"""Attitude-estimator benchmark on real IMU data: `autopilot replay` and VQF, same files, same run.

    tools/bench_estimator.py [--autopilot BIN] [--trials DIR] [--params FILE] [--json OUT]

For every BROAD trial in DIR (default: the folder tools/broad.py finds; `tools/broad.py fetch`
brings them), runs
`autopilot replay` with each of the project's attitude estimators (ATT_MODE 1, the tilt/heading
filter; ATT_MODE 0, Castillo's q-method observer; both with their default gains and only the
site's magnetic field set) and VQF (PyPI `vqf`, default parameters) on the same samples, scores
them as the benchmark does (tools/broad_score.py), and prints one table: total, heading and
inclination RMSE per trial and the means.

Then the replay of a log that does not start at rest: every trial is cut at 20, 40, 60 and 80 %
of its motion and replayed from there (the tilt/heading filter, and VQF on the same cut), and the
time each takes to converge is measured against the truth: until the inclination error stays
within 2° (and the total error within 5°) for 5 s.

Then the recovery from a large error at rest: 5 s into each trial's last rest, one gyro sample
turns the estimate by 10°, 45°, 90° or 179° (a gyro that saturated or glitched), and the time
until the errors stay within the same limits is measured, for both.

Then a start in motion with a MEMS gyro's turn-on bias: the same cuts, 1.2°/s added to each
gyro axis, ours and VQF on the same file: the largest error from 5 s to 10 s and the RMS from
10 s on. And the same on synthetic multirotor flights in a clean field
(tools/synthetic_flight.py: hover with oscillations, 60° banks, 450°/s spins, a turn; no rest),
where the magnetometer can show what BROAD's indoor field cannot.

And without the magnetometer: every trial replayed with its field removed, VQF's 6-axis
estimate beside, the heading's drift scored against the truth after taking out the offset of its
first second (with no heading reference the start is arbitrary), and the inclination as before.
--json writes the figures for tests. Needs numpy and vqf (tests/requirements.txt).
"""
import argparse
import concurrent.futures
import gzip
import json
import math
import os
import subprocess
import sys
import tempfile
import time

import numpy as np
from vqf import VQF

import broad
import broad_score
import synthetic_flight

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
# The site's field (BROAD README: medians over the undisturbed rest phases; truth referenced to
# magnetic north).
SITE = {"mag_inclination_deg": 69.2, "mag_intensity_gauss": 0.437, "mag_declination_deg": 0.0}
# The project's estimators, by ATT_MODE.
MODES = {"tilt_heading": 1, "castillo": 0}
# q_ned_from_enu: VQF's world frame is ENU (x east, y north, z up).
NED_FROM_ENU = np.array([0.0, math.sqrt(0.5), math.sqrt(0.5), 0.0])


def quat_mul(a, b):
    """Hamilton product of a (4,) with rows of b (n, 4)."""
    aw, ax, ay, az = a
    w, x, y, z = b.T
    return np.stack([aw * w - ax * x - ay * y - az * z,
                     aw * x + ax * w + ay * z - az * y,
                     aw * y - ax * z + ay * w + az * x,
                     aw * z + ax * y - ay * x + az * w], 1)


def run_vqf(trial_csv, out_csv):
    """VQF on the trial's FRD samples: it gives q_enu_from_frd; written as q_ned_from_frd."""
    d = np.genfromtxt(trial_csv, delimiter=",", names=True)
    ts = float(np.median(np.diff(d["t"])))
    col = lambda *k: np.ascontiguousarray(np.stack([d[c] for c in k], 1))
    v = VQF(ts)
    # VQF's magnetometer unit is free (it learns the norm); µT keeps its thresholds in range.
    out = v.updateBatch(col("gx", "gy", "gz"), col("ax", "ay", "az"), col("mx", "my", "mz") * 100)
    q = quat_mul(NED_FROM_ENU, out["quat9D"])
    np.savetxt(out_csv, np.column_stack([d["t"], q]), delimiter=",", header="t,qw,qx,qy,qz",
               comments="", fmt="%.9f")


def estimate(who, autopilot, params, trial_csv, est_csv):
    """The estimate of `who` (the tilt/heading filter or VQF) over the trial: its CSV's columns."""
    if who == "vqf":
        run_vqf(trial_csv, est_csv)
    else:
        subprocess.run([autopilot, "replay", "--input", trial_csv, "--output", est_csv,
                        "--params", params], check=True)
    return np.genfromtxt(est_csv, delimiter=",", names=True)


# Where the convergence runs cut the motion, and what converged means (deg, and for how long).
CUTS = (0.2, 0.4, 0.6, 0.8)
CONVERGED = {"inclination": 2.0, "total": 5.0}
HOLD_S = 5.0


def settling_time(t, err, limit):
    """The time from which err stays within limit for HOLD_S (or to the end of the log)."""
    start = 0
    for i in np.flatnonzero(err > limit):
        if t[i] - t[start] >= HOLD_S:
            break
        start = i + 1
    return float(t[min(start, len(t) - 1)] - t[0])


def convergence(autopilot, params, trial_csv, tmp):
    """Convergence times (s) of the tilt/heading filter and VQF replaying the trial from each cut
    of its motion: {who: {"inclination": [...], "total": [...]}}."""
    with open(trial_csv) as f:
        header, *lines = f.read().splitlines()
    d = np.genfromtxt(trial_csv, delimiter=",", names=True)
    quat = lambda x: np.stack([x[k] for k in ("qw", "qx", "qy", "qz")], 1)
    moving = np.flatnonzero(d["movement"] == 1)
    out = {who: {k: [] for k in CONVERGED} for who in ("tilt_heading", "vqf")}
    for frac in CUTS:
        cut = moving[0] + int(frac * (moving[-1] - moving[0]))
        cut_csv = os.path.join(tmp, "cut.csv")
        with open(cut_csv, "w") as f:
            f.write("\n".join([header] + lines[cut:]) + "\n")
        truth = quat(d)[cut:]
        known = np.isfinite(truth[:, 0])
        for who in out:
            e = estimate(who, autopilot, params, cut_csv, os.path.join(tmp, f"cut_{who}.csv"))
            errors = {k: np.degrees(v) for k, v in
                      broad_score.error_angles(quat(e)[known], truth[known]).items()}
            for k, limit in CONVERGED.items():
                out[who][k].append(settling_time(e["t"][known], errors[k], limit))
    return out


# The gyro bias of a start in motion (deg/s per axis: a MEMS gyro's turn-on bias), and the
# windows scored (s after the start): the largest error from 5 s to 10 s, the RMS from 10 s on.
START_BIAS_DEG_S = (1.2, -1.2, 1.2)


def biased_start(autopilot, params, trial_csv, tmp):
    """The trial cut at each of CUTS of its motion, the gyro biased by START_BIAS_DEG_S: for the
    tilt/heading filter and VQF, {who: {"worst_5_10_deg": [...], "rms_10_deg": [...]}} (total
    error)."""
    with open(trial_csv) as f:
        header, *lines = f.read().splitlines()
    cols = header.split(",")
    gyro = [cols.index(c) for c in ("gx", "gy", "gz")]
    bias = [math.radians(b) for b in START_BIAS_DEG_S]
    d = np.genfromtxt(trial_csv, delimiter=",", names=True)
    quat = lambda x: np.stack([x[k] for k in ("qw", "qx", "qy", "qz")], 1)
    moving = np.flatnonzero(d["movement"] == 1)
    out = {who: {"worst_5_10_deg": [], "rms_10_deg": []} for who in ("tilt_heading", "vqf")}
    for frac in CUTS:
        cut = moving[0] + int(frac * (moving[-1] - moving[0]))
        cut_csv = os.path.join(tmp, "biased.csv")
        with open(cut_csv, "w") as f:
            f.write(header + "\n")
            for line in lines[cut:]:
                row = line.split(",")
                for c, b in zip(gyro, bias):
                    row[c] = f"{float(row[c]) + b:.9g}"
                f.write(",".join(row) + "\n")
        truth = quat(d)[cut:]
        known = np.isfinite(truth[:, 0])
        for who in out:
            e = estimate(who, autopilot, params, cut_csv, os.path.join(tmp, f"biased_{who}.csv"))
            score_start(out[who], e, truth, known)
    return out


def score_start(out, e, truth, known):
    """Appends to out["worst_5_10_deg"] and out["rms_10_deg"] the estimate e's largest total
    error from 5 s to 10 s after its start and its RMS from 10 s on, against truth where known."""
    quat = lambda x: np.stack([x[k] for k in ("qw", "qx", "qy", "qz")], 1)
    total = np.degrees(broad_score.error_angles(quat(e)[known], truth[known])["total"])
    t = e["t"][known] - e["t"][0]
    # Ours has no estimate until it aligns: an unknown attitude counts as 180° off.
    total = np.where(np.isfinite(total), total, 180.0)
    out["worst_5_10_deg"].append(float(np.max(total[(t >= 5.0) & (t < 10.0)])))
    out["rms_10_deg"].append(float(np.sqrt(np.mean(total[t >= 10.0] ** 2))))


# The synthetic flights' seeds (tools/synthetic_flight.py).
SYNTHETIC_SEEDS = range(1, 7)


def synthetic_start(autopilot, params, tmp):
    """The synthetic flights in a clean field, started in motion with the gyro biased by
    START_BIAS_DEG_S: for the tilt/heading filter and VQF, {who: {"worst_5_10_deg": [...],
    "rms_10_deg": [...]}} (total error), one per seed."""
    quat = lambda x: np.stack([x[k] for k in ("qw", "qx", "qy", "qz")], 1)
    out = {who: {"worst_5_10_deg": [], "rms_10_deg": []} for who in ("tilt_heading", "vqf")}
    for seed in SYNTHETIC_SEEDS:
        path = os.path.join(tmp, f"synthetic_{seed}.csv")
        synthetic_flight.write(path, synthetic_flight.flight(seed, START_BIAS_DEG_S))
        d = np.genfromtxt(path, delimiter=",", names=True)
        for who in out:
            e = estimate(who, autopilot, params, path, os.path.join(tmp, f"synthetic_{who}.csv"))
            score_start(out[who], e, quat(d), np.ones(len(d), bool))
    return out


# The glitches at rest (deg), about one axis off every body axis.
GLITCHES_DEG = (10.0, 45.0, 90.0, 179.0)
GLITCH_AXIS = np.array([1.0, 0.5, 0.2]) / np.linalg.norm([1.0, 0.5, 0.2])


def glitch_recovery(autopilot, params, trial_csv, tmp):
    """Recovery times (s) from a gyro glitch 5 s into the trial's last rest, by glitch size:
    {who: {deg: {"inclination": s, "total": s}}}."""
    with open(trial_csv) as f:
        header, *lines = f.read().splitlines()
    d = np.genfromtxt(trial_csv, delimiter=",", names=True)
    quat = lambda x: np.stack([x[k] for k in ("qw", "qx", "qy", "qz")], 1)
    moving = np.flatnonzero(d["movement"] == 1)
    g = moving[-1] + 1 + int(5.0 / float(np.median(np.diff(d["t"]))))
    cols = header.split(",")
    gyro = [cols.index(c) for c in ("gx", "gy", "gz")]
    truth = quat(d)[g:]
    known = np.isfinite(truth[:, 0])
    out = {who: {} for who in ("tilt_heading", "vqf")}
    for deg in GLITCHES_DEG:
        row = lines[g].split(",")
        turn = GLITCH_AXIS * math.radians(deg) / (d["t"][g] - d["t"][g - 1])
        for k, c in enumerate(gyro):
            row[c] = f"{float(row[c]) + float(turn[k]):.9g}"
        glitched = os.path.join(tmp, "glitched.csv")
        with open(glitched, "w") as f:
            f.write("\n".join([header] + lines[:g] + [",".join(row)] + lines[g + 1:]) + "\n")
        for who in out:
            e = estimate(who, autopilot, params, glitched,
                         os.path.join(tmp, f"glitched_{who}.csv"))
            after = e["t"] >= d["t"][g]
            errors = {k: np.degrees(v) for k, v in
                      broad_score.error_angles(quat(e)[after][known], truth[known]).items()}
            out[who][deg] = {k: settling_time(e["t"][after][known], errors[k], limit)
                             for k, limit in CONVERGED.items()}
    return out


def no_magnetometer(autopilot, params, trial_csv, tmp):
    """The trial without its magnetometer, ours and VQF's 6-axis estimate: {who: {"drift_deg":
    the heading error at the end, "heading_rms_deg", "inclination_rms_deg"}}, the heading's
    offset over the first second taken out."""
    with open(trial_csv) as f:
        header, *lines = f.read().splitlines()
    cols = header.split(",")
    mag = [cols.index(c) for c in ("mx", "my", "mz")]
    blind = os.path.join(tmp, "no_mag.csv")
    with open(blind, "w") as f:
        f.write(header + "\n")
        for line in lines:
            row = line.split(",")
            for c in mag:
                row[c] = "nan"
            f.write(",".join(row) + "\n")
    d = np.genfromtxt(trial_csv, delimiter=",", names=True)
    quat = lambda x: np.stack([x[k] for k in ("qw", "qx", "qy", "qz")], 1)
    truth = quat(d)
    known = np.isfinite(truth[:, 0])
    t = d["t"][known]
    out = {}
    for who in ("tilt_heading", "vqf"):
        est_csv = os.path.join(tmp, f"no_mag_{who}.csv")
        if who == "vqf":
            v = VQF(float(np.median(np.diff(d["t"]))))
            col = lambda *k: np.ascontiguousarray(np.stack([d[c] for c in k], 1))
            q = quat_mul(NED_FROM_ENU, v.updateBatch(col("gx", "gy", "gz"),
                                                     col("ax", "ay", "az"))["quat6D"])
        else:
            subprocess.run([autopilot, "replay", "--input", blind, "--output", est_csv,
                            "--params", params], check=True)
            q = quat(np.genfromtxt(est_csv, delimiter=",", names=True))
        a, b = q[known], truth[known]
        # The signed heading error: the z part of a ⊗ b⁻¹ over its scalar part.
        w = np.sum(a * b, 1)
        z = -a[:, 0] * b[:, 3] + a[:, 3] * b[:, 0] - a[:, 1] * b[:, 2] + a[:, 2] * b[:, 1]
        heading = np.degrees(2 * np.arctan(z / w))
        # From the estimate's first sample (ours waits for its alignment, a second at rest).
        ok = np.isfinite(heading) & (t >= t[np.isfinite(heading)][0])
        heading, tt = heading[ok], t[ok]
        heading -= np.mean(heading[tt < tt[0] + 1.0])
        heading = (heading + 180.0) % 360.0 - 180.0
        moving = (d["movement"][known] == 1) & ok
        incl = np.degrees(broad_score.error_angles(a[moving], b[moving])["inclination"])
        out[who] = {"drift_deg": float(np.mean(heading[tt > tt[-1] - 1.0])),
                    "heading_rms_deg": float(np.sqrt(np.mean(heading ** 2))),
                    "inclination_rms_deg": float(np.sqrt(np.mean(incl ** 2)))}
    return out


def score(trial_gz, est_csv):
    r = broad_score.score(trial_gz, est_csv)
    return {k: r[k + "_rmse_deg"] for k in ("total", "heading", "inclination")}


def bench_trial(job):
    """One trial: both modes replayed and scored, VQF run and scored, the convergence from the
    middle of the motion. In a directory of its own (trials run side by side)."""
    autopilot, trial_gz, params, tmp = job
    name = os.path.basename(trial_gz)
    tmp = tempfile.mkdtemp(dir=tmp)
    trial = os.path.join(tmp, name[:-3])
    with gzip.open(trial_gz, "rb") as src, open(trial, "wb") as dst:
        dst.write(src.read())
    row = {"trial": name[:-7], "replay_s": 0.0}
    for who in MODES:
        est = os.path.join(tmp, f"{who}.csv")
        t0 = time.perf_counter()
        subprocess.run([autopilot, "replay", "--input", trial, "--output", est,
                        "--params", params[who]], check=True)
        row["replay_s"] += time.perf_counter() - t0
        row[who] = score(trial_gz, est)
    run_vqf(trial, os.path.join(tmp, "vqf.csv"))
    row["vqf"] = score(trial_gz, os.path.join(tmp, "vqf.csv"))
    row["convergence_s"] = convergence(autopilot, params["tilt_heading"], trial, tmp)
    row["biased_start"] = biased_start(autopilot, params["tilt_heading"], trial, tmp)
    row["glitch_s"] = glitch_recovery(autopilot, params["tilt_heading"], trial, tmp)
    row["no_mag"] = no_magnetometer(autopilot, params["tilt_heading"], trial, tmp)
    os.remove(trial)
    return row


def params_file(tmp, params, mode):
    """A parameter file for ATT_MODE `mode` in tmp: `params` (a file) or the site's field only."""
    base = open(params).read() if params else \
        "[attitude]\n" + "".join(f"{k} = {v}\n" for k, v in SITE.items())
    path = os.path.join(tmp, f"mode_{mode}.toml")
    with open(path, "w") as f:
        f.write(base.replace("[attitude]\n", f"[attitude]\nmode = {mode}\n", 1))
    return path


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--autopilot", default=os.path.join(ROOT, "target", "release", "autopilot"))
    ap.add_argument("--trials", help="a folder of BROAD trials (NN_name.csv.gz); default: the "
                    "one tools/broad.py finds")
    ap.add_argument("--params", help="a flight-parameter file for both modes; default: the "
                    "site's field only")
    ap.add_argument("--json", help="write the figures here")
    a = ap.parse_args()
    if a.trials is None:
        found = broad.trials_dir()
        if found is None:
            sys.exit(broad.why_none())
        a.trials = str(found)
    trials = sorted(f for f in os.listdir(a.trials) if f.endswith(".csv.gz")) \
        if os.path.isdir(a.trials) else []
    if not trials:
        sys.exit(f"{a.trials}: no BROAD trials (NN_name.csv.gz) there")
    if not os.access(a.autopilot, os.X_OK):
        sys.exit(f"{a.autopilot}: not found; build it (cargo build --release -p autopilot)")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        params = {who: params_file(tmp, a.params, mode) for who, mode in MODES.items()}
        # The trials are independent: two at a time (the machines this runs on have two
        # cores; each replay is one process).
        jobs = [(a.autopilot, os.path.join(a.trials, name), params, tmp)
                for name in trials]
        with concurrent.futures.ProcessPoolExecutor(max_workers=2) as pool:
            for n, row in enumerate(pool.map(bench_trial, jobs), 1):
                rows.append(row)
                print(f"[{n}/{len(trials)}] {row['trial']}", file=sys.stderr, flush=True)
    who_all = list(MODES) + ["vqf"]
    mean = {who: {k: sum(r[who][k] for r in rows) / len(rows)
                  for k in ("total", "heading", "inclination")} for who in who_all}
    print("RMSE (deg) on BROAD, scored as the benchmark defines it, same files, same run: total / heading / "
          "inclination for autopilot replay with ATT_MODE 1 (tilt/heading) and 0 (Castillo), "
          "and VQF (vqf, default parameters)")
    print(f"| {'trial':<44} | tilt/heading (1) | Castillo (0) | VQF |")
    print(f"|{'-' * 46}|---:|---:|---:|")
    cell = lambda e: f"{e['total']:.2f} / {e['heading']:.2f} / {e['inclination']:.2f}"
    for r in rows + [{"trial": "**mean**", **mean}]:
        print(f"| {r['trial']:<44} | " + " | ".join(cell(r[w]) for w in who_all) + " |")
    worst = max(rows, key=lambda r: r["tilt_heading"]["total"] / r["vqf"]["total"])
    ratio = worst["tilt_heading"]["total"] / worst["vqf"]["total"]
    print(f"tilt/heading: worst ratio to VQF {ratio:.2f} ({worst['trial']}); "
          f"replay time {sum(r['replay_s'] for r in rows):.1f} s")
    settle = {who: {k: [x for r in rows for x in r["convergence_s"][who][k]] for k in CONVERGED}
              for who in ("tilt_heading", "vqf")}
    summary = {who: {k: {"median": float(np.median(v)), "p75": float(np.percentile(v, 75)),
                         "max": float(np.max(v))} for k, v in by.items()}
               for who, by in settle.items()}
    print(f"\nReplay from the middle of the motion ({len(rows)} trials cut at "
          f"{', '.join(f'{c:.0%}' for c in CUTS)}): seconds until the inclination error stays "
          f"within {CONVERGED['inclination']:.0f}° and the total within "
          f"{CONVERGED['total']:.0f}° for {HOLD_S:.0f} s; median / 75th percentile / largest")
    print("| | inclination | total |")
    print("|---|---:|---:|")
    for who, name in (("tilt_heading", "tilt/heading (1)"), ("vqf", "VQF")):
        cells = [f"{summary[who][k]['median']:.1f} / {summary[who][k]['p75']:.1f} / "
                 f"{summary[who][k]['max']:.1f}" for k in CONVERGED]
        print(f"| {name} | " + " | ".join(cells) + " |")
    start = {who: {k: [x for r in rows for x in r["biased_start"][who][k]]
                   for k in ("worst_5_10_deg", "rms_10_deg")} for who in ("tilt_heading", "vqf")}
    print(f"\nA start in motion with a gyro bias of {START_BIAS_DEG_S} deg/s ({len(rows)} trials "
          f"cut at {', '.join(f'{c:.0%}' for c in CUTS)}): the largest total error from 5 s to "
          "10 s (median / largest) and the RMS total error from 10 s on (mean / largest), deg")
    print("| | error 5–10 s | RMS from 10 s |")
    print("|---|---:|---:|")
    for who, name in (("tilt_heading", "tilt/heading (1)"), ("vqf", "VQF")):
        w, r = start[who]["worst_5_10_deg"], start[who]["rms_10_deg"]
        print(f"| {name} | {np.median(w):.2f} / {np.max(w):.2f} | "
              f"{np.mean(r):.2f} / {np.max(r):.2f} |")
    with tempfile.TemporaryDirectory() as tmp:
        synthetic = synthetic_start(a.autopilot, params_file(tmp, a.params, MODES["tilt_heading"]),
                                    tmp)
    print(f"\nThe same start in motion on synthetic multirotor flights in a clean field "
          f"(tools/synthetic_flight.py, seeds {SYNTHETIC_SEEDS.start}–{SYNTHETIC_SEEDS.stop - 1}): "
          "the largest total error from 5 s to 10 s and the RMS total error from 10 s on, deg")
    print("| | error 5–10 s, by seed | largest | RMS from 10 s, by seed | mean |")
    print("|---|---|---:|---|---:|")
    for who, name in (("tilt_heading", "tilt/heading (1)"), ("vqf", "VQF")):
        w, r = synthetic[who]["worst_5_10_deg"], synthetic[who]["rms_10_deg"]
        print(f"| {name} | {' '.join(f'{x:.2f}' for x in w)} | {max(w):.2f} | "
              f"{' '.join(f'{x:.2f}' for x in r)} | {np.mean(r):.2f} |")
    glitch = {who: {deg: {k: [r["glitch_s"][who][deg][k] for r in rows] for k in CONVERGED}
                    for deg in GLITCHES_DEG} for who in ("tilt_heading", "vqf")}
    print(f"\nA gyro glitch 5 s into each trial's last rest ({len(rows)} trials): seconds until "
          f"the inclination error stays within {CONVERGED['inclination']:.0f}° and the total "
          f"within {CONVERGED['total']:.0f}° for {HOLD_S:.0f} s; median / largest")
    print("| glitch | tilt/heading (1): inclination | total | VQF: inclination | total |")
    print("|---|---:|---:|---:|---:|")
    for deg in GLITCHES_DEG:
        cells = [f"{np.median(v):.1f} / {np.max(v):.1f}"
                 for who in ("tilt_heading", "vqf") for v in glitch[who][deg].values()]
        print(f"| {deg:.0f}° | " + " | ".join(cells) + " |")
    print(f"\nWithout the magnetometer ({len(rows)} trials; the heading's first-second offset "
          "taken out): heading drift at the end, heading RMS, inclination RMS (deg); mean of |drift|")
    print("| trial | tilt/heading (1) | VQF 6-axis |")
    print("|---|---:|---:|")
    cell = lambda e: (f"{e['drift_deg']:+.1f} / {e['heading_rms_deg']:.1f} / "
                      f"{e['inclination_rms_deg']:.2f}")
    for r in rows:
        print(f"| {r['trial']} | " + " | ".join(cell(r["no_mag"][w])
                                                for w in ("tilt_heading", "vqf")) + " |")
    no_mag = {who: {k: float(np.mean([abs(r["no_mag"][who][k]) for r in rows]))
                    for k in ("drift_deg", "heading_rms_deg", "inclination_rms_deg")}
              for who in ("tilt_heading", "vqf")}
    print("| **mean** | " + " | ".join(cell(no_mag[w]) for w in ("tilt_heading", "vqf")) + " |")
    if a.json:
        with open(a.json, "w") as f:
            json.dump({"trials": rows, "mean": mean, "convergence_s": summary,
                       "biased_start": start, "synthetic_start": synthetic,
                       "glitch_s": glitch, "no_mag": no_mag}, f, indent=1)


if __name__ == "__main__":
    main()
