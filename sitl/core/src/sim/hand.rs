//! A hand that holds the vehicle on the ground: it turns it through every orientation (a
//! magnetometer calibration's dance), places it on one of its six faces and holds it still (an
//! accelerometer calibration), or sets it down level and lets go.

use super::Simulator;
use nalgebra::{UnitQuaternion, Vector3};
use serde::Deserialize;
use std::f64::consts::FRAC_PI_2;

/// How long a tumble's hand takes to speed up and to slow down (s).
pub const TUMBLE_RAMP_S: f64 = 2.0;
/// How long setting the vehicle down level after a tumble takes (s).
pub const SET_DOWN_S: f64 = 2.0;
/// How long the hand takes to turn the vehicle onto another face (s): a quarter turn in about
/// 2.5 s, half a turn in the same time, as a person does it.
pub const PLACE_S: f64 = 2.5;

/// A face of the vehicle, named as a six-side accelerometer calibration names the side that
/// faces the ground (PX4's words: "down" is upright, "up" upside down, "front" nose down),
/// numbered in PX4's order of the calibration's sides.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Deserialize)]
#[serde(rename_all = "lowercase")]
#[repr(u8)]
pub enum Face {
    /// Tail down: the body's −x axis points down.
    Back = 0,
    /// Nose down: the body's +x axis points down.
    Front = 1,
    /// On its left side: the body's −y axis points down.
    Left = 2,
    /// On its right side.
    Right = 3,
    /// Upside down.
    Up = 4,
    /// Upright: the body's +z (down) axis points down.
    Down = 5,
}

impl Face {
    /// All six, in their numbers' order.
    pub const ALL: [Face; 6] = [
        Face::Back,
        Face::Front,
        Face::Left,
        Face::Right,
        Face::Up,
        Face::Down,
    ];

    /// The attitude with this face down, heading `yaw_rad` (about the vertical before the
    /// vehicle is tipped).
    pub fn attitude(self, yaw_rad: f64) -> UnitQuaternion<f64> {
        let (roll, pitch) = match self {
            Face::Down => (0.0, 0.0),
            Face::Up => (std::f64::consts::PI, 0.0),
            Face::Front => (0.0, -FRAC_PI_2),
            Face::Back => (0.0, FRAC_PI_2),
            Face::Left => (-FRAC_PI_2, 0.0),
            Face::Right => (FRAC_PI_2, 0.0),
        };
        UnitQuaternion::from_euler_angles(0.0, 0.0, yaw_rad)
            * UnitQuaternion::from_euler_angles(roll, pitch, 0.0)
    }

    /// The body axis (FRD, unit) that points down with this face down.
    pub fn down_axis(self) -> Vector3<f64> {
        match self {
            Face::Down => Vector3::z(),
            Face::Up => -Vector3::z(),
            Face::Front => Vector3::x(),
            Face::Back => -Vector3::x(),
            Face::Left => -Vector3::y(),
            Face::Right => Vector3::y(),
        }
    }
}

/// The hand's turns during a tumble of `duration_s`, `t` seconds in, from the attitude it was
/// picked up in: Euler angles growing at incommensurate rates (0.9, 0.37, 0.23 rad/s of roll,
/// pitch and yaw), so that the body sweeps every orientation within about a minute, no faster
/// than a person turns it; the rates rise from and fall to rest smoothly over
/// [`TUMBLE_RAMP_S`] (a hand, not a step: the IMU's lever arm feels no jolt).
pub fn tumble_attitude(t: f64, duration_s: f64) -> UnitQuaternion<f64> {
    let ramp = TUMBLE_RAMP_S.min(duration_s / 2.0).max(1e-9);
    // ∫ of the speed profile smoothstep(t/ramp)·smoothstep((D − t)/ramp), as a time.
    let up = |x: f64| ramp * (x.powi(3) - x.powi(4) / 2.0);
    let t = t.clamp(0.0, duration_s);
    let progress = if t < ramp {
        up(t / ramp)
    } else if t <= duration_s - ramp {
        ramp / 2.0 + (t - ramp)
    } else {
        (duration_s - ramp) - up((duration_s - t) / ramp)
    };
    UnitQuaternion::from_euler_angles(0.9 * progress, 0.37 * progress, 0.23 * progress)
}

/// What the hand is doing.
#[derive(Debug, Clone, Copy)]
pub(super) enum Hand {
    /// Turning the vehicle through every orientation, from `q0`, for `duration_s`.
    Tumble {
        start_s: f64,
        duration_s: f64,
        q0: UnitQuaternion<f64>,
    },
    /// Turning the vehicle from `from` to `to` over `turn_s`, then holding it there; when
    /// `release`, letting go once there (it then stands on the ground).
    Place {
        start_s: f64,
        turn_s: f64,
        from: UnitQuaternion<f64>,
        to: UnitQuaternion<f64>,
        release: bool,
    },
}

/// `x` ∈ [0, 1] eased in and out (zero rate at both ends).
fn smoothstep(x: f64) -> f64 {
    let x = x.clamp(0.0, 1.0);
    x * x * (3.0 - 2.0 * x)
}

impl Hand {
    /// A move from `from` to `to`, starting at `start_s`: [`PLACE_S`] for a large turn, less
    /// for a small one (at least 0.5 s).
    pub(super) fn place(
        start_s: f64,
        from: UnitQuaternion<f64>,
        to: UnitQuaternion<f64>,
        release: bool,
    ) -> Self {
        let turn_s = (PLACE_S * from.angle_to(&to) / FRAC_PI_2).clamp(0.5, PLACE_S);
        Hand::Place {
            start_s,
            turn_s,
            from,
            to,
            release,
        }
    }

    /// The attitude the hand holds at `t_s`; at the end of a tumble, the move that sets the
    /// vehicle down instead.
    fn attitude(&self, t_s: f64) -> Result<UnitQuaternion<f64>, Hand> {
        match *self {
            Hand::Tumble {
                start_s,
                duration_s,
                q0,
            } => {
                let t = t_s - start_s;
                if t < duration_s {
                    return Ok(q0 * tumble_attitude(t, duration_s));
                }
                // The dance is over: set down level, heading kept.
                let from = q0 * tumble_attitude(duration_s, duration_s);
                let level = Face::Down.attitude(from.euler_angles().2);
                Err(Hand::Place {
                    start_s: start_s + duration_s,
                    turn_s: SET_DOWN_S,
                    from,
                    to: level,
                    release: true,
                })
            }
            Hand::Place {
                start_s,
                turn_s,
                from,
                to,
                ..
            } => {
                let x = smoothstep((t_s - start_s) / turn_s);
                Ok(from.slerp(&to, x))
            }
        }
    }

    /// Whether the hand has let go by `t_s`.
    fn released(&self, t_s: f64) -> bool {
        matches!(*self, Hand::Place { start_s, turn_s, release: true, .. } if t_s >= start_s + turn_s)
    }
}

impl Simulator {
    /// The hand picks the vehicle up (if it does not hold it already) and places it with `face`
    /// down, heading kept, and holds it there still.
    pub(super) fn place(&mut self, face: Face) {
        let from = self.body.q_ned_from_frd;
        let yaw = heading_of(&from);
        self.hand = Some(Hand::place(self.time_s(), from, face.attitude(yaw), false));
    }

    /// The hand sets the vehicle down level where it is and lets go.
    pub(super) fn set_down(&mut self) {
        if self.hand.is_some() {
            let from = self.body.q_ned_from_frd;
            let level = Face::Down.attitude(heading_of(&from));
            self.hand = Some(Hand::place(self.time_s(), from, level, true));
        }
    }

    /// A step in the hand: the body held where it is, turned to the hand's attitude (its rate
    /// the turn over the step), until the hand lets go and it stands on the ground.
    pub(super) fn turn_by_hand(&mut self, hand: Hand, dt: f64) {
        let t = self.time_s() + dt;
        let q = match hand.attitude(t) {
            Ok(q) => q,
            Err(next) => {
                self.hand = Some(next);
                return self.turn_by_hand(next, dt);
            }
        };
        if hand.released(t) {
            self.hand = None;
            self.stand_on_feet();
            return;
        }
        self.body.rate_frd_rad_s = (self.body.q_ned_from_frd.inverse() * q).scaled_axis() / dt;
        self.body.q_ned_from_frd = q;
        self.body.vel_ned_m_s = Vector3::zeros();
        self.landed = true;
    }
}

/// The heading of an attitude, however it is tipped: where the body's x axis points, or for a
/// body standing on its nose or tail, where its z axis points (mirrored).
fn heading_of(q: &UnitQuaternion<f64>) -> f64 {
    let x = q.transform_vector(&Vector3::x());
    if x.xy().norm() > 0.3 {
        x.y.atan2(x.x)
    } else {
        let z = q.transform_vector(&Vector3::z()) * -x.z.signum();
        z.y.atan2(z.x)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_face_points_its_axis_down_whatever_the_heading() {
        for (i, face) in Face::ALL.into_iter().enumerate() {
            assert_eq!(face as usize, i);
            for yaw in [0.0, 1.0, -2.5] {
                let q = face.attitude(yaw);
                let down = q.transform_vector(&face.down_axis());
                assert!((down - Vector3::z()).norm() < 1e-12, "{face:?} {yaw}");
                let turn = UnitQuaternion::from_euler_angles(0.0, 0.0, heading_of(&q) - yaw);
                assert!(turn.angle() < 1e-9, "{face:?} {yaw}");
            }
        }
    }
}
