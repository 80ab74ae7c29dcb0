#!/usr/bin/env python3
"""Derives scenes/real/dutch_ship/ from Poly Haven's "Dutch Ship (medium)", 1k glTF (CC0).

    python3 scenes/make_real.py SRC_FOLDER    # the folder holding dutch_ship_medium_1k.gltf

What changes: the glTF keeps its geometry (dutch_ship_medium.bin, as is), its three materials
(double-sided; the sails alphaMode MASK) and their base colour textures, downscaled to 512 px
JPEG (ImageMagick's `convert`); the normal and ARM (occlusion, roughness, metalness) textures,
which prt does not read, are left out. Asset metadata says where it came from. Needs
ImageMagick (`apt-get install imagemagick`) for the textures.
"""
import json
import os
import shutil
import subprocess
import sys

OUT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "real", "dutch_ship")


def main():
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    src = sys.argv[1]
    with open(os.path.join(src, "dutch_ship_medium_1k.gltf")) as f:
        g = json.load(f)
    os.makedirs(os.path.join(OUT, "textures"), exist_ok=True)
    keep_images = []
    for m in g["materials"]:
        m.pop("normalTexture", None)
        # Without its ARM texture a material's metalness is metallicFactor alone, whose glTF
        # default is 1: the wood and rope would turn to metal. They are dielectrics.
        if m["pbrMetallicRoughness"].pop("metallicRoughnessTexture", None) is not None:
            m["pbrMetallicRoughness"]["metallicFactor"] = 0
        keep_images.append(g["textures"][m["pbrMetallicRoughness"]["baseColorTexture"]["index"]]["source"])
    images, textures = [], []
    for m in g["materials"]:
        t = g["textures"][m["pbrMetallicRoughness"]["baseColorTexture"]["index"]]
        img = dict(g["images"][t["source"]])
        name = os.path.basename(img["uri"]).replace("_1k.jpg", "_512.jpg")
        subprocess.run(["convert", os.path.join(src, img["uri"]), "-resize", "512x512", "-quality", "88",
                        "-strip", os.path.join(OUT, "textures", name)], check=True)
        img["uri"] = "textures/" + name
        images.append(img)
        textures.append({"sampler": t["sampler"], "source": len(images) - 1})
        m["pbrMetallicRoughness"]["baseColorTexture"] = {"index": len(textures) - 1}
    g["images"], g["textures"] = images, textures
    g["asset"]["copyright"] = "Poly Haven, Dutch Ship (medium), CC0 1.0"
    g["asset"]["extras"] = {"derived": "scenes/make_real.py: base colour textures at 512 px, others dropped"}
    with open(os.path.join(OUT, "dutch_ship.gltf"), "w") as f:
        json.dump(g, f, indent=1)
        f.write("\n")
    shutil.copyfile(os.path.join(src, "dutch_ship_medium.bin"), os.path.join(OUT, "dutch_ship_medium.bin"))


if __name__ == "__main__":
    main()
