//! Carrying out the failsafes: the [`crate::safety`] state machine decides on every update
//! (link, battery, geofence, crash, estimator and sensors); the commander switches to what
//! it decided (Hold, Return, Land, Descend, disarm) when the decision changes.

use super::hold::Hold;
use super::line::Line;
use super::task::Task;
use super::{Commander, CommanderInput, FlightMode, LandedState};
use crate::safety::failsafe::{FailsafeAction, SafetyInput};
use nalgebra::Vector3;

impl Commander {
    /// One step of the failsafe state machine, its decision carried out when it changes.
    pub(super) fn failsafes(&mut self, i: &CommanderInput) {
        let h = i.health;
        // GF_MAX_HOR_DIST and GF_MAX_VER_DIST from home (0: no limit), with the caller's
        // polygons and circles.
        let limits = *self.safety.params();
        let breached = self.flight.home.is_some_and(|(home, _)| {
            let off = i.pos_ned_m - home;
            let beyond = |x: f64, limit: f64| limit > 0.0 && x > limit;
            beyond(off.xy().norm(), limits.fence_max_horizontal_m)
                || beyond(-off.z, limits.fence_max_vertical_m)
        });
        let d = self.safety.update(&SafetyInput {
            t_s: i.t_s,
            armed: self.flight.armed,
            in_air: self.flight.land.state() != LandedState::OnGround,
            mode_needs_position: self.mode.needs_position(),
            gcs_link_age_s: h.gcs_link_age_s,
            battery_remaining: h.battery_remaining,
            geofence_breached: h.geofence_breached || (breached && i.horizontal_valid),
            attitude_valid: h.attitude_valid,
            position_valid: i.horizontal_valid,
            altitude_valid: h.altitude_valid,
            sensors_lost: h.sensors_lost,
            roll_pitch_rad: h.roll_pitch_rad,
            home_set: self.flight.home.is_some(),
            motor_failed: h.motor_failed.is_some(),
            spinning: h.spinning,
        });
        self.safety_events.extend(d.events.iter().copied());
        for &e in &d.events {
            self.safety_log.push(e);
        }
        // Kept for a caller that drains them; bounded for one that does not.
        let excess = self.safety_events.len().saturating_sub(64);
        self.safety_events.drain(..excess);
        let changed = d.action != self.failsafe.0;
        self.failsafe = (d.action, d.cause);
        if !changed || !self.flight.armed {
            return;
        }
        match d.action {
            FailsafeAction::None | FailsafeAction::Warn => {}
            FailsafeAction::Hold if self.flight.land.state() == LandedState::InAir => {
                // Stop firmly: a braking profile at MPC_ACC_FS_BRK from the present speed
                // (its velocity and deceleration fed forward), then hold where it ends.
                let v = Vector3::new(i.vel_ned_m_s.x, i.vel_ned_m_s.y, 0.0);
                let speed = v.norm();
                let a = self.flight.params.failsafe_brake_m_s2.max(0.1);
                let stop = i.pos_ned_m + v * speed / (2.0 * a);
                let line = (speed > 0.1).then(|| Line::moving(i.pos_ned_m, stop, speed, a));
                let yaw = self.flight.auto_yaw.unwrap_or(i.yaw_rad);
                let hold = Hold::after(line, (stop, yaw));
                self.enter_with(FlightMode::Loiter, Task::Hold(hold));
            }
            FailsafeAction::Hold => self.enter(FlightMode::Loiter),
            FailsafeAction::Return => self.enter(FlightMode::Rtl),
            FailsafeAction::Land => self.enter(FlightMode::Land),
            FailsafeAction::Descend => {
                self.sensors_stopped();
            }
            FailsafeAction::Disarm | FailsafeAction::Terminate => self.disarmed(),
        }
    }
}
