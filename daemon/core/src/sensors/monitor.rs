//! Which sensors still deliver: silent ones (no fresh reading for a while, once they have been
//! heard) and frozen ones (the very same reading, to the last bit, many times over: a real
//! sensor's noise never repeats itself that long). A lost sensor is taken out of the sample, so
//! the estimators fall back as for a sensor that is off (a frozen barometer would otherwise hold
//! the altitude estimate still while the vehicle climbs), and the failsafe machine hears of it.

use crate::core::SensorSample;
use crate::safety::failsafe::SensorsLost;
use nalgebra::Vector3;

/// A sensor silent longer than this after its last fresh reading is lost (µs): magnetometer and
/// barometer (50–100 Hz), GPS (5–10 Hz).
const MAG_TIMEOUT_US: u64 = 500_000;
const BARO_TIMEOUT_US: u64 = 500_000;
const GPS_TIMEOUT_US: u64 = 1_000_000;
/// Identical readings in a row that make a sensor frozen: IMU 0.2 s at 250 Hz, magnetometer
/// 0.25 s at 100 Hz, barometer 0.5 s at 50 Hz, GPS 2 s at 10 Hz.
const IMU_FROZEN: u32 = 50;
const MAG_FROZEN: u32 = 25;
const BARO_FROZEN: u32 = 25;
const GPS_FROZEN: u32 = 20;

/// One sensor's watch.
#[derive(Debug, Clone, Copy, Default)]
struct Watch {
    last_fresh_usec: Option<u64>,
    last: [f64; 6],
    repeats: u32,
}

impl Watch {
    /// Folds in a fresh reading (as up to six numbers) at `t_usec`.
    fn fresh(&mut self, t_usec: u64, reading: [f64; 6]) {
        if self.last_fresh_usec.is_some() && reading == self.last {
            self.repeats = self.repeats.saturating_add(1);
        } else {
            self.repeats = 0;
        }
        self.last = reading;
        self.last_fresh_usec = Some(t_usec);
    }

    /// Lost: silent beyond `timeout_usec` (after having been heard), or frozen for `frozen`.
    fn lost(&self, t_usec: u64, timeout_usec: u64, frozen: u32) -> bool {
        self.last_fresh_usec
            .is_some_and(|last| t_usec.saturating_sub(last) > timeout_usec)
            || self.repeats >= frozen
    }
}

fn six(v: &Vector3<f64>) -> [f64; 6] {
    [v.x, v.y, v.z, 0.0, 0.0, 0.0]
}

/// The watch over every sensor.
#[derive(Debug, Clone, Default)]
pub struct SensorMonitor {
    imu: Watch,
    mag: Watch,
    baro: Watch,
    gps: Watch,
    lost: SensorsLost,
    /// The sensors have no noise (a simulator's ideal preset): a repeated reading is no sign.
    noise_free: bool,
}

impl SensorMonitor {
    /// Nothing heard yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// The sensors have no noise (a simulator's ideal preset, whose readings at rest repeat
    /// exactly): only silence counts, never a repeated reading.
    pub fn noise_free(&mut self) {
        self.noise_free = true;
    }

    /// Whether [`Self::noise_free`] was said.
    pub fn is_noise_free(&self) -> bool {
        self.noise_free
    }

    /// What is lost as of the last update.
    pub fn lost(&self) -> SensorsLost {
        self.lost
    }

    /// The IMU's last reading repeated the one before: suspect, not yet lost.
    pub fn imu_repeating(&self) -> bool {
        !self.noise_free && self.imu.repeats > 0
    }

    /// Folds in one sample and takes the lost sensors' readings out of it; what is lost now.
    pub fn update(&mut self, s: &mut SensorSample) -> SensorsLost {
        let t = s.t_usec;
        let frozen = |n: u32| if self.noise_free { u32::MAX } else { n };
        let (g, a) = (s.gyro, s.accel);
        self.imu.fresh(t, [g.x, g.y, g.z, a.x, a.y, a.z]);
        if let Some(m) = &s.mag {
            self.mag.fresh(t, six(m));
        }
        if let Some(b) = s.baro_alt_m {
            self.baro.fresh(t, [b, 0.0, 0.0, 0.0, 0.0, 0.0]);
        }
        // A solution without a 3D fix is no GPS: only 3D fixes refresh the watch.
        if let Some(gps) = s.gps.as_ref().filter(|g| g.fix_type >= 3) {
            let p = &gps.position;
            let v = &gps.vel_ned_m_s;
            self.gps
                .fresh(t, [p.lat_deg, p.lon_deg, p.alt_m, v.x, v.y, v.z]);
        }
        self.lost = SensorsLost {
            imu: self.imu.lost(t, u64::MAX, frozen(IMU_FROZEN)),
            mag: self.mag.lost(t, MAG_TIMEOUT_US, frozen(MAG_FROZEN)),
            baro: self.baro.lost(t, BARO_TIMEOUT_US, frozen(BARO_FROZEN)),
            gps: self.gps.lost(t, GPS_TIMEOUT_US, frozen(GPS_FROZEN)),
        };
        if self.lost.mag {
            s.mag = None;
        }
        if self.lost.baro {
            s.baro_alt_m = None;
        }
        if self.lost.gps {
            s.gps = None;
        }
        self.lost
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::estimator::translation::GpsMeasurement;
    use crate::math::geo::LatLonAlt;

    /// Sample `k` at 250 Hz with noise-like readings; mag every 2nd, baro every 5th, GPS every 25th.
    fn sample(k: u64) -> SensorSample {
        let x = (k as f64 * 0.7).sin() * 1e-3;
        SensorSample {
            t_usec: k * 4000,
            gyro: Vector3::repeat(x),
            accel: Vector3::new(x, -x, -9.8 + x),
            mag: k
                .is_multiple_of(2)
                .then_some(Vector3::new(0.2 + x, 0.0, 0.4)),
            baro_alt_m: k.is_multiple_of(5).then_some(488.0 + x),
            gps: k.is_multiple_of(25).then_some(GpsMeasurement {
                fix_type: 3,
                position: LatLonAlt {
                    lat_deg: 47.0 + x * 1e-3,
                    lon_deg: 8.0,
                    alt_m: 488.0,
                },
                vel_ned_m_s: Vector3::repeat(x),
                h_acc_m: 1.0,
                satellites: 10,
            }),
            battery_v: Some(16.0),
            esc_current_a: None,
            rotor_speed_rad_s: None,
        }
    }

    #[test]
    fn healthy_sensors_are_not_lost_and_pass_unchanged() {
        let mut m = SensorMonitor::new();
        for k in 0..2000 {
            let mut s = sample(k);
            let before = s;
            assert_eq!(m.update(&mut s), SensorsLost::default(), "k {k}");
            assert_eq!(s, before);
        }
    }

    #[test]
    fn silent_sensors_are_lost_after_their_timeout_and_come_back() {
        let mut m = SensorMonitor::new();
        let mut lost_at = [None; 3];
        for k in 0..1000 {
            let mut s = sample(k);
            if (250..600).contains(&k) {
                (s.mag, s.baro_alt_m, s.gps) = (None, None, None);
            }
            let l = m.update(&mut s);
            for (i, x) in [l.mag, l.baro, l.gps].into_iter().enumerate() {
                if x && lost_at[i].is_none() {
                    lost_at[i] = Some(k);
                }
            }
            if k >= 650 {
                assert_eq!(l, SensorsLost::default(), "back at {k}");
            }
        }
        // Last fresh readings at k 248 (mag), 245 (baro), 225 (GPS); 4 ms per sample.
        assert_eq!(lost_at, [Some(374), Some(371), Some(476)]);
    }

    /// Noise-free sensors (an ideal simulator at rest) repeat themselves exactly: only their
    /// silence counts.
    #[test]
    fn noise_free_sensors_are_lost_only_to_silence() {
        let mut m = SensorMonitor::new();
        m.noise_free();
        let still = sample(100);
        for k in 0..600 {
            let mut s = SensorSample {
                t_usec: k * 4000,
                mag: (k < 300).then_some(still.mag).flatten(),
                ..still
            };
            let l = m.update(&mut s);
            assert!(!l.imu && !l.baro && !m.imu_repeating(), "k {k}");
            // Last heard at k 299; silent for more than 0.5 s (125 samples) from k 425.
            assert_eq!(l.mag, k >= 425, "k {k}");
        }
    }

    #[test]
    fn frozen_sensors_are_lost_and_taken_out_of_the_sample() {
        let mut m = SensorMonitor::new();
        let stuck = sample(100);
        for k in 0..400 {
            let mut s = sample(k);
            if k >= 200 {
                s.mag = s.mag.and(stuck.mag);
                s.baro_alt_m = s.baro_alt_m.map(|_| 500.0);
                (s.gyro, s.accel) = (stuck.gyro, stuck.accel);
            }
            let l = m.update(&mut s);
            // IMU after 0.2 s, magnetometer after 0.25 s, barometer after 0.5 s.
            assert_eq!((l.imu, l.mag), (k >= 250, k >= 250), "k {k}");
            if k >= 330 {
                assert!(l.baro && !l.gps, "k {k}: {l:?}");
                assert!(s.mag.is_none() && s.baro_alt_m.is_none());
            }
            if k < 200 {
                assert_eq!(l, SensorsLost::default());
            }
        }
    }

    #[test]
    fn gps_without_a_3d_fix_is_lost() {
        let mut m = SensorMonitor::new();
        for k in 0..600 {
            let mut s = sample(k);
            if k >= 300 {
                s.gps = s.gps.map(|g| GpsMeasurement { fix_type: 2, ..g });
            }
            let l = m.update(&mut s);
            // The last 3D fix at k 275: lost 1 s after.
            assert_eq!(l.gps, k >= 526, "k {k}");
        }
    }
}
