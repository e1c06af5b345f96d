//! The live web viewer of `eitskin run --viewer`: a local page with the image as a heat map under
//! the pseudo-array grid, a 3-D surface of it, the touches with unit and force, a force strip
//! chart, the counters and a button that re-takes the reference.
//!
//! The server (axum on a single-threaded tokio runtime) runs on its own thread; the processing
//! loop stays synchronous. Frames go to the server over a bounded channel and are never waited
//! for: when the channel is full the frame is dropped for the viewer and counted, so a slow page
//! never stalls acquisition or processing. The server passes each frame to every page over a
//! WebSocket as one JSON text message; a page that falls behind skips frames, and those count as
//! dropped too. Pages send commands back (`{"command":"retake_reference"}`), which the processing
//! loop reads with [`Viewer::commands`] between frames.
//!
//! Messages to the page: first `{"type":"setup", …}` ([`Setup`]: image grid and mask, outline,
//! electrodes, pseudo-array, length unit), then `{"type":"frame", …}` per frame and
//! `{"type":"event", …}` per event line (bad frame, port).
//!
//! Not for: remote access (it binds to 127.0.0.1 unless told otherwise, and has no
//! authentication), nor for recording (that is `--record`).

use std::net::SocketAddr;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{mpsc, Arc};

use anyhow::{Context, Result};
use axum::extract::ws::{Message, Utf8Bytes, WebSocket, WebSocketUpgrade};
use axum::extract::State;
use axum::response::{Html, IntoResponse};
use axum::routing::get;
use axum::Router;
use eitskin_io::stream::{Event, FrameLine};
use serde::{Deserialize, Serialize};
use tokio::sync::broadcast;

/// The page, served at `/`.
const PAGE: &str = include_str!("../assets/viewer.html");

/// Frames the processing loop may have handed over and the server not yet taken.
const QUEUE_FRAMES: usize = 4;

/// Frames a page may fall behind before it skips some.
const PAGE_BACKLOG: usize = 8;

/// The address of `--viewer` without a value.
pub const DEFAULT_ADDR: &str = "127.0.0.1:8765";

/// Parses `--viewer`'s ADDR: `HOST:PORT`, or a bare `PORT` on 127.0.0.1 (port 0: any free one).
pub fn parse_addr(text: &str) -> Result<SocketAddr, String> {
    if let Ok(port) = text.parse::<u16>() {
        return Ok(SocketAddr::from(([127, 0, 0, 1], port)));
    }
    text.parse().map_err(|_| format!("{text:?} is not an address like 127.0.0.1:8765 (or a port like 8765)"))
}

/// A command from a page.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(tag = "command", rename_all = "snake_case")]
pub enum Command {
    /// Forget the reference and take a new one from the next frames.
    RetakeReference,
}

/// What a page needs to draw frames, sent once when it connects; lengths in the spec's unit.
#[derive(Debug, Clone, Serialize)]
pub struct Setup {
    /// The spec's length unit, "mm" or "m".
    pub unit: &'static str,
    /// Columns and rows of the image `[nx, ny]`.
    pub image_size: [usize; 2],
    /// The box the image covers, `[[x_min, y_min], [x_max, y_max]]`.
    pub image_bounds: [[f64; 2]; 2],
    /// Whether each pixel lies inside the sensor, row-major from the top row.
    pub inside: Vec<bool>,
    /// The outline's corners, counter-clockwise (empty for a circle).
    pub outline: Vec<[f64; 2]>,
    /// Centre of each electrode on the boundary (electrode 1 first).
    pub electrodes: Vec<[f64; 2]>,
    /// Units of the pseudo-array along x and y `[nx, ny]`.
    pub grid: [usize; 2],
    /// The box the pseudo-array covers.
    pub grid_bounds: [[f64; 2]; 2],
    /// Each unit's area, from 1, units row-major from the bottom-left.
    pub areas: Vec<usize>,
    /// Whether the grid is a calibration's (forces are shown) or the default 5 × 5 one.
    pub calibrated: bool,
    /// The colour map's stops from −1 (a decrease) to +1, sRGB ([`eitskin::colour::COLOUR_STOPS`]):
    /// the page draws with the map the CLI's figures and Python's plots use.
    pub colours: &'static [[u8; 3]],
}

/// One frame for the page: the stdout line's fields plus the image.
#[derive(Debug, Serialize)]
pub struct Frame<'a> {
    /// The frame's line, as printed (counters with `viewer_dropped`).
    #[serde(flatten)]
    pub line: &'a FrameLine,
    /// Reference frames collected and needed, while referencing.
    pub referencing: Option<[usize; 2]>,
    /// Δσ per pixel, in S/m, row-major from the top row (all 0 while referencing).
    pub image: &'a [f32],
}

/// The processing loop's end of a running viewer.
pub struct Viewer {
    addr: SocketAddr,
    frames: tokio::sync::mpsc::Sender<String>,
    commands: mpsc::Receiver<Command>,
    dropped: Arc<AtomicU64>,
    /// The pages' channel: how many pages are open.
    pages: broadcast::Sender<Utf8Bytes>,
}

/// What the server's handlers share.
struct Shared {
    setup: Utf8Bytes,
    frames: broadcast::Sender<Utf8Bytes>,
    commands: mpsc::Sender<Command>,
    dropped: Arc<AtomicU64>,
}

impl Viewer {
    /// Binds `addr` and starts serving on a thread of its own; returns once it is listening.
    pub fn start(addr: SocketAddr, setup: &Setup) -> Result<Viewer> {
        let listener = std::net::TcpListener::bind(addr).with_context(|| {
            format!("the viewer cannot listen on {addr} (is the port in use? try --viewer 127.0.0.1:0)")
        })?;
        listener.set_nonblocking(true).context("the viewer's socket")?;
        let addr = listener.local_addr().context("the viewer's socket")?;
        let runtime = tokio::runtime::Builder::new_current_thread()
            .enable_io()
            .build()
            .context("starting the viewer's runtime")?;
        let (frames, queue) = tokio::sync::mpsc::channel(QUEUE_FRAMES);
        let (command_tx, commands) = mpsc::channel();
        let dropped = Arc::new(AtomicU64::new(0));
        let pages = broadcast::channel(PAGE_BACKLOG).0;
        let shared = Arc::new(Shared {
            setup: Utf8Bytes::from(serde_json::to_string(&Tagged { kind: "setup", body: setup })?),
            frames: pages.clone(),
            commands: command_tx,
            dropped: Arc::clone(&dropped),
        });
        std::thread::Builder::new()
            .name("viewer".into())
            .spawn(move || {
                if let Err(e) = runtime.block_on(serve(listener, shared, queue)) {
                    eprintln!("eitskin run: the viewer stopped: {e:#}");
                }
            })
            .context("starting the viewer's thread")?;
        Ok(Viewer { addr, frames, commands, dropped, pages })
    }

    /// The address the server listens on (the real port when asked for port 0).
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// Messages that did not reach a page: dropped because the server was behind, plus those
    /// each page skipped because it was behind.
    pub fn dropped(&self) -> u64 {
        self.dropped.load(Ordering::Relaxed)
    }

    /// Hands a frame to the server without waiting; when the queue is full it is dropped and
    /// counted, and not even serialised.
    pub fn offer_frame(&self, frame: &Frame<'_>) {
        self.offer("frame", frame);
    }

    /// Hands an event line (bad frame, port, reference) to the server, as [`Viewer::offer_frame`].
    pub fn offer_event(&self, line: &Event) {
        self.offer("event", line);
    }

    fn offer(&self, kind: &'static str, body: &impl Serialize) {
        // With no page open there is no one to drop a frame for: none is made, none counted.
        if self.pages.receiver_count() == 0 {
            return;
        }
        // `try_reserve` is `try_send` with the message built only once there is room for it.
        let Ok(permit) = self.frames.try_reserve() else {
            self.dropped.fetch_add(1, Ordering::Relaxed);
            return;
        };
        match serde_json::to_string(&Tagged { kind, body }) {
            Ok(text) => permit.send(text),
            Err(_) => {
                self.dropped.fetch_add(1, Ordering::Relaxed);
            }
        }
    }

    /// The commands pages sent since the last call, oldest first; never waits.
    pub fn commands(&self) -> mpsc::TryIter<'_, Command> {
        self.commands.try_iter()
    }
}

/// A message with its `"type"` field first.
#[derive(Serialize)]
struct Tagged<'a, T: Serialize> {
    #[serde(rename = "type")]
    kind: &'static str,
    #[serde(flatten)]
    body: &'a T,
}

/// Serves the page and the WebSocket until the process ends.
async fn serve(
    listener: std::net::TcpListener,
    shared: Arc<Shared>,
    mut queue: tokio::sync::mpsc::Receiver<String>,
) -> Result<()> {
    let listener = tokio::net::TcpListener::from_std(listener)?;
    let pages = shared.frames.clone();
    tokio::spawn(async move {
        while let Some(text) = queue.recv().await {
            // No page connected is no error: the frame simply has no one to go to.
            let _ = pages.send(Utf8Bytes::from(text));
        }
    });
    let app = Router::new().route("/", get(page)).route("/ws", get(upgrade)).with_state(shared);
    axum::serve(listener, app).await?;
    Ok(())
}

async fn page() -> Html<&'static str> {
    Html(PAGE)
}

async fn upgrade(ws: WebSocketUpgrade, State(shared): State<Arc<Shared>>) -> impl IntoResponse {
    ws.on_upgrade(move |socket| talk(socket, shared))
}

/// One page: the setup, then every frame as it comes; commands the other way.
async fn talk(mut socket: WebSocket, shared: Arc<Shared>) {
    let mut frames = shared.frames.subscribe();
    if socket.send(Message::Text(shared.setup.clone())).await.is_err() {
        return;
    }
    loop {
        tokio::select! {
            frame = frames.recv() => match frame {
                Ok(text) => {
                    if socket.send(Message::Text(text)).await.is_err() {
                        return;
                    }
                }
                Err(broadcast::error::RecvError::Lagged(skipped)) => {
                    shared.dropped.fetch_add(skipped, Ordering::Relaxed);
                }
                Err(broadcast::error::RecvError::Closed) => return,
            },
            message = socket.recv() => match message {
                Some(Ok(Message::Text(text))) => match serde_json::from_str::<Command>(&text) {
                    Ok(command) => {
                        if shared.commands.send(command).is_err() {
                            return;
                        }
                    }
                    Err(e) => eprintln!("eitskin run: the viewer ignored {:?}: {e}", text.as_str()),
                },
                Some(Ok(Message::Close(_))) | Some(Err(_)) | None => return,
                Some(Ok(_)) => {}
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn addresses_parse_with_a_bare_port_on_localhost() {
        assert_eq!(parse_addr("8765"), Ok(SocketAddr::from(([127, 0, 0, 1], 8765))));
        assert_eq!(parse_addr("0.0.0.0:9000"), Ok(SocketAddr::from(([0, 0, 0, 0], 9000))));
        assert_eq!(parse_addr(DEFAULT_ADDR), Ok(SocketAddr::from(([127, 0, 0, 1], 8765))));
        assert!(parse_addr("localhost").unwrap_err().contains("\"localhost\" is not an address"));
    }

    #[test]
    fn commands_are_json_with_a_command_field() {
        let c: Command = serde_json::from_str(r#"{"command":"retake_reference"}"#).unwrap();
        assert_eq!(c, Command::RetakeReference);
        assert!(serde_json::from_str::<Command>(r#"{"command":"format_disk"}"#).is_err());
    }

    #[test]
    fn a_full_queue_drops_and_counts_without_waiting() {
        // A viewer whose server never takes anything from the queue.
        let (frames, mut queue) = tokio::sync::mpsc::channel(QUEUE_FRAMES);
        let (_command_tx, commands) = mpsc::channel();
        let pages = broadcast::channel(PAGE_BACKLOG).0;
        let viewer = Viewer {
            addr: SocketAddr::from(([127, 0, 0, 1], 0)),
            frames,
            commands,
            dropped: Arc::new(AtomicU64::new(0)),
            pages: pages.clone(),
        };
        // No page open: nothing is queued, nothing counted as dropped.
        let line = FrameLine::default();
        viewer.offer_frame(&Frame { line: &line, referencing: None, image: &[0.5] });
        assert!(viewer.dropped() == 0 && queue.try_recv().is_err());
        let _page = pages.subscribe();
        for seq in 0..10 {
            let line = FrameLine { seq, ..FrameLine::default() };
            viewer.offer_frame(&Frame { line: &line, referencing: None, image: &[0.5] });
        }
        assert_eq!(viewer.dropped(), 10 - QUEUE_FRAMES as u64);
        for seq in 0..QUEUE_FRAMES as u64 {
            let message: serde_json::Value = serde_json::from_str(&queue.try_recv().unwrap()).unwrap();
            assert_eq!(
                (&message["type"], &message["seq"], &message["image"][0]),
                (&"frame".into(), &seq.into(), &0.5.into())
            );
        }
        assert!(queue.try_recv().is_err(), "the dropped frames never reached the queue");
        viewer.offer_event(&Event::Bad { seq: None, reason: "garbage".into() });
        let message: serde_json::Value = serde_json::from_str(&queue.try_recv().unwrap()).unwrap();
        assert_eq!(message, serde_json::json!({"type": "event", "event": "bad", "seq": null, "reason": "garbage"}));
    }
}
