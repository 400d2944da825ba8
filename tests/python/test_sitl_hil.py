"""The simulator's HIL messages as pymavlink, an independent MAVLink implementation, decodes them.

pymavlink plays the autopilot: it answers every HIL_SENSOR with HIL_ACTUATOR_CONTROLS in lockstep,
and checks that every field carries what docs/conventions.md says, in the units MAVLink defines.
"""

import math
import struct
from types import SimpleNamespace

from pymavlink import mavutil

from conftest import free_udp_port, run_sitl

HOME = (47.397742, 8.545594, 488.0)  # PX4's default SITL home, the simulator's default
G = 9.80665


def isa_pressure_hpa(alt_m):
    return 1013.25 * (1 - 0.0065 * alt_m / 288.15) ** 5.255877


def esc_status(msg):
    """ESC_STATUS (id 291) decoded by hand: pymavlink 2.4.50's message set no longer carries it
    (rust-mavlink 0.21 and PX4's simulators do). Wire order: time_usec u64, rpm i32[4],
    voltage f32[4], current f32[4], index u8; MAVLink 2 trims trailing zero bytes."""
    frame = bytes(msg.data)  # pymavlink keeps the whole frame: 10-byte header, payload, CRC
    payload = frame[10:10 + frame[1]].ljust(57, b"\0")
    v = struct.unpack("<Q4i4f4fB", payload)
    return SimpleNamespace(time_usec=v[0], rpm=v[1:5], voltage=v[5:9], current=v[9:13], index=v[13])


def fly(scenario_path, on_frame, extra=()):
    """Runs sitl against a pymavlink 'autopilot'; on_frame(msgs_by_type) returns (controls, armed)
    or None to stop answering. Returns sitl's summary as a dict."""
    port = free_udp_port()
    ap = mavutil.mavlink_connection(f"udpin:127.0.0.1:{port}", source_system=1, source_component=1)
    proc = run_sitl(["--scenario", str(scenario_path), *extra], port)
    try:
        frame = {}
        while True:
            msg = ap.recv_match(blocking=True, timeout=1)
            if msg is None:
                if proc.poll() is not None:
                    break  # the run is over
                continue
            if msg.get_type() == "UNKNOWN_291":
                msg = esc_status(msg)
                frame.setdefault("ESC_STATUS", []).append(msg)
                continue
            frame.setdefault(msg.get_type(), []).append(msg)
            if msg.get_type() != "HIL_SENSOR":
                continue
            answer = on_frame(frame)
            frame = {}
            if answer is None:
                break
            controls, armed = answer
            ap.mav.hil_actuator_controls_send(
                msg.time_usec, list(controls) + [0.0] * (16 - len(controls)),
                mavutil.mavlink.MAV_MODE_FLAG_SAFETY_ARMED if armed else 0, 1)
    except BaseException:
        proc.kill()
        raise
    finally:
        out, err = proc.communicate(timeout=30)
    assert proc.returncode == 0, err
    line = next(l for l in out.splitlines() if l.startswith("sitl summary:"))
    return dict(kv.split("=", 1) for kv in line.split()[2:])


def test_sensor_messages_at_rest_carry_physical_values(scenario):
    path = scenario('airframe = "quad_x"\nduration_s = 2.0\nsensors = "ideal"\n')
    seen = {"HIL_GPS": 0, "ESC_STATUS": 0, "HIL_STATE_QUATERNION": 0, "HIL_SENSOR": 0}
    last_time = [None]

    def on_frame(f):
        s = f["HIL_SENSOR"][-1]
        if last_time[0] is not None:
            assert s.time_usec == last_time[0] + 4000  # 250 Hz lockstep
        last_time[0] = s.time_usec
        for k in seen:
            seen[k] += len(f.get(k, []))
        # Resting level: specific force straight up, no rotation.
        assert abs(s.zacc + G) < 1e-3 and abs(s.xacc) < 1e-3 and abs(s.yacc) < 1e-3
        assert max(abs(s.xgyro), abs(s.ygyro), abs(s.zgyro)) < 1e-6
        if s.fields_updated & (1 << 6):
            # Default Earth field: 0.48 G, inclination 63.3 deg, declination 3 deg, body = NED.
            assert abs(math.sqrt(s.xmag**2 + s.ymag**2 + s.zmag**2) - 0.48) < 1e-4
            assert abs(math.degrees(math.atan2(s.zmag, math.hypot(s.xmag, s.ymag))) - 63.3) < 0.01
        if s.fields_updated & (1 << 9):
            assert abs(s.abs_pressure - isa_pressure_hpa(HOME[2])) < 0.01
            assert abs(s.pressure_alt - HOME[2]) < 0.05
            assert abs(s.temperature - (15 - 0.0065 * HOME[2])) < 0.01
        for g in f.get("HIL_GPS", []):
            assert g.fix_type == 3 and g.satellites_visible == 14
            assert abs(g.lat * 1e-7 - HOME[0]) < 1e-7 and abs(g.lon * 1e-7 - HOME[1]) < 1e-7
            assert abs(g.alt / 1000 - HOME[2]) < 0.01 and g.vn == g.ve == g.vd == 0
        for e in f.get("ESC_STATUS", []):
            assert e.index == 0 and list(e.rpm) == [0, 0, 0, 0] and e.voltage[0] > 16.0
        for q in f.get("HIL_STATE_QUATERNION", []):
            assert abs(q.attitude_quaternion[0] - 1.0) < 1e-6
            assert abs(q.lat * 1e-7 - HOME[0]) < 1e-7 and abs(q.zacc + 1000) <= 1
        return ([0.0] * 4, False)

    summary = fly(path, on_frame)
    assert seen["HIL_SENSOR"] >= 499
    assert 19 <= seen["HIL_GPS"] <= 21          # 10 Hz
    assert 99 <= seen["ESC_STATUS"] <= 101      # 50 Hz
    assert 99 <= seen["HIL_STATE_QUATERNION"] <= 101  # 50 Hz
    assert summary["lockstep_timeouts"] == "0" and summary["malformed"] == "0"


def test_armed_dodeca_climbs_and_reports_twelve_rotors(scenario):
    path = scenario('airframe = "dodeca"\nduration_s = 1.5\nsensors = "typical"\n')
    state = {"alt0": None, "alt": None, "rpm": {}, "vz": 0.0}

    def on_frame(f):
        s = f["HIL_SENSOR"][-1]
        if s.fields_updated & (1 << 11):
            state["alt0"] = state["alt0"] if state["alt0"] is not None else s.pressure_alt
            state["alt"] = s.pressure_alt
        for e in f.get("ESC_STATUS", []):
            for k, r in enumerate(e.rpm):
                state["rpm"][e.index + k] = r
        for q in f.get("HIL_STATE_QUATERNION", []):
            state["vz"] = q.vz
        return ([0.75] * 12, True)

    fly(path, on_frame)
    assert sorted(state["rpm"]) == list(range(12))
    assert all(r > 3000 for r in state["rpm"].values()), state["rpm"]
    assert state["vz"] < -100, "climbing (cm/s, NED)"
    assert state["alt"] - state["alt0"] > 1.0
