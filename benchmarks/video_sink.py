"""FrameSink write speed and peak memory: PyAV (H.264) vs OpenCV (MPEG-4 part 2), 1280x720 frames.

    python benchmarks/video_sink.py pyav 300      # or: opencv 300 (PyAV hidden); writes out_BACKEND_N.mp4 here
"""

import resource
import sys
import time

import numpy as np

if sys.argv[1] == "opencv":
    sys.modules["av"] = None  # import av fails: the OpenCV path
from relight_rt.video.job import FrameSink  # noqa: E402

n = int(sys.argv[2])
rng = np.random.default_rng(0)
base = rng.random((720, 1280, 3), dtype=np.float32)
t0 = time.perf_counter()
with FrameSink(video=f"out_{sys.argv[1]}_{n}.mp4", fps=25) as sink:
    for i in range(n):
        sink.write(f"f{i}", np.roll(base, 8 * i, axis=1) * 0.5 + 0.25)
dt = time.perf_counter() - t0
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
print(f"{sys.argv[1]} {n} frames: {1000 * dt / n:.1f} ms/frame, peak RSS {peak:.0f} MB")
