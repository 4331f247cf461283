"""Peer side of the segmentation benchmark: one operation per process (so that peak RSS is that
operation's) on the .npy inputs written by bench_segmentation. Prints key=value lines.
usage: scipy_peer.py DIR SIZE cc|gaussian|median|dilate|otsu
"""
import resource
import sys
import time

import numpy as np
from scipy import ndimage


def ball(r):
    g = np.arange(-r, r + 1)
    z, y, x = np.meshgrid(g, g, g, indexing="ij")
    return x * x + y * y + z * z <= r * r


def main():
    d, n, op = sys.argv[1], int(sys.argv[2]), sys.argv[3]
    out = {}
    if op == "cc":
        m = np.load(d + "/mask.npy")
        t0 = time.perf_counter()
        _, count = ndimage.label(m, structure=np.ones((3, 3, 3), dtype=bool))
        t = time.perf_counter() - t0
        out["count"] = count
    elif op == "gaussian":
        f = np.load(d + "/mask.npy").astype(np.float32)
        t0 = time.perf_counter()
        g = ndimage.gaussian_filter(f, sigma=2.0, truncate=3.5, mode="nearest", output=np.float32)
        t = time.perf_counter() - t0
        if n <= 256:
            out["maxdiff"] = "%.3g" % float(np.max(np.abs(np.load(d + "/gauss.npy").astype(np.float64) - g)))
    elif op == "median":
        a = np.load(d + "/noisy_u8.npy")
        t0 = time.perf_counter()
        g = ndimage.median_filter(a, size=3, mode="nearest")
        t = time.perf_counter() - t0
        if n <= 256:
            out["differ"] = int(np.count_nonzero(np.load(d + "/median.npy") != g))
    elif op == "dilate":
        m = np.load(d + "/mask.npy")
        t0 = time.perf_counter()
        g = ndimage.binary_dilation(m != 0, structure=ball(3))
        t = time.perf_counter() - t0
        if n <= 256:
            out["differ"] = int(np.count_nonzero((np.load(d + "/dilate.npy") != 0) != g))
    elif op == "otsu":
        from skimage.filters import threshold_otsu
        f = np.load(d + "/noisy_f32.npy")
        t0 = time.perf_counter()
        th = threshold_otsu(f)
        m = f > th
        t = time.perf_counter() - t0
        out["threshold"] = "%.6f" % th
        out["object"] = int(np.count_nonzero(m))
    else:
        raise SystemExit("unknown op " + op)
    print("time=%.4f" % t)
    print("peak_rss_mib=%.0f" % (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0))
    for k, v in out.items():
        print("%s=%s" % (k, v))


if __name__ == "__main__":
    main()
