#!/usr/bin/env python3
"""Writes the bundled room with issue 42's materials (docs/render.md, "Materials"):

    python3 tools/validation/glossy_room.py OUTDIR      # writes OUTDIR/cornell_glossy.gltf (+ .bin)
    python3 tools/validation/glossy_room.py --validation-room OUTDIR
                                                        # writes OUTDIR/room_glossy.gltf (+ room.gltf, room.bin)

scenes/cornell_open.gltf with its floor a glossy dielectric (roughness 0.35) and its short box
copper (metallic 1, roughness 0.4, base colour (0.95, 0.64, 0.54)); the geometry is the bundled
room's own buffer, copied next to it. With --validation-room the same two materials go on the
room of tools/validation/validation_room.py (written into OUTDIR first), whose camera sees the
whole floor and both boxes: the scene of docs/validation.md, "Glossy materials". Standard
library only, deterministic.
"""

import json
import os
import shutil
import sys

SCENES = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "scenes")


def main(outdir, validation_room=False):
    if validation_room:
        sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
        import validation_room as vr
        vr.room(outdir)
        source, name = os.path.abspath(outdir), "room_glossy.gltf"
    else:
        source, name = SCENES, "cornell_glossy.gltf"
    with open(os.path.join(source, "room.gltf" if validation_room else "cornell_open.gltf")) as f:
        g = json.load(f)
    floor = len(g["materials"])
    g["materials"].append({"name": "glossy_floor", "pbrMetallicRoughness": {
        "baseColorFactor": [0.725, 0.71, 0.68, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.35}})
    g["materials"].append({"name": "copper", "pbrMetallicRoughness": {
        "baseColorFactor": [0.95, 0.64, 0.54, 1.0], "metallicFactor": 1.0, "roughnessFactor": 0.4}})
    meshes = {m["name"]: m for m in g["meshes"]}
    meshes["Floor"]["primitives"][0]["material"] = floor
    meshes["ShortBox"]["primitives"][0]["material"] = floor + 1
    os.makedirs(outdir, exist_ok=True)
    for b in g["buffers"]:
        if not validation_room:
            shutil.copyfile(os.path.join(source, b["uri"]), os.path.join(outdir, b["uri"]))
    with open(os.path.join(outdir, name), "w") as f:
        json.dump(g, f, indent=1)


if __name__ == "__main__":
    args = sys.argv[1:]
    room_flag = args[:1] == ["--validation-room"]
    if len(args) != 1 + room_flag:
        sys.exit("usage: glossy_room.py [--validation-room] OUTDIR")
    main(args[-1], room_flag)
