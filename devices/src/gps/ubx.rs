//! A u-blox receiver over UBX, driven as PX4's and ArduPilot's drivers drive one:
//!
//! 1. **Scan**: listen at each baud in turn ([`BaudScan`]) until a whole UBX frame or NMEA
//!    sentence with a good checksum arrives, polling `MON-VER` once at each baud for a
//!    receiver that sends nothing unasked.
//! 2. **Identify**: poll `MON-VER` (retried) for the protocol version, which tells the
//!    configuration interface apart ([`Interface::for_protocol`]).
//! 3. **Switch baud** to the one asked for, when the receiver was found at another.
//! 4. **Configure**: each message acknowledged (`ACK-ACK`) or sent again, at most
//!    [`TRIES`] times; a NAK'd `CFG-VALSET` falls back to the legacy messages.
//! 5. **Run**: `NAV-PVT` gives the solution, with the last `NAV-DOP`'s dilutions.
//!
//! Silence for [`SILENT_S`] is said once; for [`LOST_S`] the scan starts again (unplugged,
//! replugged, restarted at its defaults).

use super::ublox_config::{self, ConfigMessage, Interface};
use super::{
    BaudScan, FixType, GpsCounters, GpsEvent, GpsSolution, LOST_S, SILENT_S, nmea_checksum_ok, utc,
};
use ublox::packets::mon_ver::MonVer;
use ublox::packets::nav_dop::NavDopRef;
use ublox::packets::nav_pvt::proto23::NavPvtRef;
use ublox::proto23::{PacketRef, Proto23};
use ublox::{AnyPacketRef, FixedBuffer, Parser, ParserBuilder, UbxPacket, UbxPacketRequest};

/// How many times a configuration message (or the `MON-VER` poll) is sent before the driver
/// gives up on its answer.
pub const TRIES: u8 = 4;
/// How long an answer is waited for before a message is sent again (s).
const ANSWER_WAIT_S: f64 = 0.5;
/// How long the receiver is given to send its acknowledgement at the old baud before the
/// port switches (s).
const BAUD_SWITCH_S: f64 = 0.1;
/// The parser's buffer: the largest frame read (`MON-VER` with its extensions) fits.
const BUFFER: usize = 2048;

#[derive(Debug, Clone, Copy, PartialEq)]
enum DriverStage {
    Scan,
    Identify {
        tries: u8,
        sent_at: f64,
    },
    SwitchBaud {
        at: f64,
        sent: bool,
    },
    Configure {
        index: usize,
        tries: u8,
        sent_at: f64,
    },
    Running,
}

/// What one frame from the receiver was, read out of the parser's borrowed buffer.
enum UbxRead {
    Pvt(GpsSolution),
    Dop { hdop: f64, vdop: f64 },
    Version(GpsEvent),
    Ack { of: (u8, u8), ok: bool },
    Nmea,
    Other,
    Bad,
}

/// The driver.
pub struct UbloxDriver {
    target_baud: u32,
    period_ms: u16,
    scan: BaudScan,
    baud: u32,
    stage: DriverStage,
    parser: Parser<FixedBuffer<BUFFER>, Proto23>,
    protocol: Option<f64>,
    config: Vec<ConfigMessage>,
    interface: Interface,
    /// Configuration messages refused or unanswered in this pass.
    refusals: u32,
    /// The last (class, id) acknowledged or refused, and which.
    ack: Option<((u8, u8), bool)>,
    /// The baud `MON-VER` was last polled at while scanning.
    polled_at: Option<u32>,
    last_valid: Option<f64>,
    last_solution: Option<f64>,
    silent_said: bool,
    dop: Option<(f64, f64)>,
    counters: GpsCounters,
}

impl std::fmt::Debug for UbloxDriver {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("UbloxDriver")
            .field("baud", &self.baud)
            .field("stage", &self.stage)
            .field("protocol", &self.protocol)
            .field("counters", &self.counters)
            .finish_non_exhaustive()
    }
}

fn new_parser() -> Parser<FixedBuffer<BUFFER>, Proto23> {
    ParserBuilder::new()
        .with_protocol::<Proto23>()
        .with_fixed_buffer::<BUFFER>()
}

impl UbloxDriver {
    /// A driver that looks for its receiver at `baud` first, moves it to `baud`, and asks for
    /// a solution at `rate_hz` (clamped to 1–10 Hz, as u-blox's M8 and M9 can).
    pub fn new(baud: u32, rate_hz: f64) -> Self {
        let scan = BaudScan::new(baud);
        let rate = if rate_hz.is_finite() {
            rate_hz.clamp(1.0, 10.0)
        } else {
            5.0
        };
        Self {
            target_baud: baud,
            period_ms: (1000.0 / rate).round() as u16,
            baud: scan.baud(),
            scan,
            stage: DriverStage::Scan,
            parser: new_parser(),
            protocol: None,
            config: Vec::new(),
            interface: Interface::Legacy,
            refusals: 0,
            ack: None,
            polled_at: None,
            last_valid: None,
            last_solution: None,
            silent_said: false,
            dop: None,
            counters: GpsCounters::default(),
        }
    }

    /// The baud the port must be at now.
    pub fn baud(&self) -> u32 {
        self.baud
    }

    /// The receiver's protocol version, once it said.
    pub fn protocol(&self) -> Option<f64> {
        self.protocol
    }

    /// Configured and reading solutions.
    pub fn running(&self) -> bool {
        self.stage == DriverStage::Running
    }

    /// What the driver has counted.
    pub fn counters(&self) -> GpsCounters {
        self.counters
    }

    /// Bytes read from the port at `t_s`.
    pub fn receive(&mut self, t_s: f64, bytes: &[u8], events: &mut Vec<GpsEvent>) {
        self.counters.bytes += bytes.len() as u64;
        let mut frames = Vec::new();
        let mut it = self.parser.consume_ubx_rtcm_nmea(bytes);
        while let Some(next) = it.next() {
            frames.push(match next {
                Ok(AnyPacketRef::Ubx(UbxPacket::Proto23(p))) => read_frame(p),
                Ok(AnyPacketRef::Nmea(n)) if nmea_checksum_ok(n.data) => UbxRead::Nmea,
                // A rover's receiver sends no RTCM: a frame that looks like one is noise.
                Ok(_) | Err(_) => UbxRead::Bad,
            });
        }
        drop(it);
        for frame in frames {
            self.take(t_s, frame, events);
        }
    }

    fn take(&mut self, t_s: f64, frame: UbxRead, events: &mut Vec<GpsEvent>) {
        if matches!(frame, UbxRead::Bad) {
            self.counters.bad_frames += 1;
            return;
        }
        self.counters.frames += 1;
        self.last_valid = Some(t_s);
        if self.stage == DriverStage::Scan {
            events.push(GpsEvent::Found { baud: self.baud });
            self.stage = DriverStage::Identify {
                tries: 0,
                sent_at: f64::NEG_INFINITY,
            };
        }
        match frame {
            // Taken in every stage once found: a receiver configured beforehand (or a recording)
            // streams solutions while the dialogue is still going on, or without answering it.
            UbxRead::Pvt(mut s) => {
                if let Some((hdop, vdop)) = self.dop {
                    (s.hdop, s.vdop) = (Some(hdop), Some(vdop));
                }
                self.counters.solutions += 1;
                self.last_solution = Some(t_s);
                self.silent_said = false;
                events.push(GpsEvent::Solution(s));
            }
            UbxRead::Dop { hdop, vdop } => self.dop = Some((hdop, vdop)),
            UbxRead::Version(v) => {
                if let GpsEvent::Identified { protocol, .. } = &v {
                    self.protocol = *protocol;
                }
                if matches!(self.stage, DriverStage::Identify { .. }) {
                    events.push(v);
                    self.identified(t_s);
                }
            }
            UbxRead::Ack { of, ok } => self.ack = Some((of, ok)),
            // NMEA while running: the receiver restarted with its defaults at this baud.
            UbxRead::Nmea if self.stage == DriverStage::Running => {
                self.stage = DriverStage::Identify {
                    tries: 0,
                    sent_at: f64::NEG_INFINITY,
                };
            }
            _ => {}
        }
    }

    /// The protocol version is known (or never will be): the baud switch, then the
    /// configuration.
    fn identified(&mut self, t_s: f64) {
        self.interface = Interface::for_protocol(self.protocol);
        self.config = ublox_config::messages(self.interface, self.target_baud, self.period_ms);
        self.refusals = 0;
        self.stage = if self.baud == self.target_baud {
            Self::configure_from_start()
        } else {
            DriverStage::SwitchBaud {
                at: t_s + BAUD_SWITCH_S,
                sent: false,
            }
        };
    }

    fn configure_from_start() -> DriverStage {
        DriverStage::Configure {
            index: 0,
            tries: 0,
            sent_at: f64::NEG_INFINITY,
        }
    }

    /// The clock moved to `t_s`: bytes to send appended to `out`.
    pub fn poll(&mut self, t_s: f64, out: &mut Vec<u8>, events: &mut Vec<GpsEvent>) {
        if self.silence(t_s, events) {
            return;
        }
        match self.stage {
            DriverStage::Scan => {
                if self.scan.next_if_due(t_s) {
                    self.baud = self.scan.baud();
                    self.parser = new_parser();
                }
                if self.polled_at != Some(self.baud) {
                    self.polled_at = Some(self.baud);
                    out.extend_from_slice(&mon_ver_poll());
                }
            }
            DriverStage::Identify { tries, sent_at } => {
                if t_s - sent_at < ANSWER_WAIT_S {
                } else if tries < TRIES {
                    out.extend_from_slice(&mon_ver_poll());
                    self.stage = DriverStage::Identify {
                        tries: tries + 1,
                        sent_at: t_s,
                    };
                } else {
                    events.push(GpsEvent::Refused {
                        message: "MON-VER",
                        nak: false,
                    });
                    self.identified(t_s);
                }
            }
            DriverStage::SwitchBaud { at, sent: false } => {
                out.extend_from_slice(
                    &ublox_config::baud_switch(self.interface, self.target_baud).bytes,
                );
                self.stage = DriverStage::SwitchBaud { at, sent: true };
            }
            DriverStage::SwitchBaud { at, .. } if t_s >= at => {
                self.baud = self.target_baud;
                self.parser = new_parser();
                self.last_valid = Some(t_s);
                self.stage = Self::configure_from_start();
            }
            DriverStage::SwitchBaud { .. } | DriverStage::Running => {}
            DriverStage::Configure {
                index,
                tries,
                sent_at,
            } => self.configure(t_s, (index, tries, sent_at), out, events),
        }
    }

    /// One step of the configuration dialogue: the answer to the message in flight, or the
    /// message (again).
    fn configure(
        &mut self,
        t_s: f64,
        (index, tries, sent_at): (usize, u8, f64),
        out: &mut Vec<u8>,
        events: &mut Vec<GpsEvent>,
    ) {
        let Some(message) = self.config.get(index) else {
            // Said only when every message was taken; each refusal was said as it came.
            if self.refusals == 0 {
                events.push(GpsEvent::Configured {
                    interface: self.interface.name(),
                });
            }
            self.stage = DriverStage::Running;
            self.last_solution = Some(t_s);
            return;
        };
        let answer = self.ack.take().filter(|(of, _)| *of == message.acked_as);
        let next = |index| DriverStage::Configure {
            index,
            tries: 0,
            sent_at: f64::NEG_INFINITY,
        };
        match answer {
            Some((_, true)) => self.stage = next(index + 1),
            Some((_, false)) => {
                events.push(GpsEvent::Refused {
                    message: message.name,
                    nak: true,
                });
                if self.interface == Interface::Valset {
                    // A receiver that says it is of generation 9 but refuses its interface.
                    self.interface = Interface::Legacy;
                    self.config =
                        ublox_config::messages(self.interface, self.target_baud, self.period_ms);
                    self.stage = next(0);
                } else {
                    self.refusals += 1;
                    self.stage = next(index + 1);
                }
            }
            None if t_s - sent_at < ANSWER_WAIT_S => {}
            None if tries < TRIES => {
                out.extend_from_slice(&message.bytes);
                self.stage = DriverStage::Configure {
                    index,
                    tries: tries + 1,
                    sent_at: t_s,
                };
            }
            None => {
                events.push(GpsEvent::Refused {
                    message: message.name,
                    nak: false,
                });
                self.refusals += 1;
                self.stage = next(index + 1);
            }
        }
    }

    /// Says silence once, and starts the scan again after [`LOST_S`]. True when it did.
    fn silence(&mut self, t_s: f64, events: &mut Vec<GpsEvent>) -> bool {
        if self.stage == DriverStage::Scan {
            return false;
        }
        let heard = if self.stage == DriverStage::Running {
            self.last_solution
        } else {
            self.last_valid
        };
        let quiet = heard.map_or(0.0, |h| t_s - h);
        if quiet > SILENT_S && !self.silent_said {
            self.silent_said = true;
            events.push(GpsEvent::Silent);
        }
        if quiet > LOST_S {
            events.push(GpsEvent::Lost);
            self.stage = DriverStage::Scan;
            self.scan.restart(t_s);
            self.baud = self.scan.baud();
            self.parser = new_parser();
            self.polled_at = None;
            self.protocol = None;
            self.dop = None;
            return true;
        }
        false
    }
}

fn mon_ver_poll() -> [u8; 8] {
    UbxPacketRequest::request_for::<MonVer>().into_packet_bytes()
}

fn read_frame(p: PacketRef<'_>) -> UbxRead {
    match p {
        PacketRef::NavPvt(pvt) => UbxRead::Pvt(solution(&pvt)),
        PacketRef::NavDop(d) => dop(&d),
        PacketRef::MonVer(v) => UbxRead::Version(GpsEvent::Identified {
            software: v.software_version().to_string(),
            hardware: v.hardware_version().to_string(),
            protocol: v.extension().find_map(protocol_version),
        }),
        PacketRef::AckAck(a) => UbxRead::Ack {
            of: (a.class(), a.msg_id()),
            ok: true,
        },
        PacketRef::AckNak(a) => UbxRead::Ack {
            of: (a.class(), a.msg_id()),
            ok: false,
        },
        _ => UbxRead::Other,
    }
}

fn dop(d: &NavDopRef<'_>) -> UbxRead {
    UbxRead::Dop {
        hdop: f64::from(d.horizontal_dop()),
        vdop: f64::from(d.vertical_dop()),
    }
}

/// `PROTVER=18.00` (M8) or `PROTVER 15.00` (older) in a `MON-VER` extension.
fn protocol_version(extension: &str) -> Option<f64> {
    let rest = extension.strip_prefix("PROTVER")?;
    rest.trim_start_matches(['=', ' ']).trim().parse().ok()
}

/// `NAV-PVT`'s solution (u-blox's interface description, UBX-NAV-PVT).
fn solution(p: &NavPvtRef<'_>) -> GpsSolution {
    let flags = p.flags_raw();
    let gnss_fix_ok = flags & 0x01 != 0;
    let invalid_llh = p.flags3_raw() & 0x01 != 0;
    let fix = match p.fix_type_raw() {
        _ if !gnss_fix_ok || invalid_llh => FixType::NoFix,
        2 => FixType::Fix2d,
        3 | 4 => match (flags >> 6) & 0x03 {
            1 => FixType::RtkFloat,
            2 => FixType::RtkFixed,
            _ if flags & 0x02 != 0 => FixType::Dgps,
            _ => FixType::Fix3d,
        },
        _ => FixType::NoFix,
    };
    // validDate, validTime, fullyResolved.
    let time_utc_usec = (p.valid_raw() & 0x07 == 0x07)
        .then(|| {
            utc::unix_usec_from_fields(
                (
                    i32::from(p.year()),
                    u32::from(p.month()),
                    u32::from(p.day()),
                ),
                (u32::from(p.hour()), u32::from(p.min()), u32::from(p.sec())),
                i64::from(p.nanosec()),
            )
        })
        .flatten();
    GpsSolution {
        fix,
        lat_deg: p.latitude(),
        lon_deg: p.longitude(),
        alt_msl_m: p.height_msl(),
        vel_ne_m_s: Some([p.vel_north(), p.vel_east()]),
        vel_down_m_s: Some(p.vel_down()),
        h_acc_m: Some(p.horizontal_accuracy()),
        v_acc_m: Some(p.vertical_accuracy()),
        s_acc_m_s: Some(p.speed_accuracy()),
        heading_acc_deg: Some(p.heading_accuracy()),
        satellites: p.num_satellites(),
        hdop: None,
        vdop: None,
        time_utc_usec,
    }
}

#[cfg(test)]
mod tests;
