//! How well a flight went, scored against the simulator's ground truth (`HIL_STATE_QUATERNION`,
//! which reaches the autopilot for logs and scoring only, never the estimator).
//!
//! Positions are measured from where the vehicle truly stood when it armed: the altitude error is
//! the true height above that spot minus the take-off altitude, the horizontal drift the true
//! distance from above that spot. Both are what a person watching the flight would see, and both
//! include what the estimator cannot know (barometer drift, correlated GPS error).

use flight_core::commander::{CommanderStatus, FlightMode, LandedState};
use flight_core::math::geo::{LatLonAlt, LocalFrame};
use hil::TruthReport;
use nalgebra::{UnitQuaternion, Vector3};

/// Running figures of one flight.
#[derive(Debug, Clone, Default)]
pub struct FlightScore {
    takeoff_m: f64,
    /// The local frame at the take-off spot.
    origin: Option<LocalFrame>,
    hover: Rms,
    hover_h: Rms,
    attitude: Rms,
    height_m: f64,
    /// Highest true height above the take-off spot (m).
    pub max_height_m: f64,
    /// Fastest true descent within 0.3 m of the ground while landing (m/s).
    pub touchdown_m_s: f64,
    /// Fastest true descent within 0.3 m of the ground from arming on, whatever the mode, armed
    /// or not (m/s): a crash shows here.
    pub impact_m_s: f64,
    /// Largest true tilt from arming on (deg).
    pub max_tilt_deg: f64,
    /// The last true tilt (deg): one on its side or back is far from level.
    pub tilt_deg: f64,
    /// Farthest true horizontal distance from the take-off spot from arming on (m).
    pub max_distance_m: f64,
    /// The last true horizontal distance from the take-off spot (m): where it came down.
    pub distance_m: f64,
    /// A failsafe acted at some point.
    pub failsafe: bool,
    /// Gaps in the frames (over [`GAP_S`]) while armed, and the time the last one ended (µs).
    pub gaps: u64,
    last_frame_usec: Option<u64>,
    gap_ended_usec: Option<u64>,
    /// Largest attitude-estimate error from [`SETTLE_AFTER_GAP_S`] after a gap on, while
    /// armed (deg): how well the attitude was found again.
    pub max_attitude_err_after_gap_deg: f64,
}

/// A longer interval between frames is a gap in them (s): `ATT_MAX_DR_T`'s default.
pub const GAP_S: f64 = 0.5;
/// How long after a gap the attitude estimate may take to be right again (s).
pub const SETTLE_AFTER_GAP_S: f64 = 1.0;

#[derive(Debug, Clone, Copy, Default)]
struct Rms {
    sum_sq: f64,
    n: u64,
}

impl Rms {
    fn add(&mut self, x: f64) {
        self.sum_sq += x * x;
        self.n += 1;
    }

    fn value(&self) -> Option<f64> {
        (self.n > 0).then(|| (self.sum_sq / self.n as f64).sqrt())
    }
}

impl FlightScore {
    /// A score for a flight to `takeoff_m`.
    pub fn new(takeoff_m: f64) -> Self {
        Self {
            takeoff_m,
            ..Self::default()
        }
    }

    /// True position NED (m) of `t` relative to the take-off spot (none before arming).
    fn local(&self, t: &TruthReport) -> Option<Vector3<f64>> {
        Some(self.origin?.to_ned(&position(t)))
    }

    /// Adds one frame's truth with the attitude estimate and the commander's state: the hover
    /// figures come from holds in the air, the touchdown speed from landings. Returns the true
    /// position NED (m) from the take-off spot (none before arming).
    pub fn add(
        &mut self,
        truth: &TruthReport,
        estimate: Option<UnitQuaternion<f64>>,
        status: &CommanderStatus,
        armed: bool,
    ) -> Option<Vector3<f64>> {
        if armed && self.origin.is_none() {
            self.origin = Some(LocalFrame::new(position(truth)));
        }
        let p = self.local(truth)?;
        let height = -p.z;
        self.height_m = height;
        self.max_height_m = self.max_height_m.max(height);
        // From arming on, armed or not (a vehicle that stops its motors in the air still falls).
        self.distance_m = p.xy().norm();
        self.max_distance_m = self.max_distance_m.max(self.distance_m);
        // The body's down axis in NED: its angle from the vertical.
        let down = truth.q.transform_vector(&Vector3::z());
        self.tilt_deg = down.z.clamp(-1.0, 1.0).acos().to_degrees();
        self.max_tilt_deg = self.max_tilt_deg.max(self.tilt_deg);
        self.failsafe |= armed && status.failsafe;
        if height < 0.3 {
            self.impact_m_s = self.impact_m_s.max(truth.vel_ned_m_s.z);
        }
        if status.mode == FlightMode::Loiter && status.landed == LandedState::InAir {
            self.hover.add(height - self.takeoff_m);
            self.hover_h.add(p.xy().norm());
        }
        let gap = self
            .last_frame_usec
            .is_some_and(|last| truth.time_usec.saturating_sub(last) as f64 * 1e-6 > GAP_S);
        self.last_frame_usec = Some(truth.time_usec);
        if armed && gap {
            self.gaps += 1;
            self.gap_ended_usec = Some(truth.time_usec);
        }
        if armed && let Some(q) = estimate {
            let err = q.angle_to(&truth.q).to_degrees();
            self.attitude.add(err);
            let settled = self.gap_ended_usec.is_some_and(|end| {
                truth.time_usec.saturating_sub(end) as f64 * 1e-6 >= SETTLE_AFTER_GAP_S
            });
            if settled {
                self.max_attitude_err_after_gap_deg = self.max_attitude_err_after_gap_deg.max(err);
            }
        }
        if status.landed == LandedState::Landing && height < 0.3 {
            self.touchdown_m_s = self.touchdown_m_s.max(truth.vel_ned_m_s.z);
        }
        Some(p)
    }

    /// The last true height is within 0.2 m of the take-off spot's.
    pub fn on_ground(&self) -> bool {
        self.origin.is_some() && self.height_m < 0.2
    }

    /// Hover altitude RMS error (m).
    pub fn hover_alt_rms_m(&self) -> Option<f64> {
        self.hover.value()
    }

    /// Hover horizontal drift RMS (m).
    pub fn hover_drift_rms_m(&self) -> Option<f64> {
        self.hover_h.value()
    }

    /// Attitude estimate RMS error while armed (deg).
    pub fn attitude_rms_deg(&self) -> Option<f64> {
        self.attitude.value()
    }
}

/// Where the truth says the vehicle is.
fn position(t: &TruthReport) -> LatLonAlt {
    LatLonAlt {
        lat_deg: t.lat_deg,
        lon_deg: t.lon_deg,
        alt_m: t.alt_m,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The truth at `north_m`, `east_m`, `up_m` from a point 10 m south of the take-off spot,
    /// in the take-off spot's local frame (the one the score measures in).
    fn truth(north_m: f64, east_m: f64, up_m: f64) -> TruthReport {
        let takeoff = LatLonAlt {
            lat_deg: 47.0,
            lon_deg: 8.0,
            alt_m: 400.0,
        };
        let p = takeoff.offset_by_ned(&Vector3::new(north_m - 10.0, east_m, -up_m));
        TruthReport {
            time_usec: 0,
            q: UnitQuaternion::identity(),
            lat_deg: p.lat_deg,
            lon_deg: p.lon_deg,
            alt_m: p.alt_m,
            vel_ned_m_s: Vector3::zeros(),
            rate_frd_rad_s: Vector3::zeros(),
            specific_force_frd_m_s2: Vector3::zeros(),
        }
    }

    #[test]
    fn figures_are_measured_from_the_takeoff_spot() {
        // The ground-station tests' armed status, in the mode and landed state asked.
        let status = |mode, landed| {
            let armed = gcs::testing::telemetry(true, mode).status();
            CommanderStatus {
                landed,
                ..armed.expect("the test telemetry has a status")
            }
        };
        let hold = status(FlightMode::Loiter, LandedState::InAir);
        let mut s = FlightScore::new(5.0);
        // Before arming nothing counts.
        s.add(&truth(9.0, 9.0, 9.0), None, &hold, false);
        assert_eq!(s.hover_alt_rms_m(), None);
        s.add(
            &truth(10.0, 0.0, 0.0),
            None,
            &status(FlightMode::Takeoff, LandedState::OnGround),
            true,
        );
        s.add(&truth(10.3, 0.4, 5.1), None, &hold, true);
        s.add(&truth(10.0, 0.0, 4.9), None, &hold, true);
        assert!((s.hover_alt_rms_m().unwrap() - 0.1).abs() < 1e-6);
        let drift = (0.5f64.powi(2) / 2.0).sqrt();
        assert!((s.hover_drift_rms_m().unwrap() - drift).abs() < 1e-6);
        assert!((s.max_height_m - 5.1).abs() < 1e-6);
        assert!((s.max_distance_m - 0.5).abs() < 1e-6 && s.distance_m.abs() < 1e-6);
        assert_eq!((s.max_tilt_deg, s.failsafe), (0.0, false));
        // Tilted 30° about north, falling 3 m/s just above the ground in a failsafe.
        let mut falling = truth(10.0, 0.0, 0.2);
        falling.q = UnitQuaternion::from_euler_angles(30f64.to_radians(), 0.0, 0.0);
        falling.vel_ned_m_s.z = 3.0;
        let mut descend = status(FlightMode::Descend, LandedState::InAir);
        descend.failsafe = true;
        s.add(&falling, None, &descend, true);
        assert!((s.max_tilt_deg - 30.0).abs() < 1e-9, "{}", s.max_tilt_deg);
        assert_eq!(
            (s.impact_m_s, s.touchdown_m_s, s.failsafe),
            (3.0, 0.0, true)
        );
    }
}
