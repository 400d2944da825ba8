#!/usr/bin/env python3
"""A long flight in lockstep: the autopilot hovers for hours on the embedded simulator (a
tethered vehicle: the pack never runs down), as fast as the machine allows, while its memory,
open files and logs are watched, and the truth's height is compared with the one held.

    cargo build --release -p autopilot
    tools/soak.py [--hours 24] [--bin target/release] [--out DIR] [--seed 1]

Printed: the run's wall time; the resident memory and open descriptors over the run (after the start-up,
the first and last quarter's largest); the logs' size (total, per simulated hour); the true height's largest
distance from the one held over the hover (after the climb, before the landing), and the
estimate's; the weather's pressure change the barometer read, from the estimator's offset.
With --check, exits 1 when the memory grows (the last quarter's largest over the first's by
more than 10 % and 2 MB), a descriptor leaks, or the true height leaves 1 m of the one held.
The figures are in docs/performance.md.
"""
import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
HEIGHT_M = 10.0

# A tethered vehicle: a 1000 Ah pack, three days of hover.
SCENARIO = """airframe = "quad_x"
seed = 1
duration_s = 1.0e9
sensors = "typical"

[battery]
capacity_mah = 1.0e6
"""


def watch(proc, every_s):
    """(resident kB, open descriptors) of `proc` every `every_s` of wall time until it ends."""
    samples = []
    while proc.poll() is None:
        try:
            status = Path(f"/proc/{proc.pid}/status").read_text()
            rss = next(int(l.split()[1]) for l in status.splitlines() if l.startswith("VmRSS:"))
            fds = len(os.listdir(f"/proc/{proc.pid}/fd"))
            samples.append((rss, fds))
        except (FileNotFoundError, ProcessLookupError, StopIteration):
            break
        time.sleep(every_s)
    return samples


def heights(truth_csv, climb_s):
    """The true height's largest distance from the one held, over the hover (from `climb_s`
    after the start to 20 s before the landing leaves 1.5 m of it), and the hover's length
    (s)."""
    rows = []
    with open(truth_csv) as f:
        header = f.readline().strip().split(",")
        t_i, d_i = header.index("t_s"), header.index("d_m")
        for line in f:
            cells = line.split(",")
            t, h = float(cells[t_i]), -float(cells[d_i])
            if t < climb_s:
                continue
            if h < HEIGHT_M - 1.5 and rows:
                break  # the landing
            rows.append((t, abs(h - HEIGHT_M)))
    if not rows:
        return float("nan"), 0.0
    end = rows[-1][0] - 20.0
    hover = [e for t, e in rows if t <= end]
    return max(hover, default=float("nan")), end - rows[0][0]


def soak(bins, hours, out, seed, settings=()):
    out.mkdir(parents=True, exist_ok=True)
    scenario = out / "tethered.toml"
    scenario.write_text(SCENARIO)
    # The autopilot's own count of the pack would run down: a tether's voltage is the measure.
    params = out / "flight.toml"
    text = (ROOT / "params" / "flight.toml").read_text()
    assert "\ncapacity_mah = 0.0 " in text, "the battery's capacity parameter moved"
    text = text.replace("\ncapacity_mah = 0.0 ", "\ncapacity_mah = -1.0 ")
    for setting in settings:
        key, value = setting.split("=", 1)
        lines = [l for l in text.splitlines() if l.startswith(f"{key} = ")]
        assert len(lines) == 1, f"{key}: {len(lines)} lines in flight.toml"
        text = text.replace(lines[0], f"{key} = {value}")
    params.write_text(text)
    logs = out / "logs"
    if logs.exists():
        shutil.rmtree(logs)
    truth = out / "truth.csv"
    cmd = [str(bins / "autopilot"), "--sim", "--speed", "max", "--seed", str(seed),
           "--scenario", str(scenario), "--takeoff", str(HEIGHT_M),
           "--hover", str(hours * 3600.0), "--mavlink", "none", "--param-store", "none",
           "--params-dir", str(ROOT / "params"), "--params", str(params), "--log-dir", str(logs),
           "--truth-csv", str(truth)]
    started = time.monotonic()
    with open(out / "autopilot.out", "w") as so, open(out / "autopilot.err", "w") as se:
        proc = subprocess.Popen(cmd, stdout=so, stderr=se)
        samples = watch(proc, max(0.2, hours * 0.5))
        proc.wait()
    wall = time.monotonic() - started
    summary = [l for l in (out / "autopilot.out").read_text().splitlines()
               if l.startswith("autopilot summary:")]
    log_bytes = sum(p.stat().st_size for p in logs.iterdir()) if logs.exists() else 0
    worst_h, hover_s = heights(truth, climb_s=30.0)
    # The first tenth is the start-up (files opened, the estimator aligning): the quarter after
    # it against the last.
    samples = samples[len(samples) // 10:]
    q = max(1, len(samples) // 4)
    first_rss = max(s[0] for s in samples[:q]) if samples else 0
    last_rss = max(s[0] for s in samples[-q:]) if samples else 0
    fds = sorted({s[1] for s in samples})
    return {
        "exit": proc.returncode, "wall_s": wall, "hover_s": hover_s,
        "rss_first_kib": first_rss, "rss_last_kib": last_rss, "fds": fds,
        "log_bytes": log_bytes, "log_mb_per_h": log_bytes / 1e6 / max(hours, 1e-9),
        "worst_height_err_m": worst_h, "summary": summary[-1] if summary else "",
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--hours", type=float, default=24.0)
    ap.add_argument("--bin", default=str(ROOT / "target" / "release"))
    ap.add_argument("--out", help="keep the run's files here")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--check", action="store_true", help="exit 1 if a bound is broken")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                    help="a flight parameter's value (its key in params/flight.toml)")
    args = ap.parse_args()
    out = Path(args.out) if args.out else Path(tempfile.mkdtemp(prefix="soak-"))
    print(f"soak: {args.hours:g} simulated hours at {HEIGHT_M:g} m, files in {out}", flush=True)
    r = soak(Path(args.bin), args.hours, out, args.seed, args.set)
    print(f"exit {r['exit']}, {r['wall_s']:.0f} s of wall time, hover {r['hover_s'] / 3600:.2f} h")
    print(f"resident memory: first quarter ≤ {r['rss_first_kib'] / 1024:.1f} MB, "
          f"last quarter ≤ {r['rss_last_kib'] / 1024:.1f} MB; open descriptors {r['fds']}")
    print(f"logs: {r['log_bytes'] / 1e6:.0f} MB ({r['log_mb_per_h']:.0f} MB per simulated hour)")
    print(f"true height: at most {r['worst_height_err_m']:.2f} m from the {HEIGHT_M:g} m held")
    print(r["summary"])
    broken = []
    if r["exit"] != 0:
        broken.append(f"exit {r['exit']}")
    if r["rss_last_kib"] > max(r["rss_first_kib"] * 1.1, r["rss_first_kib"] + 2048):
        broken.append("memory grew")
    if len(r["fds"]) > 1 and r["fds"][-1] - r["fds"][0] > 2:
        broken.append(f"descriptors {r['fds']}")
    if r["worst_height_err_m"] > 1.0:
        broken.append(f"height {r['worst_height_err_m']:.2f} m off")
    if broken:
        print("bounds broken: " + ", ".join(broken))
        if args.check:
            return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
