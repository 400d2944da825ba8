"""The daemon under duress, as a user meets it: stopped by a service manager or killed outright
(its flight log keeps all but the last second), flooded with traffic at its ground-station port
(the control loop keeps its rate, a second ground station is still served), its links lost and
found again (it reacts, says so, and carries on without a restart).
"""

import json
import math
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

from pymavlink import mavutil
from pyulog import ULog

from conftest import ROOT, Daemon, PtyLink, binary, free_udp_port, greet
from test_ground_station import (INT32, REAL32, ack, armed, int_bits, ready_to_arm, set_param,
                                 start_afresh, take_off_and_land, wait, wait_holding_in_air)
from test_safety import Heartbeats, reposition_north


def csv_rows(path):
    """The flight CSV's header and its complete rows (a killed writer may leave half a line)."""
    text = path.read_text()
    lines = text.split("\n")
    header, rows = lines[0].split(","), lines[1:-1]  # the last is "" or a cut line
    assert all(len(r.split(",")) == len(header) for r in rows), "a damaged row before the end"
    return header, [dict(zip(header, r.split(","))) for r in rows]


def vehicle_time_s(gcs):
    """The vehicle's clock (its sensor time, as the flight CSV's t_s) in the newest ATTITUDE."""
    while gcs.recv_match(blocking=False) is not None:
        pass
    return wait(gcs, "ATTITUDE", lambda m: True, 5).time_boot_ms / 1000


def test_logs_are_flushed_on_sigterm_and_a_killed_daemon_loses_under_a_second(tmp_path):
    """SIGTERM on the ground: the daemon stops at once, cleanly (exit 0, its summary), its
    flight CSV whole. SIGKILL in the air: the CSV on disk reaches to within a second of the
    vehicle's last telemetry (the simulator runs 3x real time, so a wall-clock flush policy
    would lose three times more), the ULog flight log to within half a second."""
    first, second = tmp_path / "flight1.csv", tmp_path / "flight2.csv"
    daemon = Daemon(tmp_path, "udpout://127.0.0.1:{port}?bind=0",
                    ap_args=["--flight-csv", str(first)])
    try:
        gcs = daemon.gcs
        assert gcs.wait_heartbeat(timeout=30), "no heartbeat"
        ready_to_arm(gcs)
        seen_s = vehicle_time_s(gcs)
        daemon.ap.send_signal(signal.SIGTERM)
        _, err = daemon.ap.communicate(timeout=20)
        assert daemon.ap.returncode == 0, err
        assert "SIGTERM: stopping" in err, err
        assert "autopilot summary:" in daemon.out.read_text()
        header, rows = csv_rows(first)
        assert first.read_text().endswith("\n") and "motor4" in header
        assert float(rows[-1]["t_s"]) >= seen_s, (rows[-1]["t_s"], seen_s)

        daemon.ap_args = ["--flight-csv", str(second)]
        start_afresh(daemon)
        ready_to_arm(gcs)
        gcs.arducopter_arm()
        assert ack(gcs, mavutil.mavlink.MAV_CMD_COMPONENT_ARM_DISARM) == 0
        gcs.mav.command_long_send(1, 1, mavutil.mavlink.MAV_CMD_NAV_TAKEOFF, 0,
                                  0, 0, 0, float("nan"), float("nan"), float("nan"), float("nan"))
        assert ack(gcs, mavutil.mavlink.MAV_CMD_NAV_TAKEOFF) == 0
        wait_holding_in_air(gcs)
        seen_s = vehicle_time_s(gcs)
        killed_at = time.time()
        daemon.ap.kill()
        daemon.ap.wait()
        _, rows = csv_rows(second)
        last = rows[-1]
        assert float(last["t_s"]) >= seen_s - 1.0, (last["t_s"], seen_s)
        assert last["armed"] == "1" and float(last["d_m"]) < -1.5, last  # in the air
        # The telemetry log (handed to its writer every half second of wall-clock time) reaches
        # to within a second of the kill, and what it holds reads whole.
        tlog = max(daemon.logs.glob("*.tlog"), key=lambda p: p.stat().st_mtime)
        log = mavutil.mavlink_connection(str(tlog))
        stamps = []
        while (m := log.recv_match()) is not None:
            assert m.get_type() != "BAD_DATA", m
            stamps.append(m._timestamp)
        assert stamps and stamps[-1] >= killed_at - 1.0, (stamps[-1:], killed_at)
        # The flight log (handed over every half second of the vehicle's time) reads in pyulog,
        # whole, to within half a second of the vehicle's last telemetry.
        ulg = max(daemon.logs.glob("*.ulg"), key=lambda p: p.stat().st_mtime)
        flight_log = ULog(str(ulg))
        assert not flight_log.file_corruption
        # (0.5 s handed over at a time, and a moment for the writer thread to write it.)
        assert flight_log.last_timestamp / 1e6 >= seen_s - 0.6, (flight_log.last_timestamp, seen_s)
    finally:
        daemon.close()


class LoopTiming:
    """The daemon's control-loop reports (`--loop-stats-s`), read from its stderr as they come:
    (arrival time, rate Hz, jitter p99 µs, overruns) each."""

    def __init__(self, process):
        self.reports, self.taken = [], 0
        self.thread = threading.Thread(target=self._read, args=(process.stderr,), daemon=True)
        self.thread.start()

    def _read(self, stream):
        for line in stream:
            if "control loop" in line and "jitter_p99_us=" in line:
                f = dict(kv.split("=", 1) for kv in line.split() if "=" in kv)
                self.reports.append((time.monotonic(), float(f["rate_hz"].strip('"')),
                                     int(f["jitter_p99_us"]), int(f["overruns"])))

    def pending(self):
        """Reports arrived and not yet taken."""
        return len(self.reports) - self.taken

    def take(self, n):
        new = self.reports[self.taken:self.taken + n]
        self.taken += len(new)
        return new

    def next_reports(self, gcs, n, timeout=30):
        """The next `n` reports to arrive (those already in are skipped), the ground station's
        heartbeat kept going meanwhile."""
        self.taken = len(self.reports)
        end = time.monotonic() + timeout
        while self.pending() < n:
            assert time.monotonic() < end, "no control-loop reports"
            heartbeats_until(gcs, time.monotonic() + 0.1)
        return self.take(n)


# How often the daemon reports its loop's timing in the flood test (s).
REPORT_S = 5

# The control loop's own CPU in the flood test: the first (on this VM the second serves the
# virtio balloon's statistics interrupt, a 3 ms stall every 5 s; see the README).
LOOP_CPU = min(os.sched_getaffinity(0))


def cpu_s(pid):
    """CPU time a process has used (s)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def cpus_of_threads(pid):
    """Each thread name of process `pid` with the sets of CPUs its threads may run on."""
    def cpus(text):
        out = set()
        for part in text.split(","):
            lo, _, hi = part.partition("-")
            out.update(range(int(lo), int(hi or lo) + 1))
        return out
    threads = {}
    for task in Path(f"/proc/{pid}/task").iterdir():
        name = (task / "comm").read_text().strip()
        line = next(l for l in (task / "status").read_text().splitlines()
                    if l.startswith("Cpus_allowed_list:"))
        threads.setdefault(name, []).append(cpus(line.split(":", 1)[1].strip()))
    return threads


def rss_kib(pid):
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1])
    raise AssertionError("no VmRSS")


def command(gcs, cmd, *params, attempts=10):
    """COMMAND_LONG sent as a ground station does under a bad link: again every half second
    until its COMMAND_ACK comes; the result."""
    for attempt in range(attempts):
        gcs.mav.command_long_send(1, 1, cmd, attempt, *params)
        end = time.monotonic() + 0.5
        while time.monotonic() < end:
            m = gcs.recv_match(type="COMMAND_ACK", blocking=True, timeout=0.1)
            if m is not None and m.command == cmd and m.get_srcSystem() == 1:
                return m.result
    raise AssertionError(f"command {cmd}: no COMMAND_ACK in {attempts} attempts")


def test_a_flood_at_the_ground_station_port_neither_starves_the_loop_nor_the_ground_station(
        tmp_path):
    """While the vehicle hovers (simulator in real time, loop at 500 Hz on its deadlines), a peer
    blasts ≥ 50 000 frames/s of mixed valid and invalid MAVLink at the port the ground station
    uses: the daemon's memory stays put, the hover holds, and the ground station's commands are
    served (the loop's rate and deadlines are printed: a benchmark's figures)."""
    daemon = Daemon(tmp_path, "udpin://127.0.0.1:{port}", connect=False,
                    sim_args=["--speed", "1"],
                    ap_args=["--loop-stats-s", str(REPORT_S), "--loop-cpu", str(LOOP_CPU)])
    timing = LoopTiming(daemon.ap)
    # Everything but the control loop off its CPU, as on a flight computer: the simulator,
    # this process (the ground station), the flood (the daemon keeps its other threads off).
    everywhere = os.sched_getaffinity(0)
    others = everywhere - {LOOP_CPU}
    os.sched_setaffinity(daemon.sim.pid, others)
    os.sched_setaffinity(0, others)
    flooder = None
    try:
        gcs = mavutil.mavlink_connection(f"udpout:127.0.0.1:{daemon.gcs_port}",
                                         source_system=255)
        # The daemon answers a UDP peer once it has heard from it (and it may not be up yet).
        greet(gcs)
        ready_to_arm(gcs)
        home = wait(gcs, "GLOBAL_POSITION_INT", lambda m: True)
        # The loop alone on its CPU: every other thread of the daemon (the runtime, the log
        # writers, which format the flight CSV) kept off it.
        threads = cpus_of_threads(daemon.ap.pid)
        assert threads["control-loop"] == [{LOOP_CPU}], threads
        assert "log-writer" in threads, threads
        if len(everywhere) > 1:
            others = {n: c for n, c in threads.items() if n != "control-loop"}
            assert all(LOOP_CPU not in c for cs in others.values() for c in cs), threads
        assert command(gcs, mavutil.mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1, 0, 0, 0, 0, 0, 0) == 0
        assert command(gcs, mavutil.mavlink.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, math.nan, math.nan,
                       math.nan, math.nan) == 0
        wait_holding_in_air(gcs)

        # Two reports of the loop's timing unloaded, then two flooded (each over REPORT_S).
        quiet = timing.next_reports(gcs, 3)[1:]  # the first began before the hover
        rss_before, cpu_before = rss_kib(daemon.ap.pid), cpu_s(daemon.ap.pid)
        flooder = subprocess.Popen(
            [sys.executable, str(ROOT / "tools" / "mavlink_flood.py"),
             f"127.0.0.1:{daemon.gcs_port}", "--rate", "60000",
             "--seconds", str(2 * REPORT_S + 0.5)],
            stdout=subprocess.PIPE, text=True)
        flood_start = time.monotonic()
        # Served meanwhile: a climb to 4 m (DO_REPOSITION, altitude AMSL), a parameter set.
        assert command(gcs, mavutil.mavlink.MAV_CMD_DO_REPOSITION, -1, 1, 0, math.nan,
                       math.nan, math.nan, home.alt / 1000 + 4.0) == 0
        gcs.param_set_send("MPC_XY_CRUISE", 4.0, mavutil.mavlink.MAV_PARAM_TYPE_REAL32)
        wait(gcs, "PARAM_VALUE", lambda m: m.param_id == "MPC_XY_CRUISE" and m.param_value == 4.0,
             timeout=5)
        track = []
        while timing.pending() < 2:
            heartbeats_until(gcs, time.monotonic() + 0.05)
            p = wait(gcs, "LOCAL_POSITION_NED", lambda m: True, timeout=2)
            track.append((time.monotonic() - flood_start, p.x, p.y, -p.z))
        flooded = timing.take(2)
        rss_during, cpu_during = rss_kib(daemon.ap.pid), cpu_s(daemon.ap.pid)
        flood_s = time.monotonic() - flood_start
        out, _ = flooder.communicate(timeout=10)
        sent = json.loads(out)

        # A flood arrived (≥ 100 000 frames; 60 000 a second where the host lets the flooder).
        assert sent["frames"] >= 100_000, sent
        # Not starved: the loop's rate, its missed deadlines and its wake-up jitter are the
        # host's as much as ours (a busy CI machine's flooded interval once ran at 491 Hz with 47
        # deadlines missed, its unloaded p99 went 6 -> 51 µs between two intervals), so they are
        # benchmark figures (tools/bench.sh), printed here. What a starved loop cannot do is
        # asserted: the vehicle flies the climb and holds its hover, the ground station is served.
        assert rss_during - rss_before < 16 * 1024, (rss_before, rss_during)
        # The climb flown, the hover held: near the take-off point, at 4 m once there.
        assert all(math.hypot(x, y) < 1.0 for _, x, y, _ in track), track
        settled = [alt for t, _, _, alt in track if t > 5]
        assert settled and all(3.6 < alt < 4.4 for alt in settled), track
    finally:
        os.sched_setaffinity(0, everywhere)
        if flooder is not None and flooder.poll() is None:
            flooder.kill()
        daemon.close()
    print(f"\nflood: {sent['rate']} frames/s; loop Hz quiet {[r[1] for r in quiet]}, "
          f"flooded {[r[1] for r in flooded]}; overruns quiet {[r[3] for r in quiet]}, "
          f"flooded {[r[3] for r in flooded]}; loop p99 quiet {[r[2] for r in quiet]} us, "
          f"flooded {[r[2] for r in flooded]} us; rss {rss_before} -> {rss_during} KiB; "
          f"daemon CPU {100 * (cpu_during - cpu_before) / flood_s:.0f} % flooded")


def heartbeats_until(gcs, end):
    """A ground station's 1 Hz heartbeat until `end` (monotonic), reading what comes."""
    while (now := time.monotonic()) < end:
        if now >= getattr(gcs, "next_heartbeat", 0):
            gcs.next_heartbeat = now + 1.0
            gcs.mav.heartbeat_send(mavutil.mavlink.MAV_TYPE_GCS,
                                   mavutil.mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
        gcs.recv_match(blocking=True, timeout=min(0.1, end - now))


def source_lost_in_the_air_and_back(gcs, stop, start):
    """Armed, taken off to Hold, the sensor source stopped (`stop`): the ground station told
    and the vehicle descending blind; a new one started (`start`, its clock from zero): the
    vehicle reset, disarmed, and then armed and flown to 3 m and landed again."""
    gcs.arducopter_arm()
    assert ack(gcs, mavutil.mavlink.MAV_CMD_COMPONENT_ARM_DISARM) == 0
    gcs.mav.command_long_send(1, 1, mavutil.mavlink.MAV_CMD_NAV_TAKEOFF, 0,
                              0, 0, 0, math.nan, math.nan, math.nan, math.nan)
    wait_holding_in_air(gcs)
    stop()
    wait(gcs, "STATUSTEXT", lambda m: m.text == "sensor frames stopped: DESCEND", 5)
    start()
    wait(gcs, "STATUSTEXT", lambda m: m.text == "sensor source restarted: vehicle reset", 20)
    wait(gcs, "STATUSTEXT", lambda m: m.text == "sensor frames back", 5)
    wait(gcs, "HEARTBEAT", lambda m: not armed(m), 5)
    ready_to_arm(gcs)
    # 3 m above where the new world's estimate stands: its altitude origin is its own GPS's
    # (whose vertical error, 0.6 m σ, the old world's home altitude does not share).
    ground = wait(gcs, "GLOBAL_POSITION_INT", lambda m: True)
    gcs.arducopter_arm()
    assert ack(gcs, mavutil.mavlink.MAV_CMD_COMPONENT_ARM_DISARM) == 0
    take_off_and_land(gcs, ground.alt / 1000 + 3.0, (2.6, 3.4))


def test_a_simulator_restarted_in_flight_is_met_by_a_failsafe_then_flown_again(tmp_path):
    """The simulator process dies in the air: the ground station is told the sensor frames
    stopped and the vehicle descends blind; a new simulator (a new world, the vehicle on the
    ground) is started: the vehicle starts afresh, says so, and takes off and lands again — the
    daemon never restarted."""
    daemon = Daemon(tmp_path, "udpout://127.0.0.1:{port}?bind=0")
    try:
        gcs = daemon.gcs
        assert gcs.wait_heartbeat(timeout=30), "no heartbeat"
        ready_to_arm(gcs)

        def kill_sim():
            daemon.sim.kill()
            daemon.sim.wait()

        source_lost_in_the_air_and_back(gcs, kill_sim, daemon.start_sim)
        assert daemon.ap.poll() is None, "the daemon kept running"
        daemon.stop()
        assert "sensor source restarted" in daemon.ap_stderr
    finally:
        daemon.close()


def test_a_serial_radio_unplugged_in_flight_is_met_by_the_link_loss_failsafe_then_reopened(
        tmp_path):
    """The only ground station talks over a USB radio (a pty pair behind a udev-like name); the
    radio is pulled out in the air. The daemon says the serial link is lost (on its other link)
    and, once the heartbeats have been missing for COM_DL_LOSS_T, holds and then lands
    (NAV_DLL_ACT 3). The radio is plugged in again (a new device under the same name): the
    daemon reopens it by itself, says so, hears the link regained, and the operator takes over
    from the radio (Hold) mid-descent — the daemon never restarted."""
    radio = PtyLink(tmp_path / "ttyRadio", heartbeat_s=0.5)
    ML = mavutil.mavlink
    daemon = Daemon(tmp_path, "udpout://127.0.0.1:{port}?bind=0",
                    ap_args=["--mavlink", f"serial://{radio.device}?baud=57600"])
    try:
        observer = daemon.gcs  # on UDP, never sends: only the radio's heartbeats count

        def command(cmd, *params):
            radio.mav.command_long_send(1, 1, cmd, 0, *params, *[0] * (7 - len(params)))
            return radio.recv("COMMAND_ACK", lambda m: m.command == cmd).result

        def set_param(name, value, ptype=REAL32):
            radio.mav.param_set_send(1, 1, name.encode(), value, ptype)
            radio.recv("PARAM_VALUE", lambda m: m.param_id == name and m.param_value == value)

        radio.recv("HEARTBEAT", lambda m: True, 30)
        set_param("NAV_DLL_ACT", int_bits(3), INT32)  # Land
        set_param("COM_DL_LOSS_T", 2.0)
        set_param("COM_FAIL_ACT_T", 3.0)  # flight time: 1 s here
        set_param("MIS_TAKEOFF_ALT", 15.0)
        ready_to_arm(observer)
        assert command(ML.MAV_CMD_COMPONENT_ARM_DISARM, 1) == 0
        assert command(ML.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, math.nan, math.nan, math.nan,
                       math.nan) == 0
        wait(observer, "LOCAL_POSITION_NED", lambda m: m.z < -14.5, 40)

        radio.unplug()
        pulled = time.monotonic()
        wait(observer, "STATUSTEXT", lambda m: m.text == "serial link ttyRadio lost: reopening", 3)
        wait(observer, "STATUSTEXT",
             lambda m: m.text == "failsafe: ground-station link lost: Hold", 5)
        noticed = time.monotonic() - pulled
        assert 1.5 < noticed < 4.0, f"link loss said {noticed:.1f} s after (COM_DL_LOSS_T 2 s)"
        wait(observer, "STATUSTEXT",
             lambda m: m.text == "failsafe: ground-station link lost: Land now", 5)
        wait(observer, "HEARTBEAT", lambda m: observer.flightmode == "LAND" and armed(m), 3)
        landing_from = -wait(observer, "LOCAL_POSITION_NED", lambda m: True, 2).z

        radio.plug()
        wait(observer, "STATUSTEXT", lambda m: m.text == "serial link ttyRadio back", 5)
        wait(observer, "STATUSTEXT", lambda m: m.text == "ground-station link regained", 5)
        radio.recv("STATUSTEXT", lambda m: m.text == "ground-station link regained", 5)
        now = -wait(observer, "LOCAL_POSITION_NED", lambda m: True, 2).z
        assert 2.0 < now < landing_from - 0.5, f"landing from {landing_from:.1f} m: {now:.1f} m"
        # The operator takes over again, from the radio.
        assert command(ML.MAV_CMD_DO_SET_MODE, *mavutil.px4_map["LOITER"]) == 0
        wait(observer, "HEARTBEAT", lambda m: observer.flightmode == "LOITER" and armed(m), 3)
        held = [wait(observer, "LOCAL_POSITION_NED", lambda m: abs(m.vz) < 0.3, 5)]
        end = time.monotonic() + 2
        while time.monotonic() < end:
            held.append(wait(observer, "LOCAL_POSITION_NED", lambda m: True, 2))
        alts = [-m.z for m in held]
        assert max(alts) - min(alts) < 0.5 and min(alts) > 1.5, alts

        assert daemon.ap.poll() is None, "the daemon kept running"
        daemon.ap.send_signal(signal.SIGTERM)
        _, err = daemon.ap.communicate(timeout=20)
        assert "ground-station serial link lost" in err, err
        assert err.count("MAVLink serial endpoint") == 2, err
    finally:
        daemon.close()
        radio.close()
    print(f"\nradio pulled at {landing_from:.1f} m: link loss said after {noticed:.1f} s; "
          f"regained at {now:.1f} m, held at {alts[-1]:.1f} m")


class Board:
    """sitl playing a flight board in real time on a pseudo-terminal, its device behind a
    udev-like name (/dev/serial/by-id/...): `pull` kills it (the device goes), `start` plugs a
    new one in under the same name (a new world: its clock starts again)."""

    def __init__(self, name):
        self.name = name
        self.start()

    def start(self):
        self.proc = subprocess.Popen(
            [str(binary("sitl")), "--params-dir", str(ROOT / "params"), "--status-interval", "0",
             "--serial", "pty", "--mode", "realtime", "--duration", "100000",
             "--airframe", "quad_x"],
            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
        line = self.proc.stdout.readline()  # its first line, or "" if it exits
        assert line.startswith("sitl serial: "), line
        os.symlink(line.strip().removeprefix("sitl serial: "), self.name)

    def pull(self):
        self.proc.kill()
        self.proc.wait()
        os.unlink(self.name)


def test_a_flight_board_unplugged_in_flight_is_met_by_a_failsafe_then_reopened(tmp_path):
    """The sensor source is a flight board on a serial line (sitl in real time on a pty behind
    a udev-like name). Pulled out in the air: the ground station hears that the sensor frames
    stopped and the vehicle descends blind. A board is plugged in again under the same name (it
    rebooted: its clock starts again): the daemon reopens the port by itself, the vehicle starts
    afresh, says so, and takes off and lands again — the daemon never restarted."""
    board = Board(tmp_path / "ttyBoard")
    # A board's magnetometer is calibrated once by its owner (a simulator's is preset).
    params = tmp_path / "flight.toml"
    text = (ROOT / "params" / "flight.toml").read_text()
    params.write_text(text.replace("mag_calibration_id = 0 ", "mag_calibration_id = 1 ", 1))
    gcs_port = free_udp_port()
    gcs = mavutil.mavlink_connection(f"udpin:127.0.0.1:{gcs_port}", source_system=255)
    ap = subprocess.Popen(
        [str(binary("autopilot")), "--params-dir", str(ROOT / "params"), "--params", str(params),
         "--source", f"serial://{board.name}", "--loop-hz", "500", "--airframe", "quad_x",
         "--mavlink", f"udpout://127.0.0.1:{gcs_port}?bind=0",
         "--param-store", str(tmp_path / "params.toml"), "--log-dir", str(tmp_path / "logs")],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        assert gcs.wait_heartbeat(timeout=30), "no heartbeat"
        ready_to_arm(gcs)
        source_lost_in_the_air_and_back(gcs, board.pull, board.start)
        assert ap.poll() is None, "the daemon kept running"
        ap.send_signal(signal.SIGTERM)
        _, err = ap.communicate(timeout=20)
        assert ap.returncode == 0, err
        assert "serial link lost" in err and "serial link back" in err, err
    finally:
        ap.kill()
        board.proc.kill()


def test_a_ground_station_that_goes_away_is_met_by_a_failsafe_and_one_that_comes_is_served(
        tmp_path):
    """A ground station (UDP, the daemon listening) flies the vehicle 8 m north, then goes away
    (its process ends: heartbeats stop, its socket closes). The link-loss failsafe (NAV_DLL_ACT 2)
    holds, then returns. Another ground station starts (a new port): it is answered at once,
    the link is said regained, and it watches the return land at home — the daemon never
    restarted. A passive observer on a second endpoint hears what nobody else could."""
    listen = free_udp_port()
    daemon = Daemon(tmp_path, "udpout://127.0.0.1:{port}?bind=0", lockstep=True, speed=6,
                    ap_args=["--mavlink", f"udpin://127.0.0.1:{listen}"])
    observer = daemon.gcs  # never sends: only the ground stations' heartbeats count
    first = mavutil.mavlink_connection(f"udpout:127.0.0.1:{listen}", source_system=255)
    second = beats = None
    try:
        greet(first)
        beats = Heartbeats(first)
        set_param(first, "NAV_DLL_ACT", int_bits(2), INT32)  # Return
        set_param(first, "COM_DL_LOSS_T", 2.0)
        set_param(first, "COM_FAIL_ACT_T", 3.0)  # flight time: 1 s here
        ready_to_arm(observer)
        home = wait(observer, "GLOBAL_POSITION_INT", lambda m: True)
        first.arducopter_arm()
        assert ack(first, mavutil.mavlink.MAV_CMD_COMPONENT_ARM_DISARM) == 0
        first.mav.command_long_send(1, 1, mavutil.mavlink.MAV_CMD_NAV_TAKEOFF, 0,
                                    0, 0, 0, math.nan, math.nan, math.nan, math.nan)
        wait_holding_in_air(observer)
        start = wait(observer, "LOCAL_POSITION_NED", lambda m: True)
        reposition_north(first, home, 8)
        wait(observer, "LOCAL_POSITION_NED", lambda m: m.x - start.x > 7.0 and abs(m.vx) < 0.3, 30)

        beats.stop()
        first.close()
        wait(observer, "STATUSTEXT",
             lambda m: m.text == "failsafe: ground-station link lost: Hold", 5)
        wait(observer, "STATUSTEXT",
             lambda m: m.text == "failsafe: ground-station link lost: Return now", 5)
        wait(observer, "HEARTBEAT", lambda m: observer.flightmode == "RTL" and armed(m), 3)

        second = mavutil.mavlink_connection(f"udpout:127.0.0.1:{listen}", source_system=255)
        greet(second, timeout=5)  # answered at once (within a heartbeat or so)
        beats = Heartbeats(second)
        wait(observer, "STATUSTEXT", lambda m: m.text == "ground-station link regained", 5)
        wait(second, "HEARTBEAT", lambda m: second.flightmode == "RTL" and armed(m), 3)
        wait(second, "HEARTBEAT", lambda m: not armed(m), 90)
        end = wait(second, "LOCAL_POSITION_NED", lambda m: True)
        off = math.hypot(end.x - start.x, end.y - start.y)
        assert off < 1.0, f"landed {off:.2f} m from home"
        assert daemon.ap.poll() is None, "the daemon kept running"
        daemon.ap.send_signal(signal.SIGTERM)
        _, err = daemon.ap.communicate(timeout=20)
        assert err.count("ground station connected") == 2, err
        assert "failsafe: ground-station link lost: Return now" in err, err
    finally:
        if beats is not None:
            beats.stop()
        daemon.close()
