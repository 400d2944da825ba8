//! `autopilot`: the autopilot daemon.
//!
//! `autopilot --sim` flies the default vehicle in the embedded simulator: take-off, hover, land,
//! with a live status line; `--source udp://127.0.0.1:4560` flies a simulator process (`sitl`) the
//! same way. `autopilot replay` runs the attitude estimator over logged sensor data.

mod app;
mod cli;
mod control_loop;
mod devices;
#[cfg(test)]
mod fuzz;
mod gcs_links;
mod links;
mod records;
mod settings;
mod subcommands;

use anyhow::Result;
use clap::Parser;
use cli::{Cli, Command};
use settings::Settings;

fn main() -> std::process::ExitCode {
    let cli = Cli::parse();
    // A batch flies hundreds of vehicles: their own warnings (failsafes, faults) are in its CSV,
    // not the log, unless RUST_LOG asks for them.
    let quiet =
        "info,flight_core=off,autopilot::control_loop=off,autopilot::links=off,sitl_core=off";
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
        }) => subcommands::replay::run(input, output, params.as_deref()),
        Some(Command::CalibrateMag {
            input,
            params,
            device_id,
        }) => subcommands::mag_cal::run(input, params.as_deref(), *device_id),
        Some(Command::Batch(args)) => subcommands::run_batch(args),
        None => Settings::resolve(&cli.flight).and_then(app::fly),
    };
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("autopilot: error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
