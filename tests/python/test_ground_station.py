"""The vehicle as an unmodified pymavlink script sees it: sitl + autopilot over UDP, pymavlink on the
ground-station port. Every wait is on the vehicle's state with a time-out, never a fixed sleep.

The simulator runs in real time at 3x: the vehicle is given the time a script takes between two
commands (PX4's pre-flight auto-disarm, for one, counts simulated seconds).
"""

import math
import subprocess
import time

import pytest
from pymavlink import mavutil

from conftest import ROOT, binary, free_udp_port

PREARM_CHECK = mavutil.mavlink.MAV_SYS_STATUS_PREARM_CHECK


@pytest.fixture
def vehicle():
    """sitl (real time x3) + autopilot; yields a pymavlink connection that has seen a heartbeat."""
    sim_port, gcs_port = free_udp_port(), free_udp_port()
    gcs = mavutil.mavlink_connection(f"udpin:127.0.0.1:{gcs_port}", source_system=255)
    ap = subprocess.Popen(
        [str(binary("autopilot")), "--params-dir", str(ROOT / "params"),
         "--source", f"udp://127.0.0.1:{sim_port}?lockstep=false", "--loop-hz", "500",
         "--mavlink", f"udpout://127.0.0.1:{gcs_port}?bind=0"],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
    )
    sim = subprocess.Popen(
        [str(binary("sitl")), "--params-dir", str(ROOT / "params"), "--status-interval", "0",
         "--mode", "realtime", "--speed", "3", "--duration", "100000",
         "--autopilot", f"127.0.0.1:{sim_port}"],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
    )
    try:
        assert gcs.wait_heartbeat(timeout=30), "no heartbeat"
        yield gcs
    finally:
        sim.kill()
        ap.kill()
        sim.wait()
        _, err = ap.communicate()
        assert "panicked" not in err, err


def wait(gcs, what, condition, timeout=30):
    """The first message of type `what` for which condition(msg) holds, within `timeout` s."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        m = gcs.recv_match(type=what, blocking=True, timeout=0.5)
        if m is not None and m.get_srcComponent() == 1 and condition(m):
            return m
    pytest.fail(f"no {what} as expected within {timeout} s")


def ack(gcs, command, timeout=5):
    return wait(gcs, "COMMAND_ACK", lambda m: m.command == command, timeout).result


def armed(hb):
    return bool(hb.base_mode & mavutil.mavlink.MAV_MODE_FLAG_SAFETY_ARMED)


def ready_to_arm(gcs):
    wait(gcs, "SYS_STATUS", lambda m: m.onboard_control_sensors_health & PREARM_CHECK)


def test_identity_gps_and_requests(vehicle):
    gcs = vehicle
    hb = wait(gcs, "HEARTBEAT", lambda m: True)
    assert hb.autopilot == mavutil.mavlink.MAV_AUTOPILOT_PX4
    assert hb.type == mavutil.mavlink.MAV_TYPE_QUADROTOR
    assert hb.base_mode & mavutil.mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
    assert gcs.flightmode == "LOITER"  # pymavlink decodes PX4's custom_mode
    assert gcs.target_system == 1
    # MAVLink 2 from the first byte: pymavlink switched to it.
    assert gcs.mavlink20()

    # wait_gps_fix() has no time-out of its own: it runs once a fix is there.
    wait(gcs, "GPS_RAW_INT", lambda m: m.fix_type >= 3)
    gcs.wait_gps_fix()
    loc = gcs.location()
    assert abs(loc.lat - 47.397742) < 1e-3 and abs(loc.lng - 8.545594) < 1e-3, loc

    gcs.mav.command_long_send(1, 0, mavutil.mavlink.MAV_CMD_REQUEST_MESSAGE, 0,
                              mavutil.mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION, 0, 0, 0, 0, 0, 0)
    assert ack(gcs, mavutil.mavlink.MAV_CMD_REQUEST_MESSAGE) == mavutil.mavlink.MAV_RESULT_ACCEPTED
    v = wait(gcs, "AUTOPILOT_VERSION", lambda m: True, timeout=1)
    assert v.capabilities & mavutil.mavlink.MAV_PROTOCOL_CAPABILITY_MISSION_INT
    assert v.capabilities & mavutil.mavlink.MAV_PROTOCOL_CAPABILITY_MAVLINK2
    assert v.uid != 0

    # A command this vehicle does not know (an id no dialect has): acknowledged UNSUPPORTED.
    gcs.mav.command_long_send(1, 1, 31999, 0, 0, 0, 0, 0, 0, 0, 0)
    assert ack(gcs, 31999) == mavutil.mavlink.MAV_RESULT_UNSUPPORTED


def rate(gcs, what, seconds):
    """Messages of type `what` per second of wall time, counted over `seconds`."""
    n, end = 0, time.monotonic() + seconds
    while time.monotonic() < end:
        m = gcs.recv_match(type=what, blocking=True, timeout=0.1)
        n += m is not None
    return n / seconds


def test_set_message_interval_changes_a_measured_rate(vehicle):
    gcs = vehicle
    attitude = mavutil.mavlink.MAVLINK_MSG_ID_ATTITUDE
    wait(gcs, "ATTITUDE", lambda m: True)
    before = rate(gcs, "ATTITUDE", 2.0)
    gcs.mav.command_long_send(1, 0, mavutil.mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, 0,
                              attitude, 25_000, 0, 0, 0, 0, 0)
    assert ack(gcs, mavutil.mavlink.MAV_CMD_SET_MESSAGE_INTERVAL) == 0
    after = rate(gcs, "ATTITUDE", 2.0)
    assert 7 <= before <= 13 and 30 <= after <= 45, (before, after)
    gcs.mav.command_long_send(1, 0, mavutil.mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, 0,
                              attitude, -1, 0, 0, 0, 0, 0)
    assert ack(gcs, mavutil.mavlink.MAV_CMD_SET_MESSAGE_INTERVAL) == 0
    gcs.recv_match(type="ATTITUDE", blocking=True, timeout=0.3)  # one may be on its way
    assert rate(gcs, "ATTITUDE", 1.0) == 0


def test_takeoff_loiter_land_by_mode(vehicle):
    gcs = vehicle
    ready_to_arm(gcs)
    gcs.set_mode("TAKEOFF")
    assert ack(gcs, mavutil.mavlink.MAV_CMD_DO_SET_MODE) == mavutil.mavlink.MAV_RESULT_ACCEPTED
    wait(gcs, "HEARTBEAT", lambda m: gcs.flightmode == "TAKEOFF", timeout=3)
    gcs.arducopter_arm()
    assert ack(gcs, mavutil.mavlink.MAV_CMD_COMPONENT_ARM_DISARM) == 0
    wait(gcs, "HEARTBEAT", armed, timeout=3)
    wait(gcs, "EXTENDED_SYS_STATE",
         lambda m: m.landed_state == mavutil.mavlink.MAV_LANDED_STATE_TAKEOFF, timeout=10)
    # The take-off ends in Hold at MIS_TAKEOFF_ALT (2.5 m).
    wait(gcs, "HEARTBEAT", lambda m: gcs.flightmode == "LOITER", timeout=20)
    p = wait(gcs, "GLOBAL_POSITION_INT", lambda m: True)
    assert 2.2 < p.relative_alt / 1000 < 2.8, p
    gcs.set_mode("LOITER")
    assert ack(gcs, mavutil.mavlink.MAV_CMD_DO_SET_MODE) == 0
    # Disarming in the air is refused, with a reason.
    gcs.arducopter_disarm()
    assert ack(gcs, mavutil.mavlink.MAV_CMD_COMPONENT_ARM_DISARM) == \
        mavutil.mavlink.MAV_RESULT_DENIED
    wait(gcs, "STATUSTEXT", lambda m: "in the air" in m.text, timeout=2)
    gcs.set_mode("LAND")
    assert ack(gcs, mavutil.mavlink.MAV_CMD_DO_SET_MODE) == 0
    wait(gcs, "HEARTBEAT", lambda m: gcs.flightmode == "LAND", timeout=3)
    wait(gcs, "HEARTBEAT", lambda m: not armed(m), timeout=40)
    wait(gcs, "EXTENDED_SYS_STATE",
         lambda m: m.landed_state == mavutil.mavlink.MAV_LANDED_STATE_ON_GROUND, timeout=3)


def test_raw_command_long_takeoff_and_land(vehicle):
    gcs = vehicle
    ready_to_arm(gcs)
    home = wait(gcs, "GLOBAL_POSITION_INT", lambda m: True)
    gcs.mav.command_long_send(1, 1, mavutil.mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0,
                              1, 0, 0, 0, 0, 0, 0)
    assert ack(gcs, mavutil.mavlink.MAV_CMD_COMPONENT_ARM_DISARM) == 0
    # PX4's NAV_TAKEOFF: param7 is AMSL; 4 m above the start.
    target_amsl = home.alt / 1000 + 4.0
    gcs.mav.command_long_send(1, 1, mavutil.mavlink.MAV_CMD_NAV_TAKEOFF, 0,
                              0, 0, 0, math.nan, math.nan, math.nan, target_amsl)
    assert ack(gcs, mavutil.mavlink.MAV_CMD_NAV_TAKEOFF) == 0
    wait(gcs, "HEARTBEAT", lambda m: gcs.flightmode == "LOITER" and armed(m), timeout=30)
    p = wait(gcs, "GLOBAL_POSITION_INT", lambda m: True)
    assert 3.6 < p.relative_alt / 1000 < 4.4, p
    gcs.mav.command_long_send(1, 1, mavutil.mavlink.MAV_CMD_NAV_LAND, 0, 0, 0, 0, 0, 0, 0, 0)
    assert ack(gcs, mavutil.mavlink.MAV_CMD_NAV_LAND) == 0
    wait(gcs, "HEARTBEAT", lambda m: not armed(m), timeout=40)
