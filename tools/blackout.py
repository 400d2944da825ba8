#!/usr/bin/env python3
"""A sensor link that goes dark in the air: `sitl --mode realtime` and the autopilot with a relay
between them that drops every datagram, both ways, for a stretch of the simulator's time (a
telemetry radio out of range, a USB cable pulled and pushed back, a flight board that resets).

    cargo build --release -p autopilot -p sitl
    tools/blackout.py [--gaps 2,5] [--heights 5,20] [--seeds 1,2,3] [--bin target/release]

For each case the autopilot takes off on its own (`--takeoff H`), hovers, the link goes dark for
the gap while the simulator flies on with the last motor command held, and comes back. Printed
per case, from the simulator's truth and the autopilot's flight CSV: the largest tilt in the dark,
the first touch of the ground (s after the frames' return; negative: in the dark), the attitude
estimate's error at the return and at worst from 1 s after it while in the air, and the hardest
touch of the ground (its speed). The figures are in docs/performance.md.
"""
import argparse
import csv
import math
import os
import socket
import subprocess
import sys
import tempfile
import threading
from pathlib import Path

os.environ.setdefault("MAVLINK20", "1")
from peer_flight import tilt_deg  # noqa: E402
from pymavlink.dialects.v20 import common as mavlink2  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
HIL_SENSOR = 107


def free_udp_port():
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Relay(threading.Thread):
    """Forwards the simulator's frames to the autopilot and its answers back, dropping both ways
    while the simulator's clock (read from each frame's HIL_SENSOR) is in [start_s, start_s + gap_s).
    The simulator sends to `sim_side`; the autopilot listens on `autopilot_port`."""

    def __init__(self, sim_side, autopilot_port, start_s, gap_s):
        super().__init__(daemon=True)
        self.to_sim = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.to_sim.bind(("127.0.0.1", sim_side))
        self.to_ap = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.to_ap.bind(("127.0.0.1", 0))
        self.ap = ("127.0.0.1", autopilot_port)
        self.sim = None
        self.window = (start_s, start_s + gap_s)
        self.dark = False
        self.dropped = 0
        self.parser = mavlink2.MAVLink(None)
        self.stop = threading.Event()

    def sim_time_s(self, datagram):
        """The HIL_SENSOR time in the frame, if there is one."""
        try:
            for m in self.parser.parse_buffer(datagram) or []:
                if m.get_msgId() == HIL_SENSOR:
                    return m.time_usec / 1e6
        except Exception:  # a frame we cannot read is forwarded as it is
            pass
        return None

    def run(self):
        import select
        while not self.stop.is_set():
            ready, _, _ = select.select([self.to_sim, self.to_ap], [], [], 0.2)
            for s in ready:
                data, addr = s.recvfrom(65536)
                if s is self.to_sim:
                    self.sim = addr
                    t = self.sim_time_s(data)
                    if t is not None:
                        self.dark = self.window[0] <= t < self.window[1]
                    if self.dark:
                        self.dropped += 1
                    else:
                        self.to_ap.sendto(data, self.ap)
                elif self.dark:
                    self.dropped += 1
                elif self.sim is not None:
                    self.to_sim.sendto(data, self.sim)


def rows(path):
    with open(path) as f:
        return list(csv.DictReader(f))


def quat_from_euler_deg(roll, pitch, yaw):
    r, p, y = (math.radians(a) / 2 for a in (roll, pitch, yaw))
    cr, sr, cp, sp, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y), math.sin(y)
    return (cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy)


def angle_between_deg(a, b):
    dot = abs(sum(x * y for x, y in zip(a, b)))
    return math.degrees(2 * math.acos(min(1.0, dot)))


def fly(bins, height_m, gap_s, seed, workdir, speed=1.0):
    """One flight; returns its figures (a dict)."""
    workdir.mkdir(parents=True, exist_ok=True)
    ap_port, sim_side = free_udp_port(), free_udp_port()
    # The hover begins about 8 s after the start plus the climb at 1.5 m/s; the link goes dark 5 s
    # into it.
    start_s = 8.0 + height_m / 1.5 + 5.0
    relay = Relay(sim_side, ap_port, start_s, gap_s)
    relay.start()
    truth_csv, flight_csv = workdir / "truth.csv", workdir / "flight.csv"
    ap = subprocess.Popen(
        [str(bins / "autopilot"), "--params-dir", str(ROOT / "params"),
         "--source", f"udp://127.0.0.1:{ap_port}?lockstep=false", "--loop-hz", "500",
         "--takeoff", str(height_m), "--hover", "15", "--mavlink", "none",
         "--param-store", "none", "--log-dir", "none", "--flight-csv", str(flight_csv)],
        stdout=subprocess.PIPE, stderr=open(workdir / "autopilot.err", "w"), text=True)
    sim = subprocess.Popen(
        [str(bins / "sitl"), "--params-dir", str(ROOT / "params"), "--mode", "realtime",
         "--speed", str(speed), "--duration", str(start_s + gap_s + 60), "--seed", str(seed),
         "--status-interval", "0", "--truth-csv", str(truth_csv),
         "--autopilot", f"127.0.0.1:{sim_side}"],
        stdout=subprocess.PIPE, stderr=open(workdir / "sitl.err", "w"), text=True)
    try:
        ap_out, _ = ap.communicate(timeout=(start_s + gap_s + 90) / speed)
    except subprocess.TimeoutExpired:
        ap.kill()
        ap_out, _ = ap.communicate()
    sim.terminate()
    sim.communicate(timeout=30)
    relay.stop.set()
    relay.join()
    return figures(rows(truth_csv), rows(flight_csv), start_s, gap_s, ap_out, relay.dropped)


def figures(truth, flight, start_s, gap_s, ap_out, dropped):
    """The flight's figures: the largest true tilt in the dark, the first touch of the ground
    after the link went dark (s from the return; negative: in the dark), the attitude
    estimate's error at the return and its largest from 1 s after it while in the air, the
    hardest touch of the ground."""
    end_s = start_s + gap_s
    t = [float(r["t_s"]) for r in truth]
    q = [tuple(float(r[k]) for k in ("qw", "qx", "qy", "qz")) for r in truth]
    landed = [r["landed"] == "1" for r in truth]
    dark_tilt = max((tilt_deg(qq) for tt, qq in zip(t, q) if start_s <= tt < end_s), default=0.0)
    touch = next((tt for tt, on in zip(t, landed) if tt > start_s and on), math.nan)
    # The attitude estimate against the truth the flight CSV carries, from the frames' return,
    # while the vehicle is in the air.
    errors = []
    for r in flight:
        tt = float(r["t_s"])
        if tt < end_s or r["true_roll_deg"] in ("", "nan") or -float(r["true_d_m"]) < 0.3:
            continue
        est = quat_from_euler_deg(*(float(r[k]) for k in ("roll_deg", "pitch_deg", "yaw_deg")))
        true = quat_from_euler_deg(*(float(r[k]) for k in ("true_roll_deg", "true_pitch_deg", "true_yaw_deg")))
        errors.append((tt - end_s, angle_between_deg(est, true)))
    at_return = errors[0][1] if errors and errors[0][0] < 0.05 else math.nan
    after_1s = max((e for dt, e in errors if dt >= 1.0), default=math.nan)
    # The hardest touch: the largest speed in the 0.1 s before each time the truth lands.
    impact = 0.0
    for i in range(1, len(truth)):
        if landed[i] and not landed[i - 1] and t[i] > start_s:
            for j in range(max(0, i - 10), i + 1):
                v = [float(truth[j][k]) for k in ("vn_m_s", "ve_m_s", "vd_m_s")]
                impact = max(impact, math.sqrt(sum(x * x for x in v)))
    summary = next((l for l in ap_out.splitlines() if l.startswith("autopilot summary:")), "")
    return {"dark_tilt_deg": dark_tilt, "first_touch_s": touch - end_s,
            "err_at_return_deg": at_return, "err_after_1s_deg": after_1s,
            "impact_m_s": impact, "dropped": dropped, "summary": summary}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--gaps", default="2,5")
    ap.add_argument("--heights", default="5,20")
    ap.add_argument("--seeds", default="1,2,3")
    ap.add_argument("--bin", default=str(ROOT / "target" / "release"))
    ap.add_argument("--out", help="keep each flight's files here")
    args = ap.parse_args()
    out = Path(args.out) if args.out else Path(tempfile.mkdtemp(prefix="blackout-"))
    print(f"{'gap s':>5} {'height m':>8} {'seed':>4} {'tilt in the dark':>16} {'touch s':>8} "
          f"{'err at return':>13} {'err from 1 s':>12} {'impact m/s':>10}")
    for gap in [float(g) for g in args.gaps.split(",")]:
        for height in [float(h) for h in args.heights.split(",")]:
            for seed in [int(s) for s in args.seeds.split(",")]:
                f = fly(Path(args.bin), height, gap, seed, out / f"gap{gap}_h{height}_s{seed}")
                print(f"{gap:5.1f} {height:8.1f} {seed:4d} {f['dark_tilt_deg']:16.1f} "
                      f"{f['first_touch_s']:8.2f} {f['err_at_return_deg']:13.1f} {f['err_after_1s_deg']:12.1f} "
                      f"{f['impact_m_s']:10.2f}", flush=True)
    print(f"files in {out}")


if __name__ == "__main__":
    sys.exit(main())
