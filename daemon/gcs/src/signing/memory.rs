//! What signing remembers across restarts, as text: the vehicle's signing clock and the last
//! timestamp of each stream (system, component, link id), one per line.
//!
//! ```text
//! # MAVLink signing: the last timestamp of each stream (10 µs since 2015-01-01)
//! timestamp 37100000000000
//! stream 255 190 0 37099999900000
//! ```

/// The vehicle's signing clock and each stream's last timestamp (10 µs units since 2015).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct SigningMemory {
    /// The vehicle's signing clock.
    pub timestamp: u64,
    /// (system, component, link id) and the stream's last timestamp.
    pub streams: Vec<((u8, u8, u8), u64)>,
}

/// A memory's text that cannot be read: the line and what is wrong with it.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("line {line}: {what}")]
pub struct MemoryUnreadable {
    /// The line (from 1).
    pub line: usize,
    /// What is wrong.
    pub what: String,
}

/// Largest timestamp: 48 bits.
const MAX_TIMESTAMP: u64 = (1 << 48) - 1;

impl SigningMemory {
    /// The memory as text.
    pub fn to_text(&self) -> String {
        let mut t = String::from(
            "# MAVLink signing: the last timestamp of each stream (10 µs since 2015-01-01)\n",
        );
        t += &format!("timestamp {}\n", self.timestamp);
        for ((system, component, link), last) in &self.streams {
            t += &format!("stream {system} {component} {link} {last}\n");
        }
        t
    }

    /// Reads [`Self::to_text`]'s text; blank lines and `#` comments are skipped. A text without
    /// its `timestamp` line is unreadable (a file cut short).
    pub fn parse(text: &str) -> Result<Self, MemoryUnreadable> {
        let mut m = Self::default();
        let mut clock = false;
        for (k, line) in text.lines().enumerate() {
            let bad = |what: &str| MemoryUnreadable {
                line: k + 1,
                what: what.to_owned(),
            };
            let words: Vec<&str> = line.split_whitespace().collect();
            let timestamp = |w: &str| {
                w.parse::<u64>()
                    .ok()
                    .filter(|t| *t <= MAX_TIMESTAMP)
                    .ok_or_else(|| bad("a timestamp is a whole number below 2^48"))
            };
            let byte = |w: &str| w.parse::<u8>().map_err(|_| bad("an id is 0 to 255"));
            match words.as_slice() {
                [] => {}
                [w, ..] if w.starts_with('#') => {}
                ["timestamp", t] => {
                    m.timestamp = timestamp(t)?;
                    clock = true;
                }
                ["stream", s, c, l, t] => {
                    m.streams
                        .push(((byte(s)?, byte(c)?, byte(l)?), timestamp(t)?));
                }
                _ => return Err(bad("not `timestamp T` or `stream SYSTEM COMPONENT LINK T`")),
            }
        }
        if !clock {
            return Err(MemoryUnreadable {
                line: text.lines().count(),
                what: "no `timestamp` line (cut short?)".into(),
            });
        }
        Ok(m)
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn a_memory_reads_back_as_written_and_damage_is_named() {
        let m = SigningMemory {
            timestamp: 37_100_000_000_000,
            streams: vec![((255, 190, 0), 37_099_999_000_000), ((1, 1, 7), 5)],
        };
        assert_eq!(SigningMemory::parse(&m.to_text()), Ok(m.clone()));
        let text = m.to_text();
        for (damaged, line) in [
            ("", 0),
            (&text[..text.find("timestamp ").unwrap()], 1),
            (&text.replace("stream 1 1 7", "stream 1 1 700"), 4),
            (&text.replace(" 5\n", " 281474976710656\n"), 4),
            (&text.replace("timestamp", "clock"), 2),
        ] {
            assert_eq!(
                SigningMemory::parse(damaged).unwrap_err().line,
                line,
                "{damaged:?}"
            );
        }
    }
}
