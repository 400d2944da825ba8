//! `sitl --json`: the simulator as a physics for ArduPilot's JSON interface ([`hil::json`]).
//! It listens for the autopilot's servo packets and, for each new one, steps one exchange with
//! its PWM as the rotor commands and replies with the state. A resent packet (the same frame
//! count) gets the same reply again without a step, so the world moves once per command.

use crate::SitlCli;
use crate::run::{
    AwaitAutopilot, Dynamics, Pacer, Status, Summary, build, finish, open_truth, with_instance,
};
use anyhow::{Context, Result, bail};
use hil::json::{JSON_INSTANCE_STRIDE, PhysicsState, ServoPacket, command_from_pwm};
use hil::{ActuatorCommand, SimulatorEnd};
use sitl_core::scenario::Scenario;
use sitl_core::sim::Simulator;
use std::net::{SocketAddr, UdpSocket};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// How long one wait for a packet lasts: how quickly Ctrl-C is noticed.
const POLL: Duration = Duration::from_millis(100);
/// The rotors' commands of a servo packet (PWM on the first `rotors` channels), applied.
fn apply_servos(end: &mut SimulatorEnd, packet: &ServoPacket, rotors: usize) {
    let mut controls = [0.0; 16];
    for (c, &pwm) in controls.iter_mut().zip(packet.pwm()).take(rotors) {
        *c = command_from_pwm(pwm);
    }
    end.apply(&ActuatorCommand {
        time_usec: end.frame().time_usec,
        controls,
        armed: true,
        hand: hil::HandRequest::None,
    });
}

/// The state after the last step, as a JSON reply. The IMU is the true rate and specific force,
/// as a JSON physics gives them: the autopilot adds its sensors' noise (ArduPilot's `SIM_*`).
fn state(end: &SimulatorEnd) -> PhysicsState {
    let truth = end.sim().truth();
    let q = truth.body.q_ned_from_frd;
    let gravity = nalgebra::Vector3::new(0.0, 0.0, sitl_core::GRAVITY_M_S2);
    PhysicsState {
        timestamp_s: end.sim().time_s(),
        gyro_frd_rad_s: truth.body.rate_frd_rad_s,
        accel_frd_m_s2: q.inverse_transform_vector(&(truth.accel_ned_m_s2 - gravity)),
        pos_ned_m: truth.body.pos_ned_m,
        vel_ned_m_s: truth.body.vel_ned_m_s,
        q_ned_from_frd: truth.body.q_ned_from_frd,
        battery: Some((truth.battery_voltage_v, truth.battery_current_a)),
        airspeed_m_s: Some((truth.body.vel_ned_m_s - truth.wind_ned_m_s).norm()),
    }
}

/// Serves servo packets on `--json`'s address until the scenario's time is up or Ctrl-C.
pub fn run(
    scenario: &Scenario,
    cli: &SitlCli,
    speed: Option<f64>,
    stop: &AtomicBool,
) -> Result<Summary> {
    let Some(addr) = cli.json else {
        bail!("--json needs an address");
    };
    let addr = with_instance(addr, cli.instance, JSON_INSTANCE_STRIDE, "--json")?;
    let sim = build(scenario)?;
    let mut dynamics = Dynamics::start(cli, scenario, &sim)?;
    let mut truth = open_truth(cli, &sim)?;
    let mut end = SimulatorEnd::new(sim, cli.hil_rate);
    let socket = UdpSocket::bind(addr).with_context(|| {
        format!("binding {addr} for JSON servo packets (another physics there? try -i N)")
    })?;
    socket.set_read_timeout(Some(POLL))?;
    tracing::info!(
        airframe = %end.sim().airframe().name, listening = %addr, physics = ?cli.physics,
        physics_hz = 1.0 / end.sim().config().dt_s, exchange_hz = end.exchange_hz(),
        "JSON physics ready: waiting for servo packets"
    );
    let rotors = end.sim().airframe().rotors.len();
    let started = Instant::now();
    let mut pacer = Pacer::new(started, speed);
    let mut status = Status::new(cli.status_interval);
    let mut summary = Summary::default();
    let mut buf = vec![0u8; 2048];
    let mut last: Option<(u32, SocketAddr)> = None;
    let mut reply = String::new();
    let mut awaiting = AwaitAutopilot::new(started);
    while end.sim().time_s() < scenario.duration_s - 1e-9 && !stop.load(Ordering::Relaxed) {
        status.maybe_print(end.sim(), started);
        let (n, from) = match socket.recv_from(&mut buf) {
            Ok(r) => r,
            Err(e)
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::WouldBlock
                        | std::io::ErrorKind::TimedOut
                        | std::io::ErrorKind::Interrupted
                ) =>
            {
                if last.is_none() {
                    awaiting.unanswered(cli, &format!("{addr} (servo packets)"))?;
                }
                continue;
            }
            Err(e) => return Err(e).context("receiving servo packets"),
        };
        let packet = match ServoPacket::decode(&buf[..n]) {
            Ok(p) => p,
            Err(e) => {
                summary.malformed += 1;
                tracing::debug!(%from, "{e}");
                continue;
            }
        };
        summary.actuator_messages += 1;
        match last {
            Some((count, peer)) if peer == from && packet.frame_count == count => {
                // A resend: the same reply, the world does not move.
                summary.stale += 1;
                socket.send_to(reply.as_bytes(), from)?;
                continue;
            }
            Some((count, peer)) if peer != from || packet.frame_count < count => {
                tracing::info!(%from, frame_count = packet.frame_count, "servo packets start again: a new autopilot, or the same restarted");
            }
            None => {
                tracing::info!(%from, "autopilot answered: lockstep running");
                pacer.restart_at(end.sim().time_s());
            }
            _ => {}
        }
        apply_servos(&mut end, &packet, rotors);
        pacer.wait_until(end.sim().time_s());
        let record = |sim: &Simulator| -> Result<()> {
            match truth.as_mut() {
                Some(csv) => Ok(csv.record(&sim.truth(), sim.rotor_speeds())?),
                None => Ok(()),
            }
        };
        end.advance_with(|sim, u| dynamics.step(sim, u), record)?;
        state(&end).write_json(&mut reply);
        socket.send_to(reply.as_bytes(), from)?;
        summary.frames_sent += 1;
        last = Some((packet.frame_count, from));
    }
    status.maybe_print(end.sim(), started);
    if let Some(mut csv) = truth {
        csv.flush()?;
    }
    Ok(finish(end.sim(), started, summary))
}
