//! The RC transmitter as the autopilot takes it, against the simulator's physics: which sticks
//! fly (`COM_RC_IN_MODE`), a receiver's failsafe flag as lost sticks, the arm switch only when
//! moved, the mode switch's slots.

// Test code: a failed unwrap is a failed test.
#![allow(clippy::unwrap_used)]

use airframe::MAX_ROTORS;
use flight_core::autopilot::command::AutopilotCommand;
use flight_core::autopilot::{Autopilot, StepInputs};
use flight_core::commander::rc_input::{RC_CHANNELS, RcFrame};
use flight_core::commander::{FlightMode, Sticks};
use flight_core::params::FlightParams;
use sitl_core::sim::{SimConfig, Simulator};

mod common;

struct Bench {
    sim: Simulator,
    autopilot: Autopilot,
    commands: [f64; MAX_ROTORS],
}

impl Bench {
    fn new(params: FlightParams) -> Self {
        let a = common::airframe("quad_x");
        let mut p = params;
        p.attitude.mag_calibration_id = flight_core::sensors::mag_check::SIMULATED_MAG_ID;
        Self {
            sim: Simulator::new(&a, SimConfig::default(), sitl_core::BodyState::default()).unwrap(),
            autopilot: Autopilot::new(&a, &p, None).unwrap(),
            commands: [0.0; MAX_ROTORS],
        }
    }

    /// One control interval, with `rc` if given.
    fn step(&mut self, rc: Option<RcFrame>) {
        let s = common::control_interval(&mut self.sim, &self.commands[..4]);
        let inputs = StepInputs {
            rc,
            ..StepInputs::default()
        };
        self.commands = self.autopilot.step(&s, &inputs).unwrap().commands;
    }

    fn steps(&mut self, n: usize, rc: Option<RcFrame>) {
        for _ in 0..n {
            self.step(rc);
        }
    }

    fn manual_control(&self) -> Option<bool> {
        self.autopilot.status().manual_control
    }
}

/// Throttle down, the mode switch in slot `slot`, the arm switch (channel 6) at `arm` µs.
fn frame(slot: u16, arm: u16, failsafe: bool) -> RcFrame {
    let mut channels = [1500; RC_CHANNELS];
    channels[2] = 1000;
    channels[4] = 1000 + slot * 1000 / 6 + 80;
    channels[5] = arm;
    RcFrame {
        channels,
        count: 16,
        failsafe,
        link: None,
    }
}

#[test]
fn the_receivers_failsafe_flag_is_lost_sticks_and_a_joystick_only_vehicle_ignores_rc() {
    let mut b = Bench::new(FlightParams::default());
    b.steps(50, Some(frame(0, 1000, false)));
    assert_eq!(b.manual_control(), Some(true));
    // The flag up for longer than COM_RC_LOSS_T (0.5 s at 250 Hz): lost.
    b.steps(150, Some(frame(0, 1000, true)));
    assert_eq!(b.manual_control(), Some(false));

    let mut p = FlightParams::default();
    p.rc.input_mode = 1;
    let mut b = Bench::new(p);
    b.steps(50, Some(frame(0, 1000, false)));
    assert_eq!(b.manual_control(), None, "RC ignored");
    b.autopilot
        .command(AutopilotCommand::Sticks(Sticks::CENTRED))
        .unwrap();
    b.steps(1, None);
    assert_eq!(b.manual_control(), Some(true), "the joystick flies");
}

#[test]
fn rc_first_keeps_the_sticks_until_it_is_lost_then_the_joystick_takes_them() {
    let mut b = Bench::new(FlightParams::default()); // COM_RC_IN_MODE 3
    b.steps(20, Some(frame(0, 1000, false)));
    // The joystick while RC flies: ignored (the commander's sticks stay RC's).
    let joystick = Sticks {
        throttle: 0.9,
        ..Sticks::CENTRED
    };
    b.autopilot
        .command(AutopilotCommand::Sticks(joystick))
        .unwrap();
    b.steps(1, Some(frame(0, 1000, false)));
    b.steps(150, None);
    assert_eq!(
        b.manual_control(),
        Some(false),
        "RC's sticks lost, the joystick's not taken"
    );
    // RC lost: the joystick is taken now.
    b.autopilot
        .command(AutopilotCommand::Sticks(joystick))
        .unwrap();
    b.steps(1, None);
    assert_eq!(b.manual_control(), Some(true));
}

#[test]
fn the_arm_switch_arms_only_when_moved_and_the_mode_switch_enters_its_slots_mode() {
    let mut p = FlightParams::default();
    p.rc.map_arm = 6;
    let mut b = Bench::new(p);
    // Found on at start: no arming.
    b.steps(1500, Some(frame(3, 2000, false)));
    assert!(!b.autopilot.status().armed);
    // The slot found at start (Hold) was refused then (no estimate yet); a switch's mode is
    // tried again only when it moves: to Position (slot 0), then back to Hold.
    b.steps(5, Some(frame(0, 1000, false)));
    assert_eq!(b.autopilot.status().mode, FlightMode::Posctl);
    b.steps(5, Some(frame(3, 1000, false)));
    assert_eq!(b.autopilot.status().mode, FlightMode::Loiter);
    // Moved off and on: armed.
    b.steps(5, Some(frame(3, 2000, false)));
    assert!(b.autopilot.status().armed);
    b.steps(5, Some(frame(3, 1000, false)));
    assert!(!b.autopilot.status().armed, "off on the ground disarms");
}

#[test]
fn during_a_radio_calibration_the_channels_are_reported_not_flown() {
    let mut b = Bench::new(FlightParams::default());
    b.steps(1500, Some(frame(0, 1000, false)));
    assert_eq!(b.autopilot.status().mode, FlightMode::Posctl);
    b.autopilot
        .command(AutopilotCommand::CalibrateRadio)
        .unwrap();
    b.steps(5, Some(frame(3, 1000, false)));
    assert_eq!(
        b.autopilot.status().mode,
        FlightMode::Posctl,
        "the switch not flown"
    );
    assert!(b.autopilot.state().rc.is_some(), "but reported");
    let armed = b.autopilot.command(AutopilotCommand::Arm { force: false });
    assert!(armed.is_err(), "{armed:?}");
    b.autopilot
        .command(AutopilotCommand::CancelCalibration)
        .unwrap();
    b.steps(5, Some(frame(0, 1000, false)));
    b.steps(5, Some(frame(3, 1000, false)));
    assert_eq!(b.autopilot.status().mode, FlightMode::Loiter);
}
