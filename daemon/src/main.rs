//! `autopilot`: the autopilot daemon.
//!
//! `autopilot --sim` flies the default vehicle in the embedded simulator: take-off, hover, land,
//! with a live status line; `--source udp://0.0.0.0:4560` flies a simulator process (`sitl`) the
//! same way. `autopilot replay` runs the attitude estimator over logged sensor data.

mod config;
mod flight;
mod flight_csv;
mod link;
mod replay;
mod score;
mod sim;
mod vehicle;

use anyhow::{Context, Result, bail};
use clap::{Parser, Subcommand};
use flight_core::params::FlightParams;
use flight_csv::FlightCsv;
use link::{SensorLink, SerialLink, Source, UdpLink};
use sim::EmbeddedSim;
use sitl_core::Airframe;
use sitl_core::sensors::SensorPreset;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicU8, Ordering};
use vehicle::Vehicle;

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
    /// Settings file (TOML): every key mirrors a flag below (source, instance, airframe,
    /// params, params_dir, takeoff_m, hover_s, speed, seed, sensors, truth_csv, flight_csv);
    /// flags given here win. Paths in it are relative to its directory.
    #[arg(long, value_name = "FILE")]
    config: Option<PathBuf>,
    /// Fly in the embedded simulator (the physics of `sitl`, in-process, behind the same HIL
    /// messages as an external simulator). Short for `--source sim`.
    #[arg(long, conflicts_with = "source")]
    sim: bool,
    /// Sensor source: `sim` (embedded simulator), `udp://0.0.0.0:4560` (a simulator process such
    /// as `sitl`; the port is offset by --instance) or `serial:///dev/ttyUSB0?baud=921600` (a
    /// flight board streaming HIL messages).
    #[arg(long, value_name = "URL")]
    source: Option<String>,
    /// Instance number N: the UDP sensor port is offset by N (several vehicles on one machine)
    /// and the vehicle speaks as MAVLink system N + 1 [default: 0].
    #[arg(short = 'i', long, value_parser = clap::value_parser!(u16).range(0..=250))]
    instance: Option<u16>,
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
    /// Take-off altitude (m above the start, 1 to 100) [default: 5].
    #[arg(long, value_name = "M")]
    takeoff: Option<f64>,
    /// Hover time before landing (s, 0 to 3600) [default: 10].
    #[arg(long, value_name = "S")]
    hover: Option<f64>,
    /// Embedded simulator: real-time factor, 1 (real time), 20, or "max" (as fast as lockstep
    /// allows) [default: 1].
    #[arg(long, value_name = "FACTOR|max")]
    speed: Option<String>,
    /// Embedded simulator: seed of the simulated sensors [default: 1].
    #[arg(long)]
    seed: Option<u64>,
    /// Embedded simulator: sensor quality, ideal, typical or noisy (as `sitl --sensors`)
    /// [default: typical].
    #[arg(long, value_name = "PRESET")]
    sensors: Option<String>,
    /// Embedded simulator: write ground truth to this CSV file (100 rows per simulated second,
    /// the same columns as `sitl --truth-csv`).
    #[arg(long, value_name = "FILE")]
    truth_csv: Option<PathBuf>,
    /// Write the flight data (estimate, set-points, motor commands and, from a simulator, the
    /// truth) to this CSV file, one row per sensor frame.
    #[arg(long, value_name = "FILE")]
    flight_csv: Option<PathBuf>,
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
}

/// The settings of a flight: the command line over the `--config` file over the defaults.
struct Settings {
    source: String,
    instance: u16,
    airframe: String,
    params: Option<PathBuf>,
    params_dir: Option<PathBuf>,
    takeoff_m: f64,
    hover_s: f64,
    speed: Option<f64>,
    seed: u64,
    sensors: String,
    truth_csv: Option<PathBuf>,
    flight_csv: Option<PathBuf>,
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
        let flag = |name: &str, x: f64, range, unit| {
            config::in_range(x, range, unit).map_err(|e| anyhow::anyhow!("--{name}: {e}"))
        };
        let takeoff_m = match cli.takeoff {
            Some(x) => flag("takeoff", x, &config::TAKEOFF_RANGE_M, "m")?,
            None => file.takeoff_m.unwrap_or(5.0),
        };
        let hover_s = match cli.hover {
            Some(x) => flag("hover", x, &config::HOVER_RANGE_S, "s")?,
            None => file.hover_s.unwrap_or(10.0),
        };
        let speed = match &cli.speed {
            Some(s) => config::parse_speed(&config::SpeedSetting::Name(s.clone()))
                .map_err(|e| anyhow::anyhow!("--speed: {e}"))?,
            None => match &file.speed {
                // Checked when the file was read.
                Some(s) => config::parse_speed(s).map_err(|e| anyhow::anyhow!(e))?,
                None => Some(1.0),
            },
        };
        let sensors = cli
            .sensors
            .clone()
            .or(file.sensors)
            .unwrap_or_else(|| "typical".into());
        Ok(Self {
            source,
            instance: cli.instance.or(file.instance).unwrap_or(0),
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
        })
    }

    fn params_dir(&self) -> PathBuf {
        airframe::config::params_dir(self.params_dir.as_deref())
    }
}

fn fly(cli: &Cli) -> Result<()> {
    let cfg = Settings::resolve(cli)?;
    let source = Source::parse(&cfg.source, cfg.instance)?;
    let dir = cfg.params_dir();
    let airframe_path = if cfg.airframe.ends_with(".toml") {
        PathBuf::from(&cfg.airframe)
    } else {
        dir.join("airframes").join(format!("{}.toml", cfg.airframe))
    };
    let params_path = cfg
        .params
        .clone()
        .unwrap_or_else(|| dir.join("flight.toml"));
    let params = FlightParams::load(&params_path)?;
    if source != Source::Embedded && cfg.truth_csv.is_some() {
        bail!(
            "--truth-csv is for the embedded simulator; an external one writes its own (sitl --truth-csv)"
        );
    }
    let airframe = Airframe::load(&airframe_path)?;
    let mut vehicle = Vehicle::new(&airframe, &params, cfg.takeoff_m, cfg.hover_s)?;
    if let Some(path) = &cfg.flight_csv {
        vehicle.log_to(
            FlightCsv::create(path, airframe.rotors.len())
                .with_context(|| format!("creating {}", path.display()))?,
        );
    }
    let interrupts = Arc::new(AtomicU8::new(0));
    {
        let i = interrupts.clone();
        ctrlc::set_handler(move || {
            if i.fetch_add(1, Ordering::SeqCst) == 0 {
                eprintln!("\nautopilot: landing (Ctrl-C again to stop at once)");
            }
        })
        .context("installing the Ctrl-C handler")?;
    }
    let system_id = (cfg.instance + 1) as u8;
    let report = match source {
        Source::Embedded => {
            let sensors = SensorPreset::from_name(&cfg.sensors).with_context(|| {
                format!(
                    "--sensors must be ideal, typical or noisy, got {:?}",
                    cfg.sensors
                )
            })?;
            let mut link = EmbeddedSim::new(
                &airframe,
                cfg.seed,
                sensors,
                cfg.speed,
                cfg.truth_csv.as_deref(),
            )?;
            let report = flight::fly(&mut link, &mut vehicle, system_id, &interrupts)?;
            link.finish()?;
            report
        }
        Source::Udp { addr, lockstep } => {
            let mut link = UdpLink::bind(addr, lockstep)?;
            tracing::info!(listening = %link.local_addr()?, airframe = %airframe.name, "waiting for a simulator");
            flight::fly(&mut link, &mut vehicle, system_id, &interrupts)?
        }
        Source::Serial {
            path,
            baud,
            lockstep,
        } => {
            let mut link = SerialLink::open(path, baud, lockstep)?;
            tracing::info!(port = %link.describe(), airframe = %airframe.name, "waiting for the flight board");
            flight::fly(&mut link, &mut vehicle, system_id, &interrupts)?
        }
    };
    vehicle.finish_log()?;
    println!("{report}");
    Ok(())
}

fn main() -> std::process::ExitCode {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info")),
        )
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .with_writer(std::io::stderr)
        .init();
    let cli = Cli::parse();
    let result: Result<()> = match &cli.command {
        Some(Command::Replay {
            input,
            output,
            params,
        }) => replay::run(input, output, params.as_deref()),
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
        assert_eq!((s.takeoff_m, s.hover_s, s.speed), (3.0, 3.0, None));
        assert_eq!((s.seed, s.instance, s.airframe.as_str()), (1, 0, "quad_x"));
        let cli = Cli::parse_from(["autopilot", "--config", file.to_str().unwrap(), "--sim"]);
        assert_eq!(Settings::resolve(&cli).unwrap().source, "sim");
    }
}
