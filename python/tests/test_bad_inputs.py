"""No Rust panic reaches Python: every native function and method, each argument in turn given
values generated from its good one (wrong lengths and shapes, empty, NaN, infinities, huge and
negative numbers, other types, complex values, strings), answers or raises an ordinary exception;
a number or array argument refused raises `EitskinError`, never an OverflowError, a TypeError
or numpy's ValueError on its way to Rust.

The list of callables is read from the module itself, so a binding added without a good call
here fails `test_every_native_callable_is_driven`, and cannot skip the edges.
"""

import inspect
import math

import numpy as np
import pytest

import eitskin
from eitskin import _eitskin

SPEC = eitskin.SensorSpec.square_hydrogel().with_triangles(800)


def _fixtures():
    mesh = SPEC.mesh()
    protocol = SPEC.protocol()
    model = SPEC.forward_model()
    skin = eitskin.VirtualSensor(SPEC, seed=3)
    rest = skin.frame()
    skin.press(0.03, -0.02, 8.0)
    pressed = skin.frame()
    skin.release()
    recon = eitskin.Reconstructor(model, SPEC.conductivity)
    image = recon.image(rest, pressed)
    dv, positions, forces = eitskin.robot_presses(SPEC, 30, seed=2)
    learned = eitskin.LearnedModel.train(dv, positions, forces=forces, method="knn-3")
    area = [1] * 8
    force = np.arange(8, dtype=float)
    strength = 0.1 * (1.0 - np.exp(-force / 5.0))
    calibration = eitskin.Calibration.fit(SPEC, area, force, strength, grid=(1, 1))
    return locals()


F = _fixtures()
J = F["model"].jacobian(1.0)


def _pipeline():
    return eitskin.Pipeline(SPEC, reference_frames=1)


# A good call of every native callable: (name, callable, arguments by name). Arguments not
# given take their defaults from the signature, and are varied too.
GOOD = [
    ("SensorSpec.from_toml", eitskin.SensorSpec.from_toml, {"text": SPEC.to_toml()}),
    ("SensorSpec.with_triangles", SPEC.with_triangles, {"triangles": 500}),
    ("Mesh", eitskin.Mesh, {"nodes": F["mesh"].nodes, "triangles": F["mesh"].triangles, "electrodes": F["mesh"].electrodes}),
    ("Mesh.from_eidors", eitskin.Mesh.from_eidors, {"nodes": F["mesh"].nodes, "elems": F["mesh"].triangles + 1, "electrodes": [e + 1 for e in F["mesh"].electrodes]}),
    ("Protocol.two_terminal", eitskin.Protocol.two_terminal, {"electrodes": 16}),
    ("Protocol.adjacent", eitskin.Protocol.adjacent, {"electrodes": 16}),
    ("Protocol.opposite", eitskin.Protocol.opposite, {"electrodes": 16}),
    ("Protocol.from_arrays", eitskin.Protocol.from_arrays, {
        "stimulations": F["protocol"].stimulations,
        "measurement_stimulation": F["protocol"].measurement_stimulation,
        "measurement_weights": F["protocol"].measurement_weights,
    }),
    ("ForwardModel", eitskin.ForwardModel, {"mesh": F["mesh"], "protocol": F["protocol"], "electrodes": "complete", "contact_impedance": 1e-4}),
    ("ForwardModel.measure", F["model"].measure, {"conductivity": np.full(len(F["mesh"].triangles), 1.0)}),
    ("ForwardModel.jacobian", F["model"].jacobian, {"conductivity": 1.0}),
    ("one_step_matrix", eitskin.one_step_matrix, {"jacobian": J, "mesh": F["mesh"], "hyperparameter": 0.1, "background": F["rest"]}),
    ("touches", eitskin.touches, {"image": F["image"]}),
    ("Reconstructor", eitskin.Reconstructor, {"model": F["model"], "background": SPEC.conductivity, "raster": (32, 32)}),
    ("Reconstructor.from_reference", eitskin.Reconstructor.from_reference, {"spec": SPEC, "reference": np.array([F["rest"], F["rest"] * 1.001]), "frames": np.array([F["pressed"]]), "raster": (32, 32), "cache": False}),
    ("Reconstructor.image", F["recon"].image, {"v_ref": F["rest"], "v": F["pressed"]}),
    ("Reconstructor.element_values", F["recon"].element_values, {"v_ref": F["rest"], "v": F["pressed"]}),
    ("VirtualSensor", eitskin.VirtualSensor, {"spec": SPEC}),
    ("VirtualSensor.press", eitskin.VirtualSensor(SPEC).press, {"x": 0.0, "y": 0.0, "force": 5.0}),
    ("Source", eitskin.Source, {"source": "sim", "spec": SPEC, "frames": 2}),
    ("Calibration.fit", eitskin.Calibration.fit, {"spec": SPEC, "area": F["area"], "force": F["force"], "strength": F["strength"], "grid": (1, 1)}),
    ("Calibration.area_of", eitskin.Calibration.area_of, {"spec": SPEC, "x": 0.01, "y": 0.01}),
    ("Calibration.area_at", F["calibration"].area_at, {"x": 0.01, "y": 0.01}),
    ("Calibration.force", F["calibration"].force, {"area": 1, "strength": 0.05}),
    ("Pipeline", eitskin.Pipeline, {"spec": SPEC}),
    ("Pipeline.process", lambda frame: _pipeline().process(frame), {"frame": F["rest"]}),
    ("LearnedModel.train", eitskin.LearnedModel.train, {"dv": F["dv"], "positions": F["positions"], "forces": F["forces"], "method": "knn-3"}),
    ("LearnedModel.predict", F["learned"].predict, {"dv": F["dv"][0]}),
    ("robot_presses", eitskin.robot_presses, {"spec": SPEC, "count": 5}),
]

# Callables that take no argument a user gives, or only files (driven by the readers' tests):
# called once each, below.
WITHOUT_ARGUMENTS = {
    "SensorSpec.square_hydrogel", "SensorSpec.to_toml", "SensorSpec.mesh", "SensorSpec.protocol",
    "SensorSpec.forward_model", "Mesh.to_eidors", "Mesh.to_pyeit", "Mesh.areas", "Mesh.centroids", "Image.peak", "VirtualSensor.release",
    "VirtualSensor.frame", "VirtualSensor.clean_frame", "Pipeline.retake_reference",
}
FILES = {"SensorSpec.from_file", "Calibration.load", "Calibration.save", "LearnedModel.load", "LearnedModel.save"}


def _bad_values(good):
    """Values an argument whose good value is `good` is tried with."""
    common = [None, "nonsense", object()]
    if isinstance(good, bool):
        return common + [2, math.nan]
    if isinstance(good, int):
        return common + [-1, 0, 2**64, 2**70, -(2**70), 10**400, 1.5, math.nan, "5", 1j]
    if isinstance(good, float):
        return common + [math.nan, math.inf, -math.inf, -1.0, 0.0, 1e300, -1e300, 1e-300, 1j, 2**70, 10**400, "1.5"]
    if isinstance(good, str):
        return common + ["", "\0", "x" * 10_000]
    if isinstance(good, tuple):
        return common + [(), (0, 0), (-1, 5), (2**70, 5), (1.5, 2), ("a", 5), tuple(good) * 2]
    if isinstance(good, (list, np.ndarray)):
        a = np.asarray(good)
        bad = common + [
            np.array([]), np.zeros((0, 0)), a[:-1] if len(a) else a, np.concatenate([a, a[:1]]) if len(a) else a,
            a.reshape(1, -1) if a.ndim == 1 else a.ravel(), a.T, a.astype(complex) * 1j,
            np.full(a.shape, math.nan), np.full(a.shape, math.inf), np.full(a.shape, 1e300), np.zeros(a.shape),
            a.astype(object), a[::-1], -a, np.float64(1.0), a.tolist()[:1],
            np.full(a.shape, "a"), np.full(a.shape, 2**70, dtype=object), [[1.0, 2.0], [3.0]],
        ]
        if a.dtype.kind == "f":
            spiked = a.copy()
            spiked.flat[0] = math.nan
            bad.append(spiked)
        if a.dtype.kind in "iu":
            bad += [a + 10**6, a - 10**6, a.astype(float) + 0.5]
        return bad
    return common


def _numeric(good):
    """Whether an argument whose good value is `good` is a number or an array of them."""
    return isinstance(good, (int, float, tuple, list, np.ndarray)) and not isinstance(good, bool)


def _call(fn, kwargs, numeric):
    """Calls `fn`; a panic, or a refusal of a `numeric` argument other than EitskinError, fails."""
    try:
        fn(**kwargs)
    except BaseException as e:  # PanicException derives from BaseException
        if type(e).__name__ == "PanicException" or not isinstance(e, Exception):
            raise AssertionError(f"{type(e).__name__}: {e}") from None
        if numeric and not isinstance(e, eitskin.EitskinError):
            raise AssertionError(f"{type(e).__name__} instead of EitskinError: {e}") from None


def _arguments(fn, given):
    """`given` with every other parameter of `fn` at its default."""
    try:
        parameters = inspect.signature(fn).parameters
    except (TypeError, ValueError):
        return dict(given)
    # A default the signature cannot spell reads as `...`: such a parameter keeps its own.
    full = {
        n: p.default
        for n, p in parameters.items()
        if p.default is not inspect.Parameter.empty and p.default is not Ellipsis and p.kind != p.VAR_KEYWORD
    }
    full.update(given)
    return full


@pytest.mark.parametrize("name, fn, given", GOOD, ids=[g[0] for g in GOOD])
def test_no_panic_reaches_python(name, fn, given):
    arguments = _arguments(fn, given)
    fn(**arguments)  # the good call answers
    for argument, good in arguments.items():
        for bad in _bad_values(good):
            try:
                _call(fn, {**arguments, argument: bad}, _numeric(good))
            except AssertionError as e:
                raise AssertionError(f"{name}({argument}={bad!r:.80}): {e}") from None


def _native_callables():
    """Every public function and method of the native module, as 'Class.method' or 'function'."""
    names = set()
    for name, item in vars(_eitskin).items():
        if name.startswith("_") or name == "EitskinError":
            continue
        if inspect.isclass(item):
            if item.__init__ is not object.__init__ and getattr(item, "__text_signature__", None) not in (None, "($self, /, *args, **kwargs)"):
                names.add(name)
            for method, member in vars(item).items():
                if not method.startswith("_") and callable(member):
                    names.add(f"{name}.{method}")
        elif callable(item):
            names.add(name)
    return names


def test_every_native_callable_is_driven():
    driven = {g[0] for g in GOOD} | WITHOUT_ARGUMENTS | FILES
    constructors = {"SensorSpec", "Image", "Touch", "Frame", "Event", "TouchForce", "Calibration", "LearnedModel"}
    missing = sorted(_native_callables() - driven - constructors)
    assert not missing, f"native callables without a good call in GOOD: {missing}"


def test_callables_without_arguments_answer():
    spec = eitskin.SensorSpec.square_hydrogel()
    SPEC.to_toml(), SPEC.mesh(), SPEC.protocol(), SPEC.forward_model()
    F["mesh"].to_eidors(), F["mesh"].to_pyeit(), F["mesh"].areas(), F["mesh"].centroids(), F["image"].peak()
    skin = eitskin.VirtualSensor(SPEC)
    skin.frame(), skin.clean_frame(), skin.release()
    _pipeline().retake_reference()
    assert spec.electrode_count == 16


def _refused(call, message):
    """`call()` raises EitskinError whose message holds `message` (a plain string, not a pattern)."""
    with pytest.raises(eitskin.EitskinError) as refusal:
        call()
    assert message in str(refusal.value), str(refusal.value)


def test_whole_numbers_of_any_size_are_refused_with_their_value():
    _refused(lambda: SPEC.with_triangles(2**70), "triangles must be 1 to 100000000, got 1180591620717411303424")
    _refused(lambda: eitskin.VirtualSensor(SPEC, seed=2**64), "seed must be 0 to 18446744073709551615, got 18446744073709551616")
    _refused(lambda: eitskin.Source("sim", SPEC, seed=2**64), "seed must be 0 to 18446744073709551615, got 18446744073709551616")
    _refused(lambda: eitskin.Source("sim", SPEC, noise=0.5), "noise must be a number in [0, 0.1] (relative), got 0.5")
    _refused(lambda: eitskin.robot_presses(SPEC, 2**64), "count must be 1 to 1000000, got 18446744073709551616")
    reference = np.array([F["rest"], F["rest"] * 1.001])
    _refused(lambda: eitskin.Reconstructor.from_reference(SPEC, reference, raster=(-1, 5)), "raster must be (nx, ny), each 1 to 4096, got (-1, 5)")
    _refused(lambda: SPEC.with_triangles("500"), "triangles must be 1 to 100000000, got '500'")
    assert eitskin.VirtualSensor(SPEC, seed=2**64 - 1) is not None


def test_arrays_numpy_cannot_convert_are_refused_naming_the_argument():
    _refused(lambda: F["model"].measure("a"), "conductivity: could not convert string to float")
    _refused(lambda: F["recon"].image(F["rest"], ["a"] * len(F["rest"])), "v: could not convert string to float")


@pytest.mark.parametrize("exponent", [math.nan, math.inf, -5.0, 1.5])
def test_exponents_out_of_range_are_refused(exponent):
    _refused(lambda: eitskin.Reconstructor.from_reference(SPEC, F["rest"], exponent=exponent, cache=False), f"exponent must be a number in [0, 1], got {exponent}")
    _refused(lambda: eitskin.one_step_matrix(J, F["mesh"], 0.1, exponent=exponent), "exponent must be a number in [0, 1]")


def test_a_frame_in_another_unit_than_its_reference_is_refused_with_the_ratio():
    recon, rest, pressed = F["recon"], F["rest"], F["pressed"]
    for call in (recon.image, recon.element_values):
        _refused(lambda: call(rest, rest / 1000), "the frame's values are typically 1.000e-3 times the reference's")
        _refused(lambda: call(rest, -rest), "typically -1.000e0 times")
    assert recon.image(rest, pressed * 1.05).values.shape == (64, 64)


def test_a_press_whose_dv_is_not_finite_is_refused_naming_press_and_channel():
    dv = F["dv"].copy()
    dv[2, 6] = math.nan
    _refused(lambda: eitskin.LearnedModel.train(dv, F["positions"], method="knn-3"), "dv: press 3 channel 7 is NaN: every value must be a finite number")


def test_calibration_forces_and_strengths_out_of_range_are_refused():
    fit = lambda forces, grid=(1, 1): eitskin.Calibration.fit(SPEC, [1] * 4, forces, [0.4, 0.3, 0.2, 0.1], grid=grid)
    _refused(lambda: fit([-1.0, -2.0, -3.0, -4.0]), "force of sample 1 is -1 N: a press's force is 0 to 1e5 N")
    _refused(lambda: fit([1.0, 2.0, 3.0, 1e300]), "force of sample 4 is 1e300 N")
    _refused(lambda: fit([1.0, 2.0, 3.0, 4.0], grid=(2**70, 1)), "grid must be (nx, ny), each 1 to 100")
    for strength in (math.inf, -math.inf, math.nan):
        _refused(lambda: F["calibration"].force(1, strength), f"strength must be a finite number, got {strength}")
    _refused(lambda: F["calibration"].force(2**70, 0.05), "area must be 1 to 1, got 1180591620717411303424")


def test_coordinates_that_are_not_finite_are_refused():
    _refused(lambda: eitskin.Calibration.area_of(SPEC, math.nan, 0.0), "x must be a finite number, got nan")
    _refused(lambda: eitskin.Calibration.area_of(SPEC, 0.0, math.inf), "y must be a finite number, got inf")
    _refused(lambda: F["calibration"].area_at(0.0, math.nan), "y must be a finite number, got nan")


def test_mesh_indices_must_be_whole_numbers():
    nodes, electrodes = [[0, 0], [1, 0], [0, 1]], [[0], [1], [2]]
    _refused(lambda: eitskin.Mesh(nodes, [[0, 1, 2.5]], electrodes), "triangles: index 2.5 is not a whole number")
    _refused(lambda: eitskin.Mesh(nodes, [[0, 1, 2]], [[0], [1.5]]), "electrodes: index 1.5 is not a whole number")
    _refused(lambda: eitskin.Mesh(nodes, [[0, 1, -1]], electrodes), "triangles: index -1 is negative")
    _refused(lambda: eitskin.Mesh(nodes, [[0, 1, 2**70]], electrodes), "triangles: index 1.1805916207174113e21 is larger than any mesh has")
    _refused(lambda: eitskin.Mesh(nodes, [[0, 1, 3]], electrodes), "3")
    assert len(eitskin.Mesh(nodes, np.array([[0.0, 1.0, 2.0]]), electrodes).triangles) == 1


def test_save_writes_json_only_to_json_names(tmp_path):
    for name in ("x.npy", "x.csv"):
        _refused(lambda: F["learned"].save(tmp_path / name, SPEC), f"this writes .json, not .{name[2:]}: name the file so")
        _refused(lambda: F["calibration"].save(tmp_path / name), f"this writes .json, not .{name[2:]}: name the file so")
        assert not (tmp_path / name).exists()
    F["calibration"].save(tmp_path / "c.json")
    assert (tmp_path / "c.json").exists()
