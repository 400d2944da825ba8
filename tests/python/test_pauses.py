"""A simulator in real time that stops for a while (Ctrl-Z, a debugger, a starved machine) and
goes on: it goes on from now, not replaying the missed time in a burst, and the autopilot judges
nothing on frames it did not fly."""

import math
import signal
import time

import pytest
from pymavlink import mavutil

from conftest import Daemon
from test_ground_station import ack, armed, ready_to_arm, wait_holding_in_air


def fields(text, prefix):
    """The `key=value` fields of the last line of `text` starting with `prefix`."""
    line = [l for l in text.splitlines() if l.startswith(prefix)][-1]
    return dict(kv.split("=", 1) for kv in line[len(prefix):].split())


def pause_in_hover(tmp_path, pause_s):
    """Hovering, `sitl --mode realtime` stopped (SIGSTOP) for `pause_s` and continued; a landing
    asked if the vehicle still holds. Returns the simulator's summary, the autopilot's, what the
    ground station heard and what the autopilot logged."""
    daemon = Daemon(tmp_path, "udpout://127.0.0.1:{port}?bind=0")
    try:
        gcs = daemon.gcs
        assert gcs.wait_heartbeat(timeout=30), "no heartbeat"
        ready_to_arm(gcs)
        gcs.arducopter_arm()
        assert ack(gcs, mavutil.mavlink.MAV_CMD_COMPONENT_ARM_DISARM) == 0
        gcs.mav.command_long_send(1, 1, mavutil.mavlink.MAV_CMD_NAV_TAKEOFF, 0,
                                  0, 0, 0, math.nan, math.nan, math.nan, math.nan)
        wait_holding_in_air(gcs, min_height_m=2.0)
        daemon.sim.send_signal(signal.SIGSTOP)
        time.sleep(pause_s)
        daemon.sim.send_signal(signal.SIGCONT)
        texts = []
        landing_asked = False
        end = time.monotonic() + 90
        while time.monotonic() < end:
            m = gcs.recv_match(type=["HEARTBEAT", "STATUSTEXT"], blocking=True, timeout=1)
            if m is None:
                continue
            if m.get_type() == "STATUSTEXT":
                texts.append(m.text)
            elif m.get_srcSystem() == 1 and not armed(m):
                break
            elif not landing_asked and gcs.flightmode == "LOITER":
                # Still holding (the pause was shorter than the frames' watchdog): land.
                gcs.mav.command_long_send(1, 1, mavutil.mavlink.MAV_CMD_NAV_LAND, 0,
                                          0, 0, 0, math.nan, math.nan, math.nan, math.nan)
                landing_asked = True
        else:
            pytest.fail(f"not landed and disarmed within 90 s; heard {texts}")
        # A vehicle disarmed in the air (the blind descent's end) falls when the simulator goes
        # on: its touch of the ground is in the frames that follow.
        time.sleep(3)
        sim = daemon.stop_sim()
        daemon.stop()
        ap = fields(daemon.out.read_text(), "autopilot summary: ")
        assert "going on from now" in daemon.sim_err.read_text(), "the simulator said so"
        return sim, ap, texts, daemon.ap_stderr
    finally:
        daemon.close()


@pytest.mark.parametrize("pause_s", [0.5, 2.0])
def test_a_simulator_paused_in_real_time_goes_on_from_now_and_no_rotor_is_judged_failed(
        tmp_path, pause_s):
    """Hovering, `sitl --mode realtime` is stopped (SIGSTOP) for `pause_s` and continued. Before,
    it replayed the missed time in a burst with the last command held, and the autopilot took
    the burst for a failed motor (2 runs of 2) and flipped. Now the simulator says it goes on
    from now; no motor is declared failed; the vehicle lands; the autopilot's summary says what
    the truth says (landed, a gentle touchdown) and counts the failsafe the ground station was
    told of."""
    sim, ap, texts, stderr = pause_in_hover(tmp_path, pause_s)
    assert "motor failure" not in stderr, stderr[-3000:]
    assert sim["landed"] == "true" and ap["landed"] == "true", (sim, ap)
    assert float(sim["last_touchdown_speed_m_s"]) < 1.5, sim
    assert float(ap["touchdown_m_s"]) < 1.5, ap
    told = any("sensor frames stopped" in t for t in texts)
    assert ap["failsafe"] == ("true" if told else "false"), (ap, texts)


def test_a_simulator_paused_ten_seconds_is_summarised_as_the_truth_saw_it(tmp_path):
    """Paused for 10 s, longer than the blind descent: the autopilot, hearing nothing, brought
    the vehicle down open-loop as a real one would have come down, and stopped its motors;
    the simulator held it in the air meanwhile, so it falls when it goes on. Before, the summary
    said `failsafe=false` and a touchdown of 0 for such a fall. Now no motor is judged failed,
    the failsafe is counted, and the impact is the simulator's."""
    sim, ap, texts, stderr = pause_in_hover(tmp_path, 10.0)
    assert "motor failure" not in stderr, stderr[-3000:]
    assert any("sensor frames stopped" in t for t in texts), texts
    assert ap["failsafe"] == "true", ap
    assert sim["landed"] == "true" and ap["landed"] == "true", (sim, ap)
    fell = float(sim["last_touchdown_speed_m_s"])
    assert abs(float(ap["impact_m_s"]) - fell) <= max(0.5, 0.15 * fell), (sim, ap)
