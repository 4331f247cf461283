"""scikit-image peer for the thinning benchmark: skeletonize_3d (Lee et al. 1994) on the same mask.
Usage: skimage_peer.py in.npy out.npy  -> prints 'seconds peak_rss_mib' and writes the skeleton (0/1 uint8)."""
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
s = skel3d(mask)
t = time.perf_counter() - t0
np.save(sys.argv[2], (s > 0).astype(np.uint8))
print(f"{t:.4f} {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0:.1f}")
