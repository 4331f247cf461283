#!/usr/bin/python3
"""Writes the TIFF files of volume_tiff_test.cpp with tifffile (Debian's python3-tifffile), as users'
tools write them. Usage: make_tiffs.py FOLDER. Exit code 77 when numpy or tifffile is missing."""
import sys

try:
    import numpy as np
    import tifffile
except ImportError:
    sys.exit(77)

out = sys.argv[1]


def ramp(shape, dtype):
    n = int(np.prod(shape))
    a = (np.arange(n, dtype=np.int64) * 7919) % 251
    if np.dtype(dtype).kind == 'i':
        a = a - 120
    return a.astype(dtype).reshape(shape)


zyx = (5, 35, 40)  # 40 x 35 x 5 voxels as (x, y, z)
# ImageJ: spacing x/y as resolution, z and unit in the description (as Fiji saves a stack).
tifffile.imwrite(f'{out}/imagej_u16.tif', ramp(zyx, np.uint16), imagej=True, resolution=(1 / 0.5, 1 / 0.25),
                 metadata={'spacing': 2.0, 'unit': 'um', 'axes': 'ZYX'})
tifffile.imwrite(f'{out}/imagej_f32_mm.tif', ramp(zyx, np.float32) / 4, imagej=True, resolution=(1 / 0.01, 1 / 0.01),
                 metadata={'spacing': 0.02, 'unit': 'mm', 'axes': 'ZYX'})
# ImageJ hyperstack with two channels (pages interleaved c, z).
tifffile.imwrite(f'{out}/imagej_2ch.tif', np.stack([ramp(zyx, np.uint8), ramp(zyx, np.uint8) // 2], axis=1),
                 imagej=True, metadata={'axes': 'ZCYX'})
# OME-TIFF in nanometres.
tifffile.imwrite(f'{out}/ome_f32.ome.tif', ramp(zyx, np.float32), ome=True,
                 metadata={'axes': 'ZYX', 'PhysicalSizeX': 8.0, 'PhysicalSizeXUnit': 'nm', 'PhysicalSizeY': 8.0,
                           'PhysicalSizeYUnit': 'nm', 'PhysicalSizeZ': 30.0, 'PhysicalSizeZUnit': 'nm'})
# OME-TIFF with two channels, DimensionOrder XYCZT (channel pages interleaved).
tifffile.imwrite(f'{out}/ome_2ch.ome.tif', np.stack([ramp(zyx, np.uint16), ramp(zyx, np.uint16) + 1], axis=1), ome=True,
                 metadata={'axes': 'ZCYX', 'PhysicalSizeX': 0.3, 'PhysicalSizeY': 0.3, 'PhysicalSizeZ': 1.5})
# Layouts and compressions: tiles (edge tiles partial), deflate, short strips, BigTIFF, big-endian,
# (LZW and PackBits need imagecodecs for tifffile: volume_tiff_test writes those with libtiff)
# signed and 64-bit samples.
tifffile.imwrite(f'{out}/tiled_deflate.tif', ramp(zyx, np.uint16), tile=(16, 16), compression='zlib')
tifffile.imwrite(f'{out}/strips3.tif', ramp(zyx, np.uint8), rowsperstrip=3)
tifffile.imwrite(f'{out}/bigtiff.tif', ramp(zyx, np.int16), bigtiff=True)
tifffile.imwrite(f'{out}/big_endian.tif', ramp(zyx, np.float64), byteorder='>')
tifffile.imwrite(f'{out}/int8.tif', ramp(zyx, np.int8))
tifffile.imwrite(f'{out}/uint32.tif', ramp(zyx, np.uint32))
# RGB: 3 samples per pixel, and planar (separate) RGB.
tifffile.imwrite(f'{out}/rgb.tif', np.stack([ramp(zyx, np.uint8), ramp(zyx, np.uint8) // 3, ramp(zyx, np.uint8) // 5], axis=-1),
                 photometric='rgb')
tifffile.imwrite(f'{out}/rgb_planar.tif', np.stack([ramp(zyx, np.uint8), ramp(zyx, np.uint8) // 3, ramp(zyx, np.uint8) // 5], axis=1),
                 photometric='rgb', planarconfig='separate')
# Bad: pages of different sizes; an unsupported sample format (complex).
with tifffile.TiffWriter(f'{out}/bad_sizes.tif') as w:
    w.write(ramp((35, 40), np.uint8))
    w.write(ramp((35, 41), np.uint8))
tifffile.imwrite(f'{out}/bad_complex.tif', np.zeros((2, 4, 4), np.complex64))
