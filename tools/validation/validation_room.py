#!/usr/bin/env python3
"""Writes the Cornell-style rooms of the per-vertex validations (docs/validation.md):

    python3 tools/validation/validation_room.py OUTDIR        # writes OUTDIR/room.gltf and OUTDIR/room.bin
    python3 tools/validation/validation_room.py OUTDIR --lamp # writes OUTDIR/lamp_room.gltf and .bin

A 2 x 2 x 2 m room (floor y = 0, ceiling y = 2, walls at x = +-1 and z = -1) with a 0.8 m square
skylight in the ceiling and the front side (z = +1) open, the two Cornell boxes of
scenes/cornell_open.gltf, Cornell reflectances, one-sided grids of 0.1 m cells (vertices
0.1 m apart: the comparison is at the vertices, so no finer grid is needed), no receiver, and a
camera outside the open side looking in (`Camera`, yfov 0.9 rad, 16:9) for frame comparisons.
Built with scenes/make_scenes.py's writer (standard library only, deterministic); a validation
input, not a bundled scene.

`--lamp`: the same room closed (a front wall at z = +1 facing in) and lit only by its own
lights: the skylight's opening is filled by an emissive panel (`Panel`, a grid facing down,
emissiveFactor PANEL_EMISSIVE times KHR_materials_emissive_strength PANEL_STRENGTH, white
base colour: it reflects too), and a KHR_lights_punctual point light (`Lamp`, LAMP_CANDELA
candela, LAMP_COLOUR) hangs at LAMP_AT. The camera (`Camera`) stands inside against the front
wall. The panel's back side faces out of the closed room, where nothing is.
"""

import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "scenes"))
import make_scenes as ms  # noqa: E402

CELL = 0.1
OPENING = 0.8
CAMERA = {"at": (0.0, 1.0, 3.4), "pitch": 0.0, "yfov": 0.9, "aspect": 16.0 / 9.0}
LAMP_AT = (0.0, 1.45, 0.35)
LAMP_CANDELA = 2.0
LAMP_COLOUR = (1.0, 0.85, 0.7)
PANEL_EMISSIVE = (1.0, 0.95, 0.9)
PANEL_STRENGTH = 4.0
LAMP_CAMERA = {"at": (0.0, 1.0, 0.95), "pitch": 0.0, "yfov": 1.2, "aspect": 16.0 / 9.0}


def room(outdir, lamp=False):
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
    if lamp:
        add_lamp_and_panel(g, n, lo, hi)
    for name, b in (("ShortBox", ms.SHORT_BOX), ("TallBox", ms.TALL_BOX)):
        g.node(name, mesh=g.mesh(name, ms.box(b["size"], CELL), white),
               translation=list(b["at"]), rotation=ms.quat_y(b["yaw"]))
    c = LAMP_CAMERA if lamp else CAMERA
    cam = g.camera("Camera", c["yfov"], c["aspect"], 0.01)
    g.node("Camera", camera=cam, translation=list(c["at"]), rotation=ms.quat_x(c["pitch"]))
    os.makedirs(outdir, exist_ok=True)
    ms.HERE = os.path.abspath(outdir)  # the writer writes next to HERE
    g.write("lamp_room" if lamp else "room")


def add_lamp_and_panel(g, n, lo, hi):
    """The closed room's front wall, its emissive ceiling panel and its point light."""
    white = g.material("white", ms.WHITE)
    front = ms.Mesh()
    front.add_grid((1, 0, 1), (-2, 0, 0), (0, 2, 0), n, n)
    g.node("FrontWall", mesh=g.mesh("FrontWall", front, white))
    panel_material = g.material("panel", ms.WHITE)
    m = g.gltf["materials"][panel_material]
    m["emissiveFactor"] = list(PANEL_EMISSIVE)
    m["extensions"] = {"KHR_materials_emissive_strength": {"emissiveStrength": PANEL_STRENGTH}}
    panel = ms.Mesh()
    panel.add_grid((-1, 2, -1), (2, 0, 0), (0, 0, 2), n, n, keep=lambda i, j: lo <= i < hi and lo <= j < hi)
    g.node("Panel", mesh=g.mesh("Panel", panel, panel_material))
    g.gltf.setdefault("extensions", {})["KHR_lights_punctual"] = {"lights": [
        {"name": "Lamp", "type": "point", "color": list(LAMP_COLOUR), "intensity": LAMP_CANDELA}]}
    g.gltf["extensionsUsed"] = ["KHR_lights_punctual", "KHR_materials_emissive_strength"]
    g.node("Lamp", translation=list(LAMP_AT), extensions={"KHR_lights_punctual": {"light": 0}})


if __name__ == "__main__":
    if len(sys.argv) not in (2, 3) or (len(sys.argv) == 3 and sys.argv[2] != "--lamp"):
        sys.exit("usage: validation_room.py OUTDIR [--lamp]")
    room(sys.argv[1], lamp=len(sys.argv) == 3)
