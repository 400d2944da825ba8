//! Position and velocity in a local NED frame: the accelerometer, rotated to NED, integrated and
//! corrected by GPS (horizontal) and the barometer (vertical).
//!
//! A third-order complementary filter per axis, state (p, v, accelerometer bias b):
//! `v̇ = R f + g − b`, `ṗ = v`, corrected by the position innovation e with gains from one time
//! constant τ (a triple pole at −1/τ): `p += 3/τ e`, `v += 3/τ² e`, `b −= 1/τ³ e` (per second of
//! measurement interval), and by the GPS velocity innovation with gain `1/τ_v`. GPS solutions
//! are old when they arrive (the receiver's latency): each is compared with the estimate of its
//! own time from a short history, and the correction is applied now.
//!
//! The origin (and home) is the first good fix; the barometer's reference is the mean of its
//! first second of samples, so altitude is relative to where the vehicle started.

use super::gps_tilt::DelayedVelocity;
use crate::math::geo::{LatLonAlt, LocalFrame};
use nalgebra::{UnitQuaternion, Vector3};
use std::collections::VecDeque;

/// Barometer samples averaged for the reference level (one second at 50 Hz).
pub const BARO_REF_SAMPLES: u32 = 50;

/// Parameters of the translation filter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TranslationParams {
    /// Horizontal time constant τ (s): larger trusts the accelerometer longer.
    pub tau_xy_s: f64,
    /// Vertical time constant τ (s) for the barometer.
    pub tau_z_s: f64,
    /// GPS velocity correction time constant (s).
    pub tau_vel_s: f64,
    /// Age of a GPS solution on arrival (s).
    pub gps_delay_s: f64,
    /// The GPS position accuracy (m) at which `tau_xy_s` applies as set.
    pub gps_p_noise_m: f64,
    /// The GPS speed accuracy (m/s) at which `tau_vel_s` applies as set.
    pub gps_v_noise_m_s: f64,
    /// Worst horizontal accuracy (m) accepted from the GPS.
    pub gps_max_h_acc_m: f64,
    /// Local position is invalid after this long without GPS (s).
    pub gps_timeout_s: f64,
    /// Altitude is invalid after this long without the barometer (s).
    pub baro_timeout_s: f64,
    /// Bound on the accelerometer bias estimate (m/s²).
    pub accel_bias_limit: f64,
    /// Time constant of the barometer's offset learned from the GPS's height (s; 0: none).
    pub gps_hgt_tau_s: f64,
}

impl Default for TranslationParams {
    fn default() -> Self {
        Self {
            tau_xy_s: 2.5,
            tau_z_s: 2.0, // 1 s: landings up to 0.63 m/s from baro noise in the vertical speed; 2 s: ≤ 0.44 m/s
            tau_vel_s: 0.5,
            gps_delay_s: 0.1,
            gps_p_noise_m: 0.5,
            gps_v_noise_m_s: 0.3,
            gps_max_h_acc_m: 5.0,
            gps_timeout_s: 1.0,
            baro_timeout_s: 0.5,
            accel_bias_limit: 1.0,
            gps_hgt_tau_s: 400.0,
        }
    }
}

/// A GPS solution.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GpsMeasurement {
    /// Fix type (3 = 3D).
    pub fix_type: u8,
    /// Position.
    pub position: LatLonAlt,
    /// Velocity NED (m/s).
    pub vel_ned_m_s: Vector3<f64>,
    /// Horizontal accuracy (m).
    pub h_acc_m: f64,
    /// Satellites visible.
    pub satellites: u8,
    /// What a receiver on a serial port says beyond that (none from `HIL_GPS`).
    pub details: GpsDetails,
}

/// What a GPS receiver says of its solution beyond position, velocity and horizontal
/// accuracy (u-blox's `NAV-PVT` and `NAV-DOP`, NMEA's `GSA` and `GST`); `None` where it is
/// silent.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct GpsDetails {
    /// Vertical accuracy, 1σ (m).
    pub v_acc_m: Option<f64>,
    /// Speed accuracy, 1σ (m/s).
    pub s_acc_m_s: Option<f64>,
    /// Heading accuracy, 1σ (deg).
    pub heading_acc_deg: Option<f64>,
    /// Horizontal and vertical dilution of precision.
    pub dop: Option<(f64, f64)>,
    /// The solution's UTC time (µs since the Unix epoch).
    pub time_utc_usec: Option<u64>,
    /// The receiver sent no velocity over the ground with this solution (an NMEA `GGA`
    /// without `RMC` or `VTG`): the north and east components are 0, and it is not fused.
    pub no_horizontal_velocity: bool,
    /// The receiver measures no vertical velocity (NMEA): the down component is 0.
    pub no_vertical_velocity: bool,
}

/// How much longer than its own a time constant is for a GPS of stated accuracy `acc` (1σ)
/// over the noise floor `floor`: the steady-state Kalman filter of a double integrator has a
/// bandwidth ∝ (q/r)^¼, so a time constant ∝ √σ. A receiver at or below the floor (or one
/// that says nothing) is fused at the filter's own time constants, as EKF2 floors the
/// receiver's accuracy with `EKF2_GPS_P_NOISE` and `EKF2_GPS_V_NOISE`.
fn stretch(acc: Option<f64>, floor: f64) -> f64 {
    acc.filter(|a| a.is_finite() && floor > 0.0)
        .map_or(1.0, |a| (a / floor).max(1.0).sqrt())
}

/// The estimate.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct TranslationEstimate {
    /// Position NED relative to the origin (m).
    pub pos_ned_m: Vector3<f64>,
    /// Velocity NED (m/s).
    pub vel_ned_m_s: Vector3<f64>,
    /// The steps the velocity took at resets, summed (m/s): the velocity less it is continuous
    /// (PX4's `vxy_reset_delta`, summed).
    pub vel_resets_ned_m_s: Vector3<f64>,
    /// Acceleration NED (m/s²), the attitude estimator's hint.
    pub accel_ned_m_s2: Vector3<f64>,
    /// Horizontal position is usable: origin set and GPS fresh. The local frame is anchored at the
    /// GPS origin, so local and global position are valid together.
    pub horizontal_valid: bool,
    /// Altitude is usable (barometer fresh).
    pub vertical_valid: bool,
    /// The origin, once set.
    pub origin: Option<LatLonAlt>,
}

/// Counters and innovations.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct TranslationStatus {
    /// GPS solutions fused.
    pub gps_fused: u64,
    /// GPS solutions refused (no 3D fix, poor accuracy, non-finite).
    pub gps_rejected: u64,
    /// Barometer samples fused.
    pub baro_fused: u64,
    /// Last horizontal position innovation (m).
    pub gps_innovation_m: f64,
    /// Last barometer innovation (m).
    pub baro_innovation_m: f64,
    /// Accelerometer bias estimate, NED (m/s²).
    pub accel_bias: [f64; 3],
    /// The barometer's offset from the GPS's height (m, down).
    pub baro_offset_m: f64,
}

#[derive(Debug, Clone, Copy)]
struct Snapshot {
    t_usec: u64,
    pos: Vector3<f64>,
    vel: Vector3<f64>,
}

const HISTORY: usize = 512;
/// The worst stated vertical accuracy whose height corrects the barometer's offset (m).
const MAX_V_ACC_M: f64 = 5.0;

/// The translation estimator.
#[derive(Debug, Clone)]
pub struct TranslationEstimator {
    params: TranslationParams,
    frame: Option<LocalFrame>,
    pos: Vector3<f64>,
    vel: Vector3<f64>,
    bias: Vector3<f64>,
    /// The next GPS velocity is taken whole ([`Self::forget_tilt_error`]).
    take_next_gps_velocity: bool,
    /// The next barometer height is taken whole ([`Self::forget_unknown_attitude`]).
    take_next_baro_height: bool,
    /// The barometer's offset from the GPS's height (m, down): the weather's pressure change
    /// and the sensor's drift, learned over `gps_hgt_tau_s` and taken off every sample, as
    /// EKF2's baro bias estimator and EKF3 keep the barometer to the GNSS's height.
    baro_offset_m: f64,
    /// Its rate of change (m/s).
    baro_offset_rate_m_s: f64,
    /// The steps those resets made, summed.
    vel_resets: Vector3<f64>,
    accel: Vector3<f64>,
    history: VecDeque<Snapshot>,
    /// The barometer's reference level: the mean of its first [`BARO_REF_SAMPLES`] samples
    /// (sum, count), as ArduPilot's ground-pressure calibration averages at start-up: one
    /// sample's noise (0.25 m here) would offset every altitude of the flight.
    baro_ref: (f64, u32),
    last_gps_usec: Option<u64>,
    last_baro_usec: Option<u64>,
    now_usec: u64,
    status: TranslationStatus,
}

impl TranslationEstimator {
    /// An estimator with no origin yet.
    pub fn new(params: TranslationParams) -> Self {
        Self {
            params,
            frame: None,
            pos: Vector3::zeros(),
            vel: Vector3::zeros(),
            bias: Vector3::zeros(),
            take_next_gps_velocity: false,
            take_next_baro_height: false,
            baro_offset_m: 0.0,
            baro_offset_rate_m_s: 0.0,
            vel_resets: Vector3::zeros(),
            accel: Vector3::zeros(),
            history: VecDeque::with_capacity(HISTORY),
            baro_ref: (0.0, 0),
            last_gps_usec: None,
            last_baro_usec: None,
            now_usec: 0,
            status: TranslationStatus::default(),
        }
    }

    /// Changes the parameters in flight; the estimate is kept.
    pub fn set_params(&mut self, params: TranslationParams) {
        self.params = params;
    }

    /// Counters, innovations and the bias estimate.
    pub fn status(&self) -> TranslationStatus {
        TranslationStatus {
            accel_bias: self.bias.into(),
            ..self.status
        }
    }

    /// Whether the filter takes a GPS solution: a 3D fix, finite, accurate enough.
    fn accepts(&self, gps: &GpsMeasurement) -> bool {
        let finite = [
            gps.position.lat_deg,
            gps.position.lon_deg,
            gps.position.alt_m,
            gps.h_acc_m,
        ]
        .iter()
        .all(|x| x.is_finite())
            && gps.vel_ned_m_s.iter().all(|x| x.is_finite());
        gps.fix_type >= 3
            && finite
            && gps.h_acc_m <= self.params.gps_max_h_acc_m
            && !gps.details.no_horizontal_velocity
    }

    /// A GPS solution's velocity and age, if the filter takes the solution: the attitude
    /// estimator checks its tilt against it.
    pub fn gps_velocity(&self, gps: &GpsMeasurement) -> Option<DelayedVelocity> {
        self.accepts(gps).then_some(DelayedVelocity {
            vel_ned_m_s: gps.vel_ned_m_s,
            age_s: self.params.gps_delay_s,
        })
    }

    /// The attitude was reset: what was integrated through its error is dropped. The
    /// accelerometer bias took the error's `g·δ`; the velocity lags the GPS's, so the next GPS
    /// velocity is taken whole (as EKF2 resets its velocity to the GNSS's after a yaw reset),
    /// its vertical part too where the receiver measures one.
    pub fn forget_tilt_error(&mut self) {
        self.bias = Vector3::zeros();
        self.take_next_gps_velocity = true;
    }

    /// The attitude was unknown for a while in flight (`realign.rs`): the height integrated
    /// through it is dropped too, and the next barometer sample taken whole (as EKF2 resets
    /// its height to the barometer's), besides [`Self::forget_tilt_error`].
    pub fn forget_unknown_attitude(&mut self) {
        self.forget_tilt_error();
        self.take_next_baro_height = true;
    }

    /// The local frame (origin), once set.
    pub fn frame(&self) -> Option<&LocalFrame> {
        self.frame.as_ref()
    }

    /// Prediction with one IMU sample: specific force `accel_frd` (m/s²) and attitude `q`.
    pub fn predict(
        &mut self,
        t_usec: u64,
        accel_frd: &Vector3<f64>,
        q: &UnitQuaternion<f64>,
        dt: f64,
    ) {
        self.now_usec = t_usec;
        if !(accel_frd.iter().all(|x| x.is_finite()) && dt.is_finite() && dt > 0.0) {
            return;
        }
        let a = q * accel_frd + Vector3::new(0.0, 0.0, crate::GRAVITY_M_S2) - self.bias;
        self.accel = a;
        self.pos += self.vel * dt + a * (0.5 * dt * dt);
        self.vel += a * dt;
        if self.history.len() == HISTORY {
            self.history.pop_front();
        }
        self.history.push_back(Snapshot {
            t_usec,
            pos: self.pos,
            vel: self.vel,
        });
    }

    fn past(&self, t_usec: u64) -> Snapshot {
        // Newest snapshot not after t (the history is in time order).
        self.history
            .iter()
            .rev()
            .find(|s| s.t_usec <= t_usec)
            .copied()
            .unwrap_or(Snapshot {
                t_usec,
                pos: self.pos,
                vel: self.vel,
            })
    }

    fn correct(&mut self, axes: [bool; 3], e: &Vector3<f64>, tau: f64, interval: f64) {
        let (k1, k2, k3) = (3.0 / tau, 3.0 / (tau * tau), 1.0 / (tau * tau * tau));
        let interval = interval.clamp(0.0, 1.0);
        for i in 0..3 {
            if !axes[i] {
                continue;
            }
            self.pos[i] += k1 * interval * e[i];
            self.vel[i] += k2 * interval * e[i];
            self.bias[i] = (self.bias[i] - k3 * interval * e[i])
                .clamp(-self.params.accel_bias_limit, self.params.accel_bias_limit);
        }
        // Shift the history by the same correction so later delayed comparisons stay consistent.
        let (dp, dv): (Vector3<f64>, Vector3<f64>) = (
            Vector3::from_fn(|i, _| if axes[i] { k1 * interval * e[i] } else { 0.0 }),
            Vector3::from_fn(|i, _| if axes[i] { k2 * interval * e[i] } else { 0.0 }),
        );
        for s in self.history.iter_mut() {
            s.pos += dp;
            s.vel += dv;
        }
    }

    /// Fuses a GPS solution delivered at `t_usec` (older by `gps_delay_s`).
    pub fn fuse_gps(&mut self, t_usec: u64, gps: &GpsMeasurement) {
        if !self.accepts(gps) {
            self.status.gps_rejected += 1;
            return;
        }
        let interval = self
            .last_gps_usec
            .map_or(0.1, |t| t_usec.saturating_sub(t) as f64 * 1e-6);
        self.last_gps_usec = Some(t_usec);
        let frame = match self.frame {
            Some(f) => f,
            None => {
                // Origin: the first good fix, at the barometer's reference level.
                let origin = LatLonAlt {
                    alt_m: gps.position.alt_m + self.pos.z,
                    ..gps.position
                };
                let f = LocalFrame::new(origin);
                self.frame = Some(f);
                self.pos.x = 0.0;
                self.pos.y = 0.0;
                self.vel.x = gps.vel_ned_m_s.x;
                self.vel.y = gps.vel_ned_m_s.y;
                self.history.clear();
                return;
            }
        };
        let measured = frame.to_ned(&gps.position);
        let then = self.past(t_usec.saturating_sub((self.params.gps_delay_s * 1e6) as u64));
        let e = measured - then.pos;
        self.status.gps_innovation_m = e.xy().norm();
        let tau_xy = self.params.tau_xy_s * stretch(Some(gps.h_acc_m), self.params.gps_p_noise_m);
        self.correct([true, true, false], &e, tau_xy, interval);
        self.learn_baro_offset(measured.z - then.pos.z, gps, interval);
        let ev = gps.vel_ned_m_s - then.vel;
        if std::mem::take(&mut self.take_next_gps_velocity) {
            // The vertical velocity was integrated through the same error; the barometer would
            // take seconds to correct it.
            let ez = if gps.details.no_vertical_velocity || !ev.z.is_finite() {
                0.0
            } else {
                ev.z
            };
            let ev = Vector3::new(ev.x, ev.y, ez);
            self.vel += ev;
            self.vel_resets += ev;
        } else {
            let ev = Vector3::new(ev.x, ev.y, 0.0);
            let tau_vel =
                self.params.tau_vel_s * stretch(gps.details.s_acc_m_s, self.params.gps_v_noise_m_s);
            self.vel += ev * (interval / tau_vel).min(1.0);
        }
        self.status.gps_fused += 1;
    }

    /// The barometer's offset pulled toward the GPS's height: `gps_minus_estimate` (m, down)
    /// is the GPS's height less the estimate at the solution's time, which follows the
    /// corrected barometer within seconds; over `gps_hgt_tau_s` (minutes) the offset takes it
    /// up, so the height keeps the barometer's short-term smoothness and the GPS's long-term
    /// mean. A receiver stating a vertical accuracy worse than 5 m is not used.
    fn learn_baro_offset(&mut self, gps_minus_estimate: f64, gps: &GpsMeasurement, interval: f64) {
        let tau = self.params.gps_hgt_tau_s;
        let vertical_ok = gps.details.v_acc_m.is_none_or(|a| a <= MAX_V_ACC_M);
        if tau > 0.0 && vertical_ok && gps_minus_estimate.is_finite() {
            // Second order, critically damped: the weather's steady change of pressure is
            // followed without lag (its rate learned too), the GPS's wander averaged over τ.
            let (k1, k2) = (2.0 / tau, 1.0 / (tau * tau));
            let dt = interval.min(tau);
            self.baro_offset_rate_m_s -= k2 * gps_minus_estimate * dt;
            self.baro_offset_m += (self.baro_offset_rate_m_s - k1 * gps_minus_estimate) * dt;
            self.status.baro_offset_m = self.baro_offset_m;
        }
    }

    /// Fuses a barometric altitude (m AMSL, ISA) measured at `t_usec`.
    pub fn fuse_baro(&mut self, t_usec: u64, pressure_alt_m: f64) {
        if !pressure_alt_m.is_finite() {
            return;
        }
        let interval = self
            .last_baro_usec
            .map_or(0.02, |t| t_usec.saturating_sub(t) as f64 * 1e-6);
        self.last_baro_usec = Some(t_usec);
        let (sum, n) = &mut self.baro_ref;
        if *n < BARO_REF_SAMPLES {
            *sum += pressure_alt_m + self.pos.z;
            *n += 1;
        }
        let reference = *sum / *n as f64;
        let measured_down = -(pressure_alt_m - reference) - self.baro_offset_m;
        let e = Vector3::new(0.0, 0.0, measured_down - self.pos.z);
        self.status.baro_innovation_m = e.z;
        if std::mem::take(&mut self.take_next_baro_height) {
            self.pos.z = measured_down;
            for s in self.history.iter_mut() {
                s.pos.z += e.z;
            }
            self.status.baro_fused += 1;
            return;
        }
        self.correct([false, false, true], &e, self.params.tau_z_s, interval);
        self.status.baro_fused += 1;
    }

    /// The estimate now.
    pub fn estimate(&self) -> TranslationEstimate {
        let fresh = |last: Option<u64>, timeout: f64| {
            last.is_some_and(|t| self.now_usec.saturating_sub(t) as f64 * 1e-6 <= timeout)
        };
        TranslationEstimate {
            pos_ned_m: self.pos,
            vel_ned_m_s: self.vel,
            vel_resets_ned_m_s: self.vel_resets,
            accel_ned_m_s2: self.accel,
            horizontal_valid: self.frame.is_some()
                && fresh(self.last_gps_usec, self.params.gps_timeout_s),
            vertical_valid: fresh(self.last_baro_usec, self.params.baro_timeout_s)
                && self.baro_ref.1 >= BARO_REF_SAMPLES,
            origin: self.frame.map(|f| f.origin()),
        }
    }
}

crate::params::param_group! {
    /// Translation estimator (position and velocity from accelerometer, GPS and barometer).
    TranslationGroup, "translation", TRANSLATION_META {
        /// Horizontal time constant.
        tau_xy_s: f64 = 2.5, "EST_XY_TAU", "s", [0.2, 30.0], "Horizontal complementary-filter time constant: larger trusts the accelerometer longer";
        /// Vertical time constant.
        tau_z_s: f64 = 2.0, "EST_Z_TAU", "s", [0.2, 30.0], "Vertical (barometer) complementary-filter time constant";
        /// GPS velocity correction time constant.
        tau_vel_s: f64 = 0.5, "EST_VEL_TAU", "s", [0.05, 30.0], "GPS velocity correction time constant";
        /// GPS latency.
        gps_delay_s: f64 = 0.1, "EST_GPS_DELAY", "s", [0.0, 0.5], "Age of a GPS solution when it arrives";
        /// The GPS position noise floor.
        gps_p_noise_m: f64 = 0.5, "EST_GPS_P_NOISE", "m", [0.01, 10.0], "GPS position accuracy at which the horizontal time constant applies as set: a receiver stating a worse one is fused more slowly (by the square root of the ratio)";
        /// The GPS velocity noise floor.
        gps_v_noise_m_s: f64 = 0.3, "EST_GPS_V_NOISE", "m/s", [0.01, 5.0], "GPS speed accuracy at which the velocity time constant applies as set: a receiver stating a worse one is fused more slowly";
        /// Worst GPS accuracy accepted.
        gps_max_h_acc_m: f64 = 5.0, "EST_GPS_MAX_ACC", "m", [0.1, 100.0], "Worst horizontal accuracy accepted from the GPS";
        /// GPS timeout.
        gps_timeout_s: f64 = 1.0, "EST_GPS_TOUT", "s", [0.1, 10.0], "Local position is invalid after this long without GPS";
        /// Barometer timeout.
        baro_timeout_s: f64 = 0.5, "EST_BARO_TOUT", "s", [0.05, 10.0], "Altitude is invalid after this long without the barometer";
        /// Accelerometer bias bound.
        accel_bias_limit: f64 = 1.0, "EST_ACC_B_MAX", "m/s^2", [0.0, 5.0], "Bound on the accelerometer bias estimate";
        /// The barometer's offset from the GPS's height.
        gps_hgt_tau_s: f64 = 400.0, "EST_HGT_GPS_TAU", "s", [0.0, 3600.0], "Time constant of the barometer's offset learned from the GPS's height (the weather's pressure change, drift): the height keeps the barometer's smoothness and the GPS's mean (0: the barometer alone)";
    }
}

#[cfg(test)]
mod tests;
