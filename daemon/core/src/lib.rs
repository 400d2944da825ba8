//! The autopilot's flight core: the algorithms of the four papers as plain, tested code.
//!
//! No sockets, no runtime, no clock reads: every stage is a struct with an `update`/`step`
//! function of its inputs and the sample time. Conventions (NED/FRD, Hamilton quaternions
//! `q_ned_from_frd`, SI units) are those of `ARCHITECTURE.md`.

pub mod battery;
pub mod commander;
pub mod control;
pub mod core;
pub mod estimator;
pub mod failsafe;
pub mod geo;
pub mod geofence;
pub mod mag_calibrator;
pub mod mag_check;
pub mod mag_fit;
pub mod mission;
pub mod mixer;
pub mod motor_failure;
pub mod params;
pub mod quat;
pub mod replay;
pub mod safety;
pub mod sensor_monitor;

/// Standard gravity (m/s²), along NED +z.
pub const GRAVITY_M_S2: f64 = 9.806_65;
