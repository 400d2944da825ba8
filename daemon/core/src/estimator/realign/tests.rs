//! The in-flight alignment against frames it did not make: a vehicle turned any way, under
//! thrust and accelerating, seen through a gyro frame off by an unknown rotation.

use super::*;
use nalgebra::Matrix3;

const DECLINATION_RAD: f64 = 0.05;
const DIP_RAD: f64 = 1.1;

/// The field in NED: the declination's meridian, the dip down.
fn field_ned() -> Vector3<f64> {
    Vector3::new(
        DIP_RAD.cos() * DECLINATION_RAD.cos(),
        DIP_RAD.cos() * DECLINATION_RAD.sin(),
        DIP_RAD.sin(),
    )
}

/// A window in which the vehicle, its gyro frame off by `truth` (NED ← gyro frame), accelerated
/// at `accel_ned`, and the field seen in that frame `samples` times.
fn seen(
    truth: UnitQuaternion<f64>,
    accel_ned: Vector3<f64>,
    duration_s: f64,
) -> (InFlightAlignment, GpsWindow) {
    let force_ned = accel_ned - Vector3::new(0.0, 0.0, GRAVITY_M_S2);
    let window = GpsWindow {
        force: truth.inverse() * force_ned,
        rotation: Matrix3::identity(),
        accel: accel_ned,
        duration_s,
    };
    let mut a = InFlightAlignment::default();
    for _ in 0..10 {
        a.field_sum += (truth.inverse() * field_ned()).normalize();
        a.field_samples += 1;
    }
    (a, window)
}

fn turns() -> Vec<UnitQuaternion<f64>> {
    let mut q = Vec::new();
    for roll in [-170.0f64, -100.0, -30.0, 0.0, 45.0, 120.0] {
        for pitch in [-80.0f64, -20.0, 0.0, 35.0, 70.0] {
            for yaw in [-150.0f64, -60.0, 0.0, 90.0, 175.0] {
                q.push(UnitQuaternion::from_euler_angles(
                    roll.to_radians(),
                    pitch.to_radians(),
                    yaw.to_radians(),
                ));
            }
        }
    }
    q
}

#[test]
fn any_attitude_is_found_from_the_gps_window_and_the_field() {
    // Hovering, falling with little thrust, braking, swinging sideways.
    let accels = [
        Vector3::new(0.0, 0.0, 0.0),
        Vector3::new(1.0, -2.0, 6.5),
        Vector3::new(-4.0, 3.0, -5.0),
        Vector3::new(8.0, 0.0, 0.0),
    ];
    for truth in turns() {
        for a in accels {
            let (alignment, window) = seen(truth, a, 0.5);
            let found = alignment
                .solve(&window, DECLINATION_RAD, DIP_RAD)
                .unwrap_or_else(|| panic!("{truth:?} at {a:?}: not found"));
            let err = found.angle_to(&truth).to_degrees();
            assert!(err < 1e-6, "{truth:?} at {a:?}: {err}° off");
        }
    }
}

/// The dip only chooses between the two turns that put the field in the meridian: one a few
/// degrees off (a site far from the parameter's) finds the same attitude.
#[test]
fn a_dip_off_by_ten_degrees_finds_the_same_attitude() {
    for truth in turns() {
        let (alignment, window) = seen(truth, Vector3::new(2.0, 1.0, -1.0), 0.5);
        let found = alignment
            .solve(&window, DECLINATION_RAD, DIP_RAD - 10f64.to_radians())
            .unwrap();
        assert!(found.angle_to(&truth) < 1e-6);
    }
}

#[test]
fn what_cannot_show_the_attitude_is_refused() {
    let truth = UnitQuaternion::from_euler_angles(1.0, -0.4, 2.0);
    // A free fall: no force to see.
    let (a, w) = seen(truth, Vector3::new(0.0, 0.0, GRAVITY_M_S2 * 0.9), 0.5);
    assert!(a.solve(&w, DECLINATION_RAD, DIP_RAD).is_none());
    // The force's length not the GPS's (a glitch, a gap in the window).
    let (a, mut w) = seen(truth, Vector3::zeros(), 0.5);
    w.force *= 1.3;
    assert!(a.solve(&w, DECLINATION_RAD, DIP_RAD).is_none());
    // Too short a window.
    let (a, w) = seen(truth, Vector3::zeros(), 0.2);
    assert!(a.solve(&w, DECLINATION_RAD, DIP_RAD).is_none());
    // No field.
    let (_, w) = seen(truth, Vector3::zeros(), 0.5);
    assert!(
        InFlightAlignment::default()
            .solve(&w, DECLINATION_RAD, DIP_RAD)
            .is_none()
    );
    // The field along the force: no turn about it shows.
    let (mut a, w) = seen(UnitQuaternion::identity(), Vector3::zeros(), 0.5);
    a.field_sum = Vector3::new(0.0, 0.0, -1.0) * 10.0;
    assert!(a.solve(&w, DECLINATION_RAD, DIP_RAD).is_none());
}
