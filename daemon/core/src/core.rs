//! The flight core: one `step` from a sensor sample and a set-point to motor commands.
//!
//! sensors ─► attitude estimator (q-method + observer) ─► translation estimator ─► position
//! loop ─► kinematic attitude law (Castillo (63)) ─► rate loop (LADRC or PID) ─► mixer.
//! Pure: no clock (time comes with the sample), no I/O, no allocation in `step`.

use crate::control::attitude::{KinematicAttitude, TiltYawPd};
use crate::control::disturbance::{DisturbanceObserver, WindEstimate, still_air_drag};
use crate::control::motor::MotorSpeedLoop;
use crate::control::position::{AttitudeSetpoint, PositionController};
use crate::control::rate::{LadrcAxis, PidAxis};
use crate::control::reduced_attitude::ReducedAttitude;
use crate::control::{GroundContact, Setpoint};
use crate::estimator::attitude::{AttitudeEstimate, AttitudeEstimator, AttitudeInput, DT_RANGE_S};
use crate::estimator::translation::{GpsMeasurement, TranslationEstimate, TranslationEstimator};
use crate::mixer::{Mixer, MixerError, MixerInput, MixerOutput, WrenchRequest};
use crate::safety::motor_failure::{DetectorInput, MotorFailure, MotorFailureDetector};
use airframe::{Airframe, DragSpec, MAX_ROTORS};
use nalgebra::Vector3;

mod config;
pub use config::{AttitudeLaw, FlightCoreConfig, RateLoopParams};

/// One sample of the flight board's sensors.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SensorSample {
    /// Time of the sample (µs).
    pub t_usec: u64,
    /// Mean gyro rate over the interval, FRD (rad/s).
    pub gyro: Vector3<f64>,
    /// Mean specific force over the interval, FRD (m/s²).
    pub accel: Vector3<f64>,
    /// Magnetometer, when fresh.
    pub mag: Option<Vector3<f64>>,
    /// Barometric altitude (m AMSL), when fresh.
    pub baro_alt_m: Option<f64>,
    /// GPS solution, when one arrived.
    pub gps: Option<GpsMeasurement>,
    /// Battery voltage (V), when the board (or simulator) reports it; the pack's nominal
    /// voltage is flown otherwise.
    pub battery_v: Option<f64>,
    /// Current per ESC (A) by rotor, when reported (their sum is the pack's current).
    pub esc_current_a: Option<[f64; MAX_ROTORS]>,
    /// Rotor speeds from ESC telemetry (rad/s), when fresh.
    pub rotor_speed_rad_s: Option<[f64; MAX_ROTORS]>,
}

impl SensorSample {
    /// The IMU's readings alone, at time 0: every other sensor absent.
    pub fn imu(gyro: Vector3<f64>, accel: Vector3<f64>) -> Self {
        Self {
            t_usec: 0,
            gyro,
            accel,
            mag: None,
            baro_alt_m: None,
            gps: None,
            battery_v: None,
            esc_current_a: None,
            rotor_speed_rad_s: None,
        }
    }
}

/// What one step produced.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct StepOutput {
    /// Motor commands ∈ [0, 1] (all zero when disarmed or not aligned).
    pub commands: [f64; MAX_ROTORS],
    /// Attitude estimate, once aligned.
    pub attitude: Option<AttitudeEstimate>,
    /// Translation estimate.
    pub translation: TranslationEstimate,
    /// Position loop output (when flying).
    pub attitude_setpoint: Option<AttitudeSetpoint>,
    /// Rate reference (rad/s).
    pub rate_reference: Vector3<f64>,
    /// The allocation (when flying).
    pub mixer: Option<MixerOutput>,
    /// A rotor declared failed at this step.
    pub motor_failure: Option<MotorFailure>,
    /// The wind the outside force on the vehicle means (armed, once it has flown).
    pub wind: Option<WindEstimate>,
}

#[derive(Clone)]
enum RateAxis {
    Ladrc(LadrcAxis),
    Pid(PidAxis),
}

/// The flight core.
#[derive(Clone)]
pub struct FlightCore {
    config: FlightCoreConfig,
    attitude: AttitudeEstimator,
    translation: TranslationEstimator,
    position: PositionController,
    attitude_law: AttitudeLaw,
    rate: [RateAxis; 3],
    mixer: Mixer,
    motor: MotorSpeedLoop,
    motor_failure: MotorFailureDetector,
    /// A quad's reduced-attitude controller for each rotor it may lose (empty for other
    /// airframes; `None` where that rotor's loss has no relaxed hover).
    three_rotors: Vec<Option<ReducedAttitude>>,
    /// The rotor lost while a quad flies spinning on the other three.
    spinning_without: Option<usize>,
    /// The allocation flown since the last sample (what the rotors were told).
    last_mix: Option<MixerOutput>,
    in_air: bool,
    /// Whether the outside force may be learned now (climbing away or flying, not landing).
    learn_disturbance: bool,
    ground_contact: GroundContact,
    last_t_usec: Option<u64>,
    /// The attitude estimate's tilt resets seen so far.
    tilt_resets: u64,
    flying: bool,
    /// The position loop's last output, the time since it ran (s), and the time since its
    /// schedule last fell due (s; negative: it ran early, within half a sample).
    position_output: Option<AttitudeSetpoint>,
    since_position_s: f64,
    position_phase_s: f64,
    /// The outside force on the vehicle (wind), learned in the air.
    disturbance: DisturbanceObserver,
    /// The airframe's drag, to read the outside force as a wind.
    drag: DragSpec,
    /// The wind it means, and the time since it was last worked out (s).
    wind: Option<WindEstimate>,
    wind_age_s: f64,
    /// Air density from the last barometer sample (kg/m³).
    air_density_kg_m3: f64,
    /// The pack's nominal voltage (V): 3.8 V a cell, flown while no voltage is reported.
    nominal_battery_v: f64,
    /// Time steps clamped into the accepted range.
    pub dt_clamped: u64,
}

fn rate_axes(p: &RateLoopParams) -> [RateAxis; 3] {
    match p {
        RateLoopParams::Ladrc(l) => [0, 1, 2].map(|i| RateAxis::Ladrc(LadrcAxis::new(l[i]))),
        RateLoopParams::Pid(q) => [0, 1, 2].map(|i| RateAxis::Pid(PidAxis::new(q[i]))),
    }
}

/// The pack's nominal voltage (V): 3.8 V a LiPo cell.
pub fn nominal_battery_v(airframe: &Airframe) -> f64 {
    3.8 * airframe.battery.cells as f64
}

/// How often the wind is worked out from the outside force (s): the rate of the fastest
/// stream or log topic that carries it.
const WIND_PERIOD_S: f64 = 0.1;

/// ISA air density from a pressure altitude (kg/m³).
fn air_density(pressure_alt_m: f64) -> f64 {
    crate::SEA_LEVEL_AIR_DENSITY_KG_M3
        * (1.0 - 2.255_77e-5 * pressure_alt_m.clamp(-500.0, 11_000.0)).powf(4.255_9)
}

impl FlightCore {
    /// A flight core for an airframe.
    pub fn new(airframe: &Airframe, config: FlightCoreConfig) -> Result<Self, MixerError> {
        Ok(Self {
            attitude: AttitudeEstimator::new(&config.attitude),
            translation: TranslationEstimator::new(config.translation),
            position: PositionController::new(config.position),
            attitude_law: config.attitude_law,
            rate: rate_axes(&config.rate),
            mixer: Mixer::new(airframe)?,
            motor: MotorSpeedLoop::new(airframe, config.motor),
            motor_failure: MotorFailureDetector::new(airframe, config.motor_failure),
            three_rotors: if airframe.rotors.len() == 4 {
                (0..4)
                    .map(|lost| ReducedAttitude::for_lost_rotor(airframe, lost))
                    .collect()
            } else {
                Vec::new()
            },
            spinning_without: None,
            last_mix: None,
            in_air: false,
            learn_disturbance: false,
            ground_contact: GroundContact::None,
            last_t_usec: None,
            tilt_resets: 0,
            flying: false,
            position_output: None,
            since_position_s: 0.0,
            position_phase_s: 0.0,
            disturbance: DisturbanceObserver::new(config.position.disturbance_tau_s),
            drag: airframe.drag.clone(),
            wind: None,
            wind_age_s: 0.0,
            air_density_kg_m3: air_density(0.0),
            nominal_battery_v: nominal_battery_v(airframe),
            dt_clamped: 0,
            config,
        })
    }

    /// The configuration flown.
    pub fn config(&self) -> &FlightCoreConfig {
        &self.config
    }

    /// Changes the configuration in flight (a parameter set from a ground station): gains,
    /// limits and estimator settings take effect at the next step and every state (estimates,
    /// integrators, observers) is kept. Only a change of rate controller (LADRC ↔ PID) starts
    /// that loop afresh.
    pub fn set_config(&mut self, config: FlightCoreConfig) {
        self.attitude.set_params(&config.attitude);
        self.translation.set_params(config.translation);
        self.position.params = config.position;
        self.disturbance.tau_s = config.position.disturbance_tau_s;
        self.attitude_law = config.attitude_law;
        match (&mut self.rate, &config.rate) {
            (axes, RateLoopParams::Ladrc(p))
                if axes.iter().all(|a| matches!(a, RateAxis::Ladrc(_))) =>
            {
                for (a, p) in axes.iter_mut().zip(p) {
                    if let RateAxis::Ladrc(l) = a {
                        l.params = *p;
                    }
                }
            }
            (axes, RateLoopParams::Pid(p))
                if axes.iter().all(|a| matches!(a, RateAxis::Pid(_))) =>
            {
                for (a, p) in axes.iter_mut().zip(p) {
                    if let RateAxis::Pid(l) = a {
                        l.params = *p;
                    }
                }
            }
            (axes, p) => *axes = rate_axes(p),
        }
        self.motor.set_params(config.motor);
        self.motor_failure.set_params(config.motor_failure);
        self.config = config;
    }

    /// Tells the core whether the vehicle is flying (the commander's landed state): the
    /// thrust-imbalance check of motor-failure detection runs only in the air.
    pub fn set_in_air(&mut self, in_air: bool) {
        self.in_air = in_air;
    }

    /// Tells the core whether to learn the outside force (the commander taking off or flying)
    /// or hold what it learned (landing: near the ground its legs' friction would read as a
    /// push, and answering it would tip the vehicle over on them).
    pub fn set_learn_disturbance(&mut self, learn: bool) {
        self.learn_disturbance = learn;
    }

    /// Tells the core how far a landing has come on the ground (the commander's land
    /// detector): in contact the position loop stops holding the horizontal position, maybe
    /// landed the thrust is cut to idle with the attitude level and the rate loop's
    /// integrators cleared, so that the ground holds the vehicle, not the loops.
    pub fn set_ground_contact(&mut self, contact: GroundContact) {
        self.ground_contact = contact;
    }

    /// Rotors declared failed this flight (true = failed).
    pub fn failed_rotors(&self) -> &[bool] {
        self.motor_failure.failed()
    }

    /// The rotor lost while a quad flies spinning on its other three (the reduced-attitude
    /// controller flying), if it does.
    pub fn spinning_without(&self) -> Option<usize> {
        self.spinning_without
    }

    /// Whether a quad can fly on when `rotor` stops: the reduced-attitude controller of that
    /// loss exists (false for other airframes, which re-allocate instead).
    pub fn flies_on_three_rotors(&self, rotor: usize) -> bool {
        self.three_rotors.get(rotor).is_some_and(Option::is_some)
    }

    fn reallocate(&mut self) -> Result<(), MixerError> {
        if self.config.motor_failure.reallocate {
            self.mixer.set_failed(self.motor_failure.failed())
        } else {
            Ok(())
        }
    }

    /// The mixer (to mark failed rotors).
    pub fn mixer_mut(&mut self) -> &mut Mixer {
        &mut self.mixer
    }

    /// Forgets the position loop's integrator and set-point history: on the ground before
    /// take-off, so that the spool-up does not wind it against the ground.
    pub fn reset_position_loop(&mut self) {
        self.position.reset();
        self.position_output = None;
        self.position_phase_s = 0.0;
    }

    fn reset_controllers(&mut self) {
        self.reset_position_loop();
        // The wind is learned afresh each flight (it may have changed, or the vehicle moved).
        self.disturbance.reset();
        self.wind = None;
        self.rate = rate_axes(&self.config.rate);
        // A new flight judges the rotors afresh.
        self.motor_failure.reset();
        self.spinning_without = None;
        self.last_mix = None;
        // Every rotor working is always allocatable.
        let _ = self.mixer.set_failed(&[false; MAX_ROTORS]);
    }

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
        let yaw = a.q.euler_angles().2;
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

    /// Forgets the accelerometer bias learned in flight (the accelerometer's calibration
    /// changed).
    pub fn forget_accel_bias(&mut self) {
        self.attitude.forget_accel_bias();
    }

    /// The rotors' mean thrust fraction over the interval just sampled (0 when they were not
    /// driven): what the motor currents' magnetic field scales with, and what a land detector
    /// watches.
    pub fn thrust_fraction(&self) -> f64 {
        let max = self.config.position.max_thrust_n;
        match &self.last_mix {
            Some(m) if max > 0.0 => m.thrust_n.iter().sum::<f64>() / max,
            _ => 0.0,
        }
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
                self.translation.forget_tilt_error();
                self.disturbance.reset();
            }
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
        let translation = self.translation.estimate();
        let mut out = StepOutput {
            commands: [0.0; MAX_ROTORS],
            attitude: att,
            translation,
            attitude_setpoint: None,
            rate_reference: Vector3::zeros(),
            mixer: None,
            motor_failure: None,
            wind: None,
        };
        // Armed, the loops fly on any aligned attitude: one flagged invalid (no correction for
        // a while) is still the gyro's best, far better than stopping the motors in the air.
        // Whether to keep flying on it is the sequence's call (it descends).
        let Some(a) = att.filter(|_| armed) else {
            if self.flying {
                self.reset_controllers();
            }
            self.flying = false;
            return out;
        };
        self.flying = true;
        self.step_disturbance(&a, s, &translation, setpoint, dt);
        // The wind for telemetry and logs (10 Hz at most), not on every sample.
        self.wind_age_s += dt;
        if self.wind_age_s >= WIND_PERIOD_S {
            self.wind_age_s = 0.0;
            self.wind = self.disturbance.wind(
                &translation.vel_ned_m_s,
                a.q.euler_angles().2,
                self.config.position.mass_kg,
                &self.drag,
            );
        }
        out.wind = self.wind;
        // Motor-failure detection on what the rotors were told over the interval just sampled
        // (not while spinning on three rotors: a second loss leaves nothing to fly on).
        if let Some(last) = self
            .last_mix
            .as_ref()
            .filter(|_| self.spinning_without.is_none())
        {
            let n = self.motor_failure.failed().len();
            out.motor_failure = self.motor_failure.step(&DetectorInput {
                dt,
                gyro: s.gyro,
                accel: s.accel,
                speed_setpoint: &last.speed_rad_s[..n],
                thrust_setpoint: &last.thrust_n[..n],
                measured_speed: s.rotor_speed_rad_s.as_ref().map(|r| &r[..n]),
                in_air: self.in_air,
            });
            if let Some(f) = out.motor_failure {
                if self.config.motor_failure.reallocate && self.flies_on_three_rotors(f.rotor) {
                    // A quad: spin about the relaxed-hover axis and control its direction.
                    self.spinning_without = Some(f.rotor);
                }
                // Uncontrollable without it (a quad's second rotor): the old allocation is the
                // best left.
                let _ = self.reallocate();
            }
        }
        // The position loop at its own, lower rate, on the first sample within half a sample of
        // its schedule; the schedule keeps its phase, so the mean rate is the configured one
        // (100 Hz over 250 Hz samples: 8 and 12 ms alternately), over the time since it last ran.
        let (sp, rate_ff, rate_only) = match setpoint {
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
                let mut sp = self.position_step(&setpoint, &translation, &a.q, dt);
                if self.ground_contact == GroundContact::MaybeLanded {
                    // PX4's maybe landed: idle thrust, level, the rate integrators cleared.
                    let (_, _, yaw) = a.q.euler_angles();
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
        };
        // The density of the last barometer sample, held between samples (the barometer is
        // fresh at 50 Hz: falling back to sea level in between made the thrust jump by the
        // density ratio, 5 % at 500 m, four samples in five).
        if let Some(b) = s.baro_alt_m {
            self.air_density_kg_m3 = air_density(b);
        }
        let battery_v = s.battery_v.unwrap_or(self.nominal_battery_v);
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
            .and_then(|r| self.three_rotors.get(r).and_then(Option::as_ref));
        let (rate_reference, m) = match spinning {
            Some(control) => {
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
                (Vector3::zeros(), m)
            }
            None => {
                let (rate_reference, torque) = self.attitude_law(&a, &sp, &rate_ff, rate_only, dt);
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
        };
        // Rotor speeds → commands: the inverse motor curve with the estimated gains, plus the speed
        // PI when rpm is measured (Lewis (4.40)–(4.41), (6.13)).
        let rpm = s.rotor_speed_rad_s.as_ref().map(|r| &r[..]);
        out.commands = self.motor.update(&m.speed_rad_s, rpm, battery_v, dt);
        out.attitude_setpoint = Some(sp);
        out.rate_reference = rate_reference;
        out.mixer = Some(m);
        self.last_mix = Some(m);
        out
    }
}
