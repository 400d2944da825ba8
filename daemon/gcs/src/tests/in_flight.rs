//! In flight: sticks, messages on request, mission progress and commands, failsafes and health
//! said, long texts in chunks.
#![allow(clippy::unwrap_used)]

use super::*;

#[test]
fn manual_control_reaches_the_vehicle_as_sticks_and_a_loss_is_reported() {
    let mut g = GroundStation::new(1, MavType::MAV_TYPE_QUADROTOR);
    let mut t = telemetry(true, FlightMode::Posctl);
    let manual = |target, x, z| {
        MavMessage::MANUAL_CONTROL(MANUAL_CONTROL_DATA {
            x,
            y: -1000,
            z,
            r: i16::MAX,
            target,
            ..Default::default()
        })
    };
    let mut out = Outbox::default();
    g.on_message(&gcs_header(), &manual(1, 500, 750), &t, &mut out);
    assert_eq!(
        crate::testing::sticks(&out),
        Some(Sticks {
            forward: 0.5,
            right: -1.0,
            throttle: 0.75,
            yaw: 0.0
        })
    );
    assert!(out.messages.is_empty(), "never answered");
    let mut out = Outbox::default();
    g.on_message(&gcs_header(), &manual(2, 500, 750), &t, &mut out);
    assert_eq!(crate::testing::sticks(&out), None, "another vehicle's");
    g.on_message(&gcs_header(), &manual(1, 3000, -200), &t, &mut out);
    let s = crate::testing::sticks(&out).unwrap();
    assert_eq!((s.forward, s.throttle), (1.0, 0.0), "clamped");

    let mut out = Outbox::default();
    g.poll(0.0, &t, &mut out);
    if let Some(s) = t.vehicle.as_mut().map(|v| &mut v.status) {
        s.manual_losses = 1;
        s.mode = FlightMode::Rtl;
    }
    g.poll(0.01, &t, &mut out);
    g.poll(0.02, &t, &mut out);
    assert_eq!(statustexts(&out), ["manual control lost: RTL"]);
}

#[test]
fn on_request_messages_can_be_asked_for_and_say_which_set_point_axes_are_flown() {
    let mut g = GroundStation::new(1, MavType::MAV_TYPE_QUADROTOR);
    let mut t = telemetry(true, FlightMode::Posctl);
    let mut out = Outbox::default();
    for id in streams::ON_REQUEST {
        let set = command_long(
            MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL,
            [id as f32, 100_000.0, 0., 0., 0., 0., 0.],
            (1, 1),
        );
        g.on_message(&gcs_header(), &set, &t, &mut out);
    }
    assert!(
        acks(&out)
            .iter()
            .all(|a| a.result == MavResult::MAV_RESULT_ACCEPTED),
        "{:?}",
        acks(&out)
    );
    // No data yet (no set-point, no truth): asked for, refused for now.
    let mut out = Outbox::default();
    let ask = |id: u32| {
        command_long(
            MavCmd::MAV_CMD_REQUEST_MESSAGE,
            [id as f32, 0., 0., 0., 0., 0., 0.],
            (1, 1),
        )
    };
    g.on_message(
        &gcs_header(),
        &ask(HIL_STATE_QUATERNION_DATA::ID),
        &t,
        &mut out,
    );
    assert_eq!(
        acks(&out)[0].result,
        MavResult::MAV_RESULT_TEMPORARILY_REJECTED
    );
    // Velocity horizontally, position vertically (POSCTL with the pitch stick forward).
    t.vehicle.as_mut().unwrap().setpoint = Some(flight_core::control::Setpoint::Position(
        flight_core::control::position::PositionSetpoint {
            pos_ned_m: nalgebra::Vector3::new(f64::NAN, f64::NAN, -5.0),
            vel_ned_m_s: nalgebra::Vector3::new(3.0, 0.0, f64::NAN),
            accel_ned_m_s2: nalgebra::Vector3::zeros(),
            yaw_rad: 0.5,
        },
    ));
    let mut out = Outbox::default();
    g.on_message(
        &gcs_header(),
        &ask(POSITION_TARGET_LOCAL_NED_DATA::ID),
        &t,
        &mut out,
    );
    assert_eq!(acks(&out)[0].result, MavResult::MAV_RESULT_ACCEPTED);
    g.poll(100.0, &t, &mut out);
    let target = out
        .messages
        .iter()
        .find_map(|m| match m {
            Outgoing::Message(MavMessage::POSITION_TARGET_LOCAL_NED(p)) => Some(p.clone()),
            _ => None,
        })
        .unwrap();
    use PositionTargetTypemask as M;
    assert_eq!(
        target.type_mask,
        M::POSITION_TARGET_TYPEMASK_X_IGNORE
            | M::POSITION_TARGET_TYPEMASK_Y_IGNORE
            | M::POSITION_TARGET_TYPEMASK_VZ_IGNORE
            | M::POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE
    );
    assert_eq!((target.z, target.vx, target.yaw), (-5.0, 3.0, 0.5));
}

#[test]
fn mission_progress_is_streamed_and_each_reached_item_reported_once() {
    use flight_core::mission::{MissionState as S, MissionStatus};
    let mut g = GroundStation::new(1, MavType::MAV_TYPE_QUADROTOR);
    let mut t = telemetry(true, FlightMode::Mission);
    let with = |t: &mut Telemetry, current, state, reached: &[u16]| {
        let mut m = MissionStatus {
            current,
            total: 4,
            state,
            ..Default::default()
        };
        for &seq in reached {
            m.reached_recent[m.reached_count as usize % 8] = seq;
            m.reached_count += 1;
        }
        t.vehicle.as_mut().map(|v| &mut v.status).unwrap().mission = m;
    };
    let current = |out: &Outbox| -> Vec<MISSION_CURRENT_DATA> {
        out.messages
            .iter()
            .filter_map(|m| match m {
                Outgoing::Message(MavMessage::MISSION_CURRENT(c)) => Some(c.clone()),
                _ => None,
            })
            .collect()
    };
    let reached = |out: &Outbox| -> Vec<u16> {
        out.messages
            .iter()
            .filter_map(|m| match m {
                Outgoing::Message(MavMessage::MISSION_ITEM_REACHED(r)) => Some(r.seq),
                _ => None,
            })
            .collect()
    };
    with(&mut t, 0, S::Active, &[]);
    let mut out = Outbox::default();
    g.poll(0.0, &t, &mut out);
    let c = current(&out);
    assert_eq!(c.len(), 1);
    assert_eq!((c[0].seq, c[0].total, c[0].mission_mode), (0, 4, 1));
    assert_eq!(c[0].mission_state, MissionState::MISSION_STATE_ACTIVE);
    // 1 Hz, and at once on a change.
    let mut out = Outbox::default();
    g.poll(0.5, &t, &mut out);
    assert!(current(&out).is_empty());
    g.poll(1.01, &t, &mut out);
    assert_eq!(current(&out).len(), 1);
    with(&mut t, 2, S::Active, &[0, 1]);
    let mut out = Outbox::default();
    g.poll(1.1, &t, &mut out);
    assert_eq!(current(&out)[0].seq, 2);
    assert_eq!(reached(&out), [0, 1]);
    let mut out = Outbox::default();
    with(&mut t, 4, S::Complete, &[0, 1, 2, 3]);
    g.poll(1.2, &t, &mut out);
    assert_eq!(reached(&out), [2, 3], "each once");
    let c = current(&out);
    assert_eq!(
        (c[0].seq, c[0].mission_state),
        (4, MissionState::MISSION_STATE_COMPLETE)
    );
    // No mission: total is UINT16_MAX.
    with(&mut t, 0, S::NoMission, &[]);
    t.vehicle
        .as_mut()
        .map(|v| &mut v.status)
        .unwrap()
        .mission
        .total = 0;
    let mut out = Outbox::default();
    g.poll(1.3, &t, &mut out);
    assert_eq!(current(&out)[0].total, u16::MAX);
}

#[test]
fn mission_and_guided_commands_reach_the_vehicle() {
    use flight_core::mission::{MissionAltitude, SpeedChange};
    let mut g = GroundStation::new(1, MavType::MAV_TYPE_QUADROTOR);
    let t = telemetry(true, FlightMode::Loiter);
    let run = |g: &mut GroundStation, m: MavMessage| {
        let mut out = Outbox::default();
        g.on_message(&gcs_header(), &m, &t, &mut out);
        out
    };
    let one = |out: Outbox| {
        assert_eq!(
            crate::testing::requested(&out).len(),
            1,
            "{:?}",
            out.messages
        );
        crate::testing::requested(&out)[0].clone()
    };
    let long = |c, p| command_long(c, p, (1, 1));
    let nan = f32::NAN;
    let (v, _) = one(run(
        &mut g,
        long(
            MavCmd::MAV_CMD_MISSION_START,
            [2.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        ),
    ));
    assert_eq!(v, AutopilotCommand::StartMission(Some(2)));
    let (v, _) = one(run(
        &mut g,
        long(MavCmd::MAV_CMD_DO_PAUSE_CONTINUE, [0.0; 7]),
    ));
    assert_eq!(v, AutopilotCommand::SetMode(FlightMode::Loiter));
    let (v, _) = one(run(
        &mut g,
        long(
            MavCmd::MAV_CMD_DO_CHANGE_SPEED,
            [1.0, 7.5, -1.0, 0.0, 0.0, 0.0, 0.0],
        ),
    ));
    assert_eq!(v, AutopilotCommand::ChangeSpeed(SpeedChange::To(7.5)));
    let (v, _) = one(run(
        &mut g,
        long(
            MavCmd::MAV_CMD_CONDITION_YAW,
            [90.0, 20.0, -1.0, 1.0, 0.0, 0.0, 0.0],
        ),
    ));
    assert_eq!(
        v,
        AutopilotCommand::ConditionYaw {
            angle_deg: 90.0,
            rate_deg_s: Some(20.0),
            direction: -1,
            relative: true
        }
    );
    // MAVSDK's goto_location: COMMAND_INT, GLOBAL frame (AMSL), change-mode flag.
    let (v, _) = one(run(
        &mut g,
        MavMessage::COMMAND_INT(COMMAND_INT_DATA {
            param1: -1.0,
            param2: 1.0,
            param3: 0.0,
            param4: 0.5,
            x: 473_977_420,
            y: 85_455_940,
            z: 500.0,
            command: MavCmd::MAV_CMD_DO_REPOSITION,
            target_system: 1,
            target_component: 1,
            frame: MavFrame::MAV_FRAME_GLOBAL,
            current: 0,
            autocontinue: 0,
        }),
    ));
    match v {
        AutopilotCommand::Reposition {
            at,
            speed_m_s: None,
            yaw_rad: Some(0.5),
            change_mode: true,
        } => {
            assert_eq!(at.lat_lon_deg, Some((47.397742, 8.545594)));
            assert_eq!(at.alt, Some(MissionAltitude::Amsl(500.0)));
        }
        other => panic!("{other:?}"),
    }
    // COMMAND_LONG form, relative frame not expressible: AMSL; NaN altitude keeps it.
    let (v, _) = one(run(
        &mut g,
        long(
            MavCmd::MAV_CMD_DO_REPOSITION,
            [3.0, 0.0, 0.0, nan, 47.0, 8.0, nan],
        ),
    ));
    match v {
        AutopilotCommand::Reposition { at, speed_m_s, .. } => {
            assert_eq!(at.alt, None);
            assert_eq!(speed_m_s, Some(3.0));
        }
        other => panic!("{other:?}"),
    }
    // MISSION_SET_CURRENT: to the vehicle, never a COMMAND_ACK; a refusal is a STATUSTEXT.
    let (v, to) = one(run(
        &mut g,
        MavMessage::MISSION_SET_CURRENT(MISSION_SET_CURRENT_DATA {
            seq: 3,
            target_system: 1,
            target_component: 1,
        }),
    ));
    assert_eq!(v, AutopilotCommand::SetMissionCurrent(3));
    let mut out = Outbox::default();
    g.answered(to, Ok(()), &mut out);
    assert!(out.messages.is_empty());
    let no_item = Denial::NoMissionItem { seq: 3, count: 2 };
    g.answered(to, Err(no_item), &mut out);
    assert_eq!(
        statustexts(&out),
        ["mission item 3 does not exist (2 items)"]
    );
    assert!(acks(&out).is_empty());
}

/// A ground station's heartbeat restarts the link-loss clock (a vehicle's does not); each
/// failsafe's start, change and end is announced once.
#[test]
fn gcs_heartbeats_are_forwarded_and_failsafes_announced() {
    use flight_core::safety::failsafe::{Condition, FailsafeAction, SafetyEvent};
    let mut g = GroundStation::new(1, MavType::MAV_TYPE_QUADROTOR);
    let mut t = telemetry(true, FlightMode::Loiter);
    let heartbeat = |mavtype| {
        MavMessage::HEARTBEAT(HEARTBEAT_DATA {
            mavtype,
            ..Default::default()
        })
    };
    let mut out = Outbox::default();
    g.on_message(
        &gcs_header(),
        &heartbeat(MavType::MAV_TYPE_QUADROTOR),
        &t,
        &mut out,
    );
    assert!(!out.gcs_heartbeat);
    g.on_message(
        &gcs_header(),
        &heartbeat(MavType::MAV_TYPE_GCS),
        &t,
        &mut out,
    );
    assert!(out.gcs_heartbeat);

    let mut out = Outbox::default();
    g.poll(0.0, &t, &mut out);
    // The state machine's events, as many as happened between two looks at the status: a
    // crash that disarmed within the same step is said as surely as a battery running down.
    use SafetyEvent::{Cleared, Triggered};
    let steps: [&[SafetyEvent]; 5] = [
        &[Triggered(Condition::BatteryLow, FailsafeAction::Warn)],
        &[Triggered(
            Condition::BatteryCritical,
            FailsafeAction::Return,
        )],
        &[],
        &[
            Triggered(Condition::MagLost, FailsafeAction::Warn),
            Cleared(Condition::MagLost),
        ],
        &[
            Triggered(Condition::Crash, FailsafeAction::Disarm),
            Cleared(Condition::Crash),
            Cleared(Condition::BatteryLow),
        ],
    ];
    for (k, events) in steps.into_iter().enumerate() {
        if let Some(st) = t.vehicle.as_mut().map(|v| &mut v.status) {
            for &e in events {
                st.safety_log.push(e);
            }
        }
        g.poll(0.01 * (k + 1) as f64, &t, &mut out);
    }
    assert_eq!(
        statustexts(&out),
        [
            "battery low",
            "failsafe: battery critical: Return",
            "magnetometer lost",
            "failsafe over: magnetometer lost",
            "failsafe: attitude failure (crash or flip): disarm",
            "failsafe over: attitude failure (crash or flip)",
            "failsafe over: battery low",
        ]
    );
    // More than the log keeps between two looks: what was lost is counted.
    let mut out = Outbox::default();
    if let Some(st) = t.vehicle.as_mut().map(|v| &mut v.status) {
        for _ in 0..10 {
            st.safety_log
                .push(Triggered(Condition::MagLost, FailsafeAction::Warn));
            st.safety_log.push(Cleared(Condition::MagLost));
        }
    }
    g.poll(1.0, &t, &mut out);
    let said = statustexts(&out);
    assert_eq!(said.len(), 17, "{said:?}");
    assert_eq!(said[0], "4 failsafe messages missed");
}

/// A failed motor is said once: on a hexa as flying on the others, on a quad that spins on its
/// other three as such, and on a quad that does not (`CA_FAILURE_MODE` 0) as lost.
#[test]
fn a_motor_failure_is_said_once_with_how_the_vehicle_flies_on() {
    for (mav_type, spinning, said) in [
        (
            MavType::MAV_TYPE_HEXAROTOR,
            false,
            "motor 2 failed: flying on the others",
        ),
        (
            MavType::MAV_TYPE_QUADROTOR,
            true,
            "motor 1 failed: flying on three rotors, spinning",
        ),
        (
            MavType::MAV_TYPE_QUADROTOR,
            false,
            "motor 2 failed: cannot fly on three rotors",
        ),
    ] {
        let mut g = GroundStation::new(1, mav_type);
        let mut t = telemetry(true, FlightMode::Loiter);
        let mut out = Outbox::default();
        g.poll(0.0, &t, &mut out);
        if let Some(st) = t.vehicle.as_mut().map(|v| &mut v.status) {
            st.motor_failed = Some(if spinning { 1 } else { 2 });
            st.spinning = spinning;
        }
        g.poll(0.1, &t, &mut out);
        g.poll(0.2, &t, &mut out);
        assert_eq!(statustexts(&out), [said]);
    }
}

/// A reset of the attitude estimate is said once per reset, with its size; the counts starting
/// again (a restarted sensor source) say the next one again.
#[test]
fn an_attitude_estimate_reset_is_said_once() {
    use flight_core::core::StepOutput;
    use flight_core::estimator::attitude::{AttitudeEstimate, EstimateReset};
    let mut g = GroundStation::new(1, MavType::MAV_TYPE_QUADROTOR);
    let mut t = telemetry(false, FlightMode::Loiter);
    let estimate = |reset| AttitudeEstimate {
        q: nalgebra::UnitQuaternion::identity(),
        euler_rad: (0.0, 0.0, 0.0),
        rate: nalgebra::Vector3::zeros(),
        gyro_bias: nalgebra::Vector3::zeros(),
        accel_bias: nalgebra::Vector3::zeros(),
        valid: true,
        realigning: false,
        bias_settled: true,
        imu_still: false,
        reset,
    };
    let mut out = Outbox::default();
    let mut at = |g: &mut GroundStation, t: &mut Telemetry, s: f64, reset| {
        t.vehicle.as_mut().unwrap().estimate = Some(StepOutput {
            attitude: Some(estimate(reset)),
            ..Default::default()
        });
        g.poll(s, t, &mut out);
        statustexts(&out)
    };
    assert!(at(&mut g, &mut t, 0.0, EstimateReset::default()).is_empty());
    let tilt = EstimateReset {
        tilt: 1,
        tilt_rad: 23f64.to_radians(),
        ..Default::default()
    };
    at(&mut g, &mut t, 0.1, tilt);
    let heading = EstimateReset {
        heading: 1,
        heading_rad: -120f64.to_radians(),
        ..tilt
    };
    at(&mut g, &mut t, 0.2, heading);
    at(&mut g, &mut t, 0.3, EstimateReset::default());
    let said = at(&mut g, &mut t, 0.4, tilt);
    assert_eq!(
        said,
        [
            "attitude estimate reset: tilt was 23 deg off",
            "attitude estimate reset: heading was -120 deg off",
            "attitude estimate reset: tilt was 23 deg off",
        ]
    );
}

/// `SYS_STATUS` health bits follow the checks (a lost magnetometer clears the magnetometer's bit,
/// a critical battery the battery's, a motor failure the motor outputs'), the pre-arm bit the
/// arming checks; the battery estimate reaches `SYS_STATUS` and `BATTERY_STATUS`.
#[test]
fn sys_status_health_bits_and_battery_follow_the_checks() {
    use flight_core::safety::failsafe::{CONDITIONS, Condition};
    use flight_core::sensors::battery::BatteryState;
    let bit = |c: Condition| 1u32 << CONDITIONS.iter().position(|k| *k == c).unwrap();
    let mut t = telemetry(false, FlightMode::Loiter);
    t.vehicle.as_mut().unwrap().battery = BatteryState {
        voltage_v: 15.1,
        current_a: Some(12.34),
        consumed_mah: Some(1234.4),
        cell_v_at_rest: 3.8,
        remaining: Some(0.123),
        time_remaining_s: Some(95.2),
    };
    let health = |t: &Telemetry| {
        let Some(MavMessage::SYS_STATUS(s)) = streams::build(SYS_STATUS_DATA::ID, t, 0) else {
            panic!()
        };
        s
    };
    use MavSysStatusSensor as S;
    let s = health(&t);
    let all = S::MAV_SYS_STATUS_SENSOR_3D_MAG
        | S::MAV_SYS_STATUS_SENSOR_BATTERY
        | S::MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS
        | S::MAV_SYS_STATUS_PREARM_CHECK;
    assert!(s.onboard_control_sensors_health.contains(all), "{s:?}");
    assert_eq!((s.current_battery, s.battery_remaining), (1234, 12));
    if let Some(st) = t.vehicle.as_mut().map(|v| &mut v.status) {
        st.failsafe_conditions = bit(Condition::MagLost)
            | bit(Condition::BatteryLow)
            | bit(Condition::BatteryCritical)
            | bit(Condition::MotorFailure);
        st.prearm_ok = false;
    }
    let s = health(&t);
    assert!(!s.onboard_control_sensors_health.intersects(all), "{s:?}");
    assert!(
        s.onboard_control_sensors_health
            .contains(S::MAV_SYS_STATUS_SENSOR_3D_GYRO | S::MAV_SYS_STATUS_SENSOR_3D_ACCEL),
        "the others stay healthy: {s:?}"
    );
    assert!(s.onboard_control_sensors_present.contains(all));
    assert!(
        s.onboard_control_sensors_present_extended.is_empty(),
        "no recovery system: {s:?}"
    );
    let Some(MavMessage::BATTERY_STATUS(b)) = streams::build(BATTERY_STATUS_DATA::ID, &t, 0) else {
        panic!()
    };
    assert_eq!(
        (
            b.current_battery,
            b.current_consumed,
            b.battery_remaining,
            b.time_remaining
        ),
        (1234, 1234, 12, 95)
    );
    assert_eq!(
        b.charge_state,
        MavBatteryChargeState::MAV_BATTERY_CHARGE_STATE_CRITICAL
    );
    assert_eq!(b.voltages[0], 16000, "the reported voltage");
}

/// The `STATUSTEXT`s `out` holds: (id, chunk_seq, text bytes up to the first NUL).
fn statustext_chunks(out: &Outbox) -> Vec<(u16, u8, Vec<u8>)> {
    out.messages
        .iter()
        .filter_map(|m| match m {
            Outgoing::Message(MavMessage::STATUSTEXT(s)) => {
                let bytes: [u8; 50] = s.text.into();
                let end = bytes.iter().position(|&b| b == 0).unwrap_or(50);
                Some((s.id, s.chunk_seq, bytes[..end].to_vec()))
            }
            _ => None,
        })
        .collect()
}

/// Texts of up to 50 bytes go whole (id 0); longer ones in 50-byte chunks under one new id,
/// the last shorter (empty when the text fills its chunks), which reassemble to the text.
#[test]
fn long_texts_go_in_chunks_that_reassemble() {
    let mut out = Outbox::default();
    let short = "failsafe: ground-station link lost: Return now";
    out.say(MavSeverity::MAV_SEVERITY_WARNING, short);
    assert_eq!(
        statustext_chunks(&out),
        vec![(0, 0, short.as_bytes().to_vec())]
    );

    for (len, chunks) in [(51, 2), (100, 3), (120, 3), (150, 4)] {
        let mut out = Outbox::default();
        out.say(
            MavSeverity::MAV_SEVERITY_INFO,
            "first long one: which takes id 1, 50 bytes and more",
        );
        let text: String = ('a'..='z').cycle().take(len).collect();
        out.say(MavSeverity::MAV_SEVERITY_INFO, &text);
        let sent: Vec<_> = statustext_chunks(&out).into_iter().skip(2).collect();
        assert_eq!(sent.len(), chunks, "{len} bytes");
        assert!(
            sent.iter().all(|(id, _, _)| *id == 2),
            "one new id: {sent:?}"
        );
        assert!(
            sent.iter()
                .enumerate()
                .all(|(k, (_, seq, _))| usize::from(*seq) == k)
        );
        let (last, full) = sent.split_last().unwrap();
        assert!(full.iter().all(|(_, _, b)| b.len() == 50));
        assert!(last.2.len() < 50);
        let whole: Vec<u8> = sent.iter().flat_map(|(_, _, b)| b.clone()).collect();
        assert_eq!(whole, text.as_bytes());
    }
}

#[test]
fn protocol_version_origin_mission_and_component_metadata_are_answered_on_request() {
    // (The origin once the estimator has one: tests/python/test_component_metadata.py.)
    let t = telemetry(true, FlightMode::Loiter);
    let ask = |g: &mut GroundStation, id: u32| {
        let mut out = Outbox::default();
        let m = command_long(
            MavCmd::MAV_CMD_REQUEST_MESSAGE,
            [id as f32, 0., 0., 0., 0., 0., 0.],
            (1, 1),
        );
        g.on_message(&gcs_header(), &m, &t, &mut out);
        let result = acks(&out)[0].result;
        let mut sent = Outbox::default();
        g.poll(0.0, &t, &mut sent);
        let found = sent.messages.iter().any(|o| match o {
            Outgoing::Message(m) => m.message_id() == id,
            Outgoing::Raw(i, _) => *i == id,
        });
        (result, found)
    };
    let accepted = (MavResult::MAV_RESULT_ACCEPTED, true);
    let mut g = GroundStation::new(1, MavType::MAV_TYPE_QUADROTOR);
    for id in [
        PROTOCOL_VERSION_DATA::ID,
        MISSION_CURRENT_DATA::ID,
        AUTOPILOT_VERSION_DATA::ID,
    ] {
        assert_eq!(ask(&mut g, id), accepted, "{id}");
    }
    // Known, but no origin yet: refused for now.
    let origin = ask(&mut g, GPS_GLOBAL_ORIGIN_DATA::ID);
    assert_eq!(origin, (MavResult::MAV_RESULT_TEMPORARILY_REJECTED, false));
    // Component metadata only when its files are served.
    let refused = ask(&mut g, COMPONENT_METADATA_DATA::ID);
    assert_ne!(refused.0, MavResult::MAV_RESULT_ACCEPTED);
    let mut g = g.with_component_metadata("mftp://[;comp=1]@META/general.json", 7);
    assert_eq!(ask(&mut g, COMPONENT_METADATA_DATA::ID), accepted);
    assert_eq!(ask(&mut g, COMPONENT_INFORMATION_DATA::ID), accepted);
}
