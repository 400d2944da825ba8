//! The devices on the vehicle's own serial ports, at the edge: each port opened, read without
//! waiting and written, its protocol run by a pure driver of the `devices` crate, and what it
//! gives merged into the sensor frames ([`WithDevices`]). A GPS (`--gps`) replaces the
//! sensor link's GPS.

mod gps_port;
mod rc_port;
mod serial_device;
mod with_devices;

pub use gps_port::GpsPort;
pub use rc_port::{RcPort, RcSpec};
pub use with_devices::WithDevices;

use crate::links::parse_options;
use anyhow::{Result, anyhow, bail};
use devices::gps::GpsProtocol;
use std::path::PathBuf;

/// A GPS on a serial port, as `serial:///dev/ttyX?baud=…&protocol=ublox|nmea&rate=…` gives it.
#[derive(Debug, Clone, PartialEq)]
pub struct GpsSpec {
    /// The port.
    pub path: PathBuf,
    /// The baud looked at first, and the one a u-blox is moved to.
    pub baud: u32,
    /// The protocol.
    pub protocol: GpsProtocol,
    /// The navigation rate asked of a u-blox (Hz).
    pub rate_hz: f64,
}

impl GpsSpec {
    /// Parses the URL.
    pub fn parse(url: &str) -> Result<Self> {
        let Some(rest) = url.strip_prefix("serial://") else {
            bail!("--gps {url:?}: expected serial:///dev/ttyX?baud=115200&protocol=ublox");
        };
        let (path, query) = rest.split_once('?').unwrap_or((rest, ""));
        if path.is_empty() {
            bail!("--gps {url:?}: no device path");
        }
        let mut spec = Self {
            path: PathBuf::from(path),
            baud: 115_200,
            protocol: GpsProtocol::Ublox,
            rate_hz: 5.0,
        };
        let url = format!("--gps {url}");
        parse_options(
            &url,
            query,
            |k, v| {
                match k {
                    "baud" => {
                        spec.baud = v
                            .parse()
                            .ok()
                            .filter(|b| (1_200..=4_000_000).contains(b))
                            .ok_or_else(|| anyhow!("{url:?}: baud {v:?} is not a baud rate"))?;
                    }
                    "protocol" => {
                        spec.protocol = match v {
                            "ublox" | "ubx" => GpsProtocol::Ublox,
                            "nmea" => GpsProtocol::Nmea,
                            _ => bail!("{url:?}: protocol {v:?} is not ublox or nmea"),
                        }
                    }
                    "rate" => {
                        spec.rate_hz = v
                            .parse()
                            .ok()
                            .filter(|r: &f64| (1.0..=10.0).contains(r))
                            .ok_or_else(|| anyhow!("{url:?}: rate {v:?} is not 1 to 10 Hz"))?;
                    }
                    _ => return Ok(false),
                }
                Ok(true)
            },
            "baud, protocol, rate",
        )?;
        Ok(spec)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_gps_url_gives_its_port_baud_protocol_and_rate_and_a_bad_one_says_why() {
        let s = GpsSpec::parse("serial:///dev/ttyS3?baud=38400&protocol=nmea").expect("valid");
        assert_eq!(s.path, PathBuf::from("/dev/ttyS3"));
        assert_eq!(
            (s.baud, s.protocol, s.rate_hz),
            (38_400, GpsProtocol::Nmea, 5.0)
        );
        let s = GpsSpec::parse("serial:///dev/ttyACM0?rate=10").expect("valid");
        assert_eq!(
            (s.baud, s.protocol, s.rate_hz),
            (115_200, GpsProtocol::Ublox, 10.0)
        );
        for (bad, says) in [
            ("/dev/ttyS3", "expected serial://"),
            ("serial://?baud=9600", "no device path"),
            ("serial:///dev/x?baud=fast", "not a baud rate"),
            ("serial:///dev/x?protocol=sirf", "not ublox or nmea"),
            ("serial:///dev/x?rate=50", "not 1 to 10 Hz"),
            ("serial:///dev/x?parity=even", "unknown option"),
        ] {
            let e = GpsSpec::parse(bad).expect_err(bad).to_string();
            assert!(e.contains(says), "{bad}: {e}");
        }
    }
}
