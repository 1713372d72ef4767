"""Writes an N x N RGB float32 .npy image (img.npy, smooth stripes) and a
per-pixel angle map (angle.npy, circles around the centre) into the current
folder, band by band through numpy.lib.format.open_memmap: never the whole
array in memory. Used by tests/bench/gigapixel.sh.

    python tests/bench/make_large_npy.py 20000   # 4.8 GB + 1.6 GB
"""
import sys
import numpy as np
from numpy.lib.format import open_memmap

n = int(sys.argv[1])
img = open_memmap("img.npy", mode="w+", dtype=np.float32, shape=(n, n, 3))
ang = open_memmap("angle.npy", mode="w+", dtype=np.float32, shape=(n, n))
band = 512
x = np.arange(n, dtype=np.float32)
for y0 in range(0, n, band):
    y = np.arange(y0, min(n, y0 + band), dtype=np.float32)[:, None]
    v = 0.5 + 0.25 * np.sin(x[None, :] / 37.0) * np.cos(y / 23.0)
    img[y0:y0 + len(y)] = np.stack([v, 1 - v, 0.5 * v], axis=-1)
    ang[y0:y0 + len(y)] = np.degrees(np.arctan2(y - n / 2, x[None, :] - n / 2))
img.flush(); ang.flush()
