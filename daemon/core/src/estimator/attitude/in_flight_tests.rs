//! A gap in the samples in flight (`realign.rs`): a hover, two seconds unseen in which the
//! vehicle turns far over under a held thrust, and the samples back with it still turning.
//! Restarted at its last attitude, the estimate said level against a true 60°–100°; now the
//! attitude is flagged unknown from the return and found again within a second, within 5°,
//! heading included.

use super::*;
use crate::math::geo::LatLonAlt;
use crate::params::AttitudeParams;
use sitl_core::sensors::{EarthField, SensorConfig, SensorPreset, SensorSuite, fields};

const DT: f64 = 0.004;
const GAP: (f64, f64) = (10.0, 12.0);

/// What one flight showed after the gap.
struct AfterGap {
    /// The first time (s after the return) the attitude was known again.
    found_s: Option<f64>,
    /// Valid while unknown (never, if right).
    valid_while_unknown: bool,
    /// The largest error from 1 s after the return to the end (deg).
    worst_deg: f64,
    status: AttitudeStatus,
}

/// The flight: at rest disarmed to 4 s, armed hovering to the gap, unseen through it while the
/// body accelerates its turn at `spin` (rad/s², body axes) under a thrust of its weight, then
/// seen again as its rate is stopped within 0.3 s, to `end_s` (the thrust held: by then a
/// controller would have levelled it). A 10 Hz GPS 0.1 s late if `gps`.
fn fly(spin: Vector3<f64>, armed_in_gap: bool, gps: bool, seed: u64, end_s: f64) -> AfterGap {
    let mut sensors = SensorSuite::new(
        SensorConfig::preset(SensorPreset::Typical),
        EarthField::default(),
        LatLonAlt::default(),
        Vector3::zeros(),
        seed,
    );
    let params = AttitudeParams {
        mag_declination_deg: EarthField::default().declination_deg,
        mag_inclination_deg: EarthField::default().inclination_deg,
        ..AttitudeParams::default()
    };
    let mut est = AttitudeEstimator::new(&params);
    let g = Vector3::new(0.0, 0.0, crate::GRAVITY_M_S2);
    let mut q = UnitQuaternion::from_euler_angles(0.0, 0.0, 0.5);
    let mut vel = Vector3::zeros();
    let mut history: Vec<(f64, Vector3<f64>)> = Vec::new();
    let mut out = AfterGap {
        found_s: None,
        valid_while_unknown: false,
        worst_deg: 0.0,
        status: AttitudeStatus::default(),
    };
    let mut last_seen = 0.0;
    for k in 1..=(end_s / DT) as usize {
        let t = k as f64 * DT;
        let armed = t >= 4.0 && (armed_in_gap || t < GAP.0);
        // The turn: accelerating through the gap, stopped within 0.3 s of the return.
        let rate = if t < GAP.0 {
            Vector3::zeros()
        } else if t < GAP.1 {
            spin * (t - GAP.0)
        } else {
            spin * (GAP.1 - GAP.0) * (1.0 - (t - GAP.1) / 0.3).max(0.0)
        };
        q = crate::math::quat::propagate(&q, &rate, DT);
        let a_ned = if armed { q * -g + g } else { Vector3::zeros() };
        vel += a_ned * DT;
        history.push((t, vel));
        let f = super::tests::sample_at(&mut sensors, t, q, rate, a_ned);
        if (GAP.0..GAP.1).contains(&t) {
            continue;
        }
        // A 10 Hz GPS whose solutions are 0.1 s old.
        let gps_vel = (gps && k % 25 == 0 && t > 0.2).then(|| {
            let then = history[history.len() - 1 - (0.1 / DT).round() as usize].1;
            DelayedVelocity {
                vel_ned_m_s: then + Vector3::new(0.03, -0.02, 0.04),
                age_s: 0.1,
            }
        });
        let input = AttitudeInput {
            gyro: f.gyro_frd_rad_s,
            accel: f.accel_frd_m_s2,
            mag: (f.fields_updated & fields::MAG != 0).then_some(f.mag_frd_gauss),
            accel_ned_hint: None,
            // The position estimator's velocity, GPS-corrected (here the truth's).
            vel_ned_hint: armed.then_some(vel),
            gps_vel,
            thrust_fraction: 0.0,
            armed,
        };
        let Some(e) = est.update(&input, t - last_seen) else {
            last_seen = t;
            continue;
        };
        last_seen = t;
        if t < GAP.1 {
            continue;
        }
        let since = t - GAP.1;
        if e.realigning {
            out.valid_while_unknown |= e.valid;
        } else if out.found_s.is_none() {
            out.found_s = Some(since);
        }
        if since >= 1.0 {
            out.worst_deg = out.worst_deg.max(e.q.angle_to(&q).to_degrees());
        }
    }
    out.status = est.status();
    out
}

#[test]
fn a_turn_unseen_in_flight_is_found_again_within_a_second() {
    for (spin, seed) in [
        (Vector3::new(0.6, -0.35, 0.2), 1),
        (Vector3::new(-0.9, 0.2, -0.5), 2),
        (Vector3::new(0.1, 0.8, 0.6), 3),
    ] {
        let r = fly(spin, true, true, seed, GAP.1 + 3.0);
        println!(
            "spin {spin:?}: found after {:?} s, worst from 1 s {:.2}°",
            r.found_s, r.worst_deg
        );
        assert!(r.found_s.is_some_and(|s| s <= 1.0), "{:?}", r.found_s);
        assert!(!r.valid_while_unknown, "flagged invalid until found");
        assert!(r.worst_deg <= 5.0, "{:.2}°", r.worst_deg);
        assert_eq!(r.status.tilt_heading.realigned_in_flight, 1);
    }
}

/// Without a GPS nothing shows the attitude under thrust: the filter goes on from the
/// accelerometer after `REALIGN_GIVE_UP_S` (flagged invalid until then), as it did before.
#[test]
fn without_gps_the_search_gives_up_and_the_accelerometer_goes_on() {
    let give_up = crate::estimator::tilt_heading::REALIGN_GIVE_UP_S;
    let r = fly(Vector3::new(0.3, 0.1, 0.0), true, false, 4, GAP.1 + 6.0);
    assert!(!r.valid_while_unknown);
    let found = r.found_s.unwrap();
    assert!((give_up - 0.1..give_up + 0.1).contains(&found), "{found}");
    assert_eq!(r.status.tilt_heading.realign_abandoned, 1);
    assert_eq!(r.status.tilt_heading.realigned_in_flight, 0);
}

/// Disarmed, a gap is a vehicle on the ground: the steady accelerometer is the tilt, as before.
#[test]
fn a_gap_on_the_ground_is_not_a_search() {
    let r = fly(Vector3::zeros(), false, true, 5, GAP.1 + 1.0);
    assert_eq!(r.found_s, Some(0.0));
    assert_eq!(r.status.tilt_heading.realigned_in_flight, 0);
}
