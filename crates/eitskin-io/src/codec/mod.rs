//! Frame codecs: turn the byte stream of an EIT acquisition board into frames.
//!
//! One frame is the measurements of one cycle, in protocol order. A decoder is a pure,
//! incremental state machine: feed it the chunks a serial port delivers, however they are cut
//! (a frame split across chunks, several frames in one chunk), and it appends an [`Event`] for
//! each frame-sized piece of input. Bad input never stops the stream: a bad frame becomes one
//! [`Event::Bad`] saying what and where, is skipped, and decoding goes on with the next frame.
//!
//! * [`LinesDecoder`]: one frame per text line (OpenEIT and most hobby firmware).
//! * [`BinaryDecoder`]: the framed binary format of [`binary`], with counter and CRC, for
//!   firmware that can do better.
//!
//! ```
//! use eitskin_io::codec::{encode, BadFrame, BinaryDecoder, Decoder, Event, LinesDecoder};
//! let mut events = Vec::new();
//! let mut lines = LinesDecoder::new(3);
//! lines.feed(b"magnitudes: 1.5, 2, 3,\r\n1, 2\n", &mut events);
//! let mut binary = BinaryDecoder::new(3);
//! binary.feed(&encode(7, &[1.0, 2.0, 3.0]), &mut events);
//! assert!(matches!(&events[0], Event::Frame(f) if f.seq == 0 && f.values == [1.5, 2.0, 3.0]));
//! assert_eq!(events[1], Event::Bad(BadFrame::WrongCount { seq: 1, expected: 3, got: 2 }));
//! assert!(matches!(&events[2], Event::Frame(f) if f.seq == 7 && f.values == [1.0, 2.0, 3.0]));
//! ```
//!
//! A value that is NaN or infinite is passed on as it is: it marks a channel the board lost
//! (a saturated or disconnected input), which the pipeline drops and names
//! ([`eitskin::pipeline`]), rather than a reason to lose the whole frame.
//!
//! Not for: opening serial ports or timing frames (the sources do that), or checking that the
//! values make physical sense (a frame of the right length is accepted).

pub mod binary;
pub mod lines;

pub use binary::{crc16, encode, encode_into, BinaryDecoder};
pub use lines::LinesDecoder;

/// What a decoder yields for each frame-sized piece of input.
#[derive(Debug, Clone, PartialEq)]
pub enum Event {
    /// A frame that decoded cleanly.
    Frame(Frame),
    /// A piece of input that was skipped, and why.
    Bad(BadFrame),
}

/// One decoded frame.
#[derive(Debug, Clone, PartialEq)]
pub struct Frame {
    /// Sequence number: the board's frame counter (binary codec) or the count of lines seen (lines codec), from 0.
    pub seq: u64,
    /// The measurements, in protocol order (V or Ω, as the board sends).
    pub values: Vec<f64>,
}

/// A frame that was skipped, and why; `seq` is where in the stream it was.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum BadFrame {
    /// The frame does not hold the expected number of values.
    #[error(
        "frame seq {seq} has {got} values, expected {expected}; maybe the protocol is adjacent, not two-terminal, \
         or bytes were lost on the line"
    )]
    WrongCount {
        /// Where the frame was in the stream.
        seq: u64,
        /// The number of values the protocol asks for.
        expected: usize,
        /// The number of values the frame holds.
        got: usize,
    },
    /// A field that does not read as a number.
    #[error("frame seq {seq}: field {field} ({text:?}) is not a number; is the board sending another format?")]
    NotANumber {
        /// Where the frame was in the stream.
        seq: u64,
        /// The field, counted from 1.
        field: usize,
        /// The field as received (its first 24 characters and `…` when longer).
        text: String,
    },
    /// A line longer than the decoder's limit; it was dropped up to the next new line.
    #[error(
        "frame seq {seq} is {bytes} bytes long, over the line limit, and was dropped; is the board ending its lines?"
    )]
    TooLong {
        /// Where the frame was in the stream.
        seq: u64,
        /// The length of the line, in bytes, without its line ending.
        bytes: usize,
    },
    /// A binary frame whose checksum does not match its bytes.
    #[error(
        "frame seq {seq} carries CRC {expected:#06x} but its bytes give {got:#06x}; it was corrupted on the line \
         (check the cable, the ground and the baud rate)"
    )]
    Crc {
        /// The counter the frame claims (unreliable, since the frame is corrupt).
        seq: u64,
        /// The CRC the frame carries.
        expected: u16,
        /// The CRC computed over the bytes received.
        got: u16,
    },
    /// Frames missing from the board's counter that were not reported otherwise.
    #[error(
        "{missing} frames were lost before frame seq {seq}; the link drops data (on a serial line, lower the frame \
         rate or raise the baud rate)"
    )]
    Gap {
        /// The counter of the frame after the gap (that frame is still delivered).
        seq: u64,
        /// How many frames were lost before this one.
        missing: u64,
    },
    /// A frame cut short when the link went away (never decoded: its end is unknown).
    #[error("frame seq {seq} was cut off after {bytes} bytes when the link went away, and is dropped")]
    Torn {
        /// Where in the stream it was.
        seq: u64,
        /// How many of its bytes had arrived.
        bytes: usize,
    },
    /// Bytes that belong to no frame.
    #[error(
        "{bytes} bytes were skipped while looking for the start of a frame; check the baud rate and the frame format"
    )]
    Garbage {
        /// How many bytes were skipped while hunting for sync.
        bytes: usize,
    },
    /// A message from the network that is not a frame (`--source zenoh:`).
    #[error("a sample on {key}: {reason}")]
    Message {
        /// The key expression it came on.
        key: String,
        /// Why, with the place.
        reason: String,
    },
    /// A frame older than one already taken (reordered on the way), dropped: it is stale.
    #[error("frame seq {seq} came after frame seq {last} and is dropped as stale (reordered on the way)")]
    OutOfOrder {
        /// Its counter.
        seq: u64,
        /// The newest frame's counter.
        last: u64,
    },
}

impl BadFrame {
    /// Where in the stream the bad frame was; `None` for garbage, which belongs to no frame.
    pub fn seq(&self) -> Option<u64> {
        match self {
            BadFrame::WrongCount { seq, .. }
            | BadFrame::NotANumber { seq, .. }
            | BadFrame::TooLong { seq, .. }
            | BadFrame::Crc { seq, .. }
            | BadFrame::Gap { seq, .. }
            | BadFrame::Torn { seq, .. }
            | BadFrame::OutOfOrder { seq, .. } => Some(*seq),
            BadFrame::Garbage { .. } | BadFrame::Message { .. } => None,
        }
    }
}

/// A decoder: bytes in, events out.
pub trait Decoder {
    /// Decodes a chunk of the stream, appending one event per frame completed by it to `out`.
    fn feed(&mut self, bytes: &[u8], out: &mut Vec<Event>);

    /// Ends the stream: decodes or reports what is still pending (a last line without its
    /// line ending, a torn binary frame). Does nothing by default.
    fn finish(&mut self, out: &mut Vec<Event>) {
        let _ = out;
    }

    /// The link broke: reports what is pending as cut off, never decoding it (a line cut
    /// mid-number may still hold the right count of numbers). Defaults to [`Decoder::finish`],
    /// right for decoders that never accept a partial frame.
    fn abandon(&mut self, out: &mut Vec<Event>) {
        self.finish(out);
    }
}
