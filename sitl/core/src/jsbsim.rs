//! JSBSim as a physics back-end, the pure part: the multirotor model JSBSim loads, the request
//! that steps it, the state it answers and that state in the SI/NED/FRD truth of
//! docs/conventions.md. The process (JSBSim in-process in a small Python bridge) and its UDP link
//! live in the `sitl` binary; everything here is testable without JSBSim.
//!
//! The model carries only mass, inertia, ground contact and one body force and one yaw moment
//! per rotor (plus one aerodynamic force and moment): rotors, motors and drag stay our Rust
//! models, so both back-ends fly the same airframe on the same inputs and differ only in the
//! rigid body, the Earth and the ground.
//!
//! The wire between `sitl` and the bridge: a request is a `u64` sequence number and one `f64` per
//! [`input_properties`] entry; the reply the same number and one `f64` per [`STATE_PROPERTIES`]
//! entry, all little-endian. Full double precision: no unit or digit is lost on the way.
//!
//! What JSBSim 1.3.3 (the pinned PyPI package) does here, found by experiment:
//! - `<location>` is in the structural frame, x aft, y right, z up; a BODY `<direction>` is x
//!   forward, y right, z down.
//! - Its inertia tensor is `[[ixx, -ixy, ixz], [-ixy, iyy, -iyz], [ixz, -iyz, izz]]` (a roll
//!   moment with `ixz` > 0 yaws the body negative): from our tensor `J`, `ixy = -J₀₁`,
//!   `iyz = -J₁₂`, `ixz = +J₀₂`.
//! - An external force's own `magnitude` (a moment's `magnitude-lbsft`) is not a leaf property
//!   that can be set: each reaction takes its magnitude from a `<function>` of a declared
//!   `bridge/…` property, which can be set.
//! - A frame integrates first and computes the accelerations last: a value set before a frame
//!   shows in that frame's accelerations and moves the body from the next (a yaw moment set on
//!   a hovering quad_x yields 24 frames of rotation in 25). A zero-length frame in between does
//!   not change that (the reactions' functions are not re-evaluated). At 250 frames a second
//!   that delay of 4 ms was enough to make the autopilot's rate loop ring at ~5 Hz and the
//!   vehicle climb away on saturated rotors; hence [`frames_per_step`].
//! - The generated quad_x and dodeca models hover on thrust = weight/n with rates below 1e-8
//!   rad/s (JSBSim's gravity at Zurich differs from ours by 0.02 m/s²) and rest on their three
//!   feet 2 mm compressed.
//! - Through its Python API a frame of the quad_x model costs ~15 µs, setting 14 properties and
//!   reading 25 through property nodes ~8 µs more (this machine).

use crate::airframe::Airframe;
use crate::environment::AirState;
use nalgebra::{UnitQuaternion, Vector3};
use navmath::geo::{LatLonAlt, LocalFrame};
use std::fmt::Write as _;

/// Metres per foot.
pub const M_PER_FT: f64 = 0.3048;
/// Newtons per pound-force.
pub const N_PER_LBF: f64 = 4.448_221_615_260_5;
/// Pascals per pound per square foot.
pub const PA_PER_PSF: f64 = 47.880_258_980_335_8;
/// Kelvin per degree Rankine.
pub const K_PER_R: f64 = 5.0 / 9.0;
/// kg/m³ per slug/ft³.
pub const KG_M3_PER_SLUG_FT3: f64 = 515.378_818_393_2;

/// The model's name: JSBSim loads `aircraft/NAME/NAME.xml` under its root.
pub const MODEL_NAME: &str = "autopilot_multirotor";

/// The properties the bridge answers with, in this order.
pub const STATE_PROPERTIES: [&str; 25] = [
    "simulation/sim-time-sec",
    "position/lat-geod-deg",
    "position/long-gc-deg",
    "position/h-sl-ft",
    "velocities/v-north-fps",
    "velocities/v-east-fps",
    "velocities/v-down-fps",
    "attitude/phi-rad",
    "attitude/theta-rad",
    "attitude/psi-rad",
    "velocities/p-rad_sec",
    "velocities/q-rad_sec",
    "velocities/r-rad_sec",
    "accelerations/pdot-rad_sec2",
    "accelerations/qdot-rad_sec2",
    "accelerations/rdot-rad_sec2",
    "forces/fbx-total-lbs",
    "forces/fby-total-lbs",
    "forces/fbz-total-lbs",
    "forces/fbx-gear-lbs",
    "forces/fby-gear-lbs",
    "forces/fbz-gear-lbs",
    "atmosphere/P-psf",
    "atmosphere/T-R",
    "atmosphere/rho-slugs_ft3",
];

/// The bridge properties a rotor's thrust (lbf) and yaw moment (lbf·ft) are set through.
fn rotor_properties(i: usize) -> (String, String) {
    (
        format!("bridge/rotor{}-thrust-lbs", i + 1),
        format!("bridge/rotor{}-torque-lbsft", i + 1),
    )
}

/// The bridge properties of the aerodynamic force (lbf, body x y z) and moment (lbf·ft).
const AERO_FORCE: [&str; 3] = [
    "bridge/aero-x-lbs",
    "bridge/aero-y-lbs",
    "bridge/aero-z-lbs",
];
const AERO_MOMENT: [&str; 3] = [
    "bridge/aero-l-lbsft",
    "bridge/aero-m-lbsft",
    "bridge/aero-n-lbsft",
];

/// A point of the FRD body frame (m) in JSBSim's structural frame (x aft, y right, z up).
fn structural(p: &Vector3<f64>) -> [f64; 3] {
    [-p.x, p.y, -p.z]
}

fn location(out: &mut String, indent: &str, p: [f64; 3]) {
    let _ = writeln!(
        out,
        "{indent}<location unit=\"M\"><x>{:.6}</x><y>{:.6}</y><z>{:.6}</z></location>",
        p[0], p[1], p[2]
    );
}

/// What one foot's spring would sag under the whole weight (m): three share it.
const FOOT_SAG_M: f64 = 0.005;

/// How far the feet reach below the centre of mass (m): a tenth of a metre below the lowest hub.
fn foot_depth_m(a: &Airframe) -> f64 {
    let hub_down = a
        .rotors
        .iter()
        .map(|r| r.position_frd_m.z)
        .fold(f64::MIN, f64::max);
    hub_down + 0.1
}

/// Height of the centre of mass above the ground when the vehicle rests on its feet (m). The
/// bridge puts the local NED origin there, so that a vehicle at rest is at z = 0 in both
/// back-ends (the built-in physics rests the centre of mass on the ground).
pub fn rest_height_m(a: &Airframe) -> f64 {
    foot_depth_m(a) - FOOT_SAG_M / 3.0
}

/// JSBSim's initialisation file for a vehicle of `a` starting in `initial` (local NED of
/// `home`, which is the rest position of the centre of mass: see [`rest_height_m`]).
pub fn init_xml(a: &Airframe, home: &LatLonAlt, initial: &crate::body::BodyState) -> String {
    let rest = rest_height_m(a);
    let start = home.offset_by_ned(&initial.pos_ned_m);
    let (phi, theta, psi) = initial.q_ned_from_frd.euler_angles();
    let v = initial.vel_ned_m_s / M_PER_FT;
    let w = initial.rate_frd_rad_s;
    let mut x = String::new();
    let _ = writeln!(x, "<?xml version=\"1.0\"?>");
    let _ = writeln!(x, "<initialize name=\"start\">");
    let _ = writeln!(
        x,
        "  <latitude unit=\"DEG\" type=\"geodetic\">{:.12}</latitude><longitude unit=\"DEG\">{:.12}</longitude>",
        start.lat_deg, start.lon_deg
    );
    // `altitude` is above the ground; the ground lies `rest` below the NED origin.
    let _ = writeln!(
        x,
        "  <elevation unit=\"M\">{:.6}</elevation><altitude unit=\"M\">{:.6}</altitude>",
        home.alt_m - rest,
        rest - initial.pos_ned_m.z
    );
    let _ = writeln!(
        x,
        "  <phi unit=\"RAD\">{phi:.12}</phi><theta unit=\"RAD\">{theta:.12}</theta><psi unit=\"RAD\">{psi:.12}</psi>"
    );
    let _ = writeln!(
        x,
        "  <vnorth unit=\"FT/SEC\">{:.9}</vnorth><veast unit=\"FT/SEC\">{:.9}</veast><vdown unit=\"FT/SEC\">{:.9}</vdown>",
        v.x, v.y, v.z
    );
    let _ = writeln!(
        x,
        "  <p unit=\"RAD/SEC\">{:.12}</p><q unit=\"RAD/SEC\">{:.12}</q><r unit=\"RAD/SEC\">{:.12}</r>",
        w.x, w.y, w.z
    );
    let _ = writeln!(x, "</initialize>");
    x
}

/// The aircraft file for `a`: mass, inertia, three ground contacts under the rotor disc, a
/// thrust force and a yaw moment per rotor, and the aerodynamic force and moment, each driven by
/// one of the [`input_properties`].
pub fn aircraft_xml(a: &Airframe) -> String {
    let mut x = String::new();
    let _ = writeln!(x, "<?xml version=\"1.0\"?>");
    let _ = writeln!(
        x,
        "<!-- Written by the autopilot's sitl from airframe {:?}: do not edit. -->",
        a.name
    );
    let _ = writeln!(
        x,
        "<fdm_config name=\"{MODEL_NAME}\" version=\"2.0\" release=\"ALPHA\">"
    );
    let _ = writeln!(
        x,
        "  <fileheader><author>autopilot sitl</author></fileheader>"
    );
    write_metrics(&mut x, a);
    write_mass_balance(&mut x, a);
    write_ground_reactions(&mut x, a);
    write_external_reactions(&mut x, a);
    // Empty, but JSBSim wants them (without aerodynamics it refuses to initialise).
    let _ = writeln!(x, "  <propulsion/>");
    let _ = writeln!(x, "  <aerodynamics/>");
    let _ = writeln!(x, "</fdm_config>");
    x
}

/// The metrics JSBSim insists on (no aerodynamics of its own use them).
fn write_metrics(x: &mut String, a: &Airframe) {
    // Metrics JSBSim insists on; no aerodynamics of its own use them.
    let span = 2.0
        * a.rotors
            .iter()
            .map(|r| r.position_frd_m.xy().norm() + 0.5 * r.diameter_m)
            .fold(0.1, f64::max);
    let _ = writeln!(x, "  <metrics>");
    let _ = writeln!(
        x,
        "    <wingarea unit=\"M2\">{:.6}</wingarea><wingspan unit=\"M\">{span:.6}</wingspan><chord unit=\"M\">{span:.6}</chord>",
        span * span
    );
    for name in ["AERORP", "EYEPOINT", "VRP"] {
        let _ = writeln!(
            x,
            "    <location name=\"{name}\" unit=\"M\"><x>0</x><y>0</y><z>0</z></location>"
        );
    }
    let _ = writeln!(x, "  </metrics>");
}

/// The mass and inertia, about the centre of mass.
fn write_mass_balance(x: &mut String, a: &Airframe) {
    let j = &a.inertia_kg_m2;
    let _ = writeln!(x, "  <mass_balance>");
    let _ = writeln!(
        x,
        "    <ixx unit=\"KG*M2\">{:.9}</ixx><iyy unit=\"KG*M2\">{:.9}</iyy><izz unit=\"KG*M2\">{:.9}</izz>",
        j[(0, 0)],
        j[(1, 1)],
        j[(2, 2)]
    );
    // JSBSim's tensor: [[ixx, -ixy, ixz], [-ixy, iyy, -iyz], [ixz, -iyz, izz]].
    let _ = writeln!(
        x,
        "    <ixy unit=\"KG*M2\">{:.9}</ixy><ixz unit=\"KG*M2\">{:.9}</ixz><iyz unit=\"KG*M2\">{:.9}</iyz>",
        -j[(0, 1)],
        j[(0, 2)],
        -j[(1, 2)]
    );
    let _ = writeln!(x, "    <emptywt unit=\"KG\">{:.6}</emptywt>", a.mass_kg);
    let _ = writeln!(
        x,
        "    <location name=\"CG\" unit=\"M\"><x>0</x><y>0</y><z>0</z></location>"
    );
    let _ = writeln!(x, "  </mass_balance>");
}

/// The feet the vehicle stands on.
fn write_ground_reactions(x: &mut String, a: &Airframe) {
    // Three stiff, damped feet on a circle of half the arm, a tenth of a metre below the hubs.
    let arm = a
        .rotors
        .iter()
        .map(|r| r.position_frd_m.xy().norm())
        .fold(0.05, f64::max);
    let stiffness = a.mass_kg * crate::GRAVITY_M_S2 / FOOT_SAG_M;
    let damping = 2.0 * 0.7 * (stiffness * a.mass_kg).sqrt();
    let _ = writeln!(x, "  <ground_reactions>");
    for k in 0..3 {
        let angle = (k as f64) * std::f64::consts::TAU / 3.0;
        let foot = Vector3::new(
            0.5 * arm * angle.cos(),
            0.5 * arm * angle.sin(),
            foot_depth_m(a),
        );
        let _ = writeln!(x, "    <contact type=\"STRUCTURE\" name=\"foot{}\">", k + 1);
        location(x, "      ", structural(&foot));
        let _ = writeln!(
            x,
            "      <static_friction>0.8</static_friction><dynamic_friction>0.5</dynamic_friction>"
        );
        let _ = writeln!(
            x,
            "      <spring_coeff unit=\"N/M\">{stiffness:.3}</spring_coeff><damping_coeff unit=\"N/M/SEC\">{damping:.3}</damping_coeff>"
        );
        let _ = writeln!(x, "    </contact>");
    }
    let _ = writeln!(x, "  </ground_reactions>");
}

/// The rotors' forces and moments, set by the bridge each step.
fn write_external_reactions(x: &mut String, a: &Airframe) {
    let _ = writeln!(x, "  <external_reactions>");
    let declared = a
        .rotors
        .iter()
        .enumerate()
        .flat_map(|(i, _)| {
            let (t, q) = rotor_properties(i);
            [t, q]
        })
        .chain(AERO_FORCE.iter().chain(&AERO_MOMENT).map(|s| s.to_string()));
    for p in declared {
        let _ = writeln!(x, "    <property>{p}</property>");
    }
    let axes = ["x", "y", "z"];
    for (i, r) in a.rotors.iter().enumerate() {
        let (thrust, torque) = rotor_properties(i);
        let _ = writeln!(x, "    <force name=\"rotor{}\" frame=\"BODY\">", i + 1);
        let _ = writeln!(
            x,
            "      <function><property>{thrust}</property></function>"
        );
        location(x, "      ", structural(&r.position_frd_m));
        // Thrust lifts: up is -z in the body frame.
        let _ = writeln!(x, "      <direction><x>0</x><y>0</y><z>-1</z></direction>");
        let _ = writeln!(x, "    </force>");
        let _ = writeln!(x, "    <moment name=\"rotor{}-yaw\" frame=\"BODY\">", i + 1);
        let _ = writeln!(
            x,
            "      <function><property>{torque}</property></function>"
        );
        let _ = writeln!(x, "      <direction><x>0</x><y>0</y><z>1</z></direction>");
        let _ = writeln!(x, "    </moment>");
    }
    for (k, axis) in axes.iter().enumerate() {
        let mut d = [0; 3];
        d[k] = 1;
        let _ = writeln!(x, "    <force name=\"aero-{axis}\" frame=\"BODY\">");
        let _ = writeln!(
            x,
            "      <function><property>{}</property></function>",
            AERO_FORCE[k]
        );
        location(x, "      ", [0.0; 3]);
        let _ = writeln!(
            x,
            "      <direction><x>{}</x><y>{}</y><z>{}</z></direction>",
            d[0], d[1], d[2]
        );
        let _ = writeln!(x, "    </force>");
        let _ = writeln!(
            x,
            "    <moment name=\"aero-{}\" frame=\"BODY\">",
            ["l", "m", "n"][k]
        );
        let _ = writeln!(
            x,
            "      <function><property>{}</property></function>",
            AERO_MOMENT[k]
        );
        let _ = writeln!(
            x,
            "      <direction><x>{}</x><y>{}</y><z>{}</z></direction>",
            d[0], d[1], d[2]
        );
        let _ = writeln!(x, "    </moment>");
    }
    let _ = writeln!(x, "  </external_reactions>");
}

/// JSBSim's lowest frame rate (Hz): a force acts one JSBSim frame late, so frames of at most a
/// millisecond keep that delay below what the rate loop notices.
pub const MIN_FRAME_RATE_HZ: f64 = 1000.0;

/// JSBSim frames per physics step at `step_rate_hz`: enough for [`MIN_FRAME_RATE_HZ`].
pub fn frames_per_step(step_rate_hz: f64) -> u32 {
    (MIN_FRAME_RATE_HZ / step_rate_hz).ceil().clamp(1.0, 1000.0) as u32
}

/// The properties a request sets, in its order, for `rotors` rotors: each rotor's thrust (lbf)
/// and yaw moment (lbf·ft), then the aerodynamic force and moment about x, y and z.
pub fn input_properties(rotors: usize) -> Vec<String> {
    let mut names = Vec::with_capacity(2 * rotors + 6);
    for i in 0..rotors {
        let (thrust, torque) = rotor_properties(i);
        names.push(thrust);
        names.push(torque);
    }
    for k in 0..3 {
        names.push(AERO_FORCE[k].to_owned());
        names.push(AERO_MOMENT[k].to_owned());
    }
    names
}

/// What a request sets before its frame, in SI and FRD.
#[derive(Debug, Clone, PartialEq)]
pub struct BridgeInputs {
    /// Thrust of each rotor (N), along its axis (body −z).
    pub thrust_n: Vec<f64>,
    /// Yaw moment of each rotor on the body (N·m, positive clockwise seen from above: body +z).
    pub yaw_moment_n_m: Vec<f64>,
    /// Aerodynamic force at the centre of mass, FRD (N).
    pub aero_force_frd_n: Vector3<f64>,
    /// Aerodynamic moment, FRD (N·m).
    pub aero_moment_frd_n_m: Vector3<f64>,
}

/// A value JSBSim must not see: a NaN or an infinity would poison its state for good.
#[derive(Debug, Clone, PartialEq)]
pub struct NonFinite {
    /// The property it was meant for.
    pub property: String,
}

impl std::fmt::Display for NonFinite {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "a non-finite value for {}", self.property)
    }
}

impl std::error::Error for NonFinite {}

impl BridgeInputs {
    /// What a step's loads set on a vehicle of `rotors` rotors.
    pub fn from_loads(loads: &crate::sim::StepLoads, rotors: usize) -> Self {
        Self {
            thrust_n: loads.rotor.thrust_n[..rotors].to_vec(),
            yaw_moment_n_m: loads.rotor.yaw_moment_n_m[..rotors].to_vec(),
            aero_force_frd_n: loads.aero_force_frd_n,
            aero_moment_frd_n_m: loads.aero_moment_frd_n_m,
        }
    }

    /// The request of number `sequence`, appended to `out`: the values of
    /// [`input_properties`] in JSBSim's units. Refused whole if any value is not finite.
    pub fn encode(&self, sequence: u64, out: &mut Vec<u8>) -> Result<(), NonFinite> {
        let start = out.len();
        out.extend_from_slice(&sequence.to_le_bytes());
        let mut index = 0;
        let mut push = |value: f64| -> Result<(), NonFinite> {
            if !value.is_finite() {
                out.truncate(start);
                return Err(NonFinite {
                    property: input_properties(self.thrust_n.len()).swap_remove(index),
                });
            }
            out.extend_from_slice(&value.to_le_bytes());
            index += 1;
            Ok(())
        };
        for (&t, &q) in self.thrust_n.iter().zip(&self.yaw_moment_n_m) {
            push(t / N_PER_LBF)?;
            push(q / (N_PER_LBF * M_PER_FT))?;
        }
        for k in 0..3 {
            push(self.aero_force_frd_n[k] / N_PER_LBF)?;
            push(self.aero_moment_frd_n_m[k] / (N_PER_LBF * M_PER_FT))?;
        }
        Ok(())
    }
}

/// One frame of JSBSim's state, in SI, NED and FRD.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JsbsimState {
    /// JSBSim's simulation time (s).
    pub time_s: f64,
    /// Geodetic (WGS-84) position of the centre of mass (altitude above mean sea level).
    pub position: LatLonAlt,
    /// Velocity, NED (m/s).
    pub vel_ned_m_s: Vector3<f64>,
    /// Attitude, FRD to NED.
    pub q_ned_from_frd: UnitQuaternion<f64>,
    /// Body rate relative to the Earth, FRD (rad/s).
    pub rate_frd_rad_s: Vector3<f64>,
    /// Angular acceleration, FRD (rad/s²).
    pub ang_accel_frd_rad_s2: Vector3<f64>,
    /// Specific force (every force but gravity, over the mass), FRD (m/s²): what an
    /// accelerometer at the centre of mass measures.
    pub specific_force_frd_m_s2: Vector3<f64>,
    /// What the ground pushes on the feet with, FRD (N): zero in the air.
    pub ground_force_frd_n: Vector3<f64>,
    /// Air at the vehicle.
    pub air: AirState,
}

impl JsbsimState {
    /// The ground pushes harder than this (N) on a vehicle that rests on it.
    pub const GROUND_CONTACT_N: f64 = 1e-3;

    /// The simulator's view: position in the local NED frame `origin` (at the rest position of
    /// the centre of mass, see [`rest_height_m`]).
    pub fn body_step(&self, origin: &LocalFrame) -> crate::sim::ExternalBodyStep {
        crate::sim::ExternalBodyStep {
            body: crate::body::BodyState {
                pos_ned_m: origin.to_ned(&self.position),
                vel_ned_m_s: self.vel_ned_m_s,
                q_ned_from_frd: self.q_ned_from_frd,
                rate_frd_rad_s: self.rate_frd_rad_s,
            },
            specific_force_frd_m_s2: self.specific_force_frd_m_s2,
            ang_accel_frd_rad_s2: self.ang_accel_frd_rad_s2,
            on_ground: self.ground_force_frd_n.norm() > Self::GROUND_CONTACT_N,
        }
    }
}

/// Why a reply could not be read.
#[derive(Debug, Clone, PartialEq)]
pub struct BadReply(pub String);

impl std::fmt::Display for BadReply {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "JSBSim bridge reply: {}", self.0)
    }
}

impl std::error::Error for BadReply {}

/// Length of a reply datagram (bytes).
pub const REPLY_LEN: usize = 8 * (1 + STATE_PROPERTIES.len());

/// Reads a reply of a vehicle of `mass_kg`: its sequence number and the state.
pub fn decode_reply(datagram: &[u8], mass_kg: f64) -> Result<(u64, JsbsimState), BadReply> {
    if datagram.len() != REPLY_LEN {
        return Err(BadReply(format!(
            "{} bytes, {REPLY_LEN} expected",
            datagram.len()
        )));
    }
    let word = |i: usize| -> [u8; 8] {
        let mut w = [0; 8];
        w.copy_from_slice(&datagram[8 * i..8 * i + 8]);
        w
    };
    let sequence = u64::from_le_bytes(word(0));
    let mut v = [0.0; STATE_PROPERTIES.len()];
    for (i, value) in v.iter_mut().enumerate() {
        *value = f64::from_le_bytes(word(i + 1));
        if !value.is_finite() {
            return Err(BadReply(format!(
                "{} is not finite in reply {sequence}",
                STATE_PROPERTIES[i]
            )));
        }
    }
    let [
        time_s,
        lat,
        lon,
        h_sl_ft,
        vn,
        ve,
        vd,
        phi,
        theta,
        psi,
        p,
        q,
        r,
        pdot,
        qdot,
        rdot,
        fx,
        fy,
        fz,
        gx,
        gy,
        gz,
        p_psf,
        t_r,
        rho,
    ] = v;
    let ft = |x: f64| x * M_PER_FT;
    let state = JsbsimState {
        time_s,
        position: LatLonAlt {
            lat_deg: lat,
            lon_deg: lon,
            alt_m: ft(h_sl_ft),
        },
        vel_ned_m_s: Vector3::new(ft(vn), ft(ve), ft(vd)),
        q_ned_from_frd: UnitQuaternion::from_euler_angles(phi, theta, psi),
        rate_frd_rad_s: Vector3::new(p, q, r),
        ang_accel_frd_rad_s2: Vector3::new(pdot, qdot, rdot),
        specific_force_frd_m_s2: Vector3::new(fx, fy, fz) * (N_PER_LBF / mass_kg),
        ground_force_frd_n: Vector3::new(gx, gy, gz) * N_PER_LBF,
        air: AirState {
            pressure_pa: p_psf * PA_PER_PSF,
            temperature_k: t_r * K_PER_R,
            density_kg_m3: rho * KG_M3_PER_SLUG_FT3,
        },
    };
    Ok((sequence, state))
}

#[cfg(test)]
mod tests;
