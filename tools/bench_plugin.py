#!/usr/bin/env python3
"""Figures of the Python package (docs/python.md), printed:

1. How long a vehicle takes to be ready: from `Vehicle(...)` to its return (the autopilot
   started, the estimator settled, its first heartbeat and health sendable), and from then to
   MAVSDK's own `health_all_ok` (the native binding, in-process), over --vehicles vehicles.
2. A suite of 20 tests, each on a fresh `vehicle` (ten are docs/python.md's MAVSDK-Python
   example, python/examples/test_takeoff.py; ten take off with pymavlink), run --runs times in a row with `pytest -n 2`: how many runs passed, the wall time
   of each, and whether any process of a run outlived it.

    .venv/bin/python tools/bench_plugin.py --vehicles 20 --runs 50

Uses this checkout's binaries (AUTOPILOT_SITL_BIN_DIR, default target/debug) unless the package
is installed.
"""

import argparse
import asyncio
import os
import statistics
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "python"))
os.environ.setdefault("AUTOPILOT_SITL_BIN_DIR", str(ROOT / "target" / "debug"))

SUITE = f'''
import math, os, sys
import pytest
os.environ.setdefault("MAVLINK20", "1")
from pymavlink import mavutil
sys.path.insert(0, {str(ROOT / "python" / "examples")!r})
from test_takeoff import test_takeoff_reaches_5_m


@pytest.mark.parametrize("k", range(10))
def test_mavsdk_takes_off(vehicle, k):
    test_takeoff_reaches_5_m(vehicle)


@pytest.mark.parametrize("k", range(10))
def test_pymavlink_takes_off(vehicle, k):
    c = mavutil.mavlink_connection(vehicle.pymavlink_url, source_system=255)
    assert c.wait_heartbeat(timeout=10)
    c.mav.command_long_send(1, 1, mavutil.mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1, 0, 0, 0,
                            0, 0, 0)
    ack = c.recv_match(type="COMMAND_ACK", blocking=True, timeout=10)
    assert ack is not None and ack.result == 0, ack
    nan = math.nan
    c.mav.command_long_send(1, 1, mavutil.mavlink.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, nan, nan,
                            nan, nan)
    m = c.recv_match(type="GLOBAL_POSITION_INT", blocking=True, timeout=60,
                     condition="GLOBAL_POSITION_INT.relative_alt > 2300")
    c.close()
    assert m is not None
    assert vehicle.truth().height_m > 2.0
'''


def readiness(n: int) -> None:
    from mavsdk.asyncio import ComponentType, Configuration, Mavsdk
    from mavsdk.asyncio.plugins.telemetry import TelemetryAsync

    from autopilot_sitl import Vehicle

    async def health_ok(url):
        config = Configuration.create_with_component_type(ComponentType.GROUND_STATION)
        async with Mavsdk(config) as m:
            await m.add_any_connection(url)
            system = await m.first_autopilot(timeout_s=10.0)
            async for ok in TelemetryAsync(system).subscribe_health_all_ok():
                if ok:
                    return

    ready, healthy = [], []
    for k in range(n):
        t0 = time.monotonic()
        with Vehicle(speed=10, seed=k + 1) as v:
            ready.append(time.monotonic() - t0)
            asyncio.run(asyncio.wait_for(health_ok(v.mavsdk_url), 10))
            healthy.append(time.monotonic() - t0)
    for what, xs in (("vehicle ready (Vehicle() returned)", ready),
                     ("MAVSDK health_all_ok, from Vehicle()", healthy)):
        print(f"{what}: min {min(xs):.3f} s, median {statistics.median(xs):.3f} s, "
              f"max {max(xs):.3f} s over {len(xs)}")


def soak(runs: int) -> bool:
    ok = True
    with tempfile.TemporaryDirectory(prefix="autopilot-soak-") as d:
        suite = Path(d) / "suite"
        suite.mkdir()
        (suite / "test_twenty.py").write_text(textwrap.dedent(SUITE))
        env = {**os.environ, "PYTHONPATH": str(ROOT / "python")}
        times = []
        for r in range(runs):
            base = Path(d) / f"run{r}"
            t0 = time.monotonic()
            run = subprocess.run(
                [sys.executable, "-m", "pytest", "-q", "-n", "2", "-p", "no:cacheprovider",
                 "-p", "autopilot_sitl.pytest_plugin", f"--basetemp={base}", str(suite)],
                cwd=suite, env=env, capture_output=True, text=True, timeout=900)
            times.append(time.monotonic() - t0)
            left = subprocess.run(["pgrep", "-f", str(base)], capture_output=True,
                                  text=True).stdout.split()
            last = run.stdout.strip().splitlines()[-1] if run.stdout.strip() else "(nothing)"
            print(f"run {r + 1}/{runs}: {last} in {times[-1]:.1f} s"
                  + (f"; LEFT RUNNING: {left}" if left else ""), flush=True)
            if run.returncode != 0 or left:
                ok = False
                print(run.stdout[-4000:])
        print(f"{sum(1 for _ in times)} runs of 20 tests: wall time min {min(times):.1f} s, "
              f"median {statistics.median(times):.1f} s, max {max(times):.1f} s; "
              f"{'all passed, nothing left running' if ok else 'FAILURES above'}")
    return ok


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--vehicles", type=int, default=10)
    parser.add_argument("--runs", type=int, default=3)
    args = parser.parse_args()
    if args.vehicles:
        readiness(args.vehicles)
    if args.runs and not soak(args.runs):
        sys.exit(1)


if __name__ == "__main__":
    main()
