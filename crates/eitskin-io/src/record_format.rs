//! The recording format's shared parts: the header, its format name and version, and each
//! record's CRC, written by [`crate::recorder`] and read by [`crate::replay`] (the format itself
//! is described in [`crate::recorder`]'s doc).

use std::time::{SystemTime, UNIX_EPOCH};

use crc::{Crc, CRC_32_ISO_HDLC};
use serde::{Deserialize, Serialize};

use crate::Error;

/// The `format` of a recording's header.
pub const FORMAT: &str = "eitskin-recording";

/// The `version` of the format this crate writes (it reads this one and 1).
pub const VERSION: u64 = 2;

/// What a recording is of: the first line of the file.
#[derive(Debug, Clone, PartialEq)]
pub struct Header {
    /// The number of values in every frame.
    pub measurements: usize,
    /// The name of the protocol the frames follow, e.g. `two-terminal`.
    pub protocol: String,
    /// When the recording started, in seconds since 1970-01-01 UTC.
    pub started_unix_s: f64,
}

impl Header {
    /// A header for frames of `measurements` values, started now by the system clock.
    pub fn now(measurements: usize, protocol: impl Into<String>) -> Header {
        // A clock set before 1970 gives 0 rather than an error: the start is for people, not for the reader.
        let started_unix_s = SystemTime::now().duration_since(UNIX_EPOCH).map_or(0.0, |d| d.as_secs_f64());
        Header { measurements, protocol: protocol.into(), started_unix_s }
    }
}

/// The text of a record's crc field up to its value.
pub(crate) const CRC_FIELD: &[u8] = b",\"crc\":\"";

/// The length of a record's ending, from `,"crc":"` to the closing `}`, in bytes.
pub(crate) const CRC_TAIL: usize = CRC_FIELD.len() + 8 + 2;

/// The CRC-32 of a record whose text without the crc field is `open` (everything before `,"crc"`) and `}`.
pub(crate) fn record_crc(open: &[u8]) -> u32 {
    const CRC32: Crc<u32> = Crc::<u32>::new(&CRC_32_ISO_HDLC);
    let mut digest = CRC32.digest();
    digest.update(open);
    digest.update(b"}");
    digest.finalize()
}

/// Reads a header line, checking its format and version.
pub(crate) fn parse_header(line: &[u8]) -> Result<Header, Error> {
    let header: HeaderLine =
        serde_json::from_slice(line).map_err(|e| Error::Json { path: None, message: format!("header: {e}") })?;
    if header.format != FORMAT {
        return Err(Error::Key {
            path: None,
            key: "format",
            reason: format!("is {:?}, not {FORMAT:?}; this is not an eitskin recording", header.format),
        });
    }
    if !(1..=VERSION).contains(&header.version) {
        return Err(Error::Key {
            path: None,
            key: "version",
            reason: format!("is {}, but this eitskin reads versions 1 to {VERSION}; is it newer?", header.version),
        });
    }
    Ok(Header { measurements: header.measurements, protocol: header.protocol, started_unix_s: header.started_unix_s })
}

/// The header line as written, its fields in that order.
#[derive(Serialize, Deserialize)]
pub(crate) struct HeaderLine {
    format: String,
    version: u64,
    measurements: usize,
    protocol: String,
    started_unix_s: f64,
}

impl HeaderLine {
    pub(crate) fn of(header: &Header) -> HeaderLine {
        HeaderLine {
            format: FORMAT.to_string(),
            version: VERSION,
            measurements: header.measurements,
            protocol: header.protocol.clone(),
            started_unix_s: header.started_unix_s,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_crc_is_zlibs_crc32() {
        // The standard check value of CRC-32/ISO-HDLC, and the closing brace counted once.
        const CRC32: Crc<u32> = Crc::<u32>::new(&CRC_32_ISO_HDLC);
        assert_eq!(CRC32.checksum(b"123456789"), 0xCBF4_3926);
        assert_eq!(record_crc(b"{\"a\":1"), CRC32.checksum(b"{\"a\":1}"));
    }
}
