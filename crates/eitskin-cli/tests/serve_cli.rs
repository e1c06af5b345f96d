//! `eitskin serve FLEET.toml`, through the real binary: a fleet's mistakes refused before any
//! work, naming the sensor; a sensor whose bridge stops sending holds none of the others up
//! (every one of their frames reaches the subscriber, in order), and goes on when its bridge
//! comes back; a sensor that cannot start is reported, the others served, and `serve` fails at
//! the end saying which. The latency of 100 sensors at 100 frames/s is a benchmark
//! (`cargo bench -p eitskin-cli --bench serve_fleet`), not a test.
//!
//! Traffic stays on loopback: the test's peer listens on 127.0.0.1 only, serve connects to it as
//! a client, multicast scouting is off on both.

mod binary;
mod loopback;

use std::collections::BTreeMap;
use std::process::Stdio;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use binary::scratch;
use eitskin_io::middleware::FrameMessage;
use loopback::{free_port, peer};
use zenoh::qos::CongestionControl;
use zenoh::Wait;

fn sensor(name: &str, run: &[&str]) -> String {
    let run: Vec<String> = run.iter().map(|a| format!("{a:?}")).collect();
    format!("[[sensor]]\nname = \"{name}\"\nrun = [{}]\n\n", run.join(", "))
}

#[test]
fn a_fleets_mistakes_are_refused_before_any_work_naming_the_sensor() {
    let dir = scratch("serve-flags");
    let good = sensor("palm", &["--frames", "20", "--publish", "zenoh"]);
    for (fleet, says) in [
        (good.clone() + &good, "2: name \"palm\" is sensor 1's already"),
        (sensor("palm", &["--frames", "20"]), "sensor palm: it publishes nothing and records nothing"),
        (
            sensor("palm", &["--publish", "zenoh", "--connect", "tcp/127.0.0.1:7447"]),
            "sensor palm: --connect is the fleet's",
        ),
        (sensor("palm", &["--publish", "zenoh", "--sensor", "x"]), "sensor palm: --sensor is the fleet's"),
        (sensor("palm", &["--publish", "zenoh", "--frames", "x"]), "sensor palm: invalid value 'x' for '--frames"),
        (sensor("palm", &["--publish", "ros2:a//b"]), "sensor palm: the ROS namespace"),
        (sensor("9palm", &["--publish", "zenoh"]), "\"9palm\" is not a sensor's name"),
        (
            sensor("palm", &["--record", "x.jsonl"]) + &sensor("back", &["--record", "x.jsonl"]),
            "sensor back: --record x.jsonl is sensor palm's already",
        ),
    ] {
        let path = dir.join("fleet.toml");
        std::fs::write(&path, &fleet).unwrap();
        let started = Instant::now();
        let out = dir.eitskin(&["serve", path.to_str().unwrap(), "--zenoh-mode", "client", "--no-multicast-scouting"]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && err.contains(says), "{fleet}: {err}");
        assert!(started.elapsed() < Duration::from_secs(30), "{fleet} was refused only after {:?}", started.elapsed());
    }
    let missing = dir.join("no-such-fleet.toml");
    let out = dir.eitskin(&["serve", missing.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("no-such-fleet.toml"), "{err}");
    let out = dir.eitskin(&["serve", dir.join("fleet.toml").to_str().unwrap(), "--threads", "0"]);
    assert!(String::from_utf8_lossy(&out.stderr).contains("\"0\" is not a number of threads"));
}

/// Each sensor's lines: seq, and whether the frame was imaged.
type Lines = BTreeMap<String, Vec<(u64, bool)>>;

#[test]
fn a_sensor_whose_bridge_stops_holds_none_of_the_others_up() {
    const FRAMES: u64 = 200;
    const HALF: u64 = 20;
    let dir = scratch("serve-fleet");
    let recording = dir.join("sim.jsonl");
    let frames = FRAMES.to_string();
    let made = dir.eitskin(&[
        "run",
        "--fast",
        "--frames",
        &frames,
        "--triangles",
        "500",
        "--record",
        recording.to_str().unwrap(),
    ]);
    binary::ok(made);
    let recorded: Vec<Vec<f64>> = std::fs::read_to_string(&recording)
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| {
            serde_json::from_value(serde_json::from_str::<serde_json::Value>(l).unwrap()["values"].clone()).unwrap()
        })
        .collect();
    let names = ["a", "b", "c"];
    let mut fleet = String::new();
    for name in names {
        let source = format!("zenoh:board/{name}");
        let run = ["--source", &source, "--frames", &frames, "--triangles", "500", "--publish", "zenoh:fleet"];
        fleet += &sensor(name, &run);
    }
    fleet += &sensor("d", &["--source", "file:missing.jsonl", "--publish", "zenoh:fleet"]);
    // A replay read as fast as it goes: its frames wait for the reference's derivation.
    fleet += &sensor("e", &["--source", "file:sim.jsonl", "--fast", "--triangles", "500", "--publish", "zenoh:fleet"]);
    std::fs::write(dir.join("fleet.toml"), fleet).unwrap();

    let port = free_port();
    let session = peer(port);
    let lines: Arc<Mutex<Lines>> = Arc::default();
    let sink = Arc::clone(&lines);
    let _subscriber = session
        .declare_subscriber("fleet/*/touches")
        .callback(move |sample| {
            let name = sample.key_expr().as_str().split('/').nth(1).unwrap().to_owned();
            let line: serde_json::Value = serde_json::from_slice(&sample.payload().to_bytes()).unwrap();
            let said = (line["seq"].as_u64().unwrap(), line["status"] == "ok");
            sink.lock().unwrap().entry(name).or_default().push(said);
        })
        .wait()
        .unwrap();
    let bridges: Vec<_> = names
        .iter()
        .map(|n| {
            session.declare_publisher(format!("board/{n}")).congestion_control(CongestionControl::Block).wait().unwrap()
        })
        .collect();
    let child = dir
        .command()
        .args(["serve", "fleet.toml", "--zenoh-mode", "client", "--no-multicast-scouting", "--connect"])
        .arg(format!("tcp/127.0.0.1:{port}"))
        .current_dir(&*dir)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let deadline = Instant::now() + Duration::from_secs(120);
    let wait_until = |what: &str, done: &dyn Fn() -> bool| {
        while !done() {
            assert!(Instant::now() < deadline, "timed out waiting for {what}");
            std::thread::sleep(Duration::from_millis(20));
        }
    };
    // A bridge may start once its sensor says it is alive: the sensor subscribed before.
    let alive = |name: &str| {
        let replies = session.liveliness().get(format!("fleet/{name}/alive")).wait().unwrap();
        replies.iter().any(|reply| reply.result().is_ok())
    };
    wait_until("the sensors to be alive", &|| names.iter().all(|name| alive(name)));
    let put = |k: usize, seq: u64| {
        let message = FrameMessage { seq, t: seq as f64 * 0.01, values: recorded[seq as usize].clone() };
        bridges[k].put(serde_json::to_vec(&message).unwrap()).wait().unwrap();
    };
    // All three for their first frames at once, then c's bridge stops while a and b go on to the
    // end at 100 frames/s, as boards send.
    for seq in 0..HALF {
        (0..3).for_each(|k| put(k, seq));
    }
    for seq in HALF..FRAMES {
        (0..2).for_each(|k| put(k, seq));
        std::thread::sleep(Duration::from_millis(10));
    }
    let count = |name: &str| lines.lock().unwrap().get(name).map_or(0, Vec::len) as u64;
    wait_until("a and b to be served to the end", &|| count("a") == FRAMES && count("b") == FRAMES);
    wait_until("c's first frames", &|| count("c") == HALF);
    // Past a second without frames, c's source is silent, and says so.
    std::thread::sleep(Duration::from_millis(1500));
    assert_eq!(count("c"), HALF, "c had no more frames");
    // c's bridge comes back: c goes on where it was, and says after how long.
    for seq in HALF..FRAMES {
        put(2, seq);
    }
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    let lines = lines.lock().unwrap();
    for name in names {
        // Every frame, in order. Live, those until the reference's derivation is in (tens of
        // milliseconds, done while c was silent and a and b had 1.8 s of frames to go) are
        // answered as referencing; every frame after the first imaged is imaged.
        let seqs: Vec<u64> = lines[name].iter().map(|(seq, _)| *seq).collect();
        assert_eq!(seqs, (0..FRAMES).collect::<Vec<_>>(), "{name}: every frame, in order");
        let first = lines[name].iter().position(|(_, imaged)| *imaged).expect("frames imaged");
        assert!(first >= 10 && lines[name][first..].iter().all(|(_, imaged)| *imaged), "{name}: {:?}", lines[name]);
        assert!(first <= if name == "c" { HALF as usize + 1 } else { 100 }, "{name}: {:?}", lines[name]);
    }
    // The replay: every frame after the reference's 10 imaged, as `run` images it.
    let expected: Vec<(u64, bool)> = (0..FRAMES).map(|seq| (seq, seq >= 10)).collect();
    assert_eq!(lines["e"], expected, "e: every frame, imaged after the reference");
    assert!(err.contains("d: failed to start, the others go on") && err.contains("missing.jsonl"), "{err}");
    let events = |name: &str, kind: &str| {
        let said = format!("eitskin serve: {name}: {{\"event\":\"{kind}\"");
        err.lines().filter(|l| l.starts_with(&said)).map(str::to_owned).collect::<Vec<_>>()
    };
    let (silent, resumed) = (events("c", "silent"), events("c", "resumed"));
    assert!(silent.len() == 1 && silent[0].contains("\"source\":\"zenoh:board/c\""), "{err}");
    assert_eq!(resumed.len(), 1, "{err}");
    let outage: serde_json::Value = serde_json::from_str(&resumed[0][resumed[0].find('{').unwrap()..]).unwrap();
    assert!(outage["outage_s"].as_f64().unwrap() >= 1.5, "{}", resumed[0]);
    assert!(events("a", "silent").is_empty() && events("b", "silent").is_empty(), "{err}");
    assert!(!out.status.success() && err.contains("1 of 5 sensors failed: d"), "{err}");
}
