//! The embedded simulator's typed road equals the wire: a frame folded straight into a
//! `SensorUpdate` is what an autopilot decodes from the same exchange's MAVLink bytes, and an
//! actuator command taken without bytes is what the simulator decodes from them.

#![allow(clippy::unwrap_used)]

use hil::{ActuatorCommand, SensorUpdate, SimulatorEnd, actuator_command, actuator_controls};
use mavlink::dialects::common::MavMessage;
use sitl_core::sensors::{SensorConfig, SensorPreset};
use sitl_core::sim::{SimConfig, Simulator};
use std::path::Path;

fn end(airframe: &str, seed: u64) -> SimulatorEnd {
    let path = format!(
        "{}/../../params/airframes/{airframe}.toml",
        env!("CARGO_MANIFEST_DIR")
    );
    let airframe = sitl_core::Airframe::load(Path::new(&path)).unwrap();
    let config = SimConfig {
        seed,
        sensors: SensorConfig::preset(SensorPreset::Realistic),
        ..SimConfig::default()
    };
    let sim = Simulator::new(&airframe, config, sitl_core::BodyState::default()).unwrap();
    SimulatorEnd::new(sim, 250.0)
}

/// Every exchange of a take-off's first seconds (GPS, ESC status, truth and IMU frames, a
/// dodecacopter's three `ESC_STATUS`), both roads side by side.
#[test]
fn typed_frames_equal_decoded_bytes() {
    for airframe in ["quad_x", "dodeca"] {
        let (mut wire, mut typed) = (end(airframe, 7), end(airframe, 7));
        let rotors = wire.sim().airframe().rotors.len();
        let hover = wire.sim().hover_commands();
        let (mut decoded, mut folded) = (SensorUpdate::default(), SensorUpdate::default());
        let (mut gps, mut truth) = (0, 0);
        let mut bytes = Vec::new();
        for k in 0..1500 {
            bytes.clear();
            let t_wire = wire.encode_frame(&mut bytes);
            let d = hil::decode(&bytes);
            assert_eq!(d.malformed, 0);
            for (_, m) in &d.messages {
                decoded.absorb(m);
            }
            let t_typed = typed.frame_update(&mut folded);
            assert_eq!(t_wire, t_typed);
            assert_eq!(decoded, folded, "{airframe}: exchange {k} differs");
            gps += usize::from(folded.gps.take().is_some());
            truth += usize::from(folded.truth.take().is_some());
            decoded.gps = None;
            decoded.truth = None;

            // A climb: 5 % over hover thrust, sent both ways.
            let controls: Vec<f64> = hover[..rotors].iter().map(|c| c * 1.05).collect();
            let msg = actuator_controls(t_wire, &controls, true);
            bytes.clear();
            hil::sim_encoder().push(&mut bytes, &msg);
            let d = hil::decode(&bytes);
            let MavMessage::HIL_ACTUATOR_CONTROLS(m) = &d.messages[0].1 else {
                panic!("not an actuator message")
            };
            let sent = ActuatorCommand::as_sent(t_typed, &controls, true);
            assert_eq!(actuator_command(m), sent);
            wire.apply(&actuator_command(m));
            typed.apply(&sent);
            wire.advance(|_| Ok::<(), ()>(())).unwrap();
            typed.advance(|_| Ok::<(), ()>(())).unwrap();
        }
        assert!(
            gps > 50 && truth > 250,
            "{airframe}: {gps} GPS, {truth} truth frames"
        );
        assert!(typed.sim().truth().body.pos_ned_m.z < -1.0, "it climbed");
    }
}

/// A calibration's request to the hand, sent as the autopilot sends it (`CAL_POSE` then
/// `HIL_ACTUATOR_CONTROLS`): the simulator places the vehicle, keeps it there through a short
/// gap in the requests, sets it down once they have stopped; with `SIM_CAL_HAND` off nothing.
#[test]
fn the_hand_does_what_the_requests_on_the_wire_ask() {
    use hil::HandRequest;
    use sitl_core::sim::{Face, SimAction};
    let answer = |end: &SimulatorEnd, hand: HandRequest| {
        let mut bytes = Vec::new();
        let mut encoder = hil::sim_encoder();
        let cmd = ActuatorCommand::as_sent(end.frame().time_usec, &[0.0; 4], false).with_hand(hand);
        for m in cmd.messages() {
            encoder.push(&mut bytes, &m);
        }
        // What the simulator reads back: the request, then the command it goes with.
        let msgs: Vec<MavMessage> = hil::decode(&bytes)
            .messages
            .into_iter()
            .map(|(_, m)| m)
            .collect();
        let hand = msgs
            .iter()
            .find_map(HandRequest::from_message)
            .unwrap_or_default();
        match msgs.last() {
            Some(MavMessage::HIL_ACTUATOR_CONTROLS(m)) => actuator_command(m).with_hand(hand),
            other => panic!("{other:?}"),
        }
    };
    let nose_down = |end: &SimulatorEnd| {
        let q = end.sim().truth().body.q_ned_from_frd;
        q.transform_vector(&nalgebra::Vector3::x()).z > 0.99
    };
    let mut e = end("quad_x", 1);
    let fly = |e: &mut SimulatorEnd, hand: HandRequest, exchanges: usize| {
        for _ in 0..exchanges {
            let cmd = answer(e, hand);
            e.apply(&cmd);
            e.advance(|_| Ok::<(), ()>(())).unwrap();
        }
    };
    fly(&mut e, HandRequest::Place(Face::Front), 750);
    assert!(nose_down(&e), "placed on its nose within 3 s");
    fly(&mut e, HandRequest::None, 50);
    assert!(nose_down(&e), "0.2 s without a request: still held");
    fly(&mut e, HandRequest::None, 1000);
    assert!(!nose_down(&e), "the requests stopped: set down");
    e.sim_mut().apply(SimAction::CalibrationHand(false));
    fly(&mut e, HandRequest::Place(Face::Front), 750);
    assert!(!nose_down(&e), "nobody's hand");
}
