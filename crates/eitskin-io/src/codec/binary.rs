//! The binary codec: framed, counted and checksummed, for firmware that can do better than text.
//!
//! # The frame format
//!
//! A frame of `n` measurements is `10 + 4n` bytes. All integers and floats are little-endian.
//!
//! | offset    | size | field   | content                                                       |
//! |-----------|------|---------|---------------------------------------------------------------|
//! | 0         | 2    | sync    | the bytes `0xA5` then `0x5A`                                  |
//! | 2         | 4    | counter | frame counter, u32; +1 per frame, wraps from `u32::MAX` to 0  |
//! | 6         | 2    | count   | number of values `n`, u16 (the protocol's length)             |
//! | 8         | 4n   | values  | the measurements in protocol order, IEEE 754 binary32 (f32)    |
//! | 8 + 4n    | 2    | crc     | CRC-16 of bytes 2 to 7 + 4n (counter, count, values), u16     |
//!
//! The CRC is CRC-16/CCITT-FALSE (also called CRC-16/IBM-3740): polynomial 0x1021, initial
//! value 0xFFFF, input and output not reflected, no final XOR; its check value (the CRC of the
//! ASCII bytes `123456789`) is 0x29B1. It covers everything after the sync up to the last
//! value, and the sync bytes are not part of it. Send frames back to back; bytes between frames
//! are allowed (and reported as garbage). The counter starts anywhere.
//!
//! # How the decoder recovers
//!
//! It hunts for the sync bytes; bytes skipped before one are reported as one
//! [`BadFrame::Garbage`] per run. A count other than the expected one is a
//! [`BadFrame::WrongCount`] and a CRC mismatch a [`BadFrame::Crc`]; after either, the hunt
//! starts again one byte after the sync, since a good frame may start inside the bad one; the
//! bytes the bad frame claims are not reported again as garbage (up to the next good frame). A frame that passes its CRC
//! is delivered, NaN or infinite values included (lost channels, see [`super`]). Before
//! it, a [`BadFrame::Gap`] reports the counter values skipped since the last frame that passed
//! its CRC, less the frames reported bad in between, so each lost frame is reported once. A
//! counter that goes back (a board reset) reads as a gap of the wrapped distance.

use crc::{Crc, CRC_16_IBM_3740};

use super::{BadFrame, Decoder, Event, Frame};

/// The two bytes that start every frame.
pub const SYNC: [u8; 2] = [0xA5, 0x5A];

/// The bytes before the values: sync, counter and count.
const HEADER: usize = 8;

/// The bytes after the values: the CRC.
const TRAILER: usize = 2;

/// CRC-16/CCITT-FALSE: poly 0x1021, init 0xFFFF, no reflection, no final XOR.
const CRC16: Crc<u16> = Crc::<u16>::new(&CRC_16_IBM_3740);

/// The CRC-16/CCITT-FALSE of `bytes`, as the frame format uses it.
pub fn crc16(bytes: &[u8]) -> u16 {
    CRC16.checksum(bytes)
}

/// The length of a frame of `count` values, in bytes.
fn frame_length(count: usize) -> usize {
    HEADER + 4 * count + TRAILER
}

/// Encodes one frame (for tests and simulators); see [`encode_into`] for the form that reuses a buffer.
///
/// Panics if there are more than 65 535 values, which the format cannot count.
#[track_caller]
pub fn encode(seq: u32, values: &[f32]) -> Vec<u8> {
    let mut out = Vec::with_capacity(frame_length(values.len()));
    encode_into(seq, values, &mut out);
    out
}

/// Appends one encoded frame to `out`.
///
/// Panics if there are more than 65 535 values, which the format cannot count.
#[track_caller]
pub fn encode_into(seq: u32, values: &[f32], out: &mut Vec<u8>) {
    let count = u16::try_from(values.len())
        .unwrap_or_else(|_| panic!("a binary frame holds at most {} values, not {}", u16::MAX, values.len()));
    out.reserve(frame_length(values.len()));
    out.extend_from_slice(&SYNC);
    let start = out.len();
    out.extend_from_slice(&seq.to_le_bytes());
    out.extend_from_slice(&count.to_le_bytes());
    for value in values {
        out.extend_from_slice(&value.to_le_bytes());
    }
    let crc = crc16(&out[start..]);
    out.extend_from_slice(&crc.to_le_bytes());
}

/// Decodes the binary frame format of the [module doc](self).
///
/// A count of more than 65 535 can never match: with such an `expected`, every frame is reported
/// as [`BadFrame::WrongCount`].
///
/// ```
/// use eitskin_io::codec::{encode, BadFrame, BinaryDecoder, Decoder, Event};
/// let mut stream = encode(41, &[1.0, 2.0]);
/// stream.extend_from_slice(b"noise");
/// stream.extend(encode(43, &[3.0, 4.0]));
/// let mut events = Vec::new();
/// let mut decoder = BinaryDecoder::new(2);
/// for chunk in stream.chunks(3) {
///     decoder.feed(chunk, &mut events);
/// }
/// assert!(matches!(&events[0], Event::Frame(f) if f.seq == 41 && f.values == [1.0, 2.0]));
/// assert_eq!(events[1], Event::Bad(BadFrame::Garbage { bytes: 5 }));
/// assert_eq!(events[2], Event::Bad(BadFrame::Gap { seq: 43, missing: 1 }));
/// assert!(matches!(&events[3], Event::Frame(f) if f.seq == 43 && f.values == [3.0, 4.0]));
/// ```
#[derive(Debug, Clone)]
pub struct BinaryDecoder {
    /// The number of values in a frame.
    expected: usize,
    /// Bytes received and not yet decided on; starts at a sync byte or holds at most one byte.
    pending: Vec<u8>,
    /// Bytes skipped while hunting, not yet reported.
    garbage: usize,
    /// Bytes still to skip that belong to a frame already reported bad, so are not garbage.
    shadow: usize,
    /// The counter of the last frame that passed its CRC.
    last: Option<u32>,
    /// Frames reported bad since then (they are not counted again in a gap).
    bad_since_last: u64,
}

impl BinaryDecoder {
    /// A decoder for frames of `expected` values.
    pub fn new(expected: usize) -> BinaryDecoder {
        BinaryDecoder { expected, pending: Vec::new(), garbage: 0, shadow: 0, last: None, bad_since_last: 0 }
    }

    /// Counts `n` skipped bytes as garbage, except those of a frame already reported.
    fn skip(&mut self, n: usize) {
        let shadowed = n.min(self.shadow);
        self.shadow -= shadowed;
        self.garbage += n - shadowed;
    }

    /// Reports the garbage skipped so far, if any.
    fn flush_garbage(&mut self, out: &mut Vec<Event>) {
        if self.garbage > 0 {
            out.push(Event::Bad(BadFrame::Garbage { bytes: std::mem::take(&mut self.garbage) }));
        }
    }

    /// Reports a bad frame that did not pass its checks; the hunt restarts after its first byte.
    fn reject(&mut self, bad: BadFrame, length: usize, out: &mut Vec<Event>) {
        self.flush_garbage(out);
        out.push(Event::Bad(bad));
        self.bad_since_last += 1;
        self.shadow = length - 1;
    }

    /// Decides on the frame at the start of `bytes` (which starts with the sync), if it is all there;
    /// returns how many bytes were consumed, or `None` to wait for more.
    fn decide(&mut self, bytes: &[u8], out: &mut Vec<Event>) -> Option<usize> {
        let header = bytes.get(..HEADER)?;
        let counter = u32::from_le_bytes([header[2], header[3], header[4], header[5]]);
        let count = usize::from(u16::from_le_bytes([header[6], header[7]]));
        if count != self.expected {
            let bad = BadFrame::WrongCount { seq: u64::from(counter), expected: self.expected, got: count };
            self.reject(bad, frame_length(count), out);
            return Some(1);
        }
        let length = frame_length(count);
        let frame = bytes.get(..length)?;
        let carried = u16::from_le_bytes([frame[length - 2], frame[length - 1]]);
        let computed = crc16(&frame[SYNC.len()..length - TRAILER]);
        if carried != computed {
            self.reject(BadFrame::Crc { seq: u64::from(counter), expected: carried, got: computed }, length, out);
            return Some(1);
        }
        self.flush_garbage(out);
        self.shadow = 0;
        if let Some(last) = self.last {
            let skipped = u64::from(counter.wrapping_sub(last).wrapping_sub(1));
            let missing = skipped.saturating_sub(self.bad_since_last);
            if missing > 0 {
                out.push(Event::Bad(BadFrame::Gap { seq: u64::from(counter), missing }));
            }
        }
        self.last = Some(counter);
        self.bad_since_last = 0;
        let values: Vec<f64> = frame[HEADER..length - TRAILER]
            .chunks_exact(4)
            .map(|b| f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]])))
            .collect();
        let seq = u64::from(counter);
        out.push(Event::Frame(Frame { seq, values }));
        Some(length)
    }
}

impl Decoder for BinaryDecoder {
    fn feed(&mut self, bytes: &[u8], out: &mut Vec<Event>) {
        self.pending.extend_from_slice(bytes);
        let mut pending = std::mem::take(&mut self.pending);
        let mut at = 0;
        loop {
            let rest = &pending[at..];
            let Some(start) = rest.windows(2).position(|w| w == SYNC) else {
                // Keep a last 0xA5: it may be the first half of a sync.
                let keep = usize::from(rest.last() == Some(&SYNC[0]));
                self.skip(rest.len() - keep);
                at = pending.len() - keep;
                break;
            };
            self.skip(start);
            at += start;
            match self.decide(&pending[at..], out) {
                Some(consumed) => at += consumed,
                None => break,
            }
        }
        pending.drain(..at);
        self.pending = pending;
    }

    /// Reports a torn last frame, and any garbage, as garbage.
    fn finish(&mut self, out: &mut Vec<Event>) {
        let left = self.pending.len();
        self.pending.clear();
        self.skip(left);
        self.shadow = 0;
        self.flush_garbage(out);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_crc_is_ccitt_false() {
        assert_eq!(crc16(b"123456789"), 0x29B1);
        assert_eq!(crc16(b""), 0xFFFF);
    }

    #[test]
    fn a_frame_is_laid_out_as_documented() {
        let bytes = encode(0x0403_0201, &[1.0]);
        assert_eq!(bytes.len(), 10 + 4);
        assert_eq!(&bytes[..8], &[0xA5, 0x5A, 0x01, 0x02, 0x03, 0x04, 0x01, 0x00]);
        assert_eq!(&bytes[8..12], &1.0f32.to_le_bytes());
        assert_eq!(u16::from_le_bytes([bytes[12], bytes[13]]), crc16(&bytes[2..12]));
    }

    #[test]
    fn the_counter_wraps_without_a_gap() {
        let mut stream = encode(u32::MAX, &[1.0]);
        stream.extend(encode(0, &[2.0]));
        let mut out = Vec::new();
        BinaryDecoder::new(1).feed(&stream, &mut out);
        assert_eq!(out.len(), 2);
        assert!(matches!(&out[1], Event::Frame(f) if f.seq == 0));
    }

    #[test]
    fn a_torn_last_frame_is_garbage_at_the_end() {
        let stream = encode(3, &[1.0, 2.0]);
        let mut decoder = BinaryDecoder::new(2);
        let mut out = Vec::new();
        decoder.feed(&stream[..10], &mut out);
        assert!(out.is_empty());
        decoder.finish(&mut out);
        assert_eq!(out, vec![Event::Bad(BadFrame::Garbage { bytes: 10 })]);
    }
}
