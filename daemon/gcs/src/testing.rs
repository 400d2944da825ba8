//! Fixtures shared by this crate's tests and the daemon's (feature `testing`).

use crate::telemetry::Telemetry;
use flight_core::commander::{CommanderStatus, FlightMode, LandedState};

/// The telemetry of a vehicle at rest on the ground, ready to arm, `armed` or not, in `mode`,
/// with a full battery.
pub fn telemetry(armed: bool, mode: FlightMode) -> Telemetry {
    Telemetry {
        t_s: 12.0,
        status: Some(CommanderStatus {
            armed,
            mode,
            landed: LandedState::OnGround,
            home: None,
            failsafe: false,
            failsafe_action: None,
            motor_failed: None,
            failsafe_conditions: 0,
            safety_log: Default::default(),
            prearm_ok: true,
            ready: true,
            in_mode_s: 0.0,
            manual_losses: 0,
            offboard_losses: 0,
            mission: Default::default(),
            manual_control: None,
        }),
        battery_v: 16.0,
        ..Telemetry::default()
    }
}
