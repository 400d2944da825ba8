"""The events interface with MAVSDK's events plugin (pinned, unmodified), which fetches the
events metadata through component metadata and MAVLink FTP and reads EVENT,
CURRENT_EVENT_SEQUENCE and, for any it missed, REQUEST_EVENT: an arming refusal names its
check, a mode change its mode, arming and disarming are told, each with the words the
STATUSTEXTs say."""

import asyncio

import mavsdk_grpc as mavsdk
from mavsdk_grpc.action import ActionError

from conftest import first
from test_ground_station import daemon  # noqa: F401 (the fixture)
from test_mavsdk import free_tcp_port


def test_mavsdk_events_show_arming_refusals_modes_and_arming(daemon):
    async def session():
        drone = mavsdk.System(port=free_tcp_port())
        await drone.connect(system_address=f"udpin://127.0.0.1:{daemon.gcs_port}")
        await first(drone.core.connection_state(), lambda s: s.is_connected, 30)
        seen = []

        async def collect():
            async for e in drone.events.events():
                seen.append(e)

        task = asyncio.ensure_future(collect())
        try:
            await first(drone.telemetry.health_all_ok(), bool, 60)
            # Land on the ground: no mode to start in; the refusal names its check.
            await drone.action.land()
            await wait_for(seen, lambda e: e.event_name == "mode_changed", 10)
            try:
                await drone.action.arm()
                raise AssertionError("armed in Land")
            except ActionError:
                pass
            await wait_for(seen, lambda e: e.event_name == "arming_denied", 10)
            await drone.action.hold()
            await drone.action.arm()
            await wait_for(seen, lambda e: e.event_name == "armed", 10)
            await drone.action.disarm()
            await wait_for(seen, lambda e: e.event_name == "disarmed", 10)
        finally:
            task.cancel()
        return seen

    seen = asyncio.run(session())
    denied = next(e for e in seen if e.event_name == "arming_denied")
    assert denied.message == "Arming denied: not in a mode to start in", denied.message
    modes = [e.message for e in seen if e.event_name == "mode_changed"]
    assert modes[:2] == ["Flight mode: LAND", "Flight mode: LOITER"], modes
    assert all(e.event_namespace == "autopilot" and e.compid == 1 for e in seen), seen
    print("\nevents seen:", [e.message for e in seen])


async def wait_for(seen, condition, timeout):
    """Until an event for which `condition` holds has been collected (each arrival checked)."""
    end = asyncio.get_running_loop().time() + timeout
    while not any(condition(e) for e in seen):
        assert asyncio.get_running_loop().time() < end, [e.message for e in seen]
        await asyncio.sleep(0.05)  # the collector runs meanwhile; checked at each wake
