//! Baud detection: listen at each baud in turn until valid frames arrive, as ArduPilot's GPS
//! drivers do; the receiver's own default (38 400 on u-blox generation 9 and 10, 9 600 on M8)
//! is found within a second or two of listening.

/// How long one baud is listened to before the next (s): more than one epoch of an
/// unconfigured receiver's 1 Hz output.
pub const DWELL_S: f64 = 1.2;

/// The bauds a receiver is looked for at, after the one asked for.
const BAUDS: [u32; 7] = [38_400, 9_600, 115_200, 230_400, 57_600, 460_800, 4_800];

/// The scan: the baud listened at, and since when.
#[derive(Debug, Clone)]
pub struct BaudScan {
    bauds: Vec<u32>,
    index: usize,
    since: Option<f64>,
}

impl BaudScan {
    /// A scan starting at `first` (the port's configured baud), then the usual bauds.
    pub fn new(first: u32) -> Self {
        let mut bauds = vec![first];
        bauds.extend(BAUDS.iter().copied().filter(|b| *b != first));
        Self {
            bauds,
            index: 0,
            since: None,
        }
    }

    /// The baud listened at now.
    pub fn baud(&self) -> u32 {
        self.bauds[self.index]
    }

    /// Starts again from the first baud at `t_s`.
    pub fn restart(&mut self, t_s: f64) {
        self.index = 0;
        self.since = Some(t_s);
    }

    /// At `t_s`, nothing valid yet: moves to the next baud once this one has been listened
    /// to for [`DWELL_S`]. True when it moved (the port must change baud).
    pub fn next_if_due(&mut self, t_s: f64) -> bool {
        let since = *self.since.get_or_insert(t_s);
        if t_s - since < DWELL_S {
            return false;
        }
        self.index = (self.index + 1) % self.bauds.len();
        self.since = Some(t_s);
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_baud_is_listened_to_in_turn_and_the_scan_wraps() {
        let mut s = BaudScan::new(115_200);
        assert_eq!(s.baud(), 115_200);
        let mut seen = vec![s.baud()];
        let mut t = 0.0;
        while seen.len() < 8 {
            t += 0.1;
            if s.next_if_due(t) {
                seen.push(s.baud());
            }
        }
        assert_eq!(seen[1], 38_400, "{seen:?}");
        assert_eq!(seen[7], 115_200, "wraps to the first: {seen:?}");
        let mut unique = seen[..7].to_vec();
        unique.sort();
        unique.dedup();
        assert_eq!(unique.len(), 7, "{seen:?}");
    }
}
