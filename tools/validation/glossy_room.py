#!/usr/bin/env python3
"""Writes the bundled room with issue 42's materials (docs/render.md, "Materials"):

    python3 tools/validation/glossy_room.py OUTDIR      # writes OUTDIR/cornell_glossy.gltf (+ .bin)

scenes/cornell_open.gltf with its floor a glossy dielectric (roughness 0.35) and its short box
copper (metallic 1, roughness 0.4, base colour (0.95, 0.64, 0.54)); the geometry is the bundled
room's own buffer, copied next to it. Standard library only, deterministic.
"""

import json
import os
import shutil
import sys

SCENES = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "scenes")


def main(outdir):
    with open(os.path.join(SCENES, "cornell_open.gltf")) as f:
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
        shutil.copyfile(os.path.join(SCENES, b["uri"]), os.path.join(outdir, b["uri"]))
    with open(os.path.join(outdir, "cornell_glossy.gltf"), "w") as f:
        json.dump(g, f, indent=1)


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: glossy_room.py OUTDIR")
    main(sys.argv[1])
