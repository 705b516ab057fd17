#!/usr/bin/python3
"""Writes scenes/test-data/density-8x6x4.vdb: a real OpenVDB file for the VDB reader's test.

Needs Debian's python3-openvdb (`apt-get install python3-openvdb`, run with /usr/bin/python3).

One float grid named `density`, 8 x 6 x 4 active voxels at index (i, j, k) in
[-3, 5) x [2, 8) x [5, 9), value sigma(a, b, c) = (1 + a + 8 b + 64 c) / 64 with
(a, b, c) = (i + 3, j - 2, k - 5) the voxel relative to the box's lower corner (all values
distinct and > 0, so axis order, offset and every voxel are checked). Transform: linear,
voxel size 0.125 (the scene-file reader ignores it: `[medium] min/max` place the box,
default 1/longest axis = 0.125 per voxel). Saved in full precision (not half float).

solvers/tests/vdb_file.rs writes the equivalent .vol from the same formula and checks that
both load to the same sigma_t grid and box.
"""
import os
import pyopenvdb as vdb

DIMS = (8, 6, 4)
OFFSET = (-3, 2, 5)


def sigma(a, b, c):
    return (1 + a + 8 * b + 64 * c) / 64.0


def main():
    grid = vdb.FloatGrid(0.0)
    grid.name = "density"
    grid.transform = vdb.createLinearTransform(voxelSize=0.125)
    grid.saveFloatAsHalf = False
    acc = grid.getAccessor()
    for c in range(DIMS[2]):
        for b in range(DIMS[1]):
            for a in range(DIMS[0]):
                ijk = (a + OFFSET[0], b + OFFSET[1], c + OFFSET[2])
                acc.setValueOn(ijk, sigma(a, b, c))
    here = os.path.dirname(os.path.abspath(__file__))
    out = os.path.join(here, "..", "scenes", "test-data", "density-8x6x4.vdb")
    vdb.write(out, grids=[grid])
    print(out, os.path.getsize(out), "bytes")


if __name__ == "__main__":
    main()
