//! Arming: what each mode needs to start on the ground, and the arming checks
//! ([`crate::safety::preflight::preflight`]).

use super::stabilized::LOW_THROTTLE;
use super::task::Task;
use super::{ArmingDenial, Commander, CommanderInput, Denial, FlightMode};
use crate::safety::preflight::{PreflightCheck, PreflightFailure, PreflightInput, preflight};

impl Commander {
    /// Arms the motors. Refused while the estimator is not ready (unless `force`), in modes
    /// that cannot start on the ground (Land, RTL, Descend), and in modes not flown yet.
    pub fn arm(&mut self, force: bool) -> Result<(), Denial> {
        if self.flight.armed {
            return Ok(());
        }
        match self.mode {
            FlightMode::Takeoff | FlightMode::Loiter => {}
            FlightMode::Mission => self
                .mission_entry()
                .map_err(|e| Denial::Arming(ArmingDenial::Mission(Box::new(e))))?,
            FlightMode::Posctl | FlightMode::Altctl => {
                let Some(s) = self.fresh_sticks() else {
                    return Err(ArmingDenial::NeedsSticks(self.mode.name()).into());
                };
                if s.throttle > 0.5 + self.flight.params.stick_deadzone && !force {
                    return Err(ArmingDenial::ThrottleAboveCentre.into());
                }
            }
            FlightMode::Manual | FlightMode::Stabilized => {
                let Some(s) = self.fresh_sticks() else {
                    return Err(ArmingDenial::NeedsSticks(self.mode.name()).into());
                };
                // The throttle is the thrust here: arming with it up would leap.
                if s.throttle > LOW_THROTTLE && !force {
                    return Err(ArmingDenial::ThrottleNotLow.into());
                }
            }
            FlightMode::Offboard => {
                if self.fresh_offboard().is_none() {
                    return Err(ArmingDenial::NoOffboard.into());
                }
            }
            FlightMode::Land
            | FlightMode::Rtl
            | FlightMode::Descend
            | FlightMode::Orbit
            | FlightMode::FollowTarget => {
                return Err(ArmingDenial::ModeCannotStart(self.mode.name()).into());
            }
        }
        let Some(i) = self.last else {
            return Err(ArmingDenial::NoSensorData.into());
        };
        let mut failures = self.preflight_failures(&i);
        failures.retain(|f| !(force && f.skippable));
        if let Some(first) = failures.first() {
            let more = failures.len() - 1;
            let check = first.check.clone();
            return Err(ArmingDenial::Check { check, more }.into());
        }
        let f = &mut self.flight;
        f.armed = true;
        f.land.on_ground();
        if !f.home_commanded {
            f.home = Some((i.pos_ned_m, i.yaw_rad));
        }
        f.auto_yaw = None;
        self.changed = true;
        self.armed_at_s = i.t_s;
        self.since_s = i.t_s;
        // The mode's task starts afresh from the ground.
        self.task = Task::of(self.mode);
        self.task.flight_task().activate(i.t_s);
        Ok(())
    }

    /// The arming checks that fail now (whatever the mode asks for besides).
    pub(super) fn preflight_failures(&self, i: &CommanderInput) -> Vec<PreflightFailure> {
        let h = i.health;
        let mut failures = preflight(
            &PreflightInput {
                attitude_valid: h.attitude_valid,
                gyro_bias_settled: h.gyro_bias_settled,
                position_valid: i.horizontal_valid,
                altitude_valid: h.altitude_valid,
                mode_needs_position: self.mode.needs_position(),
                sensors_lost: h.sensors_lost,
                mag: h.mag,
                battery_remaining: h.battery_remaining,
                params_invalid: self.safety.params().inconsistencies().first().cloned(),
                roll_pitch_rad: h.roll_pitch_rad,
                geofence_breached: h.geofence_breached,
                motor_failed: h.motor_failed,
                terminated: self.safety.terminated(),
            },
            self.safety.params(),
        );
        if !i.ready && self.mode.needs_position() && failures.is_empty() {
            // The caller's verdict on the estimate, when its parts are not known here.
            failures.push(PreflightFailure {
                check: PreflightCheck::EstimatorNotReady,
                skippable: true,
            });
        }
        failures
    }
}
