//! [`ZenohSource`]: raw frames from a key that a board's bridge publishes on.

use std::collections::VecDeque;
use std::time::{Duration, Instant};

use zenoh::handlers::FifoChannelHandler;
use zenoh::pubsub::Subscriber;
use zenoh::sample::Sample;
use zenoh::{Session, Wait};

use super::{FrameMessage, MiddlewareError};
use crate::codec::BadFrame;
use crate::source::{Acquired, FrameSource, SourceError};

/// Samples held while the processing is busy (about 10 s of a board at 100 frames/s); a
/// reader that falls further behind holds up Zenoh's delivery (the queue is full, and the
/// source is not live: its reader waits for the processing too) rather than losing frames.
const QUEUE: usize = 1024;

/// How far back a counter may go and still be a late frame of the same stream (a sample of one
/// publisher comes in order over TCP; several publishers on one key may interleave); further
/// back, or back to 0, the bridge started again, and the frame is taken.
const RESTART: u64 = 16;

/// The shortest silence reported, and how many of its frame intervals a source may miss
/// before it is: a board at 100 frames/s is silent after 1 s, one at 1 frame/s after 10 s.
const SILENCE_MIN: Duration = Duration::from_secs(1);
const SILENCE_INTERVALS: f64 = 10.0;

/// Frames of [`FrameMessage`]s on one key: each checked for its count, the counter followed as
/// a serial board's is (frames missing before one are reported as a gap, a frame older than
/// the newest is dropped as stale), a sample that is not a frame reported with its key. A live
/// source waits for the next sample, however long, and ends only with the session; once frames
/// have come, a pause of ten of their intervals (at least a second) is reported
/// ([`Acquired::Silent`]), and so are the frames coming again ([`Acquired::Resumed`]).
pub struct ZenohSource {
    subscriber: Subscriber<FifoChannelHandler<Sample>>,
    key: String,
    measurements: usize,
    counter: Counter,
    /// Items to deliver after the one reported before them (a gap, frames again).
    pending: VecDeque<Acquired>,
    /// When the last sample came, and whether the silence after it was reported.
    last: Option<Instant>,
    silent: bool,
    /// The last frame's time and the typical interval between frames (s, a running mean), by
    /// the frames' own times: a backlog read at once does not shorten it.
    last_t: Option<f64>,
    interval: Option<f64>,
}

impl ZenohSource {
    /// Subscribes on `session` to `key` (wildcards allowed: several bridges' frames on one
    /// stream are then one counter's, so give one key per board) for frames of `measurements`
    /// values.
    pub fn open(session: &Session, key: &str, measurements: usize) -> Result<ZenohSource, MiddlewareError> {
        zenoh::key_expr::KeyExpr::try_from(key).map_err(|e| MiddlewareError::Key {
            what: "--source zenoh:",
            key: key.to_owned(),
            use_: "subscribe to",
            reason: e.to_string(),
        })?;
        let subscriber = session
            .declare_subscriber(key.to_owned())
            .with(zenoh::handlers::FifoChannel::new(QUEUE))
            .wait()
            .map_err(|e| MiddlewareError::Zenoh { key: key.to_owned(), reason: e.to_string() })?;
        Ok(ZenohSource {
            subscriber,
            key: key.to_owned(),
            measurements,
            counter: Counter::default(),
            pending: VecDeque::with_capacity(2),
            last: None,
            silent: false,
            last_t: None,
            interval: None,
        })
    }

    /// How long without a sample is a silence: ten typical intervals, at least [`SILENCE_MIN`].
    fn silence(&self) -> Duration {
        let typical = self.interval.map_or(Duration::ZERO, |s| Duration::from_secs_f64(s * SILENCE_INTERVALS));
        typical.max(SILENCE_MIN)
    }

    /// Notes a sample's arrival at `now`; the end of a silence is reported (how long none
    /// came), before the sample's own items.
    fn arrived(&mut self, now: Instant) -> Option<Acquired> {
        let since = self.last.map(|last| now.duration_since(last));
        self.last = Some(now);
        if std::mem::take(&mut self.silent) {
            let source = format!("zenoh:{}", self.key);
            return since.map(|outage| Acquired::Resumed { source, outage });
        }
        None
    }

    /// Follows the typical interval between frames by their times `t` (s).
    fn timed(&mut self, t: f64) {
        if let Some(step) = self.last_t.map(|last| t - last).filter(|s| s.is_finite() && *s > 0.0) {
            self.interval = Some(self.interval.map_or(step, |mean| mean + (step - mean) / 16.0));
        }
        self.last_t = Some(t);
    }

    /// The item a decoded message makes, and the gap before it, if any.
    fn take(&mut self, message: FrameMessage) -> Acquired {
        let FrameMessage { seq, t, values } = message;
        let gap = match self.counter.admit(seq) {
            Ok(gap) => gap,
            Err(last) => return Acquired::Bad(BadFrame::OutOfOrder { seq, last }),
        };
        self.timed(t);
        let item = if values.len() == self.measurements {
            Acquired::Frame { seq, t, values }
        } else {
            Acquired::Bad(BadFrame::WrongCount { seq, expected: self.measurements, got: values.len() })
        };
        match (gap > 0).then_some(gap) {
            Some(missing) => {
                self.pending.push_back(item);
                Acquired::Bad(BadFrame::Gap { seq, missing })
            }
            None => item,
        }
    }
}

impl FrameSource for ZenohSource {
    fn acquire(&mut self) -> Option<Result<Acquired, SourceError>> {
        if let Some(item) = self.pending.pop_front() {
            return Some(Ok(item));
        }
        // An error here is the session closing: the source ends. Before the first sample, and
        // once a silence is reported, it waits however long.
        let sample = match self.last.filter(|_| !self.silent) {
            Some(last) => match self.subscriber.recv_deadline(last + self.silence()) {
                Ok(Some(sample)) => sample,
                Ok(None) => {
                    self.silent = true;
                    let source = format!("zenoh:{}", self.key);
                    return Some(Ok(Acquired::Silent { source, after: last.elapsed() }));
                }
                Err(_) => return None,
            },
            None => self.subscriber.recv().ok()?,
        };
        let resumed = self.arrived(Instant::now());
        let payload = sample.payload().to_bytes();
        let item = match FrameMessage::decode(&payload) {
            Ok(message) => self.take(message),
            Err(error) => {
                let reason = error.to_string();
                Acquired::Bad(BadFrame::Message { key: sample.key_expr().as_str().to_owned(), reason })
            }
        };
        Some(Ok(match resumed {
            Some(resumed) => {
                self.pending.push_front(item);
                resumed
            }
            None => item,
        }))
    }

    /// Not live: Zenoh holds what is not read yet (1,024 samples), so the reader may wait.
    fn is_live(&self) -> bool {
        false
    }
}

impl std::fmt::Debug for ZenohSource {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ZenohSource").field("key", &self.key).field("last", &self.counter.last).finish_non_exhaustive()
    }
}

/// A stream's frame counter, followed.
#[derive(Debug, Clone, Copy, Default)]
struct Counter {
    /// The newest counter taken.
    last: Option<u64>,
}

impl Counter {
    /// Takes counter `seq`: how many frames were missed before it, or, for a frame older than
    /// the newest (and not so much older, nor 0, that the stream started again), the newest's counter.
    fn admit(&mut self, seq: u64) -> Result<u64, u64> {
        let missing = match self.last {
            Some(last) if seq <= last && last - seq <= RESTART && seq > 0 => return Err(last),
            Some(last) if seq > last => seq - last - 1,
            _ => 0,
        };
        self.last = Some(seq);
        Ok(missing)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_counter_tells_gaps_stale_frames_and_a_restarted_stream() {
        let mut counter = Counter::default();
        assert_eq!(counter.admit(5), Ok(0), "the first frame starts the count");
        assert_eq!(counter.admit(6), Ok(0));
        assert_eq!(counter.admit(9), Ok(2), "7 and 8 are missing");
        assert_eq!(counter.admit(8), Err(9), "8 came late: stale");
        assert_eq!(counter.admit(9), Err(9), "a repeat is stale too");
        assert_eq!(counter.admit(10), Ok(0), "the stream goes on from the newest");
        let mut restarted = Counter { last: Some(50_000) };
        assert_eq!(restarted.admit(49_000), Ok(0), "far back: the bridge started again");
        assert_eq!(restarted.admit(49_001), Ok(0));
        let mut early = Counter { last: Some(5) };
        assert_eq!(early.admit(0), Ok(0), "back to 0, however soon: started again");
        assert_eq!(early.admit(1), Ok(0));
        assert_eq!(early.admit(3), Ok(1));
    }
}
