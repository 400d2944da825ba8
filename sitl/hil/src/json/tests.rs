//! The JSON interface against ArduPilot's declared layouts and its own reading rule.
#![allow(clippy::unwrap_used)]
use super::*;

#[test]
fn the_servo_packet_is_laid_out_as_ardupilot_declares_it() {
    let p = ServoPacket::new(400, 0x0102_0304, &[1000, 1500, 2000, 1100]);
    let mut bytes = Vec::new();
    p.encode(&mut bytes);
    // struct { uint16_t magic = 18458; uint16_t frame_rate; uint32_t frame_count;
    // uint16_t pwm[16]; }, little-endian, no padding.
    assert_eq!(bytes.len(), 40);
    assert_eq!(
        &bytes[..8],
        &[0x1A, 0x48, 0x90, 0x01, 0x04, 0x03, 0x02, 0x01]
    );
    assert_eq!(&bytes[8..12], &[0xE8, 0x03, 0xDC, 0x05]);
    assert!(bytes[16..].iter().all(|&b| b == 0), "unused channels 0");
    let back = ServoPacket::decode(&bytes).unwrap();
    assert_eq!(back.pwm().len(), 16);
    assert_eq!(&back.pwm()[..4], &[1000, 1500, 2000, 1100]);
    assert_eq!((back.frame_rate, back.frame_count), (400, 0x0102_0304));

    let wide = ServoPacket::new(1000, 7, &[1234; 20]);
    let mut bytes = Vec::new();
    wide.encode(&mut bytes);
    assert_eq!(
        (bytes.len(), u16::from_le_bytes([bytes[0], bytes[1]])),
        (72, MAGIC_32)
    );
    assert_eq!(ServoPacket::decode(&bytes).unwrap().pwm()[19], 1234);

    for bad in [&bytes[..7], &bytes[..40], &[0u8; 40][..]] {
        assert!(ServoPacket::decode(bad).is_err(), "{bad:?}");
    }
}

#[test]
fn pwm_maps_to_commands_and_back() {
    assert_eq!(pwm_from_command(0.0), 1000);
    assert_eq!(pwm_from_command(0.5), 1500);
    assert_eq!(pwm_from_command(1.7), 2000);
    assert_eq!(pwm_from_command(f64::NAN), 1000);
    assert_eq!(command_from_pwm(0), 0.0);
    assert_eq!(command_from_pwm(1250), 0.25);
    assert_eq!(command_from_pwm(2100), 1.0);
}

/// A state with every field ours sends.
fn our_state() -> PhysicsState {
    PhysicsState {
        timestamp_s: 12.004,
        gyro_frd_rad_s: Vector3::new(0.01, -0.02, 0.3),
        accel_frd_m_s2: Vector3::new(0.1, 0.2, -9.81),
        pos_ned_m: Vector3::new(3.0, -4.0, -5.5),
        vel_ned_m_s: Vector3::new(0.5, 0.0, -1.0),
        q_ned_from_frd: UnitQuaternion::from_euler_angles(0.1, -0.2, 2.0),
        battery: Some((15.9, 12.5)),
        airspeed_m_s: Some(7.25),
    }
}

#[test]
fn ardupilots_documented_state_parses_and_ours_round_trips() {
    // The documentation's example: Euler angles instead of a quaternion, other keys.
    let doc = r#"{"timestamp": 2.5, "imu": {"gyro": [0.1, 0, 0], "accel_body": [0, 0, -9.8]},
        "position": [1, 2, -3], "attitude": [0, 0, 1.5707963267948966],
        "velocity": [0, 0.5, 0], "airspeed": 3.2, "rng_1": 4}"#;
    let s = PhysicsState::parse(&doc.replace('\n', " ")).unwrap();
    assert_eq!(s.timestamp_s, 2.5);
    assert_eq!(s.pos_ned_m, Vector3::new(1.0, 2.0, -3.0));
    assert_eq!(s.accel_frd_m_s2.z, -9.8);
    // Yawed 90°: the nose points east.
    let nose = s.q_ned_from_frd.transform_vector(&Vector3::x());
    assert!((nose - Vector3::y()).norm() < 1e-12, "{nose}");
    assert_eq!((s.battery, s.airspeed_m_s), (None, Some(3.2)));

    let ours = our_state();
    let text = ours.to_json();
    assert!(text.starts_with('\n') && text.ends_with('\n'));
    assert_eq!(text.trim().lines().count(), 1, "one line");
    // Two states queued in one datagram: the newer is taken.
    let mut older = ours;
    older.timestamp_s = 12.0;
    let datagram = older.to_json() + &text;
    let mut back = PhysicsState::parse_latest(datagram.as_bytes()).unwrap();
    // Every number exactly; the quaternion renormalised, within an ulp.
    assert!(back.q_ned_from_frd.angle_to(&ours.q_ned_from_frd) < 1e-12);
    back.q_ned_from_frd = ours.q_ned_from_frd;
    assert_eq!(back, ours);
}

#[test]
fn states_missing_a_field_or_not_finite_are_refused() {
    let good = r#"{"timestamp": 1, "imu": {"gyro": [0,0,0], "accel_body": [0,0,-9.8]}, "position": [0,0,0], "velocity": [0,0,0], "quaternion": [1,0,0,0]}"#;
    assert!(PhysicsState::parse(good).is_ok());
    for (from, to) in [
        ("\"timestamp\": 1", "\"time\": 1"),
        ("\"gyro\": [0,0,0]", "\"gyro\": [0,0]"),
        ("\"position\": [0,0,0]", "\"position\": [0,0,\"x\"]"),
        ("\"quaternion\": [1,0,0,0]", "\"quaternion\": [0,0,0,0]"),
        ("\"quaternion\": [1,0,0,0]", "\"heading\": 3"),
        ("\"timestamp\": 1", "\"timestamp\": 1e999"),
    ] {
        let text = good.replace(from, to);
        assert!(PhysicsState::parse(&text).is_err(), "{text}");
    }
    assert!(PhysicsState::parse("{\"timestamp\": ").is_err());
    assert!(PhysicsState::parse_latest(b"\n\n").is_err());
    assert!(PhysicsState::parse_latest(&[0xff, 0xfe]).is_err());
}

/// ArduPilot's reading of a state, as `libraries/SITL/SIM_JSON.cpp` (`recv_fdm`,
/// `parse_sensors`) and its key table (`SIM_JSON.h`) state it, written again here: no JSON
/// parser, but `strstr` for the section and the key, a skip of the key's length plus two, then
/// `atof` or `sscanf("[%f, %f, %f]")` at that place.
mod ardupilot_rule {
    /// One key of ArduPilot's table: section, key, kind, required.
    pub const KEYTABLE: [(&str, &str, Kind, bool); 17] = [
        ("", "timestamp", Kind::Double, true),
        ("imu", "gyro", Kind::Vector3, true),
        ("imu", "accel_body", Kind::Vector3, true),
        ("", "position", Kind::Vector3, true),
        ("", "attitude", Kind::Vector3, false),
        ("", "quaternion", Kind::Quaternion, false),
        ("", "velocity", Kind::Vector3, true),
        ("", "rng_1", Kind::Double, false),
        ("", "rng_2", Kind::Double, false),
        ("", "rng_3", Kind::Double, false),
        ("", "rng_4", Kind::Double, false),
        ("", "rng_5", Kind::Double, false),
        ("", "rng_6", Kind::Double, false),
        ("windvane", "direction", Kind::Double, false),
        ("windvane", "speed", Kind::Double, false),
        ("", "airspeed", Kind::Double, false),
        ("", "no_time_sync", Kind::Double, false),
    ];

    #[derive(Debug, Clone, Copy, PartialEq)]
    pub enum Kind {
        Double,
        Vector3,
        Quaternion,
    }

    /// What `parse_sensors` found: the received bitmask and each key's numbers, or the message
    /// ArduPilot prints when it gives up.
    pub fn parse_sensors(json: &str) -> Result<(u32, Vec<Vec<f64>>), String> {
        let mut mask = 0u32;
        let mut values = vec![Vec::new(); KEYTABLE.len()];
        for (i, &(section, key, kind, required)) in KEYTABLE.iter().enumerate() {
            let Some(at) = json.find(section) else {
                if required {
                    return Err(format!("Failed to find {section}"));
                }
                continue;
            };
            let p = &json[(at + section.len() + 1).min(json.len())..];
            let Some(at) = p.find(key) else {
                if required {
                    return Err(format!("Failed to find key {section}/{key}"));
                }
                continue;
            };
            mask |= 1 << i;
            let p = p.get(at + key.len() + 2..).unwrap_or("");
            values[i] = match kind {
                Kind::Double => vec![atof(p)],
                Kind::Vector3 | Kind::Quaternion => {
                    let n = if kind == Kind::Vector3 { 3 } else { 4 };
                    match sscanf_floats(p, n) {
                        Some(v) => v,
                        None => {
                            return Err(format!("Failed to parse Vector for {section}/{key}"));
                        }
                    }
                }
            };
        }
        Ok((mask, values))
    }

    /// `atof`: leading white space skipped, the longest number there, 0 if none.
    fn atof(p: &str) -> f64 {
        let p = p.trim_start();
        (1..=p.len())
            .rev()
            .filter(|&n| p.is_char_boundary(n))
            .find_map(|n| p[..n].parse::<f64>().ok())
            .unwrap_or(0.0)
    }

    /// `sscanf(p, "[%f, %f, %f]")`: `[` must be the very first character (a literal in a
    /// format skips no white space), each `%f` skips white space, each `,` is a literal and the
    /// space after it skips any white space. `None` unless all `n` conversions succeed.
    fn sscanf_floats(p: &str, n: usize) -> Option<Vec<f64>> {
        let mut rest = p.strip_prefix('[')?;
        let mut out = Vec::new();
        for k in 0..n {
            rest = rest.trim_start();
            let len = (1..=rest.len())
                .rev()
                .filter(|&l| rest.is_char_boundary(l))
                .find(|&l| rest[..l].parse::<f32>().is_ok())?;
            out.push(f64::from(rest[..len].parse::<f32>().ok()?));
            rest = &rest[len..];
            if k + 1 < n {
                rest = rest.strip_prefix(',')?.trim_start();
            }
        }
        Some(out)
    }

    /// `recv_fdm`'s framing: datagrams appended to a buffer, every newline made a NUL, and the
    /// text between the last two NULs parsed (nothing, while there are not two).
    pub fn last_line(buffer: &[u8]) -> Option<String> {
        let text: Vec<u8> = buffer
            .iter()
            .map(|&b| if b == b'\n' { 0 } else { b })
            .collect();
        let p2 = text.iter().rposition(|&b| b == 0).filter(|&p| p > 0)?;
        let p1 = text[..p2].iter().rposition(|&b| b == 0)?;
        Some(String::from_utf8_lossy(&text[p1 + 1..p2]).into_owned())
    }
}

#[test]
fn ardupilot_reads_every_field_of_our_state_by_its_own_rule() {
    let ours = our_state();
    // The first datagram ArduPilot ever gets: the newline before the state gives it two NULs.
    let line = ardupilot_rule::last_line(ours.to_json().as_bytes()).unwrap();
    let (mask, values) = ardupilot_rule::parse_sensors(&line).unwrap();
    let key = |name: &str| {
        let i = ardupilot_rule::KEYTABLE
            .iter()
            .position(|k| k.1 == name)
            .unwrap();
        assert!(mask & (1 << i) != 0, "{name} not received");
        values[i].clone()
    };
    let close = |got: Vec<f64>, want: &[f64]| {
        assert_eq!(got.len(), want.len());
        for (g, w) in got.iter().zip(want) {
            // %f reads into a float: within its precision.
            assert!(
                (g - w).abs() <= 1e-6 * w.abs().max(1.0),
                "{got:?} against {want:?}"
            );
        }
    };
    close(key("timestamp"), &[12.004]);
    close(key("gyro"), &[0.01, -0.02, 0.3]);
    close(key("accel_body"), &[0.1, 0.2, -9.81]);
    close(key("position"), &[3.0, -4.0, -5.5]);
    close(key("velocity"), &[0.5, 0.0, -1.0]);
    let q = ours.q_ned_from_frd.quaternion();
    close(key("quaternion"), &[q.w, q.i, q.j, q.k]);
    close(key("airspeed"), &[7.25]);
    // Nothing else was taken for a key of ArduPilot's (no attitude, rangefinder, wind vane).
    let received: Vec<&str> = ardupilot_rule::KEYTABLE
        .iter()
        .enumerate()
        .filter(|(i, _)| mask & (1 << i) != 0)
        .map(|(_, k)| k.1)
        .collect();
    assert_eq!(
        received,
        [
            "timestamp",
            "gyro",
            "accel_body",
            "position",
            "quaternion",
            "velocity",
            "airspeed"
        ]
    );
}

#[test]
fn the_rule_refuses_what_it_refused_before_compact_output() {
    // The old output, with a space after each colon: ArduPilot could read no vector.
    let spaced = r#"{"timestamp": 1e0, "imu": {"gyro": [0e0, 0e0, 0e0], "accel_body": [0e0, 0e0, -9.8e0]}, "position": [0e0, 0e0, 0e0], "velocity": [0e0, 0e0, 0e0], "quaternion": [1e0, 0e0, 0e0, 0e0]}"#;
    assert_eq!(
        ardupilot_rule::parse_sensors(spaced),
        Err("Failed to parse Vector for imu/gyro".into())
    );
    // The documentation's example, compact, reads.
    let doc = r#"{"timestamp":2500,"imu":{"gyro":[0,0,0],"accel_body":[0,0,0]},"position":[0,0,0],"attitude":[0,0,0],"velocity":[0,0,0]}"#;
    assert!(ardupilot_rule::parse_sensors(doc).is_ok());
    // A state without the newline before it is not read until the next one arrives.
    assert_eq!(ardupilot_rule::last_line(b"{\"timestamp\":1}\n"), None);
}

#[test]
fn the_reader_skips_every_kind_of_value_and_refuses_what_is_not_json() {
    let good = r#"{"timestamp": 1, "imu": {"gyro": [0,0,0], "accel_body": [0,0,-9.8]}, "position": [0,0,0], "velocity": [0,0,0], "quaternion": [1,0,0,0]}"#;
    // Keys it does not know, of every kind, are checked and skipped, at every level.
    let extra = r#"{"rng_1": 4.5e-1, "name": "q\"u\\ad\u00e9", "ok": true, "no": false, "x": null,
        "list": [[], {}, [1, [2, {"a": [3]}]], "s"], "obj": {"k": {"j": -0.0}},
        "imu": {"temperature": 30, "gyro": [0,0,0], "accel_body": [0,0,-9.8]},
        "battery": {"voltage": 12.6, "cells": [4.2, 4.2, 4.2]},
        "timestamp": 1, "position": [0,0,0], "velocity": [0,0,0], "quaternion": [1,0,0,0]}"#;
    let s = PhysicsState::parse(&extra.replace('\n', " ")).unwrap();
    assert_eq!(s.battery, Some((12.6, 0.0)));
    assert_eq!(
        s,
        PhysicsState {
            battery: Some((12.6, 0.0)),
            ..PhysicsState::parse(good).unwrap()
        }
    );
    let deep = format!("{}{}", "[".repeat(100_000), "]".repeat(100_000));
    for bad in [
        "",
        "[]",
        "{",
        "{\"timestamp\" 1}",
        "{\"timestamp\": 1,}",
        "{\"timestamp\": tru}",
        "{\"timestamp\": 1} x",
        "{\"a\": \"unterminated}",
        "{\"a\": [1 2]}",
        "{\"a\": .5}",
        "{\"a\": \"\u{1}\"}",
        &format!("{{\"a\": {deep}}}"),
        &good.replace("[0,0,-9.8]", "[0,0,-9.8,1]"),
        &good.replace("\"timestamp\": 1", "\"timestamp\": \"1\""),
        &good.replace("\"timestamp\": 1", "\"timestamp\": 1e5e5"),
    ] {
        assert!(PhysicsState::parse(bad).is_err(), "{bad:.80}");
    }
}

/// j 5^k in decimal digits (a number of base-10^9 limbs, multiplied by 5 k times).
fn times_power_of_five(j: u64, k: u32) -> String {
    const BASE: u64 = 1_000_000_000;
    let mut limbs = vec![j % BASE, (j / BASE) % BASE, j / BASE / BASE];
    for _ in 0..k {
        let mut carry = 0;
        for l in &mut limbs {
            let x = *l * 5 + carry;
            (*l, carry) = (x % BASE, x / BASE);
        }
        if carry > 0 {
            limbs.push(carry);
        }
    }
    while limbs.len() > 1 && limbs.last() == Some(&0) {
        limbs.pop();
    }
    let mut out = limbs.last().unwrap().to_string();
    for l in limbs.iter().rev().skip(1) {
        out += &format!("{l:09}");
    }
    out
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(4096))]
    /// The reader's numbers are the standard library's, bit for bit: every double written in
    /// both of Rust's shortest forms, decimal strings of any length and exponent, and the
    /// hardest: a tie between two doubles (an odd 54-bit integer j times 2^-k, exactly
    /// j 5^k 10^-k) and the 19-digit decimals either side of it (from 2^54 down to 2^-26, so
    /// that every one of the exact cases' divisions by 10^k meets them).
    #[test]
    fn numbers_read_exactly_as_the_standard_library_reads_them(
        bits in proptest::num::u64::ANY,
        digits in "[0-9]{1,25}",
        fraction in "[0-9]{0,25}",
        exp in -340i32..340,
        j in (1u64 << 53)..(1u64 << 54),
        k in 0u32..=80,
    ) {
        let x = f64::from_bits(bits);
        let mut texts = vec![
            format!("-{digits}.{fraction}e{exp}").replace(".e", "e"),
            format!("{digits}.{fraction}").trim_end_matches('.').to_string(),
            // Within the fast cases: up to 19 digits, small exponents.
            format!("{}.{}e{}", &digits[..digits.len().min(9)], &fraction[..fraction.len().min(10)], exp % 30)
                .replace(".e", "e"),
        ];
        if x.is_finite() {
            texts.push(format!("{x:e}"));
            texts.push(format!("{x}"));
        }
        let tie = times_power_of_five(j | 1, k);
        let below = &tie[..tie.len().min(19)];
        let above = (below.parse::<u64>().unwrap() + 1).to_string();
        let scale = |d: &str| tie.len() as i64 - d.len() as i64 - i64::from(k);
        for d in [&tie[..], below, &above[..]] {
            texts.push(format!("{d}e{}", scale(d)));
        }
        for t in texts {
            let doc = format!(r#"{{"timestamp": {t}, "imu": {{"gyro": [0,0,0], "accel_body": [0,0,-9.8]}}, "position": [0,0,0], "velocity": [0,0,0], "quaternion": [1,0,0,0]}}"#);
            let expect: f64 = t.parse().unwrap();
            match PhysicsState::parse(&doc) {
                Ok(s) => proptest::prop_assert_eq!(s.timestamp_s.to_bits(), expect.to_bits(), "{}", t),
                Err(_) => proptest::prop_assert!(!expect.is_finite(), "{}", t),
            }
        }
    }
}

#[test]
fn the_latest_line_of_a_datagram_is_the_state() {
    let ours = our_state();
    let good = ours.to_json();
    let crlf = good.trim().to_string() + "\r\n";
    for (datagram, ok) in [
        (format!("{{\"broken\": \n{good}"), true),
        (format!("{good}{{\"broken\": \n"), false),
        (format!("{good}  \n\n"), true),
        (format!("garbage\n{crlf}"), true),
        (format!("{good} x\n"), false),
        ("\n \n".to_string(), false),
    ] {
        let r = PhysicsState::parse_latest(datagram.as_bytes());
        assert_eq!(r.is_ok(), ok, "{datagram:?}: {r:?}");
    }
    let bad_utf8 = [&b"{\"name\": \"\xff\", "[..], &good.as_bytes()[2..]].concat();
    assert!(PhysicsState::parse_latest(&bad_utf8).is_err());
}

proptest::proptest! {
    /// Plain string bytes are passed over eight at a time exactly as one at a time would: to
    /// the first quote, backslash, control character or non-ASCII byte, wherever it is.
    #[test]
    fn plain_string_bytes_end_where_one_at_a_time_says(
        bytes in proptest::collection::vec(
            proptest::prop_oneof![8 => 0x20u8..0x7f, 1 => proptest::num::u8::ANY], 0..40),
        from in 0usize..8,
    ) {
        let from = from.min(bytes.len());
        let special = |c: u8| c == b'"' || c == b'\\' || !(0x20..0x80).contains(&c);
        let expect = bytes[from..].iter().position(|&c| special(c)).map_or(bytes.len(), |p| from + p);
        proptest::prop_assert_eq!(super::scan::plain_ascii(&bytes, from), expect);
    }
}
