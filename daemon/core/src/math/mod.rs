//! The mathematics every stage shares: quaternions and geodetic coordinates.

pub mod geo;
pub mod quat;
