//! [`ZenohSource`]: raw frames from a key that a board's bridge publishes on.

use std::sync::{mpsc, Arc, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use zenoh::pubsub::Subscriber;
use zenoh::sample::Sample;
use zenoh::{Session, Wait};

use super::{FrameMessage, MiddlewareError};
use crate::codec::BadFrame;
use crate::source::{Acquired, Deliver, FrameSource, Pushed, SourceError};

/// How far back a counter may go and still be a late frame of the same stream (a sample of one
/// publisher comes in order over TCP; several publishers on one key may interleave); further
/// back, or back to 0, the bridge started again, and the frame is taken.
const RESTART: u64 = 16;

/// The shortest silence reported, and how many of its frame intervals a source may miss
/// before it is: a board at 100 frames/s is silent after 1 s, one at 1 frame/s after 10 s.
const SILENCE_MIN: Duration = Duration::from_secs(1);
const SILENCE_INTERVALS: f64 = 10.0;

/// The longest step between two frames' times taken as their interval (s).
const MAX_INTERVAL_S: f64 = 60.0;

/// Frames of [`FrameMessage`]s on one key: each checked for its count, the counter followed as
/// a serial board's is (frames missing before one are reported as a gap, a frame older than
/// the newest is dropped as stale), a sample that is not a frame reported with its key. A live
/// source waits for the next sample, however long, and ends only with the session; once frames
/// have come, a pause of ten of their intervals (at least a second) is reported
/// ([`Acquired::Silent`]), and so are the frames coming again ([`Acquired::Resumed`]).
///
/// It subscribes when started: [`FrameSource::push`] hands each sample's items over on Zenoh's
/// own thread, as it comes (no thread of the caller's between the network and the frame's
/// processing; a watch thread, waking once a silence is due, reports silences); read
/// ([`FrameSource::acquire`]), it pushes to a channel of its own and reads that.
pub struct ZenohSource {
    session: Session,
    key: String,
    measurements: usize,
    /// Read: the items its own push hands over, once the first is asked for.
    read: Option<(mpsc::Receiver<Result<Acquired, SourceError>>, Pushing)>,
}

impl ZenohSource {
    /// A source on `session` of `key` (wildcards allowed: several bridges' frames on one
    /// stream are then one counter's, so give one key per board) for frames of `measurements`
    /// values; the key checked now, subscribed to when started.
    pub fn open(session: &Session, key: &str, measurements: usize) -> Result<ZenohSource, MiddlewareError> {
        zenoh::key_expr::KeyExpr::try_from(key).map_err(|e| MiddlewareError::Key {
            what: "--source zenoh:",
            key: key.to_owned(),
            use_: "subscribe to",
            reason: e.to_string(),
        })?;
        Ok(ZenohSource { session: session.clone(), key: key.to_owned(), measurements, read: None })
    }

    /// Subscribes, each sample's items handed to `deliver` on Zenoh's thread, silences by a
    /// watch thread's.
    fn start(&self, deliver: Deliver) -> Result<Pushing, SourceError> {
        let shared = Arc::new(Mutex::new(Shared {
            stream: Stream::new(&self.key, self.measurements),
            deliver: Some(deliver),
            watch: None,
        }));
        let refused = |e: String| SourceError::Zenoh { spec: format!("zenoh:{}", self.key), reason: e };
        let watching = Arc::clone(&shared);
        let watch = std::thread::Builder::new()
            .name(format!("zenoh-watch {}", self.key))
            .spawn(move || watch(&watching))
            .map_err(|e| refused(e.to_string()))?;
        lock(&shared).watch = Some(watch.thread().clone());
        let on_sample = OnSample(Arc::clone(&shared));
        let subscriber =
            self.session.declare_subscriber(self.key.clone()).callback(move |sample| on_sample.take(&sample)).wait();
        let mut pushing = Pushing { subscriber: None, shared, watch: Some(watch) };
        // Refused, `pushing` is dropped: the watch thread ends.
        pushing.subscriber = Some(subscriber.map_err(|e| refused(e.to_string()))?);
        Ok(pushing)
    }
}

impl FrameSource for ZenohSource {
    fn acquire(&mut self) -> Option<Result<Acquired, SourceError>> {
        if self.read.is_none() {
            let (tx, rx) = mpsc::channel();
            match self.start(Box::new(move |item| tx.send(item).is_ok())) {
                Ok(pushing) => self.read = Some((rx, pushing)),
                Err(e) => return Some(Err(e)),
            }
        }
        // The channel ends with the subscription: the session closed.
        self.read.as_ref().and_then(|(items, _)| items.recv().ok())
    }

    /// Not live: Zenoh's thread hands each sample over at once, never waiting for the reader.
    fn is_live(&self) -> bool {
        false
    }

    fn pushes(&self) -> bool {
        true
    }

    fn push(self: Box<Self>, deliver: Deliver) -> Result<Pushed, SourceError> {
        Ok(Pushed::new(Box::new(self.start(deliver)?)))
    }
}

impl std::fmt::Debug for ZenohSource {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ZenohSource")
            .field("key", &self.key)
            .field("started", &self.read.is_some())
            .finish_non_exhaustive()
    }
}

/// A started source: its subscription and watch thread, both stopped when it is dropped.
struct Pushing {
    subscriber: Option<Subscriber<()>>,
    shared: Arc<Mutex<Shared>>,
    watch: Option<JoinHandle<()>>,
}

impl Drop for Pushing {
    fn drop(&mut self) {
        // Undeclared, its callback dropped: `deliver` goes, and the watch thread ends.
        drop(self.subscriber.take());
        close(&self.shared);
        if let Some(watch) = self.watch.take() {
            // A panic of the watch thread was its own; the source is over either way.
            let _ = watch.join();
        }
    }
}

/// What the callback and the watch thread share: the stream followed, where its items go
/// (`None` once it ended), and the watch thread, woken when it does.
struct Shared {
    stream: Stream,
    deliver: Option<Deliver>,
    watch: Option<std::thread::Thread>,
}

fn lock(shared: &Mutex<Shared>) -> MutexGuard<'_, Shared> {
    shared.lock().unwrap_or_else(|e| e.into_inner())
}

/// Ends the source: `deliver` dropped (its reader sees the end), the watch thread woken to end.
fn close(shared: &Mutex<Shared>) {
    let mut shared = lock(shared);
    shared.deliver = None;
    if let Some(watch) = &shared.watch {
        watch.unpark();
    }
}

/// The subscription's callback: each sample's items delivered; dropped (the subscription
/// undeclared, the session closed), the source ends.
struct OnSample(Arc<Mutex<Shared>>);

impl OnSample {
    fn take(&self, sample: &Sample) {
        let mut shared = lock(&self.0);
        let Shared { stream, deliver, .. } = &mut *shared;
        let Some(to) = deliver.as_mut() else { return };
        let mut going = true;
        stream.sample(sample, Instant::now(), |item| {
            going = going && to(Ok(item));
        });
        if !going {
            drop(shared);
            close(&self.0);
        }
    }
}

impl Drop for OnSample {
    fn drop(&mut self) {
        close(&self.0);
    }
}

/// The watch thread: reports a silence once it is due, until the source ends.
fn watch(shared: &Mutex<Shared>) {
    loop {
        let mut guard = lock(shared);
        let Shared { stream, deliver, .. } = &mut *guard;
        let Some(to) = deliver.as_mut() else { return };
        let now = Instant::now();
        // Before the first frame, and once a silence is reported, only a frame wakes it (the
        // callback does not: it waits a silence's shortest length and looks again).
        let wait = match stream.silence_due() {
            Some(due) if due <= now => {
                let silent = stream.fall_silent(now);
                if !to(Ok(silent)) {
                    drop(guard);
                    close(shared);
                    return;
                }
                continue;
            }
            // At most the shortest silence: an interval that shrank is seen within it.
            Some(due) => (due - now).min(SILENCE_MIN),
            None => SILENCE_MIN,
        };
        drop(guard);
        std::thread::park_timeout(wait);
    }
}

/// One key's frames followed as samples come: the counter, the last arrival and whether the
/// silence after it was reported, and the frames' typical interval.
struct Stream {
    key: String,
    measurements: usize,
    counter: Counter,
    /// When the last sample came, and whether the silence after it was reported.
    last: Option<Instant>,
    silent: bool,
    /// The last frame's time and the typical interval between frames (s, a running mean), by
    /// the frames' own times: a backlog read at once does not shorten it.
    last_t: Option<f64>,
    interval: Option<f64>,
}

impl Stream {
    fn new(key: &str, measurements: usize) -> Stream {
        let (counter, last, silent, last_t, interval) = (Counter::default(), None, false, None, None);
        Stream { key: key.to_owned(), measurements, counter, last, silent, last_t, interval }
    }

    /// How long without a sample is a silence: ten typical intervals, at least [`SILENCE_MIN`].
    fn silence(&self) -> Duration {
        let typical = self.interval.and_then(|s| Duration::try_from_secs_f64(s * SILENCE_INTERVALS).ok());
        typical.unwrap_or(Duration::ZERO).max(SILENCE_MIN)
    }

    /// When the silence after the last sample is to be reported (`None`: none came, or it was).
    fn silence_due(&self) -> Option<Instant> {
        self.last.filter(|_| !self.silent).and_then(|last| last.checked_add(self.silence()))
    }

    /// Reports the silence since the last sample, at `now`.
    fn fall_silent(&mut self, now: Instant) -> Acquired {
        self.silent = true;
        let after = self.last.map_or(Duration::ZERO, |last| now.duration_since(last));
        Acquired::Silent { source: format!("zenoh:{}", self.key), after }
    }

    /// A sample's items, in order, to `out`: the end of a silence (how long none came), the
    /// gap before its frame, and the frame (or what is wrong with it).
    fn sample(&mut self, sample: &Sample, now: Instant, mut out: impl FnMut(Acquired)) {
        let since = self.last.map(|last| now.duration_since(last));
        self.last = Some(now);
        if std::mem::take(&mut self.silent) {
            if let Some(outage) = since {
                out(Acquired::Resumed { source: format!("zenoh:{}", self.key), outage });
            }
        }
        let message = match FrameMessage::decode(&sample.payload().to_bytes()) {
            Ok(message) => message,
            Err(error) => {
                let reason = error.to_string();
                return out(Acquired::Bad(BadFrame::Message { key: sample.key_expr().as_str().to_owned(), reason }));
            }
        };
        let FrameMessage { seq, t, values } = message;
        let gap = match self.counter.admit(seq) {
            Ok(gap) => gap,
            Err(last) => return out(Acquired::Bad(BadFrame::OutOfOrder { seq, last })),
        };
        self.timed(t);
        if gap > 0 {
            out(Acquired::Bad(BadFrame::Gap { seq, missing: gap }));
        }
        out(if values.len() == self.measurements {
            Acquired::Frame { seq, t, values }
        } else {
            Acquired::Bad(BadFrame::WrongCount { seq, expected: self.measurements, got: values.len() })
        });
    }

    /// Follows the typical interval between frames by their times `t` (s).
    fn timed(&mut self, t: f64) {
        // A step of the bridge's clock past a minute is no frame interval (a clock set, a
        // restart): it would put a silence off for hours.
        let step = self.last_t.map(|last| t - last).filter(|s| s.is_finite() && *s > 0.0 && *s <= MAX_INTERVAL_S);
        if let Some(step) = step {
            self.interval = Some(self.interval.map_or(step, |mean| mean + (step - mean) / 16.0));
        }
        self.last_t = Some(t);
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

    use crate::middleware::{Encoding, ZenohSettings};
    use crate::source::Source;

    /// A session on its own (a peer listening on loopback only, no scouting): what it publishes,
    /// its own subscribers get.
    fn session() -> Session {
        let settings = ZenohSettings {
            listen: vec!["tcp/127.0.0.1:0".into()],
            multicast_scouting: false,
            ..ZenohSettings::default()
        };
        crate::middleware::session::open(&settings).unwrap()
    }

    fn put(session: &Session, key: &str, seq: u64, values: usize) {
        let message = FrameMessage { seq, t: seq as f64 * 0.01, values: vec![1.0; values] };
        let mut bytes = Vec::new();
        Encoding::Cbor.encode_into(&message, &mut bytes).unwrap();
        session.put(key, bytes).wait().unwrap();
    }

    #[test]
    fn a_read_source_reports_gaps_wrong_counts_and_a_silence_and_its_end() {
        let session = session();
        let mut source = Source::new(Box::new(ZenohSource::open(&session, "test/board", 3).unwrap()), None);
        // The subscription is made as the first item is asked for: the frames come meanwhile.
        let putter = {
            let session = session.clone();
            std::thread::spawn(move || {
                std::thread::sleep(Duration::from_millis(300));
                [(0, 3), (1, 3), (3, 3), (4, 2)].iter().for_each(|&(seq, n)| put(&session, "test/board", seq, n));
                // Silent for 1.5 s, past the shortest silence (the frames are 10 ms apart).
                std::thread::sleep(Duration::from_millis(1500));
                put(&session, "test/board", 5, 3);
            })
        };
        let mut said = Vec::new();
        for item in source.by_ref().take(7) {
            said.push(match item.unwrap() {
                Acquired::Frame { seq, .. } => format!("frame {seq}"),
                Acquired::Bad(BadFrame::Gap { seq, missing }) => format!("gap {missing} before {seq}"),
                Acquired::Bad(BadFrame::WrongCount { seq, got, .. }) => format!("{got} values in {seq}"),
                Acquired::Silent { after, .. } => format!("silent {}", after >= SILENCE_MIN),
                Acquired::Resumed { outage, .. } => format!("resumed {}", outage >= Duration::from_millis(1400)),
                other => format!("{other:?}"),
            });
        }
        assert_eq!(
            said,
            ["frame 0", "frame 1", "gap 1 before 3", "frame 3", "2 values in 4", "silent true", "resumed true"]
        );
        assert!(matches!(source.next(), Some(Ok(Acquired::Frame { seq: 5, .. }))));
        putter.join().unwrap();
        // The session closed, the source ends.
        session.close().wait().unwrap();
        assert!(source.next().is_none());
    }

    #[test]
    fn a_pushing_source_hands_over_up_to_its_limit_then_ends() {
        let session = session();
        let source = Source::new(Box::new(ZenohSource::open(&session, "test/pushed", 2).unwrap()), Some(3));
        assert!(source.pushes());
        let (tx, rx) = mpsc::channel();
        let pushed = source.push(move |item| tx.send(item.map(|a| format!("{a:?}"))).is_ok()).unwrap();
        (0..5).for_each(|seq| put(&session, "test/pushed", seq, 2));
        let got: Vec<String> = rx.iter().map(Result::unwrap).collect();
        assert_eq!(got.len(), 3, "three frames, then the end: {got:?}");
        assert!(got.iter().all(|g| g.starts_with("Frame")), "{got:?}");
        drop(pushed);
    }

    #[test]
    fn a_bridges_clock_that_jumps_does_not_put_a_silence_off() {
        let mut stream = Stream::new("board", 3);
        for t in [0.0, 0.01, 0.02, 1e18, 1e18 + 0.01, f64::MAX, f64::NAN] {
            stream.timed(t);
        }
        assert_eq!(stream.silence(), SILENCE_MIN, "ten 10-ms intervals are under the shortest");
        stream.last = Some(Instant::now());
        assert!(stream.silence_due().is_some());
    }

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
