//! A flight: the vehicle made ready ([`prepare()`]), the control loop on its own thread, and on
//! this one the tasks around it (ground-station links, Ctrl-C, the status line: [`console`])
//! until the loop ends; the summary line; a reboot when a ground station asked for one.

mod console;
mod prepare;
mod world;

use crate::control_loop::{self, FlightReport, LoopCommand, Onboard, Pacing, Ports};
use crate::devices::{GpsPort, GpsSpec, RcPort, RcSpec, WithDevices};
use crate::gcs_links;
use crate::links::sim::{self, EmbeddedSim};
use crate::links::{SensorLink, SerialLink, Source, UdpLink, json_link};
use crate::records::FlightRecords;
use crate::settings::Settings;
use anyhow::{Context, Result, bail};
use console::{interrupts, status_line};
use flight_core::autopilot::Autopilot;
use flight_core::math::geo::LatLonAlt;
use gcs::telemetry::Telemetry;
use prepare::{Prepared, prepare, sensor_preset};
use sitl_core::Airframe;
use std::time::Duration;
use tokio::sync::{mpsc, watch};

/// Flies what the settings say: one vehicle on its sensor link, or `--count` vehicles in the
/// embedded simulator, each with its ground stations, until the flight ends; then the summary
/// line (and a reboot if a ground station asked for one).
pub fn fly(cfg: Settings) -> Result<()> {
    let source = Source::parse(cfg.source(), cfg.instance)?;
    if source != Source::Embedded && cfg.truth_csv.is_some() {
        bail!(
            "--truth-csv is for the embedded simulator; an external one writes its own (sitl --truth-csv)"
        );
    }
    if source != Source::Embedded && (cfg.scenario.is_some() || cfg.sim_control.is_some()) {
        bail!(
            "--scenario and --sim-control are for the embedded simulator; an external one takes its own (sitl --scenario, sitl --control)"
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
        control_loop::deadline::keep_off_cpu(cpu)?;
    }
    let Prepared {
        system_id,
        mut autopilot,
        mut records,
        mut ports,
        endpoints,
        gcs,
    } = prepare(&cfg, &source, &airframe, cfg.instance)?;
    let deadlines = deadline_pacing(&cfg);
    let gps = cfg
        .gps
        .as_deref()
        .map(GpsSpec::parse)
        .transpose()?
        .map(GpsPort::new);
    let rc = cfg
        .rc
        .as_deref()
        .map(RcSpec::parse)
        .transpose()?
        .map(RcPort::new);
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
                control_loop::deadline::pin_to_cpu(cpu)?;
                tracing::info!(cpu, "control loop pinned");
            }
            let vehicle = (&mut autopilot, &mut records, ports);
            fly_link(
                source,
                &cfg,
                &airframe,
                (gps, rc),
                system_id,
                deadlines,
                vehicle,
            )
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
    print_summary(&report);
    if exits.first() == Some(&Some(gcs::HostAction::Reboot)) {
        reboot()?;
    }
    Ok(())
}

/// The vehicle's parts the control loop flies, borrowed for one flight.
type Parts<'a> = (&'a mut Autopilot, &'a mut FlightRecords, &'a mut Ports);

/// One vehicle flown on its source's link, its own devices (a GPS) beside it, to the
/// flight's report.
fn fly_link(
    source: Source,
    cfg: &Settings,
    airframe: &Airframe,
    (gps, rc): (Option<GpsPort>, Option<RcPort>),
    system_id: u8,
    deadlines: Pacing,
    (autopilot, records, ports): Parts<'_>,
) -> Result<FlightReport> {
    match source {
        Source::Embedded => {
            let link = world::embedded_link(cfg, airframe, cfg.instance)?;
            let mut link = WithDevices::new(link, gps, rc).telling(ports.telemetry.subscribe());
            let report = control_loop::fly(
                onboard(&mut link, autopilot, records, ports),
                Pacing::Lockstep,
            )?;
            link.inner_mut().finish()?;
            finish(records, report)
        }
        Source::Udp { addr, lockstep } => {
            let link = UdpLink::bind(addr, lockstep, system_id)?;
            let local = link.local_addr()?;
            tracing::info!(listening = %local, airframe = %airframe.name, "waiting for a simulator");
            // Scripts read this line to learn the port (a port 0 is the system's choice).
            println!("autopilot sensor-link: system={system_id} udp://{local}");
            let mut link = WithDevices::new(link, gps, rc).telling(ports.telemetry.subscribe());
            let pacing = if lockstep {
                Pacing::Lockstep
            } else {
                deadlines
            };
            let report = control_loop::fly(onboard(&mut link, autopilot, records, ports), pacing)?;
            finish(records, report)
        }
        Source::Json { addr, channels } => {
            let channels = json_channels(channels, airframe)?;
            let sensors = sensor_preset(cfg)?;
            let link = json_link::JsonLink::connect(
                addr,
                channels,
                sensors,
                cfg.seed,
                sitl_core::geo::home_for_instance(&LatLonAlt::default(), cfg.instance),
            )
            .with_context(|| format!("opening a UDP socket for {addr}"))?;
            tracing::info!(physics = %addr, airframe = %airframe.name, "sending servo packets to a JSON physics");
            let mut link = WithDevices::new(link, gps, rc).telling(ports.telemetry.subscribe());
            let report = control_loop::fly(
                onboard(&mut link, autopilot, records, ports),
                Pacing::Lockstep,
            )?;
            finish(records, report)
        }
        Source::Serial {
            path,
            baud,
            lockstep,
        } => {
            let link = SerialLink::open(path, baud, lockstep, system_id)?;
            tracing::info!(port = %link.describe(), airframe = %airframe.name, "waiting for the flight board");
            let mut link = WithDevices::new(link, gps, rc).telling(ports.telemetry.subscribe());
            let pacing = if lockstep {
                Pacing::Lockstep
            } else {
                deadlines
            };
            let report = control_loop::fly(onboard(&mut link, autopilot, records, ports), pacing)?;
            finish(records, report)
        }
    }
}

/// The pacing of a loop that does not wait for its link: the settings' deadlines.
fn deadline_pacing(cfg: &Settings) -> Pacing {
    Pacing::Deadlines {
        period: Duration::from_secs_f64(1.0 / cfg.loop_hz),
        spin: Duration::from_secs_f64(cfg.loop_spin_us * 1e-6),
        stats: Duration::from_secs_f64(cfg.loop_stats_s),
    }
}

/// The summary line, with the process's peak memory (the bench quotes it).
fn print_summary(report: &FlightReport) {
    match peak_rss_kib() {
        Some(kib) => println!("{report} max_rss_kib={kib}"),
        None => println!("{report}"),
    }
}

/// What the control loop flies: `link`, and the vehicle's autopilot, records and channels.
fn onboard<'a>(
    link: &'a mut dyn SensorLink,
    autopilot: &'a mut Autopilot,
    records: &'a mut FlightRecords,
    ports: &'a mut Ports,
) -> Onboard<'a> {
    Onboard {
        link,
        autopilot,
        records,
        ports,
    }
}

/// The servo channel of each rotor on a JSON physics: as given (one per rotor), or in order.
fn json_channels(channels: Vec<usize>, airframe: &Airframe) -> Result<Vec<usize>> {
    let rotors = airframe.rotors.len();
    if channels.is_empty() {
        Ok((0..rotors).collect())
    } else if channels.len() == rotors {
        Ok(channels)
    } else {
        bail!(
            "json://…?channels= names {} channels for the {rotors} rotors of {}",
            channels.len(),
            airframe.name
        );
    }
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
) -> Result<Vec<Option<gcs::HostAction>>> {
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .context("starting the async runtime")?;
    let exits = runtime.block_on(async move {
        // A vehicle whose links cannot open stops every vehicle of the process (`--count`).
        let links: Vec<_> = vehicles
            .into_iter()
            .map(|(endpoints, vehicle)| {
                let stop_all = commands.clone();
                tokio::spawn(async move {
                    let run = gcs_links::run(endpoints, vehicle).await;
                    if run.is_err() {
                        for c in &stop_all {
                            let _ = c.send(LoopCommand::Stop).await;
                        }
                    }
                    run
                })
            })
            .collect();
        tokio::spawn(interrupts(commands));
        status_line(telemetry, ended).await;
        // The ground-station side ends with the loop, after its last save.
        let mut exits = Vec::with_capacity(links.len());
        for l in links {
            exits.push(match l.await {
                Ok(exit) => exit,
                Err(e) => Err(anyhow::anyhow!("the ground-station links failed: {e}")),
            });
        }
        exits
    });
    drop(runtime);
    exits.into_iter().collect()
}

/// `--count N`: N vehicles in the embedded simulator, flown together on one control-loop thread
/// in lockstep on one clock ([`control_loop::fly_together`]), each with its own ground stations.
fn fly_together(cfg: Settings, source: Source) -> Result<()> {
    refuse_one_vehicles_files(&cfg, &source)?;
    let airframe = Airframe::load(&cfg.airframe_path())?;
    let mut vehicles = Vec::with_capacity(cfg.count.into());
    let mut sims = Vec::with_capacity(cfg.count.into());
    for k in 0..cfg.count {
        let p = prepare(&cfg, &source, &airframe, cfg.instance + k)?;
        let sim = world::simulator(&cfg, &airframe, cfg.instance + k, k)?;
        sims.push(EmbeddedSim::around(sim, None, None)?);
        vehicles.push(p);
    }
    // They share the log directory: none may erase or change another's logs being written.
    let busy: Vec<_> = vehicles
        .iter()
        .flat_map(|p| p.gcs.files.busy.clone())
        .collect();
    for p in &mut vehicles {
        p.gcs.files.busy.clone_from(&busy);
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
    let speed = cfg.realtime_factor()?;
    let ended = std::sync::Arc::new(tokio::sync::Notify::new());
    let ended_guard = LoopEnded(ended.clone());
    let control = std::thread::Builder::new()
        .name("control-loop".into())
        .spawn(move || -> Result<control_loop::SwarmReport> {
            let _ended = ended_guard;
            let members = cores
                .iter_mut()
                .zip(sims.iter_mut())
                .map(|((_, autopilot, records, ports), sim)| Onboard {
                    link: sim,
                    autopilot,
                    records,
                    ports,
                })
                .collect();
            let mut report = control_loop::fly_together(members, sim::EXCHANGE_HZ, speed);
            for ((system_id, _, records, _), flight) in cores.iter_mut().zip(&mut report.flights) {
                if let Err(e) = records.finish() {
                    tracing::error!("system {system_id}: {e:#}: the logs end there");
                    if let Ok(f) = flight {
                        f.set_logs_stopped();
                    }
                }
            }
            Ok(report)
        })
        .context("starting the control loop")?;
    serve(links, commands, telemetry, ended)?;
    let report = control
        .join()
        .map_err(|_| anyhow::anyhow!("the control loop panicked"))??;
    swarm_summary(&cfg, &report)
}

/// What `--count` cannot fly: another source than the embedded simulator, files named for
/// one vehicle.
fn refuse_one_vehicles_files(cfg: &Settings, source: &Source) -> Result<()> {
    if *source != Source::Embedded {
        bail!(
            "--count flies vehicles in the embedded simulator (--sim); with simulator processes or flight boards run one autopilot per vehicle, each with its own --instance"
        );
    }
    if cfg.sim_control.is_some() {
        bail!(
            "--sim-control sets one vehicle's clock; vehicles flown together share one, paced by --speed"
        );
    }
    if cfg.gps.is_some() {
        bail!(
            "--gps names one vehicle's serial port; --count flies vehicles without their own devices"
        );
    }
    if cfg.truth_csv.is_some()
        || cfg
            .flight_csv
            .as_deref()
            .is_some_and(|p| p != std::path::Path::new("none"))
        || cfg.tlog.is_some()
        || cfg.ulog.is_some()
    {
        bail!(
            "--truth-csv, --flight-csv, --tlog and --ulog name one vehicle's file; with --count every vehicle logs to --log-dir"
        );
    }
    if let Some(p) = cfg.named_param_store() {
        bail!(
            "--param-store {} names one vehicle's file; with --count every vehicle keeps its own (the default) or none",
            p.display()
        );
    }
    Ok(())
}

/// Each vehicle's summary line, then the swarm's; an error if any vehicle's flight ended in
/// one.
fn swarm_summary(cfg: &Settings, report: &control_loop::SwarmReport) -> Result<()> {
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

/// Flushes the vehicle's logs and hands the report on. Logs that stopped (a full disk, a
/// directory gone) do not fail the flight: they end where the fault was, and the summary says
/// so.
fn finish(records: &mut FlightRecords, mut report: FlightReport) -> Result<FlightReport> {
    if let Err(e) = records.finish() {
        tracing::error!("{e:#}: the logs end there");
        report.set_logs_stopped();
    }
    Ok(report)
}
