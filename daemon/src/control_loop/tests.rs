//! Sensors that stop, flown in the embedded simulator: the link below loses frames or
//! messages on cue while the world goes on, and keeps its own clock (the simulation time),
//! so every run is the same run.
#![allow(clippy::unwrap_used)]

use super::*;
use crate::links::sim::{EXCHANGE_HZ, EmbeddedSim};
use flight_core::autopilot::AutoFlight;
use flight_core::params::FlightParams;
use nalgebra::Vector3;
use sitl_core::Airframe;
use sitl_core::sensors::SensorPreset;
use std::io;
use std::path::PathBuf;

/// What stops, and when.
#[derive(Clone, Copy)]
enum Fault {
    /// All frames, `after_s` after take-off (0: at once), for `for_s` seconds.
    Frames { after_s: f64, for_s: f64 },
    /// The link both ways (frames and commands), `after_s` into the hover, for `for_s`
    /// seconds: the simulator holds the last command meanwhile.
    Blackout { after_s: f64, for_s: f64 },
    /// All frames, half a second after arming, on the ground, for good.
    FramesOnGround,
    /// The GPS messages, two seconds into the hover, for good.
    Gps,
    /// The IMU repeats one reading (gyro and accelerometer), two seconds into the hover.
    ImuFrozen,
    /// The simulator stops two seconds into the hover and a new one (a new world, the
    /// vehicle on the ground, its clock from zero) starts a second later.
    SimRestart,
}

struct FaultyLink {
    sim: EmbeddedSim,
    fault: Fault,
    /// Simulation time the fault began, once it has.
    began_s: Option<f64>,
    lost_until_s: f64,
    armed_at_s: Option<f64>,
    hover_from_s: Option<f64>,
    last_frame_s: f64,
    silent_waits: u32,
    reaction_s: Option<f64>,
    last_answer_armed: bool,
    /// Largest tilt after the fault began, in the air (before the first touch of the ground).
    max_tilt_after_deg: f64,
    /// The ground has been touched since the fault began, and when first.
    touched: bool,
    touched_at_s: Option<f64>,
    /// Horizontal speed at the first touch after the fault (m/s).
    touch_speed_xy_m_s: f64,
    /// Largest tilt on the ground after the first touch (deg): over 90°, it tipped over.
    max_tilt_on_ground_deg: f64,
    /// Largest tilt from two seconds after the frames came back (the attitude sought for about
    /// 0.7 s of it, the rates held meanwhile, then levelled).
    max_tilt_closed_loop_deg: f64,
    touchdown_m_s: f64,
    max_height_m: f64,
    horizontal_at_fault: Vector3<f64>,
    max_drift_after_m: f64,
    /// The reading a frozen IMU repeats: gyro, accelerometer.
    frozen_imu: Option<(Vector3<f64>, Vector3<f64>)>,
    /// The seed and airframe of a simulator started again, and whether it has been.
    seed: u64,
    airframe: Airframe,
    restarted: bool,
    /// The hover's height (m).
    height_m: f64,
}

impl FaultyLink {
    fn new(fault: Fault, seed: u64, height_m: f64) -> Self {
        let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../params");
        let airframe = Airframe::load(&dir.join("airframes/quad_x.toml")).unwrap();
        Self {
            sim: EmbeddedSim::new(&airframe, seed, SensorPreset::Typical, None, None).unwrap(),
            seed,
            airframe,
            restarted: false,
            fault,
            began_s: None,
            lost_until_s: 0.0,
            armed_at_s: None,
            hover_from_s: None,
            last_frame_s: 0.0,
            silent_waits: 0,
            reaction_s: None,
            last_answer_armed: false,
            max_tilt_after_deg: 0.0,
            touched: false,
            touched_at_s: None,
            touch_speed_xy_m_s: 0.0,
            max_tilt_on_ground_deg: 0.0,
            max_tilt_closed_loop_deg: 0.0,
            touchdown_m_s: 0.0,
            max_height_m: 0.0,
            horizontal_at_fault: Vector3::zeros(),
            max_drift_after_m: 0.0,
            frozen_imu: None,
            height_m,
        }
    }

    fn now_s(&self) -> f64 {
        self.sim.truth().time_usec as f64 * 1e-6
    }

    /// Watches the truth after every exchange.
    fn observe(&mut self) {
        let truth = self.sim.truth();
        let t = self.now_s();
        let height = -truth.body.pos_ned_m.z;
        self.max_height_m = self.max_height_m.max(height);
        if height > self.height_m - 0.1 && self.hover_from_s.is_none() {
            self.hover_from_s = Some(t);
        }
        let start = match self.fault {
            Fault::Frames { after_s, for_s } | Fault::Blackout { after_s, for_s } => {
                self.lost_until_s = f64::INFINITY;
                self.hover_from_s.map(|h| {
                    self.lost_until_s = h + after_s + for_s;
                    h + after_s
                })
            }
            Fault::FramesOnGround => {
                self.lost_until_s = f64::INFINITY;
                self.armed_at_s.map(|a| a + 0.5)
            }
            Fault::Gps | Fault::ImuFrozen | Fault::SimRestart => self.hover_from_s.map(|h| h + 2.0),
        };
        if self.began_s.is_none() && !self.restarted && start.is_some_and(|s| t >= s) {
            self.began_s = Some(t);
            self.horizontal_at_fault = truth.body.pos_ned_m;
        }
        if self.began_s.is_some() {
            let up = Vector3::new(0.0, 0.0, -1.0);
            let tilt = (truth.body.q_ned_from_frd * up).angle(&up).to_degrees();
            if truth.landed && !self.touched && self.max_height_m > 1.0 {
                self.touched = true;
                self.touched_at_s = Some(t);
                self.touch_speed_xy_m_s = truth.body.vel_ned_m_s.xy().norm();
            }
            if self.touched {
                self.max_tilt_on_ground_deg = self.max_tilt_on_ground_deg.max(tilt);
            } else {
                self.max_tilt_after_deg = self.max_tilt_after_deg.max(tilt);
            }
            if t > self.lost_until_s + 2.0 {
                self.max_tilt_closed_loop_deg = self.max_tilt_closed_loop_deg.max(tilt);
            }
            let drift = (truth.body.pos_ned_m - self.horizontal_at_fault)
                .xy()
                .norm();
            self.max_drift_after_m = self.max_drift_after_m.max(drift);
        }
        if height < 0.3 && !truth.landed {
            self.touchdown_m_s = self.touchdown_m_s.max(truth.body.vel_ned_m_s.z);
        }
    }

    fn frames_lost(&self) -> bool {
        if matches!(self.fault, Fault::SimRestart) {
            return !self.restarted && self.began_s.is_some();
        }
        matches!(
            self.fault,
            Fault::Frames { .. } | Fault::Blackout { .. } | Fault::FramesOnGround
        ) && self
            .began_s
            .is_some_and(|_| self.now_s() < self.lost_until_s)
    }
}

impl SensorLink for FaultyLink {
    fn receive(&mut self, timeout: Duration, into: &mut Received) -> io::Result<bool> {
        if self.now_s() > 300.0 {
            return Err(io::Error::other("the flight did not end within 300 s"));
        }
        if matches!(self.fault, Fault::SimRestart)
            && self.frames_lost()
            && self.began_s.is_some_and(|b| self.now_s() >= b + 1.0)
        {
            // A new world: the vehicle on the ground, the clock from zero.
            self.sim = EmbeddedSim::new(
                &self.airframe,
                self.seed + 1,
                SensorPreset::Typical,
                None,
                None,
            )
            .map_err(|e| io::Error::other(format!("{e:#}")))?;
            self.restarted = true;
            self.max_height_m = 0.0;
            self.touchdown_m_s = 0.0;
        }
        if self.frames_lost() {
            // The world goes on for the wait; no frame reaches the autopilot.
            let n = (timeout.as_secs_f64() * EXCHANGE_HZ).round().max(1.0) as usize;
            self.sim.advance_silently(n);
            self.observe();
            self.silent_waits += 1;
            return Ok(false);
        }
        let before = into.frames.len();
        self.sim.receive(timeout, into)?;
        self.observe();
        for frame in &mut into.frames[before..] {
            let s = &mut frame.sample;
            if matches!(self.fault, Fault::Gps) && self.began_s.is_some() {
                s.gps = None;
            }
            if matches!(self.fault, Fault::ImuFrozen) && self.began_s.is_some() {
                (s.gyro, s.accel) = *self.frozen_imu.get_or_insert((s.gyro, s.accel));
            }
        }
        self.last_frame_s = self.now_s();
        Ok(true)
    }

    fn send(&mut self, command: &hil::ActuatorCommand) -> io::Result<()> {
        let armed = command.armed;
        if armed && self.armed_at_s.is_none() {
            self.armed_at_s = Some(self.now_s());
        }
        // The first answer sent into the silence (not the one to the last frame).
        if self.silent_waits > 0 && self.reaction_s.is_none() {
            self.reaction_s = Some(self.now_s() - self.last_frame_s);
        }
        self.last_answer_armed = armed;
        if matches!(self.fault, Fault::Blackout { .. }) && self.frames_lost() {
            return Ok(()); // lost on the way: the simulator holds the last command
        }
        self.sim.send(command)
    }

    fn describe(&self) -> String {
        "faulty sim".into()
    }

    fn silence_clock_s(&self) -> Option<f64> {
        Some(self.now_s())
    }
}

fn fly_with(fault: Fault) -> (FaultyLink, FlightReport, Autopilot) {
    fly_seed(fault, 3)
}

fn fly_seed(fault: Fault, seed: u64) -> (FaultyLink, FlightReport, Autopilot) {
    fly_at(fault, seed, 5.0)
}

/// `fault` flown from a hover at `takeoff_m`. With `FAULT_TEST_CSV=PREFIX` in the environment
/// each flight's CSV is written to `PREFIX-SEED-HEIGHT.csv` (to look at one).
fn fly_at(fault: Fault, seed: u64, takeoff_m: f64) -> (FaultyLink, FlightReport, Autopilot) {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../params");
    let airframe = Airframe::load(&dir.join("airframes/quad_x.toml")).unwrap();
    let mut params = FlightParams::load(&dir.join("flight.toml")).unwrap();
    crate::links::Source::Embedded.preset_params(&mut params);
    let auto = AutoFlight {
        takeoff_m,
        hover_s: 30.0,
    };
    let mut autopilot = Autopilot::new(&airframe, &params, Some(auto)).unwrap();
    let mut records = FlightRecords::new(auto.takeoff_m);
    if let Ok(path) = std::env::var("FAULT_TEST_CSV") {
        let path = format!("{path}-{seed}-{takeoff_m}.csv");
        records
            .log_to(crate::records::flight_csv::FlightCsv::create(path.as_ref(), 4, true).unwrap());
    }
    let mut link = FaultyLink::new(fault, seed, takeoff_m);
    let (mut ports, _ends) = Ports::new(4);
    let vehicle = Onboard {
        link: &mut link,
        autopilot: &mut autopilot,
        records: &mut records,
        ports: &mut ports,
    };
    let report = fly(vehicle, Pacing::Lockstep).unwrap();
    eprintln!(
        "fault began at {:?} s: reaction {:?} s, tilt after ≤ {:.1}° in the air, ≤ {:.1}° on the ground, drift after ≤ {:.2} m, touchdown {:.2} m/s ({:.2} m/s sideways), ended at {:.1} s\n{report}",
        link.began_s,
        link.reaction_s,
        link.max_tilt_after_deg,
        link.max_tilt_on_ground_deg,
        link.max_drift_after_m,
        link.touchdown_m_s,
        link.touch_speed_xy_m_s,
        link.now_s()
    );
    (link, report, autopilot)
}

/// Open loop, the descent is only as level as the hover commands are balanced and the
/// vehicle was still when the frames stopped: over seeds 2–6 and both blind faults (frames
/// stopped, IMU frozen) it tilts 3.9–18.8° in the air and lands at 1.2–1.7 m/s, a firm landing
/// against ≈ 10 m/s for a fall from 5 m, but with 0.8–4.9 m/s of sideways drift, on which its
/// legs catch and it tips over on the ground in 9 of the 10. What is asserted on every seed
/// is the reaction and a descent that ends on the ground, never inverted in the air, slower
/// than half a fall, motors stopped; over the five seeds, the median tilt and touchdown.
#[test]
fn frames_that_stop_in_the_air_start_a_blind_descent_to_the_ground() {
    let mut descents = Vec::new();
    for seed in 2..=6 {
        let (link, report, vehicle) = fly_seed(
            Fault::Frames {
                after_s: 2.0,
                for_s: f64::INFINITY,
            },
            seed,
        );
        let reaction = link.reaction_s.expect("a failsafe answer while silent");
        assert!(
            reaction <= 0.1,
            "seed {seed}: reacted {reaction:.3} s after the last frame"
        );
        assert_eq!(report.sensor_timeouts, 1);
        assert!(
            report.failsafe(),
            "seed {seed}: the summary counts the blind descent"
        );
        descents.push(assert_came_down_blind(&link, &vehicle, seed));
    }
    assert_typical_blind_descents(&mut descents);
}

/// Over several seeds, the median blind descent tilts at most 30° and lands at 2.5 m/s.
fn assert_typical_blind_descents(descents: &mut [(f64, f64)]) {
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let tilt = median(&mut descents.iter().map(|d| d.0).collect());
    let touchdown = median(&mut descents.iter().map(|d| d.1).collect());
    assert!(
        tilt <= 30.0 && touchdown <= 2.5,
        "median tilt {tilt:.1}°, touchdown {touchdown:.2} m/s"
    );
}

/// The end of a blind descent: on the ground, never inverted, landed slower than half a
/// fall from 5 m, motors stopped. Returns the largest tilt (°) and the touchdown (m/s).
fn assert_came_down_blind(link: &FaultyLink, vehicle: &Autopilot, seed: u64) -> (f64, f64) {
    assert!(link.max_height_m > 4.9, "was flying");
    assert!(
        link.sim.truth().landed,
        "seed {seed}: on the ground at the end"
    );
    assert!(!link.last_answer_armed, "motors stopped at the end");
    assert!(vehicle.finished() && !vehicle.status().armed);
    assert!(
        link.touchdown_m_s <= 5.0,
        "seed {seed}: touchdown at {:.2} m/s",
        link.touchdown_m_s
    );
    assert!(
        link.max_tilt_after_deg < 90.0,
        "seed {seed}: never inverted in the air: tilt up to {:.1}°",
        link.max_tilt_after_deg
    );
    (link.max_tilt_after_deg, link.touchdown_m_s)
}

#[test]
fn frames_that_stop_on_the_ground_disarm_at_once() {
    let (link, report, vehicle) = fly_with(Fault::FramesOnGround);
    let reaction = link.reaction_s.expect("a failsafe answer while silent");
    assert!(
        reaction <= 0.1,
        "reacted {reaction:.3} s after the last frame"
    );
    assert!(!link.last_answer_armed && vehicle.finished());
    assert!(report.disarmed);
    assert!(link.max_height_m < 0.1, "never left the ground");
    assert!(
        report.failsafe(),
        "armed when the frames stopped: the failsafe that disarmed it is counted"
    );
}

#[test]
fn frames_that_come_back_hand_the_descent_back_to_the_loops() {
    let (link, report, vehicle) = fly_with(Fault::Frames {
        after_s: 2.0,
        for_s: 1.5,
    });
    assert!(link.reaction_s.is_some_and(|r| r <= 0.1));
    assert_eq!(report.sensor_timeouts, 1);
    assert!(
        link.now_s() < link.began_s.unwrap() + 20.0,
        "descended instead of hovering"
    );
    assert!(link.sim.truth().landed && vehicle.finished());
    assert!(
        link.touchdown_m_s <= 1.0,
        "touchdown at {:.2} m/s",
        link.touchdown_m_s
    );
    assert!(
        link.max_tilt_closed_loop_deg <= 5.0,
        "level two seconds after the frames came back: {:.1}°",
        link.max_tilt_closed_loop_deg
    );
}

/// A simulator that stops in the air and starts again (a new world, its clock from zero):
/// the silence is met by the blind descent; the frames of the new world make the vehicle
/// start afresh (disarmed, estimator aligning) and fly again — here the auto flight: take
/// off, hover, land — without the daemon restarting.
#[test]
fn a_simulator_restarted_in_flight_restarts_the_vehicle_which_flies_again() {
    let (link, report, vehicle) = fly_with(Fault::SimRestart);
    assert!(link.restarted, "the simulator was restarted");
    assert!(link.reaction_s.is_some(), "the silence was answered");
    assert_eq!(report.sensor_timeouts, 1);
    assert_eq!(vehicle.state().source_restarts, 1);
    assert!(
        link.max_height_m > 4.5,
        "flew again: {:.2} m",
        link.max_height_m
    );
    let truth = link.sim.truth();
    assert!(
        truth.landed && report.disarmed,
        "landed and disarmed in the new world"
    );
    assert!(link.touchdown_m_s < 1.0, "{:.2} m/s", link.touchdown_m_s);
}

/// A frozen IMU leaves the frames coming: the monitor finds the repeated reading (0.2 s),
/// the loops stop and the blind descent of silent frames flies the vehicle down. What is
/// asserted holds for the silent frames too: on the ground upright, motors stopped.
#[test]
fn an_imu_that_freezes_in_the_air_starts_the_blind_descent() {
    let mut descents = Vec::new();
    for seed in 2..=6 {
        let (link, report, vehicle) = fly_seed(Fault::ImuFrozen, seed);
        let began = link.began_s.unwrap();
        assert_eq!(report.sensor_timeouts, 0, "the frames kept coming");
        assert!(link.now_s() < began + 20.0, "seed {seed}: came down");
        assert!(report.disarmed);
        descents.push(assert_came_down_blind(&link, &vehicle, seed));
    }
    assert_typical_blind_descents(&mut descents);
}

/// Without GPS the vehicle holds the level its accelerometer shows, which is off by the
/// accelerometer's horizontal bias over g (no estimator separates the two in a hover at
/// one heading): it drifts at most as that bias accelerates it for the descent, plus the
/// speed it had when the GPS stopped. A tilt held from before would drift tens of metres.
#[test]
fn gps_that_stops_in_the_air_levels_and_descends_on_the_barometer() {
    for seed in 1..=5 {
        let (link, report, vehicle) = fly_seed(Fault::Gps, seed);
        let began = link.began_s.unwrap();
        let descent_s = link.now_s() - began;
        assert!(
            descent_s < 20.0,
            "seed {seed}: descended instead of hovering 30 s"
        );
        assert_eq!(report.sensor_timeouts, 0, "the frames kept coming");
        assert!(link.sim.truth().landed && vehicle.finished());
        assert!(report.disarmed);
        assert!(
            link.touchdown_m_s <= 1.0,
            "seed {seed}: touchdown at {:.2} m/s",
            link.touchdown_m_s
        );
        assert!(link.max_tilt_after_deg <= 5.0);
        let bias_drift_m = 0.5 * link.sim.accel_bias().xy().norm() * descent_s.powi(2);
        assert!(
            link.max_drift_after_m <= bias_drift_m + 1.0,
            "seed {seed}: drifted {:.2} m ({bias_drift_m:.2} m from the accelerometer bias)",
            link.max_drift_after_m
        );
    }
}

/// A link that fails after `frames` frames: a vehicle whose flight ends in error.
struct FailingLink {
    sim: EmbeddedSim,
    frames: u32,
}

impl SensorLink for FailingLink {
    fn receive(&mut self, timeout: Duration, into: &mut Received) -> io::Result<bool> {
        if self.frames == 0 {
            return Err(io::Error::other("the simulator went away"));
        }
        self.frames -= 1;
        self.sim.receive(timeout, into)
    }
    fn send(&mut self, command: &hil::ActuatorCommand) -> io::Result<()> {
        self.sim.send(command)
    }
    fn describe(&self) -> String {
        "failing".into()
    }
    fn silence_clock_s(&self) -> Option<f64> {
        None
    }
}

/// A quad that takes off to 3 m, hovers 2 s and lands, flying with the seed's sensors.
fn swarm_member(seed: u64) -> (Autopilot, FlightRecords, EmbeddedSim, Ports) {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../params");
    let airframe = Airframe::load(&dir.join("airframes/quad_x.toml")).unwrap();
    let mut params = FlightParams::load(&dir.join("flight.toml")).unwrap();
    crate::links::Source::Embedded.preset_params(&mut params);
    let auto = AutoFlight {
        takeoff_m: 3.0,
        hover_s: 2.0,
    };
    let autopilot = Autopilot::new(&airframe, &params, Some(auto)).unwrap();
    let sim = EmbeddedSim::new(&airframe, seed, SensorPreset::Typical, None, None).unwrap();
    (
        autopilot,
        FlightRecords::new(auto.takeoff_m),
        sim,
        Ports::new(4).0,
    )
}

/// Ten vehicles in lockstep on one clock: every round each vehicle still flying takes one
/// frame, so each flies exactly the flight it flies alone (the same frames, the same
/// figures to the bit), all land, and one whose link fails ends in error while the others
/// fly on.
#[test]
fn ten_vehicles_fly_together_on_one_clock_each_as_it_flies_alone() {
    let mut members: Vec<_> = (1..=10).map(swarm_member).collect();
    let (mut failing_autopilot, mut failing_records, sim, mut failing_ports) = swarm_member(11);
    let mut failing = FailingLink { sim, frames: 500 };
    let mut all: Vec<Onboard<'_>> = members
        .iter_mut()
        .map(|(autopilot, records, sim, ports)| Onboard {
            link: sim,
            autopilot,
            records,
            ports,
        })
        .collect();
    all.push(Onboard {
        link: &mut failing,
        autopilot: &mut failing_autopilot,
        records: &mut failing_records,
        ports: &mut failing_ports,
    });
    let swarm = fly_together(all, EXCHANGE_HZ, None);
    assert_eq!(swarm.flights.len(), 11);
    let err = swarm.flights[10].as_ref().unwrap_err();
    assert!(format!("{err:#}").contains("went away"), "{err:#}");
    let mut longest = 0;
    for (k, flight) in swarm.flights[..10].iter().enumerate() {
        let r = flight.as_ref().unwrap();
        eprintln!("{r}");
        assert!(r.landed(), "vehicle {} landed", k + 1);
        assert!(
            (2.7..=3.5).contains(&r.score.max_height_m),
            "vehicle {}: {:.2} m",
            k + 1,
            r.score.max_height_m
        );
        longest = longest.max(r.frames);
    }
    assert_eq!(swarm.rounds, longest, "one frame per vehicle per round");
    assert!((swarm.sim_time_s - longest as f64 / EXCHANGE_HZ).abs() < 1e-9);
    for seed in [1, 7] {
        let (mut autopilot, mut records, mut sim, mut ports) = swarm_member(seed);
        let vehicle = Onboard {
            link: &mut sim,
            autopilot: &mut autopilot,
            records: &mut records,
            ports: &mut ports,
        };
        let alone = fly(vehicle, Pacing::Lockstep).unwrap();
        let together = swarm.flights[seed as usize - 1].as_ref().unwrap();
        assert_eq!(alone.frames, together.frames, "seed {seed}");
        assert_eq!(alone.score.max_height_m, together.score.max_height_m);
        assert_eq!(alone.score.touchdown_m_s, together.score.touchdown_m_s);
        assert_eq!(
            alone.score.attitude_rms_deg(),
            together.score.attitude_rms_deg()
        );
    }
}

/// A link dark both ways in a hover (a radio out of range, a cable pulled): the simulator
/// holds the last command while nothing is seen. From the frames' return the attitude is
/// unknown, the rates are held on the gyro alone, and the GPS's velocity and the magnetometer
/// find the attitude again (`realign.rs`); the position loop then brakes whatever fall it
/// finds. Where the vehicle is still in the air a second after the return, the estimate is
/// within 5° of the truth from then on; from 20 m after 2 s it lands gently whatever the held
/// command did. What the held command does in the dark is physics: a hover's command holds
/// its rate loop's last correction, a torque that turns the vehicle over within 2–5 s (and
/// nothing the autopilot sends can reach it); those flights are printed, not judged.
#[test]
fn a_link_dark_both_ways_in_the_air_finds_the_attitude_again() {
    let mut judged = 0;
    for (gap_s, height_m) in [(2.0, 5.0), (2.0, 20.0), (5.0, 5.0), (5.0, 20.0)] {
        for seed in 1..=3 {
            let (link, report, _) = fly_at(
                Fault::Blackout {
                    after_s: 3.0,
                    for_s: gap_s,
                },
                seed,
                height_m,
            );
            let score = report.score();
            let back_s = link.lost_until_s;
            let flying_after_1s = link.touched_at_s.is_none_or(|t| t > back_s + 1.0);
            eprintln!(
                "dark {gap_s} s at {height_m} m, seed {seed}: tilt up to {:.0}° in the air, first touch {}, attitude error from 1 s after the return ≤ {:.1}°, fastest touch of the ground {:.2} m/s",
                link.max_tilt_after_deg,
                link.touched_at_s.map_or("none".into(), |t| format!(
                    "{:+.2} s after the return",
                    t - back_s
                )),
                score.max_attitude_err_after_gap_deg,
                link.touchdown_m_s,
            );
            assert_eq!(score.gaps, 1, "one gap seen");
            if flying_after_1s {
                judged += 1;
                assert!(
                    score.max_attitude_err_after_gap_deg <= 5.0,
                    "dark {gap_s} s at {height_m} m, seed {seed}: {:.1}°",
                    score.max_attitude_err_after_gap_deg
                );
            }
            if gap_s == 2.0 && height_m == 20.0 {
                assert!(
                    link.touchdown_m_s <= 2.0,
                    "dark 2 s at 20 m, seed {seed}: touched at {:.2} m/s",
                    link.touchdown_m_s
                );
            }
        }
    }
    assert!(judged >= 3, "{judged} flights flew on after the return");
}
