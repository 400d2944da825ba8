//! The transports of the ground-station links: UDP (pushing and answering peers), a TCP server
//! and a serial line (on its own thread, reopened when it fails). Each checks every frame
//! ([`Guard`]) before it is parsed and hands what it heard to the links' task; every frame the
//! vehicle sends reaches every transport.

use super::endpoint::{Endpoint, EndpointSpec, LinkOptions};
use anyhow::{Context, Result};
use gcs::signing::Signing;
use hil::transport::{LineRead, SerialLine};
use hil::{Decoded, RawMessage, StreamDecoder};
use mavlink::MavHeader;
use mavlink::dialects::common::{MavMessage, MavSeverity};
use std::net::SocketAddr;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream, UdpSocket};
use tokio::sync::{broadcast, mpsc};

/// A UDP peer silent this long is no longer answered.
const PEER_TIMEOUT: Duration = Duration::from_secs(10);
/// Peers answered per UDP endpoint at most.
const MAX_PEERS: usize = 16;

/// Where a frame is checked before it is parsed: the endpoint's allow-list, then signing.
#[derive(Debug, Clone)]
pub(super) struct Guard {
    /// The endpoint's options.
    pub(super) options: LinkOptions,
    /// The signing state every endpoint shares.
    pub(super) signing: Arc<Mutex<Signing>>,
    /// Frames from systems not on an allow-list (all endpoints).
    pub(super) not_allowed: Arc<AtomicU64>,
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

    /// One frame judged on its own (the signing state locked for it alone).
    fn check_one(&self, frame: &[u8]) -> bool {
        let mut signing = self.signing.lock().unwrap_or_else(|e| e.into_inner());
        self.check(&mut signing, frame)
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
pub(super) struct Inbound {
    /// The messages parsed.
    pub(super) messages: Vec<(MavHeader, MavMessage)>,
    /// Frames the dialect cannot parse, kept whole.
    pub(super) unparsed: Vec<RawMessage>,
    /// Frames that did not decode.
    pub(super) malformed: u32,
    /// From a trusted endpoint.
    pub(super) trusted: bool,
}

/// The frames going out, shared by every endpoint.
pub(super) type Frames = broadcast::Sender<Arc<[u8]>>;

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
pub(super) type Notices = mpsc::Sender<(MavSeverity, String)>;

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
    // STATUSTEXT holds 50 bytes: the device's name, not its whole path.
    let name = path.file_name().map_or_else(
        || path.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    );
    let mut backoff = Duration::from_millis(100);
    let mut said_down = false;
    let mut lost_once = false;
    let mut output_full = 0u64;
    loop {
        // Frames queued while the port is closed are dropped, not sent late.
        loop {
            match frames.try_recv() {
                Ok(_) | Err(broadcast::error::TryRecvError::Lagged(_)) => {}
                Err(broadcast::error::TryRecvError::Empty) => break,
                Err(broadcast::error::TryRecvError::Closed) => return,
            }
        }
        let mut port = match SerialLine::open(&path, baud) {
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
        let mut decoded = new_decoded();
        let failure = loop {
            match port.read_into_checked(SERIAL_POLL, &mut decoded, &mut |f| guard.check_one(f)) {
                // A poll said readable and nothing came: the line hung up (a pty's other end
                // closed), which would read nothing for ever.
                Ok(LineRead::Closed) => {
                    break std::io::Error::from(std::io::ErrorKind::UnexpectedEof);
                }
                Ok(LineRead::Bytes(_)) => deliver(&mut decoded, &inbound, guard.options.trusted),
                Ok(LineRead::Nothing) => {}
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
pub(super) async fn open(
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
