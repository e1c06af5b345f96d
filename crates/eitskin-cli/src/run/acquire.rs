//! Acquisition on a thread of its own, or on the source's (a network library's callbacks),
//! handing the source's items over a channel.

use std::sync::mpsc;

use anyhow::{anyhow, Result};
use eitskin_io::source::{Acquired, Pushed, Source, SourceError};

/// Items a source that can wait may have ready before processing takes them.
const QUEUE_ITEMS: usize = 1024;

/// How long a source that can wait sleeps when the queue is full, before it tries again.
const QUEUE_WAIT: std::time::Duration = std::time::Duration::from_millis(1);

/// What acquires a source's items: a thread of its own, or the source's own threads.
#[derive(Debug)]
pub enum Acquisition {
    /// A thread reading the source.
    Thread(std::thread::JoinHandle<()>),
    /// The source, handing its items over itself; dropped, it stops.
    Pushed(Pushed),
    /// Nothing: the source failed as it started (its error is the channel's one item).
    Failed,
}

impl Acquisition {
    /// Waits for the reading thread to end, or stops the source: an error if the thread
    /// panicked.
    pub fn finish(self) -> Result<()> {
        match self {
            Acquisition::Thread(thread) => thread.join().map_err(|_| anyhow!("the acquisition thread panicked")),
            Acquisition::Pushed(pushed) => {
                drop(pushed);
                Ok(())
            }
            Acquisition::Failed => Ok(()),
        }
    }
}

/// Reads `source` on a thread of its own, handing what it yields over a channel: one without a
/// bound for a live source, so that it never waits for processing; a bounded one otherwise,
/// which the reader refills after a short sleep when it is full rather than blocking on it: a
/// blocked sender is woken by every item taken, two context switches a frame (8 µs of a
/// replay's 48 µs here). A source that hands its items over itself ([`Source::pushes`]: Zenoh's
/// callbacks) does so into a channel without a bound, on its own thread: no thread between the
/// network and the processing, and never waiting for it (a sensor behind holds its frames in
/// memory, not the network's thread).
pub fn start(source: Source) -> (mpsc::Receiver<Result<Acquired, SourceError>>, Acquisition) {
    start_notifying(source, || {})
}

/// [`start`], calling `notify` after each item handed over, and once when the source ended
/// (`serve` schedules the sensor then).
pub fn start_notifying(
    source: Source,
    notify: impl Fn() + Send + 'static,
) -> (mpsc::Receiver<Result<Acquired, SourceError>>, Acquisition) {
    if source.pushes() {
        let (tx, rx) = mpsc::channel();
        let mut to = Notifying { tx: Some(tx), notify };
        return match source.push(move |item| to.send(item)) {
            Ok(pushed) => (rx, Acquisition::Pushed(pushed)),
            // Refused at the start: that is the source's one item, and its end.
            Err(e) => {
                let (tx, rx) = mpsc::channel();
                // The receiver is held here: the send cannot fail.
                let _ = tx.send(Err(e));
                (rx, Acquisition::Failed)
            }
        };
    }
    let pump = move |source: Source, mut send: Box<dyn FnMut(Result<Acquired, SourceError>) -> bool + Send>| {
        for item in source {
            if !send(item) {
                break;
            }
            notify();
        }
        // The sender is dropped here, before the last call: whoever is notified sees the end.
        drop(send);
        notify();
    };
    if source.is_live() {
        let (tx, rx) = mpsc::channel();
        (rx, Acquisition::Thread(std::thread::spawn(move || pump(source, Box::new(move |item| tx.send(item).is_ok())))))
    } else {
        let (tx, rx) = mpsc::sync_channel(QUEUE_ITEMS);
        let send = move |mut item| loop {
            match tx.try_send(item) {
                Ok(()) => return true,
                Err(mpsc::TrySendError::Full(back)) => {
                    item = back;
                    std::thread::sleep(QUEUE_WAIT);
                }
                Err(mpsc::TrySendError::Disconnected(_)) => return false,
            }
        };
        (rx, Acquisition::Thread(std::thread::spawn(move || pump(source, Box::new(send)))))
    }
}

/// A pushing source's channel, notifying after each item, and once more when dropped (the
/// source ended), after the sender: whoever is notified sees the end.
struct Notifying<F: Fn()> {
    tx: Option<mpsc::Sender<Result<Acquired, SourceError>>>,
    notify: F,
}

impl<F: Fn()> Notifying<F> {
    fn send(&mut self, item: Result<Acquired, SourceError>) -> bool {
        let sent = self.tx.as_ref().is_some_and(|tx| tx.send(item).is_ok());
        (self.notify)();
        sent
    }
}

impl<F: Fn()> Drop for Notifying<F> {
    fn drop(&mut self) {
        drop(self.tx.take());
        (self.notify)();
    }
}
