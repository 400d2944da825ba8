//! Parameters of the flight core, declared next to the algorithms that use them.
//!
//! Each group is a serde struct with defaults (`deny_unknown_fields`), loaded from TOML under
//! `params/`, with `validate()` returning every violation. Each parameter also has a metadata row
//! (MAVLink name of at most 16 characters, unit, range, description) for the ground-station
//! parameter protocol and the generated reference.

use nalgebra::{Matrix3, Rotation3, Vector3};
use serde::Deserialize;

/// One parameter's metadata.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParamMeta {
    /// MAVLink name, at most 16 characters, stable, never reused.
    pub name: &'static str,
    /// Key in the TOML group.
    pub key: &'static str,
    /// Unit.
    pub unit: &'static str,
    /// Default value.
    pub default: f64,
    /// Smallest accepted value.
    pub min: f64,
    /// Largest accepted value.
    pub max: f64,
    /// What it does.
    pub description: &'static str,
}

/// A rejected parameter value.
#[derive(Debug, Clone, PartialEq)]
pub struct ParamViolation {
    /// Key in the TOML group, e.g. `attitude.observer_gain`.
    pub key: String,
    /// Why, with the allowed range.
    pub reason: String,
}

fn check(out: &mut Vec<ParamViolation>, group: &str, meta: &[ParamMeta], key: &str, value: f64) {
    if let Some(m) = meta.iter().find(|m| m.key == key)
        && !(value.is_finite() && value >= m.min && value <= m.max)
    {
        out.push(ParamViolation {
            key: format!("{group}.{key}"),
            reason: format!(
                "must be within [{}, {}] {}, got {value}",
                m.min, m.max, m.unit
            ),
        });
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
    /// Hard-iron offset, Castillo (75).
    pub mag_offset: [f64; 3],
    /// Ellipsoid scale E = diag(mag_scale), Castillo (75).
    pub mag_scale: [f64; 3],
    /// Ellipsoid rotation R of Castillo (75) as a rotation vector (rad).
    pub mag_rotation_rad: [f64; 3],
}

impl Default for AttitudeParams {
    fn default() -> Self {
        Self {
            observer_gain: 4.0, // Castillo 5.x: k = 4
            bias_gain: 0.5,
            bias_limit_rad_s: 0.1,
            accel_weight: 1.0,
            mag_weight: 0.1,
            accel_deweight_g: 0.05,
            accel_gate_g: 0.3,
            align_samples: 250,
            max_uncorrected_s: 0.5,
            mag_inclination_deg: 63.3,
            mag_declination_deg: 3.0,
            mag_offset: [0.0; 3],
            mag_scale: [1.0; 3],
            mag_rotation_rad: [0.0; 3],
        }
    }
}

/// Metadata of the attitude parameters.
pub const ATTITUDE_META: &[ParamMeta] = &[
    ParamMeta {
        name: "ATT_OBS_K",
        key: "observer_gain",
        unit: "1/s",
        default: 4.0,
        min: 0.05,
        max: 50.0,
        description: "Observer gain k of Castillo (105): how fast the estimate follows the q-method measurement",
    },
    ParamMeta {
        name: "ATT_BIAS_K",
        key: "bias_gain",
        unit: "1/s",
        default: 0.5,
        min: 0.0,
        max: 5.0,
        description: "Gyro-bias gain of Castillo (102)",
    },
    ParamMeta {
        name: "ATT_BIAS_MAX",
        key: "bias_limit_rad_s",
        unit: "rad/s",
        default: 0.1,
        min: 0.001,
        max: 1.0,
        description: "Bound on the gyro-bias estimate",
    },
    ParamMeta {
        name: "ATT_W_ACC",
        key: "accel_weight",
        unit: "",
        default: 1.0,
        min: 0.001,
        max: 100.0,
        description: "Wahba weight of the accelerometer vector, Castillo (80)",
    },
    ParamMeta {
        name: "ATT_W_MAG",
        key: "mag_weight",
        unit: "",
        default: 0.1,
        min: 0.001,
        max: 100.0,
        description: "Wahba weight of the magnetometer vector, Castillo (80)",
    },
    ParamMeta {
        name: "ATT_ACC_SOFT",
        key: "accel_deweight_g",
        unit: "g",
        default: 0.05,
        min: 0.0,
        max: 2.0,
        description: "Specific-force error where the accelerometer weight starts to fall",
    },
    ParamMeta {
        name: "ATT_ACC_GATE",
        key: "accel_gate_g",
        unit: "g",
        default: 0.3,
        min: 0.01,
        max: 3.0,
        description: "Specific-force error beyond which the accelerometer is not used",
    },
    ParamMeta {
        name: "ATT_ALIGN_N",
        key: "align_samples",
        unit: "samples",
        default: 250.0,
        min: 1.0,
        max: 10000.0,
        description: "IMU samples averaged for the initial alignment at rest",
    },
    ParamMeta {
        name: "ATT_MAX_DR_T",
        key: "max_uncorrected_s",
        unit: "s",
        default: 0.5,
        min: 0.01,
        max: 60.0,
        description: "Longest gyro-only propagation before the attitude is flagged invalid",
    },
    ParamMeta {
        name: "ATT_MAG_INC",
        key: "mag_inclination_deg",
        unit: "deg",
        default: 63.3,
        min: -90.0,
        max: 90.0,
        description: "Magnetic inclination at the flying site",
    },
    ParamMeta {
        name: "ATT_MAG_DEC",
        key: "mag_declination_deg",
        unit: "deg",
        default: 3.0,
        min: -180.0,
        max: 180.0,
        description: "Magnetic declination at the flying site",
    },
];

impl AttitudeParams {
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
        if self.accel_deweight_g >= self.accel_gate_g {
            v.push(ParamViolation {
                key: "attitude.accel_deweight_g".into(),
                reason: format!("must be below accel_gate_g ({})", self.accel_gate_g),
            });
        }
        for (k, arr) in [
            ("mag_offset", &self.mag_offset),
            ("mag_rotation_rad", &self.mag_rotation_rad),
        ] {
            if arr.iter().any(|x| !x.is_finite()) {
                v.push(ParamViolation {
                    key: format!("attitude.{k}"),
                    reason: "must be finite".into(),
                });
            }
        }
        if self.mag_scale.iter().any(|x| !(x.is_finite() && *x > 0.0)) {
            v.push(ParamViolation {
                key: "attitude.mag_scale".into(),
                reason: "every scale must be > 0".into(),
            });
        }
        v
    }

    /// The magnetometer calibration these parameters describe.
    pub fn mag_calibration(&self) -> crate::estimator::attitude::MagCalibration {
        let r = Rotation3::from_scaled_axis(Vector3::from(self.mag_rotation_rad));
        crate::estimator::attitude::MagCalibration::from_ellipsoid(
            Vector3::from(self.mag_offset),
            r.matrix(),
            &Vector3::from(self.mag_scale),
        )
    }

    /// Unit Earth-field direction in NED from inclination and declination.
    pub fn earth_field_ned(&self) -> Vector3<f64> {
        let (si, ci) = self.mag_inclination_deg.to_radians().sin_cos();
        let (sd, cd) = self.mag_declination_deg.to_radians().sin_cos();
        Vector3::new(ci * cd, ci * sd, si)
    }
}

/// The rotation matrix of a rotation vector (a helper for calibration tests and tools).
pub fn rotation_matrix(rotation_vector: &Vector3<f64>) -> Matrix3<f64> {
    *Rotation3::from_scaled_axis(*rotation_vector).matrix()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_valid_and_names_fit_mavlink() {
        assert!(AttitudeParams::default().validate().is_empty());
        for m in ATTITUDE_META {
            assert!(m.name.len() <= 16, "{}", m.name);
            assert!(m.min <= m.default && m.default <= m.max, "{}", m.name);
        }
    }

    #[test]
    fn every_violation_is_reported_with_its_range() {
        let p: AttitudeParams = toml::from_str(
            "observer_gain = -1.0\naccel_gate_g = 0.01\nmag_scale = [1.0, 0.0, 1.0]\n",
        )
        .unwrap();
        let v = p.validate();
        let keys: Vec<&str> = v.iter().map(|x| x.key.as_str()).collect();
        assert_eq!(
            keys,
            [
                "attitude.observer_gain",
                "attitude.accel_deweight_g",
                "attitude.mag_scale"
            ]
        );
        assert!(v[0].reason.contains("[0.05, 50] 1/s, got -1"));
        assert!(
            toml::from_str::<AttitudeParams>("observer_k = 1.0").is_err(),
            "unknown keys are refused"
        );
    }
}
