//! Stream rates per link, as PX4's `mavlink` instances keep them: what one ground station asks
//! (`SET_MESSAGE_INTERVAL`, `REQUEST_DATA_STREAM`) changes what its own link carries, never
//! another's. A link is an endpoint of the daemon ([`LinkId`]); every link starts with the
//! default streams. Sensor messages may be asked up to the rate the sensors deliver
//! ([`SampleRate`]); every other stream up to [`RATE_RANGE_HZ`].

use super::{RATE_RANGE_HZ, StreamSet};
use mavlink::MessageData;
use mavlink::dialects::common::{
    ATTITUDE_DATA, ATTITUDE_QUATERNION_DATA, HIGHRES_IMU_DATA, SCALED_IMU_DATA,
};

/// The messages made of one sensor sample each: streamed up to the sensor rate.
pub(crate) const SENSOR_STREAMS: [u32; 4] = [
    HIGHRES_IMU_DATA::ID,
    SCALED_IMU_DATA::ID,
    ATTITUDE_DATA::ID,
    ATTITUDE_QUATERNION_DATA::ID,
];

/// How early a stream may go out: a fraction of its interval, at most [`EARLY_MAX_S`]. Wake-ups
/// on sensor samples jitter, and a stream at the sample rate would otherwise lose one at each
/// early sample. Its phase is kept, so the mean rate is the one asked.
const EARLY: f64 = 0.25;

/// The most a stream goes out early (s).
const EARLY_MAX_S: f64 = 0.002;

/// Which link (endpoint) a message arrived on or a stream goes out on.
pub type LinkId = u8;

/// One stream: its interval and when it is next due (s of the ground station's clock).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Stream {
    id: u32,
    interval_s: f64,
    next_s: f64,
}

/// The streams of every link, and the set each started with.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct LinkRates {
    links: Vec<(LinkId, StreamSet, Vec<Stream>)>,
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
        if !self.links.iter().any(|l| l.0 == link) {
            self.add_with(link, StreamSet::Normal);
        }
    }

    /// A link with the streams of `set`: a link that exists starts again with them if it had
    /// another set (link 0 is there from the start, with the default one).
    pub(crate) fn add_with(&mut self, link: LinkId, set: StreamSet) {
        let streams = || {
            set.rates()
                .iter()
                .map(|&(id, hz)| Stream {
                    id,
                    interval_s: 1.0 / hz,
                    next_s: 0.0,
                })
                .collect()
        };
        match self.links.iter_mut().find(|l| l.0 == link) {
            Some(l) if l.1 != set => *l = (link, set, streams()),
            Some(_) => {}
            None => self.links.push((link, set, streams())),
        }
    }

    /// The streams of `link`, which starts with the default ones if it is new.
    fn streams(&mut self, link: LinkId) -> &mut Vec<Stream> {
        self.add(link);
        let k = self.links.iter().position(|l| l.0 == link).unwrap_or(0);
        &mut self.links[k].2
    }

    /// The rate message `id` starts with on `link` (Hz), if its set streams it.
    pub(crate) fn default_hz(&self, link: LinkId, id: u32) -> Option<f64> {
        let set = self
            .links
            .iter()
            .find(|l| l.0 == link)
            .map_or(StreamSet::Normal, |l| l.1);
        set.rates().iter().find(|s| s.0 == id).map(|s| s.1)
    }

    /// Sets message `id` on `link` to `hz` (`None`: off), from the slowest allowed rate to
    /// `max_hz`.
    pub(crate) fn set(&mut self, link: LinkId, id: u32, hz: Option<f64>, max_hz: f64) {
        let streams = self.streams(link);
        streams.retain(|s| s.id != id);
        if let Some(hz) = hz {
            let hz = hz.clamp(RATE_RANGE_HZ.0, max_hz.max(RATE_RANGE_HZ.0));
            streams.push(Stream {
                id,
                interval_s: 1.0 / hz,
                next_s: 0.0,
            });
        }
    }

    /// Every stream of `link` due at once (a ground station just arrived there); each keeps
    /// its interval from then on.
    pub(crate) fn restart(&mut self, link: LinkId) {
        for s in self.streams(link) {
            s.next_s = f64::NEG_INFINITY;
        }
    }

    /// The interval of message `id` on `link` (s), if it is streamed there.
    pub(crate) fn interval_s(&self, link: LinkId, id: u32) -> Option<f64> {
        let streams = &self.links.iter().find(|l| l.0 == link)?.2;
        streams.iter().find(|s| s.id == id).map(|s| s.interval_s)
    }

    /// The fastest stream of any link (Hz; 0 with none).
    pub(crate) fn fastest_hz(&self) -> f64 {
        let streams = self.links.iter().flat_map(|l| &l.2);
        streams.map(|s| 1.0 / s.interval_s).fold(0.0, f64::max)
    }

    /// Message `id` was just sent on every link at `now_s` (a heartbeat on a change): each
    /// link's next one is an interval later.
    pub(crate) fn sent_everywhere(&mut self, id: u32, now_s: f64) {
        for (_, _, streams) in &mut self.links {
            if let Some(s) = streams.iter_mut().find(|s| s.id == id) {
                s.next_s = now_s + s.interval_s;
            }
        }
    }

    /// The (link, message id) pairs due at `now_s` (or a little before: [`EARLY`]), each link's in its
    /// order; their next times move on (keeping the phase; after a long gap, afresh rather than
    /// in a burst).
    pub(crate) fn due(&mut self, now_s: f64) -> Vec<(LinkId, u32)> {
        let mut due = Vec::new();
        for (link, _, streams) in &mut self.links {
            let due_now =
                |s: &&mut Stream| now_s >= s.next_s - (EARLY * s.interval_s).min(EARLY_MAX_S);
            for s in streams.iter_mut().filter(due_now) {
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

/// The rate the sensor samples arrive at (Hz of the vehicle's clock), measured over windows
/// of [`SampleRate::WINDOW_S`].
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(crate) struct SampleRate {
    /// The window's start: sensor time (s) and frames stepped.
    mark: Option<(f64, u64)>,
    /// The last window's rate.
    hz: Option<f64>,
}

impl SampleRate {
    /// The window (s of sensor time).
    const WINDOW_S: f64 = 0.5;

    /// The telemetry at sensor time `t_s`, after `frames` frames.
    pub(crate) fn observe(&mut self, t_s: f64, frames: u64) {
        match self.mark {
            Some((t0, n0)) if t_s >= t0 && frames >= n0 => {
                if t_s - t0 >= Self::WINDOW_S {
                    self.hz = Some((frames - n0) as f64 / (t_s - t0));
                    self.mark = Some((t_s, frames));
                }
            }
            // The first, or a source that started again.
            _ => self.mark = Some((t_s, frames)),
        }
    }

    /// The rate, once a window has passed.
    pub(crate) fn hz(&self) -> Option<f64> {
        self.hz
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
        r.set(1, HEARTBEAT_DATA::ID, None, RATE_RANGE_HZ.1);
        r.set(1, ATTITUDE_DATA::ID, Some(1e6), RATE_RANGE_HZ.1);
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
        r.set(7, ATTITUDE_DATA::ID, Some(2.0), RATE_RANGE_HZ.1);
        assert_eq!(r.interval_s(7, HEARTBEAT_DATA::ID), Some(1.0));
    }

    /// Polled on every sensor sample (250 Hz, jittered by up to ±1 ms), a stream keeps its
    /// rate: 200 Hz and 250 Hz streams send 200 and 250 a second.
    #[test]
    fn streams_polled_on_samples_keep_the_rate_asked() {
        for hz in [200.0, 250.0, 90.0] {
            let mut r = LinkRates { links: Vec::new() };
            r.links.push((0, StreamSet::Normal, Vec::new()));
            r.set(0, ATTITUDE_DATA::ID, Some(hz), 250.0);
            let mut sent = 0;
            for k in 0..2500 {
                // A deterministic jitter in [-1, 1] ms.
                let jitter = ((k * 7919) % 201) as f64 / 100.0 - 1.0;
                let now = k as f64 * 0.004 + jitter * 1e-3;
                sent += r.due(now).len();
            }
            let rate = sent as f64 / 10.0;
            assert!((rate - hz).abs() <= 0.02 * hz, "{hz} Hz asked, {rate} sent");
        }
    }

    #[test]
    fn the_sample_rate_is_measured_over_windows_and_starts_again_with_the_source() {
        let mut s = SampleRate::default();
        for k in 0..200u64 {
            s.observe(k as f64 / 250.0, k);
        }
        assert!((s.hz().unwrap() - 250.0).abs() < 1.0, "{:?}", s.hz());
        // The source restarts: its time goes back; the last rate stands until a new window.
        s.observe(0.0, 300);
        s.observe(0.6, 300 + 60);
        assert!((s.hz().unwrap() - 100.0).abs() < 1.0, "{:?}", s.hz());
    }
}
