"""eitskin on Zenoh, read and fed by an independent client (eclipse-zenoh, json, cbor2; no eitskin).

- What `eitskin run --publish zenoh` publishes equals the JSON lines of the same run, frame for
  frame and event for event, in JSON (byte for byte) and in CBOR (field for field); each imaged
  frame's image comes with it.
- A subscriber that joins late gets the start line by a query, and sees the sensor's liveliness
  token appear while it runs and vanish when it ends.
- Frames a bridge publishes (`--source zenoh:KEY`) give the same touches as the recording they
  came from, replayed from the file; a sample that is not a frame is reported and the stream
  goes on.

All traffic is on the loopback interface: the test's Zenoh peer listens on 127.0.0.1 only,
eitskin connects to it as a client, multicast scouting is off on both. Every wait is bounded.
"""

import json
import math
import os
import queue
import socket
import subprocess
import time

import cbor2
import zenoh

EITSKIN = os.environ["EITSKIN_BIN"]

# Two presses, one after the other, on the paper's square (mm, N).
SCRIPT = "# start end x y force\n1.0 2.0 -50 40 9\n2.5 3.5 30 -20 6\n"
FRAMES = 80
WAIT_S = 60


def free_port():
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def peer(port):
    """The test's Zenoh peer: listening on loopback only, no multicast."""
    config = zenoh.Config()
    config.insert_json5("listen/endpoints", json.dumps([f"tcp/127.0.0.1:{port}"]))
    config.insert_json5("scouting/multicast/enabled", "false")
    return zenoh.open(config)


def client_flags(port):
    return ["--zenoh-mode", "client", "--connect", f"tcp/127.0.0.1:{port}", "--no-multicast-scouting"]


def script(tmp_path):
    path = tmp_path / "script.txt"
    path.write_text(SCRIPT)
    return path


def run(*args, timeout=300):
    done = subprocess.run([EITSKIN, "run", *args], capture_output=True, text=True, timeout=timeout)
    assert done.returncode == 0, done.stderr
    return done.stdout


def take(samples, count):
    """`count` samples from the queue, then nothing more within a second."""
    got = [samples.get(timeout=WAIT_S) for _ in range(count)]
    time.sleep(1.0)
    assert samples.empty(), f"more than {count} samples came"
    return got


def same(a, b):
    """Equal, numbers to f32's precision (CBOR carries a pixel's or a peak's f32 exactly, JSON its
    shortest decimal)."""
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(same(a[k], b[k]) for k in a)
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b))
    if isinstance(a, float) or isinstance(b, float):
        return isinstance(b, (int, float)) and math.isclose(a, b, rel_tol=1e-6, abs_tol=0.0)
    return a == b


def test_what_is_published_equals_the_json_lines_frame_for_frame(tmp_path):
    for encoding in ["json", "cbor"]:
        port = free_port()
        with peer(port) as session:
            # eitskin waits for a subscriber to the touches: declared last, after the others
            # on the same link, it matches once they are all known.
            samples = {topic: queue.Queue() for topic in ["events", "image", "touches"]}
            subscribers = [session.declare_subscriber(f"test/left/{t}", q.put) for t, q in samples.items()]
            out = run(
                "--source", f"sim:{script(tmp_path)}", "--fast", "--frames", str(FRAMES), "--triangles", "1500",
                "--publish", "zenoh:test", "--sensor", "left", "--publish-encoding", encoding, "--publish-image",
                "--wait-for-subscriber", str(WAIT_S), *client_flags(port),
            )
            lines = out.splitlines()
            frames = [line for line in lines if '"event"' not in line]
            events = [line for line in lines if '"event"' in line]
            assert len(frames) == FRAMES and events[0].startswith('{"event":"start"'), lines[:2]
            touches = take(samples["touches"], len(frames))
            said = take(samples["events"], len(events))
            imaged = [json.loads(f) for f in frames if json.loads(f)["status"] == "ok"]
            images = take(samples["image"], len(imaged))
            del subscribers
        for sample in touches + said + images:
            assert str(sample.encoding).startswith(f"application/{encoding}"), sample.encoding
        if encoding == "json":
            assert [s.payload.to_bytes().decode() for s in touches] == frames
            assert [s.payload.to_bytes().decode() for s in said] == events
            images = [json.loads(s.payload.to_bytes()) for s in images]
        else:
            decoded = [cbor2.loads(s.payload.to_bytes()) for s in touches + said]
            expected = [json.loads(line) for line in frames + events]
            assert all(same(d, e) for d, e in zip(decoded, expected)) and len(decoded) == len(expected)
            images = [cbor2.loads(s.payload.to_bytes()) for s in images]
        assert [i["seq"] for i in images] == [f["seq"] for f in imaged]
        pressed = [f for f in imaged if f["touches"]]
        assert pressed, "the presses were found"
        for image in images:
            raster = image["raster"]
            assert raster["nx"] * raster["ny"] == len(raster["values"]) > 1000
        # The image shows the press where the line says it is: its strongest pixel lies near the touch.
        frame = pressed[len(pressed) // 2]
        raster = next(i["raster"] for i in images if i["seq"] == frame["seq"])
        (x0, y0), (x1, y1) = raster["bounds"]
        values = raster["values"]
        k = min((k for k, v in enumerate(values) if v is not None), key=lambda k: values[k])
        x = x0 + (k % raster["nx"] + 0.5) * (x1 - x0) / raster["nx"]
        y = y1 - (k // raster["nx"] + 0.5) * (y1 - y0) / raster["ny"]
        touch = frame["touches"][0]
        assert math.hypot(x - touch["x"], y - touch["y"]) < 15, (x, y, touch)


def test_a_late_subscriber_gets_the_start_line_and_sees_the_sensor_come_and_go(tmp_path):
    port = free_port()
    with peer(port) as session:
        alive = queue.Queue()
        watcher = session.liveliness().declare_subscriber("test/*/alive", alive.put)
        frames = queue.Queue()
        subscriber = session.declare_subscriber("test/right/touches", frames.put)
        eitskin = subprocess.Popen(
            [EITSKIN, "run", "--frames", "60", "--rate", "20", "--triangles", "1500", "--publish", "zenoh:test",
             "--sensor", "right", *client_flags(port)],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        )
        try:
            came = alive.get(timeout=WAIT_S)
            assert str(came.key_expr) == "test/right/alive" and came.kind == zenoh.SampleKind.PUT
            frames.get(timeout=WAIT_S)  # running: a frame came
            replies = list(session.get("test/right/start", timeout=10.0))
            assert len(replies) == 1 and replies[0].ok is not None, replies
            start = json.loads(replies[0].ok.payload.to_bytes())
            out, err = eitskin.communicate(timeout=WAIT_S)
            went = alive.get(timeout=WAIT_S)
        finally:
            eitskin.kill()
        del watcher, subscriber
    assert eitskin.returncode == 0, err
    assert str(went.key_expr) == "test/right/alive" and went.kind == zenoh.SampleKind.DELETE
    assert start == json.loads(out.splitlines()[0]) and start["length_unit"] == "mm"


def test_frames_from_a_bridge_give_the_touches_of_the_recording_they_came_from(tmp_path):
    recording = tmp_path / "run.jsonl"
    run("--source", f"sim:{script(tmp_path)}", "--fast", "--frames", "60", "--triangles", "1500", "--record", str(recording))
    records = [json.loads(line) for line in recording.read_text().splitlines()[1:]]
    replayed = [json.loads(line) for line in run("--source", f"file:{recording}", "--fast", "--triangles", "1500").splitlines()]
    replayed = [line for line in replayed if "event" not in line]
    assert len(records) == len(replayed) == 60

    port = free_port()
    with peer(port) as session:
        key = "test/board/frames"
        publisher = session.declare_publisher(key, congestion_control=zenoh.CongestionControl.BLOCK)
        eitskin = subprocess.Popen(
            [EITSKIN, "run", "--source", f"zenoh:{key}", "--frames", "60", "--triangles", "1500", *client_flags(port)],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        )
        try:
            deadline = time.monotonic() + WAIT_S
            while not publisher.matching_status.matching:
                assert time.monotonic() < deadline and eitskin.poll() is None, "eitskin did not subscribe"
                time.sleep(0.05)
            for k, record in enumerate(records):
                message = {"seq": record["seq"], "t_s": record["t_s"], "values": record["values"]}
                # Both encodings, as bridges may send either; one sample that is no frame.
                publisher.put(json.dumps(message) if k % 2 else cbor2.dumps(message))
                if k == 30:
                    publisher.put(b"{\"seq\": 5}")
            out, err = eitskin.communicate(timeout=WAIT_S)
        finally:
            eitskin.kill()
    assert eitskin.returncode == 0, err
    lines = [json.loads(line) for line in out.splitlines()]
    frames = [line for line in lines if "event" not in line]
    bad = [line for line in lines if line.get("event") == "bad"]
    assert len(bad) == 1 and "not a frame" in bad[0]["reason"] and "test/board/frames" in bad[0]["reason"], bad
    assert [(f["seq"], f["status"], f["touches"]) for f in frames] == [(f["seq"], f["status"], f["touches"]) for f in replayed]
    assert any(f["touches"] for f in frames), "the presses were found"
