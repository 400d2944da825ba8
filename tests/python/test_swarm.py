"""Many vehicles at once: ten in one autopilot process on one clock (`--count`), and several
sitl + autopilot pairs as separate processes (`-i N`), each its own MAVLink system."""

import math
import os
import signal
import random
import socket
import subprocess
import threading
import time

import pytest
from conftest import ROOT, binary, greet, mavutil
from test_ground_station import ack, armed, ready_to_arm, wait, wait_holding_in_air

COUNT = 10


def free_udp_ports(n):
    """The first of `n` consecutive free UDP ports (held while they are checked), below the
    kernel's ephemeral range: there, a port free now could be given to any socket bound to port 0
    before the vehicle that is to use it starts (the vehicles' own ground-station sockets among
    them; one once took autopilot 0's simulator port)."""
    try:
        with open("/proc/sys/net/ipv4/ip_local_port_range") as f:
            ephemeral = int(f.read().split()[0])
    except (OSError, ValueError, IndexError):
        ephemeral = 32768
    rng = random.Random()
    for _ in range(50):
        base = rng.randrange(10000, ephemeral - n)
        held = []
        try:
            for p in range(base, base + n):
                s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
                held.append(s)
                s.bind(("127.0.0.1", p))
            return base
        except OSError:
            continue
        finally:
            for s in held:
                s.close()
    pytest.fail(f"no {n} consecutive free UDP ports")


def request(conn, sysid, what):
    """`REQUEST_MESSAGE` for `what`, sent again every 2 s until it comes (as the command protocol
    has a ground station retransmit: a datagram on a busy machine may be lost), for 20 s."""
    end = time.monotonic() + 20
    while True:
        conn.mav.command_long_send(sysid, 1, mavutil.mavlink.MAV_CMD_REQUEST_MESSAGE, 0,
                                   getattr(mavutil.mavlink, f"MAVLINK_MSG_ID_{what}"),
                                   0, 0, 0, 0, 0, 0)
        m = conn.recv_match(type=what, blocking=True, timeout=2)
        if m is not None:
            return m
        assert time.monotonic() < end, f"no {what} from system {sysid} in 20 s"


class Heartbeats:
    """A ground station's heartbeat every second on each connection, as a ground station
    keeps its links alive (a UDP peer silent for 10 s is no longer answered)."""

    def __init__(self, conns):
        self.conns, self.stop = conns, threading.Event()
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self):
        while not self.stop.wait(1.0):
            for c in list(self.conns):
                c.mav.heartbeat_send(mavutil.mavlink.MAV_TYPE_GCS,
                                     mavutil.mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)

    def close(self):
        self.stop.set()
        self.thread.join()


def test_ten_vehicles_in_one_process_fly_on_one_clock(tmp_path):
    """`autopilot --sim --count 10`: ten systems, each on its own port (udpin, offset by its
    instance), all heard together by one ground station on a shared port (QGroundControl's
    way); each armed and sent to its own height by its own commands, homes 3 m apart, all
    landed; one summary line per vehicle and the swarm's."""
    base = free_udp_ports(COUNT)
    watcher = mavutil.mavlink_connection("udpin:127.0.0.1:0", source_system=250)
    watch_port = watcher.port.getsockname()[1]
    out = tmp_path / "swarm.out"
    ap = subprocess.Popen(
        [str(binary("autopilot")), "--params-dir", str(ROOT / "params"), "--sim",
         "--count", str(COUNT), "--speed", "2", "--seed", "5",
         "--mavlink", f"udpin://127.0.0.1:{base}",
         "--mavlink", f"udpout://127.0.0.1:{watch_port}?bind=0&shared",
         "--param-store", "none", "--log-dir", str(tmp_path / "logs")],
        stdout=open(out, "w"), stderr=subprocess.PIPE, text=True,
    )
    conns = []
    heartbeats = Heartbeats(conns)
    try:
        # One port hears them all: every system's heartbeat, a quadrotor each.
        heard = set()
        end = time.monotonic() + 30
        while len(heard) < COUNT and time.monotonic() < end:
            m = watcher.recv_match(type="HEARTBEAT", blocking=True, timeout=0.5)
            if m is not None:
                assert m.type == mavutil.mavlink.MAV_TYPE_QUADROTOR
                heard.add(m.get_srcSystem())
        assert heard == set(range(1, COUNT + 1)), heard

        for k in range(COUNT):
            c = mavutil.mavlink_connection(f"udpout:127.0.0.1:{base + k}", source_system=255)
            greet(c)
            assert c.target_system == k + 1, (k, c.target_system)
            conns.append(c)
        # Each in its own world, side by side: the simulators' truth, 3 m east of each other.
        truth = [request(c, k + 1, "HIL_STATE_QUATERNION") for k, c in enumerate(conns)]
        for k in range(1, COUNT):
            north = (truth[k].lat - truth[0].lat) * 1e-7 * math.pi / 180 * 6.371e6
            east = ((truth[k].lon - truth[0].lon) * 1e-7 * math.pi / 180 * 6.371e6
                    * math.cos(math.radians(truth[0].lat * 1e-7)))
            # A spherical Earth here, WGS-84 there: 0.3 % apart.
            assert abs(north) < 0.05 and abs(east - 3.0 * k) < 0.01 * 3.0 * k, (k, north, east)

        # Above MIS_TAKEOFF_ALT (2.5 m), the least a take-off climbs.
        heights = [3.0 + 0.25 * k for k in range(COUNT)]
        for k, c in enumerate(conns):
            ready_to_arm(c)
            home = wait(c, "GLOBAL_POSITION_INT", lambda m: True)
            c.mav.command_long_send(k + 1, 1, mavutil.mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0,
                                    1, 0, 0, 0, 0, 0, 0)
            assert ack(c, mavutil.mavlink.MAV_CMD_COMPONENT_ARM_DISARM) == 0, k
            c.mav.command_long_send(k + 1, 1, mavutil.mavlink.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0,
                                    math.nan, math.nan, math.nan, home.alt / 1000 + heights[k])
            assert ack(c, mavutil.mavlink.MAV_CMD_NAV_TAKEOFF) == 0, k
        for k, c in enumerate(conns):
            wait_holding_in_air(c, timeout=60)
            p = wait(c, "GLOBAL_POSITION_INT",
                     lambda m: abs(m.relative_alt / 1000 - heights[k]) < 0.3, timeout=20)
            # Every other vehicle flies on meanwhile: all are in the air at once.
            assert p.relative_alt > 1500
        for k, c in enumerate(conns):
            c.mav.command_long_send(k + 1, 1, mavutil.mavlink.MAV_CMD_NAV_LAND, 0,
                                    0, 0, 0, 0, 0, 0, 0)
            assert ack(c, mavutil.mavlink.MAV_CMD_NAV_LAND) == 0, k
        for c in conns:
            wait(c, "HEARTBEAT", lambda m: not armed(m), timeout=60)
    finally:
        heartbeats.close()
        ap.send_signal(signal.SIGINT)
        try:
            _, err = ap.communicate(timeout=30)
        except subprocess.TimeoutExpired:
            ap.kill()
            _, err = ap.communicate()
    assert ap.returncode == 0, err[-3000:]
    assert "panicked" not in err
    text = out.read_text()
    flights = [l for l in text.splitlines() if l.startswith("autopilot summary:")]
    assert len(flights) == COUNT, text[-2000:]
    for k in range(COUNT):
        line = next(l for l in flights if l.endswith(f" system_id={k + 1}"))
        fields = dict(kv.split("=", 1) for kv in line.split()[2:])
        assert fields["landed"] == "true" and fields["disarmed"] == "true", line
        assert abs(float(fields["max_alt_m"]) - heights[k]) < 0.4, line
    swarm = next(l for l in text.splitlines() if l.startswith("swarm summary:"))
    fields = dict(kv.split("=", 1) for kv in swarm.split()[2:])
    assert fields["vehicles"] == str(COUNT) and fields["landed"] == str(COUNT), swarm
    assert fields["failed"] == "0", swarm
    assert len(list((tmp_path / "logs").glob("*.tlog"))) == COUNT


def test_ten_vehicles_as_separate_processes(tmp_path):
    """`tools/swarm.sh 10`: ten sitl + autopilot pairs (`-i k`), each pair in lockstep on its own
    HIL port, each vehicle taking off, hovering and landing on its own; one ground-station port
    shared by all hears the ten systems."""
    hil = free_udp_ports(COUNT)
    watcher = mavutil.mavlink_connection("udpin:127.0.0.1:0", source_system=250)
    watch_port = watcher.port.getsockname()[1]
    env = {**os.environ, "SWARM_BIN": str(binary("autopilot").parent),
           "SWARM_LOG_DIR": str(tmp_path / "swarm"), "SWARM_HIL_PORT": str(hil),
           "SWARM_SITL_ARGS": "--speed 4"}
    run = subprocess.Popen(
        [str(ROOT / "tools" / "swarm.sh"), str(COUNT), "--takeoff", "2", "--hover", "1",
         "--param-store", "none", "--log-dir", "none",
         "--mavlink", f"udpout://127.0.0.1:{watch_port}?bind=0&shared"],
        cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )
    heard = set()
    while run.poll() is None:
        m = watcher.recv_match(type="HEARTBEAT", blocking=True, timeout=0.5)
        if m is not None:
            heard.add(m.get_srcSystem())
    out, err = run.communicate(timeout=60)
    assert run.returncode == 0, err[-3000:]
    assert heard == set(range(1, COUNT + 1)), heard
    lines = [l for l in out.splitlines() if l.startswith("autopilot summary:")]
    assert len(lines) == COUNT, out
    for k, line in enumerate(lines):
        fields = dict(kv.split("=", 1) for kv in line.split()[2:])
        assert fields["system_id"] == str(k + 1), line
        assert fields["source"] == f"udp://127.0.0.1:{hil + k}", line
        assert fields["landed"] == "true" and fields["pacing"] == "lockstep", line
        assert 1.6 < float(fields["max_alt_m"]) < 2.5, line
    for k in range(COUNT):
        assert "sitl summary:" in (tmp_path / "swarm" / f"sitl_{k}.log").read_text()


def test_a_swarm_whose_simulator_ports_a_simulator_could_take_is_refused(tmp_path):
    """A simulator sends from a port the kernel picks in its ephemeral range; an autopilot's HIL
    port in that range can be taken before the autopilot binds it (one run in 25 lost a vehicle
    so). `tools/swarm.sh` refuses such ports before it starts anything, and says which to use;
    the ten-vehicle swarm above flies on ports below the range."""
    with open("/proc/sys/net/ipv4/ip_local_port_range") as f:
        low, high = map(int, f.read().split())
    for first in (low - 1, (low + high) // 2, high):
        run = subprocess.run(
            [str(ROOT / "tools" / "swarm.sh"), "3", "--takeoff", "2"],
            cwd=ROOT, capture_output=True, text=True, timeout=30,
            env={**os.environ, "SWARM_BIN": str(binary("autopilot").parent),
                 "SWARM_LOG_DIR": str(tmp_path / "swarm"), "SWARM_HIL_PORT": str(first)},
        )
        assert run.returncode == 2, run.stderr
        assert "overlap the kernel's ephemeral ports" in run.stderr, run.stderr
        assert f"set SWARM_HIL_PORT below {low - 2}" in run.stderr, run.stderr
        assert not (tmp_path / "swarm").exists(), "nothing started"
