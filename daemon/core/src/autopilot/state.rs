//! The vehicle as one value: what the ground stations, the status line and the records read
//! after a step (as a PX4 topic is published once a step), instead of asking the autopilot.

use super::Autopilot;
use crate::commander::CommanderStatus;
use crate::control::Setpoint;
use crate::estimator::translation::GpsMeasurement;
use crate::sample::{SensorSample, StepOutput};
use crate::sensors::battery::BatteryState;
use crate::sensors::imu_calibrator::{ImuCalStatus, ImuCalibrator};
use crate::sensors::mag_calibrator::{MagCalStatus, MagCalibrator};

/// The vehicle after its last step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VehicleState {
    /// The commander's state (the step's, or a command's since).
    pub status: CommanderStatus,
    /// The flight core's last output.
    pub estimate: Option<StepOutput>,
    /// The last sample flown: calibrated, with the magnetometer and barometer held as last
    /// seen (a sample carries them only when fresh). The logs record the raw sample, as
    /// [`super::Autopilot::step_in_place`] leaves it.
    pub held_sample: Option<SensorSample>,
    /// The set-point flown (armed only).
    pub setpoint: Option<Setpoint>,
    /// The last GPS solution received.
    pub gps: Option<GpsMeasurement>,
    /// The battery voltage (V): the board's report, else the pack's nominal voltage.
    pub battery_v: f64,
    /// The battery as estimated from the board's (or simulator's) reports.
    pub battery: BatteryState,
    /// The magnetometer calibration under way, or the last one.
    pub mag_cal: Option<MagCalStatus>,
    /// The gyro, accelerometer or level-horizon calibration under way, or the last one.
    pub imu_cal: Option<ImuCalStatus>,
    /// Times the sensor source started again from an earlier time.
    pub source_restarts: u32,
    /// How many rotors the airframe has.
    pub rotors: usize,
    /// The largest collective thrust (N): what `ATTITUDE_TARGET`'s thrust is a fraction of.
    pub max_thrust_n: f64,
    /// The RC receiver's last frame.
    pub rc: Option<super::rc::RcReport>,
}

impl Autopilot {
    /// The vehicle now: after the last step, and the commands since.
    pub fn state(&self) -> &VehicleState {
        &self.published
    }

    /// Brings what the published state computes up to date: the commander's state, the
    /// battery, the calibrations, the airframe's figures. Called at the end of every step and
    /// of whatever else changes them (commands, the sensors stopping or coming back).
    pub(super) fn publish(&mut self) {
        self.published.status = self.commander.status();
        self.publish_besides_status();
    }

    /// [`Autopilot::publish`] but for the commander's state (published by the caller).
    pub(super) fn publish_besides_status(&mut self) {
        let p = &mut self.published;
        p.battery = self.battery.state();
        p.mag_cal = self.mag_cal.as_ref().map(MagCalibrator::status);
        p.imu_cal = self.imu_cal.as_ref().map(ImuCalibrator::status);
        p.max_thrust_n = self.core.config().position.max_thrust_n;
    }
}
