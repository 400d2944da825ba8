//! One flight-core tick: attitude and translation estimators, position, attitude and rate
//! loops, mixer. Target (issue 3): ≤ 2 µs for quad_x and dodeca.
//!
//! Measured in closed loop: the simulator flies the vehicle (a hover at 5 m) so every stage sees
//! realistic inputs; only `FlightCore::step` is timed.

use airframe::Airframe;
use criterion::{Criterion, criterion_group, criterion_main};
use flight_core::control::position::PositionSetpoint;
use flight_core::core::{FlightCore, FlightCoreConfig, SensorSample};
use flight_core::estimator::translation::GpsMeasurement;
use flight_core::geo::LatLonAlt;
use nalgebra::Vector3;
use sitl_core::BodyState;
use sitl_core::sensors::fields;
use sitl_core::sim::{SimConfig, Simulator};
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

/// Advances the simulator one 250 Hz control interval and returns the averaged sensor sample.
fn sample(sim: &mut Simulator, commands: &[f64]) -> SensorSample {
    let (mut gyro, mut accel) = (Vector3::zeros(), Vector3::zeros());
    let (mut mag, mut baro, mut gps, mut rpm) = (None, None, None, None);
    for _ in 0..4 {
        sim.step(commands);
        let f = sim.sample_sensors();
        gyro += f.gyro_frd_rad_s / 4.0;
        accel += f.accel_frd_m_s2 / 4.0;
        if f.fields_updated & fields::MAG != 0 {
            mag = Some(f.mag_frd_gauss);
        }
        if f.fields_updated & fields::PRESSURE_ALT != 0 {
            baro = Some(f.pressure_alt_m);
        }
        if let Some(r) = f.rotor_rpm {
            rpm = Some(r.map(|x| x * std::f64::consts::TAU / 60.0));
        }
        if let Some(g) = f.gps {
            gps = Some(GpsMeasurement {
                fix_type: g.fix_type,
                position: LatLonAlt {
                    lat_deg: g.position.lat_deg,
                    lon_deg: g.position.lon_deg,
                    alt_m: g.position.alt_m,
                },
                vel_ned_m_s: g.vel_ned_m_s,
                h_acc_m: g.h_acc_m,
            });
        }
    }
    SensorSample {
        t_usec: sim.time_usec(),
        gyro,
        accel,
        mag,
        baro_alt_m: baro,
        gps,
        battery_v: sim.truth().battery_voltage_v,
        rotor_speed_rad_s: rpm,
    }
}

fn tick(c: &mut Criterion) {
    let mut g = c.benchmark_group("flight_core_tick");
    for name in ["quad_x", "dodeca"] {
        for (label, pid) in [("ladrc", false), ("pid", true)] {
            let a = airframe(name);
            let n = a.rotors.len();
            let mut sim =
                Simulator::new(&a, SimConfig::default(), BodyState::default()).expect("sim");
            let mut core =
                FlightCore::new(&a, FlightCoreConfig::for_airframe(&a, pid)).expect("mixer");
            let sp = PositionSetpoint {
                pos_ned_m: Vector3::new(0.0, 0.0, -5.0),
                vel_ned_m_s: Vector3::zeros(),
                yaw_rad: 0.0,
            };
            let mut commands = [0.0; 16];
            // Align, take off and settle into the hover first.
            for _ in 0..(15 * 250) {
                let s = sample(&mut sim, &commands[..n]);
                commands = core.step(&s, &sp, sim.time_s() > 3.0).commands;
            }
            g.bench_function(format!("{name}/{label}"), |b| {
                b.iter_custom(|iters| {
                    let mut spent = Duration::ZERO;
                    for _ in 0..iters {
                        let s = sample(&mut sim, &commands[..n]);
                        let start = Instant::now();
                        commands = black_box(core.step(black_box(&s), &sp, true)).commands;
                        spent += start.elapsed();
                    }
                    spent
                })
            });
        }
    }
    g.finish();
}

criterion_group!(benches, tick);
criterion_main!(benches);
