//! A u-blox receiver as the simulator plays it on a serial port: its power-on defaults (NMEA
//! out at 1 Hz, at 9 600 baud on an M8 and 38 400 on later generations), its answers to
//! `MON-VER` polls and to configuration (`CFG-VALSET` from generation 9 on, `CFG-PRT`,
//! `CFG-MSG` and `CFG-RATE` before generation 10), each `ACK-ACK`ed or `ACK-NAK`ed, and its
//! output at each navigation epoch (`NAV-PVT`, `NAV-DOP`, or NMEA sentences) from the
//! simulator's fix. Payload layouts are u-blox's interface descriptions (UBX-18010854 for M8,
//! UBX-19035940 for M9).

use super::ReceiverFix;
use super::nmea_sentences;
use super::ubx_frame::{self, UbxFrame, UbxReader};
use crate::gps::FixType;

/// The receiver generations the simulator plays.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ReceiverModel {
    /// NEO-M8N, protocol 18: legacy configuration only, 9 600 baud.
    M8,
    /// NEO-M9N, protocol 32.01: both interfaces, 38 400 baud.
    M9,
    /// MAX-M10S, protocol 34: `CFG-VALSET` only, 38 400 baud.
    M10,
    /// ZED-F9P, protocol 27.12: both interfaces, 38 400 baud.
    F9p,
}

impl ReceiverModel {
    /// The model named `name` (`m8`, `m9`, `m10`, `f9p`).
    pub fn from_name(name: &str) -> Option<Self> {
        match name.to_ascii_lowercase().as_str() {
            "m8" => Some(Self::M8),
            "m9" => Some(Self::M9),
            "m10" => Some(Self::M10),
            "f9p" => Some(Self::F9p),
            _ => None,
        }
    }

    /// Its baud at power-on.
    pub fn default_baud(self) -> u32 {
        match self {
            Self::M8 => 9_600,
            _ => 38_400,
        }
    }

    /// `MON-VER`'s software version, hardware version and extensions.
    fn version(self) -> (&'static str, &'static str, &'static [&'static str]) {
        match self {
            Self::M8 => (
                "ROM CORE 3.01 (107888)",
                "00080000",
                &["FWVER=SPG 3.01", "PROTVER=18.00", "MOD=NEO-M8N-0"],
            ),
            Self::M9 => (
                "EXT CORE 4.04 (7f89f7)",
                "00190000",
                &["FWVER=SPG 4.04", "PROTVER=32.01", "MOD=NEO-M9N"],
            ),
            Self::M10 => (
                "ROM SPG 5.10 (7b202e)",
                "000A0000",
                &["FWVER=SPG 5.10", "PROTVER=34.10", "MOD=MAX-M10S"],
            ),
            Self::F9p => (
                "EXT CORE 1.00 (61b2dd)",
                "00190000",
                &["FWVER=HPG 1.32", "PROTVER=27.31", "MOD=ZED-F9P"],
            ),
        }
    }

    fn takes_valset(self) -> bool {
        self != Self::M8
    }

    fn takes_legacy(self) -> bool {
        self != Self::M10
    }
}

/// The receiver.
#[derive(Debug)]
pub struct UbloxReceiver {
    model: ReceiverModel,
    baud: u32,
    out_ubx: bool,
    out_nmea: bool,
    pvt_rate: u8,
    dop_rate: u8,
    period_ms: u16,
    epochs: u64,
    reader: UbxReader,
    /// Configuration messages acknowledged and refused, for the simulator's summary.
    pub acks: (u32, u32),
}

// Configuration keys (u-blox's CFG-UART1, CFG-UART1OUTPROT, CFG-UART1INPROT, CFG-MSGOUT,
// CFG-RATE groups).
const KEY_UART1_BAUD: u32 = 0x4052_0001;
const KEY_IN_UBX: u32 = 0x1073_0001;
const KEY_IN_NMEA: u32 = 0x1073_0002;
const KEY_OUT_UBX: u32 = 0x1074_0001;
const KEY_OUT_NMEA: u32 = 0x1074_0002;
const KEY_PVT_UART1: u32 = 0x2091_0007;
const KEY_DOP_UART1: u32 = 0x2091_0039;
const KEY_RATE_MEAS: u32 = 0x3021_0001;
const KEY_RATE_NAV: u32 = 0x3021_0002;
/// USB's protocols and message rates: known, not this UART's (the simulated receiver is on
/// UART1).
const KEYS_USB: [u32; 5] = [
    0x1077_0001,
    0x1078_0001,
    0x1078_0002,
    0x2091_0009,
    0x2091_003B,
];

impl UbloxReceiver {
    /// A receiver at its power-on defaults.
    pub fn new(model: ReceiverModel) -> Self {
        Self {
            model,
            baud: model.default_baud(),
            out_ubx: true,
            out_nmea: true,
            pvt_rate: 0,
            dop_rate: 0,
            period_ms: 1000,
            epochs: 0,
            reader: UbxReader::default(),
            acks: (0, 0),
        }
    }

    /// Back to the power-on defaults (unplugged and plugged in again).
    pub fn restart(&mut self) {
        *self = Self::new(self.model);
    }

    /// The baud its UART is at.
    pub fn baud(&self) -> u32 {
        self.baud
    }

    /// The time between navigation epochs (s).
    pub fn period_s(&self) -> f64 {
        f64::from(self.period_ms) * 1e-3
    }

    /// UBX output configured: `NAV-PVT` on every epoch, NMEA off.
    pub fn configured(&self) -> bool {
        self.pvt_rate == 1 && !self.out_nmea
    }

    /// Bytes from the autopilot (at the receiver's baud): answers appended to `out`. A baud
    /// change takes effect after the answer.
    pub fn receive(&mut self, bytes: &[u8], out: &mut Vec<u8>) {
        let mut frames = Vec::new();
        self.reader.push(bytes, &mut frames);
        for f in frames {
            self.answer(&f, out);
        }
    }

    fn answer(&mut self, f: &UbxFrame, out: &mut Vec<u8>) {
        let ok = match (f.class, f.id) {
            (0x0A, 0x04) if f.payload.is_empty() => {
                self.mon_ver(out);
                return;
            }
            (0x06, 0x8A) => self.model.takes_valset() && self.valset(&f.payload),
            (0x06, 0x00) if f.payload.len() == 20 => {
                self.model.takes_legacy() && self.prt(&f.payload)
            }
            (0x06, 0x08) if f.payload.len() == 6 => {
                let ms = u16::from_le_bytes([f.payload[0], f.payload[1]]);
                self.model.takes_legacy() && self.set_period(ms)
            }
            (0x06, 0x01) if f.payload.len() == 3 || f.payload.len() == 8 => {
                // One rate for the port it arrived on, or six (UART1 the second).
                let rate = f.payload[if f.payload.len() == 3 { 2 } else { 3 }];
                self.model.takes_legacy() && self.set_rate(f.payload[0], f.payload[1], rate)
            }
            (0x06, _) => false,
            _ => return,
        };
        let id = if ok { 0x01 } else { 0x00 };
        if ok {
            self.acks.0 += 1;
        } else {
            self.acks.1 += 1;
        }
        ubx_frame::write(0x05, id, &[f.class, f.id], out);
    }

    fn mon_ver(&self, out: &mut Vec<u8>) {
        let (software, hardware, extensions) = self.model.version();
        let mut payload = Vec::new();
        let mut field = |text: &str, len: usize| {
            let mut b = text.as_bytes().to_vec();
            b.resize(len, 0);
            payload.extend(b);
        };
        field(software, 30);
        field(hardware, 10);
        for e in extensions {
            field(e, 30);
        }
        ubx_frame::write(0x0A, 0x04, &payload, out);
    }

    /// `CFG-VALSET`: every key known and its value in range, else refused whole.
    fn valset(&mut self, payload: &[u8]) -> bool {
        let Some(mut items) = payload.get(4..) else {
            return false;
        };
        let mut staged = Vec::new();
        while items.len() >= 4 {
            let key = u32::from_le_bytes([items[0], items[1], items[2], items[3]]);
            let size = match (key >> 28) & 0x07 {
                1 | 2 => 1,
                3 => 2,
                4 => 4,
                5 => 8,
                _ => return false,
            };
            let Some(value) = items.get(4..4 + size) else {
                return false;
            };
            let mut v = [0u8; 8];
            v[..size].copy_from_slice(value);
            staged.push((key, u64::from_le_bytes(v)));
            items = &items[4 + size..];
        }
        if !items.is_empty() || staged.is_empty() {
            return false;
        }
        let before = (self.baud, self.out_ubx, self.out_nmea);
        let before_rates = (self.pvt_rate, self.dop_rate, self.period_ms);
        let all = staged.iter().all(|&(key, value)| self.set_key(key, value));
        if !all {
            (self.baud, self.out_ubx, self.out_nmea) = before;
            (self.pvt_rate, self.dop_rate, self.period_ms) = before_rates;
        }
        all
    }

    fn set_key(&mut self, key: u32, value: u64) -> bool {
        match key {
            KEY_UART1_BAUD => return self.set_baud(value as u32),
            KEY_OUT_UBX => self.out_ubx = value != 0,
            KEY_OUT_NMEA => self.out_nmea = value != 0,
            KEY_IN_UBX | KEY_IN_NMEA => {}
            KEY_PVT_UART1 => self.pvt_rate = value as u8,
            KEY_DOP_UART1 => self.dop_rate = value as u8,
            KEY_RATE_MEAS => return self.set_period(value as u16),
            KEY_RATE_NAV => return value == 1,
            k if KEYS_USB.contains(&k) => {}
            _ => return false,
        }
        true
    }

    fn set_baud(&mut self, baud: u32) -> bool {
        let ok = [
            4_800, 9_600, 19_200, 38_400, 57_600, 115_200, 230_400, 460_800, 921_600,
        ]
        .contains(&baud);
        if ok {
            self.baud = baud;
        }
        ok
    }

    fn set_period(&mut self, ms: u16) -> bool {
        // 25 ms (40 Hz) is the fastest any generation measures.
        let ok = ms >= 25;
        if ok {
            self.period_ms = ms;
        }
        ok
    }

    fn set_rate(&mut self, class: u8, id: u8, rate: u8) -> bool {
        match (class, id) {
            (0x01, 0x07) => self.pvt_rate = rate,
            (0x01, 0x04) => self.dop_rate = rate,
            _ => {}
        }
        true
    }

    /// `CFG-PRT` for UART1: baud and the output protocols.
    fn prt(&mut self, p: &[u8]) -> bool {
        if p[0] != 1 {
            return false;
        }
        let baud = u32::from_le_bytes([p[8], p[9], p[10], p[11]]);
        let out_mask = u16::from_le_bytes([p[14], p[15]]);
        if !self.set_baud(baud) {
            return false;
        }
        self.out_ubx = out_mask & 0x01 != 0;
        self.out_nmea = out_mask & 0x02 != 0;
        true
    }

    /// One navigation epoch: what the receiver outputs for `fix`, appended to `out`.
    pub fn epoch(&mut self, fix: &ReceiverFix, out: &mut Vec<u8>) {
        self.epochs += 1;
        let due = |rate: u8| rate > 0 && self.epochs.is_multiple_of(u64::from(rate));
        if self.out_ubx && due(self.dop_rate) {
            ubx_frame::write(0x01, 0x04, &nav_dop(fix), out);
        }
        if self.out_ubx && due(self.pvt_rate) {
            ubx_frame::write(0x01, 0x07, &nav_pvt(fix), out);
        }
        if self.out_nmea {
            nmea_sentences::epoch(fix, false, out);
        }
    }
}

/// GPS time of week (ms) of a UTC time: GPS time runs 18 leap seconds ahead of UTC since 2017.
pub fn gps_time_of_week_ms(time_utc_usec: u64) -> u32 {
    const GPS_EPOCH_UNIX_S: u64 = 315_964_800;
    const LEAP_S: u64 = 18;
    let ms = (time_utc_usec / 1000).saturating_sub(GPS_EPOCH_UNIX_S * 1000) + LEAP_S * 1000;
    (ms % (604_800 * 1000)) as u32
}

fn nav_dop(fix: &ReceiverFix) -> Vec<u8> {
    let mut p = Vec::with_capacity(18);
    p.extend(gps_time_of_week_ms(fix.time_utc_usec).to_le_bytes());
    let d = |x: f64| ((x * 100.0).round().clamp(0.0, 65535.0) as u16).to_le_bytes();
    // gDOP, pDOP, tDOP, vDOP, hDOP, nDOP, eDOP.
    let g = (fix.pdop * fix.pdop + 1.0).sqrt();
    for x in [
        g,
        fix.pdop,
        1.0,
        fix.vdop,
        fix.hdop,
        fix.hdop / 2f64.sqrt(),
        fix.hdop / 2f64.sqrt(),
    ] {
        p.extend(d(x));
    }
    p
}

fn nav_pvt(fix: &ReceiverFix) -> Vec<u8> {
    let utc = nmea_sentences::Utc::of(fix.time_utc_usec);
    let mut p = Vec::with_capacity(92);
    p.extend(gps_time_of_week_ms(fix.time_utc_usec).to_le_bytes());
    p.extend(utc.year.to_le_bytes());
    p.extend([utc.month, utc.day, utc.hour, utc.minute, utc.second]);
    p.push(0x07); // validDate, validTime, fullyResolved
    p.extend(20u32.to_le_bytes()); // tAcc (ns)
    p.extend(utc.nanos.to_le_bytes());
    let (fix_type, mut flags) = match fix.fix {
        FixType::NoFix => (0u8, 0u8),
        FixType::Fix2d => (2, 0x01),
        FixType::Fix3d => (3, 0x01),
        FixType::Dgps => (3, 0x03),
        FixType::RtkFloat => (3, 0x43),
        FixType::RtkFixed => (3, 0x83),
    };
    if fix_type == 0 {
        flags = 0;
    }
    p.extend([fix_type, flags, 0xE0, fix.satellites]); // flags2: confirmed date and time
    let i = |x: f64, scale: f64| ((x * scale).round() as i32).to_le_bytes();
    let u = |x: f64, scale: f64| ((x * scale).round().max(0.0) as u32).to_le_bytes();
    p.extend(i(fix.lon_deg, 1e7));
    p.extend(i(fix.lat_deg, 1e7));
    // The simulator has no geoid: the height above the ellipsoid is the height above sea level.
    p.extend(i(fix.alt_msl_m, 1e3));
    p.extend(i(fix.alt_msl_m, 1e3));
    p.extend(u(fix.h_acc_m, 1e3));
    p.extend(u(fix.v_acc_m, 1e3));
    let [n, e, d] = fix.vel_ned_m_s;
    for v in [n, e, d] {
        p.extend(i(v, 1e3));
    }
    let speed = n.hypot(e);
    let heading = e.atan2(n).to_degrees().rem_euclid(360.0);
    p.extend(i(speed, 1e3));
    p.extend(i(heading, 1e5));
    p.extend(u(fix.s_acc_m_s, 1e3));
    // Heading accuracy: the speed's accuracy as an angle, capped at 180°.
    let head_acc = (fix.s_acc_m_s / speed.max(1e-3))
        .atan()
        .to_degrees()
        .min(180.0);
    p.extend(u(head_acc, 1e5));
    p.extend(((fix.pdop * 100.0).round().clamp(0.0, 65535.0) as u16).to_le_bytes());
    p.extend(u16::from(fix.fix == FixType::NoFix).to_le_bytes()); // flags3: invalidLlh
    p.extend([0u8; 4]);
    p.extend(i(heading, 1e5)); // headVeh: the heading of motion
    p.extend([0u8; 4]); // magDec, magAcc
    p
}

#[cfg(test)]
mod tests;
