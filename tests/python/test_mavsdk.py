"""The vehicle as an unmodified MAVSDK-Python script (the classic gRPC API, PyPI `mavsdk-grpc`,
which ships and starts its own `mavsdk_server`) sees it: sitl + autopilot over UDP, MAVSDK on the
port the autopilot pushes to. Every wait is on a telemetry stream with a time-out."""

import mavsdk_grpc as mavsdk
import pytest
from mavsdk_grpc.param import ParamError
from mavsdk_grpc.telemetry import FlightMode, LandedState

from conftest import first, run_mavsdk_flight


async def fly(vehicle):
    drone = mavsdk.System(port=vehicle.mavsdk_server_port)
    await drone.connect(system_address=vehicle.mavsdk_url)
    try:
        await first(drone.core.connection_state(), lambda s: s.is_connected, 30)
        # Health: gyro, accelerometer, magnetometer, local and global position (SYS_STATUS), home
        # (HOME_POSITION), armable (PREARM_CHECK).
        await first(drone.telemetry.health_all_ok(), bool, 60)
        position = await first(drone.telemetry.position(), lambda p: True, 5)
        assert abs(position.latitude_deg - 47.397742) < 1e-3, position
        assert abs(position.relative_altitude_m) < 0.5, position
        home = await first(drone.telemetry.home(), lambda h: True, 5)
        assert abs(home.longitude_deg - 8.545594) < 1e-3, home
        attitude = await first(drone.telemetry.attitude_euler(), lambda a: True, 5)
        assert abs(attitude.roll_deg) < 5 and abs(attitude.pitch_deg) < 5, attitude
        battery = await first(drone.telemetry.battery(), lambda b: True, 5)
        assert battery.voltage_v > 10, battery
        assert await first(drone.telemetry.flight_mode(), lambda m: True, 5) == FlightMode.HOLD
        assert await first(drone.telemetry.in_air(), lambda a: True, 5) is False
        landed = await first(drone.telemetry.landed_state(), lambda s: True, 5)
        assert landed == LandedState.ON_GROUND

        # Parameters, with PX4's names and types.
        assert await drone.param.get_param_float("MIS_TAKEOFF_ALT") == 2.5
        assert await drone.param.get_param_int("ATT_ALIGN_N") == 250
        await drone.param.set_param_float("MPC_XY_CRUISE", 4.0)
        assert await drone.param.get_param_float("MPC_XY_CRUISE") == 4.0
        with pytest.raises(ParamError):
            await drone.param.set_param_float("MPC_XY_CRUISE", 500.0)
        with pytest.raises(ParamError):
            await drone.param.get_param_float("ATT_ALIGN_N")  # an INT32
        await drone.action.set_takeoff_altitude(3.0)
        assert await drone.action.get_takeoff_altitude() == 3.0
        await drone.action.set_return_to_launch_altitude(5.0)
        assert await drone.action.get_return_to_launch_altitude() == 5.0

        # Take off to 3 m, hold, return (climb to 5 m, land at home), disarmed.
        await drone.action.arm()
        await drone.action.takeoff()
        await first(drone.telemetry.in_air(), bool, 15)
        await first(drone.telemetry.flight_mode(), lambda m: m == FlightMode.HOLD, 30)
        p = await first(drone.telemetry.position(), lambda p: True, 5)
        assert 2.6 < p.relative_altitude_m < 3.4, p
        await drone.action.hold()
        await drone.action.return_to_launch()
        await first(drone.telemetry.flight_mode(),
                    lambda m: m == FlightMode.RETURN_TO_LAUNCH, 5)
        await first(drone.telemetry.position(), lambda p: p.relative_altitude_m > 4.6, 30)
        await first(drone.telemetry.armed(), lambda a: not a, 60)
        landed = await first(drone.telemetry.landed_state(), lambda s: True, 5)
        assert landed == LandedState.ON_GROUND

        # Arm (once ready again: at rest on the ground long enough for the gyro check), take
        # off again, land where it is.
        await first(drone.telemetry.health(), lambda h: h.is_armable, 30)
        await drone.action.arm()
        await drone.action.takeoff()
        await first(drone.telemetry.position(), lambda p: p.relative_altitude_m > 2.0, 30)
        await drone.action.land()
        await first(drone.telemetry.flight_mode(), lambda m: m == FlightMode.LAND, 5)
        await first(drone.telemetry.armed(), lambda a: not a, 60)

    finally:
        drone._stop_mavsdk_server()


def test_mavsdk_connects_reads_telemetry_and_parameters_and_flies(make_vehicle):
    run_mavsdk_flight(make_vehicle, fly)
