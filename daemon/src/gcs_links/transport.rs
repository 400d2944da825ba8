//! The transports of the ground-station links: UDP (pushing and answering peers), a TCP server
//! and a serial line (on its own thread, reopened when it fails). Each checks every frame
//! ([`Guard`]) before it is parsed and hands what it heard to the links' task; every frame the
//! vehicle sends reaches every transport.

use super::endpoint::{Endpoint, EndpointSpec};
use super::guard::{Guard, Heard};
use anyhow::{Context, Result};
use gcs::LinkId;
use hil::transport::{LineRead, SerialLine};
use hil::{Decoded, RawMessage, StreamDecoder};
use mavlink::MavHeader;
use mavlink::dialects::common::{MavMessage, MavSeverity};
use std::net::SocketAddr;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream, UdpSocket};
use tokio::sync::{broadcast, mpsc};

/// A UDP peer silent this long is no longer answered.
const PEER_TIMEOUT: Duration = Duration::from_secs(10);
/// Peers answered per UDP endpoint at most.
const MAX_PEERS: usize = 16;

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
    /// The endpoint's link.
    pub(super) link: LinkId,
}

/// A frame going out, and the link it is for.
pub(super) type Frame = (LinkId, Arc<[u8]>);

/// The frames going out, shared by every endpoint.
pub(super) type Frames = broadcast::Sender<Frame>;

fn new_decoded() -> Decoded {
    Decoded {
        keep_unparsed: true,
        ..Decoded::default()
    }
}

/// Hands what `d` holds to the ground station (dropped if it is behind: never waits).
fn deliver(d: &mut Decoded, inbound: &mpsc::Sender<Inbound>, guard: &Guard) {
    d.refused = 0; // counted by the guard
    if d.messages.is_empty() && d.unparsed.is_empty() && d.malformed == 0 {
        return;
    }
    let i = Inbound {
        messages: std::mem::take(&mut d.messages),
        unparsed: std::mem::take(&mut d.unparsed),
        malformed: std::mem::take(&mut d.malformed),
        trusted: guard.options.trusted,
        link: guard.link,
    };
    if inbound.try_send(i).is_err() {
        tracing::debug!("ground-station input behind: frames dropped");
    }
}

/// The UDP peers a link answers: those that earned it ([`Guard::check`]) within
/// [`PEER_TIMEOUT`], at most [`MAX_PEERS`]; a new one takes the place of the one heard from
/// least recently.
#[derive(Debug, Default)]
struct Peers(Vec<(SocketAddr, Instant)>);

impl Peers {
    /// `from` earned the vehicle's answers at `now`.
    fn heard(&mut self, from: SocketAddr, now: Instant) {
        self.expire(now);
        if let Some(p) = self.0.iter_mut().find(|p| p.0 == from) {
            p.1 = now;
            return;
        }
        if self.0.len() >= MAX_PEERS
            && let Some(k) = (0..self.0.len()).min_by_key(|&k| self.0[k].1)
        {
            tracing::info!(peer = %self.0[k].0, "ground station dropped for a new one (too many)");
            self.0.swap_remove(k);
        }
        tracing::info!(peer = %from, "ground station connected");
        self.0.push((from, now));
    }

    /// Forgets the peers silent for [`PEER_TIMEOUT`] (checked on every frame sent, so a
    /// peer that stops talking stops being sent to, whatever else arrives).
    fn expire(&mut self, now: Instant) {
        self.0.retain(|p| {
            let live = now.duration_since(p.1) < PEER_TIMEOUT;
            if !live {
                tracing::info!(peer = %p.0, "ground station silent: no longer answered");
            }
            live
        });
    }

    fn addresses(&self) -> impl Iterator<Item = &SocketAddr> {
        self.0.iter().map(|p| &p.0)
    }
}

async fn udp(
    socket: UdpSocket,
    target: Option<SocketAddr>,
    guard: Guard,
    inbound: mpsc::Sender<Inbound>,
    mut frames: broadcast::Receiver<Frame>,
) {
    let mut peers = Peers::default();
    let mut buf = vec![0u8; 65536];
    let mut decoded = new_decoded();
    loop {
        tokio::select! {
            r = socket.recv_from(&mut buf) => match r {
                Ok((n, from)) => {
                    let earned = guard.decode(&buf[..n], &mut decoded).earns(guard.signing_active());
                    deliver(&mut decoded, &inbound, &guard);
                    if earned && Some(from) != target {
                        peers.heard(from, Instant::now());
                    }
                }
                // An ICMP "port unreachable" from an earlier push (nobody listening yet).
                Err(e) => tracing::trace!("ground-station UDP: {e}"),
            },
            f = frames.recv() => match f {
                Ok(frame) => {
                    let Some(frame) = guard.ours(&frame) else {
                        continue;
                    };
                    peers.expire(Instant::now());
                    for to in target.iter().chain(peers.addresses()) {
                        // A full socket buffer or nobody listening loses this frame only.
                        let _ = socket.try_send_to(frame, *to);
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

/// TCP clients served at once at most.
const MAX_TCP_CLIENTS: usize = 8;

/// A new client is not evicted for not having earned answers yet before this (ms): a ground
/// station's first signed frame takes a moment.
const TCP_GRACE_MS: u64 = 3_000;

/// What the server knows of a client: what its frames showed, when it connected and when it
/// last sent an accepted frame (ms since the server started).
#[derive(Debug, Default)]
struct ClientState {
    accepted: std::sync::atomic::AtomicBool,
    signed: std::sync::atomic::AtomicBool,
    connected_ms: u64,
    last_heard_ms: AtomicU64,
}

impl ClientState {
    fn heard(&self) -> Heard {
        Heard {
            accepted: self.accepted.load(Ordering::Relaxed),
            signed: self.signed.load(Ordering::Relaxed),
        }
    }
}

async fn tcp_client(
    stream: TcpStream,
    peer: SocketAddr,
    guard: Guard,
    inbound: mpsc::Sender<Inbound>,
    mut frames: broadcast::Receiver<Frame>,
    state: Arc<ClientState>,
    started: Instant,
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
                    let heard = guard.push(&mut splitter, &buf[..n], &mut decoded);
                    if heard.accepted {
                        state.accepted.store(true, Ordering::Relaxed);
                        let ms = started.elapsed().as_millis() as u64;
                        state.last_heard_ms.store(ms, Ordering::Relaxed);
                    }
                    if heard.signed {
                        state.signed.store(true, Ordering::Relaxed);
                    }
                    deliver(&mut decoded, &inbound, &guard);
                }
            },
            f = frames.recv() => match f {
                Ok(frame) => {
                    // With signing on (even turned on since), nothing for a client that has
                    // not signed.
                    if guard.signing_active() && !state.heard().signed {
                        continue;
                    }
                    let Some(frame) = guard.ours(&frame) else {
                        continue;
                    };
                    if wr.write_all(frame).await.is_err() {
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

/// A client the server keeps: its task (aborted to evict it) and what it knows of it.
struct TcpClient {
    peer: SocketAddr,
    task: tokio::task::JoinHandle<()>,
    state: Arc<ClientState>,
}

/// With [`MAX_TCP_CLIENTS`] connected, which one a new client replaces: the longest connected
/// of those that have not earned answers past their grace; else the longest silent of those
/// silent for [`PEER_TIMEOUT`]; none (the new client is turned away) if every one is live or
/// new.
fn evictable(clients: &[TcpClient], now_ms: u64, signing_active: bool) -> Option<usize> {
    // Silent since it was last heard, or since it connected.
    let silent = |c: &TcpClient| {
        let last = c.state.last_heard_ms.load(Ordering::Relaxed);
        now_ms.saturating_sub(last.max(c.state.connected_ms))
    };
    let unearned = (0..clients.len())
        .filter(|&k| {
            let c = &clients[k].state;
            !c.heard().earns(signing_active) && now_ms >= c.connected_ms + TCP_GRACE_MS
        })
        .min_by_key(|&k| clients[k].state.connected_ms);
    unearned.or_else(|| {
        (0..clients.len())
            .filter(|&k| silent(&clients[k]) >= PEER_TIMEOUT.as_millis() as u64)
            .max_by_key(|&k| silent(&clients[k]))
    })
}

async fn tcp_server(
    listener: TcpListener,
    guard: Guard,
    inbound: mpsc::Sender<Inbound>,
    frames: Frames,
) {
    let started = Instant::now();
    let mut clients: Vec<TcpClient> = Vec::new();
    loop {
        match listener.accept().await {
            Ok((stream, peer)) => {
                clients.retain(|c| !c.task.is_finished());
                let now_ms = started.elapsed().as_millis() as u64;
                if clients.len() >= MAX_TCP_CLIENTS {
                    let Some(k) = evictable(&clients, now_ms, guard.signing_active()) else {
                        tracing::warn!(%peer, "ground station turned away (TCP): {MAX_TCP_CLIENTS} clients connected and live");
                        continue;
                    };
                    let old = clients.remove(k);
                    tracing::warn!(peer = %old.peer, new = %peer, "ground station dropped for a new one (TCP, too many)");
                    old.task.abort();
                }
                tracing::info!(%peer, "ground station connected (TCP)");
                let state = Arc::new(ClientState {
                    connected_ms: now_ms,
                    ..ClientState::default()
                });
                let task = tokio::spawn(tcp_client(
                    stream,
                    peer,
                    guard.clone(),
                    inbound.clone(),
                    frames.subscribe(),
                    state.clone(),
                    started,
                ));
                clients.push(TcpClient { peer, task, state });
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
    mut frames: broadcast::Receiver<Frame>,
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
                Ok(LineRead::Bytes(_)) => deliver(&mut decoded, &inbound, &guard),
                Ok(LineRead::Nothing) => {}
                Err(e) => break e,
            }
            let mut write_error = None;
            loop {
                match frames.try_recv() {
                    Ok(frame) if guard.ours(&frame).is_none() => {}
                    Ok(frame) => match port.write_all(&frame.1) {
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

/// Opens `endpoint`; its task runs until the frames channel closes. Returns the kind and the
/// local address of a socket (a port 0 is the one the system chose), none for a serial line.
pub(super) async fn open(
    spec: &EndpointSpec,
    guard: Guard,
    inbound: &mpsc::Sender<Inbound>,
    frames: &Frames,
    notices: &Notices,
) -> Result<Option<(&'static str, SocketAddr)>> {
    Ok(Some(match &spec.endpoint {
        Endpoint::UdpOut { target, bind } => {
            let s = UdpSocket::bind(bind)
                .await
                .with_context(|| format!("binding UDP {bind}"))?;
            let local = s.local_addr()?;
            tracing::info!(%local, push_to = %target, "MAVLink UDP endpoint");
            tokio::spawn(udp(
                s,
                Some(*target),
                guard,
                inbound.clone(),
                frames.subscribe(),
            ));
            ("udpout", local)
        }
        Endpoint::UdpIn { bind } => {
            let s = UdpSocket::bind(bind)
                .await
                .with_context(|| format!("binding UDP {bind}"))?;
            let local = s.local_addr()?;
            tracing::info!(%local, "MAVLink UDP endpoint");
            tokio::spawn(udp(s, None, guard, inbound.clone(), frames.subscribe()));
            ("udpin", local)
        }
        Endpoint::TcpIn { bind } => {
            let l = TcpListener::bind(bind)
                .await
                .with_context(|| format!("listening on TCP {bind}"))?;
            let local = l.local_addr()?;
            tracing::info!(%local, "MAVLink TCP server");
            tokio::spawn(tcp_server(l, guard, inbound.clone(), frames.clone()));
            ("tcpin", local)
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
            return Ok(None);
        }
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn addr(port: u16) -> SocketAddr {
        SocketAddr::from(([127, 0, 0, 1], port))
    }

    #[test]
    fn udp_peers_expire_on_silence_and_a_new_one_replaces_the_least_recent() {
        let t0 = Instant::now();
        let mut peers = Peers::default();
        for k in 0..MAX_PEERS as u16 {
            peers.heard(addr(k), t0 + Duration::from_millis(k.into()));
        }
        peers.heard(addr(0), t0 + Duration::from_millis(100));
        peers.heard(addr(999), t0 + Duration::from_millis(101));
        let now: Vec<u16> = peers.addresses().map(|a| a.port()).collect();
        assert_eq!(now.len(), MAX_PEERS);
        assert!(
            now.contains(&999) && now.contains(&0) && !now.contains(&1),
            "{now:?}"
        );
        // Silence alone ends a peer: checked when frames go out, whatever arrives.
        peers.expire(t0 + PEER_TIMEOUT + Duration::from_millis(100));
        let now: Vec<u16> = peers.addresses().map(|a| a.port()).collect();
        assert_eq!(now, [999], "only the one heard last is within the timeout");
    }

    #[test]
    fn a_tcp_client_that_never_earned_answers_goes_first_after_its_grace_then_a_silent_one() {
        // (accepted, signed, connected, last heard) in ms.
        let client = |accepted: bool, signed: bool, connected_ms: u64, last_ms: u64| {
            let state = ClientState {
                connected_ms,
                ..ClientState::default()
            };
            state.accepted.store(accepted, Ordering::Relaxed);
            state.signed.store(signed, Ordering::Relaxed);
            state.last_heard_ms.store(last_ms, Ordering::Relaxed);
            Arc::new(state)
        };
        let rt = tokio::runtime::Builder::new_current_thread()
            .build()
            .unwrap();
        let _guard = rt.enter();
        let clients = |states: Vec<Arc<ClientState>>| -> Vec<TcpClient> {
            states
                .into_iter()
                .enumerate()
                .map(|(k, state)| TcpClient {
                    peer: addr(k as u16),
                    task: rt.spawn(async {}),
                    state,
                })
                .collect()
        };
        let now = 60_000;
        // Signing on: unsigned clients are the ones to go, the oldest first, never a signed one
        // and never one within its grace.
        let c = clients(vec![
            client(true, true, 0, now),
            client(true, false, 2_000, now),
            client(false, false, 1_000, 0),
            client(false, false, now - 1_000, 0),
        ]);
        assert_eq!(evictable(&c, now, true), Some(2), "the oldest unsigned");
        let c = clients(vec![
            client(true, true, 0, now),
            client(false, false, now - 1_000, 0),
        ]);
        assert_eq!(
            evictable(&c, now, true),
            None,
            "within its grace: the newcomer waits"
        );
        // Signing off: an accepted frame earns; then the longest silent goes.
        let c = clients(vec![
            client(true, false, 0, now),
            client(true, false, 0, 1_000),
            client(true, false, 0, 30_000),
        ]);
        assert_eq!(evictable(&c, now, false), Some(1), "the longest silent");
        let c = clients(vec![
            client(true, false, 0, now),
            client(true, false, 0, now - 1_000),
        ]);
        assert_eq!(
            evictable(&c, now, false),
            None,
            "all live: the new one is turned away"
        );
    }
}
