//! What every MAVLink link of the project shares, without the simulator's physics: frames
//! encoded and decoded without per-frame allocation (`wire.rs`), the UDP and serial byte
//! transports ([`transport`], feature `transport`), and the simulator's ground truth as
//! `HIL_STATE_QUATERNION` carries it ([`TruthReport`]). The HIL link (`hil`) and the
//! ground-station links (`gcs`) both build on it.

#[cfg(feature = "transport")]
pub mod transport;
mod truth;
mod wire;

pub use truth::TruthReport;
pub use wire::{
    Decoded, Encoder, MAX_FRAME, RawMessage, StreamDecoder, checksum, decode, decode_checked,
    decode_into,
};
