"""Frames over time from Python: sources (the virtual sensor, a capture file with bad lines),
the pipeline finding a press, a calibration fitted, saved, loaded and turning strength into
force, and meshes and protocols in EIDORS' and pyEIT's shapes."""

import numpy as np
import pytest

import eitskin


@pytest.fixture(scope="module")
def spec():
    return eitskin.SensorSpec.square_hydrogel().with_triangles(1200)


def test_a_capture_file_yields_frames_and_says_what_it_skipped(spec, tmp_path):
    good = ",".join(["1.5"] * 120)
    path = tmp_path / "capture.txt"
    path.write_text(f"{good}\n1,2,3\n{good}\n")
    items = list(eitskin.Source(f"file:{path}", spec, fast=True))
    frames = [i for i in items if isinstance(i, eitskin.Frame)]
    events = [i for i in items if isinstance(i, eitskin.Event)]
    assert len(frames) == 2 and frames[0].values.shape == (120,)
    assert len(events) == 1 and events[0].kind == "bad" and "3 values" in events[0].message
    with pytest.raises(eitskin.EitskinError, match="cannot|No such|not"):
        eitskin.Source(f"file:{tmp_path / 'missing.txt'}", spec)
    with pytest.raises(eitskin.EitskinError):
        eitskin.Source("frames.csv", spec)


def test_the_pipeline_finds_a_press_from_the_virtual_sensors_frames(spec):
    sensor = eitskin.VirtualSensor(spec, seed=2)
    pipeline = eitskin.Pipeline(spec, reference_frames=10)
    statuses = [pipeline.process(sensor.frame()) for _ in range(10)]
    assert statuses[0] == "referencing" and pipeline.has_reference
    assert pipeline.process(sensor.frame()) in ("processed", "noise updated") and pipeline.touches == []
    sensor.press(0.05, 0.04, 10.0)
    pipeline.process(sensor.frame())
    [touch] = pipeline.touches
    assert np.hypot(touch.centre[0] - 0.05, touch.centre[1] - 0.04) < 0.012
    assert touch.significance is not None and touch.significance > 4
    # Without a calibration, no force and no spread of one.
    assert touch.force is None and touch.force_std is None
    assert pipeline.image.values.shape == (64, 64)
    with pytest.raises(eitskin.EitskinError, match="has 5 values"):
        pipeline.process(np.ones(5))
    with pytest.raises(eitskin.EitskinError, match="false_alarm_rate"):
        eitskin.Pipeline(spec, false_alarm_rate=0.0)
    with pytest.raises(eitskin.EitskinError, match="reference_limit must be 1 to 1000000, got 0"):
        eitskin.Pipeline(spec, reference_limit=0)
    # A frame of the other sign is no press: refused, and the next frame is imaged as before.
    with pytest.raises(eitskin.EitskinError, match="typically -1.0"):
        pipeline.process(-sensor.frame())
    assert pipeline.process(sensor.frame()) in ("processed", "noise updated")
    # A press off the sheet would change nothing: refused.
    with pytest.raises(eitskin.EitskinError, match=r"off the sheet \(its outline spans -0.1–0.1 m"):
        sensor.press(0.15, 0.0, 8.0)


def test_a_calibration_is_fitted_saved_loaded_and_gives_forces(spec, tmp_path):
    # Samples on the curve sigma(F) = a e^(-F/b) + c of every area, a = 0.5, b = 6 N, c = 0.05.
    forces = np.linspace(1.0, 15.0, 8)
    # Areas are counted from 1, as the paper, the CLI and the files count them.
    probe = eitskin.Calibration.fit(spec, [1] * 3, [1.0, 2.0, 3.0], [3.0, 2.0, 1.0], grid=(1, 1))
    assert probe.areas == 1
    calibration = eitskin.Calibration.fit(
        spec, [1] * len(forces), forces, 0.5 * np.exp(-forces / 6.0) + 0.05, grid=(1, 1)
    )
    newtons, saturated = calibration.force(1, 0.5 * np.exp(-7.0 / 6.0) + 0.05)
    assert newtons == pytest.approx(7.0, rel=1e-6) and not saturated
    path = tmp_path / "calibration.json"
    calibration.save(path)
    again = eitskin.Calibration.load(path, spec)
    assert again.force(1, 0.2) == calibration.force(1, 0.2)
    assert again.area_at(0.0, 0.0) == 1 and again.area_at(1.0, 1.0) is None
    for wrong in (0, 3):
        with pytest.raises(eitskin.EitskinError, match=rf"area must be 1 to 1, got {wrong}"):
            calibration.force(wrong, 0.2)
    with pytest.raises(eitskin.EitskinError, match=r"area of sample 1 must be 1 to 1 \(areas are counted from 1\), got 0"):
        eitskin.Calibration.fit(spec, [0] * 3, [1.0, 2.0, 3.0], [3.0, 2.0, 1.0], grid=(1, 1))
    with pytest.raises(eitskin.EitskinError, match="one entry per sample"):
        eitskin.Calibration.fit(spec, [1, 1], [1.0], [1.0, 2.0])


def test_meshes_and_protocols_in_eidors_and_pyeit_shapes(spec):
    mesh = spec.mesh()
    eidors = mesh.to_eidors()
    assert eidors["elems"].min() == 1
    again = eitskin.Mesh.from_eidors(eidors["nodes"], eidors["elems"], eidors["electrode_nodes"])
    assert np.array_equal(again.triangles, mesh.triangles)
    with pytest.raises(eitskin.EitskinError, match="from 1"):
        eitskin.Mesh.from_eidors(eidors["nodes"], eidors["elems"] - 1, eidors["electrode_nodes"])
    pyeit = mesh.to_pyeit()
    assert len(pyeit["el_pos"]) == 16
    protocol = eitskin.Protocol.adjacent(16)
    rebuilt = eitskin.Protocol.from_arrays(
        protocol.stimulations, protocol.measurement_weights, protocol.measurement_stimulation
    )
    assert len(rebuilt) == len(protocol)
    assert np.array_equal(rebuilt.measurement_weights, protocol.measurement_weights)
    bad = protocol.stimulations.copy()
    bad[0, 0] += 1.0
    with pytest.raises(eitskin.EitskinError, match="stimulation 1"):
        eitskin.Protocol.from_arrays(bad, protocol.measurement_weights, protocol.measurement_stimulation)
