"""A GPS receiver on a serial port, checked by tools nobody here wrote.

- The simulator plays a u-blox (M8: the legacy configuration at 9 600 baud; M10: CFG-VALSET only)
  on a pseudo-terminal, a relay records the line both ways, and the autopilot flies on it: every
  byte the autopilot sent parses in pyubx2 as the configuration it should be, and every byte the
  receiver sent at the agreed baud parses too; the autopilot's flight log holds the positions
  and times pyubx2 decoded.
- pyubx2 plays the receiver: it parses the autopilot's configuration and answers it, then sends
  solutions it built; the flight log holds what it sent.
- Recordings of real receivers (gpsd's regression logs: u-blox M8N and ZED-F9P UBX, NMEA from
  u-blox, MediaTek, SiRF, Quectel and an RTK receiver) play into the autopilot and give, to 1 mm
  and 1 ms, the positions and times pyubx2 and pynmeagps decode.
"""

import calendar
import csv as csvlib
import io
import math
import os
import signal
import subprocess
import sys
import time
from datetime import datetime, timezone
from pathlib import Path

import pytest
from pynmeagps import NMEAReader
from pyubx2 import UBXMessage, UBXReader
from pyulog import ULog

from conftest import ROOT, binary, free_udp_port, run_sitl
from gps_wire import GpsRelay, Pyubx2Receiver, parse_all, parse_commands

sys.path.insert(0, str(ROOT / "tools"))
import gps_captures  # noqa: E402

MM_DEG = 1e-3 / 111_320  # a millimetre of latitude, in degrees


def gps_rows(log_dir):
    """The flight log's vehicle_gps_position rows, as pyulog reads them."""
    log = next(Path(log_dir).glob("*.ulg"))
    data = ULog(str(log), ["vehicle_gps_position"]).get_dataset("vehicle_gps_position").data
    return [{k: data[k][i] for k in data} for i in range(len(data["timestamp"]))]


def pvt_utc_usec(p):
    """NAV-PVT's UTC time as pyubx2 decodes its fields (µs since the Unix epoch)."""
    whole = calendar.timegm((p.year, p.month, p.day, p.hour, p.min, p.second))
    return whole * 1_000_000 + p.nano // 1000


def same_place(r, lat, lon, alt):
    return (abs(r["latitude_deg"] - lat) < MM_DEG and abs(r["longitude_deg"] - lon) < MM_DEG
            and abs(r["altitude_msl_m"] - alt) < 1e-3)


def assert_rows_are(rows, expected, what, undated=0):
    """Every logged solution is one of `expected` (lat, lon, alt, utc µs), to 1 mm and 1 ms, and
    nearly every expected one was logged. `undated`: how many may come before the receiver
    said the date (an NMEA epoch whose RMC comes after its velocity), logged at the computer's
    time: each is still one of the positions."""
    by_time = {e[3] // 1000: e for e in expected}
    for r in rows:
        key = int(r["time_utc_usec"]) // 1000
        if key not in by_time and undated > 0:
            assert any(same_place(r, *e[:3]) for e in expected), (what, r)
            undated -= 1
            continue
        assert key in by_time, f"{what}: a logged solution at {key} ms decoded by nobody"
        lat, lon, alt, _ = by_time[key]
        assert abs(r["latitude_deg"] - lat) < MM_DEG, (what, r, lat)
        assert abs(r["longitude_deg"] - lon) < MM_DEG, (what, r, lon)
        assert abs(r["altitude_msl_m"] - alt) < 1e-3, (what, r, alt)
    assert len(rows) >= 0.9 * len(expected), f"{what}: {len(rows)} of {len(expected)} logged"


class Autopilot:
    """The autopilot on the embedded simulator in real time, its GPS on `device`, its flight log
    in `tmp_path/logs`; Ctrl-C ends it."""

    def __init__(self, tmp_path, gps_url):
        self.logs = tmp_path / "logs"
        self.err = tmp_path / "autopilot.err"
        self.proc = subprocess.Popen(
            [str(binary("autopilot")), "--params-dir", str(ROOT / "params"), "--sim",
             "--gps", gps_url, "--mavlink", "none", "--param-store", "none",
             "--log-dir", str(self.logs)],
            stdout=subprocess.DEVNULL, stderr=open(self.err, "w"), text=True)

    def log(self):
        return self.err.read_text()

    def wait_for(self, text, timeout=20):
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            if text in self.log():
                return
            assert self.proc.poll() is None, self.log()[-3000:]
            time.sleep(0.05)
        pytest.fail(f"the autopilot never said {text!r}:\n{self.log()[-3000:]}")

    def stop(self):
        self.proc.send_signal(signal.SIGINT)
        self.proc.wait(timeout=30)
        assert self.proc.returncode == 0, self.log()[-3000:]
        assert "panicked" not in self.log()


# Each model: (its power-on baud, the interface it is configured through, what the autopilot
# must have sent it).
MODELS = {
    "m8": (9600, "CFG-PRT/CFG-RATE/CFG-MSG", {"MON-VER", "CFG-PRT", "CFG-RATE", "CFG-MSG"}),
    "m10": (38400, "CFG-VALSET", {"MON-VER", "CFG-VALSET"}),
}


def fly_through_relay(tmp_path, model, options):
    """A lockstep take-off, hover and landing, the GPS sitl's `model` seen through a relay
    (`GpsRelay`), the autopilot's `--gps` URL options `options`. Returns the autopilot's
    completed run (landed), the relay and the log directory."""
    port = free_udp_port()
    # Lockstep at up to 4× real time: the relay takes milliseconds of wall time for each chunk,
    # which at full lockstep speed would be a large part of a second of the receiver's time.
    sitl = run_sitl(["--gps-device", model, "--mode", "lockstep", "--speed", "4",
                     "--duration", "60"], port)
    relay = None
    try:
        first = sitl.stdout.readline()
        assert first.startswith("sitl gps: "), first
        relay = GpsRelay(first.split(": ", 1)[1].strip())
        logs = tmp_path / "logs"
        ap = subprocess.run(
            [str(binary("autopilot")), "--params-dir", str(ROOT / "params"),
             "--source", f"udp://127.0.0.1:{port}",
             "--gps", f"serial://{relay.device}?{options}",
             "--takeoff", "5", "--hover", "10", "--mavlink", "none",
             "--param-store", "none", "--log-dir", str(logs)],
            capture_output=True, text=True, timeout=180)
    finally:
        sitl.kill()
        sitl.wait()
        if relay:
            relay.close()
    assert ap.returncode == 0, ap.stderr[-3000:]
    assert "landed=true" in ap.stdout, ap.stdout
    return ap, relay, logs


@pytest.mark.parametrize("model", sorted(MODELS))
def test_a_flight_on_the_simulators_ublox_parses_in_pyubx2_both_ways(tmp_path, model):
    default_baud, interface, sent = MODELS[model]
    ap, relay, logs = fly_through_relay(tmp_path, model, "baud=115200")
    assert f"GPS found port=\"{relay.device}\" baud={default_baud}" in ap.stderr, ap.stderr[-3000:]
    assert f'interface="{interface}"' in ap.stderr, ap.stderr[-3000:]

    # What the autopilot sent: all of it parses, and it is what configures this model.
    sent_bytes = relay.sent()
    commands = parse_commands(sent_bytes)
    identities = {c.identity for c in commands}
    assert sent <= identities, identities
    if model == "m10":
        valset = [c for c in commands if c.identity == "CFG-VALSET" and
                  hasattr(c, "CFG_MSGOUT_UBX_NAV_PVT_UART1")][-1]
        assert (valset.CFG_MSGOUT_UBX_NAV_PVT_UART1, valset.CFG_RATE_MEAS,
                valset.CFG_UART1OUTPROT_NMEA) == (1, 200, 0), valset
        assert (valset.CFG_MSGOUT_UBX_NAV_PVT_USB, valset.CFG_USBOUTPROT_NMEA) == (1, 0), valset
    else:
        prt = [c for c in commands if c.identity == "CFG-PRT"][-1]
        assert (prt.baudRate, prt.outUBX, prt.outNMEA) == (115200, 1, 0), prt

    # What the receiver sent while the line was at its baud (the scan also heard it misread at
    # others): all of it parses.
    switch = next(c for c in commands if c.identity in ("CFG-PRT", "CFG-VALSET"))
    raw = switch.serialize()
    answers = parse_all(relay.heard_whole(default_baud, (sent_bytes.index(raw) + len(raw), 115200)))
    kinds = {m.identity for m in answers}
    assert {"MON-VER", "ACK-ACK", "NAV-PVT", "NAV-DOP"} <= kinds, kinds
    assert "ACK-NAK" not in kinds, kinds
    pvts = [m for m in answers if m.identity == "NAV-PVT"]
    assert_rows_are(gps_rows(logs),
                    [(p.lat, p.lon, p.hMSL * 1e-3, pvt_utc_usec(p)) for p in pvts],
                    f"sitl's {model}")


@pytest.mark.parametrize("protver", [18.00, 27.31])
def test_pyubx2_as_the_receiver_configured_then_its_solutions_logged(tmp_path, protver):
    rx = Pyubx2Receiver(protver)
    ap = Autopilot(tmp_path, f"serial://{rx.device}?baud=115200&rate=10")
    try:
        ap.wait_for("GPS configured")
        commands = {c.identity: c for c in rx.commands}
        if protver >= 27:
            v = commands["CFG-VALSET"]
            assert (v.CFG_MSGOUT_UBX_NAV_PVT_UART1, v.CFG_MSGOUT_UBX_NAV_DOP_UART1,
                    v.CFG_RATE_MEAS, v.CFG_UART1OUTPROT_NMEA) == (1, 1, 100, 0), v
        else:
            assert commands["CFG-RATE"].measRate == 100, commands
            assert commands["CFG-PRT"].outNMEA == 0, commands
        # Solutions pyubx2 builds: both hemispheres, every fix kind.
        sent = []
        cases = [  # (fixType, gnssFixOk, diffSoln, carrSoln, invalidLlh) -> GPS_FIX_TYPE
            ((3, 1, 0, 0, 0), 3), ((3, 1, 1, 0, 0), 4), ((3, 1, 1, 1, 0), 5),
            ((3, 1, 1, 2, 0), 6), ((2, 1, 0, 0, 0), 2), ((3, 0, 0, 0, 0), 1),
            ((3, 1, 0, 0, 1), 1), ((0, 0, 0, 0, 0), 1),
        ]
        t0 = calendar.timegm((2026, 11, 29, 12, 0, 0))
        for k in range(24):
            (fix, ok, diff, carr, invalid), mav_fix = cases[k % len(cases)]
            lat, lon = (-33.8651437 + k * 1e-7) * (-1) ** k, -151.2099001 + k * 3e-7
            dop = UBXMessage("NAV", "NAV-DOP", 0, iTOW=k * 100, hDOP=0.8 + k / 100,
                             vDOP=1.2 + k / 100, pDOP=1.5)
            pvt = UBXMessage(
                "NAV", "NAV-PVT", 0, iTOW=k * 100, year=2026, month=11, day=29, hour=12,
                min=0, second=k // 10, validDate=1, validTime=1, fullyResolved=1, tAcc=20,
                nano=(k % 10) * 100_000_000, fixType=fix, gnssFixOk=ok, diffSoln=diff,
                carrSoln=carr, invalidLlh=invalid, numSV=10 + k % 5, lat=lat, lon=lon,
                height=50_000 + k, hMSL=30_000 + k * 7, hAcc=500 + 10 * k, vAcc=900 + k,
                velN=1000 - k, velE=-250, velD=30, gSpeed=1031, headMot=345.0, sAcc=120 + k,
                headAcc=5.0 + k, pDOP=1.5)
            rx.send(dop.serialize() + pvt.serialize())
            # What was sent, as pyubx2 reads its own bytes back (it rounds to the field's unit).
            back = UBXReader.parse(pvt.serialize())
            assert pvt_utc_usec(back) == (t0 + k // 10) * 1_000_000 + (k % 10) * 100_000
            back_dop = UBXReader.parse(dop.serialize())
            sent.append((back.lat, back.lon, back.hMSL * 1e-3, pvt_utc_usec(back), mav_fix,
                         back, back_dop))
            time.sleep(0.05)
        time.sleep(0.3)
    finally:
        ap.stop()
        rx.close()
    rows = [r for r in gps_rows(ap.logs) if int(r["time_utc_usec"]) >= t0 * 1_000_000]
    assert_rows_are(rows, [s[:4] for s in sent], "pyubx2's stream")
    by_time = {s[3] // 1000: s for s in sent}
    for r in rows:
        *_, mav_fix, p, d = by_time[int(r["time_utc_usec"]) // 1000]
        close = [  # (logged, pyubx2's, tolerance: the log's float32)
            (r["eph"], p.hAcc * 1e-3, 1e-6), (r["epv"], p.vAcc * 1e-3, 1e-6),
            (r["s_variance_m_s"], p.sAcc * 1e-3, 1e-6),
            (r["c_variance_rad"], math.radians(p.headAcc), 1e-6),
            (r["hdop"], d.hDOP, 1e-5), (r["vdop"], d.vDOP, 1e-5),
            (r["vel_n_m_s"], p.velN * 1e-3, 1e-6), (r["vel_e_m_s"], p.velE * 1e-3, 1e-6),
            (r["vel_d_m_s"], p.velD * 1e-3, 1e-6),
        ]
        for logged, theirs, tolerance in close:
            assert abs(logged - theirs) < tolerance, (logged, theirs, p)
        assert (r["fix_type"], r["satellites_used"]) == (mav_fix, p.numSV), (r, p)


def captures():
    folder, why = gps_captures.captures_dir()
    if folder is None:
        if os.environ.get(gps_captures.ENV_REQUIRED):
            pytest.fail(why)
        pytest.skip(why)
    return folder


class ReplayLine:
    """A pseudo-terminal pair: the autopilot opens `device`, the replay writes `far`."""

    def __init__(self):
        self.master, slave = os.openpty()
        self.device = os.ttyname(slave)
        self._slave = slave

    def write_all(self, messages, pause_s=0.01):
        for raw in messages:
            os.write(self.master, raw)
            time.sleep(pause_s)

    def close(self):
        os.close(self.master)
        os.close(self._slave)


def body(path):
    """A gpsd log without its '#' header lines."""
    lines = path.read_bytes().split(b"\n")
    start = next(i for i, line in enumerate(lines) if not line.startswith(b"#"))
    return b"\n".join(lines[start:])


@pytest.mark.parametrize("name", gps_captures.UBX)
def test_recorded_ublox_receivers_decode_as_pyubx2_decodes_them(tmp_path, name):
    data = body(captures() / name)
    messages = [(raw, p) for raw, p in UBXReader(io.BytesIO(data), quitonerror=1)
                if p is not None]
    pvts = [p for _, p in messages if p.identity == "NAV-PVT"]
    assert len(pvts) >= 20, (name, len(pvts))
    line = ReplayLine()
    ap = Autopilot(tmp_path, f"serial://{line.device}?baud=115200")
    try:
        ap.wait_for("GPS port open")
        line.write_all([raw for raw, _ in messages])
        time.sleep(0.3)
    finally:
        ap.stop()
        line.close()
    expected = [(p.lat, p.lon, p.hMSL * 1e-3, pvt_utc_usec(p)) for p in pvts
                if p.validDate and p.validTime and p.fullyResolved]
    assert_rows_are(gps_rows(ap.logs), expected, name)


def nmea_epochs(data):
    """Each epoch's (lat, lon, alt, utc µs) as pynmeagps decodes its GGA and RMC (the first GGA of
    an epoch; the date from the RMC)."""
    ggas, dates = {}, {}
    for line in data.split(b"\n"):
        line = line.strip()
        if not line.startswith(b"$"):
            continue
        try:
            m = NMEAReader.parse(line + b"\r\n")
        except Exception:
            continue
        if m.msgID == "GGA" and m.time != "" and m.lat != "" and m.time not in ggas:
            ggas[m.time] = m
        elif m.msgID == "RMC" and m.time != "" and m.date != "":
            dates[m.time] = m.date
    epochs = []
    for t, g in ggas.items():
        if t in dates:
            stamp = datetime.combine(dates[t], t, tzinfo=timezone.utc)
            epochs.append((g.lat, g.lon, float(g.alt), int(stamp.timestamp() * 1e6)))
    return epochs


@pytest.mark.parametrize("name", gps_captures.NMEA)
def test_recorded_nmea_receivers_decode_as_pynmeagps_decodes_them(tmp_path, name):
    data = body(captures() / name)
    expected = nmea_epochs(data)
    assert len(expected) >= 10, (name, len(expected))
    sentences = [line.strip() + b"\r\n" for line in data.split(b"\n") if line.startswith(b"$")]
    line = ReplayLine()
    ap = Autopilot(tmp_path, f"serial://{line.device}?protocol=nmea&baud=4800")
    try:
        ap.wait_for("GPS port open")
        line.write_all(sentences, pause_s=0.004)
        time.sleep(0.3)
    finally:
        ap.stop()
        line.close()
    assert_rows_are(gps_rows(ap.logs), expected, name, undated=1)


def fly_with(tmp_path, gps_device=None, scenario=None, hover_s=30):
    """A lockstep take-off, hover and landing on sitl (seed 7, typical sensors), its GPS as
    HIL_GPS or, with `gps_device` (a model), a receiver on a pseudo-terminal. Returns the
    autopilot's stderr, its summary (a dict) and its flight CSV's hover rows."""
    port = free_udp_port()
    args = ["--mode", "lockstep", "--seed", "7", "--sensors", "typical", "--duration", "200"]
    args += ["--gps-device", gps_device] if gps_device else []
    args += ["--scenario", str(scenario)] if scenario else []
    sitl = run_sitl(args, port)
    try:
        gps = []
        if gps_device:
            first = sitl.stdout.readline()
            assert first.startswith("sitl gps: "), first
            gps = ["--gps", "serial://" + first.split(": ", 1)[1].strip()]
        csv = tmp_path / f"{gps_device or 'hil'}.csv"
        ap = subprocess.run(
            [str(binary("autopilot")), "--params-dir", str(ROOT / "params"),
             "--source", f"udp://127.0.0.1:{port}", *gps, "--takeoff", "5",
             "--hover", str(hover_s), "--mavlink", "none", "--param-store", "none",
             "--log-dir", "none", "--flight-csv", str(csv)],
            capture_output=True, text=True, timeout=180)
    finally:
        sitl.kill()
        sitl.wait()
    assert ap.returncode == 0, ap.stderr[-3000:]
    line = next(l for l in ap.stdout.splitlines() if l.startswith("autopilot summary:"))
    summary = dict(kv.split("=", 1) for kv in line.split()[2:] if "=" in kv)
    with open(csv) as f:
        # The hover's rows that carry the simulator's truth (HIL_STATE_QUATERNION, 50 Hz).
        rows = [r for r in csvlib.DictReader(f)
                if r["mode"] == "LOITER" and r["armed"] == "1" and r["true_n_m"] != ""]
    return ap.stderr, summary, rows


def horizontal_error_rms(rows):
    """The estimate's horizontal distance from the truth, RMS over the rows (m)."""
    sq = [(float(r["n_m"]) - float(r["true_n_m"])) ** 2 + (float(r["e_m"]) - float(r["true_e_m"])) ** 2
          for r in rows]
    return math.sqrt(sum(sq) / len(sq))


def test_a_flight_on_a_device_gps_holds_its_place_as_on_hil_gps(tmp_path):
    _, hil, hil_rows = fly_with(tmp_path)
    _, dev, dev_rows = fly_with(tmp_path, gps_device="m9")
    errors = horizontal_error_rms(hil_rows), horizontal_error_rms(dev_rows)
    drifts = float(hil["hover_drift_rms_m"]), float(dev["hover_drift_rms_m"])
    print(f"estimate's horizontal error RMS: HIL_GPS {errors[0]:.3f} m, u-blox M9 on a "
          f"pseudo-terminal {errors[1]:.3f} m; hover drift RMS {drifts[0]:.3f} m, {drifts[1]:.3f} m")
    assert len(dev_rows) > 1000 and len(hil_rows) > 1000
    assert abs(errors[1] - errors[0]) <= 0.1, errors
    assert abs(drifts[1] - drifts[0]) <= 0.1, drifts
    assert dev["landed"] == hil["landed"] == "true"


def test_a_receiver_unplugged_in_flight_is_a_lost_gps_then_found_again(tmp_path, scenario):
    path = scenario('airframe = "quad_x"\nduration_s = 200.0\n'
                    '[[events]]\nt_s = 20.0\nkind = "sensor_off"\nsensor = "gps"\nduration_s = 4.0\n')
    err, summary, _ = fly_with(tmp_path, gps_device="m9", scenario=path)
    said = [l for l in err.splitlines() if "GPS" in l or "failsafe" in l]
    assert sum("GPS silent" in l for l in said) == 1, said
    assert sum("GPS lost: looking for it" in l for l in said) == 1, said
    assert sum('GPS configured' in l for l in said) == 2, said
    assert any("failsafe: position estimate invalid" in l for l in said), said
    assert summary["landed"] == "true" and summary["failsafe"] == "true", summary


def test_nmea_built_by_pynmeagps_decodes_as_pynmeagps_reads_it(tmp_path):
    from pynmeagps import GET, NMEAMessage
    from datetime import date, time as clock
    line = ReplayLine()
    ap = Autopilot(tmp_path, f"serial://{line.device}?protocol=nmea&baud=38400")
    sentences, expected = [], []
    for k in range(20):
        lat, lon = (-33.8651437 + k * 2e-6) * (-1) ** k, 151.2099001 - k * 3e-6
        at, day = clock(12, 0, k // 5, (k % 5) * 200_000), date(2026, 11, 29)
        fix = dict(lat=lat, lon=lon, time=at)  # pynmeagps sets the hemispheres from the signs
        epoch = [
            NMEAMessage("GN", "GGA", GET, quality=1, numSV=9 + k % 3, HDOP=0.8, alt=39.4 + k,
                        altUnit="M", sep=0.0, sepUnit="M", **fix),
            NMEAMessage("GN", "RMC", GET, status="A", spd=5.8, cog=90.0, date=day,
                        posMode="A", **fix),
            NMEAMessage("GN", "VTG", GET, cogt=90.0, cogtUnit="T", sogn=5.8, sognUnit="N",
                        sogk=10.7, sogkUnit="K", posMode="A"),
            NMEAMessage("GN", "GST", GET, time=at, rangeRms=1.0, stdMajor=1.2, stdMinor=0.8,
                        orient=0.0, stdLat=0.6 + k / 100, stdLong=0.8, stdAlt=1.5),
        ]
        sentences += [m.serialize() for m in epoch]
        gga = NMEAReader.parse(epoch[0].serialize())
        stamp = datetime.combine(day, gga.time, tzinfo=timezone.utc)
        expected.append((gga.lat, gga.lon, float(gga.alt), int(stamp.timestamp() * 1e6)))
    try:
        ap.wait_for("GPS port open")
        line.write_all(sentences, pause_s=0.005)
        time.sleep(0.3)
    finally:
        ap.stop()
        line.close()
    rows = gps_rows(ap.logs)
    # The first epoch's GGA comes before any RMC gave the date: logged at the computer's time.
    assert_rows_are(rows, expected, "pynmeagps's stream", undated=1)
    # GST's deviations as the accuracies (from the second epoch: GST follows its GGA).
    by_time = {e[3] // 1000: k for k, e in enumerate(expected)}
    for r in rows[1:]:
        k = by_time[int(r["time_utc_usec"]) // 1000]
        assert abs(r["eph"] - math.hypot(0.6 + (k - 1) / 100, 0.8)) < 0.02, (k, r["eph"])
        assert abs(r["epv"] - 1.5) < 1e-6 and abs(r["vel_e_m_s"] - 5.8 * 1852 / 3600) < 1e-3


def test_a_flight_on_the_simulators_nmea_receiver_parses_in_pynmeagps(tmp_path):
    ap, relay, logs = fly_through_relay(tmp_path, "nmea", "protocol=nmea&baud=38400")
    assert relay.sent() == b"", "an NMEA receiver is told nothing"
    # Everything the receiver sent at its baud (38 400) parses in pynmeagps.
    heard = relay.heard_whole(38400, None)
    reader = NMEAReader(io.BytesIO(heard), quitonerror=2)
    sentences = [parsed for _, parsed in reader]
    kinds = {m.msgID for m in sentences}
    assert {"GGA", "RMC", "VTG", "GSA", "GST"} <= kinds, kinds
    assert_rows_are(gps_rows(logs), nmea_epochs(heard), "sitl's NMEA receiver", undated=1)
