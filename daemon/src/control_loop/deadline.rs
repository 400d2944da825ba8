//! Pacing by absolute deadlines, and the loop's timing statistics.
//!
//! Deadline k is `start + k·period`: a late tick never pushes the later ones (no drift), and
//! a tick whose work runs past one or more deadlines skips them and counts each as an overrun,
//! as PX4's work queues and ArduPilot's scheduler do.

use gcs::telemetry::LoopSummary;
use std::time::{Duration, Instant};

/// Largest lateness the histogram resolves (µs); later ticks land in its last bin and in `max`.
const HISTOGRAM_US: usize = 20_000;

/// The deadlines of a loop at a fixed period.
#[derive(Debug, Clone)]
pub struct Deadlines {
    start: Instant,
    period: Duration,
    /// Index of the next deadline.
    k: u64,
}

impl Deadlines {
    /// Deadlines every `period` from `start` (the first is `start + period`).
    pub fn new(start: Instant, period: Duration) -> Self {
        Self {
            start,
            period,
            k: 1,
        }
    }

    /// The next deadline.
    pub fn next(&self) -> Instant {
        self.start + Duration::from_nanos((self.period.as_nanos() as u64).saturating_mul(self.k))
    }

    /// The tick of the current deadline ended at `now`: moves to the first deadline after
    /// `now` and returns how many deadlines were missed on the way (overruns).
    pub fn advance(&mut self, now: Instant) -> u64 {
        self.k += 1;
        let due = self.next();
        if now < due {
            return 0;
        }
        let behind = now.duration_since(due).as_nanos() / self.period.as_nanos().max(1);
        let missed = behind as u64 + 1;
        self.k += missed;
        missed
    }
}

/// Sleeps until `deadline`: the operating system's sleep until `spin` before it, then a spin
/// on the clock. A plain sleep wakes 50–90 µs late on Linux (timer slack plus the wake-up);
/// the spin takes that to a few µs at the cost of `spin` of one core per tick.
pub fn sleep_until(deadline: Instant, spin: Duration) {
    let now = Instant::now();
    if deadline > now + spin {
        std::thread::sleep(deadline - now - spin);
    }
    while Instant::now() < deadline {
        std::hint::spin_loop();
    }
}

/// Pins the calling thread to CPU `cpu` (keeps it away from a CPU that serves periodic
/// interrupts; on a VM, say, the balloon driver's statistics).
#[cfg(target_os = "linux")]
pub fn pin_to_cpu(cpu: usize) -> anyhow::Result<()> {
    use anyhow::Context;
    use nix::sched::{CpuSet, sched_setaffinity};
    let mut set = CpuSet::new();
    set.set(cpu).with_context(|| format!("CPU {cpu}"))?;
    sched_setaffinity(nix::unistd::Pid::from_raw(0), &set)
        .with_context(|| format!("pinning the control loop to CPU {cpu}"))
}

/// Keeps the calling thread off CPU `cpu` (the other threads of a process whose control loop
/// is pinned there: they inherit its real-time priority under `chrt`, and one of them running
/// on the loop's CPU delays the loop's wake-up until it blocks). No-op on a one-CPU machine.
#[cfg(target_os = "linux")]
pub fn keep_off_cpu(cpu: usize) -> anyhow::Result<()> {
    use anyhow::Context;
    use nix::sched::{sched_getaffinity, sched_setaffinity};
    let me = nix::unistd::Pid::from_raw(0);
    let mut set = sched_getaffinity(me).context("reading the CPU affinity")?;
    let others = (0..nix::sched::CpuSet::count())
        .filter(|&c| c != cpu && set.is_set(c).unwrap_or(false))
        .count();
    if others == 0 {
        return Ok(());
    }
    set.unset(cpu).with_context(|| format!("CPU {cpu}"))?;
    sched_setaffinity(me, &set).with_context(|| format!("keeping off CPU {cpu}"))
}

/// Keeps the calling thread off a CPU: not available here (nothing to do).
#[cfg(not(target_os = "linux"))]
pub fn keep_off_cpu(_cpu: usize) -> anyhow::Result<()> {
    Ok(())
}

/// Pins the calling thread to a CPU: not available here.
#[cfg(not(target_os = "linux"))]
pub fn pin_to_cpu(cpu: usize) -> anyhow::Result<()> {
    anyhow::bail!("pinning to CPU {cpu} is only supported on Linux")
}

/// Timing of a paced loop: how late each tick woke, how long its work took, the deadlines it
/// missed. Fixed-size (no allocation per tick); read and reset once per report.
#[derive(Debug, Clone)]
pub struct LoopStats {
    /// Lateness histogram, 1 µs bins.
    late_us: Box<[u32]>,
    ticks: u64,
    max_late: Duration,
    max_work: Duration,
    overruns: u64,
}

impl Default for LoopStats {
    fn default() -> Self {
        Self {
            late_us: vec![0; HISTOGRAM_US + 1].into_boxed_slice(),
            ticks: 0,
            max_late: Duration::ZERO,
            max_work: Duration::ZERO,
            overruns: 0,
        }
    }
}

impl LoopStats {
    /// Records one tick: woke `late` after its deadline, worked for `work`, missed `overruns`
    /// deadlines.
    pub fn record(&mut self, late: Duration, work: Duration, overruns: u64) {
        let bin = (late.as_micros() as usize).min(HISTOGRAM_US);
        self.late_us[bin] += 1;
        self.ticks += 1;
        self.max_late = self.max_late.max(late);
        self.max_work = self.max_work.max(work);
        self.overruns += overruns;
    }

    /// The lateness below which a fraction `q` of the ticks woke (µs).
    fn percentile(&self, q: f64) -> u32 {
        let rank = ((self.ticks as f64 * q).ceil() as u64).max(1);
        let mut seen = 0;
        for (us, &n) in self.late_us.iter().enumerate() {
            seen += n as u64;
            if seen >= rank {
                return us as u32;
            }
        }
        HISTOGRAM_US as u32
    }

    /// The figures so far.
    pub fn summary(&self) -> LoopSummary {
        if self.ticks == 0 {
            return LoopSummary::default();
        }
        LoopSummary {
            ticks: self.ticks,
            jitter_p50_us: self.percentile(0.5),
            jitter_p99_us: self.percentile(0.99),
            jitter_max_us: self.max_late.as_micros() as u64,
            work_max_us: self.max_work.as_micros() as u64,
            overruns: self.overruns,
        }
    }

    /// Adds `other`'s ticks to these (the whole run from its intervals).
    pub fn merge(&mut self, other: &LoopStats) {
        for (a, b) in self.late_us.iter_mut().zip(other.late_us.iter()) {
            *a += b;
        }
        self.ticks += other.ticks;
        self.max_late = self.max_late.max(other.max_late);
        self.max_work = self.max_work.max(other.max_work);
        self.overruns += other.overruns;
    }

    /// Forgets everything (the start of a new interval).
    pub fn clear(&mut self) {
        self.late_us.fill(0);
        self.ticks = 0;
        self.max_late = Duration::ZERO;
        self.max_work = Duration::ZERO;
        self.overruns = 0;
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    const MS: Duration = Duration::from_millis(1);

    #[test]
    fn deadlines_stay_on_their_grid_and_count_what_a_long_tick_missed() {
        let t0 = Instant::now();
        let mut d = Deadlines::new(t0, MS);
        assert_eq!(d.next(), t0 + MS);
        // On time: the next deadline is the next grid point, however late this tick woke.
        assert_eq!(d.advance(t0 + MS + Duration::from_micros(900)), 0);
        assert_eq!(d.next(), t0 + 2 * MS);
        // A tick that ends 3.5 periods later missed the deadlines at 3 and 4 and 5 ms.
        assert_eq!(d.advance(t0 + Duration::from_micros(5_500)), 3);
        assert_eq!(d.next(), t0 + 6 * MS);
        // Ending exactly on a deadline misses it.
        assert_eq!(d.advance(t0 + 7 * MS), 1);
        assert_eq!(d.next(), t0 + 8 * MS);
    }

    #[test]
    fn percentiles_come_from_the_histogram() {
        let mut s = LoopStats::default();
        // 98 ticks 2 µs late, one 40 µs, one 30 ms (beyond the histogram: counted in max).
        for _ in 0..98 {
            s.record(Duration::from_micros(2), Duration::from_micros(10), 0);
        }
        s.record(Duration::from_micros(40), Duration::from_micros(900), 1);
        s.record(Duration::from_millis(30), Duration::from_micros(10), 29);
        let m = s.summary();
        assert_eq!((m.ticks, m.jitter_p50_us, m.jitter_p99_us), (100, 2, 40));
        assert_eq!(
            (m.jitter_max_us, m.work_max_us, m.overruns),
            (30_000, 900, 30)
        );
        let mut whole = LoopStats::default();
        whole.merge(&s);
        whole.merge(&s);
        assert_eq!(whole.summary().ticks, 200);
        assert_eq!(whole.summary().jitter_p99_us, 40);
        s.clear();
        assert_eq!(s.summary(), LoopSummary::default());
    }

    #[test]
    fn a_paced_loop_wakes_on_its_deadlines() {
        // Not a timing test (that is the benchmark's job): the sleep never returns early.
        let t0 = Instant::now();
        let mut d = Deadlines::new(t0, Duration::from_micros(500));
        for _ in 0..20 {
            let due = d.next();
            sleep_until(due, Duration::from_micros(100));
            assert!(Instant::now() >= due);
            d.advance(Instant::now());
        }
    }
}
