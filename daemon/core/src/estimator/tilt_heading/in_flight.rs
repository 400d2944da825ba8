//! A gap in the samples in flight: the attitude unknown until found again from the GPS's
//! velocity and the magnetic field (`realign.rs`), the gyro carrying a frame meanwhile.

use super::{TiltHeadingFilter, UNSEEN_TURN_S};
use crate::estimator::gps_tilt::DelayedVelocity;
use crate::estimator::realign::InFlightAlignment;
use nalgebra::{UnitQuaternion, Vector3};

/// How long the alignment is sought before the filter goes on from the accelerometer (s): no
/// GPS, or a vehicle in a free fall, shows nothing.
pub const GIVE_UP_S: f64 = 5.0;

impl TiltHeadingFilter {
    /// The samples stopped for a while in flight: what the gyro did meanwhile is lost, and the
    /// attitude is unknown until found again. The gyro frame goes on from the last attitude.
    pub fn lost_in_flight(&mut self) {
        self.start_at(self.attitude());
        self.realigning = Some(InFlightAlignment::default());
    }

    /// Whether the attitude is unknown after a gap in flight.
    pub fn realigning(&self) -> bool {
        self.realigning.is_some()
    }

    /// One sample while the attitude is unknown: the force and field collected in the gyro
    /// frame, and the alignment tried at each GPS solution. Nothing else corrects meanwhile:
    /// the accelerometer under thrust would show the stale attitude as level.
    pub(super) fn realign_step(
        &mut self,
        accel: &Vector3<f64>,
        mag: Option<&Vector3<f64>>,
        gps_vel: Option<&DelayedVelocity>,
        dt: f64,
    ) {
        let field = mag.map(|m| {
            if self.settings.learn_hard_iron {
                m - self.hard_iron.offset()
            } else {
                *m
            }
        });
        let dip = self
            .heading
            .reference_dip()
            .unwrap_or(self.settings.mag_inclination_rad);
        let declination = self.settings.heading.declination_rad;
        let q_gyro = self.q_gyro;
        let Some(r) = self.realigning.as_mut() else {
            return;
        };
        r.update(&q_gyro, accel, field.as_ref(), gps_vel, dt);
        if let Some(found) = r.try_solve(declination, dip) {
            self.realigning = None;
            self.realigned(&found);
            self.status.realigned_in_flight += 1;
        } else if r.elapsed_s > GIVE_UP_S {
            self.realigning = None;
            self.status.realign_abandoned += 1;
            self.start_at(self.attitude());
        }
    }

    /// The attitude found: the filter starts again from it, with the low-passes steady at
    /// gravity alone (the accelerometer keeps the tilt found: the low-passes are linear, so
    /// what they start from is all that matters while the force and the known acceleration
    /// agree; started at a fall's acceleration, about g, the correction's turn of the force
    /// alone would be out of proportion and grow). Said as a tilt reset: what was learned
    /// through the unknown attitude (the position estimator's velocity) is forgotten.
    fn realigned(&mut self, ned_from_gyro_frame: &UnitQuaternion<f64>) {
        let down = |q: UnitQuaternion<f64>| q * Vector3::z();
        let before = self.attitude();
        let last_vel = self.last_vel;
        self.start_at(ned_from_gyro_frame * self.q_gyro);
        // The gyro frame is NED now (no tilt or heading correction yet).
        self.accel_lp
            .reset_to(Vector3::new(0.0, 0.0, -crate::GRAVITY_M_S2));
        self.vel_accel_lp.reset_to(Vector3::zeros());
        self.last_vel = last_vel;
        self.bias.restart_tilt_at(&self.q_gyro.to_rotation_matrix());
        self.running_s = self.settings.tau_acc_s;
        self.unseen_turn_s = UNSEEN_TURN_S;
        self.status.reset.tilt += 1;
        self.status.reset.tilt_rad = down(before).angle(&down(self.attitude()));
    }
}
