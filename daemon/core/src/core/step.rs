//! `FlightCore::step` as a short sequence of named stages: the sample's interval, the
//! estimators, the outside force, motor-failure detection, the attitude set-point (position
//! loop or attitude target), the allocation (attitude law, rate loop, mixer) and the motors.

use super::{AttitudeLaw, FlightCore, RateAxis, WIND_PERIOD_S, air_density, rate_axes};
use crate::control::attitude::{KinematicAttitude, TiltYawPd};
use crate::control::disturbance::WindEstimate;
use crate::control::disturbance::still_air_drag;
use crate::control::position::AttitudeSetpoint;
use crate::control::{GroundContact, Setpoint};
use crate::estimator::attitude::{AttitudeEstimate, AttitudeInput, DT_RANGE_S};
use crate::estimator::translation::TranslationEstimate;
use crate::mixer::{MixerInput, MixerOutput, WrenchRequest};
use crate::safety::motor_failure::{DetectorInput, MotorFailure};
use crate::sample::{SensorSample, StepOutput};
use airframe::MAX_ROTORS;
use nalgebra::Vector3;

impl FlightCore {
    /// The position loop at its own, lower rate, on the first sample within half a sample of
    /// its schedule; the schedule keeps its phase, so the mean rate is the configured one
    /// (100 Hz over 250 Hz samples: 8 and 12 ms alternately), over the time since it last ran.
    fn position_step(
        &mut self,
        setpoint: &crate::control::position::PositionSetpoint,
        translation: &TranslationEstimate,
        q: &nalgebra::UnitQuaternion<f64>,
        dt: f64,
    ) -> AttitudeSetpoint {
        let period = self.config.position_period_s;
        self.since_position_s += dt;
        self.position_phase_s += dt;
        match self.position_output {
            Some(sp) if self.position_phase_s < period - 0.5 * dt => sp,
            _ => {
                // Late by more than a period (a gap in the samples): start the schedule afresh.
                self.position_phase_s = if self.position_phase_s > 2.0 * period {
                    0.0
                } else {
                    self.position_phase_s - period
                };
                let sp = self.position.update(
                    setpoint,
                    &translation.pos_ned_m,
                    &translation.vel_ned_m_s,
                    q,
                    if self.position_output.is_some() {
                        self.since_position_s
                    } else {
                        dt
                    },
                );
                self.position_output = Some(sp);
                self.since_position_s = 0.0;
                sp
            }
        }
    }

    /// The outside force learned while flying free (not on the ground, not spinning on three
    /// rotors, where the body's own spin shows in the accelerometer; held while landing), and
    /// handed to the position loop to answer: the wind's share of it, and the drag of the
    /// set-point's velocity (the vehicle's own motion's drag is the loops' damping).
    fn step_disturbance(
        &mut self,
        a: &AttitudeEstimate,
        s: &SensorSample,
        translation: &TranslationEstimate,
        setpoint: &Setpoint,
        dt: f64,
    ) {
        let free = self.ground_contact == GroundContact::None
            && self.spinning_without.is_none()
            && translation.horizontal_valid;
        if !free {
            self.position.set_disturbance(Vector3::zeros());
            return;
        }
        if self.learn_disturbance {
            self.disturbance.update(&a.q, &s.accel, dt);
        }
        let yaw = a.euler_rad.2;
        let m = self.config.position.mass_kg;
        let drag = |v: &Vector3<f64>| still_air_drag(v, yaw, m, &self.drag);
        let wind_share = self.disturbance.accel_ned_m_s2() - drag(&translation.vel_ned_m_s);
        let planned = match setpoint {
            Setpoint::Position(sp) => {
                drag(&sp.vel_ned_m_s.map(|x| if x.is_finite() { x } else { 0.0 }))
            }
            Setpoint::Attitude(_) => Vector3::zeros(),
        };
        self.position.set_disturbance(wind_share + planned);
    }

    /// The attitude law and the rate loop: the rate reference and the body moment (N·m) that
    /// fly `sp` (or, `rate_only`, the rates `rate_ff`).
    fn attitude_law(
        &mut self,
        a: &AttitudeEstimate,
        sp: &AttitudeSetpoint,
        rate_ff: &Vector3<f64>,
        rate_only: bool,
        dt: f64,
    ) -> (Vector3<f64>, Vector3<f64>) {
        match self.attitude_law {
            AttitudeLaw::Kinematic(params) => {
                let r = if rate_only {
                    // Rate mode: the body rates are the reference, within the loop's limits.
                    let mut r = *rate_ff;
                    let tilt = r.xy().norm();
                    if tilt > params.max_tilt_rate {
                        r.x *= params.max_tilt_rate / tilt;
                        r.y *= params.max_tilt_rate / tilt;
                    }
                    r.z = r.z.clamp(-params.max_yaw_rate, params.max_yaw_rate);
                    r
                } else {
                    KinematicAttitude { params }
                        .update(&a.q, &sp.q_d, rate_ff)
                        .rate
                };
                let mut torque = Vector3::zeros();
                for (i, axis) in self.rate.iter_mut().enumerate() {
                    torque[i] = match axis {
                        RateAxis::Ladrc(l) => l.update(r[i], a.rate[i], dt),
                        RateAxis::Pid(p) => p.update(r[i], a.rate[i], dt),
                    };
                }
                (r, torque)
            }
            AttitudeLaw::TiltYawPd(params) => {
                // Lewis's PD damps the rate toward Ω_d (its derivative term; rate mode has
                // no proportional term: q_d is the current attitude).
                let law = TiltYawPd { params };
                (
                    Vector3::zeros(),
                    law.update(&a.q, &sp.q_d, &(a.rate - *rate_ff)),
                )
            }
        }
    }

    /// One step: estimate, then (armed) control toward `setpoint`.
    pub fn step(&mut self, s: &SensorSample, setpoint: &Setpoint, armed: bool) -> StepOutput {
        let mut out = StepOutput::default();
        self.step_into(s, setpoint, armed, &mut out);
        out
    }

    /// [`FlightCore::step`] written over `out` in place: the output is 1.1 kB, and the
    /// autopilot keeps it once.
    pub fn step_into(
        &mut self,
        s: &SensorSample,
        setpoint: &Setpoint,
        armed: bool,
        out: &mut StepOutput,
    ) {
        let (raw_dt, dt) = self.intervals(s);
        self.estimate(s, armed, raw_dt, dt, out);
        let (att, translation) = (out.attitude, out.translation);
        // Armed, the loops fly on any aligned attitude: one flagged invalid (no correction for
        // a while) is still the gyro's best, far better than stopping the motors in the air.
        // Whether to keep flying on it is the sequence's call (it descends).
        let Some(a) = att.filter(|_| armed) else {
            if self.flying {
                self.reset_controllers();
            }
            self.flying = false;
            return;
        };
        self.flying = true;
        self.step_disturbance(&a, s, &translation, setpoint, dt);
        out.wind = self.wind(&a, &translation, dt);
        out.motor_failure = self.detect_motor_failure(s, dt);
        let (sp, rate_ff, rate_only) = if a.realigning {
            self.rates_held(&a)
        } else {
            self.attitude_setpoint(setpoint, &a, &translation, dt)
        };
        // The density of the last barometer sample, held between samples (the barometer is
        // fresh at 50 Hz: falling back to sea level in between made the thrust jump by the
        // density ratio, 5 % at 500 m, four samples in five).
        if let Some(b) = s.baro_alt_m {
            self.air_density_kg_m3 = air_density(b);
        }
        let battery_v = s.battery_v.unwrap_or(self.nominal_battery_v);
        let (rate_reference, m) = self.allocate(&a, &sp, &rate_ff, rate_only, battery_v, dt);
        // Rotor speeds → commands: the inverse motor curve with the estimated gains, plus the speed
        // PI when rpm is measured (Lewis (4.40)–(4.41), (6.13)).
        let rpm = s.rotor_speed_rad_s.as_ref().map(|r| &r[..]);
        out.commands = self.motor.update(&m.speed_rad_s, rpm, battery_v, dt);
        out.attitude_setpoint = Some(sp);
        out.rate_reference = rate_reference;
        out.mixer = Some(m);
        self.last_mix = Some(m);
    }

    /// The interval since the last sample as it came (`raw_dt`) and clamped to the loops'
    /// range (s); a clamp is counted.
    fn intervals(&mut self, s: &SensorSample) -> (f64, f64) {
        let raw_dt = self
            .last_t_usec
            .map_or(0.004, |t| s.t_usec.saturating_sub(t) as f64 * 1e-6);
        self.last_t_usec = Some(s.t_usec);
        let dt = if (DT_RANGE_S.0..=DT_RANGE_S.1).contains(&raw_dt) {
            raw_dt
        } else {
            self.dt_clamped += 1;
            raw_dt.clamp(DT_RANGE_S.0, DT_RANGE_S.1)
        };
        (raw_dt, dt)
    }

    /// The estimators on the sample: the attitude, then the translation predicted through it
    /// and corrected by the GPS and barometer. Returns the step's output with the estimates
    /// and nothing flown yet.
    fn estimate(
        &mut self,
        s: &SensorSample,
        armed: bool,
        raw_dt: f64,
        dt: f64,
        out: &mut StepOutput,
    ) {
        // The accelerometer's reference: the translation filter's acceleration R̂f + g − b, whose
        // bias b is learned from GPS position innovations. A tilt error δ shows up in b as g·δ, so
        // this turns the attitude correction into a GPS-aided one; without it, horizontal
        // acceleration reads as tilt (a/g) and couples into the position loop.
        let before = self.translation.estimate();
        let hint = before.horizontal_valid.then_some(before.accel_ned_m_s2);
        // The raw interval: the attitude estimator clamps it itself and takes a long one as a
        // gap in the samples.
        let att = self.attitude.update(
            &AttitudeInput {
                gyro: s.gyro,
                accel: s.accel,
                mag: s.mag,
                accel_ned_hint: hint,
                // Continuous: its differences are the vehicle's acceleration.
                vel_ned_hint: before
                    .horizontal_valid
                    .then_some(before.vel_ned_m_s - before.vel_resets_ned_m_s),
                gps_vel: s.gps.and_then(|g| self.translation.gps_velocity(&g)),
                thrust_fraction: self.thrust_fraction(),
                armed,
            },
            raw_dt,
        );
        if let Some(a) = &att {
            if a.reset.tilt != self.tilt_resets {
                // What was learned through the wrong tilt is wrong too: the velocity and
                // accelerometer bias integrated through it, the outside force it caused.
                self.tilt_resets = a.reset.tilt;
                if self.attitude_unknown {
                    // Found again after a gap in flight: the height went through it too.
                    self.translation.forget_unknown_attitude();
                } else {
                    self.translation.forget_tilt_error();
                }
                self.disturbance.reset();
            }
            self.attitude_unknown = a.realigning;
            // The accelerometer's bias learned in flight is the position estimator's too.
            let accel = s.accel - a.accel_bias;
            self.translation.predict(s.t_usec, &accel, &a.q, dt);
        }
        if let Some(g) = &s.gps {
            self.translation.fuse_gps(s.t_usec, g);
        }
        if let Some(b) = s.baro_alt_m {
            self.translation.fuse_baro(s.t_usec, b);
        }
        // Field by field: the output is written in place.
        out.commands = [0.0; MAX_ROTORS];
        out.attitude = att;
        out.translation = self.translation.estimate();
        out.attitude_setpoint = None;
        out.rate_reference = Vector3::zeros();
        out.mixer = None;
        out.motor_failure = None;
        out.wind = None;
    }

    /// The wind the outside force means, for telemetry and logs (10 Hz at most, not on every
    /// sample).
    fn wind(
        &mut self,
        a: &AttitudeEstimate,
        translation: &TranslationEstimate,
        dt: f64,
    ) -> Option<WindEstimate> {
        self.wind_age_s += dt;
        if self.wind_age_s >= WIND_PERIOD_S {
            self.wind_age_s = 0.0;
            self.wind = self.disturbance.wind(
                &translation.vel_ned_m_s,
                a.euler_rad.2,
                self.config.position.mass_kg,
                &self.drag,
            );
        }
        self.wind
    }

    /// Motor-failure detection on what the rotors were told over the interval just sampled
    /// (not while spinning on three rotors: a second loss leaves nothing to fly on); a rotor
    /// found failed is taken out of the allocation.
    fn detect_motor_failure(&mut self, s: &SensorSample, dt: f64) -> Option<MotorFailure> {
        let last = self
            .last_mix
            .as_ref()
            .filter(|_| self.spinning_without.is_none())?;
        let n = self.motor_failure.failed().len();
        let failure = self.motor_failure.step(&DetectorInput {
            dt,
            gyro: s.gyro,
            accel: s.accel,
            speed_setpoint: &last.speed_rad_s[..n],
            thrust_setpoint: &last.thrust_n[..n],
            measured_speed: s.rotor_speed_rad_s.as_ref().map(|r| &r[..n]),
            in_air: self.in_air,
        });
        if let Some(f) = failure {
            if self.config.motor_failure.reallocate && self.flies_on_three_rotors(f.rotor) {
                // A quad: spin about the relaxed-hover axis and control its direction.
                self.spinning_without = Some(f.rotor);
            }
            // Uncontrollable without it (a quad's second rotor): the old allocation is the
            // best left.
            let _ = self.reallocate();
        }
        failure
    }

    /// The attitude and thrust to fly, the rate feed-forward, and whether only rates are
    /// asked: from the position loop (a position set-point) or straight from an attitude
    /// set-point.
    fn attitude_setpoint(
        &mut self,
        setpoint: &Setpoint,
        a: &AttitudeEstimate,
        translation: &TranslationEstimate,
        dt: f64,
    ) -> (AttitudeSetpoint, Vector3<f64>, bool) {
        match setpoint {
            Setpoint::Position(setpoint) => {
                let mut setpoint = *setpoint;
                if self.ground_contact != GroundContact::None {
                    // PX4's ground contact: the horizontal axes free (thrust straight up).
                    for v in [
                        &mut setpoint.pos_ned_m,
                        &mut setpoint.vel_ned_m_s,
                        &mut setpoint.accel_ned_m_s2,
                    ] {
                        (v.x, v.y) = (f64::NAN, f64::NAN);
                    }
                }
                // The position loop at its own, lower rate (`position_step`).
                let mut sp = self.position_step(&setpoint, translation, &a.q, dt);
                if self.ground_contact == GroundContact::MaybeLanded {
                    // PX4's maybe landed: idle thrust, level, the rate integrators cleared.
                    let (_, _, yaw) = a.euler_rad;
                    sp.q_d = nalgebra::UnitQuaternion::from_euler_angles(0.0, 0.0, yaw);
                    sp.thrust_n = 0.0;
                    self.rate = rate_axes(&self.config.rate);
                }
                (sp, Vector3::zeros(), false)
            }
            Setpoint::Attitude(target) => {
                // The position loop rests; back in a position mode it starts from the
                // vehicle's own velocity.
                self.reset_position_loop();
                let thrust = target.thrust.clamp(0.0, 1.0);
                let thrust = if thrust.is_nan() { 0.0 } else { thrust };
                let nan = Vector3::repeat(f64::NAN);
                let sp = AttitudeSetpoint {
                    q_d: target.q_d.unwrap_or(a.q),
                    thrust_n: thrust * self.config.position.max_thrust_n,
                    accel_ned_m_s2: nan,
                    vel_ned_m_s: nan,
                };
                let rate = target
                    .rate_frd_rad_s
                    .map(|r| if r.is_finite() { r } else { 0.0 });
                (sp, rate, target.q_d.is_none())
            }
        }
    }

    /// The attitude unknown after a gap in flight (`realign.rs`): the rotation stopped on the
    /// gyro alone, at the thrust of the vehicle's weight, until the attitude is found again
    /// (a fraction of a second with a GPS); the position loop starts afresh then.
    fn rates_held(&mut self, a: &AttitudeEstimate) -> (AttitudeSetpoint, Vector3<f64>, bool) {
        self.reset_position_loop();
        let nan = Vector3::repeat(f64::NAN);
        let sp = AttitudeSetpoint {
            // Rate mode: the attitude held is wherever the vehicle is (no proportional term).
            q_d: a.q,
            thrust_n: self.config.position.mass_kg * crate::GRAVITY_M_S2,
            accel_ned_m_s2: nan,
            vel_ned_m_s: nan,
        };
        (sp, Vector3::zeros(), true)
    }

    /// The rotor speeds for `sp`: through the attitude law, the rate loop and the mixer, or,
    /// spinning on three rotors, the reduced-attitude law's thrusts. Returns the rate
    /// reference and the allocation.
    fn allocate(
        &mut self,
        a: &AttitudeEstimate,
        sp: &AttitudeSetpoint,
        rate_ff: &Vector3<f64>,
        rate_only: bool,
        battery_v: f64,
        dt: f64,
    ) -> (Vector3<f64>, MixerOutput) {
        let rho = self.air_density_kg_m3;
        let input = |torque_frd_n_m| MixerInput {
            request: WrenchRequest {
                thrust_n: sp.thrust_n,
                torque_frd_n_m,
            },
            battery_v,
            air_density: rho,
        };
        let spinning = self
            .spinning_without
            .and_then(|r| self.three_rotor_control(r));
        if let Some(control) = spinning {
            // Mueller & D'Andrea: the primary axis turned toward the thrust direction asked
            // (upright when only rates are: the spin leaves no body rate to fly), the spin
            // left free.
            let up = if rate_only {
                -Vector3::z()
            } else {
                sp.q_d * -Vector3::z()
            };
            let mut top = [0.0; MAX_ROTORS];
            for (i, t) in top.iter_mut().enumerate().take(self.three_rotors.len()) {
                *t = self.mixer.max_thrust(i, rho.max(0.1), battery_v);
            }
            let thrusts = control.update_within(&up, sp.thrust_n, &a.q, &a.rate, &top);
            let m = self.mixer.for_thrusts(&thrusts, &input(Vector3::zeros()));
            return (Vector3::zeros(), m);
        }
        let (rate_reference, torque) = self.attitude_law(a, sp, rate_ff, rate_only, dt);
        let m = self.mixer.mix(&input(torque));
        for (i, axis) in self.rate.iter_mut().enumerate() {
            match axis {
                RateAxis::Ladrc(l) => l.applied(m.achieved.torque_frd_n_m[i]),
                RateAxis::Pid(p) => p.saturation(
                    m.unallocated.torque_frd_n_m[i].signum()
                        * (m.unallocated.torque_frd_n_m[i].abs() > 1e-9) as u8 as f64,
                ),
            }
        }
        (rate_reference, m)
    }
}
