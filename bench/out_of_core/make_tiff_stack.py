#!/usr/bin/env python3
"""Writes a synthetic vessel image as an uncompressed uint8 TIFF stack (one strip per page, as Fiji
saves stacks), slice by slice, so a stack larger than memory can be made with the standard library
only (no numpy on the benchmark machine).

Vessels: tubes (mostly steep, some nearly horizontal, radii 3-8 voxels) with values 150-229 over a
background of 10-49 (uniform noise per voxel). About 3 % of the voxels are vessel at the default
density.

    make_tiff_stack.py OUT.tif NX NY NZ [SEED]
"""
import math
import random
import struct
import sys


def tubes(nx, ny, nz, rng):
    out = []
    # Tubes per unit of volume: ~3 % object at 2048 x 2048 x 512.
    scale = nx * ny * nz / (2048 * 2048 * 512)
    for _ in range(max(4, int(1400 * scale))):  # steep: from the bottom to the top, tilted
        x0, y0 = rng.uniform(0, nx), rng.uniform(0, ny)
        x1, y1 = x0 + rng.uniform(-0.3, 0.3) * nz, y0 + rng.uniform(-0.3, 0.3) * nz
        out.append(((x0, y0, -8.0), (x1, y1, nz + 8.0), rng.uniform(3, 8)))
    for _ in range(max(2, int(120 * scale))):  # nearly horizontal: across the slab
        z0 = rng.uniform(0, nz)
        x0, y0 = rng.uniform(0, nx), rng.uniform(0, ny)
        a = rng.uniform(0, 2 * math.pi)
        length = rng.uniform(0.2, 0.6) * max(nx, ny)
        out.append(((x0, y0, z0), (x0 + length * math.cos(a), y0 + length * math.sin(a), z0 + rng.uniform(-20, 20)),
                    rng.uniform(3, 6)))
    return out


def draw_slice(z, nx, ny, tubes, background, vessel):
    img = bytearray(background)
    for (p0, p1, r) in tubes:
        dz = p1[2] - p0[2]
        if min(p0[2], p1[2]) - r > z or max(p0[2], p1[2]) + r < z:
            continue
        length = math.dist(p0, p1)
        n = max(1, int(math.ceil(length)))
        # Samples along the segment whose distance in z to this slice is below r.
        if abs(dz) > 1e-9:
            ta, tb = sorted(((z - r - p0[2]) / dz, (z + r - p0[2]) / dz))
            ia, ib = max(0, int(math.floor(ta * n))), min(n, int(math.ceil(tb * n)))
        else:
            ia, ib = 0, n
        for i in range(ia, ib + 1):
            t = i / n
            cx, cy, cz = (p0[k] + t * (p1[k] - p0[k]) for k in range(3))
            h = r * r - (cz - z) ** 2
            if h <= 0:
                continue
            rr = math.sqrt(h)
            for y in range(max(0, int(math.ceil(cy - rr))), min(ny - 1, int(math.floor(cy + rr))) + 1):
                w = math.sqrt(max(0.0, h - (y - cy) ** 2))
                a, b = max(0, int(math.ceil(cx - w))), min(nx - 1, int(math.floor(cx + w)))
                if a <= b:
                    o = y * nx
                    img[o + a:o + b + 1] = vessel[o + a:o + b + 1]
    return img


def main():
    out, nx, ny, nz = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4])
    rng = random.Random(int(sys.argv[5]) if len(sys.argv) > 5 else 1)
    ts = tubes(nx, ny, nz, rng)
    page = nx * ny
    if (page + 128) * nz >= 1 << 32:  # classic TIFF: 32-bit offsets
        sys.exit("too large for a classic TIFF")
    bg_table = bytes(10 + (i % 40) for i in range(256))
    vs_table = bytes(150 + (i % 80) for i in range(256))
    pad = page % 2  # IFDs start on a word boundary
    ifd_len = 2 + 9 * 12 + 4
    with open(out, "wb") as f:
        f.write(b"II*\x00" + struct.pack("<I", 8 + page + pad))
        offset = 8
        for z in range(nz):
            noise = rng.randbytes(page)
            img = draw_slice(z, nx, ny, ts, noise.translate(bg_table), noise.translate(vs_table))
            data_offset = offset
            f.write(img + b"\x00" * pad)
            offset += page + pad
            next_ifd = offset + ifd_len + page + pad if z + 1 < nz else 0
            entries = [(256, 4, nx), (257, 4, ny), (258, 3, 8), (259, 3, 1), (262, 3, 1), (273, 4, data_offset),
                       (277, 3, 1), (278, 4, ny), (279, 4, page)]
            ifd = struct.pack("<H", len(entries))
            for tag, typ, val in entries:
                ifd += struct.pack("<HHI", tag, typ, 1) + (struct.pack("<HH", val, 0) if typ == 3 else struct.pack("<I", val))
            ifd += struct.pack("<I", next_ifd)
            assert len(ifd) == ifd_len
            f.write(ifd)
            offset += ifd_len
    print(f"{out}: {nx}x{ny}x{nz} uint8, {len(ts)} tubes")


if __name__ == "__main__":
    main()
