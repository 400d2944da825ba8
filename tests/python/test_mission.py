"""Missions end to end (and MAVSDK's goto_location): uploaded, downloaded and flown, by MAVSDK's native binding (its Mission
plugin, as a user script would) and by hand with pymavlink (the protocol message by message).
sitl + autopilot over UDP in lockstep at up to 6x real time (the flights' times are the
simulator's); every wait is on the vehicle's state with a time-out."""

import asyncio
import math
import time

import pytest
from mavsdk.asyncio.plugins.action import ActionAsync
from mavsdk.asyncio.plugins.mission import MissionAsync
from mavsdk.asyncio.plugins.param import ParamAsync
from mavsdk.asyncio.plugins.telemetry import TelemetryAsync
from mavsdk.plugins.mission import MissionItem, MissionPlan
from mavsdk.plugins.telemetry import FlightMode
from pymavlink import mavutil

from conftest import Daemon, first, land_and_disarm, mavsdk_autopilot, run_mavsdk_flight
from test_ground_station import (  # noqa: F401 (the fixtures)
    ack, daemon, fast_vehicle, ready_to_arm, vehicle, wait)

ML = mavutil.mavlink
HOME = (47.397742, 8.545594)
M_PER_DEG_LAT = 111_320.0


def offset(north_m, east_m):
    """Latitude and longitude (deg) `north_m`, `east_m` from home (a flat-Earth step: metres)."""
    lat = HOME[0] + north_m / M_PER_DEG_LAT
    lon = HOME[1] + east_m / (M_PER_DEG_LAT * math.cos(math.radians(HOME[0])))
    return lat, lon


def horizontal_m(lat1, lon1, lat2, lon2):
    dn = (lat2 - lat1) * M_PER_DEG_LAT
    de = (lon2 - lon1) * M_PER_DEG_LAT * math.cos(math.radians(lat1))
    return math.hypot(dn, de)


def waypoint(north_m, east_m, alt_m, action=MissionItem.VehicleAction.NONE):
    lat, lon = offset(north_m, east_m)
    return MissionItem(
        latitude_deg=lat, longitude_deg=lon, relative_altitude_m=alt_m, speed_m_s=5.0,
        is_fly_through=False, acceptance_radius_m=1.0, yaw_deg=float("nan"),
        # No hold (MAVSDK gives a hold of 0 back as NaN).
        loiter_time_s=float("nan"),
        camera_action=MissionItem.CameraAction.NONE, vehicle_action=action)


def same_item(a, b):
    """Field by field (NaN equal to NaN); coordinates to the 1e-7° of MISSION_ITEM_INT."""
    for f in ("latitude_deg", "longitude_deg", "relative_altitude_m", "speed_m_s",
              "acceptance_radius_m", "yaw_deg", "loiter_time_s"):
        x, y = getattr(a, f), getattr(b, f)
        if not ((math.isnan(x) and math.isnan(y)) or abs(x - y) < 2e-7):
            return False
    return a.is_fly_through == b.is_fly_through and a.vehicle_action == b.vehicle_action


async def fly_square(url):
    async with mavsdk_autopilot(url) as system:
        telemetry, action = TelemetryAsync(system), ActionAsync(system)
        mission, param = MissionAsync(system), ParamAsync(system)
        await first(telemetry.subscribe_health_all_ok(), bool, 60)
        home = await first(telemetry.subscribe_home(), lambda h: True, 5)
        # Return at the mission's altitude (the default climbs to 30 m first).
        await param.set_param_float("RTL_RETURN_ALT", 10.0)

        # Take-off at home, a 20 m square at 10 m, back home and land.
        items = [waypoint(0, 0, 10, MissionItem.VehicleAction.TAKEOFF)]
        items += [waypoint(n, e, 10) for n, e in ((20, 0), (20, 20), (0, 20), (0, 0))]
        await mission.set_return_to_launch_after_mission(True)
        await mission.upload_mission(MissionPlan(items))
        back = await mission.download_mission()
        assert len(back.mission_items) == len(items)
        for sent, got in zip(items, back.mission_items):
            assert same_item(sent, got), f"{sent} came back as {got}"
        assert await mission.get_return_to_launch_after_mission()

        # Fly it, noting where the vehicle is when each item is reached.
        latest = {}

        async def track():
            async for p in telemetry.subscribe_position():
                latest["p"] = p

        tracker = asyncio.create_task(track())
        try:
            await first(telemetry.subscribe_position(), lambda p: True, 5)
            await action.arm()
            await mission.start_mission()
            reached = []
            progress = mission.subscribe_mission_progress()
            done = await first(progress, lambda pr: _note(pr, latest, reached), 240)
            assert done.current == done.total
            assert await mission.is_mission_finished()
            await first(telemetry.subscribe_armed(), lambda a: not a, 120)
        finally:
            tracker.cancel()
        final = latest["p"]
    # Every waypoint within its acceptance radius (1 m) when reached, in order.
    assert [k for k, _ in reached] == list(range(len(items))), reached
    # MAVSDK counts the RTL it appended into the last item: progress passes that item only
    # after the landing, so its position is checked by the landing below.
    for k, p in reached[:-1]:
        target = items[k]
        d = horizontal_m(p.latitude_deg, p.longitude_deg, target.latitude_deg,
                         target.longitude_deg)
        assert d < 1.0, f"item {k} reached {d:.2f} m away"
        assert abs(p.relative_altitude_m - 10.0) < 0.8, f"item {k} at {p.relative_altitude_m} m"
    # Landed at home.
    d = horizontal_m(final.latitude_deg, final.longitude_deg, home.latitude_deg,
                     home.longitude_deg)
    assert d < 1.0, f"landed {d:.2f} m from home"
    return reached


def _note(progress, latest, reached):
    """Records the items passed since the last progress report; true once the mission is done."""
    passed = len(reached)
    for k in range(passed, min(progress.current, progress.total)):
        reached.append((k, latest["p"]))
    return progress.total > 0 and progress.current == progress.total


def test_mavsdk_uploads_downloads_and_flies_a_square_mission_home(tmp_path):
    daemon = Daemon(tmp_path, "udpout://127.0.0.1:{port}?bind=0", connect=False, lockstep=True,
                    speed=6)
    try:
        start = time.monotonic()
        asyncio.run(fly_square(f"udpin://127.0.0.1:{daemon.gcs_port}"))
        print(f"square mission flown in {time.monotonic() - start:.0f} s wall")
    finally:
        daemon.close()


def item_int(seq, command, frame, params=(0, 0, 0, float("nan")), lat_lon=(0.0, 0.0), alt=0.0):
    return ML.MAVLink_mission_item_int_message(
        1, 1, seq, frame, command, 0, 1, *params,
        int(round(lat_lon[0] * 1e7)), int(round(lat_lon[1] * 1e7)), alt)


def test_pymavlink_uploads_a_mission_by_hand_and_gets_each_item_reached(fast_vehicle):
    vehicle = fast_vehicle
    gcs = vehicle
    rel = ML.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
    plan = [
        item_int(0, ML.MAV_CMD_NAV_TAKEOFF, rel, alt=6.0),
        item_int(1, ML.MAV_CMD_NAV_WAYPOINT, rel, (0, 1.0, 0, float("nan")), offset(12, 0), 6.0),
        item_int(2, ML.MAV_CMD_DO_CHANGE_SPEED, ML.MAV_FRAME_MISSION, (1, 3.0, -1, 0)),
        item_int(3, ML.MAV_CMD_NAV_LOITER_TIME, rel, (2.0, 0, 0, 0), offset(12, 12), 8.0),
        item_int(4, ML.MAV_CMD_DO_JUMP, ML.MAV_FRAME_MISSION, (1, 1, 0, 0)),
        item_int(5, ML.MAV_CMD_NAV_LAND, rel, (0, 0, 0, float("nan")), offset(0, 0), 0.0),
    ]
    # An item the vehicle cannot fly is refused at upload, with the reason.
    gcs.mav.mission_count_send(1, 1, 1, ML.MAV_MISSION_TYPE_MISSION)
    wait(gcs, "MISSION_REQUEST_INT", lambda m: m.seq == 0, 5)
    turns = item_int(0, ML.MAV_CMD_NAV_LOITER_TURNS, rel, (2, 0, 5, 0), offset(5, 5), 5.0)
    gcs.mav.send(turns)
    a = wait(gcs, "MISSION_ACK", lambda m: True, 5)
    assert a.type == ML.MAV_MISSION_UNSUPPORTED

    # Upload by the book: each item when asked for (MISSION_REQUEST_INT, never MISSION_REQUEST).
    gcs.mav.mission_count_send(1, 1, len(plan), ML.MAV_MISSION_TYPE_MISSION)
    while True:
        m = gcs.recv_match(type=["MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_ACK"],
                           blocking=True, timeout=5)
        assert m is not None, "the vehicle stopped asking"
        assert m.get_type() != "MISSION_REQUEST", "the old request"
        if m.get_type() == "MISSION_ACK":
            assert m.type == ML.MAV_MISSION_ACCEPTED, m
            break
        gcs.mav.send(plan[m.seq])
    # Download: the same items back.
    gcs.mav.mission_request_list_send(1, 1, ML.MAV_MISSION_TYPE_MISSION)
    assert wait(gcs, "MISSION_COUNT", lambda m: True, 5).count == len(plan)
    for item in plan:
        gcs.mav.mission_request_int_send(1, 1, item.seq, ML.MAV_MISSION_TYPE_MISSION)
        got = wait(gcs, "MISSION_ITEM_INT", lambda m, s=item.seq: m.seq == s, 5)
        for f in ("command", "frame", "x", "y", "z", "param1", "param2", "param3"):
            assert getattr(got, f) == getattr(item, f), (item.seq, f)
    gcs.mav.mission_ack_send(1, 1, ML.MAV_MISSION_ACCEPTED, ML.MAV_MISSION_TYPE_MISSION)
    cur = wait(gcs, "MISSION_CURRENT", lambda m: True, 3)
    assert (cur.total, cur.mission_state) == (len(plan), ML.MISSION_STATE_NOT_STARTED)

    # Arm in Hold, MISSION_START; then every item reached in order, the jump once.
    ready_to_arm(gcs)
    gcs.mav.command_long_send(1, 1, ML.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1, 0, 0, 0, 0, 0, 0)
    assert ack(gcs, ML.MAV_CMD_COMPONENT_ARM_DISARM) == ML.MAV_RESULT_ACCEPTED
    gcs.mav.command_long_send(1, 1, ML.MAV_CMD_MISSION_START, 0, 0, 0, 0, 0, 0, 0, 0)
    assert ack(gcs, ML.MAV_CMD_MISSION_START) == ML.MAV_RESULT_ACCEPTED
    reached, where, states = [], {}, set()
    home_pos, pos, hb = None, None, None
    end = time.monotonic() + 180
    while time.monotonic() < end:
        m = gcs.recv_match(type=["MISSION_ITEM_REACHED", "GLOBAL_POSITION_INT", "HEARTBEAT",
                                 "MISSION_CURRENT", "HOME_POSITION"], blocking=True, timeout=1)
        if m is None or m.get_srcComponent() != 1:
            continue
        t = m.get_type()
        if t == "GLOBAL_POSITION_INT":
            pos = m
        elif t == "HOME_POSITION":
            home_pos = m
        elif t == "MISSION_CURRENT":
            states.add(m.mission_state)
        elif t == "MISSION_ITEM_REACHED":
            reached.append(m.seq)
            where.setdefault(m.seq, pos)
        elif t == "HEARTBEAT":
            hb = m
        landed = hb is not None and reached and not hb.base_mode & ML.MAV_MODE_FLAG_SAFETY_ARMED
        if landed and ML.MISSION_STATE_COMPLETE in states:
            break
    assert reached == [0, 1, 2, 3, 4, 1, 2, 3, 4, 5], reached
    assert ML.MISSION_STATE_ACTIVE in states
    cur = wait(gcs, "MISSION_CURRENT", lambda m: True, 3)
    assert cur.mission_state == ML.MISSION_STATE_COMPLETE and cur.seq == cur.total
    # The waypoint within its 1 m, the loiter point within NAV_ACC_RAD (2 m) and 0.8 m up.
    for seq, radius in ((1, 1.0), (3, 2.0)):
        p, want = where[seq], plan[seq]
        d = horizontal_m(p.lat * 1e-7, p.lon * 1e-7, want.x * 1e-7, want.y * 1e-7)
        assert d < radius, f"item {seq} reached {d:.2f} m away"
        assert abs(p.relative_alt * 1e-3 - want.z) < 0.8 + 0.3, (seq, p.relative_alt)
    # Landed where item 5 says (home), within a metre.
    assert home_pos is not None and pos is not None
    d = horizontal_m(pos.lat * 1e-7, pos.lon * 1e-7, home_pos.latitude * 1e-7,
                     home_pos.longitude * 1e-7)
    assert d < 1.0, f"landed {d:.2f} m from home"



async def goto(vehicle):
    async with mavsdk_autopilot(vehicle.mavsdk_url) as system:
        telemetry, action = TelemetryAsync(system), ActionAsync(system)
        await first(telemetry.subscribe_health_all_ok(), bool, 60)
        home = await first(telemetry.subscribe_home(), lambda h: True, 5)
        await action.set_takeoff_altitude(5.0)
        await action.arm()
        await action.takeoff()
        await first(telemetry.subscribe_flight_mode(), lambda m: m == FlightMode.HOLD, 30)
        # 15 m north-east, 8 m above home (goto_location takes AMSL), facing east (MAVSDK sends
        # the yaw in radians in DO_REPOSITION's param4, as PX4 reads it).
        lat, lon = offset(15, 15)
        await action.goto_location(lat, lon, home.absolute_altitude_m + 8.0, 90.0)
        at = await first(
            telemetry.subscribe_position(),
            lambda p: horizontal_m(p.latitude_deg, p.longitude_deg, lat, lon) < 0.5
            and abs(p.relative_altitude_m - 8.0) < 0.5, 60)
        assert at is not None
        heading = await first(telemetry.subscribe_heading(), lambda h: True, 5)
        assert abs(heading.heading_deg - 90.0) < 5.0, heading
        assert await first(telemetry.subscribe_flight_mode(), lambda m: True, 5) == FlightMode.HOLD
        await land_and_disarm(action, telemetry)


def test_mavsdk_goto_location_flies_there_and_holds(make_vehicle):
    run_mavsdk_flight(make_vehicle, goto)


if __name__ == "__main__":
    pytest.main([__file__, "-q", "-s"])
