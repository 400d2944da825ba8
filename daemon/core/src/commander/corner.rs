//! A mission's corner flown through: the arc of the circle inscribed in the angle α between two
//! legs, touching them `L` = the acceptance radius (`NAV_ACC_RAD`) from the waypoint (PX4's
//! turning circle, radius `R = L tan(α/2)`), at the speed whose centripetal acceleration is
//! `MPC_ACC_HOR` (PX4's `√(a L tan(α/2))`). The legs end and start at its touching points, so the
//! path stays inside the corner (`R / sin(α/2) − R` from the waypoint at most: 0.83 m for a right
//! angle and L = 2 m) and the vehicle stops only where the mission asks it to.

use crate::control::position::PositionSetpoint;
use nalgebra::{Vector2, Vector3};

/// The arc from the end of one leg to the start of the next.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Corner {
    /// Where the incoming leg ends and the arc begins (NED, m).
    pub(super) start: Vector3<f64>,
    /// Where the arc ends and the outgoing leg begins (NED, m).
    pub(super) end: Vector3<f64>,
    /// Speed along the arc (m/s).
    pub(super) speed: f64,
    center: Vector2<f64>,
    radius: f64,
    /// Angle of the start from the centre (rad, from north toward east).
    phi0: f64,
    /// The arc's signed sweep (rad; positive clockwise seen from above, toward east from north).
    sweep: f64,
    /// Angle flown so far (rad, unsigned).
    flown: f64,
}

impl Corner {
    /// The corner at waypoint `w` between the leg from `from` and the leg to `to`, touching each
    /// `touch_m` from `w` (less on a short leg: at most half of it), flown at centripetal
    /// acceleration `accel` and at most `cruise`; `None` where there is no turn to round (straight
    /// on, back on itself, a leg too short, a vertical leg).
    pub(super) fn new(
        from: Vector3<f64>,
        w: Vector3<f64>,
        to: Vector3<f64>,
        touch_m: f64,
        accel: f64,
        cruise: f64,
    ) -> Option<Self> {
        let (a, b) = ((w - from).xy(), (to - w).xy());
        let (la, lb) = (a.norm(), b.norm());
        if la < 1e-3 || lb < 1e-3 || touch_m <= 0.0 {
            return None;
        }
        let (da, db) = (a / la, b / lb);
        let turn = da.perp(&db).atan2(da.dot(&db)); // signed, positive turning right (clockwise)
        if turn.abs() < 1e-3 || turn.abs() > std::f64::consts::PI - 0.05 {
            return None;
        }
        let l = touch_m.min(0.5 * la).min(0.5 * lb);
        // The inscribed circle: radius l · tan(α/2) with α = π − |turn| the angle between legs.
        let radius = l / (0.5 * turn.abs()).tan();
        let t1 = w.xy() - da * l;
        let t2 = w.xy() + db * l;
        // The centre is to the side the vehicle turns to, a radius from the first touch point.
        let side = if turn > 0.0 {
            Vector2::new(-da.y, da.x) // right of the incoming leg (x north, y east)
        } else {
            Vector2::new(da.y, -da.x)
        };
        let center = t1 + side * radius;
        let r0 = t1 - center;
        let speed = (accel * radius).sqrt().min(cruise);
        let z = |p: Vector2<f64>, zz: f64| Vector3::new(p.x, p.y, zz);
        Some(Self {
            start: z(t1, w.z),
            end: z(t2, w.z),
            speed,
            center,
            radius,
            phi0: r0.y.atan2(r0.x),
            sweep: turn,
            flown: 0.0,
        })
    }

    /// Advances `dt`; the set-point on the arc (position, velocity, centripetal acceleration)
    /// and whether its end is reached.
    pub(super) fn step(&mut self, dt: f64, yaw_rad: f64) -> (PositionSetpoint, bool) {
        self.flown = (self.flown + self.speed * dt / self.radius).min(self.sweep.abs());
        let phi = self.phi0 + self.sweep.signum() * self.flown;
        let radial = Vector2::new(phi.cos(), phi.sin());
        let pos = self.center + radial * self.radius;
        // Moving clockwise (a right turn) the velocity is the radial turned a quarter clockwise.
        let tangent = if self.sweep > 0.0 {
            Vector2::new(-radial.y, radial.x)
        } else {
            Vector2::new(radial.y, -radial.x)
        };
        let v = tangent * self.speed;
        let a = -radial * self.speed * self.speed / self.radius;
        let sp = PositionSetpoint {
            pos_ned_m: Vector3::new(pos.x, pos.y, self.start.z),
            vel_ned_m_s: Vector3::new(v.x, v.y, 0.0),
            accel_ned_m_s2: Vector3::new(a.x, a.y, 0.0),
            yaw_rad,
        };
        (sp, self.flown >= self.sweep.abs())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_right_angle_is_rounded_inside_the_corner_from_touch_point_to_touch_point() {
        // North 20 m, then east: a right turn at (20, 0).
        let w = Vector3::new(20.0, 0.0, -10.0);
        let mut c = Corner::new(
            Vector3::new(0.0, 0.0, -10.0),
            w,
            Vector3::new(20.0, 20.0, -10.0),
            1.0,
            3.0,
            5.0,
        )
        .unwrap();
        assert!((c.start - Vector3::new(19.0, 0.0, -10.0)).norm() < 1e-9);
        assert!((c.end - Vector3::new(20.0, 1.0, -10.0)).norm() < 1e-9);
        assert!((c.speed - 3f64.sqrt()).abs() < 1e-9, "√(a R), R = 1 m");
        let (first, _) = c.step(0.0, 0.0);
        assert!((first.pos_ned_m - c.start).norm() < 1e-9);
        assert!(
            (first.vel_ned_m_s.normalize() - Vector3::x()).norm() < 1e-9,
            "along the leg"
        );
        let mut last = first;
        let mut inside = f64::INFINITY;
        for _ in 0..1000 {
            let (sp, done) = c.step(0.004, 0.0);
            // Never outside the square (north of 20 m or west of 0).
            assert!(
                sp.pos_ned_m.x <= 20.0 + 1e-9 && sp.pos_ned_m.y >= -1e-9,
                "{sp:?}"
            );
            inside = inside.min((sp.pos_ned_m - w).norm());
            last = sp;
            if done {
                break;
            }
        }
        assert!((last.pos_ned_m - c.end).norm() < 1e-6);
        assert!(
            (last.vel_ned_m_s.normalize() - Vector3::y()).norm() < 1e-6,
            "along the next"
        );
        assert!(
            (inside - (2f64.sqrt() - 1.0)).abs() < 0.01,
            "0.41 m inside: {inside}"
        );
    }

    #[test]
    fn left_turns_shallow_turns_and_no_turns() {
        let o = Vector3::zeros();
        let w = Vector3::new(10.0, 0.0, 0.0);
        // Left (toward west): the centre on the west side, the path still inside.
        let mut c = Corner::new(o, w, Vector3::new(10.0, -10.0, 0.0), 1.0, 1.0, 5.0).unwrap();
        for _ in 0..2000 {
            let (sp, done) = c.step(0.004, 0.0);
            assert!(
                sp.pos_ned_m.x <= 10.0 + 1e-9 && sp.pos_ned_m.y <= 1e-9,
                "{sp:?}"
            );
            if done {
                break;
            }
        }
        // A shallow turn is flown faster than a sharp one; straight on is no corner.
        let shallow = Corner::new(o, w, Vector3::new(20.0, 3.0, 0.0), 1.0, 3.0, 5.0).unwrap();
        let sharp = Corner::new(o, w, Vector3::new(5.0, 3.0, 0.0), 1.0, 3.0, 5.0).unwrap();
        assert!(shallow.speed > sharp.speed);
        assert!(Corner::new(o, w, Vector3::new(20.0, 0.0, 0.0), 1.0, 3.0, 5.0).is_none());
        assert!(Corner::new(o, w, Vector3::new(0.0, 0.0, 0.0), 1.0, 3.0, 5.0).is_none());
    }
}
