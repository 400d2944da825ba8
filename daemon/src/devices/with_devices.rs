//! A sensor link with the vehicle's own devices beside it: every read of the link also reads
//! the devices' ports, on the link's clock, and what they give goes into the newest frame.

use super::{GpsPort, RcPort};
use crate::links::SensorLink;
use crate::links::frames::Received;
use gcs::telemetry::Telemetry;
use hil::ActuatorCommand;
use std::io;
use std::time::Duration;
use tokio::sync::watch;

/// The link and its devices.
pub struct WithDevices<L> {
    inner: L,
    gps: Option<GpsPort>,
    rc: Option<RcPort>,
    /// The vehicle as last published, for the RC receiver's telemetry.
    vehicle: Option<watch::Receiver<Telemetry>>,
}

impl<L: SensorLink> WithDevices<L> {
    /// `inner` with a GPS on its own port (which then replaces the link's GPS) and an RC
    /// receiver.
    pub fn new(inner: L, gps: Option<GpsPort>, rc: Option<RcPort>) -> Self {
        if let Some(g) = &gps {
            tracing::info!("{} replaces the GPS of {}", g.describe(), inner.describe());
        }
        if let Some(r) = &rc {
            tracing::info!("{} beside {}", r.describe(), inner.describe());
        }
        Self {
            inner,
            gps,
            rc,
            vehicle: None,
        }
    }

    /// The telemetry the RC receiver passes on to the transmitter comes from `vehicle`.
    pub fn telling(mut self, vehicle: watch::Receiver<Telemetry>) -> Self {
        self.vehicle = Some(vehicle);
        self
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
        if let Some(rc) = self.rc.as_mut()
            && let Some(newest) = into.frames[first..].last_mut()
        {
            let t_s = newest.sample.t_usec as f64 * 1e-6;
            newest.rc = rc.poll(t_s);
            if rc.telemetry_due(t_s)
                && let Some(v) = self.vehicle.as_ref().and_then(|t| t.borrow().vehicle)
            {
                rc.tell(t_s, &v);
            }
        }
        Ok(arrived)
    }

    fn send(&mut self, command: &ActuatorCommand) -> io::Result<()> {
        self.inner.send(command)
    }

    fn describe(&self) -> String {
        let mut d = self.inner.describe();
        for device in [
            self.gps.as_ref().map(GpsPort::describe),
            self.rc.as_ref().map(RcPort::describe),
        ]
        .into_iter()
        .flatten()
        {
            d += &format!(" with the {device}");
        }
        d
    }

    fn silence_clock_s(&self) -> Option<f64> {
        self.inner.silence_clock_s()
    }
}
