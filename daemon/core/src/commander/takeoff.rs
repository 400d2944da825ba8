//! Takeoff: spool up for `COM_SPOOLUP_TIME` after arming, climb on a speed- and
//! acceleration-limited profile to the take-off altitude above home; finished there (Hold
//! follows).

use super::LandedState;
use super::flight::{Flight, Tick, brake_point, hold_setpoint, spooled};
use super::line::Line;
use super::task::FlightTask;
use crate::control::Setpoint;
use nalgebra::Vector3;

/// The take-off climb.
#[derive(Debug, Clone, PartialEq, Default)]
pub(super) struct Takeoff {
    line: Option<Line>,
    /// Where it stood on the ground when the take-off began (NED, m): the climb holds above
    /// it, not where the wind has pushed the vehicle, lightened on its feet, by the time it lifts.
    ground: Option<Vector3<f64>>,
    /// Where it holds once the climb is done.
    reached: Option<(Vector3<f64>, f64)>,
}

impl Takeoff {
    /// The climb's profile, once it has begun.
    pub(super) fn line_mut(&mut self) -> Option<&mut Line> {
        self.line.as_mut()
    }

    /// Where it holds once the climb is done.
    pub(super) fn reached(&self) -> Option<(Vector3<f64>, f64)> {
        self.reached
    }
}

impl FlightTask for Takeoff {
    fn update(&mut self, f: &mut Flight, t: &Tick) -> Setpoint {
        let (p, i) = (f.params, t.i);
        if f.land.state() == LandedState::OnGround && self.ground.is_none() {
            self.ground = Some(Vector3::new(i.pos_ned_m.x, i.pos_ned_m.y, t.home.z));
        }
        if f.land.state() == LandedState::OnGround && t.since_arming_s < p.spool_s {
            return Setpoint::Position(spooled(t.home, t.yaw));
        }
        let target_down = t.home.z - f.takeoff_alt_m;
        let line = match self.line.as_mut() {
            Some(line) => line,
            None if i.pos_ned_m.z <= target_down && f.land.state() != LandedState::OnGround => {
                // Already above the take-off altitude: hold here.
                let at = brake_point(i, p.accel_m_s2, t.yaw);
                self.reached = Some(at);
                return Setpoint::Position(hold_setpoint(at.0, at.1));
            }
            None => {
                // From the ground the climb starts at the ground, not at the estimate's noise
                // around it, above where the vehicle stood.
                let from = if f.land.state() == LandedState::OnGround {
                    self.ground
                        .unwrap_or(Vector3::new(i.pos_ned_m.x, i.pos_ned_m.y, t.home.z))
                } else {
                    i.pos_ned_m
                };
                f.land.climbing();
                self.line.insert(f.climb(from, target_down))
            }
        };
        let (sp, arrived) = line.step(t.dt, t.yaw);
        let goal = line.from.z - line.length;
        if arrived && i.pos_ned_m.z - t.home.z <= 0.95 * (goal - t.home.z) {
            f.land.airborne();
            self.reached = Some((sp.pos_ned_m, t.yaw));
        }
        Setpoint::Position(sp)
    }

    fn is_finished(&self) -> bool {
        self.reached.is_some()
    }
}
