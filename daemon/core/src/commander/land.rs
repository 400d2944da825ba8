//! Land: descend where it is (slower for the last metres, `MPC_LAND_CRWL` below
//! `MPC_LAND_ALT3`), touchdown after standing still for a second, disarm. The same descent
//! ends a return and a mission's Land item.

use super::flight::{Flight, MAYBE_LANDED_S, Tick, Touchdown};
use super::task::FlightTask;
use crate::commander::CommanderInput;
use crate::control::Setpoint;
use crate::control::position::PositionSetpoint;
use nalgebra::Vector3;

/// A landing descent over a point.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(super) struct Landing {
    /// Where it comes down (north, east; m): where it was at the first step unless given.
    xy: Option<(f64, f64)>,
    /// The descending set-point's down (m).
    down: Option<f64>,
    /// The vehicle has come down at half the speed asked since the landing began: a stop now
    /// is the ground (PX4's `hit_ground`), not the top of a climb turning into the descent.
    descended: bool,
    touchdown: Touchdown,
}

/// The thrust below which a still vehicle is on the ground, as a fraction of the hover's.
const LOW_THRUST: f64 = 0.6;

impl Landing {
    /// A landing over `north_east_m`.
    pub(super) fn over(north_east_m: (f64, f64)) -> Self {
        Self {
            xy: Some(north_east_m),
            ..Self::default()
        }
    }

    /// One step: the set-point goes down steadily (slower near the ground); touchdown when
    /// the vehicle, having come down, has stopped moving down for a second while the set-point
    /// is well below it (it cannot go lower).
    pub(super) fn step(
        &mut self,
        f: &mut Flight,
        i: &CommanderInput,
        dt: f64,
        yaw: f64,
    ) -> PositionSetpoint {
        let p = f.params;
        f.land.landing();
        let (x, y) = *self.xy.get_or_insert((i.pos_ned_m.x, i.pos_ned_m.y));
        let ground = f.home.map_or(i.pos_ned_m.z, |h| h.0.z);
        let height = ground - i.pos_ned_m.z;
        let speed = if height > p.final_height_m {
            p.land_speed_m_s
        } else {
            p.final_speed_m_s
        };
        let down = self.down.get_or_insert(i.pos_ned_m.z);
        *down = (*down + speed * dt).min(i.pos_ned_m.z + 1.0);
        let down = *down;
        // A quad spinning on three rotors wobbles on its legs, its vertical speed never quite
        // still, and on the ground only its motors and its spin can tip it over: it is down
        // when it stops coming down, and its thrust is cut at once.
        let (still_m_s, maybe_landed_s) = if i.health.spinning {
            (0.3, 0.0)
        } else {
            (0.15, MAYBE_LANDED_S)
        };
        self.descended |= i.vel_ned_m_s.z > 0.5 * speed;
        // Stopped by the estimate (its vertical speed), or by the IMU alone whatever the
        // estimate says: still, with the thrust well below a hover's (PX4's low-thrust test).
        // A steady descent is still to an IMU too, but it takes a hover's thrust.
        let imu_stopped = i.imu_still && i.thrust < LOW_THRUST * i.hover_thrust;
        let stopped = self.descended
            && (i.vel_ned_m_s.z.abs() < still_m_s || imu_stopped)
            && down - i.pos_ned_m.z > 0.5;
        self.touchdown
            .check_staged(f, stopped, i.t_s, maybe_landed_s);
        PositionSetpoint {
            pos_ned_m: Vector3::new(x, y, down),
            vel_ned_m_s: Vector3::new(0.0, 0.0, speed),
            accel_ned_m_s2: Vector3::zeros(),
            yaw_rad: yaw,
        }
    }
}

/// Land mode.
#[derive(Debug, Clone, PartialEq, Default)]
pub(super) struct Land {
    landing: Landing,
}

impl FlightTask for Land {
    fn update(&mut self, f: &mut Flight, t: &Tick) -> Setpoint {
        Setpoint::Position(self.landing.step(f, t.i, t.dt, t.yaw))
    }
}
