#!/usr/bin/env python3
"""Blasts mixed valid and invalid MAVLink traffic at a UDP port, as a hostile or broken peer
would: for testing that a vehicle keeps flying and serving its real ground station meanwhile.

    .venv/bin/python tools/mavlink_flood.py 127.0.0.1:14550 --rate 60000 --seconds 10

One frame per datagram (the most work per byte for the receiver), paced to --rate frames a
second in bursts of a millisecond's worth. The mix, from a fixed seed:
- valid MAVLink 2 frames that ask for nothing harmful: GCS heartbeats from system 200, TIMESYNC
  and PARAM_REQUEST_READ (both answered), COMMAND_LONG, MANUAL_CONTROL and
  SET_POSITION_TARGET_LOCAL_NED addressed to another system (99), messages of unknown ids;
- invalid ones: a bit flipped (checksum wrong), cut short, a length that lies, random bytes,
  MAVLink 1 frames with a bad checksum, empty datagrams.
Prints one JSON line at the end: frames sent, seconds, rate achieved.
"""

import argparse
import json
import os
import random
import socket
import sys
import time

os.environ.setdefault("MAVLINK20", "1")
from pymavlink.dialects.v20 import common as mavlink2  # noqa: E402

SEED = 9


def valid_frames(rng):
    """Well-formed frames that command nothing on system 1."""
    mav = mavlink2.MAVLink(None, srcSystem=200, srcComponent=190)
    frames = []
    for i in range(40):
        frames.append(mavlink2.MAVLink_heartbeat_message(6, 8, 0, 0, 4, 3).pack(mav))
        frames.append(mavlink2.MAVLink_timesync_message(0, rng.getrandbits(62)).pack(mav))
        frames.append(mavlink2.MAVLink_command_long_message(
            99, 1, 400, 0, 1, 0, 0, 0, 0, 0, 0).pack(mav))
        frames.append(mavlink2.MAVLink_manual_control_message(
            99, rng.randint(-1000, 1000), rng.randint(-1000, 1000), 500, 0, 0).pack(mav))
        frames.append(mavlink2.MAVLink_set_position_target_local_ned_message(
            0, 99, 1, 1, 0, 10.0, 0, -50.0, 0, 0, 0, 0, 0, 0, 0, 0).pack(mav))
        if i % 4 == 0:
            frames.append(mavlink2.MAVLink_param_request_read_message(
                1, 1, b"MIS_TAKEOFF_ALT", -1).pack(mav))
        # An id this dialect does not know (its checksum cannot be checked): a valid-looking frame.
        payload = bytes(rng.getrandbits(8) for _ in range(rng.randint(1, 40)))
        msgid = 50000 + i
        header = bytes([0xFD, len(payload), 0, 0, i & 0xFF, 200, 190,
                        msgid & 0xFF, (msgid >> 8) & 0xFF, msgid >> 16])
        frames.append(header + payload + bytes(rng.getrandbits(8) for _ in range(2)))
    return frames


def invalid_frames(rng, valid):
    """Damaged versions of the valid frames, and noise."""
    frames = []
    for f in valid:
        b = bytearray(f)
        b[rng.randrange(1, len(b))] ^= 1 << rng.randrange(8)
        frames.append(bytes(b))  # a bit flipped
        frames.append(f[:rng.randrange(1, len(f))])  # cut short
        b = bytearray(f)
        b[1] = rng.randrange(256)
        frames.append(bytes(b))  # a length that lies
    for _ in range(len(valid)):
        frames.append(bytes(rng.getrandbits(8) for _ in range(rng.randint(1, 280))))
        v1 = bytes([0xFE, 9, rng.randrange(256), 200, 190, 0]) + bytes(11)
        frames.append(v1)  # MAVLink 1, checksum wrong
    frames.append(b"")
    return frames


def traffic(seed=SEED):
    """The datagrams, valid and invalid about half and half, in a shuffled order."""
    rng = random.Random(seed)
    valid = valid_frames(rng)
    invalid = invalid_frames(rng, valid)
    mix = valid * (len(invalid) // len(valid)) + invalid
    rng.shuffle(mix)
    return mix


def flood(host, port, rate, seconds):
    datagrams = traffic()
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, 1 << 20)
    burst = max(1, rate // 1000)
    sent, i, n = 0, 0, len(datagrams)
    start = time.monotonic()
    end = start + seconds
    while True:
        now = time.monotonic()
        if now >= end:
            break
        due = int((now - start) * rate)
        if sent >= due:
            time.sleep(min(0.001, end - now))
            continue
        for _ in range(min(burst, due - sent)):
            try:
                sock.sendto(datagrams[i], (host, port))
            except OSError:  # nobody listening (ICMP refused) or the buffer full: go on
                pass
            i = (i + 1) % n
            sent += 1
    elapsed = time.monotonic() - start
    return {"frames": sent, "seconds": round(elapsed, 3), "rate": round(sent / elapsed)}


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("target", help="HOST:PORT to flood")
    p.add_argument("--rate", type=int, default=60000, help="frames a second [60000]")
    p.add_argument("--seconds", type=float, default=10.0, help="how long [10]")
    a = p.parse_args()
    host, _, port = a.target.rpartition(":")
    print(json.dumps(flood(host, int(port), a.rate, a.seconds)), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
