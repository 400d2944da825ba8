//! The attitude estimator's parameters: their values, metadata (MAVLink names, units, ranges)
//! and checks.

use super::MagCalibration;
use crate::estimator::heading::HeadingSettings;
use crate::estimator::tilt_heading::TiltHeadingSettings;
use crate::params::{ParamKind, ParamMeta, ParamViolation, check};
use nalgebra::{Matrix3, Vector3};
use serde::Deserialize;

/// Attitude estimator parameters (Castillo (80)–(105) and the safeguards around them).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct AttitudeParams {
    /// Which estimator flies: 0 Castillo's q-method observer, 1 the tilt/heading filter.
    pub mode: u32,
    /// Tilt/heading filter: time constant of the accelerometer's low-pass in the gyro frame (s).
    pub tau_acc_s: f64,
    /// Tilt/heading filter: time constant of the magnetic heading correction (s).
    pub tau_mag_s: f64,
    /// Tilt/heading filter: time constant of gyro-bias learning in motion (s); 0 off.
    pub bias_tau_s: f64,
    /// Tilt/heading filter: longest time a disturbed magnetic field is ignored (s).
    pub mag_reject_s: f64,
    /// Tilt/heading filter: learn a body-fixed field (hard iron) in flight (1) or not (0).
    pub mag_learn: u32,
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
    /// Field of the motor currents at full thrust (gauss, body frame), taken off in proportion
    /// to the thrust: `CAL_MAG0_XCOMP`…`ZCOMP`.
    pub mag_comp: [f64; 3],
    /// Diagonal of the soft-iron correction `R E Rᵀ` of Castillo (75): `CAL_MAG0_XSCALE`….
    pub mag_scale: [f64; 3],
    /// Off-diagonal of the same symmetric matrix, (xy, xz, yz): `CAL_MAG0_XODIAG`…`ZODIAG`,
    /// as PX4 and `MAG_CAL_REPORT` keep it.
    pub mag_offdiag: [f64; 3],
}

impl Default for AttitudeParams {
    fn default() -> Self {
        Self {
            // The tilt/heading filter wins the BROAD benchmark (docs/estimator.md) but is not yet
            // the default: in simulated flight Castillo's observer is still the better one.
            mode: 1,
            tau_acc_s: 3.0,
            tau_mag_s: 15.0,
            bias_tau_s: 10.0,
            mag_reject_s: 60.0,
            mag_learn: 0,
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
            mag_comp: [0.0; 3],
            mag_scale: [1.0; 3],
            mag_offdiag: [0.0; 3],
        }
    }
}

/// Metadata of the attitude parameters.
pub const ATTITUDE_META: &[ParamMeta] = &[
    ParamMeta {
        name: "ATT_MODE",
        key: "mode",
        kind: ParamKind::Int32,
        unit: "",
        default: 1.0,
        min: 0.0,
        max: 1.0,
        description: "Attitude estimator: 0 Castillo's q-method observer, 1 the tilt/heading filter (accelerometer for tilt only, magnetometer for heading only, bias learned in motion)",
    },
    ParamMeta {
        name: "ATT_TAU_ACC",
        key: "tau_acc_s",
        kind: ParamKind::Real32,
        unit: "s",
        default: 3.0,
        min: 0.1,
        max: 30.0,
        description: "Tilt/heading filter: time constant of the accelerometer's low-pass in the gyro frame (longer ignores longer accelerations)",
    },
    ParamMeta {
        name: "ATT_TAU_MAG",
        key: "tau_mag_s",
        kind: ParamKind::Real32,
        unit: "s",
        default: 15.0,
        min: 0.5,
        max: 100.0,
        description: "Tilt/heading filter: time constant of the magnetic heading correction",
    },
    ParamMeta {
        name: "ATT_BIAS_TAU",
        key: "bias_tau_s",
        kind: ParamKind::Real32,
        unit: "s",
        default: 10.0,
        min: 0.0,
        max: 1000.0,
        description: "Tilt/heading filter: time constant of the gyro-bias Kalman filter in motion (0: learn only at rest)",
    },
    ParamMeta {
        name: "ATT_MAG_REJ_T",
        key: "mag_reject_s",
        kind: ParamKind::Real32,
        unit: "s",
        default: 60.0,
        min: 0.0,
        max: 600.0,
        description: "Tilt/heading filter: longest time a disturbed magnetic field is ignored (heading on the gyro meanwhile)",
    },
    ParamMeta {
        name: "ATT_MAG_LEARN",
        key: "mag_learn",
        kind: ParamKind::Int32,
        unit: "",
        default: 0.0,
        min: 0.0,
        max: 1.0,
        description: "Tilt/heading filter: learn a body-fixed magnetic field (hard iron) in flight from the gyro",
    },
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
    ParamMeta {
        name: "CAL_MAG0_XCOMP",
        key: "mag_comp[0]",
        kind: ParamKind::Real32,
        unit: "gauss",
        default: 0.0,
        min: -1.0,
        max: 1.0,
        description: "Motor-current field at full thrust, x, taken off in proportion to the mean thrust fraction (ω/ω_max)² (PX4's throttle compensation)",
    },
    ParamMeta {
        name: "CAL_MAG0_YCOMP",
        key: "mag_comp[1]",
        kind: ParamKind::Real32,
        unit: "gauss",
        default: 0.0,
        min: -1.0,
        max: 1.0,
        description: "Motor-current field at full thrust, y",
    },
    ParamMeta {
        name: "CAL_MAG0_ZCOMP",
        key: "mag_comp[2]",
        kind: ParamKind::Real32,
        unit: "gauss",
        default: 0.0,
        min: -1.0,
        max: 1.0,
        description: "Motor-current field at full thrust, z",
    },
];

impl AttitudeParams {
    /// The value of the field `key` named in [`ATTITUDE_META`].
    pub fn get(&self, key: &str) -> Option<f64> {
        Some(match key {
            "mode" => self.mode as f64,
            "tau_acc_s" => self.tau_acc_s,
            "tau_mag_s" => self.tau_mag_s,
            "bias_tau_s" => self.bias_tau_s,
            "mag_reject_s" => self.mag_reject_s,
            "mag_learn" => self.mag_learn as f64,
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
            "mode" => {
                self.mode = value as u32;
                return true;
            }
            "mag_learn" => {
                self.mag_learn = value as u32;
                return true;
            }
            "tau_acc_s" => &mut self.tau_acc_s,
            "tau_mag_s" => &mut self.tau_mag_s,
            "bias_tau_s" => &mut self.bias_tau_s,
            "mag_reject_s" => &mut self.mag_reject_s,
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
            "mag_comp" => &self.mag_comp,
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
            "mag_comp" => &mut self.mag_comp,
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
        for key in [
            "mode",
            "tau_acc_s",
            "tau_mag_s",
            "bias_tau_s",
            "mag_reject_s",
            "mag_learn",
        ] {
            check(
                &mut v,
                "attitude",
                m,
                key,
                self.get(key).unwrap_or(f64::NAN),
            );
        }
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

    /// The tilt/heading filter's settings.
    pub fn tilt_heading_settings(&self) -> TiltHeadingSettings {
        let d = TiltHeadingSettings::default();
        TiltHeadingSettings {
            tau_acc_s: self.tau_acc_s,
            heading: HeadingSettings {
                tau_s: self.tau_mag_s,
                declination_rad: self.mag_declination_deg.to_radians(),
                max_rejection_s: self.mag_reject_s,
                ..d.heading
            },
            bias_tau_motion_s: self.bias_tau_s,
            bias_limit_rad_s: self.bias_limit_rad_s,
            learn_hard_iron: self.mag_learn != 0,
            ..d
        }
    }

    /// Unit Earth-field direction in NED from inclination and declination.
    pub fn earth_field_ned(&self) -> Vector3<f64> {
        let (si, ci) = self.mag_inclination_deg.to_radians().sin_cos();
        let (sd, cd) = self.mag_declination_deg.to_radians().sin_cos();
        Vector3::new(ci * cd, ci * sd, si)
    }
}
