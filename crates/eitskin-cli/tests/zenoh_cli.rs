//! `eitskin run` on Zenoh, through the real binary: bad Zenoh and ROS 2 flags refused before any work,
//! with the flag and the value as written; a replay that waits for a subscriber fails, saying
//! so, when none comes; frames from a bridge counted as a serial board's are (frames lost
//! before one are a gap, a late one is dropped as stale, a wrong count is bad), the rest
//! imaged. The equality of what is published with the JSON lines is checked by an independent
//! client, Python's eclipse-zenoh (python/tests/test_zenoh.py); that of the ROS 2 messages by
//! eclipse-zenoh with rosbags' definitions, type hashes and CDR (python/tests/test_ros2.py).
//!
//! Traffic stays on loopback: the test's peer listens on 127.0.0.1 only, eitskin connects to it
//! as a client, multicast scouting is off on both.

mod binary;
mod loopback;

use std::process::Stdio;
use std::time::{Duration, Instant};

use binary::scratch;
use eitskin_io::middleware::FrameMessage;
use loopback::{free_port, peer};
use zenoh::qos::CongestionControl;
use zenoh::Wait;

fn client(port: u16) -> Vec<String> {
    ["--zenoh-mode", "client", "--connect", &format!("tcp/127.0.0.1:{port}"), "--no-multicast-scouting"]
        .map(str::to_owned)
        .to_vec()
}

#[test]
fn bad_zenoh_flags_are_refused_with_the_flag_and_the_value_as_written() {
    let dir = scratch("zenoh-flags");
    // A refusal that regressed would open a session: as a client, with multicast off, it
    // listens nowhere (only the first case, which must name --connect, and the one that names
    // a mode go without).
    for (k, (args, says)) in [
        (&["--connect", "tcp/127.0.0.1:7447"][..], "--connect sets up Zenoh, which this run does not use"),
        (&["--publish", "zenoh", "--connect", "127.0.0.1:7447"], "--connect \"127.0.0.1:7447\""),
        (&["--publish", "zenoh", "--listen", "udp/127.0.0.1:7447"], "TCP links only"),
        (&["--publish", "zenoh:robot/*"], "\"robot/*\" is not a key expression to publish on"),
        (&["--publish", "zenoh", "--sensor", "arm/left"], "holds a `/`"),
        (&["--publish", "mqtt"], "write `zenoh`, `zenoh:PREFIX`, `ros2` or `ros2:NAMESPACE`"),
        (&["--publish", "ros2", "--sensor", "palm-1"], "the sensor's name \"palm-1\" is not one ROS takes"),
        (&["--publish", "ros2:robot//skin"], "empty part"),
        (
            &["--publish", "ros2", "--ros-domain", "233"],
            "\"233\" is not a ROS domain: give a whole number from 0 to 232",
        ),
        (&["--publish", "zenoh", "--ros-domain", "3"], "--ros-domain 3 applies to --publish ros2"),
        (&["--publish", "ros2", "--publish", "ros2:other"], "more than once"),
        (&["--publish", "ros2", "--publish-encoding", "cbor"], "--publish-encoding applies to --publish zenoh"),
        (&["--publish-image"], "--publish"),
        (&["--publish", "zenoh", "--wait-for-subscriber", "0"], "(0, 3600] s"),
        (&["--publish", "zenoh", "--zenoh-mode", "router"], "\"router\" is not a Zenoh mode"),
        (&["--source", "zenoh:"], "names no key expression"),
        (&["--sensor", "arm"], "--publish"),
    ]
    .into_iter()
    .enumerate()
    {
        let started = Instant::now();
        let client: &[&str] = if k == 0 || args.contains(&"--zenoh-mode") { &[] } else { &["--zenoh-mode", "client"] };
        let base = ["run", "--frames", "20", "--triangles", "500", "--no-multicast-scouting"];
        let out = dir.eitskin(&[&base[..], client, args].concat());
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && err.contains(says), "{args:?}: {err}");
        assert!(started.elapsed() < Duration::from_secs(60), "{args:?} was refused only after {:?}", started.elapsed());
    }
}

#[test]
fn a_replay_waiting_for_a_subscriber_fails_when_none_comes() {
    let dir = scratch("zenoh-wait");
    let port = free_port();
    let _peer = peer(port);
    let mut args = vec!["run", "--fast", "--frames", "20", "--triangles", "500", "--publish", "zenoh:nobody"];
    args.extend(["--wait-for-subscriber", "0.5"]);
    let flags = client(port);
    args.extend(flags.iter().map(String::as_str));
    let out = dir.eitskin(&args);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("no subscriber to nobody/skin/touches appeared within 0.5 s"),
        "{err}"
    );
}

#[test]
fn frames_from_a_bridge_are_counted_as_a_boards_are() {
    let dir = scratch("zenoh-source");
    let recording = dir.join("sim.jsonl");
    binary::ok(dir.eitskin(&[
        "run",
        "--fast",
        "--frames",
        "17",
        "--triangles",
        "500",
        "--record",
        recording.to_str().unwrap(),
    ]));
    let text = std::fs::read_to_string(&recording).unwrap();
    let recorded: Vec<Vec<f64>> = text
        .lines()
        .skip(1)
        .map(|l| {
            let record: serde_json::Value = serde_json::from_str(l).unwrap();
            serde_json::from_value(record["values"].clone()).unwrap()
        })
        .collect();
    assert_eq!(recorded.len(), 17);
    let port = free_port();
    let session = peer(port);
    let key = "bridge/board/frames";
    let publisher = session.declare_publisher(key).congestion_control(CongestionControl::Block).wait().unwrap();
    let mut args: Vec<String> = ["run", "--source", &format!("zenoh:{key}"), "--frames", "14", "--triangles", "500"]
        .map(str::to_owned)
        .to_vec();
    args.extend(client(port));
    let mut child = dir.command().args(&args).stdout(Stdio::piped()).stderr(Stdio::piped()).spawn().unwrap();
    let deadline = Instant::now() + Duration::from_secs(120);
    while !publisher.matching_status().wait().unwrap().matching() {
        if child.try_wait().unwrap().is_some() || Instant::now() > deadline {
            child.kill().unwrap();
            let out = child.wait_with_output().unwrap();
            panic!("eitskin did not subscribe: {}", String::from_utf8_lossy(&out.stderr));
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    // The virtual sensor's frames, from a recording of it.
    let frame = |seq: u64, count: usize| {
        let mut values = recorded[seq as usize].clone();
        values.truncate(count);
        serde_json::to_vec(&FrameMessage { seq, t: seq as f64 * 0.05, values }).unwrap()
    };
    // 0–9, then 12 (10 and 11 lost), 11 late, 13 with a wrong count, 14–17: 14 frames taken.
    for seq in (0..10).chain([12]) {
        publisher.put(frame(seq, 120)).wait().unwrap();
    }
    publisher.put(frame(11, 120)).wait().unwrap();
    publisher.put(frame(13, 119)).wait().unwrap();
    for seq in 14..17 {
        publisher.put(frame(seq, 120)).wait().unwrap();
    }
    let out = child.wait_with_output().unwrap();
    let (stdout, stderr) = (String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    assert!(out.status.success(), "{stderr}");
    let lines: Vec<serde_json::Value> = stdout.lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    let bad: Vec<&str> = lines.iter().filter(|l| l["event"] == "bad").map(|l| l["reason"].as_str().unwrap()).collect();
    assert_eq!(bad.len(), 3, "{bad:?}");
    assert!(bad[0].contains("2 frames were lost before frame seq 12"), "{bad:?}");
    assert!(bad[1].contains("frame seq 11 came after frame seq 12"), "{bad:?}");
    assert!(bad[2].contains("frame seq 13 has 119 values, expected 120"), "{bad:?}");
    let seqs: Vec<u64> =
        lines.iter().filter(|l| l.get("event").is_none()).map(|l| l["seq"].as_u64().unwrap()).collect();
    assert_eq!(seqs, [0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 12, 14, 15, 16]);
    assert_eq!(lines.last().unwrap()["counters"]["bad"], 3, "{}", lines.last().unwrap());
}
