//! The subcommands beside flying: `autopilot batch` (Monte-Carlo runs in the embedded
//! simulator), `autopilot replay` (the attitude estimator over a log) and
//! `autopilot calibrate-mag` (the magnetometer's calibration from a log).

pub mod batch;
pub mod mag_cal;
pub mod replay;
