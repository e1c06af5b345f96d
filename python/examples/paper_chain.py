"""The paper's chain in 20 lines: spec -> presses -> pseudo-array calibration -> image -> touch -> force."""
import numpy as np

import eitskin

spec = eitskin.SensorSpec.square_hydrogel()  # 200 x 200 mm hydrogel, 16 electrodes, 120 values
sensor = eitskin.VirtualSensor(spec, seed=1)  # the sheet, simulated on a finer mesh, 0.01 % noise
recon = eitskin.Reconstructor(spec.forward_model(), spec.conductivity)  # NOSER, lambda = 0.1
reference = np.mean([sensor.frame() for _ in range(10)], axis=0)
peak_of = lambda: eitskin.touches(recon.image(reference, sensor.frame()))[0].peak  # noqa: E731

# Calibrate: presses of known force at the 5 x 5 pseudo-array's unit centres (6 symmetry areas).
samples = []
for x in np.linspace(-0.08, 0.08, 5):
    for y in np.linspace(-0.08, 0.08, 5):
        for force in (2.0, 5.0, 9.0, 16.0):
            sensor.release(), sensor.press(x, y, force)
            samples.append((eitskin.Calibration.area_of(spec, x, y), force, peak_of()))
calibration = eitskin.Calibration.fit(spec, *zip(*samples))

sensor.release(), sensor.press(0.03, -0.02, 7.0)  # the press to find: x, y in m, 7 N (off the unit centres)
for touch in eitskin.touches(recon.image(reference, sensor.frame())):
    newtons, _ = calibration.force(calibration.area_at(*touch.centre), touch.peak)
    print(f"touch at ({touch.centre[0] * 1e3:.1f}, {touch.centre[1] * 1e3:.1f}) mm: {newtons:.1f} N (truth: 30, -20 mm, 7 N)")
