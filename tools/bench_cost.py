#!/usr/bin/env python3
"""What a flight costs, in instructions (valgrind's callgrind: the same count on any day and
any load) and in CPU time (ratios within one run), for one or more builds side by side:

1. **An embedded hover frame** (`autopilot --sim`, no logs, no ground stations): the control
   loop thread's instructions per frame (but the telemetry's publication, which follows the
   wall clock: at most once a millisecond, about 700 instructions), and its compute floor (FLOOR, DECISIONS below: the
   functions that compute the flight, each counted inclusive). Both are differences between a
   20 s and a 10 s hover, so start-up, take-off and landing cancel out; the main thread, whose
   waits follow the wall clock, is left out, so the count is the same on every run.
2. **Start-up**: instructions from the process's start to its first frame (everything before
   the control loop's `fly`), the minimal flight's whole process beside it.
3. **Logs**: the same flight with the default logs (`.tlog`, ULog, flight CSV) against none:
   the ratio of instructions (every thread but the main one: the flight and the writers) and
   of CPU time (user + system, median of --runs).
4. **ArduPilot's JSON link**: the autopilot on `sitl --json --hil-rate 1000` (1 kHz lockstep):
   its control loop's instructions and the process's CPU time per simulated second, and the
   share of the loop's instructions in parsing the JSON state (`PhysicsState::parse_latest`).

    tools/bench_cost.py                               # target/release
    tools/bench_cost.py --bin /tmp/before --bin target/release   # two builds, one run

Needs valgrind. Builds nothing: build with `cargo build --release -p autopilot -p sitl` first.
"""

import argparse
import os
import re
import socket
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PARAMS = ROOT / "params"
QUIET = ["--params-dir", str(PARAMS), "--param-store", "none", "--mavlink", "none"]
# The compute floor of a frame: the functions that compute the flight. The narrow edge is the
# flight-core step and the physics steps with their sensors (their noise drawn once per
# exchange); the wide edge adds what the autopilot decides around the core each frame (the
# commander, the battery, sensor and magnetic-field monitors, the geofence, the IMU's
# calibration, the blind descent's hover filter). Above either: status, copies, the HIL
# frame's folding, the loop's glue.
# Where a build writes its output in place (`step_into`, `apply_into`), the older name is kept
# beside it for builds before: a name not in a profile counts 0.
FLOOR = [
    "flight_core::core::step::<impl flight_core::core::FlightCore>::step_into",
    "flight_core::core::step::<impl flight_core::core::FlightCore>::step",
    "sitl_core::sim::Simulator::step",
    "sitl_core::sim::Simulator::sample_sensors",
    "hil::simulator_end::SimulatorEnd::exchange_noise",
]
DECISIONS = [
    "flight_core::commander::Commander::update",
    "flight_core::sensors::battery::BatteryEstimator::step",
    "flight_core::sensors::monitor::SensorMonitor::update",
    "flight_core::safety::geofence::FenceMonitor::update",
    "flight_core::sensors::imu_correction::ImuCorrection::apply_into",
    "flight_core::sensors::imu_correction::ImuCorrection::apply",
    "flight_core::sensors::mag_check::MagFieldMonitor::update",
    "flight_core::safety::blind_descent::HoverCommands::update",
]
# How often the loop publishes its telemetry follows the wall clock (at most every millisecond):
# counted apart, so the frame's count is the same on every run.
WALL_PACED = ["autopilot::control_loop::ControlLoop::publish_telemetry"]
PARSE = ["hil::json::PhysicsState::parse_latest"]


def callgrind(cmd, dump_before=None):
    """Instructions of `cmd` (all threads); with `dump_before`, those before that function's
    first call. Returns (instructions, stdout)."""
    with tempfile.TemporaryDirectory() as d:
        out = Path(d) / "cg.out"
        args = ["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}"]
        if dump_before:
            args.append(f"--dump-before={dump_before}")
        run = subprocess.run(args + cmd, capture_output=True, text=True, check=True)
        parts = sorted(Path(d).glob("cg.out*"))
        totals = []
        for p in parts:
            m = re.search(r"^(?:summary|totals): (\d+)", p.read_text(errors="replace"), re.M)
            totals.append(int(m.group(1)) if m else 0)
        if dump_before:
            # cg.out.1 is the part dumped before the first call; the rest come after.
            first = [p for p in parts if p.name.endswith(".1")]
            ir = totals[parts.index(first[0])] if first else 0
        else:
            ir = sum(totals)
        return ir, run.stdout


def thread_profiles(cmd, d):
    """Runs `cmd` under callgrind with a profile per thread in `d`: {thread number: (its
    instructions, its profile's path)}, and the run's stdout. Thread 1 is the main thread,
    whose idle waits follow the wall clock; the others' work follows the flight."""
    out = Path(d) / "cg.out"
    run = subprocess.run(["valgrind", "--tool=callgrind", "--separate-threads=yes",
                          f"--callgrind-out-file={out}"] + cmd,
                         capture_output=True, text=True, check=True)
    threads = {}
    for p in Path(d).glob("cg.out-*"):
        text = p.read_text(errors="replace")
        n = int(re.search(r"^thread: (\d+)", text, re.M).group(1))
        threads[n] = (int(re.search(r"^totals: (\d+)", text, re.M).group(1)), p)
    return threads, run.stdout


def field(summary, name):
    m = re.search(rf"\b{name}=(\S+)", summary)
    return float(m.group(1)) if m else float("nan")


def timed(cmd):
    """(CPU seconds of `cmd`, its stdout): user + system from wait4."""
    p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)
    out = b""
    while chunk := p.stdout.read(65536):
        out += chunk
    _, status, usage = os.wait4(p.pid, 0)
    if os.waitstatus_to_exitcode(status) != 0:
        raise RuntimeError(f"{cmd[0]} failed")
    return usage.ru_utime + usage.ru_stime, out.decode()


def hover(bin_dir, hover_s, extra=()):
    return [str(bin_dir / "autopilot"), "--sim", "--speed", "max", "--takeoff", "5",
            "--hover", str(hover_s), *QUIET, *extra]


def inclusive(profile, functions):
    """Each function's inclusive instructions in a callgrind profile; 0, and said, for one that
    is not there (never called, absent from that build, or inlined away)."""
    # The function list only, from `/`: callgrind_annotate shortens the paths under its working
    # directory, and then splits a function's cost between its relative and absolute names.
    text = subprocess.run(["callgrind_annotate", "--inclusive=yes", "--threshold=100",
                           "--auto=no", str(Path(profile).resolve())],
                          capture_output=True, text=True, check=True, cwd="/").stdout
    found = {}
    for line in text.splitlines():
        # "  1,234 (5.6%)  /path/file.rs:crate::function [/path/binary]"
        if not line.endswith("]") or ":" not in line:
            continue
        count, _, rest = line.strip().partition(" ")
        name = rest.rsplit(" [", 1)[0].split(":", 1)[-1] if " [" in rest else ""
        if name in functions and name not in found and count.replace(",", "").isdigit():
            found[name] = int(count.replace(",", ""))
    for f in functions:
        if f not in found:
            print(f"  {profile.name}: {f} not in the profile, counted as 0", file=sys.stderr)
            found[f] = 0
    return found


def frame_cost(bin_dir):
    """(instructions per hover frame, the narrow floor's, the wide floor's), in the control
    loop's thread (the busiest)."""
    per = {}
    for h in (10, 20):
        with tempfile.TemporaryDirectory() as d:
            threads, stdout = thread_profiles(hover(bin_dir, h, ["--log-dir", "none"]), d)
            total, profile = max(threads.values())
            f = inclusive(profile, FLOOR + DECISIONS + WALL_PACED)
            total -= f[WALL_PACED[0]]
            narrow = sum(f[k] for k in FLOOR)
            wide = narrow + sum(f[k] for k in DECISIONS)
            per[h] = (total, narrow, wide, field(stdout, "frames"))
            print(f"  {h} s hover: {per[h][3]:.0f} frames", file=sys.stderr)
    frames = per[20][3] - per[10][3]
    return tuple((per[20][i] - per[10][i]) / frames for i in range(3))


def startup_cost(bin_dir):
    """(instructions before the first frame, the whole minimal flight's)."""
    cmd = hover(bin_dir, 0, ["--log-dir", "none"])
    cmd[cmd.index("--takeoff") + 1] = "1"
    before, _ = callgrind(cmd, dump_before="autopilot::control_loop::fly")
    whole, _ = callgrind(cmd)
    return before, whole


def logs_cost(bin_dir, runs):
    """(instruction ratio, CPU ratio, CPU with, CPU without) of a hover with the default logs
    against none: instructions over a 20 s hover; CPU time over a 300 s one, whose 0.5 s or so
    of CPU a run's start-up and the machine's noise cannot swing as they swing a 20 s hover's
    70 ms (by ±20 % between runs)."""
    with tempfile.TemporaryDirectory() as logs:
        on = hover(bin_dir, 20, ["--log-dir", logs])
        off = hover(bin_dir, 20, ["--log-dir", "none"])
        long_on = hover(bin_dir, 300, ["--log-dir", logs])
        long_off = hover(bin_dir, 300, ["--log-dir", "none"])
        ir = {}
        for name, cmd in (("on", on), ("off", off)):
            with tempfile.TemporaryDirectory() as d:
                threads, _ = thread_profiles(cmd, d)
                # All but the main thread: the flight, its writers, the start-up's runtime.
                ir[name] = sum(t for n, (t, _) in threads.items() if n != 1)
        ir_on, ir_off = ir["on"], ir["off"]
        cpu_on, cpu_off = [], []
        for _ in range(runs):
            cpu_off.append(timed(long_off)[0])
            cpu_on.append(timed(long_on)[0])
    on_s, off_s = statistics.median(cpu_on), statistics.median(cpu_off)
    # The ratio of each pair, run one after the other, then their median: the VM's speed drifts
    # between pairs more than within one.
    ratio = statistics.median(a / b for a, b in zip(cpu_on, cpu_off))
    return ir_on / ir_off, ratio, on_s, off_s


def free_port():
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _busiest(cmd, d):
    """The busiest thread's (instructions, profile), and stdout."""
    threads, stdout = thread_profiles(cmd, d)
    return max(threads.values()), stdout


def json_flight(bin_dir, under):
    """Runs the autopilot (under `under`, a command prefix) against `sitl --json` at 1 kHz;
    returns (its result, its summary line)."""
    port = free_port()
    sitl = subprocess.Popen(
        [str(bin_dir / "sitl"), "--json", f"127.0.0.1:{port}", "--hil-rate", "1000",
         "--duration", "600", "--status-interval", "0", "--params-dir", str(PARAMS)],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        cmd = [str(bin_dir / "autopilot"), "--source", f"json://127.0.0.1:{port}",
               "--takeoff", "5", "--hover", "10", "--log-dir", "none", *QUIET]
        result = under(cmd)
    finally:
        sitl.kill()
        sitl.wait()
    out = result[1]
    summary = next((l for l in out.splitlines() if "autopilot summary" in l), "")
    return result[0], summary


def json_cost(bin_dir, runs):
    """(instructions per simulated second, parse share, CPU ms per simulated second), the
    instructions those of the control loop's thread."""
    with tempfile.TemporaryDirectory() as d:
        (total, profile), s = json_flight(bin_dir, lambda c: _busiest(c, d))
        parse = inclusive(profile, PARSE)[PARSE[0]]
    sim_s = field(s, "sim_time_s")
    parse_share = parse / total
    cpu = []
    for _ in range(runs):
        c, s3 = json_flight(bin_dir, timed)
        cpu.append(1e3 * c / field(s3, "sim_time_s"))
    return total / sim_s, parse_share, statistics.median(cpu)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--bin", action="append", type=Path,
                    help="a directory with autopilot and sitl (repeat to compare) "
                    "[default: target/release]")
    ap.add_argument("--runs", type=int, default=3, help="timed runs per CPU figure (median)")
    a = ap.parse_args()
    bins = a.bin or [ROOT / "target" / "release"]
    rows = []
    for b in bins:
        print(f"measuring {b} ...", file=sys.stderr)
        frame, floor, wide = frame_cost(b)
        start, whole = startup_cost(b)
        ir_ratio, cpu_ratio, on_s, off_s = logs_cost(b, a.runs)
        json_ir, share, json_ms = json_cost(b, a.runs)
        rows.append([
            ("hover frame, instructions (no logs, no ground stations)", f"{frame:,.0f}"),
            ("  compute floor: flight-core step, physics, sensors", f"{floor:,.0f}"),
            ("  frame / that floor", f"{frame / floor:.3f}"),
            ("  wide floor: and the autopilot's decisions", f"{wide:,.0f}"),
            ("  frame / wide floor", f"{frame / wide:.3f}"),
            ("start-up to the first frame, instructions", f"{start / 1e6:.1f} M"),
            ("  the whole minimal flight (take-off to 1 m, land)", f"{whole / 1e6:.1f} M"),
            ("logs on / off, instructions (20 s hover)", f"{ir_ratio:.2f}"),
            ("logs on / off, CPU time (300 s hover)", f"{cpu_ratio:.2f} ({on_s:.3f} / {off_s:.3f} s)"),
            ("sitl --json at 1 kHz: autopilot instructions per sim s", f"{json_ir / 1e6:.1f} M"),
            ("  parsing the JSON state, share", f"{100 * share:.1f} %"),
            ("  autopilot CPU per simulated second", f"{json_ms:.2f} ms"),
        ])
    width = max(len(n) for n, _ in rows[0])
    print(f"{'':{width}}  " + "  ".join(f"{str(b):>22}" for b in bins))
    for i, (name, _) in enumerate(rows[0]):
        print(f"{name:{width}}  " + "  ".join(f"{r[i][1]:>22}" for r in rows))


if __name__ == "__main__":
    main()
