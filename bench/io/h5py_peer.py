"""Peer side of the HDF5 I/O benchmark: h5py writes / reads the same array (from the .npy written by
bench_io) contiguous, with h5py's automatic chunks (chunks=True), and chunks=True + gzip level 1
(+ shuffle for multi-byte types, as ours); reads it whole and as block³ boxes. Also checks that
h5py reads our files back identically. Prints key=value lines prefixed by the layout.
usage: h5py_peer.py DIR uint8|float32 BLOCK
"""
import os
import resource
import sys
import time

import h5py
import numpy as np


def best_of(k, f):
    best, out = 1e300, None
    for _ in range(k):
        t0 = time.perf_counter()
        out = f()
        best = min(best, time.perf_counter() - t0)
    return best, out


def main():
    d, dtype, block = sys.argv[1], sys.argv[2], int(sys.argv[3])
    a = np.load(d + "/" + dtype + ".npy")
    nz, ny, nx = a.shape
    layouts = {
        "contiguous": dict(),
        "auto_chunks": dict(chunks=True),
        "auto_chunks_gzip1": dict(chunks=True, compression="gzip", compression_opts=1, shuffle=a.itemsize > 1),
    }
    for name, kw in layouts.items():
        path = "%s/h5py_%s_%s.h5" % (d, dtype, name)

        def write():
            with h5py.File(path, "w") as f:
                f.create_dataset("volume", data=a, **kw)

        tw, _ = best_of(2, write)

        def read():
            with h5py.File(path, "r") as f:
                return f["volume"][...]

        tr, back = best_of(2, read)
        same = np.array_equal(back, a)
        del back

        def blocks():
            s = 0
            with h5py.File(path, "r") as f:
                ds = f["volume"]
                for z in range(0, nz, block):
                    for y in range(0, ny, block):
                        for x in range(0, nx, block):
                            b = ds[z:z + block, y:y + block, x:x + block]
                            s += int(b[b.shape[0] // 2, b.shape[1] // 2, b.shape[2] // 2] != 0)
            return s

        tb, _ = best_of(2, blocks)
        with h5py.File(path, "r") as f:
            chunks = f["volume"].chunks
        chunk_text = "x".join(str(c) for c in reversed(chunks)) if chunks else "contiguous"
        print("%s.write=%.4f" % (name, tw))
        print("%s.read=%.4f" % (name, tr))
        print("%s.blocks=%.4f" % (name, tb))
        print("%s.file_bytes=%d" % (name, os.path.getsize(path)))
        print("%s.chunks=%s" % (name, chunk_text))
        print("%s.identical=%s" % (name, "yes" if same else "NO"))
        os.remove(path)
    print("peak_rss_mib=%.0f" % (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0))
    for level in (0, 1):
        path = "%s/ours_%s_%d.h5" % (d, dtype, level)
        if os.path.exists(path):
            with h5py.File(path, "r") as f:
                print("h5py_reads_ours_%d=%s" % (level, "yes" if np.array_equal(f["volume"][...], a) else "NO"))


if __name__ == "__main__":
    main()
