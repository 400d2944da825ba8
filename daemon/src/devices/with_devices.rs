//! A sensor link with the vehicle's own devices beside it: every read of the link also reads
//! the devices' ports, on the link's clock, and what they give goes into the newest frame.

use super::GpsPort;
use crate::links::SensorLink;
use crate::links::frames::Received;
use hil::ActuatorCommand;
use std::io;
use std::time::Duration;

/// The link and its devices.
pub struct WithDevices<L> {
    inner: L,
    gps: Option<GpsPort>,
}

impl<L: SensorLink> WithDevices<L> {
    /// `inner` with a GPS on its own port (which then replaces the link's GPS).
    pub fn new(inner: L, gps: Option<GpsPort>) -> Self {
        if let Some(g) = &gps {
            tracing::info!("{} replaces the GPS of {}", g.describe(), inner.describe());
        }
        Self { inner, gps }
    }

    /// The link itself.
    pub fn inner_mut(&mut self) -> &mut L {
        &mut self.inner
    }
}

impl<L: SensorLink> SensorLink for WithDevices<L> {
    fn receive(&mut self, timeout: Duration, into: &mut Received) -> io::Result<bool> {
        let first = into.frames.len();
        let arrived = self.inner.receive(timeout, into)?;
        if let Some(gps) = self.gps.as_mut() {
            let frames = &mut into.frames[first..];
            for f in frames.iter_mut() {
                f.sample.gps = None;
            }
            if let Some(newest) = frames.last_mut() {
                newest.sample.gps = gps.poll(newest.sample.t_usec as f64 * 1e-6);
            }
        }
        Ok(arrived)
    }

    fn send(&mut self, command: &ActuatorCommand) -> io::Result<()> {
        self.inner.send(command)
    }

    fn describe(&self) -> String {
        match &self.gps {
            Some(g) => format!("{} with the {}", self.inner.describe(), g.describe()),
            None => self.inner.describe(),
        }
    }

    fn silence_clock_s(&self) -> Option<f64> {
        self.inner.silence_clock_s()
    }
}
