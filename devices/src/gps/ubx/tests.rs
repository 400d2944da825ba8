use super::*;
use crate::gps::GpsDriver;
use crate::sim::ublox_receiver::{ReceiverModel, UbloxReceiver};
use crate::sim::{ReceiverFix, misread};

fn fix_at(t_s: f64) -> ReceiverFix {
    ReceiverFix {
        // 2026-11-29 00:00:00 UTC, then the simulator's clock.
        time_utc_usec: 1_795_910_400_000_000 + (t_s * 1e6) as u64,
        fix: FixType::Fix3d,
        lat_deg: 47.397_742_1 + t_s * 1e-6,
        lon_deg: 8.545_594_3,
        alt_msl_m: 488.123,
        vel_ned_m_s: [1.25, -0.5, 0.125],
        h_acc_m: 0.65,
        v_acc_m: 1.1,
        s_acc_m_s: 0.15,
        satellites: 14,
        hdop: 0.8,
        vdop: 1.2,
        pdop: 1.44,
    }
}

/// The driver and a simulated receiver on one serial line, stepped every 10 ms: bytes cross
/// whole when both ends are at one baud, misread when not.
struct Line {
    driver: GpsDriver,
    receiver: UbloxReceiver,
    t_s: f64,
    next_epoch: f64,
    events: Vec<GpsEvent>,
    plugged: bool,
}

impl Line {
    fn new(model: ReceiverModel) -> Self {
        Self {
            driver: GpsDriver::new(crate::gps::GpsProtocol::Ublox, 115_200, 5.0),
            receiver: UbloxReceiver::new(model),
            t_s: 0.0,
            next_epoch: 0.0,
            events: Vec::new(),
            plugged: true,
        }
    }

    fn cross(bytes: &[u8], from: u32, to: u32) -> Vec<u8> {
        if from == to {
            return bytes.to_vec();
        }
        let mut out = Vec::new();
        misread(bytes, from, to, &mut out);
        out
    }

    fn run(&mut self, seconds: f64) {
        let end = self.t_s + seconds;
        while self.t_s < end {
            self.t_s += 0.01;
            let mut out = Vec::new();
            self.driver.poll(self.t_s, &mut out, &mut self.events);
            if !self.plugged {
                continue;
            }
            let (ours, theirs) = (self.driver.baud(), self.receiver.baud());
            let mut answer = Vec::new();
            self.receiver
                .receive(&Self::cross(&out, ours, theirs), &mut answer);
            if self.t_s >= self.next_epoch {
                self.next_epoch += self.receiver.period_s();
                self.receiver.epoch(&fix_at(self.t_s), &mut answer);
            }
            let read = Self::cross(&answer, theirs, self.driver.baud());
            self.driver.receive(self.t_s, &read, &mut self.events);
        }
    }

    fn solutions(&self) -> Vec<GpsSolution> {
        self.events
            .iter()
            .filter_map(|e| match e {
                GpsEvent::Solution(s) => Some(*s),
                _ => None,
            })
            .collect()
    }
}

#[test]
fn every_generation_is_found_identified_configured_and_read_at_five_hertz() {
    for (model, interface) in [
        (ReceiverModel::M8, "CFG-PRT/CFG-RATE/CFG-MSG"),
        (ReceiverModel::M9, "CFG-VALSET"),
        (ReceiverModel::M10, "CFG-VALSET"),
        (ReceiverModel::F9p, "CFG-VALSET"),
    ] {
        let mut line = Line::new(model);
        line.run(12.0);
        let said: Vec<_> = line
            .events
            .iter()
            .filter(|e| !matches!(e, GpsEvent::Solution(_)))
            .collect();
        assert!(
            said.contains(&&GpsEvent::Found {
                baud: model.default_baud()
            }),
            "{model:?}: {said:?}"
        );
        assert!(
            said.contains(&&GpsEvent::Configured { interface }),
            "{model:?}: {said:?}"
        );
        assert!(
            !said
                .iter()
                .any(|e| matches!(e, GpsEvent::Refused { .. } | GpsEvent::Lost)),
            "{model:?}: {said:?}"
        );
        assert_eq!(line.receiver.baud(), 115_200, "{model:?}");
        assert!(line.receiver.configured(), "{model:?}");
        let s = line.solutions();
        // Found within a scan of a few bauds, then five a second.
        assert!(s.len() >= 30, "{model:?}: {} solutions", s.len());
        let last = s.last().expect("solutions");
        assert_eq!(last.fix, FixType::Fix3d);
        assert_eq!(last.satellites, 14);
        assert!((last.alt_msl_m - 488.123).abs() < 1e-9, "{last:?}");
        assert_eq!(last.vel_ne_m_s, Some([1.25, -0.5]));
        assert_eq!(last.vel_down_m_s, Some(0.125));
        assert_eq!(last.h_acc_m, Some(0.65));
        assert_eq!(last.v_acc_m, Some(1.1));
        assert_eq!(last.s_acc_m_s, Some(0.15));
        assert!((last.hdop.expect("NAV-DOP") - 0.8).abs() < 1e-6);
        let t = last.time_utc_usec.expect("UTC");
        let t_s = (t - 1_795_910_400_000_000) as f64 * 1e-6;
        assert!(
            (last.lat_deg - (47.397_742_1 + t_s * 1e-6)).abs() < 0.6e-7,
            "{last:?}"
        );
        let c = line.driver.counters();
        assert_eq!(c.solutions as usize, s.len());
    }
}

#[test]
fn a_receiver_replugged_is_said_silent_once_then_found_and_configured_again() {
    let mut line = Line::new(ReceiverModel::M9);
    line.run(8.0);
    let before = line.solutions().len();
    assert!(before > 10);
    line.events.clear();
    line.plugged = false;
    line.run(5.0);
    assert_eq!(
        line.events,
        [GpsEvent::Silent, GpsEvent::Lost],
        "silence said once, then the scan"
    );
    // Plugged in again: back at its defaults (38 400 baud, NMEA out).
    line.receiver.restart();
    line.plugged = true;
    line.run(10.0);
    assert!(
        line.events.contains(&GpsEvent::Configured {
            interface: "CFG-VALSET"
        }),
        "{:?}",
        line.events
    );
    assert!(line.solutions().len() > 10);
}

#[test]
fn garbage_and_cut_frames_are_counted_never_taken() {
    let mut driver = UbloxDriver::new(38_400, 5.0);
    let mut events = Vec::new();
    let mut noise = 0x1234_5678u32;
    for k in 0..2000 {
        let bytes: Vec<u8> = (0..64)
            .map(|_| {
                noise ^= noise << 13;
                noise ^= noise >> 17;
                noise ^= noise << 5;
                noise as u8
            })
            .collect();
        driver.receive(f64::from(k) * 0.01, &bytes, &mut events);
    }
    // A NAV-PVT cut short, then one with a bad checksum.
    let mut frame = Vec::new();
    crate::sim::ubx_frame::write(0x01, 0x07, &[0u8; 92], &mut frame);
    driver.receive(20.0, &frame[..50], &mut events);
    let mut bad = frame.clone();
    bad[40] ^= 1;
    driver.receive(20.0, &bad, &mut events);
    assert!(
        !events.iter().any(|e| matches!(e, GpsEvent::Solution(_))),
        "{events:?}"
    );
    assert!(driver.counters().bad_frames > 0, "{:?}", driver.counters());
}
