"""Offboard control as a companion-computer script drives it with pymavlink: set-points streamed at
20 Hz (SET_POSITION_TARGET_LOCAL_NED, SET_ATTITUDE_TARGET), OFFBOARD refused without them, flown
with them, and the failsafe when they stop. sitl + autopilot over UDP at 3x real time; every wait
is on the vehicle's state with a time-out."""

import math
import threading
import time

from pymavlink import mavutil

from test_ground_station import ack, armed, daemon, ready_to_arm, vehicle, wait  # noqa: F401

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


def test_offboard_flies_position_velocity_and_attitude_set_points_and_fails_safe(vehicle):
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
