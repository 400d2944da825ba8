//! What happens to the simulated vehicle at scheduled times: faults, disturbances, a hand that
//! tumbles it (scenario events and fault injection).

use super::{SimError, Simulator};
use crate::environment::Gust;
use crate::sensors::{SensorHealth, SensorKind};
use nalgebra::{UnitQuaternion, Vector3};

/// Something that happens at a scheduled simulation time (scenario events, fault injection).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SimAction {
    /// Motor `index` (0-based) stops turning.
    MotorFail {
        /// Rotor index.
        index: usize,
    },
    /// Motor `index` keeps turning but its propeller makes only `effectiveness` of nominal thrust.
    MotorEffectiveness {
        /// Rotor index.
        index: usize,
        /// Fraction of nominal thrust and torque, 0–1.
        effectiveness: f64,
    },
    /// Motor `index` works normally again.
    MotorRestore {
        /// Rotor index.
        index: usize,
    },
    /// A sensor goes off, sticks, or recovers.
    Sensor {
        /// Which sensor.
        sensor: SensorKind,
        /// Its new state.
        health: SensorHealth,
    },
    /// The GPS loses (true) or regains (false) its fix.
    GpsFixLost(bool),
    /// An extra magnetic field appears (NED, gauss); zero removes it.
    MagDisturbance(Vector3<f64>),
    /// A force in NED (N) acts for a while.
    ForcePulse {
        /// Force, NED (N).
        force_ned_n: Vector3<f64>,
        /// Length (s).
        duration_s: f64,
    },
    /// A torque in FRD (N·m) acts for a while.
    TorquePulse {
        /// Torque, FRD (N·m).
        torque_frd_n_m: Vector3<f64>,
        /// Length (s).
        duration_s: f64,
    },
    /// A 1 − cos gust.
    Gust {
        /// Peak air velocity, NED (m/s).
        peak_ned_m_s: Vector3<f64>,
        /// Length (s).
        duration_s: f64,
    },
    /// The mean wind and turbulence change.
    Wind {
        /// Mean wind, NED (m/s).
        mean_ned_m_s: Vector3<f64>,
        /// Turbulence intensity W20 (m/s).
        turbulence_w20_m_s: f64,
    },
    /// The vehicle is picked up and turned by hand through every orientation for `duration_s`
    /// (a magnetometer calibration's dance), then set down level over [`SET_DOWN_S`]; a new
    /// tumble replaces one under way (0: set it down now). The built-in rigid body only (an
    /// external one, such as JSBSim's, keeps its own motion).
    Tumble {
        /// Length (s).
        duration_s: f64,
    },
}

/// How long a tumble's hand takes to speed up and to slow down (s).
pub const TUMBLE_RAMP_S: f64 = 2.0;
/// How long setting the vehicle down level after a tumble takes (s).
pub const SET_DOWN_S: f64 = 2.0;

/// The hand's turns during an [`SimAction::Tumble`] of `duration_s`, `t` seconds in, from the
/// attitude it was picked up in: Euler angles growing at incommensurate rates (0.9, 0.37,
/// 0.23 rad/s of roll, pitch and yaw), so that the body sweeps every orientation within about
/// a minute, no faster than a person turns it; the rates rise from and fall to rest smoothly
/// over [`TUMBLE_RAMP_S`] (a hand, not a step: the IMU's lever arm feels no jolt).
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

/// A tumble under way.
#[derive(Debug, Clone, Copy)]
pub(super) struct Tumble {
    pub(super) start_s: f64,
    pub(super) duration_s: f64,
    /// The attitude when picked up (the dance starts from it).
    pub(super) q0: UnitQuaternion<f64>,
}

/// A scheduled action.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Event {
    /// When (s of simulation time).
    pub t_s: f64,
    /// What.
    pub action: SimAction,
}

#[derive(Debug, Clone, Copy)]
/// A force or torque applied for a while (an [`SimAction::ForcePulse`] or [`SimAction::TorquePulse`]).
pub(super) struct Pulse {
    pub(super) until_s: f64,
    pub(super) force_ned_n: Vector3<f64>,
    pub(super) torque_frd_n_m: Vector3<f64>,
}

impl Simulator {
    /// Schedules events (1-based motor numbers are already converted to indices).
    pub fn schedule(&mut self, events: &[Event]) -> Result<(), SimError> {
        for e in events {
            if let SimAction::MotorFail { index }
            | SimAction::MotorEffectiveness { index, .. }
            | SimAction::MotorRestore { index } = e.action
                && index >= self.rotors.len()
            {
                return Err(SimError::Motor {
                    t_s: e.t_s,
                    motor: index + 1,
                    count: self.rotors.len(),
                });
            }
            self.events.push(*e);
        }
        // Latest first, so due events pop off the end; stable for equal times.
        self.events.sort_by(|a, b| b.t_s.total_cmp(&a.t_s));
        Ok(())
    }

    /// Applies an action now.
    pub fn apply(&mut self, action: SimAction) {
        let t = self.time_s();
        match action {
            SimAction::MotorFail { index } => {
                if let Some(f) = self.rotors.faults.get_mut(index) {
                    f.failed = true;
                }
            }
            SimAction::MotorEffectiveness {
                index,
                effectiveness,
            } => {
                if let Some(f) = self.rotors.faults.get_mut(index) {
                    f.effectiveness = effectiveness.clamp(0.0, 1.0);
                }
            }
            SimAction::MotorRestore { index } => {
                if let Some(f) = self.rotors.faults.get_mut(index) {
                    *f = Default::default();
                }
            }
            SimAction::Sensor { sensor, health } => self.sensors.set_health(sensor, health),
            SimAction::GpsFixLost(lost) => self.sensors.gps_fix_lost = lost,
            SimAction::MagDisturbance(field) => self.sensors.mag_disturbance_ned = field,
            SimAction::ForcePulse {
                force_ned_n,
                duration_s,
            } => self.pulses.push(Pulse {
                until_s: t + duration_s,
                force_ned_n,
                torque_frd_n_m: Vector3::zeros(),
            }),
            SimAction::TorquePulse {
                torque_frd_n_m,
                duration_s,
            } => self.pulses.push(Pulse {
                until_s: t + duration_s,
                force_ned_n: Vector3::zeros(),
                torque_frd_n_m,
            }),
            SimAction::Gust {
                peak_ned_m_s,
                duration_s,
            } => self.wind.add_gust(Gust {
                start_s: t,
                duration_s,
                peak_ned_m_s,
            }),
            SimAction::Wind {
                mean_ned_m_s,
                turbulence_w20_m_s,
            } => {
                self.wind.mean_ned_m_s = mean_ned_m_s;
                self.wind.set_turbulence(turbulence_w20_m_s);
            }
            SimAction::Tumble { duration_s } => {
                self.tumble = Some(Tumble {
                    start_s: t,
                    duration_s: duration_s.max(0.0),
                    q0: self.body.q_ned_from_frd,
                });
            }
        }
    }
}
