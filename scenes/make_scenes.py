#!/usr/bin/env python3
"""Regenerates the bundled glTF scenes of prt (scenes/README.md says what each is for).

    python3 scenes/make_scenes.py            # writes scenes/*.gltf and scenes/*.bin

Standard library only and deterministic: the same script writes byte-identical files.
Conventions (glTF 2.0): +Y up, metres, counter-clockwise front faces, explicit per-vertex
NORMAL, baseColorFactor in linear RGB, indexed triangle lists, one .bin buffer per scene.
"""

import json
import math
import os
import struct

HERE = os.path.dirname(os.path.abspath(__file__))

ARRAY_BUFFER = 34962
ELEMENT_ARRAY_BUFFER = 34963
FLOAT = 5126
UNSIGNED_SHORT = 5123
UNSIGNED_INT = 5125


def f32(x):
    """x rounded to float32, so accessor min/max equal the stored values exactly."""
    return struct.unpack("<f", struct.pack("<f", x))[0]


def normalize(v):
    n = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    return (v[0] / n, v[1] / n, v[2] / n)


def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


class Mesh:
    """A triangle list with per-vertex normals. Triangles are (i, j, k), counter-clockwise seen
    from the side their normal points to."""

    def __init__(self):
        self.positions = []
        self.normals = []
        self.triangles = []

    def add_vertex(self, p, n):
        self.positions.append(p)
        self.normals.append(n)
        return len(self.positions) - 1

    def add_grid(self, origin, u, v, nu, nv, keep=None):
        """A planar nu × nv grid of cells spanning origin + s·u + t·v (s, t in [0, 1]), facing
        u × v. keep(i, j) says whether cell (i, j) is kept; vertices of dropped cells that no
        kept cell uses are not written."""
        n = normalize(cross(u, v))
        cells = [(i, j) for j in range(nv) for i in range(nu) if keep is None or keep(i, j)]
        index = {}

        def vertex(i, j):
            if (i, j) not in index:
                s, t = i / nu, j / nv
                p = tuple(origin[k] + s * u[k] + t * v[k] for k in range(3))
                index[(i, j)] = self.add_vertex(p, n)
            return index[(i, j)]

        for i, j in cells:
            a, b = vertex(i, j), vertex(i + 1, j)
            c, d = vertex(i + 1, j + 1), vertex(i, j + 1)
            self.triangles.append((a, b, c))
            self.triangles.append((a, c, d))

    def check_winding(self):
        """Every triangle's geometric normal agrees with its vertex normals (front-facing on
        the normal's side) and no triangle is degenerate."""
        for t in self.triangles:
            p = [self.positions[i] for i in t]
            g = cross(sub(p[1], p[0]), sub(p[2], p[0]))
            area2 = math.sqrt(dot(g, g))
            assert area2 > 1e-12, "degenerate triangle"
            for i in t:
                assert dot(g, self.normals[i]) > 0.5 * area2, "winding disagrees with normal"


def box(size, cell):
    """A closed box centred on the origin in x and z, standing on y = 0, outward normals, each
    face a grid of about `cell`-sized cells (faces do not share vertices)."""
    sx, sy, sz = size
    m = Mesh()
    nx, ny, nz = (max(1, round(s / cell)) for s in size)
    hx, hz = sx / 2, sz / 2
    # (origin, u, v, cells along u, cells along v); u × v is the outward normal.
    faces = [
        ((-hx, 0, hz), (sx, 0, 0), (0, sy, 0), nx, ny),      # +z
        ((hx, 0, -hz), (-sx, 0, 0), (0, sy, 0), nx, ny),     # -z
        ((hx, 0, hz), (0, 0, -sz), (0, sy, 0), nz, ny),      # +x
        ((-hx, 0, -hz), (0, 0, sz), (0, sy, 0), nz, ny),     # -x
        ((-hx, sy, hz), (sx, 0, 0), (0, 0, -sz), nx, nz),    # +y (top)
        ((-hx, 0, -hz), (sx, 0, 0), (0, 0, sz), nx, nz),     # -y (bottom)
    ]
    for origin, u, v, nu, nv in faces:
        m.add_grid(origin, u, v, nu, nv)
    return m


def uv_sphere(radius, segments, rings):
    """A UV sphere with outward normals and one vertex at each pole (no degenerate triangles)."""
    m = Mesh()
    top = m.add_vertex((0.0, radius, 0.0), (0.0, 1.0, 0.0))
    ring_start = []
    for r in range(1, rings):
        theta = math.pi * r / rings
        ring_start.append(len(m.positions))
        for s in range(segments):
            phi = 2 * math.pi * s / segments
            n = (math.sin(theta) * math.cos(phi), math.cos(theta), -math.sin(theta) * math.sin(phi))
            m.add_vertex(tuple(radius * c for c in n), n)
    bottom = m.add_vertex((0.0, -radius, 0.0), (0.0, -1.0, 0.0))
    for s in range(segments):
        s1 = (s + 1) % segments
        m.triangles.append((top, ring_start[0] + s, ring_start[0] + s1))
        for r in range(len(ring_start) - 1):
            a, b = ring_start[r] + s, ring_start[r] + s1
            c, d = ring_start[r + 1] + s, ring_start[r + 1] + s1
            m.triangles.append((a, c, d))
            m.triangles.append((a, d, b))
        m.triangles.append((ring_start[-1] + s, bottom, ring_start[-1] + s1))
    return m


def open_cavity(radius, segments, opening_deg, ring_steps):
    """The inside of a sphere with a polar cap of half-angle `opening_deg` around +Y removed.
    Normals point to the centre and triangles are front-facing from inside. Rings run from
    θ = opening_deg (the opening's rim, exactly) to the south pole in `ring_steps` equal steps."""
    m = Mesh()
    theta0 = math.radians(opening_deg)
    ring_start = []
    for r in range(ring_steps):
        theta = theta0 + (math.pi - theta0) * r / ring_steps
        ring_start.append(len(m.positions))
        for s in range(segments):
            phi = 2 * math.pi * s / segments
            d = (math.sin(theta) * math.cos(phi), math.cos(theta), -math.sin(theta) * math.sin(phi))
            m.add_vertex(tuple(radius * c for c in d), tuple(-c for c in d))
    bottom = m.add_vertex((0.0, -radius, 0.0), (0.0, 1.0, 0.0))
    for s in range(segments):
        s1 = (s + 1) % segments
        for r in range(len(ring_start) - 1):
            a, b = ring_start[r] + s, ring_start[r] + s1
            c, d = ring_start[r + 1] + s, ring_start[r + 1] + s1
            m.triangles.append((a, d, c))  # the outward sphere's (a, c, d), reversed
            m.triangles.append((a, b, d))
        m.triangles.append((ring_start[-1] + s, ring_start[-1] + s1, bottom))
    return m


class GltfWriter:
    """Collects meshes, materials and nodes; writes NAME.gltf and NAME.bin."""

    def __init__(self):
        self.bin = bytearray()
        self.gltf = {
            "asset": {"version": "2.0", "generator": "prt scenes/make_scenes.py"},
            "scene": 0,
            "scenes": [{"name": "Scene", "nodes": []}],
            "nodes": [],
            "meshes": [],
            "materials": [],
            "accessors": [],
            "bufferViews": [],
            "buffers": [],
        }
        self.material_index = {}

    def material(self, name, rgb):
        if name not in self.material_index:
            self.material_index[name] = len(self.gltf["materials"])
            self.gltf["materials"].append({
                "name": name,
                "pbrMetallicRoughness": {
                    "baseColorFactor": [rgb[0], rgb[1], rgb[2], 1.0],
                    "metallicFactor": 0.0,
                    "roughnessFactor": 1.0,
                },
            })
        return self.material_index[name]

    def _view(self, data, target):
        while len(self.bin) % 4:
            self.bin.append(0)
        view = {"buffer": 0, "byteOffset": len(self.bin), "byteLength": len(data)}
        if target is not None:  # animation data has no GL buffer target
            view["target"] = target
        self.gltf["bufferViews"].append(view)
        self.bin += data
        return len(self.gltf["bufferViews"]) - 1

    def _vec3_accessor(self, values, with_bounds):
        flat = [f32(c) for v in values for c in v]
        view = self._view(struct.pack("<%df" % len(flat), *flat), ARRAY_BUFFER)
        acc = {"bufferView": view, "componentType": FLOAT, "count": len(values), "type": "VEC3"}
        if with_bounds:
            acc["min"] = [min(flat[k::3]) for k in range(3)]
            acc["max"] = [max(flat[k::3]) for k in range(3)]
        self.gltf["accessors"].append(acc)
        return len(self.gltf["accessors"]) - 1

    def mesh(self, name, mesh, material):
        mesh.check_winding()
        flat = [i for t in mesh.triangles for i in t]
        if len(mesh.positions) <= 65535:
            data, ctype = struct.pack("<%dH" % len(flat), *flat), UNSIGNED_SHORT
        else:
            data, ctype = struct.pack("<%dI" % len(flat), *flat), UNSIGNED_INT
        position = self._vec3_accessor(mesh.positions, True)
        normal = self._vec3_accessor(mesh.normals, False)
        view = self._view(data, ELEMENT_ARRAY_BUFFER)
        self.gltf["accessors"].append({
            "bufferView": view, "componentType": ctype, "count": len(flat), "type": "SCALAR",
            "min": [min(flat)], "max": [max(flat)],
        })
        indices = len(self.gltf["accessors"]) - 1
        self.gltf["meshes"].append({"name": name, "primitives": [{
            "attributes": {"POSITION": position, "NORMAL": normal},
            "indices": indices, "material": material, "mode": 4,
        }]})
        return len(self.gltf["meshes"]) - 1

    def node(self, name, **fields):
        node = {"name": name}
        node.update(fields)
        self.gltf["nodes"].append(node)
        index = len(self.gltf["nodes"]) - 1
        self.gltf["scenes"][0]["nodes"].append(index)
        return index

    def animation(self, name, node, path, times, values):
        """A LINEAR animation of one node property: key `times` (seconds) and one value per key
        (3 floats for translation and scale). The input accessor carries min/max, as glTF asks."""
        times = [f32(t) for t in times]
        tview = self._view(struct.pack("<%df" % len(times), *times), None)
        self.gltf["accessors"].append({"bufferView": tview, "componentType": FLOAT, "count": len(times),
                                       "type": "SCALAR", "min": [min(times)], "max": [max(times)]})
        tacc = len(self.gltf["accessors"]) - 1
        flat = [f32(c) for v in values for c in v]
        vview = self._view(struct.pack("<%df" % len(flat), *flat), None)
        self.gltf["accessors"].append({"bufferView": vview, "componentType": FLOAT, "count": len(values),
                                       "type": "VEC3"})
        vacc = len(self.gltf["accessors"]) - 1
        self.gltf.setdefault("animations", []).append({
            "name": name,
            "channels": [{"sampler": 0, "target": {"node": node, "path": path}}],
            "samplers": [{"input": tacc, "output": vacc, "interpolation": "LINEAR"}],
        })

    def camera(self, name, yfov, aspect, znear):
        self.gltf.setdefault("cameras", []).append({
            "name": name, "type": "perspective",
            "perspective": {"yfov": yfov, "aspectRatio": aspect, "znear": znear},
        })
        return len(self.gltf["cameras"]) - 1

    def write(self, basename):
        while len(self.bin) % 4:
            self.bin.append(0)
        self.gltf["buffers"].append({"uri": basename + ".bin", "byteLength": len(self.bin)})
        with open(os.path.join(HERE, basename + ".bin"), "wb") as f:
            f.write(self.bin)
        with open(os.path.join(HERE, basename + ".gltf"), "w", encoding="utf-8", newline="\n") as f:
            json.dump(self.gltf, f, indent=1)
            f.write("\n")
        prims = [p for m in self.gltf["meshes"] for p in m["primitives"]]
        verts = sum(self.gltf["accessors"][p["attributes"]["POSITION"]]["count"] for p in prims)
        tris = sum(self.gltf["accessors"][p["indices"]]["count"] for p in prims) // 3
        print("%-16s %6d vertices %6d triangles %8d bytes of buffer"
              % (basename + ".gltf", verts, tris, len(self.bin)))


def quat_y(deg):
    """Rotation about +Y by `deg` degrees (right-handed), as a glTF [x, y, z, w] quaternion."""
    h = math.radians(deg) / 2
    return [0.0, math.sin(h), 0.0, math.cos(h)]


def quat_x(deg):
    h = math.radians(deg) / 2
    return [math.sin(h), 0.0, 0.0, math.cos(h)]


# Cornell-box reflectances (linear RGB), as commonly used for the classic scene.
WHITE = (0.725, 0.71, 0.68)
RED = (0.63, 0.065, 0.05)
GREEN = (0.14, 0.45, 0.091)

CELL = 0.05            # wall grid spacing (m): per-vertex transfer needs this resolution
OPENING = 0.8          # side of the square ceiling opening (m)

# Boxes: the classic Cornell boxes scaled to a 2 m room (165 and 330 units of 555 ≈ 0.6, 1.2).
SHORT_BOX = {"size": (0.6, 0.6, 0.6), "at": (0.35, 0.0, 0.3), "yaw": -17.0}
TALL_BOX = {"size": (0.6, 1.2, 0.6), "at": (-0.33, 0.0, -0.3), "yaw": 17.0}
RECEIVER = {"radius": 0.2, "at": (-0.4, 0.5, 0.3)}
# The receiver's path (glTF animation "ReceiverPath", translation, LINEAR): from its rest place
# at the left front up, over the short box to the right, and down beside the tall box. Key
# times in seconds; after the last key it stays there (glTF clamps).
RECEIVER_PATH = [
    (0.0, (-0.4, 0.5, 0.3)),
    (1.0, (-0.3, 0.95, 0.35)),
    (2.0, (0.5, 1.0, 0.05)),
    (3.0, (0.5, 0.75, -0.55)),
]

# Camera: inside, against the front wall, slightly pitched up. It frames the whole height of
# the back wall, both coloured walls, both boxes and most of the receiver. The ceiling opening
# is NOT in view: from inside a 2 m room, a 0.9 rad vertical field of view cannot hold both
# the boxes' tops (~0.7 m in front of the camera, below it) and the opening (above it); the
# light it lets in shows as the bright patch on the floor and the short box.
CAMERA = {"at": (0.0, 0.7, 0.97), "pitch": 6.0, "yfov": 0.9, "aspect": 16.0 / 9.0}


def footprint_distance(point, b):
    """Distance in the xz plane from `point` to box b's footprint (0 inside)."""
    h = math.radians(b["yaw"])
    dx, dz = point[0] - b["at"][0], point[2] - b["at"][2]
    # Into the box's frame: rotate by -yaw about Y.
    lx = math.cos(h) * dx - math.sin(h) * dz
    lz = math.sin(h) * dx + math.cos(h) * dz
    ox = max(abs(lx) - b["size"][0] / 2, 0.0)
    oz = max(abs(lz) - b["size"][2] / 2, 0.0)
    return math.hypot(ox, oz)


def cornell_open():
    g = GltfWriter()
    white, red, green = g.material("white", WHITE), g.material("red", RED), g.material("green", GREEN)
    n = round(2.0 / CELL)                       # 40 cells per 2 m wall
    lo, hi = (n - round(OPENING / CELL)) // 2, (n + round(OPENING / CELL)) // 2
    assert abs((hi - lo) * CELL - OPENING) < 1e-9

    walls = [
        # name, origin, u, v (u × v points into the room), material
        ("Floor", (-1, 0, 1), (2, 0, 0), (0, 0, -2), white),
        ("BackWall", (-1, 0, -1), (2, 0, 0), (0, 2, 0), white),
        ("FrontWall", (1, 0, 1), (-2, 0, 0), (0, 2, 0), white),
        ("LeftWall", (-1, 0, 1), (0, 0, -2), (0, 2, 0), red),
        ("RightWall", (1, 0, -1), (0, 0, 2), (0, 2, 0), green),
    ]
    for name, origin, u, v, mat in walls:
        m = Mesh()
        m.add_grid(origin, u, v, n, n)
        g.node(name, mesh=g.mesh(name, m, mat))
    # Ceiling, facing down, with the square opening in its middle: cells (i, j) of the
    # opening are left out (u runs along +x, v along +z, both symmetric about the centre).
    ceiling = Mesh()
    ceiling.add_grid((-1, 2, -1), (2, 0, 0), (0, 0, 2), n, n,
                     keep=lambda i, j: not (lo <= i < hi and lo <= j < hi))
    g.node("Ceiling", mesh=g.mesh("Ceiling", ceiling, white))

    for name, b in (("ShortBox", SHORT_BOX), ("TallBox", TALL_BOX)):
        g.node(name, mesh=g.mesh(name, box(b["size"], CELL), white),
               translation=list(b["at"]), rotation=quat_y(b["yaw"]))

    # The receiver must not intersect the boxes, the floor, the ceiling or the walls, at rest and
    # anywhere along its path (sampled finely; it moves in straight lines between keys).
    r, at = RECEIVER["radius"], RECEIVER["at"]
    assert RECEIVER_PATH[0][1] == at
    for b in (SHORT_BOX, TALL_BOX):
        assert footprint_distance(at, b) > r + 0.05
    assert at[1] - r > 0.05 and all(abs(c) + r < 0.95 for c in (at[0], at[2]))
    for (t0, p0), (t1, p1) in zip(RECEIVER_PATH, RECEIVER_PATH[1:]):
        assert t1 > t0
        for k in range(201):
            p = tuple(p0[i] + (p1[i] - p0[i]) * k / 200 for i in range(3))
            for b in (SHORT_BOX, TALL_BOX):
                assert footprint_distance(p, b) > r + 0.05 or p[1] - r > b["size"][1] + 0.05, p
            assert p[1] - r > 0.05 and p[1] + r < 1.95 and all(abs(c) + r < 0.95 for c in (p[0], p[2])), p
    receiver = g.node("Receiver", mesh=g.mesh("Receiver", uv_sphere(r, 32, 16), white),
                      translation=list(at), extras={"prt": {"receiver": True}})
    g.animation("ReceiverPath", receiver, "translation", [t for t, _ in RECEIVER_PATH],
                [p for _, p in RECEIVER_PATH])

    cam = g.camera("Camera", CAMERA["yfov"], CAMERA["aspect"], 0.01)
    g.node("Camera", camera=cam, translation=list(CAMERA["at"]), rotation=quat_x(CAMERA["pitch"]))
    g.write("cornell_open")


def cavity():
    g = GltfWriter()
    grey = g.material("grey", (0.5, 0.5, 0.5))
    # 120° from the rim to the south pole in 86 steps of 1.395°; 128 segments in φ.
    g.node("Cavity", mesh=g.mesh("Cavity", open_cavity(1.0, 128, 60.0, 86), grey))
    g.write("cavity")


def plane():
    g = GltfWriter()
    mat = g.material("albedo_0.8", (0.8, 0.8, 0.8))
    m = Mesh()
    m.add_grid((-1, 0, 1), (2, 0, 0), (0, 0, -2), 32, 32)
    g.node("Plane", mesh=g.mesh("Plane", m, mat))
    g.write("plane")


if __name__ == "__main__":
    cornell_open()
    cavity()
    plane()
