//! RC receivers on a serial port: what a frame of sticks and switches holds whatever the
//! protocol ([`RcInput`]), what the radio link says of itself ([`RcLink`]), and one reader per
//! protocol: [`crsf::CrsfReader`] (ExpressLRS, TBS Crossfire; with the telemetry a transmitter
//! shows, [`crsf::telemetry`]) and [`sbus::SbusReader`] (Futaba SBUS, FrSky and others).

pub mod crsf;
pub mod sbus;

/// Channels a frame carries at most (CRSF and SBUS both carry 16).
pub const MAX_CHANNELS: usize = 16;

/// One frame of the transmitter's sticks and switches, each channel a pulse width (µs, 1000 to
/// 2000 about a 1500 centre, as PWM receivers and every ground station count them).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RcInput {
    /// The channels, in µs.
    pub channels: [u16; MAX_CHANNELS],
    /// How many of them the protocol carries.
    pub count: u8,
    /// The receiver says this frame was lost over the air (SBUS's frame-lost flag): its
    /// channels are the last ones held.
    pub frame_lost: bool,
    /// The receiver is in failsafe: the transmitter is gone (SBUS's failsafe flag; a CRSF
    /// receiver stops sending channels instead).
    pub failsafe: bool,
}

/// What the radio link says of itself (CRSF's `LINK_STATISTICS`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RcLink {
    /// Uplink RSSI, the better antenna (dBm, negative).
    pub rssi_dbm: i16,
    /// Uplink link quality (% of packets received).
    pub link_quality: u8,
    /// Uplink signal-to-noise ratio (dB).
    pub snr_db: i8,
    /// Downlink (telemetry) RSSI (dBm, negative).
    pub downlink_rssi_dbm: i16,
    /// Downlink link quality (%).
    pub downlink_link_quality: u8,
}

/// What a reader gives.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RcEvent {
    /// A frame of channels.
    Channels(RcInput),
    /// The link's statistics.
    Link(RcLink),
}

/// What a reader has counted.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RcCounters {
    /// Bytes read.
    pub bytes: u64,
    /// Frames decoded whole, checks good.
    pub frames: u64,
    /// Frames refused: bad checksum, bad length, bad end byte.
    pub bad_frames: u64,
}
