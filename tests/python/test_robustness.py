"""The daemon under duress, as a user meets it: stopped by a service manager or killed outright
(its flight log keeps all but the last second), flooded with traffic at its ground-station port
(the control loop keeps its rate, a second ground station is still served), its links lost and
found again (it reacts, says so, and carries on without a restart).
"""

import signal

from pymavlink import mavutil

from conftest import Daemon
from test_ground_station import ack, armed, ready_to_arm, start_afresh, wait


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
    would lose three times more)."""
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
        wait(gcs, "HEARTBEAT", lambda m: gcs.flightmode == "LOITER" and armed(m), timeout=30)
        seen_s = vehicle_time_s(gcs)
        daemon.ap.kill()
        daemon.ap.wait()
        _, rows = csv_rows(second)
        last = rows[-1]
        assert float(last["t_s"]) >= seen_s - 1.0, (last["t_s"], seen_s)
        assert last["armed"] == "1" and float(last["d_m"]) < -1.5, last  # in the air
    finally:
        daemon.close()
