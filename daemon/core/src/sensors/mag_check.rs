//! The magnetometer's pre-arm consistency check: at rest, does the calibrated field look like
//! the Earth's at the site? Its strength (`ATT_MAG_STR`) and its inclination — the angle below
//! the horizon, measured against the accelerometer's "down" so it needs no attitude — must agree
//! within PX4's `EKF2_MAG_CHK_STR` and `EKF2_MAG_CHK_INC`. A steel table, a magnet near the
//! board, a hard iron never calibrated out or a wrong site all fail it; a heading from such a
//! field would be wrong by tens of degrees.

use crate::estimator::attitude::AttitudeParams;
use nalgebra::Vector3;

/// The simulated magnetometer's device id, PX4's (`DRV_MAG_DEVTYPE_MAGSIM`): what a
/// simulator source presets `CAL_MAG0_ID` to, as PX4's SITL start-up does (its field needs no
/// calibration).
pub const SIMULATED_MAG_ID: u32 = 197_388;

/// What the magnetometer measures, or what it should.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MagField {
    /// Field strength (gauss).
    pub strength_gauss: f64,
    /// Inclination, positive down (deg).
    pub inclination_deg: f64,
}

/// The magnetometer's state for the arming checks.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MagStatus {
    /// A calibration was stored (`CAL_MAG0_ID` ≠ 0).
    pub calibrated: bool,
    /// The field measured at rest, once the magnetometer has spoken for a while.
    pub measured: Option<MagField>,
    /// The field the site should have.
    pub expected: MagField,
}

impl Default for MagStatus {
    /// Calibrated, nothing measured: nothing to object to.
    fn default() -> Self {
        Self {
            calibrated: true,
            measured: None,
            expected: MagField {
                strength_gauss: 0.0,
                inclination_deg: 0.0,
            },
        }
    }
}

/// Low-passes the calibrated field and the specific force (time constant [`Self::TAU_S`]).
#[derive(Debug, Clone, Default)]
pub struct MagFieldMonitor {
    field: Vector3<f64>,
    specific_force: Vector3<f64>,
    /// Time the field has been averaged (s); it starts again after a silence.
    averaged_s: f64,
    since_mag_s: f64,
    /// The field measured, as of the last fresh reading ([`Self::measured`]): worked out when a
    /// reading comes, not on every IMU step.
    measured: Option<MagField>,
}

impl MagFieldMonitor {
    /// Filter time constant (s).
    pub const TAU_S: f64 = 0.5;
    /// Averaging before a reading counts (s).
    pub const SETTLE_S: f64 = 1.0;

    /// One IMU step of `dt` s: the raw magnetometer when fresh, and the accelerometer.
    pub fn update(
        &mut self,
        raw_mag: Option<Vector3<f64>>,
        accel: &Vector3<f64>,
        params: &AttitudeParams,
        dt: f64,
    ) {
        if !(dt.is_finite() && dt > 0.0 && accel.iter().all(|x| x.is_finite())) {
            return;
        }
        let a = (dt / Self::TAU_S).min(1.0);
        self.specific_force += a * (accel - self.specific_force);
        self.since_mag_s += dt;
        let Some(raw) = raw_mag.filter(|m| m.iter().all(|x| x.is_finite())) else {
            if self.since_mag_s > Self::SETTLE_S {
                self.averaged_s = 0.0;
                self.measured = None;
            }
            return;
        };
        let field = params.mag_calibration().apply(&raw);
        let a = (self.since_mag_s / Self::TAU_S).min(1.0);
        self.field = if self.averaged_s == 0.0 {
            field
        } else {
            self.field + a * (field - self.field)
        };
        self.averaged_s += self.since_mag_s;
        self.since_mag_s = 0.0;
        self.measured = self.field_measured();
    }

    /// The field measured, once averaged for [`Self::SETTLE_S`] (as of the last fresh reading).
    pub fn measured(&self) -> Option<MagField> {
        self.measured
    }

    /// The averaged field's strength, and its inclination against the averaged specific force.
    fn field_measured(&self) -> Option<MagField> {
        let g = self.specific_force.norm();
        if self.averaged_s < Self::SETTLE_S || g < 1e-3 {
            return None;
        }
        // At rest the specific force points up: "down" is its opposite.
        let down = -self.specific_force / g;
        let strength = self.field.norm();
        let inclination = if strength > 1e-9 {
            (self.field.dot(&down) / strength)
                .clamp(-1.0, 1.0)
                .asin()
                .to_degrees()
        } else {
            0.0
        };
        Some(MagField {
            strength_gauss: strength,
            inclination_deg: inclination,
        })
    }

    /// The arming checks' view under `params`.
    pub fn status(&self, params: &AttitudeParams) -> MagStatus {
        MagStatus {
            calibrated: params.mag_calibration_id != 0,
            measured: self.measured(),
            expected: MagField {
                strength_gauss: params.mag_intensity_gauss,
                inclination_deg: params.mag_inclination_deg,
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix3, UnitQuaternion};

    /// The field of the site (0.48 G, 63.3° down) seen by a board at `q`, distorted.
    fn feed(
        m: &mut MagFieldMonitor,
        q: UnitQuaternion<f64>,
        hard_iron: Vector3<f64>,
        soft_iron: Matrix3<f64>,
        params: &AttitudeParams,
        seconds: f64,
    ) {
        let (si, ci) = 63.3f64.to_radians().sin_cos();
        let (sd, cd) = 3.0f64.to_radians().sin_cos();
        let field_ned = 0.48 * Vector3::new(ci * cd, ci * sd, si);
        let g_ned = Vector3::new(0.0, 0.0, -9.81);
        let dt = 0.002;
        for k in 0..(seconds / dt) as usize {
            let mag = (k % 5 == 0).then(|| soft_iron * (q.inverse() * field_ned) + hard_iron);
            m.update(mag, &(q.inverse() * g_ned), params, dt);
        }
    }

    #[test]
    fn measures_strength_and_inclination_at_any_attitude_once_settled() {
        let p = AttitudeParams::default();
        let q = UnitQuaternion::from_euler_angles(0.15, -0.1, 2.0);
        let mut m = MagFieldMonitor::default();
        feed(&mut m, q, Vector3::zeros(), Matrix3::identity(), &p, 0.5);
        assert_eq!(m.measured(), None, "not settled yet");
        feed(&mut m, q, Vector3::zeros(), Matrix3::identity(), &p, 1.0);
        let f = m.measured().unwrap();
        assert!((f.strength_gauss - 0.48).abs() < 1e-6, "{f:?}");
        assert!((f.inclination_deg - 63.3).abs() < 1e-6, "{f:?}");
        let s = m.status(&p);
        assert!(!s.calibrated, "CAL_MAG0_ID 0 is uncalibrated");
        assert_eq!(s.expected.strength_gauss, 0.48);
    }

    #[test]
    fn a_hard_iron_shows_and_its_calibration_removes_it() {
        let hard = Vector3::new(0.12, -0.08, 0.2);
        let soft = Matrix3::new(1.08, 0.04, -0.02, 0.04, 0.95, 0.03, -0.02, 0.03, 1.02);
        let q = UnitQuaternion::from_euler_angles(0.0, 0.0, 0.7);
        let mut p = AttitudeParams::default();
        let mut m = MagFieldMonitor::default();
        feed(&mut m, q, hard, soft, &p, 2.0);
        let raw = m.measured().unwrap();
        assert!((raw.strength_gauss - 0.48).abs() > 0.2, "{raw:?}");
        // The calibration that inverts the distortion: offset and the soft iron's inverse
        // (symmetric: Castillo's R·E·Rᵀ).
        p.mag_offset = hard.into();
        p.set_mag_correction(&soft.try_inverse().unwrap());
        let mut m = MagFieldMonitor::default();
        feed(&mut m, q, hard, soft, &p, 2.0);
        let f = m.measured().unwrap();
        assert!((f.strength_gauss - 0.48).abs() < 1e-3, "{f:?}");
        assert!((f.inclination_deg - 63.3).abs() < 0.1, "{f:?}");
    }

    #[test]
    fn a_silent_magnetometer_has_no_reading_and_bad_input_is_ignored() {
        let p = AttitudeParams::default();
        let q = UnitQuaternion::identity();
        let mut m = MagFieldMonitor::default();
        feed(&mut m, q, Vector3::zeros(), Matrix3::identity(), &p, 2.0);
        assert!(m.measured().is_some());
        m.update(
            Some(Vector3::new(f64::NAN, 0.0, 0.0)),
            &Vector3::new(0.0, 0.0, -9.81),
            &p,
            f64::NAN,
        );
        assert!(m.measured().is_some());
        for _ in 0..1000 {
            m.update(None, &Vector3::new(0.0, 0.0, -9.81), &p, 0.002);
        }
        assert_eq!(m.measured(), None, "silent for 2 s");
    }
}
