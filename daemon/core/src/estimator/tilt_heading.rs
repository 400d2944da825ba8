//! The tilt/heading attitude filter: the estimator for real sensors (the default; Castillo's
//! q-method observer stays selectable by `ATT_MODE`).
//!
//! Castillo's observer corrects the gyro attitude towards a q-method solution of the whole
//! accelerometer and magnetometer vectors (80)–(105). On real recordings (the BROAD benchmark)
//! that fails three ways: linear acceleration tilts the estimate, a magnet near the sensor tilts
//! it too (the magnetic vector enters the tilt), and the bias is learned only when nothing moves.
//! This filter keeps the observer's structure — gyro propagation (101) corrected towards the
//! measurements — but splits the correction as VQF does (Laidig & Seel, "VQF: Highly accurate IMU
//! orientation estimation with bias estimation and magnetic disturbance rejection", Information
//! Fusion 91, 2023):
//!
//! - **Gyro**: `q_gyro ← q_gyro ⊗ exp((ω − b̂) T / 2)`, Castillo (101) with (104).
//! - **Tilt**: the specific force rotated into that almost-inertial gyro frame, minus the
//!   vehicle's acceleration when the position estimator knows it, is low-passed there with time
//!   constant `tau_acc`. In an inertial frame a linear acceleration integrates to a change of
//!   velocity, which is bounded, so its low-passed value vanishes while gravity stays; a
//!   correction about a horizontal axis then turns the low-passed vector to the vertical.
//! - **Heading**: only the horizontal part of the magnetic field corrects, only about the
//!   vertical (no magnet can tilt the estimate), with time constant `tau_mag`, a fast start, and
//!   disturbance rejection (see `heading.rs`); the body-fixed part of the field is learned online
//!   (see `hard_iron.rs`).
//! - **Gyro bias**: a Kalman filter (`bias.rs`) fed at rest by the mean rate (`rest.rs`) and in
//!   motion by the tilt and heading corrections through a model of the filters that made them,
//!   so a drifting bias is tracked in flight.
//! - **Recovery**: an error made faster than the low-pass fades it is taken at once from a
//!   steady accelerometer (`recovery.rs`) or, in flight, from the GPS's velocity
//!   (`gps_tilt.rs`).
//! - **Accelerometer bias**: learned in flight from the same GPS windows once turns have shown
//!   it (`accel_bias.rs`), and taken off the specific force before everything else.
//!
//! `q = q_heading ⊗ q_tilt ⊗ q_gyro`.

use super::accel_bias::AccelBiasEstimator;
use super::bias::{BiasEstimator, BiasSettings};
pub use super::gps_tilt::DelayedVelocity;
use super::gps_tilt::GpsTiltCheck;
use super::hard_iron::HardIronEstimator;
use super::heading::HeadingCorrector;
use super::lowpass::LowPass;
use super::motion_start::{FitSample, MotionStartFit};
use super::recovery::TiltRecovery;
use super::rest::{RestDetector, RestThresholds};
use crate::GRAVITY_M_S2;
use crate::math::quat;
use nalgebra::{UnitQuaternion, Vector3};

mod in_flight;
mod settings;
mod start;
mod status;
pub use in_flight::GIVE_UP_S as REALIGN_GIVE_UP_S;
pub use settings::TiltHeadingSettings;
pub use status::{EstimateReset, TiltHeadingStatus};

/// One sample of the filter's sensors.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FilterInput {
    /// Gyro, FRD (rad/s).
    pub gyro: Vector3<f64>,
    /// Specific force, FRD (m/s²).
    pub accel: Vector3<f64>,
    /// The calibrated magnetic field, if a new one came.
    pub mag: Option<Vector3<f64>>,
    /// The vehicle's NED velocity, if the position estimator knows it (GPS-corrected, so not
    /// this attitude's own acceleration).
    pub vel_ned: Option<Vector3<f64>>,
    /// A GPS velocity, if one arrived (made without any attitude).
    pub gps_vel: Option<DelayedVelocity>,
    /// Whether the motors are armed.
    pub armed: bool,
}

/// The filter.
#[derive(Debug, Clone)]
pub struct TiltHeadingFilter {
    settings: TiltHeadingSettings,
    q_gyro: UnitQuaternion<f64>,
    q_tilt: UnitQuaternion<f64>,
    heading: HeadingCorrector,
    bias: BiasEstimator,
    accel_lp: LowPass,
    /// The vehicle's NED acceleration from its velocity's differences, low-passed as the
    /// specific force is, and the last velocity.
    vel_accel_lp: LowPass,
    last_vel: Option<Vector3<f64>>,
    rest: RestDetector,
    /// The tilt's recovery from errors made faster than the low-pass fades them.
    recovery: TiltRecovery,
    /// The tilt against the GPS's velocity in flight.
    gps_check: GpsTiltCheck,
    /// The accelerometer's bias, from the same windows.
    accel_bias: AccelBiasEstimator,
    hard_iron: HardIronEstimator,
    /// Time since the last magnetometer sample (s).
    since_mag_s: f64,
    /// Time left in which the heading may be reset (s): the gyro may have missed a turn.
    unseen_turn_s: f64,
    /// Time since the tilt started (s).
    running_s: f64,
    /// The first rest has set the bias and restarted the tilt and heading.
    rest_aligned: bool,
    /// The fit of a start in motion, until the first rest or its end.
    motion_start: MotionStartFit,
    /// After a fitted start, the heading is held to the field until the bias about the vertical
    /// is known ([`BIAS_SETTLED_RAD_S`]).
    heading_held: bool,
    /// After a gap in flight, the attitude is sought again (`in_flight.rs`).
    realigning: Option<super::realign::InFlightAlignment>,
    status: TiltHeadingStatus,
}

/// The gyro bias is known well enough to take off once its standard deviation is below this
/// (rad/s): 0.1°/s, a tilt lag of 0.3° through the 3 s accelerometer low-pass.
pub const BIAS_SETTLED_RAD_S: f64 = 0.1 * std::f64::consts::PI / 180.0;

/// A clean field's heading this far from the estimate for a second resets it, disarmed and armed
/// (rad), within [`UNSEEN_TURN_S`] of a sign that the gyro missed a turn.
const HEADING_RESET_RAD: f64 = 2.5 * std::f64::consts::PI / 180.0;
const HEADING_RESET_ARMED_RAD: f64 = 30.0 * std::f64::consts::PI / 180.0;
/// Steady flight: the vehicle's low-passed acceleration below this (m/s²); the accelerometer's
/// time constant is then this fraction of `tau_acc_s`.
const STEADY_ACCEL_M_S2: f64 = 0.5;
const STEADY_TAU_FRACTION: f64 = 2.0 / 3.0;
/// How long after a tilt reset or a rate at the gyro's range the heading may be reset (s).
const UNSEEN_TURN_S: f64 = 10.0;
/// A rate this high is at the range of a MEMS gyro (2000°/s) or beyond it: the gyro may have
/// saturated, and the turn it missed is in the heading too (rad/s).
const GYRO_RANGE_RAD_S: f64 = 30.0;

/// What one update's tilt correction works with.
struct TiltStep<'a> {
    /// Gyro rate (rad/s) and specific force, less its learned bias (m/s²), FRD.
    gyro: &'a Vector3<f64>,
    accel: &'a Vector3<f64>,
    /// The vehicle's acceleration known from the velocity (NED, m/s²), and its low-pass.
    known_accel: Option<&'a Vector3<f64>>,
    accel_lp: Vector3<f64>,
    /// The GPS velocity, for the GPS check.
    gps_vel: Option<&'a DelayedVelocity>,
    armed: bool,
    /// Moving, the gyro bias learned from the corrections.
    moving: bool,
}

impl TiltHeadingFilter {
    /// A filter that starts from its first samples (no rest needed).
    pub fn new(settings: TiltHeadingSettings) -> Self {
        Self {
            settings,
            q_gyro: UnitQuaternion::identity(),
            q_tilt: UnitQuaternion::identity(),
            heading: HeadingCorrector::new(settings.heading),
            bias: BiasEstimator::new(settings.bias_settings()),
            accel_lp: LowPass::new(settings.tau_acc_s),
            vel_accel_lp: LowPass::new(settings.tau_acc_s),
            last_vel: None,
            rest: RestDetector::new(RestThresholds {
                max_bias_rad_s: settings.bias_limit_rad_s,
                ..RestThresholds::default()
            }),
            recovery: TiltRecovery::default(),
            gps_check: GpsTiltCheck::default(),
            accel_bias: AccelBiasEstimator::default(),
            hard_iron: HardIronEstimator::new(settings.hard_iron),
            since_mag_s: 0.0,
            unseen_turn_s: 0.0,
            running_s: 0.0,
            rest_aligned: false,
            motion_start: MotionStartFit::default(),
            heading_held: false,
            realigning: None,
            status: TiltHeadingStatus::default(),
        }
    }

    /// Changes the settings, keeping the estimate, bias and learned field.
    pub fn set_settings(&mut self, settings: TiltHeadingSettings) {
        self.accel_lp.set_tau_s(settings.tau_acc_s);
        self.vel_accel_lp.set_tau_s(settings.tau_acc_s);
        self.heading.set_settings(settings.heading);
        self.bias.set_settings(settings.bias_settings());
        self.settings = settings;
    }

    /// The attitude `q_ned_from_frd`.
    pub fn attitude(&self) -> UnitQuaternion<f64> {
        quat::shortest(&(self.heading.rotation() * self.q_tilt * self.q_gyro))
    }

    /// The accelerometer-bias estimate (m/s², body frame) and its standard deviation.
    pub fn accel_bias(&self) -> (Vector3<f64>, Vector3<f64>) {
        (self.accel_bias.bias(), self.accel_bias.sigma())
    }

    /// Forgets the accelerometer bias learned in flight (a new calibration).
    pub fn forget_accel_bias(&mut self) {
        self.accel_bias = AccelBiasEstimator::default();
    }

    /// The gyro-bias estimate (rad/s).
    pub fn bias(&self) -> Vector3<f64> {
        self.bias.bias()
    }

    /// Sets the gyro-bias estimate.
    pub fn set_bias(&mut self, bias: Vector3<f64>) {
        self.bias.set_bias(bias);
    }

    /// Starts again from `q` (the tilt and heading taken from it; the filters keep running).
    pub fn start_at(&mut self, q: UnitQuaternion<f64>) {
        self.q_gyro = q;
        self.q_tilt = UnitQuaternion::identity();
        self.heading.reset_to(0.0);
        self.accel_lp.clear();
        self.vel_accel_lp.clear();
        self.last_vel = None;
        self.recovery.clear();
        self.gps_check.clear();
        self.accel_bias.forget_error();
        self.bias.restart_tilt();
        self.running_s = 0.0;
    }

    /// The IMU alone shows the vehicle still (`TiltRecovery::still`).
    pub fn imu_still(&self) -> bool {
        self.recovery.still()
    }

    /// Whether the magnetic heading has been corrected at all.
    pub fn heading_known(&self) -> bool {
        self.heading.started()
    }

    /// Whether the gyro bias is known well enough to take off ([`BIAS_SETTLED_RAD_S`]).
    pub fn bias_settled(&self) -> bool {
        self.bias.sigma() <= BIAS_SETTLED_RAD_S
    }

    /// Counters.
    pub fn status(&self) -> TiltHeadingStatus {
        TiltHeadingStatus {
            hard_iron_fits: self.hard_iron.accepted(),
            mag_disturbed: self.heading.disturbed_samples(),
            mag_new_reference: self.heading.new_references(),
            reset: EstimateReset {
                heading: self.heading.resets().0,
                heading_rad: self.heading.resets().1,
                ..self.status.reset
            },
            ..self.status
        }
    }

    /// The body-fixed field learned online (calibrated units).
    pub fn hard_iron(&self) -> Vector3<f64> {
        self.hard_iron.offset()
    }

    /// One sample after `dt` seconds. Inputs must be finite.
    pub fn update(&mut self, input: &FilterInput, dt: f64) {
        let FilterInput {
            gyro,
            accel,
            mag,
            vel_ned,
            gps_vel,
            armed,
        } = input;
        // The accelerometer's bias learned in flight is taken off first (`accel_bias.rs`).
        let accel = &(accel - self.accel_bias.bias());
        let (gyro, mag, vel_ned, armed) = (gyro, mag.as_ref(), vel_ned.as_ref(), *armed);
        let s = self.settings;
        // Gyro: Castillo (101), (104).
        let bias = self.bias.bias();
        self.q_gyro = quat::propagate(&self.q_gyro, &(gyro - bias), dt);
        self.unseen_turn_s = if gyro.norm() >= GYRO_RANGE_RAD_S {
            UNSEEN_TURN_S
        } else {
            (self.unseen_turn_s - dt).max(0.0)
        };
        self.bias.predict(dt);
        if self.realigning.is_some() {
            self.realign_step(accel, mag, gps_vel.as_ref(), dt);
        }
        if self.realigning.is_some() {
            // After a gap in flight only the gyro carries the attitude until it is found again.
            if let Some(v) = vel_ned {
                self.last_vel = Some(*v);
            }
            return;
        }

        // Bias at rest: the mean rate. Armed, the vehicle is never at rest: a hover sways slowly
        // enough to pass for stillness, and its rate would be learned as bias.
        let at_rest = self.rest.update(gyro, accel, mag, dt);
        if armed {
            self.rest.interrupt();
        } else if at_rest {
            self.status.at_rest += 1;
            if !self.rest_aligned {
                self.align_at_rest();
            }
            self.bias.at_rest(&self.rest.mean_rate(), dt);
        }
        // In motion the bias is learned from the corrections, below a rate where gyro scale
        // and axis errors drift the attitude as much as a bias would.
        self.running_s += dt;
        // The first two time constants are the low-pass's start and the tilt's convergence (from
        // a start in motion), not a drift.
        let moving = !self.rest.at_rest()
            && self.running_s > 2.0 * s.tau_acc_s
            && (gyro - bias).norm() < s.bias_max_rate_rad_s;
        let (known_accel, accel_lp) = self.known_acceleration(vel_ned, dt);
        self.fit_start_in_motion(gyro, accel, mag, known_accel.as_ref(), &bias, dt);
        let level_from_body = self.correct_tilt(
            &TiltStep {
                gyro,
                accel,
                known_accel: known_accel.as_ref(),
                accel_lp,
                gps_vel: gps_vel.as_ref(),
                armed,
                moving,
            },
            &bias,
            dt,
        );
        if let Some(m) = mag {
            self.correct_heading(m, &level_from_body, armed, moving, dt);
        } else {
            self.since_mag_s += dt;
        }
    }

    /// The vehicle's acceleration known from the velocity's differences, and its low-pass; in
    /// steady flight the low-passes shortened.
    fn known_acceleration(
        &mut self,
        vel_ned: Option<&Vector3<f64>>,
        dt: f64,
    ) -> (Option<Vector3<f64>>, Vector3<f64>) {
        let s = self.settings;
        // Tilt: the specific force low-passed in the gyro frame, less the vehicle's acceleration
        // low-passed the same way, turned to the vertical. That acceleration is the velocity's
        // difference over the step (LP(Δv/Δt) = d/dt LP(v)): it needs no attitude, so the
        // correction does not chase its own estimate (an acceleration made from R̂f would).
        let known_accel = vel_ned.map(|vel| {
            let a = self
                .last_vel
                .map_or(Vector3::zeros(), |last| (vel - last) / dt);
            self.last_vel = Some(*vel);
            a
        });
        // In steady flight, the vehicle's acceleration known and small, the accelerometer is
        // gravity, its bias and its noise: a shorter low-pass lets an error of the gyro's bias
        // (one that walked while a fast turn kept it from being learned) lag the tilt less. The
        // bias model's low-pass is the same operator, so it changes with it.
        let steady = known_accel.is_some()
            && self.vel_accel_lp.started()
            && self.vel_accel_lp.value().norm() < STEADY_ACCEL_M_S2;
        let tau = s.tau_acc_s * if steady { STEADY_TAU_FRACTION } else { 1.0 };
        if self.accel_lp.tau_s() != tau {
            self.accel_lp.set_tau_s(tau);
            self.vel_accel_lp.set_tau_s(tau);
            self.bias.set_settings(BiasSettings {
                tau_acc_s: tau,
                ..s.bias_settings()
            });
        }
        let accel_lp = match known_accel {
            Some(a) => self.vel_accel_lp.update(&a, dt),
            None => {
                self.vel_accel_lp.clear();
                self.last_vel = None;
                Vector3::zeros()
            }
        };
        (known_accel, accel_lp)
    }

    /// A start in motion: the first seconds fitted at once (at rest, the rest's mean wins).
    fn fit_start_in_motion(
        &mut self,
        gyro: &Vector3<f64>,
        accel: &Vector3<f64>,
        mag: Option<&Vector3<f64>>,
        known_accel: Option<&Vector3<f64>>,
        bias: &Vector3<f64>,
        dt: f64,
    ) {
        if self.rest_aligned {
            self.motion_start.abandon();
        } else if !self.motion_start.done() {
            let sample = FitSample {
                gyro_frame: &self.q_gyro,
                rate: &(gyro - bias),
                accel,
                known_accel,
                estimate: (known_accel.is_some() && self.motion_start.wants_estimate())
                    .then(|| self.attitude()),
                mag,
            };
            if let Some(fit) = self.motion_start.update(&sample, dt) {
                self.align_in_motion(&fit, bias);
            }
        }
    }

    /// The tilt corrected toward the low-passed specific force less the known acceleration
    /// (after the recovery's and the GPS check's resets), the accelerometer's bias learned, the
    /// gyro bias's tilt part. Returns the level frame from the body.
    fn correct_tilt(&mut self, t: &TiltStep, bias: &Vector3<f64>, dt: f64) -> UnitQuaternion<f64> {
        let f = self.q_gyro * t.accel;
        self.recovery
            .update(&f, t.known_accel, &(t.gyro - bias), dt);
        self.gps_check
            .update(&f, self.q_gyro.to_rotation_matrix().matrix(), t.gps_vel, dt);
        let (t_s, integral) = self.gps_check.rotation_integral();
        if self.accel_bias.due(t_s)
            && let Some(w) = self.gps_check.window()
        {
            self.accel_bias.update(
                &w,
                &self.q_tilt,
                &self.heading.rotation(),
                (t_s, &integral),
                &self.bias.bias(),
            );
        }
        let mut lp = self.accel_lp.update(&f, dt);
        let mut accel_lp = t.accel_lp;
        // An error made faster than the low-pass fades it (`recovery.rs`): the low-passes start
        // again at the steady accelerometer's values, so the tilt is its at once.
        let reset = self
            .recovery
            .check(&self.q_tilt, &self.heading.rotation(), t.armed)
            .or_else(|| self.gps_check.check(&self.q_tilt, &self.heading.rotation()));
        if let Some(r) = reset {
            self.accel_lp.reset_to(r.specific_force);
            lp = r.specific_force;
            if t.known_accel.is_some() {
                self.vel_accel_lp.reset_to(r.accel_ned);
                accel_lp = r.accel_ned;
            }
            self.status.reset.tilt += 1;
            self.accel_bias.forget_error();
            self.status.reset.tilt_rad = r.error_rad;
            self.unseen_turn_s = UNSEEN_TURN_S;
        }
        let force = self.q_tilt * lp;
        let accel = self.heading.rotation().inverse() * accel_lp;
        let up = Vector3::new(0.0, 0.0, -1.0);
        // The shortest turn of the low-passed force that makes it, less the known acceleration,
        // vertical: about a horizontal axis when the acceleration is small (then the force's own
        // turn to the vertical). Turning the difference alone to the vertical would be out of
        // proportion by |force|/|force − accel|, and grow, under a sustained acceleration near g.
        let correction = ((force - accel).norm() > 0.1 * GRAVITY_M_S2)
            .then(|| force_target(&force, &accel, &up))
            .flatten()
            .and_then(|target| UnitQuaternion::rotation_between(&force, &target));
        if let Some(c) = correction {
            self.q_tilt = UnitQuaternion::new_normalize((c * self.q_tilt).into_inner());
            self.status.tilt_correction_rad = c.angle();
        }
        // The level frame (tilt corrected, heading unknown) from the body.
        let level_from_body = self.q_tilt * self.q_gyro;
        if reset.is_some() {
            // Not a drift of the bias: its model starts again from here.
            self.bias
                .restart_tilt_at(&level_from_body.to_rotation_matrix());
        } else {
            self.bias.tilt(
                &level_from_body.to_rotation_matrix(),
                correction.map(|c| c.scaled_axis()).as_ref(),
                t.moving,
                dt,
            );
        }
        level_from_body
    }

    /// The heading corrected toward the horizontal field `m` (its hard iron learned if asked),
    /// and the gyro bias about the vertical.
    fn correct_heading(
        &mut self,
        m: &Vector3<f64>,
        level_from_body: &UnitQuaternion<f64>,
        armed: bool,
        moving: bool,
        dt: f64,
    ) {
        let s = self.settings;
        self.since_mag_s += dt;
        let dt = std::mem::take(&mut self.since_mag_s);
        let field = self.heading.reference_strength().unwrap_or(m.norm());
        let m = if s.learn_hard_iron {
            m - self.hard_iron.update(m, &self.q_gyro, field, dt)
        } else {
            *m
        };
        // A wrong heading is reset from a clean field, when the gyro may have missed a turn
        // (a tilt reset, a rate at its range): beyond 5° disarmed, 30° armed (a soft-iron
        // error turns the field by a few degrees as the vehicle tilts). Otherwise a field
        // far from the heading is more likely a magnet than a heading error: crept towards.
        self.heading
            .set_reset_limit(match (self.unseen_turn_s > 0.0, armed) {
                (false, _) => std::f64::consts::PI,
                (true, false) => HEADING_RESET_RAD,
                (true, true) => HEADING_RESET_ARMED_RAD,
            });
        // After a start in motion the field has shown itself clean (`motion_start.rs`), and
        // the bias about the vertical is the part the fit saw least: the heading holds to
        // the field until it is learned (then `tau_s` again). Elsewhere (indoors, near steel) a field followed
        // that closely brings its disturbances into the heading.
        if self.heading_held {
            let sigma = self
                .bias
                .vertical_sigma(&level_from_body.to_rotation_matrix());
            self.heading_held = sigma > BIAS_SETTLED_RAD_S;
            self.heading
                .set_drift(if self.heading_held { sigma } else { 0.0 });
        }
        let resets = self.heading.resets().0;
        if let Some(step) = self.heading.update(&(level_from_body * m), dt) {
            self.status.heading_error_rad = self.heading.last_error();
            if self.heading.resets().0 == resets {
                let k = self.heading.last_gain();
                self.bias.heading(step, k, moving, dt);
            }
        }
    }
}

/// Where the low-passed `force` (level frame) must point for `force − accel` to point `up`,
/// at the force's own length: `accel + s·up` with `s > 0`, if the force is long enough to
/// reach the vertical through the acceleration.
fn force_target(
    force: &Vector3<f64>,
    accel: &Vector3<f64>,
    up: &Vector3<f64>,
) -> Option<Vector3<f64>> {
    let b = accel.dot(up);
    let disc = b * b - accel.norm_squared() + force.norm_squared();
    (disc >= 0.0).then(|| accel + up * (disc.sqrt() - b))
}
