//! A batch's progress on standard error: an `indicatif` bar on a terminal, otherwise (a CI
//! log) a line at every tenth of the runs.

use indicatif::{ProgressBar, ProgressStyle};
use std::io::IsTerminal;
use std::time::Instant;

/// The bar, or the lines, and the counts behind them.
pub struct Progress {
    bar: Option<ProgressBar>,
    total: u32,
    done: u32,
    landed: u32,
    started: Instant,
    shown_tenths: u32,
}

impl Progress {
    /// A bar for `total` runs.
    pub fn new(total: u32) -> Self {
        let bar = std::io::stderr().is_terminal().then(|| {
            let style = ProgressStyle::with_template(
                "[{bar:30}] {pos}/{len} runs, {msg}, {per_sec}, {eta} left",
            )
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("#-");
            ProgressBar::new(u64::from(total)).with_style(style)
        });
        Self {
            bar,
            total,
            done: 0,
            landed: 0,
            started: Instant::now(),
            shown_tenths: 0,
        }
    }

    /// One more run done, landed or not.
    pub fn add(&mut self, landed: bool) {
        self.done += 1;
        self.landed += u32::from(landed);
        if let Some(bar) = &self.bar {
            bar.set_message(format!("{} landed", self.landed));
            bar.inc(1);
            if self.done == self.total {
                bar.finish();
            }
            return;
        }
        let tenths = 10 * self.done / self.total.max(1);
        if tenths <= self.shown_tenths {
            return;
        }
        self.shown_tenths = tenths;
        let rate = f64::from(self.done) / self.started.elapsed().as_secs_f64().max(1e-9);
        let eta = f64::from(self.total - self.done) / rate.max(1e-9);
        eprintln!(
            "{}/{} runs, {} landed, {rate:.1} runs/s, {eta:.0} s left",
            self.done, self.total, self.landed
        );
    }
}
