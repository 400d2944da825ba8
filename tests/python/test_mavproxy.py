"""The vehicle flown from MAVProxy's console, headless, as a user types it: sitl + autopilot over
UDP, MAVProxy (pinned, installed without its GUI dependencies) on the port the autopilot pushes
to. Every wait is on what MAVProxy prints, with a time-out; the flight is checked afterwards in
the telemetry log MAVProxy wrote."""

import queue
import re
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from pymavlink import mavutil

from conftest import Daemon

MAVPROXY = Path(sys.executable).parent / "mavproxy.py"


class Console:
    """MAVProxy with its console on pipes: type a line, expect a line."""

    def __init__(self, port, cwd):
        self.proc = subprocess.Popen(
            [sys.executable, str(MAVPROXY), f"--master=udpin:127.0.0.1:{port}"],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
            text=True, cwd=cwd, bufsize=1,
        )
        self.lines = queue.Queue()
        self.seen = []
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self):
        for line in self.proc.stdout:
            self.lines.put(line.rstrip())

    def type(self, line):
        self.proc.stdin.write(line + "\n")
        self.proc.stdin.flush()

    def expect(self, pattern, timeout=30):
        """The first line (from now) matching `pattern`, within `timeout` s."""
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            try:
                line = self.lines.get(timeout=0.2)
            except queue.Empty:
                continue
            self.seen.append(line)
            if re.search(pattern, line):
                return line
        pytest.fail(f"MAVProxy never printed /{pattern}/; it printed:\n" + "\n".join(self.seen))

    def printed(self, pattern, timeout=30):
        """A line matching `pattern`, already printed or within `timeout` s (for what MAVProxy
        prints as a heartbeat arrives, which may come before or after the command's ack)."""
        done = [line for line in self.seen if re.search(pattern, line)]
        return done[0] if done else self.expect(pattern, timeout)

    def close(self):
        """End of input: MAVProxy shuts down cleanly and flushes its log."""
        self.proc.stdin.close()
        try:
            self.proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()


def test_mavproxy_connects_arms_takes_off_and_lands(tmp_path):
    assert MAVPROXY.exists(), f"{MAVPROXY}: run the tests through tools/test.sh, which installs it"
    daemon = Daemon(tmp_path, "udpout://127.0.0.1:{port}?bind=0", connect=False)
    console = Console(daemon.gcs_port, tmp_path)
    try:
        console.expect(r"Detected vehicle 1:1")
        console.expect(r"Mode LOITER")
        console.expect(r"Received \d+ parameters")
        # Parameters from the console: the pre-flight auto-disarm off, so that the script's
        # pace does not matter; the take-off altitude read.
        console.type("param set COM_DISARM_PRFLT 0")
        console.type("param show MIS_TAKEOFF_ALT")
        console.expect(r"MIS_TAKEOFF_ALT\s+2\.5")
        # Arm as soon as the vehicle allows it (the estimator aligns first).
        end = time.monotonic() + 60
        while True:
            console.type("arm throttle")
            ack = console.expect(r"COMPONENT_ARM_DISARM: \w+")
            if "ACCEPTED" in ack:
                break
            assert time.monotonic() < end, "never armable"
            console.expect(r"arming refused", 5)
            time.sleep(0.5)  # the retry interval of a patient operator
        # The heartbeat's ARMED may beat the ack, and the prompt may precede it on its line.
        console.printed(r"(^|> )ARMED$")
        # MAVProxy's take-off sends NAV_TAKEOFF with the altitude in param7, which PX4 (and this
        # vehicle) read as AMSL, at least MIS_TAKEOFF_ALT above home: 0 means "the default".
        console.type("takeoff 0")
        console.expect(r"NAV_TAKEOFF: ACCEPTED")
        console.expect(r"Mode TAKEOFF")
        console.expect(r"Mode LOITER")
        console.type("long NAV_LAND")
        console.expect(r"NAV_LAND: ACCEPTED")
        console.expect(r"Mode LAND")
        console.expect(r"DISARMED", 60)
    finally:
        console.close()
        daemon.close()

    assert "COM_DISARM_PRFLT = 0.0" in daemon.store.read_text()
    log = mavutil.mavlink_connection(str(tmp_path / "mav.tlog"))
    # (Its last second may not be in the file: MAVProxy's log writer does not always drain its
    # queue at exit. The disarm was seen on the console above.)
    top, armed_seen = 0.0, False
    while (m := log.recv_match(type=["GLOBAL_POSITION_INT", "HEARTBEAT"])) is not None:
        if m.get_srcSystem() != 1 or m.get_srcComponent() != 1:
            continue
        if m.get_type() == "GLOBAL_POSITION_INT":
            top = max(top, m.relative_alt / 1000)
        else:
            armed_seen |= bool(m.base_mode & mavutil.mavlink.MAV_MODE_FLAG_SAFETY_ARMED)
    assert armed_seen
    assert 2.2 < top < 2.9, f"climbed to {top:.2f} m, MIS_TAKEOFF_ALT is 2.5"
