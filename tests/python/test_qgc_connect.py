"""QGroundControl's initial connect to a PX4 vehicle, played with pymavlink in QGC's order and
held to QGC's own time-outs (its InitialConnectStateMachine, ParameterManager, PlanManager and
ComponentInformationManager): autopilot version, the standard modes one by one (and all at
once), component metadata and its files over MAVLink FTP, the parameters with PX4's
`_HASH_CHECK`, mission, fence and rally points, and the events' sequence."""

import struct
import time
import zlib

from pymavlink import mavutil
from pymavlink.mavftp import MAVFTP, FtpError

from test_ground_station import daemon  # noqa: F401 (the fixture)

ML = mavutil.mavlink
ACK_S, MESSAGE_S = 1.2, 1.0  # QGC: a REQUEST_MESSAGE's ack, then its message
COMPONENT_METADATA, CURRENT_EVENT_SEQUENCE = 397, 411


def receive(gcs, what, condition, timeout):
    """The first `what` from component 1 for which condition holds within `timeout` s, and
    when it came; None if none."""
    end = time.monotonic() + timeout
    while (left := end - time.monotonic()) > 0:
        m = gcs.recv_match(type=what, blocking=True, timeout=min(left, 0.1))
        if m is None:
            continue
        # A message the dialect does not know keeps its whole frame: the sender is in it.
        unknown = m.get_type().startswith("UNKNOWN_")
        component = m.data[6] if unknown else m.get_srcComponent()
        if component == 1 and condition(m):
            return m, time.monotonic()
    return None, time.monotonic()


def request(gcs, msg_id, what, param2=0, condition=lambda m: True):
    """REQUEST_MESSAGE as QGC sends it: the ack within 1.2 s, the message 1 s after it."""
    sent = time.monotonic()
    gcs.mav.command_long_send(1, 1, ML.MAV_CMD_REQUEST_MESSAGE, 0, msg_id, param2,
                              0, 0, 0, 0, 0)
    ack, acked = receive(gcs, "COMMAND_ACK",
                         lambda m: m.command == ML.MAV_CMD_REQUEST_MESSAGE, ACK_S)
    assert ack is not None and ack.result == ML.MAV_RESULT_ACCEPTED, (msg_id, ack)
    m, _ = receive(gcs, what, condition, MESSAGE_S)
    assert m is not None, f"{what} not within {MESSAGE_S} s of the ack"
    assert acked - sent <= ACK_S
    return m


def unknown_payload(m, length):
    """The payload of a message pymavlink's dialect does not know (its whole MAVLink 2 frame
    kept: a 10-byte header, the payload's length second), its trailing zeros restored."""
    frame = bytes(m.data)
    payload = frame[10:10 + frame[1]]
    return payload + bytes(length - len(payload))


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
    request(gcs, ML.MAVLINK_MSG_ID_AVAILABLE_MODES, "AVAILABLE_MODES", 0)
    rest = [receive(gcs, "AVAILABLE_MODES", lambda m: True, MESSAGE_S)[0]
            for _ in range(len(modes) - 1)]
    assert all(rest), "not every mode sent on param2 0"

    # 3. Component metadata: its URI and CRC, then each file over FTP within 30 s.
    meta = request(gcs, COMPONENT_METADATA, f"UNKNOWN_{COMPONENT_METADATA}")
    _, crc = struct.unpack_from("<II", unknown_payload(meta, 108))
    uri = unknown_payload(meta, 108)[8:].split(b"\0")[0].decode()
    assert uri.startswith("mftp://[;comp=1]"), uri
    ftp = MAVFTP(gcs, 1, 1)
    start = time.monotonic()
    local = tmp_path / "general.json"
    ftp.cmd_get([uri.removeprefix("mftp://[;comp=1]"), str(local)])
    assert ftp.process_ftp_reply("OpenFileRO", timeout=30).error_code == FtpError.Success
    assert zlib.crc32(local.read_bytes(), 0xFFFFFFFF) ^ 0xFFFFFFFF == crc
    assert time.monotonic() - start < 30

    # 4. Parameters: `_HASH_CHECK` first (1 s), then the list (first value in 5 s, no gap of
    # 3 s, every index), whose hash is the one announced.
    gcs.mav.param_request_read_send(1, 1, b"_HASH_CHECK", -1)
    announced, _ = receive(gcs, "PARAM_VALUE", lambda m: m.param_id == "_HASH_CHECK", 1.0)
    assert announced is not None and announced.param_type == ML.MAV_PARAM_TYPE_UINT32
    assert announced.param_index == 65535
    gcs.mav.param_request_list_send(1, 1)
    values, wait_s = {}, 5.0  # the first value within 5 s, each next one within 3 s
    while len(values) < announced.param_count:
        m, _ = receive(gcs, "PARAM_VALUE", lambda m: m.param_index != 65535, wait_s)
        assert m is not None, f"{len(values)} of {announced.param_count} within {wait_s} s"
        values[m.param_id] = struct.pack("<f", m.param_value)  # a float's or an int's bytes
        wait_s = 3.0
    assert len(values) == announced.param_count
    hash_bits = struct.unpack("<I", struct.pack("<f", announced.param_value))[0]
    assert px4_hash(values) == hash_bits
    # The cache matched: QGC says so with a PARAM_SET of the hash, which must not be refused.
    gcs.mav.param_set_send(1, 1, b"_HASH_CHECK", announced.param_value,
                           ML.MAV_PARAM_TYPE_UINT32)
    refused, _ = receive(gcs, "STATUSTEXT", lambda m: "_HASH_CHECK" in m.text, 0.5)
    assert refused is None, refused.text

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
