//! `RC_CHANNELS`: the RC receiver's last frame, each channel in µs, and the link's quality as
//! its RSSI (0–254, 255 unknown).

use super::prelude::*;

/// `RC_CHANNELS` from the latest telemetry, once an RC frame has come.
pub(super) fn message(s: &StreamInput) -> Option<MavMessage> {
    let rc = s.v.and_then(|v| v.rc)?;
    let f = &rc.frame;
    let ch = |k: usize| {
        if k < usize::from(f.count) {
            f.channels.get(k).copied().unwrap_or(u16::MAX)
        } else {
            u16::MAX
        }
    };
    Some(MavMessage::RC_CHANNELS(RC_CHANNELS_DATA {
        time_boot_ms: (rc.t_s * 1e3) as u32,
        chan1_raw: ch(0),
        chan2_raw: ch(1),
        chan3_raw: ch(2),
        chan4_raw: ch(3),
        chan5_raw: ch(4),
        chan6_raw: ch(5),
        chan7_raw: ch(6),
        chan8_raw: ch(7),
        chan9_raw: ch(8),
        chan10_raw: ch(9),
        chan11_raw: ch(10),
        chan12_raw: ch(11),
        chan13_raw: ch(12),
        chan14_raw: ch(13),
        chan15_raw: ch(14),
        chan16_raw: ch(15),
        chan17_raw: u16::MAX,
        chan18_raw: u16::MAX,
        chancount: f.count,
        rssi: f.link.map_or(u8::MAX, |l| rssi(l.quality_pct)),
    }))
}

/// A link quality (%) on MAVLink's RSSI scale, 0–254.
pub(super) fn rssi(pct: u8) -> u8 {
    (u16::from(pct.min(100)) * 254 / 100) as u8
}
