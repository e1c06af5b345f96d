"""What a frame costs from Python, to set beside `eitskin bench` (frame_image, frame_touches).

    python benchmarks/frame_overhead.py
"""
import timeit

import eitskin

spec = eitskin.SensorSpec.square_hydrogel()
recon = eitskin.Reconstructor(spec.forward_model(), spec.conductivity)
sensor = eitskin.VirtualSensor(spec, seed=1)
reference = sensor.frame()
sensor.press(0.03, 0.02, 6.0)
frame = sensor.frame()
pipeline = eitskin.Pipeline(spec)
for _ in range(10):
    pipeline.process(reference)

cases = {
    "Reconstructor.image": lambda: recon.image(reference, frame),
    "Reconstructor.image(...).values": lambda: recon.image(reference, frame).values,
    "Pipeline.process (image, touches)": lambda: pipeline.process(frame),
    "Pipeline.process + .touches": lambda: (pipeline.process(frame), pipeline.touches),
}
for name, call in cases.items():
    times = sorted(t / 2000 * 1e6 for t in timeit.repeat(call, number=2000, repeat=7))
    print(f"{name:36} median {times[3]:6.2f} µs, fastest {times[0]:6.2f} µs")
