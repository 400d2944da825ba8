//! The files the daemon reads: the parameter store (its checksum check and its TOML), an
//! airframe, `flight.toml`, signing's memory. Any bytes give a value or an error, never a
//! panic; a store that parses leaves every parameter valid.
#![no_main]

use flight_core::params::FlightParams;
use gcs::param_store::{ParamStore, checked_text};
use gcs::signing::SigningMemory;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let base = FlightParams::default();
    if let Ok(text) = checked_text(data.to_vec()) {
        if let Ok(loaded) = ParamStore::parse(&text, "fuzz", &base) {
            assert!(
                loaded.params.validate().is_empty(),
                "{:?}",
                loaded.params.validate()
            );
            let again = loaded.store.to_toml();
            assert!(
                checked_text(again.into_bytes()).is_ok(),
                "its own text checks out"
            );
        }
    }
    let text = String::from_utf8_lossy(data);
    let _ = airframe::Airframe::from_toml_str(&text, "fuzz");
    let _ = FlightParams::from_toml_str(&text, "fuzz");
    if let Ok(m) = SigningMemory::parse(&text) {
        assert_eq!(
            SigningMemory::parse(&m.to_text()),
            Ok(m),
            "reads back as written"
        );
    }
});
