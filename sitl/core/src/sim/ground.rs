//! The ground under the landing gear: a spring and a damper on each foot, and friction.
//!
//! Each foot of the airframe's [`LandingGear`] that is below the ground plane pushes back along
//! the normal, `F_n = k d + c ḋ` (never pulling), and holds sideways by a spring to where it
//! touched down (its anchor) with the same stiffness and damping, at most `μ F_n`: beyond that it
//! slides, and its anchor follows it. The forces act at the feet, so a touchdown turns the body
//! over time at rates its gyro measures, a vehicle set down tilted rocks onto its feet, and one
//! pushed hard enough over its feet tips over. The rotor hubs touch the ground the same way, so a
//! vehicle on its side or back lies on its arms. The push is taken at each step's start and
//! held over the step, as the rotors' loads are, and the anchors move between steps.
//!
//! The ground plane lies where the feet rest when the legs give their sag: a vehicle standing
//! level has its centre of mass at z ≈ 0, as the JSBSim back-end puts it.
//!
//! Stiffness is `weight / (feet · sag)` per foot, and the damping that of `damping_ratio` for the
//! whole vehicle bouncing on its legs (`c = 2 ζ √(k m / feet)` per foot). A step too long for that
//! spring softens it: the bounce's period stays at least 4π steps (ω dt ≤ 0.5), which every
//! integrator here carries stably.

use crate::GRAVITY_M_S2;
use crate::airframe::{Airframe, MAX_FEET, MAX_ROTORS};
use crate::body::BodyState;
use nalgebra::{Matrix3, Vector2, Vector3};

/// The softest a spring is made for a long step: ω dt at most this.
const MAX_OMEGA_DT: f64 = 0.5;
/// Points that can touch the ground: the feet, then the rotor hubs.
const MAX_POINTS: usize = MAX_FEET + MAX_ROTORS;

/// The ground and the feet on it.
#[derive(Debug, Clone)]
pub(crate) struct Ground {
    /// The feet, then the rotor hubs, FRD from the centre of mass (m).
    points: [Vector3<f64>; MAX_POINTS],
    count: usize,
    /// Per foot: stiffness (N/m), damping (N·s/m), friction coefficient.
    k: f64,
    c: f64,
    mu: f64,
    /// The ground plane's depth in the local NED frame (m).
    plane_z: f64,
    /// How far the points reach from the centre of mass (m).
    reach: f64,
    /// Where each touching point holds on, north and east (m); `None` in the air.
    anchors: [Option<Vector2<f64>>; MAX_POINTS],
    /// Some point held on after the last step.
    held: bool,
}

/// The ground's push on the body: force in NED (N), moment about the centre of mass in FRD
/// (N·m), and whether any foot touches.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Contact {
    pub force_ned_n: Vector3<f64>,
    pub moment_frd_n_m: Vector3<f64>,
    pub touching: bool,
}

impl Contact {
    /// No touch.
    pub const NONE: Self = Self {
        force_ned_n: Vector3::new(0.0, 0.0, 0.0),
        moment_frd_n_m: Vector3::new(0.0, 0.0, 0.0),
        touching: false,
    };
}

impl Ground {
    /// The ground for `airframe`'s gear, its springs made for a physics step of `dt_s`.
    pub fn new(airframe: &Airframe, dt_s: f64) -> Self {
        let gear = &airframe.landing_gear;
        let hubs = airframe.rotors.iter().map(|r| r.position_frd_m);
        let mut points = [Vector3::zeros(); MAX_POINTS];
        let mut count = 0;
        for (slot, p) in points
            .iter_mut()
            .zip(gear.feet_frd_m.iter().copied().chain(hubs))
        {
            *slot = p;
            count += 1;
        }
        // The legs carry the weight: the stiffness is the feet's share.
        let n = gear.feet_frd_m.len().clamp(1, MAX_FEET) as f64;
        let weight = airframe.mass_kg * GRAVITY_M_S2;
        // The bounce ω = √(n k / m) = √(g / sag): at most MAX_OMEGA_DT / dt.
        let sag = gear.sag_m.max(GRAVITY_M_S2 * (dt_s / MAX_OMEGA_DT).powi(2));
        let k = weight / (n * sag);
        let c = 2.0 * gear.damping_ratio * (k * airframe.mass_kg / n).sqrt();
        Self {
            reach: points[..count].iter().map(|p| p.norm()).fold(0.0, f64::max),
            points,
            count,
            k,
            c,
            mu: gear.friction,
            plane_z: gear.depth_m() - sag,
            anchors: [None; MAX_POINTS],
            held: false,
        }
    }

    /// Whether no foot can reach the ground from `s`: the cheap test flight takes.
    #[inline]
    fn out_of_reach(&self, s: &BodyState) -> bool {
        s.pos_ned_m.z + self.reach < self.plane_z
    }

    /// The points below the ground in state `s`: each one's index, place and velocity (NED),
    /// and how deep it is (m). The depth takes one row of the rotation; a point in the air costs
    /// no more.
    fn touching<'a>(
        &'a self,
        s: &'a BodyState,
        r: &'a Matrix3<f64>,
    ) -> impl Iterator<Item = (usize, Vector3<f64>, Vector3<f64>, f64)> + 'a {
        let down = r.row(2);
        (0..self.count).filter_map(move |i| {
            let p = &self.points[i];
            let depth = s.pos_ned_m.z + down.dot(&p.transpose()) - self.plane_z;
            (depth > 0.0).then(|| {
                let at = s.pos_ned_m + r * p;
                let vel = s.vel_ned_m_s + r * s.rate_frd_rad_s.cross(p);
                (i, at, vel, depth)
            })
        })
    }

    /// The ground's push on a body in state `s`, the anchors held where the step began.
    #[inline]
    pub fn contact(&self, s: &BodyState) -> Contact {
        if self.out_of_reach(s) {
            return Contact::NONE;
        }
        self.contact_near(s)
    }

    /// [`Self::contact`] within reach of the ground.
    fn contact_near(&self, s: &BodyState) -> Contact {
        let r = s.q_ned_from_frd.to_rotation_matrix().into_inner();
        let mut out = Contact::NONE;
        for (i, at, vel, depth) in self.touching(s, &r) {
            out.touching = true;
            let normal = (self.k * depth + self.c * vel.z).max(0.0);
            // Sideways: the spring to the anchor (none yet for a foot touching down within this
            // step) and the damper, at most μ F_n.
            let stretch = self.anchors[i].map_or(Vector2::zeros(), |a| at.xy() - a);
            let mut side = -self.k * stretch - self.c * vel.xy();
            let limit = self.mu * normal;
            if side.norm() > limit {
                side *= limit / side.norm();
            }
            let force = Vector3::new(side.x, side.y, -normal);
            out.force_ned_n += force;
            out.moment_frd_n_m += self.points[i].cross(&(r.transpose() * force));
        }
        out
    }

    /// After a step ending in `s`: a foot touching down holds where it touched, one pulled
    /// further than friction holds slides until it does, one in the air lets go. Returns
    /// whether any point touches.
    pub fn settle_anchors(&mut self, s: &BodyState) -> bool {
        if self.out_of_reach(s) {
            if self.held {
                self.release();
            }
            return false;
        }
        let mut anchors = [None; MAX_POINTS];
        {
            let r = s.q_ned_from_frd.to_rotation_matrix().into_inner();
            for (i, at, vel, depth) in self.touching(s, &r) {
                let normal = (self.k * depth + self.c * vel.z).max(0.0);
                let hold = self.mu * normal / self.k;
                anchors[i] = Some(match self.anchors[i] {
                    Some(a) if (at.xy() - a).norm() > hold => {
                        at.xy() - (at.xy() - a).normalize() * hold
                    }
                    Some(a) => a,
                    None => at.xy(),
                });
            }
        }
        self.anchors = anchors;
        self.held = anchors.iter().any(Option::is_some);
        self.held
    }

    /// Lets go of the ground (the body was moved by hand).
    pub fn release(&mut self) {
        self.anchors = [None; MAX_POINTS];
        self.held = false;
    }
}

#[cfg(test)]
mod tests;
