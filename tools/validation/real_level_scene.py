#!/usr/bin/python3
"""A real level made comparable with Cycles (docs/validation.md, "Real levels"; issue 43).

    /usr/bin/python3 tools/validation/real_level_scene.py SCENE.gltf|SCENE.glb OUT.gltf \
        --eye X,Y,Z --target X,Y,Z [--yfov DEG] [--albedo A] [--aspect W/H]

Writes OUT.gltf (and its buffers beside it, OUT_N.bin) from the level's geometry as it is (nodes,
transforms, meshes, normals, UVs) with:
- every material replaced by one grey Lambertian material: baseColorFactor A (default 0.8), no
  texture, metallic 0, roughness 1, doubleSided (Cycles shades both sides of every face alike);
  primitives without a material get it too; textures, images and samplers are dropped, and so
  are extensions the level declares (EXT_texture_webp, physics), none of which changes geometry;
- one more root node `Camera`: a perspective camera at EYE looking at TARGET (+Y up), vertical
  field of view DEG (default 60), aspect W/H (default 16/9).
Compressed geometry (Draco, meshopt) is refused: Blender 3.4's importer reads neither.
"""
import argparse
import json
import math
import os
import struct
import sys
import urllib.parse

GEOMETRY_EXTENSIONS = ("KHR_draco_mesh_compression", "EXT_meshopt_compression", "KHR_mesh_quantization")


def fail(message):
    sys.exit(f"real_level_scene.py: {message}")


def load(path):
    """(glTF JSON, [buffer bytes])."""
    data = open(path, "rb").read()
    if data[:4] == b"glTF":
        n = struct.unpack_from("<I", data, 12)[0]
        gltf = json.loads(data[20:20 + n])
        pos = 20 + n
        bins = []
        while pos + 8 <= len(data):
            size, kind = struct.unpack_from("<II", data, pos)
            if kind == 0x004E4942:  # BIN
                bins.append(data[pos + 8:pos + 8 + size])
            pos += 8 + size
        buffers = []
        for b in gltf.get("buffers", []):
            buffers.append(bins.pop(0) if "uri" not in b else read_uri(path, b["uri"]))
        return gltf, buffers
    gltf = json.loads(data)
    return gltf, [read_uri(path, b["uri"]) for b in gltf.get("buffers", [])]


def read_uri(scene, uri):
    if uri.startswith("data:"):
        fail(f"{scene}: data URIs are not read here")
    return open(os.path.join(os.path.dirname(scene), urllib.parse.unquote(uri)), "rb").read()


def look_at_quaternion(eye, target):
    """Rotation (x, y, z, w) taking the camera's -Z to TARGET - EYE with +Y up."""
    f = [t - e for t, e in zip(target, eye)]
    n = math.sqrt(sum(v * v for v in f))
    f = [v / n for v in f]
    r = [-f[2], 0.0, f[0]]  # f x (0, 1, 0)
    n = math.sqrt(sum(v * v for v in r))
    if n < 1e-6:
        fail("--eye and --target must not be vertically aligned")
    r = [v / n for v in r]
    u = [r[1] * f[2] - r[2] * f[1], r[2] * f[0] - r[0] * f[2], r[0] * f[1] - r[1] * f[0]]
    m = [[r[0], u[0], -f[0]], [r[1], u[1], -f[1]], [r[2], u[2], -f[2]]]  # columns: X, Y, Z
    tr = m[0][0] + m[1][1] + m[2][2]
    if tr > 0:
        s = 2 * math.sqrt(1 + tr)
        return [(m[2][1] - m[1][2]) / s, (m[0][2] - m[2][0]) / s, (m[1][0] - m[0][1]) / s, s / 4]
    i = max(range(3), key=lambda k: m[k][k])
    j, k = (i + 1) % 3, (i + 2) % 3
    s = 2 * math.sqrt(1 + m[i][i] - m[j][j] - m[k][k])
    q = [0.0] * 4
    q[i] = s / 4
    q[j] = (m[j][i] + m[i][j]) / s
    q[k] = (m[k][i] + m[i][k]) / s
    q[3] = (m[k][j] - m[j][k]) / s
    return q


def vec3(text, option):
    try:
        v = [float(x) for x in text.split(",")]
    except ValueError:
        v = []
    if len(v) != 3:
        fail(f"{option} {text}: expected X,Y,Z")
    return v


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("scene")
    ap.add_argument("out")
    ap.add_argument("--eye", required=True)
    ap.add_argument("--target", required=True)
    ap.add_argument("--yfov", type=float, default=60.0, help="vertical field of view, degrees")
    ap.add_argument("--aspect", type=float, default=16 / 9)
    ap.add_argument("--albedo", type=float, default=0.8)
    a = ap.parse_args()
    gltf, buffers = load(a.scene)
    used = set(gltf.get("extensionsUsed", [])) | set(gltf.get("extensionsRequired", []))
    if used & set(GEOMETRY_EXTENSIONS):
        fail(f"{a.scene}: compressed geometry ({', '.join(sorted(used & set(GEOMETRY_EXTENSIONS)))}) is not read here")
    for key in ("textures", "images", "samplers", "extensionsUsed", "extensionsRequired", "extensions", "animations",
                "skins"):
        gltf.pop(key, None)
    gltf["materials"] = [{"name": "grey", "doubleSided": True, "pbrMetallicRoughness": {
        "baseColorFactor": [a.albedo, a.albedo, a.albedo, 1.0], "metallicFactor": 0.0, "roughnessFactor": 1.0}}]
    for mesh in gltf.get("meshes", []):
        for prim in mesh["primitives"]:
            prim["material"] = 0
            prim.pop("extensions", None)
    for node in gltf.get("nodes", []):
        node.pop("extensions", None)
        node.pop("camera", None)
    base = os.path.splitext(a.out)[0]
    os.makedirs(os.path.dirname(os.path.abspath(a.out)), exist_ok=True)
    for i, data in enumerate(buffers):
        name = f"{os.path.basename(base)}_{i}.bin"
        with open(os.path.join(os.path.dirname(os.path.abspath(a.out)), name), "wb") as f:
            f.write(data)
        gltf["buffers"][i] = {"uri": name, "byteLength": len(data)}
    gltf["cameras"] = [{"type": "perspective", "perspective": {
        "yfov": math.radians(a.yfov), "aspectRatio": a.aspect, "znear": 0.05, "zfar": 5000.0}}]
    eye, target = vec3(a.eye, "--eye"), vec3(a.target, "--target")
    gltf["nodes"].append({"name": "Camera", "camera": 0, "translation": eye,
                          "rotation": look_at_quaternion(eye, target)})
    scene = gltf["scenes"][gltf.get("scene", 0)]
    scene["nodes"].append(len(gltf["nodes"]) - 1)
    with open(a.out + ".tmp", "w") as f:
        json.dump(gltf, f)
    os.replace(a.out + ".tmp", a.out)
    print(f"wrote {a.out}")


if __name__ == "__main__":
    main()
