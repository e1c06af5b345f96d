"""eitskin: electrical impedance tomography for tactile skins, from Python.

The Rust library's types over numpy arrays: a sensor spec, its mesh and protocol, the forward
model (voltages and Jacobian from conductivity), the one-step Gauss-Newton reconstructor
(images), touches, and the virtual sensor. Every solve releases the GIL. Lengths are in
metres, conductivities in S/m, voltages in V at 1 A.

Example
-------
>>> import eitskin
>>> spec = eitskin.SensorSpec.square_hydrogel().with_triangles(1500)
>>> sensor = eitskin.VirtualSensor(spec, seed=1)
>>> reference = sensor.clean_frame()
>>> sensor.press(0.04, -0.03, 8.0)
>>> recon = eitskin.Reconstructor(spec.forward_model(), spec.conductivity)
>>> image = recon.image(reference, sensor.clean_frame())
>>> [touch] = eitskin.touches(image)
>>> abs(touch.centre[0] - 0.04) < 0.01 and abs(touch.centre[1] + 0.03) < 0.01
True
"""

from ._eitskin import (
    COLOUR_STOPS,
    Calibration,
    EitskinError,
    Event,
    ForwardModel,
    Frame,
    Image,
    LearnedModel,
    Mesh,
    Pipeline,
    Protocol,
    Reconstructor,
    SensorSpec,
    Source,
    Touch,
    TouchForce,
    VirtualSensor,
    one_step_matrix,
    robot_presses,
    touches,
)
from .interop import colour_map, from_pyeit, mesh_from_pyeit, plot_elements, plot_image, protocol_from_pyeit

__all__ = [
    "COLOUR_STOPS",
    "Calibration",
    "colour_map",
    "EitskinError",
    "Event",
    "ForwardModel",
    "Frame",
    "Image",
    "LearnedModel",
    "Mesh",
    "Pipeline",
    "Protocol",
    "Reconstructor",
    "SensorSpec",
    "Source",
    "Touch",
    "TouchForce",
    "VirtualSensor",
    "from_pyeit",
    "robot_presses",
    "mesh_from_pyeit",
    "one_step_matrix",
    "plot_elements",
    "plot_image",
    "protocol_from_pyeit",
    "touches",
]
