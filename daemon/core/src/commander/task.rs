//! Flight tasks: what each mode flies, behind one small trait (as PX4's `FlightTask` and
//! ArduPilot's `Mode`). The commander chooses the mode and switches; the task of that mode
//! keeps its own state and turns each update into a set-point.

use super::FlightMode;
use super::descend::Descend;
use super::flight::{Flight, Tick};
use super::follow_target::FollowTarget;
use super::hold::Hold;
use super::land::Land;
use super::line::Line;
use super::manual_position::ManualPosition;
use super::mission::MissionFlight;
use super::offboard::Offboard;
use super::orbit::Orbit;
use super::rtl::Rtl;
use super::stabilized::Stabilized;
use super::takeoff::Takeoff;
use crate::control::Setpoint;
use nalgebra::Vector3;

/// What every mode's task does.
pub(super) trait FlightTask {
    /// Starts the task at `t_s` (s): its mode was entered, or the vehicle armed in it.
    fn activate(&mut self, _t_s: f64) {}

    /// One update: the set-point to fly. A touchdown is said in `f.touched_down`.
    fn update(&mut self, f: &mut Flight, t: &Tick) -> Setpoint;

    /// The task's work is done and the commander hands over: a take-off at its altitude goes
    /// on in Hold where it ended. (A landing needs none: its touchdown disarms, through
    /// `Flight::touched_down`.)
    fn is_finished(&self) -> bool {
        false
    }
}

/// The task of the current mode.
#[derive(Debug, Clone, PartialEq)]
pub(super) enum Task {
    Takeoff(Takeoff),
    Hold(Hold),
    Land(Land),
    Rtl(Rtl),
    /// Boxed: the largest task by far.
    Mission(Box<MissionFlight>),
    ManualPosition(ManualPosition),
    Stabilized(Stabilized),
    Offboard(Offboard),
    Orbit(Orbit),
    FollowTarget(FollowTarget),
    Descend(Descend),
}

impl Task {
    /// A new task for `mode`, not yet activated.
    pub(super) fn of(mode: FlightMode) -> Self {
        match mode {
            FlightMode::Takeoff => Self::Takeoff(Takeoff::default()),
            FlightMode::Loiter => Self::Hold(Hold::default()),
            FlightMode::Land => Self::Land(Land::default()),
            FlightMode::Rtl => Self::Rtl(Rtl::default()),
            FlightMode::Mission => Self::Mission(Box::default()),
            FlightMode::Posctl => Self::ManualPosition(ManualPosition::new(true)),
            FlightMode::Altctl => Self::ManualPosition(ManualPosition::new(false)),
            FlightMode::Manual | FlightMode::Stabilized => Self::Stabilized(Stabilized::default()),
            FlightMode::Offboard => Self::Offboard(Offboard::default()),
            // An orbit is made by `Commander::orbit`, never from the mode alone: Hold stands in.
            FlightMode::Orbit => Self::Hold(Hold::default()),
            FlightMode::FollowTarget => Self::FollowTarget(FollowTarget::default()),
            FlightMode::Descend => Self::Descend(Descend::default()),
        }
    }

    /// The task, to be driven.
    pub(super) fn flight_task(&mut self) -> &mut dyn FlightTask {
        match self {
            Self::Takeoff(t) => t,
            Self::Hold(t) => t,
            Self::Land(t) => t,
            Self::Rtl(t) => t,
            Self::Mission(t) => t.as_mut(),
            Self::ManualPosition(t) => t,
            Self::Stabilized(t) => t,
            Self::Offboard(t) => t,
            Self::Orbit(t) => t,
            Self::FollowTarget(t) => t,
            Self::Descend(t) => t,
        }
    }

    /// The leg being flown, if any (a speed change applies to it).
    pub(super) fn line_mut(&mut self) -> Option<&mut Line> {
        match self {
            Self::Takeoff(t) => t.line_mut(),
            Self::Hold(t) => t.line_mut(),
            Self::Rtl(t) => t.line_mut(),
            Self::Mission(t) => t.line_mut(),
            _ => None,
        }
    }

    /// The point and heading held or last flown to, if the task keeps one.
    pub(super) fn held(&self) -> Option<(Vector3<f64>, f64)> {
        match self {
            Self::Takeoff(t) => t.reached(),
            Self::Hold(t) => t.held(),
            Self::Mission(t) => t.held(),
            Self::ManualPosition(t) => t.held(),
            _ => None,
        }
    }

    /// Starts a holding task at `at` rather than where braking would stop.
    pub(super) fn hold_at(&mut self, at: (Vector3<f64>, f64)) {
        match self {
            Self::Hold(t) => *t = Hold::at(at),
            Self::ManualPosition(t) => t.hold_at(at),
            _ => {}
        }
    }
}
