//! What every codec fuzz target checks: on arbitrary bytes, cut at the point the input's first
//! byte chooses, a decoder must not panic, must give the same events however the bytes are cut,
//! and must accept only frames of `expected` finite values.

use eitskin_io::codec::{Decoder, Event};

fn decode<D: Decoder>(make: &impl Fn() -> D, bytes: &[u8], cut: usize) -> Vec<Event> {
    let mut decoder = make();
    let mut out = Vec::new();
    let (head, tail) = bytes.split_at(cut.min(bytes.len()));
    decoder.feed(head, &mut out);
    decoder.feed(tail, &mut out);
    decoder.finish(&mut out);
    out
}

/// Runs the checks on one fuzz input.
pub fn check<D: Decoder>(make: impl Fn() -> D, expected: usize, data: &[u8]) {
    let Some((&cut, bytes)) = data.split_first() else { return };
    let whole = decode(&make, bytes, bytes.len());
    // Compared as text: a lost channel's NaN (passed on by the codecs) equals nothing, not even itself.
    assert_eq!(format!("{whole:?}"), format!("{:?}", decode(&make, bytes, usize::from(cut))));
    for event in &whole {
        if let Event::Frame(f) = event {
            assert!(f.values.len() == expected);
        }
    }
}
