//! The cascade controller: attitude (outer) and rate (inner) loops.

pub mod attitude;
pub mod rate;
