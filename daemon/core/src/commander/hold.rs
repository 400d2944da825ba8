//! Hold (PX4's AUTO.LOITER): hold a point — where braking stops the vehicle, where a take-off
//! ended, or the end of a reposition's leg flown first. Armed on the ground it stays there.
//! A `CONDITION_YAW` turns the held heading.

use super::LandedState;
use super::flight::{Flight, Tick, loiter, spooled};
use super::line::Line;
use super::task::FlightTask;
use crate::control::Setpoint;
use nalgebra::Vector3;

/// Holding a point, after a leg to it if there is one.
#[derive(Debug, Clone, PartialEq, Default)]
pub(super) struct Hold {
    /// A leg flown before holding (a reposition, a failsafe's braking).
    line: Option<Line>,
    /// The point and heading held.
    at: Option<(Vector3<f64>, f64)>,
}

impl Hold {
    /// Holding `at`.
    pub(super) fn at(at: (Vector3<f64>, f64)) -> Self {
        Self {
            line: None,
            at: Some(at),
        }
    }

    /// Flying `line` (if any), then holding `at`.
    pub(super) fn after(line: Option<Line>, at: (Vector3<f64>, f64)) -> Self {
        Self { line, at: Some(at) }
    }

    /// The leg flown before holding, if any.
    pub(super) fn line_mut(&mut self) -> Option<&mut Line> {
        self.line.as_mut()
    }

    /// The point and heading held.
    pub(super) fn held(&self) -> Option<(Vector3<f64>, f64)> {
        self.at
    }
}

impl FlightTask for Hold {
    fn update(&mut self, f: &mut Flight, t: &Tick) -> Setpoint {
        if f.land.state() == LandedState::OnGround {
            return Setpoint::Position(spooled(t.home, t.yaw));
        }
        f.land.airborne();
        let yaw = if f.yaw_goal.is_some() {
            f.slew_yaw(None, t.i, t.dt)
        } else {
            self.at.map_or(t.yaw, |h| h.1)
        };
        if let Some(h) = self.at.as_mut() {
            h.1 = yaw;
        }
        let sp = match self.line.as_mut() {
            Some(line) => {
                let (sp, arrived) = line.step(t.dt, yaw);
                if arrived {
                    self.line = None;
                }
                sp
            }
            None => loiter(&mut self.at, f, t.i, yaw),
        };
        Setpoint::Position(sp)
    }
}
