//! `eitskin serve` under load: a fleet of replayed sensors, each fed at 100 frames/s by a
//! bridge on Zenoh, measured from each frame's put by its bridge to its line's arrival at a
//! subscriber (so the figure includes both Zenoh hops around eitskin), with every sequence
//! number checked at the subscriber. Everything on loopback: this process is the bridges, the
//! subscriber and the Zenoh peer they reach (127.0.0.1 only, no multicast); `serve` is a client.
//!
//! ```text
//! cargo bench -p eitskin-cli --bench serve_fleet -- [SENSORS] [SECONDS] [THREADS]   (100, 10, the cores)
//! ```
//!
//! `SERVE_FLEET_WINDOW` sets the windows' length in seconds (10 unless told).
//! `SERVE_FLEET_RUN` adds flags to every sensor's `run` (e.g. `--hyperparameter 1`, to see what
//! the automatic λ's refreshes cost, or `--precision single`); the docs say which figures took it.
//! Without it each sensor's precision is `auto`: for a fleet whose matrices overflow the cache,
//! half until its λ is chosen from its noise, then through the basis the fleet's sensors share.
//!
//! Frames are a recording of the virtual sensor: 2 s at rest, then a press every 3 s (held
//! 2 s, each at another place and force), 14 s in all. Every sensor plays the rest first (its
//! reference), then loops over the presses from a point of its own, so that presses come and go
//! on some sensor all the time, never on all at once; each sensor's puts are shifted within the
//! frame period too. The first 100 frames of each sensor (its reference, taken while every
//! sensor takes its own) are reported apart from the rest, and the run's second half apart
//! again; and when each sensor's first imaged line came.
//!
//! Sensor 0's board dies for the middle fifth of the run (its bridge sends nothing from 40 % to
//! 60 % of it) and comes back: the bench reports when its `silent` and `resumed` events came, its
//! frames after the outage, and every other sensor's latency meanwhile (the 10-s windows).

use std::collections::HashMap;
use std::process::{Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use zenoh::qos::CongestionControl;
use zenoh::Wait;

const RATE_HZ: f64 = 100.0;
/// The sensor whose board dies for a while.
const DEAD: usize = 0;
/// The latency is also given for each window of this many seconds of the frames' times
/// (`SERVE_FLEET_WINDOW` sets another, whole seconds).
const WINDOW_S: usize = 10;
const WARM_UP: u64 = 100;
/// Frames of the recording: 2 s at rest, then four presses 3 s apart, 1 s at rest after the last.
const RECORDED: u64 = 1400;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).filter(|a| !a.starts_with("--")).collect();
    let number = |k: usize, default: usize| args.get(k).and_then(|a| a.parse().ok()).unwrap_or(default);
    let (sensors, seconds) = (number(0, 100), number(1, 10));
    let threads = args.get(2).cloned();
    let frames = seconds as u64 * RATE_HZ as u64;
    let window_s =
        std::env::var("SERVE_FLEET_WINDOW").ok().and_then(|w| w.parse().ok()).filter(|w| *w > 0).unwrap_or(WINDOW_S);
    // The frames sensor DEAD's board never sends.
    let dead = if sensors > 1 { frames * 2 / 5..frames * 3 / 5 } else { 0..0 };
    let eitskin = env!("CARGO_BIN_EXE_eitskin");
    let dir = tempfile::tempdir().expect("a scratch folder");

    // The frames: the virtual sensor pressed twice, recorded once.
    let script = dir.path().join("script.txt");
    let presses = "# start end x y force\n2 4 -50 40 9\n5 7 30 -20 6\n8 10 60 60 3\n11 13 -20 -60 12\n";
    std::fs::write(&script, presses).expect("the script");
    let recording = dir.path().join("frames.jsonl");
    let made = Command::new(eitskin)
        .args(["run", "--fast", "--frames", &RECORDED.to_string(), "--record"])
        .arg(&recording)
        .arg("--source")
        .arg(format!("sim:{}", script.display()))
        .stdout(Stdio::null())
        .status()
        .expect("eitskin runs");
    assert!(made.success(), "the recording");
    let records: Vec<Vec<f64>> = std::fs::read_to_string(&recording)
        .expect("the recording")
        .lines()
        .skip(1)
        .map(|line| {
            let record: serde_json::Value = serde_json::from_str(line).expect("a record");
            record["values"].as_array().expect("values").iter().map(|v| v.as_f64().expect("a number")).collect()
        })
        .collect();

    let values: Vec<String> = records.iter().map(|v| serde_json::to_string(v).expect("values")).collect();

    // The peer: loopback only, no multicast.
    let port = std::net::TcpListener::bind("127.0.0.1:0").and_then(|l| l.local_addr()).expect("a port").port();
    let mut config = zenoh::Config::default();
    config.insert_json5("listen/endpoints", &format!("[\"tcp/127.0.0.1:{port}\"]")).expect("config");
    config.insert_json5("scouting/multicast/enabled", "false").expect("config");
    let session = zenoh::open(config).wait().expect("a Zenoh session");

    // The subscriber: when each (sensor, seq) came, and each sensor's first imaged line.
    // Room for every frame from the start: a map growing past half a million entries stalls the
    // subscriber's thread for tens of milliseconds each time it doubles (twice in a minute).
    let arrived = Arc::new(Mutex::new(HashMap::<(usize, u64), Instant>::with_capacity(sensors * frames as usize)));
    let first_imaged: Arc<Mutex<HashMap<usize, u64>>> = Arc::default();
    let (sink, imaged) = (Arc::clone(&arrived), Arc::clone(&first_imaged));
    let _subscriber = session
        .declare_subscriber("bench/*/touches")
        .callback(move |sample| {
            let now = Instant::now();
            let sensor = sample.key_expr().as_str().split('/').nth(1).and_then(|s| s[1..].parse().ok());
            let line: Result<serde_json::Value, _> = serde_json::from_slice(&sample.payload().to_bytes());
            if let (Some(sensor), Ok(line)) = (sensor, line) {
                if let Some(seq) = line["seq"].as_u64() {
                    sink.lock().expect("the map").insert((sensor, seq), now);
                    if line["status"] == "ok" {
                        imaged.lock().expect("the map").entry(sensor).or_insert(seq);
                    }
                }
            }
        })
        .wait()
        .expect("a subscriber");
    // When each sensor's derivations (its reference's, its noise's) came in, and the dead
    // sensor's source events.
    let derived: Arc<Mutex<Vec<Instant>>> = Arc::default();
    let outage: Arc<Mutex<Vec<(String, Instant)>>> = Arc::default();
    let (events, outage_events) = (Arc::clone(&derived), Arc::clone(&outage));
    let _events = session
        .declare_subscriber("bench/*/events")
        .callback(move |sample| {
            let line: Result<serde_json::Value, _> = serde_json::from_slice(&sample.payload().to_bytes());
            let Ok(line) = line else { return };
            if line["event"] == "reference_taken" || line["event"] == "noise_updated" {
                events.lock().expect("the list").push(Instant::now());
            }
            if line["event"] == "silent" || line["event"] == "resumed" {
                let said = format!("{}: {}", sample.key_expr(), line["detail"].as_str().unwrap_or_default());
                outage_events.lock().expect("the list").push((said, Instant::now()));
            }
        })
        .wait()
        .expect("a subscriber");

    // The fleet: each sensor's frames from its bridge's key, published under bench/.
    let fleet = dir.path().join("fleet.toml");
    let extra: String = std::env::var("SERVE_FLEET_RUN")
        .unwrap_or_default()
        .split_whitespace()
        .map(|flag| format!(", {flag:?}"))
        .collect();
    let mut text = String::new();
    for k in 0..sensors {
        let taken = if k == DEAD { frames - (dead.end - dead.start) } else { frames };
        text += &format!(
            "[[sensor]]\nname = \"s{k}\"\nrun = [\"--source\", \"zenoh:board/s{k}\", \"--frames\", \"{taken}\", \
             \"--publish\", \"zenoh:bench\", \"--wait-for-subscriber\", \"600\"{extra}]\n\n"
        );
    }
    std::fs::write(&fleet, text).expect("the fleet");
    let mut serve = Command::new(eitskin);
    serve.arg("serve").arg(&fleet).args(["--zenoh-mode", "client", "--no-multicast-scouting", "--connect"]);
    serve.arg(format!("tcp/127.0.0.1:{port}"));
    if let Some(threads) = &threads {
        serve.args(["--threads", threads]);
    }
    let setup = Instant::now();
    let mut child = serve.stderr(Stdio::null()).spawn().expect("eitskin serve");

    let publishers: Vec<_> = (0..sensors)
        .map(|k| {
            session
                .declare_publisher(format!("board/s{k}"))
                .congestion_control(CongestionControl::Block)
                .wait()
                .expect("a bridge")
        })
        .collect();
    for publisher in &publishers {
        while !publisher.matching_status().wait().map(|s| s.matching()).unwrap_or(false) {
            assert!(child.try_wait().expect("serve").is_none(), "serve ended during its setup");
            std::thread::sleep(Duration::from_millis(20));
        }
    }
    let setup_s = setup.elapsed().as_secs_f64();

    // 100 frames/s a sensor, sensor k shifted by k/sensors of a period.
    let period = Duration::from_secs_f64(1.0 / RATE_HZ);
    let mut sent = HashMap::with_capacity(sensors * frames as usize);
    let start = Instant::now() + Duration::from_millis(100);
    let mut late_puts = 0usize;
    let mut due: Vec<(Instant, usize, u64)> = (0..sensors)
        .flat_map(|k| {
            let shift = period.mul_f64(k as f64 / sensors as f64);
            (0..frames).map(move |seq| (start + period * seq as u32 + shift, k, seq))
        })
        .collect();
    due.sort();
    for (at, k, seq) in due {
        if k == DEAD && dead.contains(&seq) {
            continue;
        }
        let now = Instant::now();
        if at > now {
            std::thread::sleep(at - now);
        } else if now - at > period {
            late_puts += 1;
        }
        // The rest first; then the presses, looped, from sensor k's own point.
        let pressing = records.len() as u64 - WARM_UP;
        let at = if seq < WARM_UP {
            seq
        } else {
            WARM_UP + (seq - WARM_UP + k as u64 * pressing / sensors as u64) % pressing
        };
        // The message a bridge sends, its values written once per record (so that this process,
        // on the same cores, spends little of them on making the load).
        let bytes = format!("{{\"seq\":{seq},\"t_s\":{},\"values\":{}}}", seq as f64 / RATE_HZ, values[at as usize]);
        sent.insert((k, seq), Instant::now());
        publishers[k].put(bytes).wait().expect("a put");
    }
    let status = child.wait().expect("serve ends");
    std::thread::sleep(Duration::from_millis(500));

    let arrived = arrived.lock().expect("the map");
    let (mut warm, mut steady, mut late, mut lost) = (Vec::new(), Vec::new(), Vec::new(), 0usize);
    let mut windows: Vec<Vec<f64>> = vec![Vec::new(); seconds.div_ceil(window_s)];
    for (&(k, seq), &put) in &sent {
        match arrived.get(&(k, seq)) {
            Some(&came) => {
                let ms = came.duration_since(put).as_secs_f64() * 1e3;
                if seq < WARM_UP {
                    warm.push(ms)
                } else {
                    steady.push(ms)
                }
                if seq >= frames / 2 {
                    late.push(ms);
                }
                windows[(seq as f64 / RATE_HZ) as usize / window_s].push(ms);
            }
            None => lost += 1,
        }
    }
    let summary = |name: &str, mut ms: Vec<f64>| {
        if ms.is_empty() {
            return;
        }
        ms.sort_by(f64::total_cmp);
        let at = |q: f64| ms.get(((ms.len() as f64 - 1.0) * q).round() as usize).copied().unwrap_or(f64::NAN);
        println!(
            "{name}: {} frames, latency p50 {:.2} ms, p99 {:.2} ms, p99.9 {:.2} ms, max {:.2} ms",
            ms.len(),
            at(0.5),
            at(0.99),
            at(0.999),
            at(1.0)
        );
    };
    println!(
        "serve_fleet: {sensors} sensors × {RATE_HZ} frames/s for {seconds} s on {} threads (serve {}); setup {setup_s:.1} s; \
         puts more than a period late: {late_puts}",
        threads.as_deref().unwrap_or("all"),
        if status.success() { "ended well" } else { "FAILED" }
    );
    summary(&format!("first {WARM_UP} frames a sensor (reference, noise)"), warm);
    summary(&format!("after the first {WARM_UP}"), steady);
    summary("second half of the run", late);
    let derived = derived.lock().expect("the list");
    let since_start = |at: &Instant| at.saturating_duration_since(start).as_secs_f64();
    for (w, ms) in windows.into_iter().enumerate() {
        let (from, to) = ((w * window_s) as f64, ((w + 1) * window_s) as f64);
        let came = derived.iter().map(since_start).filter(|s| (from..to).contains(s)).count();
        summary(&format!("  frames of {from}–{to} s ({came} derivations came in)"), ms);
    }
    println!("lost (put, never at the subscriber): {lost} of {}", sent.len());
    let imaged = first_imaged.lock().expect("the map");
    let latest = imaged.values().max().map_or(f64::NAN, |seq| *seq as f64 / RATE_HZ);
    println!("sensors imaging: {} of {sensors}, the last from {latest:.1} s (its frame time)", imaged.len());
    let last = derived.iter().max().map_or(f64::NAN, since_start);
    println!(
        "derivations in (reference taken, noise updated): {}, the last {last:.1} s after the first put",
        derived.len()
    );
    let came = |seq: u64| arrived.contains_key(&(DEAD, seq));
    let after = (dead.end..frames).filter(|seq| came(*seq)).count();
    println!(
        "sensor {DEAD}, its board silent for frames {}–{} ({:.1}–{:.1} s): {after} of {} frames after it served",
        dead.start,
        dead.end,
        dead.start as f64 / RATE_HZ,
        dead.end as f64 / RATE_HZ,
        frames - dead.end
    );
    for (said, at) in outage.lock().expect("the list").iter() {
        println!("  at {:.1} s: {said}", at.saturating_duration_since(start).as_secs_f64());
    }
}
