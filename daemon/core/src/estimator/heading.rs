//! Heading from the magnetometer's horizontal part, with magnetic-disturbance rejection.
//!
//! The field, rotated by the tilt-corrected attitude into a frame that is level but of unknown
//! heading, gives the heading offset `δ` that turns its horizontal part to magnetic north (plus
//! the declination). `δ` follows that measurement with time constant `tau` — only about the
//! vertical, so a magnet can turn the heading but never the tilt. At the start it is the running
//! mean of the measurements (converged within `tau`, whatever the start).
//!
//! A disturbed field is recognised by its strength and dip against a reference learned from the
//! clean field (as VQF does): then the heading is the gyro's. That lasts at most
//! `max_rejection_s`, after which the field corrects again (the gyro's heading drifts without
//! bound; a disturbance that long is more likely a changed field). A field that stays disturbed
//! but steady for `new_reference_s` becomes the new reference (another place, a new calibration);
//! until the first reference has held that long it may itself be the disturbed one, so a steady
//! other field replaces it after `new_first_reference_s`, and the heading starts again from it.

use nalgebra::{UnitQuaternion, Vector3};
use std::f64::consts::{PI, TAU};

/// Settings of the heading correction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HeadingSettings {
    /// Time constant of the heading correction (s).
    pub tau_s: f64,
    /// Magnetic declination (rad, positive east).
    pub declination_rad: f64,
    /// Largest departure of the field strength from the reference, as a fraction of it.
    pub strength_tolerance: f64,
    /// Largest departure of the dip from the reference (rad).
    pub dip_tolerance_rad: f64,
    /// Longest time a disturbed field is ignored (s).
    pub max_rejection_s: f64,
    /// Time a disturbed but steady field takes to become the new reference (s).
    pub new_reference_s: f64,
    /// The same while the first reference is unconfirmed (s): the field at the start may be the
    /// disturbed one (VQF's `magNewFirstTime`).
    pub new_first_reference_s: f64,
    /// Time constant of the reference's learning from the clean field (s).
    pub reference_tau_s: f64,
}

impl Default for HeadingSettings {
    fn default() -> Self {
        Self {
            tau_s: 15.0,
            declination_rad: 0.0,
            strength_tolerance: 0.1,
            dip_tolerance_rad: 10f64.to_radians(),
            max_rejection_s: 60.0,
            new_reference_s: 20.0,
            new_first_reference_s: 5.0,
            reference_tau_s: 20.0,
        }
    }
}

/// Strength and dip of a field.
#[derive(Debug, Clone, Copy, PartialEq)]
struct FieldShape {
    strength: f64,
    dip: f64,
}

impl FieldShape {
    fn differs(&self, other: &FieldShape, s: &HeadingSettings) -> bool {
        (self.strength - other.strength).abs() > s.strength_tolerance * other.strength
            || (self.dip - other.dip).abs() > s.dip_tolerance_rad
    }

    fn approach(&mut self, other: &FieldShape, k: f64) {
        self.strength += (other.strength - self.strength) * k;
        self.dip += (other.dip - self.dip) * k;
    }
}

/// The heading corrector.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HeadingCorrector {
    settings: HeadingSettings,
    delta: f64,
    samples: f64,
    reference: Option<FieldShape>,
    /// Time the reference has held (s); it is confirmed once that reaches `new_reference_s`.
    reference_held_s: f64,
    candidate: Option<(FieldShape, f64)>,
    disturbed_s: f64,
    disturbed_samples: u64,
    new_references: u64,
    last_error: f64,
    /// The gain `dt / tau` of the last sample.
    k_nominal: f64,
    /// The gain of the last correction.
    last_gain: f64,
    /// A clean field's heading this far from the estimate for [`RESET_AFTER_S`] resets it (rad).
    reset_limit: f64,
    /// How long the clean field has been that far (s), and the error low-passed over
    /// [`RESET_AFTER_S`] / 3 (rad): one sample's noise is several degrees.
    far_s: f64,
    error_lp: f64,
    resets: u64,
    last_reset: f64,
    /// The time constant the heading's drift allows (s): see [`Self::set_drift`].
    drift_tau_s: f64,
}

/// How long a clean field must stay further than the reset limit from the heading before the
/// heading is taken from it at once (s).
pub const RESET_AFTER_S: f64 = 1.0;

/// The heading error an unknown drift may make before the field corrects it (rad): 0.5°.
pub const DRIFT_ALLOWANCE_RAD: f64 = 0.5 * PI / 180.0;

/// `x` wrapped to [−π, π).
fn wrap(x: f64) -> f64 {
    (x + PI).rem_euclid(TAU) - PI
}

impl HeadingCorrector {
    /// A corrector that has seen no field.
    pub fn new(settings: HeadingSettings) -> Self {
        Self {
            settings,
            delta: 0.0,
            samples: 0.0,
            reference: None,
            reference_held_s: 0.0,
            candidate: None,
            disturbed_s: 0.0,
            disturbed_samples: 0,
            new_references: 0,
            last_error: 0.0,
            k_nominal: 0.0,
            last_gain: 0.0,
            reset_limit: std::f64::consts::PI,
            far_s: 0.0,
            error_lp: 0.0,
            resets: 0,
            last_reset: 0.0,
            drift_tau_s: f64::INFINITY,
        }
    }

    /// Changes the settings, keeping the heading and the reference.
    pub fn set_settings(&mut self, settings: HeadingSettings) {
        self.delta += settings.declination_rad - self.settings.declination_rad;
        self.settings = settings;
    }

    /// Sets the heading offset and forgets the field (the next one starts it again).
    pub fn reset_to(&mut self, delta: f64) {
        self.delta = delta;
        self.samples = 0.0;
    }

    /// Takes the heading of a field `m` in the level frame, averaged elsewhere over `samples`
    /// measurements (a fit of the start): the running mean goes on from there.
    pub fn take_field(&mut self, m: &Vector3<f64>, samples: f64) {
        if m.x.hypot(m.y) < 0.05 * m.norm() {
            return;
        }
        self.delta = wrap(self.settings.declination_rad - m.y.atan2(m.x));
        self.samples = samples.max(1.0);
        (self.far_s, self.error_lp) = (0.0, 0.0);
    }

    /// A clean field's heading further than `limit` (rad) from the estimate for
    /// [`RESET_AFTER_S`] resets the heading to it.
    pub fn set_reset_limit(&mut self, limit: f64) {
        self.reset_limit = limit;
    }

    /// The uncertainty of the heading's drift rate (rad/s, the gyro bias about the vertical):
    /// the correction is no slower than it takes that drift to make [`DRIFT_ALLOWANCE_RAD`] of
    /// error. A gyro whose bias is not yet known (a start in motion) is held to the field
    /// closely; once it is, the correction is as slow as `tau_s` asks.
    /// Zero: no drift to hold against.
    pub fn set_drift(&mut self, sigma_rad_s: f64) {
        self.drift_tau_s = if sigma_rad_s > 0.0 {
            DRIFT_ALLOWANCE_RAD / sigma_rad_s
        } else {
            f64::INFINITY
        };
    }

    /// Heading resets so far, and the last one's size (rad).
    pub fn resets(&self) -> (u64, f64) {
        (self.resets, self.last_reset)
    }

    /// Whether the start (the running mean of the first `tau` seconds) is over.
    pub fn converged(&self) -> bool {
        self.samples > 0.0 && 1.0 / self.samples <= self.k_nominal
    }

    /// Whether a field has been taken.
    pub fn started(&self) -> bool {
        self.samples > 0.0
    }

    /// The rotation about the vertical from the level frame to NED.
    pub fn rotation(&self) -> UnitQuaternion<f64> {
        UnitQuaternion::from_axis_angle(&Vector3::z_axis(), self.delta)
    }

    /// The learned field strength, once known.
    pub fn reference_strength(&self) -> Option<f64> {
        self.reference.map(|r| r.strength)
    }

    /// The learned field's dip (rad, positive down), once known.
    pub fn reference_dip(&self) -> Option<f64> {
        self.reference.map(|r| r.dip)
    }

    /// Samples rejected as disturbed.
    pub fn disturbed_samples(&self) -> u64 {
        self.disturbed_samples
    }

    /// Times a new reference was adopted.
    pub fn new_references(&self) -> u64 {
        self.new_references
    }

    /// The last measured heading error (rad).
    pub fn last_error(&self) -> f64 {
        self.last_error
    }

    /// The fraction of the error the last correction took.
    pub fn last_gain(&self) -> f64 {
        self.last_gain
    }

    /// Takes the field in the level frame, `dt` seconds after the previous one. Returns the
    /// heading correction applied (rad), or `None` when none was (rejected, or unusable).
    pub fn update(&mut self, m: &Vector3<f64>, dt: f64) -> Option<f64> {
        let s = self.settings;
        let horizontal = m.x.hypot(m.y);
        let strength = m.norm();
        if strength.is_nan() || strength <= 0.0 || horizontal < 0.05 * strength {
            return None;
        }
        let shape = FieldShape {
            strength,
            dip: m.z.atan2(horizontal),
        };
        let target = s.declination_rad - m.y.atan2(m.x);
        let error = wrap(target - self.delta);
        self.last_error = error;
        let Some(reference) = self.reference.as_mut() else {
            self.reference = Some(shape);
            self.delta = target;
            self.samples = 1.0;
            return None;
        };
        let confirmed = self.reference_held_s >= s.new_reference_s;
        if shape.differs(reference, &s) {
            self.disturbed_samples += 1;
            self.disturbed_s += dt;
            let new_after_s = if confirmed {
                s.new_reference_s
            } else {
                s.new_first_reference_s
            };
            match self.candidate.as_mut() {
                Some((c, steady_s)) if !shape.differs(c, &s) => {
                    c.approach(&shape, (dt / s.reference_tau_s).min(1.0));
                    *steady_s += dt;
                    if *steady_s >= new_after_s {
                        *reference = *c;
                        self.candidate = None;
                        self.new_references += 1;
                        self.disturbed_s = 0.0;
                        self.reference_held_s = 0.0;
                        if !confirmed {
                            // The start was in a disturbed field: the heading starts again.
                            self.samples = 0.0;
                        }
                    }
                }
                _ => self.candidate = Some((shape, 0.0)),
            }
            if self.disturbed_s <= s.max_rejection_s {
                return None;
            }
        } else {
            self.disturbed_s = 0.0;
            self.candidate = None;
            self.reference_held_s += dt;
            reference.approach(&shape, (dt / s.reference_tau_s).min(1.0));
            // A clean field far from the heading for a second: the heading was wrong (a gyro
            // that saturated, a tilt reset), not the field. Taken at once, not crept towards.
            self.error_lp += wrap(error - self.error_lp) * (3.0 * dt / RESET_AFTER_S).min(1.0);
            self.far_s = if self.error_lp.abs() > self.reset_limit {
                self.far_s + dt
            } else {
                0.0
            };
            if self.far_s >= RESET_AFTER_S && self.samples > 0.0 {
                let step = self.error_lp;
                (self.far_s, self.error_lp) = (0.0, 0.0);
                self.resets += 1;
                self.last_reset = step;
                self.delta = wrap(self.delta + step);
                return Some(step);
            }
        }
        self.samples += 1.0;
        self.k_nominal = dt / s.tau_s.min(self.drift_tau_s);
        let k = self.k_nominal.max(1.0 / self.samples).min(1.0);
        self.last_gain = k;
        let step = k * error;
        self.delta = wrap(self.delta + step);
        Some(step)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn field(heading: f64) -> Vector3<f64> {
        // Inclination 69°, strength 0.44, seen from a level frame turned by `heading`.
        let (h, v) = (
            0.44 * 69f64.to_radians().cos(),
            0.44 * 69f64.to_radians().sin(),
        );
        Vector3::new(h * heading.cos(), -h * heading.sin(), v)
    }

    #[test]
    fn converges_at_once_and_rejects_a_magnet_for_a_bounded_time() {
        let s = HeadingSettings::default();
        let mut c = HeadingCorrector::new(s);
        let dt = 0.01;
        // 20 s of a clean field confirm it as the reference.
        for _ in 0..2100 {
            c.update(&field(1.0), dt);
        }
        assert!((c.delta - 1.0).abs() < 1e-9, "{}", c.delta);
        // A magnet: stronger field pointing elsewhere. Rejected, so the heading holds.
        let magnet = field(2.0) * 1.5;
        for _ in 0..(15.0 / dt) as usize {
            assert_eq!(c.update(&magnet, dt), None);
        }
        assert!((c.delta - 1.0).abs() < 1e-9);
        assert_eq!(c.disturbed_samples(), 1500);
        // A field that stays disturbed but steady becomes the reference (at 20 s): the heading
        // follows it from then on, with its time constant (15 s).
        for _ in 0..(80.0 / dt) as usize {
            c.update(&magnet, dt);
        }
        assert_eq!(c.new_references(), 1);
        assert!((c.delta - 2.0).abs() < 0.05, "{}", c.delta);
    }

    /// A start in a disturbed field: the first reference is the magnet's, unconfirmed, so the
    /// clean field that follows replaces it after 5 s (not 20 s), and the heading starts again
    /// from it at once.
    #[test]
    fn a_disturbed_start_is_replaced_by_the_clean_field_after_five_seconds() {
        let mut c = HeadingCorrector::new(HeadingSettings::default());
        let dt = 0.01;
        for _ in 0..300 {
            c.update(&(field(2.0) * 1.5), dt);
        }
        assert!((c.delta - 2.0).abs() < 1e-9);
        let mut replaced_at = None;
        for k in 1..=1000 {
            c.update(&field(1.0), dt);
            if replaced_at.is_none() && c.new_references() == 1 {
                replaced_at = Some(k as f64 * dt);
            }
        }
        let t = replaced_at.expect("replaced");
        assert!((t - 5.0).abs() < 0.05, "{t}");
        assert!((c.delta - 1.0).abs() < 1e-9, "{}", c.delta);
    }
}
