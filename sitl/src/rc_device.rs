//! The simulator playing an RC receiver on a serial port (`--rc-device crsf|sbus[:DEVICE]`):
//! the scenario's pilot script ([`sitl_core::scenario::PilotScript`]) as the transmitter's
//! sticks and mode switch (AETR: channel 1 roll, 2 pitch, 3 throttle, 4 yaw, 5 the mode
//! switch), written as an ExpressLRS receiver (CRSF: channels at 50 Hz, `LINK_STATISTICS` at
//! 5 Hz) or an SBUS receiver (a frame every 14 ms) writes them. The transmitter switched off
//! is what each does then: CRSF stops sending, SBUS sends its failsafe flag.

use crate::device_line::DeviceLine;
use anyhow::{Result, bail};
use devices::sim::rc_frames;
use sitl_core::scenario::PilotInput;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Protocol {
    Crsf,
    Sbus,
}

/// The device.
pub struct RcDevice {
    line: DeviceLine,
    protocol: Protocol,
    next_s: f64,
    frames: u64,
    out: Vec<u8>,
}

impl RcDevice {
    /// `crsf` or `sbus`, on `pty` (the default) or a device.
    pub fn open(spec: &str) -> Result<Self> {
        let (kind, device) = spec.split_once(':').unwrap_or((spec, "pty"));
        let protocol = match kind {
            "crsf" => Protocol::Crsf,
            "sbus" => Protocol::Sbus,
            _ => bail!("--rc-device {spec:?}: the protocol is crsf or sbus"),
        };
        let baud = if protocol == Protocol::Crsf {
            420_000
        } else {
            100_000
        };
        Ok(Self {
            line: DeviceLine::open(device, baud)?,
            protocol,
            next_s: 0.0,
            frames: 0,
            out: Vec::new(),
        })
    }

    /// The device the autopilot opens.
    pub fn name(&self) -> &str {
        self.line.name()
    }

    /// At `t_s`: the frames due, from what the pilot gives.
    pub fn step(&mut self, t_s: f64, pilot: &PilotInput) -> Result<()> {
        let period = match self.protocol {
            Protocol::Crsf => 0.02,
            Protocol::Sbus => 0.014,
        };
        if t_s < self.next_s {
            return Ok(());
        }
        self.next_s = (self.next_s + period).max(t_s);
        self.frames += 1;
        let mut us = [1500.0; 16];
        us[0] = 1500.0 + 500.0 * pilot.roll;
        us[1] = 1500.0 + 500.0 * pilot.pitch;
        us[2] = 1000.0 + 1000.0 * pilot.throttle;
        us[3] = 1500.0 + 500.0 * pilot.yaw;
        us[4] = 1000.0 + (f64::from(pilot.switch.min(5)) + 0.5) / 6.0 * 1000.0;
        self.out.clear();
        match (self.protocol, pilot.transmitter) {
            (Protocol::Crsf, true) => {
                rc_frames::crsf_channels(&us, &mut self.out);
                if self.frames.is_multiple_of(10) {
                    rc_frames::crsf_link_statistics(-60, 100, 10, (-65, 100), &mut self.out);
                }
            }
            // An ExpressLRS receiver whose transmitter is gone sends nothing ("no pulses").
            (Protocol::Crsf, false) => {}
            (Protocol::Sbus, on) => rc_frames::sbus_frame(&us, !on, !on, &mut self.out),
        }
        if self.out.is_empty() {
            return Ok(());
        }
        self.line.write(&self.out)
    }
}
