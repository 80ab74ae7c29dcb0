#!/usr/bin/env python3
"""Checks the bundled glTF scenes against what prt and glTF 2.0 expect.

    python3 scenes/check_scenes.py [FILE.gltf ...]    # default: every scenes/*.gltf

Per file: the buffer's byteLength, bufferViews inside the buffer and 4-byte aligned,
accessors inside their views, POSITION min/max equal to the data, indices in range and
UNSIGNED_SHORT / UNSIGNED_INT, triangle lists only, no degenerate triangles, unit NORMALs,
materials with a linear baseColorFactor, receivers flagged in node extras. Standard library
only; exits 1 on the first problem in a file (and goes on with the next file).
"""

import glob
import json
import math
import os
import struct
import sys

COMPONENT = {5120: ("b", 1), 5121: ("B", 1), 5122: ("h", 2), 5123: ("H", 2),
             5125: ("I", 4), 5126: ("f", 4)}
WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}


class Bad(Exception):
    pass


def expect(cond, what):
    if not cond:
        raise Bad(what)


def read_accessor(gltf, buf, index):
    acc = gltf["accessors"][index]
    view = gltf["bufferViews"][acc["bufferView"]]
    fmt, size = COMPONENT[acc["componentType"]]
    width = WIDTH[acc["type"]]
    stride = view.get("byteStride", size * width)
    start = view.get("byteOffset", 0) + acc.get("byteOffset", 0)
    end = start + stride * (acc["count"] - 1) + size * width
    where = "accessor %d" % index
    expect((view.get("byteOffset", 0) + acc.get("byteOffset", 0)) % size == 0, where + ": misaligned")
    expect(end <= view.get("byteOffset", 0) + view["byteLength"], where + ": runs past its bufferView")
    out = []
    for i in range(acc["count"]):
        out.append(struct.unpack_from("<%d%s" % (width, fmt), buf, start + i * stride))
    return acc, out


def check(path):
    with open(path, encoding="utf-8") as f:
        gltf = json.load(f)
    expect(gltf["asset"]["version"] == "2.0", "asset.version is not 2.0")
    expect(not gltf.get("extensionsRequired"), "extensionsRequired is not empty")
    expect(len(gltf["buffers"]) == 1, "expected exactly one buffer")
    b = gltf["buffers"][0]
    with open(os.path.join(os.path.dirname(path), b["uri"]), "rb") as f:
        buf = f.read()
    expect(len(buf) == b["byteLength"], "buffer byteLength %d, file has %d" % (b["byteLength"], len(buf)))
    expect(len(buf) % 4 == 0, "buffer length is not a multiple of 4")
    for i, v in enumerate(gltf["bufferViews"]):
        expect(v.get("byteOffset", 0) % 4 == 0, "bufferView %d not 4-byte aligned" % i)
        expect(v.get("byteOffset", 0) + v["byteLength"] <= len(buf), "bufferView %d past the buffer" % i)

    for i, m in enumerate(gltf["materials"]):
        c = m["pbrMetallicRoughness"]["baseColorFactor"]
        expect(len(c) == 4 and all(0 <= x <= 1 for x in c), "material %d: bad baseColorFactor" % i)

    verts = tris = 0
    for mi, mesh in enumerate(gltf["meshes"]):
        for pi, prim in enumerate(mesh["primitives"]):
            where = "mesh %d (%s) / primitive %d" % (mi, mesh.get("name", ""), pi)
            expect(prim.get("mode", 4) == 4, where + ": not a triangle list")
            expect("material" in prim, where + ": no material")
            attrs = prim["attributes"]
            expect("POSITION" in attrs and "NORMAL" in attrs, where + ": needs POSITION and NORMAL")
            pacc, pos = read_accessor(gltf, buf, attrs["POSITION"])
            expect(pacc["componentType"] == 5126 and pacc["type"] == "VEC3", where + ": POSITION type")
            for k in range(3):
                lo, hi = min(p[k] for p in pos), max(p[k] for p in pos)
                expect(pacc["min"][k] == lo and pacc["max"][k] == hi,
                       where + ": POSITION min/max differ from the data")
                expect(all(math.isfinite(p[k]) for p in pos), where + ": non-finite position")
            nacc, nrm = read_accessor(gltf, buf, attrs["NORMAL"])
            expect(nacc["count"] == pacc["count"], where + ": NORMAL count differs from POSITION")
            worst = max(abs(math.sqrt(n[0] ** 2 + n[1] ** 2 + n[2] ** 2) - 1) for n in nrm)
            expect(worst < 1e-5, where + ": NORMAL not unit length (off by %g)" % worst)
            iacc, idx = read_accessor(gltf, buf, prim["indices"])
            expect(iacc["componentType"] in (5123, 5125), where + ": indices not UNSIGNED_SHORT/INT")
            expect(iacc["count"] % 3 == 0, where + ": index count not a multiple of 3")
            idx = [i[0] for i in idx]
            expect(max(idx) < len(pos), where + ": index out of range")
            expect(len(set(idx)) == len(pos), where + ": unused vertices")
            for t in range(0, len(idx), 3):
                a, b_, c = (pos[idx[t + k]] for k in range(3))
                u = [b_[k] - a[k] for k in range(3)]
                v = [c[k] - a[k] for k in range(3)]
                g = (u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0])
                area2 = math.sqrt(sum(x * x for x in g))
                expect(area2 > 1e-10, where + ": degenerate triangle %d" % (t // 3))
                # Front faces (counter-clockwise) must agree with the vertex normals.
                for k in range(3):
                    n = nrm[idx[t + k]]
                    expect(sum(g[j] * n[j] for j in range(3)) > 0.5 * area2,
                           where + ": triangle %d wound against its normals" % (t // 3))
            verts += len(pos)
            tris += len(idx) // 3

    receivers = [n["name"] for n in gltf["nodes"] if n.get("extras", {}).get("prt", {}).get("receiver")]
    size = os.path.getsize(path) + len(buf)
    print("ok  %-20s %6d vertices %6d triangles %8d bytes%s"
          % (os.path.basename(path), verts, tris, size,
             "  receivers: " + ", ".join(receivers) if receivers else ""))


def main():
    paths = sys.argv[1:] or sorted(glob.glob(os.path.join(os.path.dirname(os.path.abspath(__file__)), "*.gltf")))
    failed = False
    for p in paths:
        try:
            check(p)
        except (Bad, KeyError, ValueError, OSError, struct.error) as e:
            print("BAD %s: %s" % (p, e))
            failed = True
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
