//! The minimal flight sequence: disarmed → armed (spool-up) → take-off → hover → land →
//! touchdown → disarmed. A pure state machine of time and the estimate; the daemon drives it
//! from the command line until MAVLink commands arrive.
//!
//! Failsafe: when the estimate stops being fit to fly on (a sensor stopped), an armed vehicle
//! on the ground disarms and one in the air levels and descends at the landing speed on what
//! estimate is left (PX4's "Descend"), until touchdown.

use crate::control::position::PositionSetpoint;
use nalgebra::Vector3;

/// Where in the sequence the vehicle is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Phase {
    /// Motors off, waiting for the estimator.
    Disarmed,
    /// Armed on the ground, motors spooling up.
    Armed,
    /// Climbing to the take-off altitude.
    Takeoff,
    /// Holding position.
    Hover,
    /// Descending to the ground.
    Land,
    /// Failsafe: level and descend on the vertical estimate alone, until touchdown.
    Descend,
    /// Touched down and disarmed: the sequence is over.
    Done,
}

/// Acceleration of the take-off set-point (m/s²).
const TAKEOFF_ACCEL_M_S2: f64 = 1.0;

/// The fastest speed from which a set-point stepping every `dt` still stops within `left` at
/// deceleration `a`: v = √(2·a·d) in the limit, here with the half-step of the discrete motion,
/// √(2·a·d + (a·dt/2)²) − a·dt/2.
fn braking_speed(left: f64, a: f64, dt: f64) -> f64 {
    let h = 0.5 * a * dt;
    (2.0 * a * left + h * h).sqrt() - h
}

/// What to fly.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SequenceParams {
    /// Take-off altitude above the start (m).
    pub takeoff_alt_m: f64,
    /// Climb speed of the take-off set-point (m/s), as PX4's `MPC_TKO_SPEED`.
    pub takeoff_speed_m_s: f64,
    /// Time to hover before landing (s); infinite hovers until told to land.
    pub hover_s: f64,
    /// Spool-up time on the ground after arming (s).
    pub spool_s: f64,
    /// Descent speed while landing (m/s).
    pub land_speed_m_s: f64,
    /// Descent speed for the last part of the landing (m/s), as PX4's two-stage landing.
    pub final_speed_m_s: f64,
    /// Height above home where the final, slower descent begins (m).
    pub final_height_m: f64,
}

/// The estimate the sequence watches.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SequenceInput {
    /// Time (s).
    pub t_s: f64,
    /// The estimator can be flown on (attitude and position valid).
    pub ready: bool,
    /// The horizontal estimate is valid (GPS fresh): a descent without a full estimate then
    /// brakes to a stop over the ground instead of only levelling.
    pub horizontal_valid: bool,
    /// Estimated position NED (m).
    pub pos_ned_m: Vector3<f64>,
    /// Estimated velocity NED (m/s).
    pub vel_ned_m_s: Vector3<f64>,
}

/// The flight sequence.
#[derive(Debug, Clone, PartialEq)]
pub struct FlightSequence {
    params: SequenceParams,
    phase: Phase,
    since_s: f64,
    home: Vector3<f64>,
    land_sp_down: f64,
    takeoff_sp_up: f64,
    takeoff_v: f64,
    still_since_s: Option<f64>,
    land_requested: bool,
    last_t_s: Option<f64>,
}

impl FlightSequence {
    /// A sequence waiting to arm.
    pub fn new(params: SequenceParams) -> Self {
        Self {
            params,
            phase: Phase::Disarmed,
            since_s: 0.0,
            home: Vector3::zeros(),
            land_sp_down: 0.0,
            takeoff_sp_up: 0.0,
            takeoff_v: 0.0,
            still_since_s: None,
            land_requested: false,
            last_t_s: None,
        }
    }

    /// The current phase.
    pub fn phase(&self) -> Phase {
        self.phase
    }

    /// Asks to land now (e.g. Ctrl-C, a failsafe).
    pub fn request_land(&mut self) {
        self.land_requested = true;
    }

    /// The estimate is lost (sensors stopped, or it is unfit to fly on): on the ground the motors stop
    /// (disarm); in the air the vehicle descends (what flies it until they return is the
    /// caller's: see [`crate::failsafe::BlindDescent`]). Returns whether it is in the air.
    pub fn sensors_stopped(&mut self) -> bool {
        let t = self.last_t_s.unwrap_or(0.0);
        match self.phase {
            Phase::Armed => {
                self.enter(Phase::Done, t);
                false
            }
            Phase::Takeoff | Phase::Hover | Phase::Land => {
                self.enter(Phase::Descend, t);
                true
            }
            Phase::Descend => true,
            Phase::Disarmed | Phase::Done => false,
        }
    }

    /// The motors stopped without the sequence (the end of a blind descent): over.
    pub fn disarmed(&mut self) {
        let t = self.last_t_s.unwrap_or(0.0);
        self.enter(Phase::Done, t);
    }

    /// The take-off spot, NED (m).
    pub fn home(&self) -> Vector3<f64> {
        self.home
    }

    /// Touchdown when the vehicle has been `stopped` for a second: disarm.
    fn touchdown_check(&mut self, stopped: bool, t: f64) {
        match (stopped, self.still_since_s) {
            (true, None) => self.still_since_s = Some(t),
            (true, Some(s)) if t - s >= 1.0 => self.enter(Phase::Done, t),
            (false, _) => self.still_since_s = None,
            _ => {}
        }
    }

    fn enter(&mut self, phase: Phase, t: f64) {
        self.phase = phase;
        self.since_s = t;
        self.still_since_s = None;
    }

    /// Advances the sequence; returns the set-point and whether the motors are armed.
    pub fn update(&mut self, i: &SequenceInput) -> (PositionSetpoint, bool) {
        let p = self.params;
        let t = i.t_s;
        let dt = self.last_t_s.map_or(0.0, |last| (t - last).max(0.0));
        self.last_t_s = Some(t);
        let in_phase = t - self.since_s;
        let hold = |pos: Vector3<f64>| PositionSetpoint {
            pos_ned_m: pos,
            vel_ned_m_s: Vector3::zeros(),
            accel_ned_m_s2: Vector3::zeros(),
            yaw_rad: 0.0,
        };
        let cruise = self.home - Vector3::new(0.0, 0.0, p.takeoff_alt_m);
        if self.land_requested && matches!(self.phase, Phase::Armed | Phase::Takeoff | Phase::Hover)
        {
            self.land_sp_down = i.pos_ned_m.z;
            self.enter(Phase::Land, t);
        }
        if !i.ready {
            // The same reaction as to silent sensors, at this update's time.
            self.sensors_stopped();
        }
        match self.phase {
            Phase::Disarmed => {
                if i.ready && !self.land_requested {
                    self.home = i.pos_ned_m;
                    self.enter(Phase::Armed, t);
                    return (hold(self.home + Vector3::new(0.0, 0.0, 0.5)), true);
                }
                (hold(i.pos_ned_m), false)
            }
            Phase::Armed => {
                if in_phase >= p.spool_s {
                    self.takeoff_sp_up = 0.0;
                    self.takeoff_v = 0.0;
                    self.enter(Phase::Takeoff, t);
                }
                // Spool-up: a set-point just below the ground keeps thrust low until take-off.
                (hold(self.home + Vector3::new(0.0, 0.0, 0.5)), true)
            }
            Phase::Takeoff => {
                // The set-point climbs from the ground to the take-off altitude with limited
                // speed and acceleration, slowing so that it stops at the altitude
                // (v ≤ √(2·a·d)); the vehicle follows it with velocity and acceleration
                // feed-forward and
                // arrives without the overshoot or slow creep of a step.
                let left = p.takeoff_alt_m - self.takeoff_sp_up;
                let v = (self.takeoff_v + TAKEOFF_ACCEL_M_S2 * dt)
                    .min(p.takeoff_speed_m_s)
                    .min(braking_speed(left.max(0.0), TAKEOFF_ACCEL_M_S2, dt));
                let climb_accel = if dt > 0.0 {
                    (v - self.takeoff_v) / dt
                } else {
                    0.0
                };
                self.takeoff_v = v;
                self.takeoff_sp_up = (self.takeoff_sp_up + v * dt).min(p.takeoff_alt_m);
                let arrived = self.takeoff_sp_up >= p.takeoff_alt_m;
                if arrived && -(i.pos_ned_m.z - self.home.z) >= 0.95 * p.takeoff_alt_m {
                    self.enter(Phase::Hover, t);
                    return (hold(cruise), true);
                }
                let sp = PositionSetpoint {
                    pos_ned_m: self.home - Vector3::new(0.0, 0.0, self.takeoff_sp_up),
                    vel_ned_m_s: Vector3::new(0.0, 0.0, if arrived { 0.0 } else { -v }),
                    accel_ned_m_s2: Vector3::new(0.0, 0.0, -climb_accel),
                    yaw_rad: 0.0,
                };
                (sp, true)
            }
            Phase::Hover => {
                if in_phase >= p.hover_s {
                    self.land_sp_down = i.pos_ned_m.z;
                    self.enter(Phase::Land, t);
                }
                (hold(cruise), true)
            }
            Phase::Land => {
                // The set-point descends steadily; touchdown when the vehicle has stopped moving
                // down for a second while the set-point is well below it (it cannot go lower).
                let height = self.home.z - i.pos_ned_m.z;
                let speed = if height > p.final_height_m {
                    p.land_speed_m_s
                } else {
                    p.final_speed_m_s
                };
                self.land_sp_down = (self.land_sp_down + speed * dt).min(i.pos_ned_m.z + 1.0);
                let stopped =
                    i.vel_ned_m_s.z.abs() < 0.15 && self.land_sp_down - i.pos_ned_m.z > 0.5;
                self.touchdown_check(stopped, t);
                let sp = PositionSetpoint {
                    pos_ned_m: Vector3::new(self.home.x, self.home.y, self.land_sp_down),
                    vel_ned_m_s: Vector3::new(0.0, 0.0, speed),
                    accel_ned_m_s2: Vector3::zeros(),
                    yaw_rad: 0.0,
                };
                (sp, self.phase != Phase::Done)
            }
            Phase::Descend => {
                // Descend: braking to zero ground speed while the horizontal estimate holds,
                // else level (horizontal velocity uncontrolled); touchdown when the vertical
                // speed has stayed near zero for a second.
                let stopped = in_phase > 1.0 && i.vel_ned_m_s.z.abs() < 0.15;
                self.touchdown_check(stopped, t);
                let h = if i.horizontal_valid { 0.0 } else { f64::NAN };
                let sp = PositionSetpoint {
                    pos_ned_m: Vector3::repeat(f64::NAN),
                    vel_ned_m_s: Vector3::new(h, h, p.land_speed_m_s),
                    accel_ned_m_s2: Vector3::zeros(),
                    yaw_rad: 0.0,
                };
                (sp, self.phase != Phase::Done)
            }
            Phase::Done => (hold(i.pos_ned_m), false),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn input(t: f64, down: f64, vd: f64) -> SequenceInput {
        SequenceInput {
            t_s: t,
            ready: true,
            horizontal_valid: true,
            pos_ned_m: Vector3::new(0.0, 0.0, down),
            vel_ned_m_s: Vector3::new(0.0, 0.0, vd),
        }
    }

    fn params() -> SequenceParams {
        SequenceParams {
            takeoff_alt_m: 5.0,
            takeoff_speed_m_s: 1.5,
            hover_s: 3.0,
            spool_s: 1.0,
            land_speed_m_s: 0.7,
            final_speed_m_s: 0.7,
            final_height_m: 0.0,
        }
    }

    /// The sequence as a table: (time, estimated down, vertical speed) → expected phase after.
    #[test]
    fn phases_follow_the_flight() {
        let mut s = FlightSequence::new(params());
        let table = [
            (0.0, 0.0, 0.0, Phase::Armed),
            (0.5, 0.0, 0.0, Phase::Armed),
            (1.0, 0.0, 0.0, Phase::Takeoff),
            (3.0, -2.0, -1.5, Phase::Takeoff),
            (5.0, -4.6, -0.5, Phase::Takeoff), // the set-point has arrived, the vehicle not yet
            (6.0, -4.9, -0.1, Phase::Hover),
            (8.0, -5.0, 0.0, Phase::Hover),
            (9.0, -5.0, 0.0, Phase::Land),
            (14.0, -1.5, 0.7, Phase::Land), // descending at 0.7 m/s
            (16.5, 0.0, 0.0, Phase::Land),  // on the ground; the set-point is not yet below it
            (17.0, 0.0, 0.0, Phase::Land),  // set-point 0.6 m below: still for...
            (17.5, 0.0, 0.0, Phase::Land),
            (18.1, 0.0, 0.0, Phase::Done), // ...a second: touchdown, disarmed
        ];
        for (t, d, vd, expected) in table {
            let (_, armed) = s.update(&input(t, d, vd));
            assert_eq!(s.phase(), expected, "at t = {t}");
            assert_eq!(armed, !matches!(expected, Phase::Disarmed | Phase::Done));
        }
    }

    #[test]
    fn waits_for_the_estimator_and_lands_on_request() {
        let mut s = FlightSequence::new(params());
        let (_, armed) = s.update(&SequenceInput {
            ready: false,
            ..input(0.0, 0.0, 0.0)
        });
        assert!(!armed && s.phase() == Phase::Disarmed);
        s.update(&input(1.0, 0.0, 0.0));
        s.update(&input(2.5, -2.0, -1.0));
        assert_eq!(s.phase(), Phase::Takeoff);
        s.request_land();
        let (sp, armed) = s.update(&input(2.6, -2.1, -1.0));
        assert!(armed && s.phase() == Phase::Land);
        assert!(sp.vel_ned_m_s.z > 0.0, "descending");
    }

    #[test]
    fn losing_the_estimate_disarms_on_the_ground_and_descends_level_in_the_air() {
        let lost = |t, down, vd| SequenceInput {
            ready: false,
            horizontal_valid: false,
            ..input(t, down, vd)
        };
        // Spooling up on the ground: disarm at once.
        let mut s = FlightSequence::new(params());
        s.update(&input(0.0, 0.0, 0.0));
        assert_eq!(s.phase(), Phase::Armed);
        let (_, armed) = s.update(&lost(0.5, 0.0, 0.0));
        assert!(!armed && s.phase() == Phase::Done);

        // Hovering: level and descend, touchdown after a second standing still, and no way back.
        let mut s = FlightSequence::new(params());
        for (t, d, vd) in [(0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (3.0, -2.0, -1.5)] {
            s.update(&input(t, d, vd));
        }
        let (sp, armed) = s.update(&lost(3.1, -2.1, -1.4));
        assert!(armed && s.phase() == Phase::Descend);
        assert!(
            sp.pos_ned_m.iter().all(|p| p.is_nan()),
            "no position control"
        );
        assert!(
            sp.vel_ned_m_s.x.is_nan() && sp.vel_ned_m_s.y.is_nan(),
            "level"
        );
        assert!((sp.vel_ned_m_s.z - 0.7).abs() < 1e-12 && sp.accel_ned_m_s2 == Vector3::zeros());
        // The barometer lost but the GPS still there: brake over the ground while descending.
        let baro_lost = SequenceInput {
            ready: false,
            ..input(3.2, -2.1, 0.5)
        };
        let (sp, _) = s.update(&baro_lost);
        assert!(sp.vel_ned_m_s.xy() == nalgebra::Vector2::zeros() && sp.pos_ned_m.x.is_nan());
        s.update(&input(3.5, -2.2, 0.0)); // valid again: still descending
        assert_eq!(s.phase(), Phase::Descend);
        s.update(&lost(4.0, -2.0, 0.05)); // passing through zero speed is not touchdown
        s.update(&lost(4.5, -1.7, 0.7));
        assert_eq!(s.phase(), Phase::Descend);
        for t in [7.0, 7.5, 7.9] {
            s.update(&lost(t, 0.0, 0.02));
            assert_eq!(s.phase(), Phase::Descend, "at {t}");
        }
        let (_, armed) = s.update(&lost(8.05, 0.0, 0.0));
        assert!(!armed && s.phase() == Phase::Done);
    }

    #[test]
    fn the_takeoff_set_point_climbs_smoothly_and_stops_at_the_altitude() {
        let mut s = FlightSequence::new(params());
        s.update(&input(0.0, 0.0, 0.0));
        let dt = 0.004;
        s.update(&input(1.0, 0.0, 0.0));
        assert_eq!(s.phase(), Phase::Takeoff);
        let (mut t, mut last_up, mut last_v) = (1.0 + dt, 0.0f64, 0.0f64);
        while t < 9.0 {
            // The vehicle is where the set-point was a step ago.
            let (sp, _) = s.update(&input(t, -last_up, -last_v));
            if s.phase() == Phase::Hover {
                break;
            }
            let (up, v) = (-sp.pos_ned_m.z, -sp.vel_ned_m_s.z);
            assert!(
                up >= last_up - 1e-12 && up <= 5.0 + 1e-12,
                "monotonic, bounded"
            );
            assert!(v <= 1.5 + 1e-12, "climb speed limited: {v}");
            assert!(
                (v - last_v).abs() <= 1.02 * dt,
                "acceleration limited at t = {t}: {last_v} → {v}"
            );
            (last_up, last_v) = (up, v);
            t += dt;
        }
        assert_eq!(s.phase(), Phase::Hover);
        // 5 m at 1.5 m/s with 1 m/s² ramps at both ends: 5/1.5 + 1.5 = 4.83 s after take-off.
        assert!((t - 1.0 - 4.83).abs() < 0.05, "arrived after {} s", t - 1.0);
    }
}
