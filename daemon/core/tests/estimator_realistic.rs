//! The attitude estimator in closed loop on the simulator's `realistic` sensors (a 0.6°/s
//! turn-on gyro bias that drifts, rotor-frequency vibration, the motor currents' magnetic field),
//! in lockstep: a hover, a magnet brought near during the hover, a 45° banked orbit at 10 m/s,
//! and a hover again. Both estimators fly the same seeds; the figures are printed side by side.

// Test code: a failed unwrap is a failed test.
#![allow(clippy::unwrap_used)]

use airframe::Airframe;
use flight_core::control::Setpoint;
use flight_core::control::position::PositionSetpoint;
use flight_core::core::{FlightCore, FlightCoreConfig};
use flight_core::params::FlightParams;
use nalgebra::{UnitQuaternion, Vector3};
use sitl_core::BodyState;
use sitl_core::sensors::{SensorConfig, SensorPreset};
use sitl_core::sim::{SimAction, SimConfig, Simulator};
use std::f64::consts::TAU;
use std::path::PathBuf;

mod common;
use common::DECIMATION;

const ALT_M: f64 = 10.0;
/// Orbit speed (m/s) and radius (m): v²/r = g, a 45° bank.
const ORBIT_SPEED: f64 = 10.0;
const ORBIT_RADIUS: f64 = ORBIT_SPEED * ORBIT_SPEED / flight_core::GRAVITY_M_S2;

/// The phases of the flight (s): hover scored, magnet present, orbit entered, orbit scored.
const HOVER_SCORED: (f64, f64) = (20.0, 40.0);
const MAGNET: (f64, f64) = (40.0, 55.0);
const ORBIT_START: f64 = 65.0;
const ORBIT_SCORED: (f64, f64) = (85.0, 105.0);
/// The orbit left for a hover over its centre, at the first hover's heading, scored.
const ORBIT_END: f64 = 110.0;
const HOVER_AFTER_SCORED: (f64, f64) = (120.0, 140.0);

fn airframe() -> Airframe {
    Airframe::load(
        &PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../params/airframes/quad_x.toml"),
    )
    .unwrap()
}

/// The set-point at `t`: the take-off spot, then a circle about it entered by a spiral whose
/// speed ramps up over 10 s, yaw along the path.
fn setpoint(t: f64) -> Setpoint {
    if !(ORBIT_START..ORBIT_END).contains(&t) {
        return Setpoint::Position(PositionSetpoint {
            pos_ned_m: Vector3::new(0.0, 0.0, -ALT_M),
            vel_ned_m_s: Vector3::zeros(),
            accel_ned_m_s2: Vector3::zeros(),
            yaw_rad: 0.0,
        });
    }
    let s = ((t - ORBIT_START) / 10.0).min(1.0);
    let ramp = s * s * (3.0 - 2.0 * s);
    let radius = ORBIT_RADIUS * ramp;
    let speed = ORBIT_SPEED * ramp;
    // The angle travelled: ∫ speed / radius = ∫ ω with ω = v/r constant once on the circle.
    let omega = ORBIT_SPEED / ORBIT_RADIUS;
    let angle = omega * (t - ORBIT_START) % TAU;
    let (sin, cos) = angle.sin_cos();
    Setpoint::Position(PositionSetpoint {
        pos_ned_m: Vector3::new(radius * cos, radius * sin, -ALT_M),
        vel_ned_m_s: Vector3::new(-speed * sin, speed * cos, 0.0),
        accel_ned_m_s2: Vector3::new(-cos, -sin, 0.0) * speed * omega,
        yaw_rad: angle + TAU / 4.0,
    })
}

#[derive(Debug, Default)]
struct Scores {
    hover_tilt_deg: f64,
    hover_heading_deg: f64,
    magnet_heading_max_deg: f64,
    magnet_tilt_deg: f64,
    orbit_tilt_deg: f64,
    orbit_heading_deg: f64,
    orbit_bank_deg: f64,
    /// The hover after the orbit, whose turns have shown the accelerometer's bias.
    hover_after_tilt_deg: f64,
    /// The hover tilt the accelerometer's bias alone leaves: its horizontal part over g.
    accel_bias_floor_deg: f64,
}

/// RMS accumulators.
#[derive(Default)]
struct Rms(f64, usize);
impl Rms {
    fn add(&mut self, x: f64) {
        self.0 += x * x;
        self.1 += 1;
    }
    fn deg(&self) -> f64 {
        (self.0 / self.1.max(1) as f64).sqrt().to_degrees()
    }
}

/// Tilt error (the angle between the true and estimated down axes) and heading error.
fn errors(est: &UnitQuaternion<f64>, truth: &UnitQuaternion<f64>) -> (f64, f64) {
    let tilt = (est.inverse() * Vector3::z()).angle(&(truth.inverse() * Vector3::z()));
    let heading =
        (est.euler_angles().2 - truth.euler_angles().2 + TAU / 2.0).rem_euclid(TAU) - TAU / 2.0;
    (tilt, heading.abs())
}

fn fly(params: &FlightParams, seed: u64) -> Scores {
    let a = airframe();
    let sensors = SensorConfig::preset(SensorPreset::Realistic);
    let mut sim = Simulator::new(
        &a,
        SimConfig {
            seed,
            sensors,
            ..SimConfig::default()
        },
        BodyState::default(),
    )
    .unwrap();
    let mut core = FlightCore::new(&a, FlightCoreConfig::from_params(params, &a)).unwrap();
    let n = a.rotors.len();
    let mut commands = [0.0; 16];
    let (mut hover_tilt, mut hover_heading, mut magnet_tilt) =
        (Rms::default(), Rms::default(), Rms::default());
    let (mut orbit_tilt, mut orbit_heading, mut bank) = (Rms::default(), Rms::default(), 0.0f64);
    let (mut magnet_heading_max, mut magnet_on) = (0.0f64, false);
    let mut hover_after_tilt = Rms::default();
    let steps = (HOVER_AFTER_SCORED.1 * 1000.0) as usize / DECIMATION;
    for _ in 0..steps {
        let t = sim.time_s();
        if (MAGNET.0..MAGNET.1).contains(&t) != magnet_on {
            magnet_on = !magnet_on;
            // A magnet 10 cm away: 0.3 gauss, half again the Earth's field.
            let field = Vector3::new(0.1, 0.25, 0.1) * f64::from(u8::from(magnet_on));
            sim.apply(SimAction::MagDisturbance(field));
        }
        let sample = common::control_interval(&mut sim, &commands[..n]);
        let truth = sim.truth();
        let t = sim.time_s();
        core.set_in_air(-truth.body.pos_ned_m.z > 0.5);
        let out = core.step(&sample, &setpoint(t), t > 3.0);
        commands = out.commands;
        let Some(e) = out.attitude else { continue };
        let q = truth.body.q_ned_from_frd;
        let (tilt, heading) = errors(&e.q, &q);
        let within = |(a, b): (f64, f64)| (a..b).contains(&t);
        if within(HOVER_SCORED) {
            hover_tilt.add(tilt);
            hover_heading.add(heading);
        }
        if within((MAGNET.0, MAGNET.1 + 10.0)) {
            magnet_tilt.add(tilt);
            magnet_heading_max = magnet_heading_max.max(heading);
        }
        if within(HOVER_AFTER_SCORED) {
            hover_after_tilt.add(tilt);
        }
        if within(ORBIT_SCORED) {
            orbit_tilt.add(tilt);
            orbit_heading.add(heading);
            bank = bank.max((q * Vector3::z()).angle(&Vector3::z()));
        }
    }
    Scores {
        hover_tilt_deg: hover_tilt.deg(),
        hover_heading_deg: hover_heading.deg(),
        magnet_heading_max_deg: magnet_heading_max.to_degrees(),
        magnet_tilt_deg: magnet_tilt.deg(),
        orbit_tilt_deg: orbit_tilt.deg(),
        orbit_heading_deg: orbit_heading.deg(),
        orbit_bank_deg: bank.to_degrees(),
        hover_after_tilt_deg: hover_after_tilt.deg(),
        accel_bias_floor_deg: (sim.sensors().accel_bias().xy().norm() / flight_core::GRAVITY_M_S2)
            .atan()
            .to_degrees(),
    }
}

/// The parameters of a user who ran the motor-current calibration: `CAL_MAG0_[XYZ]COMP` as the
/// simulator's field, and the orbit's tilt and speed allowed.
fn params(mode: u32, compensated: bool) -> FlightParams {
    let mut p = FlightParams::default();
    p.attitude.mode = mode;
    if compensated {
        p.attitude.mag_comp = SensorConfig::preset(SensorPreset::Realistic)
            .mag_motor_field
            .into();
    }
    p.position.max_tilt_deg = 55.0;
    p.position.max_speed_h = 15.0;
    p.position.max_accel_h = 12.0;
    p
}

fn report(name: &str, seed: u64, s: &Scores) {
    println!(
        "{name:<22} seed {seed}: hover tilt {:.2} (accelerometer-bias floor {:.2}) heading {:.2} | \
         magnet heading max {:.2} tilt {:.2} | orbit (bank {:.0}) tilt {:.2} heading {:.2} | \
         hover after it: tilt {:.2} deg",
        s.hover_tilt_deg,
        s.accel_bias_floor_deg,
        s.hover_heading_deg,
        s.magnet_heading_max_deg,
        s.magnet_tilt_deg,
        s.orbit_bank_deg,
        s.orbit_tilt_deg,
        s.orbit_heading_deg,
        s.hover_after_tilt_deg
    );
}

/// The estimator for real sensors on the realistic preset, three seeds, Castillo's observer
/// beside it: hover tilt RMS ≤ 0.3° and heading RMS ≤ 1°; a magnet during the hover, heading
/// error ≤ 3° and tilt ≤ 0.3°; a 45° banked orbit at 10 m/s, tilt RMS ≤ 1°; the hover after the
/// orbit, tilt RMS ≤ 0.15° on each seed. The first two tilt bounds hold over the three seeds
/// pooled, the others on each.
/// A seed's first hover tilt is its accelerometer's horizontal bias over g (which nothing
/// separates from the tilt in a hover at one heading) plus at most 0.15°: seed 3's bias alone
/// is 0.35°. The orbit's turns show the bias; the hover after it is below that floor.
#[test]
fn realistic_sensors_hover_magnet_and_banked_orbit() {
    let (mut hover_tilt, mut magnet_tilt) = (Rms::default(), Rms::default());
    for seed in 1..=3 {
        report("Castillo", seed, &fly(&params(0, true), seed));
        let s = fly(&params(1, true), seed);
        report("tilt/heading", seed, &s);
        hover_tilt.add(s.hover_tilt_deg.to_radians());
        magnet_tilt.add(s.magnet_tilt_deg.to_radians());
        assert!(s.hover_tilt_deg <= s.accel_bias_floor_deg + 0.15, "{s:?}");
        assert!(s.hover_heading_deg <= 1.0, "{s:?}");
        assert!(s.magnet_heading_max_deg <= 3.0, "{s:?}");
        assert!(s.orbit_bank_deg >= 44.0, "the orbit must be flown: {s:?}");
        assert!(s.orbit_tilt_deg <= 1.0, "{s:?}");
        // The orbit's turns have shown the accelerometer's bias (`accel_bias.rs`): the hover
        // after it is no longer held at the bias's floor (seed 3: 0.33° before, 0.34° floor).
        // The gyro's bias walked during the orbit's fast turn, where it cannot be learned (seed
        // 2: 0.11°/s); the steady hover's shorter low-pass keeps its lag small.
        assert!(s.hover_after_tilt_deg <= 0.15, "{s:?}");
    }
    println!(
        "tilt/heading, three seeds: hover tilt RMS {:.2} deg, with the magnet {:.2} deg",
        hover_tilt.deg(),
        magnet_tilt.deg()
    );
    assert!(hover_tilt.deg() <= 0.3 && magnet_tilt.deg() <= 0.3);
    // Without the motor-current compensation the heading is off by the field's share.
    let uncompensated = fly(&params(1, false), 1);
    report("tilt/heading, no comp", 1, &uncompensated);
}
