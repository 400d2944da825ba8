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
mod host;
mod outgoing;
mod routing;
mod signing;
#[cfg(test)]
mod tests;
mod to_vehicle;
mod transport;

pub use endpoint::EndpointSpec;

use crate::control_loop::{Answer, LoopCommand};
use crate::records::flight_ulog::UlogEvents;
use crate::records::log_files::Tlog;
use anyhow::Result;
use flight_core::params::FlightParams;
use gcs::params::Parameters;
use gcs::signing::{SecretKey, Signing, SigningMemory};
use gcs::telemetry::Telemetry;
use gcs::{COMPONENT_ID, GroundStation, HostAction, LinkId, Outbox};
use guard::Guard;
use host::Host;
use mavlink::dialects::common::{MavSeverity, MavType};
use outgoing::LinkOutput;
use routing::Router;
use signing::SigningWatch;
use std::sync::atomic::AtomicU64;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use to_vehicle::ToVehicle;
use tokio::sync::{broadcast, mpsc, watch};
use transport::{Frame, Inbound, open};
use vehicle_files::{FileServices, FilesConfig};

/// PX4 SITL's links: QGroundControl and MAVSDK ports pushed to, each from its own bound port,
/// and a TCP server.
pub const DEFAULT_ENDPOINTS: [&str; 3] = [
    "udpout://127.0.0.1:14550?bind=18570&shared",
    "udpout://127.0.0.1:14540?bind=14580&mode=onboard",
    "tcpin://127.0.0.1:5760",
];

/// How often the streams are looked at.
const POLL: Duration = Duration::from_millis(10);

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
    /// The control loop's answers to answered requests.
    pub answers: mpsc::UnboundedReceiver<Answer>,
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

/// Microseconds since the Unix epoch.
pub(super) fn unix_usec() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_micros() as u64)
}

/// Runs the ground-station side until the control loop ends: opens `endpoints`, answers what
/// arrives, streams telemetry, passes vehicle commands and parameters to the control loop and
/// saves the parameter store. Returns the reboot or shutdown a ground station asked for, once
/// the store is saved; an endpoint that cannot be opened (and is not `optional`) stops the
/// control loop and is the error.
pub async fn run(endpoints: Vec<EndpointSpec>, vehicle: Vehicle) -> Result<Option<HostAction>> {
    let (mut s, mut arrive) = Links::open(&endpoints, vehicle).await?;
    let mut tick = tokio::time::interval(POLL);
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    let telemetry = &mut arrive.telemetry;
    loop {
        tokio::select! {
            Some(i) = arrive.inbound.recv() => {
                // Copied out: a borrow held would hold up the control loop's publishing.
                let t = *telemetry.borrow();
                s.heard(&i, &t);
            }
            Some((id, result)) = arrive.answers.recv() => s.answered(id, result),
            Some((severity, text)) = arrive.notices.recv() => s.out.say(severity, &text),
            // A stream faster than the tick: polled on every sensor sample as well.
            changed = telemetry.changed(), if s.gcs.wants_every_sample() => {
                if changed.is_err() {
                    break;
                }
                let t = *telemetry.borrow_and_update();
                s.poll(&t);
            }
            _ = tick.tick() => {
                let t = *telemetry.borrow_and_update();
                if t.link.finished || telemetry.has_changed().is_err() {
                    break;
                }
                s.tick(&t);
            }
        }
        let t_us = (telemetry.borrow().link.t_s * 1e6) as u64;
        s.end_turn(t_us);
    }
    Ok(s.close().await)
}

/// What the links' task receives from outside: the links' frames, the control
/// loop's answers and telemetry, and notices of the tasks around it.
struct Arrivals {
    inbound: mpsc::Receiver<Inbound>,
    answers: mpsc::UnboundedReceiver<Answer>,
    notices: mpsc::Receiver<(MavSeverity, String)>,
    telemetry: watch::Receiver<Telemetry>,
}

/// The ground-station side of one vehicle, each job in its part: the protocol, what the links
/// heard, what they send, requests to the vehicle, the host's work and signing.
struct Links {
    gcs: GroundStation,
    router: Router,
    output: LinkOutput,
    vehicle: ToVehicle,
    host: Host,
    signing: SigningWatch,
    /// What the first ground station to connect is told.
    startup_notices: Vec<String>,
    out: Outbox,
}

impl Links {
    /// Opens the endpoints and everything behind them.
    async fn open(endpoints: &[EndpointSpec], v: Vehicle) -> Result<(Self, Arrivals)> {
        let signing = restore_signing(v.signing_key, &v.signing_memory);
        let not_allowed = Arc::new(AtomicU64::new(0));
        let key_file = v.signing_key_file.as_deref();
        let watch_signing = SigningWatch::new(signing.clone(), key_file, not_allowed.clone());
        let (frames, _) = broadcast::channel::<Frame>(1024);
        let (inbound_tx, inbound) = mpsc::channel::<Inbound>(256);
        let (notices_tx, notices) = mpsc::channel::<(MavSeverity, String)>(8);
        let host = Host::new(v.params, v.ulog, notices_tx.clone());
        let vehicle = ToVehicle::new(v.commands);
        let mut gcs = GroundStation::new(v.system_id, v.mav_type);
        if let Some((uri, crc)) = &v.metadata {
            gcs = gcs.with_component_metadata(uri, *crc);
        }
        let mut gcs = gcs
            .with_parameters(v.parameters, v.base_params)
            .with_reboot(v.reboot_allowed)
            .with_unix_start(unix_usec());
        for (link, e) in endpoints.iter().enumerate() {
            let link = LinkId::try_from(link).unwrap_or(LinkId::MAX);
            gcs.add_link_with(link, e.options.streams);
            let guard = Guard {
                options: e.options.clone(),
                signing: signing.clone(),
                not_allowed: not_allowed.clone(),
                link,
            };
            let optional = e.options.optional;
            match open(e, guard, &inbound_tx, &frames, &notices_tx).await {
                // Scripts read this line to learn the ports (a port 0 is the system's choice).
                Ok(Some((kind, local))) => {
                    println!(
                        "autopilot endpoint: system={} {kind}://{local}",
                        v.system_id
                    );
                }
                Ok(None) => {}
                Err(e) if optional => {
                    tracing::warn!("optional ground-station endpoint not opened: {e:#}")
                }
                Err(e) => {
                    // Flying on without a link the user asked for would be worse: stop.
                    vehicle.stop_now().await;
                    return Err(e.context(
                        "a ground-station endpoint could not be opened (another program or vehicle holds the port? give it `-i N`, or mark the endpoint `?optional`)",
                    ));
                }
            }
        }
        let files = FileServices::new(v.system_id, COMPONENT_ID, &v.files);
        let router = Router::new(v.system_id, files, signing.clone(), v.signing_key_file);
        let output = LinkOutput::new(v.system_id, endpoints.len(), frames, signing, v.tlog);
        let links = Self {
            gcs,
            router,
            output,
            vehicle,
            host,
            signing: watch_signing,
            startup_notices: v.notices,
            out: Outbox::default(),
        };
        let arrivals = Arrivals {
            inbound,
            answers: v.answers,
            notices,
            telemetry: v.telemetry,
        };
        Ok((links, arrivals))
    }

    /// What a link delivered.
    fn heard(&mut self, i: &Inbound, t: &Telemetry) {
        self.output.record_heard(i);
        self.router.heard(i, &mut self.gcs, t, &mut self.out);
    }

    /// The control loop's answer to the request numbered `id`.
    fn answered(&mut self, id: u64, result: Result<(), flight_core::commander::Denial>) {
        if let Some(to) = self.vehicle.answered(id) {
            self.gcs.answered(to, result, &mut self.out);
        }
    }

    /// The streams and announcements due.
    fn poll(&mut self, t: &Telemetry) {
        self.gcs.poll(self.router.now_s(), t, &mut self.out);
    }

    /// The periodic work: streams, file transfers, the telemetry log, signing, answers given
    /// up on.
    fn tick(&mut self, t: &Telemetry) {
        self.poll(t);
        self.router.poll_files();
        self.output.ship_log();
        self.signing.tick();
        for (to, result) in self.vehicle.given_up(Instant::now()) {
            self.gcs.answered(to, result, &mut self.out);
        }
    }

    /// After each event: the requests to the vehicle, the host's work, the texts for the flight
    /// log (at `t_us`, the vehicle's clock) and every frame to send.
    fn end_turn(&mut self, t_us: u64) {
        let out = &mut self.out;
        let requests = std::mem::take(&mut out.requests);
        for (to, result) in self.vehicle.forward(requests, Instant::now()) {
            self.gcs.answered(to, result, out);
        }
        if std::mem::take(&mut out.gcs_heartbeat) {
            self.vehicle.heartbeat();
            for text in self.startup_notices.drain(..) {
                out.say(MavSeverity::MAV_SEVERITY_WARNING, &text);
            }
        }
        self.host.carry_out(&mut self.gcs, &self.vehicle, out);
        self.router.files_to(out);
        self.host.log_said(&mut out.said, t_us);
        self.output.send(out);
    }

    /// Closes the links: signing's memory and the logs written, the parameters saved.
    /// Returns the reboot or shutdown asked for.
    async fn close(mut self) -> Option<HostAction> {
        self.signing.finish().await;
        let (refused, not_on_allow_list) = self.signing.refused();
        tracing::info!(
            malformed = self.router.malformed,
            dropped = self.gcs.dropped,
            refused_unsigned = refused.unsigned,
            refused_bad_signature = refused.bad_signature,
            refused_replayed = refused.replayed,
            refused_future = refused.future,
            refused_not_on_allow_list = not_on_allow_list,
            "ground-station links closed"
        );
        self.host.report_lost();
        self.output.finish().await;
        self.host.finish().await
    }
}

/// Signing with `key` (none: off), remembering the last run's timestamps.
fn restore_signing(key: Option<SecretKey>, memory: &SigningMemory) -> Arc<Mutex<Signing>> {
    tracing::info!(
        "MAVLink signing {}",
        if key.is_some() {
            "on: unsigned, wrongly signed and replayed frames are refused"
        } else {
            "off"
        }
    );
    let mut signing = Signing::new(key);
    signing.remember(memory);
    Arc::new(Mutex::new(signing))
}
