"""What the flights of real autopilots on `sitl` share (tools/fly_ardupilot_json.py,
tools/fly_px4.py): the autopilot's telemetry kept on its own clock, the square mission, and the
flight's figures from sitl's truth CSV."""
import bisect
import csv
import math
import os
import signal
import subprocess
import time

from pymavlink import mavutil


def stop(*procs, groups=()):
    """Stops the autopilot and sitl: SIGINT to each of `procs`, SIGTERM to the process group of
    each of `groups` (a PX4 and what it starts); then waits up to 20 s each before killing."""
    for p in groups:
        os.killpg(p.pid, signal.SIGTERM)
    for p in procs:
        p.send_signal(signal.SIGINT)
    for p in (*groups, *procs):
        try:
            p.wait(timeout=20)
        except subprocess.TimeoutExpired:
            p.kill()


def quat_angle_deg(a, b):
    """The angle between two attitudes given as (w, x, y, z) quaternions (deg): of the rotation
    from one to the other, 2 atan2(|vector part|, |scalar part|), which stays exact for small
    angles and for quaternions not quite of unit length (a float32 one); 2 acos of the dot
    product would make 0.03° of a float32's last bit near identity."""
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    # conj(a) * b
    w = aw * bw + ax * bx + ay * by + az * bz
    x = aw * bx - ax * bw - ay * bz + az * by
    y = aw * by + ax * bz - ay * bw - az * bx
    z = aw * bz - ax * by + ay * bx - az * bw
    return math.degrees(2 * math.atan2(math.sqrt(x * x + y * y + z * z), abs(w)))


def euler_to_quat(roll, pitch, yaw):
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    return (cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy)


class Log:
    """Every message of the types in `keep` kept with the autopilot's boot time (the last
    time_boot_ms seen), with its arming, its texts and its height."""

    def __init__(self, m, keep=()):
        self.m, self.t_ms, self.rows = m, 0, []
        self.kept = {k: [] for k in keep}
        self.armed, self.texts = [], []
        self.latlon = None

    def pump(self, timeout=0.5):
        msg = self.m.recv_match(blocking=True, timeout=timeout)
        for _ in range(200):  # a stream never runs dry: return now and then
            if msg is None:
                break
            t = msg.get_type()
            if hasattr(msg, "time_boot_ms"):
                self.t_ms = msg.time_boot_ms
            if t in self.kept:
                self.kept[t].append((self.t_ms, msg))
            if t == "HEARTBEAT" and msg.type != mavutil.mavlink.MAV_TYPE_GCS \
                    and msg.autopilot != mavutil.mavlink.MAV_AUTOPILOT_INVALID:
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
                      f"armed {self.is_armed()}", flush=True)
            if time.monotonic() > end:
                raise RuntimeError(f"timed out: {what}")
            self.pump()

    def alt(self):
        return self.rows[-1][1] if self.rows else 0.0

    def is_armed(self):
        return bool(self.armed) and self.armed[-1][1]


def square(home_latlon, side_m=20.0):
    """The square's corners: `side_m` north, then east, back south, back home (lat, lon)."""
    hlat, hlon = home_latlon

    def at(n, e):
        return (hlat + n / 111_195.0,
                hlon + e / (111_195.0 * math.cos(math.radians(hlat))))
    return [at(n, e) for n, e in [(side_m, 0), (side_m, side_m), (0, side_m), (0, 0)]]


def upload_mission(m, target, items, yaw=0.0):
    """The mission protocol's upload: `items` are (command, lat, lon, alt above home), each with
    `yaw` as its param 4 (NaN: the autopilot's own choice of heading)."""
    cmd = mavutil.mavlink
    m.mav.mission_count_send(*target, len(items))
    sent = 0
    while sent < len(items):
        r = m.recv_match(type=["MISSION_REQUEST_INT", "MISSION_REQUEST"], blocking=True,
                         timeout=10)
        if r is None:
            raise RuntimeError("mission upload stalled")
        c, lat, lon, alt = items[r.seq]
        m.mav.mission_item_int_send(*target, r.seq, cmd.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, c,
                                    0, 1, 0, 0, 0, yaw, int(round(lat * 1e7)),
                                    int(round(lon * 1e7)), alt)
        sent = r.seq + 1
    ack = m.recv_match(type="MISSION_ACK", blocking=True, timeout=10)
    if ack is None or ack.type != cmd.MAV_MISSION_ACCEPTED:
        raise RuntimeError(f"mission refused: {ack}")


def await_landing(log, path, armed_at, hover_from):
    """From the mission's start (now) to the disarm on the ground; then the flight's moments on
    the autopilot's clock, written to `path`."""
    auto_at = log.t_ms
    log.wait("disarm after the landing",
             lambda: log.t_ms - auto_at > 5000 and not log.is_armed(), 300)
    with open(path, "w") as f:
        w = csv.writer(f)
        w.writerow(["event", "t_boot_ms"])
        w.writerows([("armed", armed_at), ("hover_from", hover_from), ("auto", auto_at),
                     ("disarmed", log.t_ms)])


class Truth:
    """sitl's truth CSV: time, attitude, position, landed."""

    def __init__(self, path):
        rows = list(csv.DictReader(open(path)))
        self.rows = rows
        self.t = [float(r["t_s"]) for r in rows]
        self.q = [tuple(float(r[k]) for k in ("qw", "qx", "qy", "qz")) for r in rows]
        self.landed = [r["landed"] == "1" for r in rows]
        self.pos = [(float(r["n_m"]), float(r["e_m"]), float(r["d_m"])) for r in rows]

    def index(self, t_s):
        """The first row at or after `t_s`."""
        return bisect.bisect_left(self.t, t_s)


def tilt_deg(q):
    """The tilt of a (w, x, y, z) attitude: the angle of the body's down axis from the vertical."""
    return math.degrees(math.acos(max(-1.0, min(1.0, 1 - 2 * (q[1] ** 2 + q[2] ** 2)))))


def report_flight(truth, i_arm, i_hover, i_auto, i_dis):
    """The flight's figures from the truth: take-off, hover, the square, the landing. The rows
    are the truth's at arming, the hover's start, the mission's start and the disarm."""
    t, pos, q, landed = truth.t, truth.pos, truth.q, truth.landed
    first_air = next(i for i in range(i_arm, len(t)) if not landed[i])
    touch = next(i for i in range(i_auto, len(t)) if landed[i])
    print(f"armed at {t[i_arm]:.1f} s (physics), airborne {t[first_air]:.1f} s, touchdown "
          f"{t[touch]:.2f} s, disarmed {t[i_dis]:.2f} s: {t[i_dis] - t[touch]:.2f} s after the touch")
    # Hover: from the hover's start to AUTO, the distance from the point held.
    rate = round(1 / (t[1] - t[0]))
    seg = pos[i_hover + 5 * rate:i_auto]  # after 5 s of settling
    n0 = sum(p[0] for p in seg) / len(seg)
    e0 = sum(p[1] for p in seg) / len(seg)
    h_rms = math.sqrt(sum((p[0] - n0) ** 2 + (p[1] - e0) ** 2 for p in seg) / len(seg))
    alt = [-p[2] for p in seg]
    a0 = sum(alt) / len(alt)
    print(f"hover: mean ({n0:.2f}, {e0:.2f}) m from the take-off spot, horizontal RMS about it "
          f"{h_rms:.3f} m, height {a0:.2f} m RMS {math.sqrt(sum((x - a0) ** 2 for x in alt) / len(alt)):.3f} m")
    # The square: from the first move to back within 1 m of the start.
    start = pos[i_auto]

    def away(i):
        return math.hypot(pos[i][0] - start[0], pos[i][1] - start[1])
    moved = next(i for i in range(i_auto, len(t)) if away(i) > 0.5)
    far = next(i for i in range(moved, len(t)) if away(i) > 15)
    back = next(i for i in range(far, len(t)) if away(i) < 1.0)
    tilt = max(tilt_deg(q[i]) for i in range(first_air, touch))
    vz = max(float(truth.rows[i]["vd_m_s"]) for i in range(touch - 10, touch + 1))
    land_off = math.hypot(pos[touch][0] - pos[first_air][0], pos[touch][1] - pos[first_air][1])
    print(f"square: {t[back] - t[moved]:.1f} s from the first move to back at the start; "
          f"largest tilt in the air {tilt:.1f}°; touchdown {vz:.2f} m/s, {land_off:.2f} m from "
          f"the take-off spot")
