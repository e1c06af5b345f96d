"""No Rust panic reaches Python: every native function and method, each argument in turn given
values generated from its good one (wrong lengths and shapes, empty, NaN, infinities, huge and
negative numbers, other types, complex values), answers or raises an ordinary exception.

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
        return common + [-1, 0, 2**70, -(2**70), 1.5, math.nan]
    if isinstance(good, float):
        return common + [math.nan, math.inf, -math.inf, -1.0, 0.0, 1e300, -1e300, 1e-300, 1j]
    if isinstance(good, str):
        return common + ["", "\0", "x" * 10_000]
    if isinstance(good, tuple):
        return common + [(), (0, 0), (-1, 5), (2**70, 5), (1.5, 2), tuple(good) * 2]
    if isinstance(good, (list, np.ndarray)):
        a = np.asarray(good)
        bad = common + [
            np.array([]), np.zeros((0, 0)), a[:-1] if len(a) else a, np.concatenate([a, a[:1]]) if len(a) else a,
            a.reshape(1, -1) if a.ndim == 1 else a.ravel(), a.T, a.astype(complex) * 1j,
            np.full(a.shape, math.nan), np.full(a.shape, math.inf), np.full(a.shape, 1e300), np.zeros(a.shape),
            a.astype(object), a[::-1], -a, np.float64(1.0), a.tolist()[:1],
        ]
        if a.dtype.kind == "f":
            spiked = a.copy()
            spiked.flat[0] = math.nan
            bad.append(spiked)
        if a.dtype.kind in "iu":
            bad += [a + 10**6, a - 10**6, a.astype(float) + 0.5]
        return bad
    return common


def _call(fn, kwargs):
    try:
        fn(**kwargs)
    except BaseException as e:  # PanicException derives from BaseException
        if type(e).__name__ == "PanicException" or not isinstance(e, Exception):
            raise AssertionError(f"{type(e).__name__}: {e}") from None


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
                _call(fn, {**arguments, argument: bad})
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
