//! The embedded simulator's world: the settings' seed and sensors, a `--scenario`'s wind, start,
//! battery and events, each vehicle's home placed as `sitl -i` places it, and its own MAVLink
//! endpoint (`--sim-control`).

use super::prepare::sensor_preset;
use crate::links::sim::EmbeddedSim;
use crate::settings::Settings;
use anyhow::{Context, Result, bail};
use hil::control::Control;
use hil::control::params::Pace;
use sitl_core::Airframe;
use sitl_core::scenario::Scenario;
use sitl_core::sensors::SensorConfig;
use sitl_core::sim::Simulator;
use std::net::SocketAddr;

/// The scenario the settings name (or the airframe at rest at home, no wind), for `airframe`.
fn scenario(cfg: &Settings, airframe: &Airframe) -> Result<Scenario> {
    let Some(path) = &cfg.scenario else {
        return Ok(Scenario::basic(airframe.clone(), f64::INFINITY));
    };
    let s = Scenario::load(path, &cfg.params_dir().join("airframes"))
        .with_context(|| format!("--scenario {}", path.display()))?;
    if s.airframe.name != airframe.name {
        bail!(
            "--scenario {} flies {}, the autopilot {}: give --airframe {}",
            path.display(),
            s.airframe.name,
            airframe.name,
            s.airframe.name
        );
    }
    if !s.open_loop.is_empty() {
        bail!(
            "--scenario {} has an open-loop script, which flies without an autopilot (sitl --open-loop)",
            path.display()
        );
    }
    if !s.pilot.is_empty() {
        tracing::warn!(
            "--scenario {}: its [[pilot]] plays an RC receiver, which the embedded simulator has not (sitl --rc-device)",
            path.display()
        );
    }
    Ok(s)
}

/// Vehicle `instance`'s simulator, its seed `--seed` + `k` (the k-th of vehicles flown together).
pub(super) fn simulator(
    cfg: &Settings,
    airframe: &Airframe,
    instance: u16,
    k: u16,
) -> Result<Simulator> {
    let s = scenario(cfg, airframe)?;
    let mut world = s.sim;
    world.seed = cfg.seed.wrapping_add(k.into());
    world.sensors = SensorConfig::preset(sensor_preset(cfg)?);
    world.home = sitl_core::geo::home_for_instance(&world.home, instance);
    let mut sim = Simulator::new(&s.airframe, world, s.initial)?;
    sim.schedule(&s.events)?;
    if s.rotors_at_hover {
        let hover = sim.hover_speeds();
        sim.set_rotor_speeds(&hover);
    }
    Ok(sim)
}

/// The embedded simulator of vehicle `instance` alone, with its control endpoint if asked.
pub(super) fn embedded_link(
    cfg: &Settings,
    airframe: &Airframe,
    instance: u16,
) -> Result<EmbeddedSim> {
    let sim = simulator(cfg, airframe, instance, 0)?;
    let speed = cfg.realtime_factor()?;
    let control = match &cfg.sim_control {
        Some(addr) => {
            let addr = control_addr(addr, instance)?;
            let c = Control::bind(addr, &sim.config().wind, sim.config().calibration_hand)
                .with_context(|| format!("binding --sim-control {addr}"))?
                .with_clock(Pace::new(speed, cfg.paused));
            let local = c.local_addr()?;
            tracing::info!(control = %local, paused = cfg.paused, "simulator control listening");
            // Scripts read this line to learn the port (a port 0 is the system's choice).
            println!(
                "autopilot sim-control: system={} udp://{local}",
                instance + 1
            );
            Some(c)
        }
        None => None,
    };
    let link = EmbeddedSim::around(sim, speed, cfg.truth_csv.as_deref())?;
    Ok(match control {
        Some(c) => link.with_control(c),
        None => link,
    })
}

/// `--sim-control`'s address for `instance`: its port offset by the instance.
fn control_addr(given: &str, instance: u16) -> Result<SocketAddr> {
    let mut addr: SocketAddr = given.parse().with_context(|| {
        format!("--sim-control {given:?} is not an address such as 127.0.0.1:19000")
    })?;
    let port = addr
        .port()
        .checked_add(instance)
        .context("--instance pushes the --sim-control port past 65535")?;
    addr.set_port(port);
    Ok(addr)
}
