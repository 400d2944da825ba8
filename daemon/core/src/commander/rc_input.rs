//! An RC transmitter's channels as the commander takes them, as PX4's `rc_update` and
//! `manual_control` read them: each channel normalised by its calibration (`RCn_MIN`,
//! `RCn_TRIM`, `RCn_MAX`, `RCn_REV`, `RCn_DZ`), the sticks by `RC_MAP_*`, the mode switch's
//! travel cut in six slots (`COM_FLTMODE1`…`6`: a three-position switch selects 1, 4 and 6),
//! the arm switch against `RC_ARMSWITCH_TH`, and the stick gesture (throttle low, yaw right
//! for a second arms; yaw left disarms on the ground).

mod params;

pub use params::{RC_META, RcGroup};

use super::{FlightMode, Sticks};

/// The channels an RC frame carries at most.
pub const RC_CHANNELS: usize = 16;

/// One frame from the RC receiver, as the autopilot takes it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RcFrame {
    /// Channels (µs).
    pub channels: [u16; RC_CHANNELS],
    /// How many are carried.
    pub count: u8,
    /// The receiver is in failsafe (the transmitter is gone): the channels are not the pilot's.
    pub failsafe: bool,
    /// The radio link's quality, when the receiver says (CRSF's `LINK_STATISTICS`).
    pub link: Option<RcLinkQuality>,
}

/// What an RC link says of itself, for the ground stations (`RC_CHANNELS.rssi`,
/// `RADIO_STATUS`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RcLinkQuality {
    /// Uplink RSSI (dBm).
    pub rssi_dbm: i16,
    /// Uplink link quality (% of packets received).
    pub quality_pct: u8,
    /// Uplink signal-to-noise ratio (dB).
    pub snr_db: i8,
    /// Downlink (telemetry) link quality (%).
    pub downlink_quality_pct: u8,
}

/// What the transmitter asks for in one frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RcDemand {
    /// The sticks.
    pub sticks: Sticks,
    /// The mode switch's slot (0–5), when a switch is mapped.
    pub mode_slot: Option<usize>,
    /// The arm switch, when one is mapped.
    pub arm_switch: Option<bool>,
}

/// How long the arm gesture is held (s), PX4's `COM_RC_ARM_HYST`.
pub const GESTURE_S: f64 = 1.0;

/// The mode of a `COM_FLTMODEn` value (PX4's main-mode numbers); `None` for unassigned or a
/// mode this autopilot does not fly from a switch (Acro, Offboard, Follow Me, …).
pub fn px4_mode(number: i32) -> Option<FlightMode> {
    Some(match number {
        0 => FlightMode::Manual,
        1 => FlightMode::Altctl,
        2 => FlightMode::Posctl,
        3 => FlightMode::Mission,
        4 => FlightMode::Loiter,
        5 => FlightMode::Rtl,
        8 => FlightMode::Stabilized,
        10 => FlightMode::Takeoff,
        11 => FlightMode::Land,
        14 => FlightMode::Orbit,
        _ => return None,
    })
}

/// One channel's calibration (`RCn_MIN`, `RCn_TRIM`, `RCn_MAX`, `RCn_REV`, `RCn_DZ`).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Calibration {
    min: f64,
    trim: f64,
    max: f64,
    reversed: bool,
    dead_zone: f64,
}

impl RcGroup {
    /// Channel `c`'s (1-based) calibration, read from its fields (no lookup by name on a
    /// frame's path).
    fn calibration(&self, c: usize) -> Option<Calibration> {
        macro_rules! k {
            ($min:ident, $trim:ident, $max:ident, $rev:ident, $dz:ident) => {
                Calibration {
                    min: self.$min,
                    trim: self.$trim,
                    max: self.$max,
                    reversed: self.$rev < 0.0,
                    dead_zone: self.$dz,
                }
            };
        }
        Some(match c {
            1 => k!(rc1_min, rc1_trim, rc1_max, rc1_rev, rc1_dz),
            2 => k!(rc2_min, rc2_trim, rc2_max, rc2_rev, rc2_dz),
            3 => k!(rc3_min, rc3_trim, rc3_max, rc3_rev, rc3_dz),
            4 => k!(rc4_min, rc4_trim, rc4_max, rc4_rev, rc4_dz),
            5 => k!(rc5_min, rc5_trim, rc5_max, rc5_rev, rc5_dz),
            6 => k!(rc6_min, rc6_trim, rc6_max, rc6_rev, rc6_dz),
            7 => k!(rc7_min, rc7_trim, rc7_max, rc7_rev, rc7_dz),
            8 => k!(rc8_min, rc8_trim, rc8_max, rc8_rev, rc8_dz),
            9 => k!(rc9_min, rc9_trim, rc9_max, rc9_rev, rc9_dz),
            10 => k!(rc10_min, rc10_trim, rc10_max, rc10_rev, rc10_dz),
            11 => k!(rc11_min, rc11_trim, rc11_max, rc11_rev, rc11_dz),
            12 => k!(rc12_min, rc12_trim, rc12_max, rc12_rev, rc12_dz),
            13 => k!(rc13_min, rc13_trim, rc13_max, rc13_rev, rc13_dz),
            14 => k!(rc14_min, rc14_trim, rc14_max, rc14_rev, rc14_dz),
            15 => k!(rc15_min, rc15_trim, rc15_max, rc15_rev, rc15_dz),
            16 => k!(rc16_min, rc16_trim, rc16_max, rc16_rev, rc16_dz),
            _ => return None,
        })
    }

    /// Channel `c` (1-based; 0 is none) of `frame`, normalised to −1…1 about its trim.
    pub fn centred(&self, frame: &RcFrame, c: u32) -> Option<f64> {
        let (v, k) = self.raw(frame, c)?;
        let (min, trim, max, dz) = (k.min, k.trim, k.max, k.dead_zone);
        let n = if v > trim + dz {
            (v - trim - dz) / (max - trim - dz).max(1.0)
        } else if v < trim - dz {
            (v - trim + dz) / (trim - min - dz).max(1.0)
        } else {
            0.0
        };
        let n = n.clamp(-1.0, 1.0);
        Some(if k.reversed { -n } else { n })
    }

    /// Channel `c` of `frame` as a fraction 0…1 of its travel (the throttle, the switches).
    pub fn travel(&self, frame: &RcFrame, c: u32) -> Option<f64> {
        let (v, k) = self.raw(frame, c)?;
        let t = ((v - k.min) / (k.max - k.min).max(1.0)).clamp(0.0, 1.0);
        Some(if k.reversed { 1.0 - t } else { t })
    }

    fn raw(&self, frame: &RcFrame, c: u32) -> Option<(f64, Calibration)> {
        let c = usize::try_from(c)
            .ok()
            .filter(|&c| c >= 1 && c <= usize::from(frame.count))?;
        Some((f64::from(*frame.channels.get(c - 1)?), self.calibration(c)?))
    }

    /// What `frame` asks for.
    pub fn demand(&self, frame: &RcFrame) -> RcDemand {
        let stick = |c| self.centred(frame, c).unwrap_or(0.0);
        RcDemand {
            sticks: Sticks {
                forward: stick(self.map_pitch),
                right: stick(self.map_roll),
                throttle: self.travel(frame, self.map_throttle).unwrap_or(0.5),
                yaw: stick(self.map_yaw),
            },
            mode_slot: self
                .travel(frame, self.map_mode)
                .map(|t| ((t * 6.0) as usize).min(5)),
            arm_switch: self
                .travel(frame, self.map_arm)
                .map(|t| t > self.arm_threshold),
        }
    }

    /// The mode of slot `slot` (0–5), `None` when unassigned.
    pub fn slot_mode(&self, slot: usize) -> Option<FlightMode> {
        let number = [
            self.fltmode1,
            self.fltmode2,
            self.fltmode3,
            self.fltmode4,
            self.fltmode5,
            self.fltmode6,
        ];
        px4_mode(*number.get(slot)?)
    }
}

/// The stick gesture: which way it is held, since when.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Gesture {
    held: Option<(bool, f64)>,
}

impl Gesture {
    /// The sticks at `t_s`: `Some(true)` once throttle low and yaw right have been held for
    /// [`GESTURE_S`] (arm), `Some(false)` for yaw left (disarm); once each time it is held.
    pub fn update(&mut self, t_s: f64, s: &Sticks) -> Option<bool> {
        let now = (s.throttle < 0.1).then_some(()).and_then(|()| {
            if s.yaw > 0.9 {
                Some(true)
            } else if s.yaw < -0.9 {
                Some(false)
            } else {
                None
            }
        });
        match (now, self.held) {
            (None, _) => {
                self.held = None;
                None
            }
            (Some(arm), Some((was, since))) if arm == was => {
                if since.is_finite() && t_s - since >= GESTURE_S {
                    self.held = Some((arm, f64::INFINITY)); // said once
                    return Some(arm);
                }
                None
            }
            (Some(arm), _) => {
                self.held = Some((arm, t_s));
                None
            }
        }
    }
}

#[cfg(test)]
mod tests;
