"""ArduPilot's JSON interface against a physics that is not ours: tools/json_physics_example.py,
written as physics for ArduPilot's SITL are (struct-unpacked servo packets, json.dumps states),
flies the autopilot's take-off, hover and landing."""

import subprocess
import sys

import pytest

from conftest import ROOT, binary, free_udp_port


# At the autopilot's own 250 Hz, and at ArduPilot's usual 1 kHz: the physics then steps three
# times in four under the command the link holds, and the autopilot still steps at 250 Hz.
@pytest.mark.parametrize("step", ["0.004", "0.001"])
def test_a_physics_written_for_ardupilot_flies_the_autopilot(tmp_path, step):
    port = free_udp_port()
    physics = subprocess.Popen(
        [sys.executable, str(ROOT / "tools" / "json_physics_example.py"), "--port", str(port),
         "--duration", "200", "--step", step],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )
    try:
        # The autopilot starts the exchange and resends until the physics answers.
        ap = subprocess.run(
            [str(binary("autopilot")), "--params-dir", str(ROOT / "params"),
             "--source", f"json://127.0.0.1:{port}", "--seed", "3",
             "--takeoff", "3", "--hover", "3",
             "--mavlink", "none", "--param-store", "none", "--log-dir", "none"],
            capture_output=True, text=True, timeout=300,
        )
    finally:
        physics.kill()
        physics.communicate()
    assert ap.returncode == 0, ap.stderr[-3000:]
    line = next(l for l in ap.stdout.splitlines() if l.startswith("autopilot summary:"))
    s = dict(kv.split("=", 1) for kv in line.split()[2:])
    assert s["source"] == f"json://127.0.0.1:{port}", line
    assert s["landed"] == "true" and s["disarmed"] == "true", line
    assert s["malformed"] == "0", line
    # The autopilot steps at its 250 Hz whatever the physics' rate.
    assert abs(int(s["frames"]) / float(s["sim_time_s"]) - 250) < 5, line
    # The climb, the hold and the landing, on another physics: as on ours.
    assert 2.7 < float(s["max_alt_m"]) < 3.3, line
    assert float(s["hover_alt_rms_m"]) < 0.3, line
    assert float(s["attitude_rms_deg"]) < 2.0, line
    assert float(s["touchdown_m_s"]) < 0.7, line
