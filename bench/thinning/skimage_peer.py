"""scikit-image peer for the thinning benchmark: skeletonize_3d (Lee et al. 1994) on the same mask.
Usage: skimage_peer.py in.npy out.npy  -> prints 'seconds peak_rss_mib cpu_seconds' and writes the skeleton
(0/1 uint8). cpu_seconds (process CPU time of the call) is less sensitive than wall time to a loaded machine."""
import resource
import sys
import time

import numpy as np

try:
    from skimage.morphology import skeletonize_3d as skel3d
except ImportError:  # newer scikit-image: skeletonize handles 3D input
    from skimage.morphology import skeletonize as skel3d

mask = np.load(sys.argv[1]) > 0
t0 = time.perf_counter()
c0 = time.process_time()
s = skel3d(mask)
t = time.perf_counter() - t0
c = time.process_time() - c0
np.save(sys.argv[2], (s > 0).astype(np.uint8))
print(f"{t:.4f} {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0:.1f} {c:.4f}")
