use super::*;
use crate::sim::{NmeaReceiver, ReceiverFix};

fn fix(k: u64) -> ReceiverFix {
    ReceiverFix {
        time_utc_usec: 1_795_910_400_000_000 + k * 200_000,
        fix: FixType::Fix3d,
        lat_deg: -33.865_143,
        lon_deg: 151.209_900 + k as f64 * 1e-6,
        alt_msl_m: 39.4,
        vel_ned_m_s: [0.0, 3.0, -0.5],
        h_acc_m: 1.2,
        v_acc_m: 2.5,
        s_acc_m_s: 0.2,
        satellites: 9,
        hdop: 0.9,
        vdop: 1.4,
        pdop: 1.7,
    }
}

fn solutions(events: &[GpsEvent]) -> Vec<GpsSolution> {
    events
        .iter()
        .filter_map(|e| match e {
            GpsEvent::Solution(s) => Some(*s),
            _ => None,
        })
        .collect()
}

#[test]
fn each_epoch_gives_one_solution_with_what_its_sentences_say() {
    let rx = NmeaReceiver::new(38_400, 5.0);
    let mut d = NmeaDriver::new(38_400);
    let mut events = Vec::new();
    for k in 0..20 {
        let mut bytes = Vec::new();
        rx.epoch(&fix(k), &mut bytes);
        // Written in pieces, as a serial port delivers.
        for chunk in bytes.chunks(17) {
            d.receive(k as f64 * 0.2, chunk, &mut events);
        }
    }
    assert_eq!(events.first(), Some(&GpsEvent::Found { baud: 38_400 }));
    let s = solutions(&events);
    assert_eq!(
        s.len(),
        20,
        "one per epoch, as soon as GGA and a velocity are in"
    );
    for (k, s) in s.iter().enumerate() {
        let f = fix(k as u64);
        assert_eq!(s.fix, FixType::Fix3d);
        // Five decimals of a minute: 1.7e-7 degrees.
        assert!((s.lat_deg - f.lat_deg).abs() < 1e-7, "{s:?}");
        assert!((s.lon_deg - f.lon_deg).abs() < 1e-7, "{s:?}");
        assert!((s.alt_msl_m - 39.4).abs() < 1e-4);
        let [n, e] = s.vel_ne_m_s.expect("RMC's velocity");
        assert!(n.abs() < 1e-3 && (e - 3.0).abs() < 1e-3, "{s:?}");
        assert_eq!(s.vel_down_m_s, None);
        assert_eq!(s.satellites, 9);
        assert_eq!(s.hdop, Some(0.9_f32 as f64));
        // GST arrives after GGA: from the second epoch on, its accuracies.
        if k > 0 {
            assert!((s.h_acc_m.expect("GST") - 1.2).abs() < 0.02, "{s:?}");
            assert!((s.v_acc_m.expect("GST") - 2.5).abs() < 0.01, "{s:?}");
        }
        assert_eq!(s.time_utc_usec, Some(f.time_utc_usec), "to the centisecond");
    }
    assert_eq!(d.counters().bad_frames, 0);
}

fn with_checksum(body: &str) -> Vec<u8> {
    let sum = body.bytes().fold(0u8, |a, b| a ^ b);
    format!("${body}*{sum:02X}\r\n").into_bytes()
}

#[test]
fn cut_and_corrupt_sentences_are_counted_and_a_gga_alone_is_given_at_the_next_epoch() {
    let mut d = NmeaDriver::new(9_600);
    let mut events = Vec::new();
    let gga = &with_checksum("GPGGA,123519.00,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,");
    let mut wrong = gga.to_vec();
    wrong[20] = b'9';
    d.receive(0.0, &gga[..30], &mut events); // cut: the next '$' starts again
    d.receive(0.0, &wrong, &mut events);
    d.receive(0.1, gga, &mut events);
    assert!(solutions(&events).is_empty(), "no velocity yet, epoch open");
    let next = &with_checksum("GPGGA,123520.00,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,");
    d.receive(1.1, next, &mut events);
    let s = solutions(&events);
    assert_eq!(s.len(), 1, "{events:?}");
    assert!((s[0].lat_deg - (48.0 + 7.038 / 60.0)).abs() < 1e-9);
    assert!((s[0].lon_deg - (11.0 + 31.0 / 60.0)).abs() < 1e-9);
    assert_eq!(s[0].vel_ne_m_s, None);
    assert_eq!(s[0].time_utc_usec, None, "no RMC, no date");
    assert_eq!(d.counters().bad_frames, 2, "{:?}", d.counters());
}

#[test]
fn silence_is_said_once_and_the_scan_starts_again() {
    let rx = NmeaReceiver::new(9_600, 5.0);
    let mut d = NmeaDriver::new(9_600);
    let mut events = Vec::new();
    let mut bytes = Vec::new();
    rx.epoch(&fix(0), &mut bytes);
    d.receive(0.0, &bytes, &mut events);
    events.clear();
    for k in 1..500 {
        d.poll(f64::from(k) * 0.01, &mut events);
        if events.len() == 2 {
            break;
        }
    }
    assert_eq!(events, [GpsEvent::Silent, GpsEvent::Lost]);
    assert_eq!(d.baud(), 9_600, "the scan starts at the configured baud");
}

#[test]
fn an_rmc_with_an_empty_navigation_status_still_gives_the_date() {
    let mut d = NmeaDriver::new(38_400);
    let mut events = Vec::new();
    for s in [
        "GNGGA,120000.00,3351.60000,S,15112.00000,E,1,9,0.8,39.4,M,0.0,M,,",
        "GNRMC,120000.00,A,3351.60000,S,15112.00000,E,5.8,90.0,291126,0.0,,A,",
    ] {
        d.receive(0.0, &with_checksum(s), &mut events);
    }
    let s = solutions(&events);
    assert_eq!(s.len(), 1, "{events:?} {:?}", d.counters());
    assert_eq!(s[0].time_utc_usec, Some(1_795_953_600_000_000));
}
