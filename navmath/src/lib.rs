//! The mathematics the autopilot and the simulator share, so that both sides of the link turn
//! a rotation or a position the same way: quaternion algebra ([`quat`]) and WGS-84 positions
//! with the local NED frame around home ([`geo`]). Pure: no I/O, no clock.
//!
//! Feature `serde`: [`geo::LatLonAlt`] reads from TOML (a scenario's home).

pub mod geo;
pub mod quat;
