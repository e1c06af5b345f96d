"""The CLI and Python image the same frames alike: the same λ, the same weighting, the same
numbers. The CLI is `$EITSKIN_BIN` (the Rust test that runs this suite sets it), else `eitskin`
on the PATH; without either the test fails and says so.
"""

import json
import os
import shutil
import subprocess

import numpy as np
import pytest

import eitskin


def cli():
    """The eitskin program to compare with."""
    program = os.environ.get("EITSKIN_BIN") or shutil.which("eitskin")
    if not program:
        pytest.fail("no eitskin program: set EITSKIN_BIN or put eitskin on the PATH", pytrace=False)
    return program


def recording(tmp_path, spec, rest=20):
    """Writes the spec, `rest` noisy frames at rest and two pressed frames; returns the arrays."""
    sensor = eitskin.VirtualSensor(spec, seed=5)
    references = np.array([sensor.frame() for _ in range(rest)])
    sensor.press(0.03, -0.04, 9.0)
    frames = np.array([sensor.frame() for _ in range(2)])
    (tmp_path / "spec.toml").write_text(spec.to_toml())
    np.savetxt(tmp_path / "ref.csv", references, delimiter=",", fmt="%.17g")
    np.savetxt(tmp_path / "frames.csv", frames, delimiter=",", fmt="%.17g")
    return references, frames


def image_cli(tmp_path, *flags):
    """`eitskin image` of frame 1, its raster and its JSON report."""
    out = tmp_path / "cli.npy"
    done = subprocess.run(
        [cli(), "image", str(tmp_path / "spec.toml"), "--reference", str(tmp_path / "ref.csv"),
         "--frame", str(tmp_path / "frames.csv"), "--out", str(out), "--json", *flags],
        capture_output=True, text=True, timeout=600,
    )
    assert done.returncode == 0, done.stderr
    return np.load(out), json.loads(done.stdout)


@pytest.mark.parametrize("flags, keywords", [
    ((), {}),
    (("--hyperparameter", "0.3"), {"hyperparameter": 0.3}),
    (("--weighting", "none"), {"weighting": "none"}),
    (("--normalised",), {"normalised": True}),
])
def test_python_images_a_recording_as_the_cli_does(tmp_path, flags, keywords):
    spec = eitskin.SensorSpec.square_hydrogel().with_triangles(1500)
    references, frames = recording(tmp_path, spec)
    raster, report = image_cli(tmp_path, *flags)

    recon = eitskin.Reconstructor.from_reference(spec, references, **keywords)
    image = recon.image(recon.reference, frames[0])

    assert recon.hyperparameter == pytest.approx(report["hyperparameter"], rel=1e-12)
    assert recon.chosen_by == report["chosen_by"]
    assert recon.weighting == report["weighting"]
    assert recon.channels_dropped == report["channels_dropped"]
    assert raster.shape == image.values.shape
    assert np.array_equal(np.isnan(raster), np.isnan(image.values))
    inside = ~np.isnan(raster)
    scale = np.max(np.abs(raster[inside]))
    assert np.max(np.abs(raster[inside] - image.values[inside])) <= 1e-9 * scale + 1e-12
    touches = eitskin.touches(image)
    assert len(touches) == len(report["touches"])


def test_a_model_built_reconstructor_chooses_lambda_as_one_reference_frame_does(tmp_path):
    # One frame at rest measures no noise: the CLI assumes 0.3 % of each value, as a
    # reconstructor built from the forward model alone does.
    spec = eitskin.SensorSpec.square_hydrogel().with_triangles(1500)
    references, _ = recording(tmp_path, spec, rest=1)
    _, report = image_cli(tmp_path)
    recon = eitskin.Reconstructor(spec.forward_model(), spec.conductivity)
    assert report["weighting"] == recon.weighting == "noise-assumed"
    assert recon.hyperparameter == pytest.approx(report["hyperparameter"], rel=1e-9)


def test_a_dropped_channel_is_dropped_alike(tmp_path):
    spec = eitskin.SensorSpec.square_hydrogel().with_triangles(1500)
    references, frames = recording(tmp_path, spec)
    references[:, 6] = 0.0  # a dead contact: 0 at rest
    np.savetxt(tmp_path / "ref.csv", references, delimiter=",", fmt="%.17g")
    raster, report = image_cli(tmp_path)
    recon = eitskin.Reconstructor.from_reference(spec, references)
    assert report["channels_dropped"] == recon.channels_dropped == [7]
    image = recon.image(recon.reference, frames[0])
    inside = ~np.isnan(raster)
    assert np.allclose(raster[inside], image.values[inside], rtol=0, atol=1e-9 * np.max(np.abs(raster[inside])))
