//! Bytes as they arrive on a ground-station link: split into frames, each judged by the signing
//! check (a key set, the link untrusted, or trusted by the input's first byte), the accepted ones
//! parsed and handed to the protocol and through it to the vehicle. No panic; the parameters
//! stay valid.
#![no_main]

use autopilot_fuzz::Vehicle;
use gcs::signing::{SecretKey, Signing};
use hil::Decoded;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some((&first, bytes)) = data.split_first() else {
        return;
    };
    let mut signing = Signing::new(Some(SecretKey([7; 32])));
    signing.tick(1_795_400_000_000_000);
    let trusted = first & 1 == 1;
    let mut out = Decoded {
        keep_unparsed: true,
        ..Decoded::default()
    };
    hil::decode_checked(bytes, &mut out, &mut |f| {
        signing.check(f, trusted).accepted()
    });
    let mut v = Vehicle::new(first & 2 == 2);
    let mut outbox = gcs::Outbox::default();
    for (k, (h, m)) in out.messages.iter().enumerate() {
        v.gcs.on_message(h, m, &v.telemetry, &mut outbox);
        v.gcs.poll(1.0 + k as f64 * 0.1, &v.telemetry, &mut outbox);
        v.carry_out(&mut outbox);
    }
    for raw in &out.unparsed {
        v.gcs.on_unparsed(raw, &mut outbox);
    }
    v.assert_params_valid();
});
