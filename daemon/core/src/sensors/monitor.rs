//! Which sensors still deliver: silent ones (no fresh reading for a while, once they have been
//! heard) and frozen ones. A sensor is frozen when its reading stays the very same, to the last
//! bit, many times over *while the others show that it should not*: a real sensor's noise never
//! repeats itself, and a noise-free one (a simulator's ideal preset) repeats only while nothing
//! it measures changes, so an exact reading on a still vehicle is not frozen. A lost sensor is
//! taken out of the sample, so the estimators fall back as for a sensor that is off (a frozen
//! barometer would otherwise hold the altitude estimate still while the vehicle climbs), and the
//! failsafe machine hears of it. What the others show is in [`evidence`].

use crate::safety::failsafe::SensorsLost;
use crate::sample::SensorSample;
use evidence::Evidence;
use nalgebra::Vector3;

/// A sensor silent longer than this after its last fresh reading is lost (µs): magnetometer and
/// barometer (50–100 Hz), GPS (5–10 Hz).
const MAG_TIMEOUT_US: u64 = 500_000;
const BARO_TIMEOUT_US: u64 = 500_000;
const GPS_TIMEOUT_US: u64 = 1_000_000;
/// Identical readings in a row that make a sensor frozen (when the others say it should have
/// changed): IMU 0.2 s at 250 Hz, magnetometer 0.25 s at 100 Hz, barometer 0.5 s at 50 Hz,
/// GPS 2 s at 10 Hz.
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
    /// Folds in a fresh reading (as up to six numbers) at `t_usec`; whether it changed.
    fn fresh(&mut self, t_usec: u64, reading: [f64; 6]) -> bool {
        let repeated = self.last_fresh_usec.is_some() && reading == self.last;
        self.repeats = if repeated {
            self.repeats.saturating_add(1)
        } else {
            0
        };
        self.last = reading;
        self.last_fresh_usec = Some(t_usec);
        !repeated
    }

    /// Silent beyond `timeout_usec` (after having been heard).
    fn silent(&self, t_usec: u64, timeout_usec: u64) -> bool {
        self.last_fresh_usec
            .is_some_and(|last| t_usec.saturating_sub(last) > timeout_usec)
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
    evidence: Evidence,
}

impl SensorMonitor {
    /// Nothing heard yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// What is lost as of the last update.
    pub fn lost(&self) -> SensorsLost {
        self.lost
    }

    /// The IMU's last reading repeated the one before while the others say it should have
    /// changed: suspect, not yet lost.
    pub fn imu_repeating(&self) -> bool {
        self.imu.repeats > 0 && self.evidence.imu_should_change()
    }

    /// Folds in one sample and takes the lost sensors' readings out of it; what is lost now.
    pub fn update(&mut self, s: &mut SensorSample) -> SensorsLost {
        let t = s.t_usec;
        let ev = &mut self.evidence;
        // The slow sensors first: the IMU's reading is judged against them.
        if let Some(m) = s.mag {
            let changed = self.mag.fresh(t, six(&m));
            ev.mag(m, changed);
        }
        if let Some(b) = s.baro_alt_m {
            let changed = self.baro.fresh(t, [b, 0.0, 0.0, 0.0, 0.0, 0.0]);
            ev.baro(b, changed);
        }
        // A solution without a 3D fix is no GPS: only 3D fixes refresh the watch.
        if let Some(gps) = s.gps.as_ref().filter(|g| g.fix_type >= 3) {
            let (p, v) = (&gps.position, gps.vel_ned_m_s);
            let changed = self
                .gps
                .fresh(t, [p.lat_deg, p.lon_deg, p.alt_m, v.x, v.y, v.z]);
            ev.gps(p.alt_m, v, changed);
        }
        let (g, a) = (s.gyro, s.accel);
        let changed = self.imu.fresh(t, [g.x, g.y, g.z, a.x, a.y, a.z]);
        let gyro_believed = !((self.imu.repeats > 0 && ev.imu_should_change()) || self.lost.imu);
        ev.imu(t, g, changed, gyro_believed);
        self.lost = SensorsLost {
            imu: self.imu.repeats >= IMU_FROZEN && ev.imu_should_change(),
            mag: self.mag.silent(t, MAG_TIMEOUT_US)
                || (self.mag.repeats >= MAG_FROZEN && ev.mag_should_change()),
            baro: self.baro.silent(t, BARO_TIMEOUT_US)
                || (self.baro.repeats >= BARO_FROZEN && ev.baro_should_change()),
            gps: self.gps.silent(t, GPS_TIMEOUT_US)
                || (self.gps.repeats >= GPS_FROZEN && ev.gps_should_change()),
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

mod evidence;

#[cfg(test)]
mod tests;
