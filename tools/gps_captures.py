#!/usr/bin/env python3
"""Recordings of real GPS receivers, for the GPS drivers' tests: where they are, and how to get them.

    tools/gps_captures.py where     # the folder the tests read, or why none
    tools/gps_captures.py fetch     # download, check and unpack them into the cache

The recordings are gpsd's regression logs (test/daemon/*.log in gpsd's source, BSD-licensed,
each from a named receiver, with a header saying which and where), taken from the source
package Debian ships (gpsd 3.22, `gpsd_3.22.orig.tar.xz` in Debian's archive), checked against
a pinned SHA-256. They are not kept in this repository. The tests ask `captures_dir()`, which
looks in `$AUTOPILOT_GPS_CAPTURES_DIR` (when set, only there), else in the cache,
`$XDG_CACHE_HOME/autopilot/gps-captures` (default `~/.cache/autopilot/gps-captures`), which
`fetch` fills (one atomic rename). Only the standard library is needed.
"""
import argparse
import hashlib
import io
import os
import shutil
import sys
import tarfile
import tempfile
import urllib.request
from pathlib import Path

ENV_DIR = "AUTOPILOT_GPS_CAPTURES_DIR"
# Set by CI (.ci/run): missing recordings fail their test instead of skipping it.
ENV_REQUIRED = "AUTOPILOT_REQUIRE_GPS_CAPTURES"
FETCH_COMMAND = "python3 tools/gps_captures.py fetch"
SOURCE = "http://deb.debian.org/debian/pool/main/g/gpsd/gpsd_3.22.orig.tar.xz"
SHA256 = "68d2a04e237a02ce42158ceda462a24afe11eeaa2b13482e94ac7ef66693f3a0"

# The recordings used, by protocol: u-blox UBX (NAV-PVT), and NMEA 0183 from several makers.
UBX = ["ublox-neo-m8n.log", "ublox-zed-f9p-hp.log"]
NMEA = ["ublox-neo-m9n-nmea.log", "mt3339.log", "bu353s4.log", "quectel.log", "nmea-rtk.log",
        "haicom-305N.log"]


def cache_dir() -> Path:
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "autopilot" / "gps-captures"


def complete(folder: Path) -> bool:
    return all((folder / name).is_file() for name in UBX + NMEA)


def captures_dir():
    """(folder, None) when every recording is there, else (None, why)."""
    if os.environ.get(ENV_DIR):
        folder = Path(os.environ[ENV_DIR])
        if complete(folder):
            return folder, None
        return None, f"${ENV_DIR}={folder} lacks some of {UBX + NMEA}"
    if complete(cache_dir()):
        return cache_dir(), None
    return None, f"the GPS recordings are not fetched: run {FETCH_COMMAND}"


def fetch() -> Path:
    target = cache_dir()
    if complete(target):
        return target
    print(f"downloading {SOURCE}", file=sys.stderr)
    with urllib.request.urlopen(SOURCE, timeout=120) as r:
        data = r.read()
    digest = hashlib.sha256(data).hexdigest()
    if digest != SHA256:
        raise SystemExit(f"{SOURCE}: SHA-256 {digest}, expected {SHA256}")
    target.parent.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(dir=target.parent, prefix=".gps-captures-"))
    try:
        with tarfile.open(fileobj=io.BytesIO(data), mode="r:xz") as tar:
            for name in UBX + NMEA:
                member = tar.getmember(f"gpsd-3.22/test/daemon/{name}")
                (staging / name).write_bytes(tar.extractfile(member).read())
        if target.exists():
            shutil.rmtree(target)
        os.rename(staging, target)
    finally:
        if staging.exists():
            shutil.rmtree(staging)
    return target


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("command", choices=["where", "fetch"])
    args = ap.parse_args()
    if args.command == "fetch":
        print(fetch())
        return
    folder, why = captures_dir()
    if folder is None:
        raise SystemExit(why)
    print(folder)


if __name__ == "__main__":
    main()
