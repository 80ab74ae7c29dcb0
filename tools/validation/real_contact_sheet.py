#!/usr/bin/python3
"""Bakes, relights and renders every real scene of a folder, and joins the frames in a sheet.

    /usr/bin/python3 tools/validation/real_contact_sheet.py REAL_DIR HDRI OUT_DIR [--samples N]

REAL_DIR holds the real scenes of SCENES below, each in its own folder (zdm2/zdm2.glb, ...;
not in the repository, and tests never read it). Each scene goes through prt bake --probes,
prt relight, prt render and prt info with default options but --samples (speed), then is
rendered under HDRI with --background sky.
Cameras: an object, an open scene or a sealed map (no distant light inside) gets the default
orbit (its framing box, prt render), a closed map with openings a camera inside it, at the valid probe of the baked grid that sees least sky among
the most open ones (largest mean hit depth), looking along the level. Writes OUT_DIR/NAME.png,
OUT_DIR/NAME.txt (the commands' summaries) and OUT_DIR/sheet.png (ImageMagick's montage).
"""
import argparse
import os
import subprocess
import sys
import time

import numpy as np
import pyopenvdb as vdb

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
PRT = os.path.join(ROOT, "build", "tools", "prt")

# name, file, closed map (camera inside), probe spacing (scene units), exposure
SCENES = [
    ("zdm2", "zdm2/zdm2.glb", True, 1.0, 3.0),
    ("pandora", "pandora/pandora.glb", True, 1.0, 3.0),
    # Sealed: no distant light reaches inside (black, which is right), so seen from outside.
    ("cyanide", "cyanide/cyanide.gltf", False, 2.0, 0.0),
    ("cyanide_meshopt", "cyanide_meshopt/cyanide_meshopt.gltf", False, 2.0, 0.0),
    ("truck_town", "truck_town/town_model.gltf", False, 0.0, 0.0),
    ("engine_draco", "engine_draco/2CylinderEngine.gltf", False, 0.0, 0.0),
    ("dutch_ship", "dutch_ship/dutch_ship_medium_1k.gltf", False, 1.0, 0.0),
]


def run(args, log):
    t0 = time.time()
    r = subprocess.run(args, capture_output=True, text=True)
    log.write("$ " + " ".join(args) + f"\n{r.stdout}{r.stderr}({time.time() - t0:.1f} s, exit {r.returncode})\n\n")
    if r.returncode != 0:
        sys.exit(f"{args[1]} failed on {args[2]}: {r.stderr.strip().splitlines()[-1]}")
    return r


def inside_camera(vdb_path):
    """A point inside a closed map: the valid probe seeing least sky among the most open."""
    grids = {g.name: g for g in vdb.readAllGridMetadata(vdb_path)}
    meta = grids["validity"]
    sky = vdb.read(vdb_path, "sky_visibility")
    val = vdb.read(vdb_path, "validity")
    mom = vdb.read(vdb_path, "moments_mean_pos")
    off = vdb.read(vdb_path, "offset")
    best = None
    for leaf in val.citerOnValues():
        if leaf["value"] < 0.5 or not leaf["active"]:
            continue
        ijk = leaf["min"]
        s = sky.getConstAccessor().getValue(ijk)
        m = mom.getConstAccessor().getValue(ijk)
        open_ = min(m)  # the most closed of the +x, +y, +z directions: room to look around
        key = (s > 0.02, -open_)
        if best is None or key < best[0]:
            best = (key, ijk)
    ijk = best[1]
    xform = val.transform
    p = xform.indexToWorld(ijk)
    o = off.getConstAccessor().getValue(ijk)
    return [p[0] + o[0], p[1] + o[1], p[2] + o[2]]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("real")
    ap.add_argument("hdri")
    ap.add_argument("out")
    ap.add_argument("--samples", type=int, default=256)
    ap.add_argument("--only", nargs="*", default=None, help="bake only these (the sheet takes every NAME.png)")
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    tiles = []
    for name, rel, closed, spacing, exposure in SCENES:
        src = os.path.join(a.real, rel)
        base = os.path.join(a.out, name)
        tiles.append((base + ".png", name))
        if a.only is not None and name not in a.only:
            continue
        with open(base + ".txt", "w") as log:
            bake = [PRT, "bake", src, "-o", base + ".glb", "--samples", str(a.samples), "--probes", base + ".vdb"]
            if spacing:
                bake += ["--probe-spacing", str(spacing)]
            run(bake, log)
            run([PRT, "relight", base + ".glb", "--env", a.hdri, "-o", base + "_lit.glb"], log)
            render = [PRT, "render", base + ".glb", "--env", a.hdri, "--background", "sky", "--probes", base + ".vdb",
                      "--size", "480x270", "--msaa", "4", "--png", "--exposure", str(exposure), "-o", base + ".exr"]
            if closed:
                c = inside_camera(base + ".vdb")
                render += ["--orbit-target", ",".join(f"{x:.3f}" for x in c), "--orbit-distance", "0.01",
                           "--orbit-elevation", "-10", "--orbit-fov", "80"]
            else:
                render += ["--orbit-elevation", "25", "--orbit-azimuth", "35"]
            run(render, log)
            run([PRT, "info", base + ".glb", base + ".vdb"], log)
    args = ["montage"]
    for png, name in tiles:
        args += ["-label", name, png]
    args += ["-tile", "4x", "-geometry", "+4+4", "-background", "#202020", "-fill", "white",
             os.path.join(a.out, "sheet.png")]
    subprocess.run(args, check=True)
    print(os.path.join(a.out, "sheet.png"))


if __name__ == "__main__":
    main()
