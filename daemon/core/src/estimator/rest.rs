//! Rest detection from the IMU signals themselves: the gyro and the accelerometer stay close to
//! their own low-passed values, and the mean rate is small enough to be a bias, for a minimum
//! time (VQF's test). At rest the mean rate is the gyro bias.
//!
//! Beyond VQF: a slow, smooth rotation (a hovering vehicle swaying at 1°/s) passes that test, and
//! its rate would be learned as bias. So the low-passed accelerometer and magnetometer must also
//! keep the direction they had when the stillness began: 1°/s for 1.5 s turns them 1.5°.

use super::lowpass::LowPass;
use nalgebra::Vector3;

/// Thresholds of the rest detector.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RestThresholds {
    /// Largest deviation of the gyro from its low-passed value (rad/s).
    pub gyro_rad_s: f64,
    /// Largest deviation of the accelerometer from its low-passed value (m/s²).
    pub accel_m_s2: f64,
    /// Largest mean rate that can still be a bias (rad/s).
    pub max_bias_rad_s: f64,
    /// How long both must hold (s).
    pub min_time_s: f64,
    /// Time constant of the low-passed values (s).
    pub tau_s: f64,
    /// Largest turn of the low-passed accelerometer and magnetometer since the stillness began
    /// (rad).
    pub max_turn_rad: f64,
}

impl Default for RestThresholds {
    fn default() -> Self {
        Self {
            gyro_rad_s: 2f64.to_radians(),
            accel_m_s2: 0.5,
            max_bias_rad_s: 0.1,
            min_time_s: 1.5,
            tau_s: 0.5,
            max_turn_rad: 0.5f64.to_radians(),
        }
    }
}

/// The rest detector.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RestDetector {
    thresholds: RestThresholds,
    gyro_lp: LowPass,
    accel_lp: LowPass,
    mag_lp: LowPass,
    /// The low-passed accelerometer and magnetometer when the stillness began.
    anchor: (Vector3<f64>, Option<Vector3<f64>>),
    since_mag_s: f64,
    still_s: f64,
    /// How long the gyro and accelerometer low-passes, and the magnetometer's, have run (s).
    age_s: f64,
    mag_age_s: f64,
}

impl RestDetector {
    /// A detector that has seen nothing.
    pub fn new(thresholds: RestThresholds) -> Self {
        Self {
            thresholds,
            gyro_lp: LowPass::new(thresholds.tau_s),
            accel_lp: LowPass::new(thresholds.tau_s),
            mag_lp: LowPass::new(thresholds.tau_s),
            anchor: (Vector3::zeros(), None),
            since_mag_s: 0.0,
            still_s: 0.0,
            age_s: 0.0,
            mag_age_s: 0.0,
        }
    }

    /// Takes one sample (the magnetometer when a new one came); returns whether the sensor is
    /// at rest.
    pub fn update(
        &mut self,
        gyro: &Vector3<f64>,
        accel: &Vector3<f64>,
        mag: Option<&Vector3<f64>>,
        dt: f64,
    ) -> bool {
        let th = self.thresholds;
        let g = self.gyro_lp.update(gyro, dt);
        let a = self.accel_lp.update(accel, dt);
        self.age_s += dt;
        self.since_mag_s += dt;
        // A low-pass starts at its first, noisy sample: its direction is an anchor only once it
        // has averaged over a time constant (a 0.5° mean turn is within one sample's noise).
        let m = mag.and_then(|m| {
            let dt = std::mem::take(&mut self.since_mag_s);
            self.mag_age_s += dt;
            let m = self.mag_lp.update(m, dt);
            (self.mag_age_s >= th.tau_s).then_some(m)
        });
        let turned = |now: &Vector3<f64>, then: &Vector3<f64>| now.angle(then) > th.max_turn_rad;
        let mut still = self.age_s >= th.tau_s
            && (gyro - g).norm() < th.gyro_rad_s
            && (accel - a).norm() < th.accel_m_s2
            && g.norm() < th.max_bias_rad_s;
        if still && self.still_s > 0.0 {
            still = !turned(&a, &self.anchor.0)
                && !matches!((m, self.anchor.1), (Some(m), Some(then)) if turned(&m, &then));
        }
        if !still {
            self.still_s = 0.0;
            return false;
        }
        if self.still_s == 0.0 {
            let settled = self.mag_age_s >= th.tau_s;
            self.anchor = (a, m.or(settled.then(|| self.mag_lp.value())));
        } else if self.anchor.1.is_none() {
            self.anchor.1 = m;
        }
        self.still_s += dt;
        self.at_rest()
    }

    /// Whatever the signals show, the sensor is not at rest now (the stillness starts again).
    pub fn interrupt(&mut self) {
        self.still_s = 0.0;
    }

    /// Whether the sensor has been still for the minimum time.
    pub fn at_rest(&self) -> bool {
        self.still_s >= self.thresholds.min_time_s
    }

    /// The low-passed gyro: the bias while at rest.
    pub fn mean_rate(&self) -> Vector3<f64> {
        self.gyro_lp.value()
    }

    /// The low-passed specific force: gravity while at rest.
    pub fn mean_accel(&self) -> Vector3<f64> {
        self.accel_lp.value()
    }

    /// How long the sensor must be still to be at rest (s).
    pub fn min_time_s(&self) -> f64 {
        self.thresholds.min_time_s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rest_after_the_minimum_time_and_not_while_turning() {
        let mut r = RestDetector::new(RestThresholds::default());
        let bias = Vector3::new(0.01, -0.02, 0.005);
        let g = Vector3::new(0.0, 0.0, -9.8);
        let dt = 0.004;
        let m = Vector3::new(0.2, 0.0, 0.4);
        // The low-passes settle for a time constant, then the stillness must last 1.5 s.
        let first = (0..600)
            .find(|_| r.update(&bias, &g, Some(&m), dt))
            .map(|i| (i + 1) as f64 * dt);
        assert!(
            first.is_some_and(|t| (t - 2.0).abs() <= 1.5 * dt),
            "{first:?}"
        );
        for _ in 0..100 {
            assert!(r.update(&bias, &g, Some(&m), dt));
        }
        assert!((r.mean_rate() - bias).norm() < 1e-9);
        // A slow turn at 10°/s is not rest, though it is steady.
        for _ in 0..1000 {
            r.update(&Vector3::new(0.0, 0.0, 0.17), &g, Some(&m), dt);
        }
        assert!(!r.at_rest());
        // Nor is shaking.
        for i in 0..1000 {
            let s = if i % 2 == 0 { 1.0 } else { -1.0 };
            r.update(&bias, &(g + Vector3::x() * s), Some(&m), dt);
        }
        assert!(!r.at_rest());
        // Nor a sway at 1°/s, slow enough to pass for a bias: the vectors turn.
        let mut q = nalgebra::UnitQuaternion::identity();
        let mut rest_samples = 0;
        for i in 0..2000 {
            let w = Vector3::new(
                1f64.to_radians() * if (i / 500) % 2 == 0 { 1.0 } else { -1.0 },
                0.0,
                0.0,
            );
            q = crate::math::quat::propagate(&q, &w, dt);
            rest_samples += r.update(&w, &(q.inverse() * g), Some(&(q.inverse() * m)), dt) as usize;
        }
        assert_eq!(rest_samples, 0);
        // Nor a slow yaw, seen by the magnetometer alone.
        for _ in 0..1000 {
            let w = Vector3::new(0.0, 0.0, 1f64.to_radians());
            q = crate::math::quat::propagate(&q, &w, dt);
            rest_samples += r.update(&w, &(q.inverse() * g), Some(&(q.inverse() * m)), dt) as usize;
        }
        assert_eq!(rest_samples, 0);
    }
}
