//! The floor under the control loop's timing: the same deadline pacing (`src/control_loop/deadline.rs`) with
//! no work in the tick, for `SECONDS` at `HZ`, pinned to `CPU` when given. What this shows is
//! what the machine itself does to a loop (timer slack, other processes, a hypervisor taking its
//! CPU); `tools/bench.sh` prints it beside the autopilot's own figures.
//!
//! `cargo run --release -p autopilot --example idle_loop -- SECONDS [HZ] [CPU]`

#[allow(dead_code)]
#[path = "../src/control_loop/deadline.rs"]
mod deadline;

use deadline::{Deadlines, LoopStats, sleep_until};
use std::time::{Duration, Instant};

fn main() -> anyhow::Result<()> {
    let arg = |i: usize| std::env::args().nth(i);
    let usage = || anyhow::anyhow!("usage: idle_loop SECONDS [HZ] [CPU]");
    let seconds: f64 = arg(1).and_then(|s| s.parse().ok()).ok_or_else(usage)?;
    let hz: f64 = arg(2).map_or(Ok(1000.0), |s| s.parse().map_err(|_| usage()))?;
    if let Some(cpu) = arg(3) {
        deadline::pin_to_cpu(cpu.parse().map_err(|_| usage())?)?;
    }
    let period = Duration::from_secs_f64(1.0 / hz);
    let start = Instant::now();
    let mut deadlines = Deadlines::new(start, period);
    let mut stats = LoopStats::default();
    while start.elapsed().as_secs_f64() < seconds {
        let due = deadlines.next();
        sleep_until(due, Duration::from_micros(150));
        let woke = Instant::now();
        let missed = deadlines.advance(Instant::now());
        stats.record(woke - due, Duration::ZERO, missed);
    }
    let s = stats.summary();
    println!(
        "idle loop: loop_hz={:.0} ticks={} jitter_p50_us={} jitter_p99_us={} jitter_max_us={} overruns={}",
        s.ticks as f64 / start.elapsed().as_secs_f64(),
        s.ticks,
        s.jitter_p50_us,
        s.jitter_p99_us,
        s.jitter_max_us,
        s.overruns
    );
    Ok(())
}
