"""QGroundControl's initial connect to a PX4 vehicle, played with pymavlink in QGC's order and
held to QGC's own time-outs (its InitialConnectStateMachine, ParameterManager, PlanManager and
ComponentInformationManager): autopilot version, the standard modes one by one (and all at
once), component metadata and its files over MAVLink FTP, the parameters with PX4's
`_HASH_CHECK`, mission, fence and rally points, and the events' sequence."""

import struct
import zlib

from pymavlink import mavutil
from pymavlink.mavftp import FtpError

from conftest import ftp_crc32, receive, request_message as request, mavftp
from test_ground_station import daemon  # noqa: F401 (the fixture)

ML = mavutil.mavlink
MESSAGE_S = 1.0  # QGC: a REQUEST_MESSAGE's message after its ack
COMPONENT_METADATA, CURRENT_EVENT_SEQUENCE = 397, 411


def unknown_payload(m, length):
    """The payload of a message pymavlink's dialect does not know (its whole MAVLink 2 frame
    kept: a 10-byte header, the payload's length second), its trailing zeros restored."""
    frame = bytes(m.data)
    payload = frame[10:10 + frame[1]]
    return payload + bytes(length - len(payload))


def raw_value(m):
    """A PARAM_VALUE's 4 value bytes as sent (the first payload field; not through a Python
    float, which may quiet a NaN's bits)."""
    return bytes(m.get_msgbuf()[10:14])


def px4_hash(values):
    """PX4's param_hash_check: CRC-32 from 0 (no inversions) over each name and value's bytes
    in name order."""
    data = b"".join(name.encode() + raw for name, raw in sorted(values.items()))
    return zlib.crc32(data, 0xFFFFFFFF) ^ 0xFFFFFFFF


def test_qgroundcontrols_initial_connect_is_answered_in_its_order_and_time(daemon, tmp_path):
    gcs = daemon.gcs
    hb, _ = receive(gcs, "HEARTBEAT", lambda m: True, 10)
    assert hb.autopilot == ML.MAV_AUTOPILOT_PX4 and hb.get_msgbuf()[0] == 0xFD  # MAVLink 2

    # 1. Autopilot version, with what QGC needs to go on to fence and rally points.
    version = request(gcs, ML.MAVLINK_MSG_ID_AUTOPILOT_VERSION, "AUTOPILOT_VERSION")
    for cap in ("MAVLINK2", "MISSION_INT", "COMMAND_INT", "MISSION_FENCE", "MISSION_RALLY",
                "FTP", "PARAM_ENCODE_BYTEWISE"):
        assert version.capabilities & getattr(ML, f"MAV_PROTOCOL_CAPABILITY_{cap}"), cap

    # 2. Standard modes, one index at a time until the last; and all at once (param2 0).
    modes, index = [], 1
    while True:
        m = request(gcs, ML.MAVLINK_MSG_ID_AVAILABLE_MODES, "AVAILABLE_MODES", index,
                    lambda m, i=index: m.mode_index == i)
        modes.append(m.mode_name)
        if m.mode_index >= m.number_modes:
            break
        index += 1
    assert {"POSCTL", "LOITER", "MISSION", "RTL", "LAND"} <= set(modes), modes
    first = request(gcs, ML.MAVLINK_MSG_ID_AVAILABLE_MODES, "AVAILABLE_MODES", 0)
    rest = [receive(gcs, "AVAILABLE_MODES", lambda m: True, MESSAGE_S)[0]
            for _ in range(len(modes) - 1)]
    assert all(rest), "not every mode sent on param2 0"
    assert {m.mode_index for m in [first, *rest]} == set(range(1, len(modes) + 1))

    # 3. Component metadata: its URI and CRC, then each file over FTP within 30 s.
    meta = request(gcs, COMPONENT_METADATA, f"UNKNOWN_{COMPONENT_METADATA}")
    _, crc = struct.unpack_from("<II", unknown_payload(meta, 108))
    uri = unknown_payload(meta, 108)[8:].split(b"\0")[0].decode()
    assert uri.startswith("mftp://[;comp=1]"), uri
    ftp = mavftp(gcs)
    local = tmp_path / "general.json"
    ftp.cmd_get([uri.removeprefix("mftp://[;comp=1]"), str(local)])
    assert ftp.process_ftp_reply("OpenFileRO", timeout=30).error_code == FtpError.Success
    assert ftp_crc32(local.read_bytes()) == crc

    # 4. Parameters: `_HASH_CHECK` first (QGC waits 2.5 s for its cache check), then the list
    # (first value in 5 s, no gap of 3 s, every index), whose hash is the one announced.
    gcs.mav.param_request_read_send(1, 1, b"_HASH_CHECK", -1)
    announced, _ = receive(gcs, "PARAM_VALUE", lambda m: m.param_id == "_HASH_CHECK", 2.5)
    assert announced is not None and announced.param_type == ML.MAV_PARAM_TYPE_UINT32
    assert announced.param_index == 65535
    gcs.mav.param_request_list_send(1, 1)
    values, wait_s = {}, 5.0  # the first value within 5 s, each next one within 3 s
    while len(values) < announced.param_count:
        m, _ = receive(gcs, "PARAM_VALUE", lambda m: m.param_index != 65535, wait_s)
        assert m is not None, f"{len(values)} of {announced.param_count} within {wait_s} s"
        values[m.param_id] = raw_value(m)
        wait_s = 3.0
    assert len(values) == announced.param_count
    hash_bits = struct.unpack("<I", raw_value(announced))[0]
    assert px4_hash(values) == hash_bits
    # The cache matched: QGC says so with a PARAM_SET of the hash, which must not be refused.
    gcs.mav.param_set_send(1, 1, b"_HASH_CHECK", announced.param_value,
                           ML.MAV_PARAM_TYPE_UINT32)
    # Then a read of a known parameter: anything said about the hash would come before it.
    gcs.mav.param_request_read_send(1, 1, b"MIS_TAKEOFF_ALT", -1)
    said = []
    answer, _ = receive(gcs, ["PARAM_VALUE", "STATUSTEXT"],
                        lambda m: said.append(m) or m.get_type() == "PARAM_VALUE", 2.0)
    assert answer is not None and answer.param_id == "MIS_TAKEOFF_ALT"
    assert not [m.text for m in said if m.get_type() == "STATUSTEXT"], said

    # 5. Mission, fence, rally: each count within 1.5 s in its own type, then acknowledged.
    for mission_type in (ML.MAV_MISSION_TYPE_MISSION, ML.MAV_MISSION_TYPE_FENCE,
                         ML.MAV_MISSION_TYPE_RALLY):
        gcs.mav.mission_request_list_send(1, 1, mission_type)
        count, _ = receive(gcs, "MISSION_COUNT",
                           lambda m, t=mission_type: m.mission_type == t, 1.5)
        assert count is not None and count.count == 0, (mission_type, count)
        gcs.mav.mission_ack_send(1, 1, ML.MAV_MISSION_ACCEPTED, mission_type)

    # 6. The events' sequence, said every 3 s.
    current, _ = receive(gcs, f"UNKNOWN_{CURRENT_EVENT_SEQUENCE}", lambda m: True, 3.5)
    assert current is not None, "no CURRENT_EVENT_SEQUENCE"
