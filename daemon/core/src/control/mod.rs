//! The cascade controller: attitude (outer) and rate (inner) loops.

pub mod attitude;
pub mod disturbance;
pub mod motor;
pub mod position;
pub mod rate;
pub mod reduced_attitude;
pub mod relaxed_hover;

use nalgebra::{UnitQuaternion, Vector3};
use position::PositionSetpoint;

/// An attitude and collective thrust to fly directly, without the position loop: the sticks
/// of PX4's Manual and Stabilized modes, or MAVLink's `SET_ATTITUDE_TARGET`. These are
/// exactly the inputs of Castillo's cascade: the desired attitude q_d and the desired frame's
/// rate Ω_d, plus the thrust.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AttitudeTarget {
    /// Desired attitude q_d (`q_ned_from_frd`); `None` flies the body rates alone (rate mode:
    /// the rate reference is `rate_frd_rad_s`).
    pub q_d: Option<UnitQuaternion<f64>>,
    /// Ω_d: the desired frame's body rate (rad/s, FRD), a feed-forward over q_d.
    pub rate_frd_rad_s: Vector3<f64>,
    /// Collective thrust as a fraction of the vehicle's largest thrust, [0, 1] (MAVLink's
    /// normalised thrust).
    pub thrust: f64,
}

/// How far a landing has come on the ground, as PX4's land detector stages it: what the
/// loops stop doing so that the ground, not they, holds the vehicle (a vehicle whose position
/// and attitude integrators fight the ground's hold tips itself over).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum GroundContact {
    /// Flying, or not landing.
    #[default]
    None,
    /// The descent has stopped though asked to go on (PX4's `ground_contact`): the horizontal
    /// position is no longer held, the thrust points up.
    Contact,
    /// Stopped for a while longer (PX4's `maybe_landed`): the thrust is cut to idle, the
    /// attitude set level and the rate loop's integrators cleared.
    MaybeLanded,
}

/// What the flight core flies toward.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Setpoint {
    /// A position, velocity or acceleration: the position loop makes attitude and thrust.
    Position(PositionSetpoint),
    /// An attitude (or body rates) and thrust, flown by the attitude and rate loops alone.
    Attitude(AttitudeTarget),
}

impl Setpoint {
    /// The position set-point, when it is one.
    pub fn position(&self) -> Option<&PositionSetpoint> {
        match self {
            Self::Position(p) => Some(p),
            Self::Attitude(_) => None,
        }
    }
}
