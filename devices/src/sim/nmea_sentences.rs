//! NMEA 0183 sentences as a receiver writes them for one epoch: `GGA`, `RMC`, `VTG`, `GSA`
//! and, where the receiver sends it, `GST` (NMEA 0183 version 4.10 layouts, talker `GN`).

use super::ReceiverFix;
use crate::gps::FixType;
use chrono::{DateTime, Datelike, Timelike};
use std::fmt::Write as _;

/// Knots per m/s.
const KNOTS_PER_M_S: f64 = 3600.0 / 1852.0;

/// A UTC time's calendar fields.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Utc {
    /// Year.
    pub year: u16,
    /// Month, 1–12.
    pub month: u8,
    /// Day, 1–31.
    pub day: u8,
    /// Hour.
    pub hour: u8,
    /// Minute.
    pub minute: u8,
    /// Second.
    pub second: u8,
    /// Nanoseconds into the second.
    pub nanos: i32,
}

impl Utc {
    /// The fields of `usec` microseconds since the Unix epoch (the epoch itself when out of
    /// range).
    pub fn of(usec: u64) -> Self {
        let t =
            DateTime::from_timestamp_micros(i64::try_from(usec).unwrap_or(0)).unwrap_or_default();
        Self {
            year: t.year().clamp(0, 65535) as u16,
            month: t.month() as u8,
            day: t.day() as u8,
            hour: t.hour() as u8,
            minute: t.minute() as u8,
            second: t.second() as u8,
            nanos: (t.nanosecond() % 1_000_000_000) as i32,
        }
    }
}

/// Appends `$<body>*hh\r\n`.
fn sentence(body: &str, out: &mut Vec<u8>) {
    let sum = body.bytes().fold(0u8, |a, b| a ^ b);
    out.extend_from_slice(format!("${body}*{sum:02X}\r\n").as_bytes());
}

/// `ddmm.mmmmm,N` or `dddmm.mmmmm,E`.
fn angle(deg: f64, width: usize, pos: char, neg: char) -> String {
    let hemisphere = if deg < 0.0 { neg } else { pos };
    let deg = deg.abs();
    // Rounded to the last digit written, carried into the degrees.
    let total_min = (deg * 60.0 * 1e5).round() / 1e5;
    let whole = (total_min / 60.0).floor();
    let minutes = total_min - whole * 60.0;
    format!(
        "{whole:0width$}{minutes:08.5},{hemisphere}",
        whole = whole as u32
    )
}

/// The sentences of one epoch for `fix`; `gst` adds the accuracies.
pub fn epoch(fix: &ReceiverFix, gst: bool, out: &mut Vec<u8>) {
    let utc = Utc::of(fix.time_utc_usec);
    let centis = utc.nanos / 10_000_000;
    let time = format!(
        "{:02}{:02}{:02}.{centis:02}",
        utc.hour, utc.minute, utc.second
    );
    let date = format!("{:02}{:02}{:02}", utc.day, utc.month, utc.year % 100);
    let lat = angle(fix.lat_deg, 2, 'N', 'S');
    let lon = angle(fix.lon_deg, 3, 'E', 'W');
    let quality = match fix.fix {
        FixType::NoFix => 0,
        FixType::Fix2d | FixType::Fix3d => 1,
        FixType::Dgps => 2,
        FixType::RtkFixed => 4,
        FixType::RtkFloat => 5,
    };
    let valid = fix.fix != FixType::NoFix;
    let [n, e, _] = fix.vel_ned_m_s;
    let knots = n.hypot(e) * KNOTS_PER_M_S;
    let course = e.atan2(n).to_degrees().rem_euclid(360.0);
    let mut s = String::new();
    let _ = write!(
        s,
        "GNGGA,{time},{lat},{lon},{quality},{:02},{:.2},{:.1},M,0.0,M,,",
        fix.satellites, fix.hdop, fix.alt_msl_m
    );
    sentence(&s, out);
    s.clear();
    let (status, mode) = if valid { ('A', 'A') } else { ('V', 'N') };
    let _ = write!(
        s,
        "GNRMC,{time},{status},{lat},{lon},{knots:.3},{course:.2},{date},,,{mode},V"
    );
    sentence(&s, out);
    s.clear();
    let _ = write!(
        s,
        "GNVTG,{course:.2},T,,M,{knots:.3},N,{:.3},K,{mode}",
        knots * 1.852
    );
    sentence(&s, out);
    s.clear();
    let dim = match fix.fix {
        FixType::NoFix => 1,
        FixType::Fix2d => 2,
        _ => 3,
    };
    let _ = write!(s, "GNGSA,A,{dim}");
    for prn in 1..=12u8 {
        if prn <= fix.satellites.min(12) {
            let _ = write!(s, ",{:02}", prn * 2);
        } else {
            s.push(',');
        }
    }
    let g = (fix.pdop * fix.pdop + 1.0).sqrt();
    let _ = write!(s, ",{:.2},{:.2},{:.2},1", fix.pdop, fix.hdop, fix.vdop);
    sentence(&s, out);
    if gst {
        s.clear();
        let sd = fix.h_acc_m / 2f64.sqrt();
        let _ = write!(
            s,
            "GNGST,{time},{g:.1},{:.1},{:.1},0.0,{sd:.2},{sd:.2},{:.2}",
            fix.h_acc_m, fix.h_acc_m, fix.v_acc_m
        );
        sentence(&s, out);
    }
}
