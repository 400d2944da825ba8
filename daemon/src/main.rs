//! `autopilot`: the autopilot daemon.
//!
//! `autopilot --sim` flies the default vehicle in the embedded simulator: take-off, hover, land,
//! with a live status line; `--source udp://0.0.0.0:4560` flies a simulator process (`sitl`) the
//! same way. `autopilot replay` runs the attitude estimator over logged sensor data.

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
    /// and the vehicle speaks as MAVLink system N + 1.
    #[arg(short = 'i', long, default_value_t = 0, value_parser = clap::value_parser!(u16).range(0..=250))]
    instance: u16,
    /// Airframe: a name in PARAMS_DIR/airframes/ (quad_x, quad_plus, hexa_x, octa_x, dodeca) or a
    /// path to a .toml file. With an external simulator it must be the airframe it simulates.
    #[arg(long, default_value = "quad_x", value_name = "NAME|FILE")]
    airframe: String,
    /// Flight parameters file [default: PARAMS_DIR/flight.toml].
    #[arg(long, value_name = "FILE")]
    params: Option<PathBuf>,
    /// Directory holding airframes/ and flight.toml [default: ./params, else the source tree's].
    #[arg(long, value_name = "DIR")]
    params_dir: Option<PathBuf>,
    /// Take-off altitude (m above the start).
    #[arg(long, default_value_t = 5.0, value_name = "M")]
    takeoff: f64,
    /// Hover time before landing (s).
    #[arg(long, default_value_t = 10.0, value_name = "S")]
    hover: f64,
    /// Embedded simulator: real-time factor, 1 (real time), 20, or "max" (as fast as lockstep
    /// allows).
    #[arg(long, default_value = "1", value_name = "FACTOR|max")]
    speed: String,
    /// Embedded simulator: seed of the simulated sensors.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Embedded simulator: sensor quality, ideal, typical or noisy (as `sitl --sensors`).
    #[arg(long, default_value = "typical", value_name = "PRESET")]
    sensors: String,
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

fn params_dir(cli: &Cli) -> PathBuf {
    if let Some(d) = &cli.params_dir {
        return d.clone();
    }
    let local = PathBuf::from("params");
    if local.join("airframes").is_dir() {
        local
    } else {
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../params")
    }
}

fn fly(cli: &Cli, source: &str) -> Result<()> {
    let source = Source::parse(source, cli.instance)?;
    let dir = params_dir(cli);
    let airframe_path = if cli.airframe.ends_with(".toml") {
        PathBuf::from(&cli.airframe)
    } else {
        dir.join("airframes").join(format!("{}.toml", cli.airframe))
    };
    let params_path = cli
        .params
        .clone()
        .unwrap_or_else(|| dir.join("flight.toml"));
    let params = FlightParams::load(&params_path)?;
    let speed = match cli.speed.as_str() {
        "max" => None,
        s => match s.parse::<f64>() {
            Ok(f) if f.is_finite() && f > 0.0 => Some(f),
            _ => bail!("--speed must be a positive factor or \"max\", got {s:?}"),
        },
    };
    if !(cli.takeoff.is_finite() && (1.0..=100.0).contains(&cli.takeoff)) {
        bail!("--takeoff must be within [1, 100] m, got {}", cli.takeoff);
    }
    if !(cli.hover.is_finite() && (0.0..=3600.0).contains(&cli.hover)) {
        bail!("--hover must be within [0, 3600] s, got {}", cli.hover);
    }
    if source != Source::Embedded && cli.truth_csv.is_some() {
        bail!(
            "--truth-csv is for the embedded simulator; an external one writes its own (sitl --truth-csv)"
        );
    }
    let airframe = Airframe::load(&airframe_path)?;
    let mut vehicle = Vehicle::new(&airframe, &params, cli.takeoff, cli.hover)?;
    if let Some(path) = &cli.flight_csv {
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
    let system_id = (cli.instance + 1) as u8;
    let report = match source {
        Source::Embedded => {
            let sensors = SensorPreset::from_name(&cli.sensors).with_context(|| {
                format!(
                    "--sensors must be ideal, typical or noisy, got {:?}",
                    cli.sensors
                )
            })?;
            let mut link = EmbeddedSim::new(
                &airframe,
                cli.seed,
                sensors,
                speed,
                cli.truth_csv.as_deref(),
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
        None if cli.sim => fly(&cli, "sim"),
        None => match &cli.source {
            Some(source) => fly(&cli, source),
            None => Err(anyhow::anyhow!(
                "no sensor source: give --sim to fly the embedded simulator, or --source udp://0.0.0.0:4560 for a simulator process"
            )),
        },
    };
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("autopilot: error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
