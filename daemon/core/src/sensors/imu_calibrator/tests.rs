//! The calibrators on made-up readings: what makes them restart, fail or refuse.

use super::*;
use crate::GRAVITY_M_S2 as G;

const DT: f64 = 0.004;

/// Holds the readings of `side` for 12 s (long enough to be measured, and to be taken for the
/// same side again if the calibrator would), then a second of turning; returns the end time.
fn hold_on(c: &mut ImuCalibrator, t0: f64, side: Side, a: Vector3<f64>) -> f64 {
    let t = feed(c, t0, 12.0, |_| (a, Vector3::zeros()));
    if c.collecting() {
        assert!(c.status().sides_done & side.bit() != 0, "{side:?} measured");
    }
    let turning = |t: f64| {
        (
            Vector3::new(3.0 * (9.0 * t).sin(), 5.0, -5.0),
            Vector3::zeros(),
        )
    };
    feed(c, t, 1.0, turning)
}

/// Feeds the readings `f` gives at each time from `t0` for `seconds`; returns the end time.
fn feed(
    c: &mut ImuCalibrator,
    t0: f64,
    seconds: f64,
    f: impl Fn(f64) -> (Vector3<f64>, Vector3<f64>),
) -> f64 {
    let mut t = t0;
    while t < t0 + seconds && c.collecting() {
        let (a, g) = f(t);
        c.step(t, &a, &g);
        t += DT;
    }
    t
}

fn level() -> Vector3<f64> {
    Vector3::new(0.0, 0.0, -G)
}

#[test]
fn the_gyro_offset_is_the_rate_at_rest_and_a_turning_vehicle_fails_it() {
    let bias = Vector3::new(0.01, -0.02, 0.005);
    let mut c = ImuCalibrator::new(ImuCalKind::Gyro, 1, &ImuCalParams::default());
    // A little noise that the median does not take for motion.
    let noise =
        |t: f64| Vector3::new((t * 977.0).sin(), (t * 631.0).cos(), (t * 313.0).sin()) * 0.002;
    feed(&mut c, 0.0, 5.0, |t| (level(), bias + noise(t)));
    let s = c.status();
    let ImuCalState::Succeeded(ImuCalResult::Gyro { offset }) = s.state else {
        panic!("{s:?}")
    };
    assert!((offset - bias).norm() < 2e-4, "{offset}");
    assert_eq!((s.percent, s.restarts), (100, 0));
    assert_eq!(c.pose_request(), PoseRequest::None);

    // Turned by hand at 30°/s, back and forth: restarted, then refused.
    let mut c = ImuCalibrator::new(ImuCalKind::Gyro, 2, &ImuCalParams::default());
    feed(&mut c, 0.0, 60.0, |t| {
        (level(), Vector3::new(0.5 * (2.0 * t).sin(), 0.0, 0.0))
    });
    let s = c.status();
    assert_eq!(
        s.state,
        ImuCalState::Failed(ImuCalFailure::Motion(gyro::MAX_RESTARTS + 1))
    );
}

/// Specific force with `side` down, plus an offset.
fn on(side: Side, offset: Vector3<f64>) -> Vector3<f64> {
    let (axis, sign) = side.axis();
    let mut a = offset;
    a[axis] += sign * G;
    a
}

#[test]
fn six_sides_in_any_order_give_offsets_and_a_side_twice_is_said_not_measured() {
    let offset = Vector3::new(0.3, -0.2, 0.4);
    let mut c = ImuCalibrator::new(ImuCalKind::Accel, 1, &ImuCalParams::default());
    assert_eq!(c.pose_request(), PoseRequest::Place(Side::Back));
    let mut t = 0.0;
    let order = [
        Side::Down,
        Side::Up,
        Side::Down,
        Side::Left,
        Side::Back,
        Side::Right,
        Side::Front,
    ];
    for (i, side) in order.into_iter().enumerate() {
        t = hold_on(&mut c, t, side, on(side, offset));
        let s = c.status();
        if i == 2 {
            assert_eq!(
                s.repeated,
                (1, Some(Side::Down)),
                "down again: said, not measured"
            );
        }
    }
    let s = c.status();
    let ImuCalState::Succeeded(ImuCalResult::Accel { offset: o, scale }) = s.state else {
        panic!("{s:?}")
    };
    assert!((o - offset).norm() < 1e-9, "{o}");
    assert!((scale - Vector3::repeat(1.0)).norm() < 1e-9);
    assert_eq!((s.sides_done, s.percent), (0b11_1111, 100));
}

#[test]
fn an_accelerometer_calibration_left_alone_times_out_and_a_bad_one_is_refused() {
    let mut c = ImuCalibrator::new(ImuCalKind::Accel, 1, &ImuCalParams::default());
    // Only upright, for ever: one side, then nothing new.
    feed(&mut c, 0.0, 100.0, |_| (level(), Vector3::zeros()));
    assert_eq!(
        c.status().state,
        ImuCalState::Failed(ImuCalFailure::TimedOut {
            waited_s: accel::SIDE_TIMEOUT_S,
            for_what: "a pending side held still",
        })
    );
    // An accelerometer reading 30 % high on z: beyond the scales accepted.
    let mut c = ImuCalibrator::new(ImuCalKind::Accel, 2, &ImuCalParams::default());
    let mut t = 0.0;
    for side in Side::ALL {
        let a = on(side, Vector3::zeros()).component_mul(&Vector3::new(1.0, 1.0, 1.3));
        t = hold_on(&mut c, t, side, a);
    }
    assert_eq!(
        c.status().state,
        ImuCalState::Failed(ImuCalFailure::OutOfRange("accelerometer scale"))
    );
}

#[test]
fn the_level_horizon_is_the_tilt_of_the_calibrated_accelerometer() {
    let params = ImuCalParams {
        accel_offset_x: 0.2,
        accel_scale_z: 0.98,
        ..ImuCalParams::default()
    };
    let (roll, pitch) = (2f64.to_radians(), -1f64.to_radians());
    let board = nalgebra::UnitQuaternion::from_euler_angles(roll, pitch, 0.0);
    let truth = board.inverse() * level();
    // What the raw accelerometer reads: undone by the calibration.
    let raw = Vector3::new(truth.x + 0.2, truth.y, truth.z / 0.98);
    let mut c = ImuCalibrator::new(ImuCalKind::Level, 1, &params);
    assert_eq!(c.pose_request(), PoseRequest::Place(Side::Down));
    feed(&mut c, 0.0, 10.0, |_| (raw, Vector3::zeros()));
    let ImuCalState::Succeeded(ImuCalResult::Level {
        roll_deg,
        pitch_deg,
    }) = c.status().state
    else {
        panic!("{:?}", c.status())
    };
    assert!((roll_deg - 2.0).abs() < 1e-9 && (pitch_deg + 1.0).abs() < 1e-9);

    // On its side: not level, refused.
    let mut c = ImuCalibrator::new(ImuCalKind::Level, 2, &ImuCalParams::default());
    feed(&mut c, 0.0, 10.0, |_| {
        (on(Side::Left, Vector3::zeros()), Vector3::zeros())
    });
    assert!(matches!(
        c.status().state,
        ImuCalState::Failed(ImuCalFailure::OutOfRange(_))
    ));
    // Cancelled: ends at once, asks nothing more.
    let mut c = ImuCalibrator::new(ImuCalKind::Level, 3, &ImuCalParams::default());
    c.cancel();
    assert_eq!(c.status().state, ImuCalState::Cancelled);
    assert_eq!(c.pose_request(), PoseRequest::None);
}
