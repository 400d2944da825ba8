//! Physics speed: one step (rigid body + rotors + battery + air + all sensors) per integrator for
//! quad_x and dodeca, and 60 s of flight at 1 kHz in-process.
//!
//! Targets: an RK4 step of the twelve-rotor with all sensors ≤ 1 µs; 60 s at 1 kHz < 60 ms.

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use nalgebra::Vector3;
use sitl_core::sim::{SimConfig, Simulator};
use sitl_core::{Airframe, BodyState, Integrator};
use std::hint::black_box;
use std::path::PathBuf;

fn airframe(name: &str) -> Airframe {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join(format!("../../params/airframes/{name}.toml"));
    Airframe::load(&path).expect("shipped airframe")
}

fn hovering(name: &str, integrator: Integrator) -> Simulator {
    let cfg = SimConfig {
        integrator,
        ..SimConfig::default()
    }; // typical sensors
    let initial = BodyState {
        pos_ned_m: Vector3::new(0.0, 0.0, -10.0),
        ..BodyState::default()
    };
    let mut sim = Simulator::new(&airframe(name), cfg, initial).expect("valid");
    let hover = sim.hover_speeds();
    sim.set_rotor_speeds(&hover);
    sim
}

fn step(c: &mut Criterion) {
    let mut g = c.benchmark_group("physics_step_with_sensors");
    for name in ["quad_x", "dodeca"] {
        for integ in Integrator::ALL {
            let mut sim = hovering(name, integ);
            let u = sim.hover_commands();
            let n = sim.airframe().rotors.len();
            g.bench_function(BenchmarkId::new(name, integ.name()), |b| {
                b.iter(|| {
                    sim.step(black_box(&u[..n]));
                    black_box(sim.sample_sensors().accel_frd_m_s2);
                })
            });
        }
    }
    g.finish();
}

fn minute(c: &mut Criterion) {
    let mut g = c.benchmark_group("flight_60s_at_1khz");
    g.sample_size(10);
    for name in ["quad_x", "dodeca"] {
        g.bench_function(name, |b| {
            b.iter(|| {
                let mut sim = hovering(name, Integrator::Rk4);
                let n = sim.airframe().rotors.len();
                for _ in 0..60_000 {
                    let u = sim.hover_commands();
                    sim.step(&u[..n]);
                    black_box(sim.sample_sensors().gyro_frd_rad_s);
                }
                sim.truth().body.pos_ned_m
            })
        });
    }
    g.finish();
}

criterion_group!(benches, step, minute);
criterion_main!(benches);
