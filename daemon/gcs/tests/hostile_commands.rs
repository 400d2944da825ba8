//! Every command the vehicle accepts, with hostile values in every parameter slot, sent as
//! `COMMAND_LONG` and as `COMMAND_INT` to a vehicle in the simulator (one process, lockstep),
//! on the ground and hovering at 10 m. Each answer is checked against what the value means:
//! a place off the Earth or far from home, a height below the ground or above the ceiling is
//! refused. Whatever is accepted leaves the vehicle sane: home near it, the motor commands
//! finite, the set-point finite, above the ground and below the ceiling.
#![allow(clippy::unwrap_used)]
// The deprecated commands and frames are still answered, so still tested.
#![allow(deprecated)]

#[path = "../../core/tests/common/mod.rs"]
mod common;

use airframe::{Airframe, MAX_ROTORS};
use flight_core::autopilot::command::AutopilotCommand;
use flight_core::autopilot::{Autopilot, StepInputs, VehicleState};
use flight_core::commander::LandedState;
use flight_core::math::geo::{LatLonAlt, LocalFrame};
use flight_core::params::FlightParams;
use flight_core::safety::targets::{
    GROUND_CLEARANCE_M, HOME_SHIFT_MAX_M, PLAUSIBLE_RANGE_M, TargetLimits,
};
use gcs::telemetry::{LinkState, Telemetry};
use gcs::testing::{command_int, command_long};
use gcs::{GroundStation, Outbox, Outgoing};
use mavlink::MavHeader;
use mavlink::dialects::common::*;
use sitl_core::sim::{SimConfig, Simulator};

/// Values that break code, for every parameter slot.
const HOSTILE: [f32; 12] = [
    f32::NAN,
    f32::INFINITY,
    f32::NEG_INFINITY,
    f32::MAX,
    -f32::MAX,
    1e30,
    -1e30,
    1000.0,
    -5000.0,
    2.0e9,
    -1.0,
    0.0,
];

/// Hostile latitudes and longitudes of a `COMMAND_INT` (1e7 deg).
const HOSTILE_XY: [i32; 6] = [
    i32::MAX,
    i32::MIN,
    2_000_000_000,
    -2_000_000_000,
    0,
    -1_800_000_001,
];

fn gcs_header() -> MavHeader {
    MavHeader {
        system_id: 255,
        component_id: 190,
        sequence: 0,
    }
}

/// The simulated vehicle, its autopilot and its ground-station protocol.
struct Vehicle {
    sim: Simulator,
    autopilot: Autopilot,
    gcs: GroundStation,
    commands: [f64; MAX_ROTORS],
    limits: TargetLimits,
    /// Home once ready to arm (NED).
    first_home: nalgebra::Vector3<f64>,
}

impl Vehicle {
    /// On the ground, ready to arm; hovering at 10 m in Hold if `hover`.
    fn new(hover: bool) -> Self {
        let a = Airframe::load(std::path::Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../params/airframes/quad_x.toml"
        )))
        .unwrap();
        let mut p = FlightParams::default();
        p.attitude.mag_calibration_id = flight_core::sensors::mag_check::SIMULATED_MAG_ID;
        let config = SimConfig {
            seed: 7,
            ..SimConfig::default()
        };
        let mut v = Self {
            sim: Simulator::new(&a, config, sitl_core::BodyState::default()).unwrap(),
            autopilot: Autopilot::new(&a, &p, None).unwrap(),
            gcs: GroundStation::new(1, MavType::MAV_TYPE_QUADROTOR),
            commands: [0.0; MAX_ROTORS],
            limits: TargetLimits::new(&p.safety),
            first_home: nalgebra::Vector3::zeros(),
        };
        v.fly_until(60.0, |v| {
            v.autopilot.status().ready
                && v.autopilot
                    .state()
                    .estimate
                    .is_some_and(|e| e.translation.origin.is_some())
        });
        v.first_home = v.home().1;
        if hover {
            // Armed once the gyro bias has settled.
            while let Err(e) = v.autopilot.command(AutopilotCommand::Arm { force: false }) {
                assert!(v.sim.time_s() < 60.0, "not armed: {e}");
                v.fly(0.1);
            }
            v.autopilot
                .command(AutopilotCommand::Takeoff(Some(10.0)))
                .unwrap();
            v.fly_until(60.0, |v| {
                let s = v.autopilot.status();
                s.landed == LandedState::InAir
                    && s.mode == flight_core::commander::FlightMode::Loiter
            });
            v.fly(2.0);
        }
        v
    }

    fn step(&mut self) {
        let s = common::control_interval(&mut self.sim, &self.commands[..4]);
        if let Some(out) = self.autopilot.step(&s, &StepInputs::default()) {
            self.commands = out.commands;
        }
    }

    fn fly(&mut self, seconds: f64) {
        let end = self.sim.time_s() + seconds;
        while self.sim.time_s() < end {
            self.step();
        }
    }

    fn fly_until(&mut self, limit_s: f64, until: impl Fn(&Self) -> bool) {
        while !until(self) {
            assert!(self.sim.time_s() < limit_s, "not reached in {limit_s} s");
            self.step();
        }
    }

    fn telemetry(&self) -> Telemetry {
        let state = self.autopilot.state();
        Telemetry {
            vehicle: Some(VehicleState {
                status: state.status,
                estimate: state.estimate,
                held_sample: None,
                setpoint: state.setpoint,
                gps: state.gps,
                battery_v: 16.0,
                battery: Default::default(),
                mag_cal: None,
                imu_cal: None,
                source_restarts: 0,
                rotors: state.rotors,
                max_thrust_n: 0.0,
                rc: None,
            }),
            link: LinkState {
                t_s: self.sim.time_s(),
                ..LinkState::default()
            },
        }
    }

    /// The origin, home (NED) and home's global position.
    fn home(&self) -> (LatLonAlt, nalgebra::Vector3<f64>, LatLonAlt) {
        let origin = self
            .autopilot
            .state()
            .estimate
            .unwrap()
            .translation
            .origin
            .unwrap();
        let home = self.autopilot.status().home.map_or(self.here(), |h| h.0);
        (origin, home, LocalFrame::new(origin).to_geodetic(&home))
    }

    fn here(&self) -> nalgebra::Vector3<f64> {
        self.autopilot
            .state()
            .estimate
            .unwrap()
            .translation
            .pos_ned_m
    }

    /// Sends `msg`; the vehicle carries out what it is passed; the command's result (`None`:
    /// the host's to answer, as a parameter reload or a reboot).
    fn send(&mut self, msg: &MavMessage) -> Option<MavResult> {
        let t = self.telemetry();
        let mut out = Outbox::default();
        self.gcs.on_message(&gcs_header(), msg, &t, &mut out);
        for (command, to) in gcs::testing::take_requested(&mut out) {
            let r = self.autopilot.command(command);
            self.gcs.answered(to, r, &mut out);
        }
        let results: Vec<MavResult> = out
            .messages
            .iter()
            .filter_map(|m| match m {
                Outgoing::Message(MavMessage::COMMAND_ACK(a)) => Some(a.result),
                _ => None,
            })
            .collect();
        if results.is_empty() && !out.actions.is_empty() {
            return None;
        }
        assert_eq!(results.len(), 1, "{msg:?}: one answer, got {results:?}");
        Some(results[0])
    }

    /// What must hold whatever was accepted.
    fn assert_sane(&self, case: &str) {
        assert!(
            self.commands
                .iter()
                .all(|c| c.is_finite() && (0.0..=1.0).contains(c)),
            "{case}: motor commands {:?}",
            self.commands
        );
        let here = self.here();
        if let Some((home, yaw)) = self.autopilot.status().home {
            assert!(yaw.is_finite(), "{case}: home yaw {yaw}");
            assert!(
                (home.xy() - here.xy()).norm() <= PLAUSIBLE_RANGE_M,
                "{case}: home {home:?} far from {here:?}"
            );
            assert!(
                (home.z - self.first_home.z).abs() <= HOME_SHIFT_MAX_M,
                "{case}: home {home:?} far above or below the first {:?}",
                self.first_home
            );
        }
        let (_, home, _) = self.home();
        if let Some(p) = self
            .autopilot
            .state()
            .setpoint
            .and_then(|s| s.position().copied())
        {
            for v in [p.vel_ned_m_s, p.accel_ned_m_s2] {
                assert!(v.iter().all(|x| x.is_finite()), "{case}: set-point {p:?}");
            }
            // A position part may be left open (NaN), never infinite.
            assert!(
                p.pos_ned_m.iter().all(|x| !x.is_infinite()),
                "{case}: set-point {p:?}"
            );
            let height = home.z - p.pos_ned_m.z;
            assert!(
                height.is_nan() || (-2.0..=self.limits.ceiling.0 + 1.0).contains(&height),
                "{case}: set-point {height} m above home"
            );
        }
    }
}

/// A command's sane parameters for a vehicle with home at `h` (AMSL altitudes): each case
/// makes one of them hostile.
fn sane(command: MavCmd, h: &LatLonAlt) -> [f32; 7] {
    let (lat, lon, alt) = (h.lat_deg as f32, h.lon_deg as f32, h.alt_m as f32);
    match command {
        MavCmd::MAV_CMD_DO_REPOSITION => [-1.0, 1.0, 0.0, f32::NAN, lat, lon, alt + 15.0],
        MavCmd::MAV_CMD_DO_SET_HOME => [0.0, 0.0, 0.0, 0.0, lat, lon, alt],
        MavCmd::MAV_CMD_NAV_TAKEOFF => [0.0, 0.0, 0.0, f32::NAN, f32::NAN, f32::NAN, alt + 8.0],
        MavCmd::MAV_CMD_DO_CHANGE_SPEED => [1.0, 4.0, -1.0, 0.0, 0.0, 0.0, 0.0],
        MavCmd::MAV_CMD_CONDITION_YAW => [90.0, 30.0, 1.0, 0.0, 0.0, 0.0, 0.0],
        MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL => [33.0, 1e6, 0.0, 0.0, 0.0, 0.0, 0.0],
        _ => [0.0; 7],
    }
}

/// Whether a hostile `value` in `slot` (0-based) of `command` may be accepted: `None` where
/// the slot carries no place or bounded number (the sanity checks alone judge it).
fn may_accept(command: MavCmd, slot: usize, value: f32, v: &Vehicle) -> Option<bool> {
    let (_, _, h) = v.home();
    let height = |amsl: f32| amsl as f64 - h.alt_m;
    let ceiling = v.limits.ceiling.0;
    let near = |deg: f32, of: f64| (deg as f64 - of).abs() < 0.4;
    Some(match (command, slot) {
        (MavCmd::MAV_CMD_DO_REPOSITION, 3) => {
            value.is_nan() || value.abs() <= std::f32::consts::TAU
        }
        (MavCmd::MAV_CMD_DO_REPOSITION, 4) => near(value, h.lat_deg),
        (MavCmd::MAV_CMD_DO_REPOSITION, 5) => near(value, h.lon_deg),
        (MavCmd::MAV_CMD_DO_REPOSITION, 6) => {
            value.is_nan() || (GROUND_CLEARANCE_M..=ceiling).contains(&height(value))
        }
        (MavCmd::MAV_CMD_DO_SET_HOME, 4) => near(value, h.lat_deg),
        (MavCmd::MAV_CMD_DO_SET_HOME, 5) => near(value, h.lon_deg),
        (MavCmd::MAV_CMD_DO_SET_HOME, 6) => height(value).abs() <= HOME_SHIFT_MAX_M,
        (MavCmd::MAV_CMD_NAV_TAKEOFF, 6) => value.is_nan() || height(value) <= ceiling,
        (MavCmd::MAV_CMD_DO_CHANGE_SPEED, 1) => {
            value.is_finite() && (value > 0.0 || value == -1.0 || value == -2.0)
        }
        (MavCmd::MAV_CMD_CONDITION_YAW, 0) => value.abs() <= 360.0,
        (MavCmd::MAV_CMD_CONDITION_YAW, 1) => value.is_nan() || value <= 360.0,
        _ => return None,
    })
}

/// Every command, every slot, every hostile value, as `COMMAND_LONG` and (places) as
/// `COMMAND_INT`, to a fresh vehicle per command in each state.
fn table(hover: bool) {
    let mut refused = 0;
    let mut cases = 0;
    for command in gcs::answered_commands() {
        let mut v = Vehicle::new(hover);
        let (_, _, h) = v.home();
        let base = sane(command, &h);
        // The sane command is accepted where it applies: the refusals below are the values'.
        let applies = match command {
            MavCmd::MAV_CMD_DO_SET_HOME | MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL => true,
            MavCmd::MAV_CMD_NAV_TAKEOFF => !hover,
            MavCmd::MAV_CMD_DO_REPOSITION
            | MavCmd::MAV_CMD_DO_CHANGE_SPEED
            | MavCmd::MAV_CMD_CONDITION_YAW => hover,
            _ => false,
        };
        if applies {
            let sane_result = v.send(&command_long(command, base, (1, 1)));
            assert_eq!(
                sane_result,
                Some(MavResult::MAV_RESULT_ACCEPTED),
                "{command:?} {base:?}"
            );
            v.fly(0.2);
        }
        for slot in 0..7 {
            for value in HOSTILE {
                let mut p = base;
                p[slot] = value;
                let case = format!(
                    "{command:?} param{} = {value} ({})",
                    slot + 1,
                    if hover { "hovering" } else { "on the ground" }
                );
                let result = v.send(&command_long(command, p, (1, 1)));
                cases += 1;
                let accepted = result.is_none_or(|r| r == MavResult::MAV_RESULT_ACCEPTED);
                refused += usize::from(!accepted);
                if may_accept(command, slot, value, &v) == Some(false) {
                    assert!(!accepted, "{case}: accepted");
                }
                v.fly(0.2);
                v.assert_sane(&case);
            }
        }
        // COMMAND_INT: hostile latitudes and longitudes (INT32_MAX in a reposition keeps the
        // current place), and hostile heights above home in the relative frame.
        let (x, y) = (
            (h.lat_deg * 1e7).round() as i32,
            (h.lon_deg * 1e7).round() as i32,
        );
        let mut int_cases = Vec::new();
        if matches!(
            command,
            MavCmd::MAV_CMD_DO_REPOSITION | MavCmd::MAV_CMD_DO_SET_HOME
        ) {
            for bad in HOSTILE_XY {
                let keep = command == MavCmd::MAV_CMD_DO_REPOSITION && bad == i32::MAX;
                for (x, y) in [(bad, y), (x, bad)] {
                    int_cases.push((
                        command_int(command, base, x, y, MavFrame::MAV_FRAME_GLOBAL),
                        keep,
                    ));
                }
            }
        }
        if command == MavCmd::MAV_CMD_DO_REPOSITION {
            for z in HOSTILE {
                let mut p = base;
                p[6] = z;
                let height = z as f64;
                let ok = z.is_nan() || (GROUND_CLEARANCE_M..=v.limits.ceiling.0).contains(&height);
                let msg = command_int(command, p, x, y, MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT);
                int_cases.push((msg, ok));
            }
        }
        for (msg, may_accept) in int_cases {
            let case = format!("{msg:?}");
            let result = v.send(&msg);
            cases += 1;
            if !may_accept {
                assert!(
                    result.is_some_and(|r| r != MavResult::MAV_RESULT_ACCEPTED),
                    "{case}: {result:?}"
                );
                refused += 1;
            }
            v.fly(0.2);
            v.assert_sane(&case);
        }
        // Whatever was accepted, the vehicle flies on (or rests) upright.
        v.fly(3.0);
        v.assert_sane(&format!("{command:?}, 3 s on"));
        let tilt = v.sim.truth().body.q_ned_from_frd.euler_angles();
        assert!(
            tilt.0.abs() < 0.8 && tilt.1.abs() < 0.8,
            "{command:?}: tilt {tilt:?}"
        );
    }
    eprintln!(
        "{} : {cases} hostile commands, {refused} refused",
        if hover { "hovering" } else { "on the ground" }
    );
}

#[test]
fn hostile_values_in_every_slot_of_every_command_are_refused_or_harmless_on_the_ground() {
    table(false);
}

#[test]
fn hostile_values_in_every_slot_of_every_command_are_refused_or_harmless_in_flight() {
    table(true);
}
