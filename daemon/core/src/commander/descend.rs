//! Descend (a failsafe): when the estimate stops being fit to fly on, level and descend at
//! `MPC_LAND_SPEED` on what estimate is left — braking to zero ground speed while the
//! horizontal estimate holds — until touchdown. It is left only by landing.

use super::flight::{Flight, Tick, Touchdown};
use super::task::FlightTask;
use crate::control::Setpoint;
use crate::control::position::PositionSetpoint;
use nalgebra::Vector3;

/// The failsafe descent.
#[derive(Debug, Clone, PartialEq, Default)]
pub(super) struct Descend {
    /// When it began (s).
    since_s: f64,
    touchdown: Touchdown,
}

impl FlightTask for Descend {
    fn activate(&mut self, t_s: f64) {
        self.since_s = t_s;
    }

    fn update(&mut self, f: &mut Flight, t: &Tick) -> Setpoint {
        let i = t.i;
        f.land.landing();
        // Touchdown when the vertical speed has stayed near zero for a second.
        let stopped = i.t_s - self.since_s > 1.0 && i.vel_ned_m_s.z.abs() < 0.15;
        self.touchdown.check(f, stopped, i.t_s);
        // Level (horizontal velocity uncontrolled) without a horizontal estimate.
        let h = if i.horizontal_valid { 0.0 } else { f64::NAN };
        Setpoint::Position(PositionSetpoint {
            pos_ned_m: Vector3::repeat(f64::NAN),
            vel_ned_m_s: Vector3::new(h, h, f.params.land_speed_m_s),
            accel_ned_m_s2: Vector3::zeros(),
            yaw_rad: t.yaw,
        })
    }
}
