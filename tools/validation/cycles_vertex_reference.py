"""Cycles' per-vertex reference of a glTF scene: exitant radiance at every vertex, baked by
Cycles to a float colour attribute, for tools/validation/real_maps_validation.sh (docs/validation.md).

Run inside Blender 3.4, not with python3:

    blender -b --factory-startup --python tools/validation/cycles_vertex_reference.py -- \
        --scene ROOM.gltf --env MAP.hdr --bounces 8 --samples 512 --seeds 1,2 -o OUT.csv

Scene, materials (Lambertian Diffuse BSDF with the glTF baseColorFactor), world (the map,
"Closest" interpolation, `--env-rotate` as prt's) and Cycles settings (no clamping, denoising,
adaptive sampling; diffuse bounces = total bounces = K) are those of tools/validation/cycles_reference.py,
whose functions this script uses.

The bake: `bpy.ops.object.bake(type='DIFFUSE', pass_filter={'DIRECT', 'INDIRECT', 'COLOR'},
target='VERTEX_COLORS')` into a FLOAT_COLOR attribute on the POINT domain (a byte colour would
clamp to [0, 1] and store sRGB). Diffuse direct + indirect are the light reflected by a white
Lambertian surface, times Color (the albedo): the exitant radiance rho E / pi, prt relight's
L_o (docs/validation.md checks it on a uniform sky, where prt is exact). An emitting material's
own emission (cycles_reference.py's EMISSION) is added to its vertices, as prt relight adds it. The baked point is the
shading point, as a camera hit is in a render, so Cycles' diffuse bounces K are prt's
`--bounces K`.

Each seed in `--seeds` is a separate bake of `--samples` samples; the CSV keeps every seed's
colour (r_SEED, g_SEED, b_SEED), so that the comparison can average them and estimate the
noise from their difference.

Output: OUT.csv, header `object,vertex,px,py,pz,nx,ny,nz,r_S,g_S,b_S,...` with positions and
normals in glTF axes (Blender (x, y, z) -> glTF (x, z, -y)), and OUT.csv.json with the settings.
"""

import argparse
import os
import sys
import time

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import cycles_reference as cr  # noqa: E402


def parse_args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    p = argparse.ArgumentParser(prog="cycles_vertex_reference.py")
    p.add_argument("--scene", required=True)
    p.add_argument("--env", help="environment map (default: a black world, the scene's own lights)")
    p.add_argument("--env-rotate", type=float, default=0.0)
    p.add_argument("--bounces", type=int, default=8)
    p.add_argument("--samples", type=int, default=512, help="Cycles samples per vertex and seed")
    p.add_argument("--seeds", default="1,2", help="comma-separated seeds, one bake each")
    p.add_argument("--remove", action="append", default=[])
    p.add_argument("--threads", type=int, default=0)
    p.add_argument("-o", "--output", required=True)
    return p.parse_args(argv)


def emitted_radiance(obj):
    """What the object's material emits (the DIFFUSE bake leaves emission out; prt relight adds
    an emitting vertex's own emission to its radiance). One material per object here."""
    names = {slot.material.name for slot in obj.material_slots if slot.material is not None}
    emitting = [cr.EMISSION[n] for n in names if n in cr.EMISSION]
    if emitting and len(names) > 1:
        cr.fail(f"{obj.name}: an emitting object with more than one material is not supported here")
    return emitting[0] if emitting else (0.0, 0.0, 0.0)


def main():
    a = parse_args()
    seeds = [int(s) for s in a.seeds.split(",")]
    cr.clear_scene()
    cr.import_gltf(a.scene)
    cr.remove_nodes(a.remove)
    scene = bpy.context.scene
    scene.frame_set(0)
    colours = cr.setup_materials()
    cr.setup_world(scene, a.env, a.env_rotate)
    lights = cr.setup_punctual_lights(scene, a.scene)
    a.seed = seeds[0]
    cr.setup_cycles(scene, a, 16, 16)
    meshes = sorted((o for o in scene.objects if o.type == "MESH"), key=lambda o: o.name)
    bpy.ops.object.select_all(action="DESELECT")
    for obj in meshes:
        me = obj.data
        attr = me.color_attributes.new(name="prt_bake", type="FLOAT_COLOR", domain="POINT")
        me.color_attributes.active_color = attr
        me.attributes.active_color = attr
        obj.select_set(True)
    bpy.context.view_layer.objects.active = meshes[0]
    bake = scene.render.bake
    bake.target = "VERTEX_COLORS"
    bake.use_pass_direct = bake.use_pass_indirect = bake.use_pass_color = True
    values = {}
    for seed in seeds:
        scene.cycles.seed = seed
        t0 = time.time()
        result = bpy.ops.object.bake(type="DIFFUSE", pass_filter={"DIRECT", "INDIRECT", "COLOR"},
                                     target="VERTEX_COLORS")
        if "FINISHED" not in result:
            cr.fail("Cycles bake failed")
        print(f"cycles_vertex_reference.py: seed {seed}: {time.time() - t0:.1f} s")
        for obj in meshes:
            data = obj.data.color_attributes["prt_bake"].data
            emitted = emitted_radiance(obj)
            values[(obj.name, seed)] = [tuple(c + e for c, e in zip(d.color[:3], emitted)) for d in data]
    out = os.path.abspath(a.output)
    os.makedirs(os.path.dirname(out), exist_ok=True)
    rows = 0
    with open(out + ".tmp", "w") as f:
        f.write("object,vertex,px,py,pz,nx,ny,nz," + ",".join(f"r_{s},g_{s},b_{s}" for s in seeds) + "\n")
        for obj in meshes:
            m = obj.matrix_world
            rot = m.to_3x3().inverted().transposed()
            for i, v in enumerate(obj.data.vertices):
                p = m @ v.co
                n = (rot @ v.normal).normalized()
                cols = ",".join("%.7g,%.7g,%.7g" % values[(obj.name, s)][i] for s in seeds)
                f.write(f"{obj.name},{i},{p.x:.6f},{p.z:.6f},{-p.y:.6f},{n.x:.6f},{n.z:.6f},{-n.y:.6f},{cols}\n")
                rows += 1
    os.replace(out + ".tmp", out)
    meta = {"scene": a.scene, "env": a.env, "env_rotate_deg": a.env_rotate, "bounces": a.bounces,
            "samples": a.samples, "seeds": seeds, "albedo": colours, "vertices": rows,
            "lights": lights, "emission": cr.EMISSION}
    cr.write_sidecar(out, meta)
    print(f"cycles_vertex_reference.py: wrote {a.output} ({rows} vertices, {a.samples} samples x {len(seeds)} seeds, "
          f"{a.bounces} diffuse bounces)")


main()
