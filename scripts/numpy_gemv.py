"""The limit `eitskin bench`'s frame_image is compared with: numpy's A @ x on a matrix of the
image product's shape and type (4096 pixels x 120 measurements, float32), in both layouts,
with numpy's BLAS on its default threads and on one. Prints min and median of 3,000 runs, in us.

    pip install numpy && python3 scripts/numpy_gemv.py
"""
import os
import subprocess
import sys
import time


def measure():
    import numpy as np

    rng = np.random.default_rng(1)
    a = rng.random((4096, 120), dtype=np.float32)
    x = rng.random(120, dtype=np.float32)
    y = np.empty(4096, np.float32)
    for layout in ("C", "F"):
        b = np.asarray(a, order=layout)
        times = []
        for _ in range(3000):
            t = time.perf_counter()
            np.matmul(b, x, out=y)
            times.append(time.perf_counter() - t)
        times.sort()
        threads = os.environ.get("OPENBLAS_NUM_THREADS", "default")
        print(f"numpy {np.__version__} A @ x, {layout}-order, threads {threads}: "
              f"min {times[0] * 1e6:.1f} us, median {times[len(times) // 2] * 1e6:.1f} us")


if __name__ == "__main__":
    if len(sys.argv) > 1:
        measure()
    else:
        for threads in (None, "1"):
            env = dict(os.environ)
            if threads:
                env.update(OPENBLAS_NUM_THREADS=threads, OMP_NUM_THREADS=threads, MKL_NUM_THREADS=threads)
            subprocess.run([sys.executable, __file__, "measure"], env=env, check=True)
