"""Offboard control as companion-computer scripts drive it: by hand with pymavlink (set-points
streamed at 20 Hz, SET_POSITION_TARGET_LOCAL_NED and SET_ATTITUDE_TARGET; OFFBOARD refused without
them) and with MAVSDK's native Offboard plugin (which streams at 20 Hz itself): position, velocity
and attitude set-points flown, and the failsafe when the stream stops. sitl + autopilot over UDP
in lockstep at up to 6x real time; every wait is on the vehicle's state with a time-out."""

import json
import math
import threading
import time

import pytest
from mavsdk.asyncio.plugins.action import ActionAsync
from mavsdk.asyncio.plugins.mavlink_direct import MavlinkDirectAsync
from mavsdk.asyncio.plugins.offboard import OffboardAsync
from mavsdk.asyncio.plugins.telemetry import TelemetryAsync
from mavsdk.plugins.offboard import Attitude, PositionNedYaw, VelocityNedYaw
from mavsdk.plugins.telemetry import FlightMode
from pymavlink import mavutil

from conftest import first, land_and_disarm, mavsdk_autopilot, run_mavsdk_flight
from test_ground_station import (  # noqa: F401 (the fixtures)
    ack, armed, daemon, fast_vehicle, ready_to_arm, vehicle, wait)

ML = mavutil.mavlink
POSITION_ONLY = 0x09F8  # x, y, z and yaw used (MAVSDK's set_position_ned)
VELOCITY_ONLY = 0x09C7  # vx, vy, vz and yaw used (MAVSDK's set_velocity_ned)


class Stream:
    """A set-point stream from a thread at 20 Hz: `send(mav)` of the current set-point."""

    def __init__(self, gcs, send):
        self.gcs, self.send, self.running = gcs, send, True
        self.lock, self.sent = threading.Condition(), 0
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self):
        while self.running:
            with self.lock:
                self.send(self.gcs.mav)
                self.sent += 1
                self.lock.notify_all()
            time.sleep(0.05)  # the stream's period, not a wait for the vehicle

    def set(self, send):
        """The next set-point; returns once it has been sent."""
        with self.lock:
            self.send, n = send, self.sent
            assert self.lock.wait_for(lambda: self.sent > n, timeout=2)

    def stop(self):
        self.running = False
        self.thread.join()


def position(n, e, d, yaw=0.0):
    return lambda mav: mav.set_position_target_local_ned_send(
        0, 1, 1, ML.MAV_FRAME_LOCAL_NED, POSITION_ONLY, n, e, d, 0, 0, 0, 0, 0, 0, yaw, 0)


def velocity(vn, ve, vd, yaw=0.0):
    return lambda mav: mav.set_position_target_local_ned_send(
        0, 1, 1, ML.MAV_FRAME_LOCAL_NED, VELOCITY_ONLY, 0, 0, 0, vn, ve, vd, 0, 0, 0, yaw, 0)


def attitude(roll_deg, thrust):
    r = math.radians(roll_deg) / 2
    q = [math.cos(r), math.sin(r), 0.0, 0.0]
    rates_ignored = 0x07
    return lambda mav: mav.set_attitude_target_send(0, 1, 1, rates_ignored, q, 0, 0, 0, thrust)


def near(m, n, e, d, tol):
    return math.dist((m.x, m.y, m.z), (n, e, d)) < tol


def test_offboard_flies_position_velocity_and_attitude_set_points_and_fails_safe(
        fast_vehicle):
    vehicle = fast_vehicle
    gcs = vehicle
    ready_to_arm(gcs)
    offboard = (ML.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 6, 0)  # PX4 main mode 6
    gcs.mav.command_long_send(1, 1, ML.MAV_CMD_DO_SET_MODE, 0, *offboard, 0, 0, 0, 0)
    assert ack(gcs, ML.MAV_CMD_DO_SET_MODE) == ML.MAV_RESULT_DENIED
    wait(gcs, "STATUSTEXT", lambda m: "no set-point stream" in m.text, 2)
    home = wait(gcs, "LOCAL_POSITION_NED", lambda m: True)
    stream = Stream(gcs, position(home.x, home.y, home.z))
    try:
        stream.set(position(home.x, home.y, home.z))
        gcs.mav.command_long_send(1, 1, ML.MAV_CMD_DO_SET_MODE, 0, *offboard, 0, 0, 0, 0)
        assert ack(gcs, ML.MAV_CMD_DO_SET_MODE) == 0
        wait(gcs, "HEARTBEAT", lambda m: gcs.flightmode == "OFFBOARD", timeout=3)
        gcs.arducopter_arm()
        assert ack(gcs, ML.MAV_CMD_COMPONENT_ARM_DISARM) == 0
        # Up 5 m, then a 10 m square: each corner within 0.3 m.
        up = home.z - 5.0
        for n, e in [(0, 0), (10, 0), (10, 10), (0, 10), (0, 0)]:
            n, e = home.x + n, home.y + e
            stream.set(position(n, e, up))
            wait(gcs, "LOCAL_POSITION_NED",
                 lambda m: near(m, n, e, up, 0.3) and math.hypot(m.vx, m.vy) < 0.2, 40)
        # Velocity: 2 m/s east.
        stream.set(velocity(0.0, 2.0, 0.0))
        wait(gcs, "LOCAL_POSITION_NED", lambda m: abs(m.vy - 2.0) < 0.2 and abs(m.vx) < 0.2, 15)
        stream.set(velocity(0.0, 0.0, 0.0))
        wait(gcs, "LOCAL_POSITION_NED", lambda m: math.hypot(m.vx, m.vy) < 0.2, 15)
        # Attitude: 10° of roll at the thrust that holds the altitude's worth (ATTITUDE_TARGET
        # echoes what is flown).
        gcs.mav.command_long_send(1, 1, ML.MAV_CMD_SET_MESSAGE_INTERVAL, 0,
                                  ML.MAVLINK_MSG_ID_ATTITUDE_TARGET, 50_000, 0, 0, 0, 0, 0)
        assert ack(gcs, ML.MAV_CMD_SET_MESSAGE_INTERVAL) == 0
        hover = wait(gcs, "ATTITUDE_TARGET", lambda m: True).thrust
        stream.set(attitude(10.0, hover / math.cos(math.radians(10))))
        wait(gcs, "ATTITUDE", lambda m: abs(math.degrees(m.roll) - 10.0) < 1.5, 10)
        target = wait(gcs, "ATTITUDE_TARGET", lambda m: True)
        assert abs(math.degrees(2 * math.asin(target.q[1])) - 10.0) < 0.5, target.q
        stream.set(position(home.x, home.y + 10, up))
        wait(gcs, "ATTITUDE", lambda m: abs(m.roll) < math.radians(3), 10)
    finally:
        stream.stop()
    # The stream stops: COM_OBL_RC_ACT 0 (Position) without a joystick is Hold.
    wait(gcs, "STATUSTEXT", lambda m: "offboard set-points lost" in m.text, 5)
    wait(gcs, "HEARTBEAT", lambda m: gcs.flightmode == "LOITER" and armed(m), timeout=3)
    gcs.set_mode("LAND")
    assert ack(gcs, ML.MAV_CMD_DO_SET_MODE) == 0
    wait(gcs, "HEARTBEAT", lambda m: not armed(m), timeout=60)


async def hover_thrust(system):
    """The collective thrust (fraction) the vehicle flies now, from the ATTITUDE_TARGET echo
    (streamed at 2 Hz; read through MAVSDK's MavlinkDirect plugin, as a script would)."""
    direct = MavlinkDirectAsync(system)
    target = await first(direct.subscribe_message("ATTITUDE_TARGET"), lambda m: True, 5)
    return json.loads(target.fields_json)["thrust"]


async def fly_offboard(vehicle):
    async with mavsdk_autopilot(vehicle.mavsdk_url) as system:
        telemetry, action = TelemetryAsync(system), ActionAsync(system)
        offboard = OffboardAsync(system)
        await first(telemetry.subscribe_health_all_ok(), bool, 60)
        await telemetry.set_rate_position_velocity_ned(20.0)
        ned = telemetry.subscribe_position_velocity_ned()
        here = (await first(ned, lambda p: True, 5)).position

        async def settle_at(n, e, d, tol, timeout):
            def still_there(p):
                off = math.dist((p.position.north_m, p.position.east_m, p.position.down_m),
                                (n, e, d))
                return off < tol and math.hypot(p.velocity.north_m_s, p.velocity.east_m_s) < 0.2
            await first(ned, still_there, timeout)

        # Offboard entered with a set-point already streaming (MAVSDK refuses start() without).
        await offboard.set_position_ned(PositionNedYaw(here.north_m, here.east_m, here.down_m, 0.0))
        await offboard.start()
        await first(telemetry.subscribe_flight_mode(), lambda m: m == FlightMode.OFFBOARD, 5)
        await action.arm()
        # Up 5 m, then a 10 m square: each corner within 0.3 m, at rest.
        up = here.down_m - 5.0
        for n, e in [(0, 0), (10, 0), (10, 10), (0, 10), (0, 0)]:
            n, e = here.north_m + n, here.east_m + e
            await offboard.set_position_ned(PositionNedYaw(n, e, up, 0.0))
            await settle_at(n, e, up, 0.3, 40)
        # Velocity: 2 m/s east, then stop.
        await offboard.set_velocity_ned(VelocityNedYaw(0.0, 2.0, 0.0, 0.0))
        await first(ned, lambda p: abs(p.velocity.east_m_s - 2.0) < 0.2
                    and abs(p.velocity.north_m_s) < 0.2, 15)
        await offboard.set_velocity_ned(VelocityNedYaw(0.0, 0.0, 0.0, 0.0))
        await first(ned, lambda p: math.hypot(p.velocity.north_m_s, p.velocity.east_m_s) < 0.2, 15)
        # Attitude: 10° of roll, the hover thrust tilted so the altitude holds roughly.
        thrust = await hover_thrust(system)
        assert 0.1 < thrust < 0.9, thrust
        await offboard.set_attitude(Attitude(10.0, 0.0, 0.0, thrust / math.cos(math.radians(10))))
        euler = telemetry.subscribe_attitude_euler()
        await first(euler, lambda a: abs(a.roll_deg - 10.0) < 1.5 and abs(a.pitch_deg) < 1.5, 10)
        back = await first(ned, lambda p: True, 5)
        assert abs(back.position.down_m - up) < 2.0, back
        await offboard.set_position_ned(PositionNedYaw(back.position.north_m, back.position.east_m,
                                                       up, 0.0))
        await first(euler, lambda a: abs(a.roll_deg) < 3.0, 10)
        # The script stops streaming without leaving OFFBOARD (its offboard part gone): after
        # COM_OF_LOSS_T the failsafe, Hold (COM_OBL_RC_ACT 0 without a joystick).
        texts = telemetry.subscribe_status_text()
        offboard.destroy()
        await first(texts, lambda t: "offboard set-points lost" in t.text, 5)
        await first(telemetry.subscribe_flight_mode(), lambda m: m == FlightMode.HOLD, 3)
        assert await first(telemetry.subscribe_armed(), lambda a: True, 3)
        await land_and_disarm(action, telemetry)


def test_mavsdk_offboard_flies_a_square_velocity_and_attitude_and_fails_safe(make_vehicle):
    run_mavsdk_flight(make_vehicle, fly_offboard)


if __name__ == "__main__":
    pytest.main([__file__, "-q", "-s"])
