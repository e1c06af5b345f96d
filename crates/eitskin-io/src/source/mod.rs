//! Frame sources: where the byte stream of an acquisition board comes from, decoded into
//! frames by a [`codec`](crate::codec) decoder.
//!
//! * [`serial`]: a board on a serial port (USB CDC or a UART adapter), reopened when it is
//!   unplugged and plugged back in.
//!
//! Not for: decoding bytes (that is [`codec`](crate::codec)) or reconstructing images from the
//! frames (that is `eitskin`).

pub mod serial;
