"""Touches from a running `eitskin run --publish zenoh`, read with eclipse-zenoh alone (no eitskin).

    eitskin run --publish zenoh --listen tcp/0.0.0.0:7447          # on the sensor's computer
    python zenoh_touches.py --connect tcp/SENSOR-HOST:7447          # anywhere on the network

Each frame's sample is the JSON line's schema (or CBOR of it, `--publish-encoding cbor`): `seq`,
`t`, `status`, `touches` (x, y in the spec's unit, force in N with `force_std`), `counters`.
"""
import argparse
import json
import queue
import sys

import zenoh

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--connect", action="append", default=[], help="endpoint to connect to, e.g. tcp/127.0.0.1:7447")
parser.add_argument("--listen", action="append", default=[], help="endpoint to listen on instead")
parser.add_argument("--key", default="eitskin/*/touches", help="key expression (default: every sensor's touches)")
parser.add_argument("--frames", type=int, help="stop after this many frames")
parser.add_argument("--timeout", type=float, default=30.0, help="give up after this many seconds without a frame")
parser.add_argument("--no-multicast-scouting", action="store_true", help="reach only the endpoints given")
args = parser.parse_args()


def decode(sample):
    """A sample's payload as a dict: JSON or CBOR, as its encoding says."""
    payload = sample.payload.to_bytes()
    if str(sample.encoding).startswith("application/cbor"):
        import cbor2  # only for --publish-encoding cbor

        return cbor2.loads(payload)
    return json.loads(payload)


config = zenoh.Config()
if args.connect:
    config.insert_json5("connect/endpoints", json.dumps(args.connect))
if args.listen:
    config.insert_json5("listen/endpoints", json.dumps(args.listen))
if args.no_multicast_scouting:
    config.insert_json5("scouting/multicast/enabled", "false")

with zenoh.open(config) as session:
    samples = queue.Queue()  # filled on Zenoh's thread, read here with a timeout
    subscriber = session.declare_subscriber(args.key, samples.put)
    print(f"listening on {args.key}", file=sys.stderr, flush=True)
    frames = 0
    while args.frames is None or frames < args.frames:
        try:
            sample = samples.get(timeout=args.timeout)
        except queue.Empty:
            sys.exit(f"no frame within {args.timeout} s")
        line = decode(sample)
        frames += 1
        for touch in line["touches"]:
            force = f"{touch['force']:.1f} ± {touch['force_std']:.1f} N" if touch.get("force") is not None else f"peak {touch['peak']:.3f} S/m"
            print(f"{sample.key_expr} frame {line['seq']}: touch at ({touch['x']:.0f}, {touch['y']:.0f}), {force}", flush=True)
