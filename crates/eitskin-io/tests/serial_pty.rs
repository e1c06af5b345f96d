//! The serial source over real pseudo-terminals, no hardware. A board is played by the
//! master side of a pty pair and reached through a symlink, as udev's `/dev/serial/by-id/…` names
//! are. Every good frame comes through in order with its values, every bad one as the right
//! [`BadFrame`]; pulling the board (closing the pty) is reported, the half frame before it is
//! reported as bad, and plugging a new board in behind the same name resumes decoding.
#![cfg(unix)]

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use eitskin_io::codec::{BadFrame, LinesDecoder};
use eitskin_io::source::serial::{SerialSource, SourceEvent};
use serialport::{SerialPort, TTYPort};

/// The longest any step may take before the test gives up; never reached when things work.
const DEADLINE: Duration = Duration::from_secs(5);

/// What an event should be, without its arrival time.
#[derive(Debug, Clone, PartialEq)]
enum Expected {
    Frame { seq: u64, values: Vec<f64> },
    Bad(BadFrame),
    Disconnected { path: PathBuf },
    Reconnected { path: PathBuf },
}

fn expected(event: &SourceEvent) -> Expected {
    match event {
        SourceEvent::Frame { frame, .. } => Expected::Frame { seq: frame.seq, values: frame.values.clone() },
        SourceEvent::Bad(bad) => Expected::Bad(bad.clone()),
        SourceEvent::Disconnected { path, .. } => Expected::Disconnected { path: path.clone() },
        SourceEvent::Reconnected { path, .. } => Expected::Reconnected { path: path.clone() },
    }
}

/// A new pty pair: the master plays the board, the slave is the device node the source opens.
fn board() -> (TTYPort, TTYPort) {
    let (mut master, slave) = TTYPort::pair().expect("this system should provide pseudo-terminals");
    master.set_timeout(DEADLINE).unwrap();
    (master, slave)
}

/// Points the symlink `link` at the slave's device node, replacing what it pointed at atomically.
fn point(link: &Path, slave: &TTYPort) {
    let target = slave.name().expect("a pty slave has a name");
    let staged = link.with_extension("new");
    let _ = std::fs::remove_file(&staged);
    std::os::unix::fs::symlink(target, &staged).unwrap();
    std::fs::rename(&staged, link).unwrap();
}

/// Polls until `done` holds for the events gathered so far; panics after [`DEADLINE`].
fn poll_until(
    source: &mut SerialSource,
    events: &mut Vec<SourceEvent>,
    what: &str,
    done: impl Fn(&SerialSource, &[SourceEvent]) -> bool,
) {
    let start = Instant::now();
    while !done(source, events) {
        assert!(start.elapsed() < DEADLINE, "gave up waiting for {what}; got {:?}", &events[..]);
        source.poll(events);
    }
}

/// A tiny seeded xorshift64 generator, so that the write sizes are the same on every run.
struct XorShift(u64);

impl XorShift {
    /// A number in `1..=max`.
    fn size(&mut self, max: usize) -> usize {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        1 + (self.0 % max as u64) as usize
    }
}

/// The board's stream of `count` lines, good and bad, with the events it should give.
fn stream(count: u64) -> (Vec<String>, Vec<Expected>) {
    let mut lines = Vec::new();
    let mut events = Vec::new();
    for seq in 0..count {
        let x = seq as f64;
        let (line, event) = match seq % 50 {
            10 => ("1,2,3".to_owned(), Expected::Bad(BadFrame::WrongCount { seq, expected: 4, got: 3 })),
            20 => ("1,x,3,4".to_owned(), Expected::Bad(BadFrame::NotANumber { seq, field: 2, text: "x".into() })),
            // A lost channel is passed on (∞ rather than NaN, so that the frames compare equal).
            30 => ("1,2,inf,4".to_owned(), Expected::Frame { seq, values: vec![1.0, 2.0, f64::INFINITY, 4.0] }),
            _ => {
                let values = vec![x, x + 0.5, -x, 1e-3 * x];
                let line = format!("{},{},{},{}", values[0], values[1], values[2], values[3]);
                (line, Expected::Frame { seq, values })
            }
        };
        lines.push(line + if seq % 7 == 0 { "\r\n" } else { "\n" });
        events.push(event);
    }
    (lines, events)
}

#[test]
fn frames_survive_an_unplug_and_a_new_board_behind_the_same_name() {
    let dir = tempfile::Builder::new().prefix("eitskin-serial-").tempdir().expect("a temporary folder");
    let link = dir.path().join("ttyEIT");
    let (mut master, slave) = board();
    point(&link, &slave);
    let mut source = SerialSource::open(&link, 115_200, || Box::new(LinesDecoder::new(4))).unwrap();
    assert!(source.is_connected());
    let mut events = Vec::new();

    // The board sends 300 lines at speed, in writes of random sizes that tear lines apart, and one
    // line torn across two writes with a pause between, so that the source reads it in two pieces.
    let (lines, want) = stream(300);
    let bytes: Vec<u8> = lines.concat().into_bytes();
    let torn_at = lines[..150].concat().len() + 3;
    let writer = std::thread::spawn(move || {
        let mut sizes = XorShift(0x5EED);
        let (before, after) = bytes.split_at(torn_at);
        for part in [before, after] {
            let mut rest = part;
            while !rest.is_empty() {
                let n = sizes.size(700).min(rest.len());
                master.write_all(&rest[..n]).unwrap();
                rest = &rest[n..];
            }
            std::thread::sleep(Duration::from_millis(100));
        }
        master
    });
    poll_until(&mut source, &mut events, "300 frames", |_, events| events.len() >= want.len());
    let mut master = writer.join().unwrap();
    let got: Vec<Expected> = events.iter().map(expected).collect();
    assert_eq!(got, want);
    let received: Vec<Instant> = events
        .iter()
        .filter_map(|e| if let SourceEvent::Frame { received, .. } = e { Some(*received) } else { None })
        .collect();
    assert!(received.windows(2).all(|w| w[0] <= w[1]), "frames are stamped in the order they arrive");

    // Half a frame, then the board is pulled: the half frame is torn, and the outage is reported.
    // As udev does, the name goes with the device (and so cannot reach a pty another process
    // opens meanwhile under the number just freed).
    events.clear();
    let total = source.bytes_received();
    master.write_all(b"5,6").unwrap();
    poll_until(&mut source, &mut events, "the half frame's bytes", |source, _| source.bytes_received() == total + 3);
    drop(master);
    drop(slave);
    std::fs::remove_file(&link).unwrap();
    poll_until(&mut source, &mut events, "the disconnect", |_, events| events.len() >= 2);
    let got: Vec<Expected> = events.iter().map(expected).collect();
    // Cut off, never decoded: "5,6" could have been the start of "5,6,7,8".
    let torn = BadFrame::Torn { seq: 300, bytes: 3 };
    assert_eq!(got, [Expected::Bad(torn), Expected::Disconnected { path: link.clone() }]);
    assert!(matches!(&events[1], SourceEvent::Disconnected { error, .. } if !error.is_empty()));
    assert!(!source.is_connected());

    // While the name is gone, polling reports nothing and returns.
    events.clear();
    for _ in 0..5 {
        source.poll(&mut events);
    }
    assert_eq!(events, []);
    assert!(!source.is_connected());

    // A new board behind the same name: the source reopens it and decodes with a fresh decoder.
    let (mut master, slave) = board();
    point(&link, &slave);
    poll_until(&mut source, &mut events, "the reconnect", |_, events| !events.is_empty());
    assert_eq!(events.iter().map(expected).collect::<Vec<_>>(), [Expected::Reconnected { path: link.clone() }]);
    assert!(matches!(&events[0], SourceEvent::Reconnected { outage, .. } if *outage > Duration::ZERO));
    assert!(source.is_connected());
    events.clear();
    master.write_all(b"9,8,7,6\n1,2\n").unwrap();
    poll_until(&mut source, &mut events, "frames from the new board", |_, events| events.len() >= 2);
    let got: Vec<Expected> = events.iter().map(expected).collect();
    let want = [
        Expected::Frame { seq: 0, values: vec![9.0, 8.0, 7.0, 6.0] },
        Expected::Bad(BadFrame::WrongCount { seq: 1, expected: 4, got: 2 }),
    ];
    assert_eq!(got, want);
    drop(slave);
}
