//! The parameter protocol: the list, sets checked against their type and range, storage,
//! reset and reboot.
#![allow(clippy::unwrap_used)]

use super::*;

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
    // Sent over the next polls, a few tens at a time (a burst of all would overflow a link's
    // socket buffer), each once.
    let n = FlightParams::count();
    let mut polls = 0;
    while param_values(&out).len() < n {
        g.poll(polls as f64 * 0.01, &t, &mut out);
        polls += 1;
        assert!(polls <= n.div_ceil(24), "{polls} polls");
    }
    let values = param_values(&out);
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
    assert_eq!(
        out.actions,
        [HostAction::ParamsChanged, HostAction::SaveParams]
    );

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
    assert_eq!(
        out.actions,
        [HostAction::ParamsChanged, HostAction::SaveParams]
    );

    let mut out = Outbox::default();
    g.on_message(&gcs_header(), &storage(0.0), &ground, &mut out);
    assert!(acks(&out).is_empty(), "acknowledged once the store is read");
    assert!(matches!(out.actions[..], [HostAction::ReloadParams(_)]));

    for (p1, action) in [(1.0, HostAction::Reboot), (2.0, HostAction::Shutdown)] {
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
    assert_eq!(out.actions, [HostAction::Shutdown]);
}

#[test]
fn a_hash_check_set_stops_the_list_as_qgroundcontrol_asks_when_its_cache_matched() {
    let mut g = GroundStation::new(1, MavType::MAV_TYPE_QUADROTOR);
    let t = telemetry(false, FlightMode::Loiter);
    let mut out = Outbox::default();
    let list = MavMessage::PARAM_REQUEST_LIST(PARAM_REQUEST_LIST_DATA {
        target_system: 1,
        target_component: 0,
    });
    g.on_message(&gcs_header(), &list, &t, &mut out);
    g.poll(0.0, &t, &mut out);
    let first = param_values(&out).len();
    assert!(first > 0 && first < FlightParams::count());
    let stop = param_set("_HASH_CHECK", 0.0, MavParamType::MAV_PARAM_TYPE_UINT32);
    g.on_message(&gcs_header(), &stop, &t, &mut out);
    for k in 1..20 {
        g.poll(f64::from(k) * 0.01, &t, &mut out);
    }
    assert_eq!(param_values(&out).len(), first);
}
