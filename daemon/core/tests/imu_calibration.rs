//! The gyro, accelerometer and level-horizon calibrations against the simulator's sensor
//! errors, in-process: the simulator's "uncalibrated" board (accelerometer offsets and scale
//! errors, a gyro turn-on bias, a board mounted off level) calibrated the way a person does it —
//! the simulator's hand does what each calibration asks — and a hover flown before and after.

// Test code: a failed unwrap is a failed test.
#![allow(clippy::unwrap_used)]

use airframe::{Airframe, MAX_ROTORS};
use flight_core::autopilot::command::AutopilotCommand;
use flight_core::autopilot::{Autopilot, AutopilotOutput, StepInputs};
use flight_core::commander::{FlightMode, LandedState};
use flight_core::params::FlightParams;
use flight_core::sensors::imu_calibrator::{
    ImuCalKind, ImuCalResult, ImuCalState, PoseRequest, Side,
};
use nalgebra::Vector3;
use sitl_core::sensors::{SensorConfig, SensorPreset};
use sitl_core::sim::{Face, SimAction, SimConfig, Simulator};

mod common;

fn quad() -> Airframe {
    Airframe::load(std::path::Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../params/airframes/quad_x.toml"
    )))
    .unwrap()
}

/// The simulator, the autopilot, and the hand between them.
struct Bench {
    sim: Simulator,
    autopilot: Autopilot,
    params: FlightParams,
    commands: [f64; MAX_ROTORS],
    hand: PoseRequest,
}

fn face(side: Side) -> Face {
    match side {
        Side::Back => Face::Back,
        Side::Front => Face::Front,
        Side::Left => Face::Left,
        Side::Right => Face::Right,
        Side::Up => Face::Up,
        Side::Down => Face::Down,
    }
}

impl Bench {
    fn new(seed: u64) -> Self {
        let a = quad();
        let config = SimConfig {
            seed,
            sensors: SensorConfig::preset(SensorPreset::Uncalibrated),
            ..SimConfig::default()
        };
        let mut params = FlightParams::default();
        params.attitude.mag_calibration_id = flight_core::sensors::mag_check::SIMULATED_MAG_ID;
        Self {
            sim: Simulator::new(&a, config, sitl_core::BodyState::default()).unwrap(),
            autopilot: Autopilot::new(&a, &params, None).unwrap(),
            params,
            commands: [0.0; MAX_ROTORS],
            hand: PoseRequest::None,
        }
    }

    /// One control interval; the hand does what the calibration under way asks (as the
    /// simulator's does on the HIL link).
    fn step(&mut self) -> AutopilotOutput {
        let s = common::control_interval(&mut self.sim, &self.commands[..4]);
        let out = self.autopilot.step(&s, &StepInputs::default()).unwrap();
        self.commands = out.commands;
        let asked = self.autopilot.pose_request();
        if asked != self.hand {
            self.hand = asked;
            self.sim.apply(match asked {
                PoseRequest::None => SimAction::SetDown,
                PoseRequest::Place(side) => SimAction::Place { face: face(side) },
                PoseRequest::Tumble => SimAction::Tumble { duration_s: 600.0 },
            });
        }
        out
    }

    fn run_for(&mut self, s: f64) {
        let end = self.sim.time_s() + s;
        while self.sim.time_s() < end {
            self.step();
        }
    }

    /// Runs a calibration to its end and flies its result, as the ground station sets it.
    fn calibrate(&mut self, kind: ImuCalKind) -> ImuCalResult {
        self.autopilot
            .command(AutopilotCommand::CalibrateImu(kind))
            .unwrap();
        let start = self.sim.time_s();
        let status = loop {
            self.step();
            let s = self.autopilot.state().imu_cal.unwrap();
            if s.state != ImuCalState::Collecting {
                break s;
            }
            assert!(self.sim.time_s() - start < 120.0, "{kind:?} never ended");
        };
        println!(
            "{kind:?}: {:.1} s, {} restarts",
            self.sim.time_s() - start,
            status.restarts
        );
        let ImuCalState::Succeeded(r) = status.state else {
            panic!("{kind:?}: {:?}", status.state);
        };
        let imu = &mut self.params.imu;
        match r {
            ImuCalResult::Gyro { offset } => {
                (imu.gyro_offset_x, imu.gyro_offset_y, imu.gyro_offset_z) =
                    (offset.x, offset.y, offset.z);
            }
            ImuCalResult::Accel { offset, scale } => {
                (imu.accel_offset_x, imu.accel_offset_y, imu.accel_offset_z) =
                    (offset.x, offset.y, offset.z);
                (imu.accel_scale_x, imu.accel_scale_y, imu.accel_scale_z) =
                    (scale.x, scale.y, scale.z);
            }
            ImuCalResult::Level {
                roll_deg,
                pitch_deg,
            } => (imu.board_roll_deg, imu.board_pitch_deg) = (roll_deg, pitch_deg),
        }
        self.autopilot.set_params(&self.params);
        r
    }

    /// Takes off to 5 m, holds 20 s, lands. Returns the RMS of the estimator's tilt error
    /// (deg, against the simulator's truth) and of the horizontal distance from the take-off
    /// point (m), over the hold.
    fn hover(&mut self) -> (f64, f64) {
        // Armed once the estimator is ready (aligned, the gyro bias settled at rest).
        let start = self.sim.time_s();
        self.autopilot
            .command(AutopilotCommand::Takeoff(Some(5.0)))
            .unwrap();
        while let Err(e) = self
            .autopilot
            .command(AutopilotCommand::Arm { force: false })
        {
            assert!(self.sim.time_s() - start < 30.0, "{e:?}");
            self.step();
        }
        let home = self.sim.truth().body.pos_ned_m;
        while self.autopilot.status().mode != FlightMode::Loiter {
            self.step();
        }
        let (mut tilt2, mut drift2, mut n) = (0.0, 0.0, 0.0);
        let end = self.sim.time_s() + 20.0;
        while self.sim.time_s() < end {
            self.step();
            let truth = self.sim.truth().body;
            let est = self.autopilot.state().estimate.unwrap().attitude.unwrap().q;
            // The tilt error: the angle between the true and the estimated down axes.
            let down = |q: &nalgebra::UnitQuaternion<f64>| q.transform_vector(&Vector3::z());
            let tilt = down(&truth.q_ned_from_frd).angle(&down(&est)).to_degrees();
            tilt2 += tilt * tilt;
            drift2 += (truth.pos_ned_m - home).xy().norm_squared();
            n += 1.0;
        }
        self.autopilot
            .command(AutopilotCommand::SetMode(FlightMode::Land))
            .unwrap();
        while self.autopilot.status().armed {
            self.step();
        }
        assert_eq!(self.autopilot.status().landed, LandedState::OnGround);
        ((tilt2 / n).sqrt(), (drift2 / n).sqrt())
    }
}

/// Each calibration recovers what the simulator put in: the gyro's turn-on bias, the
/// accelerometer's offsets and scale errors, the board's mounting angles.
#[test]
fn calibrations_recover_the_simulated_sensor_errors() {
    let mut b = Bench::new(3);
    b.run_for(3.0);
    let sensors = b.sim.sensors();
    let (bias, accel_bias, scale_err) = (
        sensors.gyro_bias(),
        sensors.accel_bias(),
        sensors.accel_scale_error(),
    );
    let (roll, pitch) = sensors.board_tilt_rad();
    let ImuCalResult::Gyro { offset } = b.calibrate(ImuCalKind::Gyro) else {
        panic!()
    };
    let err = (offset - bias).norm().to_degrees();
    println!(
        "gyro: bias {:.3} °/s, error {err:.4} °/s",
        bias.norm().to_degrees()
    );
    assert!(err < 0.02, "{err} °/s");

    let ImuCalResult::Accel { offset, scale } = b.calibrate(ImuCalKind::Accel) else {
        panic!()
    };
    let offset_err = (offset - accel_bias).amax();
    let truth_scale = scale_err.map(|e| 1.0 / (1.0 + e));
    let scale_err_max = (scale - truth_scale).amax();
    println!(
        "accel: offsets {:.3?} m/s², error {offset_err:.4}; scales {:.4?}, error {scale_err_max:.5}",
        accel_bias.as_slice(),
        truth_scale.as_slice()
    );
    assert!(offset_err < 0.01, "{offset_err} m/s²");
    assert!(scale_err_max < 1e-3, "{scale_err_max}");

    let ImuCalResult::Level {
        roll_deg,
        pitch_deg,
    } = b.calibrate(ImuCalKind::Level)
    else {
        panic!()
    };
    let (dr, dp) = (roll_deg - roll.to_degrees(), pitch_deg - pitch.to_degrees());
    println!(
        "level: board ({:.3}, {:.3})°, error ({dr:.4}, {dp:.4})°",
        roll.to_degrees(),
        pitch.to_degrees()
    );
    assert!(dr.abs() < 0.05 && dp.abs() < 0.05);
}

/// A hover on the uncalibrated board, then the three calibrations, then the same hover: the
/// estimator's tilt error falls to a fraction (the accelerometer's offsets and the board's
/// angle no longer pass for tilt).
#[test]
fn a_hover_after_calibrating_is_better_than_before() {
    let mut b = Bench::new(5);
    let (tilt_before, drift_before) = b.hover();
    for kind in [ImuCalKind::Gyro, ImuCalKind::Accel, ImuCalKind::Level] {
        b.calibrate(kind);
    }
    b.run_for(10.0);
    let (tilt_after, drift_after) = b.hover();
    println!(
        "tilt error RMS {tilt_before:.2}° before, {tilt_after:.2}° after; \
         distance from take-off RMS {drift_before:.2} m before, {drift_after:.2} m after"
    );
    assert!(
        tilt_after < tilt_before / 3.0,
        "{tilt_after} vs {tilt_before}"
    );
    assert!(tilt_after < 0.5, "{tilt_after}");
}
