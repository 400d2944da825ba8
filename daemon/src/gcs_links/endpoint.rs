//! Ground-station endpoint URLs (`--mavlink`): where each link listens or pushes, and how it is
//! guarded (`trusted`, `sysids=`).

use anyhow::{Context, Result, bail};
use std::net::SocketAddr;

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
                    // ADDR:PORT as given; a bare PORT on the side of the target (below).
                    bind = Some(match p.parse::<u16>() {
                        Ok(port) => BindTo::Port(port),
                        Err(_) => BindTo::Addr(addr(p).with_context(|| {
                            format!("{url:?}: bind={p} is neither a port nor ADDR:PORT")
                        })?),
                    });
                }
                _ => bail!(
                    "{url:?}: unknown option {kv:?} (udpout takes bind=PORT or bind=ADDR:PORT, and shared)"
                ),
            }
        }
        Ok(match scheme {
            "udpout" => {
                let target = offset(host, if shared { 0 } else { instance })?;
                // Pushing to this machine, the port is this machine's alone; pushing to
                // another host, it must be reachable from there.
                let local = |port| {
                    let ip: std::net::IpAddr = match (target.ip().is_loopback(), target.is_ipv4()) {
                        (true, true) => std::net::Ipv4Addr::LOCALHOST.into(),
                        (true, false) => std::net::Ipv6Addr::LOCALHOST.into(),
                        (false, true) => std::net::Ipv4Addr::UNSPECIFIED.into(),
                        (false, false) => std::net::Ipv6Addr::UNSPECIFIED.into(),
                    };
                    SocketAddr::new(ip, port)
                };
                let bind = match bind {
                    Some(BindTo::Addr(a)) => a,
                    Some(BindTo::Port(0)) | None => local(0),
                    Some(BindTo::Port(p)) => offset(&local(p).to_string(), instance)?,
                };
                Endpoint::UdpOut { target, bind }
            }
            "udpin" | "tcpin" if shared => bail!("{url:?}: shared is for udpout"),
            "udpin" if bind.is_none() => Endpoint::UdpIn { bind: addr(host)? },
            "tcpin" if bind.is_none() => Endpoint::TcpIn { bind: addr(host)? },
            "udpin" | "tcpin" => bail!("{url:?}: bind= is for udpout"),
            _ => bail!("{url:?}: expected udpout://, udpin://, tcpin:// or serial://"),
        })
    }
}

/// A `udpout` endpoint's `bind=`: a port (on loopback when the target is this machine, on
/// every interface when it is another host) or an address.
enum BindTo {
    Port(u16),
    Addr(SocketAddr),
}

/// What every endpoint takes besides its address.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct LinkOptions {
    /// A physically secure link: exempt from signing, may set the key (`SETUP_SIGNING`).
    pub trusted: bool,
    /// Only these systems are heard (empty: all).
    pub allowed_systems: Vec<u8>,
    /// A port that cannot be opened is a warning, not a start-up error.
    pub optional: bool,
    /// The streams it starts with (`mode=normal|onboard`, PX4's `mavlink start -m`).
    pub streams: gcs::StreamSet,
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
    /// Parses `URL[?options]`: the options every endpoint takes (`trusted`, `sysids=A,B`,
    /// `optional`, `mode=normal|onboard`), the rest as [`Endpoint::parse`].
    pub fn parse(url: &str, instance: u16) -> Result<Self> {
        let (base, query) = url.split_once('?').unwrap_or((url, ""));
        let mut options = LinkOptions::default();
        let mut rest = Vec::new();
        for kv in query.split('&').filter(|s| !s.is_empty()) {
            match kv.split_once('=') {
                None if kv == "trusted" => options.trusted = true,
                None if kv == "optional" => options.optional = true,
                Some(("mode", mode)) => {
                    options.streams = gcs::StreamSet::from_name(mode).with_context(|| {
                        format!("{url:?}: mode={mode}: the stream sets are normal and onboard")
                    })?;
                }
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
