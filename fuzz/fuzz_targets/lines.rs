//! The lines codec on arbitrary bytes (see `check.rs` for what is checked).
#![no_main]

#[path = "check.rs"]
mod check;

use eitskin_io::codec::LinesDecoder;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| check::check(|| LinesDecoder::new(4).with_line_limit(256), 4, data));
