//! The simulated world the autopilot flies in: multirotor rigid-body physics, rotors, battery,
//! atmosphere and wind, ground contact, and the sensors a flight board reads.
//!
//! Everything here is pure and deterministic: plain structs with `step` functions, no I/O, no
//! clock reads, randomness only from seeded streams. The `sitl` binary puts it behind a MAVLink
//! HIL link. Conventions (frames NED/FRD, Hamilton quaternions `q_ned_from_frd`, SI units) are
//! those of `docs/conventions.md`.

/// Airframe descriptions (the shared `airframe` crate).
pub mod airframe {
    pub use ::airframe::*;
}
pub mod body;
pub mod environment;
pub mod geo;
pub mod jsbsim;
pub mod powertrain;
pub use navmath::quat;
pub mod rng;
pub mod scenario;
pub mod sensors;
pub mod sim;
pub mod torque_free;
pub mod truth_csv;

/// Standard gravity (m/s²), along NED +z.
pub const GRAVITY_M_S2: f64 = ::airframe::GRAVITY_M_S2;

pub use ::airframe::ConfigError;
pub use airframe::Airframe;
pub use body::{BodyState, Integrator};
pub use sim::{SimConfig, Simulator};
