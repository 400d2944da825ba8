"""The vehicle as an unmodified pymavlink script sees it: sitl + autopilot over UDP, pymavlink on the
ground-station port. Every wait is on the vehicle's state with a time-out, never a fixed sleep.

The simulator runs in real time at 3x: the vehicle is given the time a script takes between two
commands (PX4's pre-flight auto-disarm, for one, counts simulated seconds).
"""

import math
import random
import struct
import threading
import time

import pytest
from pymavlink import mavutil

from conftest import Daemon, PtyLink, ack_and_said

PREARM_CHECK = mavutil.mavlink.MAV_SYS_STATUS_PREARM_CHECK


@pytest.fixture
def daemon(tmp_path):
    d = Daemon(tmp_path, "udpout://127.0.0.1:{port}?bind=0")
    try:
        assert d.gcs.wait_heartbeat(timeout=30), "no heartbeat"
        yield d
    finally:
        d.close()


@pytest.fixture
def vehicle(daemon):
    """A pymavlink connection that has seen a heartbeat."""
    return daemon.gcs


@pytest.fixture
def fast_vehicle(tmp_path):
    """As `vehicle`, the simulator in lockstep at up to six times real time: for flights whose
    times are the simulator's (what the vehicle does, not how fast the link answers)."""
    d = Daemon(tmp_path, "udpout://127.0.0.1:{port}?bind=0", lockstep=True, speed=6)
    try:
        assert d.gcs.wait_heartbeat(timeout=30), "no heartbeat"
        yield d.gcs
    finally:
        d.close()


def wait(gcs, what, condition, timeout=30):
    """The first message of type `what` for which condition(msg) holds, within `timeout` s. A
    wait that fails says the last such message seen (and pymavlink's mode then) and what the
    vehicle said meanwhile (STATUSTEXT)."""
    wanted = [what] if isinstance(what, str) else list(what)
    end = time.monotonic() + timeout
    last, said = None, []
    while time.monotonic() < end:
        m = gcs.recv_match(type=wanted + ["STATUSTEXT"], blocking=True, timeout=0.5)
        if m is None or m.get_srcComponent() != 1:
            continue
        if m.get_type() not in wanted:
            said.append(m.text)
            continue
        if condition(m):
            return m
        last = f"{m} (mode {gcs.flightmode})"
    pytest.fail(f"no {what} as expected within {timeout} s; the last one: {last}; said: {said[-10:]}")


def ack(gcs, command, timeout=5):
    return wait(gcs, "COMMAND_ACK", lambda m: m.command == command, timeout).result


def armed(hb):
    return bool(hb.base_mode & mavutil.mavlink.MAV_MODE_FLAG_SAFETY_ARMED)


def ready_to_arm(gcs):
    wait(gcs, "SYS_STATUS", lambda m: m.onboard_control_sensors_health & PREARM_CHECK)


def wait_holding_in_air(gcs, timeout=30, min_height_m=1.0):
    """Hold (LOITER), armed, at least `min_height_m` above home: a take-off has ended. Hold
    armed on the ground does not count (arming enters it; a heartbeat sent before the take-off
    command was acted on may still be queued)."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        wait(gcs, "HEARTBEAT", lambda m: gcs.flightmode == "LOITER" and armed(m),
             max(end - time.monotonic(), 0.5))
        if wait(gcs, "GLOBAL_POSITION_INT", lambda m: True, 5).relative_alt > min_height_m * 1e3:
            return
    pytest.fail(f"not holding {min_height_m} m up within {timeout} s")


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

    # The on-request messages, on the ground before arming.
    imu = request(gcs, "HIGHRES_IMU")
    assert abs(imu.zacc + 9.81) < 0.5 and abs(imu.xgyro) < 0.05, imu
    assert 900 < imu.abs_pressure < 1013.25 and abs(imu.pressure_alt - loc.alt) < 10, imu
    assert abs(request(gcs, "SCALED_IMU").zacc + 1000) < 50
    servo = request(gcs, "SERVO_OUTPUT_RAW")
    assert (servo.servo1_raw, servo.servo4_raw) == (1000, 1000), servo  # disarmed: stopped
    assert request(gcs, "ACTUATOR_OUTPUT_STATUS").actuator[0] == 0.0
    est = request(gcs, "ESTIMATOR_STATUS")
    assert est.flags & mavutil.mavlink.ESTIMATOR_ATTITUDE, est
    assert est.flags & mavutil.mavlink.ESTIMATOR_POS_HORIZ_ABS, est
    truth = request(gcs, "HIL_STATE_QUATERNION")  # SITL: the simulator's ground truth
    assert abs(truth.lat / 1e7 - loc.lat) < 1e-4 and abs(truth.alt / 1e3 - loc.alt) < 2, truth

    # A command this vehicle does not know (an id no dialect has): acknowledged UNSUPPORTED.
    gcs.mav.command_long_send(1, 1, 31999, 0, 0, 0, 0, 0, 0, 0, 0)
    assert ack(gcs, 31999) == mavutil.mavlink.MAV_RESULT_UNSUPPORTED


def request(gcs, what):
    """REQUEST_MESSAGE for message type `what`; the message, which follows within 1 s."""
    msg_id = getattr(mavutil.mavlink, f"MAVLINK_MSG_ID_{what}")
    gcs.mav.command_long_send(1, 1, mavutil.mavlink.MAV_CMD_REQUEST_MESSAGE, 0,
                              msg_id, 0, 0, 0, 0, 0, 0)
    assert ack(gcs, mavutil.mavlink.MAV_CMD_REQUEST_MESSAGE) == 0, what
    return wait(gcs, what, lambda m: True, timeout=1)


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


def test_sensor_messages_stream_up_to_the_sensor_rate(vehicle):
    """HIGHRES_IMU and SCALED_IMU as fast as asked up to the sensor rate (250 Hz), each message
    a sample of its own; faster is refused with the reason, and nothing changes. The rates are
    measured on the wall clock and printed; the test asserts the interval the vehicle reports
    and that the stream came at more than half the rate asked (the interval applied: a loaded
    machine may slow the vehicle's own samples, which the streams follow)."""
    gcs = vehicle
    ML = mavutil.mavlink
    wait(gcs, "ATTITUDE", lambda m: True)
    asked = {"HIGHRES_IMU": 200.0, "SCALED_IMU": 50.0, "ATTITUDE_QUATERNION": 250.0}
    for name, hz in asked.items():
        msg_id = getattr(ML, f"MAVLINK_MSG_ID_{name}")
        gcs.mav.command_long_send(1, 1, ML.MAV_CMD_SET_MESSAGE_INTERVAL, 0,
                                  msg_id, 1e6 / hz, 0, 0, 0, 0, 0)
        assert ack(gcs, ML.MAV_CMD_SET_MESSAGE_INTERVAL) == ML.MAV_RESULT_ACCEPTED, name
    gcs.recv_match(type="HIGHRES_IMU", blocking=True, timeout=1.0)
    counts = {name: 0 for name in asked}
    stamps = set()
    seconds = 4.0
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        m = gcs.recv_match(type=list(asked), blocking=True, timeout=0.1)
        if m is not None:
            counts[m.get_type()] += 1
            if m.get_type() == "HIGHRES_IMU":
                stamps.add(m.time_usec)
    measured = {name: n / seconds for name, n in counts.items()}
    print("asked", asked, "measured", measured)
    for name, hz in asked.items():
        assert measured[name] > 0.5 * hz, (name, measured[name], hz)
        msg_id = getattr(ML, f"MAVLINK_MSG_ID_{name}")
        gcs.mav.command_long_send(1, 1, ML.MAV_CMD_GET_MESSAGE_INTERVAL, 0,
                                  msg_id, 0, 0, 0, 0, 0, 0)
        m = wait(gcs, "MESSAGE_INTERVAL", lambda m: m.message_id == msg_id, 2)
        assert m.interval_us == round(1e6 / hz), (name, m)
    assert len(stamps) >= 0.99 * counts["HIGHRES_IMU"], "a sample sent twice"
    gcs.mav.command_long_send(1, 1, ML.MAV_CMD_SET_MESSAGE_INTERVAL, 0,
                              ML.MAVLINK_MSG_ID_HIGHRES_IMU, 1000, 0, 0, 0, 0, 0)
    result, said = ack_and_said(gcs, ML.MAV_CMD_SET_MESSAGE_INTERVAL,
                                wanted=lambda t: "HIGHRES_IMU" in t)
    why = next((t for t in said if "HIGHRES_IMU" in t), None)
    print(why)
    assert result == ML.MAV_RESULT_DENIED and why == "HIGHRES_IMU: at most 250 Hz (sensor rate)", why
    gcs.mav.command_long_send(1, 1, ML.MAV_CMD_GET_MESSAGE_INTERVAL, 0,
                              ML.MAVLINK_MSG_ID_HIGHRES_IMU, 0, 0, 0, 0, 0, 0)
    m = wait(gcs, "MESSAGE_INTERVAL", lambda m: m.message_id == ML.MAVLINK_MSG_ID_HIGHRES_IMU, 2)
    assert m.interval_us == 5000, m


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
    # What the loops are asked to fly: the held point, a level attitude, hover thrust.
    here = wait(gcs, "LOCAL_POSITION_NED", lambda m: True)
    target = request(gcs, "POSITION_TARGET_LOCAL_NED")
    assert math.dist((target.x, target.y, target.z), (here.x, here.y, here.z)) < 0.5, target
    assert target.type_mask & mavutil.mavlink.POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE
    att = request(gcs, "ATTITUDE_TARGET")
    assert abs(att.q[1]) < 0.1 and abs(att.q[2]) < 0.1, att  # level: no roll or pitch part
    assert 0.2 < att.thrust < 0.8, att
    servo = request(gcs, "SERVO_OUTPUT_RAW")
    assert all(1100 < s < 1900 for s in (servo.servo1_raw, servo.servo2_raw,
                                         servo.servo3_raw, servo.servo4_raw)), servo
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
    take_off_and_land(gcs, home.alt / 1000 + 4.0, (3.6, 4.4))


def arm_and_take_off(gcs):
    """Arms once ready and takes off to MIS_TAKEOFF_ALT (NAV_TAKEOFF without an altitude), both
    accepted; returns once the vehicle holds there, armed, in Hold."""
    ready_to_arm(gcs)
    gcs.arducopter_arm()
    assert ack(gcs, mavutil.mavlink.MAV_CMD_COMPONENT_ARM_DISARM) == 0
    gcs.mav.command_long_send(1, 1, mavutil.mavlink.MAV_CMD_NAV_TAKEOFF, 0,
                              0, 0, 0, math.nan, math.nan, math.nan, math.nan)
    assert ack(gcs, mavutil.mavlink.MAV_CMD_NAV_TAKEOFF) == 0
    wait_holding_in_air(gcs)


def take_off_and_land(gcs, amsl, height_range):
    """NAV_TAKEOFF to `amsl` (NaN: MIS_TAKEOFF_ALT) of an armed vehicle, Hold reached at a
    height within `height_range` (m), then NAV_LAND and the disarm that ends it."""
    gcs.mav.command_long_send(1, 1, mavutil.mavlink.MAV_CMD_NAV_TAKEOFF, 0,
                              0, 0, 0, math.nan, math.nan, math.nan, amsl)
    assert ack(gcs, mavutil.mavlink.MAV_CMD_NAV_TAKEOFF) == 0
    wait_holding_in_air(gcs)
    p = wait(gcs, "GLOBAL_POSITION_INT", lambda m: True)
    assert height_range[0] < p.relative_alt / 1000 < height_range[1], p
    gcs.mav.command_long_send(1, 1, mavutil.mavlink.MAV_CMD_NAV_LAND, 0, 0, 0, 0, 0, 0, 0, 0)
    assert ack(gcs, mavutil.mavlink.MAV_CMD_NAV_LAND) == 0
    wait(gcs, "HEARTBEAT", lambda m: not armed(m), timeout=40)


REAL32 = mavutil.mavlink.MAV_PARAM_TYPE_REAL32
INT32 = mavutil.mavlink.MAV_PARAM_TYPE_INT32


def int_bits(value):
    """An INT32 parameter value as it travels (byte-wise in the float field), as MAVProxy packs it."""
    return struct.unpack(">f", struct.pack(">i", value))[0]


def from_bits(raw):
    return struct.unpack(">i", struct.pack(">f", raw))[0]


def param(gcs, name, timeout=20):
    """PARAM_REQUEST_READ by name, repeated every second as clients do (the vehicle may be
    starting); the PARAM_VALUE that answers it."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        gcs.mav.param_request_read_send(1, 1, name.encode(), -1)
        asked = time.monotonic()
        while time.monotonic() - asked < 1.0:
            m = gcs.recv_match(type="PARAM_VALUE", blocking=True, timeout=0.2)
            if m is not None and m.param_id == name:
                return m
    pytest.fail(f"no PARAM_VALUE {name} within {timeout} s")


def set_param(gcs, name, value, ptype=REAL32, texts=None):
    """PARAM_SET as pymavlink's param_set_send; the PARAM_VALUE echo. STATUSTEXTs that arrive
    meanwhile are appended to `texts`."""
    gcs.param_set_send(name, value, ptype)
    end = time.monotonic() + 3
    while time.monotonic() < end:
        m = gcs.recv_match(type=["PARAM_VALUE", "STATUSTEXT"], blocking=True, timeout=0.5)
        if m is None or m.get_srcComponent() != 1:
            continue
        if m.get_type() == "STATUSTEXT" and texts is not None:
            texts.append(m.text)
        if m.get_type() == "PARAM_VALUE" and m.param_id == name:
            return m
    pytest.fail(f"no PARAM_VALUE {name} after PARAM_SET")


def param_list(gcs):
    """PARAM_REQUEST_LIST's answer: every index once, with a constant count; index ->
    PARAM_VALUE."""
    gcs.mav.param_request_list_send(1, 0)
    first = wait(gcs, "PARAM_VALUE", lambda m: True, 3)
    count, seen = first.param_count, {first.param_index: first}
    end = time.monotonic() + 10
    while len(seen) < count and time.monotonic() < end:
        m = gcs.recv_match(type="PARAM_VALUE", blocking=True, timeout=0.5)
        if m is not None:
            assert m.param_count == count
            seen[m.param_index] = m
    assert sorted(seen) == list(range(count)), f"{len(seen)} of {count}"
    return seen


def test_parameters_fetch_set_persist_across_restart_and_reboot(daemon):
    gcs = daemon.gcs
    # Fetch all: a constant count, every index once, each name once.
    seen = param_list(gcs)
    count = len(seen)
    by_name = {m.param_id: m for m in seen.values()}
    assert len(by_name) == count >= 50
    assert (by_name["MIS_TAKEOFF_ALT"].param_type, by_name["MIS_TAKEOFF_ALT"].param_value) == \
        (REAL32, 2.5)
    assert by_name["ATT_ALIGN_N"].param_type == INT32
    assert from_bits(by_name["ATT_ALIGN_N"].param_value) == 250

    # Set and read back; a bad value is answered with the value in force and a reason.
    assert set_param(gcs, "MIS_TAKEOFF_ALT", 4.0).param_value == 4.0
    assert from_bits(set_param(gcs, "ATT_ALIGN_N", int_bits(300), INT32).param_value) == 300
    texts = []
    assert set_param(gcs, "MPC_XY_P", 99.0, texts=texts).param_value == pytest.approx(0.95)
    assert set_param(gcs, "MPC_XY_P", math.nan, texts=texts).param_value == pytest.approx(0.95)
    # The wrong type: REAL32 for an INT32 parameter.
    assert set_param(gcs, "ATT_ALIGN_N", 1000.0, texts=texts).param_value == int_bits(300)
    assert texts[0].startswith("MPC_XY_P: 99 is outside [0, 5]"), texts
    assert texts[1].startswith("MPC_XY_P: NaN is not a number"), texts
    assert texts[2].startswith("ATT_ALIGN_N: INT32 parameter, sent as REAL32"), texts
    assert param(gcs, "MIS_TAKEOFF_ALT").param_value == 4.0
    gcs.mav.param_request_read_send(1, 1, b"", by_name["MIS_TAKEOFF_ALT"].param_index)
    assert wait(gcs, "PARAM_VALUE", lambda m: m.param_id == "MIS_TAKEOFF_ALT", 3).param_value == 4.0

    # Persisted: after a clean stop and a new start the values are still there.
    daemon.stop()
    assert "MIS_TAKEOFF_ALT = 4.0" in daemon.store.read_text()
    daemon.start()
    assert gcs.wait_heartbeat(timeout=30)
    assert param(gcs, "MIS_TAKEOFF_ALT").param_value == 4.0
    assert from_bits(param(gcs, "ATT_ALIGN_N").param_value) == 300

    # And flown: a take-off without an altitude climbs to MIS_TAKEOFF_ALT.
    arm_and_take_off(gcs)
    p = wait(gcs, "GLOBAL_POSITION_INT", lambda m: True)
    assert 3.6 < p.relative_alt / 1000 < 4.4, p
    # Reboot is refused in the air.
    reboot = mavutil.mavlink.MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN
    gcs.mav.command_long_send(1, 1, reboot, 0, 1, 0, 0, 0, 0, 0, 0)
    assert ack(gcs, reboot) == mavutil.mavlink.MAV_RESULT_DENIED
    gcs.mav.command_long_send(1, 1, mavutil.mavlink.MAV_CMD_NAV_LAND, 0, 0, 0, 0, 0, 0, 0, 0)
    assert ack(gcs, mavutil.mavlink.MAV_CMD_NAV_LAND) == 0
    wait(gcs, "HEARTBEAT", lambda m: not armed(m), timeout=40)

    # A reboot (the process starts again in place) keeps a value set just before it.
    assert set_param(gcs, "RTL_RETURN_ALT", 40.0).param_value == 40.0
    runs = daemon.summaries()
    gcs.mav.command_long_send(1, 1, reboot, 0, 1, 0, 0, 0, 0, 0, 0)
    assert ack(gcs, reboot) == mavutil.mavlink.MAV_RESULT_ACCEPTED
    end = time.monotonic() + 10
    while daemon.summaries() == runs and time.monotonic() < end:
        gcs.recv_match(blocking=True, timeout=0.2)
    assert daemon.summaries() == runs + 1, "the first run did not end"
    assert daemon.ap.poll() is None, "the process exited instead of starting again"
    assert gcs.wait_heartbeat(timeout=30)
    assert param(gcs, "RTL_RETURN_ALT").param_value == 40.0

    # Reset to defaults: flight.toml's values, the store emptied.
    gcs.mav.command_long_send(1, 1, mavutil.mavlink.MAV_CMD_PREFLIGHT_STORAGE, 0,
                              2, 0, 0, 0, 0, 0, 0)
    assert ack(gcs, mavutil.mavlink.MAV_CMD_PREFLIGHT_STORAGE) == 0
    assert param(gcs, "MIS_TAKEOFF_ALT").param_value == 2.5
    daemon.stop()
    assert "MIS_TAKEOFF_ALT" not in daemon.store.read_text()


def start_afresh(daemon):
    """Starts the stopped daemon and waits for its first heartbeat. What the stopped process sent
    is read away first: it is not the new one's answer, and pymavlink answers the address it
    last heard from."""
    while daemon.gcs.recv_match(blocking=False) is not None:
        pass
    daemon.start()
    if daemon.gcs.wait_heartbeat(timeout=30) is None:
        daemon.ap.kill()
        _, err = daemon.ap.communicate()
        raise AssertionError(f"no heartbeat from the restarted daemon: {err[-2000:]}")


def test_a_daemon_killed_while_saving_keeps_its_store_and_a_damaged_store_falls_back(daemon):
    """SIGKILL at a random point of a burst of PARAM_SETs (each one saved): the daemon starts
    again with one of the values sent; a store damaged on disk is replaced by its previous good
    copy, and the ground station told."""
    gcs = daemon.gcs
    rng = random.Random(9)
    sent = [2.5]
    for burst in range(3):
        values = [round(3.0 + burst + 0.05 * i, 2) for i in range(20)]
        sent += values
        for v in values:
            gcs.param_set_send("MIS_TAKEOFF_ALT", v, REAL32)
        # Killed once the vehicle has answered some of them (each answer follows its save's
        # request: the saves are under way).
        k = rng.randrange(1, 20)
        wait(gcs, "PARAM_VALUE", lambda m: m.param_id == "MIS_TAKEOFF_ALT"
             and m.param_value >= values[k] - 1e-3, 5)
        daemon.ap.kill()
        daemon.ap.wait()
        start_afresh(daemon)
        value = param(gcs, "MIS_TAKEOFF_ALT").param_value
        assert any(abs(value - v) < 1e-4 for v in sent), (burst, value)
    # Two saves for certain (the kills may have come before any), each ended by a clean stop:
    # the second keeps the first as the previous good copy.
    assert set_param(gcs, "MIS_TAKEOFF_ALT", 9.0).param_value == 9.0
    daemon.stop()
    start_afresh(daemon)
    assert set_param(gcs, "MIS_TAKEOFF_ALT", 9.5).param_value == 9.5
    daemon.stop()

    # A bit gone bad on the disk.
    text = daemon.store.read_text()
    assert "MIS_TAKEOFF_ALT = 9.5" in text
    daemon.store.write_text(text.replace("9.5", "9.6"))
    start_afresh(daemon)
    gcs.mav.heartbeat_send(mavutil.mavlink.MAV_TYPE_GCS, mavutil.mavlink.MAV_AUTOPILOT_INVALID,
                           0, 0, 0)
    wait(gcs, "STATUSTEXT", lambda m: m.text == "param store damaged: previous copy used", 10)
    assert param(gcs, "MIS_TAKEOFF_ALT").param_value == 9.0
    daemon.stop()
    assert "previous good copy" in daemon.ap_stderr


class Sticks:
    """A joystick through the ground station: MANUAL_CONTROL at 20 Hz from a thread, as
    QGroundControl sends it (x pitch, y roll, r yaw: ±1000; z throttle 0–1000, 500 centred)."""

    def __init__(self, gcs):
        self.gcs, self.values = gcs, (0, 0, 500, 0)
        self.running, self.sent = True, 0
        self.cond = threading.Condition()
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self):
        while self.running:
            with self.cond:
                x, y, z, r = self.values
                self.gcs.mav.manual_control_send(1, x, y, z, r, 0)
                self.sent += 1
                self.cond.notify_all()
            time.sleep(0.05)  # the stream's period, not a wait for the vehicle

    def set(self, x=0, y=0, z=500, r=0):
        self.values = (x, y, z, r)

    def sent_now(self, x=0, y=0, z=500, r=0):
        """Sets the sticks and returns once they have been sent: a command sent next on the
        same link reaches the vehicle after them."""
        with self.cond:
            self.values = (x, y, z, r)
            n = self.sent
            assert self.cond.wait_for(lambda: self.sent > n, timeout=2)

    def stop(self):
        self.running = False
        self.thread.join()


def test_position_mode_flies_the_sticks_and_holds_then_holds_on_their_loss(vehicle):
    gcs = vehicle
    ready_to_arm(gcs)
    gcs.set_mode("POSCTL")
    assert ack(gcs, mavutil.mavlink.MAV_CMD_DO_SET_MODE) == mavutil.mavlink.MAV_RESULT_DENIED
    wait(gcs, "STATUSTEXT", lambda m: "no manual control" in m.text, 2)
    rc = mavutil.mavlink.MAV_SYS_STATUS_SENSOR_RC_RECEIVER
    sticks = Sticks(gcs)
    try:
        sticks.set(z=0)
        # The vehicle reports the joystick as PX4 reports its RC: in SYS_STATUS.
        wait(gcs, "SYS_STATUS", lambda m: m.onboard_control_sensors_health & rc, 5)
        gcs.set_mode("POSCTL")
        assert ack(gcs, mavutil.mavlink.MAV_CMD_DO_SET_MODE) == 0
        wait(gcs, "HEARTBEAT", lambda m: gcs.flightmode == "POSCTL", timeout=3)
        gcs.arducopter_arm()
        assert ack(gcs, mavutil.mavlink.MAV_CMD_COMPONENT_ARM_DISARM) == 0
        # Throttle up: climbs; centred: holds the altitude.
        sticks.set(z=850)
        wait(gcs, "GLOBAL_POSITION_INT", lambda m: m.relative_alt > 4000, 20)
        sticks.set()
        wait(gcs, "GLOBAL_POSITION_INT", lambda m: abs(m.vz) < 20, 10)
        alt0 = wait(gcs, "GLOBAL_POSITION_INT", lambda m: True).relative_alt / 1000
        end, worst = time.monotonic() + 2.0, 0.0
        while time.monotonic() < end:
            m = wait(gcs, "GLOBAL_POSITION_INT", lambda m: True)
            worst = max(worst, abs(m.relative_alt / 1000 - alt0))
        assert worst < 0.4, f"altitude hold: {worst:.2f} m off"
        # Full forward: flies along its heading at MPC_VEL_MANUAL (5 m/s).
        yaw = wait(gcs, "ATTITUDE", lambda m: True).yaw
        sticks.set(x=1000)
        fast = wait(gcs, "LOCAL_POSITION_NED", lambda m: math.hypot(m.vx, m.vy) > 4.0, 15)
        heading = math.atan2(fast.vy, fast.vx)
        assert abs(math.remainder(heading - yaw, math.tau)) < math.radians(15), (heading, yaw)
        # Centred: brakes and holds the position.
        sticks.set()
        wait(gcs, "LOCAL_POSITION_NED", lambda m: math.hypot(m.vx, m.vy) < 0.3, 15)
        p0 = wait(gcs, "LOCAL_POSITION_NED", lambda m: True)
        end, worst = time.monotonic() + 2.0, 0.0
        while time.monotonic() < end:
            m = wait(gcs, "LOCAL_POSITION_NED", lambda m: True)
            worst = max(worst, math.hypot(m.x - p0.x, m.y - p0.y))
        assert worst < 0.5, f"position hold: {worst:.2f} m off"
    finally:
        sticks.stop()
    # The sticks stop: NAV_RCL_ACT's Return (PX4's default) after COM_RC_LOSS_T, with a reason.
    wait(gcs, "STATUSTEXT", lambda m: "manual control lost: RTL" in m.text, 5)
    wait(gcs, "HEARTBEAT", lambda m: gcs.flightmode == "RTL" and armed(m), timeout=3)
    gcs.set_mode("LAND")
    assert ack(gcs, mavutil.mavlink.MAV_CMD_DO_SET_MODE) == 0
    wait(gcs, "HEARTBEAT", lambda m: not armed(m), timeout=60)


def pilot(gcs, sticks, until, climb=0.0, timeout=30, **stick):
    """A pilot's throttle hand in STABILIZED (no altitude hold there): throttle around its centre
    (hover thrust) to keep the climb rate at `climb` m/s, the other sticks as given, until
    until(LOCAL_POSITION_NED or ATTITUDE message) holds."""
    end = time.monotonic() + timeout
    throttle, last = 500, {}
    while time.monotonic() < end:
        m = gcs.recv_match(type=["LOCAL_POSITION_NED", "ATTITUDE"], blocking=True, timeout=0.5)
        if m is None or m.get_srcComponent() != 1:
            continue
        last[m.get_type()] = m
        if m.get_type() == "LOCAL_POSITION_NED":
            throttle = min(1000, max(0, 500 + 60 * (m.vz + climb)))
        sticks.set(z=int(throttle), **stick)
        if until(m):
            return m
    pytest.fail(f"the pilot's condition not met within {timeout} s: "
                f"{ {k: v.to_dict() for k, v in last.items()} }, throttle {throttle}, "
                f"mode {gcs.flightmode}")


def test_stabilized_flies_attitude_and_thrust_from_the_sticks(vehicle):
    """STABILIZED as on PX4 multicopters: roll and pitch sticks to tilt (MPC_MAN_TILT_MAX 35°),
    yaw stick to a turn rate (MPC_MAN_Y_MAX 150°/s), throttle to thrust through hover at its
    centre; the vehicle levels when the sticks centre; touchdown on low throttle disarms."""
    gcs = vehicle
    set_param(gcs, "MPC_MAN_Y_MAX", 60.0)
    # 20 Hz sticks at 3x speed are 0.15 s of vehicle time apart: a scheduling hiccup of this
    # process must not read as a lost joystick (the loss itself is tested in POSCTL).
    set_param(gcs, "COM_RC_LOSS_T", 2.0)
    ready_to_arm(gcs)
    sticks = Sticks(gcs)
    try:
        sticks.sent_now(z=0)
        gcs.set_mode("STABILIZED")
        assert ack(gcs, mavutil.mavlink.MAV_CMD_DO_SET_MODE) == 0
        wait(gcs, "HEARTBEAT", lambda m: gcs.flightmode == "STABILIZED", timeout=3)
        sticks.sent_now(z=600)
        gcs.arducopter_arm()
        assert ack(gcs, mavutil.mavlink.MAV_CMD_COMPONENT_ARM_DISARM) == mavutil.mavlink.MAV_RESULT_DENIED
        wait(gcs, "STATUSTEXT", lambda m: "throttle stick not low" in m.text, 2)
        sticks.sent_now(z=0)
        gcs.arducopter_arm()
        assert ack(gcs, mavutil.mavlink.MAV_CMD_COMPONENT_ARM_DISARM) == 0
        # Climb at 1.5 m/s to 4 m on the throttle alone.
        pilot(gcs, sticks, lambda m: m.get_type() == "LOCAL_POSITION_NED" and m.z < -4.0, 1.5)
        pilot(gcs, sticks, lambda m: m.get_type() == "LOCAL_POSITION_NED" and abs(m.vz) < 0.2)
        # Roll stick 40 % right: 14° of roll, flying east of the heading.
        roll = math.radians(0.4 * 35)
        pilot(gcs, sticks, lambda m: m.get_type() == "ATTITUDE"
              and abs(m.roll - roll) < math.radians(1.5) and abs(m.pitch) < math.radians(1.5),
              timeout=10, y=400)
        # Pitch stick 30 % forward: nose down 10.5°, level in roll.
        pitch = -math.radians(0.3 * 35)
        pilot(gcs, sticks, lambda m: m.get_type() == "ATTITUDE"
              and abs(m.pitch - pitch) < math.radians(1.5) and abs(m.roll) < math.radians(1.5),
              timeout=10, x=300)
        # Centred: level again.
        pilot(gcs, sticks, lambda m: m.get_type() == "ATTITUDE"
              and math.hypot(m.roll, m.pitch) < math.radians(1.0), timeout=10)
        # Full yaw stick: turns at MPC_MAN_Y_MAX (set to 60°/s, below the rate loop's limit).
        m = pilot(gcs, sticks, lambda m: m.get_type() == "ATTITUDE"
                  and abs(m.yawspeed - math.radians(60)) < math.radians(5), timeout=10, r=1000)
        pilot(gcs, sticks, lambda m: m.get_type() == "ATTITUDE" and abs(m.yawspeed) < 0.1,
              timeout=10)
        # Down at 0.8 m/s, throttle to zero near the ground: touchdown, disarmed, still STABILIZED.
        pilot(gcs, sticks, lambda m: m.get_type() == "LOCAL_POSITION_NED" and m.z > -0.5, -0.8,
              timeout=40)
        sticks.set(z=0)
        wait(gcs, "HEARTBEAT", lambda m: not armed(m), timeout=15)
        assert gcs.flightmode == "STABILIZED"
    finally:
        sticks.stop()


def test_a_ground_station_on_a_serial_line(tmp_path):
    link = PtyLink()
    daemon = Daemon(tmp_path, f"serial://{link.device}?baud=57600", connect=False)
    try:
        hb = link.recv("HEARTBEAT", lambda m: True, 30)
        assert hb.autopilot == mavutil.mavlink.MAV_AUTOPILOT_PX4
        # Sent again after 3 s without an answer, as the command protocol has a ground station
        # do (a line opened moments ago may lose what crosses it meanwhile: seen once in CI).
        for attempt in range(3):
            link.mav.command_long_send(1, 1, mavutil.mavlink.MAV_CMD_REQUEST_MESSAGE, attempt,
                                       mavutil.mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION,
                                       0, 0, 0, 0, 0, 0)
            ack = link.try_recv("COMMAND_ACK",
                                lambda m: m.command == mavutil.mavlink.MAV_CMD_REQUEST_MESSAGE, 3)
            if ack is not None:
                break
        assert ack is not None and ack.result == 0, ack
        assert link.recv("AUTOPILOT_VERSION", lambda m: True).uid != 0
        link.mav.param_request_read_send(1, 1, b"MIS_TAKEOFF_ALT", -1)
        assert link.recv("PARAM_VALUE", lambda m: m.param_id == "MIS_TAKEOFF_ALT").param_value \
            == 2.5
    finally:
        daemon.close()
        link.close()
