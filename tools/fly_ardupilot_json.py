#!/usr/bin/env python3
"""An unmodified ArduCopter SITL flown on `sitl --json` as its physics: take-off to 10 m, a
20 s hover, a four-waypoint 20 m square in AUTO, landing and disarm; in calm air or a steady
wind. Prints the figures, from sitl's truth CSV and ArduCopter's own telemetry.

    tools/fly_ardupilot_json.py --ardupilot DIR [--sitl BIN] [--wind 10 [--roughness 0.03]]
                                [--instance 7] [--speedup 4] [--out DIR]
    tools/fly_ardupilot_json.py --report DIR     # the figures of a flight already flown

DIR is an ArduPilot tree with `build/sitl/bin/arducopter` built (`./waf configure --board sitl
&& ./waf copter`); its quad-X defaults (copter.parm, copter-X.parm) are loaded, nothing else.
Instance N takes ArduPilot's JSON port 9002 + 10 N and its MAVLink TCP port 5760 + 10 N (7 by
default: away from the ports other runs fly on). Needs pymavlink (tests/requirements.txt).
What it measured is in docs/simulator.md.
"""
import argparse
import bisect
import csv
import os
import subprocess
import sys
import tempfile
import time

from pymavlink import mavutil

from peer_flight import (Log, Truth, euler_to_quat, quat_angle_deg, report_flight, square,
                         stop, upload_mission, await_landing)

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--ardupilot", help="an ArduPilot tree with arducopter built for SITL")
    ap.add_argument("--sitl", default=os.path.join(ROOT, "target", "release", "sitl"))
    ap.add_argument("--wind", type=float, default=0.0, help="steady wind from the north (m/s)")
    ap.add_argument("--instance", type=int, default=7)
    ap.add_argument("--speedup", type=float, default=4.0)
    ap.add_argument("--out", default=None)
    ap.add_argument("--hil-rate", default="1000")
    ap.add_argument("--roughness", type=float, default=None,
                    help="a surface layer: the wind falls to nothing at this roughness length (m)")
    ap.add_argument("--report", help="only report on a flight already flown in this folder")
    a = ap.parse_args()
    if a.report:
        report(a.report, os.path.join(a.report, "truth.csv"))
        return
    if not a.ardupilot:
        sys.exit("--ardupilot DIR: an ArduPilot tree with build/sitl/bin/arducopter")
    arducopter = os.path.join(a.ardupilot, "build", "sitl", "bin", "arducopter")
    params = os.path.join(a.ardupilot, "Tools", "autotest", "default_params")
    defaults = f"{params}/copter.parm,{params}/copter-X.parm"
    out = a.out or tempfile.mkdtemp(prefix="arducopter-json-")
    os.makedirs(out, exist_ok=True)
    scenario = os.path.join(out, "scenario.toml")
    with open(scenario, "w") as f:
        f.write('airframe = "quad_x"\nseed = 1\nduration_s = 3000.0\nsensors = "ideal"\n')
        if a.wind:
            # Blowing toward the south: from the north.
            f.write(f"[wind]\nmean_ned_m_s = [{-a.wind}, 0.0, 0.0]\n")
            if a.roughness:
                f.write(f"roughness_m = {a.roughness}\n")
    truth_csv = os.path.join(out, "truth.csv")
    sitl = subprocess.Popen(
        [a.sitl, "--json", "127.0.0.1:9002", "-i", str(a.instance), "--scenario", scenario,
         "--truth-csv", truth_csv, "--truth-rate", "1000", "--status-interval", "0",
         "--hil-rate", a.hil_rate],
        stdout=open(os.path.join(out, "sitl.out"), "w"), stderr=subprocess.STDOUT)
    copter = subprocess.Popen(
        [arducopter, "--model", "JSON:127.0.0.1", "--speedup", str(a.speedup), "--defaults",
         defaults, f"-I{a.instance}", "-w"], cwd=out,
        stdout=open(os.path.join(out, "arducopter.out"), "w"), stderr=subprocess.STDOUT)
    try:
        fly(a, out)
    finally:
        stop(copter, sitl)
    report(out, truth_csv)


def fly(a, out):
    port = 5760 + 10 * a.instance
    m = None
    for _ in range(60):
        try:
            time.sleep(1)
            m = mavutil.mavlink_connection(f"tcp:127.0.0.1:{port}", source_system=255)
            if m.wait_heartbeat(timeout=10):
                break
        except OSError as e:
            print("  connecting:", e, flush=True)
    else:
        raise RuntimeError("no heartbeat")
    log = Log(m, keep=("SIMSTATE",))
    for msg_id, hz in [(mavutil.mavlink.MAVLINK_MSG_ID_SIMSTATE, 50),
                       (mavutil.mavlink.MAVLINK_MSG_ID_ATTITUDE, 50),
                       (mavutil.mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT, 10)]:
        m.mav.command_long_send(1, 1, mavutil.mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, 0,
                                msg_id, 1e6 / hz, 0, 0, 0, 0, 0)
    # Arming when its checks pass (the EKF's GPS alignment takes a while).
    end = time.monotonic() + 240
    while True:
        m.set_mode("GUIDED")
        m.mav.command_long_send(1, 1, mavutil.mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0,
                                1, 0, 0, 0, 0, 0, 0)
        t0 = time.monotonic()
        while time.monotonic() - t0 < 2 and not log.is_armed():
            log.pump(0.2)
        if log.is_armed():
            break
        if time.monotonic() > end:
            raise RuntimeError("never armed")
    armed_at = log.t_ms
    m.mav.command_long_send(1, 1, mavutil.mavlink.MAV_CMD_NAV_TAKEOFF, 0,
                            0, 0, 0, 0, 0, 0, 10.0)
    log.wait("take-off to 9.5 m", lambda: log.alt() > 9.5, 120)
    hover_from = log.t_ms
    log.wait("20 s hover", lambda: log.t_ms - hover_from > 20_000, 120)
    # The square: 20 m north, 20 m east, back south, back home; then land there.
    cmd = mavutil.mavlink
    hlat, hlon = log.latlon
    items = [(cmd.MAV_CMD_NAV_WAYPOINT, hlat, hlon, 10.0)]  # item 0: home (ArduPilot's way)
    items += [(cmd.MAV_CMD_NAV_WAYPOINT, lat, lon, 10.0) for lat, lon in square(log.latlon)]
    items.append((cmd.MAV_CMD_NAV_LAND, hlat, hlon, 0.0))
    upload_mission(m, (1, 1), items)
    m.set_mode("AUTO")
    await_landing(log, os.path.join(out, "ardupilot.csv"), armed_at, hover_from)
    with open(os.path.join(out, "simstate.csv"), "w") as f:
        w = csv.writer(f)
        w.writerow(["t_boot_ms", "roll", "pitch", "yaw"])
        w.writerows((t, s.roll, s.pitch, s.yaw) for t, s in log.kept["SIMSTATE"])


def report(out, truth_csv):
    truth = Truth(truth_csv)
    t, q = truth.t, truth.q
    events = {r["event"]: int(r["t_boot_ms"]) for r in csv.DictReader(open(os.path.join(out, "ardupilot.csv")))}
    sims = [tuple(map(float, (r["t_boot_ms"], r["roll"], r["pitch"], r["yaw"])))
            for r in csv.DictReader(open(os.path.join(out, "simstate.csv")))]
    # ArduPilot's boot clock against the physics' clock: the offset that makes SIMSTATE's
    # attitude meet a truth row (each SIMSTATE is one of the states sent).

    def nearest_err(ts, att, offset_s, window=0.03):
        i = bisect.bisect_left(t, ts + offset_s - window)
        best = 180.0
        qa = euler_to_quat(*att)
        while i < len(t) and t[i] <= ts + offset_s + window:
            best = min(best, quat_angle_deg(qa, q[i]))
            i += 1
        return best
    # The clocks: the offset that best matches the first 200 samples (coarse), then each sample
    # against the truth's states within 3 s of it: SIMSTATE is one of the states sent, so the
    # nearest state on the trajectory is the one it decoded.
    moving = [s for s in sims[::10]]
    offsets = [o * 0.01 for o in range(-3000, 3000)]
    coarse = min(offsets, key=lambda o: sum(nearest_err(s[0] / 1000, s[1:], o, 0.01) for s in moving[:200]))
    errs = [nearest_err(s[0] / 1000, s[1:], coarse, 3.0) for s in sims]
    errs.sort()
    print(f"SIMSTATE against the truth: {len(errs)} samples, offset {coarse:.2f} s, median "
          f"{errs[len(errs)//2]:.5f}°, 99th {errs[int(0.99*len(errs))]:.5f}°, max {errs[-1]:.5f}°")

    def truth_at(ms):
        return truth.index(ms / 1000 + coarse)
    report_flight(truth, truth_at(events["armed"]), truth_at(events["hover_from"]),
                  truth_at(events["auto"]), truth_at(events["disarmed"]))


if __name__ == "__main__":
    main()
