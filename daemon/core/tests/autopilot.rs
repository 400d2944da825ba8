//! The autopilot's step against the simulator's physics, in-process: what it does with samples
//! that repeat, go back in time or lose a sensor.

// Test code: a failed unwrap is a failed test.
#![allow(clippy::unwrap_used)]

use airframe::{Airframe, MAX_ROTORS};
use flight_core::autopilot::command::AutopilotCommand;
use flight_core::autopilot::{
    AutoFlight, Autopilot, AutopilotOutput, SOURCE_RESTART_S, StepInputs, StepKind,
};
use flight_core::commander::LandedState;
use flight_core::core::SensorSample;
use flight_core::params::FlightParams;
use flight_core::safety::failsafe::{Condition, SafetyEvent};
use flight_core::safety::failure_injection::{FailureType, FailureUnit, Injection};
use sitl_core::sim::{SimConfig, Simulator};

mod common;

fn quad() -> Airframe {
    common::airframe("quad_x")
}

/// The default parameters as the daemon flies them in a simulator (whose magnetometer needs no
/// calibration), with failure injection allowed.
fn params(att_mode: u32) -> FlightParams {
    let mut p = FlightParams::default();
    p.attitude.mode = att_mode;
    p.attitude.mag_calibration_id = flight_core::sensors::mag_check::SIMULATED_MAG_ID;
    p.safety.failure_injection = 1;
    p
}

/// A simulated flight: the simulator, and the autopilot flying its samples.
struct Flight {
    sim: Simulator,
    autopilot: Autopilot,
    commands: [f64; MAX_ROTORS],
}

impl Flight {
    fn new(seed: u64, att_mode: u32, auto: Option<AutoFlight>) -> Self {
        let a = quad();
        let config = SimConfig {
            seed,
            ..SimConfig::default()
        };
        Self {
            sim: Simulator::new(&a, config, sitl_core::BodyState::default()).unwrap(),
            autopilot: Autopilot::new(&a, &params(att_mode), auto).unwrap(),
            commands: [0.0; MAX_ROTORS],
        }
    }

    /// One control interval of physics, and the sample it makes.
    fn sample(&mut self) -> SensorSample {
        common::control_interval(&mut self.sim, &self.commands[..4])
    }

    /// Flies one sample.
    fn step(&mut self) -> AutopilotOutput {
        let s = self.sample();
        let out = self.autopilot.step(&s, &StepInputs::default()).unwrap();
        self.commands = out.commands;
        out
    }

    /// Flies until `until` holds, at most `limit_s` of simulated time.
    fn fly_until(&mut self, limit_s: f64, mut until: impl FnMut(&Self) -> bool) {
        while !until(self) {
            assert!(self.sim.time_s() < limit_s, "not reached in {limit_s} s");
            self.step();
        }
    }

    /// The safety events logged so far.
    fn safety_events(&self) -> Vec<SafetyEvent> {
        self.autopilot.status().safety_log.since(0).1.collect()
    }
}

/// A sample seen before is answered again, unchanged, without a step; an older one is dropped;
/// one more than [`SOURCE_RESTART_S`] older is a source that started again: the autopilot starts
/// afresh and says so, its mission kept.
#[test]
fn repeated_samples_are_answered_again_and_a_clock_that_goes_back_restarts_the_autopilot() {
    let mut f = Flight::new(1, 1, None);
    for _ in 0..750 {
        f.step();
    }
    let s = f.sample();
    let first = f.autopilot.step(&s, &StepInputs::default()).unwrap();
    assert_eq!(first.kind, StepKind::Flown);
    let again = f.autopilot.step(&s, &StepInputs::default()).unwrap();
    assert_eq!(again.kind, StepKind::Repeated);
    assert_eq!(again.commands, first.commands);
    assert_eq!(again.t_usec, first.t_usec);
    let older = SensorSample {
        t_usec: s.t_usec - 4000,
        ..s
    };
    assert!(f.autopilot.step(&older, &StepInputs::default()).is_none());
    assert_eq!(f.autopilot.repeated_frames(), 2);

    let items = vec![flight_core::mission::MissionItem::Land {
        at: flight_core::mission::MissionPoint {
            lat_lon_deg: None,
            alt: None,
        },
        yaw_rad: None,
    }];
    f.autopilot
        .command(AutopilotCommand::SetMission(items))
        .unwrap();
    // Less than SOURCE_RESTART_S back is no restart (a serial line's backlog goes back that far): dropped.
    let backlog = SensorSample {
        t_usec: s.t_usec - (0.8 * SOURCE_RESTART_S * 1e6) as u64,
        ..s
    };
    assert!(f.autopilot.step(&backlog, &StepInputs::default()).is_none());
    assert_eq!(f.autopilot.state().source_restarts, 0);
    let back = SensorSample {
        t_usec: s.t_usec - (2.0 * SOURCE_RESTART_S * 1e6) as u64,
        ..s
    };
    let out = f.autopilot.step(&back, &StepInputs::default()).unwrap();
    assert!(out.restarted && out.kind == StepKind::Flown);
    assert_eq!(f.autopilot.state().source_restarts, 1);
    assert!(!f.autopilot.status().armed);
    assert_eq!(f.autopilot.mission_status().total, 1, "the mission is kept");
}

/// A GPS that fails in the hover leaves the attitude estimate valid: the failsafe that acts is
/// the position's (a level descent on the barometer), and the operator hears that, never that
/// the attitude estimate is invalid. Both attitude estimators, a GPS off and one stuck, three
/// seeds.
#[test]
fn a_gps_failure_in_the_air_is_said_as_the_position_lost_not_the_attitude() {
    for (att_mode, kind) in [
        (0, FailureType::Off),
        (1, FailureType::Off),
        (1, FailureType::Stuck),
    ] {
        for seed in 1..=3 {
            let mut f = Flight::new(
                seed,
                att_mode,
                Some(AutoFlight {
                    takeoff_m: 5.0,
                    hover_s: 60.0,
                }),
            );
            f.fly_until(60.0, |f| {
                f.autopilot.status().landed == LandedState::InAir
                    && -f.sim.truth().body.pos_ned_m.z > 4.8
            });
            let hover_t = f.sim.time_s();
            f.fly_until(hover_t + 2.0, |f| f.sim.time_s() >= hover_t + 1.9);
            f.autopilot
                .command(AutopilotCommand::InjectFailure(Injection {
                    unit: FailureUnit::Gps,
                    kind,
                    instance: 0,
                }))
                .unwrap();
            f.fly_until(hover_t + 60.0, |f| f.autopilot.finished());
            let events = f.safety_events();
            let said: Vec<String> = events.iter().map(|e| e.to_string()).collect();
            eprintln!("ATT_MODE {att_mode}, GPS {kind:?}, seed {seed}: {said:?}");
            assert!(
                events
                    .iter()
                    .any(|e| matches!(e, SafetyEvent::Triggered(Condition::GpsLost, _))),
                "ATT_MODE {att_mode} seed {seed}: the GPS loss is said: {said:?}"
            );
            assert!(
                !events
                    .iter()
                    .any(|e| matches!(e, SafetyEvent::Triggered(Condition::AttitudeInvalid, _))),
                "ATT_MODE {att_mode} seed {seed}: the attitude estimate was said invalid: {said:?}"
            );
            assert!(f.sim.truth().landed);
        }
    }
}

/// A fence uploaded and an arm asked between two samples (a ground station's upload, then its
/// arm, in one batch of commands): the arm meets the new fence, not the last step's.
#[test]
fn an_arm_right_after_a_fence_upload_meets_the_new_fence() {
    use flight_core::safety::geofence::GeoZone;
    let mut f = Flight::new(1, 1, None);
    f.fly_until(60.0, |f| f.autopilot.status().prearm_ok);
    let home = f.sim.truth().position();
    // A circle 200 m north of the vehicle, 50 m across: the vehicle is outside it.
    let away = GeoZone::Circle {
        inclusion: true,
        center_deg: (home.lat_deg + 200.0 / 111_195.0, home.lon_deg),
        radius_m: 50.0,
    };
    f.autopilot
        .command(AutopilotCommand::SetFence(vec![away]))
        .unwrap();
    let refused = f
        .autopilot
        .command(AutopilotCommand::Arm { force: false })
        .unwrap_err();
    assert!(refused.to_string().contains("geofence"), "{refused}");
    // Around the vehicle: allowed at once too.
    let around = GeoZone::Circle {
        inclusion: true,
        center_deg: (home.lat_deg, home.lon_deg),
        radius_m: 50.0,
    };
    f.autopilot
        .command(AutopilotCommand::SetFence(vec![around]))
        .unwrap();
    f.autopilot
        .command(AutopilotCommand::Arm { force: false })
        .unwrap();
}
