//! A rigid body moved by an external flight-dynamics model (JSBSim): the loads of a step handed
//! to it, the body it returns.

use crate::body::BodyState;
use crate::powertrain::RotorWrench;
use nalgebra::Vector3;

/// The loads of one step, taken at its start, for an external flight-dynamics model that has
/// gravity and the ground of its own.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepLoads {
    /// The step (s).
    pub dt_s: f64,
    /// The rotors: each one's thrust at its hub and yaw moment (and their totals).
    pub rotor: RotorWrench,
    /// Drag and external force at the centre of mass, FRD (N).
    pub aero_force_frd_n: Vector3<f64>,
    /// The rotors' gyroscopic torque, aerodynamic torque, damping and external torque, FRD
    /// (N·m).
    pub aero_moment_frd_n_m: Vector3<f64>,
}

/// The body after a step of an external model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ExternalBodyStep {
    /// Position (local NED of the simulator's home), velocity, attitude and rate.
    pub body: BodyState,
    /// Every force but gravity over the mass, FRD (m/s²): what an accelerometer at the centre
    /// of mass measures.
    pub specific_force_frd_m_s2: Vector3<f64>,
    /// Angular acceleration, FRD (rad/s²).
    pub ang_accel_frd_rad_s2: Vector3<f64>,
    /// The ground bears (part of) the vehicle.
    pub on_ground: bool,
}

/// A rigid body moved by someone else (JSBSim): see [`crate::sim::Simulator::step_with`].
pub trait ExternalBody {
    /// Applies `loads` over one step and returns the body after it.
    fn advance(&mut self, loads: &StepLoads) -> Result<ExternalBodyStep, ExternalBodyError>;
}

/// Why an external model could not step: it died, stalled or answered nonsense.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{0}")]
pub struct ExternalBodyError(pub String);
