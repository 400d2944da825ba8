//! The sensors before the estimators: which are lost or frozen, the battery's state of charge,
//! the IMU's calibrations and their correction, and the magnetometer's checks and calibration.

pub mod battery;
pub mod imu_calibrator;
pub mod imu_correction;
pub mod mag_calibrator;
pub mod mag_check;
pub mod mag_fit;
pub mod monitor;
