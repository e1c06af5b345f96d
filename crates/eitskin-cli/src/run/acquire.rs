//! Acquisition on a thread of its own, handing the source's items over a channel.

use std::sync::mpsc;

use eitskin_io::source::{Acquired, Source, SourceError};

/// Items a source that can wait may have ready before processing takes them.
const QUEUE_ITEMS: usize = 1024;

/// How long a source that can wait sleeps when the queue is full, before it tries again.
const QUEUE_WAIT: std::time::Duration = std::time::Duration::from_millis(1);

/// Reads `source` on a thread of its own, handing what it yields over a channel: one without a
/// bound for a live source, so that it never waits for processing; a bounded one otherwise,
/// which the reader refills after a short sleep when it is full rather than blocking on it: a
/// blocked sender is woken by every item taken, two context switches a frame (8 µs of a
/// replay's 48 µs here).
pub fn start(source: Source) -> (mpsc::Receiver<Result<Acquired, SourceError>>, std::thread::JoinHandle<()>) {
    start_notifying(source, || {})
}

/// [`start`], calling `notify` after each item handed over, and once when the source ended
/// (`serve` schedules the sensor then).
pub fn start_notifying(
    source: Source,
    notify: impl Fn() + Send + 'static,
) -> (mpsc::Receiver<Result<Acquired, SourceError>>, std::thread::JoinHandle<()>) {
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
        (rx, std::thread::spawn(move || pump(source, Box::new(move |item| tx.send(item).is_ok()))))
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
        (rx, std::thread::spawn(move || pump(source, Box::new(send))))
    }
}
