#![allow(clippy::unwrap_used)]
use super::*;
use mavlink::dialects::common::{
    COMMAND_LONG_DATA, HEARTBEAT_DATA, MavCmd, MavMessage, MavType, RADIO_STATUS_DATA,
};

const KEY: [u8; 32] = [7; 32];
/// 2026-11-23 in Unix µs.
const NOW_USEC: u64 = 1_795_400_000_000_000;

fn signing(key: [u8; 32]) -> Signing {
    let mut s = Signing::new(Some(SecretKey(key)));
    s.tick(NOW_USEC);
    s
}

fn arm() -> MavMessage {
    MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
        command: MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
        param1: 1.0,
        target_system: 1,
        target_component: 1,
        ..Default::default()
    })
}

fn heartbeat(mavtype: MavType) -> MavMessage {
    MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        mavtype,
        ..Default::default()
    })
}

/// `msg` as an unsigned frame from system 255.
fn frame(msg: &MavMessage) -> Vec<u8> {
    let mut out = Vec::new();
    mavwire::Encoder::with_ids(255, 190).push(&mut out, msg);
    out
}

/// `msg` signed by `sender`.
fn signed(sender: &mut Signing, msg: &MavMessage) -> Vec<u8> {
    let mut f = frame(msg);
    sender.sign(&mut f);
    f
}

#[test]
fn a_signed_frame_is_accepted_once_and_still_decodes() {
    let mut gcs = signing(KEY);
    let mut vehicle = signing(KEY);
    let f = signed(&mut gcs, &arm());
    assert_eq!(f.len(), frame(&arm()).len() + SIGNATURE_LEN);
    assert_eq!(f[2] & IFLAG_SIGNED, IFLAG_SIGNED);
    let d = mavwire::decode(&f);
    assert_eq!(d.messages.len(), 1, "the checksum covers the new flag");
    assert_eq!(d.messages[0].1, arm());
    assert_eq!(vehicle.check(&f, false), Verdict::Signed);
    assert_eq!(
        vehicle.check(&f, false),
        Verdict::RefusedReplay,
        "the same frame again"
    );
    // The next frame of the stream (a later timestamp) is fine.
    assert_eq!(
        vehicle.check(&signed(&mut gcs, &arm()), false),
        Verdict::Signed
    );
    assert_eq!(vehicle.refused.replayed, 1);
}

#[test]
fn wrong_keys_altered_frames_and_unsigned_commands_are_refused() {
    let mut vehicle = signing(KEY);
    let mut other = signing([8; 32]);
    assert_eq!(
        vehicle.check(&signed(&mut other, &arm()), false),
        Verdict::RefusedBadSignature
    );
    let mut gcs = signing(KEY);
    let good = signed(&mut gcs, &arm());
    for i in 1..good.len() {
        let mut bad = good.clone();
        bad[i] ^= 0x10;
        assert!(!vehicle.check(&bad, false).accepted(), "byte {i} changed");
    }
    assert_eq!(
        vehicle.check(&frame(&arm()), false),
        Verdict::RefusedUnsigned
    );
    // A forged frame with a far-future timestamp does not move its stream on.
    let mut forged = good.clone();
    let n = forged.len();
    forged[n - 8] = 0xff;
    assert_eq!(vehicle.check(&forged, false), Verdict::RefusedBadSignature);
    assert_eq!(vehicle.check(&good, false), Verdict::Signed);
    let r = vehicle.refused;
    assert_eq!((r.unsigned, r.replayed), (1, 0));
    assert_eq!(r.bad_signature, good.len() as u64 - 1 + 2);
}

#[test]
fn a_new_stream_more_than_a_minute_old_is_a_replay() {
    let mut vehicle = signing(KEY);
    let mut old = Signing::new(Some(SecretKey(KEY)));
    old.tick(NOW_USEC - 61_000_000);
    assert_eq!(
        vehicle.check(&signed(&mut old, &arm()), false),
        Verdict::RefusedReplay
    );
    let mut recent = Signing::new(Some(SecretKey(KEY)));
    recent.tick(NOW_USEC - 59_000_000);
    assert_eq!(
        vehicle.check(&signed(&mut recent, &arm()), false),
        Verdict::Signed
    );
    // The vehicle's clock follows the newest accepted timestamp.
    let mut ahead = Signing::new(Some(SecretKey(KEY)));
    ahead.tick(NOW_USEC + 30_000_000);
    let f = signed(&mut ahead, &heartbeat(MavType::MAV_TYPE_GCS));
    assert_eq!(vehicle.check(&f, false), Verdict::Signed);
    assert_eq!(vehicle.timestamp(), ahead.timestamp() - 1);
}

#[test]
fn radios_heartbeats_and_trusted_links_may_be_unsigned_a_ground_stations_heartbeat_not() {
    let mut vehicle = signing(KEY);
    let radio = MavMessage::RADIO_STATUS(RADIO_STATUS_DATA::default());
    assert_eq!(vehicle.check(&frame(&radio), false), Verdict::Unsigned);
    let companion = heartbeat(MavType::MAV_TYPE_ONBOARD_CONTROLLER);
    assert_eq!(vehicle.check(&frame(&companion), false), Verdict::Unsigned);
    let generic = heartbeat(MavType::MAV_TYPE_GENERIC); // type 0: truncated away
    assert_eq!(vehicle.check(&frame(&generic), false), Verdict::Unsigned);
    let gcs = heartbeat(MavType::MAV_TYPE_GCS);
    assert_eq!(vehicle.check(&frame(&gcs), false), Verdict::RefusedUnsigned);
    assert_eq!(vehicle.check(&frame(&gcs), true), Verdict::Unsigned);
    assert_eq!(vehicle.check(&frame(&arm()), true), Verdict::Unsigned);
    // MAVLink 1 frames cannot be signed.
    let mut v1 = Vec::new();
    let mut ser = [0u8; 255];
    use mavlink::Message;
    let len = arm().ser(mavlink::MavlinkVersion::V1, &mut ser);
    v1.extend_from_slice(&[0xFE, len as u8, 0, 255, 190, 76]);
    v1.extend_from_slice(&ser[..len]);
    v1.extend_from_slice(&[0, 0]);
    assert_eq!(vehicle.check(&v1, false), Verdict::RefusedUnsigned);
}

#[test]
fn without_a_key_everything_passes_and_nothing_is_signed() {
    let mut off = Signing::new(None);
    let mut gcs = signing([9; 32]);
    assert_eq!(
        off.check(&signed(&mut gcs, &arm()), false),
        Verdict::Unsigned
    );
    assert_eq!(off.check(&frame(&arm()), false), Verdict::Unsigned);
    let mut f = frame(&arm());
    off.sign(&mut f);
    assert_eq!(f, frame(&arm()));
    // SETUP_SIGNING's all-zero key turns it off, any other on.
    let mut s = signing(KEY);
    s.set_key(SecretKey([0; 32]), 0);
    assert!(!s.active());
    s.set_key(SecretKey(KEY), 5);
    assert!(s.active());
}

#[test]
fn the_stream_table_is_bounded() {
    let mut vehicle = signing(KEY);
    for sys in 0..=255u8 {
        for comp in 0..4u8 {
            let mut f = Vec::new();
            mavwire::Encoder::with_ids(sys, comp).push(&mut f, &arm());
            let mut gcs = signing(KEY);
            gcs.sign(&mut f);
            assert_eq!(vehicle.check(&f, false), Verdict::Signed);
        }
    }
    assert_eq!(vehicle.streams.len(), MAX_STREAMS);
}

#[test]
fn keys_are_read_from_64_hexadecimal_digits() {
    let hex = "00112233445566778899aabbccddeeff00112233445566778899AABBCCDDEEFF\n";
    let k = SecretKey::from_hex(hex).unwrap();
    assert_eq!(k.0[1], 0x11);
    assert_eq!(k.to_hex(), hex.trim().to_lowercase());
    for bad in ["", "0011", &hex[..63], &format!("{}g", &hex[..63])] {
        assert!(SecretKey::from_hex(bad).is_err(), "{bad:?}");
    }
    assert_eq!(format!("{k:?}"), "SecretKey(…)");
}

proptest::proptest! {
    /// Whatever a frame holds, judging it does not panic, and nothing unsigned passes but what
    /// the spec lets through.
    #[test]
    fn any_bytes_are_judged_without_panic(
        bytes in proptest::collection::vec(proptest::prelude::any::<u8>(), 0..300),
        signed_flag in proptest::prelude::any::<bool>(),
    ) {
        let mut b = bytes;
        if b.len() > 2 {
            b[0] = STX_V2;
            b[2] = u8::from(signed_flag);
        }
        let mut vehicle = signing(KEY);
        let v = vehicle.check(&b, false);
        proptest::prop_assert!(v != Verdict::Signed, "a random frame passed the signature");
        if v == Verdict::Unsigned {
            proptest::prop_assert!(unsigned_allowed(&b));
        }
    }
}

#[test]
fn a_timestamp_far_ahead_is_refused_and_does_not_move_the_clock() {
    let mut vehicle = signing(KEY);
    let clock = vehicle.timestamp();
    let mut ahead = signing(KEY);
    // Ten years ahead, then two minutes ahead: both refused; one minute ahead is fine.
    ahead.tick(NOW_USEC + 10 * 365 * 86_400 * 1_000_000);
    assert_eq!(
        vehicle.check(&signed(&mut ahead, &arm()), false),
        Verdict::RefusedFuture
    );
    let mut ahead = signing(KEY);
    ahead.tick(NOW_USEC + 120_000_000);
    assert_eq!(
        vehicle.check(&signed(&mut ahead, &arm()), false),
        Verdict::RefusedFuture
    );
    assert_eq!(vehicle.timestamp(), clock, "the clock stays");
    assert_eq!(vehicle.refused.future, 2);
    let mut ahead = signing(KEY);
    ahead.tick(NOW_USEC + 50_000_000);
    assert_eq!(
        vehicle.check(&signed(&mut ahead, &arm()), false),
        Verdict::Signed
    );
}

#[test]
fn a_frame_captured_before_a_restart_is_refused_after_it() {
    let mut gcs = signing(KEY);
    let mut vehicle = signing(KEY);
    let captured = signed(&mut gcs, &arm());
    assert_eq!(vehicle.check(&captured, false), Verdict::Signed);
    let memory = vehicle.memory();
    assert_eq!(memory.streams.len(), 1);
    // A new process a second later: without the memory the capture is a new stream within
    // its minute; with it, a replay.
    let mut forgetful = signing(KEY);
    forgetful.tick(NOW_USEC + 1_000_000);
    assert_eq!(forgetful.check(&captured, false), Verdict::Signed);
    let mut restarted = signing(KEY);
    restarted.tick(NOW_USEC + 1_000_000);
    restarted.remember(&SigningMemory::parse(&memory.to_text()).unwrap());
    assert_eq!(restarted.check(&captured, false), Verdict::RefusedReplay);
    assert_eq!(
        restarted.check(&signed(&mut gcs, &arm()), false),
        Verdict::Signed
    );
}

#[test]
fn a_vehicle_without_a_believable_clock_takes_the_ground_stations() {
    // A board that booted in 1970 (no real-time clock, no network time yet).
    let mut vehicle = Signing::new(Some(SecretKey(KEY)));
    vehicle.tick(0);
    let mut gcs = signing(KEY);
    assert_eq!(
        vehicle.check(&signed(&mut gcs, &arm()), false),
        Verdict::Signed
    );
    assert_eq!(vehicle.timestamp(), gcs.timestamp() - 1);
    // Restarted after a day powered off, its memory kept, still without a wall clock: the
    // ground station's timestamps, a day ahead of the remembered clock, are taken.
    let mut restarted = Signing::new(Some(SecretKey(KEY)));
    restarted.remember(&vehicle.memory());
    restarted.tick(0);
    let mut gcs = signing(KEY);
    gcs.tick(NOW_USEC + 86_400_000_000);
    assert_eq!(
        restarted.check(&signed(&mut gcs, &arm()), false),
        Verdict::Signed
    );
    // Once the wall clock is believable, far ahead is refused.
    restarted.tick(NOW_USEC + 86_400_000_000);
    let mut ahead = signing(KEY);
    ahead.tick(NOW_USEC + 2 * 86_400_000_000);
    assert_eq!(
        restarted.check(&signed(&mut ahead, &arm()), false),
        Verdict::RefusedFuture
    );
}
