#!/usr/bin/env python3
"""Flight-quality benchmark: the autopilot flies `sitl` in lockstep (UDP), and the figures come
from the simulator's own truth CSV.

    cargo build --release -p autopilot -p sitl
    tools/bench_flight.py [--airframes quad_x,hexa_x (all)] [--sensors ideal,typical]
                          [--cases hover_calm,hover_wind,hover_turbulence,square] [--out DIR]

Cases, each with every sensor preset and airframe asked for:
- hover_calm, hover_wind (10 m/s steady from the north), hover_turbulence (8 m/s with Dryden
  turbulence, W20 8 m/s): the autopilot's own flight (`--takeoff 10 --hover 40`): the take-off's
  largest tilt, the hover's horizontal RMS about the hold point (above the take-off spot) and
  about its own mean, its height RMS, the landing spot's distance from the take-off spot and the
  touchdown speed;
- square: a mission uploaded with pymavlink (take-off to 10 m, a 20 m square of four waypoints
  at the 5 m/s cruise speed, a landing home): from the first move to back within 1 m of the start,
  the farthest from the ideal path, the farthest outside the square, the touchdown speed.
BENCH_LOG_DIR=DIR keeps the autopilot's flight logs (CSV, ULog, .tlog) there.
What it measured is in docs/performance.md; ArduCopter's and PX4's figures on the same physics
are in docs/simulator.md.
"""
import argparse
import math
import os
import signal
import socket
import subprocess
import sys
import tempfile
import time

# pymavlink's MAVLink 2 dialect, chosen when it is first imported (by peer_flight).
os.environ.setdefault("MAVLINK20", "1")
from peer_flight import Truth, square, tilt_deg, upload_mission

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
WIND = {
    "hover_calm": "",
    "hover_wind": "[wind]\nmean_ned_m_s = [-10.0, 0.0, 0.0]\n",
    "hover_turbulence": "[wind]\nmean_ned_m_s = [-8.0, 0.0, 0.0]\nturbulence_w20_m_s = 8.0\n",
    "square": "",
}
HOVER_S = 40.0


def free_port():
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def fly(a, airframe, sensors, case, out):
    """One flight; returns the truth."""
    scenario = os.path.join(out, "scenario.toml")
    with open(scenario, "w") as f:
        f.write(f'airframe = "{airframe}"\nseed = 1\nduration_s = 600.0\nsensors = "{sensors}"\n')
        f.write(WIND[case])
    sim_port = free_port()
    truth_csv = os.path.join(out, "truth.csv")
    sitl = subprocess.Popen(
        [os.path.join(a.bin_dir, "sitl"), "--params-dir", os.path.join(ROOT, "params"),
         "--scenario", scenario, "--autopilot", f"127.0.0.1:{sim_port}", "--truth-csv",
         truth_csv, "--truth-rate", "100", "--status-interval", "0", "--connect-timeout", "60"],
        stdout=subprocess.DEVNULL, stderr=open(os.path.join(out, "sitl.err"), "w"))
    ap_args = [os.path.join(a.bin_dir, "autopilot"), "--source", f"udp://127.0.0.1:{sim_port}",
               "--params-dir", os.path.join(ROOT, "params"), "--airframe", airframe,
               "--param-store", "none", "--log-dir", os.environ.get("BENCH_LOG_DIR", "none"),
               *(["--params", a.params] if a.params else [])]
    try:
        if case == "square":
            gcs_port = free_port()
            ap = subprocess.Popen(ap_args + ["--mavlink", f"udpin://127.0.0.1:{gcs_port}"],
                                  stdout=subprocess.DEVNULL,
                                  stderr=open(os.path.join(out, "autopilot.err"), "w"))
            try:
                fly_square(gcs_port)
            finally:
                ap.send_signal(signal.SIGINT)
                ap.wait(timeout=30)
        else:
            subprocess.run(ap_args + ["--mavlink", "none", "--takeoff", "10", "--hover",
                                      str(HOVER_S)], stdout=subprocess.DEVNULL,
                           stderr=open(os.path.join(out, "autopilot.err"), "w"), timeout=600,
                           check=True)
    finally:
        sitl.send_signal(signal.SIGINT)
        sitl.wait(timeout=30)
    return Truth(truth_csv)


def fly_square(gcs_port):
    from pymavlink import mavutil
    ml = mavutil.mavlink
    m = mavutil.mavlink_connection(f"udpout:127.0.0.1:{gcs_port}", source_system=255)
    end = time.monotonic() + 60
    while not m.wait_heartbeat(timeout=0.5):
        m.mav.heartbeat_send(ml.MAV_TYPE_GCS, ml.MAV_AUTOPILOT_INVALID, 0, 0, 0)
        if time.monotonic() > end:
            raise RuntimeError("no heartbeat from the autopilot")
    pos = m.recv_match(type="GLOBAL_POSITION_INT", blocking=True, timeout=30)
    home = (pos.lat * 1e-7, pos.lon * 1e-7)
    plan = [(ml.MAV_CMD_NAV_TAKEOFF, *home, 10.0)]
    plan += [(ml.MAV_CMD_NAV_WAYPOINT, lat, lon, 10.0) for lat, lon in square(home)]
    plan.append((ml.MAV_CMD_NAV_LAND, *home, 0.0))
    upload_mission(m, (1, 1), plan, yaw=math.nan)
    # Armed when the estimator is ready; then the mission; done once disarmed on the ground.
    end = time.monotonic() + 120
    while True:
        m.mav.command_long_send(1, 1, ml.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1, 0, 0, 0, 0, 0, 0)
        ack = m.recv_match(type="COMMAND_ACK", blocking=True, timeout=1)
        if ack and ack.command == ml.MAV_CMD_COMPONENT_ARM_DISARM and ack.result == 0:
            break
        if time.monotonic() > end:
            raise RuntimeError("never armed")
    m.mav.command_long_send(1, 1, ml.MAV_CMD_MISSION_START, 0, 0, 0, 0, 0, 0, 0, 0)
    armed_seen, end = False, time.monotonic() + 600
    while time.monotonic() < end:
        hb = m.recv_match(type="HEARTBEAT", blocking=True, timeout=5)
        if hb is None or hb.get_srcComponent() != 1:
            continue
        armed = bool(hb.base_mode & ml.MAV_MODE_FLAG_SAFETY_ARMED)
        armed_seen |= armed
        if armed_seen and not armed:
            return
    raise RuntimeError("the mission did not end in a landing")


def hover_figures(tr):
    t, pos, q, landed = tr.t, tr.pos, tr.q, tr.landed
    air = next(i for i, x in enumerate(landed) if not x)
    reach = next(i for i in range(air, len(t)) if -pos[i][2] > 9.5)
    rate = round(1 / (t[1] - t[0]))
    seg = range(reach + 10 * rate, reach + int((HOVER_S - 5) * rate))
    n0, e0 = pos[air - 1][0], pos[air - 1][1]  # the take-off spot: the hold point below
    rms_hold = math.sqrt(sum((pos[i][0] - n0) ** 2 + (pos[i][1] - e0) ** 2 for i in seg) / len(seg))
    nm = sum(pos[i][0] for i in seg) / len(seg)
    em = sum(pos[i][1] for i in seg) / len(seg)
    rms_mean = math.sqrt(sum((pos[i][0] - nm) ** 2 + (pos[i][1] - em) ** 2 for i in seg) / len(seg))
    hm = sum(-pos[i][2] for i in seg) / len(seg)
    h_rms = math.sqrt(sum((-pos[i][2] - hm) ** 2 for i in seg) / len(seg))
    touch = next(i for i in range(reach, len(t)) if landed[i])
    return {
        "takeoff_tilt_deg": max(tilt_deg(q[i]) for i in range(air, reach + 3 * rate)),
        "hold_rms_m": rms_hold, "rms_about_mean_m": rms_mean, "height_rms_m": h_rms,
        "landing_from_takeoff_m": math.hypot(pos[touch][0] - n0, pos[touch][1] - e0),
        "touchdown_m_s": max(float(tr.rows[i]["vd_m_s"]) for i in range(touch - 3, touch + 1)),
    }


def segment_distance(p, a, b):
    (pn, pe), (an, ae), (bn, be) = p, a, b
    dn, de = bn - an, be - ae
    k = max(0.0, min(1.0, ((pn - an) * dn + (pe - ae) * de) / (dn * dn + de * de)))
    return math.hypot(pn - an - k * dn, pe - ae - k * de)


def square_figures(tr, side=20.0):
    t, pos, landed = tr.t, tr.pos, tr.landed
    air = next(i for i, x in enumerate(landed) if not x)
    n0, e0 = pos[air - 1][0], pos[air - 1][1]

    def rel(i):
        return pos[i][0] - n0, pos[i][1] - e0
    moved = next(i for i in range(air, len(t)) if math.hypot(*rel(i)) > 0.5)
    far = next(i for i in range(moved, len(t)) if math.hypot(*rel(i)) > 15)
    back = next(i for i in range(far, len(t)) if math.hypot(*rel(i)) < 1.0)
    corners = [(0, 0), (side, 0), (side, side), (0, side), (0, 0)]
    off_path = max(min(segment_distance(rel(i), corners[k], corners[k + 1]) for k in range(4))
                   for i in range(moved, back + 1))
    outside = max(max(0.0, -rel(i)[0], rel(i)[0] - side, -rel(i)[1], rel(i)[1] - side)
                  for i in range(moved, back + 1))
    touch = next(i for i in range(back, len(t)) if landed[i])
    return {
        "square_s": t[back] - t[moved], "off_path_m": off_path, "outside_m": outside,
        "touchdown_m_s": max(float(tr.rows[i]["vd_m_s"]) for i in range(touch - 3, touch + 1)),
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--airframes", default=",".join(sorted(
        f[:-5] for f in os.listdir(os.path.join(ROOT, "params", "airframes"))
        if f.endswith(".toml"))))
    ap.add_argument("--sensors", default="ideal,typical")
    ap.add_argument("--cases", default=",".join(WIND))
    ap.add_argument("--bin-dir", default=os.path.join(ROOT, "target", "release"))
    ap.add_argument("--params", default=None,
                    help="the autopilot's flight parameters file (default: params/flight.toml)")
    ap.add_argument("--out", default=None)
    a = ap.parse_args()
    for b in ("sitl", "autopilot"):
        if not os.path.exists(os.path.join(a.bin_dir, b)):
            sys.exit(f"{a.bin_dir}/{b} missing: cargo build --release -p autopilot -p sitl")
    out = a.out or tempfile.mkdtemp(prefix="bench-flight-")
    runs = [(f, s, c) for f in a.airframes.split(",") for s in a.sensors.split(",")
            for c in a.cases.split(",")]
    for k, (airframe, sensors, case) in enumerate(runs, 1):
        d = os.path.join(out, f"{airframe}-{sensors}-{case}")
        os.makedirs(d, exist_ok=True)
        started = time.monotonic()
        print(f"[{k}/{len(runs)}] {airframe} {sensors} {case} ...", end=" ", flush=True)
        tr = fly(a, airframe, sensors, case, d)
        figs = square_figures(tr) if case == "square" else hover_figures(tr)
        print(" ".join(f"{n}={v:.3f}" for n, v in figs.items()),
              f"({time.monotonic() - started:.0f} s)", flush=True)
    print(f"runs kept in {out}")


if __name__ == "__main__":
    main()
