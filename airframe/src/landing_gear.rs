//! The landing gear: the points the vehicle stands on, and how stiff, damped and grippy they are.
//!
//! The airframe file may give it (`[landing_gear]`); without it, four feet are assumed where a
//! 450-class frame's legs are: on a circle of 0.6 times the rotors' arm at ±45° and ±135°, a
//! tenth of a metre below the lowest hub (quad_x: a footprint 0.19 m square, the centre of mass
//! 0.1 m above it).

use crate::config::Checker;
use nalgebra::Vector3;
use serde::Deserialize;

/// Most feet (or skid ends) a landing gear may have.
pub const MAX_FEET: usize = 8;

/// The feet and their springs.
#[derive(Debug, Clone, PartialEq)]
pub struct LandingGear {
    /// Each foot's contact point, FRD from the centre of mass (m); below it (z > 0).
    pub feet_frd_m: Vec<Vector3<f64>>,
    /// How far the legs give under the vehicle's weight at rest, shared evenly (m): sets each
    /// foot's stiffness, `weight / (feet · sag)`.
    pub sag_m: f64,
    /// Damping ratio of the vehicle bouncing on its legs (0.7: one small rebound).
    pub damping_ratio: f64,
    /// Friction coefficient between a foot and the ground (0.8: grass, concrete).
    pub friction: f64,
}

/// `[landing_gear]` as written: every key optional.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct LandingGearFile {
    feet_m: Option<Vec<[f64; 3]>>,
    sag_m: Option<f64>,
    damping_ratio: Option<f64>,
    friction: Option<f64>,
}

impl LandingGear {
    /// The gear a file gives, its gaps filled from the default for rotors at `hubs`.
    pub(crate) fn from_file(raw: Option<LandingGearFile>, hubs: &[Vector3<f64>]) -> Self {
        let raw = raw.unwrap_or_default();
        let feet = raw.feet_m.map_or_else(
            || default_feet(hubs),
            |f| f.into_iter().map(Vector3::from).collect(),
        );
        Self {
            feet_frd_m: feet,
            sag_m: raw.sag_m.unwrap_or(0.005),
            damping_ratio: raw.damping_ratio.unwrap_or(0.7),
            friction: raw.friction.unwrap_or(0.8),
        }
    }

    /// Every violation: 3 to [`MAX_FEET`] feet below the centre of mass, standing it up (the
    /// centre of mass above the area they span), positive sag, a damping ratio in (0, 2], a
    /// friction in [0, 2].
    pub(crate) fn check(&self, c: &mut Checker) {
        let n = self.feet_frd_m.len();
        if !(3..=MAX_FEET).contains(&n) {
            c.fail(
                "landing_gear.feet_m",
                format!("3 to {MAX_FEET} feet stand a vehicle, got {n}"),
            );
            return;
        }
        for (i, f) in self.feet_frd_m.iter().enumerate() {
            c.finite(format!("landing_gear.feet_m[{i}]"), f.as_slice());
            if f.z.is_nan() || f.z <= 0.0 {
                c.fail(
                    format!("landing_gear.feet_m[{i}]"),
                    "a foot must be below the centre of mass (z > 0, FRD)",
                );
            }
        }
        if !stands(&self.feet_frd_m) {
            c.fail(
                "landing_gear.feet_m",
                "the feet must surround the centre of mass seen from above, or the vehicle falls over",
            );
        }
        c.within("landing_gear.sag_m", self.sag_m, 1e-4, 0.2);
        c.within("landing_gear.damping_ratio", self.damping_ratio, 0.01, 2.0);
        c.within("landing_gear.friction", self.friction, 0.0, 2.0);
    }

    /// The depth of the lowest foot below the centre of mass, level (m).
    pub fn depth_m(&self) -> f64 {
        self.feet_frd_m.iter().map(|f| f.z).fold(0.0, f64::max)
    }
}

/// Four feet on a circle of 0.6 times the rotors' arm at ±45° and ±135°, a tenth of a metre below
/// the lowest hub.
fn default_feet(hubs: &[Vector3<f64>]) -> Vec<Vector3<f64>> {
    let arm = hubs.iter().map(|h| h.xy().norm()).fold(0.05, f64::max);
    let depth = hubs.iter().map(|h| h.z).fold(f64::MIN, f64::max).max(0.0) + 0.1;
    let half = 0.6 * arm * std::f64::consts::FRAC_1_SQRT_2;
    [(1.0, 1.0), (-1.0, 1.0), (-1.0, -1.0), (1.0, -1.0)]
        .into_iter()
        .map(|(x, y)| Vector3::new(x * half, y * half, depth))
        .collect()
}

/// Whether the centre of mass lies strictly inside the convex hull of the feet seen from above.
fn stands(feet: &[Vector3<f64>]) -> bool {
    // Inside the hull: on the inner side of every edge of it. Brute force over pairs (at most
    // eight feet): an edge of the hull has every foot on one side; the origin must be on that
    // side too, not on the line.
    let mut edges = 0;
    for (i, a) in feet.iter().enumerate() {
        for b in &feet[i + 1..] {
            let side = |p: &Vector3<f64>| (b.x - a.x) * (p.y - a.y) - (b.y - a.y) * (p.x - a.x);
            let sides: Vec<f64> = feet.iter().map(side).collect();
            let left = sides.iter().all(|&s| s >= -1e-12);
            let right = sides.iter().all(|&s| s <= 1e-12);
            if left || right {
                edges += 1;
                let o = side(&Vector3::zeros());
                if (left && o <= 1e-9) || (right && o >= -1e-9) {
                    return false;
                }
            }
        }
    }
    edges >= 3
}
