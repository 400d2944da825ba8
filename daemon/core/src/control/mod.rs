//! The cascade controller: attitude (outer) and rate (inner) loops.

pub mod attitude;
pub mod motor;
pub mod position;
pub mod rate;
