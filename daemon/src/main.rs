//! `autopilot`: the autopilot daemon.
//!
//! The flight daemon itself (the flight core behind the sensor and ground-station links) comes
//! with the next issue; today the binary offers `autopilot replay`, which runs the attitude
//! estimator over logged sensor data.

mod replay;

use anyhow::Result;
use clap::{Parser, Subcommand};
use std::path::PathBuf;

/// A MAVLink multirotor autopilot.
#[derive(Debug, Parser)]
#[command(name = "autopilot", version, about, arg_required_else_help = true)]
struct Cli {
    #[command(subcommand)]
    command: Command,
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

fn main() -> std::process::ExitCode {
    let cli = Cli::parse();
    let result: Result<()> = match &cli.command {
        Command::Replay {
            input,
            output,
            params,
        } => replay::run(input, output, params.as_deref()),
    };
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("autopilot: error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
