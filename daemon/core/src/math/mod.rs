//! The mathematics every stage shares, from the `navmath` crate the simulator uses too:
//! quaternions and geodetic coordinates.

pub use navmath::{geo, quat};
