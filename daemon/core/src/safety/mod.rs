//! Safety: what keeps the vehicle and the people around it safe when something goes wrong.
//!
//! - [`failsafe`]: the failsafe state machine (conditions, actions, clear rules, take-over);
//! - [`preflight`]: the arming checks;
//! - [`failure_injection`]: `MAV_CMD_INJECT_FAILURE` carried out on the autopilot's side;
//! - [`blind_descent`]: the open-loop descent when the sensor frames stop in the air;
//! - [`geofence`]: uploaded fence zones, breach prediction;
//! - [`motor_failure`]: motor-failure detection;
//! - [`targets`]: where a command or mission item may send the vehicle.

pub mod blind_descent;
pub mod failsafe;
pub mod failure_injection;
pub mod geofence;
pub mod motor_failure;
pub mod preflight;
pub mod targets;

#[cfg(test)]
mod tests;
