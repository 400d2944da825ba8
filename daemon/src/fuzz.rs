//! Fuzz targets for everything a peer can reach: random payloads for every message of
//! the dialect, parsed by the `mavlink` crate as a received frame would be, handed to the
//! ground-station protocol and to the vehicle (its HIL sensor input and the commands the
//! protocol passes on), with payloads biased toward the values that break code: NaN, ±inf,
//! the largest floats and integers, out-of-range enums. No panic; the motor commands stay finite
//! and in range; the parameter table stays valid.
//!
//! Proptest (the toolchain here is stable, where cargo-fuzz needs nightly): a short run in every
//! `cargo test`; `FUZZ_CASES=100000 cargo test -p autopilot fuzz -- --nocapture` for a long one.
//! The frame decoder's own fuzz targets are in `hil`'s `wire.rs`.

#![allow(clippy::unwrap_used)]
use crate::links::frames::{FrameAssembler, answer};
use flight_core::autopilot::command::AutopilotCommand;
use flight_core::autopilot::{Autopilot, StepInputs};
use flight_core::commander::FlightMode;
use flight_core::params::FlightParams;
use gcs::{GroundStation, Outbox};
use mavlink::dialects::common::{MavMessage, MavType};
use mavlink::{MavHeader, MavlinkVersion, Message};
use proptest::prelude::*;
use std::sync::OnceLock;

/// Every message id of the dialect.
fn message_ids() -> &'static [u32] {
    static IDS: OnceLock<Vec<u32>> = OnceLock::new();
    IDS.get_or_init(|| {
        (0..65_536)
            .filter(|&id| MavMessage::default_message_from_id(id).is_some())
            .collect()
    })
}

/// Ids the vehicle reads from a simulator or flight board, fuzzed more often.
const HIL_IDS: [u32; 4] = [107, 113, 115, 291]; // HIL_SENSOR, HIL_GPS, HIL_STATE_QUATERNION, ESC_STATUS

/// A payload of `len` bytes: random, or 4-byte words of values that break code.
fn payload() -> impl Strategy<Value = Vec<u8>> {
    let nasty = prop_oneof![
        Just(f32::NAN.to_le_bytes()),
        Just(f32::INFINITY.to_le_bytes()),
        Just(f32::NEG_INFINITY.to_le_bytes()),
        Just(f32::MAX.to_le_bytes()),
        Just(f32::MIN_POSITIVE.to_le_bytes()),
        Just(u32::MAX.to_le_bytes()),
        Just(i32::MIN.to_le_bytes()),
        Just(1e9f32.to_le_bytes()),
        any::<[u8; 4]>(),
    ];
    prop_oneof![
        proptest::collection::vec(any::<u8>(), 0..=255),
        proptest::collection::vec(nasty, 0..64).prop_map(|w| w.concat()),
    ]
}

/// A received message: an id (a HIL one a third of the time) and a payload.
fn received() -> impl Strategy<Value = (u32, Vec<u8>)> {
    let id = prop_oneof![
        1 => proptest::sample::select(HIL_IDS.to_vec()),
        2 => (0..message_ids().len()).prop_map(|i| message_ids()[i]),
    ];
    (id, payload())
}

fn quad() -> airframe::Airframe {
    let dir = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../params/airframes/quad_x.toml"
    );
    airframe::Airframe::load(std::path::Path::new(dir)).unwrap()
}

/// What the control loop shows: armed or not, in Hold.
fn telemetry(armed: bool) -> gcs::telemetry::Telemetry {
    gcs::testing::telemetry(armed, FlightMode::Loiter)
}

/// The cases of a run: `FUZZ_CASES`, else `default`.
fn cases(default: u32) -> ProptestConfig {
    let n = std::env::var("FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default);
    ProptestConfig::with_cases(n)
}

/// The autopilot behind its HIL frames, as the control loop flies it.
struct FuzzedVehicle {
    autopilot: Autopilot,
    frames: FrameAssembler,
}

impl FuzzedVehicle {
    fn new(airframe: &sitl_core::Airframe, params: &FlightParams) -> Self {
        Self {
            autopilot: Autopilot::new(airframe, params, None).unwrap(),
            frames: FrameAssembler::default(),
        }
    }

    /// Folds one message in; a complete sensor frame is stepped on and answered.
    fn on_message(&mut self, m: &MavMessage) -> Option<hil::ActuatorCommand> {
        let frame = self.frames.absorb(m)?;
        let out = self.autopilot.step(&frame.sample, &StepInputs::default())?;
        Some(answer(
            &out,
            self.autopilot.state().rotors,
            self.autopilot.pose_request(),
        ))
    }

    fn command(&mut self, c: AutopilotCommand) -> Result<(), flight_core::commander::Denial> {
        self.autopilot.command(c)
    }
}

proptest! {
    #![proptest_config(cases(400))]

    /// Any sequence of messages, through the protocol and into the vehicle: no panic, motor
    /// commands finite and in [-1, 1], every parameter still within its range.
    #[test]
    fn any_messages_reach_the_protocol_and_the_vehicle_safely(
        msgs in proptest::collection::vec(received(), 1..40),
        armed in any::<bool>(),
        sender in any::<(u8, u8)>(),
    ) {
        let airframe = quad();
        let params = FlightParams::default();
        let mut vehicle = FuzzedVehicle::new(&airframe, &params);
        let mut gcs = GroundStation::new(1, MavType::MAV_TYPE_QUADROTOR)
            .with_parameters(gcs::params::Parameters::default(), params.clone());
        let mut out = Outbox::default();
        let header = MavHeader { system_id: sender.0.into(), component_id: sender.1, sequence: 0 };
        let t = telemetry(armed);
        for (i, (id, bytes)) in msgs.iter().enumerate() {
            match MavMessage::parse(MavlinkVersion::V2, *id, bytes) {
                Ok(m) => {
                    if let MavMessage::SERIAL_CONTROL(d) = &m {
                        gcs.on_serial_control(0, &header, d, true, &t, &mut out);
                    }
                    gcs.on_message(&header, &m, &t, &mut out);
                    if let Some(c) = vehicle.on_message(&m) {
                        prop_assert!(
                            c.controls.iter().all(|u| u.is_finite() && u.abs() <= 1.0),
                            "motor commands {:?} after {}", c.controls, m.message_name()
                        );
                    }
                }
                Err(_) => gcs.on_unparsed(
                    &hil::RawMessage { header, msg_id: *id, payload: bytes.clone() },
                    &mut out,
                ),
            }
            gcs.poll(3.0 + i as f64 * 0.05, &t, &mut out);
            gcs::testing::carry_out(&mut gcs, &mut vehicle.autopilot, &mut out);
        }
        let values = gcs.parameters().values();
        for (group, meta) in FlightParams::metadata() {
            let v = values.get(group, meta.key).unwrap();
            prop_assert!(
                v.is_finite() && meta.min <= v && v <= meta.max,
                "{} = {}", meta.name, v
            );
        }
        prop_assert!(values.validate().is_empty(), "{:?}", values.validate());
    }
}

proptest! {
    #![proptest_config(cases(48))]

    /// A vehicle flying (armed, climbing in the simulator) that then receives any messages:
    /// its motor commands stay finite and in [-1, 1] whatever its sensors and commands say.
    #[test]
    fn a_flying_vehicle_fed_any_messages_commands_its_motors_sanely(
        msgs in proptest::collection::vec(received(), 1..60),
        seed in 0u64..1000,
    ) {
        let (mut vehicle, mut end) = flying(seed);
        prop_assert!(vehicle.autopilot.status().armed, "the warm-up armed it");
        let mut gcs = GroundStation::new(1, MavType::MAV_TYPE_QUADROTOR)
            .with_parameters(gcs::params::Parameters::default(), FlightParams::default());
        let mut out = Outbox::default();
        let header = MavHeader { system_id: 255, component_id: 190, sequence: 0 };
        let t = telemetry(true);
        for (id, bytes) in &msgs {
            // A good frame from the simulator between the hostile ones, as a link would mix them.
            for m in sim_frame(&mut end) {
                if let Some(step) = vehicle.on_message(&m) {
                    check_motors(&step, &m)?;
                    end.apply(&step);
                }
            }
            end.advance(|_| Ok::<(), std::convert::Infallible>(())).unwrap();
            if let Ok(m) = MavMessage::parse(MavlinkVersion::V2, *id, bytes) {
                gcs.on_message(&header, &m, &t, &mut out);
                if let Some(step) = vehicle.on_message(&m) {
                    check_motors(&step, &m)?;
                }
            }
            gcs::testing::carry_out(&mut gcs, &mut vehicle.autopilot, &mut out);
        }
    }
}

/// The motor commands of a step are finite and in [-1, 1].
fn check_motors(c: &hil::ActuatorCommand, after: &MavMessage) -> Result<(), TestCaseError> {
    prop_assert!(
        c.controls.iter().all(|u| u.is_finite() && u.abs() <= 1.0),
        "motor commands {:?} after {:?}",
        c.controls,
        after
    );
    Ok(())
}

/// The messages of the simulator's next frame.
fn sim_frame(end: &mut hil::SimulatorEnd) -> Vec<MavMessage> {
    let mut bytes = Vec::new();
    end.encode_frame(&mut bytes);
    hil::decode(&bytes)
        .messages
        .into_iter()
        .map(|(_, m)| m)
        .collect()
}

/// A quad that has aligned at rest in the simulator (2 s), armed and climbed for 1 s.
fn flying(seed: u64) -> (FuzzedVehicle, hil::SimulatorEnd) {
    use sitl_core::sim::{SimConfig, Simulator};
    let airframe = quad();
    let mut vehicle = FuzzedVehicle::new(&airframe, &FlightParams::default());
    let sim = Simulator::new(
        &airframe,
        SimConfig {
            seed,
            ..SimConfig::default()
        },
        sitl_core::BodyState::default(),
    )
    .unwrap();
    let mut end = hil::SimulatorEnd::new(sim, 250.0);
    for i in 0..750 {
        if i == 500 {
            vehicle
                .command(AutopilotCommand::Arm { force: true })
                .unwrap();
            vehicle.command(AutopilotCommand::Takeoff(None)).unwrap();
        }
        for m in sim_frame(&mut end) {
            if let Some(step) = vehicle.on_message(&m) {
                end.apply(&step);
            }
        }
        end.advance(|_| Ok::<(), std::convert::Infallible>(()))
            .unwrap();
    }
    (vehicle, end)
}
