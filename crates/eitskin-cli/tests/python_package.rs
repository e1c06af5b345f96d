//! The Python package (`python/`, PyO3 + maturin) built and tested as its users install it: a
//! fresh virtual environment under `target/`, `pip install ./python`, then its pytest suite
//! (every class, bad input raising, pyEIT's reference numbers from Python, eitskin's Zenoh
//! samples read by eclipse-zenoh, its ROS 2 messages by rosbags). Needs `python3` with `venv`, and PyPI for maturin, numpy,
//! pytest, matplotlib, eclipse-zenoh, cbor2 and rosbags on the first run; without them this test
//! fails and says which step it could not take.

use std::path::{Path, PathBuf};
use std::process::Command;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// Runs `program args` in the checkout's root with `bin` first on the search path (as an
/// activated virtual environment has it: maturin's build backend runs the `maturin` program it
/// installed), failing the test with its output.
fn step(what: &str, program: &Path, args: &[&str], bin: &Path) {
    let mut path = std::ffi::OsString::from(bin);
    if let Some(rest) = std::env::var_os("PATH") {
        path.push(":");
        path.push(rest);
    }
    let output = Command::new(program)
        .args(args)
        .env("PATH", path)
        // The CLI the Python tests compare with (tests/test_same_as_cli.py).
        .env("EITSKIN_BIN", env!("CARGO_BIN_EXE_eitskin"))
        .current_dir(root())
        .output()
        .unwrap_or_else(|e| panic!("{what}: cannot start {}: {e}", program.display()));
    let text = format!("{}{}", String::from_utf8_lossy(&output.stdout), String::from_utf8_lossy(&output.stderr));
    assert!(output.status.success(), "{what} failed ({}):\n{text}", output.status);
    eprintln!("{what}: ok\n{}", text.lines().rev().take(3).collect::<Vec<_>>().join("\n"));
}

#[test]
fn the_python_package_installs_and_passes_its_tests() {
    let venv = root().join("target/python-test-venv");
    let (python, bin) = (venv.join("bin/python"), venv.join("bin"));
    if !python.exists() {
        step("creating a virtual environment", Path::new("python3"), &["-m", "venv", &venv.to_string_lossy()], &bin);
    }
    let python = python.as_path();
    let pip = |what: &str, arguments: &[&str]| {
        let quiet = ["-m", "pip", "install", "--quiet", "--disable-pip-version-check"];
        step(what, python, &[&quiet[..], arguments].concat(), &bin);
    };
    // eclipse-zenoh (the release of the zenoh crate eitskin links) and cbor2: the independent
    // client that reads what `eitskin run --publish zenoh` sends (tests/test_zenoh.py); rosbags:
    // ROS 2's message definitions, type hashes and CDR, without ROS (tests/test_ros2.py).
    pip(
        "installing maturin, numpy, pytest, matplotlib, eclipse-zenoh, cbor2 and rosbags",
        &["maturin>=1.5,<2", "numpy", "pytest", "matplotlib", "eclipse-zenoh==1.10.2", "cbor2", "rosbags==0.11.9"],
    );
    pip("pip install ./python", &["--no-build-isolation", "--force-reinstall", "--no-deps", "./python"]);
    step("pytest python/tests", python, &["-m", "pytest", "-q", "python/tests"], &bin);
}
