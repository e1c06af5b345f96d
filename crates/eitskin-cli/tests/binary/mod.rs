//! Running the `eitskin` binary from the flow tests: a reconstructor and press-model cache of
//! the test process's own, and scratch directories.
// Each test binary uses a subset of these helpers.
#![allow(dead_code)]

use std::path::PathBuf;
use std::process::{Command, Output};

/// Runs `eitskin` with `args`, its caches under a directory of this test process.
pub fn eitskin(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_eitskin"))
        .args(args)
        .env("EITSKIN_CACHE", cache())
        .output()
        .expect("the binary runs")
}

/// The cache directory the binary is given.
pub fn cache() -> PathBuf {
    std::env::temp_dir().join(format!("eitskin-test-{}-cache", std::process::id()))
}

/// The standard output of a run that must have succeeded (else its standard error, failing).
pub fn ok(out: Output) -> String {
    assert!(out.status.success(), "failed: {}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8(out.stdout).expect("UTF-8")
}

/// A scratch directory of this test process, named `name`.
pub fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("eitskin-test-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("a scratch directory");
    dir
}
