//! The flight core: one `step` from a sensor sample and a set-point to motor commands.
//!
//! sensors ─► attitude estimator (q-method + observer) ─► translation estimator ─► position
//! loop ─► kinematic attitude law (Castillo (63)) ─► rate loop (LADRC or PID) ─► mixer.
//! Pure: no clock (time comes with the sample), no I/O, no allocation in `step`.

use crate::control::attitude::{KinematicAttitude, KinematicParams};
use crate::control::motor::{MotorLoopParams, MotorSpeedLoop};
use crate::control::position::{
    AttitudeSetpoint, PositionController, PositionParams, PositionSetpoint,
};
use crate::control::rate::{LadrcAxis, LadrcParams, PidAxis, PidParams};
use crate::estimator::attitude::{AttitudeEstimate, AttitudeEstimator, AttitudeInput, DT_RANGE_S};
use crate::estimator::translation::{
    GpsMeasurement, TranslationEstimate, TranslationEstimator, TranslationParams,
};
use crate::mixer::{Mixer, MixerError, MixerInput, MixerOutput, WrenchRequest};
use crate::params::AttitudeParams;
use airframe::{Airframe, MAX_ROTORS};
use nalgebra::Vector3;

/// Which inner loop flies the rates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum RateLoopParams {
    /// Castillo's LADRC, one set of parameters per axis.
    Ladrc([LadrcParams; 3]),
    /// The PID alternative.
    Pid([PidParams; 3]),
}

/// Everything the flight core needs to know.
#[derive(Debug, Clone, PartialEq)]
pub struct FlightCoreConfig {
    /// Attitude estimator.
    pub attitude: AttitudeParams,
    /// Translation estimator.
    pub translation: TranslationParams,
    /// Position loop.
    pub position: PositionParams,
    /// Attitude loop.
    pub kinematic: KinematicParams,
    /// Rate loop.
    pub rate: RateLoopParams,
    /// Rotor-speed loop (used when the ESCs report rpm).
    pub motor: MotorLoopParams,
}

impl FlightCoreConfig {
    /// Defaults for an airframe: b̄ = 1/I per axis (so the rate loop's output is a torque), mass
    /// and thrust limits from the airframe.
    pub fn for_airframe(a: &Airframe, use_pid: bool) -> Self {
        let inertia = a.inertia_kg_m2.diagonal();
        let max_thrust: f64 = a
            .rotors
            .iter()
            .map(|r| r.thrust_n(1.225, r.max_speed_rad_s))
            .sum();
        let rate = if use_pid {
            RateLoopParams::Pid([0, 1, 2].map(|i| {
                let j = inertia[i];
                let (kp, ki) = if i < 2 { (12.0, 20.0) } else { (6.0, 4.0) };
                PidParams {
                    k_p: kp * j,
                    k_i: ki * j,
                    k_d: 0.0,
                    k_ff: 0.0,
                    d_cutoff_hz: 30.0,
                    i_limit: 0.3 * a.weight_n() * 0.2,
                    u_max: 1e3,
                }
            }))
        } else {
            RateLoopParams::Ladrc([0, 1, 2].map(|i| LadrcParams {
                b_bar: 1.0 / inertia[i],
                k_d: if i < 2 { 12.0 } else { 6.0 },
                beta: 60.0,
                td_limit: f64::INFINITY,
                u_max: 1e3,
            }))
        };
        Self {
            attitude: AttitudeParams::default(),
            translation: TranslationParams::default(),
            position: PositionParams {
                mass_kg: a.mass_kg,
                k_pos: Vector3::new(0.95, 0.95, 1.0),
                k_vel: Vector3::new(1.8, 1.8, 4.0),
                k_vel_i: Vector3::new(0.4, 0.4, 2.0),
                max_speed_h: 5.0,
                max_speed_up: 3.0,
                max_speed_down: 1.0,
                max_accel_h: 4.0,
                max_accel_v: 4.0,
                max_tilt: 35f64.to_radians(),
                max_thrust_n: max_thrust,
                i_limit: 3.0,
            },
            kinematic: KinematicParams {
                k_k: 6.0,
                yaw_weight: 0.4,
                max_tilt_rate: 3.5,
                max_yaw_rate: 1.5,
            },
            rate,
            motor: MotorLoopParams {
                k_p: 2e-4,
                k_i: 2e-3,
                k_g: 2.0,
                i_limit: 0.2,
                gain_range: 0.3,
            },
        }
    }
}

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
    /// Battery voltage (V).
    pub battery_v: f64,
    /// Rotor speeds from ESC telemetry (rad/s), when fresh.
    pub rotor_speed_rad_s: Option<[f64; MAX_ROTORS]>,
}

/// What one step produced.
#[derive(Debug, Clone, Copy, PartialEq)]
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
}

enum RateAxis {
    Ladrc(LadrcAxis),
    Pid(PidAxis),
}

/// The flight core.
pub struct FlightCore {
    config: FlightCoreConfig,
    attitude: AttitudeEstimator,
    translation: TranslationEstimator,
    position: PositionController,
    kinematic: KinematicAttitude,
    rate: [RateAxis; 3],
    mixer: Mixer,
    motor: MotorSpeedLoop,
    last_t_usec: Option<u64>,
    flying: bool,
    /// Time steps clamped into the accepted range.
    pub dt_clamped: u64,
}

fn rate_axes(p: &RateLoopParams) -> [RateAxis; 3] {
    match p {
        RateLoopParams::Ladrc(l) => [0, 1, 2].map(|i| RateAxis::Ladrc(LadrcAxis::new(l[i]))),
        RateLoopParams::Pid(q) => [0, 1, 2].map(|i| RateAxis::Pid(PidAxis::new(q[i]))),
    }
}

/// ISA air density from a pressure altitude (kg/m³).
fn air_density(pressure_alt_m: f64) -> f64 {
    1.225 * (1.0 - 2.255_77e-5 * pressure_alt_m.clamp(-500.0, 11_000.0)).powf(4.255_9)
}

impl FlightCore {
    /// A flight core for an airframe.
    pub fn new(airframe: &Airframe, config: FlightCoreConfig) -> Result<Self, MixerError> {
        Ok(Self {
            attitude: AttitudeEstimator::new(&config.attitude),
            translation: TranslationEstimator::new(config.translation),
            position: PositionController::new(config.position),
            kinematic: KinematicAttitude {
                params: config.kinematic,
            },
            rate: rate_axes(&config.rate),
            mixer: Mixer::new(airframe)?,
            motor: MotorSpeedLoop::new(airframe, config.motor),
            last_t_usec: None,
            flying: false,
            dt_clamped: 0,
            config,
        })
    }

    /// The mixer (to mark failed rotors).
    pub fn mixer_mut(&mut self) -> &mut Mixer {
        &mut self.mixer
    }

    fn reset_controllers(&mut self) {
        self.position.reset();
        self.rate = rate_axes(&self.config.rate);
    }

    /// One step: estimate, then (armed) control toward `setpoint`.
    pub fn step(
        &mut self,
        s: &SensorSample,
        setpoint: &PositionSetpoint,
        armed: bool,
    ) -> StepOutput {
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
        let att = self.attitude.update(
            &AttitudeInput {
                gyro: s.gyro,
                accel: s.accel,
                mag: s.mag,
                accel_ned_hint: hint,
            },
            dt,
        );
        if let Some(a) = &att {
            self.translation.predict(s.t_usec, &s.accel, &a.q, dt);
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
        };
        let Some(a) = att.filter(|a| a.valid && armed) else {
            if self.flying {
                self.reset_controllers();
            }
            self.flying = false;
            return out;
        };
        self.flying = true;
        let sp = self.position.update(
            setpoint,
            &translation.pos_ned_m,
            &translation.vel_ned_m_s,
            &a.q,
            dt,
        );
        let r = self.kinematic.update(&a.q, &sp.q_d, &Vector3::zeros());
        let mut torque = Vector3::zeros();
        for (i, axis) in self.rate.iter_mut().enumerate() {
            torque[i] = match axis {
                RateAxis::Ladrc(l) => l.update(r.rate[i], a.rate[i], dt),
                RateAxis::Pid(p) => p.update(r.rate[i], a.rate[i], dt),
            };
        }
        let rho = air_density(s.baro_alt_m.unwrap_or(0.0));
        let m = self.mixer.mix(&MixerInput {
            request: WrenchRequest {
                thrust_n: sp.thrust_n,
                torque_frd_n_m: torque,
            },
            battery_v: s.battery_v,
            air_density: rho,
        });
        for (i, axis) in self.rate.iter_mut().enumerate() {
            match axis {
                RateAxis::Ladrc(l) => l.applied(m.achieved.torque_frd_n_m[i]),
                RateAxis::Pid(p) => p.saturation(
                    m.unallocated.torque_frd_n_m[i].signum()
                        * (m.unallocated.torque_frd_n_m[i].abs() > 1e-9) as u8 as f64,
                ),
            }
        }
        // Rotor speeds → commands: the inverse motor curve with the estimated gains, plus the speed
        // PI when rpm is measured (Lewis (4.40)–(4.41), (6.13)).
        let rpm = s.rotor_speed_rad_s.as_ref().map(|r| &r[..]);
        out.commands = self.motor.update(&m.speed_rad_s, rpm, s.battery_v, dt);
        out.attitude_setpoint = Some(sp);
        out.rate_reference = r.rate;
        out.mixer = Some(m);
        out
    }
}
