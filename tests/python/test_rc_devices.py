"""An RC receiver on a serial port, flown by frames made by crsf-parser (PyPI), which nobody here
wrote: the autopilot reads CRSF's RC_CHANNELS_PACKED and LINK_STATISTICS from a pseudo-terminal
and a pymavlink ground station watches what it makes of them.

The flight is a pilot's: the channels say exactly what crsf-parser encoded (RC_CHANNELS), the
link's quality goes to RC_CHANNELS and RADIO_STATUS, the mode switch enters its slots' modes,
the stick gesture arms, the throttle takes off in Position mode, the sticks take over from Hold,
and the transmitter switched off is lost sticks: NAV_RCL_ACT's Return lands the vehicle.
"""

import csv as csvlib
import math
import os
import signal
import subprocess
import threading
import time
import tty

import pytest
import select
import struct

from crsf_parser.frames import crsf_frame
from crsf_parser.handling import crsf_build_frame, crsf_crc
from crsf_parser.payloads import PacketsTypes
from pymavlink import mavutil

from conftest import ROOT, Daemon, binary, free_udp_port, run_sitl
from test_ground_station import armed, ready_to_arm, wait

# CRSF's channel values: 172 (988 µs), 992 (1500 µs), 1811 (2012 µs).
LOW, MID, HIGH = 172, 992, 1811
LINK = {
    "uplink_rssi_ant_1": 64, "uplink_rssi_ant_2": 70, "uplink_link_quality": 93,
    "uplink_snr": 9, "diversity_active_antenna": "ANTENNA_1", "rf_mode": "RF_150_FPS",
    "uplink_tx_power": "TX_POWER_100_MW", "downlink_rssi": 75, "downlink_link_quality": 88,
    "downlink_snr": 7,
}


def us(ticks):
    """A CRSF value as a pulse width (TBS: 1500 µs at 992, 0.625 µs a step)."""
    return round(1500 + (ticks - 992) * 0.625)


def mode_switch(slot):
    """The channel value that puts the mode switch in the middle of `slot` (0–5: COM_FLTMODE1
    to 6; its travel from RC5_MIN to RC5_MAX, 1000 to 2000 µs, cut in six)."""
    pulse = 1000 + (slot + 0.5) / 6 * 1000
    return round(992 + (pulse - 1500) / 0.625)


def channels_frame(channels):
    """RC_CHANNELS_PACKED of `channels` (channel 1 first), built by crsf-parser. Its `channels`
    array reads the byte-swapped payload big-endian, so its first element is channel 16: the
    channels go in last first, and channel 1 lands in the payload's first 11 bits, where
    TBS's specification, ExpressLRS and Betaflight put it (checked)."""
    frame = crsf_build_frame(PacketsTypes.RC_CHANNELS_PACKED, {"channels": channels[::-1]})
    assert (frame[3] | frame[4] << 8) & 0x7FF == channels[0]
    return frame


class Transmitter:
    """An ExpressLRS receiver's output: RC_CHANNELS_PACKED at 50 Hz and LINK_STATISTICS at 5 Hz,
    built by crsf-parser, on a pseudo-terminal whose far end (`device`) the autopilot opens.
    AETR: channel 1 roll, 2 pitch, 3 throttle, 4 yaw, 5 the mode switch."""

    def __init__(self):
        self.master, slave = os.openpty()
        tty.setraw(self.master)
        self.device = os.ttyname(slave)
        self._slave = slave
        self.channels = [MID] * 16
        self.channels[2] = LOW
        self.on = True
        # What the autopilot sends back (telemetry for the transmitter).
        self.heard = bytearray()
        self.running = True
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def set(self, **named):
        for name, value in named.items():
            self.channels[["roll", "pitch", "throttle", "yaw", "mode"].index(name)] = value

    def _read_back(self):
        if select.select([self.master], [], [], 0)[0]:
            self.heard += os.read(self.master, 4096)

    def told(self):
        """The telemetry frames heard, by type, each's CRC checked by crsf-parser's
        `crsf_crc`: (type, payload bytes)."""
        frames, data, i = {}, bytes(self.heard), 0
        while i + 2 < len(data):
            if data[i] != 0xC8 or not 2 <= data[i + 1] <= 62 or i + 2 + data[i + 1] > len(data):
                i += 1
                continue
            n = data[i + 1]
            body, crc = data[i + 2:i + 1 + n], data[i + 1 + n]
            assert crsf_crc(body) == crc, data[i:i + 2 + n]
            frames.setdefault(body[0], []).append(data[i:i + 2 + n])
            i += 2 + n
        return frames

    def _run(self):
        k = 0
        while self.running:
            self._read_back()
            if self.on:
                frame = channels_frame(self.channels)
                if k % 10 == 0:
                    frame += crsf_build_frame(PacketsTypes.LINK_STATISTICS, LINK)
                os.write(self.master, frame)
            k += 1
            time.sleep(0.02)  # the receiver's frame period, not a wait for the vehicle

    def close(self):
        self.running = False
        self.thread.join()
        os.close(self.master)
        os.close(self._slave)


@pytest.fixture
def piloted(tmp_path):
    tx = Transmitter()
    d = Daemon(tmp_path, "udpout://127.0.0.1:{port}?bind=0",
               ap_args=["--rc", f"serial://{tx.device}?protocol=crsf"])
    try:
        assert d.gcs.wait_heartbeat(timeout=30), "no heartbeat"
        yield d.gcs, tx
    finally:
        d.close()
        tx.close()


def altitude(gcs):
    return wait(gcs, "GLOBAL_POSITION_INT", lambda m: True).relative_alt / 1000


def test_a_crsf_transmitter_flies_position_mode_switches_modes_and_fails_safe(piloted):
    gcs, tx = piloted
    gcs.mav.request_data_stream_send(1, 1, mavutil.mavlink.MAV_DATA_STREAM_ALL, 10, 1)
    # The channels as crsf-parser encoded them, the link's quality as it said it.
    tx.set(roll=1234, pitch=567, mode=mode_switch(3))
    rc = wait(gcs, "RC_CHANNELS", lambda m: m.chan1_raw == us(1234) and m.chan2_raw == us(567), 10)
    assert (rc.chancount, rc.chan3_raw, rc.chan4_raw) == (16, us(LOW), us(MID))
    assert rc.rssi == 93 * 254 // 100
    radio = wait(gcs, "RADIO_STATUS", lambda m: True, 10)
    assert (radio.rssi, radio.remrssi) == (93 * 254 // 100, 88 * 254 // 100)
    tx.set(roll=MID, pitch=MID)

    # The mode switch moved to its first slot: Position (COM_FLTMODE1).
    ready_to_arm(gcs)
    tx.set(mode=mode_switch(0))
    wait(gcs, "HEARTBEAT", lambda m: gcs.flightmode == "POSCTL", 10)

    # The stick gesture arms: throttle low, yaw right, a second.
    tx.set(yaw=HIGH)
    wait(gcs, "HEARTBEAT", armed, 10)
    tx.set(yaw=MID)
    # Throttle up climbs; centred holds.
    tx.set(throttle=1500)
    wait(gcs, "GLOBAL_POSITION_INT", lambda m: m.relative_alt > 4000, 30)
    tx.set(throttle=MID)
    wait(gcs, "GLOBAL_POSITION_INT", lambda m: abs(m.vz) < 20, 10)

    # Hold from the switch (COM_FLTMODE4); sticks beyond COM_RC_STICK_OV take over into Position.
    tx.set(mode=mode_switch(3))
    wait(gcs, "HEARTBEAT", lambda m: gcs.flightmode == "LOITER", 10)
    tx.set(roll=1500)
    wait(gcs, "HEARTBEAT", lambda m: gcs.flightmode == "POSCTL", 10)
    tx.set(roll=MID)
    # Return from the switch (COM_FLTMODE5), then Position again.
    tx.set(mode=mode_switch(4))
    wait(gcs, "HEARTBEAT", lambda m: gcs.flightmode == "RTL", 10)
    tx.set(mode=mode_switch(0))
    wait(gcs, "HEARTBEAT", lambda m: gcs.flightmode == "POSCTL", 10)

    # The telemetry a CRSF receiver passes on to the transmitter: the battery as crsf-parser
    # parses it; GPS and attitude (which crsf-parser 0.3.2 fails on: its default payload
    # refers to a field it does not have) and the flight mode (a type it does not know) by
    # TBS's layout; every CRC checked with crsf-parser's.
    battery = wait(gcs, "BATTERY_STATUS", lambda m: True, 5)
    position = wait(gcs, "GPS_RAW_INT", lambda m: True, 5)
    told = tx.told()
    volts = crsf_frame.parse(told[0x08][-1]).payload.voltage / 10
    assert abs(volts - battery.voltages[0] / 1000) < 0.3, (volts, battery)
    lat, lon = struct.unpack(">ii", told[0x02][-1][3:11])
    assert abs(lat - position.lat) < 200 and abs(lon - position.lon) < 200, (lat, lon, position)
    assert len(told[0x1E][-1]) == 10
    assert told[0x21][-1][3:-1] == b"POSCTL\0", told[0x21][-1]

    # The transmitter off: lost sticks, NAV_RCL_ACT's Return, landed, disarmed.
    assert altitude(gcs) > 2.0
    tx.on = False
    wait(gcs, "STATUSTEXT", lambda m: "manual control lost: RTL" in m.text, 10)
    wait(gcs, "HEARTBEAT", lambda m: not armed(m), 90)
    assert altitude(gcs) < 0.5


PILOT = """airframe = "quad_x"
seed = 7
duration_s = 150.0
[[pilot]]
t_s = 0.0
switch = 0        # Position (COM_FLTMODE1)
throttle = 0.0
[[pilot]]
t_s = 8.0
yaw = 1.0         # the arm gesture
[[pilot]]
t_s = 10.0
yaw = 0.0
throttle = 0.85   # climb
[[pilot]]
t_s = 14.0
throttle = 0.5    # hold
[[pilot]]
t_s = 35.0
switch = 4        # Return (COM_FLTMODE5)
[[pilot]]
t_s = 40.0
switch = 0        # Position again
[[pilot]]
t_s = 45.0
transmitter = false
"""


def fly_piloted(tmp_path, gps_device, rc="crsf"):
    """The scenario's pilot flies sitl's CRSF receiver on a pseudo-terminal, in lockstep; the GPS
    a u-blox M9 on another (`gps_device`) or HIL_GPS. Returns the autopilot's stderr, both
    summaries and the flight CSV's rows."""
    scenario = tmp_path / "pilot.toml"
    scenario.write_text(PILOT)
    port = free_udp_port()
    sitl = run_sitl(["--scenario", str(scenario), "--mode", "lockstep", "--rc-device", rc,
                     *(["--gps-device", "m9"] if gps_device else [])], port)
    devices = {}
    for _ in range(2 if gps_device else 1):
        kind, _, path = sitl.stdout.readline().strip().partition(": ")
        devices[kind] = path
    gps = ["--gps", f"serial://{devices['sitl gps']}"] if gps_device else []
    csv = tmp_path / f"piloted-{rc}-{'gps' if gps_device else 'hil'}.csv"
    ap = subprocess.Popen(
        [str(binary("autopilot")), "--params-dir", str(ROOT / "params"),
         "--source", f"udp://127.0.0.1:{port}", *gps,
         "--rc", f"serial://{devices['sitl rc']}?protocol={rc}", "--mavlink", "none",
         "--param-store", "none", "--log-dir", "none", "--flight-csv", str(csv)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        sitl_out, _ = sitl.communicate(timeout=300)
    finally:
        sitl.kill()
        # Ctrl-C twice: the simulator has ended, no frame will come to land on.
        ap.send_signal(signal.SIGINT)
        try:
            ap.wait(timeout=2)
        except subprocess.TimeoutExpired:
            ap.send_signal(signal.SIGINT)
        ap_out, ap_err = ap.communicate(timeout=60)
    summary = lambda text, name: dict(  # noqa: E731
        kv.split("=", 1) for kv in next(l for l in text.splitlines()
                                        if l.startswith(name)).split()[2:] if "=" in kv)
    with open(csv) as f:
        rows = list(csvlib.DictReader(f))
    return ap_err, summary(ap_out, "autopilot summary:"), summary(sitl_out, "sitl summary:"), rows


def test_a_piloted_lockstep_flight_on_a_crsf_receiver_and_a_ublox_only(tmp_path):
    err, ap, sim, rows = fly_piloted(tmp_path, gps_device=True)
    said = [l for l in err.splitlines() if "RC " in l or "GPS configured" in l]
    for expected in ['GPS configured', 'RC arm gesture', 'RC mode switch mode="RTL"',
                     'RC mode switch mode="POSCTL"']:
        assert any(expected in l for l in said), (expected, said)
    assert sim["landed"] == "true" and ap["disarmed"] == "true", (sim, ap)
    flown = [r for r in rows if r["armed"] == "1"]
    assert max(-float(r["d_m"]) for r in flown) > 5.0
    # After the transmitter went off (45 s): NAV_RCL_ACT's Return flew it down.
    after = {r["mode"] for r in flown if float(r["t_s"]) > 46.0}
    assert after == {"RTL"}, after
    # The switch to Return at 35 s (a frame then: CRSF's go every 20 ms from 0) is flown on the
    # step of the sensor frame it came with: the simulator writes it before that frame.
    first_rtl = next(float(r["t_s"]) for r in flown if r["mode"] == "RTL")
    assert 35.0 <= first_rtl <= 35.0 + 0.004, first_rtl

    # The same flight on HIL_GPS: the estimate's error against the truth in the hold.
    _, _, _, hil_rows = fly_piloted(tmp_path, gps_device=False)

    def hold_error(rows):
        hold = [r for r in rows if 16.0 <= float(r["t_s"]) <= 34.0 and r["true_n_m"] != ""]
        sq = [(float(r["n_m"]) - float(r["true_n_m"])) ** 2
              + (float(r["e_m"]) - float(r["true_e_m"])) ** 2 for r in hold]
        return math.sqrt(sum(sq) / len(sq))

    errors = hold_error(hil_rows), hold_error(rows)
    print(f"estimate's horizontal error in the hold: HIL_GPS {errors[0]:.3f} m, u-blox M9 and "
          f"CRSF on pseudo-terminals {errors[1]:.3f} m")
    assert abs(errors[1] - errors[0]) <= 0.1, errors


def test_an_sbus_receiver_flies_the_same_and_its_failsafe_flag_is_lost_sticks(tmp_path):
    err, ap, sim, rows = fly_piloted(tmp_path, gps_device=False, rc="sbus")
    assert 'RC arm gesture' in err and 'RC mode switch mode="RTL"' in err, err[-2000:]
    assert sim["landed"] == "true" and ap["disarmed"] == "true", (sim, ap)
    flown = [r for r in rows if r["armed"] == "1"]
    assert max(-float(r["d_m"]) for r in flown) > 5.0
    assert {r["mode"] for r in flown if float(r["t_s"]) > 46.0} == {"RTL"}
