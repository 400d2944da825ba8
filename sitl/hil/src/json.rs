//! ArduPilot's JSON simulator interface (`sim_vehicle.py --model JSON`), both sides: the
//! autopilot sends a binary servo packet to the physics on UDP 9002 (+ 10 per instance), and
//! the physics answers each one with its state as one line of JSON
//! (<https://ardupilot.org/dev/docs/sitl-with-JSON.html>, `libraries/SITL/SIM_JSON.cpp`).
//!
//! The servo packet, little-endian: `magic: u16` (18458 for 16 channels, 29569 for 32),
//! `frame_rate: u16` (the autopilot's loop rate, Hz), `frame_count: u32` (one more every
//! packet; the same again is a resend), `pwm: [u16; 16 | 32]` (µs, 1000 = off, 2000 = full).
//!
//! The state, newline-framed: `timestamp` (s of simulation time), `imu.gyro` (rad/s FRD),
//! `imu.accel_body` (specific force, m/s² FRD: −9.8 down at rest), `position` and `velocity`
//! (NED, m and m/s, from the physics' origin), and the attitude as `quaternion` ([w, x, y, z],
//! body to NED) or `attitude` ([roll, pitch, yaw], rad). Other keys (`battery`, `rng_1`,
//! `airspeed`, …) are optional; of them, `battery.voltage`, `battery.current` and `airspeed`
//! are read.
//!
//! ArduPilot reads the state with no JSON parser (`SIM_JSON.cpp`, `parse_sensors`): it finds
//! each key as the first match of its name, skips the name and two characters (the closing
//! quote and the colon) and reads `[%f, %f, %f]` there, so a space after the colon makes every
//! vector unreadable. [`PhysicsState::to_json`] writes compact JSON, `"key":value`, with no
//! key inside another's name before it; `tests.rs` reads it with that rule.

use nalgebra::{UnitQuaternion, Vector3};

/// The physics' UDP port for instance 0; instance N listens on this + 10 N.
pub const JSON_PORT: u16 = 9002;
/// Ports between instances.
pub const JSON_INSTANCE_STRIDE: u16 = 10;
/// Magic of the 16-channel servo packet.
pub const MAGIC_16: u16 = 18458;
/// Magic of the 32-channel servo packet.
pub const MAGIC_32: u16 = 29569;
/// PWM of a motor off and at full thrust (µs).
pub const PWM_MIN: u16 = 1000;
/// PWM at full thrust (µs).
pub const PWM_MAX: u16 = 2000;

/// Why bytes or text are not what the protocol says.
#[derive(Debug, Clone, PartialEq)]
pub enum JsonError {
    /// A servo packet of the wrong size for its magic, or no known magic.
    Packet(String),
    /// A state that does not parse or lacks a required field.
    State(String),
}

impl std::fmt::Display for JsonError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            JsonError::Packet(why) => write!(f, "servo packet: {why}"),
            JsonError::State(why) => write!(f, "JSON state: {why}"),
        }
    }
}

impl std::error::Error for JsonError {}

/// Channels in the wide servo packet.
pub const MAX_CHANNELS: usize = 32;

/// The autopilot's servo output: a plain value, encoded and decoded without allocating.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ServoPacket {
    /// The autopilot's loop rate (Hz).
    pub frame_rate: u16,
    /// Packet number: one more every packet, the same again for a resend.
    pub frame_count: u32,
    /// PWM of each channel (µs); the first [`ServoPacket::channels`] are sent.
    pub pwm_us: [u16; MAX_CHANNELS],
    /// 16 or 32: the packet's layout.
    pub channels: usize,
}

impl ServoPacket {
    /// A packet of `pwm` (µs, channel 0 first): the 16-channel layout, or the 32-channel one
    /// for more than 16 channels (missing channels 0). Channels past 32 are dropped.
    pub fn new(frame_rate: u16, frame_count: u32, pwm: &[u16]) -> Self {
        let mut pwm_us = [0; MAX_CHANNELS];
        let n = pwm.len().min(MAX_CHANNELS);
        pwm_us[..n].copy_from_slice(&pwm[..n]);
        Self {
            frame_rate,
            frame_count,
            pwm_us,
            channels: if n > 16 { MAX_CHANNELS } else { 16 },
        }
    }

    /// The PWM of the channels the packet carries (µs).
    pub fn pwm(&self) -> &[u16] {
        &self.pwm_us[..self.channels]
    }

    /// Appends the packet's bytes to `out`.
    pub fn encode(&self, out: &mut Vec<u8>) {
        let magic = if self.channels > 16 {
            MAGIC_32
        } else {
            MAGIC_16
        };
        out.extend_from_slice(&magic.to_le_bytes());
        out.extend_from_slice(&self.frame_rate.to_le_bytes());
        out.extend_from_slice(&self.frame_count.to_le_bytes());
        for pwm in self.pwm() {
            out.extend_from_slice(&pwm.to_le_bytes());
        }
    }

    /// Reads a packet; a wrong magic or a size that is not its layout's is refused.
    pub fn decode(bytes: &[u8]) -> Result<Self, JsonError> {
        if bytes.len() < 8 {
            return Err(JsonError::Packet(format!(
                "{} bytes, too short",
                bytes.len()
            )));
        }
        let u16_at = |i: usize| u16::from_le_bytes([bytes[i], bytes[i + 1]]);
        let n = match u16_at(0) {
            MAGIC_16 => 16,
            MAGIC_32 => MAX_CHANNELS,
            m => return Err(JsonError::Packet(format!("unknown magic {m}"))),
        };
        if bytes.len() != 8 + 2 * n {
            return Err(JsonError::Packet(format!(
                "{} bytes, expected {} for {n} channels",
                bytes.len(),
                8 + 2 * n
            )));
        }
        let mut pwm_us = [0; MAX_CHANNELS];
        for (i, pwm) in pwm_us[..n].iter_mut().enumerate() {
            *pwm = u16_at(8 + 2 * i);
        }
        Ok(Self {
            frame_rate: u16_at(2),
            frame_count: u32::from_le_bytes([bytes[4], bytes[5], bytes[6], bytes[7]]),
            pwm_us,
            channels: n,
        })
    }
}

/// A motor command in [0, 1] as PWM (µs); anything not finite is off.
pub fn pwm_from_command(c: f64) -> u16 {
    let c = if c.is_finite() {
        c.clamp(0.0, 1.0)
    } else {
        0.0
    };
    PWM_MIN + (c * f64::from(PWM_MAX - PWM_MIN)).round() as u16
}

/// PWM (µs) as a motor command in [0, 1]: 1000 and below off, 2000 and above full.
pub fn command_from_pwm(pwm: u16) -> f64 {
    (f64::from(pwm.saturating_sub(PWM_MIN)) / f64::from(PWM_MAX - PWM_MIN)).min(1.0)
}

/// The physics' state, as one JSON reply carries it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PhysicsState {
    /// Simulation time (s).
    pub timestamp_s: f64,
    /// Gyro, FRD (rad/s).
    pub gyro_frd_rad_s: Vector3<f64>,
    /// Specific force, FRD (m/s²).
    pub accel_frd_m_s2: Vector3<f64>,
    /// Position from the physics' origin, NED (m).
    pub pos_ned_m: Vector3<f64>,
    /// Velocity, NED (m/s).
    pub vel_ned_m_s: Vector3<f64>,
    /// Attitude, body (FRD) to NED.
    pub q_ned_from_frd: UnitQuaternion<f64>,
    /// Battery voltage (V) and current (A), when the physics has them.
    pub battery: Option<(f64, f64)>,
    /// True airspeed, the speed through the air (m/s), when the physics has wind. ArduPilot's
    /// JSON side otherwise takes the ground speed as the airspeed: it assumes no wind.
    pub airspeed_m_s: Option<f64>,
}

impl PhysicsState {
    /// The state as ArduPilot reads it: one line of compact JSON (`"key":value`, no space
    /// after a colon) between newlines, the attitude as a quaternion. The newline before it
    /// matters too: ArduPilot takes the text between the last two newlines it has.
    pub fn to_json(&self) -> String {
        let mut s = String::with_capacity(512);
        self.write_json(&mut s);
        s
    }

    /// [`PhysicsState::to_json`] into `out` (cleared first), which keeps its allocation from
    /// one reply to the next.
    pub fn write_json(&self, out: &mut String) {
        use std::fmt::Write;
        out.clear();
        let q = self.q_ned_from_frd.quaternion();
        let v = |v: &Vector3<f64>| [v.x, v.y, v.z];
        // Writing to a String cannot fail.
        let _ = write!(out, "\n{{\"timestamp\":{:e},\"imu\":{{", self.timestamp_s);
        write_array(out, "gyro", &v(&self.gyro_frd_rad_s));
        out.push(',');
        write_array(out, "accel_body", &v(&self.accel_frd_m_s2));
        out.push_str("},");
        write_array(out, "position", &v(&self.pos_ned_m));
        out.push(',');
        write_array(out, "velocity", &v(&self.vel_ned_m_s));
        out.push(',');
        write_array(out, "quaternion", &[q.w, q.i, q.j, q.k]);
        if let Some(airspeed) = self.airspeed_m_s {
            let _ = write!(out, ",\"airspeed\":{airspeed:e}");
        }
        if let Some((voltage, current)) = self.battery {
            let _ = write!(
                out,
                ",\"battery\":{{\"voltage\":{voltage:e},\"current\":{current:e}}}"
            );
        }
        out.push_str("}\n");
    }

    /// Parses one JSON state; unknown keys are ignored, every required one must be there and
    /// finite, and a quaternion must have a length (it is normalised). The text is read
    /// in one pass by a reader written for it (`json/scan.rs`): no document tree, no allocation.
    pub fn parse(text: &str) -> Result<Self, JsonError> {
        Self::from_wire(scan::read_state(text.as_bytes())?)
    }

    /// The state of the keys read, checked.
    fn from_wire(w: scan::WireState) -> Result<Self, JsonError> {
        let bad = |why: String| JsonError::State(why);
        let finite = |x: Option<f64>, name: &str| match x {
            Some(x) if x.is_finite() => Ok(x),
            Some(_) => Err(bad(format!("{name}: not finite"))),
            None => Err(bad(format!("{name}: missing"))),
        };
        let vector = |v: Option<[f64; 3]>, name: &str| {
            let v = v.ok_or_else(|| bad(format!("{name}: missing")))?;
            Ok(Vector3::new(
                finite(Some(v[0]), name)?,
                finite(Some(v[1]), name)?,
                finite(Some(v[2]), name)?,
            ))
        };
        let q_ned_from_frd = match (w.quaternion, w.attitude) {
            (Some(q), _) => {
                for x in q {
                    finite(Some(x), "quaternion")?;
                }
                let q = nalgebra::Quaternion::new(q[0], q[1], q[2], q[3]);
                if q.norm() < 1e-6 {
                    return Err(bad("quaternion: zero length".into()));
                }
                UnitQuaternion::from_quaternion(q)
            }
            (None, Some(a)) => {
                let a = vector(Some(a), "attitude")?;
                UnitQuaternion::from_euler_angles(a.x, a.y, a.z)
            }
            (None, None) => return Err(bad("neither quaternion nor attitude".into())),
        };
        let battery = match w.battery {
            Some((voltage, current)) => Some((
                finite(voltage, "battery.voltage")?,
                finite(Some(current), "battery.current")?,
            )),
            None => None,
        };
        Ok(Self {
            timestamp_s: finite(w.timestamp, "timestamp")?,
            gyro_frd_rad_s: vector(w.gyro, "imu.gyro")?,
            accel_frd_m_s2: vector(w.accel_body, "imu.accel_body")?,
            pos_ned_m: vector(w.position, "position")?,
            vel_ned_m_s: vector(w.velocity, "velocity")?,
            q_ned_from_frd,
            battery,
            airspeed_m_s: w
                .airspeed
                .map(|a| finite(Some(a), "airspeed"))
                .transpose()?,
        })
    }

    /// The newest state in a datagram (several lines may have queued): its last line that is
    /// not blank.
    pub fn parse_latest(datagram: &[u8]) -> Result<Self, JsonError> {
        Self::from_wire(scan::read_latest(datagram)?)
    }
}

/// `"name":[a,b,c]`, each number in the shortest form that reads back exactly.
fn write_array(out: &mut String, name: &str, values: &[f64]) {
    use std::fmt::Write;
    let _ = write!(out, "\"{name}\":[");
    for (i, x) in values.iter().enumerate() {
        if i > 0 {
            out.push(',');
        }
        let _ = write!(out, "{x:e}");
    }
    out.push(']');
}

mod scan;

#[cfg(test)]
mod tests;
