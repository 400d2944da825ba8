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
import math
import os
import signal
import subprocess
import sys
import tempfile
import time

from pymavlink import mavutil

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def quat_angle_deg(a, b):
    d = abs(sum(x * y for x, y in zip(a, b)))
    return math.degrees(2 * math.acos(min(1.0, d)))


def euler_to_quat(roll, pitch, yaw):
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    return (cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy)


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
        for p in (copter, sitl):
            p.send_signal(signal.SIGINT)
        for p in (copter, sitl):
            try:
                p.wait(timeout=20)
            except subprocess.TimeoutExpired:
                p.kill()
    report(out, truth_csv)


class Log:
    """Every message kept with ArduPilot's boot time (the last time_boot_ms seen)."""

    def __init__(self, m):
        self.m, self.t_ms, self.rows = m, 0, []
        self.simstate, self.armed, self.texts = [], [], []

    def pump(self, timeout=0.5):
        msg = self.m.recv_match(blocking=True, timeout=timeout)
        for _ in range(200):  # a stream never runs dry: return now and then
            if msg is None:
                break
            t = msg.get_type()
            if hasattr(msg, "time_boot_ms"):
                self.t_ms = msg.time_boot_ms
            if t == "SIMSTATE":
                self.simstate.append((self.t_ms, msg.roll, msg.pitch, msg.yaw))
            elif t == "HEARTBEAT" and msg.type != mavutil.mavlink.MAV_TYPE_GCS:
                armed = bool(msg.base_mode & mavutil.mavlink.MAV_MODE_FLAG_SAFETY_ARMED)
                self.armed.append((self.t_ms, armed))
            elif t == "STATUSTEXT":
                self.texts.append((self.t_ms, msg.text))
                print(f"  [{self.t_ms / 1000:7.2f}] {msg.text}", flush=True)
            elif t == "GLOBAL_POSITION_INT":
                self.rows.append((self.t_ms, msg.relative_alt / 1000.0))
                self.latlon = (msg.lat * 1e-7, msg.lon * 1e-7)
            msg = self.m.recv_match(blocking=False)

    def wait(self, what, cond, limit_s):
        end = time.monotonic() + limit_s
        said = time.monotonic()
        while not cond():
            if time.monotonic() - said > 5:
                said = time.monotonic()
                print(f"  waiting for {what}: boot {self.t_ms / 1000:.1f} s, alt {self.alt():.2f} m, "
                      f"armed {self.is_armed()}, {len(self.simstate)} SIMSTATE", flush=True)
            if time.monotonic() > end:
                raise RuntimeError(f"timed out: {what}")
            self.pump()

    def alt(self):
        return self.rows[-1][1] if self.rows else 0.0

    def is_armed(self):
        return bool(self.armed) and self.armed[-1][1]


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
    log = Log(m)
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
    hlat, hlon = log.latlon
    def at(n, e):
        return (hlat + n / 111_195.0,
                hlon + e / (111_195.0 * math.cos(math.radians(hlat))))
    cmd = mavutil.mavlink
    items = [(cmd.MAV_CMD_NAV_WAYPOINT, hlat, hlon, 10.0)]  # item 0: home
    for n, e in [(20, 0), (20, 20), (0, 20), (0, 0)]:
        lat, lon = at(n, e)
        items.append((cmd.MAV_CMD_NAV_WAYPOINT, lat, lon, 10.0))
    items.append((cmd.MAV_CMD_NAV_LAND, hlat, hlon, 0.0))
    m.mav.mission_count_send(1, 1, len(items))
    sent = 0
    while sent < len(items):
        r = m.recv_match(type=["MISSION_REQUEST_INT", "MISSION_REQUEST"], blocking=True,
                         timeout=10)
        if r is None:
            raise RuntimeError("mission upload stalled")
        c, lat, lon, alt = items[r.seq]
        m.mav.mission_item_int_send(1, 1, r.seq, cmd.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, c,
                                    0, 1, 0, 0, 0, 0, int(lat * 1e7), int(lon * 1e7), alt)
        sent = r.seq + 1
    ack = m.recv_match(type="MISSION_ACK", blocking=True, timeout=10)
    print("mission:", ack)
    m.set_mode("AUTO")
    auto_at = log.t_ms
    log.wait("disarm after the landing", lambda: log.t_ms - auto_at > 5000 and not log.is_armed(), 300)
    disarm_at = log.t_ms
    with open(os.path.join(out, "ardupilot.csv"), "w") as f:
        w = csv.writer(f)
        w.writerow(["event", "t_boot_ms"])
        w.writerows([("armed", armed_at), ("hover_from", hover_from), ("auto", auto_at),
                     ("disarmed", disarm_at)])
    with open(os.path.join(out, "simstate.csv"), "w") as f:
        w = csv.writer(f)
        w.writerow(["t_boot_ms", "roll", "pitch", "yaw"])
        w.writerows(log.simstate)


def report(out, truth_csv):
    rows = list(csv.DictReader(open(truth_csv)))
    t = [float(r["t_s"]) for r in rows]
    q = [tuple(float(r[k]) for k in ("qw", "qx", "qy", "qz")) for r in rows]
    landed = [r["landed"] == "1" for r in rows]
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
    # The flight from the truth.
    off = coarse
    def truth_at(ms):
        return bisect.bisect_left(t, ms / 1000 + off)
    i_arm, i_auto, i_dis = truth_at(events["armed"]), truth_at(events["auto"]), truth_at(events["disarmed"])
    first_air = next(i for i in range(i_arm, len(t)) if not landed[i])
    touch = next(i for i in range(i_auto, len(t)) if landed[i])
    print(f"armed at {t[i_arm]:.1f} s (physics), airborne {t[first_air]:.1f} s, touchdown "
          f"{t[touch]:.2f} s, disarmed {t[i_dis]:.2f} s: {t[i_dis] - t[touch]:.2f} s after the touch")
    # Hover: from the hover's start to AUTO, the distance from the point held.
    i_h = truth_at(events["hover_from"])
    pos = [(float(r["n_m"]), float(r["e_m"]), float(r["d_m"])) for r in rows]
    seg = pos[i_h + 5000:i_auto]  # after 5 s of settling (1000 rows a second)
    n0 = sum(p[0] for p in seg) / len(seg)
    e0 = sum(p[1] for p in seg) / len(seg)
    h_rms = math.sqrt(sum((p[0] - n0) ** 2 + (p[1] - e0) ** 2 for p in seg) / len(seg))
    alt = [-p[2] for p in seg]
    a0 = sum(alt) / len(alt)
    print(f"hover: mean ({n0:.2f}, {e0:.2f}) m from the take-off spot, horizontal RMS about it "
          f"{h_rms:.3f} m, height {a0:.2f} m RMS {math.sqrt(sum((x - a0) ** 2 for x in alt) / len(alt)):.3f} m")
    # The square: from the first move to back within 1 m of the start.
    start = pos[i_auto]
    moved = next(i for i in range(i_auto, len(t)) if math.hypot(pos[i][0] - start[0], pos[i][1] - start[1]) > 0.5)
    far = next(i for i in range(moved, len(t)) if math.hypot(pos[i][0] - start[0], pos[i][1] - start[1]) > 15)
    back = next(i for i in range(far, len(t)) if math.hypot(pos[i][0] - start[0], pos[i][1] - start[1]) < 1.0)
    tilt = max(math.degrees(math.acos(max(-1, min(1, 1 - 2 * (q[i][1] ** 2 + q[i][2] ** 2)))))
               for i in range(first_air, touch))
    vz = max(float(rows[i]["vd_m_s"]) for i in range(touch - 10, touch + 1))
    land_off = math.hypot(pos[touch][0] - pos[first_air][0], pos[touch][1] - pos[first_air][1])
    print(f"square: {t[back] - t[moved]:.1f} s from the first move to back at the start; "
          f"largest tilt in the air {tilt:.1f}°; touchdown {vz:.2f} m/s, {land_off:.2f} m from "
          f"the take-off spot")


if __name__ == "__main__":
    main()
