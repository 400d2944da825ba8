//! What the fuzz targets share: the vehicle behind the ground-station protocol (an autopilot at
//! rest, the default quad), and the invariants every input must leave standing.

use airframe::Airframe;
use flight_core::autopilot::Autopilot;
use flight_core::commander::FlightMode;
use flight_core::params::FlightParams;
use gcs::telemetry::Telemetry;
use gcs::{GroundStation, Outbox};
use mavlink::dialects::common::MavType;

/// The default quad, compiled in (no file is read while fuzzing), parsed once.
pub fn quad() -> &'static Airframe {
    static QUAD: std::sync::OnceLock<Airframe> = std::sync::OnceLock::new();
    QUAD.get_or_init(|| {
        let text = include_str!("../../params/airframes/quad_x.toml");
        Airframe::from_toml_str(text, "quad_x.toml").expect("the shipped airframe parses")
    })
}

/// The default quad's autopilot with the default parameters, made once and cloned for each
/// input (making one solves its controllers' LQRs: most of an input's time, were it made anew).
fn resting_autopilot() -> &'static Autopilot {
    static AUTOPILOT: std::sync::OnceLock<Autopilot> = std::sync::OnceLock::new();
    AUTOPILOT.get_or_init(|| {
        Autopilot::new(quad(), &FlightParams::default(), None).expect("the default quad flies")
    })
}

/// The protocol, the vehicle it passes commands to, and the telemetry it reads.
pub struct Vehicle {
    /// The ground-station protocol.
    pub gcs: GroundStation,
    /// The autopilot.
    pub autopilot: Autopilot,
    /// What the control loop shows: at rest, home set.
    pub telemetry: Telemetry,
}

impl Vehicle {
    /// A vehicle at rest, `armed` or not, in Hold.
    pub fn new(armed: bool) -> Self {
        let params = FlightParams::default();
        let mut telemetry = gcs::testing::telemetry(armed, FlightMode::Loiter);
        if let Some(v) = telemetry.vehicle.as_mut() {
            v.status.home = Some((nalgebra::Vector3::zeros(), 0.0));
        }
        Self {
            gcs: GroundStation::new(1, MavType::MAV_TYPE_QUADROTOR)
                .with_parameters(gcs::params::Parameters::default(), params),
            autopilot: resting_autopilot().clone(),
            telemetry,
        }
    }

    /// Carries out what the protocol passed on, as the links and the control loop do.
    pub fn carry_out(&mut self, out: &mut Outbox) {
        gcs::testing::carry_out(&mut self.gcs, &mut self.autopilot, out);
    }

    /// Every parameter finite, in its range, consistent: whatever was sent.
    pub fn assert_params_valid(&self) {
        let values = self.gcs.parameters().values();
        for (group, meta) in FlightParams::metadata() {
            let v = values
                .get(group, meta.key)
                .expect("every parameter has a value");
            assert!(
                v.is_finite() && meta.min <= v && v <= meta.max,
                "{} = {v}",
                meta.name
            );
        }
        assert!(values.validate().is_empty(), "{:?}", values.validate());
    }
}
