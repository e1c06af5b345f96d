//! The live viewer, in a real browser: `eitskin run --viewer` on the virtual sensor,
//! pressed hard at one place, opened in headless Chromium driven through chromedriver's WebDriver
//! HTTP API. The page connects, its heat map changes (and turns to the press colour where the
//! press is) when the sheet is pressed, the touch's unit and force it shows are the stdout line's
//! for the same frame, and its button re-takes the reference. A screenshot is left in
//! `target/viewer_browser.png`.
//!
//! Needs `chromium` and `chromedriver` on the PATH (Debian: `apt-get install chromium
//! chromium-driver`; `.ci/run` installs them); without them the test fails and says so.

mod binary;

use binary::{scratch, Scratch};
use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::{mpsc, Arc, Mutex};
use std::time::{Duration, Instant};

use serde_json::{json, Value};

/// Where the press is, in mm, and with what force, in N.
const PRESS: (f64, f64, f64) = (-50.0, 40.0, 9.0);

/// When the press starts, in s of the virtual sensor's clock: after the page has seen untouched
/// frames (on a busy 2-core machine the browser has taken more than 8 s to connect).
const PRESS_START: f64 = 20.0;

fn bin() -> &'static str {
    env!("CARGO_BIN_EXE_eitskin")
}

/// The first of `names` found on the PATH, or a failure that says how to install it.
fn find_program(names: &[&str], package: &str) -> PathBuf {
    let path = std::env::var_os("PATH").unwrap_or_default();
    for dir in std::env::split_paths(&path) {
        for name in names {
            let candidate = dir.join(name);
            if candidate.is_file() {
                return candidate;
            }
        }
    }
    panic!(
        "this test drives a real headless browser and needs {} on the PATH, which is not there. \
         Install it (Debian: `apt-get update && apt-get install -y chromium chromium-driver`; \
         package {package}), or run `.ci/run`, which installs it.",
        names.join(" or ")
    );
}

/// Kills the processes it holds when dropped, test failed or not; ends the browser session first.
#[derive(Default)]
struct Guard {
    children: Vec<Child>,
    session: Option<(u16, String)>,
}

impl Drop for Guard {
    fn drop(&mut self) {
        if let Some((port, session)) = self.session.take() {
            let _ = http(port, "DELETE", &format!("/session/{session}"), None, Duration::from_secs(10));
        }
        for child in &mut self.children {
            let _ = child.kill();
            let _ = child.wait();
        }
    }
}

/// One blocking HTTP/1.1 request to 127.0.0.1:`port`; the JSON body of the answer.
fn http(port: u16, method: &str, path: &str, body: Option<&Value>, timeout: Duration) -> Result<Value, String> {
    let mut stream = TcpStream::connect(("127.0.0.1", port)).map_err(|e| format!("connect: {e}"))?;
    stream.set_read_timeout(Some(timeout)).map_err(|e| e.to_string())?;
    stream.set_write_timeout(Some(timeout)).map_err(|e| e.to_string())?;
    let body = body.map(Value::to_string).unwrap_or_default();
    let request = format!(
        "{method} {path} HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nContent-Type: application/json; charset=utf-8\r\n\
         Content-Length: {}\r\nConnection: close\r\n\r\n{body}",
        body.len()
    );
    stream.write_all(request.as_bytes()).map_err(|e| format!("send: {e}"))?;
    // chromedriver keeps the connection open: read the headers, then as much as they announce.
    let (mut answer, mut buffer) = (Vec::new(), [0u8; 8192]);
    let (head, mut content) = loop {
        let n = stream.read(&mut buffer).map_err(|e| format!("{method} {path}: no answer: {e}"))?;
        answer.extend_from_slice(&buffer[..n]);
        let Some(split) = answer.windows(4).position(|w| w == b"\r\n\r\n") else {
            if n == 0 {
                return Err(format!("{method} {path}: the answer ends inside its headers"));
            }
            continue;
        };
        let head = String::from_utf8_lossy(&answer[..split]).to_ascii_lowercase();
        let content = &answer[split + 4..];
        let length = head.lines().find_map(|l| l.strip_prefix("content-length:")).and_then(|v| v.trim().parse().ok());
        let complete = match length {
            Some(length) => content.len() >= length,
            None if head.contains("transfer-encoding: chunked") => content.ends_with(b"0\r\n\r\n"),
            None => n == 0,
        };
        if complete || n == 0 {
            break (head.clone(), content.to_vec());
        }
    };
    if head.contains("transfer-encoding: chunked") {
        content = unchunk(&content)?;
    }
    let value: Value = serde_json::from_slice(&content).map_err(|e| format!("{method} {path}: not JSON: {e}"))?;
    let status = head.split_whitespace().nth(1).unwrap_or("?").to_string();
    if status != "200" {
        return Err(format!("{method} {path}: HTTP {status}: {value}"));
    }
    Ok(value)
}

fn unchunk(mut data: &[u8]) -> Result<Vec<u8>, String> {
    let mut out = Vec::new();
    loop {
        let line = data.windows(2).position(|w| w == b"\r\n").ok_or("a torn chunk")?;
        let size =
            usize::from_str_radix(String::from_utf8_lossy(&data[..line]).trim(), 16).map_err(|e| e.to_string())?;
        if size == 0 {
            return Ok(out);
        }
        let start = line + 2;
        out.extend_from_slice(data.get(start..start + size).ok_or("a short chunk")?);
        data = data.get(start + size + 2..).ok_or("a short chunk")?;
    }
}

/// A WebDriver session in one browser window.
struct Browser {
    port: u16,
    session: String,
}

impl Browser {
    fn call(&self, method: &str, path: &str, body: Option<Value>) -> Value {
        let path = format!("/session/{}{path}", self.session);
        match http(self.port, method, &path, body.as_ref(), Duration::from_secs(30)) {
            Ok(v) => v["value"].clone(),
            Err(e) => panic!("WebDriver: {e}"),
        }
    }

    /// Runs `script` (a function body) in the page and returns what it returns.
    fn js(&self, script: &str) -> Value {
        self.call("POST", "/execute/sync", Some(json!({"script": script, "args": []})))
    }
}

/// Polls `probe` every 100 ms until it gives a value or `seconds` have passed.
fn wait_for<T>(seconds: u64, what: &str, mut probe: impl FnMut() -> Option<T>) -> T {
    let deadline = Instant::now() + Duration::from_secs(seconds);
    loop {
        if let Some(v) = probe() {
            return v;
        }
        assert!(Instant::now() < deadline, "gave up after {seconds} s waiting for {what}");
        std::thread::sleep(Duration::from_millis(100));
    }
}

/// A free TCP port on 127.0.0.1 (free when asked; chromedriver takes it a moment later).
fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port()
}

/// A calibration made as a user makes one: `eitskin study`, then `eitskin calibrate`.
fn calibration(dir: &Scratch) -> PathBuf {
    let study = dir.join("study");
    let status = dir
        .command()
        .args([
            "study",
            "--out",
            study.to_str().unwrap(),
            "--validation",
            "20",
            // The paper's 15 frames a press: the pipeline measures the noise on the frames at
            // rest, and two of them leave the image's peak without samples in an area.
            "--repeats",
            "15",
            "--sweep-presses",
            "0",
        ])
        .stdout(Stdio::null())
        .status()
        .unwrap();
    assert!(status.success(), "eitskin study failed");
    let file = dir.join("calibration.json");
    let samples = study.join("calibration_frames.csv");
    let reference = study.join("reference.csv");
    let status = dir
        .command()
        .args(["calibrate", "--samples", samples.to_str().unwrap(), "--reference", reference.to_str().unwrap()])
        .args(["--out", file.to_str().unwrap()])
        .stdout(Stdio::null())
        .status()
        .unwrap();
    assert!(status.success(), "eitskin calibrate failed");
    file
}

/// Decodes standard base64 (the WebDriver screenshot).
fn base64(text: &str) -> Vec<u8> {
    let digit = |c: u8| match c {
        b'A'..=b'Z' => c - b'A',
        b'a'..=b'z' => c - b'a' + 26,
        b'0'..=b'9' => c - b'0' + 52,
        b'+' => 62,
        b'/' => 63,
        _ => panic!("not base64: {c}"),
    };
    let digits: Vec<u8> = text.bytes().filter(|c| !c.is_ascii_whitespace() && *c != b'=').map(digit).collect();
    let mut out = Vec::with_capacity(digits.len() * 3 / 4);
    for chunk in digits.chunks(4) {
        let n = chunk.iter().enumerate().fold(0u32, |n, (i, &d)| n | u32::from(d) << (18 - 6 * i));
        out.extend_from_slice(&n.to_be_bytes()[1..chunk.len()]);
    }
    out
}

#[test]
fn the_page_shows_the_press_the_stdout_force_and_retakes_the_reference() {
    let chromium = find_program(&["chromium", "chromium-browser", "google-chrome"], "chromium");
    let chromedriver = find_program(&["chromedriver"], "chromium-driver");
    let dir = scratch("page");
    let calibration = calibration(&dir);
    let script = dir.join("script.txt");
    let (x, y, force) = PRESS;
    std::fs::write(&script, format!("# start end x y force\n{PRESS_START} 1000 {x} {y} {force}\n")).unwrap();
    let mut guard = Guard::default();

    // The sensor, with its viewer on a free port.
    let source = format!("sim:{}", script.display());
    let mut run = dir
        .command()
        .args(["run", "--source", &source, "--viewer", "127.0.0.1:0", "--triangles", "1500", "--rate", "10"])
        .args(["--frames", "3000", "--calibration", calibration.to_str().unwrap(), "--fit"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let (stdout, stderr) = (run.stdout.take().unwrap(), run.stderr.take().unwrap());
    guard.children.push(run);
    let lines: Arc<Mutex<Vec<Value>>> = Arc::default();
    let sink = Arc::clone(&lines);
    std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines().map_while(Result::ok) {
            sink.lock().unwrap().push(serde_json::from_str(&line).expect("a JSON line on stdout"));
        }
    });
    let (said, heard) = mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            let _ = said.send(line);
        }
    });

    // The browser, started meanwhile.
    let driver_port = free_port();
    // In the test's folder, which outlives `guard`: the browser is stopped before it is removed.
    let profile = dir.join("profile");
    guard.children.push(
        Command::new(&chromedriver)
            .arg(format!("--port={driver_port}"))
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap(),
    );
    wait_for(30, "chromedriver to answer", || {
        http(driver_port, "GET", "/status", None, Duration::from_secs(5)).ok().filter(|v| v["value"]["ready"] == true)
    });
    let args = [
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--disable-quic",
        "--no-first-run",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        "--disable-dev-shm-usage",
        "--window-size=1500,1000",
        &format!("--user-data-dir={}", profile.display()),
    ];
    let capabilities = json!({"capabilities": {"alwaysMatch": {"goog:chromeOptions": {
        "binary": chromium.to_str().unwrap(), "args": args}}}});
    let session = http(driver_port, "POST", "/session", Some(&capabilities), Duration::from_secs(60))
        .unwrap_or_else(|e| panic!("chromedriver did not start {}: {e}", chromium.display()));
    let session = session["value"]["sessionId"].as_str().expect("a session id").to_string();
    guard.session = Some((driver_port, session.clone()));
    let browser = Browser { port: driver_port, session };

    let deadline = Instant::now() + Duration::from_secs(120);
    let url = loop {
        let remaining = deadline.saturating_duration_since(Instant::now());
        let line = heard.recv_timeout(remaining).expect("eitskin run said where its viewer is before the deadline");
        if let Some(rest) = line.strip_prefix("eitskin run: viewer at ") {
            break rest.trim().to_string();
        }
    };
    assert!(url.starts_with("http://127.0.0.1:") && url.ends_with('/'), "{url}");
    browser.call("POST", "/url", Some(json!({"url": url})));

    // The page connects and shows frames.
    wait_for(30, "the page to connect and draw a frame", || {
        (browser.js("return window.eitskin.connected && window.eitskin.drawn > 0;") == true).then_some(())
    });

    // Untouched frames, then the press: the heat map changes, and its strongest change is a press.
    let pressed = wait_for(60, "the page to show the press", || {
        let state = browser.js(
            "const s = window.eitskin; if (!s.touches.length) return null;
             const p = s.raster.getContext('2d').getImageData(s.peakPixel[0], s.peakPixel[1], 1, 1).data;
             return {seq: s.seq, peak: s.peak, checksum: s.checksum, touches: s.touches, pixel: Array.from(p),
                     floor: s.floor, scale: s.scale, expected: colour(s.peak / s.scale),
                     map: [-1, -0.6, 0, 0.4, 1].map(colour),
                     shown: Array.from(document.querySelectorAll('#touches tbody tr')).map(r => Array.from(r.cells).map(c => c.textContent)),
                     history: s.history};",
        );
        (!state.is_null()).then_some(state)
    });
    let history = pressed["history"].as_array().unwrap();
    let before: Vec<&Value> = history.iter().filter(|h| h["status"] == "ok" && h["touches"] == 0).collect();
    assert!(!before.is_empty(), "the page saw no untouched frame before the press: {history:?}");
    // The touch comes from Δv (the press model against the measured noise), not from the image,
    // whose λ is the calibration's (the paper's 0.1, noisy on this mesh): so the drawn peak need
    // not stand out from the untouched frames' noise peaks.
    assert!(before.iter().all(|h| h["checksum"] != pressed["checksum"]), "the heat map did not change with the press");
    // The colour scale is tied to the noise once the reference is taken: never below twice the
    // change a touch must reach, so an untouched sheet's noise stays pale.
    let floor = pressed["floor"].as_f64().expect("a colour-scale floor from the reference_taken event");
    assert!(floor > 0.0 && pressed["scale"].as_f64().unwrap() >= floor, "{pressed}");
    let quiet = before.iter().map(|h| h["peak"].as_f64().unwrap().abs()).fold(0.0, f64::max);
    assert!(quiet < floor, "an untouched frame's peak {quiet} S/m is drawn at full colour (floor {floor} S/m)");
    // The strongest change is a decrease, drawn at its pixel of the raster in the colour of its
    // value on the scale (blue for a decrease). At the calibration's λ, 0.1, the image is too
    // noisy on this mesh to place it at the press: the touch comes from Δv.
    assert!(pressed["peak"].as_f64().unwrap() < 0.0, "{pressed}");
    let [r, g, b] = [0, 1, 2].map(|i| pressed["pixel"][i].as_i64().unwrap());
    let want = [0, 1, 2].map(|i| pressed["expected"][i].as_i64().unwrap());
    assert!(want[2] > want[0], "a decrease is drawn blue: {want:?}");
    // The page's map is the library's, which the CLI's figures and Python's plots use.
    for (k, u) in [-1.0, -0.6, 0.0, 0.4, 1.0].into_iter().enumerate() {
        let drawn: Vec<i64> = (0..3).map(|i| pressed["map"][k][i].as_i64().unwrap()).collect();
        let library = eitskin::colour::colour(u).map(i64::from);
        assert_eq!(drawn, library, "the page colours {u} as {drawn:?}, the library as {library:?}");
    }
    assert!(
        [r, g, b].iter().zip(want).all(|(got, want)| (got - want).abs() <= 1),
        "the heat map at its peak is {r},{g},{b}, not {want:?}, the colour of its value"
    );

    // The touch shown is the stdout line's for the same frame: position, unit, force.
    let seq = pressed["seq"].as_u64().unwrap();
    let line = wait_for(10, "the stdout line of the frame shown", || {
        lines.lock().unwrap().iter().find(|l| l["seq"] == seq && l.get("event").is_none()).cloned()
    });
    let (page, printed) = (&pressed["touches"][0], &line["touches"][0]);
    // Numbers compared as numbers: the page's JSON writes 10.0 as 10.
    assert_eq!(
        as_floats(&pressed["touches"]),
        as_floats(&line["touches"]),
        "frame {seq}: the page's touches differ from stdout's"
    );
    let (tx, ty) = (printed["x"].as_f64().unwrap(), printed["y"].as_f64().unwrap());
    assert!((tx - x).hypot(ty - y) < 15.0, "the touch is at ({tx}, {ty}) mm, pressed at ({x}, {y})");
    let printed_force = printed["force"].as_f64().expect("a force, with the calibration");
    assert!(printed_force > 2.0, "a hard press gives {printed_force} N");
    let row = &pressed["shown"][0];
    assert_eq!(row[3], printed["unit"].to_string(), "unit shown: {row}");
    // Without a calibration the page still names the unit a touch sits in, numbered as the
    // library numbers them (from 1 here), the far edges in the last unit, nothing outside.
    let setup = browser.js("return window.eitskin.setup;");
    let grid = [0, 1].map(|i| setup["grid"][i].as_u64().unwrap() as usize);
    let bounds = [0, 1].map(|c| [0, 1].map(|i| setup["grid_bounds"][c][i].as_f64().unwrap()));
    let array = eitskin::pseudo_array::PseudoArray::one_area_per_unit(bounds, grid).unwrap();
    let [[x0, y0], [x1, y1]] = bounds;
    let places =
        [[x0, y0], [x1, y1], [x1, y0], [(x0 + x1) / 2.0, (y0 + y1) / 3.0], [x1 + 1.0, y0], [x0, y0 - 1.0], [tx, ty]];
    for [px, py] in places {
        let page = browser.js(&format!("return unitAt({px}, {py});")).as_u64().map(|u| u as usize);
        assert_eq!(page, array.unit_at([px, py]).map(|u| u + 1), "the page's unit at ({px}, {py})");
    }
    let printed_drop = printed["press"]["drop"].as_f64().expect("a fitted press, with --fit");
    assert_eq!(row[8], format!("{printed_drop:.3}"), "drop shown: {row}");
    let printed_z = printed["z"].as_f64().expect("the touch's detection confidence");
    assert_eq!(row[6], format!("{printed_z:.1}"), "z shown: {row}");
    let shown_force: f64 = row[7].as_str().unwrap().split(' ').next().unwrap().parse().unwrap();
    assert!(
        (shown_force - printed_force).abs() <= 0.005 + 1e-9,
        "force shown {shown_force} N, printed {printed_force} N"
    );
    assert_eq!(page["force"], printed["force"]);
    assert!(line["counters"]["viewer_dropped"].is_u64(), "the stdout counters carry viewer_dropped: {line}");

    // The rate shown is the sensor's, 10 frames/s, from the frames' own clock (arrival times in
    // the browser read 123 to 2,700 frames/s while the source ran at 20).
    let fps = browser.js("return window.eitskin.fps;").as_f64().expect("a frame rate");
    assert!((fps - 10.0).abs() < 0.5, "the page shows {fps} frames/s for a 10 frames/s source");

    // A screenshot, kept beside the build.
    let png = base64(browser.call("GET", "/screenshot", None).as_str().expect("a base64 screenshot"));
    assert!(png.starts_with(b"\x89PNG"), "the screenshot is not a PNG");
    let target = Path::new(bin()).ancestors().nth(2).expect("the binary lies in target/PROFILE/");
    std::fs::write(target.join("viewer_browser.png"), png).unwrap();

    // The button re-takes the reference: stdout shows referencing frames again after the click.
    let clicked_after = lines.lock().unwrap().iter().filter_map(|l| l["seq"].as_u64()).max().unwrap_or(0);
    let button = browser.call("POST", "/element", Some(json!({"using": "css selector", "value": "#retake"})));
    let button =
        button.as_object().and_then(|o| o.values().next()).and_then(Value::as_str).expect("the button").to_string();
    browser.call("POST", &format!("/element/{button}/click"), Some(json!({})));
    wait_for(30, "referencing frames after the click", || {
        let lines = lines.lock().unwrap();
        let asked = lines.iter().any(|l| l["event"] == "reference");
        let again = lines.iter().any(|l| l["status"] == "referencing" && l["seq"].as_u64() > Some(clicked_after));
        (asked && again).then_some(())
    });
    wait_for(30, "the page to show the reference being taken", || {
        (browser.js("return window.eitskin.status;") == "referencing").then_some(())
    });
    drop(guard);
}

/// `value` with every number as an f64 (JavaScript writes a whole float as an integer).
fn as_floats(value: &serde_json::Value) -> serde_json::Value {
    use serde_json::Value;
    match value {
        Value::Number(n) => n.as_f64().map_or(Value::Null, |x| serde_json::json!(x)),
        Value::Array(items) => Value::Array(items.iter().map(as_floats).collect()),
        Value::Object(fields) => Value::Object(fields.iter().map(|(k, v)| (k.clone(), as_floats(v))).collect()),
        other => other.clone(),
    }
}
