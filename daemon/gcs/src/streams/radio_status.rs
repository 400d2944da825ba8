//! `RADIO_STATUS`: the RC link's quality both ways, as a receiver's `LINK_STATISTICS` says it:
//! `rssi` the uplink's link quality and `remrssi` the telemetry downlink's, on MAVLink's 0–254
//! scale; `noise` the uplink's signal-to-noise margin below its RSSI, on the same scale as the
//! RSSI in dBm (0 at −127 dBm).

use super::prelude::*;

/// `RADIO_STATUS` from the latest telemetry, once the RC link has said how it is.
pub(super) fn message(s: &StreamInput) -> Option<MavMessage> {
    let l = s.v.and_then(|v| v.rc)?.frame.link?;
    let noise_dbm = i32::from(l.rssi_dbm) - i32::from(l.snr_db);
    Some(MavMessage::RADIO_STATUS(RADIO_STATUS_DATA {
        rxerrors: 0,
        fixed: 0,
        rssi: super::rc_channels::rssi(l.quality_pct),
        remrssi: super::rc_channels::rssi(l.downlink_quality_pct),
        txbuf: 100,
        noise: (noise_dbm + 127).clamp(0, 254) as u8,
        remnoise: u8::MAX,
    }))
}
