"""The calibration learned from labelled presses, from Python: robot presses of the imperfect
virtual skin, a model on the fitted press, its answers and uncertainty, the model file shared
with `eitskin learn` and `eitskin run --model`, and bad input refused."""

import numpy as np
import pytest

import eitskin


@pytest.fixture(scope="module")
def spec():
    return eitskin.SensorSpec.square_hydrogel().with_triangles(1500)


@pytest.fixture(scope="module")
def presses(spec):
    return eitskin.robot_presses(spec, 140, seed=4)


def test_robot_presses_are_arrays_in_metres_and_newtons(spec, presses):
    dv, positions, forces = presses
    assert dv.shape == (140, 120) and positions.shape == (140, 2) and forces.shape == (140,)
    assert np.all(np.hypot(positions[:, 0], positions[:, 1]) <= 0.08 + 1e-12)
    assert forces.min() >= 2.0 and forces.max() <= 16.0
    # The first drive's channels are dead on the skin as built.
    assert np.all(dv[:, 0] == 0.0)


def test_press_features_place_held_out_presses_within_millimetres(spec, presses):
    dv, positions, forces = presses
    model = eitskin.LearnedModel.train(dv[:100], positions[:100], forces=forces[:100], spec=spec)
    assert model.method in ("gp-press", "gp-curve-press")  # chosen by cross-validation
    assert 0 in model.dead_channels
    errors, force_errors = [], []
    for k in range(100, 140):
        answer = model.predict(dv[k])
        errors.append(np.hypot(answer["x"] - positions[k, 0], answer["y"] - positions[k, 1]))
        force_errors.append(answer["force"] - forces[k])
        assert answer["position_std"] > 0 and answer["force_std"] > 0
    assert np.mean(errors) < 0.006, np.mean(errors)
    assert np.sqrt(np.mean(np.square(force_errors))) < 0.08 * 16.0


def test_a_model_file_round_trips(spec, presses, tmp_path):
    dv, positions, _ = presses
    model = eitskin.LearnedModel.train(dv[:60], positions[:60], method="knn-5")
    path = tmp_path / "model.json"
    model.save(path, spec)
    again = eitskin.LearnedModel.load(path, spec)
    assert again.method == "knn-5"
    assert again.predict(dv[70]) == model.predict(dv[70])
    assert "force" not in model.predict(dv[70])


def test_bad_input_is_refused_with_the_reason(spec, presses):
    dv, positions, forces = presses
    with pytest.raises(eitskin.EitskinError, match="positions: expected 2 columns"):
        eitskin.LearnedModel.train(dv, positions[:, :1])
    with pytest.raises(eitskin.EitskinError, match="forces: every value must be finite"):
        eitskin.LearnedModel.train(dv[:20], positions[:20], forces=-forces[:20])
    with pytest.raises(eitskin.EitskinError, match="is not a method"):
        eitskin.LearnedModel.train(dv[:20], positions[:20], method="svm")
    with pytest.raises(eitskin.EitskinError, match="press features need the sensor's spec"):
        eitskin.LearnedModel.train(dv[:20], positions[:20], method="gp-press")
    with pytest.raises(eitskin.EitskinError, match=r"positions: `x, y` of press 1 are \(500, 0\) mm, far off the sheet"):
        eitskin.LearnedModel.train(dv[:20], np.vstack([[0.5, 0.0], positions[1:20]]), spec=spec)
    with pytest.raises(eitskin.EitskinError, match="knn-10 needs at least 10 presses to learn from, and has 5"):
        eitskin.LearnedModel.train(dv[:5], positions[:5], method="knn-10")
    model = eitskin.LearnedModel.train(dv[:20], positions[:20], method="knn-1")
    with pytest.raises(eitskin.EitskinError, match="dv has 3 values, the model 120 channels"):
        model.predict(np.zeros(3))
    with pytest.raises(eitskin.EitskinError, match="count must be 1 to 1000000"):
        eitskin.robot_presses(spec, 0)
    # A raw frame (Δv on the frame at rest, some 200 Ω) given for Δv is refused with the sizes.
    rest = spec.forward_model().measure(spec.conductivity)
    with pytest.raises(eitskin.EitskinError, match="times that of the presses the model learned from"):
        model.predict(dv[30] + rest)
    # Copies teach nothing: named in a warning and left out; presses at one place are refused.
    with pytest.warns(UserWarning, match="3 of 23 presses repeat an earlier one exactly"):
        eitskin.LearnedModel.train(np.vstack([dv[:20], dv[:3]]), np.vstack([positions[:20], positions[:3]]), method="knn-1")
    with pytest.raises(eitskin.EitskinError, match="a model of position needs presses at two places or more"):
        eitskin.LearnedModel.train(dv[:20], np.tile(positions[:1], (20, 1)), method="knn-1")
