"""The reference for `cargo bench --bench erode`: fastscapelib 0.3 (pip install fastscapelib),
the same work as the erode kind's fluvial step on a 1025² grid — priority-flood sink resolving,
multiple flow directions (slope exponent 1), an implicit stream-power step (k 2e-4, m 0.45,
n 1, 500 years) for 100 iterations, uplift 0 — plus linear hillslope diffusion (fastscapelib
has no talus-angle eroder) as the nearest to our thermal step. Prints seconds per part.

    python3 benches/reference/fastscapelib_spl.py [SIZE] [ITERATIONS]
"""
import sys
import time

import numpy as np
import fastscapelib as fs

size = int(sys.argv[1]) if len(sys.argv) > 1 else 1025
iterations = int(sys.argv[2]) if len(sys.argv) > 2 else 100
grid = fs.RasterGrid([size, size], [2.0, 2.0], fs.NodeStatus.FIXED_VALUE)
rng = np.random.default_rng(11)
# A smooth dome with noise: land draining to the fixed border.
y, x = np.mgrid[0:size, 0:size] / (size - 1) - 0.5
elevation = np.ascontiguousarray(120.0 * np.clip(1.0 - 2.0 * np.hypot(x, y), 0.0, None) + rng.random((size, size)))
flow = fs.FlowGraph(grid, [fs.PFloodSinkResolver(), fs.MultiFlowRouter(1.0)])
spl = fs.SPLEroder(flow, 2e-4, 0.45, 1.0, 1e-5)
diffusion = fs.DiffusionADIEroder(grid, 0.01)
drainage = np.empty_like(elevation)
t_route = t_spl = t_diff = 0.0
start = time.perf_counter()
for _ in range(iterations):
    a = time.perf_counter()
    filled = flow.update_routes(elevation)
    flow.accumulate(drainage, 1.0)
    b = time.perf_counter()
    erosion = spl.erode(filled, drainage, 500.0)
    c = time.perf_counter()
    elevation = filled - erosion
    elevation -= diffusion.erode(elevation, 500.0)
    d = time.perf_counter()
    t_route += b - a
    t_spl += c - b
    t_diff += d - c
total = time.perf_counter() - start
print(f"fastscapelib {fs.__version__}, {size}² × {iterations}: {total:.2f} s "
      f"(routing + area {t_route:.2f} s, SPL {t_spl:.2f} s, diffusion {t_diff:.2f} s)")
