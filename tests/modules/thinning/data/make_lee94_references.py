#!/usr/bin/env python3
"""Writes the scikit-image references of tests/modules/thinning/lee94_test.cpp.

Run once with Debian's /usr/bin/python3 (numpy, scikit-image 0.19):
    /usr/bin/python3 tests/modules/thinning/data/make_lee94_references.py
Each case is data/lee94/<name>.bin: a text line "nx ny nz\n", then the mask and then
skimage.morphology.skeletonize_3d(mask), each as np.packbits(a.ravel(), bitorder='little') of the
C-order array [z][y][x] (x fastest, as Skelflow's volumes). The case 'fiji_blobs' is scikit-image's own
Fiji test (test_3d_vs_fiji): its skeleton is the one Fiji's Skeletonize3D computed
(skimage/data/_blobs_3d_fiji_skeleton.tif), checked here to equal scikit-image's.
"""
import os

import numpy as np
import skimage
from skimage import io
from skimage.data import binary_blobs
from skimage.morphology import skeletonize_3d

HERE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "lee94")


def smooth_blobs(shape, seed, threshold, radius=2):
    rng = np.random.RandomState(seed)
    noise = rng.random_sample(shape)
    acc = np.zeros(shape)
    k = 2 * radius + 1
    padded = np.pad(noise, radius, mode="wrap")
    for dz in range(k):
        for dy in range(k):
            for dx in range(k):
                acc += padded[dz:dz + shape[0], dy:dy + shape[1], dx:dx + shape[2]]
    return (acc / k**3 > threshold).astype(np.uint8)


def grid(shape):
    return np.meshgrid(*[np.arange(s) for s in shape], indexing="ij")  # z, y, x


def cases():
    c = {}
    # scikit-image's Fiji comparison volume (30 x 32 x 32).
    c["fiji_blobs"] = binary_blobs(32, 0.05, n_dim=3, seed=1234)[:-2].astype(np.uint8)
    # Random blobs on non-cubic grids (catches axis mix-ups), touching the border.
    c["blobs_a"] = smooth_blobs((20, 28, 36), 1, 0.5)
    c["blobs_b"] = smooth_blobs((33, 25, 17), 2, 0.47, radius=3)
    c["blobs_dense"] = smooth_blobs((24, 24, 24), 3, 0.45)
    # Sparse noise: many tiny components, several of which Lee94 deletes.
    c["noise"] = (np.random.RandomState(4).random_sample((16, 18, 20)) < 0.12).astype(np.uint8)
    # Tubes: cylinders along each axis, a torus and a tube leaving the volume.
    z, y, x = grid((30, 26, 34))
    t = ((y - 12) ** 2 + (z - 14) ** 2 <= 9) & (x > 2) & (x < 31)           # along x
    t |= ((x - 8) ** 2 + (z - 8) ** 2 <= 6) & (y > 1)                         # along y, touching y = 25
    t |= ((x - 25) ** 2 + (y - 6) ** 2 <= 5)                                  # along z, through the volume
    c["tubes"] = t.astype(np.uint8)
    z, y, x = grid((16, 40, 40))
    r = np.sqrt((x - 19.5) ** 2 + (y - 19.5) ** 2)
    c["torus"] = ((r - 12) ** 2 + (z - 7.5) ** 2 <= 10).astype(np.uint8)
    # Plates: thickness 3 and 4 in different orientations, one with holes, one touching the border.
    z, y, x = grid((28, 30, 26))
    p = (z >= 5) & (z <= 7) & (x > 2) & (x < 23) & (y > 2) & (y < 27)
    p &= ~(((x - 12) ** 2 + (y - 14) ** 2) <= 9)                              # a hole
    p |= (x >= 18) & (x <= 21) & (z > 8)                                      # a wall touching y and z borders
    p |= (np.abs(x + y - 2 * z) <= 1) & (z > 14)                              # an oblique plate
    c["plates"] = p.astype(np.uint8)
    # Cubes: solid, hollow (a cavity), touching a corner; full and empty volumes.
    a = np.zeros((16, 16, 16), np.uint8)
    a[3:13, 3:13, 3:13] = 1
    c["cube"] = a
    a = np.zeros((14, 14, 14), np.uint8)
    a[2:12, 2:12, 2:12] = 1
    a[5:9, 5:9, 5:9] = 0
    c["hollow_cube"] = a
    a = np.zeros((12, 13, 14), np.uint8)
    a[:7, :8, :9] = 1
    c["corner_cube"] = a
    c["full"] = np.ones((8, 10, 12), np.uint8)
    c["empty"] = np.zeros((5, 6, 7), np.uint8)
    # 1-voxel-thin inputs: a random 26-connected walk, a digital plane, single and paired voxels.
    rng = np.random.RandomState(5)
    a = np.zeros((20, 20, 20), np.uint8)
    p = np.array([10, 10, 10])
    for _ in range(120):
        a[tuple(p)] = 1
        p = np.clip(p + rng.randint(-1, 2, 3), 0, 19)
    c["thin_walk"] = a
    a = np.zeros((10, 12, 14), np.uint8)
    a[4, 1:11, 1:13] = 1
    c["thin_plane"] = a
    a = np.zeros((9, 9, 9), np.uint8)
    a[1, 1, 1] = 1
    a[4, 4, 4] = a[4, 4, 5] = 1          # two voxels
    a[7, 6, 6] = a[7, 7, 7] = a[7, 8, 8] = 1  # a diagonal of three
    c["tiny"] = a
    # One z-slice: scikit-image treats it as 2D (four border directions).
    c["slice"] = smooth_blobs((1, 40, 48), 6, 0.5)[..., :]
    # Thin in another axis: one y-row of slices (six directions).
    c["one_row"] = smooth_blobs((18, 1, 30), 7, 0.5)
    return c


def main():
    os.makedirs(HERE, exist_ok=True)
    fiji = io.imread(os.path.join(os.path.dirname(skimage.__file__), "data", "_blobs_3d_fiji_skeleton.tif"))
    for name, mask in cases().items():
        skel = (skeletonize_3d(mask * np.uint8(255)) > 0).astype(np.uint8)
        if name == "fiji_blobs":
            assert np.array_equal(skel, (fiji > 0).astype(np.uint8)), "scikit-image differs from Fiji"
        nz, ny, nx = mask.shape
        with open(os.path.join(HERE, name + ".bin"), "wb") as f:
            f.write(f"{nx} {ny} {nz}\n".encode())
            f.write(np.packbits(mask.ravel(), bitorder="little").tobytes())
            f.write(np.packbits(skel.ravel(), bitorder="little").tobytes())
        print(f"{name}: {nx}x{ny}x{nz}, {int(mask.sum())} -> {int(skel.sum())} voxels")


if __name__ == "__main__":
    main()
