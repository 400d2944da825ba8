"""Onboard magnetometer calibration end to end: sitl's noisy magnetometer (hard and soft iron,
noise) in lockstep at up to 8x real time, the vehicle turned through every orientation by the simulator's hand —
set going by hand (`SIM_TUMBLE_S` on `sitl --control`, the calibration hand `SIM_CAL_HAND`
off), or by the calibration itself —, the calibration asked for as a ground station does
(`MAV_CMD_PREFLIGHT_CALIBRATION`, param2 = 1) with pymavlink and with MAVSDK's calibration
plugin, which reads PX4's `[cal]` texts. Every wait is on a message with a time-out.
The calibrator itself is tested in daemon/core/src/mag_calibrator.rs."""

import asyncio

import numpy as np
import pytest
from pymavlink import mavutil

from conftest import Daemon, mavsdk_autopilot, sim_control, sim_param
from test_ground_station import ack, param, ready_to_arm, wait

ML = mavutil.mavlink

# The simulator's "noisy" magnetometer (sitl/core/src/sensors.rs): raw = S m + hard.
HARD_IRON = np.array([0.12, -0.08, 0.2])
SOFT_IRON = np.array([[1.08, 0.04, -0.02], [0.04, 0.95, 0.03], [-0.02, 0.03, 1.02]])
FIELD_GAUSS = 0.48


def calibrate(gcs, which=(0, 1, 0, 0, 0, 0, 0)):
    gcs.mav.command_long_send(1, 1, ML.MAV_CMD_PREFLIGHT_CALIBRATION, 0, *which)


def arm_denial(gcs, timeout=5):
    """Arms; the refusal's text, its chunks joined (fails if the vehicle armed)."""
    gcs.mav.command_long_send(1, 1, ML.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1, 0, 0, 0, 0, 0, 0)
    assert ack(gcs, ML.MAV_CMD_COMPONENT_ARM_DISARM) == ML.MAV_RESULT_DENIED
    text = ""
    while True:  # a full 50-byte chunk says more follows
        chunk = wait(gcs, "STATUSTEXT", lambda m: True, timeout).text
        text += chunk
        if len(chunk) < 50:
            return text


def test_the_magnetometer_is_calibrated_onboard_while_turned_by_hand(tmp_path):
    """Before: arming refused, the distorted field off the site's strength. The calibration is
    acknowledged, said started, arming refused while it runs, progress in `[cal] progress <N>`
    rising to 100, `[cal] calibration done: mag`, `MAG_CAL_REPORT` with the simulator's hard
    iron within 1 % of the field and its soft iron undone within 2 %; the `CAL_MAG0_*`
    parameters hold the result (announced, and read back after a restart: saved); set down,
    the vehicle is ready to arm. The barometer's calibration is refused as unsupported."""
    d = Daemon(tmp_path, "udpout://127.0.0.1:{port}?bind=0", control=True,
               sim_args=["--sensors", "noisy"], lockstep=True, speed=8)
    try:
        gcs = d.gcs
        assert gcs.wait_heartbeat(timeout=30), "no heartbeat"
        sim = sim_control(d.control_port)
        # Uncalibrated, the field reads far from 0.48 G: the pre-arm check says so (once the
        # vehicle has measured it at rest).
        reason = ""
        for _ in range(20):
            reason = arm_denial(gcs)
            if "mag field" in reason:
                break
            wait(gcs, "SYS_STATUS", lambda m: True)  # a second on, try again
        assert "mag field" in reason, reason

        calibrate(gcs, (0, 0, 1, 0, 0, 0, 0))
        assert ack(gcs, ML.MAV_CMD_PREFLIGHT_CALIBRATION) == ML.MAV_RESULT_UNSUPPORTED
        # A person turns it, not the calibration's hand.
        assert sim_param(sim, "SIM_CAL_HAND", 0.0) == 0.0
        calibrate(gcs)
        assert ack(gcs, ML.MAV_CMD_PREFLIGHT_CALIBRATION) == ML.MAV_RESULT_ACCEPTED
        assert "calibrating the magnetometer" in arm_denial(gcs)
        assert sim_param(sim, "SIM_TUMBLE_S", 90.0) == 90.0

        texts, params, report = [], {}, None
        while report is None:
            m = gcs.recv_match(type=["STATUSTEXT", "MAG_CAL_REPORT", "PARAM_VALUE"],
                               blocking=True, timeout=60)
            assert m is not None, f"the calibration stopped talking: {texts}"
            if m.get_type() == "STATUSTEXT" and m.text.startswith("[cal]"):
                texts.append(m.text)
            elif m.get_type() == "PARAM_VALUE" and m.param_id.startswith("CAL_MAG0_"):
                params[m.param_id] = m.param_value
            elif m.get_type() == "MAG_CAL_REPORT":
                report = m
        print("\n".join(texts))
        assert texts[0] == "[cal] calibration started: 2 mag", texts
        assert texts[-1] == "[cal] calibration done: mag", texts
        progress = [int(t.split("<")[1].rstrip(">")) for t in texts if "progress" in t]
        assert progress == sorted(progress) and progress[-1] == 100 and len(progress) >= 5
        assert report.cal_status == ML.MAG_CAL_SUCCESS and report.autosaved == 1

        offset = np.array([report.ofs_x, report.ofs_y, report.ofs_z])
        s = np.array([[report.diag_x, report.offdiag_x, report.offdiag_y],
                      [report.offdiag_x, report.diag_y, report.offdiag_z],
                      [report.offdiag_y, report.offdiag_z, report.diag_z]])
        offset_error = np.linalg.norm(offset - HARD_IRON)
        soft_error = np.linalg.norm(s @ SOFT_IRON - np.eye(3))
        print(f"onboard: offset error {1000 * offset_error:.2f} mG "
              f"({100 * offset_error / FIELD_GAUSS:.2f} % of the field), "
              f"‖S_cal S − I‖ = {soft_error:.4f}, fit residual {report.fitness:.1f} mG")
        assert offset_error < 0.01 * FIELD_GAUSS
        assert soft_error < 0.02
        assert params["CAL_MAG0_XOFF"] == pytest.approx(report.ofs_x)
        assert params["CAL_MAG0_ZODIAG"] == pytest.approx(report.offdiag_z)
        assert len(params) == 10, sorted(params)

        # Set down and calibrated: the field checks out, the vehicle may arm.
        ready_to_arm(gcs)

        # Saved: a new run of the daemon reads the calibration back from its store.
        d.stop()
        d.start()
        assert gcs.wait_heartbeat(timeout=30)
        assert param(gcs, "CAL_MAG0_XOFF").param_value == pytest.approx(report.ofs_x)
        assert param(gcs, "CAL_MAG0_YSCALE").param_value == pytest.approx(report.diag_y)
    finally:
        d.close()


def test_mavsdk_calibrates_the_magnetometer_with_its_calibration_plugin(tmp_path):
    """MAVSDK's `calibrate_magnetometer()` (native binding): progress from 0 to 100 %, and the
    stream ends in success; the calibration's own request turns the vehicle."""
    from mavsdk.asyncio.plugins.calibration import CalibrationAsync
    from mavsdk.plugins.calibration import CalibrationResult

    d = Daemon(tmp_path, "udpout://127.0.0.1:{port}?bind=0", connect=False,
               sim_args=["--sensors", "noisy"], lockstep=True, speed=8)

    async def run():
        async with mavsdk_autopilot(f"udpin://127.0.0.1:{d.gcs_port}") as system:
            calibration = CalibrationAsync(system)
            progress, results = [], []

            async def stream():
                async for result, data in calibration.calibrate_magnetometer():
                    results.append(result)
                    if data.has_progress:
                        progress.append(data.progress)

            await asyncio.wait_for(stream(), 90)
            print(f"MAVSDK progress: {[round(p, 2) for p in progress]}")
            assert results[-1] == CalibrationResult.SUCCESS
            assert progress[0] == 0.0 and progress == sorted(progress) and len(progress) >= 5
            assert progress[-1] == 1.0

    try:
        asyncio.run(run())
    finally:
        d.close()


if __name__ == "__main__":
    pytest.main([__file__, "-q", "-s"])
