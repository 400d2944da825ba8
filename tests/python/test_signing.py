"""MAVLink 2 signing end to end with pymavlink's own signing: a signed session flies; unsigned
frames, frames signed with another key, replays of captured signed frames and a new stream more
than a minute old are refused; the key is set once through SETUP_SIGNING on a trusted link only;
an endpoint's allow-list of system ids.

Refusals leave no answer to wait for, so each attack is followed, on the same socket, by a signed
request: the vehicle handles one socket's frames in order, so once that request is answered the
attack has been judged, and its effect (a parameter value, the armed state) can be read.
"""

import math
import os
import time

from pymavlink import mavutil
from pymavlink.dialects.v20 import common as mavlink2

from conftest import Daemon, free_udp_port
from test_ground_station import (REAL32, ack, armed, param, ready_to_arm, take_off_and_land,
                                 wait)

KEY = bytes(range(1, 33))
OTHER_KEY = bytes(range(2, 34))
ARM = mavutil.mavlink.MAV_CMD_COMPONENT_ARM_DISARM
EPOCH_2015 = 1420070400


def now_10us():
    return int((time.time() - EPOCH_2015) * 100_000)


def packer(key=None, link_id=0, timestamp=None, system=255):
    """A pymavlink encoder as system `system`, signing with `key` if given."""
    mav = mavlink2.MAVLink(None, srcSystem=system, srcComponent=190)
    if key is not None:
        mav.signing.secret_key = key
        mav.signing.sign_outgoing = True
        mav.signing.link_id = link_id
        mav.signing.timestamp = now_10us() if timestamp is None else timestamp
    return mav


def param_set_frame(mav, value):
    return mavlink2.MAVLink_param_set_message(1, 1, b"MIS_TAKEOFF_ALT", value, REAL32).pack(mav)


def takeoff_alt_after(gcs, frame):
    """Writes `frame` (a PARAM_SET of MIS_TAKEOFF_ALT, or anything) on the ground station's
    socket, then asks for another parameter: the MIS_TAKEOFF_ALT echo that came before that
    answer (the value set), or None (nothing was set)."""
    while gcs.recv_match(blocking=False) is not None:
        pass
    gcs.write(frame)
    gcs.mav.param_request_read_send(1, 1, b"RTL_RETURN_ALT", -1)
    value, end = None, time.monotonic() + 5
    while time.monotonic() < end:
        m = gcs.recv_match(type="PARAM_VALUE", blocking=True, timeout=0.5)
        if m is None:
            continue
        if m.param_id == "MIS_TAKEOFF_ALT":
            value = m.param_value
        elif m.param_id == "RTL_RETURN_ALT":
            return value
    raise AssertionError("no answer to the fence request")


def signed_gcs(daemon, key=KEY):
    gcs = daemon.gcs
    gcs.setup_signing(key, sign_outgoing=True)
    return gcs


def test_a_signed_session_flies_and_unsigned_wrong_and_replayed_frames_are_refused(tmp_path):
    key_file = tmp_path / "signing.key"
    key_file.write_text(KEY.hex() + "\n")
    key_file.chmod(0o600)
    daemon = Daemon(tmp_path, "udpout://127.0.0.1:{port}?bind=0",
                    ap_args=["--signing-key-file", str(key_file)])
    try:
        gcs = signed_gcs(daemon)
        # pymavlink with a key drops unsigned or wrongly signed frames: the vehicle signs.
        hb = gcs.wait_heartbeat(timeout=30)
        assert hb is not None and hb.get_signed(), "no signed heartbeat"
        assert param(gcs, "MIS_TAKEOFF_ALT").param_value == 2.5

        assert takeoff_alt_after(gcs, param_set_frame(packer(), 7.0)) is None, "unsigned"
        assert takeoff_alt_after(gcs, param_set_frame(packer(OTHER_KEY, 1), 7.0)) is None, \
            "another key"
        old = packer(KEY, 2, timestamp=now_10us() - 2 * 60 * 100_000)
        assert takeoff_alt_after(gcs, param_set_frame(old, 7.0)) is None, "two minutes old"
        # A captured signed frame acts once; replayed later it does not.
        captured = param_set_frame(packer(KEY, 3), 6.0)
        assert takeoff_alt_after(gcs, captured) == 6.0, "the signed original"
        assert takeoff_alt_after(gcs, param_set_frame(packer(KEY, 3), 3.0)) == 3.0
        assert takeoff_alt_after(gcs, captured) is None, "replayed"
        assert param(gcs, "MIS_TAKEOFF_ALT").param_value == 3.0

        # An unsigned arm does not arm; the signed session arms, takes off and lands.
        ready_to_arm(gcs)
        unsigned_arm = mavlink2.MAVLink_command_long_message(
            1, 1, ARM, 0, 1, 0, 0, 0, 0, 0, 0).pack(packer())
        takeoff_alt_after(gcs, unsigned_arm)
        assert not armed(wait(gcs, "HEARTBEAT", lambda m: True, 5))
        gcs.arducopter_arm()
        assert ack(gcs, ARM) == 0
        take_off_and_land(gcs, math.nan, (2.5, 3.5))
        daemon.stop()
        closed = next(l for l in daemon.ap_stderr.splitlines()
                      if "ground-station links closed" in l)
        counts = dict(kv.split("=") for kv in closed.split() if "=" in kv)
        assert int(counts["refused_unsigned"]) >= 2, closed
        assert int(counts["refused_bad_signature"]) >= 1, closed
        assert int(counts["refused_replayed"]) >= 2, closed
    finally:
        daemon.close()


def test_the_key_is_set_only_through_a_trusted_link_and_allow_lists_are_kept(tmp_path):
    key_file = tmp_path / "signing.key"
    trusted_port, listed_port = free_udp_port(), free_udp_port()
    daemon = Daemon(tmp_path, "udpout://127.0.0.1:{port}?bind=0",
                    ap_args=["--signing-key-file", str(key_file),
                             "--mavlink", f"udpin://127.0.0.1:{trusted_port}?trusted",
                             "--mavlink", f"udpin://127.0.0.1:{listed_port}?sysids=255"])
    trusted = mavutil.mavlink_connection(f"udpout:127.0.0.1:{trusted_port}", source_system=255)
    listed = mavutil.mavlink_connection(f"udpout:127.0.0.1:{listed_port}", source_system=255)
    try:
        gcs = daemon.gcs
        assert gcs.wait_heartbeat(timeout=30)
        # No key yet: everything is heard.
        assert takeoff_alt_after(gcs, param_set_frame(packer(), 4.0)) == 4.0

        # The allow-list: system 200 is not heard on that endpoint, 255 is.
        listed.mav.heartbeat_send(mavutil.mavlink.MAV_TYPE_GCS,
                                  mavutil.mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
        assert listed.wait_heartbeat(timeout=10)
        assert takeoff_alt_after(listed, param_set_frame(packer(system=200), 4.5)) is None
        assert takeoff_alt_after(listed, param_set_frame(packer(), 4.5)) == 4.5

        # SETUP_SIGNING from an ordinary link is refused.
        ts = now_10us()
        gcs.mav.setup_signing_send(1, 1, list(KEY), ts)
        wait(gcs, "STATUSTEXT", lambda m: m.text == "SETUP_SIGNING refused: link not trusted", 5)
        assert not key_file.exists()
        assert takeoff_alt_after(gcs, param_set_frame(packer(), 5.0)) == 5.0, "still unsigned"

        # From the trusted link it is taken, kept (owner-only), and required from then on.
        trusted.mav.heartbeat_send(mavutil.mavlink.MAV_TYPE_GCS,
                                   mavutil.mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
        trusted.mav.setup_signing_send(1, 1, list(KEY), ts)
        wait(trusted, "STATUSTEXT", lambda m: m.text == "MAVLink signing on", 5)
        assert key_file.read_text().strip() == KEY.hex()
        assert os.stat(key_file).st_mode & 0o077 == 0
        gcs = signed_gcs(daemon)
        assert takeoff_alt_after(gcs, param_set_frame(packer(), 7.0)) is None, "unsigned"
        assert takeoff_alt_after(gcs, param_set_frame(packer(KEY, 5), 6.0)) == 6.0, "signed"
        # The trusted link is exempt (a USB cable); it may turn signing off again.
        assert takeoff_alt_after(trusted, param_set_frame(packer(), 6.5)) == 6.5
        trusted.mav.setup_signing_send(1, 1, [0] * 32, 0)
        wait(trusted, "STATUSTEXT", lambda m: m.text == "MAVLink signing off", 5)
        assert not key_file.exists()
    finally:
        trusted.close()
        listed.close()
        daemon.close()
