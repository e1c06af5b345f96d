//! [`SourceSpec`]: which source, as a user names it on the command line.

use std::fmt;
use std::path::PathBuf;
use std::str::FromStr;

use super::serial::parse_serial_spec;
use super::SourceError;

/// Which source frames come from, parsed from the text a user writes (`--source`).
///
/// | text                 | source                                                              |
/// |----------------------|---------------------------------------------------------------------|
/// | `sim`                | the virtual sensor, pressed at random places                        |
/// | `sim:SCRIPT`         | the virtual sensor, pressed as the script says (`start end x y force` lines) |
/// | `file:PATH`          | a recording (its JSON header tells), or a capture of the board's bytes |
/// | `serial:PATH[@BAUD]` | a board on a serial port, 8N1, at 115200 bit/s unless told          |
/// | `zenoh:KEY`          | frames a board's bridge publishes on a Zenoh key expression          |
///
/// It only names the source: nothing is opened or checked on disk until
/// [`Source::open`](super::Source::open). It implements [`FromStr`], so clap takes it as a
/// flag's type directly, and [`Display`](fmt::Display) writes it back as it parses.
///
/// ```
/// use eitskin_io::source::SourceSpec;
/// let spec: SourceSpec = "serial:/dev/ttyACM0@921600".parse()?;
/// assert_eq!(spec, SourceSpec::Serial { path: "/dev/ttyACM0".into(), baud: 921_600 });
/// assert_eq!("sim".parse::<SourceSpec>()?, SourceSpec::Sim { script: None });
/// let error = "frames.csv".parse::<SourceSpec>().unwrap_err().to_string();
/// assert!(error.contains("\"frames.csv\"") && error.contains("file:frames.csv"), "{error}");
/// # Ok::<(), eitskin_io::source::SourceError>(())
/// ```
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum SourceSpec {
    /// The virtual sensor (`sim`, `sim:SCRIPT`).
    Sim {
        /// A press script (`start end x y force` per line, in s, the spec's length unit and N);
        /// random presses without one.
        script: Option<PathBuf>,
    },
    /// A file (`file:PATH`): a recording, or a capture of one frame per text line.
    File(PathBuf),
    /// A serial port (`serial:PATH[@BAUD]`).
    Serial {
        /// The port, e.g. `/dev/ttyACM0` or `COM3`.
        path: PathBuf,
        /// The baud rate, in bit/s.
        baud: u32,
    },
    /// Frames published on Zenoh (`zenoh:KEY`), as `crate::middleware` reads them.
    Zenoh {
        /// The key expression, as written.
        key: String,
    },
}

impl FromStr for SourceSpec {
    type Err = SourceError;

    fn from_str(text: &str) -> Result<SourceSpec, SourceError> {
        if text == "sim" {
            return Ok(SourceSpec::Sim { script: None });
        }
        if let Some(script) = text.strip_prefix("sim:") {
            if script.is_empty() {
                return Err(SourceError::NoScript { spec: text.to_owned() });
            }
            return Ok(SourceSpec::Sim { script: Some(PathBuf::from(script)) });
        }
        if let Some(path) = text.strip_prefix("file:") {
            if path.is_empty() {
                return Err(SourceError::NoFile { spec: text.to_owned() });
            }
            return Ok(SourceSpec::File(PathBuf::from(path)));
        }
        if text == "file" {
            return Err(SourceError::NoFile { spec: text.to_owned() });
        }
        if text.starts_with("serial:") || text == "serial" {
            let (path, baud) =
                parse_serial_spec(if text == "serial" { "serial:" } else { text }).map_err(|e| with_spec(e, text))?;
            return Ok(SourceSpec::Serial { path, baud });
        }
        if let Some(key) = text.strip_prefix("zenoh:").or((text == "zenoh").then_some("")) {
            if key.is_empty() {
                return Err(SourceError::NoKey { spec: text.to_owned() });
            }
            return Ok(SourceSpec::Zenoh { key: key.to_owned() });
        }
        Err(SourceError::Unknown { spec: text.to_owned() })
    }
}

/// The error, quoting `text` (as written) rather than the form it was rewritten to.
fn with_spec(error: SourceError, text: &str) -> SourceError {
    match error {
        SourceError::EmptyPath { .. } => SourceError::EmptyPath { spec: text.to_owned() },
        other => other,
    }
}

impl fmt::Display for SourceSpec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SourceSpec::Sim { script: None } => write!(f, "sim"),
            SourceSpec::Sim { script: Some(path) } => write!(f, "sim:{}", path.display()),
            SourceSpec::File(path) => write!(f, "file:{}", path.display()),
            SourceSpec::Serial { path, baud } => write!(f, "serial:{}@{baud}", path.display()),
            SourceSpec::Zenoh { key } => write!(f, "zenoh:{key}"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::source::serial::DEFAULT_BAUD;

    fn parse(text: &str) -> Result<SourceSpec, SourceError> {
        text.parse()
    }

    #[test]
    fn every_kind_parses() {
        assert_eq!(parse("sim"), Ok(SourceSpec::Sim { script: None }));
        assert_eq!(parse("sim:a b.txt"), Ok(SourceSpec::Sim { script: Some("a b.txt".into()) }));
        assert_eq!(parse("file:/tmp/run.jsonl"), Ok(SourceSpec::File("/tmp/run.jsonl".into())));
        assert_eq!(parse("file:C:\\runs\\a.csv"), Ok(SourceSpec::File("C:\\runs\\a.csv".into())));
        assert_eq!(parse("serial:COM3"), Ok(SourceSpec::Serial { path: "COM3".into(), baud: DEFAULT_BAUD }));
        assert_eq!(parse("zenoh:robot/skin/0/frames"), Ok(SourceSpec::Zenoh { key: "robot/skin/0/frames".into() }));
        assert_eq!(
            parse("serial:/dev/ttyUSB0@9600"),
            Ok(SourceSpec::Serial { path: "/dev/ttyUSB0".into(), baud: 9600 })
        );
    }

    #[test]
    fn display_writes_what_parses_back() {
        for text in ["sim", "sim:s.txt", "file:/tmp/x y.csv", "serial:/dev/ttyACM0@921600", "zenoh:a/*/frames"] {
            let spec = parse(text).unwrap();
            assert_eq!(spec.to_string(), text);
            assert_eq!(parse(&spec.to_string()), Ok(spec));
        }
        assert_eq!(parse("serial:COM3").unwrap().to_string(), "serial:COM3@115200", "the baud is written out");
    }

    #[test]
    fn errors_quote_the_text_as_written_and_say_what_is_accepted() {
        let unknown = parse("Sim").unwrap_err();
        assert_eq!(unknown, SourceError::Unknown { spec: "Sim".into() });
        let message = unknown.to_string();
        for accepted in ["\"Sim\"", "`sim`", "`sim:SCRIPT`", "`file:PATH`", "`serial:PATH[@BAUD]`", "`zenoh:KEY`"] {
            assert!(message.contains(accepted), "{message:?} does not say {accepted}");
        }
        assert!(!message.contains("a file?"), "no path hint for a word: {message}");
        assert!(parse("runs/a.jsonl").unwrap_err().to_string().contains("write `file:runs/a.jsonl`"));
        assert_eq!(parse("sim:"), Err(SourceError::NoScript { spec: "sim:".into() }));
        assert_eq!(parse("file:"), Err(SourceError::NoFile { spec: "file:".into() }));
        assert_eq!(parse("file"), Err(SourceError::NoFile { spec: "file".into() }));
        assert_eq!(parse("zenoh:"), Err(SourceError::NoKey { spec: "zenoh:".into() }));
        assert_eq!(parse("zenoh"), Err(SourceError::NoKey { spec: "zenoh".into() }));
        assert_eq!(parse("serial"), Err(SourceError::EmptyPath { spec: "serial".into() }));
        assert_eq!(parse("serial:@9600"), Err(SourceError::EmptyPath { spec: "serial:@9600".into() }));
        let bad_baud = parse("serial:/dev/ttyUSB0@fast").unwrap_err();
        assert_eq!(bad_baud, SourceError::BadBaud { spec: "serial:/dev/ttyUSB0@fast".into(), baud: "fast".into() });
        assert!(bad_baud.to_string().contains("\"fast\""), "{bad_baud}");
    }
}
