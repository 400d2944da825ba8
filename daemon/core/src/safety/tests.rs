//! The failsafe state machine as tables: a script of inputs over time, and what must come out
//! at each step (the action, and the events the operator hears).

use super::failsafe::*;
use super::preflight::*;
use crate::sensors::mag_check::{MagField, MagStatus};
use Condition as C;
use FailsafeAction as A;
use SafetyEvent as E;

/// Armed, flying, every estimate valid, home set, the link fresh, a full battery.
fn flying() -> SafetyInput {
    SafetyInput {
        t_s: 0.0,
        armed: true,
        in_air: true,
        mode_needs_position: true,
        gcs_link_age_s: Some(0.1),
        battery_remaining: Some(0.8),
        geofence_breached: false,
        attitude_valid: true,
        position_valid: true,
        altitude_valid: true,
        sensors_lost: SensorsLost::default(),
        roll_pitch_rad: (0.0, 0.0),
        home_set: true,
        motor_failed: false,
        spinning: false,
    }
}

/// One row of a script: at `t_s`, change the input, then expect `action` and `events`.
struct Row {
    t_s: f64,
    change: fn(&mut SafetyInput),
    action: FailsafeAction,
    events: Vec<SafetyEvent>,
}

fn row(
    t_s: f64,
    change: fn(&mut SafetyInput),
    action: FailsafeAction,
    events: &[SafetyEvent],
) -> Row {
    Row {
        t_s,
        change,
        action,
        events: events.to_vec(),
    }
}

/// Runs a script from [`flying`]; changes accumulate.
fn run(name: &str, params: SafetyParams, rows: &[Row]) -> Safety {
    let mut s = Safety::new(params);
    let mut i = flying();
    for (k, r) in rows.iter().enumerate() {
        i.t_s = r.t_s;
        (r.change)(&mut i);
        let d = s.update(&i);
        assert_eq!(
            (d.action, &d.events),
            (r.action, &r.events),
            "{name}, row {k} (t = {} s)",
            r.t_s
        );
    }
    s
}

fn same(_: &mut SafetyInput) {}

fn params(f: fn(&mut SafetyParams)) -> SafetyParams {
    let mut p = SafetyParams::default();
    f(&mut p);
    p
}

#[test]
fn nothing_wrong_nothing_done() {
    run(
        "healthy",
        SafetyParams::default(),
        &[row(0.0, same, A::None, &[]), row(10.0, same, A::None, &[])],
    );
}

/// `COM_DL_LOSS_T` 5 s, `NAV_DLL_ACT` 2 (Return): Hold for `COM_FAIL_ACT_T` first, then Return;
/// the link back clears it (the vehicle keeps the mode it is in: the caller's part).
#[test]
fn gcs_link_loss_holds_then_returns_and_clears_when_the_link_returns() {
    let p = params(|p| p.gcs_loss_action = 2);
    run(
        "link loss",
        p,
        &[
            row(0.0, |i| i.gcs_link_age_s = Some(4.9), A::None, &[]),
            row(
                0.2,
                |i| i.gcs_link_age_s = Some(5.1),
                A::Hold,
                &[E::Triggered(C::GcsLinkLost, A::Hold)],
            ),
            row(5.1, |i| i.gcs_link_age_s = Some(10.0), A::Hold, &[]),
            row(
                5.2,
                |i| i.gcs_link_age_s = Some(10.1),
                A::Return,
                &[E::Escalated(C::GcsLinkLost, A::Return)],
            ),
            row(6.0, |i| i.gcs_link_age_s = Some(10.9), A::Return, &[]),
            row(
                7.0,
                |i| i.gcs_link_age_s = Some(0.0),
                A::None,
                &[E::Cleared(C::GcsLinkLost)],
            ),
        ],
    );
    // No action (PX4's default): the loss and the return are only said, armed or not.
    run(
        "link loss, no action",
        SafetyParams::default(),
        &[
            row(
                0.0,
                |i| i.gcs_link_age_s = Some(60.0),
                A::Warn,
                &[E::Triggered(C::GcsLinkLost, A::Warn)],
            ),
            row(1.0, |i| i.armed = false, A::Warn, &[]),
            row(
                2.0,
                |i| i.gcs_link_age_s = Some(0.5),
                A::None,
                &[E::Cleared(C::GcsLinkLost)],
            ),
        ],
    );
    assert_eq!(
        E::Cleared(C::GcsLinkLost).to_string(),
        "ground-station link regained"
    );
    // Never connected: nothing.
    run(
        "never connected",
        p,
        &[row(0.0, |i| i.gcs_link_age_s = None, A::None, &[])],
    );
    // No delay: Land at once.
    run(
        "link loss, no delay",
        params(|p| {
            p.gcs_loss_action = 3;
            p.action_delay_s = 0.0;
        }),
        &[row(
            0.0,
            |i| i.gcs_link_age_s = Some(6.0),
            A::Land,
            &[E::Triggered(C::GcsLinkLost, A::Land)],
        )],
    );
}

/// An action the vehicle cannot fly becomes the one it can: Return without home or position is
/// Land, Land without a position is Descend; on the ground, disarm.
#[test]
fn actions_degrade_to_what_the_vehicle_can_fly() {
    let p = params(|p| {
        p.gcs_loss_action = 2;
        p.action_delay_s = 0.0;
    });
    let lost = |i: &mut SafetyInput| i.gcs_link_age_s = Some(6.0);
    run(
        "no home",
        p,
        &[row(
            0.0,
            |i| {
                i.gcs_link_age_s = Some(6.0);
                i.home_set = false;
            },
            A::Land,
            &[E::Triggered(C::GcsLinkLost, A::Land)],
        )],
    );
    run(
        "position lost on the way",
        p,
        &[
            row(
                0.0,
                lost,
                A::Return,
                &[E::Triggered(C::GcsLinkLost, A::Return)],
            ),
            row(
                1.0,
                |i| i.position_valid = false,
                A::Descend,
                &[E::Triggered(C::PositionInvalid, A::Descend)],
            ),
        ],
    );
    run(
        "on the ground",
        p,
        &[row(
            0.0,
            |i| {
                i.gcs_link_age_s = Some(6.0);
                i.in_air = false;
            },
            A::Disarm,
            &[E::Triggered(C::GcsLinkLost, A::Disarm)],
        )],
    );
}

/// `COM_LOW_BAT_ACT` 3: warn at low, Return at critical, Land at emergency. Levels latch until
/// disarm (a recovering voltage does not undo them); the operator may take over from the
/// critical Return, never from the emergency Land.
#[test]
fn battery_levels_warn_return_land_and_latch_until_disarm() {
    let mut s = run(
        "battery",
        SafetyParams::default(),
        &[
            row(0.0, |i| i.battery_remaining = Some(0.16), A::None, &[]),
            row(
                1.0,
                |i| i.battery_remaining = Some(0.14),
                A::Warn,
                &[E::Triggered(C::BatteryLow, A::Warn)],
            ),
            row(
                2.0,
                |i| i.battery_remaining = Some(0.06),
                A::Return,
                &[E::Triggered(C::BatteryCritical, A::Return)],
            ),
            row(3.0, |i| i.battery_remaining = Some(0.2), A::Return, &[]),
        ],
    );
    assert_eq!(s.take_over(), Ok(()));
    let mut i = flying();
    i.t_s = 4.0;
    i.battery_remaining = Some(0.06);
    assert_eq!(s.update(&i).action, A::None, "overridden");
    i.battery_remaining = Some(0.04);
    let d = s.update(&i);
    assert_eq!(
        (d.action, d.events),
        (A::Land, vec![E::Triggered(C::BatteryEmergency, A::Land)])
    );
    let refused = s.take_over().unwrap_err();
    assert!(
        refused.to_string().contains("battery emergency"),
        "{refused}"
    );
    // Landed and disarmed with a recharged (or swapped) battery: all clear.
    i.armed = false;
    i.in_air = false;
    i.battery_remaining = Some(0.9);
    let d = s.update(&i);
    assert_eq!(d.action, A::None);
    assert_eq!(
        d.events,
        vec![
            E::Cleared(C::BatteryLow),
            E::Cleared(C::BatteryCritical),
            E::Cleared(C::BatteryEmergency)
        ]
    );
    // COM_LOW_BAT_ACT 0: warnings only; 4: terminate at emergency, latched.
    run(
        "warn only",
        params(|p| p.low_battery_action = 0),
        &[row(
            0.0,
            |i| i.battery_remaining = Some(0.01),
            A::Warn,
            &[
                E::Triggered(C::BatteryLow, A::Warn),
                E::Triggered(C::BatteryCritical, A::Warn),
                E::Triggered(C::BatteryEmergency, A::Warn),
            ],
        )],
    );
    let s = run(
        "terminate",
        params(|p| p.low_battery_action = 4),
        &[row(
            0.0,
            |i| i.battery_remaining = Some(0.04),
            A::Terminate,
            &[
                E::Triggered(C::BatteryLow, A::Warn),
                E::Triggered(C::BatteryCritical, A::Return),
                E::Triggered(C::BatteryEmergency, A::Terminate),
            ],
        )],
    );
    assert!(s.terminated());
}

/// A low battery on the ground warns (and keeps warning until it is charged); nothing else acts
/// while disarmed.
#[test]
fn disarmed_only_warnings() {
    run(
        "disarmed",
        params(|p| p.gcs_loss_action = 3),
        &[row(
            0.0,
            |i| {
                i.armed = false;
                i.in_air = false;
                i.battery_remaining = Some(0.06);
                i.gcs_link_age_s = Some(9.0);
            },
            A::Warn,
            &[E::Triggered(C::BatteryLow, A::Warn)],
        )],
    );
}

/// `GF_ACTION` 2: Hold while outside; back inside clears it; an operator's mode change silences
/// it until the next breach.
#[test]
fn geofence_breach_holds_until_back_inside_or_taken_over() {
    let mut s = run(
        "fence",
        SafetyParams::default(),
        &[
            row(
                0.0,
                |i| i.geofence_breached = true,
                A::Hold,
                &[E::Triggered(C::GeofenceBreach, A::Hold)],
            ),
            row(
                1.0,
                |i| i.geofence_breached = false,
                A::None,
                &[E::Cleared(C::GeofenceBreach)],
            ),
        ],
    );
    let mut i = flying();
    i.geofence_breached = true;
    assert_eq!(s.update(&i).action, A::Hold);
    s.take_over().unwrap();
    i.t_s = 2.0;
    assert_eq!(
        s.update(&i),
        SafetyDecision {
            action: A::None,
            cause: None,
            events: vec![]
        }
    );
    i.geofence_breached = false;
    i.t_s = 3.0;
    assert_eq!(s.update(&i).events, vec![E::Cleared(C::GeofenceBreach)]);
    i.geofence_breached = true;
    i.t_s = 4.0;
    assert_eq!(s.update(&i).action, A::Hold, "a new breach acts again");
}

/// Roll or pitch beyond `FD_FAIL_R`/`FD_FAIL_P` (60°) for `FD_FAIL_R_TTRI` (0.3 s): disarm.
#[test]
fn crash_detection_disarms_after_the_trigger_time() {
    run(
        "crash",
        SafetyParams::default(),
        &[
            row(0.0, |i| i.roll_pitch_rad = (1.2, 0.0), A::None, &[]),
            row(0.2, same, A::None, &[]),
            row(0.31, same, A::Disarm, &[E::Triggered(C::Crash, A::Disarm)]),
            row(
                0.32,
                |i| {
                    i.armed = false;
                    i.in_air = false;
                },
                A::None,
                &[E::Cleared(C::Crash)],
            ),
        ],
    );
    // A brief excursion (a flip manoeuvre's worth) does not.
    run(
        "brief",
        SafetyParams::default(),
        &[
            row(0.0, |i| i.roll_pitch_rad = (0.0, -1.3), A::None, &[]),
            row(0.2, |i| i.roll_pitch_rad = (0.0, 0.2), A::None, &[]),
            row(0.6, |i| i.roll_pitch_rad = (0.0, -1.3), A::None, &[]),
        ],
    );
}

/// A motor failure: `COM_ACT_FAIL_ACT` 0 warns and flies on; 3 returns, the operator may take
/// over, and it stays until disarm (the rotor does not come back).
#[test]
fn motor_failure_warns_or_returns_and_latches_until_disarm() {
    run(
        "warn",
        SafetyParams::default(),
        &[
            row(
                0.0,
                |i| i.motor_failed = true,
                A::Warn,
                &[E::Triggered(C::MotorFailure, A::Warn)],
            ),
            row(5.0, same, A::Warn, &[]),
        ],
    );
    let mut s = run(
        "return",
        params(|p| p.motor_failure_action = 3),
        &[
            row(
                0.0,
                |i| i.motor_failed = true,
                A::Return,
                &[E::Triggered(C::MotorFailure, A::Return)],
            ),
            row(0.1, same, A::Return, &[]),
        ],
    );
    s.take_over().unwrap();
    let mut i = flying();
    i.motor_failed = true;
    i.t_s = 0.2;
    assert_eq!(s.update(&i).action, A::None, "taken over");
    i.armed = false;
    i.in_air = false;
    i.motor_failed = false;
    i.t_s = 0.3;
    assert_eq!(s.update(&i).events, [E::Cleared(C::MotorFailure)]);
}

/// A quad spinning on three rotors lands when the action would warn or hold, and returns when
/// asked to; termination stays termination.
#[test]
fn a_quad_spinning_on_three_rotors_lands_or_returns() {
    for (action, expected) in [
        (0, A::Land),
        (1, A::Land),
        (2, A::Land),
        (3, A::Return),
        (4, A::Terminate),
    ] {
        let mut s = Safety::new(SafetyParams {
            motor_failure_action: action,
            ..SafetyParams::default()
        });
        let mut i = flying();
        i.motor_failed = true;
        i.spinning = true;
        let d = s.update(&i);
        assert_eq!(d.action, expected, "COM_ACT_FAIL_ACT {action}");
        assert_eq!(d.events, [E::Triggered(C::MotorFailure, expected)]);
    }
}

/// Estimator and sensor failures: the estimate's validity decides (Descend without position or
/// altitude); a lost sensor warns; a position loss only matters to modes that fly on it.
#[test]
fn estimator_and_sensor_failures() {
    run(
        "GPS lost in Position",
        SafetyParams::default(),
        &[
            row(
                0.0,
                |i| i.sensors_lost.gps = true,
                A::Warn,
                &[E::Triggered(C::GpsLost, A::Warn)],
            ),
            row(
                1.0,
                |i| i.position_valid = false,
                A::Descend,
                &[E::Triggered(C::PositionInvalid, A::Descend)],
            ),
            row(
                2.0,
                |i| i.mode_needs_position = false,
                A::Warn,
                &[E::Cleared(C::PositionInvalid)],
            ),
            row(
                3.0,
                |i| {
                    i.sensors_lost.gps = false;
                    i.position_valid = true;
                },
                A::None,
                &[E::Cleared(C::GpsLost)],
            ),
        ],
    );
    run(
        "baro lost",
        SafetyParams::default(),
        &[
            row(
                0.0,
                |i| i.sensors_lost.baro = true,
                A::Warn,
                &[E::Triggered(C::BaroLost, A::Warn)],
            ),
            row(
                1.0,
                |i| i.altitude_valid = false,
                A::Descend,
                &[E::Triggered(C::AltitudeInvalid, A::Descend)],
            ),
            // The altitude back: still descending (cleared only at disarm).
            row(
                2.0,
                |i| {
                    i.sensors_lost.baro = false;
                    i.altitude_valid = true;
                },
                A::Descend,
                &[E::Cleared(C::BaroLost)],
            ),
        ],
    );
    let mut s = run(
        "attitude",
        SafetyParams::default(),
        &[row(
            0.0,
            |i| {
                i.sensors_lost.imu = true;
                i.attitude_valid = false;
            },
            A::Descend,
            &[
                E::Triggered(C::AttitudeInvalid, A::Descend),
                E::Triggered(C::ImuLost, A::Warn),
            ],
        )],
    );
    assert!(s.take_over().is_err(), "no way out of a blind descent");
}

/// Several at once: the most severe wins, and the cause says which.
#[test]
fn the_most_severe_action_wins() {
    let p = params(|p| {
        p.gcs_loss_action = 3;
        p.action_delay_s = 0.0;
    });
    let mut s = Safety::new(p);
    let mut i = flying();
    i.geofence_breached = true;
    i.gcs_link_age_s = Some(7.0);
    i.battery_remaining = Some(0.1);
    let d = s.update(&i);
    assert_eq!((d.action, d.cause), (A::Land, Some(C::GcsLinkLost)));
    assert_eq!(
        s.active(),
        vec![C::GcsLinkLost, C::BatteryLow, C::GeofenceBreach]
    );
}

#[test]
fn inconsistent_battery_levels_are_reported() {
    assert!(SafetyParams::default().inconsistencies().is_empty());
    let p = params(|p| p.battery_critical = 0.2);
    assert_eq!(p.inconsistencies().len(), 1);
}

/// Arming checks: each failure alone, and whether a forced arm may skip it.
#[test]
fn preflight_checks_each_reason_and_what_force_skips() {
    let ok = PreflightInput {
        attitude_valid: true,
        gyro_bias_settled: true,
        position_valid: true,
        altitude_valid: true,
        mode_needs_position: true,
        sensors_lost: SensorsLost::default(),
        mag: MagStatus {
            calibrated: true,
            measured: Some(MagField {
                strength_gauss: 0.5,
                inclination_deg: 60.0,
            }),
            expected: MagField {
                strength_gauss: 0.48,
                inclination_deg: 63.3,
            },
        },
        battery_remaining: Some(0.9),
        params_invalid: None,
        roll_pitch_rad: (0.0, 0.0),
        geofence_breached: false,
        motor_failed: None,
        terminated: false,
    };
    let p = SafetyParams::default();
    assert!(preflight(&ok, &p).is_empty());
    type Change = fn(&mut PreflightInput);
    let table: [(Change, &str, bool); 16] = [
        (|i| i.terminated = true, "flight terminated", false),
        (|i| i.sensors_lost.imu = true, "IMU", false),
        (|i| i.motor_failed = Some(3), "motor 3 failed", false),
        (|i| i.roll_pitch_rad = (0.5, 0.0), "tilted 29°", false),
        (|i| i.battery_remaining = Some(0.04), "emergency", false),
        (
            |i| i.battery_remaining = Some(0.1),
            "battery low (10 %)",
            true,
        ),
        (
            |i| i.params_invalid = Some("x".into()),
            "parameters invalid",
            false,
        ),
        (|i| i.attitude_valid = false, "attitude", true),
        (
            |i| i.gyro_bias_settled = false,
            "gyro bias not settled",
            true,
        ),
        (|i| i.position_valid = false, "position", true),
        (|i| i.altitude_valid = false, "altitude", true),
        (
            |i| i.sensors_lost.mag = true,
            "magnetometer silent or frozen",
            true,
        ),
        (|i| i.mag.calibrated = false, "not calibrated", true),
        (
            |i| i.mag.measured.as_mut().unwrap().strength_gauss = 0.72,
            "mag field 0.72 G, expected 0.48 G",
            true,
        ),
        (
            |i| i.mag.measured.as_mut().unwrap().inclination_deg = 40.0,
            "mag inclination 40°, expected 63°",
            true,
        ),
        (|i| i.geofence_breached = true, "geofence", true),
    ];
    for (change, text, skippable) in table {
        let mut i = ok.clone();
        change(&mut i);
        let f = preflight(&i, &p);
        assert_eq!(f.len(), 1, "{text}: {f:?}");
        let said = f[0].check.to_string();
        assert!(said.contains(text), "{text}: {said}");
        assert_eq!(f[0].skippable, skippable, "{text}");
    }
    // A mode that needs no position arms without one (and without the GPS).
    let mut i = ok.clone();
    i.mode_needs_position = false;
    i.position_valid = false;
    i.sensors_lost.gps = true;
    assert!(preflight(&i, &p).is_empty());
    // COM_ARM_BAT_MIN above the low level.
    let mut i = ok;
    i.battery_remaining = Some(0.3);
    let strict = params(|p| p.arm_battery_min = 0.5);
    assert_eq!(preflight(&i, &strict).len(), 1);
}

/// The numbered log: read from any point, what fell out counted, a new log read from its start.
#[test]
fn the_safety_log_gives_each_event_once_and_counts_what_it_lost() {
    let mut log = SafetyLog::default();
    let e = |k: usize| E::Triggered(CONDITIONS[k % CONDITIONS.len()], A::Warn);
    for k in 0..3 {
        log.push(e(k));
    }
    let read = |log: &SafetyLog, seen| {
        let (missed, events) = log.since(seen);
        (missed, events.collect::<Vec<_>>())
    };
    assert_eq!(read(&log, 0), (0, vec![e(0), e(1), e(2)]));
    assert_eq!(read(&log, 2), (0, vec![e(2)]));
    assert_eq!(read(&log, 3), (0, vec![]));
    for k in 3..20 {
        log.push(e(k));
    }
    let (missed, events) = read(&log, 3);
    assert_eq!((missed, events.len()), (1, SafetyLog::LEN));
    assert_eq!(events[0], e(4));
    assert_eq!(read(&SafetyLog::default(), 7), (0, vec![]), "a new log");
}
