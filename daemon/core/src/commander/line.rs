//! The straight-line set-point profile every automatic mode flies its legs on.

use crate::control::position::PositionSetpoint;
use nalgebra::Vector3;

/// A straight-line set-point profile from `from` to `to`: speed ramps up at `accel`, cruises
/// at `speed`, and slows so that it stops at the end (v ≤ √(2·a·d)), or passes its end at
/// `end_speed` (v ≤ √(v_end² + 2·a·d)) where a corner goes on.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Line {
    pub(super) from: Vector3<f64>,
    pub(super) dir: Vector3<f64>,
    pub(super) length: f64,
    pub(super) s: f64,
    v: f64,
    pub(super) speed: f64,
    accel: f64,
    /// Speed at the end (m/s): 0 stops there.
    pub(super) end_speed: f64,
    /// Stepped at least once: the first step starts the profile (no time has passed on it).
    started: bool,
}

impl Line {
    /// A profile at rest at `from`.
    pub(super) fn new(from: Vector3<f64>, to: Vector3<f64>, speed: f64, accel: f64) -> Self {
        let d = to - from;
        let length = d.norm();
        Self {
            from,
            dir: if length > 1e-9 {
                d / length
            } else {
                Vector3::zeros()
            },
            length,
            s: 0.0,
            v: 0.0,
            speed,
            accel,
            end_speed: 0.0,
            started: false,
        }
    }

    /// The same profile passing its end at `end_speed` (at most its cruise speed).
    pub(super) fn passing_at(mut self, end_speed: f64) -> Self {
        self.end_speed = end_speed.clamp(0.0, self.speed);
        self
    }

    /// The same profile already moving at `speed` (at most its cruise speed) at its start.
    pub(super) fn starting_at(mut self, speed: f64) -> Self {
        self.v = speed.clamp(0.0, self.speed);
        self
    }

    /// A profile already at `speed` at `from` (a stop from that speed).
    pub(super) fn moving(from: Vector3<f64>, to: Vector3<f64>, speed: f64, accel: f64) -> Self {
        Self {
            v: speed,
            ..Self::new(from, to, speed, accel)
        }
    }

    /// Where the profile ends.
    pub(super) fn end(&self) -> Vector3<f64> {
        self.from + self.dir * self.length
    }

    /// Advances `dt`; returns the set-point (position, velocity and acceleration feed-forward,
    /// yaw left to the caller) and whether the end is reached.
    pub(super) fn step(&mut self, dt: f64, yaw_rad: f64) -> (PositionSetpoint, bool) {
        let dt = if self.started { dt } else { 0.0 };
        self.started = true;
        let left = (self.length - self.s).max(0.0);
        // A lower speed (a speed change on the way) is reached at the same deceleration.
        let v = (self.v + self.accel * dt)
            .min(self.speed)
            .max(self.v - self.accel * dt)
            .min(braking_speed(left, self.accel, dt, self.end_speed));
        let a = if dt > 0.0 { (v - self.v) / dt } else { 0.0 };
        self.v = v;
        self.s = (self.s + v * dt).min(self.length);
        let arrived = self.s >= self.length;
        let sp = PositionSetpoint {
            pos_ned_m: self.from + self.dir * self.s,
            vel_ned_m_s: if arrived && self.end_speed == 0.0 {
                Vector3::zeros()
            } else {
                self.dir * v
            },
            accel_ned_m_s2: self.dir * a,
            yaw_rad,
        };
        (sp, arrived)
    }
}

/// The fastest speed from which a set-point stepping every `dt` still slows to `end` within
/// `left` at deceleration `a`: v = √(end² + 2·a·d) in the limit, here with the half-step of the
/// discrete motion, √(end² + 2·a·d + (a·dt/2)²) − a·dt/2.
fn braking_speed(left: f64, a: f64, dt: f64, end: f64) -> f64 {
    let h = 0.5 * a * dt;
    (end * end + 2.0 * a * left + h * h).sqrt() - h
}
