//! Online hard-iron estimation: a field fixed to the body (a magnet on the frame, a changed
//! offset since the last calibration) learned in flight from the gyro, as PX4's EKF2 learns its
//! magnetometer bias states and ArduPilot its in-flight offsets — but without needing the
//! attitude or the Earth field.
//!
//! A world-fixed field seen by a rotating magnetometer with offset `o` obeys
//! `m(t) − o = M (m(t−L) − o)`, with `M = R(t)ᵀ R(t−L)` the body's rotation between the two
//! instants from the gyro alone. So `(I − M) o = m(t) − M m(t−L)`, linear in `o`; rotations about
//! two or more axes make it solvable. The magnetometer is averaged over short blocks (noise), and
//! pairs of blocks at two lags feed a least-squares fit with exponential forgetting. The fit is
//! taken only when it is well conditioned and consistent (its residual small against the field):
//! a world field that changes from place to place (a magnet on the floor) breaks the model and is
//! left out. Not yet handled: an offset that changes (a magnet taken off) is not learned again, as
//! the pairs spanning the change keep the fit inconsistent; hence `ATT_MAG_LEARN` is off by
//! default.

use crate::math::quat;
use nalgebra::{Matrix3, UnitQuaternion, Vector3};

/// Length of one averaging block (s).
pub const BLOCK_S: f64 = 0.1;
/// The lags, in blocks, at which blocks are paired.
const LAGS: [usize; 2] = [3, 10];
/// Ring of past blocks (at least the longest lag + 1).
const RING: usize = 11;

/// Settings of the online hard-iron estimator.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HardIronSettings {
    /// Forgetting time constant of the fit (s).
    pub tau_s: f64,
    /// Smallest eigenvalue of the normal matrix for a solution (rad², summed over the pairs the
    /// forgetting keeps): the rotation the fit needs about its least-seen axis.
    pub min_information: f64,
    /// Largest RMS residual of an accepted fit, as a fraction of the field strength.
    pub max_residual: f64,
    /// Largest accepted offset, as a multiple of the field strength.
    pub max_offset: f64,
}

impl Default for HardIronSettings {
    fn default() -> Self {
        Self {
            tau_s: 5.0,
            min_information: 1.0,
            max_residual: 0.04,
            max_offset: 3.0,
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
struct Block {
    mag: Vector3<f64>,
    /// Rotation matrix of the gyro-only attitude at the block's middle.
    rotation: Matrix3<f64>,
}

/// The estimator.
#[derive(Debug, Clone, PartialEq)]
pub struct HardIronEstimator {
    settings: HardIronSettings,
    ring: [Option<Block>; RING],
    head: usize,
    sum: Vector3<f64>,
    count: u32,
    elapsed_s: f64,
    middle: Option<Matrix3<f64>>,
    normal: Matrix3<f64>,
    rhs: Vector3<f64>,
    z_sq: f64,
    pairs: f64,
    offset: Vector3<f64>,
    accepted: u64,
}

impl HardIronEstimator {
    /// An estimator with no offset learned.
    pub fn new(settings: HardIronSettings) -> Self {
        Self {
            settings,
            ring: [None; RING],
            head: 0,
            sum: Vector3::zeros(),
            count: 0,
            elapsed_s: 0.0,
            middle: None,
            normal: Matrix3::zeros(),
            rhs: Vector3::zeros(),
            z_sq: 0.0,
            pairs: 0.0,
            offset: Vector3::zeros(),
            accepted: 0,
        }
    }

    /// The offset learned so far (zero until a fit is accepted).
    pub fn offset(&self) -> Vector3<f64> {
        self.offset
    }

    /// Fits accepted so far.
    pub fn accepted(&self) -> u64 {
        self.accepted
    }

    /// Takes one magnetometer sample `mag` (calibrated, before this offset), `dt` seconds after
    /// the previous one, with the gyro-only attitude `q_gyro` of the same instant and the field
    /// strength `field` (same unit). Returns the offset to subtract.
    pub fn update(
        &mut self,
        mag: &Vector3<f64>,
        q_gyro: &UnitQuaternion<f64>,
        field: f64,
        dt: f64,
    ) -> Vector3<f64> {
        self.sum += mag;
        self.count += 1;
        self.elapsed_s += dt;
        if self.middle.is_none() && self.elapsed_s >= 0.5 * BLOCK_S {
            self.middle = Some(quat::to_rotation_matrix(q_gyro));
        }
        if self.elapsed_s >= BLOCK_S {
            let block = Block {
                mag: self.sum / f64::from(self.count),
                rotation: self
                    .middle
                    .unwrap_or_else(|| quat::to_rotation_matrix(q_gyro)),
            };
            self.sum = Vector3::zeros();
            self.count = 0;
            self.elapsed_s = 0.0;
            self.middle = None;
            self.add_block(block, field);
        }
        self.offset
    }

    fn add_block(&mut self, block: Block, field: f64) {
        let forget = (-BLOCK_S / self.settings.tau_s).exp();
        self.normal *= forget;
        self.rhs *= forget;
        self.z_sq *= forget;
        self.pairs *= forget;
        for lag in LAGS {
            let Some(old) = self.ring[(self.head + RING - lag) % RING] else {
                continue;
            };
            let m = block.rotation.transpose() * old.rotation;
            let h = Matrix3::identity() - m;
            let z = block.mag - m * old.mag;
            self.normal += h.transpose() * h;
            self.rhs += h.transpose() * z;
            self.z_sq += z.norm_squared();
            self.pairs += 1.0;
        }
        self.ring[self.head] = Some(block);
        self.head = (self.head + 1) % RING;
        self.solve(field);
    }

    fn solve(&mut self, field: f64) {
        let s = &self.settings;
        if field.is_nan() || field <= 0.0 || self.pairs < 1.0 {
            return;
        }
        let eigen = self.normal.symmetric_eigen();
        if eigen.eigenvalues.min() < s.min_information {
            return;
        }
        let Some(inverse) = self.normal.try_inverse() else {
            return;
        };
        let o = inverse * self.rhs;
        let residual = (self.z_sq - 2.0 * o.dot(&self.rhs) + o.dot(&(self.normal * o))).max(0.0);
        let rms = (residual / self.pairs).sqrt();
        if o.iter().all(|x| x.is_finite())
            && rms < s.max_residual * field
            && o.norm() < s.max_offset * field
        {
            self.offset = o;
            self.accepted += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A body tumbling about changing axes in a uniform field, with a magnet on the frame.
    fn tumble(
        offset: Vector3<f64>,
        seconds: f64,
        est: &mut HardIronEstimator,
        q: &mut UnitQuaternion<f64>,
        t0: f64,
    ) {
        let field = Vector3::new(0.2, 0.0, 0.45);
        let dt = 0.004;
        let mut t = t0;
        while t < t0 + seconds {
            let w = Vector3::new((0.7 * t).sin(), (0.5 * t).cos(), (0.3 * t).sin() * 0.5);
            *q = quat::propagate(q, &w, dt);
            let m = q.inverse() * field + offset;
            est.update(&m, q, field.norm(), dt);
            t += dt;
        }
    }

    #[test]
    fn learns_a_body_fixed_offset() {
        let mut est = HardIronEstimator::new(HardIronSettings::default());
        let magnet = Vector3::new(-0.07, 0.01, -0.58);
        let mut q = UnitQuaternion::identity();
        tumble(magnet, 20.0, &mut est, &mut q, 0.0);
        assert!((est.offset() - magnet).norm() < 1e-3, "{}", est.offset());
    }

    #[test]
    fn without_rotation_nothing_is_learned() {
        let mut est = HardIronEstimator::new(HardIronSettings::default());
        let q = UnitQuaternion::identity();
        for _ in 0..10_000 {
            est.update(&Vector3::new(0.3, 0.1, 0.4), &q, 0.5, 0.004);
        }
        assert_eq!(est.accepted(), 0);
        assert_eq!(est.offset(), Vector3::zeros());
    }
}
