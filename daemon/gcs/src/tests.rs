//! The ground-station protocol: commands and their acks, modes, streams (the parameter protocol
//! and what is said in flight in the files beside this one), and the helpers every test of it
//! shares.
#![allow(clippy::unwrap_used)]
use super::*;
pub(crate) use crate::testing::telemetry;
use flight_core::commander::Sticks;
use mavlink::{MavHeader, Message};
use params::Parameters;

mod in_flight;
mod parameters;

pub(crate) fn gcs_header() -> MavHeader {
    MavHeader {
        system_id: 255,
        component_id: 190,
        sequence: 0,
    }
}

pub(crate) use crate::testing::command_long;

pub(crate) fn acks(out: &Outbox) -> Vec<&COMMAND_ACK_DATA> {
    out.messages
        .iter()
        .filter_map(|m| match m {
            Outgoing::Message(MavMessage::COMMAND_ACK(a)) => Some(a),
            _ => None,
        })
        .collect()
}

#[test]
fn commands_for_us_reach_the_vehicle_and_others_are_ignored() {
    let mut g = GroundStation::new(1, MavType::MAV_TYPE_QUADROTOR);
    let t = telemetry(false, FlightMode::Loiter);
    let arm = [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0];
    let mut out = Outbox::default();
    // Target component 0 (pymavlink's default) and 1 are ours; system 0 is everyone.
    for target in [(1, 0), (1, 1), (0, 0)] {
        g.on_message(
            &gcs_header(),
            &command_long(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, arm, target),
            &t,
            &mut out,
        );
    }
    assert_eq!(crate::testing::requested(&out).len(), 3);
    assert_eq!(
        crate::testing::requested(&out)[0].0,
        AutopilotCommand::Arm { force: false }
    );
    assert_eq!(
        (
            crate::testing::requested(&out)[0].1.system,
            crate::testing::requested(&out)[0].1.component
        ),
        (255, 190)
    );
    // Another system's, or another component's: no ack, nothing done.
    let mut out = Outbox::default();
    for target in [(2, 1), (1, 100)] {
        g.on_message(
            &gcs_header(),
            &command_long(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, arm, target),
            &t,
            &mut out,
        );
    }
    assert!(crate::testing::requested(&out).is_empty() && out.messages.is_empty());
    // Force, and a NaN where a value is needed: denied with a reason.
    let mut out = Outbox::default();
    let force = [0.0, 21196.0, 0.0, 0.0, 0.0, 0.0, 0.0];
    g.on_message(
        &gcs_header(),
        &command_long(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, force, (1, 1)),
        &t,
        &mut out,
    );
    assert_eq!(
        crate::testing::requested(&out)[0].0,
        AutopilotCommand::Disarm { force: true }
    );
    let mut out = Outbox::default();
    let nan = [f32::NAN, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0];
    g.on_message(
        &gcs_header(),
        &command_long(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, nan, (1, 1)),
        &t,
        &mut out,
    );
    assert_eq!(acks(&out)[0].result, MavResult::MAV_RESULT_DENIED);
    assert!(
        out.messages
            .iter()
            .any(|m| matches!(m, Outgoing::Message(MavMessage::STATUSTEXT(_))))
    );
}

#[test]
fn every_command_gets_exactly_one_ack_addressed_to_the_requester() {
    let mut g = GroundStation::new(1, MavType::MAV_TYPE_QUADROTOR);
    let t = telemetry(false, FlightMode::Loiter);
    let nan = [f32::NAN; 7];
    let mut interval = nan;
    interval[0] = ATTITUDE_DATA::ID as f32;
    interval[1] = 20_000.0;
    for (cmd, p) in [
        (MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL, interval),
        (MavCmd::MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES, nan),
        (MavCmd::MAV_CMD_DO_FLIGHTTERMINATION, nan), // not supported
    ] {
        let mut out = Outbox::default();
        // Twice: a retransmission gets its own ack.
        for _ in 0..2 {
            g.on_message(&gcs_header(), &command_long(cmd, p, (1, 0)), &t, &mut out);
        }
        let a = acks(&out);
        assert_eq!(a.len(), 2, "{cmd:?}");
        assert!(
            a.iter()
                .all(|a| a.command == cmd && a.target_system == 255 && a.target_component == 190)
        );
    }
    assert_eq!(g.interval_s(ATTITUDE_DATA::ID), Some(0.02));
    // The vehicle's answers become acks too.
    let to = AckTo {
        command: MavCmd::MAV_CMD_NAV_LAND,
        system: 255,
        component: 190,
        reply: Reply::Ack,
    };
    let mut out = Outbox::default();
    g.answered(to, Err(Denial::NoHome), &mut out);
    assert_eq!(acks(&out)[0].result, MavResult::MAV_RESULT_DENIED);
}

#[test]
fn an_unknown_command_id_is_acknowledged_unsupported() {
    // COMMAND_LONG with command 31999 (no MAV_CMD has it): parse it as the wire does.
    let mut payload = [0u8; 33];
    payload[28..30].copy_from_slice(&31999u16.to_le_bytes());
    payload[30] = 1;
    payload[31] = 1;
    let mut frame = Vec::new();
    mavwire::Encoder::with_ids(255, 190).push_raw(&mut frame, COMMAND_LONG_DATA::ID, &payload);
    let mut d = mavwire::Decoded {
        keep_unparsed: true,
        ..mavwire::Decoded::default()
    };
    mavwire::decode_into(&frame, &mut d);
    assert!(d.messages.is_empty() && d.unparsed.len() == 1 && d.malformed == 1);
    let mut g = GroundStation::new(1, MavType::MAV_TYPE_QUADROTOR);
    let mut out = Outbox::default();
    g.on_unparsed(&d.unparsed[0], &mut out);
    let Outgoing::Raw(id, ack) = &out.messages[0] else {
        panic!("a raw ack");
    };
    assert_eq!(*id, COMMAND_ACK_DATA::ID);
    // Through the wire again: an ack of 31999, UNSUPPORTED, to 255/190.
    let mut frame = Vec::new();
    mavwire::Encoder::with_ids(1, 1).push_raw(&mut frame, *id, ack);
    let raw = &frame[10..frame.len() - 2];
    assert_eq!(u16::from_le_bytes([raw[0], raw[1]]), 31999);
    assert_eq!(raw[2], MavResult::MAV_RESULT_UNSUPPORTED as u8);
    assert_eq!((raw[8], raw[9]), (255, 190));
}

#[test]
fn heartbeats_show_px4_modes_and_follow_a_change_at_once() {
    let mut g = GroundStation::new(3, MavType::MAV_TYPE_HEXAROTOR);
    let mut out = Outbox::default();
    g.poll(0.0, &telemetry(false, FlightMode::Loiter), &mut out);
    let beats = |out: &Outbox| -> Vec<HEARTBEAT_DATA> {
        out.messages
            .iter()
            .filter_map(|m| match m {
                Outgoing::Message(MavMessage::HEARTBEAT(h)) => Some(h.clone()),
                _ => None,
            })
            .collect()
    };
    let hb = beats(&out);
    assert_eq!(hb.len(), 1, "one heartbeat, not two, at the start");
    assert_eq!(hb[0].custom_mode, 0x0304_0000);
    assert_eq!(hb[0].autopilot, MavAutopilot::MAV_AUTOPILOT_PX4);
    assert_eq!(hb[0].mavtype, MavType::MAV_TYPE_HEXAROTOR);
    assert!(
        hb[0]
            .base_mode
            .contains(MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED)
    );
    assert_eq!(hb[0].system_status, MavState::MAV_STATE_STANDBY);
    // Nothing new 0.1 s later; armed in TAKEOFF 0.01 s after that: a heartbeat at once.
    let mut out = Outbox::default();
    g.poll(0.1, &telemetry(false, FlightMode::Loiter), &mut out);
    assert!(beats(&out).is_empty());
    g.poll(0.11, &telemetry(true, FlightMode::Takeoff), &mut out);
    let hb = beats(&out);
    assert_eq!(hb.len(), 1);
    assert!(
        hb[0]
            .base_mode
            .contains(MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED)
    );
    assert_eq!(hb[0].custom_mode, 0x0204_0000);
    assert_eq!(hb[0].system_status, MavState::MAV_STATE_ACTIVE);
}

/// A ground station heard for the first time gets the heartbeat and the status at once, not
/// at the streams' next second; one heard before waits for their times.
#[test]
fn a_new_ground_station_gets_the_streams_at_once() {
    let mut g = GroundStation::new(1, MavType::MAV_TYPE_QUADROTOR);
    let t = telemetry(false, FlightMode::Loiter);
    let gcs_beat = MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        mavtype: MavType::MAV_TYPE_GCS,
        autopilot: MavAutopilot::MAV_AUTOPILOT_INVALID,
        ..HEARTBEAT_DATA::default()
    });
    let sent = |out: &Outbox, id: u32| {
        let streamed = out.streamed.iter().map(|(_, m)| m);
        out.messages
            .iter()
            .chain(streamed)
            .filter(|m| matches!(m, Outgoing::Message(m) if m.message_id() == id))
            .count()
    };
    g.add_link(1);
    let mut out = Outbox::default();
    g.poll(0.0, &t, &mut out);
    assert_eq!(
        sent(&out, HEARTBEAT_DATA::ID),
        1,
        "to every link at the start"
    );
    // 0.3 s later a ground station speaks on link 1: everything of link 1 at the next poll.
    let mut out = Outbox::default();
    g.on_link_message(1, &gcs_header(), &gcs_beat, &t, &mut out);
    g.poll(0.31, &t, &mut out);
    assert_eq!(sent(&out, HEARTBEAT_DATA::ID), 1, "its heartbeat at once");
    assert_eq!(sent(&out, SYS_STATUS_DATA::ID), 1, "its status at once");
    // Heard again, it waits for the streams' times; so does a link nobody new spoke on.
    let mut out = Outbox::default();
    g.on_link_message(1, &gcs_header(), &gcs_beat, &t, &mut out);
    g.poll(0.5, &t, &mut out);
    assert_eq!(sent(&out, HEARTBEAT_DATA::ID), 0);
    let mut out = Outbox::default();
    g.poll(1.0, &t, &mut out);
    assert_eq!(sent(&out, HEARTBEAT_DATA::ID), 1, "link 0's, on its second");
    let mut out = Outbox::default();
    g.poll(1.31, &t, &mut out);
    assert_eq!(
        sent(&out, HEARTBEAT_DATA::ID),
        1,
        "link 1's, a second after its start"
    );
}

/// A link of PX4's onboard set (MAVSDK's) streams the status five times as often as a normal
/// one, link 0 included.
#[test]
fn an_onboard_link_streams_the_status_at_five_hz() {
    let mut g = GroundStation::new(1, MavType::MAV_TYPE_QUADROTOR);
    g.add_link_with(0, StreamSet::Onboard);
    g.add_link(1);
    let t = telemetry(false, FlightMode::Loiter);
    // A message heard on a link leaves its set as it is.
    let mut out = Outbox::default();
    g.on_link_message(
        0,
        &gcs_header(),
        &MavMessage::HEARTBEAT(HEARTBEAT_DATA::default()),
        &t,
        &mut out,
    );
    let mut counts = [0; 2];
    for k in 0..100 {
        let mut out = Outbox::default();
        g.poll(f64::from(k) * 0.01, &t, &mut out);
        for (link, m) in &out.streamed {
            if matches!(m, Outgoing::Message(MavMessage::SYS_STATUS(_))) {
                counts[usize::from(*link)] += 1;
            }
        }
    }
    assert_eq!(
        counts,
        [5, 1],
        "SYS_STATUS in 1 s on the onboard and the normal link"
    );
}

/// An IMU stream faster than the samples come (a vehicle slower than the wall clock) sends each
/// sample once, not the last one again.
#[test]
fn an_imu_stream_sends_each_sample_once() {
    let mut g = GroundStation::new(1, MavType::MAV_TYPE_QUADROTOR);
    let mut t = telemetry(false, FlightMode::Loiter);
    t.vehicle.as_mut().unwrap().held_sample = Some(flight_core::core::SensorSample::imu(
        nalgebra::Vector3::zeros(),
        nalgebra::Vector3::new(0.0, 0.0, -9.81),
    ));
    // Polled at 250 Hz; a new sample at every poll (`every` 1) or every other one (2).
    let run = |g: &mut GroundStation, t: &mut Telemetry, polls: u64, every: u64| {
        let mut sent = Vec::new();
        for _ in 0..polls {
            let k = t.link.frames + 1;
            if k.is_multiple_of(every) {
                t.link.t_s += 0.004 * every as f64;
                if let Some(s) = t.vehicle.as_mut().unwrap().held_sample.as_mut() {
                    s.t_usec = (t.link.t_s * 1e6) as u64;
                }
            }
            t.link.frames = k;
            let mut out = Outbox::default();
            g.poll(k as f64 * 0.004, t, &mut out);
            for (_, m) in &out.streamed {
                if let Outgoing::Message(MavMessage::HIGHRES_IMU(m)) = m {
                    sent.push(m.time_usec);
                }
            }
        }
        sent
    };
    // The sample rate is measured first (a sensor stream may go up to it).
    run(&mut g, &mut t, 250, 1);
    let mut out = Outbox::default();
    let set = command_long(
        MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL,
        [HIGHRES_IMU_DATA::ID as f32, 4_000.0, 0., 0., 0., 0., 0.],
        (1, 1),
    );
    g.on_message(&gcs_header(), &set, &t, &mut out);
    assert_eq!(acks(&out)[0].result, MavResult::MAV_RESULT_ACCEPTED);
    // Then the samples slow to half the stream's rate (a loaded machine).
    let sent = run(&mut g, &mut t, 500, 2);
    let mut distinct = sent.clone();
    distinct.dedup();
    assert!(sent.len() >= 240, "{}", sent.len());
    assert_eq!(distinct.len(), sent.len(), "a sample sent twice");
}

#[test]
fn streams_run_at_their_rates_and_can_be_changed_or_stopped_on_one_link_only() {
    let mut g = GroundStation::new(1, MavType::MAV_TYPE_QUADROTOR);
    g.add_link(3);
    let t = telemetry(false, FlightMode::Loiter);
    let mut clock = 100.0;
    // Ten seconds of polls at 100 Hz: how often `id` went out on links 0 and 3.
    let mut count = |g: &mut GroundStation, id: u32| {
        let mut n = [0, 0];
        for _ in 0..1000 {
            let mut out = Outbox::default();
            clock += 0.01;
            g.poll(clock, &t, &mut out);
            for (link, m) in &out.streamed {
                if matches!(m, Outgoing::Message(m) if m.message_id() == id) {
                    n[usize::from(*link == 3)] += 1;
                }
            }
        }
        n
    };
    assert_eq!(count(&mut g, SYS_STATUS_DATA::ID), [10, 10]);
    let [h0, h3] = count(&mut g, HEARTBEAT_DATA::ID);
    assert!((9..=11).contains(&h0) && (9..=11).contains(&h3));
    let mut p = [0.0f32; 7];
    p[0] = SYS_STATUS_DATA::ID as f32;
    p[1] = 200_000.0; // 5 Hz
    let mut out = Outbox::default();
    let set = |p| command_long(MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL, p, (1, 1));
    g.on_link_message(3, &gcs_header(), &set(p), &t, &mut out);
    assert_eq!(
        count(&mut g, SYS_STATUS_DATA::ID),
        [10, 50],
        "link 3's only"
    );
    p[1] = -1.0;
    g.on_message(&gcs_header(), &set(p), &t, &mut out);
    assert_eq!(count(&mut g, SYS_STATUS_DATA::ID), [0, 50], "link 0's only");
    // A client that stops heartbeats stops them on its own link.
    p[0] = HEARTBEAT_DATA::ID as f32;
    g.on_link_message(3, &gcs_header(), &set(p), &t, &mut out);
    let [h0, h3] = count(&mut g, HEARTBEAT_DATA::ID);
    assert!((9..=11).contains(&h0) && h3 == 0, "{h0} {h3}");
}

#[test]
fn set_mode_in_both_forms_names_px4_modes() {
    let mut g = GroundStation::new(1, MavType::MAV_TYPE_QUADROTOR);
    let t = telemetry(false, FlightMode::Loiter);
    let mut out = Outbox::default();
    // pymavlink's set_mode('LAND'): the legacy SET_MODE message.
    g.on_message(
        &gcs_header(),
        &MavMessage::SET_MODE(SET_MODE_DATA {
            custom_mode: 0x0604_0000,
            target_system: 1,
            base_mode: MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
        }),
        &t,
        &mut out,
    );
    assert_eq!(
        crate::testing::requested(&out)[0].0,
        AutopilotCommand::SetMode(FlightMode::Land)
    );
    assert_eq!(
        crate::testing::requested(&out)[0].1.command,
        MavCmd::MAV_CMD_DO_SET_MODE
    );
    // COMMAND_LONG DO_SET_MODE to AUTO.RTL, and a mode that does not exist.
    let mut out = Outbox::default();
    for (main, sub) in [(4.0, 5.0), (4.0, 1.0)] {
        g.on_message(
            &gcs_header(),
            &command_long(
                MavCmd::MAV_CMD_DO_SET_MODE,
                [1.0, main, sub, 0.0, 0.0, 0.0, 0.0],
                (1, 1),
            ),
            &t,
            &mut out,
        );
    }
    assert_eq!(crate::testing::requested(&out).len(), 1);
    assert_eq!(
        crate::testing::requested(&out)[0].0,
        AutopilotCommand::SetMode(FlightMode::Rtl)
    );
    assert_eq!(acks(&out)[0].result, MavResult::MAV_RESULT_DENIED);
}

pub(crate) fn param_values(out: &Outbox) -> Vec<&PARAM_VALUE_DATA> {
    out.messages
        .iter()
        .filter_map(|m| match m {
            Outgoing::Message(MavMessage::PARAM_VALUE(v)) => Some(v),
            _ => None,
        })
        .collect()
}

pub(crate) fn statustexts(out: &Outbox) -> Vec<String> {
    out.messages
        .iter()
        .filter_map(|m| match m {
            Outgoing::Message(MavMessage::STATUSTEXT(s)) => Some(s.text.to_str().unwrap().into()),
            _ => None,
        })
        .collect()
}

#[test]
fn every_answered_command_is_handled_and_others_are_unsupported() {
    let mut g = GroundStation::new(1, MavType::MAV_TYPE_QUADROTOR);
    let t = telemetry(false, FlightMode::Loiter);
    let mut result = |command| {
        let mut out = Outbox::default();
        g.on_message(
            &gcs_header(),
            &command_long(command, [0.0; 7], (1, 1)),
            &t,
            &mut out,
        );
        // Passed to the vehicle (answered later), or answered here.
        (
            !crate::testing::requested(&out).is_empty() || !out.actions.is_empty(),
            acks(&out).first().map(|a| a.result),
        )
    };
    for command in answered_commands() {
        let (passed_on, ack) = result(command);
        assert!(
            passed_on || ack.is_some_and(|r| r != MavResult::MAV_RESULT_UNSUPPORTED),
            "{command:?}: {ack:?}"
        );
    }
    assert_eq!(
        result(MavCmd::MAV_CMD_DO_FOLLOW).1,
        Some(MavResult::MAV_RESULT_UNSUPPORTED)
    );
}
