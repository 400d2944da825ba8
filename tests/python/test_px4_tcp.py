"""sitl as PX4's simulator: pymavlink plays PX4's `simulator_mavlink` as its source states it
(src/modules/simulation/simulator_mavlink/SimulatorMavlink.cpp, PX4 v1.16):

- it connects over TCP to the simulator's port (4560 + instance) and sends a COMMAND_LONG
  MAV_CMD_SET_MESSAGE_INTERVAL for HIL_STATE_QUATERNION (5000 us) and one HEARTBEAT
  (autopilot 12), which is to start the simulator's sensor stream;
- its clock is each HIL_SENSOR's time_usec (id 0): while it boots it does not answer, so the
  simulator's clock must run on its own;
- once its mixer runs it answers every HIL_SENSOR with HIL_ACTUATOR_CONTROLS stamped with its
  clock (the frame's time), mode MAV_MODE_FLAG_CUSTOM_MODE_ENABLED (+ SAFETY_ARMED when armed),
  flags 1 (lockstep), motors in [0, 1] in its quad-X order (1 front-right ccw, 2 rear-left ccw,
  3 front-left cw, 4 rear-right cw).

The real PX4 flown on the same interface: tools/fly_px4.py, docs/simulator.md.
"""
import signal

from pymavlink import mavutil

from conftest import run_sitl

ML = mavutil.mavlink
CUSTOM, ARMED = ML.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, ML.MAV_MODE_FLAG_SAFETY_ARMED


class Px4:
    """PX4's end of the link: a TCP client speaking as system 1, component 1."""

    def __init__(self, port):
        self.m = mavutil.mavlink_connection(f"tcp:127.0.0.1:{port}", source_system=1,
                                            source_component=1)
        self.states = 0  # HIL_STATE_QUATERNION seen

    def hello(self):
        self.m.mav.command_long_send(0, 0, ML.MAV_CMD_SET_MESSAGE_INTERVAL, 0,
                                     ML.MAVLINK_MSG_ID_HIL_STATE_QUATERNION, 5000, 0, 0, 0, 0, 0)
        self.m.mav.heartbeat_send(0, 12, 0, 0, 0)

    def next(self, timeout=20.0):
        """The next message that is not ESC_STATUS (pymavlink's set lacks it)."""
        while True:
            msg = self.m.recv_match(blocking=True, timeout=timeout)
            assert msg is not None, f"nothing from sitl in {timeout} s"
            if msg.get_type() == "HIL_STATE_QUATERNION":
                self.states += 1
                self.state = msg
            if not msg.get_type().startswith("UNKNOWN"):
                return msg

    def sensor(self, timeout=20.0):
        while True:
            msg = self.next(timeout)
            if msg.get_type() == "HIL_SENSOR":
                return msg

    def answer(self, time_usec, controls=(0.0,) * 4, armed=False):
        self.m.mav.hil_actuator_controls_send(
            time_usec, list(controls) + [0.0] * (16 - len(controls)),
            CUSTOM | (ARMED if armed else 0), 1)

    def fly(self, seconds, controls=(0.0,) * 4, armed=False):
        """Lockstep for `seconds` of sensor time: each frame answered at once. Returns the last
        frame; asserts one frame per answer, each one exchange (4 ms) after the last."""
        s = self.sensor()
        self.answer(s.time_usec, controls, armed)
        end = s.time_usec + seconds * 1e6
        while s.time_usec < end:
            n = self.sensor()
            assert n.time_usec == s.time_usec + 4000, (s.time_usec, n.time_usec)
            s = n
            self.answer(s.time_usec, controls, armed)
        return s


def sitl_on_tcp(scenario):
    path = scenario('airframe = "quad_x"\nduration_s = 60.0\nsensors = "ideal"\nseed = 3\n')
    proc = run_sitl(["--scenario", str(path), "--tcp", "127.0.0.1:0", "--speed", "20",
                     "--timeout-ms", "10000", "--status-interval", "0"], 0)
    line = proc.stdout.readline()
    assert line.startswith("sitl tcp: "), line + proc.stderr.read()
    return proc, int(line.rsplit(":", 1)[1])


def finish(proc):
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=30)
    assert proc.returncode == 0, err
    line = next(l for l in out.splitlines() if l.startswith("sitl summary:"))
    return dict(kv.split("=", 1) for kv in line.split()[2:])


def test_px4s_protocol_boots_on_the_simulators_clock_then_steps_in_lockstep(scenario):
    proc, port = sitl_on_tcp(scenario)
    try:
        px4 = Px4(port)
        # Nothing until PX4 has spoken: its heartbeat starts the stream.
        assert px4.m.recv_match(blocking=True, timeout=0.5) is None
        px4.hello()
        ack = px4.m.recv_match(type="COMMAND_ACK", blocking=True, timeout=20)
        assert ack.command == ML.MAV_CMD_SET_MESSAGE_INTERVAL and ack.result == ML.MAV_RESULT_ACCEPTED
        assert (ack.target_system, ack.target_component) == (1, 1)

        # Booting: no answers, and the clock runs, one exchange a frame.
        first = px4.sensor()
        s = first
        while s.time_usec < first.time_usec + 500_000:
            n = px4.sensor()
            assert n.time_usec == s.time_usec + 4000
            s = n

        # The first answer: lockstep from then on (frames already on their way are answered
        # as PX4 would, each with its own time, until the stream waits for each answer).
        px4.answer(s.time_usec)
        px4.fly(0.2)
        # An answer withheld holds the clock: no next frame.
        held = px4.sensor()
        assert px4.m.recv_match(type="HIL_SENSOR", blocking=True, timeout=1.0) is None
        px4.answer(held.time_usec)

        # Disarmed, the motors' values are not applied.
        states0 = px4.states
        px4.fly(1.0, controls=(0.9,) * 4, armed=False)
        assert px4.state.vz == 0 and abs(px4.state.yawspeed) < 1e-6
        # The ground truth at the 200 Hz PX4 asked for.
        assert 199 <= px4.states - states0 <= 201, px4.states - states0

        # PX4's quad-X order: the counter-clockwise pair (1 front-right, 2 rear-left) faster
        # than the clockwise pair turns the body clockwise seen from above (yaw rate > 0) and
        # lifts it; then the right side (1 front-right, 4 rear-right) faster rolls it left.
        px4.fly(0.6, controls=(0.75, 0.75, 0.55, 0.55), armed=True)
        assert px4.state.yawspeed > 0.3 and px4.state.vz < -20, px4.state
        px4.fly(0.15, controls=(0.75, 0.6, 0.6, 0.75), armed=True)
        assert px4.state.rollspeed < -0.3, px4.state
        px4.m.close()
    except BaseException:
        proc.kill()
        raise
    summary = finish(proc)
    assert summary["malformed"] == "0" and summary["lockstep_timeouts"] == "0", summary


def test_a_px4_that_restarts_connects_again_and_boots_on_the_running_clock(scenario):
    proc, port = sitl_on_tcp(scenario)
    try:
        px4 = Px4(port)
        px4.hello()
        s = px4.sensor()
        px4.answer(s.time_usec)
        last = px4.fly(0.3)
        px4.m.close()  # PX4 stopped

        again = Px4(port)
        again.hello()
        # The clock goes on from where it stood, running on its own until the new PX4 answers.
        s = again.sensor()
        assert s.time_usec > last.time_usec
        n = again.sensor()
        assert n.time_usec == s.time_usec + 4000, "no answer needed while it boots"
        again.answer(n.time_usec)
        again.fly(0.2)
        again.m.close()
    except BaseException:
        proc.kill()
        raise
    summary = finish(proc)
    assert summary["malformed"] == "0", summary
