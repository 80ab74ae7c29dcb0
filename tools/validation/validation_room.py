#!/usr/bin/env python3
"""Writes the Cornell-style room of issue 12's validation (docs/validation.md, "Per vertex"):

    python3 tools/validation/validation_room.py OUTDIR        # writes OUTDIR/room.gltf and OUTDIR/room.bin

A 2 x 2 x 2 m room (floor y = 0, ceiling y = 2, walls at x = +-1 and z = -1) with a 0.8 m square
skylight in the ceiling and the front side (z = +1) open, the two Cornell boxes of
scenes/cornell_open.gltf, Cornell reflectances, one-sided grids of 0.1 m cells (vertices
0.1 m apart: the comparison is at the vertices, so no finer grid is needed), no receiver, and a
camera outside the open side looking in (`Camera`, yfov 0.9 rad, 16:9) for frame comparisons.
Built with scenes/make_scenes.py's writer (standard library only, deterministic); a validation
input, not a bundled scene.
"""

import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "scenes"))
import make_scenes as ms  # noqa: E402

CELL = 0.1
OPENING = 0.8
CAMERA = {"at": (0.0, 1.0, 3.4), "pitch": 0.0, "yfov": 0.9, "aspect": 16.0 / 9.0}


def room(outdir):
    g = ms.GltfWriter()
    white, red, green = g.material("white", ms.WHITE), g.material("red", ms.RED), g.material("green", ms.GREEN)
    n = round(2.0 / CELL)
    lo, hi = (n - round(OPENING / CELL)) // 2, (n + round(OPENING / CELL)) // 2
    assert abs((hi - lo) * CELL - OPENING) < 1e-9
    walls = [
        ("Floor", (-1, 0, 1), (2, 0, 0), (0, 0, -2), white),
        ("BackWall", (-1, 0, -1), (2, 0, 0), (0, 2, 0), white),
        ("LeftWall", (-1, 0, 1), (0, 0, -2), (0, 2, 0), red),
        ("RightWall", (1, 0, -1), (0, 0, 2), (0, 2, 0), green),
    ]
    for name, origin, u, v, mat in walls:
        m = ms.Mesh()
        m.add_grid(origin, u, v, n, n)
        g.node(name, mesh=g.mesh(name, m, mat))
    ceiling = ms.Mesh()
    ceiling.add_grid((-1, 2, -1), (2, 0, 0), (0, 0, 2), n, n,
                     keep=lambda i, j: not (lo <= i < hi and lo <= j < hi))
    g.node("Ceiling", mesh=g.mesh("Ceiling", ceiling, white))
    for name, b in (("ShortBox", ms.SHORT_BOX), ("TallBox", ms.TALL_BOX)):
        g.node(name, mesh=g.mesh(name, ms.box(b["size"], CELL), white),
               translation=list(b["at"]), rotation=ms.quat_y(b["yaw"]))
    cam = g.camera("Camera", CAMERA["yfov"], CAMERA["aspect"], 0.01)
    g.node("Camera", camera=cam, translation=list(CAMERA["at"]), rotation=ms.quat_x(CAMERA["pitch"]))
    os.makedirs(outdir, exist_ok=True)
    ms.HERE = os.path.abspath(outdir)  # the writer writes next to HERE
    g.write("room")


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: validation_room.py OUTDIR")
    room(sys.argv[1])
