//! Estimator replay: logged sensor samples in, the attitude estimate for every one out — how users
//! tune the attitude estimator on real flight data (like PX4's replay).

use crate::estimator::attitude::{AttitudeEstimator, AttitudeInput};
use crate::estimator::wahba::{VectorObservation, quest};
use crate::params::AttitudeParams;
use nalgebra::{UnitQuaternion, Vector3};

/// One logged sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReplaySample {
    /// Time (s).
    pub t_s: f64,
    /// Gyro, FRD (rad/s).
    pub gyro: Vector3<f64>,
    /// Specific force, FRD (m/s²): level at rest reads z ≈ −9.81.
    pub accel: Vector3<f64>,
    /// Magnetometer, FRD (any unit consistent with the calibration), if present.
    pub mag: Option<Vector3<f64>>,
}

/// The estimate for one sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReplayRow {
    /// Time (s).
    pub t_s: f64,
    /// Attitude `q_ned_from_frd`, or `None` before the first sample with accelerometer and
    /// magnetometer.
    pub q: Option<UnitQuaternion<f64>>,
    /// Gyro-bias estimate (rad/s).
    pub gyro_bias: Vector3<f64>,
}

/// Runs the attitude estimator over samples in time order.
///
/// With Castillo's observer (`ATT_MODE` 0) the first `align_samples` samples are a pre-roll, as
/// the live estimator's alignment: if the
/// vehicle was at rest then (rates steady), the initial gyro bias is their mean rate and the
/// initial attitude the q-method of their mean vectors; otherwise the estimate starts at the first
/// sample's q-method with zero bias. Either way every sample gets a row.
pub struct Replay {
    estimator: AttitudeEstimator,
    params: AttitudeParams,
    last_t: Option<f64>,
    started: bool,
    pending: Vec<ReplaySample>,
}

impl Replay {
    /// A replay with these parameters (gains, magnetometer calibration, Earth field).
    pub fn new(params: &AttitudeParams) -> Self {
        // The tilt/heading filter needs no pre-roll: it starts from the first samples, at rest or
        // not, and its estimate is written from the first magnetic heading on.
        let filter = params.mode == 1;
        let params = AttitudeParams {
            align_samples: if filter { 1 } else { params.align_samples },
            ..params.clone()
        };
        Self {
            estimator: AttitudeEstimator::new(&params),
            params,
            last_t: None,
            started: filter,
            pending: Vec::new(),
        }
    }

    fn start(&mut self) {
        let n = self.pending.len().max(1) as f64;
        let mean = |f: fn(&ReplaySample) -> Vector3<f64>| {
            self.pending.iter().map(f).sum::<Vector3<f64>>() / n
        };
        let gyro = mean(|s| s.gyro);
        let spread = self
            .pending
            .iter()
            .map(|s| (s.gyro - gyro).norm())
            .fold(0.0, f64::max);
        let at_rest = spread < 0.05 && gyro.norm() < self.params.bias_limit_rad_s;
        let with_mag: Vec<&ReplaySample> =
            self.pending.iter().filter(|s| s.mag.is_some()).collect();
        let first = if at_rest {
            None
        } else {
            with_mag.first().copied()
        };
        let (accel, mag) = match first {
            Some(s) => (s.accel, s.mag),
            None if !with_mag.is_empty() => (
                mean(|s| s.accel),
                Some(
                    with_mag.iter().filter_map(|s| s.mag).sum::<Vector3<f64>>()
                        / with_mag.len() as f64,
                ),
            ),
            None => (mean(|s| s.accel), None),
        };
        let Some(m) = mag else { return };
        let cal = self.params.mag_calibration();
        let obs = [
            VectorObservation {
                body: accel,
                reference: Vector3::new(0.0, 0.0, -1.0),
                weight: self.params.accel_weight,
            },
            VectorObservation {
                body: cal.apply(&m),
                reference: self.params.earth_field_ned(),
                weight: self.params.mag_weight,
            },
        ];
        if let Ok(q) = quest(&obs) {
            self.estimator.start_at(q);
            if at_rest {
                self.estimator.set_gyro_bias(gyro);
            }
            self.started = true;
        }
    }

    fn run(&mut self, s: &ReplaySample) -> ReplayRow {
        let dt = self.last_t.map_or(0.004, |t| s.t_s - t);
        self.last_t = Some(s.t_s);
        if !self.started {
            return ReplayRow {
                t_s: s.t_s,
                q: None,
                gyro_bias: Vector3::zeros(),
            };
        }
        let input = AttitudeInput {
            gyro: s.gyro,
            accel: s.accel,
            mag: s.mag,
            accel_ned_hint: None,
            vel_ned_hint: None,
            gps_vel: None,
            thrust_fraction: 0.0,
            armed: false,
        };
        let e = self.estimator.update(&input, dt);
        ReplayRow {
            t_s: s.t_s,
            q: e.map(|e| e.q),
            gyro_bias: e.map_or(Vector3::zeros(), |e| e.gyro_bias),
        }
    }

    /// Feeds one sample; returns the rows now known (none during the pre-roll, then the whole
    /// pre-roll at once).
    pub fn push(&mut self, s: &ReplaySample) -> Vec<ReplayRow> {
        if !self.started && self.pending.len() < self.params.align_samples as usize {
            self.pending.push(*s);
            if self.pending.len() < self.params.align_samples as usize {
                return Vec::new();
            }
            return self.flush();
        }
        vec![self.run(s)]
    }

    /// Rows still held in the pre-roll (call at the end of the log).
    pub fn finish(&mut self) -> Vec<ReplayRow> {
        if self.pending.is_empty() {
            Vec::new()
        } else {
            self.flush()
        }
    }

    fn flush(&mut self) -> Vec<ReplayRow> {
        self.start();
        let pending = std::mem::take(&mut self.pending);
        pending.iter().map(|s| self.run(s)).collect()
    }
}
