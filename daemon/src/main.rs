//! `autopilot`: the autopilot daemon.
//!
//! `autopilot --sim` flies the default vehicle in the embedded simulator: take-off, hover, land,
//! with a live status line. The sensor links to an external simulator (UDP) and a flight board
//! (serial) come next. `autopilot replay` runs the attitude estimator over logged sensor data.

mod replay;
mod sim;
mod vehicle;

use anyhow::{Context, Result, bail};
use clap::{Parser, Subcommand};
use flight_core::params::FlightParams;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicU8, Ordering};

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
    /// messages as an external simulator).
    #[arg(long)]
    sim: bool,
    /// Airframe: a name in PARAMS_DIR/airframes/ (quad_x, quad_plus, hexa_x, octa_x, dodeca) or a
    /// path to a .toml file.
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
    /// Real-time factor of the embedded simulator: 1 (real time), 20, or "max".
    #[arg(long, default_value = "1", value_name = "FACTOR|max")]
    speed: String,
    /// Seed of the simulated sensors.
    #[arg(long, default_value_t = 1)]
    seed: u64,
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

fn fly(cli: &Cli) -> Result<()> {
    let dir = params_dir(cli);
    let airframe = if cli.airframe.ends_with(".toml") {
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
    let options = sim::SimOptions {
        airframe,
        params,
        takeoff_m: cli.takeoff,
        hover_s: cli.hover,
        speed,
        seed: cli.seed,
    };
    let report = sim::run(&options, &interrupts)?;
    println!("{report}");
    Ok(())
}

fn main() -> std::process::ExitCode {
    let cli = Cli::parse();
    let result: Result<()> = match &cli.command {
        Some(Command::Replay {
            input,
            output,
            params,
        }) => replay::run(input, output, params.as_deref()),
        None if cli.sim => fly(&cli),
        None => Err(anyhow::anyhow!(
            "no sensor source: give --sim to fly the embedded simulator (links to an external simulator over UDP and to a flight board over serial are not implemented yet)"
        )),
    };
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("autopilot: error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
