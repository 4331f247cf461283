"""SciPy peers for the skeleton-distance benchmark, on the same .npy skeletons: the distance of every
reference skeleton voxel to the nearest voxel of the other skeleton by
  edt:    scipy.ndimage.distance_transform_edt of the complement of the other skeleton (a seeded
          Euclidean distance transform, the thesis' method), read at the reference voxels;
  kdtree: scipy.spatial.cKDTree over the other skeleton's voxels, queried with the reference voxels.
Usage: scipy_peer.py WORK_DIR edt|kdtree THREADS
  -> prints 'seconds peak_rss_mib points mean changed(>2)' (timing excludes loading the files)."""
import resource
import sys
import time

import numpy as np
from scipy import ndimage
from scipy.spatial import cKDTree

work, method, threads = sys.argv[1], sys.argv[2], int(sys.argv[3])
ref = np.load(work + "/reference.npy")
other = np.load(work + "/other.npy")
t0 = time.perf_counter()
if method == "edt":
    d = ndimage.distance_transform_edt(other == 0)
    values = d[ref > 0]
else:
    tree = cKDTree(np.argwhere(other > 0).astype(np.float64))
    values, _ = tree.query(np.argwhere(ref > 0).astype(np.float64), k=1, workers=threads)
t = time.perf_counter() - t0
print(f"{t:.4f} {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0:.1f} {values.size} "
      f"{values.mean():.4f} {int(np.count_nonzero(values > 2.0))}")
