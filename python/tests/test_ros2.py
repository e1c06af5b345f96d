"""eitskin's ROS 2 messages, read as a ROS 2 node on rmw_zenoh would read them, by independent
code: eclipse-zenoh for the transport, rosbags for the message definitions, type hashes and CDR.

- `eitskin run --publish ros2` puts each topic's messages on the key rmw_zenoh subscribes to
  (DOMAIN/TOPIC/TYPE/HASH), the hash computed here by rosbags from the standard definitions
  (Jazzy) and from this repository's `ros2/eitskin_msgs/msg/*.msg`;
- every message decodes as its type, and says what the JSON lines of the same run say, frame for
  frame: touches (m, N, NaN where the line has null), the net wrench, the markers (placed by the
  spec's mount), the images (pixel for pixel);
- each message carries rmw_zenoh's attachment (sequence number from 1, time, a 16-byte id), and
  the node and its publishers hold rmw_zenoh's liveliness tokens (what `ros2 topic list` reads).

All traffic is on the loopback interface: the test's Zenoh peer listens on 127.0.0.1 only,
eitskin connects to it as a client, multicast scouting is off on both. Every wait is bounded.
"""

import json
import math
import queue
import subprocess
from pathlib import Path

import numpy as np
import zenoh
from rosbags.typesys import Stores, get_typestore, get_types_from_msg
from zenoh.ext import Int64, UInt8, z_deserialize

from test_zenoh import EITSKIN, FRAMES, WAIT_S, client_flags, free_port, peer, run, script, take

MESSAGES = Path(__file__).resolve().parents[2] / "ros2" / "eitskin_msgs" / "msg"
MOUNT = '\n[mount]\nframe_id = "skin_palm"\nparent = "hand_link"\nposition = [10.0, -20.0, 150.0]\norientation = [0.0, 0.0, 0.7071067811865476, 0.7071067811865476]\n'
TOPICS = {
    "touches": "eitskin_msgs/msg/Touches",
    "wrench": "geometry_msgs/msg/WrenchStamped",
    "markers": "visualization_msgs/msg/MarkerArray",
    "image": "sensor_msgs/msg/Image",
}


def typestore():
    store = get_typestore(Stores.ROS2_JAZZY)
    types = {}
    for path in sorted(MESSAGES.glob("*.msg")):
        types.update(get_types_from_msg(path.read_text(), f"eitskin_msgs/msg/{path.stem}"))
    store.register(types)
    return store


def dds_name(ros_type):
    package, kind, name = ros_type.split("/")
    return f"{package}::{kind}::dds_::{name}_"


def close(a, b):
    """Equal, NaN equal to NaN (a field the line has as null)."""
    return (math.isnan(a) and math.isnan(b)) or math.isclose(a, b, rel_tol=1e-9, abs_tol=1e-12)


def rotate_z90(x, y, z):
    return -y, x, z


def test_ros2_messages_equal_the_json_lines_frame_for_frame(tmp_path):
    store = typestore()
    spec = tmp_path / "palm.toml"
    spec.write_text(subprocess.run([EITSKIN, "spec"], capture_output=True, text=True, check=True).stdout + MOUNT)
    keys = {leaf: f"0/eitskin/palm/{leaf}/{dds_name(t)}/{store.hash_rihs01(t)}" for leaf, t in TOPICS.items()}
    port = free_port()
    with peer(port) as session:
        samples = {leaf: queue.Queue() for leaf in TOPICS}
        # eitskin waits for a subscriber to the touches: declared last, after the others on the
        # same link, it matches once they are all known.
        order = sorted(samples.items(), key=lambda item: item[0] == "touches")
        subscribers = [session.declare_subscriber(keys[leaf], q.put) for leaf, q in order]
        tokens = queue.Queue()
        watcher = session.liveliness().declare_subscriber("@ros2_lv/0/**", tokens.put)
        out = run(
            str(spec), "--source", f"sim:{script(tmp_path)}", "--fast", "--frames", str(FRAMES),
            "--triangles", "1500", "--virtual-calibration", "--publish", "ros2", "--sensor", "palm", "--publish-image",
            "--stream-image",
            "--wait-for-subscriber", str(WAIT_S), *client_flags(port),
        )
        lines = [json.loads(line) for line in out.splitlines()]
        frames = [line for line in lines if "event" not in line]
        imaged = [f for f in frames if f["status"] == "ok"]
        got = {leaf: take(samples[leaf], len(imaged if leaf == "image" else frames)) for leaf in TOPICS}
        seen = []
        while not tokens.empty():
            seen.append(tokens.get())
        del subscribers, watcher
    assert len(frames) == FRAMES and any(f["touches"] for f in frames), "the presses were found"

    # The attachment: sequence numbers 1, 2, … a publisher, a time, one 16-byte id a publisher.
    for leaf, sent in got.items():
        attachments = [z_deserialize(tuple[Int64, Int64, list[UInt8]], s.attachment) for s in sent]
        assert [a[0] for a in attachments] == list(range(1, len(sent) + 1)), leaf
        assert len({bytes(a[2]) for a in attachments}) == 1 and len(attachments[0][2]) == 16, leaf
        assert all(a[1] > 1.7e18 for a in attachments), leaf  # ns since 1970, after 2023

    decoded = {leaf: [store.deserialize_cdr(s.payload.to_bytes(), TOPICS[leaf]) for s in sent] for leaf, sent in got.items()}
    for frame, touches, wrench, markers in zip(frames, decoded["touches"], decoded["wrench"], decoded["markers"]):
        assert touches.header.frame_id == wrench.header.frame_id == "skin_palm"
        assert (touches.seq, touches.t, touches.imaged) == (frame["seq"], frame["t"], frame["status"] == "ok")
        assert (touches.frames, touches.bad) == (frame["counters"]["frames"], frame["counters"]["bad"])
        assert len(touches.touches) == len(frame["touches"])
        for message, line in zip(touches.touches, frame["touches"]):
            assert message.sign == (-1 if line["sign"] == "decrease" else 1)
            assert close(message.position.x, line["x"] * 1e-3) and close(message.position.y, line["y"] * 1e-3)
            assert np.float32(message.peak) == np.float32(line["peak"])
            for field in ["z", "force", "force_std"]:
                assert close(getattr(message, field), math.nan if line[field] is None else line[field]), field
            assert message.unit == (line["unit"] or 0) and message.calibration_area == (line["calibration_area"] or 0)
            assert message.has_press == (line["press"] is not None)
            if line["press"] is not None:
                assert close(message.press_position.x, line["press"]["x"] * 1e-3)
                assert close(message.press_radius, line["press"]["radius"] * 1e-3)
        # The net wrench: each press pushes along -z at its centre.
        presses = [t for t in frame["touches"] if t["sign"] == "decrease"]
        force = sum(t["force"] for t in presses)
        assert close(wrench.wrench.force.z, -force) and close(wrench.wrench.force.x, 0.0)
        assert close(wrench.wrench.torque.x, -sum(t["y"] * 1e-3 * t["force"] for t in presses))
        assert close(wrench.wrench.torque.y, sum(t["x"] * 1e-3 * t["force"] for t in presses))
        # The markers: one that clears, then a cylinder a touch, on the hand by the mount's pose.
        assert markers.markers[0].action == 3 and len(markers.markers) == 1 + len(frame["touches"])
        for marker, line in zip(markers.markers[1:], frame["touches"]):
            assert marker.header.frame_id == "hand_link" and marker.type == 3 and marker.action == 0
            x, y, z = rotate_z90(line["x"] * 1e-3, line["y"] * 1e-3, marker.scale.z / 2)
            p = marker.pose.position
            assert close(p.x, x + 0.010) and close(p.y, y - 0.020) and close(p.z, z + 0.150), (p, line)
    assert any(t.force > 0 for m in decoded["touches"] for t in m.touches), "forces came with the touches"

    # The images: 32FC1, pixel for pixel the lines' rasters (NaN outside the outline).
    assert len(decoded["image"]) == len(imaged)
    for image, frame in zip(decoded["image"], imaged):
        raster = frame["raster"]
        assert (image.width, image.height, image.encoding, image.step) == (raster["nx"], raster["ny"], "32FC1", 4 * raster["nx"])
        assert image.header.frame_id == "skin_palm"
        pixels = np.frombuffer(bytes(image.data), dtype="<f4")
        expected = np.array([math.nan if v is None else v for v in raster["values"]], dtype="<f4")
        assert np.array_equal(pixels, expected, equal_nan=True)

    # The graph: the node and its four publishers, as rmw_zenoh's tokens name them.
    keys = [str(s.key_expr) for s in seen if s.kind == zenoh.SampleKind.PUT]
    nodes = [k for k in keys if "/NN/" in k]
    assert len(nodes) == 1 and nodes[0].endswith("/NN/%/%/eitskin_palm"), keys
    publishers = sorted(k.split("/")[9:13] for k in keys if "/MP/" in k)
    expected = sorted([f"%eitskin%palm%{leaf}", dds_name(t), store.hash_rihs01(t), "::,10:,:,:,,"] for leaf, t in TOPICS.items())
    assert publishers == expected, keys
