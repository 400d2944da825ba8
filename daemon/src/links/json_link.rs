//! ArduPilot's JSON physics interface as a sensor link (`--source json://127.0.0.1:9002`), so
//! that a physics written for ArduPilot's SITL (`--model JSON`) flies this autopilot: the link
//! plays ArduPilot's side ([`hil::json`]). Each answer of the vehicle goes out as a servo
//! packet; the physics steps and replies with its state; the state is made into the same HIL
//! messages every other link carries (their quantisation included) and folded into a typed
//! frame, so the flight loop does not know the difference.
//!
//! What the state does not carry is made here, as ArduPilot's SITL makes it: the magnetometer
//! (the site's field seen through the attitude), the barometer (ISA pressure at the height) and
//! the GPS (position and velocity with latency), by the simulator's own sensor models at the
//! preset asked for; the IMU is the physics' own with the preset's noise and bias on it (as
//! ArduPilot's SITL adds its `SIM_ACC_RND`, `SIM_GYR_RND`; with the ideal preset it stays
//! exact).
//! The truth (`HIL_STATE_QUATERNION`, for logs and scoring) is the state itself.
//!
//! The autopilot steps at its own rate ([`FRAME_RATE_HZ`]), whatever the physics' rate, as
//! ArduPilot's loop does: a physics faster than that (ArduPilot's usual 1 kHz) steps again under
//! the command the link holds, answered at once with the same servo outputs in a new packet,
//! and the IMU reaches the autopilot as the average of the states between two of its steps.

use super::SensorLink;
use super::frames::{Received, close};
use flight_core::math::geo::{LatLonAlt, LocalFrame};
use hil::json::{PhysicsState, ServoPacket, pwm_from_command};
use hil::{ActuatorCommand, STATE_INTERVAL_USEC, SensorUpdate};
use nalgebra::Vector3;
use sitl_core::body::BodyState;
use sitl_core::environment::isa;
use sitl_core::sensors::{EarthField, SensorConfig, SensorPreset, SensorSuite, Truth};
use sitl_core::sim::TruthState;
use std::io;
use std::net::{SocketAddr, UdpSocket};
use std::time::{Duration, Instant};

/// Without a reply this long, the last servo packet goes out again (ArduPilot does the same:
/// the physics may have started after it, or lost a datagram).
const RESEND_AFTER: Duration = Duration::from_secs(1);

/// A state this much older than the last is a physics started again, not a late datagram (s).
const RESTART_BACK_S: f64 = 0.5;

/// The rate the autopilot steps at on this link, told to the physics as the servo packets'
/// `frame_rate` (Hz): the embedded simulator's exchange rate.
const FRAME_RATE_HZ: u16 = 250;

/// The IMU of the states since the autopilot last stepped, summed.
#[derive(Debug, Default)]
struct ImuSum {
    gyro_frd_rad_s: Vector3<f64>,
    accel_frd_m_s2: Vector3<f64>,
    states: u32,
}

/// The link to a JSON physics.
pub struct JsonLink {
    socket: UdpSocket,
    physics: SocketAddr,
    /// Servo channel (0-based) of each rotor.
    channels: Vec<usize>,
    frame_count: u32,
    packet: Vec<u8>,
    sent_at: Option<Instant>,
    sensors: SensorSuite,
    /// The local frame at home: the truth's geodetic position.
    home: LocalFrame,
    last_timestamp_s: Option<f64>,
    /// The state time of the last frame the autopilot stepped on (s).
    last_frame_s: Option<f64>,
    imu: ImuSum,
    next_truth_usec: u64,
    buf: Vec<u8>,
    /// The socket's read timeout as last set.
    read_timeout: Option<Duration>,
    /// What the states so far have told the autopilot's side.
    update: SensorUpdate,
    /// States dropped as older than the last (a resend crossing a reply).
    stale: u64,
}

impl JsonLink {
    /// A link to the physics at `physics`, its rotors on servo `channels` (0-based, one per
    /// rotor), the sensors it lacks made at `preset` from `seed`, its origin at `home`.
    pub fn connect(
        physics: SocketAddr,
        channels: Vec<usize>,
        preset: SensorPreset,
        seed: u64,
        home: LatLonAlt,
    ) -> io::Result<Self> {
        let bind: SocketAddr = if physics.is_ipv4() {
            ([0, 0, 0, 0], 0).into()
        } else {
            (std::net::Ipv6Addr::UNSPECIFIED, 0).into()
        };
        let socket = UdpSocket::bind(bind)?;
        // Connected: the kernel takes datagrams from the physics alone, and each exchange's
        // two system calls skip the address (`send`, `recv`).
        socket.connect(physics)?;
        let sensors = SensorSuite::new(
            SensorConfig::preset(preset),
            EarthField::default(),
            home,
            Vector3::zeros(),
            seed,
        );
        Ok(Self {
            socket,
            physics,
            channels,
            frame_count: 0,
            packet: Vec::with_capacity(72),
            sent_at: None,
            sensors,
            home: LocalFrame::new(home),
            last_timestamp_s: None,
            last_frame_s: None,
            imu: ImuSum::default(),
            next_truth_usec: 0,
            buf: vec![0; 65_536],
            read_timeout: None,
            update: SensorUpdate::default(),
            stale: 0,
        })
    }

    /// The servo packet for these rotor commands (disarmed: every channel at 1000 µs).
    fn servo_packet(&mut self, controls: &[f64], armed: bool) {
        let n = self.channels.iter().max().map_or(0, |&c| c + 1).max(16);
        self.frame_count = self.frame_count.wrapping_add(1);
        let mut packet = ServoPacket::new(
            FRAME_RATE_HZ,
            self.frame_count,
            &[hil::json::PWM_MIN; hil::json::MAX_CHANNELS][..n],
        );
        for (rotor, &channel) in self.channels.iter().enumerate() {
            let c = if armed {
                controls.get(rotor).copied().unwrap_or(0.0)
            } else {
                0.0
            };
            packet.pwm_us[channel] = pwm_from_command(c);
        }
        self.packet.clear();
        packet.encode(&mut self.packet);
    }

    fn send_packet(&mut self) -> io::Result<()> {
        self.sent_at = Some(Instant::now());
        match self.socket.send(&self.packet) {
            // A physics not (yet) listening, told by an earlier packet's ICMP port unreachable
            // (a connected socket reports it at its next call): the packet goes out again
            // after RESEND_AFTER.
            Err(e) if e.kind() == io::ErrorKind::ConnectionRefused => Ok(()),
            r => r.map(|_| ()),
        }
    }

    /// The held servo outputs again in a new packet: the physics steps once more under them.
    fn repeat_packet(&mut self) -> io::Result<()> {
        if self.packet.len() < 8 {
            self.servo_packet(&[], false);
        }
        self.frame_count = self.frame_count.wrapping_add(1);
        // The frame count's place in the packet (`frame_count: u32` after two u16s).
        self.packet[4..8].copy_from_slice(&self.frame_count.to_le_bytes());
        self.send_packet()
    }

    /// Whether the autopilot steps on the state at `t_s` (`previous_s`: the state before it):
    /// the first, one a step's period or more (less half the physics' own step) after the last
    /// stepped on, or one from a physics started again.
    fn step_due(&self, t_s: f64, previous_s: Option<f64>) -> bool {
        let Some(last) = self.last_frame_s else {
            return true;
        };
        let physics_step = previous_s.map_or(0.0, |p| (t_s - p).max(0.0));
        t_s < last || t_s - last >= 1.0 / f64::from(FRAME_RATE_HZ) - 0.5 * physics_step
    }

    /// The frame of one state, folded from its HIL messages: the sensor frame (the physics'
    /// IMU, the made sensors), a GPS solution when one is delivered, the truth at 50 Hz.
    /// The IMU is the average of the states since the last frame (their sum taken here).
    fn frame(&mut self, s: &PhysicsState, into: &mut Received) {
        let time_usec = (s.timestamp_s.max(0.0) * 1e6).round() as u64;
        let gravity = Vector3::new(0.0, 0.0, sitl_core::GRAVITY_M_S2);
        let imu = std::mem::take(&mut self.imu);
        let n = f64::from(imu.states.max(1));
        let (gyro, accel) = (imu.gyro_frd_rad_s / n, imu.accel_frd_m_s2 / n);
        let accel_ned = s.q_ned_from_frd * s.accel_frd_m_s2 + gravity;
        let truth = Truth {
            time_usec,
            pos_ned_m: s.pos_ned_m,
            vel_ned_m_s: s.vel_ned_m_s,
            // The IMU models take the specific force back out of it: the average's.
            accel_ned_m_s2: s.q_ned_from_frd * accel + gravity,
            q_ned_from_frd: s.q_ned_from_frd,
            rate_frd_rad_s: gyro,
            ang_accel_frd_rad_s2: Vector3::zeros(),
            air: isa(self.home.origin().alt_m - s.pos_ned_m.z),
            rotor_speed_rad_s: &[],
            rotor_max_speed_rad_s: &[],
        };
        // The IMU models see the physics' specific force and rate (the acceleration is made
        // from the specific force, so they give it back) and add their noise and bias.
        let frame = self.sensors.sample(&truth);
        if let Some(fix) = &frame.gps {
            self.update.absorb(&hil::hil_gps(time_usec, fix));
        }
        if time_usec >= self.next_truth_usec {
            self.next_truth_usec = time_usec + STATE_INTERVAL_USEC;
            let (voltage, current) = s.battery.unwrap_or((0.0, 0.0));
            let t = TruthState {
                time_usec,
                body: BodyState {
                    pos_ned_m: s.pos_ned_m,
                    vel_ned_m_s: s.vel_ned_m_s,
                    q_ned_from_frd: s.q_ned_from_frd,
                    rate_frd_rad_s: s.gyro_frd_rad_s,
                },
                accel_ned_m_s2: accel_ned,
                home: self.home,
                wind_ned_m_s: Vector3::zeros(),
                landed: false,
                battery_voltage_v: voltage,
                battery_current_a: current,
                battery_remaining: 0.0,
            };
            self.update.absorb(&hil::hil_state_quaternion(&t));
        }
        // The sensor frame last: it is what makes the vehicle step.
        self.update.absorb(&hil::hil_sensor(frame));
        into.frames.extend(close(&mut self.update));
    }
}

impl SensorLink for JsonLink {
    /// Waits up to `timeout` for the physics' next state; the first call starts the exchange
    /// with a packet of motors off, and a packet unanswered for a second goes out again.
    fn receive(&mut self, timeout: Duration, into: &mut Received) -> io::Result<bool> {
        if self.sent_at.is_none_or(|t| t.elapsed() >= RESEND_AFTER) {
            if self.packet.is_empty() {
                self.servo_packet(&[], false);
            }
            self.send_packet()?;
        }
        // The read timeout is the call's (set only when it changes: one system call fewer per
        // exchange), the deadline checked after each datagram: a call in which the physics
        // answers and then falls silent may last up to twice `timeout`.
        let deadline = Instant::now() + timeout;
        let wait = Some(timeout.max(Duration::from_micros(1)));
        if self.read_timeout != wait {
            self.socket.set_read_timeout(wait)?;
            self.read_timeout = wait;
        }
        let mut first = true;
        loop {
            if !std::mem::take(&mut first) && Instant::now() > deadline {
                return Ok(false);
            }
            let n = match self.socket.recv(&mut self.buf) {
                Ok(n) => n,
                Err(e)
                    if matches!(
                        e.kind(),
                        io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut
                    ) =>
                {
                    return Ok(false);
                }
                // A physics not (yet) listening: ICMP port unreachable. The packet goes out
                // again after RESEND_AFTER.
                Err(e) if e.kind() == io::ErrorKind::ConnectionRefused => return Ok(false),
                Err(e) => return Err(e),
            };
            let state = match PhysicsState::parse_latest(&self.buf[..n]) {
                Ok(s) => s,
                Err(e) => {
                    tracing::debug!("{e}");
                    into.malformed += 1;
                    continue;
                }
            };
            let previous = self.last_timestamp_s;
            if let Some(last) = previous
                && state.timestamp_s <= last
                && state.timestamp_s > last - RESTART_BACK_S
            {
                self.stale += 1;
                continue;
            }
            self.last_timestamp_s = Some(state.timestamp_s);
            if previous.is_some_and(|p| state.timestamp_s < p) {
                // A physics started again: nothing from before it is averaged in.
                self.imu = ImuSum::default();
            }
            self.imu.gyro_frd_rad_s += state.gyro_frd_rad_s;
            self.imu.accel_frd_m_s2 += state.accel_frd_m_s2;
            self.imu.states += 1;
            if !self.step_due(state.timestamp_s, previous) {
                // Between the autopilot's steps: the physics steps on under the held command.
                self.repeat_packet()?;
                continue;
            }
            self.last_frame_s = Some(state.timestamp_s);
            self.frame(&state, into);
            return Ok(true);
        }
    }

    /// Sends the vehicle's command as the next servo packet.
    fn send(&mut self, cmd: &ActuatorCommand) -> io::Result<()> {
        self.servo_packet(&cmd.controls, cmd.armed);
        self.send_packet()
    }

    fn describe(&self) -> String {
        format!("json://{}", self.physics)
    }

    /// Lockstep: the physics waits for each packet, so silence is a paused world.
    fn silence_clock_s(&self) -> Option<f64> {
        None
    }
}

impl Drop for JsonLink {
    fn drop(&mut self) {
        if self.stale > 0 {
            tracing::info!(
                stale = self.stale,
                "JSON states older than the last, dropped"
            );
        }
    }
}

#[cfg(test)]
mod tests {
    //! The link against a physics played by the test: the packets it sends, the messages it
    //! makes of the replies, what it drops.
    #![allow(clippy::unwrap_used)]
    use super::*;
    use hil::json::command_from_pwm;

    fn physics() -> UdpSocket {
        let s = UdpSocket::bind("127.0.0.1:0").unwrap();
        s.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
        s
    }

    /// A link to `physics` (ideal sensors, seed 1, home at the origin), rotor k on servo
    /// channel `channels[k]`.
    fn link_to(physics: SocketAddr, channels: Vec<usize>) -> JsonLink {
        JsonLink::connect(
            physics,
            channels,
            SensorPreset::Ideal,
            1,
            LatLonAlt::default(),
        )
        .unwrap()
    }

    /// A physics and a link to it (rotor k on servo channel `channels[k]`) whose first receive
    /// has started the exchange: the physics holds the first servo packet and its sender.
    fn started(channels: Vec<usize>) -> (UdpSocket, JsonLink, Received, ServoPacket, SocketAddr) {
        let physics = physics();
        let mut link = link_to(physics.local_addr().unwrap(), channels);
        let mut into = Received::default();
        // The first receive starts the exchange: motors off.
        assert!(!link.receive(Duration::from_millis(20), &mut into).unwrap());
        let (first, from) = packet(&physics);
        (physics, link, into, first, from)
    }

    fn packet(physics: &UdpSocket) -> (ServoPacket, SocketAddr) {
        let mut buf = [0u8; 256];
        let (n, from) = physics.recv_from(&mut buf).unwrap();
        (ServoPacket::decode(&buf[..n]).unwrap(), from)
    }

    fn reply(t: f64, z: f64) -> String {
        turning(t, z, 0.1)
    }

    /// A state turning at `r` rad/s about the body's z axis.
    fn turning(t: f64, z: f64, r: f64) -> String {
        // ArduPilot's documented form: Euler angles, extra keys.
        format!(
            "\n{{\"timestamp\": {t}, \"imu\": {{\"gyro\": [0, 0, {r}], \"accel_body\": [0, 0, -9.80665]}}, \"position\": [0, 0, {z}], \"velocity\": [0, 0, 0], \"attitude\": [0, 0, 0.5], \"airspeed\": 0}}\n"
        )
    }

    #[test]
    fn a_physics_not_listening_is_waited_for_not_an_error() {
        let port = physics().local_addr().unwrap(); // bound, then closed: nothing listens
        let mut link = link_to(port, vec![0, 1, 2, 3]);
        let mut into = Received::default();
        let answer = ActuatorCommand::as_sent(1000, &[0.5; 4], true);
        for _ in 0..3 {
            // The port unreachable each packet brings back is reported at the next call.
            assert!(!link.receive(Duration::from_millis(20), &mut into).unwrap());
            link.send(&answer).unwrap();
            link.send(&answer).unwrap();
        }
    }

    #[test]
    fn a_faster_physics_steps_on_under_the_held_command_and_its_imu_is_averaged() {
        let (physics, mut link, mut into, _, from) = started(vec![0, 1, 2, 3]);
        // A 1 kHz physics: the first state is stepped on.
        physics
            .send_to(turning(0.001, 0.0, 0.0).as_bytes(), from)
            .unwrap();
        assert!(link.receive(Duration::from_secs(5), &mut into).unwrap());
        let answer = ActuatorCommand::as_sent(1000, &[0.5, 0.5, 0.6, 0.6], true);
        link.send(&answer).unwrap();
        let (held, _) = packet(&physics);
        into.frames.clear();
        // The next three states are not: each is answered at once with the held outputs in a
        // new packet, and no frame reaches the autopilot.
        for (k, t) in [0.002, 0.003, 0.004].into_iter().enumerate() {
            let r = 0.1 * (k + 1) as f64;
            physics
                .send_to(turning(t, 0.0, r).as_bytes(), from)
                .unwrap();
            assert!(
                !link.receive(Duration::from_millis(50), &mut into).unwrap(),
                "{t}"
            );
            let (again, _) = packet(&physics);
            assert_eq!(again.frame_count, held.frame_count + k as u32 + 1);
            assert_eq!(again.pwm(), held.pwm());
        }
        assert!(into.frames.is_empty());
        // The fourth, 4 ms on, is: its IMU the average of the four.
        physics
            .send_to(turning(0.005, 0.0, 0.4).as_bytes(), from)
            .unwrap();
        assert!(link.receive(Duration::from_secs(5), &mut into).unwrap());
        let s = into.frames.pop().unwrap().sample;
        assert_eq!(s.t_usec, 5000);
        assert!((s.gyro.z - 0.25).abs() < 1e-6, "{}", s.gyro.z);
        assert!((s.accel.z + 9.80665).abs() < 1e-5, "{}", s.accel.z);
    }

    #[test]
    fn plays_ardupilots_side_of_the_json_interface() {
        // Rotors 1–4 on servo channels 3, 1, 4, 2.
        let (physics, mut link, mut into, first, from) = started(vec![2, 0, 3, 1]);
        assert_eq!((first.frame_count, first.frame_rate), (1, FRAME_RATE_HZ));
        assert!(first.pwm().iter().all(|&p| p == 1000), "{:?}", first.pwm());

        physics
            .send_to(reply(0.004, -2.0).as_bytes(), from)
            .unwrap();
        assert!(link.receive(Duration::from_secs(5), &mut into).unwrap());
        assert_eq!(into.frames.len(), 1);
        let f = into.frames.pop().unwrap();
        assert!(f.truth.is_some(), "the truth comes with the first frame");
        let s = f.sample;
        assert_eq!(s.t_usec, 4000);
        // The physics' own IMU (the ideal preset adds no noise).
        assert!(
            (s.accel.z + 9.80665).abs() < 1e-5 && (s.gyro.z - 0.1).abs() < 1e-6,
            "{s:?}"
        );
        // The barometer it made: 2 m above home.
        let baro = s.baro_alt_m.unwrap();
        assert!((baro - (488.0 + 2.0)).abs() < 0.5, "{baro}");
        // The magnetometer it made sees the 0.5 rad yaw: the site's field turned.
        let field = EarthField::default().ned();
        let yaw = nalgebra::UnitQuaternion::from_euler_angles(0.0, 0.0, 0.5);
        let expected = yaw.inverse_transform_vector(&field);
        let mag = s.mag.unwrap();
        assert!((mag - expected).norm() < 1e-3, "{mag} vs {expected}");

        // The answer goes out as the next packet, each rotor on its channel.
        let answer = ActuatorCommand::as_sent(4000, &[0.1, 0.2, 0.3, 0.4], true);
        link.send(&answer).unwrap();
        let (second, _) = packet(&physics);
        assert_eq!(second.frame_count, 2);
        let commands: Vec<f64> = [2, 0, 3, 1]
            .iter()
            .map(|&c| command_from_pwm(second.pwm()[c]))
            .collect();
        assert_eq!(commands, [0.1, 0.2, 0.3, 0.4]);

        // Dropped: a reply from elsewhere (by the kernel: the socket is connected), garbage, a
        // state older than the last; the newer one behind them is taken.
        into.frames.clear();
        let stranger = UdpSocket::bind("127.0.0.1:0").unwrap();
        stranger
            .send_to(reply(0.008, 0.0).as_bytes(), from)
            .unwrap();
        physics.send_to(b"{\"timestamp\": ", from).unwrap();
        physics.send_to(reply(0.002, 0.0).as_bytes(), from).unwrap();
        physics
            .send_to(reply(0.008, -2.1).as_bytes(), from)
            .unwrap();
        assert!(link.receive(Duration::from_secs(5), &mut into).unwrap());
        assert_eq!(into.malformed, 1);
        assert_eq!(link.stale, 1);
        assert_eq!(into.frames.len(), 1);
        assert_eq!(into.frames[0].sample.t_usec, 8000);

        // A physics started again (its time from zero, seconds back) is taken, not dropped as
        // stale: the vehicle sees its clock go back and starts again.
        for t in [3.0, 0.0] {
            physics.send_to(reply(t, 0.0).as_bytes(), from).unwrap();
            assert!(
                link.receive(Duration::from_secs(5), &mut into).unwrap(),
                "{t}"
            );
        }
        assert_eq!(link.stale, 1);

        // Unanswered for a second, the packet goes out again, the same frame count.
        assert!(
            !link
                .receive(Duration::from_millis(1100), &mut into)
                .unwrap()
        );
        assert!(!link.receive(Duration::ZERO, &mut into).unwrap());
        let (again, _) = packet(&physics);
        assert_eq!(again, second);
    }
}
