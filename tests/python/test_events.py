"""The events interface with MAVSDK's events plugin (pinned, unmodified), which fetches the
events metadata through component metadata and MAVLink FTP and reads EVENT and
CURRENT_EVENT_SEQUENCE: an arming refusal names its check, a mode change its mode, arming and
disarming are told, each with the words the STATUSTEXTs say, across the sequence's wrap from
65535 to 0. REQUEST_EVENT with pymavlink: an event sent again, an old one refused to the
requester."""

import asyncio
import struct

import mavsdk_grpc as mavsdk
from mavsdk_grpc.action import ActionError
from pymavlink.generator.mavcrc import x25crc

from pymavlink import mavutil

from conftest import first, receive
from test_ground_station import daemon, ready_to_arm  # noqa: F401 (the fixture)
from conftest import free_tcp_port


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
            # (Each change waited for: a mode held for less than a telemetry update is not
            # seen, so not told.)
            await wait_for(seen, lambda e: len(seen) >= 3, 10)
            # Back and forth on the ground: the sequence (from 65526) wraps past 65535.
            for k in range(3):
                await drone.action.land()
                await wait_for(seen, lambda e, n=4 + 2 * k: len(seen) >= n, 10)
                await drone.action.hold()
                await wait_for(seen, lambda e, n=5 + 2 * k: len(seen) >= n, 10)
            await drone.action.arm()
            await wait_for(seen, lambda e: e.event_name == "armed", 10)
            await drone.action.disarm()
            await wait_for(seen, lambda e: e.event_name == "disarmed", 10)
        finally:
            task.cancel()
            drone._stop_mavsdk_server()
        return seen

    seen = asyncio.run(session())
    denied = next(e for e in seen if e.event_name == "arming_denied")
    assert denied.message == "Arming denied: not in a mode to start in", denied.message
    modes = [e.message for e in seen if e.event_name == "mode_changed"]
    assert modes == ["Flight mode: LAND", "Flight mode: LOITER"] * 4, modes
    assert [e.event_name for e in seen][-2:] == ["armed", "disarmed"], seen
    assert all(e.event_namespace == "autopilot" and e.compid == 1 for e in seen), seen
    print("\nevents seen:", [e.message for e in seen])


async def wait_for(seen, condition, timeout):
    """Until an event for which `condition` holds has been collected (each arrival checked)."""
    end = asyncio.get_running_loop().time() + timeout
    while not any(condition(e) for e in seen):
        assert asyncio.get_running_loop().time() < end, [e.message for e in seen]
        await asyncio.sleep(0.05)  # the collector runs meanwhile; checked at each wake


def test_a_missed_event_is_sent_again_and_an_old_one_refused_to_the_requester(daemon):
    """REQUEST_EVENT, as a receiver sends it for a gap: the event again, with its sequence;
    for one no longer kept, RESPONSE_EVENT_ERROR addressed to the requester. (pymavlink's
    dialect does not know these messages: their payloads are read as the spec lays them out.)"""
    gcs = daemon.gcs
    ready_to_arm(gcs)  # the vehicle's state is out: a change from it is an event
    gcs.mav.command_long_send(1, 1, mavutil.mavlink.MAV_CMD_NAV_LAND, 0, 0, 0, 0, 0, 0, 0, 0)
    event, _ = receive(gcs, "UNKNOWN_410", lambda m: True, 5)
    assert event is not None, "no EVENT"
    seq = struct.unpack_from("<H", payload(event, 53), 8)[0]
    request_event(gcs, seq)
    again, _ = receive(gcs, "UNKNOWN_410",
                       lambda m: struct.unpack_from("<H", payload(m, 53), 8)[0] == seq, 2)
    assert again is not None and payload(again, 53) == payload(event, 53)
    old = (seq - 1000) % 65536
    request_event(gcs, old)
    error, _ = receive(gcs, "UNKNOWN_413", lambda m: True, 2)
    assert error is not None, "no RESPONSE_EVENT_ERROR"
    sequence, _oldest, system, component, reason = struct.unpack("<HHBBB", payload(error, 7))
    assert (sequence, system, component, reason) == (old, 255, gcs.source_component, 0)


def payload(m, length):
    """The payload of a message the dialect does not know, its trailing zeros restored."""
    frame = bytes(m.data)
    return frame[10:10 + frame[1]] + bytes(length - frame[1])


def request_event(gcs, seq):
    """REQUEST_EVENT (412) for `seq` alone, framed by hand (MAVLink 2, its CRC extra 33): the
    dialect pymavlink 2.4.50 carries lacks it."""
    body = struct.pack("<HHBB", seq, seq, 1, 1)
    n = gcs.mav.seq
    gcs.mav.seq = (n + 1) % 256
    header = bytes([0xFD, len(body), 0, 0, n, gcs.mav.srcSystem, gcs.mav.srcComponent,
                    412 & 0xFF, 412 >> 8, 0])
    crc = x25crc(header[1:] + body)
    crc.accumulate(bytes([33]))
    gcs.write(header + body + struct.pack("<H", crc.crc))
