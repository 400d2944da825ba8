//! Follow Target (PX4's Follow Me, AUTO sub-mode 8): fly at `FLW_TGT_DST` from a target that
//! reports its place (`FOLLOW_TARGET`), at the angle `FLW_TGT_FA` from its course (180°:
//! behind it), `FLW_TGT_HT` above home (or above the target, `FLW_TGT_ALT_M` = 2), facing it.
//!
//! The target's fixes are noisy and come at 1 Hz or so: an alpha-beta filter
//! ([`TargetFilter`], PX4's gains from `FLW_TGT_RS`: lower follows more closely) holds its
//! position and velocity and predicts between fixes. The course is the filtered velocity's,
//! once the target moves at 1 m/s; until then the vehicle keeps the bearing it had from the
//! target. The angle about the target turns at most at `FLW_TGT_MAX_VEL / FLW_TGT_DST`.
//! Fixes that stop for [`STALE_S`]: the target is taken as standing where it was last
//! estimated, and the vehicle holds its place behind it (the ground station's link failsafe
//! is what acts if the ground station itself has gone).

use super::flight::{Flight, Tick, wrap_pi};
use super::task::FlightTask;
use super::{Commander, Denial, FlightMode, LandedState};
use crate::control::Setpoint;
use crate::control::position::PositionSetpoint;
use nalgebra::{Vector2, Vector3};

/// A fix of the target: where it is (NED, m) and, if it says, how fast it moves.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TargetFix {
    /// Position, local NED (m).
    pub pos_ned_m: Vector3<f64>,
    /// Velocity NED (m/s), if the target reports one.
    pub vel_ned_m_s: Option<Vector3<f64>>,
}

/// Fixes older than this (s) leave the target standing where it was last estimated.
pub const STALE_S: f64 = 3.0;

/// The farthest a fix may be from the vehicle (m): one farther is a wrong fix, not a target
/// the vehicle can be following.
pub const TARGET_RANGE_M: f64 = 1000.0;

/// Fixes closer together than this (s) move the position only: a velocity from a few
/// milliseconds would be the noise divided by them.
const MIN_FIX_INTERVAL_S: f64 = 0.05;

/// The fastest target believed (m/s).
const TARGET_SPEED_MAX_M_S: f64 = 30.0;

/// The target's speed (m/s) from which its course counts.
const COURSE_SPEED_M_S: f64 = 1.0;

/// The target's state as the filter holds it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TargetEstimate {
    /// Position NED (m), predicted to the time asked.
    pub pos_ned_m: Vector3<f64>,
    /// Velocity NED (m/s); zero once stale.
    pub vel_ned_m_s: Vector3<f64>,
    /// No fix for [`STALE_S`].
    pub stale: bool,
}

/// An alpha-beta filter of the target's position and velocity (PX4's `TargetEstimator`
/// gains, without its acceleration state).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct TargetFilter {
    /// Position, velocity, and the time of the last fix (s).
    state: Option<(Vector3<f64>, Vector3<f64>, f64)>,
}

impl TargetFilter {
    /// A fix at `t_s` with responsiveness `rs` (`FLW_TGT_RS`, 0.1 to 1: lower trusts the fixes
    /// more).
    pub fn fix(&mut self, fix: &TargetFix, t_s: f64, rs: f64) {
        // At 1 the gains are zero and the filter would stand still.
        let beta = rs.clamp(0.1, 0.99).cbrt();
        let (g_p, h_p) = (
            1.0 - beta.powi(3),
            1.5 * (1.0 - beta).powi(2) * (1.0 + beta),
        );
        let g_v = 1.0 - (0.9 * beta).powi(2);
        let first = (fix.pos_ned_m, fix.vel_ned_m_s.unwrap_or_default(), t_s);
        let Some((x, v, t0)) = self.state.filter(|s| t_s - s.2 <= STALE_S && t_s >= s.2) else {
            // The first fix, or the first after the target was lost: it starts again there.
            self.state = Some(first);
            return;
        };
        let dt = t_s - t0;
        let predicted = x + v * dt;
        let r = fix.pos_ned_m - predicted;
        let mut v = if dt >= MIN_FIX_INTERVAL_S {
            v + r * (h_p / dt)
        } else {
            v
        };
        if let Some(m) = fix.vel_ned_m_s {
            v += (m - v) * g_v;
        }
        let v = v * (TARGET_SPEED_MAX_M_S / v.norm().max(TARGET_SPEED_MAX_M_S));
        self.state = Some((predicted + r * g_p, v, t_s));
    }

    /// Forgets a target lost for longer than [`STALE_S`] at `t_s`.
    pub fn forget_if_stale(&mut self, t_s: f64) {
        if self.state.is_some_and(|s| t_s - s.2 > STALE_S) {
            self.state = None;
        }
    }

    /// The estimate at `t_s`, if there has been a fix.
    pub fn estimate(&self, t_s: f64) -> Option<TargetEstimate> {
        let (x, v, t0) = self.state?;
        let age = (t_s - t0).max(0.0);
        let stale = age > STALE_S;
        Some(TargetEstimate {
            pos_ned_m: x + v * age.min(STALE_S),
            vel_ned_m_s: if stale { Vector3::zeros() } else { v },
            stale,
        })
    }
}

/// Following the target.
#[derive(Debug, Clone, PartialEq, Default)]
pub(super) struct FollowTarget {
    /// The angle of the vehicle about the target now (rad from north), once there is one.
    angle: Option<f64>,
    /// The target's course (rad from north), once it has moved.
    course: Option<f64>,
    /// Where it held before there was a target.
    hold: Option<(Vector3<f64>, f64)>,
}

impl FlightTask for FollowTarget {
    fn update(&mut self, f: &mut Flight, t: &Tick) -> Setpoint {
        f.land.airborne();
        let p = f.params;
        let i = t.i;
        let Some(target) = t.target else {
            // No fix yet: hold where it is.
            let (pos, yaw) = *self.hold.get_or_insert((i.pos_ned_m, i.yaw_rad));
            return Setpoint::Position(super::flight::hold_setpoint(pos, yaw));
        };
        let tv = target.vel_ned_m_s.xy();
        if tv.norm() >= COURSE_SPEED_M_S {
            self.course = Some(tv.y.atan2(tv.x));
        }
        let dist = p.follow_distance_m;
        let from_target = i.pos_ned_m.xy() - target.pos_ned_m.xy();
        let angle = *self
            .angle
            .get_or_insert_with(|| from_target.y.atan2(from_target.x));
        let goal = self
            .course
            .map_or(angle, |c| c + p.follow_angle_deg.to_radians());
        let max_step = p.follow_max_speed_m_s / dist.max(1.0) * t.dt;
        let angle = wrap_pi(angle + wrap_pi(goal - angle).clamp(-max_step, max_step));
        self.angle = Some(angle);
        let at = target.pos_ned_m.xy() + Vector2::new(angle.cos(), angle.sin()) * dist;
        let down = match p.follow_altitude_mode {
            // Above the target, but never below a metre above home (a target's altitude may
            // be wrong by tens of metres).
            2 => (target.pos_ned_m.z - p.follow_height_m).min(t.home.z - 1.0),
            _ => t.home.z - p.follow_height_m,
        };
        let to_target = target.pos_ned_m.xy() - i.pos_ned_m.xy();
        let yaw = if to_target.norm() > 1.0 {
            to_target.y.atan2(to_target.x)
        } else {
            i.yaw_rad
        };
        Setpoint::Position(PositionSetpoint {
            pos_ned_m: Vector3::new(at.x, at.y, down),
            vel_ned_m_s: Vector3::new(tv.x, tv.y, 0.0),
            accel_ned_m_s2: Vector3::zeros(),
            yaw_rad: yaw,
        })
    }
}

impl Commander {
    /// A fix of the follow target (`FOLLOW_TARGET`), at the time of the last update. Refused
    /// for a place not finite, more than [`TARGET_RANGE_M`] from the vehicle, or out of range
    /// (as a command's target).
    pub fn follow_target_fix(&mut self, fix: TargetFix) -> Result<(), Denial> {
        let finite = fix.pos_ned_m.iter().all(|x| x.is_finite())
            && fix
                .vel_ned_m_s
                .is_none_or(|v| v.iter().all(|x| x.is_finite()));
        if !finite {
            return Err(Denial::NotFinite {
                command: "follow target",
                what: "not a number",
            });
        }
        let here = self.last.map_or(fix.pos_ned_m, |i| i.pos_ned_m);
        let away = (fix.pos_ned_m.xy() - here.xy()).norm();
        if away > TARGET_RANGE_M {
            return Err(Denial::TargetTooFar {
                away_m: away,
                max_m: TARGET_RANGE_M,
            });
        }
        let home = self.flight.home.map_or(here, |h| h.0);
        let mut ne = fix.pos_ned_m;
        ne.z = f64::NAN; // its height is the target's, not a place to fly to
        self.target_limits()
            .check_target(&ne, &home)
            .map_err(|why| Denial::Target {
                command: "follow target",
                why,
            })?;
        let rs = self.flight.params.follow_responsiveness;
        self.target.fix(&fix, self.now(), rs);
        Ok(())
    }

    /// The target as the filter holds it now.
    pub fn follow_target(&self) -> Option<TargetEstimate> {
        self.target.estimate(self.now())
    }

    /// Whether Follow Target may be entered: flying, with a global position (the fixes are
    /// places on the Earth). A target lost before is forgotten: it holds until a fix.
    pub(super) fn follow_entry(&mut self) -> Result<(), Denial> {
        let name = FlightMode::FollowTarget.name();
        if !self.flight.armed || self.flight.land.state() != LandedState::InAir {
            return Err(Denial::NotFlying { command: name });
        }
        if self.last.and_then(|i| i.origin).is_none() {
            return Err(Denial::NoGlobalPosition { command: name });
        }
        self.target.forget_if_stale(self.now());
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A target walking north at 2 m/s, fixed once a second with ±1 m of noise: the filter's
    /// velocity settles near 2 m/s and its position within the noise; the fixes stopped, it
    /// stands where it was last estimated.
    #[test]
    fn the_filter_follows_a_walking_target_and_stands_when_the_fixes_stop() {
        let mut f = TargetFilter::default();
        let noise = [0.8, -0.6, 0.3, -1.0, 0.9, -0.2, 0.5, -0.7, 0.1, -0.4];
        for k in 0..30 {
            let t = k as f64;
            let n = noise[k % noise.len()];
            let fix = TargetFix {
                pos_ned_m: Vector3::new(2.0 * t + n, -n, 0.0),
                vel_ned_m_s: None,
            };
            f.fix(&fix, t, 0.1);
        }
        let e = f.estimate(29.5).unwrap();
        assert!((e.vel_ned_m_s.x - 2.0).abs() < 0.4, "{e:?}");
        assert!((e.pos_ned_m.x - 59.0).abs() < 1.0, "{e:?}");
        let later = f.estimate(29.0 + STALE_S + 5.0).unwrap();
        assert!(later.stale && later.vel_ned_m_s == Vector3::zeros());
        assert!(
            (later.pos_ned_m.x - (e.pos_ned_m.x + 2.0 * 2.5)).abs() < 1.0,
            "{later:?}"
        );
    }

    /// Two fixes a millisecond apart move the position, not the velocity; the first fix after
    /// the target was lost starts the filter again there, standing.
    #[test]
    fn close_fixes_and_a_fix_after_a_loss_do_not_throw_the_velocity() {
        let mut f = TargetFilter::default();
        let at = |n: f64| TargetFix {
            pos_ned_m: Vector3::new(n, 0.0, 0.0),
            vel_ned_m_s: None,
        };
        f.fix(&at(0.0), 0.0, 0.1);
        f.fix(&at(1.0), 1e-3, 0.1);
        let e = f.estimate(1e-3).unwrap();
        assert!(e.vel_ned_m_s.norm() < 1e-9, "{e:?}");
        f.fix(&at(100.0), 60.0, 0.1);
        let e = f.estimate(60.0).unwrap();
        assert_eq!(
            (e.pos_ned_m.x, e.vel_ned_m_s.norm(), e.stale),
            (100.0, 0.0, false)
        );
        // However wild the fixes, the target is never believed faster than 30 m/s.
        f.fix(&at(1e4), 61.0, 0.1);
        assert!(f.estimate(61.0).unwrap().vel_ned_m_s.norm() <= 30.0 + 1e-9);
    }
}
