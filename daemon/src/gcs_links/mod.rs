//! The links to ground stations (tokio tasks), like mavlink-router: several endpoints at once,
//! every frame the vehicle sends goes out on all of them, every frame received on any of them
//! reaches the one [`GroundStation`].
//!
//! - `udpout://HOST:PORT?bind=LOCAL`: pushes to HOST:PORT (where QGroundControl, pymavlink or
//!   MAVSDK listen) from the bound LOCAL port, and also answers every peer that writes to it.
//! - `udpin://ADDR:PORT`: a bound port that answers every peer that writes to it.
//! - `tcpin://ADDR:PORT`: a TCP server; every client gets the stream.
//!
//! Every endpoint also takes `trusted` (a physically secure link, such as a USB cable: exempt
//! from signing, and the only kind that may set the signing key) and `sysids=255,250` (only
//! these systems are heard; others are refused).
//!
//! A frame that does not parse is counted and dropped; it never closes a link. With a signing
//! key ([`gcs::signing`]) frames that are unsigned, wrongly signed or replayed are refused
//! before they are parsed, and the vehicle's frames go out signed. A UDP peer is answered only
//! once it has sent a frame that was accepted. Sending never waits on a slow peer: a link that
//! falls behind loses frames, not the vehicle's time.

pub mod endpoint;
mod guard;
mod signing;
#[cfg(test)]
mod tests;
mod transport;

pub use endpoint::EndpointSpec;

use crate::control_loop::LoopCommand;
use crate::records::flight_ulog::UlogEvents;
use crate::records::log_files::Tlog;
use crate::records::param_file;
use anyhow::Result;
use flight_core::autopilot::command::AutopilotCommand;
use flight_core::commander::Denial;
use flight_core::params::FlightParams;
use gcs::param_store::{Loaded, ParamStore, Unreadable};
use gcs::params::Parameters;
use gcs::signing::{SecretKey, Signing, SigningMemory};
use gcs::telemetry::Telemetry;
use gcs::{AckTo, COMPONENT_ID, GroundStation, HostAction, LinkId, Outbox, Outgoing};
use vehicle_files::{FileServices, FilesConfig};

use guard::Guard;
use hil::Encoder;
use mavlink::dialects::common::{MavMessage, MavSeverity, MavType};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tokio::sync::{broadcast, mpsc, oneshot, watch};
use transport::{Frame, Inbound, Notices, open};

/// PX4 SITL's links: QGroundControl and MAVSDK ports pushed to, each from its own bound port,
/// and a TCP server.
pub const DEFAULT_ENDPOINTS: [&str; 3] = [
    "udpout://127.0.0.1:14550?bind=18570&shared",
    "udpout://127.0.0.1:14540?bind=14580",
    "tcpin://127.0.0.1:5760",
];

/// How often the streams are looked at.
const POLL: Duration = Duration::from_millis(10);
/// How long a command waits for the control loop's answer.
const ANSWER_TIMEOUT: Duration = Duration::from_secs(2);

/// The vehicle side the links serve.
pub struct Vehicle {
    /// MAVLink system id.
    pub system_id: u8,
    /// MAVLink vehicle type.
    pub mav_type: MavType,
    /// The control loop's latest telemetry.
    pub telemetry: watch::Receiver<Telemetry>,
    /// Commands to the control loop.
    pub commands: mpsc::Sender<LoopCommand>,
    /// The parameter table and its store.
    pub parameters: Parameters,
    /// The values a parameter reset returns to.
    pub base_params: FlightParams,
    /// The parameters the control loop flies with.
    pub params: watch::Sender<FlightParams>,
    /// What the first ground station to connect is told (`STATUSTEXT` warnings, ≤ 50 bytes
    /// each), such as a damaged parameter store.
    pub notices: Vec<String>,
    /// The MAVLink signing key (none: signing off), and the file a key set by `SETUP_SIGNING`
    /// is kept in.
    pub signing_key: Option<SecretKey>,
    /// Where a key set by `SETUP_SIGNING` is saved (none: kept in memory only); signing's
    /// memory is kept beside it.
    pub signing_key_file: Option<std::path::PathBuf>,
    /// What signing remembered from the run before (its clock, each stream's last timestamp).
    pub signing_memory: SigningMemory,
    /// The MAVLink telemetry log, if one is kept.
    pub tlog: Option<Tlog>,
    /// The flight log's way in for what is said and parameter changes, if one is kept.
    pub ulog: Option<UlogEvents>,
    /// What MAVLink FTP and the log download serve.
    pub files: FilesConfig,
    /// The general component-metadata file's URI and CRC, when FTP serves it.
    pub metadata: Option<(String, u32)>,
    /// Whether a reboot is allowed: it restarts the process, so not for one of several
    /// vehicles in it.
    pub reboot_allowed: bool,
}

/// Messages of file transfers (FTP burst reads, log downloads) sent per poll: with a poll
/// every 10 ms, up to 12 800 a second, on the requester's link whatever its speed. Over
/// loopback UDP that is 1.7 MiB/s of FTP to pymavlink and 1.1 MiB/s of log download to MAVSDK
/// (the clients' own pace: tests/python/test_files.py).
const FILES_PER_POLL: usize = 128;

/// How often refused frames are reported in the log.
const REFUSALS_REPORT: Duration = Duration::from_secs(5);

/// Microseconds since the Unix epoch.
fn unix_usec() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_micros() as u64)
}

/// Saves every store it is handed, the latest first (a burst of sets is one write), and says
/// so when a save fails.
async fn saver(mut stores: watch::Receiver<Option<ParamStore>>, notices: Notices) {
    while stores.changed().await.is_ok() {
        let Some(store) = stores.borrow_and_update().clone() else {
            continue;
        };
        let result = tokio::task::spawn_blocking(move || param_file::save(&store)).await;
        let failure = match result {
            Ok(Ok(())) => continue,
            Ok(Err(e)) => format!("{e:#}"),
            Err(e) => format!("saving parameters: {e}"),
        };
        tracing::error!("{failure}");
        let _ = notices
            .send((
                MavSeverity::MAV_SEVERITY_ERROR,
                format!("parameters not saved: {failure}"),
            ))
            .await;
    }
}

/// Runs the ground-station side until the control loop ends: opens `endpoints`, answers what
/// arrives, streams telemetry, passes vehicle commands and parameters to the control loop and
/// saves the parameter store. Returns the reboot or shutdown a ground station asked for, once
/// the store is saved; an endpoint that cannot be opened (and is not `optional`) stops the
/// control loop and is the error.
pub async fn run(endpoints: Vec<EndpointSpec>, vehicle: Vehicle) -> Result<Option<HostAction>> {
    let Vehicle {
        system_id,
        mav_type,
        mut telemetry,
        commands,
        parameters,
        base_params,
        params,
        notices: mut startup_notices,
        signing_key,
        signing_key_file,
        signing_memory,
        mut tlog,
        mut ulog,
        files,
        metadata,
        reboot_allowed,
    } = vehicle;
    let mut files = FileServices::new(system_id, COMPONENT_ID, &files);
    let mut files_out = Vec::new();
    tracing::info!(
        "MAVLink signing {}",
        if signing_key.is_some() {
            "on: unsigned, wrongly signed and replayed frames are refused"
        } else {
            "off"
        }
    );
    let mut memory = signing::MemoryKeeper::new(signing_key_file.as_deref());
    let mut restored = Signing::new(signing_key);
    restored.remember(&signing_memory);
    let signing = Arc::new(Mutex::new(restored));
    let not_allowed = Arc::new(AtomicU64::new(0));
    let (frames, _) = broadcast::channel::<Frame>(1024);
    let (inbound_tx, mut inbound) = mpsc::channel::<Inbound>(256);
    let (answers_tx, mut answers) = mpsc::channel::<(AckTo, Result<(), Denial>)>(64);
    let (notices_tx, mut notices) = mpsc::channel::<(MavSeverity, String)>(8);
    let (save_tx, save_rx) = watch::channel(None::<ParamStore>);
    let saving = tokio::spawn(saver(save_rx, notices_tx.clone()));
    let mut gcs = GroundStation::new(system_id, mav_type);
    if let Some((uri, crc)) = &metadata {
        gcs = gcs.with_component_metadata(uri, *crc);
    }
    let mut gcs = gcs
        .with_parameters(parameters, base_params)
        .with_reboot(reboot_allowed)
        .with_unix_start(unix_usec());
    for (link, e) in endpoints.iter().enumerate() {
        let link = LinkId::try_from(link).unwrap_or(LinkId::MAX);
        gcs.add_link(link);
        let guard = Guard {
            options: e.options.clone(),
            signing: signing.clone(),
            not_allowed: not_allowed.clone(),
            link,
        };
        let optional = e.options.optional;
        match open(e, guard, &inbound_tx, &frames, &notices_tx).await {
            Ok(()) => {}
            Err(e) if optional => {
                tracing::warn!("optional ground-station endpoint not opened: {e:#}")
            }
            Err(e) => {
                // Flying on without a link the user asked for would be worse: stop.
                let _ = commands.send(LoopCommand::Stop).await;
                return Err(e.context(
                    "a ground-station endpoint could not be opened (another program or vehicle holds the port? give it `-i N`, or mark the endpoint `?optional`)",
                ));
            }
        }
    }
    // One encoder (one sequence) per link, so that each ground station sees its link's
    // sequence without gaps; at least one, for the telemetry log.
    let mut encoders: Vec<Encoder> = (0..endpoints.len().max(1))
        .map(|_| Encoder::with_ids(system_id, COMPONENT_ID))
        .collect();
    let mut out = Outbox::default();
    let mut tick = tokio::time::interval(POLL);
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    let start = Instant::now();
    let mut malformed = 0u64;
    let mut exit = None;
    let mut pending = std::collections::VecDeque::new();
    let mut refusals_reported = (Default::default(), 0u64);
    let mut refusals_next = Instant::now();
    loop {
        tokio::select! {
            Some(i) = inbound.recv() => {
                malformed += i.malformed as u64;
                if let Some(log) = tlog.as_mut() {
                    log_heard(log, &i);
                }
                let t = *telemetry.borrow();
                for (h, m) in &i.messages {
                    match m {
                        m if FileServices::handles(m) => {
                            let now = start.elapsed().as_secs_f64();
                            files.on_message(i.link, h, m, now, &mut files_out);
                        }
                        MavMessage::SETUP_SIGNING(d) if d.target_system == system_id => {
                            let (severity, text) =
                                signing::setup_signing(&signing, signing_key_file.as_deref(), d, i.trusted);
                            out.say(severity, &text);
                        }
                        MavMessage::SERIAL_CONTROL(d) => {
                            // The shell: with signing on, on a trusted endpoint only.
                            let signing_on =
                                signing.lock().unwrap_or_else(|e| e.into_inner()).active();
                            let allowed = i.trusted || !signing_on;
                            gcs.on_serial_control(i.link, h, d, allowed, &t, &mut out);
                        }
                        _ => gcs.on_link_message(i.link, h, m, &t, &mut out),
                    }
                }
                for raw in &i.unparsed {
                    gcs.on_unparsed(raw, &mut out);
                }
            }
            Some((to, result)) = answers.recv() => gcs.answered(to, result, &mut out),
            Some((severity, text)) = notices.recv() => {
                out.say(severity, &text);
            }
            // A stream faster than the tick: polled on every sensor sample as well.
            changed = telemetry.changed(), if gcs.wants_every_sample() => {
                if changed.is_err() {
                    break;
                }
                let t = *telemetry.borrow_and_update();
                gcs.poll(start.elapsed().as_secs_f64(), &t, &mut out);
            }
            _ = tick.tick() => {
                let t = *telemetry.borrow_and_update();
                if t.finished || telemetry.has_changed().is_err() {
                    break;
                }
                gcs.poll(start.elapsed().as_secs_f64(), &t, &mut out);
                files.poll(start.elapsed().as_secs_f64(), FILES_PER_POLL, &mut files_out);
                if let Some(log) = tlog.as_mut()
                    && let Err(e) = log.ship_if_due(unix_usec())
                {
                    // A full disk stops the log, not the links.
                    tracing::error!(file = %log.path().display(), "telemetry log: {e}; logging stopped");
                    tlog = None;
                }
                if let Some(m) = memory.as_mut() {
                    m.note(&signing);
                }
                if Instant::now() >= refusals_next {
                    refusals_next = Instant::now() + REFUSALS_REPORT;
                    let now = (
                        signing.lock().unwrap_or_else(|e| e.into_inner()).refused,
                        not_allowed.load(Ordering::Relaxed),
                    );
                    if now != refusals_reported {
                        refusals_reported = now;
                        let (r, n) = now;
                        tracing::warn!(
                            unsigned = r.unsigned,
                            bad_signature = r.bad_signature,
                            replayed = r.replayed,
                            future = r.future,
                            not_on_allow_list = n,
                            "frames refused so far"
                        );
                    }
                }
            }
        }
        for (cmd, to) in out.vehicle.drain(..) {
            let (tx, rx) = oneshot::channel();
            if commands
                .try_send(LoopCommand::Autopilot(cmd, Some(tx)))
                .is_err()
            {
                let _ = answers_tx.try_send((to, Err(Denial::Busy)));
                continue;
            }
            let answers = answers_tx.clone();
            tokio::spawn(async move {
                let result = match tokio::time::timeout(ANSWER_TIMEOUT, rx).await {
                    Ok(Ok(r)) => r,
                    _ => Err(Denial::NoAnswer),
                };
                let _ = answers.send((to, result)).await;
            });
        }
        if std::mem::take(&mut out.gcs_heartbeat) {
            let _ = commands.try_send(LoopCommand::GcsHeartbeat);
            for text in startup_notices.drain(..) {
                out.say(MavSeverity::MAV_SEVERITY_WARNING, &text);
            }
        }
        if let Some(sticks) = out.sticks.take() {
            // A full queue loses these sticks only: the next ones follow within 50 ms.
            let _ = commands.try_send(LoopCommand::Autopilot(
                AutopilotCommand::Sticks(sticks),
                None,
            ));
        }
        // Plans must arrive (they were acknowledged): a full queue keeps them, in order, for the
        // next turn of this loop; a newer plan of a kind replaces one still waiting.
        if let Some(items) = out.mission.take() {
            pending.retain(|c| !matches!(c, AutopilotCommand::SetMission(_)));
            pending.push_back(AutopilotCommand::SetMission(items));
        }
        if let Some(zones) = out.fence.take() {
            pending.retain(|c| !matches!(c, AutopilotCommand::SetFence(_)));
            pending.push_back(AutopilotCommand::SetFence(zones));
        }
        while let Some(c) = pending.pop_front() {
            if let Err(mpsc::error::TrySendError::Full(LoopCommand::Autopilot(c, _))) =
                commands.try_send(LoopCommand::Autopilot(c, None))
            {
                pending.push_front(c);
                break;
            }
        }
        if let Some(target) = out.offboard.take() {
            // Likewise a set-point of a stream.
            let _ = commands.try_send(LoopCommand::Autopilot(
                AutopilotCommand::Offboard(target),
                None,
            ));
        }
        for action in std::mem::take(&mut out.actions) {
            match action {
                HostAction::ParamsChanged => {
                    fly_with(&params, gcs.parameters().values(), ulog.as_mut());
                }
                HostAction::SaveParams => {
                    save_tx.send_replace(Some(gcs.parameters().store().clone()));
                }
                HostAction::ReloadParams(to) => {
                    let loaded = match gcs.parameters().store().path() {
                        Some(path) => param_file::load(path, gcs.base_parameters())
                            .map_err(|e| Unreadable(format!("{e:#}"))),
                        None => Ok(Loaded {
                            store: gcs.parameters().store().clone(),
                            params: gcs.parameters().values().clone(),
                            warnings: Vec::new(),
                            from_previous_copy: false,
                        }),
                    };
                    gcs.params_reloaded(to, loaded, &mut out);
                    fly_with(&params, gcs.parameters().values(), ulog.as_mut());
                }
                HostAction::Reboot | HostAction::Shutdown => {
                    exit = Some(action);
                    // Disarmed (checked before): the loop may stop at once.
                    let _ = commands.try_send(LoopCommand::Stop);
                }
            }
        }
        out.streamed.extend(
            files_out
                .drain(..)
                .map(|(link, m)| (link, Outgoing::Message(m))),
        );
        let said = out.said.drain(..);
        if let Some(log) = ulog.as_mut() {
            let t_us = (telemetry.borrow().t_s * 1e6) as u64;
            for (severity, text) in said {
                log.said(severity as u8, t_us, &text);
            }
            log.flush();
        }
        if !out.messages.is_empty() || !out.streamed.is_empty() {
            signing
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .tick(unix_usec());
        }
        // A message for every link goes out on each in its own sequence; the telemetry log
        // records what link 0 carries.
        let links = encoders.len() as LinkId;
        let everywhere = out
            .messages
            .drain(..)
            .flat_map(|m| (0..links).map(move |l| (l, m.clone())));
        let one_link = out.streamed.drain(..);
        for (link, m) in everywhere.chain(one_link) {
            let Some(encoder) = encoders.get_mut(usize::from(link)) else {
                continue;
            };
            let mut bytes = Vec::with_capacity(64);
            match &m {
                Outgoing::Message(m) => encoder.push(&mut bytes, m),
                Outgoing::Raw(id, payload) => encoder.push_raw(&mut bytes, *id, payload),
            }
            signing
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .sign(&mut bytes);
            // File transfers stay out of it: a log downloaded would grow the log.
            let transfer = matches!(
                m,
                Outgoing::Message(
                    MavMessage::FILE_TRANSFER_PROTOCOL(_)
                        | MavMessage::LOG_DATA(_)
                        | MavMessage::LOG_ENTRY(_)
                )
            );
            if link == 0
                && !transfer
                && let Some(log) = tlog.as_mut()
            {
                log.record(unix_usec(), &bytes);
            }
            // No endpoint listening is not an error.
            let _ = frames.send((link, bytes.into()));
        }
    }
    if let Some(m) = memory {
        m.finish(&signing).await;
    }
    let refused = signing.lock().unwrap_or_else(|e| e.into_inner()).refused;
    tracing::info!(
        malformed,
        dropped = gcs.dropped,
        refused_unsigned = refused.unsigned,
        refused_bad_signature = refused.bad_signature,
        refused_replayed = refused.replayed,
        refused_future = refused.future,
        refused_not_on_allow_list = not_allowed.load(Ordering::Relaxed),
        "ground-station links closed"
    );
    if let Some(lost) = ulog.map(|u| u.lost).filter(|&n| n > 0) {
        tracing::warn!(
            lost,
            "flight log: batches of texts and parameter changes lost"
        );
    }
    if let Some(log) = tlog {
        let path = log.path().to_owned();
        match tokio::task::spawn_blocking(move || log.finish()).await {
            Ok(Ok(())) => tracing::info!(file = %path.display(), "telemetry log written"),
            Ok(Err(e)) => tracing::error!(file = %path.display(), "telemetry log: {e}"),
            Err(e) => tracing::error!(file = %path.display(), "telemetry log: {e}"),
        }
    }
    drop(save_tx);
    let _ = saving.await;
    Ok(exit)
}

/// Hands the parameters `now` to the control loop, and logs in the flight log each one that
/// changed.
fn fly_with(
    params: &watch::Sender<FlightParams>,
    now: &FlightParams,
    log: Option<&mut UlogEvents>,
) {
    let before = params.send_replace(now.clone());
    let Some(log) = log else {
        return;
    };
    let after = now;
    for (group, m) in FlightParams::metadata() {
        let value = after.get(group, m.key);
        if before.get(group, m.key) != value {
            log.param_changed(m.name, m.kind, value.unwrap_or(m.default));
        }
    }
}

/// Records in the telemetry log what a link heard, each message framed again as its sender
/// sent it (header and sequence kept; a signature is not).
fn log_heard(log: &mut Tlog, i: &Inbound) {
    let now = unix_usec();
    let mut frame = Vec::with_capacity(280);
    for (h, m) in &i.messages {
        frame.clear();
        Encoder::push_heard(&mut frame, h, m);
        log.record(now, &frame);
    }
    for raw in &i.unparsed {
        frame.clear();
        Encoder::push_raw_heard(&mut frame, &raw.header, raw.msg_id, &raw.payload);
        log.record(now, &frame);
    }
}
