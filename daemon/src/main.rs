//! `autopilot`: the autopilot daemon.
//!
//! `autopilot --sim` flies the default vehicle in the embedded simulator: take-off, hover, land,
//! with a live status line; `--source udp://0.0.0.0:4560` flies a simulator process (`sitl`) the
//! same way. `autopilot replay` runs the attitude estimator over logged sensor data.

mod config;
mod control_loop;
#[cfg(test)]
mod fuzz;
mod gcs;
mod gcs_links;
mod links;
mod records;
mod subcommands;

use anyhow::{Context, Result, bail};
use clap::{Parser, Subcommand};
use control_loop::{FlightReport, LoopCommand, Onboard, Pacing, Ports, Telemetry};
use flight_core::autopilot::{AutoFlight, Autopilot};
use flight_core::params::FlightParams;
use links::sim::{self, EmbeddedSim};
use links::{SensorLink, SerialLink, Source, UdpLink, json_link};
use records::FlightRecords;
use records::flight_csv::FlightCsv;
use records::param_store::ParamStore;
use sitl_core::Airframe;
use sitl_core::geo::Geodetic;
use sitl_core::sensors::{SensorConfig, SensorPreset};
use sitl_core::sim::SimConfig;
use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};
use subcommands::{batch, mag_cal, replay};
use tokio::sync::{mpsc, watch};

/// A MAVLink multirotor autopilot.
#[derive(Debug, Parser)]
#[command(
    name = "autopilot",
    version,
    about,
    arg_required_else_help = true,
    args_override_self = true
)]
struct Cli {
    /// Settings file (TOML): every key mirrors a flag below (source, instance, count, airframe,
    /// params, params_dir, takeoff_m, hover_s, speed, seed, sensors, truth_csv, flight_csv,
    /// log_dir, tlog, loop_hz, loop_spin_us, loop_cpu, loop_stats_s,
    /// mavlink, param_store); flags given here win. Paths in it are relative to its directory.
    #[arg(long, value_name = "FILE")]
    config: Option<PathBuf>,
    /// Fly in the embedded simulator (the physics of `sitl`, in-process, behind the same HIL
    /// messages as an external simulator). Short for `--source sim`.
    #[arg(long, conflicts_with = "source")]
    sim: bool,
    /// Sensor source: `sim` (embedded simulator), `udp://0.0.0.0:4560` (a simulator process such
    /// as `sitl`; the port is offset by --instance), `json://127.0.0.1:9002` (a physics speaking
    /// ArduPilot's JSON interface, such as `sitl --json`; the port is offset by 10 × --instance;
    /// `?channels=3,1,4,2` puts rotor k on that servo channel; --sensors and --seed make the
    /// magnetometer, barometer and GPS it lacks) or `serial:///dev/ttyUSB0?baud=921600` (a
    /// flight board streaming HIL messages).
    #[arg(long, value_name = "URL")]
    source: Option<String>,
    /// Instance number N: the UDP sensor port is offset by N (several vehicles on one machine)
    /// and the vehicle speaks as MAVLink system N + 1 [default: 0].
    #[arg(short = 'i', long, value_parser = clap::value_parser!(u16).range(0..=250))]
    instance: Option<u16>,
    /// Fly this many vehicles together in the embedded simulator, in one process on one
    /// clock: instances --instance … --instance + N − 1, each its own MAVLink system,
    /// ground-station ports, seed (--seed + k), parameter store and logs, and its home 3 m east
    /// of the one before (as `sitl -i`) [default: 1].
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u16).range(1..=251))]
    count: Option<u16>,
    /// Airframe: a name in PARAMS_DIR/airframes/ (quad_x, quad_plus, hexa_x, octa_x, dodeca) or a
    /// path to a .toml file. With an external simulator it must be the airframe it simulates
    /// [default: quad_x].
    #[arg(long, value_name = "NAME|FILE")]
    airframe: Option<String>,
    /// Flight parameters file [default: PARAMS_DIR/flight.toml].
    #[arg(long, value_name = "FILE")]
    params: Option<PathBuf>,
    /// Directory holding airframes/ and flight.toml [default: ./params, else the source tree's].
    #[arg(long, value_name = "DIR")]
    params_dir: Option<PathBuf>,
    /// Fly on its own, without a ground station: arm as soon as the estimator is ready, take
    /// off to this altitude (m above the start, 1 to 100), hover --hover seconds, land, and end
    /// the run once disarmed [default: wait for ground-station commands].
    #[arg(long, value_name = "M")]
    takeoff: Option<f64>,
    /// With --takeoff: hover time before landing (s, 0 to 3600) [default: 10].
    #[arg(long, value_name = "S")]
    hover: Option<f64>,
    /// Embedded simulator: real-time factor, 1 (real time), 20, or "max" (as fast as lockstep
    /// allows) [default: 1].
    #[arg(long, value_name = "FACTOR|max")]
    speed: Option<String>,
    /// Embedded simulator: seed of the simulated sensors [default: 1].
    #[arg(long)]
    seed: Option<u64>,
    /// Embedded simulator: sensor quality, ideal, typical, noisy or realistic (as `sitl --sensors`)
    /// [default: typical].
    #[arg(long, value_name = "PRESET")]
    sensors: Option<String>,
    /// Embedded simulator: write ground truth to this CSV file (100 rows per simulated second,
    /// the same columns as `sitl --truth-csv`).
    #[arg(long, value_name = "FILE")]
    truth_csv: Option<PathBuf>,
    /// Write the flight data (estimate, set-points, motor commands, loop timing and, from a
    /// simulator, the truth) to this CSV file, one row per sensor frame [default:
    /// LOG_DIR/<start time>.csv].
    #[arg(long, value_name = "FILE")]
    flight_csv: Option<PathBuf>,
    /// Where every run leaves its logs, named by its start time (UTC): a MAVLink telemetry log
    /// (`.tlog`: mavlogdump.py, MAVExplorer, QGroundControl) and the flight-data CSV; `none`
    /// for no logs but those asked for by --tlog or --flight-csv [default: ./logs].
    #[arg(long, value_name = "DIR|none")]
    log_dir: Option<PathBuf>,
    /// Write the MAVLink telemetry log (every frame sent and every message heard, each after
    /// its 8-byte big-endian Unix time in µs) to this file [default: LOG_DIR/<start time>.tlog].
    #[arg(long, value_name = "FILE")]
    tlog: Option<PathBuf>,
    /// With a source that does not wait for answers (a flight board, or `?lockstep=false`):
    /// the control loop's rate, 50 to 2000 Hz. It wakes at absolute deadlines, steps on every
    /// sensor frame that arrived, and logs its jitter and overruns [default: 1000].
    #[arg(long, value_name = "HZ")]
    loop_hz: Option<f64>,
    /// The part of each loop period before the deadline spent spinning on the clock rather
    /// than sleeping (µs, 0 to 1000): a sleep alone wakes ~60 µs late on Linux [default: 150].
    #[arg(long, value_name = "US")]
    loop_spin_us: Option<f64>,
    /// Pin the control loop's thread to this CPU (Linux), away from CPUs that serve periodic
    /// interrupts [default: not pinned].
    #[arg(long, value_name = "N")]
    loop_cpu: Option<usize>,
    /// With deadline pacing: how often the control loop logs its rate, jitter (p50, p99, max)
    /// and overruns (s, 0.5 to 3600) [default: 10].
    #[arg(long, value_name = "S")]
    loop_stats_s: Option<f64>,
    /// A ground-station endpoint; repeat for several, `none` for none. `udpout://HOST:PORT?bind=LOCAL`
    /// pushes to HOST:PORT from the LOCAL port and answers every peer writing to it;
    /// `udpin://ADDR:PORT` answers every peer writing to it; `tcpin://ADDR:PORT` is a TCP
    /// server. Every port is offset by --instance, but a udpout target marked `shared` (one
    /// ground station hearing every vehicle, as PX4 does it) [default:
    /// udpout://127.0.0.1:14550?bind=18570&shared (QGroundControl, pymavlink, MAVProxy),
    /// udpout://127.0.0.1:14540?bind=14580 (MAVSDK), tcpin://0.0.0.0:5760].
    #[arg(long, value_name = "URL")]
    mavlink: Vec<String>,
    /// Where the parameters a ground station changes are kept (applied over the flight
    /// parameters at start; written atomically on every change), or `none` to keep them in
    /// memory only [default: autopilot-params-N.toml in the working directory, N the instance].
    #[arg(long, value_name = "FILE|none")]
    param_store: Option<PathBuf>,
    /// MAVLink 2 signing: the 32-byte secret key as 64 hexadecimal digits in FILE. With a key,
    /// unsigned, wrongly signed and replayed frames are refused (but on endpoints marked
    /// `?trusted`) and the vehicle signs what it sends. A missing FILE is no key (signing off)
    /// until a `SETUP_SIGNING` on a trusted endpoint writes it [default: no key, not kept].
    #[arg(long, value_name = "FILE")]
    signing_key_file: Option<PathBuf>,
    #[command(subcommand)]
    command: Option<Command>,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Run the attitude estimator over logged sensor samples (estimator tuning, like PX4's
    /// replay). The input CSV needs a header with at least t,gx,gy,gz,ax,ay,az,mx,my,mz (seconds;
    /// gyro rad/s FRD; specific force m/s² FRD, level at rest z ≈ −9.81; magnetometer FRD in any
    /// consistent unit, empty or nan when not fresh); other columns are ignored. Writes
    /// t,qw,qx,qy,qz,bx,by,bz (q_ned_from_frd and the gyro-bias estimate, rad/s) for every sample.
    Replay {
        /// Input CSV.
        #[arg(long, short)]
        input: PathBuf,
        /// Output CSV.
        #[arg(long, short)]
        output: PathBuf,
        /// Parameter file whose attitude table sets the gains and magnetometer calibration
        /// [default: the built-in defaults, as in params/flight.toml].
        #[arg(long)]
        params: Option<PathBuf>,
    },
    /// Calibrate the magnetometer from a log (Castillo (75)–(79): the ellipsoid's offset,
    /// rotation and scale fitted to the raw samples): any CSV with raw FRD columns mx,my,mz,
    /// such as the flight-data CSV of a run in which the vehicle was turned through every
    /// orientation. Writes mag_offset, mag_scale, mag_offdiag and mag_calibration_id into
    /// the [attitude] table of --params (atomically, comments kept), or prints them.
    CalibrateMag {
        /// Input CSV.
        #[arg(long, short)]
        input: PathBuf,
        /// Flight-parameter file to write the calibration into; its ATT_MAG_STR
        /// (mag_intensity_gauss) is the field strength the calibration scales to [default:
        /// print the calibration for the default parameters].
        #[arg(long)]
        params: Option<PathBuf>,
        /// CAL_MAG0_ID to record [default: the file's if set, else 1].
        #[arg(long)]
        device_id: Option<u32>,
    },
    /// Monte-Carlo batch: fly the take-off, hover and landing many times in the embedded
    /// simulator, each run with its own sensor seed, wind, turbulence and fault drawn from the
    /// batch's seed, on every core, with a progress bar; one CSV row of flight-quality figures
    /// per run (landed, failsafe, height, hover errors, attitude-estimate error, tilt, distance,
    /// touchdown and impact speeds) and a summary per fault.
    Batch {
        /// Runs to fly.
        #[arg(long, default_value_t = 100)]
        runs: u32,
        /// The first run's number: run i draws from (seed, i), so a run of a batch is flown
        /// again with the batch's seed, `--first i --runs 1`.
        #[arg(long, default_value_t = 0)]
        first: u32,
        /// The batch's seed.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Worker threads [default: every CPU].
        #[arg(long)]
        jobs: Option<usize>,
        /// Airframe: a name in PARAMS_DIR/airframes/ or a .toml file.
        #[arg(long, default_value = "quad_x")]
        airframe: String,
        /// Directory holding airframes/ and flight.toml [default: ./params, else the source
        /// tree's].
        #[arg(long)]
        params_dir: Option<PathBuf>,
        /// Flight parameters file [default: PARAMS_DIR/flight.toml].
        #[arg(long)]
        params: Option<PathBuf>,
        /// Take-off height (m, 1 to 100).
        #[arg(long, default_value_t = 5.0)]
        takeoff: f64,
        /// Hover time (s, 0 to 3600).
        #[arg(long, default_value_t = 20.0)]
        hover: f64,
        /// Largest mean wind (m/s): each run's is drawn from 0 to this, from any direction.
        #[arg(long, default_value_t = 5.0)]
        wind_max: f64,
        /// Largest turbulence intensity W20 (m/s), drawn likewise.
        #[arg(long, default_value_t = 3.0)]
        turbulence_max: f64,
        /// The faults each run's one is drawn from (comma-separated): none, motor (a propeller
        /// at 50–90 %), motor_off, gps (fix lost 5–15 s), mag (0.1–0.3 G for 3–10 s), baro
        /// (silent 2–10 s), gust (3–8 m/s), imu (stuck); each strikes during the hover.
        #[arg(
            long,
            value_delimiter = ',',
            default_value = "none,motor,gps,mag,baro,gust"
        )]
        faults: Vec<String>,
        /// Sensor quality: ideal, typical, noisy or realistic.
        #[arg(long, default_value = "typical")]
        sensors: String,
        /// The CSV written [default: batch-SEED.csv].
        #[arg(long, short)]
        output: Option<PathBuf>,
    },
}

/// The settings of a flight: the command line over the `--config` file over the defaults.
struct Settings {
    source: String,
    instance: u16,
    count: u16,
    airframe: String,
    params: Option<PathBuf>,
    params_dir: Option<PathBuf>,
    takeoff_m: Option<f64>,
    hover_s: f64,
    speed: Option<f64>,
    seed: u64,
    sensors: String,
    truth_csv: Option<PathBuf>,
    flight_csv: Option<PathBuf>,
    /// None: no logs but those named.
    log_dir: Option<PathBuf>,
    tlog: Option<PathBuf>,
    loop_hz: f64,
    loop_spin_us: f64,
    loop_stats_s: f64,
    loop_cpu: Option<usize>,
    mavlink: Vec<String>,
    param_store: StoreSetting,
    signing_key_file: Option<PathBuf>,
}

/// Where the parameters a ground station changes are kept.
#[derive(Debug, Clone, PartialEq)]
enum StoreSetting {
    /// autopilot-params-N.toml in the working directory, N the instance.
    PerInstance,
    /// This file.
    File(PathBuf),
    /// In memory only.
    Memory,
}

impl Settings {
    fn resolve(cli: &Cli) -> Result<Self> {
        let file = match &cli.config {
            Some(p) => config::ConfigFile::load(p)?,
            None => config::ConfigFile::default(),
        };
        let source = if cli.sim {
            Some("sim".to_owned())
        } else {
            cli.source.clone()
        };
        let Some(source) = source.or(file.source) else {
            bail!(
                "no sensor source: give --sim to fly the embedded simulator, or --source udp://0.0.0.0:4560 for a simulator process (or source = ... in a --config file)"
            );
        };
        // A number from the flag (checked here) or from the file (checked when it was read).
        let number =
            |flag: Option<f64>, name: &str, range, unit, file: Option<f64>, default| match flag {
                Some(x) => {
                    config::in_range(x, range, unit).map_err(|e| anyhow::anyhow!("--{name}: {e}"))
                }
                None => Ok(file.unwrap_or(default)),
            };
        let takeoff_m = match cli.takeoff {
            Some(x) => Some(
                config::in_range(x, &config::TAKEOFF_RANGE_M, "m")
                    .map_err(|e| anyhow::anyhow!("--takeoff: {e}"))?,
            ),
            None => file.takeoff_m,
        };
        let hover_s = number(
            cli.hover,
            "hover",
            &config::HOVER_RANGE_S,
            "s",
            file.hover_s,
            10.0,
        )?;
        let speed = match &cli.speed {
            Some(s) => config::parse_speed(&config::SpeedSetting::Name(s.clone()))
                .map_err(|e| anyhow::anyhow!("--speed: {e}"))?,
            None => match &file.speed {
                // Checked when the file was read.
                Some(s) => config::parse_speed(s).map_err(|e| anyhow::anyhow!(e))?,
                None => Some(1.0),
            },
        };
        let loop_hz = number(
            cli.loop_hz,
            "loop-hz",
            &config::LOOP_HZ_RANGE,
            "Hz",
            file.loop_hz,
            1000.0,
        )?;
        let loop_spin_us = number(
            cli.loop_spin_us,
            "loop-spin-us",
            &config::LOOP_SPIN_RANGE_US,
            "µs",
            file.loop_spin_us,
            150.0,
        )?;
        let loop_stats_s = number(
            cli.loop_stats_s,
            "loop-stats-s",
            &config::LOOP_STATS_RANGE_S,
            "s",
            file.loop_stats_s,
            10.0,
        )?;
        let sensors = cli
            .sensors
            .clone()
            .or(file.sensors)
            .unwrap_or_else(|| "typical".into());
        let instance = cli.instance.or(file.instance).unwrap_or(0);
        let count = cli.count.or(file.count).unwrap_or(1);
        let last = usize::from(instance) + usize::from(count) - 1;
        if last > usize::from(*config::INSTANCE_RANGE.end()) {
            bail!(
                "--count {count} from instance {instance} goes past the last instance, {}",
                config::INSTANCE_RANGE.end()
            );
        }
        Ok(Self {
            source,
            instance,
            count,
            airframe: cli
                .airframe
                .clone()
                .or(file.airframe)
                .unwrap_or_else(|| "quad_x".into()),
            params: cli.params.clone().or(file.params),
            params_dir: cli.params_dir.clone().or(file.params_dir),
            takeoff_m,
            hover_s,
            speed,
            seed: cli.seed.or(file.seed).unwrap_or(1),
            sensors,
            truth_csv: cli.truth_csv.clone().or(file.truth_csv),
            flight_csv: cli.flight_csv.clone().or(file.flight_csv),
            log_dir: match cli.log_dir.clone().or(file.log_dir) {
                Some(p) if p == Path::new("none") => None,
                Some(p) => Some(p),
                None => Some(PathBuf::from("logs")),
            },
            tlog: cli.tlog.clone().or(file.tlog),
            loop_hz,
            loop_spin_us,
            loop_stats_s,
            loop_cpu: cli.loop_cpu.or(file.loop_cpu),
            mavlink: if cli.mavlink.is_empty() {
                file.mavlink.unwrap_or_else(|| {
                    gcs_links::DEFAULT_ENDPOINTS
                        .iter()
                        .map(|s| s.to_string())
                        .collect()
                })
            } else {
                cli.mavlink.clone()
            },
            param_store: match cli.param_store.clone().or(file.param_store) {
                Some(p) if p == Path::new("none") => StoreSetting::Memory,
                Some(p) => StoreSetting::File(p),
                None => StoreSetting::PerInstance,
            },
            signing_key_file: cli.signing_key_file.clone().or(file.signing_key_file),
        })
    }

    fn params_dir(&self) -> PathBuf {
        airframe::config::params_dir(self.params_dir.as_deref())
    }

    /// Instance `instance`'s parameter store (none: in memory only).
    fn param_store(&self, instance: u16) -> Option<PathBuf> {
        match &self.param_store {
            StoreSetting::PerInstance => {
                Some(PathBuf::from(format!("autopilot-params-{instance}.toml")))
            }
            StoreSetting::File(p) => Some(p.clone()),
            StoreSetting::Memory => None,
        }
    }

    /// The airframe file.
    fn airframe_path(&self) -> PathBuf {
        if self.airframe.ends_with(".toml") {
            PathBuf::from(&self.airframe)
        } else {
            self.params_dir()
                .join("airframes")
                .join(format!("{}.toml", self.airframe))
        }
    }
}

/// One vehicle made ready to fly: its flight core and logs, the control loop's channels, and
/// its ground-station side.
struct Prepared {
    system_id: u8,
    autopilot: Autopilot,
    records: FlightRecords,
    ports: Ports,
    endpoints: Vec<gcs_links::EndpointSpec>,
    gcs: gcs_links::Vehicle,
}

/// Builds instance `instance`'s vehicle: its parameters (flight.toml, then what ground stations
/// changed, then the command line), logs, endpoints (ports offset by the instance) and
/// channels.
fn prepare(
    cfg: &Settings,
    source: &Source,
    airframe: &Airframe,
    instance: u16,
) -> Result<Prepared> {
    let params_path = cfg
        .params
        .clone()
        .unwrap_or_else(|| cfg.params_dir().join("flight.toml"));
    let mut base = FlightParams::load(&params_path)?;
    source.preset_params(&mut base);
    let mut notices = Vec::new();
    let (mut params, store) = match cfg.param_store(instance) {
        Some(path) => {
            let loaded = ParamStore::load(&path, &base)?;
            for w in &loaded.warnings {
                tracing::warn!("{w}");
            }
            if loaded.from_previous_copy {
                notices.push("param store damaged: previous copy used".to_owned());
            }
            let names: Vec<&str> = loaded.store.names().collect();
            if !names.is_empty() {
                tracing::info!(store = %path.display(), "parameters set from a ground station: {}", names.join(", "));
            }
            (loaded.params, loaded.store)
        }
        None => (base.clone(), ParamStore::in_memory()),
    };
    if let Some(t) = cfg.takeoff_m {
        params.commander.takeoff_alt_m = t;
        base.commander.takeoff_alt_m = t;
    }
    let auto = cfg.takeoff_m.map(|takeoff_m| AutoFlight {
        takeoff_m,
        hover_s: cfg.hover_s,
    });
    let autopilot = Autopilot::new(airframe, &params, auto).context("building the mixer")?;
    let mut records = FlightRecords::new(params.commander.takeoff_alt_m);
    let (flight_csv, tlog) = log_paths(cfg, instance, &mut notices);
    if let Some(path) = &flight_csv {
        records.log_to(
            FlightCsv::create(path, airframe.rotors.len(), source.lockstep())
                .with_context(|| format!("creating {}", path.display()))?,
        );
    }
    let tlog = match &tlog {
        Some(path) => Some(
            records::log_files::Tlog::create(path)
                .with_context(|| format!("creating {}", path.display()))?,
        ),
        None => None,
    };
    if flight_csv.is_some() || tlog.is_some() {
        tracing::info!(
            tlog = ?tlog.as_ref().map(|t| t.path()),
            flight_csv = ?flight_csv,
            "logging"
        );
    }
    let system_id = (instance + 1) as u8;
    let endpoints = cfg
        .mavlink
        .iter()
        .filter(|u| u.as_str() != "none")
        .map(|u| gcs_links::EndpointSpec::parse(u, instance))
        .collect::<Result<Vec<_>>>()
        .context("--mavlink")?;
    let signing_key = match &cfg.signing_key_file {
        Some(path) => match std::fs::read_to_string(path) {
            Ok(text) => Some(
                gcs::signing::SecretKey::from_hex(&text)
                    .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?,
            ),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => None,
            Err(e) => return Err(e).with_context(|| format!("reading {}", path.display())),
        },
        None => None,
    };
    let (mut ports, commands, telemetry) = Ports::new(16);
    let (params_tx, params_rx) = watch::channel(params.clone());
    ports.params = Some(params_rx);
    Ok(Prepared {
        system_id,
        autopilot,
        records,
        ports,
        endpoints,
        gcs: gcs_links::Vehicle {
            system_id,
            mav_type: gcs::GroundStation::mav_type(airframe.rotors.len()),
            telemetry,
            commands,
            parameters: gcs::params::Parameters::new(params, store),
            base_params: base,
            params: params_tx,
            notices,
            signing_key,
            signing_key_file: cfg.signing_key_file.clone(),
            tlog,
            reboot_allowed: cfg.count == 1,
        },
    })
}

/// The embedded simulator's sensor preset.
fn sensor_preset(cfg: &Settings) -> Result<SensorPreset> {
    SensorPreset::from_name(&cfg.sensors).with_context(|| {
        format!(
            "--sensors must be ideal, typical, noisy or realistic, got {:?}",
            cfg.sensors
        )
    })
}

fn fly(cli: &Cli) -> Result<()> {
    let cfg = Settings::resolve(cli)?;
    let source = Source::parse(&cfg.source, cfg.instance)?;
    if source != Source::Embedded && cfg.truth_csv.is_some() {
        bail!(
            "--truth-csv is for the embedded simulator; an external one writes its own (sitl --truth-csv)"
        );
    }
    if cfg.count > 1 {
        return fly_together(cfg, source);
    }
    let airframe = Airframe::load(&cfg.airframe_path())?;
    if let Some(cpu) = cfg.loop_cpu {
        // This thread runs the tasks around the loop, and the threads it starts (the log
        // writers, the runtime's) inherit where it may run: none on the loop's CPU. The loop's
        // own thread pins itself there.
        control_loop::deadline::keep_off_cpu(cpu).map_err(anyhow::Error::msg)?;
    }
    let Prepared {
        system_id,
        mut autopilot,
        mut records,
        mut ports,
        endpoints,
        gcs,
    } = prepare(&cfg, &source, &airframe, cfg.instance)?;
    let deadlines = Pacing::Deadlines {
        period: Duration::from_secs_f64(1.0 / cfg.loop_hz),
        spin: Duration::from_secs_f64(cfg.loop_spin_us * 1e-6),
        stats: Duration::from_secs_f64(cfg.loop_stats_s),
    };
    let (commands, telemetry) = (gcs.commands.clone(), gcs.telemetry.clone());
    // The control loop on its own thread owns the vehicle and the sensor link; this thread runs
    // the tasks that talk to it (ground stations, status line, Ctrl-C).
    let ended = std::sync::Arc::new(tokio::sync::Notify::new());
    let ended_guard = LoopEnded(ended.clone());
    let control = std::thread::Builder::new()
        .name("control-loop".into())
        .spawn(move || -> Result<FlightReport> {
            let _ended = ended_guard;
            let ports = &mut ports;
            if let Some(cpu) = cfg.loop_cpu {
                control_loop::deadline::pin_to_cpu(cpu).map_err(anyhow::Error::msg)?;
                tracing::info!(cpu, "control loop pinned");
            }
            match source {
                Source::Embedded => {
                    let sensors = sensor_preset(&cfg)?;
                    if sensors == SensorPreset::Ideal {
                        autopilot.sensors_noise_free();
                    }
                    let world = SimConfig {
                        seed: cfg.seed,
                        sensors: SensorConfig::preset(sensors),
                        home: Geodetic::default().for_instance(cfg.instance),
                        ..SimConfig::default()
                    };
                    let mut link = EmbeddedSim::with_world(
                        &airframe,
                        world,
                        &[],
                        cfg.speed,
                        cfg.truth_csv.as_deref(),
                    )?;
                    let report =
                        control_loop::fly(Onboard { link: &mut link, autopilot: &mut autopilot, records: &mut records, ports, system_id }, Pacing::Lockstep)?;
                    link.finish()?;
                    finish(&mut records, report)
                }
                Source::Udp { addr, lockstep } => {
                    let mut link = UdpLink::bind(addr, lockstep)?;
                    tracing::info!(listening = %link.local_addr()?, airframe = %airframe.name, "waiting for a simulator");
                    let pacing = if lockstep { Pacing::Lockstep } else { deadlines };
                    let report = control_loop::fly(Onboard { link: &mut link, autopilot: &mut autopilot, records: &mut records, ports, system_id }, pacing)?;
                    finish(&mut records, report)
                }
                Source::Json { addr, channels } => {
                    let rotors = airframe.rotors.len();
                    let channels = if channels.is_empty() {
                        (0..rotors).collect()
                    } else if channels.len() == rotors {
                        channels
                    } else {
                        bail!(
                            "json://…?channels= names {} channels for the {rotors} rotors of {}",
                            channels.len(),
                            airframe.name
                        );
                    };
                    let sensors = sensor_preset(&cfg)?;
                    if sensors == SensorPreset::Ideal {
                        autopilot.sensors_noise_free();
                    }
                    let mut link = json_link::JsonLink::connect(
                        addr,
                        channels,
                        sensors,
                        cfg.seed,
                        Geodetic::default().for_instance(cfg.instance),
                    )
                    .with_context(|| format!("opening a UDP socket for {addr}"))?;
                    tracing::info!(physics = %addr, airframe = %airframe.name, "sending servo packets to a JSON physics");
                    let report =
                        control_loop::fly(Onboard { link: &mut link, autopilot: &mut autopilot, records: &mut records, ports, system_id }, Pacing::Lockstep)?;
                    finish(&mut records, report)
                }
                Source::Serial {
                    path,
                    baud,
                    lockstep,
                } => {
                    let mut link = SerialLink::open(path, baud, lockstep)?;
                    tracing::info!(port = %link.describe(), airframe = %airframe.name, "waiting for the flight board");
                    let pacing = if lockstep { Pacing::Lockstep } else { deadlines };
                    let report = control_loop::fly(Onboard { link: &mut link, autopilot: &mut autopilot, records: &mut records, ports, system_id }, pacing)?;
                    finish(&mut records, report)
                }
            }
        })
        .context("starting the control loop")?;
    let exits = serve(
        vec![(endpoints, gcs)],
        vec![commands],
        vec![telemetry],
        ended,
    )?;
    let report = control
        .join()
        .map_err(|_| anyhow::anyhow!("the control loop panicked"))??;
    // The process's peak memory joins the summary (the bench quotes it).
    match peak_rss_kib() {
        Some(kib) => println!("{report} max_rss_kib={kib}"),
        None => println!("{report}"),
    }
    if exits.first() == Some(&Some(gcs::Action::Reboot)) {
        reboot()?;
    }
    Ok(())
}

/// Says the control loop's thread has ended when dropped (at its end, on an error or a panic
/// alike), so the tasks around it stop at once rather than at their next poll.
struct LoopEnded(std::sync::Arc<tokio::sync::Notify>);

impl Drop for LoopEnded {
    fn drop(&mut self) {
        self.0.notify_one();
    }
}

/// Runs the tasks around the control loop on this thread until the loop ends: every vehicle's
/// ground stations, Ctrl-C for all of them, the status line. Returns what each vehicle's
/// ground stations asked the process to do at the end (a reboot).
fn serve(
    vehicles: Vec<(Vec<gcs_links::EndpointSpec>, gcs_links::Vehicle)>,
    commands: Vec<mpsc::Sender<LoopCommand>>,
    telemetry: Vec<watch::Receiver<Telemetry>>,
    ended: std::sync::Arc<tokio::sync::Notify>,
) -> Result<Vec<Option<gcs::Action>>> {
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .context("starting the async runtime")?;
    let exits = runtime.block_on(async move {
        let links: Vec<_> = vehicles
            .into_iter()
            .map(|(endpoints, vehicle)| tokio::spawn(gcs_links::run(endpoints, vehicle)))
            .collect();
        tokio::spawn(interrupts(commands));
        status_line(telemetry, ended).await;
        // The ground-station side ends with the loop, after its last save.
        let mut exits = Vec::with_capacity(links.len());
        for l in links {
            exits.push(l.await.ok().flatten());
        }
        exits
    });
    drop(runtime);
    Ok(exits)
}

/// `--count N`: N vehicles in the embedded simulator, flown together on one control-loop thread
/// in lockstep on one clock ([`flight::fly_together`]), each with its own ground stations.
fn fly_together(cfg: Settings, source: Source) -> Result<()> {
    if source != Source::Embedded {
        bail!(
            "--count flies vehicles in the embedded simulator (--sim); with simulator processes or flight boards run one autopilot per vehicle, each with its own --instance"
        );
    }
    if cfg.truth_csv.is_some() || cfg.flight_csv.is_some() || cfg.tlog.is_some() {
        bail!(
            "--truth-csv, --flight-csv and --tlog name one vehicle's file; with --count every vehicle logs to --log-dir"
        );
    }
    if let StoreSetting::File(p) = &cfg.param_store {
        bail!(
            "--param-store {} names one vehicle's file; with --count every vehicle keeps its own (the default) or none",
            p.display()
        );
    }
    let airframe = Airframe::load(&cfg.airframe_path())?;
    let sensors = sensor_preset(&cfg)?;
    let mut vehicles = Vec::with_capacity(cfg.count.into());
    let mut sims = Vec::with_capacity(cfg.count.into());
    for k in 0..cfg.count {
        let mut p = prepare(&cfg, &source, &airframe, cfg.instance + k)?;
        if sensors == SensorPreset::Ideal {
            p.autopilot.sensors_noise_free();
        }
        let world = SimConfig {
            seed: cfg.seed.wrapping_add(k.into()),
            sensors: SensorConfig::preset(sensors),
            home: Geodetic::default().for_instance(cfg.instance + k),
            ..SimConfig::default()
        };
        sims.push(EmbeddedSim::with_world(&airframe, world, &[], None, None)?);
        vehicles.push(p);
    }
    let commands: Vec<_> = vehicles.iter().map(|p| p.gcs.commands.clone()).collect();
    let telemetry: Vec<_> = vehicles.iter().map(|p| p.gcs.telemetry.clone()).collect();
    let (mut cores, links): (Vec<_>, Vec<_>) = vehicles
        .into_iter()
        .map(|p| {
            (
                (p.system_id, p.autopilot, p.records, p.ports),
                (p.endpoints, p.gcs),
            )
        })
        .unzip();
    tracing::info!(
        vehicles = cfg.count,
        first_system_id = cfg.instance + 1,
        airframe = %airframe.name,
        "flying together on one clock"
    );
    let speed = cfg.speed;
    let ended = std::sync::Arc::new(tokio::sync::Notify::new());
    let ended_guard = LoopEnded(ended.clone());
    let control = std::thread::Builder::new()
        .name("control-loop".into())
        .spawn(move || -> Result<control_loop::SwarmReport> {
            let _ended = ended_guard;
            let members = cores
                .iter_mut()
                .zip(sims.iter_mut())
                .map(|((system_id, autopilot, records, ports), sim)| Onboard {
                    link: sim,
                    autopilot,
                    records,
                    ports,
                    system_id: *system_id,
                })
                .collect();
            let mut report = control_loop::fly_together(members, sim::EXCHANGE_HZ, speed);
            for ((system_id, _, records, _), flight) in cores.iter_mut().zip(&mut report.flights) {
                if let Err(e) = records.finish()
                    && flight.is_ok()
                {
                    *flight = Err(e.context(format!("system {system_id}")));
                }
            }
            Ok(report)
        })
        .context("starting the control loop")?;
    serve(links, commands, telemetry, ended)?;
    let report = control
        .join()
        .map_err(|_| anyhow::anyhow!("the control loop panicked"))??;
    let mut failed = 0;
    let mut landed = 0;
    for (k, flight) in report.flights.iter().enumerate() {
        let system_id = usize::from(cfg.instance) + k + 1;
        match flight {
            Ok(r) => {
                landed += usize::from(r.landed());
                println!("{} system_id={system_id}", r);
            }
            Err(e) => {
                failed += 1;
                eprintln!("autopilot: system {system_id}: error: {e:#}");
            }
        }
    }
    println!(
        "swarm summary: vehicles={} rounds={} sim_time_s={:.2} wall_time_s={:.2} realtime_factor={:.2} max_lag_s={:.3} landed={landed} failed={failed} max_rss_kib={}",
        cfg.count,
        report.rounds,
        report.sim_time_s,
        report.wall_time_s,
        report.sim_time_s / report.wall_time_s.max(1e-9),
        report.max_lag_s,
        peak_rss_kib().unwrap_or(0),
    );
    if failed > 0 {
        bail!("{failed} of {} vehicles ended in error", cfg.count);
    }
    Ok(())
}

/// The process's peak resident memory (KiB), where Linux's /proc tells it.
fn peak_rss_kib() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    line.split_whitespace().nth(1)?.parse().ok()
}

/// The run's flight-data CSV and telemetry log: those named, else LOG_DIR/<start time>.csv and
/// .tlog. A log directory that cannot be made costs the default logs, not the flight: it is
/// said in the log and to the first ground station.
fn log_paths(
    cfg: &Settings,
    instance: u16,
    notices: &mut Vec<String>,
) -> (Option<PathBuf>, Option<PathBuf>) {
    let both_named = cfg.flight_csv.is_some() && cfg.tlog.is_some();
    let stem = cfg
        .log_dir
        .as_deref()
        .filter(|_| !both_named)
        .and_then(|dir| {
            let now = std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map_or(0, |d| d.as_secs());
            match records::log_files::run_stem(dir, now, instance) {
                Ok(stem) => Some(stem),
                Err(e) => {
                    tracing::warn!(dir = %dir.display(), "no logs: {e}");
                    notices.push(format!("no logs: {e}"));
                    None
                }
            }
        });
    let default = |ext| stem.as_ref().map(|s| s.with_extension(ext));
    (
        cfg.flight_csv.clone().or_else(|| default("csv")),
        cfg.tlog.clone().or_else(|| default("tlog")),
    )
}

/// `PREFLIGHT_REBOOT_SHUTDOWN` reboot: the process starts again with the same arguments, as a
/// flight board does (the new process reads the saved parameters, aligns, waits for commands).
fn reboot() -> Result<()> {
    use std::os::unix::process::CommandExt;
    let exe = std::env::current_exe().context("reboot: finding the executable")?;
    tracing::info!("rebooting");
    let err = std::process::Command::new(exe)
        .args(std::env::args_os().skip(1))
        .exec();
    Err(err).context("reboot")
}

/// Flushes the vehicle's log and hands the report on.
fn finish(records: &mut FlightRecords, report: FlightReport) -> Result<FlightReport> {
    records.finish()?;
    Ok(report)
}

/// Ctrl-C: the first lands (every vehicle), the second stops the loop at once. SIGTERM (a service
/// manager, `kill`) stops it at once. Either way the run ends as every run does: logs flushed,
/// parameters saved.
async fn interrupts(commands: Vec<mpsc::Sender<LoopCommand>>) {
    use tokio::signal::unix::{SignalKind, signal};
    let mut terminate = match signal(SignalKind::terminate()) {
        Ok(s) => Some(s),
        Err(e) => {
            tracing::warn!("SIGTERM not handled: {e}");
            None
        }
    };
    let terminated = async {
        match terminate.as_mut() {
            Some(s) => s.recv().await,
            None => std::future::pending().await,
        }
    };
    tokio::pin!(terminated);
    let mut interrupts = 0;
    loop {
        tokio::select! {
            Some(()) = &mut terminated => {
                tracing::info!("SIGTERM: stopping");
                for c in &commands {
                    let _ = c.send(LoopCommand::Stop).await;
                }
                return;
            }
            r = tokio::signal::ctrl_c() => {
                if r.is_err() {
                    return;
                }
                interrupts += 1;
                if interrupts == 1 {
                    eprintln!("\nautopilot: landing (Ctrl-C again to stop at once)");
                }
                let mut reached = 0;
                for c in &commands {
                    let command = if interrupts == 1 { LoopCommand::Land } else { LoopCommand::Stop };
                    reached += usize::from(c.send(command).await.is_ok());
                }
                if reached == 0 {
                    return;
                }
            }
        }
    }
}

/// The live one-line status, four times a second from the latest telemetry, until the loop
/// ends: on a terminal it rewrites itself, otherwise one line each time. One vehicle's line
/// shows its state; several vehicles' a count of each mode and the spread of their altitudes.
async fn status_line(
    mut telemetry: Vec<watch::Receiver<Telemetry>>,
    ended: std::sync::Arc<tokio::sync::Notify>,
) {
    let tty = std::io::stdout().is_terminal();
    let started = Instant::now();
    let mut tick = tokio::time::interval(Duration::from_millis(250));
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    let loop_ended = ended.notified();
    tokio::pin!(loop_ended);
    let mut ended_seen = false;
    loop {
        // Polled, not awaited on every change: the loop publishes at its own rate, and waking
        // this thread that often would take CPU time from it. Its end wakes it at once.
        tokio::select! {
            _ = tick.tick() => {}
            _ = &mut loop_ended, if !ended_seen => ended_seen = true,
        }
        let latest: Vec<Telemetry> = telemetry
            .iter_mut()
            .filter_map(|rx| {
                let t = *rx.borrow_and_update();
                // The loop ended, or its thread did (an error before it started).
                (!t.finished && rx.has_changed().is_ok()).then_some(t)
            })
            .collect();
        if latest.is_empty() {
            break;
        }
        let wall = started.elapsed().as_secs_f64().max(1e-9);
        let line = if telemetry.len() == 1 {
            let t = &latest[0];
            let (Some(out), Some(status)) = (t.output, t.status) else {
                continue;
            };
            let (roll, pitch, yaw) = out.attitude.map_or((0.0, 0.0, 0.0), |a| a.q.euler_angles());
            let mut line = format!(
                "t {:6.1} s  {:<8} {:<8} alt {:6.2} m  vz {:5.2} m/s  roll {:5.1}  pitch {:5.1}  yaw {:6.1} deg  {:.0} frames/s x{:.0} real time",
                t.t_s,
                if status.armed { "armed" } else { "disarmed" },
                status.mode.name(),
                -out.translation.pos_ned_m.z,
                -out.translation.vel_ned_m_s.z,
                roll.to_degrees(),
                pitch.to_degrees(),
                yaw.to_degrees(),
                t.frames as f64 / wall,
                t.t_s / wall
            );
            if let Some(s) = t.loop_stats {
                line += &format!("  loop p99 {} us, {} overruns", s.jitter_p99_us, s.overruns);
            }
            line
        } else {
            swarm_status(&latest, telemetry.len(), wall)
        };
        let mut stdout = std::io::stdout();
        if tty {
            let _ = write!(stdout, "\r{line}\x1b[K");
            let _ = stdout.flush();
        } else {
            let _ = writeln!(stdout, "{line}");
        }
    }
    if tty {
        println!();
    }
}

/// Several vehicles' status in one line: how many fly, armed, in each mode, and their altitudes.
fn swarm_status(latest: &[Telemetry], count: usize, wall_s: f64) -> String {
    let t_s = latest.iter().map(|t| t.t_s).fold(0.0, f64::max);
    let armed = latest
        .iter()
        .filter(|t| t.status.is_some_and(|s| s.armed))
        .count();
    let mut modes: Vec<(&str, usize)> = Vec::new();
    for s in latest.iter().filter_map(|t| t.status) {
        match modes.iter_mut().find(|(m, _)| *m == s.mode.name()) {
            Some((_, n)) => *n += 1,
            None => modes.push((s.mode.name(), 1)),
        }
    }
    let alts = latest
        .iter()
        .filter_map(|t| t.output.map(|o| -o.translation.pos_ned_m.z));
    let (lo, hi) = alts.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), a| {
        (lo.min(a), hi.max(a))
    });
    let modes: Vec<String> = modes.iter().map(|(m, n)| format!("{n} {m}")).collect();
    let mut line = format!(
        "t {t_s:6.1} s  {} of {count} vehicles flying, {armed} armed ({})",
        latest.len(),
        modes.join(", ")
    );
    if lo <= hi {
        line += &format!("  alt {lo:.2} to {hi:.2} m");
    }
    line + &format!("  x{:.1} real time", t_s / wall_s)
}

fn main() -> std::process::ExitCode {
    let cli = Cli::parse();
    // A batch flies hundreds of vehicles: their own warnings (failsafes, faults) are in its CSV,
    // not the log, unless RUST_LOG asks for them.
    let quiet = "info,autopilot::vehicle=off,autopilot::flight=off";
    let default = match cli.command {
        Some(Command::Batch { .. }) => quiet,
        _ => "info",
    };
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new(default)),
        )
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .with_writer(std::io::stderr)
        .init();
    let result: Result<()> = match &cli.command {
        Some(Command::Replay {
            input,
            output,
            params,
        }) => replay::run(input, output, params.as_deref()),
        Some(Command::CalibrateMag {
            input,
            params,
            device_id,
        }) => mag_cal::run(input, params.as_deref(), *device_id),
        Some(Command::Batch {
            runs,
            first,
            seed,
            jobs,
            airframe,
            params_dir,
            params,
            takeoff,
            hover,
            wind_max,
            turbulence_max,
            faults,
            sensors,
            output,
        }) => (|| {
            let dir = airframe::config::params_dir(params_dir.as_deref());
            let airframe_path = if airframe.ends_with(".toml") {
                PathBuf::from(airframe)
            } else {
                dir.join("airframes").join(format!("{airframe}.toml"))
            };
            let cfg = batch::BatchConfig {
                runs: *runs,
                first: *first,
                seed: *seed,
                takeoff_m: config::in_range(*takeoff, &config::TAKEOFF_RANGE_M, "m")
                    .map_err(|e| anyhow::anyhow!("--takeoff: {e}"))?,
                hover_s: config::in_range(*hover, &config::HOVER_RANGE_S, "s")
                    .map_err(|e| anyhow::anyhow!("--hover: {e}"))?,
                wind_max_m_s: *wind_max,
                turbulence_max_m_s: *turbulence_max,
                faults: faults
                    .iter()
                    .map(|f| batch::FaultKind::from_name(f.trim()))
                    .collect::<Result<_>>()
                    .context("--faults")?,
                sensors: SensorPreset::from_name(sensors).with_context(|| {
                    format!("--sensors must be ideal, typical, noisy or realistic, got {sensors:?}")
                })?,
            };
            batch::run(
                &cfg,
                &airframe_path,
                &params.clone().unwrap_or_else(|| dir.join("flight.toml")),
                jobs.unwrap_or_else(batch::default_jobs),
                &output
                    .clone()
                    .unwrap_or_else(|| batch::default_output(*seed)),
            )
        })(),
        None => fly(&cli),
    };
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("autopilot: error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn flags_win_over_the_file_which_wins_over_the_defaults() {
        let dir = std::env::temp_dir().join(format!("autopilot-settings-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("autopilot.toml");
        std::fs::write(
            &file,
            "source = \"udp://127.0.0.1:4560\"\ntakeoff_m = 8\nhover_s = 3\nspeed = \"max\"\n",
        )
        .unwrap();
        let cli = Cli::parse_from([
            "autopilot",
            "--config",
            file.to_str().unwrap(),
            "--takeoff",
            "3",
        ]);
        let s = Settings::resolve(&cli).unwrap();
        assert_eq!(s.source, "udp://127.0.0.1:4560");
        assert_eq!((s.takeoff_m, s.hover_s, s.speed), (Some(3.0), 3.0, None));
        assert_eq!((s.seed, s.instance, s.airframe.as_str()), (1, 0, "quad_x"));
        let cli = Cli::parse_from(["autopilot", "--config", file.to_str().unwrap(), "--sim"]);
        assert_eq!(Settings::resolve(&cli).unwrap().source, "sim");
    }
}
