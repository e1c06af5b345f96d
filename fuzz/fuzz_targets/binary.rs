//! The binary codec on arbitrary bytes (see `check.rs` for what is checked).
#![no_main]

#[path = "check.rs"]
mod check;

use eitskin_io::codec::BinaryDecoder;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| check::check(|| BinaryDecoder::new(3), 3, data));
