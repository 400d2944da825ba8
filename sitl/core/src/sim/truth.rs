//! The simulator's true state, for logs, scoring and `HIL_STATE_QUATERNION`.

use crate::body::BodyState;
use nalgebra::Vector3;
use navmath::geo::{LatLonAlt, LocalFrame};

/// The true state, for logs, scoring and `HIL_STATE_QUATERNION`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TruthState {
    /// Simulation time (µs).
    pub time_usec: u64,
    /// Rigid-body state.
    pub body: BodyState,
    /// Mean linear acceleration over the last step, NED (m/s²).
    pub accel_ned_m_s2: Vector3<f64>,
    /// The local frame at home, where [`TruthState::position`] is measured.
    pub home: LocalFrame,
    /// Air velocity at the vehicle, NED (m/s).
    pub wind_ned_m_s: Vector3<f64>,
    /// Whether the ground bears the vehicle (a foot touches it).
    pub landed: bool,
    /// Battery terminal voltage (V).
    pub battery_voltage_v: f64,
    /// Battery current (A).
    pub battery_current_a: f64,
    /// Battery state of charge (0–1).
    pub battery_remaining: f64,
}

impl TruthState {
    /// Geodetic (WGS-84) position, computed when asked: only `HIL_STATE_QUATERNION` (at
    /// 50 Hz) reads it, of the truths made every frame.
    pub fn position(&self) -> LatLonAlt {
        self.home.to_geodetic(&self.body.pos_ned_m)
    }
}
