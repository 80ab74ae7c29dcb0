#!/usr/bin/env python3
"""Writes the small seed corpora of the glTF, image and rig fuzz targets (tests/fuzz/corpus/).

Each seed is a valid file that exercises one feature of its loader; the fuzzer mutates from
there. Run from anywhere: python3 tests/fuzz/make_corpus.py. The VDB seeds come from
`prt bake` (docs/robustness.md), not from here.
"""
import base64
import json
import os
import struct
import zlib

HERE = os.path.dirname(os.path.abspath(__file__))


def out(target, name, data):
    path = os.path.join(HERE, "corpus", target, name)
    os.makedirs(os.path.dirname(path), exist_ok=True)
    with open(path, "wb") as f:
        f.write(data)


# ---- glTF -------------------------------------------------------------------------------
FLOAT, UBYTE, USHORT, UINT = 5126, 5121, 5123, 5125


class Gltf:
    def __init__(self):
        self.doc = {"asset": {"version": "2.0"}, "bufferViews": [], "accessors": []}
        self.bin = b""

    def accessor(self, data, ctype, count, typ, **extra):
        self.bin += b"\0" * (-len(self.bin) % 4)
        self.doc["bufferViews"].append({"buffer": 0, "byteOffset": len(self.bin), "byteLength": len(data)})
        self.bin += data
        a = {"bufferView": len(self.doc["bufferViews"]) - 1, "componentType": ctype, "count": count, "type": typ}
        a.update(extra)
        self.doc["accessors"].append(a)
        return len(self.doc["accessors"]) - 1

    def floats(self, values, typ, n):
        return self.accessor(struct.pack("<%df" % len(values), *values), FLOAT, len(values) // n, typ)

    def image(self, png):
        self.bin += b"\0" * (-len(self.bin) % 4)
        self.doc["bufferViews"].append({"buffer": 0, "byteOffset": len(self.bin), "byteLength": len(png)})
        self.bin += png
        self.doc.setdefault("images", []).append({"bufferView": len(self.doc["bufferViews"]) - 1, "mimeType": "image/png"})

    def gltf(self):
        d = dict(self.doc)
        d["buffers"] = [{"byteLength": len(self.bin),
                         "uri": "data:application/octet-stream;base64," + base64.b64encode(self.bin).decode()}]
        return json.dumps(d, separators=(",", ":")).encode()

    def glb(self):
        d = dict(self.doc)
        d["buffers"] = [{"byteLength": len(self.bin)}]
        js = json.dumps(d, separators=(",", ":")).encode()
        js += b" " * (-len(js) % 4)
        bn = self.bin + b"\0" * (-len(self.bin) % 4)
        total = 12 + 8 + len(js) + 8 + len(bn)
        return (b"glTF" + struct.pack("<II", 2, total) + struct.pack("<I", len(js)) + b"JSON" + js +
                struct.pack("<I", len(bn)) + b"BIN\0" + bn)


def png(w, h, rgba):
    raw = b"".join(b"\0" + bytes(rgba[y * w * 4:(y + 1) * w * 4]) for y in range(h))

    def chunk(t, d):
        return struct.pack(">I", len(d)) + t + d + struct.pack(">I", zlib.crc32(t + d) & 0xFFFFFFFF)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 6, 0, 0, 0)) +
            chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))


QUAD = [0, 0, 0, 1, 0, 0, 1, 0, 1, 0, 0, 1]


def triangle():
    g = Gltf()
    pos = g.floats([0, 0, 0, 1, 0, 0, 0, 1, 0], "VEC3", 3)
    g.doc.update(scene=0, scenes=[{"nodes": [0]}], nodes=[{"mesh": 0}],
                 meshes=[{"primitives": [{"attributes": {"POSITION": pos}}]}])
    return g


def textured():
    g = Gltf()
    pos = g.floats(QUAD, "VEC3", 3)
    nrm = g.floats([0, 1, 0] * 4, "VEC3", 3)
    uv = g.floats([0, 0, 1, 0, 1, 1, 0, 1], "VEC2", 2)
    col = g.accessor(bytes([255, 128, 0, 255] * 4), UBYTE, 4, "VEC4", normalized=True)
    idx = g.accessor(struct.pack("<6H", 0, 2, 1, 0, 3, 2), USHORT, 6, "SCALAR")
    g.image(png(2, 2, [255, 0, 0, 255, 0, 255, 0, 255, 0, 0, 255, 255, 255, 255, 255, 128]))
    g.doc.update(scene=0, scenes=[{"nodes": [0]}],
                 nodes=[{"mesh": 0, "translation": [1, 2, 3], "rotation": [0, 0.7071068, 0, 0.7071068],
                         "scale": [2, 2, 2]}],
                 samplers=[{"wrapS": 33071, "wrapT": 33648}], textures=[{"source": 0, "sampler": 0}],
                 materials=[{"pbrMetallicRoughness": {"baseColorFactor": [1, 1, 1, 1],
                                                      "baseColorTexture": {"index": 0}}, "doubleSided": True}],
                 meshes=[{"primitives": [{"attributes": {"POSITION": pos, "NORMAL": nrm, "TEXCOORD_0": uv,
                                                         "COLOR_0": col}, "indices": idx, "material": 0}]}])
    return g


def hierarchy():
    """Nested nodes (matrix and TRS), a shared mesh, a strip and a fan, a camera and lights."""
    g = Gltf()
    pos = g.floats(QUAD, "VEC3", 3)
    idx = g.accessor(struct.pack("<4B", 0, 1, 3, 2), UBYTE, 4, "SCALAR")
    g.doc.update(
        scene=0, scenes=[{"nodes": [0, 3]}],
        nodes=[{"children": [1, 2], "matrix": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 5, 0, 0, 1]},
               {"mesh": 0, "extras": {"prt": {"receiver": True}}},
               {"mesh": 1, "scale": [1, -1, 1]},
               {"camera": 0, "translation": [0, 1, 5],
                "extensions": {"KHR_lights_punctual": {"light": 0}}}],
        meshes=[{"primitives": [{"attributes": {"POSITION": pos}, "indices": idx, "mode": 5}]},
                {"primitives": [{"attributes": {"POSITION": pos}, "mode": 6},
                                {"attributes": {"POSITION": pos}, "mode": 1}]}],
        cameras=[{"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.1}}],
        extensionsUsed=["KHR_lights_punctual"],
        extensions={"KHR_lights_punctual": {"lights": [{"type": "spot", "color": [1, 1, 1], "intensity": 2,
                                                        "spot": {"innerConeAngle": 0.1, "outerConeAngle": 0.5}}]}})
    return g


# asset.extras.prt as prt bake writes it (docs/formats.md, "The bake record"): loadScene
# validates every key, so the seed carries a whole record for the fuzzer to mutate.
BAKE_RECORD = {"version": 1, "scene": "baked.gltf", "bands": 2, "samples": 16, "bounces": 1, "shadowed": True,
               "seed": 1, "transfer": "irradiance",
               "sh_convention": "real orthonormal, no Condon-Shortley phase, index l(l+1)+m, glTF axes",
               "units": "E = transfer . light (irradiance); L_o = albedo / pi * E", "prt_version": "0.1.0"}


def baked():
    """Per-vertex transfer attributes (_PRT_SH_00.._03, 2 bands) as prt bake writes them."""
    g = Gltf()
    pos = g.floats([0, 0, 0, 1, 0, 0, 0, 1, 0], "VEC3", 3)
    attrs = {"POSITION": pos}
    for i in range(4):
        attrs["_PRT_SH_%02d" % i] = g.floats([0.1 * (i + 1)] * 9, "VEC3", 3)
    g.doc.update(scene=0, scenes=[{"nodes": [0]}], nodes=[{"mesh": 0}],
                 meshes=[{"primitives": [{"attributes": attrs}]}], asset={"version": "2.0", "extras": {"prt": BAKE_RECORD}})
    return g


out("gltf", "triangle.gltf", triangle().gltf())
out("gltf", "triangle.glb", triangle().glb())
out("gltf", "textured.glb", textured().glb())
out("gltf", "hierarchy.gltf", hierarchy().gltf())
out("gltf", "baked.glb", baked().glb())

# ---- Radiance .hdr ----------------------------------------------------------------------


def rgbe(r, g, b):
    import math
    m = max(r, g, b)
    if m < 1e-32:
        return bytes(4)
    mant, e = math.frexp(m)
    s = mant * 256.0 / m
    return bytes([int(r * s), int(g * s), int(b * s), e + 128])


def hdr_flat(w, h):
    head = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y %d +X %d\n" % (h, w)
    return head + b"".join(rgbe(x / w, y / h, 0.5) for y in range(h) for x in range(w))


def hdr_rle(w, h):
    head = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y %d +X %d\n" % (h, w)
    body = b""
    for y in range(h):
        px = [rgbe(x / w, y / h, 0.5) for x in range(w)]
        body += bytes([2, 2, w >> 8, w & 255])
        for c in range(4):
            vals = bytes(p[c] for p in px)
            half = w // 2  # one literal run, then one repeat run: both encodings appear
            body += bytes([half]) + vals[:half] + bytes([128 + (w - half), vals[-1]])
    return head + body


out("image", "flat.hdr", hdr_flat(4, 3))
out("image", "rle.hdr", hdr_rle(16, 2))

# ---- OpenEXR (scan lines; none, RLE and ZIP compression) --------------------------------
HALF, FLOAT_T = 1, 2


def exr(w, h, channels, compression, pixel):
    """channels: [(name, type)]; pixel(x, y, c) -> float."""
    def attr(name, typ, data):
        return name.encode() + b"\0" + typ.encode() + b"\0" + struct.pack("<i", len(data)) + data
    chl = b"".join(n.encode() + b"\0" + struct.pack("<iB3xii", t, 0, 1, 1) for n, t in sorted(channels)) + b"\0"
    box = struct.pack("<4i", 0, 0, w - 1, h - 1)
    header = (attr("channels", "chlist", chl) + attr("compression", "compression", bytes([compression])) +
              attr("dataWindow", "box2i", box) + attr("displayWindow", "box2i", box) +
              attr("lineOrder", "lineOrder", b"\0") + attr("pixelAspectRatio", "float", struct.pack("<f", 1)) +
              attr("screenWindowCenter", "v2f", struct.pack("<2f", 0, 0)) +
              attr("screenWindowWidth", "float", struct.pack("<f", 1)) + b"\0")
    lines_per_chunk = {0: 1, 1: 1, 3: 16}[compression]
    chunks = []
    for y0 in range(0, h, lines_per_chunk):
        raw = b""
        for y in range(y0, min(h, y0 + lines_per_chunk)):
            for n, t in sorted(channels):
                c = "RGBY".index(n) if n in "RGBY" else 0
                vals = [pixel(x, y, c) for x in range(w)]
                raw += struct.pack("<%de" % w, *vals) if t == HALF else struct.pack("<%df" % w, *vals)
        if compression in (1, 3):  # both predict and interleave the bytes first
            inter = raw[0::2] + raw[1::2]
            pred = bytearray(inter)
            for i in range(len(pred) - 1, 0, -1):
                pred[i] = (inter[i] - inter[i - 1] + 128 + 256) & 255
            data = zlib.compress(bytes(pred)) if compression == 3 else rle(bytes(pred))
        else:
            data = raw
        chunks.append(struct.pack("<ii", y0, len(data)) + data)
    start = 8 + len(header) + 8 * len(chunks)
    offsets, pos = [], start
    for c in chunks:
        offsets.append(pos)
        pos += len(c)
    return (bytes([0x76, 0x2F, 0x31, 0x01]) + struct.pack("<I", 2) + header +
            struct.pack("<%dQ" % len(offsets), *offsets) + b"".join(chunks))


def rle(data):
    """OpenEXR's RLE: runs of 3+ equal bytes as (count-1, byte), else (-count, bytes...)."""
    out_, i = bytearray(), 0
    while i < len(data):
        j = i
        while j < len(data) and data[j] == data[i] and j - i < 127:
            j += 1
        if j - i >= 3:
            out_ += bytes([j - i - 1, data[i]])
            i = j
        else:
            j = i
            while j < len(data) and j - i < 127 and not (j + 2 < len(data) and data[j] == data[j + 1] == data[j + 2]):
                j += 1
            out_ += bytes([(256 - (j - i)) & 255]) + data[i:j]
            i = j
    return bytes(out_)


ramp = lambda x, y, c: 0.25 * x + 0.5 * y + 0.125 * c
rgb_f = [("R", FLOAT_T), ("G", FLOAT_T), ("B", FLOAT_T)]
rgb_h = [("R", HALF), ("G", HALF), ("B", HALF)]
out("image", "none_float.exr", exr(4, 3, rgb_f, 0, ramp))
out("image", "rle_half.exr", exr(8, 4, rgb_h, 1, ramp))
out("image", "zip_float.exr", exr(5, 17, rgb_f, 3, ramp))
out("image", "luminance_half.exr", exr(3, 2, [("Y", HALF)], 0, ramp))


# ---- Light rigs (JSON, docs/lights.md) ---------------------------------------------------
# The bundled rigs, with their maps renamed to the maps fuzz_rig holds in memory, plus one
# seed per feature the bundled ones miss. Written compact: the fuzzer mutates fewer bytes.
def rig_seed(name, doc):
    out("rig", name, json.dumps(doc, separators=(",", ":")).encode())


ROOT = os.path.dirname(os.path.dirname(HERE))
for f in sorted(os.listdir(os.path.join(ROOT, "scenes", "rigs"))):
    with open(os.path.join(ROOT, "scenes", "rigs", f)) as fh:
        doc = json.load(fh)
    doc.pop("description", None)
    for light in doc["lights"]:
        if light["type"] == "environment":
            light["file"] = "sky.hdr"
    rig_seed(f, doc)

keys = lambda *kv: [{"frame": f, "value": v} for f, v in kv]
rig_seed("hot_map_turning.json", {"version": 1, "lights": [
    {"type": "environment", "file": "hot.exr", "axis": keys((0, [1, 0, 0]), (5, [0, 0, 1])),
     "rotation": keys((0, 0), (10, 1e6))},
    {"type": "environment", "file": "one.exr", "intensity": {"interpolation": "step", "keys": keys((0, 1), (2, [0, 3, 1]))}}]})
rig_seed("tiny_suns.json", {"version": 1, "fps": 0.001, "window": "hann", "lights": [
    {"type": "sun", "direction": [0, 0, 1], "radius": keys((0, 0), (1e9, 1e-300)), "irradiance": 1e12},
    {"type": "disk", "azimuth": -1e12, "elevation": -90, "radius": 1e-12, "irradiance": 1e12},
    {"type": "disk", "direction": [1e-12, 1e12, 0], "radius": 180, "radiance": 1e12}]})
rig_seed("disks_and_keys.json", {"version": 1, "window": "lanczos", "lights": [
    {"type": "disk", "direction": keys((0, [0, 1, 0]), (3, [0, -0.2, 1]), (4, [-1, 0, 0])), "radius": 1e-300, "radiance": 1e12},
    {"type": "disk", "azimuth": keys((0, 350), (9, 370)), "elevation": 89.999999999999986,
     "radius": {"interpolation": "step", "keys": keys((0, 180), (1, 0.5))}, "radiance": [1, 0, 2]},
    {"type": "sun", "direction": [1, 1, 1], "radius": keys((0, 89.999999999999986), (1e-9, 0)), "irradiance": [0, 1e12, 1]},
    {"type": "uniform", "radiance": keys((-1e9, 0), (1e9, 1e12))}]})
