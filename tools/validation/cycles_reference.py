"""Cycles reference render of a bundled glTF scene, for docs/validation.md.

Run inside Blender 3.4 (Debian package `blender`), not with python3:

    blender -b --factory-startup --python tools/validation/cycles_reference.py -- \
        --scene scenes/cornell_open.gltf --remove Receiver \
        --env scenes/env/white_sky_64.hdr --bounces 2 --samples 1024 \
        --size 160x90 --camera Camera -o out/cycles.exr

The scene is imported with Blender's own glTF importer, so its axis conversion (glTF
(x, y, z) -> Blender (x, -z, y)), camera and node transforms are Blender's, not prt's: that is
the point of an independent check. Every material becomes a Lambertian Diffuse BSDF
(roughness 0: not Oren-Nayar, not the Principled BSDF, whose diffuse lobe is not Lambertian)
with the glTF baseColorFactor (`--materials lambert`, the default), or, with `--materials
principled`, the importer's Principled BSDF as the glTF metallic-roughness model maps to it:
base colour, metallic and roughness from the file, distribution GGX (single scattering, as the
glTF BRDF), specular 0.5 (F0 = 0.04), no sheen, clearcoat, subsurface or specular tint, glossy
bounces as many as diffuse ones and reflective caustics on (the full light transport, glossy
interreflection included, which prt's bake leaves out). Blender 3.4's Principled diffuse is not
Lambertian (Burley's, with its retro-reflection and grazing darkening), so `--materials gltf`
builds the glTF BRDF as prt evaluates it (docs/render.md, "Materials") from Cycles' nodes: a
Lambertian Diffuse BSDF of colour baseColor·(1 − metallic) added to a Principled BSDF with
metallic 1, base colour F0 = mix(0.04, baseColor, metallic) and the material's roughness (GGX,
the specular lobe alone, Fresnel from F0), same bounces and caustics. `--materials gltf-bake`
keeps that BRDF for camera rays and gives every later bounce a Lambertian of the bounce albedo
prt's bake uses (docs/bake.md, "Materials"): prt's light transport, seen through the exact BRDF
(docs/validation.md, "Glossy materials"). The world is the equirectangular map, sampled with "Closest"
interpolation (prt projects each pixel as a constant, docs/lights.md), strength 1.

Bounces: `prt bake --bounces K` stores t0 + ... + tK (prt-math.md): light that reached the
visible point directly, plus paths with up to K diffuse reflections before it. Cycles'
"diffuse bounces" counts the reflections after the first (camera) hit, so 0 is direct light
only: K maps to diffuse bounces = total bounces = K.

Lights inside the scene: a glTF emissive material becomes the Lambertian diffuse plus an
Emission shader of colour emissiveFactor and strength KHR_materials_emissive_strength (as
Blender's importer reads them; Cycles' emission of strength S and colour C is a radiance C S, the
units of a world of strength 1, which are prt's). A KHR_lights_punctual point light gets the
power that makes Cycles' irradiance prt's I cos(theta) / r^2 for I candela: Cycles gives a
point light of P "watts" a radiant intensity P / (4 pi) in these units (measured:
docs/validation.md, "Lights inside the scene"), so P = 4 pi I, and radius 0 (Blender's importer
leaves the default 0.25 m and writes P = 4 pi I / 683). Without `--env` the world is black.

`--env-rotate DEG` turns the lighting as `prt render --env-rotate DEG` does: +DEG about glTF +Y,
which is Blender +Z. The Mapping node (type POINT) rotates the lookup vector, L'(w) = L(R w),
so it gets -DEG.

Output: an uncompressed 32-bit multilayer EXR with the passes Combined (linear radiance: no
view transform applies to multilayer EXR; "Standard" and exposure 0 are set anyway), Normal
(world normals, Blender axes) and IndexOB (object pass index), and OUTPUT.json with the
object indices and the settings used. tools/validation/cycles_validation.sh reads both.
"""

import argparse
import json
import math
import os
import sys

import bpy


def parse_args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    p = argparse.ArgumentParser(prog="cycles_reference.py")
    p.add_argument("--scene", help="glTF scene (.gltf or .glb)")
    p.add_argument("--env", help="equirectangular environment map (.hdr or .exr), linear radiance "
                                 "(default: a black world; the scene's own lights light it)")
    p.add_argument("--env-rotate", type=float, default=0.0,
                   help="degrees about glTF +Y, as prt render --env-rotate")
    p.add_argument("--bounces", type=int, default=2, help="prt bake --bounces K: diffuse bounces")
    p.add_argument("--samples", type=int, default=1024, help="Cycles samples per pixel")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--size", default="160x90", help="WxH")
    p.add_argument("--camera", default="", help="glTF camera node name (default: the first camera)")
    p.add_argument("--remove", action="append", default=[],
                   help="node name to delete after import (receivers: prt draws none without probes)")
    p.add_argument("--threads", type=int, default=0, help="render threads (0: all)")
    p.add_argument("--pixel-filter", choices=["blackman-harris", "box"], default="blackman-harris",
                   help="Cycles' pixel filter: its default (Blackman-Harris, 1.5 pixels wide) or a box one "
                        "pixel wide (each pixel the mean radiance over its square, as a supersampled "
                        "prt frame averaged down)")
    p.add_argument("--materials", choices=["lambert", "principled", "gltf", "gltf-bake"], default="lambert",
                   help="every material a Lambertian Diffuse BSDF (default), the glTF metallic-roughness "
                        "material as a Principled BSDF (GGX, specular 0.5), or as glTF's BRDF (a Lambertian "
                        "diffuse plus a GGX specular lobe), or glTF's BRDF for camera rays and a Lambertian of "
                        "prt's bounce albedo for every other ray (gltf-bake: prt's light transport)")
    p.add_argument("--no-caustics", action="store_true",
                   help="with --materials principled or gltf: reflective caustics off (no glossy reflection after a "
                        "diffuse bounce: the light transport of prt's bake, which bounces the diffuse albedo only)")
    p.add_argument("-o", "--output", help="output multilayer EXR")
    a = p.parse_args(argv)
    if not (a.scene and a.output):
        p.error("--scene and -o are required")
    return a


def fail(message):
    print(f"cycles_reference.py: {message}", file=sys.stderr)
    sys.exit(1)


def clear_scene():
    for obj in list(bpy.data.objects):
        bpy.data.objects.remove(obj, do_unlink=True)


def import_gltf(path):
    if not os.path.isfile(path):
        fail(f"{path}: no such file")
    # Debian 12 pairs Blender 3.4's importer with NumPy 1.24, which removed the alias np.bool
    # that the importer's set_poly_smoothing still uses; give it back (it is the builtin bool).
    import numpy
    if "bool" not in vars(numpy):
        numpy.bool = bool
    result = bpy.ops.import_scene.gltf(filepath=os.path.abspath(path))
    if "FINISHED" not in result:
        fail(f"{path}: Blender's glTF importer failed")


def remove_nodes(names):
    for name in names:
        obj = bpy.data.objects.get(name)
        if obj is None:
            fail(f"--remove {name}: no such node in the imported scene")
        for child in list(obj.children_recursive):
            bpy.data.objects.remove(child, do_unlink=True)
        bpy.data.objects.remove(obj, do_unlink=True)


def base_color(material):
    """The glTF baseColorFactor, as the importer put it on the Principled BSDF."""
    if material.use_nodes:
        for node in material.node_tree.nodes:
            if node.type == "BSDF_PRINCIPLED":
                if node.inputs["Base Color"].is_linked:
                    fail(f"material {material.name}: textured base colour is not supported here")
                return tuple(node.inputs["Base Color"].default_value)
    return tuple(material.diffuse_color)


def emission(material):
    """The glTF emissive radiance (emissiveFactor x emissive strength), as the importer put it on
    the Principled BSDF; (0, 0, 0) when the material does not emit."""
    if material.use_nodes:
        for node in material.node_tree.nodes:
            if node.type == "BSDF_PRINCIPLED":
                if node.inputs["Emission"].is_linked:
                    fail(f"material {material.name}: textured emission is not supported here")
                strength = node.inputs["Emission Strength"].default_value
                return tuple(c * strength for c in node.inputs["Emission"].default_value[:3])
    return (0.0, 0.0, 0.0)


def make_lambertian(material):
    rgba = base_color(material)
    emitted = emission(material)
    material.use_nodes = True
    nodes = material.node_tree.nodes
    nodes.clear()
    diffuse = nodes.new("ShaderNodeBsdfDiffuse")
    diffuse.inputs["Color"].default_value = rgba
    diffuse.inputs["Roughness"].default_value = 0.0
    out = nodes.new("ShaderNodeOutputMaterial")
    links = material.node_tree.links
    if max(emitted) > 0.0:
        emit = nodes.new("ShaderNodeEmission")
        emit.inputs["Color"].default_value = emitted + (1.0,)
        emit.inputs["Strength"].default_value = 1.0
        add = nodes.new("ShaderNodeAddShader")
        links.new(diffuse.outputs["BSDF"], add.inputs[0])
        links.new(emit.outputs["Emission"], add.inputs[1])
        links.new(add.outputs["Shader"], out.inputs["Surface"])
        material.cycles.sample_as_light = True
        EMISSION[material.name] = emitted
    else:
        links.new(diffuse.outputs["BSDF"], out.inputs["Surface"])
    return rgba[:3]


EMISSION = {}  # material name -> emitted radiance, for the materials that emit


def setup_punctual_lights(scene, scene_path):
    """Each imported point light gets P = 4 pi I watts for the glTF's I candela (per channel:
    colour x intensity) and radius 0; returns {name: (I, colour)}. Spot lights are refused
    (Blender's cone blend is not glTF's falloff)."""
    lights = [o for o in scene.objects if o.type == "LIGHT" and o.data.type != "SUN"]
    if not lights:
        return {}
    if not scene_path.lower().endswith(".gltf"):
        fail(f"{scene_path}: point lights are read from a .gltf only")
    with open(scene_path) as f:
        gltf = json.load(f)
    defs = gltf.get("extensions", {}).get("KHR_lights_punctual", {}).get("lights", [])
    by_node = {}
    for node in gltf.get("nodes", []):
        index = node.get("extensions", {}).get("KHR_lights_punctual", {}).get("light")
        if index is not None:
            by_node[node.get("name")] = defs[index]
    used = {}
    for obj in lights:
        d = by_node.get(obj.name)
        if d is None or d.get("type") != "point" or obj.data.type != "POINT":
            fail(f"light {obj.name}: only glTF point lights on named nodes are supported here")
        intensity = float(d.get("intensity", 1.0))
        colour = tuple(d.get("color", [1.0, 1.0, 1.0]))
        obj.data.energy = 4.0 * math.pi * intensity
        obj.data.color = colour
        obj.data.shadow_soft_size = 0.0
        used[obj.name] = {"candela": intensity, "color": colour, "watts": obj.data.energy}
    return used


def make_principled(material):
    """The importer's Principled BSDF kept with glTF's metallic-roughness model only: returns
    (base colour, metallic, roughness)."""
    nodes = material.node_tree.nodes if material.use_nodes else []
    bsdf = [n for n in nodes if n.type == "BSDF_PRINCIPLED"]
    if len(bsdf) != 1:
        fail(f"material {material.name}: expected one Principled BSDF from the glTF importer")
    bsdf = bsdf[0]
    for name in ("Base Color", "Metallic", "Roughness", "Normal", "Emission"):
        if bsdf.inputs[name].is_linked:
            fail(f"material {material.name}: textured {name} is not supported here")
    bsdf.distribution = "GGX"
    values = {"Specular": 0.5, "Specular Tint": 0.0, "Sheen": 0.0, "Clearcoat": 0.0, "Subsurface": 0.0,
              "Anisotropic": 0.0, "Transmission": 0.0, "Emission Strength": 0.0}
    for name, value in values.items():
        bsdf.inputs[name].default_value = value
    return (tuple(bsdf.inputs["Base Color"].default_value)[:3], bsdf.inputs["Metallic"].default_value,
            bsdf.inputs["Roughness"].default_value)


def make_gltf(material):
    """glTF's BRDF as prt evaluates it: Lambertian baseColor·(1 − metallic)/π plus the GGX lobe
    with F0 = mix(0.04, baseColor, metallic) (a metallic Principled BSDF: its specular lobe alone)."""
    rgb, metallic, roughness = make_principled(material)
    nodes = material.node_tree.nodes
    links = material.node_tree.links
    bsdf = [n for n in nodes if n.type == "BSDF_PRINCIPLED"][0]
    out = [n for n in nodes if n.type == "OUTPUT_MATERIAL"][0]
    bsdf.inputs["Base Color"].default_value = tuple(0.04 + (c - 0.04) * metallic for c in rgb) + (1.0,)
    bsdf.inputs["Metallic"].default_value = 1.0
    diffuse = nodes.new("ShaderNodeBsdfDiffuse")
    diffuse.inputs["Color"].default_value = tuple(c * (1.0 - metallic) for c in rgb) + (1.0,)
    diffuse.inputs["Roughness"].default_value = 0.0
    add = nodes.new("ShaderNodeAddShader")
    links.new(diffuse.outputs["BSDF"], add.inputs[0])
    links.new(bsdf.outputs["BSDF"], add.inputs[1])
    links.new(add.outputs["Shader"], out.inputs["Surface"])
    return rgb, metallic, roughness


def lobe_albedo(roughness):
    """(A, B) of the GGX lobe averaged over cosine-weighted views, 2 ∫ (A, B)(μ) μ dμ: a lobe of
    Schlick Fresnel from F0 reflects F0·A + B of a uniform radiance (prt's brdf::cosineAveragedDfg,
    docs/bake.md, "Materials"). Its own quadrature, from the glTF specification's GGX D and
    height-correlated Smith V: 32 Gauss-Legendre views, 128 x 128 stratified half vectors each."""
    import numpy as np
    alpha = max(roughness * roughness, 1e-4)
    a2 = alpha * alpha
    nodes, weights = np.polynomial.legendre.leggauss(32)
    mus, ws = 0.5 * (nodes + 1.0), 0.5 * weights
    n = 128
    u1, u2 = np.meshgrid((np.arange(n) + 0.5) / n, (np.arange(n) + 0.5) / n)
    u1, u2 = u1.ravel(), u2.ravel()
    cos_h = np.sqrt((1.0 - u1) / (1.0 + (a2 - 1.0) * u1))  # GGX's D(h)(n·h) sampled
    sin_h = np.sqrt(1.0 - cos_h * cos_h)
    h = np.stack([sin_h * np.cos(2 * np.pi * u2), sin_h * np.sin(2 * np.pi * u2), cos_h], axis=1)
    total = np.zeros(2)
    for mu, w in zip(mus, ws):
        v = np.array([np.sqrt(1.0 - mu * mu), 0.0, mu])
        vh = h @ v
        l = 2.0 * vh[:, None] * h - v
        nl = l[:, 2]
        ok = (nl > 0.0) & (vh > 0.0)
        nl, vh_, nh = nl[ok], vh[ok], h[ok, 2]
        vis = 0.5 / (nl * np.sqrt(mu * mu * (1.0 - a2) + a2) + mu * np.sqrt(nl * nl * (1.0 - a2) + a2))
        g = 4.0 * vis * nl * vh_ / nh  # f / F · cos / pdf
        fc = (1.0 - vh_) ** 5
        total += 2.0 * mu * w * np.array([np.sum(g * (1.0 - fc)), np.sum(g * fc)]) / (n * n)
    return total


def make_gltf_bake(material):
    """glTF's BRDF (make_gltf) where a camera ray lands, and everywhere else a Lambertian of the
    bounce albedo prt's bake gives the material: the base colour for a dielectric, baseColor·(1 −
    metallic) + metallic·(baseColor·A + B) (lobe_albedo) for a metal. That is prt's light
    transport (its bake re-emits every bounce diffusely) seen through the exact BRDF."""
    rgb, metallic, roughness = make_gltf(material)
    a, b = lobe_albedo(roughness) if metallic > 0.0 else (0.0, 0.0)
    bounce = tuple(c * (1.0 - metallic) + metallic * (c * a + b) for c in rgb)
    nodes = material.node_tree.nodes
    links = material.node_tree.links
    out = [n for n in nodes if n.type == "OUTPUT_MATERIAL"][0]
    full = out.inputs["Surface"].links[0].from_socket
    diffuse = nodes.new("ShaderNodeBsdfDiffuse")
    diffuse.inputs["Color"].default_value = bounce + (1.0,)
    diffuse.inputs["Roughness"].default_value = 0.0
    path = nodes.new("ShaderNodeLightPath")
    mix = nodes.new("ShaderNodeMixShader")
    links.new(path.outputs["Is Camera Ray"], mix.inputs["Fac"])
    links.new(diffuse.outputs["BSDF"], mix.inputs[1])
    links.new(full, mix.inputs[2])
    links.new(mix.outputs["Shader"], out.inputs["Surface"])
    return {"base": rgb, "metallic": metallic, "roughness": roughness, "bounce": bounce}


def setup_materials(kind="lambert"):
    colours = {}
    make = {"principled": make_principled, "gltf": make_gltf, "gltf-bake": make_gltf_bake}.get(kind, make_lambertian)
    for obj in bpy.context.scene.objects:
        for slot in obj.material_slots if obj.type == "MESH" else []:
            if slot.material is not None and slot.material.name not in colours:
                colours[slot.material.name] = make(slot.material)
    return colours


def setup_world(scene, env_path, rotate_deg):
    if env_path is None:
        world = bpy.data.worlds.new("prt_validation_black")
        scene.world = world
        world.use_nodes = True
        world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.0
        return
    if not os.path.isfile(env_path):
        fail(f"{env_path}: no such file")
    world = bpy.data.worlds.new("prt_validation")
    scene.world = world
    world.use_nodes = True
    nodes = world.node_tree.nodes
    nodes.clear()
    coord = nodes.new("ShaderNodeTexCoord")
    mapping = nodes.new("ShaderNodeMapping")
    mapping.vector_type = "POINT"
    mapping.inputs["Rotation"].default_value = (0.0, 0.0, math.radians(-rotate_deg))
    env = nodes.new("ShaderNodeTexEnvironment")
    env.image = bpy.data.images.load(os.path.abspath(env_path))
    env.image.colorspace_settings.name = "Linear"
    env.interpolation = "Closest"
    env.projection = "EQUIRECTANGULAR"
    background = nodes.new("ShaderNodeBackground")
    background.inputs["Strength"].default_value = 1.0
    out = nodes.new("ShaderNodeOutputWorld")
    links = world.node_tree.links
    links.new(coord.outputs["Generated"], mapping.inputs["Vector"])
    links.new(mapping.outputs["Vector"], env.inputs["Vector"])
    links.new(env.outputs["Color"], background.inputs["Color"])
    links.new(background.outputs["Background"], out.inputs["Surface"])
    world.cycles.sampling_method = "AUTOMATIC"


def camera_yfov(scene_path, name):
    """yfov of the named glTF camera node, read from the file itself (.gltf only)."""
    if not scene_path.lower().endswith(".gltf"):
        return None
    with open(scene_path) as f:
        gltf = json.load(f)
    for node in gltf.get("nodes", []):
        if "camera" in node and (not name or node.get("name") == name):
            cam = gltf["cameras"][node["camera"]]
            return cam.get("perspective", {}).get("yfov")
    return None


def setup_camera(scene, scene_path, name):
    cameras = [o for o in scene.objects if o.type == "CAMERA"]
    chosen = [o for o in cameras if not name or o.name == name]
    if not chosen:
        fail(f"--camera {name}: no such camera (cameras: {', '.join(o.name for o in cameras) or 'none'})")
    cam = chosen[0]
    yfov = camera_yfov(scene_path, name)
    if yfov is not None:
        cam.data.sensor_fit = "VERTICAL"
        cam.data.angle_y = yfov
    scene.camera = cam
    return cam, yfov


def setup_cycles(scene, a, width, height):
    scene.render.engine = "CYCLES"
    c = scene.cycles
    c.device = "CPU"
    c.samples = a.samples
    c.use_adaptive_sampling = False
    c.use_denoising = False
    c.seed = a.seed
    c.use_animated_seed = False
    c.max_bounces = a.bounces
    c.diffuse_bounces = a.bounces
    principled = getattr(a, "materials", "lambert") != "lambert"
    c.glossy_bounces = a.bounces if principled else 0
    c.transmission_bounces = 0
    c.volume_bounces = 0
    c.transparent_max_bounces = 0
    c.caustics_reflective = principled and not a.no_caustics
    c.caustics_refractive = False
    c.sample_clamp_direct = 0.0
    c.sample_clamp_indirect = 0.0
    c.blur_glossy = 0.0
    c.light_sampling_threshold = 0.0
    c.use_fast_gi = False
    if getattr(a, "pixel_filter", None) == "box":
        c.pixel_filter_type = "BOX"
        c.filter_width = 1.0
    c.film_exposure = 1.0
    scene.render.film_transparent = False
    scene.render.use_compositing = False  # no glare or any other compositor node
    scene.render.use_sequencer = False
    scene.render.resolution_x = width
    scene.render.resolution_y = height
    scene.render.resolution_percentage = 100
    scene.render.pixel_aspect_x = scene.render.pixel_aspect_y = 1.0
    if a.threads > 0:
        scene.render.threads_mode = "FIXED"
        scene.render.threads = a.threads
    scene.display_settings.display_device = "sRGB"
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    layer = scene.view_layers[0]
    layer.use_pass_combined = True
    layer.use_pass_normal = True
    layer.use_pass_object_index = True
    settings = scene.render.image_settings
    settings.file_format = "OPEN_EXR_MULTILAYER"
    settings.color_depth = "32"
    settings.exr_codec = "NONE"


def index_objects(scene):
    indices = {}
    for i, obj in enumerate(sorted((o for o in scene.objects if o.type == "MESH"), key=lambda o: o.name)):
        obj.pass_index = i + 1
        indices[obj.name] = i + 1
    return indices


def parse_size(text):
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        fail(f"--size {text}: expected WxH")
    if w < 1 or h < 1:
        fail(f"--size {text}: expected WxH")
    return w, h


def write_sidecar(out, meta):
    """OUT.json: the settings a result was made with (the validation scripts reuse it when they match)."""
    meta = dict(meta, blender=bpy.app.version_string)
    with open(out + ".json.tmp", "w") as f:
        json.dump(meta, f, indent=1)
    os.replace(out + ".json.tmp", out + ".json")


def render(a):
    width, height = parse_size(a.size)
    clear_scene()
    import_gltf(a.scene)
    remove_nodes(a.remove)
    scene = bpy.context.scene
    scene.frame_set(0)  # frame 0 = t 0 s, prt render's frame 0; no animated node is left anyway
    colours = setup_materials(a.materials)
    setup_world(scene, a.env, a.env_rotate)
    lights = setup_punctual_lights(scene, a.scene)
    cam, yfov = setup_camera(scene, a.scene, a.camera)
    setup_cycles(scene, a, width, height)
    indices = index_objects(scene)
    out = os.path.abspath(a.output)
    os.makedirs(os.path.dirname(out), exist_ok=True)
    tmp = out + ".tmp.exr"
    scene.render.filepath = tmp
    bpy.ops.render.render(write_still=True)
    os.replace(tmp, out)
    meta = {"scene": a.scene, "env": a.env, "env_rotate_deg": a.env_rotate, "bounces": a.bounces,
            "samples": a.samples, "seed": a.seed, "size": [width, height], "camera": cam.name,
            "yfov": yfov, "removed": a.remove, "pixel_filter": a.pixel_filter, "object_index": indices, "albedo": colours,
            "materials": a.materials, "caustics": a.materials != "lambert" and not a.no_caustics,
            "lights": lights, "emission": EMISSION}
    write_sidecar(out, meta)
    print(f"cycles_reference.py: wrote {a.output} ({width}x{height}, {a.samples} samples, "
          f"{a.bounces} bounces, {a.materials} materials, objects {indices})")


def main():
    render(parse_args())


if __name__ == "__main__":  # Blender runs --python scripts as __main__; importing only defines
    main()
