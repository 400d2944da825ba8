#![allow(clippy::unwrap_used)]
use super::*;
use crate::control::AttitudeTarget;
use nalgebra::UnitQuaternion;
use std::f64::consts::FRAC_PI_2;

fn input(t: f64, down: f64, vd: f64) -> CommanderInput {
    CommanderInput {
        t_s: t,
        ready: true,
        horizontal_valid: true,
        pos_ned_m: Vector3::new(0.0, 0.0, down),
        vel_ned_m_s: Vector3::new(0.0, 0.0, vd),
        yaw_rad: 0.0,
        hover_thrust: 0.5,
        thrust: 0.5,
        imu_still: false,
        origin: None,
        health: Health::default(),
    }
}

/// Stick positions: forward, right, throttle, yaw.
fn sticks(forward: f64, right: f64, throttle: f64, yaw: f64) -> Sticks {
    Sticks {
        forward,
        right,
        throttle,
        yaw,
    }
}

/// One update of a commander in a position mode.
fn step(c: &mut Commander, i: &CommanderInput) -> (PositionSetpoint, bool) {
    match c.update(i) {
        (Setpoint::Position(p), armed) => (p, armed),
        (s, _) => panic!("a position set-point expected, not {s:?}"),
    }
}

fn params() -> CommanderParams {
    CommanderParams {
        takeoff_alt_m: 5.0,
        final_speed_m_s: 0.7,
        final_height_m: 0.0,
        ..CommanderParams::default()
    }
}

/// A commander that has seen the estimate at rest, ready.
fn ready() -> Commander {
    let mut c = Commander::new(params());
    step(&mut c, &input(0.0, 0.0, 0.0));
    c
}

/// Take-off, hold, land as a table: (time, estimated down, vertical speed, command) →
/// (mode, landed state, armed) after the update.
#[test]
fn takeoff_hold_and_land_follow_the_flight() {
    use FlightMode::{Land, Loiter, Takeoff};
    use LandedState::{InAir, Landing, OnGround, Takeoff as Climbing};
    enum Do {
        Nothing,
        Takeoff,
        Arm,
        Land,
    }
    let mut c = ready();
    let table = [
        (0.1, 0.0, 0.0, Do::Takeoff, Takeoff, OnGround, false),
        (0.2, 0.0, 0.0, Do::Arm, Takeoff, OnGround, true),
        (0.7, 0.0, 0.0, Do::Nothing, Takeoff, OnGround, true), // spooling up
        (1.3, 0.0, 0.0, Do::Nothing, Takeoff, Climbing, true),
        (3.0, -2.0, -1.5, Do::Nothing, Takeoff, Climbing, true),
        (6.0, -4.6, -0.5, Do::Nothing, Takeoff, Climbing, true), // set-point there, vehicle not
        (6.5, -4.9, -0.1, Do::Nothing, Loiter, InAir, true),
        (9.0, -5.0, 0.0, Do::Nothing, Loiter, InAir, true),
        (9.1, -5.0, 0.0, Do::Land, Land, Landing, true),
        (14.0, -1.5, 0.7, Do::Nothing, Land, Landing, true), // descending at 0.7 m/s
        (16.6, 0.0, 0.0, Do::Nothing, Land, Landing, true),  // on the ground, set-point not below
        (17.1, 0.0, 0.0, Do::Nothing, Land, Landing, true),  // set-point 0.6 m below: still for...
        (17.3, 0.0, 0.0, Do::Nothing, Land, Landing, true),  // ground contact
        (17.6, 0.0, 0.0, Do::Nothing, Land, Landing, true),  // maybe landed (0.3 s)
        (18.2, 0.0, 0.0, Do::Nothing, Loiter, OnGround, false), // ...a second: disarmed
    ];
    for (t, d, vd, cmd, mode, landed, armed) in table {
        match cmd {
            Do::Nothing => Ok(()),
            Do::Takeoff => c.takeoff(None),
            Do::Arm => c.arm(false),
            Do::Land => c.set_mode(FlightMode::Land),
        }
        .unwrap();
        let (_, out_armed) = step(&mut c, &input(t, d, vd));
        assert_eq!(
            (c.mode(), c.landed(), c.armed(), out_armed),
            (mode, landed, armed, armed),
            "at t = {t}"
        );
        // PX4's land detector stages on the ground, from the first still update at 17.1 s.
        let contact = match t {
            17.1 | 17.3 => GroundContact::Contact,
            17.6 => GroundContact::MaybeLanded,
            _ => GroundContact::None,
        };
        assert_eq!(c.status().ground_contact, contact, "at t = {t}");
    }
}

#[test]
fn commands_are_refused_with_a_reason_and_repeats_are_harmless() {
    let mut c = Commander::new(params());
    assert!(
        c.arm(false)
            .unwrap_err()
            .to_string()
            .contains("no sensor data")
    );
    step(
        &mut c,
        &CommanderInput {
            ready: false,
            ..input(0.0, 0.0, 0.0)
        },
    );
    assert!(
        c.arm(false)
            .unwrap_err()
            .to_string()
            .contains("estimator not ready")
    );
    assert!(
        c.set_mode(FlightMode::Rtl)
            .unwrap_err()
            .to_string()
            .contains("no home")
    );
    assert!(
        c.set_mode(FlightMode::Mission)
            .unwrap_err()
            .to_string()
            .contains("no mission uploaded")
    );
    assert!(c.set_mode(FlightMode::Descend).is_err());
    assert!(c.takeoff(Some(f64::NAN)).is_err() && c.takeoff(Some(-3.0)).is_err());
    step(&mut c, &input(0.1, 0.0, 0.0));
    c.set_mode(FlightMode::Land).unwrap();
    assert!(c.arm(false).unwrap_err().to_string().contains("LAND"));
    c.set_mode(FlightMode::Loiter).unwrap();
    // Arming twice, taking off twice: the same as once (a retransmitted command).
    c.arm(false).unwrap();
    assert!(c.take_changed());
    c.arm(false).unwrap();
    assert!(!c.take_changed(), "a repeated arm changes nothing");
    c.takeoff(Some(3.0)).unwrap();
    c.takeoff(Some(3.0)).unwrap();
    assert_eq!(c.mode(), FlightMode::Takeoff);
    // Airborne: disarm refused unless forced.
    for t in [0.2, 1.5, 2.0] {
        step(&mut c, &input(t, -0.5, -1.0));
    }
    assert_eq!(c.landed(), LandedState::Takeoff);
    assert!(
        c.disarm(false)
            .unwrap_err()
            .to_string()
            .contains("in the air")
    );
    assert!(c.armed());
    c.disarm(true).unwrap();
    assert!(!c.armed() && c.landed() == LandedState::OnGround);
}

#[test]
fn armed_on_the_ground_and_left_there_disarms() {
    let mut c = ready();
    c.arm(false).unwrap();
    assert_eq!(c.mode(), FlightMode::Loiter);
    let (sp, armed) = step(&mut c, &input(5.0, 0.0, 0.0));
    assert!(
        armed && sp.pos_ned_m.z > 0.0,
        "held below the ground: idle thrust"
    );
    step(&mut c, &input(9.9, 0.0, 0.0));
    assert!(c.armed());
    let (_, armed) = step(&mut c, &input(10.0, 0.0, 0.0));
    assert!(!armed && !c.armed(), "COM_DISARM_PRFLT");
}

/// A landing whose estimate is wrong (its vertical speed reads 0.3 m/s down, as with a tilted
/// estimate on the ground): the IMU's stillness and a thrust well below a hover's land it; a
/// still IMU at a hover's thrust (a steady descent) does not.
#[test]
fn a_landing_is_detected_by_the_imu_whatever_the_estimate_says() {
    for (thrust, lands) in [(0.1, true), (0.5, false)] {
        let mut c = ready();
        c.takeoff(None).unwrap();
        c.arm(false).unwrap();
        step(&mut c, &input(0.1, 0.0, 0.0));
        step(&mut c, &input(5.0, -5.0, 0.0));
        c.set_mode(FlightMode::Land).unwrap();
        step(&mut c, &input(5.1, -5.0, 0.0));
        let mut t = 5.1;
        while t < 12.0 {
            t += 0.1;
            step(&mut c, &input(t, -5.0 + 0.7 * (t - 5.1), 0.7)); // descending
        }
        let touch = t;
        while t < touch + 10.0 && c.armed() {
            t += 0.1;
            let i = CommanderInput {
                thrust,
                imu_still: true,
                ..input(t, 0.0, 0.3)
            };
            step(&mut c, &i);
        }
        assert_eq!(!c.armed(), lands, "thrust {thrust}: disarmed at {t:.1} s");
        if lands {
            assert!(t - touch < 2.5, "landed {:.1} s after the touch", t - touch);
        }
    }
}

#[test]
fn rtl_climbs_returns_and_lands_at_home() {
    let mut c = Commander::new(CommanderParams {
        rtl_return_alt_m: 10.0,
        ..params()
    });
    step(&mut c, &input(0.0, 0.0, 0.0));
    c.takeoff(None).unwrap();
    c.arm(false).unwrap();
    // Fly the set-points perfectly: the vehicle is where the set-point was a step ago.
    let dt = 0.01;
    let mut t = 0.0;
    let mut pos = Vector3::zeros();
    let mut vel = Vector3::zeros();
    let fly = |c: &mut Commander, t: f64, pos: &mut Vector3<f64>, vel: &mut Vector3<f64>| {
        let (sp, armed) = step(
            c,
            &CommanderInput {
                pos_ned_m: *pos,
                vel_ned_m_s: *vel,
                ..input(t, 0.0, 0.0)
            },
        );
        if armed && sp.pos_ned_m.z < 0.0 {
            *vel = (sp.pos_ned_m - *pos) / dt;
            *pos = sp.pos_ned_m;
        } else {
            *vel = Vector3::zeros();
            pos.z = 0.0;
        }
    };
    while c.mode() != FlightMode::Loiter && t < 20.0 {
        t += dt;
        fly(&mut c, t, &mut pos, &mut vel);
    }
    assert!((pos.z + 5.0).abs() < 0.01, "took off to 5 m: {pos:?}");
    // Somewhere else: 40 m north, 30 m east (moved there by hand).
    pos += Vector3::new(40.0, 30.0, 0.0);
    c.set_mode(FlightMode::Loiter).unwrap();
    c.set_mode(FlightMode::Rtl).unwrap();
    let mut max_up = 0.0f64;
    let mut max_speed = 0.0f64;
    let start = t;
    while c.armed() && t < start + 120.0 {
        t += dt;
        fly(&mut c, t, &mut pos, &mut vel);
        max_up = max_up.max(-pos.z);
        max_speed = max_speed.max(vel.xy().norm());
    }
    assert!(!c.armed(), "landed and disarmed");
    assert!(pos.xy().norm() < 0.05, "at home: {pos:?}");
    assert!(
        (max_up - 10.0).abs() < 0.01,
        "climbed to the return altitude: {max_up}"
    );
    assert!(max_speed <= 5.0 + 1e-9, "cruise speed limited: {max_speed}");
    // 50 m at 5 m/s with 3 m/s² ramps: 11.7 s; climb 5 m at 1.5 with the take-off's 1 m/s²
    // ramps: 4.8 s; descent 10 m at 0.7: 14.3 s; touchdown 1 s and more.
    let took = t - start;
    assert!((30.0..42.0).contains(&took), "RTL took {took:.1} s");
}

#[test]
fn losing_the_estimate_disarms_on_the_ground_and_descends_level_in_the_air() {
    let lost = |t, down, vd| CommanderInput {
        ready: false,
        horizontal_valid: false,
        ..input(t, down, vd)
    };
    // Spooling up on the ground: disarm at once.
    let mut c = ready();
    c.takeoff(None).unwrap();
    c.arm(false).unwrap();
    let (_, armed) = step(&mut c, &lost(0.5, 0.0, 0.0));
    assert!(!armed && !c.armed());

    // Climbing: level and descend, touchdown after a second standing still, and no way back.
    let mut c = ready();
    c.takeoff(None).unwrap();
    c.arm(false).unwrap();
    for (t, d, vd) in [(1.2, 0.0, 0.0), (3.0, -2.0, -1.5)] {
        step(&mut c, &input(t, d, vd));
    }
    let (sp, armed) = step(&mut c, &lost(3.1, -2.1, -1.4));
    assert!(armed && c.mode() == FlightMode::Descend && c.status().failsafe);
    assert!(
        sp.pos_ned_m.iter().all(|p| p.is_nan()),
        "no position control"
    );
    assert!(
        sp.vel_ned_m_s.x.is_nan() && sp.vel_ned_m_s.y.is_nan(),
        "level"
    );
    assert!((sp.vel_ned_m_s.z - 0.7).abs() < 1e-12 && sp.accel_ned_m_s2 == Vector3::zeros());
    assert!(
        c.set_mode(FlightMode::Loiter).is_err(),
        "no way out but down"
    );
    // The barometer lost but the GPS still there: brake over the ground while descending.
    let baro_lost = CommanderInput {
        ready: false,
        ..input(3.2, -2.1, 0.5)
    };
    let (sp, _) = step(&mut c, &baro_lost);
    assert!(sp.vel_ned_m_s.xy() == nalgebra::Vector2::zeros() && sp.pos_ned_m.x.is_nan());
    step(&mut c, &input(3.5, -2.2, 0.0)); // valid again: still descending
    assert_eq!(c.mode(), FlightMode::Descend);
    step(&mut c, &lost(4.0, -2.0, 0.05)); // passing through zero speed is not touchdown
    step(&mut c, &lost(4.5, -1.7, 0.7));
    assert_eq!(c.mode(), FlightMode::Descend);
    for t in [7.0, 7.5, 7.9] {
        step(&mut c, &lost(t, 0.0, 0.02));
        assert!(c.armed(), "at {t}");
    }
    let (_, armed) = step(&mut c, &lost(8.05, 0.0, 0.0));
    assert!(!armed && !c.armed() && c.landed() == LandedState::OnGround);
}

#[test]
fn the_takeoff_set_point_climbs_smoothly_and_stops_at_the_altitude() {
    let mut c = ready();
    c.takeoff(None).unwrap();
    c.arm(false).unwrap();
    let dt = 0.004;
    step(&mut c, &input(1.0, 0.0, 0.0));
    let (mut t, mut last_up, mut last_v) = (1.0 + dt, 0.0f64, 0.0f64);
    while t < 9.0 {
        // The vehicle is where the set-point was a step ago.
        let (sp, _) = step(&mut c, &input(t, -last_up, -last_v));
        if c.mode() == FlightMode::Loiter {
            break;
        }
        let (up, v) = (-sp.pos_ned_m.z, -sp.vel_ned_m_s.z);
        assert!(
            up >= last_up - 1e-12 && up <= 5.0 + 1e-12,
            "monotonic, bounded"
        );
        assert!(v <= 1.5 + 1e-12, "climb speed limited: {v}");
        assert!(
            (v - last_v).abs() <= 1.02 * dt,
            "acceleration limited at t = {t}: {last_v} → {v}"
        );
        (last_up, last_v) = (up, v);
        t += dt;
    }
    assert_eq!(c.mode(), FlightMode::Loiter);
    // 5 m at 1.5 m/s with S-curve ramps (1 m/s², 6 m/s³) at both ends, each 1.5/1 + 1/6 s
    // over 1.5/2 m/s × that: 2 × 1.667 + (5 − 2.5)/1.5 = 5.0 s after take-off (the defaults).
    let p = c.params();
    let ramp = p.takeoff_speed_m_s / p.takeoff_accel_m_s2() + p.takeoff_accel_m_s2() / p.jerk_m_s3;
    let best = 2.0 * ramp + (5.0 - p.takeoff_speed_m_s * ramp) / p.takeoff_speed_m_s;
    assert!((t - 1.0 - best).abs() < 0.05, "arrived after {} s", t - 1.0);
}

/// A wind that slides the vehicle on its feet as the thrust comes up, and drifts it on the
/// climb, does not move the point it climbs above and then holds: where it stood.
#[test]
fn the_takeoff_holds_above_where_the_vehicle_stood_not_where_the_wind_pushed_it() {
    let mut c = ready();
    c.takeoff(None).unwrap();
    c.arm(false).unwrap();
    // Armed at t = 0: the spool-up's second on the ground, then the climb.
    let dt = 0.004;
    let (mut t, mut up): (f64, f64) = (dt, 0.0);
    while t < 12.0 && c.mode() != FlightMode::Loiter {
        // 1.5 m downwind within 2 s, on the ground and in the climb.
        let slid = -1.5 * ((t - 0.1) / 2.0).clamp(0.0, 1.0);
        let (sp, _) = step(
            &mut c,
            &at(
                t,
                Vector3::new(slid, 0.2 * slid, -up),
                Vector3::zeros(),
                0.0,
            ),
        );
        assert!(
            sp.pos_ned_m.xy().norm() < 1e-9,
            "at t = {t}: {:?}",
            sp.pos_ned_m
        );
        if !sp.pos_ned_m.z.is_nan() {
            up = -sp.pos_ned_m.z;
        }
        t += dt;
    }
    assert_eq!(c.mode(), FlightMode::Loiter);
    let (hold, _) = step(
        &mut c,
        &at(t, Vector3::new(-1.5, -0.3, -5.0), Vector3::zeros(), 0.0),
    );
    assert!(
        hold.pos_ned_m.xy().norm() < 1e-9,
        "holds there: {:?}",
        hold.pos_ned_m
    );
}

/// Takeoff selected as a mode climbs to MIS_TAKEOFF_ALT as it is now, not as it was when the
/// commander started (or at the last `MAV_CMD_NAV_TAKEOFF`).
#[test]
fn the_takeoff_mode_climbs_to_the_parameter_of_the_moment() {
    let mut c = ready();
    c.takeoff(Some(3.0)).unwrap();
    c.set_mode(FlightMode::Loiter).unwrap();
    c.set_params(CommanderParams {
        takeoff_alt_m: 15.0,
        ..params()
    });
    c.set_mode(FlightMode::Takeoff).unwrap();
    c.arm(false).unwrap();
    let mut t = 1.0;
    let mut top = 0.0f64;
    while t < 30.0 && c.mode() == FlightMode::Takeoff {
        let (sp, _) = step(&mut c, &input(t, -top, 0.0));
        top = -sp.pos_ned_m.z;
        t += 0.01;
    }
    assert!((top - 15.0).abs() < 1e-6, "climbed to {top} m");
}

#[test]
fn home_is_set_once_the_position_is_valid_and_again_at_arming_unless_commanded() {
    let mut c = Commander::new(params());
    step(
        &mut c,
        &CommanderInput {
            ready: false,
            ..input(0.0, 0.0, 0.0)
        },
    );
    assert_eq!(c.home(), None, "not from an invalid estimate");
    step(&mut c, &input(0.1, 1.0, 0.0));
    assert_eq!(
        c.home(),
        Some(Vector3::new(0.0, 0.0, 1.0)),
        "on the ground, disarmed"
    );
    step(&mut c, &input(0.2, 2.0, 0.0));
    assert_eq!(c.home(), Some(Vector3::new(0.0, 0.0, 1.0)), "set once");
    c.arm(false).unwrap();
    assert_eq!(
        c.home(),
        Some(Vector3::new(0.0, 0.0, 2.0)),
        "again at arming"
    );
    c.disarm(false).unwrap();
    c.set_home(Some(Vector3::new(5.0, 5.0, 0.0))).unwrap();
    step(&mut c, &input(0.3, 3.0, 0.0));
    c.arm(false).unwrap();
    assert_eq!(
        c.home(),
        Some(Vector3::new(5.0, 5.0, 0.0)),
        "a commanded home is kept"
    );
}

fn at(t: f64, pos: Vector3<f64>, vel: Vector3<f64>, yaw: f64) -> CommanderInput {
    CommanderInput {
        t_s: t,
        ready: true,
        horizontal_valid: true,
        pos_ned_m: pos,
        vel_ned_m_s: vel,
        yaw_rad: yaw,
        hover_thrust: 0.5,
        thrust: 0.5,
        imu_still: false,
        origin: None,
        health: Health::default(),
    }
}

#[test]
fn position_mode_flies_the_sticks_and_holds_when_they_centre() {
    let mut c = Commander::new(CommanderParams::default());
    let z = Vector3::zeros();
    step(&mut c, &at(0.0, z, z, 0.0));
    let err = c.set_mode(FlightMode::Posctl).unwrap_err();
    assert!(err.to_string().contains("no manual control"), "{err}");
    c.manual_control(sticks(0.0, 0.0, 1.0, 0.0));
    c.set_mode(FlightMode::Posctl).unwrap();
    assert!(
        c.arm(false)
            .unwrap_err()
            .to_string()
            .contains("throttle stick above centre")
    );
    c.manual_control(sticks(0.0, 0.0, 0.0, 0.0));
    c.arm(false).unwrap();
    let (sp, armed) = step(&mut c, &at(0.1, z, z, 0.0));
    assert!(
        armed && sp.pos_ned_m.z > 0.0,
        "throttle low: stays on the ground {sp:?}"
    );
    assert_eq!(c.landed(), LandedState::OnGround);

    // Full throttle: climb at MAN_Z_VEL_UP; airborne above a metre.
    c.manual_control(sticks(0.0, 0.0, 1.0, 0.0));
    let (sp, _) = step(&mut c, &at(0.2, z, z, 0.0));
    assert_eq!(sp.vel_ned_m_s.z, -3.0);
    assert!(sp.pos_ned_m.z.is_nan());
    assert_eq!(c.landed(), LandedState::Takeoff);
    let up = Vector3::new(0.0, 0.0, -2.0);
    step(&mut c, &at(0.3, up, Vector3::new(0.0, 0.0, -3.0), 0.0));
    assert_eq!(c.landed(), LandedState::InAir);

    // Centred: hold the point where it was when the stick centred.
    c.manual_control(Sticks::CENTRED);
    let (sp, _) = step(&mut c, &at(0.4, up, z, 0.0));
    assert_eq!(sp.pos_ned_m, up);
    // Full forward, heading east: 5 m/s east; the held point follows.
    c.manual_control(sticks(1.0, 0.0, 0.5, 0.0));
    let (sp, _) = step(&mut c, &at(0.5, up, z, FRAC_PI_2));
    assert!(sp.pos_ned_m.x.is_nan() && sp.pos_ned_m.z == up.z, "{sp:?}");
    assert!((sp.vel_ned_m_s.y - 5.0).abs() < 1e-9 && sp.vel_ned_m_s.x.abs() < 1e-9);
    let there = Vector3::new(0.0, 3.0, -2.0);
    step(&mut c, &at(0.6, there, z, FRAC_PI_2));
    c.manual_control(Sticks::CENTRED);
    let (sp, _) = step(&mut c, &at(0.7, there, z, FRAC_PI_2));
    assert_eq!(sp.pos_ned_m, there);
    // The yaw stick turns the heading set-point at MPC_MAN_Y_MAX.
    c.manual_control(sticks(0.0, 0.0, 0.5, 1.0));
    let (a, _) = step(&mut c, &at(0.8, there, z, FRAC_PI_2));
    let (b, _) = step(&mut c, &at(0.9, there, z, FRAC_PI_2));
    assert!((b.yaw_rad - a.yaw_rad - 15f64.to_radians()).abs() < 1e-9);

    // Altitude mode: the stick is a tilt (horizontal acceleration), position uncontrolled.
    c.set_mode(FlightMode::Altctl).unwrap();
    c.manual_control(sticks(-1.0, 0.0, 0.5, 0.0));
    let (sp, _) = step(&mut c, &at(1.0, there, z, 0.0));
    let a = crate::GRAVITY_M_S2 * 35f64.to_radians().tan();
    assert!(sp.pos_ned_m.x.is_nan() && sp.vel_ned_m_s.x.is_nan());
    assert!((sp.accel_ned_m_s2.x + a).abs() < 1e-9, "{sp:?}");

    // The sticks stop: after COM_RC_LOSS_T, NAV_RCL_ACT's Return (PX4's default).
    step(&mut c, &at(1.3, there, z, 0.0));
    assert_eq!(c.mode(), FlightMode::Altctl);
    step(&mut c, &at(1.6, there, z, 0.0));
    assert_eq!(c.mode(), FlightMode::Rtl);
    assert_eq!(c.status().manual_losses, 1);
}

#[test]
fn position_mode_lands_and_disarms_on_a_low_throttle() {
    let mut c = Commander::new(CommanderParams::default());
    let z = Vector3::zeros();
    step(&mut c, &at(0.0, z, z, 0.0));
    c.manual_control(Sticks::CENTRED);
    c.set_mode(FlightMode::Posctl).unwrap();
    c.arm(false).unwrap();
    c.manual_control(Sticks {
        throttle: 1.0,
        ..Sticks::CENTRED
    });
    step(&mut c, &at(0.1, Vector3::new(0.0, 0.0, -3.0), z, 0.0));
    assert_eq!(c.landed(), LandedState::InAir);
    let mut t = 0.1;
    // Throttle low: sink; standing on the ground for a second: disarmed.
    while c.armed() && t < 10.0 {
        t += 0.1;
        c.manual_control(Sticks {
            throttle: 0.0,
            ..Sticks::CENTRED
        });
        let (sp, _) = step(&mut c, &at(t, Vector3::new(0.0, 0.0, -0.05), z, 0.0));
        if c.armed() {
            assert_eq!(sp.vel_ned_m_s.z, 1.0, "MAN_Z_VEL_DN");
        }
    }
    assert!(
        !c.armed() && (1.0..1.3).contains(&(t - 0.1)),
        "disarmed at {t}"
    );
    assert_eq!(c.landed(), LandedState::OnGround);
}

/// One update of a commander in a stick-to-attitude mode.
fn attitude(c: &mut Commander, i: &CommanderInput) -> (AttitudeTarget, bool) {
    match c.update(i) {
        (Setpoint::Attitude(a), armed) => (a, armed),
        (s, _) => panic!("an attitude target expected, not {s:?}"),
    }
}

/// Stabilized as PX4 flies it on a multicopter: the throttle curve through hover thrust, the
/// roll and pitch sticks as a tilt limited to MPC_MAN_TILT_MAX in the heading's frame, the yaw
/// stick as a turn rate (not on the ground), arming only with the throttle low.
#[test]
fn stabilized_turns_sticks_into_attitude_and_thrust() {
    let mut c = Commander::new(CommanderParams::default());
    let z = Vector3::zeros();
    let hover = |t, pos, yaw| CommanderInput {
        hover_thrust: 0.4,
        thrust: 0.4,
        imu_still: false,
        origin: None,
        ..at(t, pos, z, yaw)
    };
    step(&mut c, &hover(0.0, z, 0.0));
    let err = c.set_mode(FlightMode::Stabilized).unwrap_err();
    assert!(err.to_string().contains("no manual control"), "{err}");
    c.manual_control(sticks(0.0, 0.0, 0.5, 0.0));
    c.set_mode(FlightMode::Stabilized).unwrap();
    let err = c.arm(false).unwrap_err();
    assert!(err.to_string().contains("throttle stick not low"), "{err}");
    c.manual_control(sticks(0.0, 0.0, 0.0, 0.0));
    c.arm(false).unwrap();
    // Throttle curve: 0 → MPC_MANTHR_MIN, ½ → hover, 1 → full, linear between.
    for (throttle, thrust) in [
        (0.0, 0.08),
        (0.25, 0.24),
        (0.5, 0.4),
        (0.75, 0.7),
        (1.0, 1.0),
    ] {
        c.manual_control(sticks(0.0, 0.0, throttle, 0.0));
        let (a, armed) = attitude(&mut c, &hover(0.1, z, 0.3));
        assert!(armed);
        assert!(
            (a.thrust - thrust).abs() < 1e-12,
            "{throttle}: {}",
            a.thrust
        );
    }
    // Thrust above hover lifts off; risen above a metre, it is in the air.
    assert_eq!(c.landed(), LandedState::Takeoff);
    let up = Vector3::new(0.0, 0.0, -2.0);
    attitude(&mut c, &hover(0.3, up, 0.3));
    assert_eq!(c.landed(), LandedState::InAir);
    // Centred, the heading is held while the vehicle turns away; the yaw stick asks for a
    // turn at MPC_MAN_Y_MAX from wherever the vehicle points; centred again, that heading holds.
    let (a, _) = attitude(&mut c, &hover(0.35, up, 0.4));
    assert!((a.q_d.unwrap().euler_angles().2 - 0.3).abs() < 1e-9);
    assert_eq!(a.rate_frd_rad_s, Vector3::zeros());
    c.manual_control(sticks(0.0, 0.0, 0.5, 1.0));
    let (a, _) = attitude(&mut c, &hover(0.4, up, 0.5));
    assert!((a.q_d.unwrap().euler_angles().2 - 0.5).abs() < 1e-9);
    let rate = a.q_d.unwrap() * a.rate_frd_rad_s;
    assert!((rate - Vector3::new(0.0, 0.0, 150f64.to_radians())).norm() < 1e-9);
    c.manual_control(sticks(0.0, 0.0, 0.5, 0.0));
    for (t, yaw) in [(0.42, 0.7), (0.44, 0.75)] {
        let (a, _) = attitude(&mut c, &hover(t, up, yaw));
        assert!((a.q_d.unwrap().euler_angles().2 - 0.7).abs() < 1e-9);
    }
    // Roll right, pitch forward (nose down), and both at once: the tilt is limited.
    let max = 35f64.to_radians();
    for (forward, right, roll, pitch) in [
        (0.0, 1.0, max, 0.0),
        (1.0, 0.0, 0.0, -max),
        (-0.5, 0.0, 0.0, max / 2.0),
    ] {
        c.manual_control(sticks(forward, right, 0.5, 0.0));
        let (a, _) = attitude(&mut c, &hover(0.5, up, 0.0));
        let heading =
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), -a.q_d.unwrap().euler_angles().2);
        let (r, p, _) = (heading * a.q_d.unwrap()).euler_angles();
        assert!(
            (r - roll).abs() < 1e-9 && (p - pitch).abs() < 1e-9,
            "{r} {p}"
        );
    }
    c.manual_control(sticks(1.0, 1.0, 0.5, 0.0));
    let (a, _) = attitude(&mut c, &hover(0.6, up, 0.0));
    let tilt = (a.q_d.unwrap() * Vector3::z()).angle(&Vector3::z());
    assert!((tilt - max).abs() < 1e-9, "tilt {}", tilt.to_degrees());
    // Manual is the same on a multicopter.
    c.set_mode(FlightMode::Manual).unwrap();
    let (b, armed) = attitude(&mut c, &hover(0.7, up, 0.0));
    let b_tilt = (b.q_d.unwrap() * Vector3::z()).angle(&Vector3::z());
    assert!(
        armed && b.thrust == a.thrust && (b_tilt - max).abs() < 1e-9,
        "{b:?}"
    );
}

/// Touchdown in Stabilized: the throttle held low with the vehicle still for a second disarms
/// (and stays in Stabilized, as PX4); sticks that stop arriving hand over to Hold.
#[test]
fn stabilized_lands_on_low_throttle_and_holds_without_sticks() {
    let mut c = Commander::new(CommanderParams::default());
    let z = Vector3::zeros();
    step(&mut c, &at(0.0, z, z, 0.0));
    let sticks = |throttle| Sticks {
        throttle,
        ..Sticks::CENTRED
    };
    c.manual_control(sticks(0.0));
    c.set_mode(FlightMode::Stabilized).unwrap();
    c.arm(false).unwrap();
    let up = Vector3::new(0.0, 0.0, -3.0);
    for t in [0.1, 0.2, 0.3] {
        c.manual_control(sticks(0.8));
        attitude(&mut c, &at(t, up, z, 0.0));
    }
    assert_eq!(c.landed(), LandedState::InAir);
    // Throttle low, falling: not a touchdown.
    for t in [0.4, 0.8, 1.2, 1.6] {
        c.manual_control(sticks(0.0));
        let (_, armed) = attitude(&mut c, &at(t, up, Vector3::new(0.0, 0.0, 2.0), 0.0));
        assert!(armed);
    }
    // On the ground, still: disarmed after a second.
    let mut disarmed_at = None;
    for k in 0..20 {
        let t = 1.7 + 0.1 * f64::from(k);
        c.manual_control(sticks(0.0));
        let (_, armed) = c.update(&at(t, z, z, 0.0)); // disarmed: a position set-point
        if !armed && disarmed_at.is_none() {
            disarmed_at = Some(t);
        }
    }
    let t = disarmed_at.unwrap();
    assert!((2.65..2.85).contains(&t), "disarmed at {t}");
    assert_eq!(c.mode(), FlightMode::Stabilized);
    // Again in the air, then the sticks stop: Return, holding first where it brakes.
    c.arm(false).unwrap();
    for t in [4.0, 4.1, 4.2] {
        c.manual_control(sticks(0.8));
        attitude(&mut c, &at(t, up, z, 0.0));
    }
    let (sp, armed) = step(&mut c, &at(4.8, up, z, 0.0));
    assert!(armed && c.mode() == FlightMode::Rtl, "{:?}", c.mode());
    assert_eq!(sp.pos_ned_m, up);
    assert_eq!(c.status().manual_losses, 1);
}

/// Offboard as PX4: entered (and armed in) only while set-points arrive; a position set-point
/// above the ground takes off, its NaN yaw holds the heading or turns it at the yaw rate given;
/// an attitude target's NaN thrust is hover; the stream stopping for COM_OF_LOSS_T hands over to
/// COM_OBL_RC_ACT's mode (Position without a joystick is Hold; Land when asked).
#[test]
fn offboard_flies_the_stream_and_fails_safe_when_it_stops() {
    use crate::control::AttitudeTarget;
    let mut c = Commander::new(CommanderParams::default());
    let z = Vector3::zeros();
    step(&mut c, &at(0.0, z, z, 0.0));
    let err = c.set_mode(FlightMode::Offboard).unwrap_err();
    assert!(err.to_string().contains("no set-point stream"), "{err}");
    let target = |pos: Vector3<f64>, yaw: f64, rate: Option<f64>| OffboardTarget {
        setpoint: Setpoint::Position(PositionSetpoint {
            pos_ned_m: pos,
            vel_ned_m_s: Vector3::repeat(f64::NAN),
            accel_ned_m_s2: Vector3::zeros(),
            yaw_rad: yaw,
        }),
        yaw_rate_rad_s: rate,
    };
    // On the ground, a set-point on the ground: spooled, staying there.
    c.offboard_setpoint(target(z, f64::NAN, None));
    c.set_mode(FlightMode::Offboard).unwrap();
    c.arm(false).unwrap();
    let (sp, armed) = step(&mut c, &at(0.1, z, z, 0.2));
    assert!(armed && sp.pos_ned_m.z > 0.0 && c.landed() == LandedState::OnGround);
    // 5 m up: taking off; no yaw given: the heading at that moment holds.
    let up = Vector3::new(1.0, 2.0, -5.0);
    c.offboard_setpoint(target(up, f64::NAN, None));
    let (sp, _) = step(&mut c, &at(0.2, z, z, 0.2));
    assert_eq!(c.landed(), LandedState::Takeoff);
    assert_eq!((sp.pos_ned_m, sp.yaw_rad), (up, 0.2));
    // A yaw rate turns it from there; a yaw is flown as given.
    c.offboard_setpoint(target(up, f64::NAN, Some(0.5)));
    let (sp, _) = step(&mut c, &at(0.4, up, z, 0.25));
    assert!((sp.yaw_rad - 0.3).abs() < 1e-12, "{}", sp.yaw_rad);
    assert_eq!(c.landed(), LandedState::InAir);
    c.offboard_setpoint(target(up, -1.0, None));
    let (sp, _) = step(&mut c, &at(0.5, up, z, 0.3));
    assert_eq!(sp.yaw_rad, -1.0);
    // An attitude target without a thrust: hover thrust.
    c.offboard_setpoint(OffboardTarget {
        setpoint: Setpoint::Attitude(AttitudeTarget {
            q_d: None,
            rate_frd_rad_s: Vector3::new(0.0, 0.0, 0.3),
            thrust: f64::NAN,
        }),
        yaw_rate_rad_s: None,
    });
    match c.update(&at(0.6, up, z, 0.3)) {
        (Setpoint::Attitude(a), true) => assert_eq!(a.thrust, 0.5),
        other => panic!("{other:?}"),
    }
    // The stream stops: Hold after COM_OF_LOSS_T (0.5 s), no joystick for Position.
    // (The last set-point arrived at the update of 0.5 s.)
    match c.update(&at(0.95, up, z, 0.3)) {
        (Setpoint::Attitude(_), true) => {}
        other => panic!("{other:?}"),
    }
    assert_eq!(c.mode(), FlightMode::Offboard);
    let (sp, armed) = step(&mut c, &at(1.05, up, z, 0.3));
    assert!(armed && c.mode() == FlightMode::Loiter && sp.pos_ned_m == up);
    assert_eq!(c.status().offboard_losses, 1);
    // COM_OBL_RC_ACT 4: Land.
    c.set_params(CommanderParams {
        offboard_loss_action: 4,
        ..CommanderParams::default()
    });
    c.offboard_setpoint(target(up, f64::NAN, None));
    c.set_mode(FlightMode::Offboard).unwrap();
    step(&mut c, &at(1.2, up, z, 0.3));
    step(&mut c, &at(1.8, up, z, 0.3));
    assert_eq!(c.mode(), FlightMode::Land);
    // Back on the ground through the stream: touchdown after a still second, disarmed.
    c.offboard_setpoint(target(z, f64::NAN, None));
    c.set_mode(FlightMode::Offboard).unwrap();
    let mut t = 1.9;
    while c.armed() && t < 5.0 {
        c.offboard_setpoint(target(z, f64::NAN, None));
        c.update(&at(t, Vector3::new(0.0, 0.0, -0.1), z, 0.3));
        t += 0.1;
    }
    assert!(
        !c.armed() && (2.85..3.05).contains(&t),
        "disarmed at {t:.2}"
    );
}

mod mission;

/// When [`hovering`] hands over (s): the tests' times count from here.
const T0: f64 = 20.0;

/// A commander flying at 10 m in Hold, home at the origin, at [`T0`].
fn hovering(safety: crate::safety::failsafe::SafetyParams) -> Commander {
    let mut c = ready();
    c.set_safety_params(safety);
    c.takeoff(Some(10.0)).unwrap();
    c.arm(false).unwrap();
    // The vehicle where the set-point was a step before.
    let (mut t, mut down) = (0.1, 0.0);
    while c.mode() == FlightMode::Takeoff && t < 20.0 {
        down = step(&mut c, &input(t, down, 0.0)).0.pos_ned_m.z;
        t += 0.1;
    }
    step(&mut c, &input(T0, -10.0, 0.0));
    assert_eq!(
        (c.mode(), c.landed()),
        (FlightMode::Loiter, LandedState::InAir)
    );
    c.take_safety_events();
    c
}

/// At 10 m, `t` s after [`T0`], with the health `f` makes.
fn with(t: f64, f: impl Fn(&mut Health)) -> CommanderInput {
    let mut i = input(T0 + t, -10.0, 0.0);
    f(&mut i.health);
    i
}

/// The failsafe machine's decisions carried out: the link lost holds, then returns; the
/// operator takes over with a mode change; each change is said once.
#[test]
fn link_loss_holds_then_returns_and_the_operator_can_take_over() {
    use crate::safety::failsafe::{Condition, FailsafeAction, SafetyEvent, SafetyParams};
    let mut c = hovering(SafetyParams {
        gcs_loss_action: 2,
        ..SafetyParams::default()
    });
    c.set_mode(FlightMode::Mission).unwrap_err(); // no mission: stays in Hold
    c.manual_control(Sticks::CENTRED);
    c.set_mode(FlightMode::Posctl).unwrap();
    step(&mut c, &with(3.0, |h| h.gcs_link_age_s = Some(1.0)));
    step(&mut c, &with(7.0, |h| h.gcs_link_age_s = Some(5.5)));
    assert_eq!(c.mode(), FlightMode::Loiter, "Hold first");
    assert_eq!(
        c.status().failsafe_action,
        Some((FailsafeAction::Hold, Condition::GcsLinkLost))
    );
    assert_eq!(
        c.take_safety_events(),
        [SafetyEvent::Triggered(
            Condition::GcsLinkLost,
            FailsafeAction::Hold
        )]
    );
    step(&mut c, &with(12.1, |h| h.gcs_link_age_s = Some(10.6)));
    assert_eq!(c.mode(), FlightMode::Rtl, "then Return");
    assert!(c.status().failsafe);
    // The link back: the failsafe clears, the vehicle keeps returning until told otherwise.
    step(&mut c, &with(13.0, |h| h.gcs_link_age_s = Some(0.2)));
    assert_eq!((c.mode(), c.status().failsafe), (FlightMode::Rtl, false));
    c.set_mode(FlightMode::Loiter).unwrap();
    // Lost again, and the operator (on another link) takes over during the hold.
    step(&mut c, &with(20.0, |h| h.gcs_link_age_s = Some(6.0)));
    assert!(c.status().failsafe);
    c.manual_control(Sticks::CENTRED);
    c.set_mode(FlightMode::Posctl).unwrap();
    for k in 1..=80 {
        let dt = 0.1 * k as f64;
        c.manual_control(Sticks::CENTRED);
        step(
            &mut c,
            &with(20.0 + dt, |h| h.gcs_link_age_s = Some(6.0 + dt)),
        );
    }
    assert_eq!(c.mode(), FlightMode::Posctl, "taken over: no Return");
}

/// A battery at its emergency level lands, and no mode change gets out of it; a forced arm
/// skips a low battery but not an emergency one; a crash disarms.
#[test]
fn battery_emergency_lands_and_crash_disarms() {
    use crate::safety::failsafe::SafetyParams;
    let mut c = hovering(SafetyParams::default());
    step(&mut c, &with(3.0, |h| h.battery_remaining = Some(0.06)));
    assert_eq!(c.mode(), FlightMode::Rtl, "critical: Return");
    step(&mut c, &with(3.1, |h| h.battery_remaining = Some(0.04)));
    assert_eq!(c.mode(), FlightMode::Land, "emergency: Land");
    let refused = c.set_mode(FlightMode::Loiter).unwrap_err();
    assert!(
        refused.to_string().contains("battery emergency"),
        "{refused}"
    );
    // Arming checks on the ground.
    let mut c = ready();
    step(&mut c, &with(0.1, |h| h.battery_remaining = Some(0.1)));
    assert!(
        c.arm(false)
            .unwrap_err()
            .to_string()
            .contains("battery low")
    );
    c.arm(true).unwrap();
    c.disarm(false).unwrap();
    step(&mut c, &with(0.2, |h| h.battery_remaining = Some(0.04)));
    assert!(c.arm(true).unwrap_err().to_string().contains("emergency"));
    // Flipped in the air for FD_FAIL_R_TTRI: motors off.
    let mut c = hovering(SafetyParams::default());
    step(&mut c, &with(3.0, |h| h.roll_pitch_rad = (2.0, 0.0)));
    assert!(c.armed());
    step(&mut c, &with(3.35, |h| h.roll_pitch_rad = (2.5, 0.0)));
    assert!(!c.armed(), "disarmed");
}

/// `GF_MAX_HOR_DIST` / `GF_MAX_VER_DIST` from home: Hold (`GF_ACTION` 2) on the breach.
#[test]
fn the_distance_and_height_fences_hold_the_vehicle() {
    use crate::safety::failsafe::{Condition, FailsafeAction, SafetyParams};
    let mut c = hovering(SafetyParams {
        fence_max_horizontal_m: 20.0,
        fence_max_vertical_m: 15.0,
        ..SafetyParams::default()
    });
    c.set_mode(FlightMode::Rtl).unwrap();
    step(
        &mut c,
        &CommanderInput {
            pos_ned_m: Vector3::new(19.0, 0.0, -14.0),
            ..with(1.0, |_| {})
        },
    );
    assert_eq!(
        (c.mode(), c.status().failsafe_action),
        (FlightMode::Rtl, None)
    );
    step(
        &mut c,
        &CommanderInput {
            pos_ned_m: Vector3::new(19.0, 0.0, -15.5),
            ..with(2.0, |_| {})
        },
    );
    assert_eq!(
        (c.mode(), c.status().failsafe_action),
        (
            FlightMode::Loiter,
            Some((FailsafeAction::Hold, Condition::GeofenceBreach))
        )
    );
}

/// A touchdown in position mode disarms within the update that detects it (the motors stop
/// with that update's answer), and a new flight in the mode starts from the heading it has
/// then, not from the last flight's.
#[test]
fn position_mode_touchdown_disarms_at_once_and_a_new_flight_starts_afresh() {
    let mut c = Commander::new(CommanderParams::default());
    let z = Vector3::zeros();
    step(&mut c, &at(0.0, z, z, 1.0));
    c.manual_control(sticks(0.0, 0.0, 0.0, 0.0));
    c.set_mode(FlightMode::Posctl).unwrap();
    c.arm(false).unwrap();
    c.manual_control(sticks(0.0, 0.0, 1.0, 0.0));
    let (sp, _) = step(&mut c, &at(0.1, z, z, 1.0));
    assert_eq!(sp.yaw_rad, 1.0, "the heading at take-off is held");
    let up = Vector3::new(0.0, 0.0, -2.0);
    step(&mut c, &at(0.2, up, Vector3::new(0.0, 0.0, -3.0), 1.0));
    assert_eq!(c.landed(), LandedState::InAir);

    // Throttle low (sent every half second, as a joystick streams), half a metre up and no
    // longer sinking: down after a second.
    let low = Vector3::new(0.0, 0.0, -0.5);
    for t in [0.5, 1.0, 1.4] {
        c.manual_control(sticks(0.0, 0.0, 0.0, 0.0));
        let (_, armed) = step(&mut c, &at(t, low, z, 1.0));
        assert!(armed && c.armed(), "{t}");
    }
    c.manual_control(sticks(0.0, 0.0, 0.0, 0.0));
    let (_, armed) = step(&mut c, &at(1.5, low, z, 1.0));
    assert!(
        !armed && !c.armed(),
        "disarmed in the update that saw the touchdown"
    );
    assert_eq!(c.landed(), LandedState::OnGround);

    // Turned by hand on the ground, armed again: the climb holds today's heading.
    step(&mut c, &at(3.0, z, z, 0.0));
    c.manual_control(sticks(0.0, 0.0, 0.0, 0.0));
    c.arm(false).unwrap();
    c.manual_control(sticks(0.0, 0.0, 1.0, 0.0));
    let (sp, _) = step(&mut c, &at(3.1, z, z, 0.0));
    assert_eq!(sp.yaw_rad, 0.0, "not the last flight's 1 rad");
}

/// A guided command is the operator taking over from a failsafe, as a mode change is: the
/// failsafe's Hold (the link lost) ends, overridden, rather than staying on the books while
/// the orbit flies.
#[test]
fn an_orbit_takes_over_from_a_failsafe_as_a_mode_change_does() {
    use crate::safety::failsafe::SafetyParams;
    let mut c = hovering(SafetyParams {
        gcs_loss_action: 2,
        ..SafetyParams::default()
    });
    step(&mut c, &with(7.0, |h| h.gcs_link_age_s = Some(5.5)));
    assert!(c.status().failsafe && c.mode() == FlightMode::Loiter);
    c.orbit(OrbitRequest::default()).unwrap();
    assert_eq!(c.mode(), FlightMode::Orbit);
    assert!(!c.status().failsafe, "taken over");
    step(&mut c, &with(8.0, |h| h.gcs_link_age_s = Some(6.5)));
    assert_eq!(c.mode(), FlightMode::Orbit, "overridden until it clears");
}

/// Land entered in a climb: the vehicle turns over at the top, its vertical speed near zero
/// with the set-point already below it. That is not the ground (a battery failsafe's Land after
/// a Return's climb cut the thrust there, 8 m up); a stop after coming down is.
#[test]
fn a_land_begun_in_a_climb_is_not_grounded_at_the_top() {
    let mut c = ready();
    c.takeoff(None).unwrap();
    c.arm(false).unwrap();
    for (t, d, vd) in [(1.5, 0.0, 0.0), (3.0, -2.0, -1.5), (6.0, -5.0, -1.5)] {
        step(&mut c, &input(t, d, vd));
    }
    c.set_mode(FlightMode::Land).unwrap();
    // Still climbing, then slowing through zero for a second at the top.
    let mut t = 6.0;
    for k in 0..150 {
        t += 0.01;
        let vd = (-1.5 + 0.015 * k as f64).min(0.05);
        step(&mut c, &input(t, -6.0, vd));
        assert_eq!(
            c.status().ground_contact,
            GroundContact::None,
            "at {t:.2} s"
        );
        assert!(c.armed(), "at {t:.2} s");
    }
    // Then down at the land speed, and stopped on the ground: contact, maybe landed, disarm.
    for k in 0..300 {
        t += 0.02;
        step(&mut c, &input(t, -6.0 + 0.7 * 0.02 * k as f64, 0.7));
    }
    let mut stages = Vec::new();
    while c.armed() {
        t += 0.02;
        step(&mut c, &input(t, 0.0, 0.0));
        stages.push(c.status().ground_contact);
        assert!(t < 40.0, "disarmed on the ground");
    }
    assert!(
        stages.contains(&GroundContact::Contact) && stages.contains(&GroundContact::MaybeLanded)
    );
}
