"""The paper's chain: spec -> presses -> pseudo-array calibration -> image -> touch -> force.

It prints the force of one press and, beside it, the error this method makes elsewhere on the
sheet: one press's answer says little without the spread of the answers around it.
"""
import numpy as np

import eitskin

spec = eitskin.SensorSpec.square_hydrogel()  # 200 x 200 mm hydrogel, 16 electrodes, 120 values
sensor = eitskin.VirtualSensor(spec, seed=1)  # the sheet, simulated on a finer mesh
rest = np.array([sensor.frame() for _ in range(20)])  # frames at rest: their mean and their noise
recon = eitskin.Reconstructor.from_reference(spec, rest)  # NOSER, lambda as `eitskin image` picks it


def press(x, y, force):
    """Press the virtual sheet (x, y in m from the centre, force in N) and image one frame."""
    sensor.release(), sensor.press(x, y, force)
    return eitskin.touches(recon.image(recon.reference, sensor.frame()))


def newtons(touch):
    return calibration.force(calibration.area_at(*touch.centre), touch.peak)[0]


# Calibrate: presses of known force at the 5 x 5 pseudo-array's unit centres (6 symmetry areas).
samples = []
for x in np.linspace(-0.08, 0.08, 5):
    for y in np.linspace(-0.08, 0.08, 5):
        for force in (2.0, 5.0, 9.0, 16.0):
            [touch, *_] = press(x, y, force)
            samples.append((eitskin.Calibration.area_of(spec, x, y), force, touch.peak))
calibration = eitskin.Calibration.fit(spec, *zip(*samples))

# The method's error: presses of 1-15 N at random places, off the unit centres.
rng = np.random.default_rng(7)
errors = []
for x, y, force in zip(*rng.uniform(-0.08, 0.08, (2, 20)), rng.uniform(1.0, 15.0, 20)):
    found = press(x, y, force)
    errors.append(newtons(found[0]) - force if found else -force)
rms = float(np.sqrt(np.mean(np.square(errors))))

[touch, *_] = press(0.03, -0.02, 7.0)  # the press to find: x, y in m, 7 N
print(
    f"touch at ({touch.centre[0] * 1e3:.1f}, {touch.centre[1] * 1e3:.1f}) mm: {newtons(touch):.1f} N "
    f"(truth: 30, -20 mm, 7 N; RMS error elsewhere on the sheet: {rms:.1f} N over 20 presses of 1-15 N)"
)
