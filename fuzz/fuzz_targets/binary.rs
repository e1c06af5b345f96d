//! The binary codec on arbitrary bytes, cut at a point the input chooses: it must not panic,
//! must give the same events however the bytes are cut, and accepts only well-formed frames.
#![no_main]

use eitskin_io::codec::{BinaryDecoder, Decoder, Event};
use libfuzzer_sys::fuzz_target;

fn decode(bytes: &[u8], cut: usize) -> Vec<Event> {
    let mut decoder = BinaryDecoder::new(3);
    let mut out = Vec::new();
    let (head, tail) = bytes.split_at(cut.min(bytes.len()));
    decoder.feed(head, &mut out);
    decoder.feed(tail, &mut out);
    decoder.finish(&mut out);
    out
}

fuzz_target!(|data: &[u8]| {
    let Some((&cut, bytes)) = data.split_first() else { return };
    let whole = decode(bytes, bytes.len());
    assert_eq!(whole, decode(bytes, usize::from(cut)));
    for event in &whole {
        if let Event::Frame(f) = event {
            assert!(f.values.len() == 3 && f.values.iter().all(|v| v.is_finite()));
        }
    }
});
