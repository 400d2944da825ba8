//! Stream rates per link, as PX4's `mavlink` instances keep them: what one ground station asks
//! (`SET_MESSAGE_INTERVAL`, `REQUEST_DATA_STREAM`) changes what its own link carries, never
//! another's. A link is an endpoint of the daemon ([`LinkId`]); every link starts with the
//! default streams.

use super::{DEFAULT_STREAMS, RATE_RANGE_HZ};

/// Which link (endpoint) a message arrived on or a stream goes out on.
pub type LinkId = u8;

/// One stream: its interval and when it is next due (s of the ground station's clock).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Stream {
    id: u32,
    interval_s: f64,
    next_s: f64,
}

/// The streams of every link.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct LinkRates {
    links: Vec<(LinkId, Vec<Stream>)>,
}

impl Default for LinkRates {
    /// Link 0, with the default streams.
    fn default() -> Self {
        let mut r = Self { links: Vec::new() };
        r.add(0);
        r
    }
}

impl LinkRates {
    /// A link with the default streams (nothing if it exists).
    pub(crate) fn add(&mut self, link: LinkId) {
        self.streams(link);
    }

    /// The streams of `link`, which starts with the default ones if it is new.
    fn streams(&mut self, link: LinkId) -> &mut Vec<Stream> {
        let k = match self.links.iter().position(|l| l.0 == link) {
            Some(k) => k,
            None => {
                let streams = DEFAULT_STREAMS
                    .iter()
                    .map(|&(id, hz)| Stream {
                        id,
                        interval_s: 1.0 / hz,
                        next_s: 0.0,
                    })
                    .collect();
                self.links.push((link, streams));
                self.links.len() - 1
            }
        };
        &mut self.links[k].1
    }

    /// Sets message `id` on `link` to `hz` (`None`: off), within the allowed rates.
    pub(crate) fn set(&mut self, link: LinkId, id: u32, hz: Option<f64>) {
        let streams = self.streams(link);
        streams.retain(|s| s.id != id);
        if let Some(hz) = hz {
            let hz = hz.clamp(RATE_RANGE_HZ.0, RATE_RANGE_HZ.1);
            streams.push(Stream {
                id,
                interval_s: 1.0 / hz,
                next_s: 0.0,
            });
        }
    }

    /// The interval of message `id` on `link` (s), if it is streamed there.
    pub(crate) fn interval_s(&self, link: LinkId, id: u32) -> Option<f64> {
        let streams = &self.links.iter().find(|l| l.0 == link)?.1;
        streams.iter().find(|s| s.id == id).map(|s| s.interval_s)
    }

    /// Message `id` was just sent on every link at `now_s` (a heartbeat on a change): each
    /// link's next one is an interval later.
    pub(crate) fn sent_everywhere(&mut self, id: u32, now_s: f64) {
        for (_, streams) in &mut self.links {
            if let Some(s) = streams.iter_mut().find(|s| s.id == id) {
                s.next_s = now_s + s.interval_s;
            }
        }
    }

    /// The (link, message id) pairs due at `now_s`, each link's in its order; their next
    /// times move on (keeping the phase; after a long gap, afresh rather than in a burst).
    pub(crate) fn due(&mut self, now_s: f64) -> Vec<(LinkId, u32)> {
        let mut due = Vec::new();
        for (link, streams) in &mut self.links {
            for s in streams.iter_mut().filter(|s| now_s >= s.next_s) {
                s.next_s = if now_s - s.next_s > s.interval_s {
                    now_s + s.interval_s
                } else {
                    s.next_s + s.interval_s
                };
                due.push((*link, s.id));
            }
        }
        due
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use mavlink::MessageData;
    use mavlink::dialects::common::{ATTITUDE_DATA, HEARTBEAT_DATA};

    #[test]
    fn a_rate_set_on_one_link_leaves_the_others_as_they_were() {
        let mut r = LinkRates::default();
        r.add(1);
        r.set(1, HEARTBEAT_DATA::ID, None);
        r.set(1, ATTITUDE_DATA::ID, Some(1e6));
        assert_eq!(r.interval_s(1, HEARTBEAT_DATA::ID), None);
        assert_eq!(
            r.interval_s(1, ATTITUDE_DATA::ID),
            Some(1.0 / RATE_RANGE_HZ.1)
        );
        assert_eq!(r.interval_s(0, HEARTBEAT_DATA::ID), Some(1.0));
        assert_eq!(r.interval_s(0, ATTITUDE_DATA::ID), Some(0.1));
        let due = r.due(0.0);
        assert!(due.contains(&(0, HEARTBEAT_DATA::ID)));
        assert!(!due.contains(&(1, HEARTBEAT_DATA::ID)));
        // A link first heard of starts with the defaults.
        r.set(7, ATTITUDE_DATA::ID, Some(2.0));
        assert_eq!(r.interval_s(7, HEARTBEAT_DATA::ID), Some(1.0));
    }
}
