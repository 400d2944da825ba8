"""The ten-line test of docs/python.md: MAVSDK-Python arms a fresh vehicle, takes off to 5 m and
checks the altitude, on the `vehicle` fixture of the autopilot_sitl pytest plugin."""
import asyncio

import mavsdk_grpc as mavsdk


def test_takeoff_reaches_5_m(vehicle):
    async def fly():
        drone = mavsdk.System(port=vehicle.mavsdk_server_port)
        await drone.connect(system_address=vehicle.mavsdk_url)
        async for state in drone.core.connection_state():
            if state.is_connected:
                break
        await drone.action.set_takeoff_altitude(5.0)
        await drone.action.arm()
        await drone.action.takeoff()
        async for position in drone.telemetry.position():
            if position.relative_altitude_m > 4.8:
                return

    asyncio.run(asyncio.wait_for(fly(), timeout=60))
    assert abs(vehicle.truth().height_m - 5.0) < 0.5
