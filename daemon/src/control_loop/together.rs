//! Several vehicles flown on one thread, in lockstep on one clock (`--count`).

use super::{ControlLoop, Flow, Onboard, POLL};
use anyhow::Result;
use std::time::{Duration, Instant};

use super::FlightReport;

/// How a flight of several vehicles together went.
#[derive(Debug)]
pub struct SwarmReport {
    /// Each vehicle's report, or why its flight ended in error, in the members' order.
    pub flights: Vec<Result<FlightReport>>,
    /// Rounds flown: in each, every vehicle still flying took one sensor frame.
    pub rounds: u64,
    /// Simulated time of the last round (s).
    pub sim_time_s: f64,
    /// Wall-clock time (s).
    pub wall_time_s: f64,
    /// Paced (`speed`): the largest lag of a round behind its wall-clock time (s); a swarm
    /// that runs in real time keeps it within a few exchange periods.
    pub max_lag_s: f64,
}

/// Flies several vehicles on this thread, in lockstep on one clock: every round each vehicle
/// still flying takes the next frame of its simulator (one exchange, `1 / exchange_hz` of
/// simulated time) and answers it, so all worlds advance together. With `speed` the rounds are
/// paced against the wall clock (× real time); without, they run as fast as they can. A vehicle
/// whose run ends (landed and disarmed, `Stop`, an error) leaves the round; the others fly on.
pub fn fly_together(
    members: Vec<Onboard<'_>>,
    exchange_hz: f64,
    speed: Option<f64>,
) -> SwarmReport {
    let started = Instant::now();
    let mut loops: Vec<Option<ControlLoop<'_>>> = members
        .into_iter()
        .map(|m| Some(ControlLoop::new(m)))
        .collect();
    let mut flights: Vec<Option<Result<FlightReport>>> = loops.iter().map(|_| None).collect();
    let (mut rounds, mut max_lag_s) = (0u64, 0.0f64);
    let mut flying = loops.len();
    while flying > 0 {
        for (slot, flight) in loops.iter_mut().zip(flights.iter_mut()) {
            let Some(l) = slot.as_mut() else { continue };
            let end = match l.tick(POLL, false) {
                Ok(Flow::Continue) => continue,
                Ok(Flow::Stop) => Ok(()),
                Err(e) => Err(e),
            };
            let Some(l) = slot.take() else { continue };
            l.ports.telemetry.send_modify(|t| t.link.finished = true);
            *flight = Some(end.map(|()| l.into_report(started)));
            flying -= 1;
        }
        rounds += 1;
        if let Some(speed) = speed {
            let due = started + Duration::from_secs_f64(rounds as f64 / exchange_hz / speed);
            match due.checked_duration_since(Instant::now()) {
                Some(wait) => std::thread::sleep(wait),
                None => max_lag_s = max_lag_s.max(due.elapsed().as_secs_f64()),
            }
        }
    }
    SwarmReport {
        flights: flights
            .into_iter()
            .map(|f| f.unwrap_or_else(|| Err(anyhow::anyhow!("never flown"))))
            .collect(),
        rounds,
        sim_time_s: rounds as f64 / exchange_hz,
        wall_time_s: started.elapsed().as_secs_f64(),
        max_lag_s,
    }
}
