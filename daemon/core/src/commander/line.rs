//! The straight-line set-point profile every automatic mode flies its legs on.
//!
//! With a jerk limit (`MPC_JERK_AUTO`) the speed follows S-curves: the acceleration ramps at
//! the jerk `J` to at most `A` and back. The stop (or the slowing to a corner's speed) is
//! planned as one piece when the distance left reaches what it needs, and played back exactly:
//! from `v` to `v_e` the time is `Δv/A + A/J` (`2√(Δv/J)` when `A` is never reached), and the
//! distance that time times the mean speed `(v + v_e)/2` (the S-curve is point-symmetric), so the
//! set-point never passes the end.

use crate::control::position::PositionSetpoint;
use nalgebra::Vector3;

/// A straight-line set-point profile from `from` to `to`: speed ramps up at `accel`, cruises
/// at `speed`, and slows so that it stops at the end (v ≤ √(2·a·d)), or passes its end at
/// `end_speed` (v ≤ √(v_end² + 2·a·d)) where a corner goes on; with a jerk limit the ramps are
/// S-curves (`with_jerk`).
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
    /// Jerk limit (m/s³; infinite: the speed ramps at `accel` with steps in the acceleration).
    jerk: f64,
    /// The acceleration along the line now (m/s²; with a jerk limit).
    a: f64,
    /// The stop being played back: jerk segments (duration s, jerk m/s³), in order; played
    /// out, the profile flies on at the end speed.
    braking: Option<[(f64, f64); 4]>,
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
            jerk: f64::INFINITY,
            a: 0.0,
            braking: None,
        }
    }

    /// The same profile with its acceleration changing at most at `jerk` (m/s³).
    pub(super) fn with_jerk(mut self, jerk: f64) -> Self {
        if jerk.is_finite() && jerk > 0.0 {
            self.jerk = jerk;
        }
        self
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
        if self.jerk.is_finite() {
            return self.step_s_curve(dt, yaw_rad);
        }
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

impl Line {
    /// One step of the jerk-limited profile.
    fn step_s_curve(&mut self, dt: f64, yaw_rad: f64) -> (PositionSetpoint, bool) {
        let (amax, j) = (self.accel, self.jerk);
        if self.braking.is_none() && dt > 0.0 {
            // Brake now if one more step of the speed-seeking would leave less than the stop
            // needs: the stop from the state after it (its acceleration first brought to zero).
            let (a1, v1, ds) = seek(self.a, self.v, self.speed, amax, j, dt);
            let left = self.length - self.s;
            let after = stop_distance(v1, a1, self.end_speed, amax, j);
            if self.v > self.end_speed && left - ds < after {
                self.braking = Some(stop_plan(self.v, self.a, self.end_speed, amax, j));
            }
        }
        let (a, v, ds) = match self.braking.as_mut() {
            Some(plan) => play(plan, self.a, self.v, dt),
            None => seek(self.a, self.v, self.speed, amax, j, dt),
        };
        (self.a, self.v) = (a, v.max(0.0));
        self.s = (self.s + ds).min(self.length);
        // A stop played out ends at the end (it began within a step's travel of the latest
        // point it could; a played-out slowing flies on at the end speed).
        let played_out = self
            .braking
            .is_some_and(|plan| plan.iter().all(|seg| seg.0 <= 1e-12));
        if played_out && self.end_speed == 0.0 {
            (self.s, self.v, self.a) = (self.length, 0.0, 0.0);
        }
        let arrived = self.s >= self.length;
        let stopped = arrived && self.end_speed == 0.0;
        let sp = PositionSetpoint {
            pos_ned_m: self.from + self.dir * self.s,
            vel_ned_m_s: if stopped {
                Vector3::zeros()
            } else {
                self.dir * self.v
            },
            accel_ned_m_s2: if stopped {
                Vector3::zeros()
            } else {
                self.dir * self.a
            },
            yaw_rad,
        };
        (sp, arrived)
    }
}

/// One step seeking `target` speed from acceleration `a` and speed `v`: the acceleration heads
/// for `A` toward the target at most at `J`, and turns back in time to land on the target with
/// none left (the constant jerk `a²/(2 Δv)` that does it exactly); returns the new acceleration,
/// speed and the distance flown (exact for the step's jerk).
fn seek(a: f64, v: f64, target: f64, amax: f64, j: f64, dt: f64) -> (f64, f64, f64) {
    let dv = target - v;
    if dv == 0.0 && a == 0.0 {
        return (0.0, v, v * dt);
    }
    // Along the way to the target: `ad` the acceleration toward it, `r` the speed still to go.
    let sgn = if dv != 0.0 { dv.signum() } else { -a.signum() };
    let (ad, r) = (a * sgn, dv.abs());
    let up = (amax - ad).clamp(-j * dt, j * dt) / dt.max(1e-12);
    let next = ad + up * dt;
    let late = next > 0.0 && next * next / (2.0 * j) >= r - 0.5 * (ad + next) * dt;
    if ad > 0.0 && late {
        // Land: the acceleration falls to zero just as the speed reaches the target.
        let jerk = -(ad * ad / (2.0 * r.max(1e-12))).min(j);
        let t_land = ad / -jerk;
        if t_land <= dt {
            let (_, _, d) = integrate(a, v, jerk * sgn, t_land);
            return (0.0, target, d + target * (dt - t_land));
        }
        return integrate(a, v, jerk * sgn, dt);
    }
    let (a1, v1, d) = integrate(a, v, up * sgn, dt);
    if (target - v1) * sgn < 0.0 && ad.abs() <= j * dt {
        // Within a step's jerk of the target: on it.
        return (0.0, target, 0.5 * (v + target) * dt);
    }
    (a1, v1, d)
}

/// The jerk segments of the stop from speed `v` and acceleration `a` to `v_e`: the acceleration
/// to zero first, then the S-curve down.
fn stop_plan(v: f64, a: f64, v_e: f64, amax: f64, j: f64) -> [(f64, f64); 4] {
    let t0 = a.abs() / j;
    let v1 = v + a * t0 - a.signum() * 0.5 * j * t0 * t0;
    let dv = (v1 - v_e).max(0.0);
    let (t1, t2) = s_curve_times(dv, amax, j);
    [(t0, -a.signum() * j), (t1, -j), (t2, 0.0), (t1, j)]
}

/// The distance the stop of `stop_plan` flies.
fn stop_distance(v: f64, a: f64, v_e: f64, amax: f64, j: f64) -> f64 {
    let t0 = a.abs() / j;
    let jerk0 = -a.signum() * j;
    let (_, v1, d0) = integrate(a, v, jerk0, t0);
    let dv = (v1 - v_e).max(0.0);
    let (t1, t2) = s_curve_times(dv, amax, j);
    d0 + 0.5 * (v1 + (v1 - dv)) * (2.0 * t1 + t2)
}

/// The jerk phase and the constant-deceleration phase of an S-curve losing `dv`.
fn s_curve_times(dv: f64, amax: f64, j: f64) -> (f64, f64) {
    if dv >= amax * amax / j {
        (amax / j, dv / amax - amax / j)
    } else {
        ((dv / j).sqrt(), 0.0)
    }
}

/// Plays `dt` of the plan's segments, consuming them; the new acceleration, speed and distance.
fn play(plan: &mut [(f64, f64); 4], a: f64, v: f64, dt: f64) -> (f64, f64, f64) {
    let (mut a, mut v, mut ds, mut left) = (a, v, 0.0, dt);
    for seg in plan.iter_mut() {
        if left <= 0.0 {
            break;
        }
        let t = seg.0.min(left);
        if t <= 0.0 {
            continue;
        }
        let (a1, v1, d) = integrate(a, v, seg.1, t);
        (a, v, ds) = (a1, v1, ds + d);
        seg.0 -= t;
        left -= t;
    }
    if plan.iter().all(|seg| seg.0 <= 1e-12) {
        a = 0.0; // the rounding of the last segment
    }
    (a, v, ds + v * left.max(0.0))
}

/// Constant jerk over `t`: the acceleration, speed and distance after it.
fn integrate(a: f64, v: f64, jerk: f64, t: f64) -> (f64, f64, f64) {
    (
        a + jerk * t,
        v + a * t + 0.5 * jerk * t * t,
        v * t + 0.5 * a * t * t + jerk * t * t * t / 6.0,
    )
}

/// The fastest speed from which a set-point stepping every `dt` still slows to `end` within
/// `left` at deceleration `a`: v = √(end² + 2·a·d) in the limit, here with the half-step of the
/// discrete motion, √(end² + 2·a·d + (a·dt/2)²) − a·dt/2.
fn braking_speed(left: f64, a: f64, dt: f64, end: f64) -> f64 {
    let h = 0.5 * a * dt;
    (end * end + 2.0 * a * left + h * h).sqrt() - h
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Flies `line` in steps of `dt` to its end; every step's (time, distance, speed,
    /// acceleration), asserting the jerk, acceleration and speed limits and that it never
    /// passes the end.
    fn fly(mut line: Line, dt: f64, jerk: f64) -> Vec<(f64, f64, f64, f64)> {
        let mut out = Vec::new();
        let (mut t, mut last_a, mut last_s) = (0.0, 0.0, 0.0);
        for _ in 0..100_000 {
            let (sp, arrived) = line.step(dt, 0.0);
            let s = (sp.pos_ned_m - line.from).dot(&line.dir);
            let (v, a) = (
                sp.vel_ned_m_s.dot(&line.dir),
                sp.accel_ned_m_s2.dot(&line.dir),
            );
            assert!(
                (a - last_a).abs() <= jerk * dt + 1e-9,
                "jerk at {t}: {last_a} -> {a}"
            );
            assert!(a.abs() <= line.accel + 1e-9 && v <= line.speed + 1e-9);
            assert!(
                s >= last_s - 1e-12 && s <= line.length + 1e-12,
                "{s} at {t}"
            );
            out.push((t, s, v, a));
            (last_a, last_s) = (a, s);
            if arrived {
                return out;
            }
            t += dt;
        }
        panic!("never arrived");
    }

    #[test]
    fn a_jerk_limited_stop_takes_the_s_curves_time_and_ends_at_rest_at_the_end() {
        let (a, j) = (3.0, 4.0);
        let to = Vector3::new(20.0, 0.0, -5.0);
        let line = Line::new(Vector3::new(0.0, 0.0, -5.0), to, 5.0, a).with_jerk(j);
        let run = fly(line, 0.01, j);
        let &(t, s, v, acc) = run.last().unwrap();
        assert!((s - 20.0).abs() < 1e-12 && v == 0.0 && acc == 0.0);
        // Up and down to 5 m/s each 5/3 + 3/4 s over 2.5 m/s × that, the rest at 5 m/s.
        let ramp = 5.0 / a + a / j;
        let best = 2.0 * ramp + (20.0 - 2.0 * 2.5 * ramp) / 5.0;
        assert!(t >= best - 0.02 && t < best + 0.1, "{t} s against {best} s");
        // The last step before the end is slow: the stop was planned, not clipped.
        let before = run[run.len() - 2];
        assert!(before.2 < 0.1, "{before:?}");
    }

    #[test]
    fn a_jerk_limited_leg_into_a_corner_passes_its_end_at_the_corners_speed() {
        let line = Line::new(Vector3::zeros(), Vector3::new(0.0, 15.0, 0.0), 5.0, 3.0)
            .with_jerk(4.0)
            .passing_at(1.7);
        let &(_, s, v, a) = fly(line, 0.004, 4.0).last().unwrap();
        assert!((s - 15.0).abs() < 1e-12);
        assert!(
            (v - 1.7).abs() < 1e-6 && a.abs() < 1e-6,
            "{v} m/s, {a} m/s²"
        );
    }

    #[test]
    fn a_short_jerk_limited_leg_never_reaches_its_cruise_and_still_stops_at_its_end() {
        for length in [0.05, 0.5, 2.0] {
            let line = Line::new(Vector3::zeros(), Vector3::new(length, 0.0, 0.0), 5.0, 3.0)
                .with_jerk(4.0);
            let run = fly(line, 0.01, 4.0);
            let top = run.iter().map(|r| r.2).fold(0.0, f64::max);
            assert!(top < 2.0, "{length} m: {top} m/s");
            assert_eq!(run.last().unwrap().1, length);
        }
    }
}
