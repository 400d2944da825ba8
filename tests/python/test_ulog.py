"""The ULog flight log, read by PyPI's pyulog (pinned, unmodified): every topic a PX4 layout
plots is there under PX4's names, its values are the flight CSV's, the parameters at the start
are the ones a ground station fetches, a change during the flight is logged, and every
STATUSTEXT the ground station heard is a logged string."""

import math
import time

from pymavlink import mavutil
from pyulog import ULog

from conftest import Daemon
from test_ground_station import (INT32, ack, arm_and_take_off, armed, from_bits, param_list,
                                 set_param)

TOPICS = {
    "sensor_combined", "vehicle_attitude", "vehicle_angular_velocity", "vehicle_rates_setpoint",
    "vehicle_attitude_setpoint", "actuator_motors", "actuator_outputs", "vehicle_local_position",
    "vehicle_global_position", "vehicle_local_position_setpoint", "vehicle_gps_position",
    "vehicle_air_data", "vehicle_magnetometer", "battery_status", "estimator_status",
    "vehicle_status", "vehicle_land_detected",
}


def fetch_params(gcs):
    """Every parameter as PARAM_REQUEST_LIST gives it: name -> value (INT32 decoded)."""
    return {m.param_id: from_bits(m.param_value) if m.param_type == INT32 else m.param_value
            for m in param_list(gcs).values()}


def euler_deg(q0, q1, q2, q3):
    """Roll, pitch, yaw (deg) of a w, x, y, z quaternion (ZYX, as the CSV's columns)."""
    roll = math.atan2(2 * (q0 * q1 + q2 * q3), 1 - 2 * (q1 * q1 + q2 * q2))
    pitch = math.asin(max(-1.0, min(1.0, 2 * (q0 * q2 - q3 * q1))))
    yaw = math.atan2(2 * (q0 * q3 + q1 * q2), 1 - 2 * (q2 * q2 + q3 * q3))
    return [math.degrees(a) for a in (roll, pitch, yaw)]


def csv_by_time(path):
    """The flight CSV's rows by their time (µs)."""
    lines = path.read_text().splitlines()
    header = lines[0].split(",")
    rows = {}
    for line in lines[1:]:
        r = dict(zip(header, line.split(",")))
        rows[round(float(r["t_s"]) * 1e6)] = r
    return rows


def test_a_flight_log_reads_in_pyulog_with_px4_topics_csv_values_params_and_texts(tmp_path):
    daemon = Daemon(tmp_path, "udpout://127.0.0.1:{port}?bind=0")
    texts = []
    try:
        gcs = daemon.gcs
        assert gcs.wait_heartbeat(timeout=30), "no heartbeat"
        params = fetch_params(gcs)
        assert set_param(gcs, "MPC_XY_VEL_MAX", 7.5).param_value == 7.5
        set_param(gcs, "MPC_XY_P", 99.0, texts=texts)  # refused, with a reason said
        assert texts, "no reason given for a refused value"
        arm_and_take_off(gcs)
        gcs.mav.command_long_send(1, 1, mavutil.mavlink.MAV_CMD_NAV_LAND, 0, 0, 0, 0, 0, 0, 0, 0)
        assert ack(gcs, mavutil.mavlink.MAV_CMD_NAV_LAND) == 0
        end, landed = time.monotonic() + 60, False
        while time.monotonic() < end and not landed:
            m = gcs.recv_match(type=["HEARTBEAT", "STATUSTEXT"], blocking=True, timeout=0.5)
            if m is None or m.get_srcComponent() != 1:
                continue
            if m.get_type() == "STATUSTEXT":
                texts.append(m.text)
            landed = m.get_type() == "HEARTBEAT" and not armed(m)
        assert landed, "not disarmed after landing within 60 s"
        daemon.stop()
    finally:
        daemon.close()

    ulg = next(daemon.logs.glob("*.ulg"))
    log = ULog(str(ulg))
    assert not log.file_corruption
    topics = {d.name: d.data for d in log.data_list}
    assert TOPICS <= topics.keys(), TOPICS - topics.keys()
    assert log.msg_info_dict["ver_data_format"] == 2

    # The values are the flight CSV's, row for row where both have one.
    rows = csv_by_time(next(daemon.logs.glob("*.csv")))
    pos, att, motors = (topics[n] for n in ("vehicle_local_position", "vehicle_attitude",
                                            "actuator_motors"))
    matched = 0
    for i, t in enumerate(pos["timestamp"]):
        r = rows.get(int(t))
        if r is None:
            continue
        matched += 1
        for field, column in (("x", "n_m"), ("y", "e_m"), ("z", "d_m")):
            assert abs(pos[field][i] - float(r[column])) < 1e-3, (t, field)
    assert matched > 0.9 * len(pos["timestamp"]) > 100, matched
    for i in range(0, len(att["timestamp"]), 25):
        r = rows[int(att["timestamp"][i])]
        got = euler_deg(*(att[f"q[{k}]"][i] for k in range(4)))
        want = [float(r[c]) for c in ("roll_deg", "pitch_deg", "yaw_deg")]
        assert all(abs((g - w + 180) % 360 - 180) < 0.01 for g, w in zip(got, want)), (got, want)
    flying = [i for i, c in enumerate(motors["control[0]"]) if not math.isnan(c)]
    assert flying, "no armed motor rows"
    for i in flying[::50]:
        r = rows[int(motors["timestamp"][i])]
        assert abs(motors["control[0]"][i] - float(r["motor1"])) < 1e-3
    assert all(math.isnan(c) for c in motors["control[4]"])  # a quad: four motors

    # The modes flown (PX4's nav_state), armed then disarmed.
    status = topics["vehicle_status"]
    assert {17, 4, 18} <= set(status["nav_state"]), set(status["nav_state"])
    assert list(status["arming_state"]).count(2) > 0 and status["arming_state"][-1] == 1

    # The parameters at the start are those a ground station fetched; the change is logged.
    start = log.initial_parameters
    assert start.keys() == params.keys()
    for name, value in params.items():
        assert math.isclose(start[name], value, rel_tol=1e-6), name
    assert ("MPC_XY_VEL_MAX", 7.5) in [(n, v) for _, n, v in log.changed_parameters]

    # Every STATUSTEXT heard is a logged string.
    logged = [m.message for m in log.logged_messages]
    assert texts and all(t in logged for t in texts), (texts, logged)

    minutes = (log.last_timestamp - log.start_timestamp) / 60e6
    print(f"\nULog: {ulg.stat().st_size / 1e6:.2f} MB for {minutes * 60:.0f} s of flight: "
          f"{ulg.stat().st_size / 1e6 / minutes:.2f} MB per minute")
