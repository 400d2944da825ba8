//! The landed state's one writer (ArduCopter's `set_land_complete`, PX4's `land_detector`): the
//! flight tasks and the commander report what they see — a climb from the ground begun, the
//! vehicle clear of the ground, a descent to land begun, the vehicle on the ground (a touchdown,
//! arming there, the motors stopped) — and the detector keeps `MAV_LANDED_STATE`, logging each
//! change.

use super::LandedState;

/// Where the vehicle is relative to the ground, as the flight tasks saw it last.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct LandDetector {
    state: LandedState,
}

impl LandDetector {
    /// On the ground.
    pub(super) fn new() -> Self {
        Self {
            state: LandedState::OnGround,
        }
    }

    /// The landed state.
    pub(super) fn state(&self) -> LandedState {
        self.state
    }

    /// A climb from the ground has begun (a take-off's climb, sticks or a set-point lifting it).
    pub(super) fn climbing(&mut self) {
        self.set(LandedState::Takeoff);
    }

    /// Clear of the ground: flying.
    pub(super) fn airborne(&mut self) {
        self.set(LandedState::InAir);
    }

    /// A descent to land has begun.
    pub(super) fn landing(&mut self) {
        self.set(LandedState::Landing);
    }

    /// On the ground: touched down, armed there, or the motors stopped.
    pub(super) fn on_ground(&mut self) {
        self.set(LandedState::OnGround);
    }

    fn set(&mut self, state: LandedState) {
        if state != self.state {
            tracing::debug!(from = ?self.state, to = ?state, "landed state");
            self.state = state;
        }
    }
}
