//! `autopilot batch`: Monte-Carlo runs of the take-off, hover and landing in the embedded
//! simulator, over seeds, wind and faults, on every core, into one CSV of flight-quality figures.
//!
//! Run `i` of a batch draws everything it varies from the random stream `(seed, i)` alone
//! ([`RunPlan::draw`]), so a batch gives the same rows whatever the number of workers and
//! whichever finishes first, and one run can be flown again from its row (`--seed`, `--first`).

use crate::control_loop::{self, LoopCommand, Onboard, Pacing, Ports};
use crate::links::frames::Received;
use crate::links::sim::EmbeddedSim;
use crate::links::{SensorLink, Source};
use crate::records::FlightRecords;
use anyhow::{Context, Result, bail};
use flight_core::autopilot::{AutoFlight, Autopilot};
use flight_core::params::FlightParams;
use sitl_core::Airframe;
use sitl_core::sensors::SensorPreset;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};
use tokio::sync::mpsc;

pub mod manifest;
pub mod merge;
mod plan;
mod progress;
pub mod shard;
pub mod summary;

use manifest::{Campaign, Manifest, Version};
pub use plan::{FaultKind, RunPlan};
use progress::Progress;
use shard::Shard;
use summary::BatchSummary;

/// What a batch varies and over what ranges.
#[derive(Debug, Clone)]
pub struct BatchConfig {
    /// Runs to fly.
    pub runs: u32,
    /// The first run's number (to fly again part of a batch).
    pub first: u32,
    /// The batch's seed: run `i` draws from the stream `(seed, i)`.
    pub seed: u64,
    /// Take-off height (m) and hover time (s) of every flight.
    pub takeoff_m: f64,
    /// Hover time (s).
    pub hover_s: f64,
    /// Largest mean wind (m/s): each run's is drawn uniformly from 0 to this, from any direction.
    pub wind_max_m_s: f64,
    /// Largest Dryden turbulence intensity W20 (m/s), drawn likewise.
    pub turbulence_max_m_s: f64,
    /// The faults a run's one is drawn from, uniformly.
    pub faults: Vec<FaultKind>,
    /// Sensor quality.
    pub sensors: SensorPreset,
}

impl BatchConfig {
    /// Refuses a batch without runs or faults, a wind or turbulence out of range, run numbers
    /// past the last.
    fn check(&self) -> Result<()> {
        if self.runs == 0 || self.faults.is_empty() {
            bail!("a batch needs at least one run and one fault kind (none is one)");
        }
        for (name, x, max) in [
            ("--wind-max", self.wind_max_m_s, 30.0),
            ("--turbulence-max", self.turbulence_max_m_s, 30.0),
        ] {
            if !(x.is_finite() && (0.0..=max).contains(&x)) {
                bail!("{name} must be within [0, {max}] m/s, got {x}");
            }
        }
        if self.first.checked_add(self.runs).is_none() {
            bail!(
                "--first {} and --runs {}: run numbers end at {}",
                self.first,
                self.runs,
                u32::MAX - 1
            );
        }
        Ok(())
    }
}

/// The campaign's CSV at `output`, its header written; a manifest left at `manifest_path` by a
/// batch before (which would vouch for it) removed first.
fn start_csv(
    output: &Path,
    manifest_path: &Path,
) -> Result<csv::Writer<std::io::BufWriter<std::fs::File>>> {
    match std::fs::remove_file(manifest_path) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
            Err(e).with_context(|| format!("removing {}", manifest_path.display()))?
        }
        _ => {}
    }
    let file =
        std::fs::File::create(output).with_context(|| format!("creating {}", output.display()))?;
    let mut csv = csv::Writer::from_writer(std::io::BufWriter::new(file));
    csv.write_record(CSV_HEADER.split(','))?;
    csv.flush()?;
    Ok(csv)
}

/// The batch's summary: the faults' table and one line; an error if runs could not be flown.
fn say_done(manifest: &Manifest, rows: usize, output: &Path, manifest_path: &Path) -> Result<()> {
    manifest.summary.print_faults();
    println!(
        "batch summary: {} shard={} jobs={} wall_time_s={:.2} runs_per_s={:.2} csv={} manifest={}",
        manifest.summary.total,
        manifest.shard,
        manifest.jobs,
        manifest.wall_time_s,
        rows as f64 / manifest.wall_time_s.max(1e-9),
        output.display(),
        manifest_path.display()
    );
    let errors = manifest.summary.total.errors;
    if errors > 0 {
        bail!("{errors} of {rows} runs could not be flown");
    }
    Ok(())
}

/// Faster than this at the ground (m/s) is a crash, not a landing: a fall from over half a metre.
pub const CRASH_IMPACT_M_S: f64 = 3.0;
/// Tilted more than this at the end (deg) is a vehicle on its side or back.
pub const CRASH_TILT_DEG: f64 = 60.0;

/// How a run ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Outcome {
    /// On the ground, disarmed, upright, no faster than [`CRASH_IMPACT_M_S`] at the ground.
    Landed,
    /// It hit the ground faster than that, or lies on its side or back.
    Crashed,
    /// Still armed or off the ground when its time was up.
    NotLanded,
    /// The run could not be flown.
    Error,
}

impl Outcome {
    /// How `flight` ended.
    pub fn of(flight: &Result<control_loop::FlightReport>) -> Self {
        let Ok(f) = flight else {
            return Outcome::Error;
        };
        let s = f.score();
        if s.impact_m_s > CRASH_IMPACT_M_S || s.tilt_deg > CRASH_TILT_DEG {
            Outcome::Crashed
        } else if f.landed() {
            Outcome::Landed
        } else {
            Outcome::NotLanded
        }
    }

    /// Its name in the CSV.
    pub fn name(self) -> &'static str {
        match self {
            Outcome::Landed => "landed",
            Outcome::Crashed => "crashed",
            Outcome::NotLanded => "not_landed",
            Outcome::Error => "error",
        }
    }
}

/// One run's figures, or why it could not be flown.
#[derive(Debug)]
pub struct RunResult {
    /// What was flown.
    pub plan: RunPlan,
    /// Its report.
    pub flight: Result<control_loop::FlightReport>,
}

/// The simulator of a run, which stops the flight once its time is up (a vehicle that never
/// comes to rest: upside down, a rotor short).
struct TimeLimited {
    sim: EmbeddedSim,
    limit_s: f64,
    stop: mpsc::Sender<LoopCommand>,
    stopped: bool,
}

impl SensorLink for TimeLimited {
    fn receive(&mut self, timeout: Duration, into: &mut Received) -> std::io::Result<bool> {
        if !self.stopped && self.sim.time_s() >= self.limit_s {
            self.stopped = true;
            // Drained before the next step.
            let _ = self.stop.try_send(LoopCommand::Stop);
        }
        self.sim.receive(timeout, into)
    }

    fn send(&mut self, command: &hil::ActuatorCommand) -> std::io::Result<()> {
        self.sim.send(command)
    }

    fn describe(&self) -> String {
        self.sim.describe()
    }

    fn silence_clock_s(&self) -> Option<f64> {
        None
    }
}

impl BatchConfig {
    /// Simulated time after which a run is stopped wherever it is: the flight's own length
    /// (the climb, the hover, the descent at 0.3 m/s) and a minute.
    pub fn time_limit_s(&self) -> f64 {
        3.5 + self.takeoff_m / 1.5 + self.hover_s + self.takeoff_m / 0.3 + 60.0
    }
}

/// Flies one run: the take-off, hover and landing of `airframe` with `params`, lockstep as fast
/// as it goes, no ground station, no logs; stopped at [`BatchConfig::time_limit_s`].
pub fn fly_run(
    cfg: &BatchConfig,
    airframe: &Airframe,
    params: &FlightParams,
    plan: RunPlan,
) -> RunResult {
    let flight = (|| {
        let auto = AutoFlight {
            takeoff_m: cfg.takeoff_m,
            hover_s: cfg.hover_s,
        };
        let mut autopilot = Autopilot::new(airframe, params, Some(auto))?;
        let mut records = FlightRecords::new(cfg.takeoff_m);
        let sim =
            EmbeddedSim::with_world(airframe, plan.world(cfg.sensors), &plan.events, None, None)?;
        let (mut ports, ends) = Ports::new(1);
        let stop = ends.commands;
        let mut link = TimeLimited {
            sim,
            limit_s: cfg.time_limit_s(),
            stop,
            stopped: false,
        };
        control_loop::fly(
            Onboard {
                link: &mut link,
                autopilot: &mut autopilot,
                records: &mut records,
                ports: &mut ports,
            },
            Pacing::Lockstep,
        )
    })();
    RunResult { plan, flight }
}

/// The CSV's columns, one row per run.
pub const CSV_HEADER: &str = "run,sim_seed,wind_m_s,wind_from_deg,turbulence_w20_m_s,fault,fault_t_s,fault_detail,outcome,failsafe,max_alt_m,hover_alt_rms_m,hover_drift_rms_m,attitude_rms_deg,max_tilt_deg,final_tilt_deg,max_distance_m,landing_distance_m,touchdown_m_s,impact_m_s,sensor_timeouts,sim_time_s,error";

/// A run as the CSV's cells (the `csv` writer quotes what needs quoting).
pub fn csv_row(r: &RunResult) -> Vec<String> {
    let p = &r.plan;
    let opt = |x: Option<f64>| x.map_or(String::new(), |x| format!("{x:.4}"));
    let mut cells = vec![
        p.run.to_string(),
        p.sim_seed.to_string(),
        format!("{:.3}", p.wind_m_s),
        format!("{:.1}", p.wind_from_deg),
        format!("{:.3}", p.turbulence_m_s),
        p.fault.name().to_string(),
        p.fault_t_s.map_or(String::new(), |t| format!("{t:.3}")),
        p.fault_detail.clone(),
    ];
    match &r.flight {
        Ok(f) => {
            let s = f.score();
            cells.extend([
                Outcome::of(&r.flight).name().to_string(),
                s.failsafe.to_string(),
                format!("{:.4}", s.max_height_m),
                opt(s.hover_alt_rms_m()),
                opt(s.hover_drift_rms_m()),
                opt(s.attitude_rms_deg()),
                format!("{:.3}", s.max_tilt_deg),
                format!("{:.3}", s.tilt_deg),
                format!("{:.4}", s.max_distance_m),
                format!("{:.4}", s.distance_m),
                format!("{:.4}", s.touchdown_m_s),
                format!("{:.4}", s.impact_m_s),
                f.sensor_timeouts().to_string(),
                format!("{:.3}", f.sim_time_s()),
                String::new(),
            ]);
        }
        Err(e) => {
            cells.push("error".into());
            cells.extend(std::iter::repeat_n(String::new(), 13));
            cells.push(format!("{e:#}"));
        }
    }
    cells
}

/// Runs `shard` of the batch on `jobs` threads into the CSV `output`, each row written as soon
/// as the runs before it are (rows in run order whatever the workers, so an interrupted batch
/// keeps the runs done); then the manifest beside it ([`Manifest::path_of`]) and a summary.
/// Fails if a run could not be flown.
pub fn run(
    cfg: &BatchConfig,
    shard: Shard,
    airframe_path: &Path,
    params_path: &Path,
    jobs: usize,
    output: &Path,
) -> Result<()> {
    cfg.check()?;
    refuse_json(output)?;
    let airframe = Airframe::load(airframe_path)?;
    let campaign = Campaign::new(cfg, &airframe.name, airframe_path, params_path)?;
    let mut params = FlightParams::load(params_path)?;
    Source::Embedded.preset_params(&mut params);
    params.commander.takeoff_alt_m = cfg.takeoff_m;
    let manifest_path = Manifest::path_of(output);
    let mut csv = start_csv(output, &manifest_path)?;
    let runs: Vec<u32> = shard.runs(cfg.first, cfg.runs).collect();
    let jobs = jobs.clamp(1, runs.len().max(1));
    tracing::info!(
        runs = runs.len(),
        %shard,
        jobs,
        airframe = %airframe.name,
        output = %output.display(),
        "batch"
    );
    let next = AtomicUsize::new(0);
    let (tx, rx) = std::sync::mpsc::channel::<(usize, RunResult)>();
    let started = Instant::now();
    let mut progress = Progress::new(runs.len() as u32);
    let mut rows: Vec<csv::StringRecord> = Vec::with_capacity(runs.len());
    // Rows that finished before one with a smaller number, by their place in `runs`.
    let mut waiting = std::collections::BTreeMap::new();
    std::thread::scope(|scope| -> Result<()> {
        for _ in 0..jobs {
            let tx = tx.clone();
            let (next, runs, airframe, params) = (&next, &runs, &airframe, &params);
            scope.spawn(move || {
                loop {
                    let i = next.fetch_add(1, Ordering::Relaxed);
                    let Some(&run) = runs.get(i) else {
                        break;
                    };
                    let plan = RunPlan::draw(cfg, run, airframe.rotors.len());
                    if tx.send((i, fly_run(cfg, airframe, params, plan))).is_err() {
                        break;
                    }
                }
            });
        }
        drop(tx);
        // Owned here, so that an error below drops it and the workers stop at their next run.
        let rx = rx;
        for (i, result) in rx.iter() {
            if let Err(e) = &result.flight {
                tracing::error!(run = result.plan.run, "run failed: {e:#}");
            }
            progress.add(Outcome::of(&result.flight) == Outcome::Landed);
            waiting.insert(i, csv::StringRecord::from(csv_row(&result)));
            while let Some(row) = waiting.remove(&rows.len()) {
                csv.write_record(&row)?;
                csv.flush()?;
                rows.push(row);
            }
        }
        Ok(())
    })?;
    drop(csv);
    let wall = started.elapsed().as_secs_f64();
    let summary = BatchSummary::of(&rows);
    let manifest = Manifest {
        format: manifest::FORMAT.into(),
        campaign,
        version: Version::this(),
        shard,
        runs_done: rows.len() as u32,
        csv: manifest::file_name(output),
        csv_sha256: manifest::sha256_hex(
            &std::fs::read(output).with_context(|| format!("reading {}", output.display()))?,
        ),
        jobs,
        wall_time_s: wall,
        merged_shards: None,
        summary,
    };
    manifest.write(&manifest_path)?;
    say_done(&manifest, rows.len(), output, &manifest_path)
}

/// The CSV to write: `given`, or `name` in it when it is a directory (made when it ends in /),
/// or `name` here; never a `.json`.
pub fn output_path(given: Option<&Path>, name: &str) -> Result<PathBuf> {
    let Some(given) = given else {
        return Ok(PathBuf::from(name));
    };
    if given.as_os_str().to_string_lossy().ends_with('/') {
        std::fs::create_dir_all(given).with_context(|| format!("creating {}", given.display()))?;
    }
    let path = if given.is_dir() {
        given.join(name)
    } else {
        given.to_path_buf()
    };
    refuse_json(&path)?;
    Ok(path)
}

/// The CSV's column `name` (its position in [`CSV_HEADER`]).
pub fn column(name: &str) -> usize {
    CSV_HEADER
        .split(',')
        .position(|c| c == name)
        .unwrap_or(usize::MAX)
}

/// Refuses a CSV named `.json`: its manifest is written beside it under that name.
pub fn refuse_json(output: &Path) -> Result<()> {
    if output.extension().is_some_and(|e| e == "json") {
        bail!(
            "{}: the CSV's name; its manifest is written beside it as .json",
            output.display()
        );
    }
    Ok(())
}

/// The CSV's name of `shard` of a batch with `seed`: `batch-SEED.csv` whole, else
/// `batch-SEED-shard-K-of-N.csv` (K as wide as N, so the names sort in order).
pub fn default_name(seed: u64, shard: Shard) -> String {
    if shard == Shard::WHOLE {
        return format!("batch-{seed}.csv");
    }
    let width = shard.count.to_string().len();
    format!(
        "batch-{seed}-shard-{:0width$}-of-{}.csv",
        shard.index, shard.count
    )
}

/// The default number of workers: every CPU this process may run on.
pub fn default_jobs() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

#[cfg(test)]
mod tests;
