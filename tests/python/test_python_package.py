"""The Python package (python/autopilot_sitl) and its pytest plugin, on this checkout's binaries:
the clock, weather, truth and parameter overrides of a vehicle; a real-time vehicle; a swarm; and,
run as a user runs it (pytest in a subprocess, two workers), a failed test's report naming the
logs and no process outliving the run, nor a test run killed mid-flight."""

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest
from pymavlink import mavutil

from autopilot_sitl import Vehicle, VehicleError
from conftest import ROOT


def processes_mentioning(text):
    """Pids of live processes whose command line holds `text`."""
    found = []
    for proc in Path("/proc").iterdir():
        if not proc.name.isdigit():
            continue
        try:
            cmdline = (proc / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
            state = (proc / "stat").read_text().split(") ", 1)[1][0]
        except OSError:
            continue
        if text in cmdline and state != "Z":
            found.append(int(proc.name))
    return found


def param(url, name):
    """A parameter's value read by pymavlink over the vehicle's TCP server."""
    conn = mavutil.mavlink_connection(url, source_system=255)
    try:
        assert conn.wait_heartbeat(timeout=10) is not None
        conn.mav.param_request_read_send(1, 1, name.encode(), -1)
        m = conn.recv_match(type="PARAM_VALUE", blocking=True, timeout=10,
                            condition=f"PARAM_VALUE.param_id == '{name}'")
        assert m is not None, f"no PARAM_VALUE for {name}"
        return m.param_value
    finally:
        conn.close()


def test_a_vehicle_pauses_advances_resumes_and_tells_its_truth(vehicle):
    t0 = vehicle.truth().time_s
    assert t0 > 1.5, "ready: the estimator took its simulated seconds"
    vehicle.pause()
    held = vehicle.truth()
    # Paused, simulated time holds whatever the wall clock does.
    assert vehicle.truth().time_s == held.time_s
    vehicle.advance(3.0)
    assert vehicle.truth().time_s == pytest.approx(held.time_s + 3.0, abs=0.005)
    vehicle.resume()
    with pytest.raises(VehicleError, match="pause"):
        vehicle.advance(1.0)
    # At rest on the ground at home, level.
    truth = vehicle.truth()
    assert abs(truth.height_m) < 0.05 and abs(truth.north_m) < 0.05 and abs(truth.east_m) < 0.05
    roll, pitch, _ = truth.euler_deg
    assert abs(roll) < 2 and abs(pitch) < 2
    assert truth.lat_deg == pytest.approx(47.397742, abs=1e-3)


@pytest.mark.vehicle(params={"MIS_TAKEOFF_ALT": 4.0}, wind=(6.0, 90.0), speed="max")
def test_parameter_overrides_and_the_wind_reach_the_vehicle(vehicle):
    assert param(vehicle.pymavlink_url, "MIS_TAKEOFF_ALT") == pytest.approx(4.0)
    assert vehicle.control.get("SIM_WIND_SPD") == pytest.approx(6.0)
    assert vehicle.control.get("SIM_WIND_DIR") == pytest.approx(90.0)
    with pytest.raises(RuntimeError, match="must be within"):
        vehicle.set_wind(80.0, 0.0)
    with pytest.raises(ValueError):
        Vehicle(params={"not a name": 1})


def test_a_real_time_vehicle_runs_on_the_wall_clock(make_vehicle):
    v = make_vehicle(lockstep=False, speed=1)
    a = v.truth()
    time.sleep(0.3)
    assert v.truth().time_s > a.time_s, "its clock runs on its own, never waiting"
    with pytest.raises(VehicleError, match="wall clock"):
        v.pause()
    assert v.stop()["pacing"] == "deadlines"


@pytest.mark.swarm(count=3, speed="max")
def test_a_swarm_flies_in_one_process_each_on_its_own_ports(swarm):
    assert [v.system_id for v in swarm] == [1, 2, 3]
    assert len({v.mavsdk_url for v in swarm} | {v.pymavlink_url for v in swarm}) == 6
    for v in swarm:
        conn = mavutil.mavlink_connection(v.pymavlink_url, source_system=255)
        hb = conn.wait_heartbeat(timeout=10)
        conn.close()
        assert hb is not None and hb.get_srcSystem() == v.system_id
    assert [s["system_id"] for s in swarm.stop()] == ["1", "2", "3"]


def test_a_failed_test_reports_its_logs_and_no_process_outlives_the_run(tmp_path):
    suite = tmp_path / "suite"
    suite.mkdir()
    (suite / "test_user.py").write_text(textwrap.dedent("""
        def test_passes(vehicle):
            assert vehicle.truth().time_s > 0

        def test_fails(vehicle):
            assert vehicle.truth().height_m > 100, "never so high"
    """))
    basetemp = tmp_path / "basetemp"
    env = {**os.environ, "PYTHONPATH": str(ROOT / "python")}
    run = subprocess.run(
        [sys.executable, "-m", "pytest", "-n", "2", "-p", "autopilot_sitl.pytest_plugin",
         "-p", "no:cacheprovider", f"--basetemp={basetemp}", "--autopilot-speed", "max",
         "-rA", str(suite)],
        cwd=suite, env=env, capture_output=True, text=True, timeout=300)
    out = run.stdout
    assert run.returncode == 1, out[-3000:] + run.stderr[-3000:]
    assert "1 failed, 1 passed" in out, out[-3000:]
    # The report names the failed test's logs, which are there and hold its flight.
    section = out[out.index("autopilot logs"):]
    ulog = Path(section.split("ulog ", 1)[1].split(",", 1)[0])
    assert ulog.suffix == ".ulg" and ulog.stat().st_size > 10_000, section[:800]
    assert "autopilot summary:" in Path(section.split("daemon ", 1)[1].split()[0]).read_text()
    # The passed test's logs were removed; nothing of the run still runs.
    assert len(list(basetemp.rglob("*.ulg"))) == 1
    assert processes_mentioning(str(basetemp)) == []


def test_a_test_run_killed_mid_flight_leaves_no_vehicle(tmp_path):
    script = textwrap.dedent(f"""
        import sys, time
        from autopilot_sitl import Vehicle
        v = Vehicle(speed=1, log_dir={str(tmp_path / "v")!r})
        print(v.ap.pid, flush=True)
        time.sleep(600)
    """)
    env = {**os.environ, "PYTHONPATH": str(ROOT / "python")}
    runner = subprocess.Popen([sys.executable, "-c", script], env=env, stdout=subprocess.PIPE,
                              text=True)
    try:
        pid = int(runner.stdout.readline())
        assert pid in processes_mentioning(str(tmp_path / "v"))
    finally:
        runner.send_signal(signal.SIGKILL)
        runner.wait()
    # Linux ends the autopilot with the process that started it (PR_SET_PDEATHSIG).
    end = time.monotonic() + 10
    while processes_mentioning(str(tmp_path / "v")) and time.monotonic() < end:
        time.sleep(0.05)
    assert processes_mentioning(str(tmp_path / "v")) == []


def test_a_scenario_gives_the_embedded_world_and_must_name_the_airframe(make_vehicle, scenario):
    windy = scenario('airframe = "quad_x"\nduration_s = 60.0\n[wind]\nmean_ned_m_s = [0.0, -5.0, 0.0]\n')
    v = make_vehicle(scenario=windy, speed="max")
    # Air moving west: a 5 m/s wind from the east, read back from the simulator.
    assert v.control.get("SIM_WIND_SPD") == pytest.approx(5.0)
    assert v.control.get("SIM_WIND_DIR") == pytest.approx(90.0)
    with pytest.raises(VehicleError, match="give --airframe quad_x"):
        make_vehicle(scenario=windy, airframe="hexa_x")
