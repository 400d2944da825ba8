//! The subcommands beside flying: `autopilot batch` (Monte-Carlo runs in the embedded
//! simulator), `autopilot replay` (the attitude estimator over a log) and
//! `autopilot calibrate-mag` (the magnetometer's calibration from a log).

pub mod batch;
pub mod mag_cal;
pub mod replay;

use crate::cli::BatchArgs;
use crate::settings::{self, HOVER_RANGE_S, TAKEOFF_RANGE_M, in_range};
use anyhow::{Context, Result};

/// `autopilot batch`: its flags checked, then the batch flown.
pub fn run_batch(args: &BatchArgs) -> Result<()> {
    let dir = airframe::config::params_dir(args.params_dir.as_deref());
    let sensors = &args.sensors;
    let cfg = batch::BatchConfig {
        runs: args.runs,
        first: args.first,
        seed: args.seed,
        takeoff_m: in_range(args.takeoff, &TAKEOFF_RANGE_M, "m")
            .map_err(|e| anyhow::anyhow!("--takeoff: {e}"))?,
        hover_s: in_range(args.hover, &HOVER_RANGE_S, "s")
            .map_err(|e| anyhow::anyhow!("--hover: {e}"))?,
        wind_max_m_s: args.wind_max,
        turbulence_max_m_s: args.turbulence_max,
        faults: args
            .faults
            .iter()
            .map(|f| batch::FaultKind::from_name(f.trim()))
            .collect::<Result<_>>()
            .context("--faults")?,
        sensors: settings::sensor_preset(sensors)?,
    };
    batch::run(
        &cfg,
        &settings::airframe_path(&args.airframe, &dir),
        &settings::params_path(args.params.as_deref(), &dir),
        args.jobs.unwrap_or_else(batch::default_jobs),
        &args
            .output
            .clone()
            .unwrap_or_else(|| batch::default_output(args.seed)),
    )
}
