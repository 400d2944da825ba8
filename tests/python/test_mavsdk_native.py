"""The vehicle as a script on MAVSDK's native Python binding sees it (PyPI `mavsdk` 4.x: ctypes over
the C library, no `mavsdk_server`; a different API from the gRPC one of test_mavsdk.py): sitl +
autopilot over UDP, MAVSDK on the port the autopilot pushes to. Every wait is on a telemetry stream
with a time-out."""

import asyncio

from mavsdk.asyncio.plugins.action import ActionAsync
from mavsdk.asyncio.plugins.manual_control import ManualControlAsync
from mavsdk.asyncio.plugins.param import ParamAsync
from mavsdk.asyncio.plugins.telemetry import TelemetryAsync
from mavsdk.autopilot import Autopilot
from mavsdk.plugins.telemetry import FlightMode, LandedState
from mavsdk.vehicle import Vehicle

from conftest import first, mavsdk_autopilot, run_mavsdk_flight


async def joystick(manual, sticks):
    """MANUAL_CONTROL at 20 Hz through MAVSDK, from the current value of sticks[0]."""
    while True:
        await manual.set_manual_control_input(*sticks[0])
        await asyncio.sleep(0.05)  # the stream's period, not a wait for the vehicle


async def fly(vehicle):
    async with mavsdk_autopilot(vehicle.mavsdk_url) as system:
        # Component 1, autopilot PX4, a multicopter from the heartbeat's type.
        assert await system.autopilot_type() == Autopilot.PX4
        assert await system.vehicle_type() == Vehicle.MULTICOPTER
        telemetry, action = TelemetryAsync(system), ActionAsync(system)
        param, manual = ParamAsync(system), ManualControlAsync(system)

        await first(telemetry.subscribe_health_all_ok(), bool, 60)
        home = await first(telemetry.subscribe_home(), lambda h: True, 5)
        assert abs(home.latitude_deg - 47.397742) < 1e-3, home
        assert await first(telemetry.subscribe_flight_mode(), lambda m: True, 5) == FlightMode.HOLD
        landed = await first(telemetry.subscribe_landed_state(), lambda s: True, 5)
        assert landed == LandedState.ON_GROUND
        assert await param.get_param_float("MIS_TAKEOFF_ALT") == 2.5
        await param.set_param_float("MPC_XY_CRUISE", 4.0)
        assert await param.get_param_float("MPC_XY_CRUISE") == 4.0

        # Take off to 2.5 m; Hold after the climb.
        await action.arm()
        await action.takeoff()
        await first(telemetry.subscribe_in_air(), bool, 15)
        await first(telemetry.subscribe_flight_mode(), lambda m: m == FlightMode.HOLD, 30)

        # A joystick through MAVSDK's ManualControl plugin: position control, forward stick.
        sticks = [(0.0, 0.0, 0.5, 0.0)]  # x forward, y right, z throttle 0..1, r yaw
        stream = asyncio.create_task(joystick(manual, sticks))
        try:
            await first(telemetry.subscribe_rc_status(), lambda r: r.is_available, 10)
            await manual.start_position_control()
            await first(telemetry.subscribe_flight_mode(), lambda m: m == FlightMode.POSCTL, 5)
            sticks[0] = (0.6, 0.0, 0.5, 0.0)
            await first(telemetry.subscribe_velocity_ned(),
                        lambda v: (v.north_m_s ** 2 + v.east_m_s ** 2) ** 0.5 > 2.0, 20)
            sticks[0] = (0.0, 0.0, 0.5, 0.0)
            await first(telemetry.subscribe_velocity_ned(),
                        lambda v: (v.north_m_s ** 2 + v.east_m_s ** 2) ** 0.5 < 0.3, 20)
            await action.land()
            await first(telemetry.subscribe_flight_mode(), lambda m: m == FlightMode.LAND, 5)
            await first(telemetry.subscribe_armed(), lambda a: not a, 60)
        finally:
            stream.cancel()


def test_native_mavsdk_finds_the_autopilot_flies_and_takes_a_joystick(make_vehicle):
    run_mavsdk_flight(make_vehicle, fly)
