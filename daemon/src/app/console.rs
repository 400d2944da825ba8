//! What the operator sees and does at the terminal while a flight runs: the live status line,
//! and Ctrl-C or SIGTERM to land or stop.

use crate::control_loop::LoopCommand;
use gcs::telemetry::Telemetry;
use std::io::{IsTerminal, Write};
use std::time::{Duration, Instant};
use tokio::sync::{mpsc, watch};

/// Ctrl-C: the first lands (every vehicle), the second stops the loop at once. SIGTERM (a service
/// manager, `kill`) stops it at once. Either way the run ends as every run does: logs flushed,
/// parameters saved.
pub(super) async fn interrupts(commands: Vec<mpsc::Sender<LoopCommand>>) {
    use tokio::signal::unix::{SignalKind, signal};
    let mut terminate = match signal(SignalKind::terminate()) {
        Ok(s) => Some(s),
        Err(e) => {
            tracing::warn!("SIGTERM not handled: {e}");
            None
        }
    };
    let terminated = async {
        match terminate.as_mut() {
            Some(s) => s.recv().await,
            None => std::future::pending().await,
        }
    };
    tokio::pin!(terminated);
    let mut interrupts = 0;
    loop {
        tokio::select! {
            Some(()) = &mut terminated => {
                tracing::info!("SIGTERM: stopping");
                for c in &commands {
                    let _ = c.send(LoopCommand::Stop).await;
                }
                return;
            }
            r = tokio::signal::ctrl_c() => {
                if r.is_err() {
                    return;
                }
                interrupts += 1;
                if interrupts == 1 {
                    eprintln!("\nautopilot: landing (Ctrl-C again to stop at once)");
                }
                let mut reached = 0;
                for c in &commands {
                    let command = if interrupts == 1 { LoopCommand::Land } else { LoopCommand::Stop };
                    reached += usize::from(c.send(command).await.is_ok());
                }
                if reached == 0 {
                    return;
                }
            }
        }
    }
}

/// The live one-line status, four times a second from the latest telemetry, until the loop
/// ends: on a terminal it rewrites itself, otherwise one line each time. One vehicle's line
/// shows its state; several vehicles' a count of each mode and the spread of their altitudes.
pub(super) async fn status_line(
    mut telemetry: Vec<watch::Receiver<Telemetry>>,
    ended: std::sync::Arc<tokio::sync::Notify>,
) {
    let tty = std::io::stdout().is_terminal();
    let started = Instant::now();
    let mut tick = tokio::time::interval(Duration::from_millis(250));
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    let loop_ended = ended.notified();
    tokio::pin!(loop_ended);
    let mut ended_seen = false;
    loop {
        // Polled, not awaited on every change: the loop publishes at its own rate, and waking
        // this thread that often would take CPU time from it. Its end wakes it at once.
        tokio::select! {
            _ = tick.tick() => {}
            _ = &mut loop_ended, if !ended_seen => ended_seen = true,
        }
        let latest: Vec<Telemetry> = telemetry
            .iter_mut()
            .filter_map(|rx| {
                let t = *rx.borrow_and_update();
                // The loop ended, or its thread did (an error before it started).
                (!t.link.finished && rx.has_changed().is_ok()).then_some(t)
            })
            .collect();
        if latest.is_empty() {
            break;
        }
        let wall = started.elapsed().as_secs_f64().max(1e-9);
        let line = if telemetry.len() == 1 {
            let t = &latest[0];
            let (Some(out), Some(status)) = (t.estimate(), t.status()) else {
                continue;
            };
            let (roll, pitch, yaw) = out.attitude.map_or((0.0, 0.0, 0.0), |a| a.q.euler_angles());
            let mut line = format!(
                "t {:6.1} s  {:<8} {:<8} alt {:6.2} m  vz {:5.2} m/s  roll {:5.1}  pitch {:5.1}  yaw {:6.1} deg  {:.0} frames/s x{:.0} real time",
                t.link.t_s,
                if status.armed { "armed" } else { "disarmed" },
                status.mode.name(),
                -out.translation.pos_ned_m.z,
                -out.translation.vel_ned_m_s.z,
                roll.to_degrees(),
                pitch.to_degrees(),
                yaw.to_degrees(),
                t.link.frames as f64 / wall,
                t.link.t_s / wall
            );
            if let Some(s) = t.link.loop_stats {
                line += &format!("  loop p99 {} us, {} overruns", s.jitter_p99_us, s.overruns);
            }
            line
        } else {
            swarm_status(&latest, telemetry.len(), wall)
        };
        let mut stdout = std::io::stdout();
        if tty {
            let _ = write!(stdout, "\r{line}\x1b[K");
            let _ = stdout.flush();
        } else {
            let _ = writeln!(stdout, "{line}");
        }
    }
    if tty {
        println!();
    }
}

/// Several vehicles' status in one line: how many fly, armed, in each mode, and their altitudes.
fn swarm_status(latest: &[Telemetry], count: usize, wall_s: f64) -> String {
    let t_s = latest.iter().map(|t| t.link.t_s).fold(0.0, f64::max);
    let armed = latest
        .iter()
        .filter(|t| t.status().is_some_and(|s| s.armed))
        .count();
    let mut modes: Vec<(&str, usize)> = Vec::new();
    for s in latest.iter().filter_map(|t| t.status()) {
        match modes.iter_mut().find(|(m, _)| *m == s.mode.name()) {
            Some((_, n)) => *n += 1,
            None => modes.push((s.mode.name(), 1)),
        }
    }
    let alts = latest
        .iter()
        .filter_map(|t| t.estimate().map(|o| -o.translation.pos_ned_m.z));
    let (lo, hi) = alts.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), a| {
        (lo.min(a), hi.max(a))
    });
    let modes: Vec<String> = modes.iter().map(|(m, n)| format!("{n} {m}")).collect();
    let mut line = format!(
        "t {t_s:6.1} s  {} of {count} vehicles flying, {armed} armed ({})",
        latest.len(),
        modes.join(", ")
    );
    if lo <= hi {
        line += &format!("  alt {lo:.2} to {hi:.2} m");
    }
    line + &format!("  x{:.1} real time", t_s / wall_s)
}
