"""Failsafes end to end (issue 7), one scenario per failsafe as they land: sitl + autopilot over
UDP at 3x real time, driven with pymavlink; every wait is on the vehicle's state with a
time-out. The state machine itself is table-tested in daemon/core/src/safety/tests.rs."""

import math
import threading
import time

import pytest
from pymavlink import mavutil

from test_ground_station import (  # noqa: F401
    INT32, ack, armed, daemon, int_bits, ready_to_arm, set_param, vehicle, wait)

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


def test_gcs_link_loss_holds_then_returns_and_lands_at_home(vehicle):
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
        gcs.set_mode("TAKEOFF")
        assert ack(gcs, ML.MAV_CMD_DO_SET_MODE) == 0
        gcs.arducopter_arm()
        assert ack(gcs, ML.MAV_CMD_COMPONENT_ARM_DISARM) == 0
        wait(gcs, "HEARTBEAT", lambda m: gcs.flightmode == "LOITER" and armed(m), timeout=30)
        # Fly 8 m north so the return has somewhere to go.
        # DO_REPOSITION: default speed, no mode change (in Hold already), no yaw.
        gcs.mav.command_int_send(1, 1, ML.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
                                 ML.MAV_CMD_DO_REPOSITION, 0, 0, -1, 0, 0, math.nan,
                                 home.lat + int(8 / 111_320 * 1e7), home.lon, 4.0)
        assert ack(gcs, ML.MAV_CMD_DO_REPOSITION) == 0
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


if __name__ == "__main__":
    pytest.main([__file__, "-q", "-s"])


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
