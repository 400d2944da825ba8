//! One flight-core tick: attitude and translation estimators, position, attitude and rate
//! loops, mixer. Target: ≤ 2 µs for quad_x and dodeca.
//!
//! Measured in closed loop: the simulator flies the vehicle (a hover at 5 m) so every stage sees
//! realistic inputs; only `FlightCore::step` is timed. Also a quad's tick spinning on three
//! rotors (the reduced-attitude controller in place of the attitude and rate loops), and what
//! a flight core costs to build: a quad's solves four relaxed hovers and 36 LQRs.

#[path = "../tests/common/mod.rs"]
mod common;

use airframe::Airframe;
use criterion::{Criterion, criterion_group, criterion_main};
use flight_core::control::position::PositionSetpoint;
use flight_core::core::{FlightCore, FlightCoreConfig};
use flight_core::params::FlightParams;
use nalgebra::Vector3;
use sitl_core::BodyState;
use sitl_core::sim::{SimAction, SimConfig, Simulator};
use std::hint::black_box;
use std::path::PathBuf;
use std::time::{Duration, Instant};

fn airframe(name: &str) -> Airframe {
    Airframe::load(
        &PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join(format!("../../params/airframes/{name}.toml")),
    )
    .expect("shipped")
}

/// A flight core flying its airframe in the simulator, toward a hover at 5 m.
struct Hover {
    sim: Simulator,
    core: FlightCore,
    setpoint: flight_core::control::Setpoint,
    commands: [f64; 16],
    rotors: usize,
}

impl Hover {
    fn new(a: &Airframe, p: &FlightParams) -> Self {
        Self {
            sim: Simulator::new(a, SimConfig::default(), BodyState::default()).expect("sim"),
            core: FlightCore::new(a, FlightCoreConfig::from_params(p, a)).expect("mixer"),
            setpoint: flight_core::control::Setpoint::Position(PositionSetpoint {
                pos_ned_m: Vector3::new(0.0, 0.0, -5.0),
                vel_ned_m_s: Vector3::zeros(),
                accel_ned_m_s2: Vector3::zeros(),
                yaw_rad: 0.0,
            }),
            commands: [0.0; 16],
            rotors: a.rotors.len(),
        }
    }

    /// One control interval of the simulator, then the core's step on its sample; the time
    /// of the step alone.
    fn step(&mut self) -> Duration {
        let s = common::control_interval(&mut self.sim, &self.commands[..self.rotors]);
        let armed = self.sim.time_s() > 3.0;
        let start = Instant::now();
        let out = black_box(self.core.step(black_box(&s), &self.setpoint, armed));
        let spent = start.elapsed();
        self.commands = out.commands;
        spent
    }

    /// Aligns, takes off (armed after 3 s) and flies until `t_s` of simulated time.
    fn fly_until(&mut self, t_s: f64) {
        while self.sim.time_s() < t_s {
            self.step();
        }
    }

    /// Criterion's timing of `iters` steps.
    fn timed(&mut self, iters: u64) -> Duration {
        (0..iters).map(|_| self.step()).sum()
    }
}

fn tick(c: &mut Criterion) {
    let mut g = c.benchmark_group("flight_core_tick");
    for name in ["quad_x", "dodeca"] {
        // The rate loop and the attitude estimator (ATT_MODE 1 tilt/heading, the default; 0
        // Castillo's observer).
        for (label, pid, mode) in [
            ("ladrc", false, 1),
            ("pid", true, 1),
            ("ladrc-castillo", false, 0),
        ] {
            let mut p = FlightParams::default();
            p.rate.controller = pid as u32;
            p.attitude.mode = mode;
            let mut hover = Hover::new(&airframe(name), &p);
            // Align, take off and settle into the hover first.
            hover.fly_until(15.0);
            g.bench_function(format!("{name}/{label}"), |b| {
                b.iter_custom(|iters| hover.timed(iters))
            });
        }
    }
    g.finish();
}

/// `quad_x` hovering at 5 m, rotor 1 cut and 10 s of spinning on the other three, then its
/// tick timed; and `FlightCore::new` for a quad and a hexa.
fn three_rotors(c: &mut Criterion) {
    let mut g = c.benchmark_group("flight_core_three_rotors");
    let p = FlightParams::default();
    let mut hover = Hover::new(&airframe("quad_x"), &p);
    hover.fly_until(15.0);
    hover.sim.apply(SimAction::MotorFail { index: 0 });
    hover.fly_until(25.0);
    assert_eq!(
        hover.core.spinning_without(),
        Some(0),
        "spinning on three rotors"
    );
    g.bench_function("quad_x/spinning tick", |b| {
        b.iter_custom(|iters| hover.timed(iters))
    });
    for name in ["quad_x", "hexa_x"] {
        let a = airframe(name);
        let config = FlightCoreConfig::from_params(&p, &a);
        g.bench_function(format!("{name}/FlightCore::new"), |b| {
            b.iter(|| black_box(FlightCore::new(black_box(&a), config.clone()).expect("core")))
        });
    }
    g.finish();
}

criterion_group!(benches, tick, three_rotors);
criterion_main!(benches);
