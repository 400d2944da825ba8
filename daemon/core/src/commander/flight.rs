//! What the flight tasks share: the commander's state of the flight (armed, landed, home, the
//! uploaded mission, the heading and speed of automatic flight), what each update gives them,
//! and the small pieces several tasks fly with (touchdown, hold, spool-up).

use super::mission_run::MissionRun;
use super::{CommanderInput, CommanderParams, Denial, OffboardTarget, Sticks};
use crate::control::GroundContact;
use crate::control::position::PositionSetpoint;
use crate::mission::SpeedChange;
use nalgebra::Vector3;
use std::f64::consts::{PI, TAU};

use super::land_detector::LandDetector;
use super::line::Line;

/// The state of the flight that outlives a mode: the tasks read it and change it.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Flight {
    /// The commander's parameters.
    pub(super) params: CommanderParams,
    /// Motors armed.
    pub(super) armed: bool,
    /// On the ground, taking off, flying or landing: its one writer.
    pub(super) land: LandDetector,
    /// Home position NED (m) and heading (rad), once set.
    pub(super) home: Option<(Vector3<f64>, f64)>,
    /// Home was set by a command: arming keeps it.
    pub(super) home_commanded: bool,
    /// The take-off altitude of the current take-off (m above home).
    pub(super) takeoff_alt_m: f64,
    /// The uploaded mission and its progress.
    pub(super) mission: MissionRun,
    /// The horizontal speed of automatic flight `DO_CHANGE_SPEED` set (m/s).
    pub(super) speed_override: Option<f64>,
    /// The heading automatic flight turns (rad): set by missions and repositions, held by the
    /// other automatic modes; cleared at arming (home's heading then).
    pub(super) auto_yaw: Option<f64>,
    /// A `CONDITION_YAW` heading (rad) and rate (rad/s), until the mode or item changes.
    pub(super) yaw_goal: Option<(f64, Option<f64>)>,
    /// A task saw the vehicle touch down in this update: the commander disarms after it.
    pub(super) touched_down: bool,
    /// How far a landing has come on the ground in this update (said by [`Touchdown`]).
    pub(super) ground_contact: GroundContact,
}

impl Flight {
    /// Disarmed on the ground, no home, no mission.
    pub(super) fn new(params: CommanderParams) -> Self {
        Self {
            params,
            armed: false,
            land: LandDetector::new(),
            home: None,
            home_commanded: false,
            takeoff_alt_m: params.takeoff_alt_m,
            mission: MissionRun::new(),
            speed_override: None,
            auto_yaw: None,
            yaw_goal: None,
            touched_down: false,
            ground_contact: GroundContact::None,
        }
    }

    /// Sets home to `pos_ned_m`, or to the estimate `i` if `None`.
    pub(super) fn set_home(
        &mut self,
        pos_ned_m: Option<Vector3<f64>>,
        i: &CommanderInput,
    ) -> Result<(), Denial> {
        let pos = match pos_ned_m {
            Some(p) => p,
            None if i.ready => i.pos_ned_m,
            None => return Err(Denial::PositionNotValid { command: "home" }),
        };
        if !pos.iter().all(|x| x.is_finite()) {
            return Err(Denial::NotFinite {
                command: "home",
                what: "position not finite",
            });
        }
        let yaw = self.home.map_or(i.yaw_rad, |h| h.1);
        self.home = Some((pos, yaw));
        self.home_commanded = true;
        Ok(())
    }

    /// `DO_CHANGE_SPEED`: the horizontal speed of automatic flight from now on; `line`, the
    /// leg in progress, too if it is horizontal (not a take-off's or a landing's climb).
    pub(super) fn change_speed(
        &mut self,
        change: SpeedChange,
        line: Option<&mut Line>,
    ) -> Result<(), Denial> {
        let speed_m_s = match change {
            SpeedChange::To(s) if s.is_finite() && s > 0.0 => Some(s),
            SpeedChange::To(s) => return Err(Denial::Speed(s)),
            SpeedChange::Default => None,
            SpeedChange::Unchanged => return Ok(()),
        };
        self.speed_override = speed_m_s.map(|s| s.min(20.0));
        if let Some(line) = line.filter(|l| l.dir.xy().norm() > 0.5) {
            line.speed = self.leg(line.from, line.end()).speed;
        }
        Ok(())
    }

    /// The horizontal speed of automatic flight.
    fn cruise_speed(&self) -> f64 {
        self.speed_override.unwrap_or(self.params.cruise_speed_m_s)
    }

    /// A leg from `from` to `to` at the cruise speed, its vertical part no faster than
    /// `MPC_Z_V_AUTO_UP` / `MPC_Z_V_AUTO_DN`.
    pub(super) fn leg(&self, from: Vector3<f64>, to: Vector3<f64>) -> Line {
        let p = self.params;
        let d = to - from;
        let n = d.norm().max(1e-9);
        let (h, v) = (d.xy().norm() / n, d.z / n);
        let mut speed = if h > 1e-6 {
            self.cruise_speed() / h
        } else {
            f64::INFINITY
        };
        if v < -1e-6 {
            speed = speed.min(p.auto_climb_m_s / -v);
        } else if v > 1e-6 {
            speed = speed.min(p.auto_sink_m_s / v);
        }
        if !speed.is_finite() {
            speed = self.cruise_speed();
        }
        Line::new(from, to, speed, p.accel_m_s2).with_jerk(p.jerk_m_s3)
    }

    /// The take-off's climb (and the Return's) straight up from `from` to `down` (NED, m): at
    /// `MPC_TKO_SPEED`, reached over `MPC_TKO_RAMP_T`, jerk-limited.
    pub(super) fn climb(&self, from: Vector3<f64>, down: f64) -> Line {
        let p = self.params;
        let to = Vector3::new(from.x, from.y, down);
        Line::new(from, to, p.takeoff_speed_m_s, p.takeoff_accel_m_s2()).with_jerk(p.jerk_m_s3)
    }

    /// The heading of automatic flight, turned towards `goal` (or the `CONDITION_YAW` goal) at
    /// most at `MPC_YAWRAUTO_MAX` (or the command's rate).
    pub(super) fn slew_yaw(&mut self, goal: Option<f64>, i: &CommanderInput, dt: f64) -> f64 {
        let (goal, rate) = match (self.yaw_goal, goal) {
            (Some((g, r)), _) => (Some(g), r),
            (None, g) => (g, None),
        };
        let rate = rate.unwrap_or(self.params.auto_yaw_rate_deg_s.to_radians());
        let yaw = self.auto_yaw.unwrap_or(i.yaw_rad);
        let yaw = match goal {
            Some(g) => wrap_pi(yaw + wrap_pi(g - yaw).clamp(-rate * dt, rate * dt)),
            None => yaw,
        };
        self.auto_yaw = Some(yaw);
        yaw
    }
}

/// What a flight task is given on each update.
#[derive(Debug, Clone, Copy)]
pub(super) struct Tick<'a> {
    /// The estimate.
    pub(super) i: &'a CommanderInput,
    /// Time since the last update (s).
    pub(super) dt: f64,
    /// Home, or where the vehicle is before home is set (NED, m).
    pub(super) home: Vector3<f64>,
    /// The heading automatic flight holds (rad).
    pub(super) yaw: f64,
    /// Time since arming (s).
    pub(super) since_arming_s: f64,
    /// The sticks, if they arrived within `COM_RC_LOSS_T`.
    pub(super) sticks: Option<Sticks>,
    /// The offboard set-point, if it arrived within `COM_OF_LOSS_T`.
    pub(super) offboard: Option<OffboardTarget>,
    /// The follow target as filtered, if there has been a fix.
    pub(super) target: Option<super::TargetEstimate>,
}

/// Touchdown detection: the vehicle has stood still (as its task judges it) for a second.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(super) struct Touchdown {
    still_since_s: Option<f64>,
}

/// Stopped this long, a landing is maybe landed (PX4's `MAYBE_LAND_TRIGGER_TIME`, s).
pub(super) const MAYBE_LANDED_S: f64 = 0.3;
/// Stopped this long, it is on the ground (s).
const LANDED_S: f64 = 1.0;

impl Touchdown {
    /// Watches whether the vehicle is `stopped` at `t_s`; after [`LANDED_S`] of it, the vehicle
    /// is on the ground and the commander disarms once the task's update returns (within the
    /// same [`super::Commander::update`]). Returns whether it touched down.
    pub(super) fn check(&mut self, f: &mut Flight, stopped: bool, t_s: f64) -> bool {
        self.held_s(stopped, t_s)
            .is_some_and(|held| held >= LANDED_S && Self::touched_down(f))
    }

    /// [`Self::check`] for a landing whose descent a set-point below the vehicle asks for,
    /// staged as PX4's land detector stages it in `f.ground_contact`: ground contact at once,
    /// maybe landed after `maybe_landed_s` ([`MAYBE_LANDED_S`], or 0 for a vehicle only its
    /// motors can tip over), on the ground after [`LANDED_S`].
    pub(super) fn check_staged(
        &mut self,
        f: &mut Flight,
        stopped: bool,
        t_s: f64,
        maybe_landed_s: f64,
    ) -> bool {
        let Some(held_s) = self.held_s(stopped, t_s) else {
            return false;
        };
        if held_s >= LANDED_S {
            return Self::touched_down(f);
        }
        f.ground_contact = if held_s >= maybe_landed_s {
            GroundContact::MaybeLanded
        } else {
            GroundContact::Contact
        };
        false
    }

    /// How long the vehicle has been `stopped` (s), or `None` when it is not.
    fn held_s(&mut self, stopped: bool, t_s: f64) -> Option<f64> {
        if !stopped {
            self.still_since_s = None;
            return None;
        }
        Some(t_s - *self.still_since_s.get_or_insert(t_s))
    }

    fn touched_down(f: &mut Flight) -> bool {
        f.touched_down = true;
        f.land.on_ground();
        true
    }

    /// Forgets a stillness in progress.
    pub(super) fn reset(&mut self) {
        self.still_since_s = None;
    }
}

/// A position set-point holding `pos` at `yaw_rad`.
pub(super) fn hold_setpoint(pos: Vector3<f64>, yaw_rad: f64) -> PositionSetpoint {
    PositionSetpoint {
        pos_ned_m: pos,
        vel_ned_m_s: Vector3::zeros(),
        accel_ned_m_s2: Vector3::zeros(),
        yaw_rad,
    }
}

/// Armed on the ground: a set-point just below home keeps the thrust low (spooled up).
pub(super) fn spooled(home: Vector3<f64>, yaw_rad: f64) -> PositionSetpoint {
    hold_setpoint(home + Vector3::new(0.0, 0.0, 0.5), yaw_rad)
}

/// Where braking at `accel` (m/s²) from the present velocity stops the vehicle, held at `yaw`.
pub(super) fn brake_point(i: &CommanderInput, accel: f64, yaw: f64) -> (Vector3<f64>, f64) {
    let a = accel.max(0.1);
    let v = i.vel_ned_m_s;
    (i.pos_ned_m + v * v.norm() / (2.0 * a), yaw)
}

/// Hold: the point `at` (set on the first call to where braking at the profile's acceleration
/// stops the vehicle).
pub(super) fn loiter(
    at: &mut Option<(Vector3<f64>, f64)>,
    f: &Flight,
    i: &CommanderInput,
    yaw: f64,
) -> PositionSetpoint {
    let (pos, yaw) = *at.get_or_insert_with(|| brake_point(i, f.params.accel_m_s2, yaw));
    hold_setpoint(pos, yaw)
}

/// An angle wrapped to [−π, π).
pub(super) fn wrap_pi(a: f64) -> f64 {
    (a + PI).rem_euclid(TAU) - PI
}

/// A stick value with the dead zone `dz` around zero taken out, rescaled to reach ±1.
pub(super) fn deadzone(x: f64, dz: f64) -> f64 {
    if x.abs() <= dz {
        0.0
    } else {
        x.signum() * (x.abs() - dz) / (1.0 - dz).max(1e-6)
    }
}
