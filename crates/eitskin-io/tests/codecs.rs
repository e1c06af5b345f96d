//! Frame codecs for serial byte streams. Every kind of bad frame is reported with the
//! right variant and place, the good frames around it come out unchanged and in order, and the
//! output does not depend on how the stream is cut into chunks. Real OpenEIT captures included.

use eitskin_io::codec::{crc16, encode, BadFrame, BinaryDecoder, Decoder, Event, Frame, LinesDecoder};

/// A tiny seeded xorshift64 generator, so that the chunkings are the same on every run.
struct XorShift(u64);

impl XorShift {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }

    /// A number in `1..=max`.
    fn size(&mut self, max: usize) -> usize {
        1 + (self.next() % max as u64) as usize
    }
}

/// Feeds `stream` in the given chunk sizes (cycled), then finishes.
fn decode_in(decoder: &mut dyn Decoder, stream: &[u8], mut chunk: impl FnMut() -> usize) -> Vec<Event> {
    let mut out = Vec::new();
    let mut rest = stream;
    while !rest.is_empty() {
        let n = chunk().min(rest.len());
        decoder.feed(&rest[..n], &mut out);
        rest = &rest[n..];
    }
    decoder.finish(&mut out);
    out
}

/// Checks that whole, byte-by-byte and randomly chunked feeding give the same events; returns them.
fn chunking_invariant(make: &dyn Fn() -> Box<dyn Decoder>, stream: &[u8], seed: u64) -> Vec<Event> {
    // Compared as text: a lost channel's NaN equals nothing, not even itself.
    let text = |events: Vec<Event>| format!("{events:?}");
    let whole = decode_in(make().as_mut(), stream, || usize::MAX);
    assert_eq!(text(decode_in(make().as_mut(), stream, || 1)), text(whole.clone()), "byte by byte");
    let mut rng = XorShift(seed);
    assert_eq!(text(decode_in(make().as_mut(), stream, || rng.size(64))), text(whole.clone()), "small random chunks");
    assert_eq!(text(decode_in(make().as_mut(), stream, || rng.size(5000))), text(whole.clone()), "large random chunks");
    whole
}

fn frame(seq: u64, values: &[f64]) -> Event {
    Event::Frame(Frame { seq, values: values.to_vec() })
}

fn bad(bad: BadFrame) -> Event {
    Event::Bad(bad)
}

#[test]
fn lines_every_bad_frame_is_reported_where_it_is() {
    let long = format!("{}\n", "1, ".repeat(40));
    let stream = [
        "magnitudes: 1.0, 2.0, 3.0,\r\n", // 0: good, OpenEIT style
        "1 2\r\n",                        // 1: a value short
        "\r\n",                           // empty: ignored, not counted
        "4; 5; x6\n",                     // 2: not a number, third field
        "7\t8\tNaN\n",                    // 3: NaN: a lost channel, passed on
        "label : 9 , 10 , 11\n",          // 4: good
        &long,                            // 5: over the 100-byte limit
        "12, 13, 14\n",                   // 6: good
        "15, 1",                          // 7: torn: the rest of the line was lost ...
        "6\n",                            //    ... and the line ends here, a value short
        "-1.5e3 2E-2 +3\n",               // 8: good
        "1, inf, 3\n",                    // 9: infinity, passed on too
        "4 5 6",                          // 10: good, the last line has no line ending
    ]
    .concat();
    let make = || Box::new(LinesDecoder::new(3).with_line_limit(100)) as Box<dyn Decoder>;
    let got = chunking_invariant(&make, stream.as_bytes(), 5);
    let want = vec![
        frame(0, &[1.0, 2.0, 3.0]),
        bad(BadFrame::WrongCount { seq: 1, expected: 3, got: 2 }),
        bad(BadFrame::NotANumber { seq: 2, field: 3, text: "x6".into() }),
        frame(3, &[7.0, 8.0, f64::NAN]),
        frame(4, &[9.0, 10.0, 11.0]),
        bad(BadFrame::TooLong { seq: 5, bytes: long.len() - 1 }),
        frame(6, &[12.0, 13.0, 14.0]),
        bad(BadFrame::WrongCount { seq: 7, expected: 3, got: 2 }),
        frame(8, &[-1500.0, 0.02, 3.0]),
        frame(9, &[1.0, f64::INFINITY, 3.0]),
        frame(10, &[4.0, 5.0, 6.0]),
    ];
    assert_eq!(format!("{got:?}"), format!("{want:?}"));
}

#[test]
fn lines_a_frame_split_across_chunks_is_whole() {
    let mut decoder = LinesDecoder::new(4);
    let mut out = Vec::new();
    for chunk in ["magnit", "udes:  1.2", "5 ,  2", ".5 , 3.75", " , 4\r", "\n"] {
        decoder.feed(chunk.as_bytes(), &mut out);
    }
    assert_eq!(out, vec![frame(0, &[1.25, 2.5, 3.75, 4.0])]);
}

#[test]
fn messages_are_sentences_with_the_numbers() {
    let message = BadFrame::WrongCount { seq: 12, expected: 120, got: 119 }.to_string();
    assert!(
        message.starts_with("frame seq 12 has 119 values, expected 120; maybe the protocol is adjacent"),
        "{message}"
    );
    let message = BadFrame::Gap { seq: 9, missing: 2 }.to_string();
    assert!(message.starts_with("2 frames were lost before frame seq 9"), "{message}");
    assert_eq!(BadFrame::Garbage { bytes: 3 }.seq(), None);
    assert_eq!(BadFrame::Crc { seq: 4, expected: 1, got: 2 }.seq(), Some(4));
}

/// Torn lines of a capture, as (sequence number, values received).
type Torn = &'static [(u64, usize)];

/// (file, values per frame, frames that decode, torn lines).
const OPENEIT: [(&str, usize, usize, Torn); 10] = [
    ("Baseline1.txt", 928, 4, &[]),
    ("Baseline2.txt", 928, 3, &[]),
    ("CupInMiddle.txt", 928, 2, &[]),
    ("CupOnBottom.txt", 928, 3, &[]),
    ("CupOnLeft.txt", 928, 2, &[]),
    ("CupOnRight.txt", 928, 3, &[]),
    ("CupOnTop.txt", 928, 4, &[]),
    ("background_32.txt", 928, 1, &[]),
    ("background_8.txt", 28, 1, &[]),
    // 51 lines, but line 21 was torn in the capture: 24 values, one of them cut ("276.1875").
    ("anticlockwise_motion.txt", 28, 50, &[(20, 24)]),
];

#[test]
fn openeit_captures_decode_whole_and_in_chunks() {
    let Some(shared) = eitskin_testdata::shared() else { return };
    let dir = shared.join("data/openeit");
    for (seed, (file, expected, frames, torn)) in OPENEIT.into_iter().enumerate() {
        let path = dir.join(file);
        let bytes = std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let make = || Box::new(LinesDecoder::new(expected)) as Box<dyn Decoder>;
        let events = chunking_invariant(&make, &bytes, 1 + seed as u64);
        let good: Vec<&Frame> = events
            .iter()
            .filter_map(|e| match e {
                Event::Frame(f) => Some(f),
                Event::Bad(_) => None,
            })
            .collect();
        let bad: Vec<(u64, usize)> = events
            .iter()
            .filter_map(|e| match e {
                Event::Bad(BadFrame::WrongCount { seq, got, .. }) => Some((*seq, *got)),
                Event::Bad(other) => panic!("{file}: unexpected {other}"),
                Event::Frame(_) => None,
            })
            .collect();
        assert_eq!(good.len(), frames, "{file}: frames");
        assert_eq!(bad, torn, "{file}: torn lines");
        assert!(good.iter().all(|f| f.values.len() == expected && f.values.iter().all(|&x| x >= 0.0)), "{file}");
        // The sequence numbers count every non-empty line, the torn one included.
        let seqs: Vec<u64> = good.iter().map(|f| f.seq).collect();
        let want: Vec<u64> = (0..(frames + torn.len()) as u64).filter(|s| !torn.iter().any(|t| t.0 == *s)).collect();
        assert_eq!(seqs, want, "{file}: sequence numbers");
    }
    // The first values of Baseline1.txt, as printed in the file.
    let text = std::fs::read(dir.join("Baseline1.txt")).expect("read above");
    let mut events = Vec::new();
    LinesDecoder::new(928).feed(&text, &mut events);
    let Event::Frame(first) = &events[0] else { panic!("{:?}", events[0]) };
    assert_eq!(&first.values[..4], &[169.875, 239.625, 239.125, 169.5]);
}

#[test]
fn crc_check_value() {
    assert_eq!(crc16(b"123456789"), 0x29B1);
}

#[test]
fn binary_every_bad_frame_is_reported_where_it_is() {
    let v = [1.5f32, -2.25, 1e-3];
    let as_f64 = |values: &[f32]| values.iter().map(|&x| f64::from(x)).collect::<Vec<f64>>();
    let mut stream = b"\x00\xA5junk".to_vec(); // the port opened mid-stream
    stream.extend(encode(0, &v));
    stream.extend_from_slice(b"\xA5\xA5 noise \x5A"); // between frames, with sync halves
    stream.extend(encode(1, &v));
    let mut corrupt = encode(2, &v);
    corrupt[9] ^= 0x10; // a bit flipped in the first value
    let carried = u16::from_le_bytes([corrupt[corrupt.len() - 2], corrupt[corrupt.len() - 1]]);
    let computed = crc16(&corrupt[2..corrupt.len() - 2]);
    stream.extend(&corrupt);
    stream.extend(encode(3, &v));
    stream.extend(encode(4, &v[..2])); // a value short
    stream.extend(encode(5, &v));
    stream.extend(encode(6, &[1.0, f32::NAN, 3.0]));
    // Frames 7 and 8 never arrive.
    stream.extend(encode(9, &v));
    stream.extend(&encode(10, &v)[..7]); // torn at the end of the stream

    let make = || Box::new(BinaryDecoder::new(3)) as Box<dyn Decoder>;
    let got = chunking_invariant(&make, &stream, 9);
    let want = vec![
        bad(BadFrame::Garbage { bytes: 6 }),
        frame(0, &as_f64(&v)),
        bad(BadFrame::Garbage { bytes: 10 }),
        frame(1, &as_f64(&v)),
        bad(BadFrame::Crc { seq: 2, expected: carried, got: computed }),
        frame(3, &as_f64(&v)),
        bad(BadFrame::WrongCount { seq: 4, expected: 3, got: 2 }),
        frame(5, &as_f64(&v)),
        frame(6, &[1.0, f64::NAN, 3.0]),
        bad(BadFrame::Gap { seq: 9, missing: 2 }),
        frame(9, &as_f64(&v)),
        bad(BadFrame::Garbage { bytes: 7 }),
    ];
    assert_ne!(carried, computed);
    assert_eq!(format!("{got:?}"), format!("{want:?}"));
}

#[test]
fn binary_nothing_accepted_is_lost_in_noise() {
    // 200 frames with random values, random noise between some of them and a few frames dropped:
    // every frame sent comes out once, in order, with its values exactly.
    let mut rng = XorShift(0x5eed);
    let mut stream = Vec::new();
    let mut sent = Vec::new();
    let mut dropped = 0u64;
    for counter in u32::MAX - 100..=u32::MAX {
        let values: Vec<f32> = (0..16).map(|_| (rng.next() % 100_000) as f32 / 7.0).collect();
        if rng.next().is_multiple_of(20) {
            dropped += 1;
            continue;
        }
        if rng.next().is_multiple_of(4) {
            let noise: Vec<u8> = (0..rng.size(40)).map(|_| rng.next() as u8).collect();
            stream.extend(noise);
        }
        stream.extend(encode(counter, &values));
        sent.push(frame(u64::from(counter), &values.iter().map(|&x| f64::from(x)).collect::<Vec<_>>()));
    }
    for counter in 0..100u32 {
        let values: Vec<f32> = (0..16).map(|_| (rng.next() % 100_000) as f32 / 7.0).collect();
        stream.extend(encode(counter, &values));
        sent.push(frame(u64::from(counter), &values.iter().map(|&x| f64::from(x)).collect::<Vec<_>>()));
    }
    let make = || Box::new(BinaryDecoder::new(16)) as Box<dyn Decoder>;
    let events = chunking_invariant(&make, &stream, 11);
    let frames: Vec<Event> = events.iter().filter(|e| matches!(e, Event::Frame(_))).cloned().collect();
    assert_eq!(frames, sent);
    let missing: u64 = events
        .iter()
        .map(|e| match e {
            Event::Bad(BadFrame::Gap { missing, .. }) => *missing,
            _ => 0,
        })
        .sum();
    let reported_bad = events.iter().filter(|e| matches!(e, Event::Bad(b) if b.seq().is_some())).count() as u64;
    let gaps = events.iter().filter(|e| matches!(e, Event::Bad(BadFrame::Gap { .. }))).count() as u64;
    // Each dropped frame is reported, as a gap or as a bad frame (from a false sync in the noise).
    assert!(missing + (reported_bad - gaps) >= dropped, "{events:?}");
    assert!(dropped > 0 && missing <= dropped);
}
