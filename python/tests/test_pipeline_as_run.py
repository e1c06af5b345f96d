"""Python's Pipeline and `eitskin run` build the same sensor through the same builder: a spec
that drops two channels, the same frames, the same touches, peaks and fitted presses, frame for
frame. The CLI is `$EITSKIN_BIN` (the Rust test that runs this suite sets it), else `eitskin`
on the PATH.
"""

import json
import subprocess

import numpy as np

import eitskin
from test_same_as_cli import cli


def test_a_masked_sensor_gives_the_same_touches_from_python_and_from_run(tmp_path):
    toml = eitskin.SensorSpec.square_hydrogel().with_triangles(1500).to_toml()
    toml = toml.replace('kind = "two-terminal"', 'kind = "two-terminal"\ndrop_channels = [6, 40]')
    (tmp_path / "spec.toml").write_text(toml)
    spec = eitskin.SensorSpec.from_toml(toml)

    sensor = eitskin.VirtualSensor(spec, seed=4)
    frames = [sensor.frame() for _ in range(25)]
    sensor.press(0.04, -0.03, 8.0)
    frames += [sensor.frame() for _ in range(4)]
    sensor.release()
    frames += [sensor.frame() for _ in range(3)]
    np.save(tmp_path / "frames.npy", np.array(frames))

    done = subprocess.run(
        [cli(), "run", str(tmp_path / "spec.toml"), "--source", f"file:{tmp_path / 'frames.npy'}", "--fast", "--fit"],
        capture_output=True, text=True, timeout=600,
    )
    assert done.returncode == 0, done.stderr
    assert "channels [6, 40] left out" in done.stderr, done.stderr
    lines = [json.loads(line) for line in done.stdout.splitlines()]
    by_frame = [line["touches"] for line in lines if "seq" in line and "touches" in line]
    assert len(by_frame) == len(frames)

    pipeline = eitskin.Pipeline(spec, fit=True)
    pressed = 0
    for frame, cli_touches in zip(frames, by_frame):
        pipeline.process(frame)
        touches = pipeline.touches
        assert len(touches) == len(cli_touches)
        for touch, line in zip(touches, cli_touches):
            pressed += 1
            # The CLI writes mm (the spec's unit), Python m; the peak is the f32 the image holds.
            assert np.allclose(np.array(touch.centre) * 1e3, [line["x"], line["y"]], rtol=0, atol=1e-9)
            assert np.allclose(np.array(touch.press_centre) * 1e3, [line["press"]["x"], line["press"]["y"]], atol=1e-9)
            assert abs(touch.peak - line["peak"]) <= 1e-6 * abs(line["peak"])
    assert pressed >= 4, "the press was found in every pressed frame"
