//! What the tilt/heading filter has done: its counters and the resets of its estimate.

/// Counters of the tilt/heading filter.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct TiltHeadingStatus {
    /// Samples taken at rest.
    pub at_rest: u64,
    /// Magnetometer samples rejected as disturbed.
    pub mag_disturbed: u64,
    /// Times a new magnetic reference was adopted.
    pub mag_new_reference: u64,
    /// Online hard-iron fits accepted.
    pub hard_iron_fits: u64,
    /// Angle of the last tilt correction (rad).
    pub tilt_correction_rad: f64,
    /// Angle between the last magnetic heading and the estimate (rad).
    pub heading_error_rad: f64,
    /// The tilt taken from a steady accelerometer at once (`recovery.rs`), the heading from a
    /// clean magnetometer: how often, and the last ones' sizes.
    pub reset: EstimateReset,
    /// The bias and attitude were fitted to the first seconds of a start in motion.
    pub started_in_motion: bool,
    /// Attitudes found again in flight.
    pub realigned_in_flight: u64,
    /// Gaps in flight after which none could be (no GPS, or no thrust): the filter went on
    /// from the accelerometer.
    pub realign_abandoned: u64,
}

/// The resets of the attitude estimate so far.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct EstimateReset {
    /// Tilt resets.
    pub tilt: u64,
    /// The last tilt reset's size (rad).
    pub tilt_rad: f64,
    /// Heading resets.
    pub heading: u64,
    /// The last heading reset's size (rad, signed).
    pub heading_rad: f64,
}
