//! Running the `eitskin` binary from the flow tests: each test in a scratch folder of its own,
//! which also holds the binary's reconstructor and press-model cache, removed when the test ends.
// Each test binary uses a subset of these helpers.
#![allow(dead_code)]

use std::ops::Deref;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use tempfile::TempDir;

/// A test's own folder under the system's temporary folder, removed with everything in it when
/// dropped: when the test ends, passed or failed (a failing assertion unwinds through it). Keep it
/// in a named binding (`let dir = scratch("…")`) for the whole test. Derefs to its path.
pub struct Scratch(TempDir);

/// A new scratch folder, named `eitskin-test-NAME-…`.
pub fn scratch(name: &str) -> Scratch {
    let prefix = format!("eitskin-test-{name}-");
    Scratch(tempfile::Builder::new().prefix(&prefix).tempdir().expect("a scratch folder"))
}

impl Deref for Scratch {
    type Target = Path;

    fn deref(&self) -> &Path {
        self.0.path()
    }
}

impl Scratch {
    /// The cache folder the binary is given (`EITSKIN_CACHE`): inside this one, shared by the
    /// test's runs of the binary and by no other test.
    pub fn cache(&self) -> PathBuf {
        self.join("cache")
    }

    /// The `eitskin` command with its cache in this folder, to be given arguments and run or spawned.
    pub fn command(&self) -> Command {
        let mut command = Command::new(env!("CARGO_BIN_EXE_eitskin"));
        command.env("EITSKIN_CACHE", self.cache());
        command
    }

    /// Runs `eitskin` with `args`, its cache in this folder, and waits for it.
    pub fn eitskin(&self, args: &[&str]) -> Output {
        self.command().args(args).output().expect("the binary runs")
    }
}

/// The standard output of a run that must have succeeded (else its standard error, failing).
pub fn ok(out: Output) -> String {
    assert!(out.status.success(), "failed: {}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8(out.stdout).expect("UTF-8")
}
