#!/usr/bin/python3
"""Bakes, relights and renders every real scene of a folder, and joins the frames in a sheet.

    /usr/bin/python3 tools/validation/real_contact_sheet.py REAL_DIR HDRI OUT_DIR [--samples N]
    /usr/bin/python3 tools/validation/real_contact_sheet.py --lamps REAL_DIR OUT_DIR [--samples N] [--frames A-B]
    /usr/bin/python3 tools/validation/real_contact_sheet.py --place-lamps PROBES.vdb
    /usr/bin/python3 tools/validation/real_contact_sheet.py REAL_DIR HDRI OUT_DIR --materials [--only NAME...]

REAL_DIR holds the real scenes of SCENES below, each in its own folder (zdm2/zdm2.glb, ...;
not in the repository, and tests never read it). Each scene goes through prt bake --probes,
prt relight, prt render and prt info with default options but --samples (speed), then is
rendered under HDRI with --background sky.
Cameras: an object, an open scene or a sealed map (no distant light inside) gets the default
orbit (its framing box, prt render), a closed map with openings a camera inside it, at the valid probe of the baked grid that sees least sky among
the most open ones (largest mean hit depth), looking along the level. Writes OUT_DIR/NAME.png,
OUT_DIR/NAME.txt (the commands' summaries) and OUT_DIR/sheet.png (ImageMagick's montage).

--lamps: the closed maps of LAMP_SCENES lit from inside by their rigs of lamps
(scenes/rigs/lamps_NAME.json: point, spot and area lights, one point light moving), no sky: each
is baked with prt bake's defaults (the lamps' bounces go through its bounce operator), rendered frame by
frame from the camera inside of LAMP_SCENES, and the frames of all maps joined in
OUT_DIR/lamps_sheet.png, a row per map. --materials: each scene also rendered with --materials
diffuse (NAME_diffuse.png) beside the full material (NAME.png, the default), the pairs joined in
OUT_DIR/materials_sheet.png, a row per scene (--only picks them). --place-lamps: how those rigs and cameras were found,
from a probe grid baked with the map (prt bake --probes): prints a rig and a camera (below).
"""
import argparse
import json
import os
import re
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

# --materials: closer views where the materials show (the town's from the real-level validation's
# camera at a house's corner, tools/validation/real_level_validation.sh, moved back).
MATERIAL_VIEWS = {
    "truck_town": ["--orbit-target", "16,10,-5", "--orbit-distance", "12", "--orbit-azimuth", "30",
                   "--orbit-elevation", "15", "--orbit-fov", "60"],
    "dutch_ship": ["--orbit-target", "1.5,3,0", "--orbit-distance", "20", "--orbit-azimuth", "55",
                   "--orbit-elevation", "12", "--orbit-fov", "50"],
}


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


# The closed maps lit by lamps (--lamps; their rigs scenes/rigs/lamps_NAME.json): name, file, camera
# position, the point it looks at, vertical field of view (degrees), exposure (stops). Rigs and
# cameras printed by --place-lamps for a probe grid baked at spacing 2 (docs/lights.md, "Lamps in
# the real maps"), but zdm2's spot, moving lamp and camera placed by hand; exposures set by eye.
LAMP_SCENES = [
    ("zdm2", "zdm2/zdm2.glb", (-17.28, -5.5, -16.49), (-3.28, -1.0, -6.49), 75, -4.5),
    ("pandora", "pandora/pandora.glb", (-51.0, 30.4, -5.0), (-45.0, 32.4, -15.0), 60, -5.0),
    ("cyanide", "cyanide/cyanide.gltf", (-38.0, 52.4, 88.0), (-28.0, 54.4, 84.0), 60, -4.0),
]


def interior_probes(vdb_path):
    """The valid probes that see no sky (inside the map): {ijk: (world position, depth to the ceiling)},
    and the grid's spacing."""
    val = vdb.read(vdb_path, "validity")
    sky = vdb.read(vdb_path, "sky_visibility").getConstAccessor()
    off = vdb.read(vdb_path, "offset").getConstAccessor()
    up = vdb.read(vdb_path, "moments_mean_pos").getConstAccessor()
    probes = {}
    for leaf in val.citerOnValues():
        ijk = tuple(leaf["min"])
        if leaf["value"] < 0.5 or not leaf["active"] or sky.getValue(ijk) >= 0.02:
            continue
        p = np.array(val.transform.indexToWorld(ijk)) + np.array(off.getValue(ijk))
        probes[ijk] = (p, up.getValue(ijk)[1])
    return probes, val.transform.voxelSize()[0]


def flood(probes, seed, keep):
    """The probes connected to `seed` through face neighbours for which keep(ijk) holds."""
    region, todo = {seed}, [seed]
    while todo:
        i, j, k = todo.pop()
        for n in ((i + 1, j, k), (i - 1, j, k), (i, j + 1, k), (i, j - 1, k), (i, j, k + 1), (i, j, k - 1)):
            if n in probes and n not in region and keep(n):
                region.add(n)
                todo.append(n)
    return region


def place_lamps(vdb_path, reach=5):
    """A rig of lamps and a camera in the map's largest hall, from its probe grid.

    The hall: the interior probe with the most interior probes within 2 cells, and the probes
    connected to it within `reach` cells across. Lamps hang halfway between the top probe of a column
    and the ceiling above it (the probe's mean depth along +Y): a point light over the hall's centre,
    a spot over the column farthest from it, a small sphere light over the column farthest from
    both (and from the camera); a point light moves across the camera's view along the straight run
    of probes through the centre. The camera stands a cell above the floor of the farthest column
    with open space around it, at most two cells below the centre column's middle, that sees the
    centre along probes; it looks at the centre a cell above its eye where there is room there
    (else at the middle), the height the moving lamp runs at. Intensities grow with the hall's
    size squared; the moving lamp is three times brighter."""
    probes, spacing = interior_probes(vdb_path)
    cells = set(probes)

    def room(t):
        return sum((t[0] + a, t[1] + b, t[2] + c) in cells for a in range(-2, 3) for b in range(-2, 3)
                   for c in range(-2, 3))

    hall = max(sorted(cells), key=room)
    region = flood(cells, hall, lambda t: max(abs(t[0] - hall[0]), abs(t[2] - hall[2])) <= reach)
    columns = {}
    for t in region:
        lo, hi = columns.get((t[0], t[2]), (t, t))
        columns[(t[0], t[2])] = (min(lo, t, key=lambda u: u[1]), max(hi, t, key=lambda u: u[1]))

    def lamp_at(col):
        p, depth = probes[columns[col][1]]
        return p + np.array([0.0, 0.5 * depth, 0.0])

    def across(a, b):
        return np.hypot(a[0] - b[0], a[1] - b[1])

    centre = (hall[0], hall[2])
    mid = (columns[centre][0][1] + columns[centre][1][1]) // 2
    if (hall[0], mid, hall[2]) not in region:  # a column with a gap
        mid = hall[1]
    target = probes[(hall[0], mid, hall[2])][0]

    def sees(a, b):
        return all(tuple(int(round(x)) for x in np.array(a) + s * (np.array(b) - np.array(a))) in cells
                   for s in np.linspace(0.0, 1.0, 16))

    def standing(c):  # a cell above the column's floor, with open space all around
        i, j, k = columns[c][0]
        j += 1
        if j < mid - 2:  # not far below the centre: a view along the hall, not up into it
            return None
        if any((i + a, j, k + b) not in cells for a in (-1, 0, 1) for b in (-1, 0, 1)):
            return None
        return (i, j, k) if sees((i, j, k), (hall[0], mid, hall[2])) else None

    eye = next((c for c in sorted(columns, key=lambda c: (-across(c, centre), c)) if standing(c)), centre)
    foot = standing(eye) or columns[eye][0]
    camera = probes[foot][0]
    # Look and move the lamp a cell above the eye, where the centre's column has room.
    level = foot[1] + 1
    if (hall[0], level, hall[2]) in region and sees(foot, (hall[0], level, hall[2])):
        mid = level
        target = probes[(hall[0], mid, hall[2])][0]
    # Lamps ahead of the camera: the spot at the far side, the globe away from all three.
    spot = max(sorted(columns), key=lambda c: across(c, eye))
    sphere = max(sorted(columns), key=lambda c: min(across(c, centre), across(c, spot), across(c, eye)))
    # The moving lamp crosses the view: along the axis farther from the camera's line of sight.
    axis = 0 if abs(eye[0] - centre[0]) < abs(eye[1] - centre[1]) else 2
    ends = []
    for sign in (-1, 1):
        t = [hall[0], mid, hall[2]]
        while tuple(t) in region:
            t[axis] += sign
        t[axis] -= 2 * sign  # one cell inside the last probe of the run
        ends.append(tuple(t) if tuple(t) in region else (hall[0], mid, hall[2]))
    size = max(across(c, centre) for c in columns) * spacing
    scale = 3.0 * max(size, 1.0) ** 2  # about irradiance 3 at the hall's edge
    r = lambda v: [round(float(x), 2) for x in v]
    rig = {"version": 1, "fps": 4, "lights": [
        {"type": "point", "name": "ceiling", "position": r(lamp_at(centre)), "intensity": r(scale * np.array([1.0, 0.85, 0.6]))},
        {"type": "spot", "name": "spot", "position": r(lamp_at(spot)), "direction": [0, -1, 0], "inner_cone": 25,
         "outer_cone": 50, "intensity": r(2 * scale * np.array([0.6, 0.8, 1.0]))},
        {"type": "area", "name": "globe", "shape": "sphere", "radius": 0.15, "position": r(lamp_at(sphere)),
         "power": r(4 * np.pi * scale * np.array([0.9, 1.0, 0.8]))},
        {"type": "point", "name": "moving", "intensity": r(3 * scale * np.array([1.0, 0.4, 0.1])),
         "position": [{"frame": 0, "value": r(probes[ends[0]][0])}, {"frame": 2, "value": r(probes[ends[1]][0])}]},
    ]}
    return rig, camera, target


def orbit_from(camera, target, fov):
    """prt render's orbit options that put the camera at `camera` looking at `target`."""
    d = np.array(camera) - np.array(target)
    r = float(np.linalg.norm(d))
    return ["--orbit-target", ",".join(f"{x:g}" for x in target), "--orbit-distance", f"{r:.4f}",
            "--orbit-azimuth", f"{np.degrees(np.arctan2(d[0], d[2])):.3f}",
            "--orbit-elevation", f"{np.degrees(np.arcsin(d[1] / r)):.3f}", "--orbit-fov", str(fov)]


def number(pattern, text):
    m = re.search(pattern, text)
    return float(m.group(1)) if m else float("nan")


def lamps(a):
    """--lamps: bake each closed map with its bounce operator, render its rig's frames from inside."""
    real, out = a.paths
    os.makedirs(out, exist_ok=True)
    first, last = (int(x) for x in (a.frames.split("-") + [a.frames])[:2])
    tiles, rows = [], []
    for name, rel, camera, target, fov, exposure in LAMP_SCENES:
        base = os.path.join(out, "lamps_" + name)
        rig = os.path.join(ROOT, "scenes", "rigs", f"lamps_{name}.json")
        tiles += [f"{base}_{f}.png" for f in range(first, last + 1)]
        if a.only is not None and name not in a.only:
            continue
        with open(base + ".txt", "w") as log:
            if not (a.keep_bakes and os.path.exists(base + ".glb")):
                t0 = time.time()
                baked = run([PRT, "bake", os.path.join(real, rel), "-o", base + ".glb", "--samples", str(a.samples)],
                            log)
                bake_s = time.time() - t0
            else:
                baked, bake_s = None, float("nan")
            r = run([PRT, "render", base + ".glb", "--rig", rig, "--frames", f"{first}-{last}", "--size", a.size,
                     "--msaa", "4", "--png", "--exposure", str(exposure), "-o", base + "_%d.exr"]
                    + orbit_from(camera, target, fov), log)
        text = r.stderr
        rows.append((name, number(r"([\d.]+) k vertices", baked.stderr) if baked else float("nan"), bake_s,
                     number(r"([\d.]+) ms per light update", text), number(r"shadow rays ([\d.]+),", text),
                     number(r"products ([\d.]+)\)", text), number(r"([\d.]+) ms/frame draw", text)))
    print("map        k vertices  bake s  light update ms (shadow rays, products)  draw ms/frame")
    for name, kv, bake_s, light, shadow, products, draw in rows:
        print(f"{name:10s} {kv:10.1f} {bake_s:7.1f}  {light:8.1f} ({shadow:.1f}, {products:.1f}){'':20s}{draw:8.1f}")
    # A row per map, a column per frame; no labels (montage then needs no font). 64 levels a
    # channel keep the sheet under 300 KB for the docs without visible banding.
    args = ["montage"] + tiles
    sheet = os.path.join(out, "lamps_sheet.png")
    args += ["-tile", f"{last - first + 1}x", "-geometry", "+2+2", "-background", "#202020", "-depth", "8", sheet]
    subprocess.run(args, check=True)
    subprocess.run(["convert", sheet, "-posterize", "64", "-strip", "-define", "png:exclude-chunk=date,time", sheet],
                   check=True)
    print(sheet)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("paths", nargs="+", help="REAL_DIR HDRI OUT_DIR; with --lamps REAL_DIR OUT_DIR; with --place-lamps a .vdb")
    ap.add_argument("--samples", type=int, default=256)
    ap.add_argument("--only", nargs="*", default=None, help="bake only these (the sheet takes every NAME.png)")
    ap.add_argument("--lamps", action="store_true", help="the closed maps lit by their rigs of lamps")
    ap.add_argument("--frames", default="0-2", help="--lamps: the frames rendered, A-B")
    ap.add_argument("--size", default="240x135", help="--lamps: the frames' size")
    ap.add_argument("--keep-bakes", action="store_true", help="--lamps: reuse OUT_DIR/lamps_NAME.glb where it exists")
    ap.add_argument("--materials", action="store_true", help="also render --materials diffuse; pairs in materials_sheet.png")
    ap.add_argument("--place-lamps", action="store_true", help="print a rig of lamps and a camera for a probe grid")
    a = ap.parse_args()
    if a.place_lamps:
        rig, camera, target = place_lamps(a.paths[0])
        print(json.dumps(rig, indent=2))
        print("camera", [round(float(x), 2) for x in camera], "looking at", [round(float(x), 2) for x in target])
        return
    if a.lamps:
        lamps(a)
        return
    a.real, a.hdri, a.out = a.paths
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
            # --materials: supersampled, not multisampled, so that the screen-space reflections run
            aa = ["--supersample", "2"] if a.materials else ["--msaa", "4"]
            render = [PRT, "render", base + ".glb", "--env", a.hdri, "--background", "sky", "--probes", base + ".vdb",
                      "--size", "480x270", *aa, "--png", "--exposure", str(exposure), "-o", base + ".exr"]
            if a.materials and name in MATERIAL_VIEWS:
                render += MATERIAL_VIEWS[name]
            elif closed:
                c = inside_camera(base + ".vdb")
                render += ["--orbit-target", ",".join(f"{x:.3f}" for x in c), "--orbit-distance", "0.01",
                           "--orbit-elevation", "-10", "--orbit-fov", "80"]
            else:
                render += ["--orbit-elevation", "25", "--orbit-azimuth", "35"]
            run(render, log)
            if a.materials:
                diffuse = [x if x != base + ".exr" else base + "_diffuse.exr" for x in render]
                run(diffuse + ["--materials", "diffuse"], log)
            run([PRT, "info", base + ".glb", base + ".vdb"], log)
    args = ["montage"]
    for png, name in tiles:
        if a.materials and (a.only is None or name in a.only):
            args += ["-label", name + ": --materials full", png, "-label", name + ": --materials diffuse",
                     png.replace(".png", "_diffuse.png")]
        elif not a.materials:
            args += ["-label", name, png]
    sheet = os.path.join(a.out, "materials_sheet.png" if a.materials else "sheet.png")
    args += ["-tile", "2x" if a.materials else "4x", "-geometry", "+4+4", "-background", "#202020", "-fill", "white",
             sheet]
    subprocess.run(args, check=True)
    print(sheet)


if __name__ == "__main__":
    main()
