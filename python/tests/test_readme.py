"""The README's first page works as written: its Python snippet runs, and the `eitskin image`
command after it gives the snippet's λ, weighting and image (to 1e-9 of the image's peak).
"""

import json
import os
import pathlib
import re
import shlex
import subprocess

import matplotlib
import numpy as np
import pytest

from test_same_as_cli import cli

README = pathlib.Path(__file__).resolve().parents[2] / "README.md"


def blocks(language):
    """The README's fenced blocks in `language`, in order."""
    return re.findall(rf"```{language}\n(.*?)```", README.read_text(encoding="utf-8"), re.S)


def test_the_readmes_python_snippet_and_cli_command_give_the_same_image(tmp_path, monkeypatch):
    matplotlib.use("Agg")  # the README installs the plot extra; plot_image draws off screen here
    monkeypatch.chdir(tmp_path)
    names = {}
    exec(compile(blocks("python")[0], str(README), "exec"), names)
    recon, image = names["recon"], names["image"]

    lines = [line for block in blocks("sh") for line in block.splitlines()]
    [command] = [line for line in lines if line.startswith("eitskin image --reference rest.csv")]
    words = shlex.split(command.split("#")[0])
    done = subprocess.run([cli(), *words[1:]], capture_output=True, text=True, timeout=600, env=os.environ)
    assert done.returncode == 0, done.stderr
    report = json.loads(done.stdout)
    assert (tmp_path / "image.png").stat().st_size > 0

    assert recon.hyperparameter == pytest.approx(report["hyperparameter"], rel=1e-12)
    assert recon.weighting == report["weighting"]
    raster = np.load(tmp_path / "image.npy")
    assert np.array_equal(np.isnan(raster), np.isnan(image.values))
    inside = ~np.isnan(raster)
    scale = np.max(np.abs(raster[inside]))
    assert np.max(np.abs(raster[inside] - image.values[inside])) <= 1e-9 * scale
