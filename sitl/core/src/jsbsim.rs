//! JSBSim as a physics back-end (issue 8), the pure part: the multirotor model JSBSim loads,
//! the command batch that steps it, the state it streams back and that state in the SI/NED/FRD
//! truth of ARCHITECTURE.md. The process, its TCP command port and its UDP output live in the
//! `sitl` binary; everything here is testable without JSBSim.
//!
//! The model carries only mass, inertia, ground contact and one body force and one yaw moment
//! per rotor (plus one aerodynamic force and moment): rotors, motors and drag stay our Rust
//! models, so both back-ends fly the same airframe on the same inputs and differ only in the
//! rigid body, the Earth and the ground.
//!
//! What JSBSim 1.3.3 (the pinned PyPI package) does here, found by experiment:
//! - `<location>` is in the structural frame, x aft, y right, z up; a BODY `<direction>` is x
//!   forward, y right, z down.
//! - Its inertia tensor is `[[ixx, -ixy, ixz], [-ixy, iyy, -iyz], [ixz, -iyz, izz]]` (a roll
//!   moment with `ixz` > 0 yaws the body negative): from our tensor `J`, `ixy = -J₀₁`,
//!   `iyz = -J₁₂`, `ixz = +J₀₂`.
//! - An external force's own `magnitude` (a moment's `magnitude-lbsft`) cannot be set on the
//!   TCP command port (`Not a leaf property`): each reaction takes its magnitude from a
//!   `<function>` of a declared `bridge/…` property, which can be set.
//! - `set` answers `set successful` or `Unknown property`; the UDP socket output sends one
//!   `<LABELS>` line, then per output one line `time, value, value, …`.
//! - A value set before `iterate 1` acts from the frame after: a yaw moment set on a hovering
//!   quad_x yields 24 frames of acceleration in 25 (17.46 rad/s² measured over 0.1 s against
//!   1/Izz = 18.18), and the output of the first frame still shows the old forces.
//! - The generated quad_x and dodeca models hover on thrust = weight/n with rates below 1e-8
//!   rad/s (JSBSim's gravity at Zurich differs from ours by 0.02 m/s²) and rest on their three
//!   feet 2 mm compressed (checked with the pinned JSBSim's Python API).
//! - Lockstep from Python reaches ~9 600 `iterate 1` round trips a second on this machine.

use crate::airframe::Airframe;
use crate::environment::AirState;
use crate::geo::Geodetic;
use nalgebra::{UnitQuaternion, Vector3};
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

/// The properties JSBSim streams back each frame, in this order after its `Time` column.
pub const STATE_PROPERTIES: [&str; 25] = [
    "bridge/frame-mod",
    "bridge/dlat-geod-deg",
    "bridge/dlon-deg",
    "bridge/dh-sl-ft",
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

/// JSBSim's socket output prints 7 significant digits: the position goes out as offsets from the
/// origin (computed inside JSBSim in double precision; `position/lat-geod-deg` itself would be
/// a metre coarse) and the frame counter modulo this (it would be rounded past 10⁷ frames).
pub const FRAME_MODULUS: u64 = 1_000_000;

/// Where the bridge talks to JSBSim.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BridgePorts {
    /// JSBSim's TCP command port (`<input port>`).
    pub command_tcp: u16,
    /// The UDP port JSBSim streams its state to, on 127.0.0.1.
    pub state_udp: u16,
}

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
pub fn init_xml(a: &Airframe, home: &Geodetic, initial: &crate::body::BodyState) -> String {
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
/// thrust force and a yaw moment per rotor, the aerodynamic force and moment, the command
/// port and the state output (`rate_hz`: one datagram per frame at the simulation rate), its
/// position as offsets from `origin`.
pub fn aircraft_xml(a: &Airframe, origin: &Geodetic, ports: BridgePorts, rate_hz: f64) -> String {
    let j = &a.inertia_kg_m2;
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
        location(&mut x, "      ", structural(&foot));
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
        location(&mut x, "      ", structural(&r.position_frd_m));
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
        location(&mut x, "      ", [0.0; 3]);
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
    // Empty, but JSBSim wants them (without aerodynamics it refuses to initialise).
    let _ = writeln!(x, "  <propulsion/>");
    // The precise outputs: offsets from the origin and the frame counter modulo FRAME_MODULUS.
    let _ = writeln!(x, "  <flight_control name=\"bridge\">");
    let _ = writeln!(x, "    <channel name=\"output\">");
    let function = |x: &mut String, name: &str, op: &str, property: &str, value: String| {
        let _ = writeln!(
            x,
            "      <fcs_function name=\"{name}\"><function><{op}><property>{property}</property><value>{value}</value></{op}></function></fcs_function>"
        );
    };
    function(
        &mut x,
        "bridge/frame-mod",
        "mod",
        "simulation/frame",
        FRAME_MODULUS.to_string(),
    );
    function(
        &mut x,
        "bridge/dlat-geod-deg",
        "difference",
        "position/lat-geod-deg",
        format!("{:.12}", origin.lat_deg),
    );
    function(
        &mut x,
        "bridge/dlon-deg",
        "difference",
        "position/long-gc-deg",
        format!("{:.12}", origin.lon_deg),
    );
    function(
        &mut x,
        "bridge/dh-sl-ft",
        "difference",
        "position/h-sl-ft",
        format!("{:.9}", origin.alt_m / M_PER_FT),
    );
    let _ = writeln!(x, "    </channel>");
    let _ = writeln!(x, "  </flight_control>");
    let _ = writeln!(x, "  <aerodynamics/>");
    let _ = writeln!(x, "  <input port=\"{}\"/>", ports.command_tcp);
    let _ = writeln!(
        x,
        "  <output name=\"127.0.0.1\" type=\"SOCKET\" protocol=\"UDP\" port=\"{}\" rate=\"{rate_hz}\">",
        ports.state_udp
    );
    for p in STATE_PROPERTIES {
        let _ = writeln!(x, "    <property>{p}</property>");
    }
    let _ = writeln!(x, "  </output>");
    let _ = writeln!(x, "</fdm_config>");
    x
}

/// What the bridge sets before each `iterate 1`, in SI and FRD.
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

/// A value JSBSim must not see: a NaN or an infinity silently cancels the batch's `iterate`.
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

    /// The command batch: one `set` line per bridge property, then `iterate 1`. Refused whole
    /// if any value is not finite.
    pub fn encode(&self) -> Result<String, NonFinite> {
        let mut out = String::new();
        let mut set = |property: &str, value: f64| -> Result<(), NonFinite> {
            if !value.is_finite() {
                return Err(NonFinite {
                    property: property.to_owned(),
                });
            }
            let _ = writeln!(out, "set {property} {value:.9e}");
            Ok(())
        };
        for (i, (&t, &q)) in self.thrust_n.iter().zip(&self.yaw_moment_n_m).enumerate() {
            let (thrust, torque) = rotor_properties(i);
            set(&thrust, t / N_PER_LBF)?;
            set(&torque, q / (N_PER_LBF * M_PER_FT))?;
        }
        for k in 0..3 {
            set(AERO_FORCE[k], self.aero_force_frd_n[k] / N_PER_LBF)?;
            set(
                AERO_MOMENT[k],
                self.aero_moment_frd_n_m[k] / (N_PER_LBF * M_PER_FT),
            )?;
        }
        out.push_str("iterate 1\n");
        Ok(out)
    }
}

/// One frame of JSBSim's state, in SI, NED and FRD.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JsbsimState {
    /// JSBSim's simulation time (s).
    pub time_s: f64,
    /// Its frame counter (`simulation/frame`) modulo [`FRAME_MODULUS`].
    pub frame: u64,
    /// Geodetic position of the centre of mass (altitude above mean sea level).
    pub position: Geodetic,
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

    /// The simulator's view: position in the local NED frame of `origin` (the rest position of
    /// the centre of mass, see [`rest_height_m`]).
    pub fn body_step(&self, origin: &Geodetic) -> crate::sim::ExternalBodyStep {
        crate::sim::ExternalBodyStep {
            body: crate::body::BodyState {
                pos_ned_m: origin.ned_to(&self.position),
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

/// A line of JSBSim's UDP output.
#[derive(Debug, Clone, Copy, PartialEq)]
// Read once per frame and consumed at once: kept on the stack, no allocation per step.
#[allow(clippy::large_enum_variant)]
pub enum OutputLine {
    /// The `<LABELS>` line that opens the stream.
    Labels,
    /// One frame.
    State(JsbsimState),
}

/// Why a line of output could not be read.
#[derive(Debug, Clone, PartialEq)]
pub struct BadOutput(pub String);

impl std::fmt::Display for BadOutput {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "JSBSim output: {}", self.0)
    }
}

impl std::error::Error for BadOutput {}

/// Reads one output line (`Time` and the [`STATE_PROPERTIES`]) of a vehicle of `mass_kg` whose
/// model was written for `origin`.
pub fn parse_output(line: &str, mass_kg: f64, origin: &Geodetic) -> Result<OutputLine, BadOutput> {
    let line = line.trim();
    if line.starts_with("<LABELS>") {
        return Ok(OutputLine::Labels);
    }
    let mut v = [0.0; STATE_PROPERTIES.len() + 1];
    let mut n = 0;
    for field in line.split(',') {
        if n == v.len() {
            return Err(BadOutput(format!(
                "more than {} columns in {line:?}",
                v.len()
            )));
        }
        v[n] = field
            .trim()
            .parse::<f64>()
            .map_err(|_| BadOutput(format!("column {} is not a number in {line:?}", n + 1)))?;
        if !v[n].is_finite() {
            return Err(BadOutput(format!(
                "column {} is not finite in {line:?}",
                n + 1
            )));
        }
        n += 1;
    }
    if n != v.len() {
        return Err(BadOutput(format!(
            "{n} columns, {} expected, in {line:?}",
            v.len()
        )));
    }
    let [
        time_s,
        frame,
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
    if frame < 0.0 || frame.fract() != 0.0 {
        return Err(BadOutput(format!("frame {frame} is not a count")));
    }
    let ft = |x: f64| x * M_PER_FT;
    Ok(OutputLine::State(JsbsimState {
        time_s,
        frame: frame as u64,
        position: Geodetic {
            lat_deg: origin.lat_deg + lat,
            lon_deg: origin.lon_deg + lon,
            alt_m: origin.alt_m + ft(h_sl_ft),
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
    }))
}

/// What a datagram's frame is to the bridge waiting for the next one.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FrameVerdict {
    /// The frame asked for: take it.
    Next,
    /// The frame before, which JSBSim re-sends ahead of every new one: skip it.
    Stale,
    /// Neither: JSBSim stepped more or less than asked.
    Unexpected,
}

/// Takes each frame once, in order, by its counter (modulo [`FRAME_MODULUS`]): JSBSim answers
/// every `iterate` with the frame it had (stale) and then the new one, so counting datagrams
/// is wrong.
#[derive(Debug, Clone, Copy)]
pub struct FrameFilter {
    next: u64,
}

impl Default for FrameFilter {
    /// JSBSim starts at frame 0: the first `iterate 1` gives frame 1.
    fn default() -> Self {
        Self { next: 1 }
    }
}

impl FrameFilter {
    /// The frame waited for (the full count).
    pub fn next(&self) -> u64 {
        self.next
    }

    /// What `frame` (as sent, modulo [`FRAME_MODULUS`]) is; a [`FrameVerdict::Next`] moves on.
    pub fn check(&mut self, frame: u64) -> FrameVerdict {
        let expected = self.next % FRAME_MODULUS;
        if frame == expected {
            self.next += 1;
            FrameVerdict::Next
        } else if (frame + 1) % FRAME_MODULUS == expected {
            FrameVerdict::Stale
        } else {
            FrameVerdict::Unexpected
        }
    }
}

/// What JSBSim's command port answered to a batch.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Replies {
    /// `set successful` lines.
    pub sets: usize,
    /// `Iterations performed` lines.
    pub iterations: usize,
    /// Anything else (`Unknown property`, `Not a leaf property`, …), as received.
    pub errors: Vec<String>,
    /// A partial line kept for the next read.
    partial: String,
}

impl Replies {
    /// Folds in bytes read from the command port (replies end in `\r\n`, the prompt is
    /// `JSBSim> ` and may run into the next reply).
    pub fn push(&mut self, bytes: &[u8]) {
        self.partial.push_str(&String::from_utf8_lossy(bytes));
        while let Some(end) = self.partial.find('\n') {
            let line: String = self.partial.drain(..=end).collect();
            let mut text = line.trim();
            while let Some(rest) = text.strip_prefix("JSBSim>") {
                text = rest.trim_start();
            }
            match text {
                "" | "Connected to JSBSim server" => {}
                "set successful" => self.sets += 1,
                "Iterations performed" => self.iterations += 1,
                other => self.errors.push(other.to_owned()),
            }
        }
    }
}

#[cfg(test)]
mod tests;
