//! The simulator's end of the HIL exchange, shared by the `sitl` process and the autopilot's
//! embedded simulator so that one seed gives the same messages (as bytes for a link, folded
//! straight into a frame in-process), and the same flight, on either.

use crate::{
    Accumulator, ActuatorCommand, Encoder, HandRequest, SensorUpdate, encode_exchange,
    exchange_messages,
};
use sitl_core::airframe::MAX_ROTORS;
use sitl_core::sensors::SensorFrame;
use sitl_core::sim::SimAction;
use sitl_core::sim::Simulator;

/// Interval of the ground truth (`HIL_STATE_QUATERNION`, 50 Hz) unless the autopilot asks for
/// another ([`SimulatorEnd::set_state_interval`]).
pub const STATE_INTERVAL_USEC: u64 = 20_000;

/// How long the hand keeps doing what it was asked after the requests stop (s): a lost
/// datagram in real time is not an end.
const HAND_PATIENCE_S: f64 = 0.5;

/// Longest turning through every orientation, if the request never stops (s).
const TUMBLE_MAX_S: f64 = 600.0;

/// One exchange after another: the sensor frame of time k goes out, the answer to it comes in,
/// then physics steps over the exchange interval with that answer (docs/conventions.md lockstep).
pub struct SimulatorEnd {
    sim: Simulator,
    acc: Accumulator,
    encoder: Encoder,
    steps_per_exchange: usize,
    next_state_usec: u64,
    /// Interval of the ground truth (µs); `None`: not sent.
    state_interval_usec: Option<u64>,
    controls: [f64; MAX_ROTORS],
    /// What the hand is doing on request, and when a request last came (s).
    hand: HandRequest,
    hand_heard_s: f64,
    /// The GPS goes out as `HIL_GPS` (else a GPS device on a serial port carries it).
    hil_gps: bool,
}

impl SimulatorEnd {
    /// Wraps `sim`, exchanging at `exchange_hz` (rounded to a whole number of physics steps).
    pub fn new(mut sim: Simulator, exchange_hz: f64) -> Self {
        let physics_hz = 1.0 / sim.config().dt_s;
        let steps = (physics_hz / exchange_hz.max(1e-3)).round().max(1.0) as usize;
        // The autopilot sees the IMU's average over each exchange: its noise is drawn once
        // for that average (`SensorSuite::draw_imu_noise_per_exchange`).
        sim.sensors_mut().draw_imu_noise_per_exchange();
        let acc = Accumulator::new(sim.sample_sensors());
        let mut end = Self {
            sim,
            acc,
            encoder: crate::sim_encoder(),
            steps_per_exchange: steps,
            next_state_usec: 0,
            state_interval_usec: Some(STATE_INTERVAL_USEC),
            controls: [0.0; MAX_ROTORS],
            hand: HandRequest::None,
            hand_heard_s: f64::NEG_INFINITY,
            hil_gps: true,
        };
        end.exchange_noise();
        end
    }

    /// The IMU noise of the exchange just stepped, on its average. (Never inlined: a function
    /// of its own, `tools/bench_cost.py` counts it in the frame's compute floor.)
    #[inline(never)]
    fn exchange_noise(&mut self) {
        let interval_s = self.steps_per_exchange as f64 * self.sim.config().dt_s;
        let (accel, gyro) = self.acc.imu_mut();
        self.sim
            .sensors_mut()
            .exchange_imu_noise(interval_s, accel, gyro);
    }

    /// Appends the current exchange's messages to `out` (`HIL_SENSOR` last; the truth when due)
    /// and returns the frame's time, which the answer must echo.
    pub fn encode_frame(&mut self, out: &mut Vec<u8>) -> u64 {
        let send_state = self.state_due();
        let frame = self.acc.frame();
        let rotors = self.sim.airframe().rotors.len();
        let truth = || self.sim.truth();
        if self.hil_gps || frame.gps.is_none() {
            encode_exchange(&mut self.encoder, out, frame, truth, rotors, send_state);
        } else {
            let without_gps = SensorFrame {
                gps: None,
                ..frame.clone()
            };
            encode_exchange(
                &mut self.encoder,
                out,
                &without_gps,
                truth,
                rotors,
                send_state,
            );
        }
        frame.time_usec
    }

    /// Sends the GPS as `HIL_GPS` (the default), or not: a GPS device on its own serial port
    /// carries it instead.
    pub fn set_hil_gps(&mut self, on: bool) {
        self.hil_gps = on;
    }

    /// The current exchange as an autopilot decodes it from [`Self::encode_frame`]'s bytes,
    /// without the bytes: the same messages folded into `into`, their f32 and integer
    /// quantisation included (the embedded simulator's road). Returns the frame's time.
    pub fn frame_update(&mut self, into: &mut SensorUpdate) -> u64 {
        let send_state = self.state_due();
        let frame = self.acc.frame();
        let rotors = self.sim.airframe().rotors.len();
        exchange_messages(
            frame,
            || self.sim.truth(),
            rotors,
            send_state,
            |m| {
                into.absorb(m);
            },
        );
        frame.time_usec
    }

    /// Whether this exchange carries the ground truth: every interval on average (at most once
    /// an exchange), the next due time kept on the interval's grid so that a rate the exchange
    /// rate does not divide (PX4 asks for 200 Hz) is still kept.
    fn state_due(&mut self) -> bool {
        let Some(interval) = self.state_interval_usec else {
            return false;
        };
        let t = self.acc.frame().time_usec;
        let due = t >= self.next_state_usec;
        if due {
            self.next_state_usec = (self.next_state_usec + interval).max(t);
        }
        due
    }

    /// Sends the ground truth every `interval_usec` (MAV_CMD_SET_MESSAGE_INTERVAL for
    /// `HIL_STATE_QUATERNION`, as PX4's simulator interface asks on connecting), or not at all
    /// (`None`). Takes effect from the next frame.
    pub fn set_state_interval(&mut self, interval_usec: Option<u64>) {
        self.state_interval_usec = interval_usec.map(|i| i.max(1));
        self.next_state_usec = self.acc.frame().time_usec;
    }

    /// Takes an answer: an armed command's controls, all rotors off otherwise; and, when the
    /// simulator plays the person holding the vehicle, what a calibration asks of that person.
    pub fn apply(&mut self, cmd: &ActuatorCommand) {
        self.controls = if cmd.armed {
            cmd.controls
        } else {
            [0.0; MAX_ROTORS]
        };
        self.ask_hand(cmd.hand);
    }

    /// The hand acts on a change of request; no request for [`HAND_PATIENCE_S`] — none in the
    /// answers, or no answers — is the end of one (it sets the vehicle down and lets go).
    fn ask_hand(&mut self, request: HandRequest) {
        let now = self.sim.time_s();
        if request != HandRequest::None {
            self.hand_heard_s = now;
        } else if now - self.hand_heard_s < HAND_PATIENCE_S {
            return;
        }
        if !self.sim.calibration_hand() {
            // Nobody's hand: a request finds it idle when it is back.
            self.hand = HandRequest::None;
            return;
        }
        if request == self.hand {
            return;
        }
        self.hand = request;
        self.sim.apply(match request {
            HandRequest::None => SimAction::SetDown,
            HandRequest::Place(face) => SimAction::Place { face },
            HandRequest::Tumble => SimAction::Tumble {
                duration_s: TUMBLE_MAX_S,
            },
        });
    }

    /// Steps physics over one exchange interval with the current controls and starts the next
    /// frame; `each_step` sees the simulator after every physics step (truth logs).
    pub fn advance<E>(
        &mut self,
        each_step: impl FnMut(&Simulator) -> Result<(), E>,
    ) -> Result<(), E> {
        self.advance_with(
            |sim, u| {
                sim.step(u);
                Ok(())
            },
            each_step,
        )
    }

    /// [`SimulatorEnd::advance`] with the physics step given: `step(sim, controls)` moves the
    /// world one step (e.g. with [`Simulator::step_with`] and an external flight-dynamics model).
    pub fn advance_with<E>(
        &mut self,
        mut step: impl FnMut(&mut Simulator, &[f64]) -> Result<(), E>,
        mut each_step: impl FnMut(&Simulator) -> Result<(), E>,
    ) -> Result<(), E> {
        let n = self.sim.airframe().rotors.len();
        // Answers that stopped coming stop the requests too.
        self.ask_hand(HandRequest::None);
        self.acc.start();
        for _ in 0..self.steps_per_exchange {
            step(&mut self.sim, &self.controls[..n])?;
            self.acc.add(self.sim.sample_sensors());
            each_step(&self.sim)?;
        }
        self.exchange_noise();
        Ok(())
    }

    /// Real time: steps physics over one exchange interval one step at a time. Before each step
    /// `before_step` gets the step's start time (s), waits for it on its own clock, and returns
    /// the newest answer that has arrived, which takes effect from that step on: a command acts
    /// as soon as it is there, as on a real vehicle, not an exchange later. `step` moves the
    /// world as in [`SimulatorEnd::advance_with`].
    pub fn advance_live<E>(
        &mut self,
        mut before_step: impl FnMut(f64) -> Result<Option<ActuatorCommand>, E>,
        mut step: impl FnMut(&mut Simulator, &[f64]) -> Result<(), E>,
        mut each_step: impl FnMut(&Simulator) -> Result<(), E>,
    ) -> Result<(), E> {
        let n = self.sim.airframe().rotors.len();
        self.ask_hand(HandRequest::None);
        self.acc.start();
        for _ in 0..self.steps_per_exchange {
            if let Some(cmd) = before_step(self.sim.time_s())? {
                self.apply(&cmd);
            }
            step(&mut self.sim, &self.controls[..n])?;
            self.acc.add(self.sim.sample_sensors());
            each_step(&self.sim)?;
        }
        self.exchange_noise();
        Ok(())
    }

    /// The simulator.
    pub fn sim(&self) -> &Simulator {
        &self.sim
    }

    /// The simulator, to act on it between exchanges (run-time weather, injected faults).
    pub fn sim_mut(&mut self) -> &mut Simulator {
        &mut self.sim
    }

    /// The frame that goes out next.
    pub fn frame(&self) -> &SensorFrame {
        self.acc.frame()
    }

    /// Exchange rate actually used (Hz).
    pub fn exchange_hz(&self) -> f64 {
        1.0 / (self.sim.config().dt_s * self.steps_per_exchange as f64)
    }
}
