"""What a hostile or careless peer could do, tried again end to end with pymavlink over loopback:
impossible places and heights, endpoints reachable from elsewhere, answer slots and telemetry for
unsigned peers, a signed command replayed after a restart, timestamps from the future, weak key
files, an emptied parameter store, a second sender on the simulator's port. Each is refused or
harmless, and the vehicle still flies afterwards.
"""

import math
import os
import socket
import subprocess
import time

from pymavlink import mavutil
from pymavlink.dialects.v20 import common as mavlink2

from conftest import ROOT, Daemon, binary, free_udp_port
from test_ground_station import (ack, arm_and_take_off, armed, ready_to_arm, set_param,
                                 start_afresh, wait)
from test_signing import KEY, now_10us, packer, param_set_frame, signed_gcs, takeoff_alt_after

DENIED = mavutil.mavlink.MAV_RESULT_DENIED
REBOOT = mavutil.mavlink.MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN
MISSION = mavutil.mavlink.MAV_MISSION_TYPE_MISSION
RELATIVE = mavutil.mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT


def key_file(tmp_path, key=KEY, mode=0o600):
    f = tmp_path / "signing.key"
    f.write_text(key.hex() + "\n")
    f.chmod(mode)
    return f


def upload_result(gcs, items):
    """Uploads `items` ((command, frame, x, y, z), ...) by the book; the MISSION_ACK's type."""
    gcs.mav.mission_count_send(1, 1, len(items), MISSION)
    while True:
        m = wait(gcs, ["MISSION_REQUEST_INT", "MISSION_ACK"], lambda m: True, 10)
        if m.get_type() == "MISSION_ACK":
            return m.type
        command, frame, x, y, z = items[m.seq]
        gcs.mav.mission_item_int_send(1, 1, m.seq, frame, command, int(m.seq == 0), 1,
                                      0, 0, 0, math.nan, x, y, z, MISSION)


def test_impossible_places_and_heights_are_refused_and_the_vehicle_still_flies(tmp_path):
    daemon = Daemon(tmp_path, "udpout://127.0.0.1:{port}?bind=0")
    try:
        gcs = daemon.gcs
        assert gcs.wait_heartbeat(timeout=30)
        ready_to_arm(gcs)
        home = wait(gcs, "HOME_POSITION", lambda m: True)
        lat, lon = home.latitude, home.longitude
        cmd = mavutil.mavlink
        # Home at latitude 1000°, longitude -5000°; 200° as a COMMAND_INT.
        gcs.mav.command_long_send(1, 1, cmd.MAV_CMD_DO_SET_HOME, 0, 0, 0, 0, 0, 1000, -5000, 0)
        assert ack(gcs, cmd.MAV_CMD_DO_SET_HOME) == DENIED
        gcs.mav.command_int_send(1, 1, cmd.MAV_FRAME_GLOBAL, cmd.MAV_CMD_DO_SET_HOME, 0, 0,
                                 0, 0, 0, 0, 2_000_000_000, lon, 0)
        assert ack(gcs, cmd.MAV_CMD_DO_SET_HOME) == DENIED
        # A take-off to 1e30 m.
        gcs.mav.command_long_send(1, 1, cmd.MAV_CMD_NAV_TAKEOFF, 0,
                                  0, 0, 0, math.nan, math.nan, math.nan, 1e30)
        assert ack(gcs, cmd.MAV_CMD_NAV_TAKEOFF) == DENIED
        text = wait(gcs, "STATUSTEXT", lambda m: "take-off refused" in m.text, 5).text
        assert text.startswith("take-off refused: 1.0e30 m above home"), text
        # Mission items at 1e30 m and 1e6 m below sea level: the altitude field named.
        wp = cmd.MAV_CMD_NAV_WAYPOINT
        for z, frame in [(1e30, RELATIVE), (-1e6, cmd.MAV_FRAME_GLOBAL_INT)]:
            result = upload_result(gcs, [(wp, RELATIVE, lat, lon, 10.0), (wp, frame, lat, lon, z)])
            assert result == cmd.MAV_MISSION_INVALID_PARAM7, (z, result)
        # In the air: a reposition 50 m below home, and one 1e30 m up.
        arm_and_take_off(gcs)
        for z in [-50.0, 1e30]:
            gcs.mav.command_int_send(1, 1, cmd.MAV_FRAME_GLOBAL_RELATIVE_ALT,
                                     cmd.MAV_CMD_DO_REPOSITION, 0, 0, -1, 1, 0, math.nan,
                                     lat, lon, z)
            assert ack(gcs, cmd.MAV_CMD_DO_REPOSITION) == DENIED, z
        # A sane reposition is flown, then the vehicle lands and disarms.
        gcs.mav.command_int_send(1, 1, cmd.MAV_FRAME_GLOBAL_RELATIVE_ALT,
                                 cmd.MAV_CMD_DO_REPOSITION, 0, 0, -1, 1, 0, math.nan,
                                 lat, lon, 4.0)
        assert ack(gcs, cmd.MAV_CMD_DO_REPOSITION) == 0
        wait(gcs, "GLOBAL_POSITION_INT", lambda m: 3.5 < m.relative_alt / 1000 < 4.5, 30)
        gcs.mav.command_long_send(1, 1, cmd.MAV_CMD_NAV_LAND, 0, 0, 0, 0, 0, 0, 0, 0)
        assert ack(gcs, cmd.MAV_CMD_NAV_LAND) == 0
        wait(gcs, "HEARTBEAT", lambda m: not armed(m), timeout=40)
    finally:
        daemon.close()


def run_autopilot(tmp_path, *args, timeout=60):
    """`autopilot --sim` on its default endpoints, a short flight at full speed."""
    return subprocess.run(
        [str(binary("autopilot")), "--sim", "--speed", "max", "--takeoff", "2", "--hover", "1",
         "--params-dir", str(ROOT / "params"), "--param-store", "none",
         "--log-dir", str(tmp_path / "logs"), *args],
        capture_output=True, text=True, timeout=timeout)


def test_endpoints_are_on_loopback_by_default_and_a_taken_port_stops_the_daemon(tmp_path):
    run = run_autopilot(tmp_path)
    assert run.returncode == 0, run.stderr[-2000:]
    local = [w.split("=", 1)[1] for line in run.stderr.splitlines() if "MAVLink" in line
             for w in line.split() if w.startswith("local=")]
    assert len(local) == 3, run.stderr
    assert all(a.startswith("127.0.0.1:") for a in local), local
    with socket.socket() as taken:
        taken.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        taken.bind(("127.0.0.1", 5760))
        taken.listen()
        run = run_autopilot(tmp_path)
        assert run.returncode != 0
        assert "127.0.0.1:5760" in run.stderr and "?optional" in run.stderr, run.stderr[-2000:]
        optional = run_autopilot(tmp_path, "--mavlink", "tcpin://127.0.0.1:5760?optional")
        assert optional.returncode == 0, optional.stderr[-2000:]


def test_a_key_others_can_read_or_an_all_zero_key_stops_the_daemon(tmp_path):
    for key, mode, says in [(KEY, 0o644, "chmod 600"), (bytes(32), 0o600, "all-zero key")]:
        run = run_autopilot(tmp_path, "--signing-key-file", str(key_file(tmp_path, key, mode)),
                            "--mavlink", "none")
        assert run.returncode != 0 and says in run.stderr, run.stderr[-2000:]


def heartbeat_frame(mavtype, system=200):
    mav = mavlink2.MAVLink(None, srcSystem=system, srcComponent=1)
    return mavlink2.MAVLink_heartbeat_message(
        mavtype, mavutil.mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0, 3).pack(mav)


def received(sockets, seconds):
    """Bytes each socket receives within `seconds`."""
    counts = [0] * len(sockets)
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        for k, s in enumerate(sockets):
            try:
                while True:
                    counts[k] += len(s.recv(65536))
            except BlockingIOError:
                pass
        time.sleep(0.05)
    return counts


def udp_socket():
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    s.setblocking(False)
    return s


def test_with_signing_on_unsigned_peers_hold_no_answer_slot_and_hear_nothing(tmp_path):
    port = free_udp_port()
    daemon = Daemon(tmp_path, "udpout://127.0.0.1:{port}?bind=0",
                    ap_args=["--signing-key-file", str(key_file(tmp_path)),
                             "--mavlink", f"udpin://127.0.0.1:{port}"])
    attackers = [udp_socket() for _ in range(20)]
    gcs = None
    try:
        assert signed_gcs(daemon).wait_heartbeat(timeout=30)
        # 20 unsigned vehicle heartbeats (the spec lets them through): no answers for them.
        for s in attackers:
            s.sendto(heartbeat_frame(mavutil.mavlink.MAV_TYPE_QUADROTOR), ("127.0.0.1", port))
        assert received(attackers, 2.0) == [0] * len(attackers)
        # A signed ground station on the same endpoint is answered.
        gcs = mavutil.mavlink_connection(f"udpout:127.0.0.1:{port}", source_system=255)
        gcs.setup_signing(KEY, sign_outgoing=True)
        gcs.mav.heartbeat_send(mavutil.mavlink.MAV_TYPE_GCS,
                               mavutil.mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
        hb = gcs.wait_heartbeat(timeout=10)
        assert hb is not None and hb.get_signed()
    finally:
        for s in attackers:
            s.close()
        if gcs is not None:
            gcs.close()
        daemon.close()


def test_one_datagram_buys_ten_seconds_of_telemetry_not_more(tmp_path):
    daemon = Daemon(tmp_path, "udpin://127.0.0.1:{port}", connect=False)
    peer = udp_socket()
    try:
        # Sent again until answered: the daemon binds its port as it starts.
        heard, end = 0, time.monotonic() + 30
        while heard == 0 and time.monotonic() < end:
            peer.sendto(heartbeat_frame(mavutil.mavlink.MAV_TYPE_GCS, 255),
                        ("127.0.0.1", daemon.gcs_port))
            heard = received([peer], 0.5)[0]
        assert heard > 0, "no answer to the datagram"
        assert received([peer], 6.0)[0] > 1000
        # Silent for 10 s: no longer sent to, whatever the vehicle sends.
        received([peer], 5.0)
        assert received([peer], 3.0) == [0]
    finally:
        peer.close()
        daemon.close()


def test_a_signed_reboot_replayed_after_the_restart_and_a_timestamp_from_the_future_are_refused(
        tmp_path):
    daemon = Daemon(tmp_path, "udpout://127.0.0.1:{port}?bind=0",
                    ap_args=["--signing-key-file", str(key_file(tmp_path))])
    try:
        gcs = signed_gcs(daemon)
        assert gcs.wait_heartbeat(timeout=30)
        ten_years = 10 * 365 * 86_400 * 100_000
        future = packer(KEY, 4, timestamp=now_10us() + ten_years)
        assert takeoff_alt_after(gcs, param_set_frame(future, 7.0)) is None, "from the future"
        reboot = mavlink2.MAVLink_command_long_message(
            1, 1, REBOOT, 0, 1, 0, 0, 0, 0, 0, 0).pack(packer(KEY, 5))
        runs = daemon.summaries()
        gcs.write(reboot)
        assert ack(gcs, REBOOT) == mavutil.mavlink.MAV_RESULT_ACCEPTED
        end = time.monotonic() + 15
        while daemon.summaries() == runs and time.monotonic() < end:
            gcs.recv_match(blocking=True, timeout=0.2)
        assert daemon.summaries() == runs + 1, "no reboot"
        assert gcs.wait_heartbeat(timeout=30)
        assert (tmp_path / "signing.key.timestamps").exists()
        # The same frame again, a few seconds after the restart: refused as a replay.
        gcs.write(reboot)
        assert takeoff_alt_after(gcs, param_set_frame(packer(KEY, 6), 4.0)) == 4.0
        daemon.stop()
        assert daemon.summaries() == runs + 2, "rebooted again"
        first, after = [l for l in daemon.ap_stderr.splitlines()
                        if "ground-station links closed" in l]
        for line, key in [(first, "refused_future"), (after, "refused_replayed")]:
            counts = dict(kv.split("=") for kv in line.split() if "=" in kv)
            assert int(counts[key]) >= 1, line
    finally:
        daemon.close()


def test_a_store_truncated_to_nothing_falls_back_to_its_previous_copy(tmp_path):
    daemon = Daemon(tmp_path, "udpout://127.0.0.1:{port}?bind=0")
    try:
        gcs = daemon.gcs
        assert gcs.wait_heartbeat(timeout=30)
        assert set_param(gcs, "MIS_TAKEOFF_ALT", 4.0).param_value == 4.0
        assert set_param(gcs, "MIS_TAKEOFF_ALT", 5.0).param_value == 5.0
        daemon.stop()
        daemon.store.write_bytes(b"")
        start_afresh(daemon)
        # Said to the first ground station heard.
        gcs.mav.heartbeat_send(mavutil.mavlink.MAV_TYPE_GCS,
                               mavutil.mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
        wait(gcs, "STATUSTEXT", lambda m: m.text == "param store damaged: previous copy used", 10)
        assert set_param(gcs, "RTL_RETURN_ALT", 40.0).param_value == 40.0
        daemon.stop()
        # The good copy was flown and saved; the empty file never became the previous copy.
        assert "MIS_TAKEOFF_ALT = 4.0" in daemon.store.read_text()
        prev = daemon.store.with_name(daemon.store.name + ".prev").read_text()
        assert "MIS_TAKEOFF_ALT = 4.0" in prev, prev
    finally:
        daemon.close()


def test_a_second_sender_on_the_simulator_port_does_not_take_over_the_vehicle(tmp_path):
    daemon = Daemon(tmp_path, "udpout://127.0.0.1:{port}?bind=0")
    rogue = udp_socket()
    try:
        gcs = daemon.gcs
        assert gcs.wait_heartbeat(timeout=30)
        arm_and_take_off(gcs)
        # A stream of HIL_SENSOR frames saying the vehicle falls upside down.
        mav = mavlink2.MAVLink(None, srcSystem=1, srcComponent=51)
        usec = 10**12
        end = time.monotonic() + 3
        while time.monotonic() < end:
            usec += 4000
            frame = mavlink2.MAVLink_hil_sensor_message(
                usec, 0, 0, 30.0, 5, 5, 5, 0.2, 0, 0.4, 1013, 0, 0, 25, 0x1fff).pack(mav)
            rogue.sendto(frame, ("127.0.0.1", daemon.sim_port))
            time.sleep(0.004)
        # What was received during the attack is read away: the state after it is judged.
        while gcs.recv_match(blocking=False) is not None:
            pass
        p = wait(gcs, "GLOBAL_POSITION_INT", lambda m: True)
        assert 2.0 < p.relative_alt / 1000 < 3.0, p
        att = wait(gcs, "ATTITUDE", lambda m: True)
        assert abs(att.roll) < 0.2 and abs(att.pitch) < 0.2, att
        gcs.mav.command_long_send(1, 1, mavutil.mavlink.MAV_CMD_NAV_LAND, 0, 0, 0, 0, 0, 0, 0, 0)
        assert ack(gcs, mavutil.mavlink.MAV_CMD_NAV_LAND) == 0
        wait(gcs, "HEARTBEAT", lambda m: not armed(m), timeout=40)
        daemon.stop()
        assert "sensor frames from another address dropped" in daemon.ap_stderr
    finally:
        rogue.close()
        daemon.close()


def test_stopping_heartbeats_on_one_link_leaves_the_others_alone(tmp_path):
    port = free_udp_port()
    daemon = Daemon(tmp_path, "udpout://127.0.0.1:{port}?bind=0",
                    ap_args=["--mavlink", f"udpin://127.0.0.1:{port}"])
    other = mavutil.mavlink_connection(f"udpout:127.0.0.1:{port}", source_system=254)
    try:
        gcs = daemon.gcs
        assert gcs.wait_heartbeat(timeout=30)
        other.mav.heartbeat_send(mavutil.mavlink.MAV_TYPE_GCS,
                                 mavutil.mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
        assert other.wait_heartbeat(timeout=10)
        interval = mavutil.mavlink.MAV_CMD_SET_MESSAGE_INTERVAL
        other.mav.command_long_send(1, 1, interval, 0, 0, -1, 0, 0, 0, 0, 0)
        assert ack(other, interval) == 0
        # The link that asked hears no more heartbeats (the vehicle rests: no change of state
        # sends one) but still its other streams; the other link goes on at 1 Hz.
        while other.recv_match(blocking=False) is not None:
            pass
        heard = {("gcs", "HEARTBEAT"): 0, ("other", "HEARTBEAT"): 0, ("other", "ATTITUDE"): 0}
        end = time.monotonic() + 4
        while time.monotonic() < end:
            for name, conn in [("gcs", gcs), ("other", other)]:
                m = conn.recv_match(blocking=True, timeout=0.01)
                if m is not None and m.get_srcComponent() == 1 and (name, m.get_type()) in heard:
                    heard[(name, m.get_type())] += 1
        assert heard[("gcs", "HEARTBEAT")] >= 3, heard
        assert heard[("other", "HEARTBEAT")] == 0 and heard[("other", "ATTITUDE")] >= 10, heard
    finally:
        other.close()
        daemon.close()


def test_idle_tcp_connections_are_capped_and_a_ground_station_still_gets_in(tmp_path):
    port = free_udp_port()  # a free port number, taken here for TCP
    daemon = Daemon(tmp_path, "udpout://127.0.0.1:{port}?bind=0",
                    ap_args=["--mavlink", f"tcpin://127.0.0.1:{port}"])
    idle = []
    gcs = None
    try:
        assert daemon.gcs.wait_heartbeat(timeout=30)
        # Twenty connections that never say a word: at most eight are kept.
        for _ in range(20):
            s = socket.create_connection(("127.0.0.1", port))
            s.setblocking(False)
            idle.append(s)

        def open_count():
            return len(os.listdir(f"/proc/{daemon.ap.pid}/fd"))

        # Past the new ones' grace, a ground station takes an idle one's place.
        end = time.monotonic() + 30
        hb = None
        while hb is None and time.monotonic() < end:
            # Turned away (every idle one still within its grace): closed at once; again.
            gcs = mavutil.mavlink_connection(f"tcp:127.0.0.1:{port}", source_system=255)
            try:
                gcs.mav.heartbeat_send(mavutil.mavlink.MAV_TYPE_GCS,
                                       mavutil.mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
                hb = gcs.wait_heartbeat(timeout=2)
            except (ConnectionResetError, BrokenPipeError):
                hb = None
            if hb is None:
                gcs.close()
                gcs = None
                time.sleep(0.1)  # a moment before knocking again
        assert hb is not None, "the ground station was turned away"
        closed = 0
        for s in idle:
            try:
                while s.recv(1 << 16):  # telemetry sent before it was closed, if any
                    pass
                closed += 1
            except BlockingIOError:
                pass  # open, nothing more yet
            except ConnectionResetError:
                closed += 1
        assert closed >= 12, f"{closed} of the 20 idle connections closed"
        assert open_count() < 60, open_count()
    finally:
        for s in idle:
            s.close()
        if gcs is not None:
            gcs.close()
        daemon.close()
