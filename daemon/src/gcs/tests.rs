#![allow(clippy::unwrap_used)]
use super::*;
use crate::control_loop::Telemetry;
use flight_core::commander::CommanderStatus;
use flight_core::commander::Sticks;
use mavlink::Message;
use params::Parameters;

pub(crate) fn gcs_header() -> MavHeader {
    MavHeader {
        system_id: 255,
        component_id: 190,
        sequence: 0,
    }
}

pub(crate) fn telemetry(armed: bool, mode: FlightMode) -> Telemetry {
    Telemetry {
        t_s: 12.0,
        status: Some(CommanderStatus {
            armed,
            mode,
            landed: LandedState::OnGround,
            home: None,
            failsafe: false,
            failsafe_action: None,
            motor_failed: None,
            failsafe_conditions: 0,
            safety_log: Default::default(),
            prearm_ok: true,
            ready: true,
            in_mode_s: 0.0,
            manual_losses: 0,
            offboard_losses: 0,
            mission: Default::default(),
            manual_control: None,
        }),
        battery_v: 16.0,
        ..Telemetry::default()
    }
}

pub(crate) fn command_long(command: MavCmd, p: [f32; 7], target: (u8, u8)) -> MavMessage {
    MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
        param1: p[0],
        param2: p[1],
        param3: p[2],
        param4: p[3],
        param5: p[4],
        param6: p[5],
        param7: p[6],
        command,
        target_system: target.0,
        target_component: target.1,
        confirmation: 0,
    })
}

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
    assert_eq!(out.vehicle.len(), 3);
    assert_eq!(out.vehicle[0].0, AutopilotCommand::Arm { force: false });
    assert_eq!(
        (out.vehicle[0].1.system, out.vehicle[0].1.component),
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
    assert!(out.vehicle.is_empty() && out.messages.is_empty());
    // Force, and a NaN where a value is needed: denied with a reason.
    let mut out = Outbox::default();
    let force = [0.0, 21196.0, 0.0, 0.0, 0.0, 0.0, 0.0];
    g.on_message(
        &gcs_header(),
        &command_long(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, force, (1, 1)),
        &t,
        &mut out,
    );
    assert_eq!(out.vehicle[0].0, AutopilotCommand::Disarm { force: true });
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
        quiet: false,
    };
    let mut out = Outbox::default();
    g.answered(to, Err("not now".into()), &mut out);
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
    hil::Encoder::with_ids(255, 190).push_raw(&mut frame, COMMAND_LONG_DATA::ID, &payload);
    let mut d = hil::Decoded {
        keep_unparsed: true,
        ..hil::Decoded::default()
    };
    hil::decode_into(&frame, &mut d);
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
    hil::Encoder::with_ids(1, 1).push_raw(&mut frame, *id, ack);
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

#[test]
fn streams_run_at_their_rates_and_can_be_changed_or_stopped() {
    let mut g = GroundStation::new(1, MavType::MAV_TYPE_QUADROTOR);
    let t = telemetry(false, FlightMode::Loiter);
    let mut clock = 100.0;
    let mut count = |g: &mut GroundStation, id: u32| {
        let mut n = 0;
        for _ in 0..1000 {
            let mut out = Outbox::default();
            clock += 0.01;
            g.poll(clock, &t, &mut out);
            n += out
                .messages
                .iter()
                .filter(|m| matches!(m, Outgoing::Message(m) if m.message_id() == id))
                .count();
        }
        n
    };
    // Ten seconds of polls at 100 Hz.
    assert_eq!(count(&mut g, SYS_STATUS_DATA::ID), 10);
    assert!((9..=11).contains(&count(&mut g, HEARTBEAT_DATA::ID)));
    let mut p = [0.0f32; 7];
    p[0] = SYS_STATUS_DATA::ID as f32;
    p[1] = 200_000.0; // 5 Hz
    let mut out = Outbox::default();
    g.on_message(
        &gcs_header(),
        &command_long(MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL, p, (1, 1)),
        &t,
        &mut out,
    );
    assert_eq!(count(&mut g, SYS_STATUS_DATA::ID), 50);
    p[1] = -1.0;
    g.on_message(
        &gcs_header(),
        &command_long(MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL, p, (1, 1)),
        &t,
        &mut out,
    );
    assert_eq!(count(&mut g, SYS_STATUS_DATA::ID), 0);
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
        out.vehicle[0].0,
        AutopilotCommand::SetMode(FlightMode::Land)
    );
    assert_eq!(out.vehicle[0].1.command, MavCmd::MAV_CMD_DO_SET_MODE);
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
    assert_eq!(out.vehicle.len(), 1);
    assert_eq!(out.vehicle[0].0, AutopilotCommand::SetMode(FlightMode::Rtl));
    assert_eq!(acks(&out)[0].result, MavResult::MAV_RESULT_DENIED);
}

#[test]
fn endpoints_parse_with_the_instance_offset() {
    let e = links::Endpoint::parse("udpout://127.0.0.1:14550?bind=18570", 2).unwrap();
    assert_eq!(
        e,
        links::Endpoint::UdpOut {
            target: "127.0.0.1:14552".parse().unwrap(),
            bind: "0.0.0.0:18572".parse().unwrap(),
        }
    );
    // QGroundControl's port, shared by every vehicle (PX4's multi-vehicle ports).
    let e = links::Endpoint::parse("udpout://127.0.0.1:14550?bind=18570&shared", 2).unwrap();
    assert_eq!(
        e,
        links::Endpoint::UdpOut {
            target: "127.0.0.1:14550".parse().unwrap(),
            bind: "0.0.0.0:18572".parse().unwrap(),
        }
    );
    let e = links::Endpoint::parse("tcpin://0.0.0.0:5760", 1).unwrap();
    assert_eq!(
        e,
        links::Endpoint::TcpIn {
            bind: "0.0.0.0:5761".parse().unwrap()
        }
    );
    assert_eq!(
        links::Endpoint::parse("serial:///dev/ttyUSB0?baud=921600", 3).unwrap(),
        links::Endpoint::Serial {
            path: "/dev/ttyUSB0".into(),
            baud: 921_600
        }
    );
    assert_eq!(
        links::Endpoint::parse("serial:///dev/ttyACM0", 0).unwrap(),
        links::Endpoint::Serial {
            path: "/dev/ttyACM0".into(),
            baud: 57_600
        },
        "a telemetry radio's rate by default"
    );
    for bad in [
        "udp://1.2.3.4:5",
        "udpout://localhost",
        "udpin://0.0.0.0:1?bind=3",
        "udpin://0.0.0.0:1?shared",
        "tcpin://0.0.0.0:1?shared",
        "udpout://1.2.3.4:5?speed=9",
        "serial://?baud=57600",
        "serial:///dev/ttyS0?baud=fast",
        "serial:///dev/ttyS0?baud=0",
        "serial:///dev/ttyS0?bind=3",
    ] {
        assert!(links::Endpoint::parse(bad, 0).is_err(), "{bad}");
    }
}

#[test]
fn endpoint_options_trusted_and_allow_lists_parse_on_every_kind() {
    let e =
        links::EndpointSpec::parse("udpin://127.0.0.1:14560?trusted&sysids=255,250", 1).unwrap();
    assert_eq!(
        e.endpoint,
        links::Endpoint::UdpIn {
            bind: "127.0.0.1:14561".parse().unwrap()
        }
    );
    assert!(e.options.trusted);
    assert_eq!(e.options.allowed_systems, [255, 250]);
    let e =
        links::EndpointSpec::parse("udpout://127.0.0.1:14550?sysids=255&bind=18570", 0).unwrap();
    assert_eq!(
        e.endpoint,
        links::Endpoint::UdpOut {
            target: "127.0.0.1:14550".parse().unwrap(),
            bind: "0.0.0.0:18570".parse().unwrap(),
        },
        "the endpoint's own options are kept"
    );
    assert!(!e.options.trusted);
    let e = links::EndpointSpec::parse("serial:///dev/ttyACM0?baud=115200&trusted", 0).unwrap();
    assert!(e.options.trusted && e.options.allowed_systems.is_empty());
    for bad in [
        "udpin://0.0.0.0:1?sysids=0",
        "udpin://0.0.0.0:1?sysids=256",
        "udpin://0.0.0.0:1?sysids=255,x",
        "udpin://0.0.0.0:1?trusted=yes",
        "tcpin://0.0.0.0:1?sysids=",
    ] {
        assert!(links::EndpointSpec::parse(bad, 0).is_err(), "{bad}");
    }
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

fn param_set(name: &str, value: f32, ty: MavParamType) -> MavMessage {
    MavMessage::PARAM_SET(PARAM_SET_DATA {
        param_value: value,
        target_system: 1,
        target_component: 1,
        param_id: name.into(),
        param_type: ty,
    })
}

#[test]
fn the_parameter_list_has_a_constant_count_stable_indices_and_bytewise_integers() {
    let mut g = GroundStation::new(1, MavType::MAV_TYPE_QUADROTOR);
    let t = telemetry(false, FlightMode::Loiter);
    let mut out = Outbox::default();
    let list = MavMessage::PARAM_REQUEST_LIST(PARAM_REQUEST_LIST_DATA {
        target_system: 1,
        target_component: 0,
    });
    g.on_message(&gcs_header(), &list, &t, &mut out);
    let values = param_values(&out);
    let n = FlightParams::count();
    assert_eq!(values.len(), n);
    for (i, v) in values.iter().enumerate() {
        assert_eq!((v.param_index as usize, v.param_count as usize), (i, n));
    }
    let align = values
        .iter()
        .find(|v| v.param_id.to_str().unwrap() == "ATT_ALIGN_N")
        .unwrap();
    assert_eq!(align.param_type, MavParamType::MAV_PARAM_TYPE_INT32);
    assert_eq!(
        align.param_value.to_bits(),
        250,
        "the integer's bits, not 250.0"
    );
    let takeoff = values
        .iter()
        .find(|v| v.param_id.to_str().unwrap() == "MIS_TAKEOFF_ALT")
        .unwrap();
    assert_eq!(
        (takeoff.param_type, takeoff.param_value),
        (MavParamType::MAV_PARAM_TYPE_REAL32, 2.5)
    );

    // One by name, one by index (which wins over the name), an unknown one.
    let read = |name: &str, index: i16| {
        MavMessage::PARAM_REQUEST_READ(PARAM_REQUEST_READ_DATA {
            param_index: index,
            target_system: 1,
            target_component: 1,
            param_id: name.into(),
        })
    };
    let mut out = Outbox::default();
    g.on_message(&gcs_header(), &read("MIS_TAKEOFF_ALT", -1), &t, &mut out);
    g.on_message(&gcs_header(), &read("MIS_TAKEOFF_ALT", 0), &t, &mut out);
    g.on_message(&gcs_header(), &read("NOPE", -1), &t, &mut out);
    g.on_message(&gcs_header(), &read("", n as i16), &t, &mut out);
    let v = param_values(&out);
    assert_eq!(v.len(), 2);
    assert_eq!(v[0].param_index, takeoff.param_index);
    assert_eq!(v[1].param_index, 0);
    assert_eq!(
        statustexts(&out),
        ["no parameter NOPE", format!("no parameter #{n}").as_str()]
    );
}

#[test]
fn param_set_checks_type_and_value_and_always_answers_with_the_value_in_force() {
    let mut g = GroundStation::new(1, MavType::MAV_TYPE_QUADROTOR);
    let t = telemetry(false, FlightMode::Loiter);
    let real = MavParamType::MAV_PARAM_TYPE_REAL32;
    let int = MavParamType::MAV_PARAM_TYPE_INT32;

    let mut out = Outbox::default();
    g.on_message(
        &gcs_header(),
        &param_set("MPC_XY_P", 0.1, real),
        &t,
        &mut out,
    );
    assert_eq!(param_values(&out)[0].param_value, 0.1);
    assert_eq!(
        g.parameters().values().position.k_pos_xy,
        0.1,
        "0.1, not 0.1f32's f64"
    );
    assert_eq!(out.actions, [Action::ParamsChanged, Action::SaveParams]);

    let mut out = Outbox::default();
    g.on_message(
        &gcs_header(),
        &param_set("ATT_ALIGN_N", f32::from_bits(400), int),
        &t,
        &mut out,
    );
    assert_eq!(param_values(&out)[0].param_value.to_bits(), 400);
    assert_eq!(g.parameters().values().attitude.align_samples, 400);
    assert_eq!(
        g.parameters().store().names().collect::<Vec<_>>(),
        ["ATT_ALIGN_N", "MPC_XY_P"]
    );

    for (msg, says) in [
        (
            param_set("ATT_ALIGN_N", 500.0, real),
            "ATT_ALIGN_N: INT32 parameter, sent as REAL32",
        ),
        (
            param_set("MPC_XY_P", f32::NAN, real),
            "MPC_XY_P: NaN is not a number",
        ),
        (
            param_set("MPC_XY_P", 7.0, real),
            "MPC_XY_P: 7 is outside [0, 5] 1/s",
        ),
        (
            param_set("MPC_XY_P", 1.0, int),
            "MPC_XY_P: REAL32 parameter, sent as INT32",
        ),
        (
            param_set("ATT_ALIGN_N", f32::from_bits(-3i32 as u32), int),
            "ATT_ALIGN_N: -3 is outside [1, 10000]",
        ),
    ] {
        let mut out = Outbox::default();
        g.on_message(&gcs_header(), &msg, &t, &mut out);
        let v = param_values(&out);
        assert_eq!(v.len(), 1, "answered with the value in force");
        let texts = statustexts(&out);
        assert!(texts.len() == 1 && texts[0].starts_with(says), "{texts:?}");
        assert!(out.actions.is_empty(), "a refused value changes nothing");
    }
    assert_eq!(g.parameters().values().position.k_pos_xy, 0.1);
    assert_eq!(g.parameters().values().attitude.align_samples, 400);

    let mut out = Outbox::default();
    g.on_message(&gcs_header(), &param_set("NOPE", 1.0, real), &t, &mut out);
    assert!(param_values(&out).is_empty());
    assert_eq!(statustexts(&out), ["no parameter NOPE"]);
    // Another vehicle's parameter is not ours to answer.
    let mut out = Outbox::default();
    let mut other = param_set("MPC_XY_P", 1.0, real);
    if let MavMessage::PARAM_SET(s) = &mut other {
        s.target_system = 2;
    }
    g.on_message(&gcs_header(), &other, &t, &mut out);
    assert!(out.messages.is_empty());
}

#[test]
fn storage_reset_and_reboot_are_for_a_disarmed_vehicle() {
    let mut base = FlightParams::default();
    base.commander.takeoff_alt_m = 6.0;
    let mut g = GroundStation::new(1, MavType::MAV_TYPE_QUADROTOR).with_parameters(
        Parameters::new(base.clone(), Default::default()),
        base.clone(),
    );
    let real = MavParamType::MAV_PARAM_TYPE_REAL32;
    let ground = telemetry(false, FlightMode::Loiter);
    let flying = telemetry(true, FlightMode::Loiter);
    let mut out = Outbox::default();
    g.on_message(
        &gcs_header(),
        &param_set("MIS_TAKEOFF_ALT", 9.0, real),
        &flying,
        &mut out,
    );
    assert_eq!(
        g.parameters().values().commander.takeoff_alt_m,
        9.0,
        "set in flight: fine"
    );

    let storage = |p1| {
        command_long(
            MavCmd::MAV_CMD_PREFLIGHT_STORAGE,
            [p1, 0., 0., 0., 0., 0., 0.],
            (1, 1),
        )
    };
    let reboot = |p1| {
        command_long(
            MavCmd::MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN,
            [p1, 0., 0., 0., 0., 0., 0.],
            (1, 1),
        )
    };
    for (msg, result) in [
        (storage(2.0), MavResult::MAV_RESULT_DENIED),
        (storage(0.0), MavResult::MAV_RESULT_DENIED),
        (reboot(1.0), MavResult::MAV_RESULT_DENIED),
        (reboot(2.0), MavResult::MAV_RESULT_DENIED),
        (storage(1.0), MavResult::MAV_RESULT_ACCEPTED),
    ] {
        let mut out = Outbox::default();
        g.on_message(&gcs_header(), &msg, &flying, &mut out);
        assert_eq!(acks(&out)[0].result, result, "{msg:?}");
    }
    assert_eq!(g.parameters().values().commander.takeoff_alt_m, 9.0);

    let mut out = Outbox::default();
    g.on_message(&gcs_header(), &storage(2.0), &ground, &mut out);
    assert_eq!(acks(&out)[0].result, MavResult::MAV_RESULT_ACCEPTED);
    assert_eq!(g.parameters().values(), &base, "back to the base values");
    assert_eq!(g.parameters().store().names().count(), 0);
    assert_eq!(out.actions, [Action::ParamsChanged, Action::SaveParams]);

    let mut out = Outbox::default();
    g.on_message(&gcs_header(), &storage(0.0), &ground, &mut out);
    assert!(acks(&out).is_empty(), "acknowledged once the store is read");
    assert!(matches!(out.actions[..], [Action::ReloadParams(_)]));

    for (p1, action) in [(1.0, Action::Reboot), (2.0, Action::Shutdown)] {
        let mut out = Outbox::default();
        g.on_message(&gcs_header(), &reboot(p1), &ground, &mut out);
        assert_eq!(acks(&out)[0].result, MavResult::MAV_RESULT_ACCEPTED);
        assert_eq!(out.actions, [action]);
    }
    let mut out = Outbox::default();
    g.on_message(&gcs_header(), &reboot(3.0), &ground, &mut out);
    assert_eq!(acks(&out)[0].result, MavResult::MAV_RESULT_DENIED);

    // One of several vehicles in a process: a reboot would restart them all, so it is
    // refused; a shutdown ends this one.
    let mut g = g.with_reboot(false);
    let mut out = Outbox::default();
    g.on_message(&gcs_header(), &reboot(1.0), &ground, &mut out);
    assert_eq!(acks(&out)[0].result, MavResult::MAV_RESULT_DENIED);
    assert!(out.actions.is_empty());
    let mut out = Outbox::default();
    g.on_message(&gcs_header(), &reboot(2.0), &ground, &mut out);
    assert_eq!(out.actions, [Action::Shutdown]);
}

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
        out.sticks,
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
    assert_eq!(out.sticks, None, "another vehicle's");
    g.on_message(&gcs_header(), &manual(1, 3000, -200), &t, &mut out);
    let s = out.sticks.unwrap();
    assert_eq!((s.forward, s.throttle), (1.0, 0.0), "clamped");

    let mut out = Outbox::default();
    g.poll(0.0, &t, &mut out);
    if let Some(s) = t.status.as_mut() {
        s.manual_losses = 1;
    }
    g.poll(0.01, &t, &mut out);
    g.poll(0.02, &t, &mut out);
    assert_eq!(statustexts(&out), ["manual control lost: Hold"]);
}

#[test]
fn on_request_messages_can_be_asked_for_and_say_which_set_point_axes_are_flown() {
    let mut g = GroundStation::new(1, MavType::MAV_TYPE_QUADROTOR);
    let mut t = telemetry(true, FlightMode::Posctl);
    let mut out = Outbox::default();
    for id in telemetry::ON_REQUEST {
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
    t.setpoint = Some(flight_core::control::Setpoint::Position(
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
        t.status.as_mut().unwrap().mission = m;
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
    t.status.as_mut().unwrap().mission.total = 0;
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
        assert_eq!(out.vehicle.len(), 1, "{:?}", out.messages);
        out.vehicle[0].clone()
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
    g.answered(to, Err("no item 3".into()), &mut out);
    assert_eq!(statustexts(&out), ["no item 3"]);
    assert!(acks(&out).is_empty());
}

/// A ground station's heartbeat restarts the link-loss clock (a vehicle's does not); each
/// failsafe's start, change and end is announced once.
#[test]
fn gcs_heartbeats_are_forwarded_and_failsafes_announced() {
    use flight_core::safety::failsafe::{Action, Condition, SafetyEvent};
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
        &[Triggered(Condition::BatteryLow, Action::Warn)],
        &[Triggered(Condition::BatteryCritical, Action::Return)],
        &[],
        &[
            Triggered(Condition::MagLost, Action::Warn),
            Cleared(Condition::MagLost),
        ],
        &[
            Triggered(Condition::Crash, Action::Disarm),
            Cleared(Condition::Crash),
            Cleared(Condition::BatteryLow),
        ],
    ];
    for (k, events) in steps.into_iter().enumerate() {
        if let Some(st) = t.status.as_mut() {
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
    if let Some(st) = t.status.as_mut() {
        for _ in 0..10 {
            st.safety_log
                .push(Triggered(Condition::MagLost, Action::Warn));
            st.safety_log.push(Cleared(Condition::MagLost));
        }
    }
    g.poll(1.0, &t, &mut out);
    let said = statustexts(&out);
    assert_eq!(said.len(), 17, "{said:?}");
    assert_eq!(said[0], "4 failsafe messages missed");
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
    t.battery = BatteryState {
        voltage_v: 15.1,
        current_a: Some(12.34),
        consumed_mah: Some(1234.4),
        cell_v_at_rest: 3.8,
        remaining: Some(0.123),
        time_remaining_s: Some(95.2),
    };
    let health = |t: &Telemetry| {
        let Some(MavMessage::SYS_STATUS(s)) = telemetry::build(SYS_STATUS_DATA::ID, t, 0) else {
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
    if let Some(st) = t.status.as_mut() {
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
    let Some(MavMessage::BATTERY_STATUS(b)) = telemetry::build(BATTERY_STATUS_DATA::ID, &t, 0)
    else {
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
