//! The devices a real vehicle carries on its serial ports, as pure state machines: bytes read
//! from the port go in with the time they arrived, what they mean comes out as events, and the
//! bytes the device must be told (its configuration) and the baud the port must be at are
//! asked for. Nothing here opens a port or reads a clock: the daemon's edge does
//! (`daemon/src/devices/`), and tests drive the machines with bytes alone.
//!
//! - [`gps`]: a u-blox receiver (UBX: baud detection, configuration through the generation-9
//!   `CFG-VALSET` interface or the older `CFG-PRT`/`CFG-MSG`/`CFG-RATE`, `NAV-PVT` and
//!   `NAV-DOP`) or any NMEA 0183 receiver (GGA, RMC, VTG, GSA, GST).
//! - [`rc`]: an RC receiver: CRSF (ExpressLRS, TBS Crossfire: channels, link statistics, and
//!   the telemetry a transmitter shows) or SBUS (channels, frame-lost and failsafe flags).
//! - [`sim`]: the same devices as the simulator plays them, so that the autopilot flies
//!   through the real protocols in SITL.

pub mod gps;
pub mod rc;
pub mod sim;
