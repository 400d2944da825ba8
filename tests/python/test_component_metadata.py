"""Component metadata as QGroundControl reads a PX4 vehicle's, with MAVSDK's own
component-metadata client (pinned, unmodified): `REQUEST_MESSAGE` for `COMPONENT_METADATA`,
the general file fetched over MAVLink FTP from the `mftp://` URI it names, then the parameter
metadata it lists. The files are checked against the MAVLink project's JSON schemas
(`tests/schemas/component_metadata/`, pinned `jsonschema`) and their CRCs, fetched again with
pymavlink's FTP client; the parameter metadata is the table the parameter protocol serves."""

import asyncio
import json
import re

import jsonschema
import mavsdk_grpc as mavsdk
from mavsdk_grpc.component_metadata import MetadataType
from pymavlink import mavutil
from pymavlink.mavftp import FtpError

from conftest import ROOT, first, ftp_crc32, request_message, mavftp
from test_ground_station import ack, daemon, wait  # noqa: F401 (the fixture)
from conftest import free_tcp_port
from test_ulog import fetch_params

# The MAVLink project's schemas (their origin and licence in the folder's README).
SCHEMAS = ROOT / "tests" / "schemas" / "component_metadata"


def ftp_get(ftp, path, tmp_path):
    local = tmp_path / path.replace("/", "_")
    ftp.cmd_get([path, str(local)])
    assert ftp.process_ftp_reply("OpenFileRO", timeout=10).error_code == FtpError.Success
    return local.read_bytes()


def test_component_metadata_over_ftp_matches_the_schemas_and_the_parameters(daemon, tmp_path):
    async def mavsdk_reads_it():
        drone = mavsdk.System(port=free_tcp_port())
        await drone.connect(system_address=f"udpin://127.0.0.1:{daemon.gcs_port}")
        await first(drone.core.connection_state(), lambda s: s.is_connected, 30)
        await drone.component_metadata.request_autopilot_component()
        await first(drone.component_metadata.metadata_available(),
                    lambda u: u.type == MetadataType.ALL_COMPLETED, 30)
        data = await drone.component_metadata.get_metadata(1, MetadataType.PARAMETER)
        drone._stop_mavsdk_server()
        return json.loads(data.json_metadata)

    metadata = asyncio.run(mavsdk_reads_it())
    jsonschema.validate(metadata, json.loads((SCHEMAS / "parameter.schema.json").read_text()))

    # The general file, and the parameters' file it names with its CRC, over pymavlink's FTP.
    gcs = daemon.gcs
    ftp = mavftp(gcs)
    general = json.loads(ftp_get(ftp, "@META/general.json", tmp_path))
    jsonschema.validate(general, json.loads((SCHEMAS / "general.schema.json").read_text()))
    [entry] = [t for t in general["metadataTypes"] if t["type"] == 1]  # PARAMETER
    path = re.fullmatch(r"mftp://\[;comp=1\](.+)", entry["uri"]).group(1)
    param_bytes = ftp_get(ftp, path, tmp_path)
    assert ftp_crc32(param_bytes) == entry["fileCrc"]
    assert json.loads(param_bytes) == metadata

    # The same table as the parameter protocol: every name once, each value in its range.
    values = fetch_params(gcs)
    by_name = {p["name"]: p for p in metadata["parameters"]}
    assert by_name.keys() == values.keys()
    for name, value in values.items():
        p = by_name[name]
        assert p["min"] <= value <= p["max"], (name, value, p)
        assert p["shortDesc"] and p["longDesc"] and p["group"], p
        if p["type"] == "Int32":
            assert p["decimalPlaces"] == 0 and value == int(value), p
    assert by_name["MIS_TAKEOFF_ALT"]["default"] == 2.5
    assert by_name["MIS_TAKEOFF_ALT"]["units"] == "m"


def test_what_a_ground_station_asks_for_on_connecting_is_answered(daemon):
    """REQUEST_MESSAGE of what QGroundControl and MAVSDK ask for at once (PX4 1.18 has no
    other way): each answered with its message. (PROTOCOL_VERSION too, which pymavlink 2.4.50's
    dialect does not decode: gcs's unit test.)"""
    gcs = daemon.gcs
    wait(gcs, "HOME_POSITION", lambda m: True, 30)  # the estimator has its origin, home is set
    # The streamed ones off first, so that what comes is the answer.
    for name in ("HOME_POSITION", "CURRENT_MODE", "EXTENDED_SYS_STATE"):
        msg_id = getattr(mavutil.mavlink, f"MAVLINK_MSG_ID_{name}")
        gcs.mav.command_long_send(1, 1, mavutil.mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, 0,
                                  msg_id, -1, 0, 0, 0, 0, 0)
        assert ack(gcs, mavutil.mavlink.MAV_CMD_SET_MESSAGE_INTERVAL) == 0, name
    for name in ("AUTOPILOT_VERSION", "GPS_GLOBAL_ORIGIN", "HOME_POSITION",
                 "MISSION_CURRENT", "CURRENT_MODE", "EXTENDED_SYS_STATE", "AVAILABLE_MODES"):
        msg_id = getattr(mavutil.mavlink, f"MAVLINK_MSG_ID_{name}")
        # MISSION_CURRENT also goes out at 1 Hz: the answer must come at once to count.
        request_message(gcs, msg_id, name, 1, within_s=0.3)
