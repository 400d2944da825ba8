//! The HIL wire protocol of docs/conventions.md: MAVLink 2 messages between simulator and
//! autopilot, shared by the `sitl` process, the autopilot's sensor links and its embedded simulator.
//!
//! Encoding turns a [`SensorFrame`] and the truth into `HIL_SENSOR`, `HIL_GPS`, `ESC_STATUS` and
//! `HIL_STATE_QUATERNION`; decoding splits a datagram into frames, counting every malformed one.
//! [`json`] is the other protocol a physics may speak: ArduPilot's JSON interface. The framing,
//! the byte transports (feature `transport`) and the truth report are `mavwire`'s, re-exported
//! here.

#[cfg(feature = "transport")]
pub mod control;
pub mod hand;
pub mod json;
mod simulator_end;
pub use hand::HandRequest;
#[cfg(feature = "transport")]
pub use mavwire::transport;
pub use mavwire::{
    Decoded, Encoder, MAX_FRAME, RawMessage, StreamDecoder, TruthReport, checksum, decode,
    decode_checked, decode_into,
};
pub use simulator_end::{STATE_INTERVAL_USEC, SimulatorEnd};

use mavlink::dialects::common::{
    ESC_STATUS_DATA, HIL_ACTUATOR_CONTROLS_DATA, HIL_GPS_DATA, HIL_SENSOR_DATA,
    HIL_STATE_QUATERNION_DATA, HilActuatorControlsFlags, HilSensorUpdatedFlags, MavMessage,
    MavModeFlag,
};
use nalgebra::Vector3;
use sitl_core::sensors::fields;
use sitl_core::sensors::{GpsFix, SensorFrame};
use sitl_core::sim::TruthState;

/// System id the simulator speaks as on the HIL link: the vehicle it simulates.
pub const SIM_SYSTEM_ID: u8 = 1;
/// Component id of the simulator: MAV_COMP_ID_USER1 (0 is the broadcast address, 1 the autopilot).
pub const SIM_COMPONENT_ID: u8 = 25;

/// The simulator's encoder: its system and component ids.
pub fn sim_encoder() -> Encoder {
    Encoder::with_ids(SIM_SYSTEM_ID, SIM_COMPONENT_ID)
}

/// `HIL_SENSOR` from a sensor frame (SI units; pressure in hPa as the message defines).
pub fn hil_sensor(f: &SensorFrame) -> MavMessage {
    let a = f.accel_frd_m_s2.cast::<f32>();
    let g = f.gyro_frd_rad_s.cast::<f32>();
    let m = f.mag_frd_gauss.cast::<f32>();
    MavMessage::HIL_SENSOR(HIL_SENSOR_DATA {
        time_usec: f.time_usec,
        xacc: a.x,
        yacc: a.y,
        zacc: a.z,
        xgyro: g.x,
        ygyro: g.y,
        zgyro: g.z,
        xmag: m.x,
        ymag: m.y,
        zmag: m.z,
        abs_pressure: f.abs_pressure_hpa as f32,
        diff_pressure: 0.0,
        pressure_alt: f.pressure_alt_m as f32,
        temperature: f.temperature_c as f32,
        fields_updated: HilSensorUpdatedFlags::from_bits_truncate(f.fields_updated),
        id: 0,
    })
}

fn clamp_i16(x: f64) -> i16 {
    x.round().clamp(i16::MIN as f64, i16::MAX as f64) as i16
}

/// `HIL_GPS` delivered at `time_usec` (the solution itself is older by the receiver's latency).
pub fn hil_gps(time_usec: u64, fix: &GpsFix) -> MavMessage {
    let v = fix.vel_ned_m_s;
    let ground_speed = v.x.hypot(v.y);
    let cog = if ground_speed > 0.2 {
        (v.y.atan2(v.x).to_degrees().rem_euclid(360.0) * 100.0) as u16
    } else {
        u16::MAX
    };
    MavMessage::HIL_GPS(HIL_GPS_DATA {
        time_usec,
        lat: (fix.position.lat_deg * 1e7).round() as i32,
        lon: (fix.position.lon_deg * 1e7).round() as i32,
        alt: (fix.position.alt_m * 1000.0).round() as i32,
        // HDOP/VDOP × 100; a DOP of about 1 per metre of accuracy.
        eph: (fix.h_acc_m * 100.0).clamp(1.0, 65534.0) as u16,
        epv: (fix.v_acc_m * 100.0).clamp(1.0, 65534.0) as u16,
        vel: (ground_speed * 100.0).clamp(0.0, 65534.0) as u16,
        vn: clamp_i16(v.x * 100.0),
        ve: clamp_i16(v.y * 100.0),
        vd: clamp_i16(v.z * 100.0),
        cog,
        fix_type: fix.fix_type,
        satellites_visible: fix.satellites,
        id: 0,
        yaw: 0, // 0: no GPS heading (a single-antenna receiver)
    })
}

/// `ESC_STATUS` messages (four rotors each, `index` = first rotor) for `rpm` of `count` rotors.
pub fn esc_status(
    time_usec: u64,
    rpm: &[f64],
    voltage_v: f64,
    current_a: f64,
) -> impl Iterator<Item = MavMessage> + '_ {
    let per = current_a / rpm.len().max(1) as f64;
    rpm.chunks(4).enumerate().map(move |(k, chunk)| {
        let mut r = [0i32; 4];
        let mut v = [0f32; 4];
        let mut c = [0f32; 4];
        for (i, x) in chunk.iter().enumerate() {
            r[i] = x.round() as i32;
            v[i] = voltage_v as f32;
            c[i] = per as f32;
        }
        MavMessage::ESC_STATUS(ESC_STATUS_DATA {
            time_usec,
            rpm: r,
            voltage: v,
            current: c,
            index: (4 * k) as u8,
        })
    })
}

/// `HIL_STATE_QUATERNION`: ground truth for logs and scoring (never for the estimator).
pub fn hil_state_quaternion(t: &TruthState) -> MavMessage {
    let q = t.body.q_ned_from_frd.quaternion();
    let w = t.body.rate_frd_rad_s;
    let v = t.body.vel_ned_m_s;
    let airspeed = ((v - t.wind_ned_m_s).norm() * 100.0).clamp(0.0, 65534.0) as u16;
    // Specific force in the body frame, in milli-g.
    let f = t.body.q_ned_from_frd.inverse()
        * (t.accel_ned_m_s2 - nalgebra::Vector3::new(0.0, 0.0, sitl_core::GRAVITY_M_S2));
    let mg = |x: f64| clamp_i16(x / sitl_core::GRAVITY_M_S2 * 1000.0);
    let position = t.position();
    MavMessage::HIL_STATE_QUATERNION(HIL_STATE_QUATERNION_DATA {
        time_usec: t.time_usec,
        attitude_quaternion: [q.w as f32, q.i as f32, q.j as f32, q.k as f32],
        rollspeed: w.x as f32,
        pitchspeed: w.y as f32,
        yawspeed: w.z as f32,
        lat: (position.lat_deg * 1e7).round() as i32,
        lon: (position.lon_deg * 1e7).round() as i32,
        alt: (position.alt_m * 1000.0).round() as i32,
        vx: clamp_i16(v.x * 100.0),
        vy: clamp_i16(v.y * 100.0),
        vz: clamp_i16(v.z * 100.0),
        ind_airspeed: airspeed,
        true_airspeed: airspeed,
        xacc: mg(f.x),
        yacc: mg(f.y),
        zacc: mg(f.z),
    })
}

/// Actuator commands as the autopilot sent them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ActuatorCommand {
    /// The sensor frame this answers (`time_usec` echo).
    pub time_usec: u64,
    /// Normalised rotor commands, [0, 1] expected (the simulator clamps and counts).
    pub controls: [f64; 16],
    /// `mode` has MAV_MODE_FLAG_SAFETY_ARMED.
    pub armed: bool,
    /// What a calibration asks of the person holding the vehicle (a `CAL_POSE` before the
    /// `HIL_ACTUATOR_CONTROLS`; none: [`HandRequest::None`]).
    pub hand: HandRequest,
}

/// An actuator command from `HIL_ACTUATOR_CONTROLS`.
pub fn actuator_command(m: &HIL_ACTUATOR_CONTROLS_DATA) -> ActuatorCommand {
    let mut controls = [0.0; 16];
    for (c, x) in controls.iter_mut().zip(m.controls) {
        *c = x as f64;
    }
    ActuatorCommand {
        time_usec: m.time_usec,
        controls,
        armed: m.mode.contains(MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED),
        hand: HandRequest::None,
    }
}

impl ActuatorCommand {
    /// The command the simulator reads from the `HIL_ACTUATOR_CONTROLS` an autopilot sends for
    /// `controls` (quantised to the message's f32), without the bytes in between.
    pub fn as_sent(time_usec: u64, controls: &[f64], armed: bool) -> Self {
        actuator_command(&actuator_controls_data(time_usec, controls, armed))
    }

    /// The same command with a calibration's request to the hand.
    pub fn with_hand(self, hand: HandRequest) -> Self {
        Self { hand, ..self }
    }

    /// The messages that carry it: the hand's request if there is one, then
    /// `HIL_ACTUATOR_CONTROLS` (last: it closes the answer).
    pub fn messages(&self) -> impl Iterator<Item = MavMessage> {
        let controls = actuator_controls(self.time_usec, &self.controls, self.armed);
        self.hand
            .message()
            .into_iter()
            .chain(std::iter::once(controls))
    }
}

/// Accumulates the sensor frames of one exchange interval: IMU averaged (as a flight board's
/// driver integrates), slower sensors forwarded when fresh.
pub struct Accumulator {
    frame: SensorFrame,
    n: u32,
}

impl Accumulator {
    /// Starts from a first frame (before any exchange).
    pub fn new(first: &SensorFrame) -> Self {
        Self {
            frame: first.clone(),
            n: 0,
        }
    }

    /// Begins a new exchange interval.
    pub fn start(&mut self) {
        self.n = 0;
        self.frame.fields_updated = 0;
        self.frame.gps = None;
        self.frame.rotor_rpm = None;
    }

    /// Adds one physics step's sensor frame.
    pub fn add(&mut self, f: &SensorFrame) {
        let a = &mut self.frame;
        if f.fields_updated & fields::ACCEL != 0 {
            let k = self.n as f64;
            a.accel_frd_m_s2 = (a.accel_frd_m_s2 * k + f.accel_frd_m_s2) / (k + 1.0);
            a.gyro_frd_rad_s = (a.gyro_frd_rad_s * k + f.gyro_frd_rad_s) / (k + 1.0);
            self.n += 1;
        }
        if f.fields_updated & fields::MAG != 0 {
            a.mag_frd_gauss = f.mag_frd_gauss;
        }
        if f.fields_updated & fields::BARO != 0 {
            a.abs_pressure_hpa = f.abs_pressure_hpa;
            a.pressure_alt_m = f.pressure_alt_m;
            a.temperature_c = f.temperature_c;
        }
        a.fields_updated |= f.fields_updated;
        if f.gps.is_some() {
            a.gps = f.gps;
        }
        if f.rotor_rpm.is_some() {
            a.rotor_rpm = f.rotor_rpm;
        }
        a.time_usec = f.time_usec;
    }

    /// The interval's averaged accelerometer and gyro, to add what is drawn once per interval.
    pub fn imu_mut(&mut self) -> (&mut Vector3<f64>, &mut Vector3<f64>) {
        (
            &mut self.frame.accel_frd_m_s2,
            &mut self.frame.gyro_frd_rad_s,
        )
    }

    /// The frame of the interval so far.
    pub fn frame(&self) -> &SensorFrame {
        &self.frame
    }
}

/// The messages of one exchange, in order, to `emit`: `HIL_GPS` and `ESC_STATUS` when fresh,
/// `HIL_STATE_QUATERNION` when `send_state` (ground truth at its own rate), and `HIL_SENSOR`
/// last. `HIL_SENSOR` closes the frame: an autopilot reading the stream steps on it with
/// everything that came before it. Encoded to bytes for a link, or folded straight into a
/// [`SensorUpdate`] in-process: the same messages, so the same quantisation either way.
pub fn exchange_messages(
    f: &SensorFrame,
    truth: impl FnOnce() -> TruthState,
    rotors: usize,
    send_state: bool,
    mut emit: impl FnMut(&MavMessage),
) {
    if let Some(fix) = &f.gps {
        emit(&hil_gps(f.time_usec, fix));
    }
    // The truth is worked out only for the messages that carry it.
    let truth = (f.rotor_rpm.is_some() || send_state).then(truth);
    if let (Some(rpm), Some(t)) = (&f.rotor_rpm, &truth) {
        let rpm = &rpm[..rotors.min(rpm.len())];
        for m in esc_status(f.time_usec, rpm, t.battery_voltage_v, t.battery_current_a) {
            emit(&m);
        }
    }
    if let (true, Some(t)) = (send_state, &truth) {
        emit(&hil_state_quaternion(t));
    }
    emit(&hil_sensor(f));
}

/// Encodes one exchange ([`exchange_messages`]) to MAVLink 2 bytes.
pub fn encode_exchange(
    encoder: &mut Encoder,
    out: &mut Vec<u8>,
    f: &SensorFrame,
    truth: impl FnOnce() -> TruthState,
    rotors: usize,
    send_state: bool,
) {
    exchange_messages(f, truth, rotors, send_state, |m| encoder.push(out, m));
}

/// `HIL_ACTUATOR_CONTROLS` answering the sensor frame of `time_usec` (the autopilot's side).
pub fn actuator_controls(time_usec: u64, controls: &[f64], armed: bool) -> MavMessage {
    MavMessage::HIL_ACTUATOR_CONTROLS(actuator_controls_data(time_usec, controls, armed))
}

/// The payload of [`actuator_controls`].
fn actuator_controls_data(
    time_usec: u64,
    controls: &[f64],
    armed: bool,
) -> HIL_ACTUATOR_CONTROLS_DATA {
    let mut c = [0f32; 16];
    for (o, x) in c.iter_mut().zip(controls) {
        *o = *x as f32;
    }
    HIL_ACTUATOR_CONTROLS_DATA {
        time_usec,
        flags: HilActuatorControlsFlags::HIL_ACTUATOR_CONTROLS_FLAGS_LOCKSTEP,
        controls: c,
        mode: if armed {
            MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED
        } else {
            MavModeFlag::empty()
        },
    }
}

/// A GPS solution as the autopilot reads it from `HIL_GPS`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GpsReport {
    /// Fix type.
    pub fix_type: u8,
    /// Latitude (deg).
    pub lat_deg: f64,
    /// Longitude (deg).
    pub lon_deg: f64,
    /// Altitude (m AMSL).
    pub alt_m: f64,
    /// Velocity NED (m/s).
    pub vel_ned_m_s: Vector3<f64>,
    /// Horizontal accuracy (m): this link sends `eph` as the accuracy in cm.
    pub h_acc_m: f64,
    /// Satellites visible.
    pub satellites: u8,
}

/// What the autopilot has taken from the simulator's messages since the last sensor frame.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SensorUpdate {
    /// The sensor frame's time (µs): the autopilot's clock in SITL.
    pub time_usec: Option<u64>,
    /// Gyro, FRD (rad/s), when fresh.
    pub gyro_frd: Option<Vector3<f64>>,
    /// Specific force, FRD (m/s²), when fresh.
    pub accel_frd: Option<Vector3<f64>>,
    /// Magnetometer, FRD (gauss), when fresh.
    pub mag_frd: Option<Vector3<f64>>,
    /// Pressure altitude (m), when fresh.
    pub pressure_alt_m: Option<f64>,
    /// A GPS solution, when one arrived.
    pub gps: Option<GpsReport>,
    /// Rotor speeds (rad/s) by rotor, when reported.
    pub rotor_speed_rad_s: Option<[f64; 16]>,
    /// Battery voltage (V), from `ESC_STATUS`.
    pub battery_v: Option<f64>,
    /// Current per ESC (A), from `ESC_STATUS`, by rotor (their sum is the pack's current).
    pub esc_current_a: Option<[f64; 16]>,
    /// Ground truth from `HIL_STATE_QUATERNION` (for logs and scoring, never the estimator).
    pub truth: Option<TruthReport>,
}

impl SensorUpdate {
    /// Folds one message in; returns true for `HIL_SENSOR` (a new sensor frame).
    pub fn absorb(&mut self, msg: &MavMessage) -> bool {
        match msg {
            MavMessage::HIL_SENSOR(s) => {
                let f = s.fields_updated.bits();
                self.time_usec = Some(s.time_usec);
                let v = |x: f32, y: f32, z: f32| Vector3::new(x as f64, y as f64, z as f64);
                if f & fields::ACCEL != 0 {
                    self.accel_frd = Some(v(s.xacc, s.yacc, s.zacc));
                    self.gyro_frd = Some(v(s.xgyro, s.ygyro, s.zgyro));
                }
                if f & fields::MAG != 0 {
                    self.mag_frd = Some(v(s.xmag, s.ymag, s.zmag));
                }
                if f & fields::PRESSURE_ALT != 0 {
                    self.pressure_alt_m = Some(s.pressure_alt as f64);
                }
                true
            }
            MavMessage::HIL_GPS(g) => {
                self.gps = Some(GpsReport {
                    fix_type: g.fix_type,
                    lat_deg: g.lat as f64 * 1e-7,
                    lon_deg: g.lon as f64 * 1e-7,
                    alt_m: g.alt as f64 * 1e-3,
                    vel_ned_m_s: Vector3::new(g.vn as f64, g.ve as f64, g.vd as f64) * 0.01,
                    h_acc_m: g.eph as f64 * 0.01,
                    satellites: g.satellites_visible,
                });
                false
            }
            MavMessage::ESC_STATUS(e) => {
                let speeds = self.rotor_speed_rad_s.get_or_insert([0.0; 16]);
                for (k, rpm) in e.rpm.iter().enumerate() {
                    if let Some(slot) = speeds.get_mut(e.index as usize + k) {
                        *slot = *rpm as f64 * std::f64::consts::TAU / 60.0;
                    }
                }
                let currents = self.esc_current_a.get_or_insert([0.0; 16]);
                for (k, i) in e.current.iter().enumerate() {
                    if let Some(slot) = currents.get_mut(e.index as usize + k) {
                        // A NaN or negative report counts as nothing drawn.
                        *slot = if i.is_finite() {
                            (*i as f64).max(0.0)
                        } else {
                            0.0
                        };
                    }
                }
                self.battery_v = Some(e.voltage[0] as f64).filter(|v| v.is_finite());
                false
            }
            MavMessage::HIL_STATE_QUATERNION(q) => {
                self.truth = Some(TruthReport::from(q));
                false
            }
            _ => false,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn actuators(t: u64) -> MavMessage {
        MavMessage::HIL_ACTUATOR_CONTROLS(HIL_ACTUATOR_CONTROLS_DATA {
            time_usec: t,
            flags: HilActuatorControlsFlags::HIL_ACTUATOR_CONTROLS_FLAGS_LOCKSTEP,
            controls: [0.5; 16],
            mode: MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED,
        })
    }

    #[test]
    fn frames_round_trip_and_junk_is_counted() {
        let mut enc = sim_encoder();
        let mut buf = Vec::new();
        enc.push(&mut buf, &actuators(10));
        enc.push(&mut buf, &actuators(20));
        let d = decode(&buf);
        assert_eq!(d.malformed, 0);
        assert_eq!(d.messages.len(), 2);
        let MavMessage::HIL_ACTUATOR_CONTROLS(m) = &d.messages[1].1 else {
            panic!()
        };
        let cmd = actuator_command(m);
        assert_eq!((cmd.time_usec, cmd.armed, cmd.controls[3]), (20, true, 0.5));

        // Junk before, a corrupted CRC in the middle, a truncated frame at the end.
        let mut bad = b"hello".to_vec();
        let mut one = Vec::new();
        enc.push(&mut one, &actuators(30));
        bad.extend_from_slice(&one);
        let mut corrupt = one.clone();
        let n = corrupt.len();
        corrupt[n - 1] ^= 0xFF;
        bad.extend_from_slice(&corrupt);
        bad.extend_from_slice(&one[..n / 2]);
        let d = decode(&bad);
        assert_eq!(d.messages.len(), 1);
        assert_eq!(d.malformed, 3, "junk, bad CRC, truncation");
    }

    /// A reader of the stream that steps on `HIL_SENSOR` has the same exchange's GPS fix and
    /// rotor speeds by then: `HIL_SENSOR` comes last.
    #[test]
    fn hil_sensor_closes_the_exchange() {
        let airframe = sitl_core::Airframe::load(std::path::Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../params/airframes/quad_x.toml"
        )))
        .unwrap();
        let mut sim = sitl_core::sim::Simulator::new(
            &airframe,
            sitl_core::sim::SimConfig::default(),
            sitl_core::BodyState::default(),
        )
        .unwrap();
        let frame = loop {
            sim.step(&[0.0; 4]);
            let f = sim.sample_sensors();
            if f.gps.is_some() && f.rotor_rpm.is_some() {
                break f.clone();
            }
        };
        let mut bytes = Vec::new();
        encode_exchange(
            &mut sim_encoder(),
            &mut bytes,
            &frame,
            || sim.truth(),
            4,
            true,
        );
        let d = decode(&bytes);
        assert_eq!(d.malformed, 0);
        assert!(matches!(
            d.messages.last(),
            Some((_, MavMessage::HIL_SENSOR(_)))
        ));
        let mut update = SensorUpdate::default();
        let closed: Vec<bool> = d.messages.iter().map(|(_, m)| update.absorb(m)).collect();
        assert_eq!(closed.iter().filter(|c| **c).count(), 1);
        assert_eq!(update.time_usec, Some(frame.time_usec));
        assert!(update.gps.is_some() && update.rotor_speed_rad_s.is_some());
        assert!(update.truth.is_some());
    }

    /// Frames split anywhere across reads come out whole; junk and a bad CRC count once each
    /// and never take the next good frame with them.
    #[test]
    fn a_stream_is_split_into_frames_wherever_the_reads_fall() {
        let mut enc = sim_encoder();
        let mut stream = Vec::new();
        enc.push(&mut stream, &actuators(1));
        stream.extend_from_slice(b"\x00\x13junk");
        let mut corrupt = Vec::new();
        enc.push(&mut corrupt, &actuators(2));
        let n = corrupt.len();
        corrupt[n - 2] ^= 0x55;
        stream.extend_from_slice(&corrupt);
        enc.push(&mut stream, &actuators(3));
        enc.push(&mut stream, &actuators(4));
        for chunk in [1, 3, 7, 64, stream.len()] {
            let mut d = StreamDecoder::default();
            let mut out = Decoded::default();
            for piece in stream.chunks(chunk) {
                d.push(piece, &mut out);
            }
            let times: Vec<u64> = out
                .messages
                .iter()
                .filter_map(|(_, m)| match m {
                    MavMessage::HIL_ACTUATOR_CONTROLS(c) => Some(c.time_usec),
                    _ => None,
                })
                .collect();
            assert_eq!(times, [1, 3, 4], "reads of {chunk} bytes");
            assert_eq!(out.malformed, 2, "reads of {chunk} bytes");
            assert_eq!(d.pending(), 0);
        }
    }

    #[test]
    fn esc_status_splits_rotors_in_fours() {
        let rpm: Vec<f64> = (0..12).map(|i| 1000.0 + i as f64).collect();
        let msgs: Vec<_> = esc_status(5, &rpm, 22.0, 24.0).collect();
        assert_eq!(msgs.len(), 3);
        let MavMessage::ESC_STATUS(m) = &msgs[2] else {
            panic!()
        };
        assert_eq!((m.index, m.rpm[3]), (8, 1011));
        assert!((m.current[0] - 2.0).abs() < 1e-6);
        // Read back: the pack's voltage, and the currents adding up to the pack's.
        let mut u = SensorUpdate::default();
        for m in &msgs {
            assert!(!u.absorb(m));
        }
        let currents = u.esc_current_a.unwrap();
        assert!((currents.iter().sum::<f64>() - 24.0).abs() < 1e-4);
        assert_eq!(u.battery_v, Some(22.0));
    }
}
