//! The attitude estimator's parameters: their values, metadata (MAVLink names, units, ranges)
//! and checks.

use super::MagCalibration;
use super::meta::ATTITUDE_META;
use crate::estimator::heading::HeadingSettings;
use crate::estimator::tilt_heading::TiltHeadingSettings;
use crate::params::{ParamViolation, check};
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
        let fields = [
            ("observer_gain", self.observer_gain),
            ("bias_gain", self.bias_gain),
            ("bias_limit_rad_s", self.bias_limit_rad_s),
            ("accel_weight", self.accel_weight),
            ("mag_weight", self.mag_weight),
            ("accel_deweight_g", self.accel_deweight_g),
            ("accel_gate_g", self.accel_gate_g),
            ("align_samples", self.align_samples as f64),
            ("max_uncorrected_s", self.max_uncorrected_s),
            ("mag_inclination_deg", self.mag_inclination_deg),
            ("mag_declination_deg", self.mag_declination_deg),
            ("mag_intensity_gauss", self.mag_intensity_gauss),
            ("mag_calibration_id", self.mag_calibration_id as f64),
        ];
        for (key, value) in fields {
            check(&mut v, "attitude", m, key, value);
        }
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
            mag_inclination_rad: self.mag_inclination_deg.to_radians(),
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
