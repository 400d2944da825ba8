#!/usr/bin/env python3
"""The JSBSim back-end's speed: the lockstep real-time factor of `sitl --physics jsbsim` flying
an open-loop hover (no autopilot: the bridge round trip, JSBSim's frames and our models alone),
against the built-in physics, at 250 and 400 Hz, for a quad and a dodecacopter (2n + 6
properties set per step; JSBSim at 1 kHz or more: 4 frames per step at 250 Hz, 3 at 400 Hz).

    .venv/bin/python tools/bench_jsbsim.py [--seconds 20]

Run it from the project's venv (the test command creates it): the Python running this script
runs the JSBSim bridge. Build first: cargo build --release -p sitl.
"""

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
HOVER = """
airframe = "{airframe}"
duration_s = {seconds}
sensors = "typical"
[initial]
position_ned_m = [0.0, 0.0, -20.0]
rotors_at_hover = true
[wind]
mean_ned_m_s = [2.0, 0.0, 0.0]
turbulence_w20_m_s = 2.0
[[open_loop]]
t_s = 0.0
hover_delta = 0.0
"""


def run(sitl, scenario, physics, rate):
    out = subprocess.run(
        [str(sitl), "--params-dir", str(ROOT / "params"), "--open-loop", "--scenario",
         str(scenario), "--rate", str(rate), "--status-interval", "0", "--physics", physics,
         "--jsbsim-python", sys.executable],
        capture_output=True, text=True, check=True).stdout
    line = next(l for l in out.splitlines() if l.startswith("sitl summary:"))
    s = dict(kv.split("=", 1) for kv in line.split()[2:])
    return float(s["realtime_factor"]), int(s["steps"]) / float(s["wall_time_s"])


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seconds", type=float, default=20.0, help="simulated seconds per run")
    p.add_argument("--sitl", type=Path, default=ROOT / "target" / "release" / "sitl")
    a = p.parse_args()
    if not a.sitl.exists():
        sys.exit(f"no {a.sitl}: cargo build --release -p sitl (or give --sitl)")
    print(f"{'airframe':<9} {'rate':>5} {'physics':<8} {'x real time':>11} {'steps/s':>9}")
    with tempfile.TemporaryDirectory() as tmp:
        for airframe in ("quad_x", "dodeca"):
            scenario = Path(tmp) / f"{airframe}.toml"
            scenario.write_text(HOVER.format(airframe=airframe, seconds=a.seconds))
            for rate in (250, 400):
                for physics in ("builtin", "jsbsim"):
                    rtf, steps = run(a.sitl, scenario, physics, rate)
                    print(f"{airframe:<9} {rate:>5} {physics:<8} {rtf:>11.1f} {steps:>9.0f}",
                          flush=True)


if __name__ == "__main__":
    main()
