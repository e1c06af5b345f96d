"""A live loop: frames from a board on a serial port through the pipeline, touches and forces.

    python live_serial.py serial:/dev/ttyACM0@921600 --calibration calibration.json --spec sensor.toml

Any source eitskin reads works the same: "file:capture.txt", "sim" (the virtual sensor).
"""
import argparse
import sys

import eitskin

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("source", nargs="?", default="serial:/dev/ttyACM0")
parser.add_argument("--spec", help="spec file (TOML); default: the paper's sensor")
parser.add_argument("--calibration", help="calibration file from `eitskin calibrate` or Calibration.save")
parser.add_argument("--frames", type=int, help="stop after this many frames")
parser.add_argument("--fast", action="store_true", help="a file or the virtual sensor as fast as possible")
args = parser.parse_args()

spec = eitskin.SensorSpec.from_file(args.spec) if args.spec else eitskin.SensorSpec.square_hydrogel()
calibration = eitskin.Calibration.load(args.calibration, spec) if args.calibration else None
pipeline = eitskin.Pipeline(spec, calibration=calibration)
for item in eitskin.Source(args.source, spec, frames=args.frames, fast=args.fast):
    if isinstance(item, eitskin.Event):  # bad input, a damaged record, the port gone or back
        print(f"{item.kind}: {item.message}", file=sys.stderr)
        continue
    pipeline.process(item.values)
    for touch in pipeline.touches:
        force = f"{touch.force:.1f} N" if touch.force is not None else f"peak {touch.peak:.3f} S/m"
        print(f"frame {item.seq}: touch at ({touch.centre[0] * 1e3:.0f}, {touch.centre[1] * 1e3:.0f}) mm, {force}")
