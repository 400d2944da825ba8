//! The translation estimator against the sensors it fuses: GPS fusion, its accuracy weights,
//! the barometer and its offset from the GPS's height.

use super::*;
use crate::math::geo::LatLonAlt;
use sitl_core::environment::isa;
use sitl_core::sensors::{EarthField, SensorConfig, SensorPreset, SensorSuite, Truth, fields};

/// A receiver's stated accuracy weights its fusion: one 4× less sure of its position
/// (2 m against the 0.5 m floor) pulls a 10 m offset in half as fast (τ × √4), and one at
/// or under the floor, or saying nothing of its speed, exactly as the filter's own τ.
#[test]
fn a_gps_less_sure_of_itself_is_fused_more_slowly() {
    assert_eq!(stretch(Some(0.3), 0.5), 1.0);
    assert_eq!(stretch(None, 0.3), 1.0);
    assert_eq!(stretch(Some(f64::NAN), 0.5), 1.0);
    assert!((stretch(Some(2.0), 0.5) - 2.0).abs() < 1e-12);
    let pull = |h_acc_m: f64| {
        let mut est = TranslationEstimator::new(TranslationParams::default());
        let origin = LatLonAlt::default();
        let gps = |north_m: f64| GpsMeasurement {
            fix_type: 3,
            position: LocalFrame::new(origin).to_geodetic(&Vector3::new(north_m, 0.0, 0.0)),
            vel_ned_m_s: Vector3::zeros(),
            h_acc_m,
            satellites: 12,
            details: GpsDetails::default(),
        };
        est.fuse_gps(0, &gps(0.0));
        for k in 1..=10u64 {
            est.predict(
                k * 100_000,
                &Vector3::new(0.0, 0.0, -crate::GRAVITY_M_S2),
                &UnitQuaternion::identity(),
                0.1,
            );
            est.fuse_gps(k * 100_000, &gps(10.0));
        }
        est.estimate().pos_ned_m.x
    };
    let (sure, unsure) = (pull(0.5), pull(2.0));
    assert!(sure > 1.5 * unsure && unsure > 0.0, "{sure} {unsure}");
}

/// A 20 m circle at 5 m/s with a 3 m altitude swing, level flight, typical sensors.
#[test]
fn tracks_a_circle_with_typical_sensors_and_flags_gps_loss() {
    let dt = 0.004;
    let home = LatLonAlt::default();
    let mut sensors = SensorSuite::new(
        SensorConfig::preset(SensorPreset::Typical),
        EarthField::default(),
        home,
        Vector3::zeros(),
        4,
    );
    let mut est = TranslationEstimator::new(TranslationParams::default());
    let (r, w) = (20.0, 0.25); // m, rad/s: 5 m/s
    let truth_at = |t: f64| {
        let p = Vector3::new(
            r * (w * t).sin(),
            r * (1.0 - (w * t).cos()),
            -10.0 - 3.0 * (0.2 * t).sin(),
        );
        let v = Vector3::new(
            r * w * (w * t).cos(),
            r * w * (w * t).sin(),
            -0.6 * (0.2 * t).cos(),
        );
        let a = Vector3::new(
            -r * w * w * (w * t).sin(),
            r * w * w * (w * t).cos(),
            0.12 * (0.2 * t).sin(),
        );
        (p, v, a)
    };
    let speeds = [520.0; 4];
    let max = [950.0; 4];
    let (mut sum_p, mut sum_v, mut sum_z, mut n) = (0.0, 0.0, 0.0, 0);
    let (mut sum_gps, mut n_gps) = (0.0, 0);
    let q = UnitQuaternion::identity();
    let mut gps_lost_at = None;
    for k in 1..=(90.0 / dt) as usize {
        let t = k as f64 * dt;
        let (p, v, a) = truth_at(t);
        let t_usec = (t * 1e6).round() as u64;
        let truth = Truth {
            time_usec: t_usec,
            pos_ned_m: p,
            vel_ned_m_s: v,
            accel_ned_m_s2: a,
            q_ned_from_frd: q,
            rate_frd_rad_s: Vector3::zeros(),
            ang_accel_frd_rad_s2: Vector3::zeros(),
            air: isa(home.alt_m - p.z),
            rotor_speed_rad_s: &speeds,
            rotor_max_speed_rad_s: &max,
        };
        if t > 80.0 && gps_lost_at.is_none() {
            sensors.set_health(
                sitl_core::sensors::SensorKind::Gps,
                sitl_core::sensors::SensorHealth::Off,
            );
            gps_lost_at = Some(t);
        }
        let f = sensors.sample(&truth).clone();
        est.predict(t_usec, &f.accel_frd_m_s2, &q, dt);
        if let Some(g) = f.gps {
            if (20.0..80.0).contains(&t) {
                // The receiver's own error against the truth of the solution's time.
                let then = truth_at(g.time_usec as f64 * 1e-6).0;
                sum_gps += (home.ned_to(&g.position) - then).xy().norm_squared();
                n_gps += 1;
            }
            est.fuse_gps(
                t_usec,
                &GpsMeasurement {
                    fix_type: g.fix_type,
                    position: g.position,
                    vel_ned_m_s: g.vel_ned_m_s,
                    h_acc_m: g.h_acc_m,
                    satellites: g.satellites,
                    details: Default::default(),
                },
            );
        }
        if f.fields_updated & fields::PRESSURE_ALT != 0 {
            est.fuse_baro(t_usec, f.pressure_alt_m);
        }
        let e = est.estimate();
        if (20.0..80.0).contains(&t) {
            // The origin is where the first fix was: compare displacements from it.
            let origin = e.origin.expect("origin set");
            let offset = home.ned_to(&origin);
            let err = e.pos_ned_m + Vector3::new(offset.x, offset.y, 0.0) - p;
            sum_p += err.xy().norm_squared();
            sum_z += (e.pos_ned_m.z - (p.z - truth_at(0.0).0.z)).powi(2);
            sum_v += (e.vel_ned_m_s - v).norm_squared();
            n += 1;
            assert!(e.horizontal_valid && e.vertical_valid);
        }
    }
    let (rp, rv, rz) = (
        (sum_p / n as f64).sqrt(),
        (sum_v / n as f64).sqrt(),
        (sum_z / n as f64).sqrt(),
    );
    let gps_rms = (sum_gps / n_gps as f64).sqrt();
    println!(
        "circle at 5 m/s: horizontal RMS {rp:.3} m (the GPS itself {gps_rms:.3} m), altitude RMS {rz:.3} m, velocity RMS {rv:.3} m/s; accel bias {:?}",
        est.status().accel_bias
    );
    // The GPS error is correlated over a minute: no filter removes it; it must not add to it.
    assert!(rp < 1.1 * gps_rms + 0.05, "{rp} vs GPS {gps_rms}");
    assert!(rz < 0.5 && rv < 0.2);
    assert!(
        !est.estimate().horizontal_valid,
        "10 s without GPS must invalidate the horizontal estimate"
    );
    assert!(est.estimate().vertical_valid);
}

#[test]
fn refuses_bad_fixes() {
    let mut est = TranslationEstimator::new(TranslationParams::default());
    let good = GpsMeasurement {
        fix_type: 3,
        position: LatLonAlt {
            lat_deg: 47.0,
            lon_deg: 8.0,
            alt_m: 500.0,
        },
        vel_ned_m_s: Vector3::zeros(),
        h_acc_m: 0.5,
        satellites: 10,
        details: Default::default(),
    };
    est.fuse_gps(
        0,
        &GpsMeasurement {
            fix_type: 1,
            ..good
        },
    );
    est.fuse_gps(
        0,
        &GpsMeasurement {
            h_acc_m: 50.0,
            satellites: 10,
            details: Default::default(),
            ..good
        },
    );
    est.fuse_gps(
        0,
        &GpsMeasurement {
            position: LatLonAlt {
                lat_deg: f64::NAN,
                ..good.position
            },
            ..good
        },
    );
    assert_eq!(est.status().gps_rejected, 3);
    assert!(est.estimate().origin.is_none());
    est.fuse_gps(1000, &good);
    assert_eq!(est.estimate().origin, Some(good.position));
}

/// A front passing over a hovering vehicle: the pressure falls by 1 hPa an hour, which the
/// barometer reads as a climb of 8 m an hour; the GPS's height wanders by 0.6 m over a
/// minute. With the barometer's offset learned from the GPS's height the estimate stays
/// within 1 m of the truth in the second hour (0.88 m: the GPS's own wander, averaged over
/// `EST_HGT_GPS_TAU`, is the floor: 1.04 m at 200 s, 0.76 m at 800 s); on the barometer
/// alone it goes with the front, 16 m.
#[test]
fn a_front_passing_is_taken_off_the_barometer_by_the_gps_height() {
    let worst = |gps_hgt_tau_s: f64| {
        let mut est = TranslationEstimator::new(TranslationParams {
            gps_hgt_tau_s,
            ..TranslationParams::default()
        });
        let mut rng = sitl_core::rng::Rng::stream(7, 1);
        let home = LatLonAlt {
            lat_deg: 47.0,
            lon_deg: 8.0,
            alt_m: 500.0,
        };
        let q = UnitQuaternion::identity();
        let f = Vector3::new(0.0, 0.0, -crate::GRAVITY_M_S2);
        let (mut gps_err, mut worst) = (0.0, 0.0f64);
        let dt = 0.004;
        for k in 1..=(2.0 * 3600.0 / dt) as u64 {
            let t = k as f64 * dt;
            let t_usec = (t * 1e6) as u64;
            est.predict(t_usec, &f, &q, dt);
            if k % 5 == 0 {
                let front_m = 8.0 * t / 3600.0;
                est.fuse_baro(t_usec, home.alt_m + front_m + 0.25 * rng.normal());
            }
            if k % 25 == 0 {
                // Gauss–Markov, σ 0.6 m over 60 s.
                let a = (-0.1f64 / 60.0).exp();
                gps_err = gps_err * a + 0.6 * (1.0 - a * a).sqrt() * rng.normal();
                est.fuse_gps(
                    t_usec,
                    &GpsMeasurement {
                        fix_type: 3,
                        position: LatLonAlt {
                            alt_m: home.alt_m + gps_err,
                            ..home
                        },
                        vel_ned_m_s: Vector3::zeros(),
                        h_acc_m: 0.5,
                        satellites: 14,
                        details: Default::default(),
                    },
                );
            }
            if t > 3600.0 {
                worst = worst.max(est.estimate().pos_ned_m.z.abs());
            }
        }
        worst
    };
    let (with_gps, baro_alone) = (worst(400.0), worst(0.0));
    println!("second hour, largest height error: {with_gps:.2} m (baro alone {baro_alone:.2} m)");
    assert!(with_gps < 1.0, "{with_gps} m");
    assert!(baro_alone > 7.0, "{baro_alone} m");
}
