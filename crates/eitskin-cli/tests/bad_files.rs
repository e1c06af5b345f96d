//! Every file a command reads, given each kind of bad content under each name it may carry:
//! a clean refusal that names the file, within seconds, no panic, and no output written. The
//! kinds and the commands are crossed here, not listed case by case, so that a reader added
//! later is held to the same edge by adding one line.

mod binary;

use std::path::PathBuf;
use std::process::Stdio;
use std::time::{Duration, Instant};

use binary::{ok, scratch, Scratch};

/// Kinds of bad content, each with a name for the failure message.
fn bad_contents() -> Vec<(&'static str, Vec<u8>)> {
    let binary: Vec<u8> = (0..=255u8).cycle().take(700).collect();
    vec![
        ("empty", Vec::new()),
        ("a header alone", b"x,y,force\n".to_vec()),
        ("binary", binary),
        ("a byte-order mark and words", "\u{feff}hello,world\n1,2\n".as_bytes().to_vec()),
        ("NaN", b"NaN,NaN,NaN\nNaN,NaN,NaN\n".to_vec()),
        ("ragged rows", b"1,2,3\n4,5\n".to_vec()),
        ("torn JSON", br#"{"a": [1, 2"#.to_vec()),
        ("another JSON", br#"{"kind": "something else", "values": [1, 2, 3]}"#.to_vec()),
        ("an overflowing number", b"1e400,2,3\n".to_vec()),
    ]
}

/// A command reading one file: its arguments with `{}` for the file, the names the file is
/// given (each extension a reader may dispatch on), and the output it must not leave.
struct Reader {
    args: Vec<String>,
    extensions: &'static [&'static str],
    output: Option<PathBuf>,
}

fn readers(dir: &Scratch) -> Vec<Reader> {
    let path = |name: &str| dir.join(name).to_str().unwrap().to_owned();
    // Good inputs for the other flags: a reference frame, presses and a model.
    let reference = path("reference.csv");
    std::fs::write(&reference, ok(dir.eitskin(&["forward", "--format", "csv"]))).unwrap();
    let presses = path("presses.csv");
    ok(dir.eitskin(&["robot-presses", "--count", "12", "--out", &presses]));
    let model = path("model.json");
    ok(dir.eitskin(&["learn", "--samples", &presses, "--method", "knn-1", "--out", &model]));
    let frames: &[&str] = &["txt", "csv", "npy", "mat", "json"];
    let reader = |args: &[&str], extensions, output: Option<&str>| Reader {
        args: args.iter().map(|a| a.to_string()).collect(),
        extensions,
        output: output.map(|o| dir.join(o)),
    };
    let labels = path("labels.npy");
    let calibration = path("calibration.json");
    let learned = path("learned.json");
    vec![
        reader(&["image", "--reference", "{}", "--frame", &reference], frames, None),
        reader(&["image", "--reference", &reference, "--frame", "{}"], frames, None),
        reader(&["segment", "--reference", &reference, "--frame", "{}", "--out", &labels], frames, Some("labels.npy")),
        reader(&["calibrate", "--samples", "{}", "--out", &calibration], &["csv"], Some("calibration.json")),
        reader(&["evaluate", "--calibration", "{}", "--samples", &presses], &["json"], None),
        reader(&["evaluate", "--model", "{}", "--samples", &presses], &["json"], None),
        reader(&["evaluate", "--model", &model, "--samples", "{}"], &["csv"], None),
        reader(&["learn", "--samples", "{}", "--out", &learned], &["csv"], Some("learned.json")),
        reader(&["learn", "--samples", &presses, "--held-out", "{}"], &["csv"], None),
        reader(&["learn", "--samples", &presses, "--reference", "{}"], &["txt", "npy", "mat"], None),
        reader(&["run", "--calibration", "{}", "--frames", "12"], &["json"], None),
        reader(&["run", "--model", "{}", "--frames", "12"], &["json"], None),
        reader(&["run", "--source", "file:{}", "--frames", "12"], &["txt", "npy", "mat"], None),
        reader(&["forward", "--mesh", "{}"], &["json"], None),
        reader(&["forward", "--protocol", "{}"], &["json"], None),
        reader(&["spec", "{}"], &["toml"], None),
    ]
}

/// Runs `args` with a time limit; its exit code (None if killed) and standard error.
fn run_limited(dir: &Scratch, args: &[String], limit: Duration) -> (Option<i32>, String) {
    let mut child = dir.command().args(args).stdout(Stdio::null()).stderr(Stdio::piped()).spawn().unwrap();
    let started = Instant::now();
    loop {
        if let Some(status) = child.try_wait().unwrap() {
            let mut stderr = String::new();
            std::io::Read::read_to_string(child.stderr.as_mut().unwrap(), &mut stderr).unwrap();
            return (status.code(), stderr);
        }
        if started.elapsed() > limit {
            child.kill().unwrap();
            let _ = child.wait();
            return (None, String::new());
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

#[test]
fn every_reader_refuses_every_kind_of_bad_file_cleanly() {
    let dir = scratch("bad-files");
    let mut failures = Vec::new();
    let mut cases = 0;
    for reader in readers(&dir) {
        for (kind, content) in bad_contents() {
            for extension in reader.extensions {
                let bad = dir.join(format!("bad.{extension}"));
                std::fs::write(&bad, &content).unwrap();
                let args: Vec<String> = reader.args.iter().map(|a| a.replace("{}", bad.to_str().unwrap())).collect();
                let said = format!("{} ({kind}, .{extension})", args.join(" "));
                cases += 1;
                let (code, stderr) = run_limited(&dir, &args, Duration::from_secs(10));
                let named = stderr.contains(&format!("bad.{extension}"));
                if std::env::var_os("EITSKIN_SHOW_REFUSALS").is_some() {
                    eprintln!("{said}:\n  {}", stderr.trim().replace('\n', "\n  "));
                }
                let problem = match code {
                    None => Some("still running after 10 s".to_owned()),
                    Some(_) if stderr.contains("panicked") => Some(format!("a panic: {stderr}")),
                    Some(0) => Some("exit 0".to_owned()),
                    Some(_) if !named => Some(format!("the message does not name the file: {stderr}")),
                    Some(_) => {
                        reader.output.as_deref().filter(|o| o.exists()).map(|o| format!("{} written", o.display()))
                    }
                };
                if let Some(problem) = problem {
                    failures.push(format!("{said}: {problem}"));
                }
                let _ = std::fs::remove_file(&bad);
            }
        }
    }
    assert!(failures.is_empty(), "{} of {cases} cases:\n{}", failures.len(), failures.join("\n"));
    assert!(cases > 200, "every reader, kind and name crossed: {cases} cases");
}
