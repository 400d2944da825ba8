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
//! key ([`super::signing`]) frames that are unsigned, wrongly signed or replayed are refused
//! before they are parsed, and the vehicle's frames go out signed. A UDP peer is answered only
//! once it has sent a frame that was accepted. Sending never waits on a slow peer: a link that
//! falls behind loses frames, not the vehicle's time.

use super::params::Parameters;
use super::signing::{SecretKey, Signing};
use super::{AckTo, Action, GroundStation, Outbox, Outgoing};
use crate::control_loop::{LoopCommand, Telemetry};
use crate::records::log_files::Tlog;
use crate::records::param_store::{Loaded, ParamStore};
use anyhow::{Context, Result, bail};
use flight_core::autopilot::command::AutopilotCommand;
use flight_core::params::FlightParams;
use hil::{Decoded, Encoder, RawMessage, StreamDecoder};
use mavlink::MavHeader;
use mavlink::dialects::common::{MavMessage, MavSeverity, MavType};
use std::net::SocketAddr;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream, UdpSocket};
use tokio::sync::{broadcast, mpsc, oneshot, watch};

/// PX4 SITL's links: QGroundControl and MAVSDK ports pushed to, each from its own bound port,
/// and a TCP server.
pub const DEFAULT_ENDPOINTS: [&str; 3] = [
    "udpout://127.0.0.1:14550?bind=18570&shared",
    "udpout://127.0.0.1:14540?bind=14580",
    "tcpin://0.0.0.0:5760",
];

/// How often the streams are looked at.
const POLL: Duration = Duration::from_millis(10);
/// A UDP peer silent this long is no longer answered.
const PEER_TIMEOUT: Duration = Duration::from_secs(10);
/// Peers answered per UDP endpoint at most.
const MAX_PEERS: usize = 16;
/// How long a command waits for the control loop's answer.
const ANSWER_TIMEOUT: Duration = Duration::from_secs(2);

/// One endpoint.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Endpoint {
    /// Push to `target` from `bind`, answering every peer.
    UdpOut {
        /// Where to push.
        target: SocketAddr,
        /// The local address.
        bind: SocketAddr,
    },
    /// A bound UDP port answering every peer.
    UdpIn {
        /// The local address.
        bind: SocketAddr,
    },
    /// A TCP server.
    TcpIn {
        /// The local address.
        bind: SocketAddr,
    },
    /// A serial line (a telemetry radio or a USB link to a ground station).
    Serial {
        /// The device.
        path: std::path::PathBuf,
        /// Its baud rate.
        baud: u32,
    },
}

impl Endpoint {
    /// Parses an endpoint URL; every port is offset by `instance` (a port 0 stays 0: any) but
    /// a `udpout` target marked `shared`: one ground station that hears every vehicle on one
    /// port, as QGroundControl does on 14550 (PX4's multi-vehicle ports: local 18570 + N,
    /// remote 14550).
    pub fn parse(url: &str, instance: u16) -> Result<Self> {
        let offset = |s: &str, instance: u16| -> Result<SocketAddr> {
            let mut a: SocketAddr = s.parse().with_context(|| {
                format!("{url:?}: {s:?} is not an address like 127.0.0.1:14550")
            })?;
            if a.port() != 0 {
                let port = a.port().checked_add(instance).with_context(|| {
                    format!(
                        "{url:?}: port {} + instance {instance} is past 65535",
                        a.port()
                    )
                })?;
                a.set_port(port);
            }
            Ok(a)
        };
        let addr = |s: &str| offset(s, instance);
        let (scheme, rest) = url.split_once("://").with_context(|| {
            format!("{url:?}: expected udpout://, udpin://, tcpin:// or serial://")
        })?;
        let (host, query) = rest.split_once('?').unwrap_or((rest, ""));
        if scheme == "serial" {
            let mut baud = 57_600;
            for kv in query.split('&').filter(|s| !s.is_empty()) {
                match kv.split_once('=') {
                    Some(("baud", b)) => {
                        baud = b
                            .parse()
                            .ok()
                            .filter(|&b| b > 0)
                            .with_context(|| format!("{url:?}: baud={b} is not a baud rate"))?;
                    }
                    _ => bail!("{url:?}: unknown option {kv:?} (serial takes baud=N)"),
                }
            }
            if host.is_empty() {
                bail!("{url:?}: no device (serial:///dev/ttyUSB0?baud=57600)");
            }
            return Ok(Endpoint::Serial {
                path: host.into(),
                baud,
            });
        }
        let (mut bind, mut shared) = (None, false);
        for kv in query.split('&').filter(|s| !s.is_empty()) {
            match kv.split_once('=') {
                None if kv == "shared" => shared = true,
                Some(("bind", p)) => {
                    let port: u16 = p
                        .parse()
                        .with_context(|| format!("{url:?}: bind={p} is not a port"))?;
                    bind = Some(addr(&format!("0.0.0.0:{port}"))?);
                }
                _ => bail!("{url:?}: unknown option {kv:?} (udpout takes bind=PORT and shared)"),
            }
        }
        Ok(match scheme {
            "udpout" => Endpoint::UdpOut {
                target: offset(host, if shared { 0 } else { instance })?,
                bind: bind.unwrap_or_else(|| SocketAddr::from(([0, 0, 0, 0], 0))),
            },
            "udpin" | "tcpin" if shared => bail!("{url:?}: shared is for udpout"),
            "udpin" if bind.is_none() => Endpoint::UdpIn { bind: addr(host)? },
            "tcpin" if bind.is_none() => Endpoint::TcpIn { bind: addr(host)? },
            "udpin" | "tcpin" => bail!("{url:?}: bind= is for udpout"),
            _ => bail!("{url:?}: expected udpout://, udpin://, tcpin:// or serial://"),
        })
    }
}

/// What every endpoint takes besides its address.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct LinkOptions {
    /// A physically secure link: exempt from signing, may set the key (`SETUP_SIGNING`).
    pub trusted: bool,
    /// Only these systems are heard (empty: all).
    pub allowed_systems: Vec<u8>,
}

/// An endpoint and its options, as written on the command line.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct EndpointSpec {
    /// Where.
    pub endpoint: Endpoint,
    /// How it is guarded.
    pub options: LinkOptions,
}

impl EndpointSpec {
    /// Parses `URL[?options]`: the options every endpoint takes (`trusted`, `sysids=A,B`), the
    /// rest as [`Endpoint::parse`].
    pub fn parse(url: &str, instance: u16) -> Result<Self> {
        let (base, query) = url.split_once('?').unwrap_or((url, ""));
        let mut options = LinkOptions::default();
        let mut rest = Vec::new();
        for kv in query.split('&').filter(|s| !s.is_empty()) {
            match kv.split_once('=') {
                None if kv == "trusted" => options.trusted = true,
                Some(("sysids", list)) => {
                    for id in list.split(',') {
                        let id: u8 = id.parse().ok().filter(|&i| i > 0).with_context(|| {
                            format!("{url:?}: sysids={list}: {id:?} is not a system id 1-255")
                        })?;
                        options.allowed_systems.push(id);
                    }
                }
                _ => rest.push(kv),
            }
        }
        let url = if rest.is_empty() {
            base.to_owned()
        } else {
            format!("{base}?{}", rest.join("&"))
        };
        Ok(Self {
            endpoint: Endpoint::parse(&url, instance)?,
            options,
        })
    }
}

/// Where a frame is checked before it is parsed: the endpoint's allow-list, then signing.
#[derive(Debug, Clone)]
struct Guard {
    options: LinkOptions,
    signing: Arc<Mutex<Signing>>,
    /// Frames from systems not on an allow-list (all endpoints).
    not_allowed: Arc<AtomicU64>,
}

impl Guard {
    /// Splits a datagram into `out`, checking each frame.
    fn decode(&self, datagram: &[u8], out: &mut Decoded) {
        let mut signing = self.signing.lock().unwrap_or_else(|e| e.into_inner());
        hil::decode_checked(datagram, out, &mut |f| self.check(&mut signing, f));
    }

    /// Adds a stream's bytes to `splitter`, checking each frame.
    fn push(&self, splitter: &mut StreamDecoder, bytes: &[u8], out: &mut Decoded) {
        let mut signing = self.signing.lock().unwrap_or_else(|e| e.into_inner());
        splitter.push_checked(bytes, out, &mut |f| self.check(&mut signing, f));
    }

    fn check(&self, signing: &mut Signing, frame: &[u8]) -> bool {
        let system = if frame[0] == 0xFE { frame[3] } else { frame[5] };
        if !self.options.allowed_systems.is_empty()
            && !self.options.allowed_systems.contains(&system)
        {
            self.not_allowed.fetch_add(1, Ordering::Relaxed);
            return false;
        }
        signing.check(frame, self.options.trusted).accepted()
    }
}

/// What an endpoint received: the messages of one datagram or read.
#[derive(Debug)]
struct Inbound {
    messages: Vec<(MavHeader, MavMessage)>,
    unparsed: Vec<RawMessage>,
    malformed: u32,
    /// From a trusted endpoint.
    trusted: bool,
}

/// The frames going out, shared by every endpoint.
type Frames = broadcast::Sender<Arc<[u8]>>;

fn new_decoded() -> Decoded {
    Decoded {
        keep_unparsed: true,
        ..Decoded::default()
    }
}

/// Hands what `d` holds to the ground station (dropped if it is behind: never waits).
fn deliver(d: &mut Decoded, inbound: &mpsc::Sender<Inbound>, trusted: bool) {
    d.refused = 0; // counted by the guard
    if d.messages.is_empty() && d.unparsed.is_empty() && d.malformed == 0 {
        return;
    }
    let i = Inbound {
        messages: std::mem::take(&mut d.messages),
        unparsed: std::mem::take(&mut d.unparsed),
        malformed: std::mem::take(&mut d.malformed),
        trusted,
    };
    if inbound.try_send(i).is_err() {
        tracing::debug!("ground-station input behind: frames dropped");
    }
}

async fn udp(
    socket: UdpSocket,
    target: Option<SocketAddr>,
    guard: Guard,
    inbound: mpsc::Sender<Inbound>,
    mut frames: broadcast::Receiver<Arc<[u8]>>,
) {
    let mut peers: Vec<(SocketAddr, Instant)> = Vec::new();
    let mut buf = vec![0u8; 65536];
    let mut decoded = new_decoded();
    loop {
        tokio::select! {
            r = socket.recv_from(&mut buf) => match r {
                Ok((n, from)) => {
                    guard.decode(&buf[..n], &mut decoded);
                    // Only a peer that said something acceptable is answered.
                    let heard = !decoded.messages.is_empty() || !decoded.unparsed.is_empty();
                    deliver(&mut decoded, &inbound, guard.options.trusted);
                    let now = Instant::now();
                    peers.retain(|p| now - p.1 < PEER_TIMEOUT);
                    if let Some(p) = peers.iter_mut().find(|p| p.0 == from) {
                        p.1 = now;
                    } else if heard && peers.len() < MAX_PEERS && Some(from) != target {
                        tracing::info!(peer = %from, "ground station connected");
                        peers.push((from, now));
                    }
                }
                // An ICMP "port unreachable" from an earlier push (nobody listening yet).
                Err(e) => tracing::trace!("ground-station UDP: {e}"),
            },
            f = frames.recv() => match f {
                Ok(frame) => {
                    for to in target.iter().chain(peers.iter().map(|p| &p.0)) {
                        // A full socket buffer or nobody listening loses this frame only.
                        let _ = socket.try_send_to(&frame, *to);
                    }
                }
                Err(broadcast::error::RecvError::Lagged(n)) => {
                    tracing::debug!("ground-station UDP behind: {n} frames dropped");
                }
                Err(broadcast::error::RecvError::Closed) => return,
            },
        }
    }
}

async fn tcp_client(
    stream: TcpStream,
    peer: SocketAddr,
    guard: Guard,
    inbound: mpsc::Sender<Inbound>,
    mut frames: broadcast::Receiver<Arc<[u8]>>,
) {
    let _ = stream.set_nodelay(true);
    let (mut rd, mut wr) = stream.into_split();
    let mut buf = vec![0u8; 4096];
    let mut splitter = StreamDecoder::default();
    let mut decoded = new_decoded();
    loop {
        tokio::select! {
            r = rd.read(&mut buf) => match r {
                Ok(0) | Err(_) => break,
                Ok(n) => {
                    guard.push(&mut splitter, &buf[..n], &mut decoded);
                    deliver(&mut decoded, &inbound, guard.options.trusted);
                }
            },
            f = frames.recv() => match f {
                Ok(frame) => {
                    if wr.write_all(&frame).await.is_err() {
                        break;
                    }
                }
                Err(broadcast::error::RecvError::Lagged(n)) => {
                    tracing::debug!(%peer, "ground-station TCP behind: {n} frames dropped");
                }
                Err(broadcast::error::RecvError::Closed) => break,
            },
        }
    }
    tracing::info!(%peer, "ground station disconnected (TCP)");
}

async fn tcp_server(
    listener: TcpListener,
    guard: Guard,
    inbound: mpsc::Sender<Inbound>,
    frames: Frames,
) {
    loop {
        match listener.accept().await {
            Ok((stream, peer)) => {
                tracing::info!(%peer, "ground station connected (TCP)");
                tokio::spawn(tcp_client(
                    stream,
                    peer,
                    guard.clone(),
                    inbound.clone(),
                    frames.subscribe(),
                ));
            }
            Err(e) => {
                tracing::warn!("ground-station TCP accept: {e}");
                tokio::time::sleep(Duration::from_millis(100)).await;
            }
        }
    }
}

/// How long a serial read waits: the latency of frames going out while nothing comes in.
const SERIAL_POLL: Duration = Duration::from_millis(10);

/// What the ground stations are told (on every link that is up), besides the log.
type Notices = mpsc::Sender<(MavSeverity, String)>;

/// A serial endpoint on its own thread (serial I/O blocks): reads frames in, writes the
/// vehicle's frames out, and reopens the port with backoff (0.1 s doubling to 2 s) when it
/// fails or vanishes (a USB radio unplugged: its device gone, then back under the same udev
/// name), until the frames channel closes. Frames sent while it is closed are lost. The loss
/// and the return are told to the other links' ground stations (and to this one once back).
fn serial(
    path: std::path::PathBuf,
    baud: u32,
    guard: Guard,
    inbound: mpsc::Sender<Inbound>,
    mut frames: broadcast::Receiver<Arc<[u8]>>,
    notices: Notices,
) {
    use std::io::{Read, Write};
    // STATUSTEXT holds 50 bytes: the device's name, not its whole path.
    let name = path.file_name().map_or_else(
        || path.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    );
    let mut backoff = Duration::from_millis(100);
    let mut said_down = false;
    let mut lost_once = false;
    let mut output_full = 0u64;
    let mut buf = vec![0u8; 4096];
    loop {
        // Frames queued while the port is closed are dropped, not sent late.
        loop {
            match frames.try_recv() {
                Ok(_) | Err(broadcast::error::TryRecvError::Lagged(_)) => {}
                Err(broadcast::error::TryRecvError::Empty) => break,
                Err(broadcast::error::TryRecvError::Closed) => return,
            }
        }
        let mut port = match serialport::new(path.to_string_lossy(), baud)
            .timeout(SERIAL_POLL)
            .open_native()
        {
            Ok(p) => p,
            Err(e) => {
                if !said_down {
                    tracing::warn!(port = %path.display(), "ground-station serial port: {e}; retrying");
                    said_down = true;
                }
                std::thread::sleep(backoff);
                backoff = (backoff * 2).min(Duration::from_secs(2));
                continue;
            }
        };
        tracing::info!(port = %path.display(), baud, "MAVLink serial endpoint");
        if lost_once {
            let _ = notices.try_send((
                MavSeverity::MAV_SEVERITY_NOTICE,
                format!("serial link {name} back"),
            ));
        }
        backoff = Duration::from_millis(100);
        let mut splitter = StreamDecoder::default();
        let mut decoded = new_decoded();
        let failure = loop {
            match port.read(&mut buf) {
                // A poll said readable and nothing came: the line hung up (a pty's other end
                // closed), which would read nothing for ever.
                Ok(0) => break std::io::Error::from(std::io::ErrorKind::UnexpectedEof),
                Ok(n) => {
                    guard.push(&mut splitter, &buf[..n], &mut decoded);
                    deliver(&mut decoded, &inbound, guard.options.trusted);
                }
                Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {}
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => break e,
            }
            let mut write_error = None;
            loop {
                match frames.try_recv() {
                    Ok(frame) => match port.write_all(&frame) {
                        Ok(()) => {}
                        // Output full (a radio holding CTS, a reader that stalls): this frame
                        // is lost (the far parser skips a cut one), not the port.
                        Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {
                            output_full += 1;
                            if output_full.is_power_of_two() {
                                tracing::warn!(port = %path.display(), dropped = output_full, "ground-station serial output full: frames dropped");
                            }
                        }
                        Err(e) => {
                            write_error = Some(e);
                            break;
                        }
                    },
                    Err(broadcast::error::TryRecvError::Lagged(n)) => {
                        tracing::debug!("ground-station serial behind: {n} frames dropped");
                    }
                    Err(broadcast::error::TryRecvError::Empty) => break,
                    Err(broadcast::error::TryRecvError::Closed) => return,
                }
            }
            if let Some(e) = write_error {
                break e;
            }
        };
        tracing::warn!(port = %path.display(), "ground-station serial link lost: {failure}; reopening");
        let _ = notices.try_send((
            MavSeverity::MAV_SEVERITY_WARNING,
            format!("serial link {name} lost: reopening"),
        ));
        lost_once = true;
        // The first attempt waits too: a device that is going away may still open at once.
        said_down = true;
        std::thread::sleep(backoff);
    }
}

/// Opens `endpoint`; its task runs until the frames channel closes. A port that cannot be
/// bound is reported and skipped (another vehicle may hold it: give it `-i N`).
async fn open(
    spec: &EndpointSpec,
    guard: Guard,
    inbound: &mpsc::Sender<Inbound>,
    frames: &Frames,
    notices: &Notices,
) -> Result<()> {
    match &spec.endpoint {
        Endpoint::UdpOut { target, bind } => {
            let s = UdpSocket::bind(bind)
                .await
                .with_context(|| format!("binding UDP {bind}"))?;
            tracing::info!(local = %s.local_addr()?, push_to = %target, "MAVLink UDP endpoint");
            tokio::spawn(udp(
                s,
                Some(*target),
                guard,
                inbound.clone(),
                frames.subscribe(),
            ));
        }
        Endpoint::UdpIn { bind } => {
            let s = UdpSocket::bind(bind)
                .await
                .with_context(|| format!("binding UDP {bind}"))?;
            tracing::info!(local = %s.local_addr()?, "MAVLink UDP endpoint");
            tokio::spawn(udp(s, None, guard, inbound.clone(), frames.subscribe()));
        }
        Endpoint::TcpIn { bind } => {
            let l = TcpListener::bind(bind)
                .await
                .with_context(|| format!("listening on TCP {bind}"))?;
            tracing::info!(local = %l.local_addr()?, "MAVLink TCP server");
            tokio::spawn(tcp_server(l, guard, inbound.clone(), frames.clone()));
        }
        Endpoint::Serial { path, baud } => {
            let (path, baud, inbound, frames, notices) = (
                path.clone(),
                *baud,
                inbound.clone(),
                frames.subscribe(),
                notices.clone(),
            );
            std::thread::Builder::new()
                .name("gcs-serial".into())
                .spawn(move || serial(path, baud, guard, inbound, frames, notices))
                .context("starting the serial endpoint")?;
        }
    }
    Ok(())
}

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
    /// Where a key set by `SETUP_SIGNING` is saved (none: kept in memory only).
    pub signing_key_file: Option<std::path::PathBuf>,
    /// The MAVLink telemetry log, if one is kept.
    pub tlog: Option<Tlog>,
    /// Whether a reboot is allowed: it restarts the process, so not for one of several
    /// vehicles in it.
    pub reboot_allowed: bool,
}

/// How often refused frames are reported in the log.
const REFUSALS_REPORT: Duration = Duration::from_secs(5);

/// Microseconds since the Unix epoch.
fn unix_usec() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_micros() as u64)
}

/// `SETUP_SIGNING` (<https://mavlink.io/en/guide/message_signing.html>): only from a trusted
/// link; the key is used at once and saved (mode 0600) where the daemon was told to keep it;
/// an all-zero key turns signing off (and removes the file). Returns what to tell the sender.
fn setup_signing(
    signing: &Mutex<Signing>,
    key_file: Option<&std::path::Path>,
    data: &mavlink::dialects::common::SETUP_SIGNING_DATA,
    trusted: bool,
) -> (MavSeverity, String) {
    if !trusted {
        tracing::warn!("SETUP_SIGNING refused: it came over a link not marked trusted");
        return (
            MavSeverity::MAV_SEVERITY_WARNING,
            "SETUP_SIGNING refused: link not trusted".into(),
        );
    }
    let key = SecretKey(data.secret_key);
    let on = key.0 != [0; 32];
    let saved = match key_file {
        Some(path) if on => {
            crate::records::param_store::write_private(path, &format!("{}\n", key.to_hex()))
        }
        Some(path) => match std::fs::remove_file(path) {
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                Err(anyhow::Error::from(e).context(format!("removing {}", path.display())))
            }
            _ => Ok(()),
        },
        None => Ok(()),
    };
    let mut s = signing.lock().unwrap_or_else(|e| e.into_inner());
    s.set_key(key, data.initial_timestamp);
    let state = if s.active() {
        "signing on"
    } else {
        "signing off"
    };
    drop(s);
    match saved {
        Ok(()) => {
            tracing::info!(
                file = ?key_file,
                "SETUP_SIGNING from a trusted link: MAVLink {state}"
            );
            (MavSeverity::MAV_SEVERITY_INFO, format!("MAVLink {state}"))
        }
        Err(e) => {
            tracing::error!("SETUP_SIGNING: MAVLink {state}, but the key is not kept: {e:#}");
            (
                MavSeverity::MAV_SEVERITY_ERROR,
                format!("MAVLink {state}; key not saved"),
            )
        }
    }
}

/// Saves every store it is handed, the latest first (a burst of sets is one write), and says
/// so when a save fails.
async fn saver(mut stores: watch::Receiver<Option<ParamStore>>, notices: Notices) {
    while stores.changed().await.is_ok() {
        let Some(store) = stores.borrow_and_update().clone() else {
            continue;
        };
        let result = tokio::task::spawn_blocking(move || store.save()).await;
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
/// the store is saved.
pub async fn run(endpoints: Vec<EndpointSpec>, vehicle: Vehicle) -> Option<Action> {
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
        mut tlog,
        reboot_allowed,
    } = vehicle;
    tracing::info!(
        "MAVLink signing {}",
        if signing_key.is_some() {
            "on: unsigned, wrongly signed and replayed frames are refused"
        } else {
            "off"
        }
    );
    let signing = Arc::new(Mutex::new(Signing::new(signing_key)));
    let not_allowed = Arc::new(AtomicU64::new(0));
    let (frames, _) = broadcast::channel::<Arc<[u8]>>(1024);
    let (inbound_tx, mut inbound) = mpsc::channel::<Inbound>(256);
    let (answers_tx, mut answers) = mpsc::channel::<(AckTo, Result<(), String>)>(64);
    let (notices_tx, mut notices) = mpsc::channel::<(MavSeverity, String)>(8);
    let (save_tx, save_rx) = watch::channel(None::<ParamStore>);
    let saving = tokio::spawn(saver(save_rx, notices_tx.clone()));
    for e in &endpoints {
        let guard = Guard {
            options: e.options.clone(),
            signing: signing.clone(),
            not_allowed: not_allowed.clone(),
        };
        if let Err(e) = open(e, guard, &inbound_tx, &frames, &notices_tx).await {
            tracing::warn!("ground-station endpoint not opened: {e:#}");
        }
    }
    let mut gcs = GroundStation::new(system_id, mav_type)
        .with_parameters(parameters, base_params)
        .with_reboot(reboot_allowed);
    let mut encoder = Encoder::with_ids(system_id, super::COMPONENT_ID);
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
                        MavMessage::SETUP_SIGNING(d) if d.target_system == system_id => {
                            let (severity, text) =
                                setup_signing(&signing, signing_key_file.as_deref(), d, i.trusted);
                            out.say(severity, &text);
                        }
                        _ => gcs.on_message(h, m, &t, &mut out),
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
            _ = tick.tick() => {
                let t = *telemetry.borrow_and_update();
                if t.finished || telemetry.has_changed().is_err() {
                    break;
                }
                gcs.poll(start.elapsed().as_secs_f64(), &t, &mut out);
                if let Some(log) = tlog.as_mut()
                    && let Err(e) = log.ship_if_due(unix_usec())
                {
                    // A full disk stops the log, not the links.
                    tracing::error!(file = %log.path().display(), "telemetry log: {e}; logging stopped");
                    tlog = None;
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
                let _ = answers_tx.try_send((to, Err("vehicle busy: try again".into())));
                continue;
            }
            let answers = answers_tx.clone();
            tokio::spawn(async move {
                let result = match tokio::time::timeout(ANSWER_TIMEOUT, rx).await {
                    Ok(Ok(r)) => r,
                    _ => Err("the control loop did not answer".into()),
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
                Action::ParamsChanged => {
                    params.send_replace(gcs.parameters().values().clone());
                }
                Action::SaveParams => {
                    save_tx.send_replace(Some(gcs.parameters().store().clone()));
                }
                Action::ReloadParams(to) => {
                    let loaded = match gcs.parameters().store().path() {
                        Some(path) => ParamStore::load(path, gcs.base_parameters())
                            .map_err(|e| format!("{e:#}")),
                        None => Ok(Loaded {
                            store: gcs.parameters().store().clone(),
                            params: gcs.parameters().values().clone(),
                            warnings: Vec::new(),
                            from_previous_copy: false,
                        }),
                    };
                    gcs.params_reloaded(to, loaded, &mut out);
                    params.send_replace(gcs.parameters().values().clone());
                }
                Action::Reboot | Action::Shutdown => {
                    exit = Some(action);
                    // Disarmed (checked before): the loop may stop at once.
                    let _ = commands.try_send(LoopCommand::Stop);
                }
            }
        }
        if !out.messages.is_empty() {
            signing
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .tick(unix_usec());
        }
        for m in out.messages.drain(..) {
            let mut bytes = Vec::with_capacity(64);
            match &m {
                Outgoing::Message(m) => encoder.push(&mut bytes, m),
                Outgoing::Raw(id, payload) => encoder.push_raw(&mut bytes, *id, payload),
            }
            signing
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .sign(&mut bytes);
            if let Some(log) = tlog.as_mut() {
                log.record(unix_usec(), &bytes);
            }
            // No endpoint listening is not an error.
            let _ = frames.send(bytes.into());
        }
    }
    let refused = signing.lock().unwrap_or_else(|e| e.into_inner()).refused;
    tracing::info!(
        malformed,
        dropped = gcs.dropped,
        refused_unsigned = refused.unsigned,
        refused_bad_signature = refused.bad_signature,
        refused_replayed = refused.replayed,
        refused_not_on_allow_list = not_allowed.load(Ordering::Relaxed),
        "ground-station links closed"
    );
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
    exit
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
