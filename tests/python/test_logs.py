"""The logs a run leaves, read with the tools people already have: the MAVLink telemetry log with
pymavlink (its reader and mavlogdump.py), the flight-data CSV with the csv module."""

import csv
import subprocess
import sys
import time
from pathlib import Path

from pymavlink import mavutil

from conftest import ROOT, binary, free_udp_port


def fly_with_a_ground_station(tmp_path, *args):
    """An embedded-simulator flight (4x real time: take off to 3 m, hover 2 s, land) with a
    pymavlink ground station that sends heartbeats and asks for one parameter; its logs go to
    tmp_path/logs. The wall-clock start and end of the run."""
    port = free_udp_port()
    gcs = mavutil.mavlink_connection(f"udpin:127.0.0.1:{port}", source_system=255)
    started = time.time()
    ap = subprocess.Popen(
        [str(binary("autopilot")), "--sim", "--speed", "4", "--takeoff", "3", "--hover", "2",
         "--params-dir", str(ROOT / "params"), "--param-store", "none",
         "--log-dir", str(tmp_path / "logs"),
         "--mavlink", f"udpout://127.0.0.1:{port}?bind=0", *args],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    asked = False
    next_heartbeat = 0.0
    try:
        while ap.poll() is None:
            now = time.monotonic()
            if now >= next_heartbeat:
                next_heartbeat = now + 0.5
                gcs.mav.heartbeat_send(mavutil.mavlink.MAV_TYPE_GCS,
                                       mavutil.mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
            m = gcs.recv_match(blocking=True, timeout=0.1)
            if m is not None and m.get_type() == "HEARTBEAT" and not asked:
                gcs.mav.param_request_read_send(1, 1, b"MPC_XY_CRUISE", -1)
                asked = True
        out, err = ap.communicate(timeout=30)
    finally:
        if ap.poll() is None:
            ap.kill()
        gcs.close()
    assert ap.returncode == 0, err
    assert asked, "no heartbeat from the vehicle"
    return started, time.time(), out


def read_tlog(path):
    """Every message of a .tlog as pymavlink reads it, with its timestamp."""
    log = mavutil.mavlink_connection(str(path))
    messages = []
    while (m := log.recv_match()) is not None:
        messages.append(m)
    return messages


def test_every_run_leaves_a_tlog_pymavlink_reads_and_a_full_rate_flight_csv(tmp_path):
    started, ended, out = fly_with_a_ground_station(tmp_path)
    logs = sorted((tmp_path / "logs").iterdir())
    names = [p.name for p in logs]
    assert len(logs) == 3 and {p.suffix for p in logs} == {".csv", ".tlog", ".ulg"}, names
    assert len({p.stem for p in logs}) == 1  # one run, one name: its UTC start time
    assert time.strftime("%Y-%m-%d_%H-%M", time.gmtime(started)) <= logs[0].stem[:16] <= \
        time.strftime("%Y-%m-%d_%H-%M", time.gmtime(ended)), names
    tlog = tmp_path / "logs" / f"{logs[0].stem}.tlog"

    messages = read_tlog(tlog)
    assert not [m for m in messages if m.get_type() == "BAD_DATA"]
    stamps = [m._timestamp for m in messages]
    # Wall-clock time of passing, in order, within the run.
    assert stamps == sorted(stamps)
    assert started - 1 <= stamps[0] and stamps[-1] <= ended + 1, (started, stamps[0], stamps[-1])

    vehicle = [m for m in messages if m.get_srcSystem() == 1]
    heartbeats = [m for m in vehicle if m.get_type() == "HEARTBEAT"]
    run_s = stamps[-1] - stamps[0]
    assert len(heartbeats) >= run_s - 1, (len(heartbeats), run_s)  # 1 Hz, all of them
    armed = [bool(m.base_mode & mavutil.mavlink.MAV_MODE_FLAG_SAFETY_ARMED) for m in heartbeats]
    assert any(armed) and not armed[-1], armed  # flown, and landed and disarmed at the end
    heights = [m.relative_alt / 1000 for m in vehicle if m.get_type() == "GLOBAL_POSITION_INT"]
    assert 2.6 < max(heights) < 3.4, max(heights)
    assert any(m.get_type() == "ATTITUDE" for m in vehicle)
    assert any(m.get_type() == "PARAM_VALUE" and m.param_id == "MPC_XY_CRUISE" for m in vehicle)
    # What the ground station said is in it too, as it said it.
    heard = [m for m in messages if m.get_srcSystem() == 255]
    assert any(m.get_type() == "HEARTBEAT" and m.type == mavutil.mavlink.MAV_TYPE_GCS
               for m in heard)
    assert any(m.get_type() == "PARAM_REQUEST_READ" and m.param_id == "MPC_XY_CRUISE"
               for m in heard)

    # pymavlink's own dump tool reads the same heartbeats.
    dump = subprocess.run(
        [sys.executable, str(Path(sys.executable).parent / "mavlogdump.py"), "--types",
         "HEARTBEAT", "--source-system", "1", str(tlog)],
        capture_output=True, text=True, timeout=60, check=True)
    assert dump.stdout.count("HEARTBEAT") == len(heartbeats), dump.stdout[-500:]

    # The flight-data CSV: a row per sensor frame of the whole flight, full rate.
    with open(tmp_path / "logs" / f"{logs[0].stem}.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    summary = next(line for line in out.splitlines() if line.startswith("autopilot summary:"))
    fields = dict(kv.split("=", 1) for kv in summary.split()[2:])
    assert len(rows) == int(fields["frames"]), (len(rows), summary)
    t = [float(r["t_s"]) for r in rows]
    assert all(b > a for a, b in zip(t, t[1:]))
    assert 2.6 < max(-float(r["d_m"]) for r in rows) < 3.4
    assert 2.6 < max(-float(r["true_d_m"]) for r in rows if r["true_d_m"]) < 3.4
    # Lockstep: the simulator paces the loop, so the loop-timing column stays empty.
    assert all(r["loop_late_us"] == "" for r in rows)


def test_logs_go_where_asked_and_none_is_none(tmp_path):
    fly_with_a_ground_station(tmp_path, "--log-dir", "none", "--tlog", str(tmp_path / "a.tlog"))
    assert not (tmp_path / "logs").exists()
    assert [p.name for p in tmp_path.iterdir() if p.is_file()] == ["a.tlog"]
    assert any(m.get_type() == "HEARTBEAT" for m in read_tlog(tmp_path / "a.tlog"))


def test_the_flight_csv_can_be_left_out_and_the_other_logs_stay(tmp_path):
    fly_with_a_ground_station(tmp_path, "--flight-csv", "none")
    suffixes = sorted(p.suffix for p in (tmp_path / "logs").iterdir())
    assert suffixes == [".tlog", ".ulg"], suffixes
    assert not (tmp_path / "none").exists()


def test_the_plot_tool_turns_a_flight_csv_into_figures(tmp_path):
    _, _, _ = fly_with_a_ground_station(tmp_path)
    log = next((tmp_path / "logs").glob("*.csv"))
    for args, names in (([], ["attitude", "position", "motors", "estimator", "loop"]),
                        (["--overview"], ["overview"])):
        run = subprocess.run([sys.executable, str(ROOT / "tools" / "plot_flight.py"), str(log),
                              "--out", str(tmp_path / "figures"), *args],
                             capture_output=True, text=True, timeout=120)
        assert run.returncode == 0, run.stderr
        for name in names:
            png = tmp_path / "figures" / f"{log.stem}_{name}.png"
            assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", png
            assert str(png) in run.stdout
    # A file that is not a flight-data CSV: a clear refusal, no traceback.
    bad = tmp_path / "bad.csv"
    bad.write_text("a,b\n1,2\n")
    run = subprocess.run([sys.executable, str(ROOT / "tools" / "plot_flight.py"), str(bad)],
                         capture_output=True, text=True, timeout=60)
    assert run.returncode != 0 and "not a flight-data CSV" in run.stderr
    assert "Traceback" not in run.stderr
