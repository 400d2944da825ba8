//! One step of the autopilot ([`Autopilot::step`]): the sample through the failure injection,
//! the sensor monitor and the calibrations, the commander's set-point, the flight core, and
//! the answer — each written in place where it is kept (the sample the logs record, the
//! calibrated sample and the core's output in the published state, the answer), no copy
//! between.

use super::{Autopilot, AutopilotOutput, SOURCE_RESTART_USEC, StepInputs, StepKind};
use crate::commander::LandedState;
use crate::control::{GroundContact, Setpoint};
use crate::estimator::attitude::EstimateReset;
use crate::safety::motor_failure::MotorFailure;
use crate::sample::{SensorSample, StepOutput};
use airframe::MAX_ROTORS;
use nalgebra::Vector3;

/// The magnetometer and barometer as last seen (a sample carries them only when fresh).
type LastSeen = (Option<Vector3<f64>>, Option<f64>);

impl Autopilot {
    /// One sensor sample: the whole chain, and what to tell the rotors. `None` for a sample
    /// older than the last (stale: dropped). A sample more than [`super::SOURCE_RESTART_S`] older than
    /// the last is a source that started again: the autopilot does too.
    pub fn step(&mut self, sample: &SensorSample, inputs: &StepInputs) -> Option<AutopilotOutput> {
        let mut sample = *sample;
        if self.step_in_place(&mut sample, inputs) {
            self.last_answer
        } else {
            None
        }
    }

    /// [`Autopilot::step`] without copying its answer out: whether there is one, which
    /// [`Autopilot::output`] then holds (the control loop's way). The sample is flown in place
    /// and left as the logs record it: raw (before the IMU's calibration), after the failure
    /// injection and the sensor monitor, but for the GPS solution, which is the receiver's
    /// whether or not the monitor took it (a 2D fix, a frozen receiver).
    pub fn step_in_place(&mut self, sample: &mut SensorSample, inputs: &StepInputs) -> bool {
        let t_usec = sample.t_usec;
        let mut restarted = false;
        if let Some(last) = &self.last_answer
            && t_usec.saturating_add(SOURCE_RESTART_USEC) < last.t_usec
        {
            let back_s = (last.t_usec - t_usec) as f64 * 1e-6;
            self.source_restarted(back_s);
            restarted = true;
        }
        if let Some(last) = self.last_answer.as_mut()
            && t_usec <= last.t_usec
        {
            // A sample seen before: answered again without stepping; an older one is dropped.
            self.repeated_frames += 1;
            if t_usec == last.t_usec {
                last.kind = StepKind::Repeated;
                return true;
            }
            return false;
        }
        self.power_and_gps(sample, t_usec);
        self.injected.apply_to_sample(sample);
        // What the receiver said, for the logs, whether or not the estimators take it. Copied
        // only when there is one: a solution is 160 bytes, and a plain `sample.gps` copies them
        // every step (80 instructions a frame more, measured).
        let received_gps = if sample.gps.is_some() {
            sample.gps
        } else {
            None
        };
        // Lost sensors are taken out: the estimators fall back as for a sensor that is off.
        self.monitor.update(sample);
        if let Some(commands) = self.imu_frozen(t_usec) {
            return self.blind_output(t_usec, commands, restarted);
        }
        let t_s = t_usec as f64 * 1e-6;
        let last_seen = self.calibrate(t_s, t_usec, sample);
        if received_gps.is_some() {
            // The logs' sample keeps the receiver's solution.
            sample.gps = received_gps;
        }
        if let Some(frame) = &inputs.rc {
            self.rc_frame(t_s, frame);
        }
        let (setpoint, armed) = self.command_setpoint(t_s, inputs);
        // The commander's state once a step, published in place: nothing below changes it.
        self.published.status = self.commander.status();
        let spooling = self.set_flight_phase();
        let core_commands = self.fly_core(sample, &setpoint, armed, last_seen);
        self.published.setpoint = armed.then_some(setpoint);
        if armed && !spooling && !self.monitor.imu_repeating() {
            // Not while the IMU repeats itself: if it is freezing, the loops fly blind and the
            // blind descent must not inherit what they command meanwhile. Nor at idle on the
            // ground before the take-off: the filter starts from the climb's first commands.
            let dt = self.dt_since_last(t_usec);
            self.hover.update(&core_commands, dt);
        } else if !armed {
            self.hover.reset();
        }
        let mut commands = core_commands;
        self.injected
            .apply_to_commands(&mut commands[..self.rotors]);
        self.answer(t_usec, commands, (armed, setpoint, restarted));
        self.publish_besides_status();
        true
    }

    /// The calibrations step on the raw `sample`; the calibrated one is written where it is
    /// published (the held sample), with the magnetometer and barometer as fresh as they came
    /// (the flight core steps on it so, [`Self::fly_core`]). Returns them as last seen before.
    fn calibrate(&mut self, t_s: f64, t_usec: u64, sample: &SensorSample) -> LastSeen {
        // The calibrations take the raw readings, the estimators the calibrated ones; the logs
        // keep the raw.
        self.step_calibrations(t_s, sample);
        let (dt, first) = (self.dt_since_last(t_usec), self.last_answer.is_none());
        let flown = self.published.held_sample.get_or_insert(*sample);
        let last_seen = (flown.mag, flown.baro_alt_m);
        self.imu_correction.apply_into(sample, flown);
        if !first {
            let p = &self.core.config().attitude;
            self.mag_field.update(flown.mag, &flown.accel, p, dt);
        }
        last_seen
    }

    /// The flight core's step on the calibrated sample ([`Self::calibrate`]), its output
    /// written in place where it is kept once, the published state (the answer does not copy
    /// it); then the magnetometer and barometer held as last seen. Returns the core's commands.
    fn fly_core(
        &mut self,
        sample: &SensorSample,
        setpoint: &Setpoint,
        armed: bool,
        last_seen: LastSeen,
    ) -> [f64; MAX_ROTORS] {
        let p = &mut self.published;
        let output = p.estimate.get_or_insert_with(StepOutput::default);
        let flown = p.held_sample.get_or_insert(*sample);
        self.core.step_into(flown, setpoint, armed, output);
        // Magnetometer and barometer as last seen (a sample carries them only when fresh).
        flown.mag = flown.mag.or(last_seen.0);
        flown.baro_alt_m = flown.baro_alt_m.or(last_seen.1);
        let (commands, motor_failure) = (output.commands, output.motor_failure);
        let reset = output.attitude.map(|a| a.reset);
        self.report_core(motor_failure, reset);
        commands
    }

    /// The answer to a flown step, written over the last one in place.
    fn answer(
        &mut self,
        t_usec: u64,
        commands: [f64; MAX_ROTORS],
        (armed, setpoint, restarted): (bool, Setpoint, bool),
    ) {
        match &mut self.last_answer {
            Some(a) => {
                (a.t_usec, a.commands, a.armed, a.kind) =
                    (t_usec, commands, armed, StepKind::Flown);
                (a.setpoint, a.restarted) = (setpoint, restarted);
            }
            None => {
                self.last_answer = Some(AutopilotOutput {
                    t_usec,
                    commands,
                    armed,
                    kind: StepKind::Flown,
                    setpoint,
                    restarted,
                })
            }
        }
    }

    /// The battery's voltage and charge, and the last GPS solution, from `sample`.
    fn power_and_gps(&mut self, sample: &SensorSample, t_usec: u64) {
        self.published.battery_v = sample.battery_v.unwrap_or(self.nominal_v);
        if let Some(g) = sample.gps {
            self.published.gps = Some(g);
        }
        if let Some(v) = sample.battery_v {
            let current = sample
                .esc_current_a
                .map(|c| c[..self.rotors.min(c.len())].iter().sum::<f64>());
            let throttle = self.published.estimate.as_ref().map_or(0.0, |e| {
                e.commands[..self.rotors].iter().sum::<f64>() / self.rotors.max(1) as f64
            });
            let dt = self.dt_since_last(t_usec);
            self.battery.step(v, current, throttle, dt);
        }
    }

    /// Tells the flight core where the vehicle is in its flight (from the commander's state as
    /// published); returns whether it is spooling up on the ground.
    fn set_flight_phase(&mut self) -> bool {
        let (armed, landed) = (self.published.status.armed, self.published.status.landed);
        let ground_contact = self.published.status.ground_contact;
        let spooling = armed && landed == LandedState::OnGround;
        if spooling {
            // Spooling up on the ground: the position loop starts fresh at take-off.
            self.core.reset_position_loop();
        }
        self.core
            .set_in_air(matches!(landed, LandedState::InAir | LandedState::Landing));
        self.core
            .set_learn_disturbance(matches!(landed, LandedState::InAir | LandedState::Takeoff));
        // On the ground until a take-off begins: idle, level, held by the ground (PX4's spool-up
        // at idle). Near the hover thrust the wind would slide it off on light feet.
        self.core.set_ground_contact(if spooling {
            GroundContact::MaybeLanded
        } else {
            ground_contact
        });
        spooling
    }

    /// Logs what the flight core's step found: a motor failure, an attitude estimate reset.
    fn report_core(&mut self, motor_failure: Option<MotorFailure>, reset: Option<EstimateReset>) {
        if let Some(f) = motor_failure {
            tracing::error!(
                motor = f.rotor + 1,
                by = ?f.by,
                lost = format!("{:.0} %", 100.0 * f.lost_fraction),
                reallocated = self.core.config().motor_failure.reallocate,
                "motor failure detected"
            );
        }
        if let Some(r) = reset {
            if r.tilt > self.estimate_resets.0 {
                tracing::warn!(off_deg = %format!("{:.1}", r.tilt_rad.to_degrees()), "attitude estimate reset: tilt");
            }
            if r.heading > self.estimate_resets.1 {
                tracing::warn!(off_deg = %format!("{:.1}", r.heading_rad.to_degrees()), "attitude estimate reset: heading");
            }
            self.estimate_resets = (r.tilt, r.heading);
        }
    }
}
