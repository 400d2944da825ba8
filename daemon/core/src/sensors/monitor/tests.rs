//! The sensor monitor on noisy sensors (a real board) and on noise-free ones (a simulator's
//! ideal preset), still and moving.
use super::*;
use crate::estimator::translation::GpsMeasurement;
use crate::math::geo::LatLonAlt;
use nalgebra::UnitQuaternion;

/// Deterministic white noise in [−1, 1] for sample `k`, channel `c` (splitmix64).
fn noise(k: u64, c: u64) -> f64 {
    let mut z = k.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ c.wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^= z >> 31;
    (z >> 11) as f64 / (1u64 << 52) as f64 - 1.0
}

/// Sample `k` at 250 Hz of a vehicle turning at `yaw_rate` (rad/s) and climbing at `climb`
/// (m/s), with white noise of `n` (gyro n rad/s, field n gauss, height 100 n m, velocity 10 n
/// m/s); magnetometer every 2nd sample, barometer every 5th, GPS every 25th.
fn flight(k: u64, yaw_rate: f64, climb: f64, n: f64) -> SensorSample {
    let t = k as f64 * 0.004;
    let w = |c| n * noise(k, c);
    let field = UnitQuaternion::from_scaled_axis(Vector3::z() * yaw_rate * t)
        .inverse_transform_vector(&Vector3::new(0.2, 0.0, 0.4));
    SensorSample {
        t_usec: k * 4000,
        gyro: Vector3::new(w(0), w(1), yaw_rate + w(2)),
        accel: Vector3::new(w(3), w(4), -9.8 + w(5)),
        mag: k
            .is_multiple_of(2)
            .then_some(field + Vector3::new(w(6), w(7), w(8))),
        baro_alt_m: k
            .is_multiple_of(5)
            .then_some(488.0 + climb * t + 100.0 * w(9)),
        gps: k.is_multiple_of(25).then_some(GpsMeasurement {
            fix_type: 3,
            position: LatLonAlt {
                lat_deg: 47.0 + w(10) * 1e-3,
                lon_deg: 8.0,
                alt_m: 488.0 + climb * t,
            },
            vel_ned_m_s: Vector3::new(10.0 * w(11), 0.0, -climb),
            h_acc_m: 1.0,
            satellites: 10,
            details: Default::default(),
        }),
        battery_v: Some(16.0),
        esc_current_a: None,
        rotor_speed_rad_s: None,
    }
}

/// A board's noise, still.
fn noisy(k: u64) -> SensorSample {
    flight(k, 0.0, 0.0, 2e-3)
}

#[test]
fn healthy_sensors_are_not_lost_and_pass_unchanged() {
    for sample in [
        noisy as fn(u64) -> SensorSample,
        |k| flight(k, 0.0, 0.0, 0.0),
        |k| flight(k, 0.5, 1.0, 0.0),
    ] {
        let mut m = SensorMonitor::new();
        for k in 0..2500 {
            let mut s = sample(k);
            let before = s;
            assert_eq!(m.update(&mut s), SensorsLost::default(), "k {k}");
            assert!(!m.imu_repeating(), "k {k}");
            assert_eq!(s, before);
        }
    }
}

#[test]
fn silent_sensors_are_lost_after_their_timeout_and_come_back() {
    for sample in [noisy as fn(u64) -> SensorSample, |k| {
        flight(k, 0.0, 0.0, 0.0)
    }] {
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
}

#[test]
fn frozen_sensors_of_a_noisy_board_are_lost_by_their_repeats_alone() {
    let mut m = SensorMonitor::new();
    let stuck = noisy(100);
    for k in 0..400 {
        let mut s = noisy(k);
        if k >= 200 {
            s.mag = s.mag.and(stuck.mag);
            s.baro_alt_m = s.baro_alt_m.map(|_| 500.0);
            (s.gyro, s.accel) = (stuck.gyro, stuck.accel);
        }
        let l = m.update(&mut s);
        // IMU after 0.2 s, magnetometer after 0.25 s, barometer after 0.5 s: the others jitter.
        assert_eq!((l.imu, l.mag), (k >= 250, k >= 250), "k {k}");
        assert_eq!(m.imu_repeating(), k > 200, "k {k}");
        assert_eq!(l.baro, k >= 325, "k {k}");
        assert!(!l.gps);
        if k >= 325 {
            assert!(s.mag.is_none() && s.baro_alt_m.is_none());
        }
    }
}

/// A noise-free still vehicle (an ideal simulator at rest) repeats every reading for ever.
#[test]
fn exact_readings_of_a_still_vehicle_are_not_frozen() {
    let mut m = SensorMonitor::new();
    let still = flight(100, 0.0, 0.0, 0.0);
    for k in 0..2500 {
        let mut s = SensorSample {
            t_usec: k * 4000,
            ..flight(k, 0.0, 0.0, 0.0)
        };
        (s.gyro, s.accel) = (still.gyro, still.accel);
        assert_eq!(m.update(&mut s), SensorsLost::default(), "k {k}");
        assert!(!m.imu_repeating());
    }
}

/// A steady turn repeats an exact IMU's reading while the field turns as its gyro says: not
/// frozen. The same IMU stuck at another rate is.
#[test]
fn an_exact_imu_in_a_steady_turn_is_frozen_only_when_the_field_disagrees() {
    for (stuck_rate, frozen_from) in [(0.5, None), (0.3, Some(200..=260))] {
        let mut m = SensorMonitor::new();
        let mut found = None;
        for k in 0..600 {
            let mut s = flight(k, 0.5, 1.0, 0.0);
            if k >= 150 {
                s.gyro = Vector3::new(0.0, 0.0, stuck_rate);
            }
            if m.update(&mut s).imu && found.is_none() {
                found = Some(k);
            }
        }
        // 0.2 rad/s apart, 1° apart after 87 ms: found at the 50th repeat (k 200).
        match frozen_from {
            None => assert_eq!(found, None),
            Some(window) => assert!(found.is_some_and(|k| window.contains(&k)), "{found:?}"),
        }
    }
}

#[test]
fn an_exact_magnetometer_is_frozen_only_when_the_gyro_turns_the_body() {
    // Flying straight and climbing: the field does not move, the others do.
    let mut m = SensorMonitor::new();
    for k in 0..1500 {
        assert!(!m.update(&mut flight(k, 0.0, 2.0, 0.0)).mag, "k {k}");
    }
    // Turning at 0.5 rad/s with the field stuck: 1° across it after 78 ms, 25 repeats at 0.2 s.
    // (The IMU's reading changes, as in any real turn: a roll rate creeps up, too small to turn
    // the field. An exact IMU in a steady turn beside an exact, stuck field would leave the
    // two alone to disagree, and the IMU is the one suspected.)
    let mut m = SensorMonitor::new();
    let stuck = flight(0, 0.5, 0.0, 0.0).mag;
    let lost_at = (0..600).find(|&k| {
        let mut s = flight(k, 0.5, 0.0, 0.0);
        s.gyro.x = k as f64 * 1e-9;
        if k >= 100 {
            s.mag = s.mag.and(stuck);
        }
        m.update(&mut s).mag
    });
    assert_eq!(lost_at, Some(150));
}

#[test]
fn an_exact_barometer_or_gps_is_frozen_only_when_the_height_or_speed_says_so() {
    // Barometer stuck while the GPS climbs 2 m/s: its altitude 1 m away 0.5 s after.
    let mut m = SensorMonitor::new();
    let lost_at = (0..1000).find(|&k| {
        let mut s = flight(k, 0.0, 2.0, 0.0);
        if k >= 100 {
            s.baro_alt_m = s.baro_alt_m.map(|_| 489.0);
        }
        m.update(&mut s).baro
    });
    // 25 repeats by k 225; the GPS at k 225 is 1.0 m above the barometer's last change (k 95).
    assert_eq!(lost_at, Some(225));
    // GPS stuck with its climb of 2 m/s: a moving receiver whose position stays: 20 repeats.
    let mut m = SensorMonitor::new();
    let stuck = flight(100, 0.0, 2.0, 0.0).gps;
    let lost_at = (0..1500).find(|&k| {
        let mut s = flight(k, 0.0, 2.0, 0.0);
        if k >= 100 {
            s.gps = s.gps.and(stuck);
        }
        m.update(&mut s).gps
    });
    assert_eq!(lost_at, Some(600));
}

#[test]
fn gps_without_a_3d_fix_is_lost() {
    let mut m = SensorMonitor::new();
    for k in 0..600 {
        let mut s = noisy(k);
        if k >= 300 {
            s.gps = s.gps.map(|g| GpsMeasurement { fix_type: 2, ..g });
        }
        let l = m.update(&mut s);
        // The last 3D fix at k 275: lost 1 s after.
        assert_eq!(l.gps, k >= 526, "k {k}");
    }
}
