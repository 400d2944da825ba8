//! The subcommands beside flying: `autopilot batch` (Monte-Carlo runs in the embedded
//! simulator), `autopilot replay` (the attitude estimator over a log) and
//! `autopilot calibrate-mag` (the magnetometer's calibration from a log).

pub mod batch;
pub mod mag_cal;
pub mod replay;

use crate::cli::{BatchAction, BatchArgs};
use crate::settings::{self, HOVER_RANGE_S, TAKEOFF_RANGE_M, in_range};
use anyhow::{Context, Result};
use batch::shard::Shard;

/// `autopilot batch`: its flags checked, then the batch (or the shard of it) flown; or the
/// shards merged.
pub fn run_batch(args: &BatchArgs) -> Result<()> {
    if let Some(BatchAction::Merge { shards, output }) = &args.action {
        return batch::merge::merge(shards, output.as_deref());
    }
    let shard = match (&args.shard, args.shard_count) {
        (Some(s), _) => Shard::parse(s).context("--shard")?,
        (None, Some(n)) => Shard::from_cluster(n, |v| std::env::var(v).ok())?,
        (None, None) => Shard::WHOLE,
    };
    let output = batch::output_path(
        args.output.as_deref(),
        &batch::default_name(args.seed, shard),
    )?;
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
        shard,
        &settings::airframe_path(&args.airframe, &dir),
        &settings::params_path(args.params.as_deref(), &dir),
        args.jobs.unwrap_or_else(batch::default_jobs),
        &output,
    )
}
