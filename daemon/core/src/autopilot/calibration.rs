//! The autopilot's onboard calibrations: one at a time, disarmed; fed the raw
//! readings every step; what each needs of the person holding the vehicle.

use super::Autopilot;
use crate::commander::Denial;
use crate::sample::SensorSample;
use crate::sensors::imu_calibrator::{
    ImuCalKind, ImuCalState, ImuCalStatus, ImuCalibrator, PoseRequest,
};
use crate::sensors::mag_calibrator::{MagCalState, MagCalStatus, MagCalibrator};

/// Calibrations started in this process: each run's number, unique across the autopilots a
/// reboot or a restarted source makes, so the ground-station side never takes a new run for
/// one it has reported.
static CALIBRATION_RUNS: std::sync::atomic::AtomicU32 = std::sync::atomic::AtomicU32::new(0);

fn next_run() -> u32 {
    CALIBRATION_RUNS.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1
}

/// Logs how a magnetometer calibration ended, if it has.
fn log_mag_end(s: &MagCalStatus) {
    match s.state {
        MagCalState::Collecting | MagCalState::Cancelled => {}
        MagCalState::Succeeded(r) => tracing::info!(
            samples = r.samples,
            coverage = r.coverage,
            residual = format!("{:.2} %", 100.0 * r.residual_rms),
            offset = ?r.offset.as_slice(),
            "magnetometer calibration done"
        ),
        MagCalState::Failed(f) => tracing::warn!("magnetometer calibration failed: {f}"),
    }
}

/// Logs how an IMU calibration ended, if it has.
fn log_imu_end(s: &ImuCalStatus) {
    let kind = s.kind.name();
    match s.state {
        ImuCalState::Collecting | ImuCalState::Cancelled => {}
        ImuCalState::Succeeded(r) => tracing::info!(result = ?r, "{kind} calibration done"),
        ImuCalState::Failed(f) => tracing::warn!("{kind} calibration failed: {f}"),
    }
}

impl Autopilot {
    /// The calibration collecting now, by the name PX4's texts give it.
    pub(super) fn calibrating(&self) -> Option<&'static str> {
        if self.mag_cal.as_ref().is_some_and(MagCalibrator::collecting) {
            return Some("magnetometer");
        }
        if self.calibrating_radio() {
            return Some("radio");
        }
        self.imu_cal
            .as_ref()
            .filter(|c| c.collecting())
            .map(|c| match c.status().kind {
                ImuCalKind::Gyro => "gyro",
                ImuCalKind::Accel => "accelerometer",
                ImuCalKind::Level => "level horizon",
            })
    }

    /// Refused armed, or while another calibration runs.
    pub(super) fn may_calibrate(&self) -> Result<(), Denial> {
        if self.commander.status().armed {
            return Err(Denial::CalibrationArmed);
        }
        if let Some(kind) = self.calibrating() {
            return Err(Denial::CalibrationRunning(kind));
        }
        Ok(())
    }

    /// Starts a magnetometer calibration.
    pub(super) fn start_mag_calibration(&mut self) -> Result<(), Denial> {
        self.may_calibrate()?;
        let run = next_run();
        let strength = self.params.attitude.mag_intensity_gauss;
        self.mag_cal = Some(MagCalibrator::new(run, strength));
        tracing::info!(
            run,
            "magnetometer calibration started: turn the vehicle through every orientation"
        );
        Ok(())
    }

    /// Starts a gyro, accelerometer or level-horizon calibration.
    pub(super) fn start_imu_calibration(&mut self, kind: ImuCalKind) -> Result<(), Denial> {
        self.may_calibrate()?;
        let run = next_run();
        self.imu_cal = Some(ImuCalibrator::new(kind, run, &self.params.imu));
        tracing::info!(run, "{} calibration started", kind.name());
        Ok(())
    }

    /// Cancels the calibration under way, if any.
    pub(super) fn cancel_calibration(&mut self) {
        if let Some(cal) = self.mag_cal.as_mut().filter(|c| c.collecting()) {
            cal.cancel();
            tracing::warn!("magnetometer calibration cancelled");
        }
        if let Some(cal) = self.imu_cal.as_mut().filter(|c| c.collecting()) {
            cal.cancel();
            tracing::warn!("{} calibration cancelled", cal.status().kind.name());
        }
    }

    /// Feeds the raw sample to the calibration collecting, if any.
    pub(super) fn step_calibrations(&mut self, t_s: f64, raw: &SensorSample) {
        if let Some(cal) = self.mag_cal.as_mut().filter(|c| c.collecting()) {
            cal.step(t_s, raw.mag);
            log_mag_end(&cal.status());
        }
        if let Some(cal) = self.imu_cal.as_mut().filter(|c| c.collecting()) {
            cal.step(t_s, &raw.accel, &raw.gyro);
            log_imu_end(&cal.status());
        }
    }

    /// The calibrations end when the sensor frames stop (or go back in time).
    pub(super) fn end_calibrations(&mut self) {
        if let Some(c) = self.mag_cal.as_mut() {
            c.cancel();
        }
        if let Some(c) = self.imu_cal.as_mut()
            && c.sensors_stopped()
        {
            log_imu_end(&c.status());
        }
    }

    /// What the calibration under way needs of the person holding the vehicle.
    pub fn pose_request(&self) -> PoseRequest {
        if self.mag_cal.as_ref().is_some_and(MagCalibrator::collecting) {
            return PoseRequest::Tumble;
        }
        self.imu_cal
            .as_ref()
            .map_or(PoseRequest::None, ImuCalibrator::pose_request)
    }
}
