//! Both frame codecs fed arbitrary bytes, cut into arbitrary chunks, never panic, give
//! the same events however the bytes are cut, and only ever accept well-formed frames (of the
//! right length; NaN or infinite values, lost channels, are passed on); valid
//! binary frames mixed into random garbage all come out. Property-based (proptest, fixed
//! seed per run as proptest chooses, 256 cases each), so it runs in every CI build.

use eitskin_io::codec::{encode, BinaryDecoder, Decoder, Event, LinesDecoder};
use proptest::prelude::*;

fn decode(mut decoder: impl Decoder, bytes: &[u8], cuts: &[usize]) -> Vec<Event> {
    let mut out = Vec::new();
    let mut rest = bytes;
    for &cut in cuts {
        let (head, tail) = rest.split_at(cut.min(rest.len()));
        decoder.feed(head, &mut out);
        rest = tail;
    }
    decoder.feed(rest, &mut out);
    decoder.finish(&mut out);
    out
}

/// Events as text, to compare: a lost channel's NaN equals nothing, not even itself.
fn debug(events: &[Event]) -> String {
    format!("{events:?}")
}

fn well_formed(events: &[Event], expected: usize) -> bool {
    events.iter().all(|e| match e {
        Event::Frame(f) => f.values.len() == expected,
        Event::Bad(_) => true,
    })
}

proptest! {
    #[test]
    fn lines_survive_any_bytes(bytes in prop::collection::vec(any::<u8>(), 0..2048), cuts in prop::collection::vec(0usize..300, 0..20)) {
        let whole = decode(LinesDecoder::new(3), &bytes, &[]);
        let cut = decode(LinesDecoder::new(3), &bytes, &cuts);
        prop_assert_eq!(debug(&whole), debug(&cut));
        prop_assert!(well_formed(&whole, 3));
    }

    #[test]
    fn lines_of_number_like_text_survive(text in "[0-9eE.,;: \\-+\\r\\nNaInf]{0,600}", cuts in prop::collection::vec(0usize..100, 0..10)) {
        let whole = decode(LinesDecoder::new(2), text.as_bytes(), &[]);
        prop_assert_eq!(debug(&whole), debug(&decode(LinesDecoder::new(2), text.as_bytes(), &cuts)));
        prop_assert!(well_formed(&whole, 2));
    }

    #[test]
    fn binary_survives_any_bytes(bytes in prop::collection::vec(any::<u8>(), 0..2048), cuts in prop::collection::vec(0usize..300, 0..20)) {
        let whole = decode(BinaryDecoder::new(4), &bytes, &[]);
        prop_assert_eq!(debug(&whole), debug(&decode(BinaryDecoder::new(4), &bytes, &cuts)));
        prop_assert!(well_formed(&whole, 4));
    }

    #[test]
    fn binary_frames_in_garbage_all_come_out(
        frames in prop::collection::vec(prop::collection::vec(-1e6f32..1e6, 4), 1..20),
        garbage in prop::collection::vec(prop::collection::vec(any::<u8>(), 0..40), 20),
        cuts in prop::collection::vec(0usize..200, 0..20),
    ) {
        let mut bytes = Vec::new();
        for (k, values) in frames.iter().enumerate() {
            // Garbage without the first sync byte cannot start a false frame.
            bytes.extend(garbage[k].iter().map(|&b| if b == 0xA5 { 0 } else { b }));
            bytes.extend(encode(k as u32, values));
        }
        let events = decode(BinaryDecoder::new(4), &bytes, &cuts);
        let got: Vec<(u64, Vec<f64>)> = events
            .iter()
            .filter_map(|e| match e { Event::Frame(f) => Some((f.seq, f.values.clone())), Event::Bad(_) => None })
            .collect();
        let want: Vec<(u64, Vec<f64>)> =
            frames.iter().enumerate().map(|(k, v)| (k as u64, v.iter().map(|&x| f64::from(x)).collect())).collect();
        prop_assert_eq!(got, want);
    }
}
