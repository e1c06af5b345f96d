"""The examples run as a user runs them, and say what they should."""

import pathlib
import re
import subprocess
import sys

from conftest import reference

EXAMPLES = pathlib.Path(__file__).resolve().parents[1] / "examples"


def run(name, *args):
    done = subprocess.run([sys.executable, str(EXAMPLES / name), *args], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    return done.stdout


def test_the_papers_chain_finds_the_press_and_gives_a_force():
    [line] = run("paper_chain.py").strip().splitlines()
    found = re.match(r"touch at \((\S+), (\S+)\) mm: (\S+) N .*RMS error elsewhere on the sheet: (\S+) N", line)
    x, y, newtons, rms = map(float, found.groups())
    assert abs(x - 30) < 10 and abs(y + 20) < 10
    # The press's force lies within three of the method's RMS errors elsewhere, which is itself
    # a force error, not a failure to find the presses (under 8 N of 1-15 N).
    assert abs(newtons - 7) < 3 * rms + 0.5 and 0 < rms < 8


def test_the_pyeit_migration_reproduces_pyeit():
    out = run("pyeit_migration.py", str(reference("pyeit", "square16_4k.json")))
    assert float(re.search(r"voltages vs pyEIT: (\S+)", out).group(1)) < 1e-10
    assert "image peak -0.227 S/m at [0.428 0.012]" in out


def test_the_live_loop_runs_on_the_virtual_sensor():
    out = run("live_serial.py", "sim", "--frames", "120", "--fast")
    assert re.search(r"frame \d+: touch at \(-?\d+, -?\d+\) mm, peak \S+ S/m", out), out


def test_the_zenoh_example_prints_the_touches_eitskin_publishes(tmp_path):
    """eclipse-zenoh alone, on loopback: the example listens, `eitskin run` connects to it."""
    import os
    import socket

    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    endpoint = f"tcp/127.0.0.1:{port}"
    script = tmp_path / "script.txt"
    script.write_text("1.0 2.0 -50 40 9\n")
    example = subprocess.Popen(
        [sys.executable, str(EXAMPLES / "zenoh_touches.py"), "--listen", endpoint, "--no-multicast-scouting",
         "--key", "demo/*/touches", "--frames", "50", "--timeout", "120"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )
    try:
        assert "listening" in example.stderr.readline()
        published = subprocess.run(
            [os.environ["EITSKIN_BIN"], "run", "--source", f"sim:{script}", "--fast", "--frames", "50",
             "--triangles", "1500", "--publish", "zenoh:demo", "--sensor", "palm", "--wait-for-subscriber", "60",
             "--zenoh-mode", "client", "--connect", endpoint, "--no-multicast-scouting"],
            capture_output=True, text=True, timeout=300,
        )
        assert published.returncode == 0, published.stderr
        out, err = example.communicate(timeout=120)
    finally:
        example.kill()
    assert example.returncode == 0, err
    assert re.search(r"demo/palm/touches frame \d+: touch at \(-?\d+, -?\d+\), peak \S+ S/m", out), out
