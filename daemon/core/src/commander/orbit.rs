//! Orbit (PX4's Orbit mode, `MAV_CMD_DO_ORBIT`): circle a centre at a radius and tangential
//! speed, facing as asked, for a number of turns or until another mode is chosen.
//!
//! A vehicle off the circle first flies a leg to its nearest point at the circle's altitude,
//! facing the centre (PX4's circle approach). On the circle the set-point is the nearest point
//! of the circle, with the tangential velocity and the centripetal acceleration `v²/r` as
//! feed-forward: the position loop corrects the radial error only, the velocity loop the
//! speed. The drag of the vehicle's own motion turns with the path, which the velocity loop's
//! integrator (in fixed axes, for the wind) cannot learn — it flew 10 % slow — so the task
//! integrates the speed error along the path into a tangential acceleration feed-forward of
//! its own, of either sign: with the outside force fed forward the drag is answered already,
//! and what is left is the attitude's lag behind a thrust that turns with the path (5.35 m/s
//! for 5 m/s when it could only push forward). The tangential speed ramps up at `MPC_ACC_HOR` and is bounded by the radius:
//! `v ≤ √(a r)` with `a` = `MC_ORBIT_ACC_MAX`.

use super::flight::{Flight, Tick, wrap_pi};
use super::line::Line;
use super::task::FlightTask;
use super::{Commander, Denial, FlightMode, LandedState};
use crate::control::Setpoint;
use crate::control::position::PositionSetpoint;
use nalgebra::{Vector2, Vector3};
use std::f64::consts::{FRAC_PI_2, PI, TAU};

/// Which way the vehicle faces while it orbits (MAVLink's `ORBIT_YAW_BEHAVIOUR`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum OrbitYaw {
    /// The front points at the centre (PX4's default).
    #[default]
    FrontToCenter,
    /// The heading when the orbit was asked is kept.
    HoldInitialHeading,
    /// The heading is not controlled (held where it is).
    Uncontrolled,
    /// The front points along the path.
    FrontTangent,
    /// The yaw stick turns the vehicle.
    RcControlled,
}

impl OrbitYaw {
    /// From `ORBIT_YAW_BEHAVIOUR`'s number (5, "unchanged", is the caller's to handle).
    pub fn from_mavlink(n: u8) -> Option<Self> {
        Some(match n {
            0 => Self::FrontToCenter,
            1 => Self::HoldInitialHeading,
            2 => Self::Uncontrolled,
            3 => Self::FrontTangent,
            4 => Self::RcControlled,
            _ => return None,
        })
    }
}

/// An orbit as asked: every `None` keeps the orbit flown (or, starting one, takes the
/// current position as the centre and the defaults).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct OrbitRequest {
    /// Radius (m); positive clockwise seen from above, negative counter-clockwise.
    pub radius_m: Option<f64>,
    /// Tangential speed (m/s).
    pub speed_m_s: Option<f64>,
    /// Which way to face.
    pub yaw: Option<OrbitYaw>,
    /// Turns to fly, then Hold; `Some(0)` or `None` orbits until another mode is chosen.
    pub turns: Option<f64>,
    /// The centre, north and east (m, local frame).
    pub center_ne_m: Option<Vector2<f64>>,
    /// The circle's altitude, down (m, local frame).
    pub center_down_m: Option<f64>,
}

/// An orbit in progress, as `ORBIT_EXECUTION_STATUS` reports it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OrbitStatus {
    /// The centre, its down part the circle's altitude (NED, m).
    pub center_ned_m: Vector3<f64>,
    /// Radius (m), positive clockwise.
    pub radius_m: f64,
    /// The tangential speed flown to (m/s, after the radius's bound).
    pub speed_m_s: f64,
    /// On the circle (not still flying to it).
    pub circling: bool,
    /// Turns flown on the circle.
    pub turns_done: f64,
}

/// A radius of the mode chosen without a command (m), and its speed (m/s).
const DEFAULT_ORBIT: (f64, f64) = (10.0, 2.0);

/// The fastest orbit asked that is not refused (m/s): automatic flight's bound.
pub const SPEED_MAX_M_S: f64 = 20.0;

/// Smallest radius (m), as PX4.
pub const RADIUS_MIN_M: f64 = 1.0;

/// Gain of the speed error's integral along the path (1/s).
const SPEED_I_GAIN: f64 = 0.5;

/// Bound of the tangential feed-forward it makes (m/s²).
const DRAG_FF_MAX_M_S2: f64 = 2.0;

/// How near the circle (m, horizontally and in height) counts as on it, as PX4's acceptance.
const ON_CIRCLE_M: f64 = 2.0;

/// Flying an orbit.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Orbit {
    center: Vector3<f64>,
    radius_m: f64,
    clockwise: bool,
    speed_m_s: f64,
    yaw: OrbitYaw,
    initial_yaw: f64,
    turns: Option<f64>,
    /// The leg to the circle, while flying it.
    approach: Option<Line>,
    /// The tangential speed now (ramped up to `speed_m_s`).
    speed_now: f64,
    /// The angle of the vehicle about the centre at the last update (rad from north).
    angle: Option<f64>,
    /// The tangential acceleration feed-forward learned from the speed error (m/s²).
    drag_ff: f64,
    turned_rad: f64,
    heading: f64,
    done: bool,
}

impl Orbit {
    /// The status to report.
    pub(super) fn status(&self) -> OrbitStatus {
        OrbitStatus {
            center_ned_m: self.center,
            radius_m: if self.clockwise {
                self.radius_m
            } else {
                -self.radius_m
            },
            speed_m_s: self.speed_m_s,
            circling: self.approach.is_none() && self.angle.is_some(),
            turns_done: self.turned_rad / TAU,
        }
    }

    /// Heads for the circle from `pos` if it is not on it.
    fn approach_from(&mut self, f: &Flight, pos: Vector3<f64>, yaw: f64) {
        let rel = pos.xy() - self.center.xy();
        let dir = if rel.norm() > 1e-3 {
            rel.normalize()
        } else {
            Vector2::new(yaw.cos(), yaw.sin())
        };
        let on = (rel.norm() - self.radius_m).abs() < ON_CIRCLE_M
            && (pos.z - self.center.z).abs() < ON_CIRCLE_M;
        self.approach = (!on).then(|| {
            let p = self.center.xy() + dir * self.radius_m;
            f.leg(pos, Vector3::new(p.x, p.y, self.center.z))
        });
        self.angle = None;
    }

    /// The heading asked on the circle at `angle` (rad from north, of the vehicle about the
    /// centre), before the slew.
    fn heading_goal(&self, angle: f64, t: &Tick, stick_rate_rad_s: f64) -> f64 {
        match self.yaw {
            OrbitYaw::FrontToCenter => angle + PI,
            OrbitYaw::FrontTangent if self.clockwise => angle + FRAC_PI_2,
            OrbitYaw::FrontTangent => angle - FRAC_PI_2,
            OrbitYaw::HoldInitialHeading => self.initial_yaw,
            OrbitYaw::Uncontrolled => self.heading,
            OrbitYaw::RcControlled => {
                let stick = t.sticks.map_or(0.0, |s| s.yaw);
                self.heading + stick * stick_rate_rad_s * t.dt
            }
        }
    }
}

impl FlightTask for Orbit {
    fn update(&mut self, f: &mut Flight, t: &Tick) -> Setpoint {
        f.land.airborne();
        let p = f.params;
        let pos = t.i.pos_ned_m;
        let rel = pos.xy() - self.center.xy();
        let angle = if rel.norm() > 1e-3 {
            rel.y.atan2(rel.x)
        } else {
            self.heading
        };
        // Turning to the goal at MPC_YAWRAUTO_MAX on top of the orbit's own turn rate.
        let turn_rate = p.auto_yaw_rate_deg_s.to_radians() + self.speed_now / self.radius_m;
        let step = turn_rate * t.dt;
        let slew = |from: f64, to: f64| wrap_pi(from + wrap_pi(to - from).clamp(-step, step));
        if let Some(line) = self.approach.as_mut() {
            let face = (-rel).y.atan2((-rel).x);
            let goal = if rel.norm() > 1e-3 {
                face
            } else {
                self.heading
            };
            self.heading = slew(self.heading, goal);
            let (sp, arrived) = line.step(t.dt, self.heading);
            if arrived {
                self.approach = None;
                self.speed_now = 0.0;
            }
            return Setpoint::Position(sp);
        }
        let sign = if self.clockwise { 1.0 } else { -1.0 };
        if let Some(last) = self.angle {
            self.turned_rad += sign * wrap_pi(angle - last);
        }
        self.angle = Some(angle);
        if self
            .turns
            .is_some_and(|n| n > 0.0 && self.turned_rad >= n * TAU)
        {
            self.done = true;
        }
        self.speed_now = (self.speed_now + p.accel_m_s2 * t.dt).min(self.speed_m_s);
        let radial = Vector2::new(angle.cos(), angle.sin());
        let tangent = if self.clockwise {
            Vector2::new(-radial.y, radial.x)
        } else {
            Vector2::new(radial.y, -radial.x)
        };
        let on = self.center.xy() + radial * self.radius_m;
        let v = tangent * self.speed_now;
        let along = t.i.vel_ned_m_s.xy().dot(&tangent);
        self.drag_ff = (self.drag_ff + SPEED_I_GAIN * (self.speed_now - along) * t.dt)
            .clamp(-DRAG_FF_MAX_M_S2, DRAG_FF_MAX_M_S2);
        let a = -radial * self.speed_now.powi(2) / self.radius_m + tangent * self.drag_ff;
        let goal = self.heading_goal(angle, t, p.manual_yaw_rate_deg_s.to_radians());
        self.heading = slew(self.heading, goal);
        Setpoint::Position(PositionSetpoint {
            pos_ned_m: Vector3::new(on.x, on.y, self.center.z),
            vel_ned_m_s: Vector3::new(v.x, v.y, 0.0),
            accel_ned_m_s2: Vector3::new(a.x, a.y, 0.0),
            yaw_rad: self.heading,
        })
    }

    fn is_finished(&self) -> bool {
        self.done
    }
}

impl Commander {
    /// `MAV_CMD_DO_ORBIT` (or the Orbit mode chosen): in the air, orbit as `req` asks — what it
    /// leaves out keeps the orbit flown, or starts one about the current position. Refused on
    /// the ground, in a failsafe descent, for a radius below [`RADIUS_MIN_M`] or above
    /// `MC_ORBIT_RAD_MAX`, a speed not above zero or above [`SPEED_MAX_M_S`], a centre out of
    /// range. A speed above the radius's bound `√(a r)` is lowered to it (as PX4 does).
    pub fn orbit(&mut self, req: OrbitRequest) -> Result<(), Denial> {
        let Some(i) = self.last else {
            return Err(Denial::NoPositionEstimate { command: "orbit" });
        };
        if !self.flight.armed || self.flight.land.state() != LandedState::InAir {
            return Err(Denial::NotFlying { command: "orbit" });
        }
        if self.mode == FlightMode::Descend {
            return Err(Denial::FailsafeDescent { command: "orbit" });
        }
        let p = self.flight.params;
        let current = match &self.task {
            super::task::Task::Orbit(o) => Some(o.clone()),
            _ => None,
        };
        let signed = req
            .radius_m
            .or(current.as_ref().map(|o| o.status().radius_m));
        let signed = signed.unwrap_or(DEFAULT_ORBIT.0);
        if !(signed.is_finite() && (RADIUS_MIN_M..=p.orbit_radius_max_m).contains(&signed.abs())) {
            return Err(Denial::OrbitRadius {
                radius_m: signed,
                min_m: RADIUS_MIN_M,
                max_m: p.orbit_radius_max_m,
            });
        }
        let speed = req
            .speed_m_s
            .or(current.as_ref().map(|o| o.speed_m_s))
            .unwrap_or(DEFAULT_ORBIT.1);
        if !(speed.is_finite() && speed > 0.0 && speed <= SPEED_MAX_M_S) {
            return Err(Denial::OrbitSpeed {
                speed_m_s: speed,
                max_m_s: SPEED_MAX_M_S,
            });
        }
        let radius = signed.abs();
        let bound = speed_bound_m_s(p.orbit_accel_m_s2, radius);
        let here = i.pos_ned_m;
        let center_ne = req
            .center_ne_m
            .or(current.as_ref().map(|o| o.center.xy()))
            .unwrap_or(here.xy());
        let down = req
            .center_down_m
            .or(current.as_ref().map(|o| o.center.z))
            .unwrap_or(here.z);
        let center = Vector3::new(center_ne.x, center_ne.y, down);
        if !center.iter().all(|x| x.is_finite()) {
            return Err(Denial::NotFinite {
                command: "orbit",
                what: "centre not finite",
            });
        }
        let home = self.flight.home.map_or(here, |h| h.0);
        // The circle's farthest point from home, not only its centre, within the limits.
        let out = (center.xy() - home.xy())
            .try_normalize(1e-9)
            .unwrap_or(Vector2::x());
        let far = center + Vector3::new(out.x, out.y, 0.0) * radius;
        self.target_limits()
            .check_target(&far, &home)
            .map_err(|why| Denial::Target {
                command: "orbit",
                why,
            })?;
        let yaw = req
            .yaw
            .or(current.as_ref().map(|o| o.yaw))
            .unwrap_or_default();
        let heading = current.as_ref().map_or(i.yaw_rad, |o| o.heading);
        self.operator_takes_over()?;
        let mut orbit = Orbit {
            center,
            radius_m: radius,
            clockwise: signed > 0.0,
            speed_m_s: speed.min(bound),
            yaw,
            initial_yaw: current.as_ref().map_or(i.yaw_rad, |o| o.initial_yaw),
            turns: req.turns.or(current.as_ref().and_then(|o| o.turns)),
            // Turns asked again count from now; kept, they count on.
            turned_rad: match (&current, req.turns) {
                (Some(o), None) => o.turned_rad,
                _ => 0.0,
            },
            approach: None,
            speed_now: current.as_ref().map_or(0.0, |o| o.speed_now),
            angle: None,
            drag_ff: 0.0,
            heading,
            done: false,
        };
        orbit.approach_from(&self.flight, here, heading);
        self.enter_with(FlightMode::Orbit, super::task::Task::Orbit(orbit));
        Ok(())
    }
}

/// The fastest orbit of `radius_m` (m/s) whose centripetal acceleration is `accel_m_s2`.
pub fn speed_bound_m_s(accel_m_s2: f64, radius_m: f64) -> f64 {
    (accel_m_s2 * radius_m).sqrt()
}
