//! State estimation: attitude (q-method + nonlinear observer) and, later, translation.

pub mod attitude;
pub mod observer;
pub mod translation;
pub mod wahba;
