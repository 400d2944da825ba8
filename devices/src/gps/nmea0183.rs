//! Any receiver's NMEA 0183, read as it comes (nothing is configured): sentences are
//! assembled from the bytes, their checksums checked and their fields decoded by the `nmea`
//! crate, and the sentences of one epoch (one fix time) gathered into a solution:
//!
//! - `GGA`: position, altitude above mean sea level, fix quality, satellites, HDOP;
//! - `RMC`: the date (for the UTC time), speed and course over the ground;
//! - `VTG`: speed and course, when `RMC` does not come;
//! - `GSA`: 2D or 3D, PDOP, HDOP, VDOP (the latest, whichever epoch);
//! - `GST`: the position's standard deviations, as the accuracies (the latest).
//!
//! A solution is given as soon as its epoch has a `GGA` and a velocity (`RMC` or `VTG`),
//! whichever comes last, as ArduPilot's NMEA driver does; a `GGA` left without a velocity is
//! given, without one, when the next epoch starts. The baud is found as for u-blox
//! ([`BaudScan`]).

use super::{
    BaudScan, FixType, GpsCounters, GpsEvent, GpsSolution, LOST_S, SILENT_S, nmea_checksum_ok, utc,
};
use chrono::{NaiveDate, NaiveTime};
use nmea::ParseResult;
use nmea::sentences::FixType as NmeaFix;
use nmea::sentences::gsa::GsaMode2;
use nmea::sentences::rmc::RmcStatusOfFix;

/// The longest sentence NMEA 0183 allows is 82 characters; longer lines are garbage.
const MAX_LINE: usize = 96;
/// Knots to m/s.
const KNOT_M_S: f64 = 1852.0 / 3600.0;

/// What a `GGA` said.
#[derive(Debug, Clone, Copy)]
struct Position {
    fix: Option<NmeaFix>,
    lat_deg: Option<f64>,
    lon_deg: Option<f64>,
    alt_m: Option<f32>,
    satellites: Option<u32>,
    hdop: Option<f32>,
}

/// One epoch's sentences so far.
#[derive(Debug, Clone, Default)]
struct Epoch {
    time: Option<NaiveTime>,
    gga: Option<Position>,
    /// Speed (m/s) and course (deg) over the ground.
    motion: Option<(f64, f64)>,
    given: bool,
}

/// The driver.
#[derive(Debug)]
pub struct NmeaDriver {
    scan: BaudScan,
    found: bool,
    line: Vec<u8>,
    epoch: Epoch,
    date: Option<NaiveDate>,
    /// GSA: 3D (else 2D), HDOP, VDOP.
    gsa: Option<(bool, Option<f64>, Option<f64>)>,
    /// GST: latitude, longitude and altitude standard deviations (m).
    gst: Option<(f64, f64, f64)>,
    last_valid: Option<f64>,
    last_solution: Option<f64>,
    silent_said: bool,
    counters: GpsCounters,
}

impl NmeaDriver {
    /// A driver that listens at `baud` first.
    pub fn new(baud: u32) -> Self {
        Self {
            scan: BaudScan::new(baud),
            found: false,
            line: Vec::with_capacity(MAX_LINE),
            epoch: Epoch::default(),
            date: None,
            gsa: None,
            gst: None,
            last_valid: None,
            last_solution: None,
            silent_said: false,
            counters: GpsCounters::default(),
        }
    }

    /// The baud the port must be at now.
    pub fn baud(&self) -> u32 {
        self.scan.baud()
    }

    /// What the driver has counted.
    pub fn counters(&self) -> GpsCounters {
        self.counters
    }

    /// Bytes read from the port at `t_s`.
    pub fn receive(&mut self, t_s: f64, bytes: &[u8], events: &mut Vec<GpsEvent>) {
        self.counters.bytes += bytes.len() as u64;
        for &b in bytes {
            match b {
                b'$' => {
                    if !self.line.is_empty() {
                        self.counters.bad_frames += 1; // a sentence cut short
                    }
                    self.line.clear();
                    self.line.push(b);
                }
                b'\n' | b'\r' if !self.line.is_empty() => {
                    let line = std::mem::take(&mut self.line);
                    self.sentence(t_s, &line, events);
                    self.line = line;
                    self.line.clear();
                }
                _ if !self.line.is_empty() => {
                    if self.line.len() >= MAX_LINE {
                        self.counters.bad_frames += 1;
                        self.line.clear();
                    } else {
                        self.line.push(b);
                    }
                }
                _ => {}
            }
        }
    }

    fn sentence(&mut self, t_s: f64, line: &[u8], events: &mut Vec<GpsEvent>) {
        let text = match std::str::from_utf8(line) {
            Ok(text) if nmea_checksum_ok(line) => text,
            _ => {
                self.counters.bad_frames += 1;
                return;
            }
        };
        let mended;
        let parsed = match nmea::parse_str(text) {
            Err(_) if let Some(m) = rmc_without_lone_variation(text) => {
                mended = m;
                nmea::parse_str(&mended)
            }
            p => p,
        };
        self.counters.frames += 1;
        self.last_valid = Some(t_s);
        if !self.found {
            self.found = true;
            events.push(GpsEvent::Found { baud: self.baud() });
        }
        match parsed {
            Ok(ParseResult::GGA(gga)) => {
                self.new_epoch(gga.fix_time, events);
                // The first GGA of an epoch: a receiver may send one per constellation
                // (GPGGA, GLGGA) of the same fix.
                if self.epoch.gga.is_some() {
                    return;
                }
                self.epoch.gga = Some(Position {
                    fix: gga.fix_type,
                    lat_deg: gga.latitude,
                    lon_deg: gga.longitude,
                    alt_m: gga.altitude,
                    satellites: gga.fix_satellites,
                    hdop: gga.hdop,
                });
            }
            Ok(ParseResult::RMC(rmc)) => {
                self.new_epoch(rmc.fix_time, events);
                if let Some(date) = rmc.fix_date {
                    self.date = Some(date);
                }
                if rmc.status_of_fix != RmcStatusOfFix::Invalid {
                    self.motion(rmc.speed_over_ground, rmc.true_course);
                }
            }
            Ok(ParseResult::VTG(vtg)) => self.motion(vtg.speed_over_ground, vtg.true_course),
            Ok(ParseResult::GSA(gsa)) => {
                let dop = |x: Option<f32>| x.map(f64::from);
                self.gsa = Some((gsa.mode2 == GsaMode2::Fix3D, dop(gsa.hdop), dop(gsa.vdop)));
            }
            Ok(ParseResult::GST(gst)) => {
                if let (Some(lat), Some(lon), Some(alt)) = (gst.lat_sd, gst.long_sd, gst.alt_sd) {
                    self.gst = Some((f64::from(lat), f64::from(lon), f64::from(alt)));
                }
            }
            // Good checksum, but a sentence not read here (GSV, GLL, TXT, …) or fields the
            // crate refuses: counted as heard, not used.
            _ => {}
        }
        self.give(t_s, events, false);
    }

    fn motion(&mut self, speed_knots: Option<f32>, course_deg: Option<f32>) {
        if let Some(speed) = speed_knots {
            let speed = f64::from(speed) * KNOT_M_S;
            // A receiver standing still may leave the course empty.
            self.epoch.motion = Some((speed, course_deg.map_or(0.0, f64::from)));
        }
    }

    /// A sentence of time `time` arrived: a new epoch starts when it differs, the last one's
    /// `GGA` given first if it was not.
    fn new_epoch(&mut self, time: Option<NaiveTime>, events: &mut Vec<GpsEvent>) {
        if time.is_some() && time != self.epoch.time {
            let t = self.last_valid.unwrap_or(0.0);
            self.give(t, events, true);
            self.epoch = Epoch {
                time,
                ..Epoch::default()
            };
        }
    }

    /// Gives the epoch's solution once it has a `GGA` and a velocity (or, `closing`, without
    /// the velocity).
    fn give(&mut self, t_s: f64, events: &mut Vec<GpsEvent>, closing: bool) {
        let e = &self.epoch;
        let Some(gga) = e.gga.filter(|_| !e.given) else {
            return;
        };
        if e.motion.is_none() && !closing {
            return;
        }
        let (Some(lat_deg), Some(lon_deg)) = (gga.lat_deg, gga.lon_deg) else {
            self.epoch.given = true;
            return;
        };
        let three_d = self.gsa.is_none_or(|(three_d, _, _)| three_d) && gga.alt_m.is_some();
        let fix = match gga.fix {
            Some(NmeaFix::Gps | NmeaFix::Pps | NmeaFix::Simulation) if three_d => FixType::Fix3d,
            Some(NmeaFix::Gps | NmeaFix::Pps | NmeaFix::Simulation) => FixType::Fix2d,
            Some(NmeaFix::DGps) => FixType::Dgps,
            Some(NmeaFix::FloatRtk) => FixType::RtkFloat,
            Some(NmeaFix::Rtk) => FixType::RtkFixed,
            _ => FixType::NoFix,
        };
        let vel_ne_m_s = e.motion.map(|(speed, course)| {
            let c = course.to_radians();
            [speed * c.cos(), speed * c.sin()]
        });
        let (gsa_hdop, vdop) = self.gsa.map_or((None, None), |(_, h, v)| (h, v));
        let solution = GpsSolution {
            fix,
            lat_deg,
            lon_deg,
            alt_msl_m: gga.alt_m.map_or(0.0, f64::from),
            vel_ne_m_s,
            vel_down_m_s: None,
            h_acc_m: self.gst.map(|(lat, lon, _)| lat.hypot(lon)),
            v_acc_m: self.gst.map(|(_, _, alt)| alt),
            s_acc_m_s: None,
            heading_acc_deg: None,
            satellites: gga.satellites.map_or(0, |n| n.min(255) as u8),
            hdop: gga.hdop.map(f64::from).or(gsa_hdop),
            vdop,
            time_utc_usec: self
                .date
                .zip(e.time)
                .and_then(|(d, t)| utc::unix_usec(d, t)),
        };
        self.epoch.given = true;
        self.counters.solutions += 1;
        self.last_solution = Some(t_s);
        self.silent_said = false;
        events.push(GpsEvent::Solution(solution));
    }

    /// The clock moved to `t_s`: the baud scan while nothing is heard, silence said once, the
    /// scan again after [`LOST_S`].
    pub fn poll(&mut self, t_s: f64, events: &mut Vec<GpsEvent>) {
        if !self.found {
            if self.scan.next_if_due(t_s) {
                self.line.clear();
            }
            return;
        }
        let quiet = self
            .last_solution
            .or(self.last_valid)
            .map_or(0.0, |h| t_s - h);
        if quiet > SILENT_S && !self.silent_said {
            self.silent_said = true;
            events.push(GpsEvent::Silent);
        }
        if self.last_valid.map_or(0.0, |h| t_s - h) > LOST_S {
            events.push(GpsEvent::Lost);
            self.found = false;
            self.scan.restart(t_s);
            self.line.clear();
            self.epoch = Epoch::default();
        }
    }
}

/// An `RMC` whose magnetic variation has no hemisphere (`…,0.0,,A*hh`, as some receivers and
/// pynmeagps write it) with the variation left out, its checksum made again: the `nmea` crate
/// refuses the sentence whole for it, and its time, position, speed and date are good.
fn rmc_without_lone_variation(text: &str) -> Option<String> {
    let body = text.trim_end().strip_prefix('$')?.split('*').next()?;
    let mut fields: Vec<&str> = body.split(',').collect();
    if !fields.first()?.ends_with("RMC") || fields.len() < 12 {
        return None;
    }
    if fields[10].is_empty() || !fields[11].is_empty() {
        return None;
    }
    fields[10] = "";
    let body = fields.join(",");
    let sum = body.bytes().fold(0u8, |a, b| a ^ b);
    Some(format!("${body}*{sum:02X}"))
}

#[cfg(test)]
mod tests;
