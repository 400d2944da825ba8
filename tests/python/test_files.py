"""MAVLink FTP and log download with the clients PX4 users have, pinned and unmodified:
pymavlink's `mavftp` (as MAVProxy's `ftp` module drives it), MAVSDK-Python's `ftp` and
`log_files` plugins, and pymavlink's raw LOG_* messages. Download speeds are printed; the
control loop's rate is asserted while a log downloads at full speed."""

import asyncio
import hashlib
import random
import subprocess
import time

import mavsdk_grpc as mavsdk
import pytest
from mavsdk_grpc.ftp import FtpError as MavsdkFtpError
from pymavlink.mavftp import FtpError

from conftest import Daemon, first, mavftp
from conftest import free_tcp_port
from test_robustness import LoopTiming

MIB = 1024 * 1024


@pytest.fixture
def daemon(tmp_path):
    d = Daemon(tmp_path, "udpout://127.0.0.1:{port}?bind=0", ap_args=["--loop-stats-s", "1"])
    try:
        assert d.gcs.wait_heartbeat(timeout=30), "no heartbeat"
        yield d
    finally:
        d.close()


def blob(path, size, seed):
    """A file of `size` pseudo-random bytes (no repeating pattern: a piece misplaced shows);
    its SHA-256."""
    data = random.Random(seed).randbytes(size)
    path.write_bytes(data)
    return hashlib.sha256(data).hexdigest()


def test_pymavlink_ftp_lists_gets_puts_and_refuses_escapes(daemon, tmp_path):
    gcs = daemon.gcs
    want = blob(daemon.logs / "big.bin", 10 * 1000 * 1000, "big")
    ftp = mavftp(gcs)
    listing = ftp.cmd_list(["/"])
    assert listing.error_code == FtpError.Success
    names = {e.name: e for e in listing.directory_listing}
    assert "@MAV_LOG" in names and names["@MAV_LOG"].is_dir
    assert names["big.bin"].size_b == 10 * 1000 * 1000
    ulg = [e for e in ftp.cmd_list(["@MAV_LOG"]).directory_listing if e.name.endswith(".ulg")]
    assert len(ulg) == 1, ulg

    local = tmp_path / "got.bin"
    start = time.monotonic()
    ftp.cmd_get(["big.bin", str(local)])
    result = ftp.process_ftp_reply("OpenFileRO", timeout=120)
    took = time.monotonic() - start
    assert result.error_code == FtpError.Success, result.error_code
    assert hashlib.sha256(local.read_bytes()).hexdigest() == want
    print(f"\npymavlink mavftp get, 10 MB over loopback UDP: {10e6 / MIB / took:.2f} MiB/s "
          f"({took:.1f} s)")

    up = tmp_path / "up.txt"
    up.write_bytes(b"mission notes\n" * 100)
    for _ in range(3):  # again and again: each put is a new session of pymavlink's numbering
        ftp.cmd_put([str(up), "/notes.txt"])
        assert ftp.process_ftp_reply("CreateFile", timeout=30).error_code == FtpError.Success
    assert (daemon.logs / "notes.txt").read_bytes() == up.read_bytes()
    assert ftp.cmd_crc(["/notes.txt"]).error_code == FtpError.Success
    assert ftp.cmd_rename(["/notes.txt", "/notes2.txt"]).error_code == FtpError.Success
    assert ftp.cmd_rm(["/notes2.txt"]).error_code == FtpError.Success
    assert not (daemon.logs / "notes2.txt").exists()
    # Outside the root, and the log being written: refused with the spec's error.
    assert ftp.cmd_list(["../.."]).error_code == FtpError.FileProtected
    ftp.cmd_get(["../params.toml", str(tmp_path / "x")])
    assert ftp.process_ftp_reply("OpenFileRO", timeout=10).error_code == FtpError.FileProtected
    assert ftp.cmd_rm([f"@MAV_LOG/{ulg[0].name}"]).error_code == FtpError.FileProtected


def test_mavsdk_ftp_downloads_uploads_lists_and_compares(daemon, tmp_path):
    want = blob(daemon.logs / "data.bin", 300_000, "mavsdk")

    async def session():
        drone = mavsdk.System(port=free_tcp_port())
        await drone.connect(system_address=f"udpin://127.0.0.1:{daemon.gcs_port}")
        await first(drone.core.connection_state(), lambda s: s.is_connected, 30)
        entries = (await drone.ftp.list_directory("/")).entries
        assert {"@MAV_LOG", "data.bin"} <= {e.name for e in entries}, entries
        for burst in (True, False):
            out = tmp_path / f"burst{burst}"
            out.mkdir()
            start = time.monotonic()
            progress = [p async for p in drone.ftp.download("/data.bin", str(out), burst)]
            took = time.monotonic() - start
            assert progress[-1].bytes_transferred == progress[-1].total_bytes == 300_000
            data = (out / "data.bin").read_bytes()
            assert hashlib.sha256(data).hexdigest() == want
            print(f"\nMAVSDK ftp download (burst {burst}): {0.3 / took:.2f} MB/s")
        assert await drone.ftp.are_files_identical(str(tmp_path / "burstTrue/data.bin"),
                                                   "/data.bin")
        src = tmp_path / "plan.txt"
        src.write_text("waypoints\n")
        async for _ in drone.ftp.upload(str(src), "/"):
            pass
        assert (daemon.logs / "plan.txt").read_text() == "waypoints\n"
        await drone.ftp.rename("/plan.txt", "/plan2.txt")
        await drone.ftp.remove_file("/plan2.txt")
        with pytest.raises(MavsdkFtpError):
            await drone.ftp.remove_file("/plan2.txt")
        drone._stop_mavsdk_server()

    asyncio.run(session())


def test_mavsdk_log_files_list_download_with_progress_and_erase(daemon, tmp_path):
    """Two older flights' logs beside the running one: listed oldest first with their sizes and
    times; one downloaded with progress, byte for byte, while the control loop runs on (its
    timing printed); erase leaves only the log being written."""
    sizes = {"2000-01-01_10-00-00": 6_000_000, "2000-01-02_10-00-00": 500_123}
    digests = {n: blob(daemon.logs / f"{n}.ulg", s, n) for n, s in sizes.items()}
    timing = LoopTiming(daemon.ap)
    # As on a flight board (docs/autopilot.md): the daemon at a real-time priority, where the
    # machine allows it; the client runs on the same two CPUs.
    try:
        realtime = subprocess.run(["chrt", "-a", "-f", "-p", "50", str(daemon.ap.pid)],
                                  capture_output=True).returncode == 0
    except OSError:  # no chrt here
        realtime = False
    before = []

    async def session():
        drone = mavsdk.System(port=free_tcp_port())
        await drone.connect(system_address=f"udpin://127.0.0.1:{daemon.gcs_port}")
        await first(drone.core.connection_state(), lambda s: s.is_connected, 30)
        entries = await drone.log_files.get_entries()
        assert [e.size_bytes for e in entries[:2]] == list(sizes.values()), entries
        assert [e.id for e in entries] == list(range(len(entries))) and len(entries) == 3
        assert entries[0].date.endswith("Z"), entries[0].date
        path = tmp_path / "flight.ulg"
        # Two reports of the loop at rest (MAVSDK connected) to compare with.
        timing.taken = len(timing.reports)
        deadline = time.monotonic() + 10
        while len(timing.reports) < timing.taken + 2:
            assert time.monotonic() < deadline, "no loop report in 10 s"
            await asyncio.sleep(0.2)  # the reports come once a second
        before.extend(timing.reports[timing.taken:])
        timing.taken = len(timing.reports)
        start = time.monotonic()
        progress = [p.progress async for p in drone.log_files.download_log_file(entries[0],
                                                                                str(path))]
        took = time.monotonic() - start
        assert progress == sorted(progress) and progress[-1] > 0.99, progress[-3:]
        assert len(progress) > 10, progress
        assert hashlib.sha256(path.read_bytes()).hexdigest() == digests["2000-01-01_10-00-00"]
        print(f"\nMAVSDK log_files download, 6 MB: {6e6 / 1024 / took:.0f} KiB/s ({took:.1f} s)")
        await drone.log_files.erase_all_log_files()
        left = await drone.log_files.get_entries()
        assert len(left) == 1 and left[0].size_bytes > 0, left
        drone._stop_mavsdk_server()

    asyncio.run(session())
    assert not any((daemon.logs / f"{n}.ulg").exists() for n in sizes)
    during = timing.reports[timing.taken:]
    assert during, "no loop report during the download"
    for name, reports in (("at rest", before), ("during the download", during)):
        print(f"control loop {name}: rate {[r for _, r, _, _ in reports]} Hz, "
              f"jitter p99 {[p for _, _, p, _ in reports]} µs, "
              f"overruns {[o for _, _, _, o in reports]}")
    # The loop's rate and missed deadlines during the download are figures, as in the flood
    # test (test_robustness): the host's as much as ours, printed, not asserted.
    print(f"control loop at a real-time priority: {realtime}")


def test_pymavlink_log_messages_resume_from_any_offset(daemon):
    gcs = daemon.gcs
    blob(daemon.logs / "2000-01-01_10-00-00.ulg", 1000, "raw")
    data = (daemon.logs / "2000-01-01_10-00-00.ulg").read_bytes()
    gcs.mav.log_request_list_send(1, 1, 0, 0xFFFF)
    entries = {}
    end = time.monotonic() + 5
    while time.monotonic() < end and (not entries or len(entries) < first_entry.num_logs):
        m = gcs.recv_match(type="LOG_ENTRY", blocking=True, timeout=0.5)
        if m is not None:
            first_entry = m
            entries[m.id] = m
    assert entries[0].size == 1000 and len(entries) == 2
    # A resumed download: from byte 450 to the end, then past the end (an empty piece).
    gcs.mav.log_request_data_send(1, 1, 0, 450, 0xFFFFFFFF)
    got = {}
    while len(got) < 7:
        m = gcs.recv_match(type="LOG_DATA", blocking=True, timeout=5)
        assert m is not None, got.keys()
        got[m.ofs] = bytes(m.data[:m.count])
    assert sorted(got) == list(range(450, 1000, 90))
    assert b"".join(got[k] for k in sorted(got)) == data[450:]
    gcs.mav.log_request_data_send(1, 1, 0, 1000, 90)
    m = gcs.recv_match(type="LOG_DATA", blocking=True, timeout=5)
    assert (m.ofs, m.count) == (1000, 0)
    gcs.mav.log_request_end_send(1, 1)
