"""SciPy peer for the graph benchmark: a pixel-graph analysis of the same skeleton (the core of
skan-style tools): 26-neighbour counts by convolution, junction clusters and branches by connected
component labelling, end points, and the pixel-graph length (sum of 26-neighbour step lengths).
Usage: scipy_peer.py skeleton.npy -> prints 'seconds peak_rss_mib junction_clusters branches end_points'."""
import resource
import sys
import time

import numpy as np
from scipy import ndimage

sk = np.load(sys.argv[1]) > 0
t0 = time.perf_counter()
k = np.ones((3, 3, 3), dtype=np.uint8)
k[1, 1, 1] = 0
nb = ndimage.convolve(sk.astype(np.uint8), k, mode="constant") * sk
junction = nb >= 3
ends = int(np.count_nonzero(nb == 1))
s26 = np.ones((3, 3, 3), dtype=bool)
_, n_junction = ndimage.label(junction, structure=s26)
_, n_branch = ndimage.label(sk & ~junction, structure=s26)
length = 0.0
z, y, x = sk.shape
for dz, dy, dx in [(0, 0, 1), (0, 1, 0), (1, 0, 0), (0, 1, 1), (0, 1, -1), (1, 0, 1), (1, 0, -1), (1, 1, 0),
                   (1, -1, 0), (1, 1, 1), (1, 1, -1), (1, -1, 1), (1, -1, -1)]:
    a = sk[0:z - dz, max(0, -dy):y - max(0, dy), max(0, -dx):x - max(0, dx)]
    b = sk[dz:z, max(0, dy):y - max(0, -dy), max(0, dx):x - max(0, -dx)]
    length += np.count_nonzero(a & b) * np.sqrt(dz * dz + dy * dy + dx * dx)
t = time.perf_counter() - t0
print(f"{t:.4f} {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0:.1f} {n_junction} {n_branch} {ends}")
