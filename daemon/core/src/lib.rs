//! The autopilot's flight core: the algorithms of the four papers as plain, tested code.
//!
//! No sockets, no runtime, no clock reads: every stage is a struct with an `update`/`step`
//! function of its inputs and the sample time. Conventions (NED/FRD, Hamilton quaternions
//! `q_ned_from_frd`, SI units) are those of `docs/conventions.md`.

pub mod autopilot;
pub mod commander;
pub mod control;
pub mod core;
pub mod estimator;
pub mod logger_params;
pub mod math;
pub mod mission;
pub mod mixer;
pub mod params;
pub mod safety;
pub mod sample;
pub mod sensors;

/// Standard gravity (m/s²), along NED +z.
pub const GRAVITY_M_S2: f64 = 9.806_65;

/// ISA sea-level air density (kg/m³): what the rotors' top thrusts are rated in.
pub const SEA_LEVEL_AIR_DENSITY_KG_M3: f64 = 1.225;
