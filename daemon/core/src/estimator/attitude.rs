//! The attitude estimator: q-method measurement (Castillo (80)–(90)) from the accelerometer and
//! the calibrated magnetometer, filtered by the nonlinear observer (97)–(105) with the gyros.
//!
//! Beyond the paper, as a flying autopilot must: an initial alignment at rest (averaged vectors,
//! gyro bias from the mean rate), an accelerometer weight that falls as |a| departs from the
//! expected specific force (and gating beyond a limit), an optional known NED acceleration that
//! turns the gravity reference into the true specific-force reference in accelerated flight, typed
//! rejection of degenerate vectors, and counters for all of it.

use super::observer::AttitudeObserver;
use super::wahba::{ObservationError, VectorObservation, quest};
use crate::GRAVITY_M_S2;
use crate::params::{ParamKind, ParamMeta, ParamViolation, check};
use nalgebra::{Matrix3, UnitQuaternion, Vector3};
use serde::Deserialize;

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
    /// The vehicle's acceleration in NED (m/s²), when the position estimator knows it.
    pub accel_ned_hint: Option<Vector3<f64>>,
}

/// The estimator's output.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AttitudeEstimate {
    /// Attitude `q_ned_from_frd`, `w ≥ 0`.
    pub q: UnitQuaternion<f64>,
    /// Body rate corrected by the bias estimate (rad/s).
    pub rate: Vector3<f64>,
    /// Gyro bias estimate (rad/s).
    pub gyro_bias: Vector3<f64>,
    /// Whether the estimate can be flown on: aligned, and corrected recently enough.
    pub valid: bool,
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
}

/// A magnetometer silent this long (s) no longer corrects: the accelerometer corrects the tilt
/// alone, against the magnetic field the estimate itself predicts, so the heading is the gyro's.
pub const MAG_SILENT_S: f64 = 0.2;

/// Smallest and largest time step accepted (s); outside, the step is clamped and counted.
pub const DT_RANGE_S: (f64, f64) = (1.25e-4, 0.02);

/// The attitude estimator.
#[derive(Debug, Clone)]
pub struct AttitudeEstimator {
    params: AttitudeParams,
    mag_cal: MagCalibration,
    mag_ref_ned: Vector3<f64>,
    observer: Option<AttitudeObserver>,
    align_sum: (Vector3<f64>, Vector3<f64>, Vector3<f64>, u32, u32),
    last_mag: Option<Vector3<f64>>,
    /// Time since the last magnetometer reading (s).
    since_mag_s: f64,
    /// The samples stopped for longer than `max_uncorrected_s`: the gyros saw nothing of what
    /// happened meanwhile, so the next measurement is taken as it is (the bias is kept).
    realign: bool,
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
            observer: None,
            align_sum: (Vector3::zeros(), Vector3::zeros(), Vector3::zeros(), 0, 0),
            last_mag: None,
            since_mag_s: 0.0,
            realign: false,
            status: AttitudeStatus::default(),
        }
    }

    /// Changes the parameters in flight: gains, weights, gates and the magnetic model take
    /// effect at the next sample; the estimate and its bias are kept.
    pub fn set_params(&mut self, params: &AttitudeParams) {
        self.mag_cal = params.mag_calibration();
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
        if let Some(o) = self.observer.as_mut() {
            o.bias = bias;
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
        let o = self.observer.as_ref()?;
        Some(AttitudeEstimate {
            q: crate::quat::shortest(&o.q),
            rate: o.rate(gyro),
            gyro_bias: o.bias,
            valid: self.status.since_correction_s <= self.params.max_uncorrected_s,
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
        if dt > self.params.max_uncorrected_s && self.observer.is_some() {
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
                let body = self.mag_cal.apply(&m);
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

/// Attitude estimator parameters (Castillo (80)–(105) and the safeguards around them).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct AttitudeParams {
    /// Observer gain k of (105).
    pub observer_gain: f64,
    /// Bias gain of (102).
    pub bias_gain: f64,
    /// Bound on the gyro-bias estimate.
    pub bias_limit_rad_s: f64,
    /// Wahba weight of the accelerometer vector.
    pub accel_weight: f64,
    /// Wahba weight of the magnetometer vector.
    pub mag_weight: f64,
    /// |a| deviation (in g) from the expected specific force where the accelerometer weight starts
    /// to fall.
    pub accel_deweight_g: f64,
    /// |a| deviation (in g) beyond which the accelerometer is not used.
    pub accel_gate_g: f64,
    /// IMU samples averaged for the initial alignment at rest.
    pub align_samples: u32,
    /// Longest time without a measurement correction before the estimate is invalid (s).
    pub max_uncorrected_s: f64,
    /// Magnetic inclination at the site (deg, positive down).
    pub mag_inclination_deg: f64,
    /// Magnetic declination at the site (deg, positive east).
    pub mag_declination_deg: f64,
    /// Magnetic field strength at the site (gauss), what a calibrated magnetometer reads.
    pub mag_intensity_gauss: f64,
    /// Set by a magnetometer calibration (PX4 stores the device id); 0: never calibrated.
    pub mag_calibration_id: u32,
    /// Hard-iron offset (gauss), Castillo (75): `CAL_MAG0_XOFF`…`ZOFF`.
    pub mag_offset: [f64; 3],
    /// Diagonal of the soft-iron correction `R E Rᵀ` of Castillo (75): `CAL_MAG0_XSCALE`….
    pub mag_scale: [f64; 3],
    /// Off-diagonal of the same symmetric matrix, (xy, xz, yz): `CAL_MAG0_XODIAG`…`ZODIAG`,
    /// as PX4 and `MAG_CAL_REPORT` keep it.
    pub mag_offdiag: [f64; 3],
}

impl Default for AttitudeParams {
    fn default() -> Self {
        Self {
            // Castillo 5.x flies k = 4 and a bias gain of ½. With a MEMS gyro aligned at rest
            // and the q-method's noise (magnetometer yaw, vibration in the tilt), lower gains
            // filter better: 8 seeded hovers, attitude RMS 1.07° → 0.50° (PX4's attitude_q
            // uses 0.2/0.1 for the same reason).
            observer_gain: 1.0,
            bias_gain: 0.05,
            bias_limit_rad_s: 0.1,
            accel_weight: 1.0,
            mag_weight: 0.1,
            accel_deweight_g: 0.05,
            accel_gate_g: 0.3,
            align_samples: 250,
            max_uncorrected_s: 0.5,
            mag_inclination_deg: 63.3,
            mag_declination_deg: 3.0,
            mag_intensity_gauss: 0.48,
            mag_calibration_id: 0,
            mag_offset: [0.0; 3],
            mag_scale: [1.0; 3],
            mag_offdiag: [0.0; 3],
        }
    }
}

/// Metadata of the attitude parameters.
pub const ATTITUDE_META: &[ParamMeta] = &[
    ParamMeta {
        name: "ATT_OBS_K",
        key: "observer_gain",
        kind: ParamKind::Real32,
        unit: "1/s",
        default: 1.0,
        min: 0.05,
        max: 50.0,
        description: "Observer gain k of Castillo (105): how fast the estimate follows the q-method measurement",
    },
    ParamMeta {
        name: "ATT_BIAS_K",
        key: "bias_gain",
        kind: ParamKind::Real32,
        unit: "1/s",
        default: 0.05,
        min: 0.0,
        max: 5.0,
        description: "Gyro-bias gain of Castillo (102)",
    },
    ParamMeta {
        name: "ATT_BIAS_MAX",
        key: "bias_limit_rad_s",
        kind: ParamKind::Real32,
        unit: "rad/s",
        default: 0.1,
        min: 0.001,
        max: 1.0,
        description: "Bound on the gyro-bias estimate",
    },
    ParamMeta {
        name: "ATT_W_ACC",
        key: "accel_weight",
        kind: ParamKind::Real32,
        unit: "",
        default: 1.0,
        min: 0.001,
        max: 100.0,
        description: "Wahba weight of the accelerometer vector, Castillo (80)",
    },
    ParamMeta {
        name: "ATT_W_MAG",
        key: "mag_weight",
        kind: ParamKind::Real32,
        unit: "",
        default: 0.1,
        min: 0.001,
        max: 100.0,
        description: "Wahba weight of the magnetometer vector, Castillo (80)",
    },
    ParamMeta {
        name: "ATT_ACC_SOFT",
        key: "accel_deweight_g",
        kind: ParamKind::Real32,
        unit: "g",
        default: 0.05,
        min: 0.0,
        max: 2.0,
        description: "Specific-force error where the accelerometer weight starts to fall",
    },
    ParamMeta {
        name: "ATT_ACC_GATE",
        key: "accel_gate_g",
        kind: ParamKind::Real32,
        unit: "g",
        default: 0.3,
        min: 0.01,
        max: 3.0,
        description: "Specific-force error beyond which the accelerometer is not used",
    },
    ParamMeta {
        name: "ATT_ALIGN_N",
        key: "align_samples",
        kind: ParamKind::Int32,
        unit: "samples",
        default: 250.0,
        min: 1.0,
        max: 10000.0,
        description: "IMU samples averaged for the initial alignment at rest",
    },
    ParamMeta {
        name: "ATT_MAX_DR_T",
        key: "max_uncorrected_s",
        kind: ParamKind::Real32,
        unit: "s",
        default: 0.5,
        min: 0.01,
        max: 60.0,
        description: "Longest gyro-only propagation before the attitude is flagged invalid",
    },
    ParamMeta {
        name: "ATT_MAG_INC",
        key: "mag_inclination_deg",
        kind: ParamKind::Real32,
        unit: "deg",
        default: 63.3,
        min: -90.0,
        max: 90.0,
        description: "Magnetic inclination at the flying site",
    },
    ParamMeta {
        name: "ATT_MAG_DEC",
        key: "mag_declination_deg",
        kind: ParamKind::Real32,
        unit: "deg",
        default: 3.0,
        min: -180.0,
        max: 180.0,
        description: "Magnetic declination at the flying site",
    },
    ParamMeta {
        name: "ATT_MAG_STR",
        key: "mag_intensity_gauss",
        kind: ParamKind::Real32,
        unit: "gauss",
        default: 0.48,
        min: 0.2,
        max: 0.7,
        description: "Magnetic field strength at the flying site (the pre-arm consistency check)",
    },
    ParamMeta {
        name: "CAL_MAG0_ID",
        key: "mag_calibration_id",
        kind: ParamKind::Int32,
        unit: "",
        default: 0.0,
        min: 0.0,
        max: 2147483647.0,
        description: "Set by a magnetometer calibration (a simulator presets its own); 0: never calibrated, arming refused",
    },
    ParamMeta {
        name: "CAL_MAG0_XOFF",
        key: "mag_offset[0]",
        kind: ParamKind::Real32,
        unit: "gauss",
        default: 0.0,
        min: -2.0,
        max: 2.0,
        description: "Magnetometer hard-iron offset, x (Castillo (75); set by a calibration)",
    },
    ParamMeta {
        name: "CAL_MAG0_YOFF",
        key: "mag_offset[1]",
        kind: ParamKind::Real32,
        unit: "gauss",
        default: 0.0,
        min: -2.0,
        max: 2.0,
        description: "Magnetometer hard-iron offset, y",
    },
    ParamMeta {
        name: "CAL_MAG0_ZOFF",
        key: "mag_offset[2]",
        kind: ParamKind::Real32,
        unit: "gauss",
        default: 0.0,
        min: -2.0,
        max: 2.0,
        description: "Magnetometer hard-iron offset, z",
    },
    ParamMeta {
        name: "CAL_MAG0_XSCALE",
        key: "mag_scale[0]",
        kind: ParamKind::Real32,
        unit: "",
        default: 1.0,
        min: 0.2,
        max: 5.0,
        description: "Soft-iron correction R E Rᵀ (Castillo (75)), xx (set by a calibration)",
    },
    ParamMeta {
        name: "CAL_MAG0_YSCALE",
        key: "mag_scale[1]",
        kind: ParamKind::Real32,
        unit: "",
        default: 1.0,
        min: 0.2,
        max: 5.0,
        description: "Soft-iron correction, yy",
    },
    ParamMeta {
        name: "CAL_MAG0_ZSCALE",
        key: "mag_scale[2]",
        kind: ParamKind::Real32,
        unit: "",
        default: 1.0,
        min: 0.2,
        max: 5.0,
        description: "Soft-iron correction, zz",
    },
    ParamMeta {
        name: "CAL_MAG0_XODIAG",
        key: "mag_offdiag[0]",
        kind: ParamKind::Real32,
        unit: "",
        default: 0.0,
        min: -1.0,
        max: 1.0,
        description: "Soft-iron correction, xy (the matrix must stay positive definite)",
    },
    ParamMeta {
        name: "CAL_MAG0_YODIAG",
        key: "mag_offdiag[1]",
        kind: ParamKind::Real32,
        unit: "",
        default: 0.0,
        min: -1.0,
        max: 1.0,
        description: "Soft-iron correction, xz",
    },
    ParamMeta {
        name: "CAL_MAG0_ZODIAG",
        key: "mag_offdiag[2]",
        kind: ParamKind::Real32,
        unit: "",
        default: 0.0,
        min: -1.0,
        max: 1.0,
        description: "Soft-iron correction, yz",
    },
];

impl AttitudeParams {
    /// The value of the field `key` named in [`ATTITUDE_META`].
    pub fn get(&self, key: &str) -> Option<f64> {
        Some(match key {
            "observer_gain" => self.observer_gain,
            "bias_gain" => self.bias_gain,
            "bias_limit_rad_s" => self.bias_limit_rad_s,
            "accel_weight" => self.accel_weight,
            "mag_weight" => self.mag_weight,
            "accel_deweight_g" => self.accel_deweight_g,
            "accel_gate_g" => self.accel_gate_g,
            "align_samples" => self.align_samples as f64,
            "max_uncorrected_s" => self.max_uncorrected_s,
            "mag_inclination_deg" => self.mag_inclination_deg,
            "mag_declination_deg" => self.mag_declination_deg,
            "mag_intensity_gauss" => self.mag_intensity_gauss,
            "mag_calibration_id" => self.mag_calibration_id as f64,
            k => return self.mag_element(k).map(|(a, i)| a[i]),
        })
    }

    /// Sets the field `key` named in [`ATTITUDE_META`] (unchecked: see `validate`); false if
    /// there is none.
    pub fn set(&mut self, key: &str, value: f64) -> bool {
        let field = match key {
            "observer_gain" => &mut self.observer_gain,
            "bias_gain" => &mut self.bias_gain,
            "bias_limit_rad_s" => &mut self.bias_limit_rad_s,
            "accel_weight" => &mut self.accel_weight,
            "mag_weight" => &mut self.mag_weight,
            "accel_deweight_g" => &mut self.accel_deweight_g,
            "accel_gate_g" => &mut self.accel_gate_g,
            "align_samples" => {
                self.align_samples = value as u32;
                return true;
            }
            "max_uncorrected_s" => &mut self.max_uncorrected_s,
            "mag_inclination_deg" => &mut self.mag_inclination_deg,
            "mag_declination_deg" => &mut self.mag_declination_deg,
            "mag_intensity_gauss" => &mut self.mag_intensity_gauss,
            "mag_calibration_id" => {
                self.mag_calibration_id = value as u32;
                return true;
            }
            k => match self.mag_element_mut(k) {
                Some(x) => x,
                None => return false,
            },
        };
        *field = value;
        true
    }

    /// The calibration array and index a key such as `mag_offset[1]` names.
    fn mag_element(&self, key: &str) -> Option<(&[f64; 3], usize)> {
        let (name, i) = key.strip_suffix(']')?.split_once('[')?;
        let i: usize = i.parse().ok().filter(|&i| i < 3)?;
        let array = match name {
            "mag_offset" => &self.mag_offset,
            "mag_scale" => &self.mag_scale,
            "mag_offdiag" => &self.mag_offdiag,
            _ => return None,
        };
        Some((array, i))
    }

    fn mag_element_mut(&mut self, key: &str) -> Option<&mut f64> {
        let (_, i) = self.mag_element(key)?;
        let name = key.split_once('[')?.0;
        let array = match name {
            "mag_offset" => &mut self.mag_offset,
            "mag_scale" => &mut self.mag_scale,
            _ => &mut self.mag_offdiag,
        };
        Some(&mut array[i])
    }

    /// The soft-iron correction `R E Rᵀ` (symmetric) from its diagonal and off-diagonal.
    pub fn mag_correction(&self) -> Matrix3<f64> {
        let (d, o) = (self.mag_scale, self.mag_offdiag);
        Matrix3::new(d[0], o[0], o[1], o[0], d[1], o[2], o[1], o[2], d[2])
    }

    /// Sets the soft-iron correction from a symmetric matrix (its upper triangle is read).
    pub fn set_mag_correction(&mut self, s: &Matrix3<f64>) {
        self.mag_scale = [s[(0, 0)], s[(1, 1)], s[(2, 2)]];
        self.mag_offdiag = [s[(0, 1)], s[(0, 2)], s[(1, 2)]];
    }

    /// Every out-of-range value.
    pub fn validate(&self) -> Vec<ParamViolation> {
        let mut v = Vec::new();
        let m = ATTITUDE_META;
        check(&mut v, "attitude", m, "observer_gain", self.observer_gain);
        check(&mut v, "attitude", m, "bias_gain", self.bias_gain);
        check(
            &mut v,
            "attitude",
            m,
            "bias_limit_rad_s",
            self.bias_limit_rad_s,
        );
        check(&mut v, "attitude", m, "accel_weight", self.accel_weight);
        check(&mut v, "attitude", m, "mag_weight", self.mag_weight);
        check(
            &mut v,
            "attitude",
            m,
            "accel_deweight_g",
            self.accel_deweight_g,
        );
        check(&mut v, "attitude", m, "accel_gate_g", self.accel_gate_g);
        check(
            &mut v,
            "attitude",
            m,
            "align_samples",
            self.align_samples as f64,
        );
        check(
            &mut v,
            "attitude",
            m,
            "max_uncorrected_s",
            self.max_uncorrected_s,
        );
        check(
            &mut v,
            "attitude",
            m,
            "mag_inclination_deg",
            self.mag_inclination_deg,
        );
        check(
            &mut v,
            "attitude",
            m,
            "mag_declination_deg",
            self.mag_declination_deg,
        );
        check(
            &mut v,
            "attitude",
            m,
            "mag_intensity_gauss",
            self.mag_intensity_gauss,
        );
        check(
            &mut v,
            "attitude",
            m,
            "mag_calibration_id",
            self.mag_calibration_id as f64,
        );
        if self.accel_deweight_g >= self.accel_gate_g {
            v.push(ParamViolation {
                key: "attitude.accel_deweight_g".into(),
                reason: format!("must be below accel_gate_g ({})", self.accel_gate_g),
            });
        }
        for m in ATTITUDE_META.iter().filter(|m| m.key.ends_with(']')) {
            let value = self.get(m.key).unwrap_or(f64::NAN);
            check(&mut v, "attitude", ATTITUDE_META, m.key, value);
        }
        // A correction that is not positive definite folds the field over (or flattens it).
        if v.is_empty() && self.mag_correction().cholesky().is_none() {
            v.push(ParamViolation {
                key: "attitude.mag_offdiag".into(),
                reason: "the soft-iron correction (mag_scale on its diagonal, mag_offdiag off \
                         it) must be positive definite"
                    .into(),
            });
        }
        v
    }

    /// The magnetometer calibration these parameters describe.
    pub fn mag_calibration(&self) -> MagCalibration {
        MagCalibration {
            offset: Vector3::from(self.mag_offset),
            correction: self.mag_correction(),
        }
    }

    /// Unit Earth-field direction in NED from inclination and declination.
    pub fn earth_field_ned(&self) -> Vector3<f64> {
        let (si, ci) = self.mag_inclination_deg.to_radians().sin_cos();
        let (sd, cd) = self.mag_declination_deg.to_radians().sin_cos();
        Vector3::new(ci * cd, ci * sd, si)
    }
}

#[cfg(test)]
mod tests;
