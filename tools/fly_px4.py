#!/usr/bin/env python3
"""An unmodified PX4 SITL flown on `sitl --tcp` as its simulator, connected the way PX4's own
start-up connects (`simulator_mavlink start -c 4560+i`): take-off to 10 m, a 20 s hover, a
four-waypoint 20 m square in Mission mode, landing and disarm; in calm air or a steady wind.
Prints the figures, from sitl's truth CSV and PX4's own telemetry.

    tools/fly_px4.py --px4 DIR [--sitl BIN] [--airframe quad_x] [--wind 10 [--roughness 0.03]]
                     [--instance 7] [--out DIR]
    tools/fly_px4.py --report DIR        # the figures of a flight already flown
    tools/fly_px4.py --params quad_x     # the PX4 parameters of one of our airframes

DIR is a PX4-Autopilot tree with `build/px4_sitl_default` built (`make px4_sitl_default`). PX4
runs its generic quad airframe (10016 none_iris: PX4's quad-X motor order, which is ours) with
the rotor geometry of our airframe (CA_ROTORn_PX/PY/KM, set through PX4_PARAM_* as rcS allows)
and MIS_TAKEOFF_ALT = 10; every other parameter is PX4's default. Instance N takes TCP 4560 + N
for the simulator and PX4's offboard link, UDP 14540 + N (7 by default: away from the ports
other runs fly on). Needs pymavlink (tests/requirements.txt). What it measured is in
docs/simulator.md.
"""
import argparse
import csv
import math
import os
import shutil
import subprocess
import sys
import tempfile
import time
import tomllib

from pymavlink import mavutil

from peer_flight import (Log, Truth, euler_to_quat, quat_angle_deg, report_flight, square,
                         stop, upload_mission, await_landing)

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
# PX4's generic quad airframe on its MAVLink simulator interface (init.d-posix/airframes).
PX4_AIRFRAME = 10016


def px4_params(airframe):
    """PX4's control-allocation geometry for one of our airframes (params/airframes/NAME.toml):
    rotor n at CA_ROTORn_PX/PY (m, forward/right), CA_ROTORn_KM the rotor's torque per thrust
    (m), positive for a counter-clockwise rotor as PX4 counts it, on output n + 1. Our rotor
    order is kept: our
    quad_x is PX4's quad-X order (1 front-right ccw, 2 rear-left ccw, 3 front-left cw, 4
    rear-right cw)."""
    path = airframe if airframe.endswith(".toml") else os.path.join(
        ROOT, "params", "airframes", f"{airframe}.toml")
    with open(path, "rb") as f:
        a = tomllib.load(f)
    defaults = a.get("rotor_defaults", {})
    params = {"CA_AIRFRAME": 0, "CA_ROTOR_COUNT": len(a["rotors"])}
    for n, r in enumerate(a["rotors"]):
        rotor = {**defaults, **r}
        # Torque over thrust of a propeller: (K_Q rho n^2 D^5) / (K_T rho n^2 D^4) = D K_Q / K_T.
        km = rotor["diameter_m"] * rotor["k_q"] / rotor["k_t"]
        x, y, _ = rotor["position_m"]
        params[f"CA_ROTOR{n}_PX"] = round(x, 4) or 0.0  # no -0.0
        params[f"CA_ROTOR{n}_PY"] = round(y, 4) or 0.0
        params[f"CA_ROTOR{n}_KM"] = round(km if rotor["spin"] == "ccw" else -km, 4)
        # Output n + 1 drives motor n + 1 (function 101 is motor 1): HIL_ACTUATOR_CONTROLS
        # carries them in that order, sitl's rotor n takes controls[n].
        params[f"PWM_MAIN_FUNC{n + 1}"] = 101 + n
    return params


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--px4", help="a PX4-Autopilot tree with build/px4_sitl_default built")
    ap.add_argument("--sitl", default=os.path.join(ROOT, "target", "release", "sitl"))
    ap.add_argument("--airframe", default="quad_x")
    ap.add_argument("--wind", type=float, default=0.0, help="steady wind from the north (m/s)")
    ap.add_argument("--roughness", type=float, default=None,
                    help="a surface layer: the wind falls to nothing at this roughness length (m)")
    ap.add_argument("--sensors", default="typical",
                    help="sitl's sensor preset (PX4 takes a noise-free reading that repeats for "
                         "100 samples for a stale sensor, as its own simulators are noisy)")
    ap.add_argument("--speed", default="4",
                    help="sitl's pace at most, times real time: PX4's protocols time out on its "
                         "clock, which in lockstep is the simulator's")
    ap.add_argument("--instance", type=int, default=7)
    ap.add_argument("--out", default=None)
    ap.add_argument("--report", help="only report on a flight already flown in this folder")
    ap.add_argument("--params", metavar="AIRFRAME", help="print PX4's parameters for AIRFRAME")
    a = ap.parse_args()
    if a.params:
        for k, v in px4_params(a.params).items():
            print(f"param set {k} {v}")
        return
    if a.report:
        report(a.report)
        return
    if not a.px4:
        sys.exit("--px4 DIR: a PX4-Autopilot tree with build/px4_sitl_default")
    build = os.path.join(a.px4, "build", "px4_sitl_default")
    out = os.path.abspath(a.out or tempfile.mkdtemp(prefix="px4-tcp-"))
    # PX4 keeps its parameters and its mission (and where it stood in it) in its working
    # folder: a new flight starts from a new one.
    shutil.rmtree(os.path.join(out, "px4"), ignore_errors=True)
    os.makedirs(os.path.join(out, "px4"))
    scenario = os.path.join(out, "scenario.toml")
    with open(scenario, "w") as f:
        f.write(f'airframe = "{a.airframe}"\nseed = 1\nduration_s = 3000.0\n'
                f'sensors = "{a.sensors}"\n')
        if a.wind:
            # Blowing toward the south: from the north.
            f.write(f"[wind]\nmean_ned_m_s = [{-a.wind}, 0.0, 0.0]\n")
            if a.roughness:
                f.write(f"roughness_m = {a.roughness}\n")
    sitl = subprocess.Popen(
        [a.sitl, "--tcp", "127.0.0.1:4560", "-i", str(a.instance), "--scenario", scenario,
         "--truth-csv", os.path.join(out, "truth.csv"), "--truth-rate", "1000",
         "--status-interval", "0", "--speed", a.speed],
        stdout=open(os.path.join(out, "sitl.out"), "w"), stderr=subprocess.STDOUT)
    env = dict(os.environ, PX4_SYS_AUTOSTART=str(PX4_AIRFRAME))
    for k, v in {**px4_params(a.airframe), "MIS_TAKEOFF_ALT": 10.0}.items():
        env[f"PX4_PARAM_{k}"] = str(v)
    # A stale lock of an earlier instance N would stop this one.
    sock = f"/tmp/px4-sock-{a.instance}"
    if os.path.exists(sock):
        os.remove(sock)
    px4 = subprocess.Popen(
        [os.path.join(build, "bin", "px4"), "-i", str(a.instance), "-d", "-w",
         os.path.join(out, "px4"), os.path.join(build, "etc")],
        cwd=os.path.join(out, "px4"), env=env, start_new_session=True,
        stdout=open(os.path.join(out, "px4.out"), "w"), stderr=subprocess.STDOUT)
    try:
        fly(a, out)
    finally:
        stop(sitl, groups=(px4,))
    report(out)


def command(m, target, cmd, *params):
    """COMMAND_LONG, sent until acknowledged; returns the result."""
    p = list(params) + [0.0] * (7 - len(params))
    for _ in range(10):
        m.mav.command_long_send(*target, cmd, 0, *p)
        ack = m.recv_match(type="COMMAND_ACK", blocking=True, timeout=1)
        if ack is not None and ack.command == cmd:
            return ack.result
    raise RuntimeError(f"command {cmd} never acknowledged")


def fly(a, out):
    m = mavutil.mavlink_connection(f"udpin:127.0.0.1:{14540 + a.instance}", source_system=255)
    if not m.wait_heartbeat(timeout=120):
        raise RuntimeError("no heartbeat from PX4")
    target = (m.target_system, 1)
    log = Log(m, keep=("HIL_STATE_QUATERNION", "ATTITUDE"))
    for msg_id, hz in [(mavutil.mavlink.MAVLINK_MSG_ID_HIL_STATE_QUATERNION, 50),
                       (mavutil.mavlink.MAVLINK_MSG_ID_ATTITUDE, 50),
                       (mavutil.mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT, 10)]:
        command(m, target, mavutil.mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, msg_id, 1e6 / hz)
    log.wait("a position", lambda: log.latlon is not None, 120)
    # Arming when its checks pass (the EKF's alignment takes a while), then the take-off.
    end = time.monotonic() + 240
    while not log.is_armed():
        if time.monotonic() > end:
            raise RuntimeError("never armed")
        m.mav.command_long_send(*target, mavutil.mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0,
                                1, 0, 0, 0, 0, 0, 0)
        t0 = time.monotonic()
        while time.monotonic() - t0 < 2 and not log.is_armed():
            log.pump(0.2)
    armed_at = log.t_ms
    m.mav.command_long_send(*target, mavutil.mavlink.MAV_CMD_NAV_TAKEOFF, 0,
                            0, 0, 0, math.nan, math.nan, math.nan, math.nan)
    log.wait("take-off to 9.5 m", lambda: log.alt() > 9.5, 120)
    hover_from = log.t_ms
    log.wait("20 s hover", lambda: log.t_ms - hover_from > 20_000, 120)
    # The square: 20 m north, 20 m east, back south, back home; then land there.
    cmd = mavutil.mavlink
    hlat, hlon = log.latlon
    items = [(cmd.MAV_CMD_NAV_WAYPOINT, lat, lon, 10.0) for lat, lon in square(log.latlon)]
    items.append((cmd.MAV_CMD_NAV_LAND, hlat, hlon, 0.0))
    upload_mission(m, target, items)
    # Mission mode: PX4's custom main mode AUTO (4), sub-mode MISSION (4); refused until PX4
    # has checked the new mission.
    end = time.monotonic() + 30
    while command(m, target, cmd.MAV_CMD_DO_SET_MODE, cmd.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
                  4, 4) != cmd.MAV_RESULT_ACCEPTED:
        if time.monotonic() > end:
            raise RuntimeError("Mission mode refused")
        log.pump(1.0)
    await_landing(log, os.path.join(out, "px4.csv"), armed_at, hover_from)
    with open(os.path.join(out, "hil_state.csv"), "w") as f:
        w = csv.writer(f)
        w.writerow(["t_boot_ms", "qw", "qx", "qy", "qz"])
        w.writerows((t, *s.attitude_quaternion) for t, s in log.kept["HIL_STATE_QUATERNION"])
    with open(os.path.join(out, "attitude.csv"), "w") as f:
        w = csv.writer(f)
        w.writerow(["t_boot_ms", "roll", "pitch", "yaw"])
        w.writerows((s.time_boot_ms, s.roll, s.pitch, s.yaw) for _, s in log.kept["ATTITUDE"])


def down_axis(q):
    """The body's down axis in NED for a (w, x, y, z) attitude."""
    w, x, y, z = q
    return (2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y))


def yaw_of(q):
    w, x, y, z = q
    return math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


def spread(errs):
    errs = sorted(errs)
    return (f"{len(errs)} samples, median {errs[len(errs) // 2]:.5f}°, "
            f"99th {errs[int(0.99 * len(errs))]:.5f}°, max {errs[-1]:.5f}°")


def report(out):
    truth = Truth(os.path.join(out, "truth.csv"))
    events = {r["event"]: int(r["t_boot_ms"]) for r in csv.DictReader(open(os.path.join(out, "px4.csv")))}
    # In lockstep PX4's clock is the simulator's: HIL_SENSOR's time_usec sets it. PX4 sends its
    # decoded ground truth without a time (time_usec 0): each is matched with the nearest of
    # the truth's states within 0.1 s of the telemetry's clock (it is one of the states sent).
    states = list(csv.DictReader(open(os.path.join(out, "hil_state.csv"))))
    errs = []
    for s in states:
        qs = tuple(float(s[k]) for k in ("qw", "qx", "qy", "qz"))
        t_s = int(s["t_boot_ms"]) / 1e3
        i, end = truth.index(t_s - 0.1), truth.index(t_s + 0.1)
        if end < len(truth.t):
            errs.append(min(quat_angle_deg(qs, truth.q[j]) for j in range(i, end + 1)))
    print(f"PX4's decoded ground truth (HIL_STATE_QUATERNION) against the truth: {spread(errs)}")
    # Its estimate against the truth of the same instant: the tilt (the body's down axis) and
    # the rest, the heading (PX4 takes the magnetic declination from its own world model).
    att = list(csv.DictReader(open(os.path.join(out, "attitude.csv"))))
    tilt, heading = [], []
    for r in att:
        i = truth.index(int(r["t_boot_ms"]) / 1e3 - 5e-7)
        if i < len(truth.t):
            q = euler_to_quat(float(r["roll"]), float(r["pitch"]), float(r["yaw"]))
            tilt.append(math.degrees(math.acos(min(1.0, sum(
                a * b for a, b in zip(down_axis(q), down_axis(truth.q[i])))))))
            heading.append(abs((float(r["yaw"]) - yaw_of(truth.q[i]) + math.pi) % (2 * math.pi)
                               - math.pi) * 180 / math.pi)
    print(f"PX4's attitude estimate (ATTITUDE) against the truth: tilt {spread(tilt)}; "
          f"heading {spread(heading)}")

    def truth_at(ms):
        return truth.index(ms / 1000)
    report_flight(truth, truth_at(events["armed"]), truth_at(events["hover_from"]),
                  truth_at(events["auto"]), truth_at(events["disarmed"]))


if __name__ == "__main__":
    main()
