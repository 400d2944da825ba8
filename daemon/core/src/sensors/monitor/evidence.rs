//! What the other sensors say about whether a sensor's reading should have changed since it
//! last did. Either the world is noisy, and a real sensor's reading always changes: another
//! sensor has been seen to *jitter*, its change reversing sign from one reading to the next as
//! white noise does two times in three (a smooth motion reverses only at its turning points);
//! a noisy sensor stays one, even when it freezes itself. Or the vehicle moved in a way the
//! sensor measures:
//! - IMU: the magnetometer turned 1° away from where the IMU's repeated rate would have turned
//!   it (a steady turn repeats an exact IMU's reading; the field then turns as its gyro says);
//! - magnetometer: the gyro turned the body 1° about an axis across the field;
//! - barometer: the GPS altitude moved 1 m;
//! - GPS: its own velocity is over 0.5 m/s (it moves, but its position does not), or the
//!   barometer moved 1 m.

use nalgebra::{UnitQuaternion, Vector3};

/// A turn that any magnetometer shows (rad).
const TURN_RAD: f64 = 1.0 * std::f64::consts::PI / 180.0;
/// A change of height that the barometer or the GPS shows (m).
const HEIGHT_M: f64 = 1.0;
/// A GPS velocity whose position must change between solutions (m/s).
const GPS_MOVING_M_S: f64 = 0.5;
/// The share of readings whose change reverses sign that makes a sensor noisy (white noise:
/// 2/3, less the steps under the floor), and the readings it is averaged over.
const NOISY_SHARE: f64 = 0.25;
const JITTER_WINDOW: f64 = 16.0;
/// Steps too small to count as a reversal: below any real sensor's noise, above a simulator's
/// numerical dither (gyro rad/s, field gauss, height m).
const GYRO_FLOOR: f64 = 3e-4;
const MAG_FLOOR: f64 = 2e-4;
const BARO_FLOOR: f64 = 0.02;
const GPS_VEL_FLOOR: f64 = 0.01;

/// Whether a sensor's readings jitter as noise does.
#[derive(Debug, Clone, Copy, Default)]
struct Jitter {
    last: Option<f64>,
    last_step: f64,
    share: f64,
    /// The share has reached [`NOISY_SHARE`]: a noisy sensor.
    seen: bool,
}

impl Jitter {
    fn add(&mut self, x: f64, floor: f64) {
        if let Some(prev) = self.last {
            let step = x - prev;
            let reversed = step.abs() >= floor
                && self.last_step.abs() >= floor
                && step.signum() != self.last_step.signum();
            self.share += (f64::from(u8::from(reversed)) - self.share) / JITTER_WINDOW;
            self.seen |= self.share >= NOISY_SHARE;
            self.last_step = step;
        }
        self.last = Some(x);
    }

    fn noisy(&self) -> bool {
        self.seen
    }
}

/// The newest reading of each slow sensor.
#[derive(Debug, Clone, Copy, Default)]
struct Latest {
    mag: Option<Vector3<f64>>,
    baro_m: Option<f64>,
    gps_alt_m: Option<f64>,
    gps_vel_m_s: Option<Vector3<f64>>,
}

/// How far `now` is from `then`, where both are known (else 0).
fn moved<T: Copy>(now: Option<T>, then: Option<T>, by: impl Fn(T, T) -> f64) -> f64 {
    match (now, then) {
        (Some(a), Some(b)) => by(a, b),
        _ => 0.0,
    }
}

/// The evidence, kept up to date from every sample.
#[derive(Debug, Clone, Default)]
pub(super) struct Evidence {
    gyro_jitter: Jitter,
    mag_jitter: Jitter,
    baro_jitter: Jitter,
    gps_jitter: Jitter,
    latest: Latest,
    /// When the IMU's reading last changed, its gyro then, and the slow sensors then.
    imu_change_usec: u64,
    imu_gyro: Vector3<f64>,
    at_imu_change: Latest,
    /// The turn across the field the gyro has measured since the magnetometer last changed
    /// (rad).
    turn_since_mag_change: f64,
    at_baro_change: Latest,
    at_gps_change: Latest,
    last_t_usec: Option<u64>,
}

impl Evidence {
    /// A fresh magnetometer reading (gauss), and whether it changed.
    pub fn mag(&mut self, m: Vector3<f64>, changed: bool) {
        self.latest.mag = Some(m);
        self.mag_jitter.add(m.x, MAG_FLOOR);
        if changed {
            self.turn_since_mag_change = 0.0;
        }
    }

    /// A fresh barometric height (m), and whether it changed.
    pub fn baro(&mut self, height_m: f64, changed: bool) {
        self.latest.baro_m = Some(height_m);
        self.baro_jitter.add(height_m, BARO_FLOOR);
        if changed {
            self.at_baro_change = self.latest;
        }
    }

    /// A fresh 3D fix's altitude (m) and velocity (NED, m/s), and whether it changed.
    pub fn gps(&mut self, alt_m: f64, vel_ned_m_s: Vector3<f64>, changed: bool) {
        (self.latest.gps_alt_m, self.latest.gps_vel_m_s) = (Some(alt_m), Some(vel_ned_m_s));
        self.gps_jitter.add(vel_ned_m_s.x, GPS_VEL_FLOOR);
        if changed {
            self.at_gps_change = self.latest;
        }
    }

    /// The IMU's reading at `t_usec` (its gyro, rad/s), whether it changed, and whether its gyro
    /// is believed (not suspect, not lost): only then does it measure the field's turn.
    pub fn imu(&mut self, t_usec: u64, gyro: Vector3<f64>, changed: bool, believed: bool) {
        let dt_s = self
            .last_t_usec
            .map_or(0.0, |last| t_usec.saturating_sub(last) as f64 * 1e-6);
        self.last_t_usec = Some(t_usec);
        self.gyro_jitter.add(gyro.x, GYRO_FLOOR);
        if changed {
            (self.imu_change_usec, self.imu_gyro) = (t_usec, gyro);
            self.at_imu_change = self.latest;
        }
        if let (Some(m), true) = (self.latest.mag, believed) {
            let across = gyro.cross(&m.try_normalize(1e-9).unwrap_or_else(Vector3::zeros));
            self.turn_since_mag_change += across.norm() * dt_s;
        }
    }

    /// The IMU's reading should have changed since it last did.
    pub fn imu_should_change(&self) -> bool {
        if self.mag_jitter.noisy() || self.baro_jitter.noisy() || self.gps_jitter.noisy() {
            return true;
        }
        // The field where the repeated rate would have turned it, against where it is.
        let (Some(then), Some(now)) = (self.at_imu_change.mag, self.latest.mag) else {
            return false;
        };
        let t_s = self
            .last_t_usec
            .unwrap_or(0)
            .saturating_sub(self.imu_change_usec) as f64
            * 1e-6;
        let turn = UnitQuaternion::from_scaled_axis(self.imu_gyro * t_s);
        turn.inverse_transform_vector(&then).angle(&now) >= TURN_RAD
    }

    /// The magnetometer's reading should have changed since it last did.
    pub fn mag_should_change(&self) -> bool {
        self.gyro_jitter.noisy()
            || self.baro_jitter.noisy()
            || self.gps_jitter.noisy()
            || self.turn_since_mag_change >= TURN_RAD
    }

    /// The barometer's reading should have changed since it last did.
    pub fn baro_should_change(&self) -> bool {
        let (now, then) = (self.latest, self.at_baro_change);
        self.gyro_jitter.noisy()
            || self.mag_jitter.noisy()
            || self.gps_jitter.noisy()
            || moved(now.gps_alt_m, then.gps_alt_m, |a, b| (a - b).abs()) >= HEIGHT_M
    }

    /// The GPS solution should have changed since it last did.
    pub fn gps_should_change(&self) -> bool {
        let (now, then) = (self.latest, self.at_gps_change);
        self.gyro_jitter.noisy()
            || self.mag_jitter.noisy()
            || self.baro_jitter.noisy()
            || now.gps_vel_m_s.is_some_and(|v| v.norm() >= GPS_MOVING_M_S)
            || moved(now.baro_m, then.baro_m, |a, b| (a - b).abs()) >= HEIGHT_M
    }
}
