//! One vehicle made ready to fly: its parameters, flight core, logs, channels and ground-station
//! side.

use crate::control_loop::Ports;
use crate::gcs_links;
use crate::links::Source;
use crate::records::flight_csv::FlightCsv;
use crate::records::flight_ulog::{FlightUlog, UlogStart};
use crate::records::{self, FlightRecords};
use crate::records::{param_file, signing_file};
use crate::settings::Settings;
use anyhow::{Context, Result};
use flight_core::autopilot::{AutoFlight, Autopilot};
use flight_core::params::{FlightParams, LoggerGroup};
use gcs::component_metadata::{ComponentMetadata, METADATA_DIR};
use gcs::param_store::ParamStore;
use gcs::signing::{SecretKey, SigningMemory};
use sitl_core::Airframe;
use sitl_core::sensors::SensorPreset;
use std::path::{Path, PathBuf};
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
    let mut notices = Vec::new();
    let (mut base, mut params, store) = load_params(cfg, source, instance, &mut notices)?;
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
    let system_id = (instance + 1) as u8;
    let mav_type = gcs::GroundStation::mav_type(airframe.rotors.len());
    let LogPaths {
        flight_csv,
        tlog,
        ulog,
    } = log_paths(cfg, instance, &params.logger, &mut notices);
    if let Some(path) = &flight_csv {
        records.log_to(
            FlightCsv::create(path, airframe.rotors.len(), source.lockstep())
                .with_context(|| format!("creating {}", path.display()))?,
        );
    }
    let tlog_path = tlog.clone();
    let tlog = match &tlog {
        Some(path) => Some(
            records::log_files::Tlog::create(path)
                .with_context(|| format!("creating {}", path.display()))?,
        ),
        None => None,
    };
    let mut ulog_events = None;
    if let Some(path) = &ulog {
        let log = open_ulog(path, &params, system_id, mav_type as u8, airframe, source)?;
        ulog_events = log.events();
        records.log_ulog_to(log);
    }
    if flight_csv.is_some() || tlog.is_some() || ulog.is_some() {
        tracing::info!(
            tlog = ?tlog.as_ref().map(|t| t.path()),
            ulog = ?ulog,
            flight_csv = ?flight_csv,
            "logging"
        );
    }
    let endpoints = cfg
        .mavlink
        .iter()
        .filter(|u| u.as_str() != "none")
        .map(|u| gcs_links::EndpointSpec::parse(u, instance))
        .collect::<Result<Vec<_>>>()
        .context("--mavlink")?;
    let (signing_key, signing_memory) = load_signing(cfg, &mut notices)?;
    let busy = [&ulog, &tlog_path, &flight_csv]
        .into_iter()
        .flatten()
        .cloned()
        .collect();
    let served = !endpoints.is_empty();
    let (files, metadata) = files_config(cfg, airframe, ulog.as_ref(), busy, served);
    let (mut ports, ends) = Ports::new(16);
    let (params_tx, params_rx) = watch::channel(params.clone());
    ports.params = Some(params_rx);
    ports.announce_ready = Some(system_id);
    Ok(Prepared {
        system_id,
        autopilot,
        records,
        ports,
        endpoints,
        gcs: gcs_links::Vehicle {
            system_id,
            mav_type,
            telemetry: ends.telemetry,
            commands: ends.commands,
            answers: ends.answers,
            parameters: gcs::params::Parameters::new(params, store),
            base_params: base,
            params: params_tx,
            notices,
            signing_key,
            signing_key_file: cfg.signing_key_file.clone(),
            signing_memory,
            tlog,
            ulog: ulog_events,
            files,
            metadata,
            reboot_allowed: cfg.count == 1,
        },
    })
}

/// The flight log at `path`, its header saying the parameters, the vehicle and its source.
fn open_ulog(
    path: &Path,
    params: &FlightParams,
    system_id: u8,
    mav_type: u8,
    airframe: &Airframe,
    source: &Source,
) -> Result<FlightUlog> {
    let start = UlogStart {
        params: params.clone(),
        system_id,
        mav_type,
        airframe: airframe.name.clone(),
        unix_start_us: std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_micros() as u64),
        lockstep: source.lockstep(),
    };
    FlightUlog::create(path, start).with_context(|| format!("creating {}", path.display()))
}

/// The flight parameters: the file's (with what the source presets), then the store's over
/// them. Returns the base values (what a reset returns to), the values flown and the store;
/// what the first ground station is told goes to `notices`.
fn load_params(
    cfg: &Settings,
    source: &Source,
    instance: u16,
    notices: &mut Vec<String>,
) -> Result<(FlightParams, FlightParams, ParamStore)> {
    let mut base = FlightParams::load(&cfg.params_path())?;
    source.preset_params(&mut base);
    let (params, store) = match cfg.param_store(instance) {
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
    Ok((base, params, store))
}

/// The signing key and what signing remembered, from the key's file (none: signing off).
fn load_signing(
    cfg: &Settings,
    notices: &mut Vec<String>,
) -> Result<(Option<SecretKey>, SigningMemory)> {
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
    Ok((signing_key, signing_memory))
}

/// What MAVLink FTP and the log download serve (the logs being written, `busy`, protected),
/// with the component metadata in its virtual folder; the metadata's URI and CRC when FTP
/// serves it. Without a ground-station endpoint (`served` false) nothing can ask for the
/// metadata, and it is not made (a quarter of a minimal flight's start-up).
fn files_config(
    cfg: &Settings,
    airframe: &Airframe,
    ulog: Option<&PathBuf>,
    busy: Vec<PathBuf>,
    served: bool,
) -> (vehicle_files::FilesConfig, Option<(String, u32)>) {
    let mut files = vehicle_files::FilesConfig {
        ftp_root: cfg.ftp_root().map(Path::to_path_buf),
        logs: cfg.log_dir().map(Path::to_path_buf).or_else(|| {
            // `--ulog x.ulg` names a file here: its directory is `.`.
            let dir = ulog?.parent()?;
            let dir = if dir.as_os_str().is_empty() {
                Path::new(".")
            } else {
                dir
            };
            Some(dir.to_path_buf())
        }),
        writable: !cfg.ftp_read_only,
        busy,
        virtual_dir: vehicle_files::VirtualDir::default(),
    };
    if !served {
        return (files, None);
    }
    // The component metadata, read by FTP: named only when FTP serves it.
    let metadata = ComponentMetadata::new(&airframe.name, gcs::COMPONENT_ID);
    files.virtual_dir = vehicle_files::VirtualDir {
        name: METADATA_DIR.to_owned(),
        files: metadata
            .files
            .iter()
            .map(|(name, bytes)| (name.clone(), bytes.as_slice().into()))
            .collect(),
    };
    let metadata = files
        .ftp_root
        .is_some()
        .then_some((metadata.uri, metadata.crc));
    (files, metadata)
}

/// The embedded simulator's sensor preset.
pub(super) fn sensor_preset(cfg: &Settings) -> Result<SensorPreset> {
    crate::settings::sensor_preset(&cfg.sensors)
}

/// A run's log files.
struct LogPaths {
    flight_csv: Option<PathBuf>,
    tlog: Option<PathBuf>,
    ulog: Option<PathBuf>,
}

/// The run's flight-data CSV, telemetry log and flight log: those named, else
/// `LOG_DIR/<start time>.csv`, `.tlog` and `.ulg`, the oldest runs there removed first as
/// `logger` (`SDLOG_*`) keeps the directory. A log directory that cannot be made costs the
/// default logs, not the flight: it is said in the log and to the first ground station.
fn log_paths(
    cfg: &Settings,
    instance: u16,
    logger: &LoggerGroup,
    notices: &mut Vec<String>,
) -> LogPaths {
    let min_free = u64::from(logger.min_free_mb) * 1_000_000;
    records::log_budget::keep_free(min_free);
    records::log_budget::rotate_at(u64::from(logger.max_size_mb) * 1_000_000, logger.rotate);
    let all_named = cfg.flight_csv.is_some() && cfg.tlog.is_some() && cfg.ulog.is_some();
    let stem = cfg.log_dir().filter(|_| !all_named).and_then(|dir| {
        // Once a process, before its first vehicle's logs (not between its vehicles').
        if instance == cfg.instance && dir.is_dir() {
            match records::log_budget::make_room(dir, logger.dirs_max, min_free) {
                Ok(removed) if !removed.is_empty() => {
                    tracing::info!(dir = %dir.display(), files = removed.len(), "oldest logs removed (SDLOG_DIRS_MAX, SDLOG_MIN_FREE)");
                }
                Ok(_) => {}
                Err(e) => tracing::warn!(dir = %dir.display(), "removing the oldest logs: {e}"),
            }
        }
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
    LogPaths {
        flight_csv: match cfg.flight_csv.as_deref() {
            Some(p) if p == Path::new("none") => None,
            Some(p) => Some(p.to_path_buf()),
            None => default("csv"),
        },
        tlog: cfg.tlog.clone().or_else(|| default("tlog")),
        ulog: cfg.ulog.clone().or_else(|| default("ulg")),
    }
}
