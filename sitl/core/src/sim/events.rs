//! What happens to the simulated vehicle at scheduled times: faults, disturbances, a hand that
//! tumbles it (scenario events and fault injection).

use super::hand::{Face, Hand};
use super::{SimError, Simulator};
use crate::environment::Gust;
use crate::sensors::{SensorHealth, SensorKind};
use nalgebra::Vector3;

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
    /// external one, such as JSBSim's, keeps its own motion), as for the other moves of the hand.
    Tumble {
        /// Length (s).
        duration_s: f64,
    },
    /// The hand places the vehicle with `face` down (heading kept) and holds it there still
    /// (an accelerometer calibration's sides).
    Place {
        /// The face put on the ground.
        face: Face,
    },
    /// The hand sets the vehicle down level where it is and lets go (nothing if it holds
    /// nothing).
    SetDown,
    /// Whether the hand does what the autopilot's calibrations ask (`SIM_CAL_HAND`); off, it
    /// sets down what it holds.
    CalibrationHand(bool),
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
                self.hand = Some(Hand::Tumble {
                    start_s: t,
                    duration_s: duration_s.max(0.0),
                    q0: self.body.q_ned_from_frd,
                });
            }
            SimAction::Place { face } => self.place(face),
            SimAction::SetDown => self.set_down(),
            SimAction::CalibrationHand(on) => {
                self.calibration_hand = on;
                if !on {
                    // Off with the vehicle in hand: set down, not held for ever.
                    self.set_down();
                }
            }
        }
    }
}
