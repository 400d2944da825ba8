//! A flight flown without a ground station (the command line's `--takeoff`), and the end of a
//! run: arm and take off once the estimator is ready, hold, land, end once disarmed; an
//! operator's Ctrl-C lands first.

use super::Autopilot;
use crate::commander::LandedState;

/// A flight flown without a ground station (the command line's `--takeoff`): arm and take off
/// as soon as the estimator is ready, hold for `hover_s`, land; the run ends once disarmed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AutoFlight {
    /// Take-off altitude above home (m).
    pub takeoff_m: f64,
    /// Time to hold before landing (s); infinite holds until told otherwise.
    pub hover_s: f64,
}

impl Autopilot {
    /// Whether the run is over: the auto flight has landed and disarmed, or an operator asked
    /// to end and the vehicle is disarmed.
    pub fn finished(&self) -> bool {
        self.ended
    }

    /// The auto flight is waiting for the estimator before it takes off.
    pub fn awaiting_takeoff(&self) -> bool {
        self.auto.is_some() && !self.end_when_disarmed
    }

    /// Ends the run (Ctrl-C): lands first if in the air.
    pub fn request_land(&mut self) {
        self.end_when_disarmed = true;
        self.auto = None;
        if self.commander.armed() {
            if let Err(e) = self.commander.set_mode(crate::commander::FlightMode::Land) {
                tracing::warn!("landing: {e}");
            }
        } else {
            self.ended = true;
        }
        self.publish();
    }

    /// The run ends when disarmed after the auto flight (or an operator's Ctrl-C).
    pub(super) fn check_end(&mut self) {
        if self.end_when_disarmed && !self.commander.armed() {
            self.ended = true;
        }
    }

    /// The auto flight: take off when ready, land after the hold.
    pub(super) fn fly_auto(&mut self) {
        let Some(a) = self.auto else {
            return;
        };
        // As published after the commander last changed: the same as computing it again.
        let s = self.published.status;
        let c = &mut self.commander;
        if !self.end_when_disarmed {
            if s.ready && !s.armed {
                if let Err(e) = c.takeoff(Some(a.takeoff_m)).and_then(|()| c.arm(false)) {
                    if self.auto_denial.as_ref() != Some(&e) {
                        tracing::warn!("auto flight: {e}");
                        self.auto_denial = Some(e);
                    }
                    return;
                }
                tracing::info!(takeoff_m = a.takeoff_m, "auto flight: armed, taking off");
                self.end_when_disarmed = true;
            }
        } else if s.mode == crate::commander::FlightMode::Loiter
            && s.landed == LandedState::InAir
            && s.in_mode_s >= a.hover_s
        {
            tracing::info!("auto flight: landing");
            if let Err(e) = c.set_mode(crate::commander::FlightMode::Land) {
                tracing::warn!("auto flight: {e}");
            }
        }
    }
}
