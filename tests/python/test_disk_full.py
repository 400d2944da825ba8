"""The log disk fills in flight: the flight goes on and ends as it would have, the ground station
is told once, and the logs end whole where the disk was full."""

import csv
import shutil
import struct
import subprocess
import time

import pytest
from pymavlink import mavutil
from pyulog import ULog

from conftest import ROOT, binary, free_udp_port
from test_events import payload

# Of the logs' ~120 kB a simulated second, this fills during the take-off.
DISK = "640k"


def small_disk_available():
    """Whether a user and mount namespace with a tmpfs of its own can be made here."""
    try:
        return subprocess.run(["unshare", "-rm", "sh", "-c", "mount -t tmpfs -o size=64k tmpfs /mnt"],
                               capture_output=True, timeout=10).returncode == 0
    except (OSError, subprocess.TimeoutExpired):
        return False


@pytest.mark.skipif(not small_disk_available(),
                    reason="no user and mount namespaces here to mount a small disk in")
@pytest.mark.parametrize("min_free_mb", [0, 50])
def test_a_full_log_disk_stops_the_logs_cleanly_and_not_the_flight(tmp_path, min_free_mb):
    """The logs go to a 640 kB disk (a tmpfs in a namespace of the autopilot's own). With no
    free space kept (SDLOG_MIN_FREE 0) it is full during the take-off; with the default 50 MB
    kept, the logs stop at their first write. Before, the vehicle flew and landed but the ground
    station was never told, the run ended with exit status 1 and no summary, and the CSV's last
    row was cut mid-field. Now: `STATUSTEXT` "logging stopped: disk full" and a
    `logging_stopped` EVENT, each once; the flight lands; its summary says `logs=stopped`; exit
    0; the CSV ends with a whole row and the ULog reads to the moment of the fault."""
    logs, kept = tmp_path / "logs", tmp_path / "kept"
    logs.mkdir()
    kept.mkdir()
    params = tmp_path / "flight.toml"
    params.write_text(f"[logger]\nmin_free_mb = {min_free_mb}\n")
    port = free_udp_port()
    gcs = mavutil.mavlink_connection(f"udpin:127.0.0.1:{port}", source_system=255)
    autopilot = [str(binary("autopilot")), "--sim", "--speed", "5", "--takeoff", "5",
                 "--hover", "5", "--params-dir", str(ROOT / "params"), "--params", str(params),
                 "--param-store", "none",
                 "--mavlink", f"udpout://127.0.0.1:{port}", "--log-dir", str(logs)]
    # The disk lives as long as the namespace: what is on it is copied out at the end.
    script = (f'mount -t tmpfs -o size={DISK} tmpfs "{logs}" || exit 90; "$@"; status=$?; '
              f'cp -a "{logs}/." "{kept}/"; exit $status')
    run = subprocess.Popen(["unshare", "-rm", "sh", "-c", script, "sh", *autopilot],
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    texts, events = [], []
    try:
        end = time.monotonic() + 120
        while run.poll() is None and time.monotonic() < end:
            # EVENT (410): pymavlink's dialect does not know it; its id leads the payload.
            m = gcs.recv_match(type=["STATUSTEXT", "UNKNOWN_410"], blocking=True, timeout=0.5)
            if m is None:
                continue
            if m.get_type() == "STATUSTEXT":
                texts.append(m.text)
            else:
                events.append(struct.unpack_from("<I", payload(m, 53))[0])
        out, err = run.communicate(timeout=30)
    finally:
        if run.poll() is None:
            run.kill()
            run.communicate()
    assert run.returncode == 0, err[-3000:]
    assert texts.count("logging stopped: disk full") == 1, texts
    stopped_id = (1 << 24) | (_fnv1a("logging_stopped") & 0xFFFFFF)
    assert events.count(stopped_id) == 1, events
    summary = next(l for l in out.splitlines() if l.startswith("autopilot summary:"))
    fields = dict(kv.split("=", 1) for kv in summary.split()[2:])
    assert fields["logs"] == "stopped", summary
    assert fields["landed"] == "true" and fields["disarmed"] == "true", summary
    # The logs end whole where the disk was full.
    (table,) = kept.glob("*.csv")
    text = table.read_text()
    assert text.endswith("\n"), text[-200:]
    rows = list(csv.reader(text.splitlines()))
    assert all(len(r) == len(rows[0]) for r in rows), "every row whole"
    (flight_log,) = kept.glob("*.ulg")
    ulog = ULog(str(flight_log))
    if min_free_mb == 0:
        assert len(rows) > 100, "logged until the disk was full"
        att = ulog.get_dataset("vehicle_attitude").data["timestamp"]
        assert len(att) > 100 and att[-1] > att[0], "read to the fault"
    else:
        assert len(rows) == 1, "the header alone: nothing written below the floor"
        assert "SDLOG_MIN_FREE" in err, err[-2000:]
    assert not [p for p in kept.iterdir() if p.name.endswith(".tmp")], list(kept.iterdir())
    shutil.rmtree(kept)


def _fnv1a(name):
    """The 32-bit FNV-1a hash, as PX4 makes an event's sub-id of its name."""
    h = 0x811C9DC5
    for b in name.encode():
        h = ((h ^ b) * 0x01000193) & 0xFFFFFFFF
    return h
