//! What a sensor link delivers and takes, typed: a sensor frame as the autopilot's
//! [`SensorSample`] (with the simulator's truth), and the answer as an [`ActuatorCommand`].
//! Links that carry MAVLink bytes fold the decoded HIL messages into frames here; the embedded
//! simulator folds the same messages without the bytes.

use flight_core::autopilot::AutopilotOutput;
use flight_core::commander::rc_input::RcFrame;
use flight_core::core::SensorSample;
use flight_core::estimator::translation::GpsMeasurement;
use flight_core::math::geo::LatLonAlt;
use flight_core::sensors::imu_calibrator::{PoseRequest, Side};
use hil::{ActuatorCommand, Decoded, HandRequest, SensorUpdate, TruthReport};
use mavlink::dialects::common::MavMessage;
use sitl_core::sim::Face;

/// One sensor frame: the autopilot's sample and, from a simulator, its ground truth.
#[derive(Debug, Clone, PartialEq)]
pub struct LinkFrame {
    /// What the sensors measured.
    pub sample: SensorSample,
    /// The simulator's truth, when this frame carried it (for logs and scoring only).
    pub truth: Option<TruthReport>,
    /// A frame from the RC receiver on its own port ([`crate::devices`]), when one arrived.
    pub rc: Option<RcFrame>,
}

/// What reads of a link brought.
#[derive(Debug, Default)]
pub struct Received {
    /// Complete sensor frames, oldest first.
    pub frames: Vec<LinkFrame>,
    /// Malformed input counted on the way (bad frames, junk, a stranger's datagrams).
    pub malformed: u32,
}

/// What has arrived since the last sensor frame, until `HIL_SENSOR` closes it.
#[derive(Debug, Default)]
pub struct FrameAssembler {
    update: SensorUpdate,
    /// Reused to decode bytes into.
    decoded: Decoded,
}

impl FrameAssembler {
    /// Folds one message in; `HIL_SENSOR` closes a frame: its sample (with what arrived before
    /// it: GPS, rotor speeds, battery) and the simulator's truth, if one came.
    pub fn absorb(&mut self, msg: &MavMessage) -> Option<LinkFrame> {
        if !self.update.absorb(msg) {
            return None;
        }
        close(&mut self.update)
    }

    /// Decodes a datagram (or a stream's bytes, split by `split`) and folds every message in,
    /// complete frames into `into`. Returns whether any message was decoded.
    pub fn absorb_bytes(&mut self, into: &mut Received, split: impl FnOnce(&mut Decoded)) -> bool {
        self.decoded.messages.clear();
        self.decoded.malformed = 0;
        split(&mut self.decoded);
        into.malformed += self.decoded.malformed;
        let messages = std::mem::take(&mut self.decoded.messages);
        for (_, m) in &messages {
            if let Some(f) = self.absorb(m) {
                into.frames.push(f);
            }
        }
        let any = !messages.is_empty();
        self.decoded.messages = messages;
        any
    }
}

/// The frame a [`SensorUpdate`] holds once `HIL_SENSOR` has closed it: fresh readings are taken
/// out of it, the IMU and the pack's state stay (they are what the next frame repeats if it
/// has none). `None` before the first IMU reading.
pub fn close(u: &mut SensorUpdate) -> Option<LinkFrame> {
    let (t_usec, gyro, accel) = (u.time_usec?, u.gyro_frd?, u.accel_frd?);
    let sample = SensorSample {
        t_usec,
        gyro,
        accel,
        mag: u.mag_frd.take(),
        baro_alt_m: u.pressure_alt_m.take(),
        gps: fresh(&mut u.gps).map(|g| GpsMeasurement {
            fix_type: g.fix_type,
            position: LatLonAlt {
                lat_deg: g.lat_deg,
                lon_deg: g.lon_deg,
                alt_m: g.alt_m,
            },
            vel_ned_m_s: g.vel_ned_m_s,
            h_acc_m: g.h_acc_m,
            satellites: g.satellites,
            details: Default::default(),
        }),
        // The pack's state as last reported (ESC_STATUS comes at its own rate).
        battery_v: u.battery_v,
        esc_current_a: u.esc_current_a,
        rotor_speed_rad_s: fresh(&mut u.rotor_speed_rad_s),
    };
    Some(LinkFrame {
        rc: None,
        sample,
        truth: fresh(&mut u.truth),
    })
}

/// Takes a fresh reading out; when there is none, copies nothing (`take` moves the whole
/// `Option` every frame, and the GPS, the rotor speeds and the truth are hundreds of bytes
/// that most frames do not carry).
fn fresh<T>(reading: &mut Option<T>) -> Option<T> {
    if reading.is_some() {
        reading.take()
    } else {
        None
    }
}

/// The answer to a step: the first `rotors` commands of `out`, quantised as
/// `HIL_ACTUATOR_CONTROLS` carries them, with what a calibration asks of the hand.
pub fn answer(out: &AutopilotOutput, rotors: usize, pose: PoseRequest) -> ActuatorCommand {
    ActuatorCommand::as_sent(out.t_usec, &out.commands[..rotors], out.armed).with_hand(hand(pose))
}

/// A calibration's request as the simulator's hand takes it.
fn hand(pose: PoseRequest) -> HandRequest {
    match pose {
        PoseRequest::None => HandRequest::None,
        PoseRequest::Tumble => HandRequest::Tumble,
        PoseRequest::Place(side) => HandRequest::Place(match side {
            Side::Back => Face::Back,
            Side::Front => Face::Front,
            Side::Left => Face::Left,
            Side::Right => Face::Right,
            Side::Up => Face::Up,
            Side::Down => Face::Down,
        }),
    }
}
