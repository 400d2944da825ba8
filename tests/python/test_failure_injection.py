"""Fault injection end to end: MAVSDK's Failure plugin sends MAV_CMD_INJECT_FAILURE; a
hexarotor in Hold at 10 m loses motor 1 and must find out by itself (the autopilot's flight
core is not told), say so, and keep its altitude and position; a quad that loses motor 1 says
it flies on three rotors, spinning, lands and disarms. sitl + autopilot over UDP at 3x real
time; every wait is on the vehicle's state with a time-out."""

import asyncio
import math

import pytest
from mavsdk.asyncio.plugins.action import ActionAsync
from mavsdk.asyncio.plugins.failure import FailureAsync
from mavsdk.asyncio.plugins.param import ParamAsync
from mavsdk.asyncio.plugins.telemetry import TelemetryAsync
from mavsdk.plugins.failure import FailureError, FailureType, FailureUnit
from mavsdk.plugins.telemetry import FlightMode

from conftest import first, land_and_disarm, mavsdk_autopilot, run_mavsdk_flight


async def collect(stream, into):
    async for item in stream:
        into.append(item)


async def hexa_loses_a_motor(vehicle):
    async with mavsdk_autopilot(vehicle.mavsdk_url) as system:
        telemetry, action = TelemetryAsync(system), ActionAsync(system)
        param, failure = ParamAsync(system), FailureAsync(system)
        texts = []
        listener = asyncio.create_task(collect(telemetry.subscribe_status_text(), texts))
        await first(telemetry.subscribe_health_all_ok(), bool, 60)

        # Refused until SYS_FAILURE_EN is 1, as PX4 (the plugin reads the parameter when it
        # starts and says DISABLED; the autopilot refuses the command too); an airspeed sensor is
        # not ours to fail.
        with pytest.raises(FailureError, match="DISABLED"):
            await failure.inject(FailureUnit.SYSTEM_MOTOR, FailureType.OFF, 1)
        await param.set_param_int("SYS_FAILURE_EN", 1)
        failure.destroy()
        failure = FailureAsync(system)  # reads the parameter again
        with pytest.raises(FailureError, match="UNSUPPORTED"):
            await failure.inject(FailureUnit.SENSOR_AIRSPEED, FailureType.OFF, 0)

        await action.set_takeoff_altitude(10.0)
        await action.arm()
        await action.takeoff()
        await first(telemetry.subscribe_flight_mode(), lambda m: m == FlightMode.HOLD, 40)
        await first(telemetry.subscribe_position(), lambda p: p.relative_altitude_m > 9.5, 10)
        await asyncio.sleep(1.0)  # let the climb's last overshoot settle (3 s of flight)
        before = await first(telemetry.subscribe_position_velocity_ned(), lambda p: True, 5)

        await failure.inject(FailureUnit.SYSTEM_MOTOR, FailureType.OFF, 1)
        track = []
        watcher = asyncio.create_task(
            collect(telemetry.subscribe_position_velocity_ned(), track))
        await first(telemetry.subscribe_status_text(),
                    lambda t: "motor 1 failed" in t.text, 5)
        await asyncio.sleep(4.0)  # 12 s of flight on five rotors, watched
        watcher.cancel()
        assert await first(telemetry.subscribe_flight_mode(), lambda m: True, 5) == FlightMode.HOLD
        b = before.position
        drop = max(p.position.down_m - b.down_m for p in track)
        away = max(math.hypot(p.position.north_m - b.north_m, p.position.east_m - b.east_m)
                   for p in track)
        print(f"hexa_x, motor 1 cut in Hold at 10 m: lost {drop:.2f} m of altitude, "
              f"moved {away:.2f} m (estimate)")
        assert drop <= 1.0 and away <= 2.0, (drop, away)
        listener.cancel()
        said = [t.text for t in texts]
        assert "failsafe: motor failure" in said or any("motor failure" in s for s in said), said

        await land_and_disarm(action, telemetry)


async def quad_loses_a_motor(vehicle):
    async with mavsdk_autopilot(vehicle.mavsdk_url) as system:
        telemetry, action = TelemetryAsync(system), ActionAsync(system)
        param, failure = ParamAsync(system), FailureAsync(system)
        await first(telemetry.subscribe_health_all_ok(), bool, 60)
        await param.set_param_int("SYS_FAILURE_EN", 1)
        failure.destroy()
        failure = FailureAsync(system)
        await action.set_takeoff_altitude(10.0)
        await action.arm()
        await action.takeoff()
        await first(telemetry.subscribe_flight_mode(), lambda m: m == FlightMode.HOLD, 40)
        await first(telemetry.subscribe_position(), lambda p: p.relative_altitude_m > 9.5, 10)
        await asyncio.sleep(1.0)
        before = await first(telemetry.subscribe_position_velocity_ned(), lambda p: True, 5)

        texts = []
        listener = asyncio.create_task(collect(telemetry.subscribe_status_text(), texts))
        track = []
        watcher = asyncio.create_task(
            collect(telemetry.subscribe_position_velocity_ned(), track))
        await failure.inject(FailureUnit.SYSTEM_MOTOR, FailureType.OFF, 1)
        said = await first(telemetry.subscribe_status_text(),
                           lambda t: "motor 1 failed" in t.text, 5)
        assert said.text == "motor 1 failed: flying on three rotors, spinning", said.text
        # The failsafe lands it (COM_ACT_FAIL_ACT left at its warning: a spinning quad lands).
        await first(telemetry.subscribe_flight_mode(), lambda m: m == FlightMode.LAND, 5)
        await first(telemetry.subscribe_armed(), lambda armed: not armed, 40)
        watcher.cancel()
        listener.cancel()
        b = before.position
        away = max(math.hypot(p.position.north_m - b.north_m, p.position.east_m - b.east_m)
                   for p in track)
        end = track[-1].position
        print(f"quad_x, motor 1 cut in Hold at 10 m: {len(track)} positions, away at most "
              f"{away:.2f} m, landed {math.hypot(end.north_m - b.north_m, end.east_m - b.east_m):.2f} m "
              f"from the cut (estimate); said: {[t.text for t in texts]}")
        assert away <= 4.0, away
        assert "failsafe: motor failure: Land" in [t.text for t in texts], texts
        assert not await first(telemetry.subscribe_in_air(), lambda a: True, 5)


def test_a_quad_that_loses_a_motor_says_so_spins_on_three_and_lands(make_vehicle):
    run_mavsdk_flight(make_vehicle, quad_loses_a_motor, airframe="quad_x")


def test_motor_cut_in_hold_is_found_and_flown_through(make_vehicle):
    run_mavsdk_flight(make_vehicle, hexa_loses_a_motor, airframe="hexa_x")
