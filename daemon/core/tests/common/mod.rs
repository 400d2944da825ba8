//! What the HIL link does, in-process: one control interval of simulator physics turned into the
//! flight core's sensor sample (IMU averaged, slower sensors forwarded when fresh). Shared by the
//! closed-loop tests and the tick benchmark.

use flight_core::core::SensorSample;
use flight_core::estimator::translation::GpsMeasurement;
use nalgebra::Vector3;
use sitl_core::sensors::fields;
use sitl_core::sim::Simulator;

/// An airframe of `params/airframes/` by name.
#[allow(dead_code)] // not every test crate sharing this module loads one
pub fn airframe(name: &str) -> airframe::Airframe {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../params/airframes");
    match airframe::Airframe::load(&dir.join(format!("{name}.toml"))) {
        Ok(a) => a,
        Err(e) => panic!("airframe {name}: {e}"),
    }
}

/// The simulator on `config` with `airframe` on the ground, and the whole autopilot on default
/// parameters (the simulated magnetometer taken as calibrated) that takes off to `takeoff_m`
/// by itself, hovers `hover_s` and lands.
#[allow(dead_code)] // not every test crate sharing this module flies an automatic flight
pub fn auto_flight(
    airframe: &airframe::Airframe,
    config: sitl_core::sim::SimConfig,
    takeoff_m: f64,
    hover_s: f64,
) -> (Simulator, flight_core::autopilot::Autopilot) {
    let sim = Simulator::new(airframe, config, sitl_core::BodyState::default())
        .expect("the simulator starts");
    let mut params = flight_core::params::FlightParams::default();
    params.attitude.mag_calibration_id = flight_core::sensors::mag_check::SIMULATED_MAG_ID;
    let auto = flight_core::autopilot::AutoFlight { takeoff_m, hover_s };
    let autopilot = flight_core::autopilot::Autopilot::new(airframe, &params, Some(auto))
        .expect("the autopilot starts");
    (sim, autopilot)
}

/// One control interval of the whole autopilot: physics under `commands`, the sample (its ESC
/// telemetry dropped unless `esc_telemetry`) stepped, and `commands` replaced by the answer's.
#[allow(dead_code)] // not every test crate sharing this module flies the whole autopilot
pub fn autopilot_interval(
    sim: &mut Simulator,
    autopilot: &mut flight_core::autopilot::Autopilot,
    commands: &mut [f64; airframe::MAX_ROTORS],
    rotors: usize,
    esc_telemetry: bool,
) -> flight_core::autopilot::AutopilotOutput {
    let mut s = control_interval(sim, &commands[..rotors]);
    if !esc_telemetry {
        s.rotor_speed_rad_s = None;
    }
    let out = autopilot
        .step(&s, &flight_core::autopilot::StepInputs::default())
        .expect("a sample from the simulator steps");
    *commands = out.commands;
    out
}

/// Physics steps per control step: 1 kHz physics, 250 Hz control (as the HIL link).
pub const DECIMATION: usize = 4;

/// Advances `sim` one control interval under `commands` and returns the sensor sample.
pub fn control_interval(sim: &mut Simulator, commands: &[f64]) -> SensorSample {
    let (mut gyro, mut accel) = (Vector3::zeros(), Vector3::zeros());
    let (mut mag, mut baro, mut gps, mut rpm) = (None, None, None, None);
    for _ in 0..DECIMATION {
        sim.step(commands);
        let f = sim.sample_sensors();
        gyro += f.gyro_frd_rad_s / DECIMATION as f64;
        accel += f.accel_frd_m_s2 / DECIMATION as f64;
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
                position: g.position,
                vel_ned_m_s: g.vel_ned_m_s,
                h_acc_m: g.h_acc_m,
                satellites: g.satellites,
                details: Default::default(),
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
        battery_v: Some(sim.truth().battery_voltage_v),
        esc_current_a: None,
        rotor_speed_rad_s: rpm,
    }
}
