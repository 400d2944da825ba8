"""MAVSDK-Python's example `takeoff_and_land.py` (github.com/mavlink/MAVSDK-Python, examples/),
its calls in its order, as a test on the plugin's `vehicle`: wait for the connection and for a
global position and home, arm, take off, hover, land; then check what the example only prints,
from the simulator's truth and the flight summary."""
import asyncio

import mavsdk_grpc as mavsdk


async def takeoff_and_land(drone, address):
    await drone.connect(system_address=address)
    async for state in drone.core.connection_state():
        if state.is_connected:
            break
    async for health in drone.telemetry.health():
        if health.is_global_position_ok and health.is_home_position_ok:
            break
    await drone.action.arm()
    await drone.action.takeoff()
    await asyncio.sleep(10)
    await drone.action.land()
    async for in_air in drone.telemetry.in_air():
        if not in_air:
            break


def test_takeoff_and_land(vehicle):
    drone = mavsdk.System(port=vehicle.mavsdk_server_port)
    asyncio.run(asyncio.wait_for(takeoff_and_land(drone, vehicle.mavsdk_url), timeout=120))
    truth = vehicle.truth()
    assert truth.height_m < 0.2, truth
    summary = vehicle.stop()
    # MAVSDK's default take-off altitude is the vehicle's MIS_TAKEOFF_ALT (2.5 m).
    assert 2.0 < float(summary["max_alt_m"]) < 3.5, summary
    assert float(summary["touchdown_m_s"]) < 1.0, summary
