"""Every class from Python: shapes, units, the paper's chain, and bad input raising with the
library's message."""

import doctest

import numpy as np
import pytest

import eitskin


@pytest.fixture(scope="module")
def spec():
    return eitskin.SensorSpec.square_hydrogel().with_triangles(1200)


def test_the_package_docstring_runs():
    failures, tried = doctest.testmod(eitskin, verbose=False)
    assert tried > 0 and failures == 0


def test_spec_round_trips_through_toml(spec):
    again = eitskin.SensorSpec.from_toml(spec.to_toml())
    assert again.to_toml() == spec.to_toml()
    assert spec.electrode_count == 16 and spec.conductivity > 0


def test_mesh_arrays_and_constructor(spec):
    mesh = spec.mesh()
    nodes, triangles = mesh.nodes, mesh.triangles
    assert nodes.shape[1] == 2 and triangles.shape[1] == 3 and triangles.dtype == np.int64
    assert len(mesh.electrodes) == 16
    assert mesh.areas().sum() == pytest.approx(0.2 * 0.2, rel=1e-9)
    again = eitskin.Mesh(nodes, triangles.astype(np.int32), mesh.electrodes)
    assert np.array_equal(again.triangles, triangles)


def test_protocol_patterns():
    protocol = eitskin.Protocol.two_terminal(16)
    assert len(protocol) == 120
    assert protocol.stimulations.shape == (120, 16)
    assert np.allclose(protocol.stimulations.sum(axis=1), 0.0)
    assert protocol.measurement_weights.shape == (120, 16)
    assert len(eitskin.Protocol.adjacent(16)) == 208


def test_the_jacobian_is_the_derivative_of_the_voltages(spec):
    model = spec.forward_model()
    sigma = np.full(len(model.mesh.triangles), spec.conductivity)
    v = model.measure(sigma)
    assert v.shape == (120,) and np.all(v > 0)
    jacobian = model.jacobian(sigma)
    assert jacobian.shape == (120, len(sigma))
    # Central differences along a random direction: second order, so 1e-6 relative holds.
    direction = np.random.default_rng(5).uniform(-1.0, 1.0, len(sigma)) * spec.conductivity
    h = 1e-4
    difference = (model.measure(sigma + h * direction) - model.measure(sigma - h * direction)) / (2 * h)
    assert np.max(np.abs(jacobian @ direction - difference)) < 1e-6 * np.max(np.abs(difference))


def test_the_papers_chain_finds_the_press(spec):
    sensor = eitskin.VirtualSensor(spec, seed=3)
    reference = sensor.clean_frame()
    sensor.press(-0.05, 0.03, 10.0)
    frame = sensor.frame()
    assert not np.array_equal(frame, sensor.frame()), "frames carry noise"
    recon = eitskin.Reconstructor(spec.forward_model(), spec.conductivity)
    image = recon.image(reference, frame)
    assert image.values.shape == (64, 64) and image.inside.all()
    found = eitskin.touches(image)
    assert len(found) >= 1
    assert np.hypot(found[0].centre[0] + 0.05, found[0].centre[1] - 0.03) < 0.012
    assert recon.element_values(reference, frame).shape == (len(spec.mesh().triangles),)
    sensor.release()
    assert np.allclose(sensor.clean_frame(), reference, rtol=1e-12)


def test_bad_input_raises_with_the_message(spec):
    model = spec.forward_model()
    recon = eitskin.Reconstructor(model, spec.conductivity)
    v = model.measure(spec.conductivity)
    with pytest.raises(eitskin.EitskinError, match="has 3 values but the protocol has 120"):
        recon.image(v, v[:3].copy())
    bad = v.copy()
    bad[7] = np.nan
    with pytest.raises(eitskin.EitskinError, match="measurement 8"):
        recon.image(v, bad)
    with pytest.raises(eitskin.EitskinError, match="conductivity has 2 values"):
        model.measure([1.0, 2.0])
    with pytest.raises(eitskin.EitskinError, match="hyperparameter"):
        eitskin.Reconstructor(model, 1.0, hyperparameter=-1.0)
    with pytest.raises(eitskin.EitskinError, match="prior must be"):
        eitskin.Reconstructor(model, 1.0, prior="nosir")
    with pytest.raises(eitskin.EitskinError, match=r"threshold must be a number in \(0, 1\], got 1.5"):
        eitskin.touches(recon.image(v, v), threshold=1.5)
    with pytest.raises(eitskin.EitskinError):
        eitskin.SensorSpec.from_toml("[outline]\nkind = 'hexagon'\n")
    with pytest.raises(eitskin.EitskinError, match="index -1 is negative"):
        eitskin.Mesh([[0, 0], [1, 0], [0, 1]], [[0, 1, -1]], [[0], [1]])
    with pytest.raises(eitskin.EitskinError, match=r"force must be a number in \[0, 1e5\] N, got -1.0"):
        eitskin.VirtualSensor(spec).press(0.0, 0.0, -1.0)
    assert issubclass(eitskin.EitskinError, ValueError)
    # A negative count is a ValueError that quotes it with its range, never an OverflowError.
    for call, name in [
        (lambda: spec.with_triangles(-5), "triangles"),
        (lambda: eitskin.Protocol.adjacent(-16), "electrodes"),
        (lambda: eitskin.VirtualSensor(spec, seed=-1), "seed"),
        (lambda: eitskin.robot_presses(spec, -3), "count"),
        (lambda: eitskin.Pipeline(spec, reference_frames=-1), "reference_frames"),
    ]:
        with pytest.raises(eitskin.EitskinError, match=rf"{name} must be \d+ to \d+, got -\d"):
            call()
    with pytest.raises(eitskin.EitskinError, match="frames must be 1 to 1000000000000, got 0"):
        eitskin.Source("sim", spec, frames=0)


def test_a_spec_from_keyword_arguments():
    tank = eitskin.SensorSpec(
        units="mm",
        thickness=10.0,
        conductivity=1.0,
        outline={"kind": "circle", "radius": 140.0},
        electrodes={"count": 8, "width": 10.0, "contact_impedance": 1e-4, "placement": "equal"},
        protocol={"kind": "adjacent"},
        mesh={"triangles": 800},
    )
    assert tank.electrode_count == 8 and len(tank.protocol()) == 40
    assert tank.mesh().areas().sum() == pytest.approx(np.pi * 0.14**2, rel=0.01)
    with pytest.raises(eitskin.EitskinError, match="radius"):
        eitskin.SensorSpec(units="mm", thickness=10.0, conductivity=1.0, outline={"kind": "circle"},
                           electrodes={"count": 8, "placement": "equal"})
    with pytest.raises(eitskin.EitskinError, match="give the spec's fields"):
        eitskin.SensorSpec()


def test_images_draw_with_matplotlib(spec, tmp_path):
    import matplotlib  # the plot extra: the suite installs it, and a test without it fails

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    model = spec.forward_model()
    recon = eitskin.Reconstructor(model, spec.conductivity)
    sigma = np.full(len(model.mesh.triangles), spec.conductivity)
    sigma[np.hypot(*(model.mesh.centroids() - [0.03, 0.0]).T) < 0.015] *= 0.5
    v0, v1 = model.measure(spec.conductivity), model.measure(sigma)
    fig, (left, right) = plt.subplots(1, 2)
    raster = eitskin.plot_image(recon.image(v0, v1), ax=left)
    elements = eitskin.plot_elements(model.mesh, recon.element_values(v0, v1), ax=right)
    assert raster.get_array().shape == (64, 64) and len(elements.get_array()) == len(sigma)
    fig.savefig(tmp_path / "image.png")
    assert (tmp_path / "image.png").stat().st_size > 1000
