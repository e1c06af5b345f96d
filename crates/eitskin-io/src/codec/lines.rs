//! The text codec: one frame per line, as OpenEIT and most hobby firmware print them.
//!
//! A line is an optional label up to the first `:` (OpenEIT's `magnitudes:` or
//! `magnitudes :`), then numbers separated by commas, semicolons, spaces or tabs, with any
//! padding and an optional trailing separator, ended by `\n` or `\r\n`. Empty lines are
//! ignored. There is no checksum and no counter: the sequence number of a frame is the count of
//! non-empty lines before it, so a lost line shows only as a [`BadFrame::WrongCount`] when it
//! was torn, and not at all when it was lost whole.

use super::{BadFrame, Decoder, Event, Frame};

/// The longest line accepted by default, in bytes (64 KiB; an OpenEIT frame of 928 values is about 14 KiB).
pub const DEFAULT_LINE_LIMIT: usize = 64 * 1024;

/// Decodes one frame per text line; see the [module doc](self) for the format.
///
/// ```
/// use eitskin_io::codec::{BadFrame, Decoder, Event, LinesDecoder};
/// let mut decoder = LinesDecoder::new(2);
/// let mut events = Vec::new();
/// decoder.feed(b"magnitudes : 1.0 , 2", &mut events); // a frame split across two chunks
/// decoder.feed(b".5 ,\r\n\r\n1; nan\n1 x\n", &mut events);
/// assert!(matches!(&events[0], Event::Frame(f) if f.seq == 0 && f.values == [1.0, 2.5]));
/// assert!(matches!(&events[1], Event::Frame(f) if f.seq == 1 && f.values[1].is_nan())); // a lost channel
/// assert_eq!(events[2], Event::Bad(BadFrame::NotANumber { seq: 2, field: 2, text: "x".into() }));
/// ```
#[derive(Debug, Clone)]
pub struct LinesDecoder {
    /// The number of values in a frame.
    expected: usize,
    /// The longest line accepted, in bytes, without its line ending.
    limit: usize,
    /// The bytes of the current line so far (emptied once it goes over the limit).
    line: Vec<u8>,
    /// The length of the current line so far, in bytes, counted on past the limit.
    length: usize,
    /// Whether the last byte of the current line so far is `\r`.
    cr: bool,
    /// The sequence number of the next non-empty line.
    seq: u64,
}

impl LinesDecoder {
    /// A decoder for frames of `expected` values, with lines up to [`DEFAULT_LINE_LIMIT`] bytes.
    pub fn new(expected: usize) -> LinesDecoder {
        LinesDecoder { expected, limit: DEFAULT_LINE_LIMIT, line: Vec::new(), length: 0, cr: false, seq: 0 }
    }

    /// The same decoder, accepting lines up to `bytes` long (without the line ending).
    pub fn with_line_limit(mut self, bytes: usize) -> LinesDecoder {
        self.limit = bytes;
        self
    }

    /// Appends a piece of the current line, keeping at most `limit + 1` bytes (room for a `\r`).
    fn extend(&mut self, bytes: &[u8]) {
        let Some(&last) = bytes.last() else { return };
        self.length += bytes.len();
        self.cr = last == b'\r';
        if self.length <= self.limit.saturating_add(1) {
            self.line.extend_from_slice(bytes);
        } else {
            self.line.clear();
        }
    }

    /// Decodes the current line, unless it is empty, and starts the next one.
    fn end_line(&mut self, out: &mut Vec<Event>) {
        let bytes = self.length - usize::from(self.cr);
        if bytes > self.limit {
            out.push(Event::Bad(BadFrame::TooLong { seq: self.seq, bytes }));
            self.seq += 1;
        } else if !self.line.iter().all(u8::is_ascii_whitespace) {
            out.push(decode_line(&self.line, self.seq, self.expected));
            self.seq += 1;
        }
        self.line.clear();
        self.length = 0;
        self.cr = false;
    }
}

impl Decoder for LinesDecoder {
    fn feed(&mut self, mut bytes: &[u8], out: &mut Vec<Event>) {
        while let Some(end) = bytes.iter().position(|&b| b == b'\n') {
            self.extend(&bytes[..end]);
            self.end_line(out);
            bytes = &bytes[end + 1..];
        }
        self.extend(bytes);
    }

    /// Decodes a last line that has no line ending.
    fn finish(&mut self, out: &mut Vec<Event>) {
        self.end_line(out);
    }

    /// Reports a pending partial line as torn instead of decoding it.
    fn abandon(&mut self, out: &mut Vec<Event>) {
        if !self.line.iter().all(u8::is_ascii_whitespace) || self.length > self.line.len() {
            out.push(Event::Bad(BadFrame::Torn { seq: self.seq, bytes: self.length }));
            self.seq += 1;
        }
        self.line.clear();
        self.length = 0;
        self.cr = false;
    }
}

/// Whether a byte separates two values.
fn is_separator(byte: u8) -> bool {
    matches!(byte, b',' | b';' | b' ' | b'\t' | b'\r')
}

/// The longest a field that is not a number is quoted, in characters: a line of binary noise
/// is one long field.
const QUOTED: usize = 24;

/// `field` as a message quotes it: its first [`QUOTED`] characters, and `…` where it is cut.
fn quoted(field: &str) -> String {
    match field.char_indices().nth(QUOTED) {
        Some((cut, _)) => format!("{}…", &field[..cut]),
        None => field.to_owned(),
    }
}

/// Decodes one complete, non-empty line (without its `\n`) as frame `seq`.
fn decode_line(line: &[u8], seq: u64, expected: usize) -> Event {
    let body = match line.iter().position(|&b| b == b':') {
        Some(colon) => &line[colon + 1..],
        None => line,
    };
    let mut values = Vec::with_capacity(expected);
    for (i, field) in body.split(|&b| is_separator(b)).filter(|f| !f.is_empty()).enumerate() {
        match std::str::from_utf8(field).ok().and_then(|text| text.parse::<f64>().ok()) {
            Some(x) => values.push(x),
            None => {
                let text = quoted(&String::from_utf8_lossy(field));
                return Event::Bad(BadFrame::NotANumber { seq, field: i + 1, text });
            }
        }
    }
    if values.len() != expected {
        return Event::Bad(BadFrame::WrongCount { seq, expected, got: values.len() });
    }
    Event::Frame(Frame { seq, values })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn decode(decoder: &mut LinesDecoder, chunks: &[&[u8]]) -> Vec<Event> {
        let mut out = Vec::new();
        for chunk in chunks {
            decoder.feed(chunk, &mut out);
        }
        decoder.finish(&mut out);
        out
    }

    fn frame(seq: u64, values: &[f64]) -> Event {
        Event::Frame(Frame { seq, values: values.to_vec() })
    }

    #[test]
    fn an_abandoned_line_is_torn_not_decoded() {
        let mut decoder = LinesDecoder::new(2);
        let mut out = Vec::new();
        decoder.feed(b"1,2\n3,4", &mut out);
        decoder.abandon(&mut out);
        decoder.feed(b"5,6\n", &mut out);
        assert_eq!(out.len(), 3);
        assert_eq!(out[1], Event::Bad(BadFrame::Torn { seq: 1, bytes: 3 }));
        assert!(matches!(&out[2], Event::Frame(f) if f.seq == 2 && f.values == [5.0, 6.0]));
        decoder.abandon(&mut out);
        assert_eq!(out.len(), 3, "nothing pending, nothing reported");
    }

    #[test]
    fn separators_padding_labels_and_line_endings() {
        let text = b"a:1,2,3\r\n\n  \r\n  magnitudes :   4 ;\t5  6 , \r\n7 8 9";
        let got = decode(&mut LinesDecoder::new(3), &[text]);
        assert_eq!(got, vec![frame(0, &[1.0, 2.0, 3.0]), frame(1, &[4.0, 5.0, 6.0]), frame(2, &[7.0, 8.0, 9.0])]);
    }

    #[test]
    fn field_numbers_count_from_one_after_the_label() {
        let got = decode(&mut LinesDecoder::new(3), &[b"1 2 3\nv: 1, x2, 3\n1 inf 3\n"]);
        assert_eq!(got[1], Event::Bad(BadFrame::NotANumber { seq: 1, field: 2, text: "x2".into() }));
        let noise = "é".repeat(100);
        assert_eq!(quoted(&noise), format!("{}…", "é".repeat(QUOTED)), "cut at a character, not a byte");
        assert_eq!(quoted("short"), "short");
        assert_eq!(got[2], frame(2, &[1.0, f64::INFINITY, 3.0]), "a lost channel is passed on");
    }

    #[test]
    fn the_line_limit_excludes_the_line_ending() {
        let mut decoder = LinesDecoder::new(2).with_line_limit(3);
        let got = decode(&mut decoder, &[b"1 2\r\n1 23\r\n", b"1 2"]);
        assert_eq!(
            got,
            vec![frame(0, &[1.0, 2.0]), Event::Bad(BadFrame::TooLong { seq: 1, bytes: 4 }), frame(2, &[1.0, 2.0])]
        );
    }
}
