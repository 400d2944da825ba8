//! One vehicle made ready to fly: its parameters, flight core, logs, channels and ground-station
//! side.

use crate::control_loop::Ports;
use crate::gcs_links;
use crate::links::Source;
use crate::records::flight_csv::FlightCsv;
use crate::records::{self, FlightRecords};
use crate::records::{param_file, signing_file};
use crate::settings::Settings;
use anyhow::{Context, Result};
use flight_core::autopilot::{AutoFlight, Autopilot};
use flight_core::params::FlightParams;
use gcs::param_store::ParamStore;
use sitl_core::Airframe;
use sitl_core::sensors::SensorPreset;
use std::path::PathBuf;
use tokio::sync::watch;

/// One vehicle made ready to fly: its flight core and logs, the control loop's channels, and
/// its ground-station side.
pub(super) struct Prepared {
    /// Its MAVLink system id.
    pub(super) system_id: u8,
    /// Its flight core.
    pub(super) autopilot: Autopilot,
    /// Its flight CSV and score.
    pub(super) records: FlightRecords,
    /// The control loop's side of its channels.
    pub(super) ports: Ports,
    /// Its ground-station endpoints.
    pub(super) endpoints: Vec<gcs_links::EndpointSpec>,
    /// What its ground-station links serve.
    pub(super) gcs: gcs_links::Vehicle,
}

/// Builds instance `instance`'s vehicle: its parameters (flight.toml, then what ground stations
/// changed, then the command line), logs, endpoints (ports offset by the instance) and
/// channels.
pub(super) fn prepare(
    cfg: &Settings,
    source: &Source,
    airframe: &Airframe,
    instance: u16,
) -> Result<Prepared> {
    let mut base = FlightParams::load(&cfg.params_path())?;
    source.preset_params(&mut base);
    let mut notices = Vec::new();
    let (mut params, store) = match cfg.param_store(instance) {
        Some(path) => {
            let loaded = param_file::load(&path, &base)?;
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
        Some(path) => signing_file::load_key(path)?,
        None => None,
    };
    let signing_memory = match &cfg.signing_key_file {
        Some(path) => {
            let (memory, warning) = signing_file::load_memory(&signing_file::memory_path(path));
            if let Some(w) = warning {
                tracing::warn!("{w}");
                notices.push("signing timestamps lost: see the log".to_owned());
            }
            memory
        }
        None => Default::default(),
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
            signing_memory,
            tlog,
            reboot_allowed: cfg.count == 1,
        },
    })
}

/// The embedded simulator's sensor preset.
pub(super) fn sensor_preset(cfg: &Settings) -> Result<SensorPreset> {
    crate::settings::sensor_preset(&cfg.sensors)
}

/// The run's flight-data CSV and telemetry log: those named, else `LOG_DIR/<start time>.csv` and
/// .tlog. A log directory that cannot be made costs the default logs, not the flight: it is
/// said in the log and to the first ground station.
fn log_paths(
    cfg: &Settings,
    instance: u16,
    notices: &mut Vec<String>,
) -> (Option<PathBuf>, Option<PathBuf>) {
    let both_named = cfg.flight_csv.is_some() && cfg.tlog.is_some();
    let stem = cfg.log_dir().filter(|_| !both_named).and_then(|dir| {
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
