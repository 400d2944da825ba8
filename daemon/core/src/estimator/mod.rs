//! State estimation: attitude (q-method + nonlinear observer) and, later, translation.

pub mod accel_bias;
pub mod attitude;
pub mod bias;
pub mod gps_tilt;
pub mod hard_iron;
pub mod heading;
pub mod lowpass;
pub mod motion_start;
pub mod observer;
pub mod realign;
pub mod recovery;
pub mod replay;
pub mod rest;
pub mod tilt_heading;
pub mod translation;
pub mod wahba;
