"""Helpers shared by the Python end-to-end tests: find the binaries, run them on free ports."""

import asyncio
import contextlib
import os
import queue
import select
import signal
import socket
import subprocess
import sys
import threading
import time
import zlib
from pathlib import Path

import pytest

# pymavlink's MAVLink 2 dialect (extension fields such as MISSION_ITEM_INT.mission_type): chosen
# by this variable when pymavlink is first imported.
os.environ.setdefault("MAVLINK20", "1")
from pymavlink import mavutil  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]

# The Python package's API and pytest plugin (python/autopilot_sitl), on the binaries
# tools/test.sh built: the `vehicle`, `swarm` and `make_vehicle` fixtures.
sys.path.insert(0, str(ROOT / "python"))
os.environ.setdefault(
    "AUTOPILOT_SITL_BIN_DIR",
    str(Path(os.environ.get("CARGO_TARGET_DIR", ROOT / "target")) / os.environ.get("PROFILE", "debug")))
pytest_plugins = ["autopilot_sitl.pytest_plugin"]


def binary(name: str) -> Path:
    """A binary built by tools/test.sh (debug profile unless PROFILE says otherwise)."""
    target = Path(os.environ.get("CARGO_TARGET_DIR", ROOT / "target"))
    path = target / os.environ.get("PROFILE", "debug") / name
    if not path.exists():
        pytest.fail(f"{path} not built: run tools/test.sh (it builds before testing)")
    return path


def free_tcp_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def greet(conn, timeout=30.0):
    """A ground station's heartbeat every half second on `conn` until a heartbeat comes back: a
    UDP peer that answers only once it has heard from us may not be listening yet (a datagram
    sent before it binds is lost), so one heartbeat is not enough."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        conn.mav.heartbeat_send(mavutil.mavlink.MAV_TYPE_GCS,
                                mavutil.mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
        if conn.wait_heartbeat(timeout=0.5):
            return
    raise AssertionError(f"no heartbeat on {conn.address} in {timeout:.0f} s")


def receive(gcs, what, condition, timeout):
    """The first `what` from component 1 for which condition holds within `timeout` s, and
    when it came; (None, now) if none. A message pymavlink's dialect does not know
    (`UNKNOWN_<id>`) keeps its whole frame, the sender's component in it."""
    end = time.monotonic() + timeout
    while (left := end - time.monotonic()) > 0:
        m = gcs.recv_match(type=what, blocking=True, timeout=min(left, 0.1))
        if m is None:
            continue
        unknown = m.get_type().startswith("UNKNOWN_")
        component = m.data[6] if unknown else m.get_srcComponent()
        if component == 1 and condition(m):
            return m, time.monotonic()
    return None, time.monotonic()


def ack_and_said(gcs, command, timeout=5, said_within=1.0, wanted=lambda text: True):
    """The result of `command`'s COMMAND_ACK (None if none within `timeout` s) and every
    STATUSTEXT around it, reading on up to `said_within` s after the ack until one is
    `wanted` (a refusal's reason may come before or after its ack)."""
    result, said = None, []
    end = time.monotonic() + timeout
    while time.monotonic() < end and (result is None or not any(map(wanted, said))):
        m = gcs.recv_match(type=["COMMAND_ACK", "STATUSTEXT"], blocking=True, timeout=0.1)
        if m is None:
            continue
        if m.get_type() == "STATUSTEXT":
            said.append(m.text)
        elif m.command == command and result is None:
            result = m.result
            end = min(end, time.monotonic() + said_within)
    return result, said


def request_message(gcs, msg_id, what, param2=0, condition=lambda m: True, within_s=1.0):
    """REQUEST_MESSAGE as QGroundControl sends it: accepted within 1.2 s, the message within
    `within_s` (QGC: 1 s) of the ack."""
    gcs.mav.command_long_send(1, 1, mavutil.mavlink.MAV_CMD_REQUEST_MESSAGE, 0, msg_id, param2,
                              0, 0, 0, 0, 0)
    ack, _ = receive(gcs, "COMMAND_ACK",
                     lambda m: m.command == mavutil.mavlink.MAV_CMD_REQUEST_MESSAGE, 1.2)
    assert ack is not None and ack.result == mavutil.mavlink.MAV_RESULT_ACCEPTED, (msg_id, ack)
    m, _ = receive(gcs, what, condition, within_s)
    assert m is not None, f"{what} not within {within_s} s of the ack"
    return m


def mavftp(gcs):
    """pymavlink's MAVFTP client with its own settings but one: an operation ends after 1.5 s of
    silence instead of 3.7 (`idle_detection_time`, a setting MAVProxy's `ftp set` also
    offers), as suits a loopback link where a reply comes within milliseconds."""
    from pymavlink.mavftp import MAVFTP, MAVFTPSettings

    settings = MAVFTPSettings([
        ("debug", int, 0), ("pkt_loss_tx", int, 0), ("pkt_loss_rx", int, 0),
        ("max_backlog", int, 5), ("burst_read_size", int, 80), ("write_size", int, 80),
        ("write_qsize", int, 5), ("idle_detection_time", float, 1.5),
        ("read_retry_time", float, 1.0), ("retry_time", float, 0.5),
    ])
    return MAVFTP(gcs, 1, 1, settings=settings)


def ftp_crc32(data):
    """CRC-32 as MAVLink FTP computes it (from 0, no final inversion)."""
    return zlib.crc32(data, 0xFFFFFFFF) ^ 0xFFFFFFFF


def sim_control(port):
    """A pymavlink connection to the simulator's own endpoint (`sitl --control`), greeted."""
    sim = mavutil.mavlink_connection(f"udpout:127.0.0.1:{port}", source_system=255)
    greet(sim)  # sitl may still be starting
    return sim


def sim_param(sim, name, value):
    """PARAM_SET of a simulator parameter (REAL32); the value it answers with."""
    sim.mav.param_set_send(sim.target_system, sim.target_component, name.encode(), value,
                           mavutil.mavlink.MAV_PARAM_TYPE_REAL32)
    m = sim.recv_match(type="PARAM_VALUE", blocking=True, timeout=5,
                       condition=f"PARAM_VALUE.param_id == '{name}'")
    assert m is not None, f"no PARAM_VALUE for {name}"
    return m.param_value


class PtyLink:
    """A ground station on a serial line: the master side of a pseudo-terminal pair, read on a
    thread through pymavlink's parser (so the line never fills); the autopilot opens the slave
    side as a serial port. `name`: a symlink to the slave side, as udev names a USB radio
    (/dev/serial/by-id/...): `unplug` closes the pair and removes the name (the device is
    gone), `plug` makes a new pair under the same name. `heartbeat_s`: a ground-station
    heartbeat that often while plugged in."""

    def __init__(self, name=None, heartbeat_s=None):
        self.name, self.heartbeat_s = name, heartbeat_s
        self.lock = threading.Lock()
        self.master = None
        self.plugged = threading.Event()
        self.arrived = queue.Queue()
        self.mav = mavutil.mavlink.MAVLink(self, srcSystem=255, srcComponent=190)
        self.mav.robust_parsing = True
        self.plug()
        self.running = True
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def plug(self):
        master, slave = os.openpty()
        tty = os.ttyname(slave)
        os.close(slave)  # the autopilot opens it by name
        if self.name is not None:
            os.symlink(tty, self.name)
        self.device = str(self.name) if self.name is not None else tty
        while not self.arrived.empty():  # what came over the line before
            self.arrived.get_nowait()
        with self.lock:
            self.master = master
        self.plugged.set()

    def unplug(self):
        with self.lock:
            os.close(self.master)
            self.master = None
            self.plugged.clear()
        if self.name is not None:
            os.unlink(self.name)

    def close(self):
        self.running = False
        self.thread.join()
        if self.master is not None:
            self.unplug()

    def write(self, data):
        with self.lock:
            if self.master is not None:
                os.write(self.master, data)

    def _run(self):
        next_heartbeat = 0.0
        while self.running:
            if self.heartbeat_s and time.monotonic() >= next_heartbeat:
                next_heartbeat = time.monotonic() + self.heartbeat_s
                self.mav.heartbeat_send(mavutil.mavlink.MAV_TYPE_GCS,
                                        mavutil.mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
            with self.lock:
                fd = self.master
            try:
                if fd is None:
                    self.plugged.wait(0.1)  # unplugged: nothing to read until plugged in
                    continue
                if not select.select([fd], [], [], 0.05)[0]:
                    continue
                data = os.read(fd, 4096)
            except OSError:
                # Nobody has the slave side open (yet, or any more), or it was just unplugged:
                # look again shortly.
                time.sleep(0.05)
                continue
            for m in self.mav.parse_buffer(data) or []:
                self.arrived.put(m)

    def recv(self, what, condition, timeout=10):
        """The first message of type `what` from component 1 for which condition(msg) holds
        (those before it are dropped)."""
        m = self.try_recv(what, condition, timeout)
        if m is None:
            pytest.fail(f"no {what} over the serial line within {timeout} s")
        return m

    def try_recv(self, what, condition, timeout):
        """As `recv`, None when nothing came in time."""
        end = time.monotonic() + timeout
        while (left := end - time.monotonic()) > 0:
            try:
                m = self.arrived.get(timeout=left)
            except queue.Empty:
                break
            if m.get_type() == what and m.get_srcComponent() == 1 and condition(m):
                return m
        return None


@pytest.fixture
def scenario(tmp_path):
    """Writes scenario TOML text to a file and returns its path."""

    def write(text: str) -> Path:
        path = tmp_path / "scenario.toml"
        path.write_text(text)
        return path

    return write


def run_sitl(args, port):
    return subprocess.Popen(
        [str(binary("sitl")), "--params-dir", str(ROOT / "params"), "--status-interval", "0",
         "--connect-timeout", "20", "--autopilot", f"127.0.0.1:{port}", *args],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )


class Daemon:
    """sitl (real time x3) and an autopilot that can be stopped and started again on its ports,
    with its parameter store in a temporary directory."""

    def __init__(self, tmp_path, mavlink, connect=True, airframe="quad_x", scenario=None,
                 control=False, sim_args=(), lockstep=False, ap_args=(), speed=3):
        """`mavlink`: the ground-station endpoint, `{port}` standing for a free UDP port (on which
        a pymavlink connection listens when `connect`); both processes fly `airframe`, the
        simulator in `scenario` (a file) if given, its weather controlled on `control_port` if
        `control` (sitl --control), with `sim_args` added to its command line. `lockstep`: the
        simulator waits for each answer (still no faster than x3), so that how the machine
        schedules the processes cannot change the flight. `ap_args` are added to the autopilot's
        command line. `speed`: the simulator's pace, times real time (at most)."""
        self.ap_args = list(ap_args)
        self.airframe = airframe
        self.lockstep = lockstep
        self.sim_port, self.gcs_port = free_udp_port(), free_udp_port()
        self.control_port = free_udp_port() if control else None
        self.mavlink = mavlink.format(port=self.gcs_port)
        self.store = tmp_path / "params.toml"
        self.out = tmp_path / "autopilot.out"
        self.logs = tmp_path / "logs"
        self.sim_err = tmp_path / "sitl.err"
        self.gcs = None
        if connect:
            self.gcs = mavutil.mavlink_connection(f"udpin:127.0.0.1:{self.gcs_port}",
                                                  source_system=255)
        self.ap = None
        self.start()
        self.sim_args = [
            "--mode", "lockstep" if lockstep else "realtime", "--speed", str(speed),
            "--duration", "100000",
            "--airframe", airframe,
            *(["--scenario", str(scenario)] if scenario else []),
            *(["--control", f"127.0.0.1:{self.control_port}"] if control else []),
            *sim_args,
        ]
        self.sim = None
        self.start_sim()

    def start_sim(self):
        """Starts the simulator (again): a new world, the vehicle on the ground."""
        self.sim = subprocess.Popen(
            [str(binary("sitl")), "--params-dir", str(ROOT / "params"), "--status-interval", "0",
             *self.sim_args, "--autopilot", f"127.0.0.1:{self.sim_port}"],
            stdout=subprocess.PIPE, stderr=open(self.sim_err, "a"), text=True,
        )

    def stop_sim(self):
        """Ctrl-C to the simulator: its run ends cleanly (truth CSV flushed); its summary."""
        self.sim.send_signal(signal.SIGINT)
        out, _ = self.sim.communicate(timeout=30)
        assert self.sim.returncode == 0, out
        line = next(l for l in out.splitlines() if l.startswith("sitl summary:"))
        return dict(kv.split("=", 1) for kv in line.split()[2:])

    def start(self):
        self.ap = subprocess.Popen(
            [str(binary("autopilot")), "--params-dir", str(ROOT / "params"),
             "--source", f"udp://127.0.0.1:{self.sim_port}?lockstep={str(self.lockstep).lower()}",
             "--loop-hz", "500",
             "--airframe", self.airframe,
             "--mavlink", self.mavlink,
             "--param-store", str(self.store), "--log-dir", str(self.logs), *self.ap_args],
            stdout=open(self.out, "a"), stderr=subprocess.PIPE, text=True,
        )

    def summaries(self):
        """How many runs of the control loop have ended (one summary line each)."""
        return self.out.read_text().count("autopilot summary:")

    def stop(self):
        """Ctrl-C on a disarmed vehicle: the run ends cleanly, its store saved."""
        self.ap.send_signal(signal.SIGINT)
        _, err = self.ap.communicate(timeout=20)
        self.ap_stderr = err
        assert self.ap.returncode == 0, err
        assert "panicked" not in err, err

    def close(self):
        """Kills both processes. Printed (pytest shows it when the test fails): whether either
        had already ended, and the end of what each logged."""
        sim_ended, ap_ended = self.sim.poll(), self.ap.poll()
        self.sim.kill()
        self.sim.wait()
        if ap_ended is None:
            self.ap.kill()
            _, err = self.ap.communicate()
        elif self.ap.stderr and not self.ap.stderr.closed:
            err = self.ap.stderr.read()
        else:
            err = getattr(self, "ap_stderr", "")

        def state(code):
            return "killed" if code is None else f"had ended (exit {code})"

        print(f"sitl {state(sim_ended)}; its log's end:\n{self.sim_err.read_text()[-1500:]}\n"
              f"autopilot {state(ap_ended)}; its log's end:\n{err[-3000:]}", file=sys.stderr)
        assert "panicked" not in err, err


async def first(stream, condition, timeout):
    """The first item of an async stream for which condition(item) holds, within `timeout` s."""

    async def scan():
        async for item in stream:
            if condition(item):
                return item

    try:
        return await asyncio.wait_for(scan(), timeout)
    except asyncio.TimeoutError:
        pytest.fail(f"nothing as expected within {timeout} s")


@contextlib.asynccontextmanager
async def mavsdk_autopilot(url):
    """MAVSDK's native binding as a ground station connected by `url`, and the autopilot it
    found."""
    from mavsdk.asyncio import ComponentType, Configuration, Mavsdk

    config = Configuration.create_with_component_type(ComponentType.GROUND_STATION)
    async with Mavsdk(config) as mavsdk:
        await mavsdk.add_any_connection(url)
        system = await mavsdk.first_autopilot(timeout_s=30.0)
        assert system is not None, "no autopilot found"
        yield system


def run_mavsdk_flight(make_vehicle, flight, airframe="quad_x"):
    """Runs the coroutine `flight(vehicle)` against a fresh vehicle of `airframe` (the plugin's
    `make_vehicle`: the embedded simulator in lockstep at six times real time, the flights'
    times being the simulator's); the plugin stops it after."""
    asyncio.run(flight(make_vehicle(airframe=airframe, speed=6)))


async def land_and_disarm(action, telemetry):
    """MAVSDK's land(), then the disarm that ends it."""
    await action.land()
    await first(telemetry.subscribe_armed(), lambda a: not a, 60)
