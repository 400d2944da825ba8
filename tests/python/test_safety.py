"""Failsafes end to end, one scenario per failsafe as they land: sitl + autopilot over UDP at 3x
real time (the flights that only fly: in lockstep at up to 6x), driven with pymavlink; every wait
is on the vehicle's state with a time-out. The state machine itself is table-tested in daemon/core/src/safety/tests.rs."""

import math
import threading
import time

import pytest
from pymavlink import mavutil

from conftest import Daemon, sim_control, sim_param
from test_ground_station import (  # noqa: F401
    INT32, PREARM_CHECK, ack, armed, daemon, fast_vehicle, int_bits, ready_to_arm, set_param,
    vehicle, wait)

ML = mavutil.mavlink


class Heartbeats:
    """A ground station's heartbeat at 2 Hz from a thread, until stopped (the link "lost")."""

    def __init__(self, gcs):
        self.gcs, self.running = gcs, True
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self):
        while self.running:
            self.gcs.mav.heartbeat_send(ML.MAV_TYPE_GCS, ML.MAV_AUTOPILOT_INVALID, 0, 0, 0)
            time.sleep(0.5)  # the heartbeat's period, not a wait for the vehicle

    def stop(self):
        self.running = False
        self.thread.join()


def take_off(gcs):
    """TAKEOFF mode, armed, in the air in Hold (LOITER) at the take-off altitude."""
    gcs.set_mode("TAKEOFF")
    assert ack(gcs, ML.MAV_CMD_DO_SET_MODE) == 0
    gcs.arducopter_arm()
    assert ack(gcs, ML.MAV_CMD_COMPONENT_ARM_DISARM) == 0
    wait(gcs, "HEARTBEAT", lambda m: gcs.flightmode == "LOITER" and armed(m), timeout=30)


def reposition_north(gcs, home, metres):
    """DO_REPOSITION `metres` north of `home` (GLOBAL_POSITION_INT) at 4 m: default speed, no
    mode change (in Hold already), no yaw."""
    gcs.mav.command_int_send(1, 1, ML.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
                             ML.MAV_CMD_DO_REPOSITION, 0, 0, -1, 0, 0, math.nan,
                             home.lat + int(metres / 111_320 * 1e7), home.lon, 4.0)
    assert ack(gcs, ML.MAV_CMD_DO_REPOSITION) == 0


def test_gcs_link_loss_holds_then_returns_and_lands_at_home(fast_vehicle):
    vehicle = fast_vehicle
    """NAV_DLL_ACT 2 (Return) after COM_DL_LOSS_T of wall time without a GCS heartbeat, Hold
    for COM_FAIL_ACT_T first; the return lands at home and disarms."""
    gcs = vehicle
    beats = Heartbeats(gcs)
    try:
        # Failure injection is refused while SYS_FAILURE_EN is 0 (MAVSDK checks the parameter
        # itself; a raw command must meet the autopilot's own refusal).
        gcs.mav.command_long_send(1, 1, ML.MAV_CMD_INJECT_FAILURE, 0, 101, 1, 1, 0, 0, 0, 0)
        assert ack(gcs, ML.MAV_CMD_INJECT_FAILURE) == ML.MAV_RESULT_DENIED
        set_param(gcs, "NAV_DLL_ACT", int_bits(2), INT32)
        set_param(gcs, "COM_DL_LOSS_T", 2.0)
        set_param(gcs, "COM_FAIL_ACT_T", 2.0)
        ready_to_arm(gcs)
        home = wait(gcs, "GLOBAL_POSITION_INT", lambda m: True)
        take_off(gcs)
        # Fly 8 m north so the return has somewhere to go.
        reposition_north(gcs, home, 8)
        start = wait(gcs, "HOME_POSITION", lambda m: True, timeout=5)
        wait(gcs, "LOCAL_POSITION_NED", lambda m: m.x - start.x > 7.0 and abs(m.vx) < 0.3, 30)
    finally:
        beats.stop()
    lost = time.monotonic()
    wait(gcs, "STATUSTEXT", lambda m: "ground-station link lost: Hold" in m.text, timeout=5)
    seen = time.monotonic() - lost
    assert 1.5 < seen < 4.0, f"after {seen:.1f} s of wall time (COM_DL_LOSS_T 2 s)"
    wait(gcs, "STATUSTEXT", lambda m: "ground-station link lost: Return" in m.text, timeout=5)
    wait(gcs, "HEARTBEAT", lambda m: gcs.flightmode == "RTL", timeout=3)
    wait(gcs, "HEARTBEAT", lambda m: not armed(m), timeout=90)
    end = wait(gcs, "LOCAL_POSITION_NED", lambda m: True)
    off = math.hypot(end.x - start.x, end.y - start.y)
    assert off < 1.0, f"landed {off:.2f} m from home"


def inject(gcs, unit, kind, instance=0):
    """MAV_CMD_INJECT_FAILURE; its result."""
    gcs.mav.command_long_send(1, 1, ML.MAV_CMD_INJECT_FAILURE, 0, unit, kind, instance, 0, 0, 0, 0)
    return ack(gcs, ML.MAV_CMD_INJECT_FAILURE)


def test_frozen_and_silent_sensors_warn_refuse_arming_and_clear(vehicle):
    """A stuck magnetometer and a barometer switched off (MAV_CMD_INJECT_FAILURE): each found
    (frozen readings, silence), announced, taken out of the estimate, arming refused with the
    reason; back to working, the failsafe is over and the vehicle arms."""
    gcs = vehicle
    set_param(gcs, "SYS_FAILURE_EN", int_bits(1), INT32)
    ready_to_arm(gcs)
    assert inject(gcs, ML.FAILURE_UNIT_SENSOR_MAG, ML.FAILURE_TYPE_STUCK) == 0
    wait(gcs, "STATUSTEXT", lambda m: m.text == "magnetometer lost", 5)
    gcs.arducopter_arm()
    assert ack(gcs, ML.MAV_CMD_COMPONENT_ARM_DISARM) == ML.MAV_RESULT_DENIED
    wait(gcs, "STATUSTEXT", lambda m: "magnetometer silent or frozen" in m.text, 2)
    assert inject(gcs, ML.FAILURE_UNIT_SENSOR_BARO, ML.FAILURE_TYPE_OFF) == 0
    wait(gcs, "STATUSTEXT", lambda m: m.text == "barometer lost", 5)
    # Still refused (which reason leads depends on what lapsed first without the sensors: the
    # attitude estimate without a magnetometer, the altitude estimate without a barometer).
    gcs.arducopter_arm()
    assert ack(gcs, ML.MAV_CMD_COMPONENT_ARM_DISARM) == ML.MAV_RESULT_DENIED
    assert inject(gcs, ML.FAILURE_UNIT_SENSOR_MAG, ML.FAILURE_TYPE_OK) == 0
    assert inject(gcs, ML.FAILURE_UNIT_SENSOR_BARO, ML.FAILURE_TYPE_OK) == 0
    wait(gcs, "STATUSTEXT", lambda m: m.text == "failsafe over: magnetometer lost", 5)
    # The altitude estimate waits for the barometer again before arming is allowed.
    ready_to_arm(gcs)
    gcs.arducopter_arm()
    assert ack(gcs, ML.MAV_CMD_COMPONENT_ARM_DISARM) == 0
    gcs.arducopter_disarm()
    assert ack(gcs, ML.MAV_CMD_COMPONENT_ARM_DISARM) == 0


def test_battery_failsafe_warns_returns_lands_and_refuses_to_arm(tmp_path, scenario):
    """A pack at 35 % (600 mAh, so it runs down in a minute of hover): the estimate (voltage at
    rest, then the current counted) falls through BAT_LOW_THR (warn), BAT_CRIT_THR (Return, the
    default COM_LOW_BAT_ACT 3) and BAT_EMERGEN_THR (Land); SYS_STATUS and BATTERY_STATUS carry the
    charge, the current and the charge state; once landed, arming is refused for the battery."""
    path = scenario('airframe = "quad_x"\nduration_s = 100000.0\n'
                    '[battery]\ncharge = 0.35\ncapacity_mah = 600.0\n')
    d = Daemon(tmp_path, "udpout://127.0.0.1:{port}?bind=0", scenario=path)
    try:
        gcs = d.gcs
        assert gcs.wait_heartbeat(timeout=30), "no heartbeat"
        set_param(gcs, "BAT1_CAPACITY", 600.0)
        ready_to_arm(gcs)
        first = wait(gcs, "BATTERY_STATUS", lambda m: m.battery_remaining >= 0)
        assert 15 < first.battery_remaining < 40, first
        assert first.charge_state == ML.MAV_BATTERY_CHARGE_STATE_OK, first
        home = wait(gcs, "GLOBAL_POSITION_INT", lambda m: True)
        take_off(gcs)
        reposition_north(gcs, home, 6)
        # Everything in order until the vehicle is down and disarmed.
        events, charge, states, current = [], [], set(), []
        end = time.monotonic() + 120
        while time.monotonic() < end:
            m = gcs.recv_match(type=["STATUSTEXT", "HEARTBEAT", "SYS_STATUS", "BATTERY_STATUS"],
                               blocking=True, timeout=0.5)
            if m is None or m.get_srcComponent() != 1:
                continue
            kind = m.get_type()
            if kind == "STATUSTEXT" and "battery" in m.text:
                events.append(m.text)
            elif kind == "HEARTBEAT":
                if not events or events[-1] != gcs.flightmode:
                    events.append(gcs.flightmode)
                if not armed(m) and "RTL" in events:
                    break
            elif kind == "SYS_STATUS" and m.battery_remaining >= 0:
                charge.append(m.battery_remaining)
                current.append(m.current_battery)
            elif kind == "BATTERY_STATUS":
                states.add(m.charge_state)
        else:
            pytest.fail(f"not landed and disarmed in time: {events}")
        print(f"battery failsafe: {events}; charge {charge[0]} % to {charge[-1]} %")
        texts = [e for e in events if "battery" in e]
        assert texts[:3] == ["battery low", "failsafe: battery critical: Return",
                             "failsafe: battery emergency: Land"], events
        modes = [e for e in events if e.isupper()]
        assert modes.index("RTL") < modes.index("LAND"), events
        # Falling (the lean toward the voltage may lift it by a percent), down to the emergency.
        assert all(b <= a + 1 for a, b in zip(charge, charge[1:])) and charge[-1] <= 5, charge
        assert max(current) > 500, f"hover current (cA): {max(current)}"
        assert {ML.MAV_BATTERY_CHARGE_STATE_LOW, ML.MAV_BATTERY_CHARGE_STATE_CRITICAL,
                ML.MAV_BATTERY_CHARGE_STATE_EMERGENCY} <= states, states
        gcs.set_mode("TAKEOFF")
        ack(gcs, ML.MAV_CMD_DO_SET_MODE)
        gcs.arducopter_arm()
        assert ack(gcs, ML.MAV_CMD_COMPONENT_ARM_DISARM) == ML.MAV_RESULT_DENIED
        wait(gcs, "STATUSTEXT", lambda m: "battery" in m.text, 2)
    finally:
        d.close()


def upload_fence(gcs, items):
    """Uploads fence items (MISSION_ITEM_INT messages) by the mission protocol; the ack's type."""
    gcs.mav.mission_count_send(1, 1, len(items), ML.MAV_MISSION_TYPE_FENCE)
    for it in items:
        wait(gcs, "MISSION_REQUEST_INT",
             lambda m: m.seq == it.seq and m.mission_type == ML.MAV_MISSION_TYPE_FENCE, 5)
        gcs.mav.send(it)
    return wait(gcs, "MISSION_ACK", lambda m: m.mission_type == ML.MAV_MISSION_TYPE_FENCE, 5).type


def fence_item(seq, command, p1, lat, lon):
    return ML.MAVLink_mission_item_int_message(
        1, 1, seq, ML.MAV_FRAME_GLOBAL_INT, command, 0, 1, p1, 0, 0, 0,
        lat, lon, 0, mission_type=ML.MAV_MISSION_TYPE_FENCE)


def test_uploaded_geofence_refuses_arming_outside_and_holds_at_the_breach(fast_vehicle):
    vehicle = fast_vehicle
    """A fence plan (MAV_MISSION_TYPE_FENCE): an exclusion circle around home refuses arming
    ("outside the geofence"); replaced by an inclusion square of ±12 m, the vehicle arms, is sent
    25 m north, is stopped at the square's edge by GF_ACTION 2 (Hold) — the breach predicted from
    the stopping distance, announced, the SYS_STATUS geofence bit unhealthy — and is brought home by
    RTL."""
    gcs = vehicle
    ready_to_arm(gcs)
    home = wait(gcs, "GLOBAL_POSITION_INT", lambda m: True)
    deg = 1e7 / 111_320  # 1e7 degrees per metre north
    east = deg / math.cos(math.radians(home.lat * 1e-7))
    circle = [fence_item(0, ML.MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION, 5.0, home.lat, home.lon)]
    assert upload_fence(gcs, circle) == ML.MAV_MISSION_ACCEPTED
    # Not armable: the pre-arm bit of SYS_STATUS goes (it takes the vehicle's next step).
    wait(gcs, "SYS_STATUS", lambda m: not m.onboard_control_sensors_health & PREARM_CHECK, 5)
    gcs.set_mode("TAKEOFF")
    assert ack(gcs, ML.MAV_CMD_DO_SET_MODE) == 0
    gcs.arducopter_arm()
    assert ack(gcs, ML.MAV_CMD_COMPONENT_ARM_DISARM) == ML.MAV_RESULT_DENIED
    wait(gcs, "STATUSTEXT", lambda m: "outside the geofence" in m.text, 2)
    corners = [(-12, -12), (-12, 12), (12, 12), (12, -12)]
    square = [fence_item(k, ML.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION, 4,
                         home.lat + int(n * deg), home.lon + int(e * east))
              for k, (n, e) in enumerate(corners)]
    assert upload_fence(gcs, square) == ML.MAV_MISSION_ACCEPTED
    ready_to_arm(gcs)
    take_off(gcs)
    start = wait(gcs, "LOCAL_POSITION_NED", lambda m: True)
    # SYS_STATUS at 20 Hz: the breach's health bit is seen while the stop lasts (about 2 s).
    gcs.mav.command_long_send(1, 1, ML.MAV_CMD_SET_MESSAGE_INTERVAL, 0,
                              ML.MAVLINK_MSG_ID_SYS_STATUS, 50_000, 0, 0, 0, 0, 0)
    assert ack(gcs, ML.MAV_CMD_SET_MESSAGE_INTERVAL) == 0
    reposition_north(gcs, home, 25)
    breach, furthest, unhealthy = None, 0.0, False
    end = time.monotonic() + 40
    while time.monotonic() < end:
        m = gcs.recv_match(type=["STATUSTEXT", "LOCAL_POSITION_NED", "SYS_STATUS"],
                           blocking=True, timeout=0.5)
        if m is None or m.get_srcComponent() != 1:
            continue
        if m.get_type() == "STATUSTEXT" and "geofence breached" in m.text:
            breach = breach or m.text
        elif m.get_type() == "LOCAL_POSITION_NED":
            furthest = max(furthest, m.x - start.x)
            if breach and abs(m.vx) < 0.2 and abs(m.vy) < 0.2:
                break
        elif m.get_type() == "SYS_STATUS":
            unhealthy |= not m.onboard_control_sensors_health & ML.MAV_SYS_STATUS_GEOFENCE
    else:
        pytest.fail(f"no breach, or not stopped: {breach}, {furthest:.1f} m")
    print(f"geofence: {breach!r}, stopped {furthest:.1f} m north of home (fence at 12 m)")
    assert breach == "failsafe: geofence breached: Hold", breach
    # Predicted (GF_PREDICT): the stop is ordered before the fence, so it is crossed by little.
    assert 8.0 < furthest < 13.5, furthest
    assert unhealthy
    gcs.set_mode("RTL")
    assert ack(gcs, ML.MAV_CMD_DO_SET_MODE) == 0
    wait(gcs, "HEARTBEAT", lambda m: not armed(m), timeout=60)
    down = wait(gcs, "LOCAL_POSITION_NED", lambda m: True)
    assert math.hypot(down.x - start.x, down.y - start.y) < 1.5


def arm_once(gcs, timeout=5):
    """One arming attempt, its answer read alone (what came before is drained, the attempts are
    paced): the COMMAND_ACK result and, when refused, the reason said in STATUSTEXT."""
    time.sleep(0.2)  # pacing only: no more than five attempts a second
    while gcs.recv_match(blocking=False) is not None:
        pass
    gcs.arducopter_arm()
    result, text = None, ""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        m = gcs.recv_match(type=["COMMAND_ACK", "STATUSTEXT"], blocking=True, timeout=0.5)
        if m is None or m.get_srcComponent() != 1:
            continue
        if m.get_type() == "COMMAND_ACK" and m.command == ML.MAV_CMD_COMPONENT_ARM_DISARM:
            result = m.result
        elif m.get_type() == "STATUSTEXT" and "arming refused" in m.text:
            text = m.text
        if result == ML.MAV_RESULT_ACCEPTED or (result is not None and text):
            return result, text
    pytest.fail(f"no answer to an arming attempt within {timeout} s: {result}, {text!r}")


def test_magnet_under_the_board_refuses_arming_until_it_is_gone(tmp_path, scenario):
    """A magnet under the board for the first 40 s (scenario `mag_disturbance`, 0.35 G up): the
    field measured at rest is 0.23 G and 20° below the horizon where the site's is 0.48 G and 63°
    (ATT_MAG_STR, ATT_MAG_INC): arming is refused naming the field (EKF2_MAG_CHK_STR), the pre-arm
    bit stays down; once the magnet is gone the check passes and the vehicle arms."""
    path = scenario('airframe = "quad_x"\nduration_s = 100000.0\n'
                    '[[events]]\nkind = "mag_disturbance"\nt_s = 0.0\n'
                    'field_ned_gauss = [0.0, 0.0, -0.35]\nduration_s = 40.0\n')
    d = Daemon(tmp_path, "udpout://127.0.0.1:{port}?bind=0", scenario=path, lockstep=True,
               speed=6)
    try:
        gcs = d.gcs
        assert gcs.wait_heartbeat(timeout=30), "no heartbeat"
        wait(gcs, "GLOBAL_POSITION_INT", lambda m: True, 30)
        # Until the estimate has converged its own reasons lead; then the magnetometer's.
        end, text = time.monotonic() + 20, ""
        while "mag field" not in text:
            assert time.monotonic() < end, f"last refusal: {text!r}"
            result, text = arm_once(gcs)
            assert result == ML.MAV_RESULT_DENIED, f"armed; the refusal before: {text!r}"
        assert "mag field 0.2" in text and "expected 0.48 G" in text, text
        status = wait(gcs, "SYS_STATUS", lambda m: True)
        assert not status.onboard_control_sensors_health & PREARM_CHECK
        # The magnet goes at 40 s of simulated time (about 13 s here).
        ready_to_arm(gcs)
        gcs.set_mode("TAKEOFF")
        assert ack(gcs, ML.MAV_CMD_DO_SET_MODE) == 0
        gcs.arducopter_arm()
        assert ack(gcs, ML.MAV_CMD_COMPONENT_ARM_DISARM) == 0
    finally:
        d.close()


def test_a_quad_that_loses_both_front_rotors_flips_and_is_disarmed(vehicle):
    """Crash detection: a quad_x in Hold at 15 m loses both front rotors
    (motors 1 and 3, injected); nothing can hold its pitch, it goes over past FD_FAIL_P (60°) and
    after FD_FAIL_R_TTRI (0.3 s) the motors are stopped: announced and disarmed."""
    gcs = vehicle
    set_param(gcs, "SYS_FAILURE_EN", int_bits(1), INT32)
    set_param(gcs, "MIS_TAKEOFF_ALT", 15.0)  # high enough to go over before the ground
    ready_to_arm(gcs)
    take_off(gcs)
    for motor in (1, 3):
        assert inject(gcs, ML.FAILURE_UNIT_SYSTEM_MOTOR, ML.FAILURE_TYPE_OFF, motor) == 0
    seen, pitch = [], 0.0
    end = time.monotonic() + 20
    while time.monotonic() < end:
        m = gcs.recv_match(type=["STATUSTEXT", "HEARTBEAT", "ATTITUDE"], blocking=True,
                           timeout=0.5)
        if m is None or m.get_srcComponent() != 1:
            continue
        if m.get_type() == "ATTITUDE":
            pitch = max(pitch, abs(math.degrees(m.pitch)))
        elif m.get_type() == "STATUSTEXT":
            seen.append(m.text)
        elif not armed(m):
            break
    else:
        pytest.fail(f"still armed: {seen}")
    # The announcement may trail the heartbeat that shows the motors stopped.
    crash = "failsafe: attitude failure (crash or flip): disarm"
    if crash not in seen:
        seen.append(wait(gcs, "STATUSTEXT", lambda m: "failsafe" in m.text, 2).text)
    assert crash in seen, seen
    assert pitch > 60, f"largest pitch seen {pitch:.0f}°"
    print(f"crash: {seen}, pitch up to {pitch:.0f}°")


def test_wind_set_at_run_time_is_flown_through(tmp_path):
    """The weather changed while flying, through the simulator's own MAVLink endpoint (sitl
    --control, ArduPilot's SIM_WIND_* names): in Hold at 2.5 m, an 8 m/s wind from the west with
    light turbulence is set and confirmed (PARAM_VALUE); the vehicle leans into it (rolls left)
    and keeps its position within 2 m (a step of wind). A speed out of range is refused, the old
    value kept."""
    d = Daemon(tmp_path, "udpout://127.0.0.1:{port}?bind=0", control=True)
    try:
        gcs = d.gcs
        assert gcs.wait_heartbeat(timeout=30), "no heartbeat"
        sim = sim_control(d.control_port)
        assert sim_param(sim, "SIM_WIND_SPD", 80.0) == 0.0, "out of range: refused"
        ready_to_arm(gcs)
        take_off(gcs)
        hold = wait(gcs, "LOCAL_POSITION_NED", lambda m: True)
        assert sim_param(sim, "SIM_WIND_DIR", 270.0) == 270.0
        assert sim_param(sim, "SIM_WIND_TURB", 3.0) == pytest.approx(3.0)
        assert sim_param(sim, "SIM_WIND_SPD", 8.0) == 8.0
        # 20 s of simulated time (about 7 s here) in the wind.
        end, rolls, off = time.monotonic() + 7, [], 0.0
        while time.monotonic() < end:
            m = gcs.recv_match(type=["ATTITUDE", "LOCAL_POSITION_NED"], blocking=True,
                               timeout=0.5)
            if m is None or m.get_srcComponent() != 1:
                continue
            if m.get_type() == "ATTITUDE":
                rolls.append(math.degrees(m.roll))
            else:
                off = max(off, math.hypot(m.x - hold.x, m.y - hold.y))
        lean = sum(rolls[len(rolls) // 2:]) / len(rolls[len(rolls) // 2:])
        print(f"wind 8 m/s from the west set at run time: roll {lean:.1f}° (second half), "
              f"largest offset {off:.2f} m")
        assert lean < -2.0, f"not leaning into the wind: {lean:.1f}°"
        assert off < 2.0, f"{off:.2f} m from the hold"
    finally:
        d.close()


if __name__ == "__main__":
    pytest.main([__file__, "-q", "-s"])
