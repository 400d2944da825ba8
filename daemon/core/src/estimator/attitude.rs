//! The attitude estimator: q-method measurement (Castillo (80)–(90)) from the accelerometer and
//! the calibrated magnetometer, filtered by the nonlinear observer (97)–(105) with the gyros.
//!
//! Beyond the paper, as a flying autopilot must: an initial alignment at rest (averaged vectors,
//! gyro bias from the mean rate), an accelerometer weight that falls as |a| departs from the
//! expected specific force (and gating beyond a limit), an optional known NED acceleration that
//! turns the gravity reference into the true specific-force reference in accelerated flight, typed
//! rejection of degenerate vectors, and counters for all of it.

use super::observer::AttitudeObserver;
pub use super::tilt_heading::DelayedVelocity;
pub use super::tilt_heading::EstimateReset;
use super::tilt_heading::{FilterInput, TiltHeadingFilter, TiltHeadingStatus};
use super::wahba::{ObservationError, VectorObservation, quest};
use crate::GRAVITY_M_S2;
use nalgebra::{Matrix3, UnitQuaternion, Vector3};

mod meta;
mod params;
pub use meta::ATTITUDE_META;
pub use params::AttitudeParams;

/// Magnetometer calibration of Castillo (75): offset, rotation R and scale E of the fitted
/// ellipsoid.
///
/// (75) as printed, `m = E Rᵀ (m_raw − offset)`, gives the field in the ellipsoid's principal axes,
/// which differ from the body axes by R. The body-frame field is `R E Rᵀ (m_raw − offset)`; that
/// is what [`MagCalibration::apply`] returns.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MagCalibration {
    /// Hard-iron offset (sensor units).
    pub offset: Vector3<f64>,
    /// `R E Rᵀ`, the soft-iron correction in body axes.
    pub correction: Matrix3<f64>,
}

impl MagCalibration {
    /// No correction.
    pub fn identity() -> Self {
        Self {
            offset: Vector3::zeros(),
            correction: Matrix3::identity(),
        }
    }

    /// From Castillo's parameters: offset, ellipsoid rotation R and scale E = diag(scale).
    pub fn from_ellipsoid(
        offset: Vector3<f64>,
        rotation: &Matrix3<f64>,
        scale: &Vector3<f64>,
    ) -> Self {
        Self {
            offset,
            correction: rotation * Matrix3::from_diagonal(scale) * rotation.transpose(),
        }
    }

    /// The field in the body frame.
    pub fn apply(&self, raw: &Vector3<f64>) -> Vector3<f64> {
        self.correction * (raw - self.offset)
    }
}

/// One IMU sample with the other sensors' latest values.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AttitudeInput {
    /// Gyroscope, FRD (rad/s).
    pub gyro: Vector3<f64>,
    /// Accelerometer specific force, FRD (m/s²).
    pub accel: Vector3<f64>,
    /// Raw magnetometer, FRD (any unit consistent with the calibration), if fresh.
    pub mag: Option<Vector3<f64>>,
    /// The vehicle's acceleration in NED (m/s²), when the position estimator knows it
    /// (Castillo's observer).
    pub accel_ned_hint: Option<Vector3<f64>>,
    /// The vehicle's velocity in NED (m/s), when the position estimator knows it (the
    /// tilt/heading filter).
    pub vel_ned_hint: Option<Vector3<f64>>,
    /// A GPS velocity that arrived with this sample, and its age (the tilt/heading filter checks
    /// its tilt against it in flight).
    pub gps_vel: Option<DelayedVelocity>,
    /// The rotors' mean thrust fraction `(ω/ω_max)²` (0 when unknown or disarmed): the motor
    /// currents' field `CAL_MAG0_[XYZ]COMP` times it is taken off the calibrated field.
    pub thrust_fraction: f64,
    /// The motors are armed: the vehicle is not at rest, whatever the sensors show (the
    /// tilt/heading filter learns the bias at rest only when disarmed).
    pub armed: bool,
}

/// The estimator's output.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AttitudeEstimate {
    /// Attitude `q_ned_from_frd`, `w ≥ 0`.
    pub q: UnitQuaternion<f64>,
    /// Roll, pitch and yaw of `q` (rad; Z-Y-X, as MAVLink's `ATTITUDE`), worked out once here
    /// for the controller and the commander that read them every step.
    pub euler_rad: (f64, f64, f64),
    /// Body rate corrected by the bias estimate (rad/s).
    pub rate: Vector3<f64>,
    /// Gyro bias estimate (rad/s).
    pub gyro_bias: Vector3<f64>,
    /// Accelerometer bias estimate (m/s², body frame; zero until GPS windows with turns between
    /// them have shown it, and from Castillo's observer).
    pub accel_bias: Vector3<f64>,
    /// Whether the estimate can be flown on: aligned, and corrected recently enough.
    pub valid: bool,
    /// After a gap in the samples in flight, the attitude is unknown until found again from
    /// the GPS and the magnetometer (`realign.rs`): only the body rates can be flown (invalid
    /// meanwhile).
    pub realigning: bool,
    /// The last reset of the estimate (the tilt or heading taken afresh from a steady
    /// accelerometer or a clean magnetometer, `recovery.rs`), and how many there have been (as
    /// PX4's `quat_reset_counter`).
    pub reset: EstimateReset,
    /// Whether the gyro bias is known well enough to take off (an arming check): Castillo's
    /// observer takes it at the alignment; the tilt/heading filter once its uncertainty is
    /// below 0.1°/s (a rest of 1.5 s, or learning in motion).
    pub bias_settled: bool,
    /// The IMU alone shows the vehicle still (rate, and the specific force's direction and
    /// length, steady for 0.4 s): what a land detector may trust when the estimate is wrong.
    /// The tilt/heading filter only; `false` from Castillo's observer.
    pub imu_still: bool,
}

/// Counters and health of the attitude estimator.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct AttitudeStatus {
    /// Initial alignment finished.
    pub aligned: bool,
    /// Samples taken.
    pub samples: u64,
    /// Accelerometer samples given reduced weight because |a| differed from the expected magnitude.
    pub accel_deweighted: u64,
    /// Accelerometer samples rejected outright (too far from the expected magnitude).
    pub accel_rejected: u64,
    /// q-method solutions refused, by reason.
    pub rejected_non_finite: u64,
    /// Zero-length vectors.
    pub rejected_zero: u64,
    /// Parallel vectors (or only one usable).
    pub rejected_parallel: u64,
    /// Time steps outside the accepted range, clamped.
    pub dt_clamped: u64,
    /// Angle between the last measurement and the estimate (rad): the innovation.
    pub innovation_rad: f64,
    /// Time since the last measurement correction (s).
    pub since_correction_s: f64,
    /// Times the attitude was taken afresh from the measurement after a gap in the samples
    /// longer than `max_uncorrected_s`.
    pub realigned: u64,
    /// Corrections made without a magnetometer (silent for [`MAG_SILENT_S`]): the tilt from
    /// the accelerometer, the heading held on the gyro.
    pub heading_held: u64,
    /// The tilt/heading filter's counters (`ATT_MODE` 1).
    pub tilt_heading: TiltHeadingStatus,
}

/// A magnetometer silent this long (s) no longer corrects: the accelerometer corrects the tilt
/// alone, against the magnetic field the estimate itself predicts, so the heading is the gyro's.
pub const MAG_SILENT_S: f64 = 0.2;

/// No magnetometer sample at all this long (s): the tilt/heading filter aligns without one.
pub const MAG_ABSENT_S: f64 = 1.0;

/// Smallest and largest time step accepted (s); outside, the step is clamped and counted.
pub const DT_RANGE_S: (f64, f64) = (1.25e-4, 0.02);

/// The attitude estimator.
#[derive(Debug, Clone)]
pub struct AttitudeEstimator {
    params: AttitudeParams,
    mag_cal: MagCalibration,
    /// The motor currents' field at full thrust (calibrated units, body frame).
    mag_motor_field: Vector3<f64>,
    mag_ref_ned: Vector3<f64>,
    observer: Option<AttitudeObserver>,
    align_sum: (Vector3<f64>, Vector3<f64>, Vector3<f64>, u32, u32),
    last_mag: Option<Vector3<f64>>,
    /// Time since the last magnetometer reading (s).
    since_mag_s: f64,
    /// The samples stopped for longer than `max_uncorrected_s`: the gyros saw nothing of what
    /// happened meanwhile, so the next measurement is taken as it is (the bias is kept).
    realign: bool,
    /// The tilt/heading filter, when `ATT_MODE` is 1 (then the observer is not used).
    filter: Option<TiltHeadingFilter>,
    status: AttitudeStatus,
}

impl AttitudeEstimator {
    /// An estimator that has not aligned yet.
    pub fn new(params: &AttitudeParams) -> Self {
        let mag_cal = params.mag_calibration();
        Self {
            mag_ref_ned: params.earth_field_ned(),
            params: params.clone(),
            mag_cal,
            mag_motor_field: Vector3::from(params.mag_comp),
            observer: None,
            align_sum: (Vector3::zeros(), Vector3::zeros(), Vector3::zeros(), 0, 0),
            last_mag: None,
            since_mag_s: 0.0,
            realign: false,
            filter: (params.mode == 1)
                .then(|| TiltHeadingFilter::new(params.tilt_heading_settings())),
            status: AttitudeStatus::default(),
        }
    }

    /// Changes the parameters in flight: gains, weights, gates and the magnetic model take
    /// effect at the next sample; the estimate and its bias are kept.
    pub fn set_params(&mut self, params: &AttitudeParams) {
        if params.mode != self.params.mode {
            // Another estimator: it starts afresh (and aligns again).
            *self = Self::new(params);
            return;
        }
        if let Some(f) = self.filter.as_mut() {
            f.set_settings(params.tilt_heading_settings());
        }
        self.mag_cal = params.mag_calibration();
        self.mag_motor_field = Vector3::from(params.mag_comp);
        self.mag_ref_ned = params.earth_field_ned();
        if let Some(o) = self.observer.as_mut() {
            o.gain = params.observer_gain;
            o.bias_gain = params.bias_gain;
            o.bias_limit = params.bias_limit_rad_s;
        }
        self.params = params.clone();
    }

    /// Starts the observer at a given attitude (skipping alignment), e.g. to test recovery.
    pub fn start_at(&mut self, q: UnitQuaternion<f64>) {
        if let Some(f) = self.filter.as_mut() {
            f.start_at(q);
            self.status.aligned = true;
            return;
        }
        let p = &self.params;
        self.observer = Some(AttitudeObserver::new(
            q,
            p.observer_gain,
            p.bias_gain,
            p.bias_limit_rad_s,
        ));
        self.status.aligned = true;
    }

    /// Sets the gyro-bias estimate (an alignment done elsewhere, e.g. a replay's pre-roll).
    pub fn set_gyro_bias(&mut self, bias: Vector3<f64>) {
        if let Some(f) = self.filter.as_mut() {
            f.set_bias(bias);
        }
        if let Some(o) = self.observer.as_mut() {
            o.bias = bias;
        }
    }

    /// Forgets the accelerometer bias learned in flight (a new calibration).
    pub fn forget_accel_bias(&mut self) {
        if let Some(f) = self.filter.as_mut() {
            f.forget_accel_bias();
        }
    }

    /// Forgets everything: the next samples align again.
    pub fn reset(&mut self) {
        *self = Self::new(&self.params);
    }

    /// Counters and health.
    pub fn status(&self) -> AttitudeStatus {
        self.status
    }

    /// The current estimate, if aligned.
    pub fn estimate(&self, gyro: &Vector3<f64>) -> Option<AttitudeEstimate> {
        if let Some(f) = &self.filter {
            return self.status.aligned.then(|| {
                let q = f.attitude();
                AttitudeEstimate {
                    q,
                    euler_rad: q.euler_angles(),
                    rate: gyro - f.bias(),
                    gyro_bias: f.bias(),
                    accel_bias: f.accel_bias().0,
                    valid: self.status.since_correction_s <= self.params.max_uncorrected_s
                        && !f.realigning(),
                    realigning: f.realigning(),
                    bias_settled: f.bias_settled(),
                    imu_still: f.imu_still(),
                    // As this sample's update left them (`status.tilt_heading`, not worked out again).
                    reset: self.status.tilt_heading.reset,
                }
            });
        }
        let o = self.observer.as_ref()?;
        let q = crate::math::quat::shortest(&o.q);
        Some(AttitudeEstimate {
            q,
            euler_rad: q.euler_angles(),
            rate: o.rate(gyro),
            gyro_bias: o.bias,
            accel_bias: Vector3::zeros(),
            valid: self.status.since_correction_s <= self.params.max_uncorrected_s,
            realigning: false,
            bias_settled: true,
            imu_still: false,
            reset: EstimateReset::default(),
        })
    }

    /// The q-method attitude from one accelerometer and magnetometer sample, and how far to trust
    /// it (1: |a| matches the expected specific force; falling to 0 at the gate).
    /// The q-method's attitude from the specific force and the calibrated magnetic field (both
    /// body frame), and the trust in it.
    fn measure(
        &mut self,
        accel: &Vector3<f64>,
        mag_body: &Vector3<f64>,
        accel_ned: Option<&Vector3<f64>>,
    ) -> Option<(UnitQuaternion<f64>, f64)> {
        // Specific force in NED: a − g. At rest: (0, 0, −g).
        let reference = accel_ned.copied().unwrap_or_else(Vector3::zeros)
            - Vector3::new(0.0, 0.0, GRAVITY_M_S2);
        let expected = reference.norm();
        let deviation = (accel.norm() - expected).abs() / GRAVITY_M_S2;
        let p = &self.params;
        if deviation > p.accel_gate_g {
            self.status.accel_rejected += 1;
            return None;
        }
        let mut trust = 1.0;
        if deviation > p.accel_deweight_g {
            // Linear fall from full trust at the soft limit to none at the gate. The trust scales
            // the observer's correction, not the Wahba weight: a de-weighted accelerometer would
            // still define the tilt of the q-method solution, only with the magnetometer's noise.
            trust = 1.0 - (deviation - p.accel_deweight_g) / (p.accel_gate_g - p.accel_deweight_g);
            self.status.accel_deweighted += 1;
        }
        let obs = [
            VectorObservation {
                body: *accel,
                reference,
                weight: p.accel_weight,
            },
            VectorObservation {
                body: *mag_body,
                reference: self.mag_ref_ned,
                weight: p.mag_weight,
            },
        ];
        match quest(&obs) {
            Ok(q) => Some((q, trust)),
            Err(e) => {
                match e {
                    ObservationError::NonFinite => self.status.rejected_non_finite += 1,
                    ObservationError::Zero => self.status.rejected_zero += 1,
                    ObservationError::Parallel | ObservationError::TooFew => {
                        self.status.rejected_parallel += 1
                    }
                }
                None
            }
        }
    }

    /// One IMU sample after `dt` seconds. Returns the estimate once aligned.
    ///
    /// A `dt` beyond `max_uncorrected_s` is a gap in the samples (a link that went silent): the
    /// estimate is invalid until the next measurement, which is taken as it is.
    pub fn update(&mut self, input: &AttitudeInput, dt: f64) -> Option<AttitudeEstimate> {
        self.status.samples += 1;
        if dt > self.params.max_uncorrected_s && (self.observer.is_some() || self.status.aligned) {
            self.realign = true;
            self.status.since_correction_s += dt;
        }
        let dt = if !(DT_RANGE_S.0..=DT_RANGE_S.1).contains(&dt) {
            self.status.dt_clamped += 1;
            if dt.is_finite() {
                dt.clamp(DT_RANGE_S.0, DT_RANGE_S.1)
            } else {
                DT_RANGE_S.0
            }
        } else {
            dt
        };
        if !(input
            .gyro
            .iter()
            .chain(input.accel.iter())
            .all(|x| x.is_finite()))
        {
            self.status.rejected_non_finite += 1;
            return self.estimate(&Vector3::zeros());
        }
        if let Some(m) = input.mag {
            if m.iter().all(|x| x.is_finite()) {
                self.last_mag = Some(m);
            } else {
                self.status.rejected_non_finite += 1;
            }
        }
        if self.filter.is_some() {
            return self.update_filter(input, dt);
        }
        if self.observer.is_none() {
            self.align(input);
            return self.estimate(&input.gyro);
        }
        if input.mag.is_some() {
            self.since_mag_s = 0.0;
        } else {
            self.since_mag_s += dt;
        }
        let hint = input.accel_ned_hint.as_ref();
        let measured = match (self.last_mag, input.mag.is_some()) {
            // Correct at the magnetometer's rate, with the freshest accelerometer sample.
            (Some(m), true) => {
                let body = self.mag_body(&m, input);
                self.measure(&input.accel, &body, hint)
            }
            // The magnetometer is gone: the field where the estimate says it is, so the q-method
            // corrects the tilt and leaves the heading to the gyro.
            _ if self.since_mag_s > MAG_SILENT_S => {
                let predicted = self
                    .observer
                    .as_ref()
                    .map(|o| o.q.inverse() * self.mag_ref_ned);
                let m = predicted.and_then(|body| self.measure(&input.accel, &body, hint));
                self.status.heading_held += m.is_some() as u64;
                m
            }
            _ => None,
        };
        let observer = self.observer.as_mut()?;
        if let (true, Some((q, _))) = (self.realign, measured) {
            observer.q = q;
            self.realign = false;
            self.status.realigned += 1;
        }
        let (q_meas, trust) = match measured {
            Some((q, t)) => (Some(q), t),
            None => (None, 0.0),
        };
        let innovation = observer.update(q_meas.as_ref(), trust, &input.gyro, dt);
        if measured.is_some() {
            self.status.innovation_rad = innovation;
            self.status.since_correction_s = 0.0;
        } else {
            self.status.since_correction_s += dt;
        }
        self.estimate(&input.gyro)
    }

    /// The calibrated field less the motor currents' (PX4's `CAL_MAG_COMP_TYP` by throttle).
    fn mag_body(&self, raw: &Vector3<f64>, input: &AttitudeInput) -> Vector3<f64> {
        self.mag_cal.apply(raw) - self.mag_motor_field * input.thrust_fraction.clamp(0.0, 1.0)
    }

    /// [`Self::update`] with the tilt/heading filter: it starts from the first samples, at rest
    /// or not, and is flown once `align_samples` samples and a magnetic heading have been taken.
    fn update_filter(&mut self, input: &AttitudeInput, dt: f64) -> Option<AttitudeEstimate> {
        let mag = input
            .mag
            .filter(|m| m.iter().all(|x| x.is_finite()))
            .map(|m| self.mag_body(&m, input));
        if mag.is_some() {
            self.since_mag_s = 0.0;
        } else {
            self.since_mag_s += dt;
        }
        let filter = self.filter.as_mut()?;
        if self.realign {
            // After a gap the bias is kept. In flight the attitude is unknown until found again
            // (`realign.rs`); on the ground the low-passed accelerometer and the heading start
            // again from the next samples (a steady accelerometer is the tilt at once).
            if input.armed {
                filter.lost_in_flight();
            } else {
                filter.start_at(filter.attitude());
            }
            self.realign = false;
            self.status.realigned += 1;
        }
        let hint = input
            .vel_ned_hint
            .filter(|v| v.iter().all(|x| x.is_finite()));
        let gps_vel = input
            .gps_vel
            .filter(|g| g.vel_ned_m_s.iter().all(|x| x.is_finite()) && g.age_s.is_finite());
        filter.update(
            &FilterInput {
                gyro: input.gyro,
                accel: input.accel,
                mag,
                vel_ned: hint,
                gps_vel,
                armed: input.armed,
            },
            dt,
        );
        // The accelerometer corrects the tilt on every sample.
        self.status.since_correction_s = 0.0;
        if self.since_mag_s > MAG_SILENT_S {
            self.status.heading_held += 1;
        }
        let fs = filter.status();
        self.status.innovation_rad = fs.tilt_correction_rad;
        self.status.tilt_heading = fs;
        // Aligned once the heading is known, or at once without a magnetometer at all (the
        // heading then starts where the gyro does: VQF's 6-axis estimate).
        if !self.status.aligned
            && self.status.samples >= u64::from(self.params.align_samples)
            && (filter.heading_known() || self.since_mag_s > MAG_ABSENT_S)
        {
            self.status.aligned = true;
        }
        self.estimate(&input.gyro)
    }

    /// Initial alignment at rest: average the vectors over the alignment window, then solve the
    /// q-method once and take the mean gyro rate as the initial bias.
    fn align(&mut self, input: &AttitudeInput) {
        let (acc, gyr, mag, n, nm) = &mut self.align_sum;
        *acc += input.accel;
        *gyr += input.gyro;
        *n += 1;
        if let Some(m) = input.mag.filter(|m| m.iter().all(|x| x.is_finite())) {
            *mag += m;
            *nm += 1;
        }
        if *n < self.params.align_samples || *nm == 0 {
            return;
        }
        let (acc, gyr, mag) = (*acc / *n as f64, *gyr / *n as f64, *mag / *nm as f64);
        let q = self.measure(&acc, &mag, None);
        match q {
            Some((q, _)) => {
                self.start_at(q);
                if let Some(o) = self.observer.as_mut() {
                    // At rest the mean rate is the bias, if it is plausibly one.
                    if gyr.norm() < self.params.bias_limit_rad_s {
                        o.bias = gyr;
                    }
                }
            }
            None => self.align_sum = (Vector3::zeros(), Vector3::zeros(), Vector3::zeros(), 0, 0),
        }
    }
}

#[cfg(test)]
mod flight_bias_tests;
#[cfg(test)]
mod in_flight_tests;
#[cfg(test)]
mod recovery_tests;
#[cfg(test)]
mod tests;
