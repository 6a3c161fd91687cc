"""Test and README scenes for the Lacquer extension, rendered with Cycles and with LACQUER.

Runs in a Python that has bpy (scripts/blender-env.sh makes one); installs the extension zip
into the user resources folder given by $BLENDER_USER_RESOURCES (set it to a temporary
folder: it must be set before bpy starts), enables it, builds each scene from factory
settings, assigns presets with the extension's operator, renders, and writes EXRs and a JSON
report (timings, fit, engine messages).

    BLENDER_USER_RESOURCES=$(mktemp -d) .venv-blender/bin/python blender-addon/scripts/scenes.py \
        --zip dist/lacquer-0.1.0-linux_x64.zip --out out/ --size 128 --spp 16 --scenes compare,density

Scenes:
  compare   gold_flake_8 on a 10 cm sphere, uniform world and a soft area light, film transparent
  density   a 2 cm plate filling the frame, looked at from above, a sun 20° off the view
            direction: gold_flake_0, _2, _8 (sparkle grows with density)
  lights    a Diffuse BSDF plate under each light type in turn (point, point with radius and
            soft falloff off, spot, sun, area rectangle, world colour, world HDRI): the engine's
            light, world and camera conversions, with an exact material on both sides
  instances collection instances (rotated, non-uniformly scaled), a two-material cube with a
            bevel modifier and its linked duplicate, Diffuse BSDFs: transforms and instancing
  principled  a sphere with a plain Principled BSDF (coat, metallic, thin film): LACQUER's
            approximation of non-Lacquer materials by the core's `principled` model
  flakescale  gold_flake_8 on plates parented under a 0.01 root, plain, and collection instances
            scaled 0.5 and 0.25, at Unit Scale 1 and 0.5: the flake cells' coordinate rendered by
            Cycles (an emission copy of the node group) and LACQUER's exported sparkle uv
  engine    the LACQUER engine as a production engine: progressive rounds, Denoising Albedo /
            Normal passes, the compositor's Denoise node, Esc, the viewport's worker and buffer
  editing   refits on a worker thread, keyframed parameters, load_post upgrades, linked node
            groups, bad edits (invalid JSON, out-of-range values) keeping the previous paint
  readme    gold_flake_8 ("Gold metallic 8 %") on a sphere above a floor, studio-like lighting;
            also writes a side-by-side PNG (Cycles | LACQUER) with --png
  shots     the README screenshots into --img-dir (PNG): the asset library as a contact sheet,
            orange peel and a normal map (LACQUER), a textured Base Color (Cycles | LACQUER),
            flakes on a parented, scaled instance (Cycles | LACQUER), LACQUER's passes and the
            compositor's Denoise node; panels --shot-size px at --shot-spp (readme-image.sh)

With --render-blend FILE (no --zip needed, nothing installed) it only opens FILE and renders
its scene with Cycles into --out: a farm node without the extension.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time

import bpy

ADDON = "bl_ext.user_default.lacquer"
EEVEE = "BLENDER_EEVEE_NEXT" if bpy.app.version < (5, 0, 0) else "BLENDER_EEVEE"


def install(zip_path: str) -> dict:
    t = time.perf_counter()
    if ADDON not in bpy.context.preferences.addons:
        r = bpy.ops.extensions.package_install_files(filepath=os.path.abspath(zip_path), repo="user_default",
                                                     enable_on_install=True)
        if r != {"FINISHED"} or ADDON not in bpy.context.preferences.addons:
            raise SystemExit(f"installing {zip_path} failed: {r}")
    return {"install_seconds": time.perf_counter() - t}


def engine_registered() -> bool:
    return any(getattr(c, "bl_idname", None) == "LACQUER" and c.is_registered
               for c in bpy.types.RenderEngine.__subclasses__())


def uninstall() -> dict:
    # bpy 4.5 may hang at exit while the extension's classes are registered.
    if ADDON in bpy.context.preferences.addons:
        bpy.ops.preferences.addon_disable(module=ADDON)
    return {"unregistered": {
        "addon_disabled": ADDON not in bpy.context.preferences.addons,
        "engine_gone": not engine_registered(),
        "operators_gone": not hasattr(bpy.types, "LACQUER_OT_assign_paint"),
        "material_props_gone": not hasattr(bpy.types.Material, "lacquer"),
    }}


def fresh_scene(size: int, spp: int):
    # Not read_factory_settings: that would also reset the preferences and so the extension.
    for coll in (bpy.data.objects, bpy.data.meshes, bpy.data.materials, bpy.data.lights, bpy.data.cameras,
                 bpy.data.worlds, bpy.data.node_groups, bpy.data.images):
        for item in list(coll):
            coll.remove(item)
    scene = bpy.context.scene
    scene.render.resolution_x = scene.render.resolution_y = size
    scene.render.resolution_percentage = 100
    scene.render.film_transparent = True
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"
    scene.render.image_settings.exr_codec = "ZIP"
    scene.view_settings.view_transform = "Standard"
    scene.render.threads_mode = "AUTO"
    c = scene.cycles
    c.device = "CPU"
    c.samples = spp
    c.use_adaptive_sampling = False
    c.use_denoising = False
    c.max_bounces = 8
    c.diffuse_bounces = c.glossy_bounces = c.transmission_bounces = 8
    c.sample_clamp_direct = c.sample_clamp_indirect = 0.0
    c.caustics_reflective = c.caustics_refractive = True
    if hasattr(c, "pixel_filter_type"):  # Blender 5.0
        c.pixel_filter_type = "BOX"
    else:
        c.filter_type = "BOX"
    c.filter_width = 1.0
    c.seed = 0
    scene.lacquer.samples = spp
    scene.lacquer.max_depth = 8
    world = bpy.data.worlds.new("World")
    scene.world = world
    return scene


def set_world(scene, color, strength=1.0):
    w = scene.world
    if hasattr(w, "use_nodes"):
        w.use_nodes = True
    bg = next(n for n in w.node_tree.nodes if n.bl_idname == "ShaderNodeBackground")
    bg.inputs["Color"].default_value = (*color, 1.0)
    bg.inputs["Strength"].default_value = strength


def add_camera(scene, location, target, lens=50.0):
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    scene.collection.objects.link(cam)
    cam.data.lens = lens
    cam.location = location
    direction = (target[0] - location[0], target[1] - location[1], target[2] - location[2])
    from mathutils import Vector

    cam.rotation_euler = Vector(direction).to_track_quat("-Z", "Y").to_euler()
    scene.camera = cam
    return cam


def add_light(scene, kind, location, target=None, energy=10.0, **attrs):
    data = bpy.data.lights.new(kind.title(), kind)
    data.energy = energy
    for k, v in attrs.items():
        setattr(data, k, v)
    ob = bpy.data.objects.new(kind.title(), data)
    scene.collection.objects.link(ob)
    ob.location = location
    if target is not None:
        from mathutils import Vector

        ob.rotation_euler = (Vector(target) - Vector(location)).to_track_quat("-Z", "Y").to_euler()
    return ob


def assign(ob, preset):
    for o in bpy.context.view_layer.objects:
        o.select_set(False)
    ob.select_set(True)
    bpy.context.view_layer.objects.active = ob
    r = bpy.ops.lacquer.assign_paint(preset=preset, new_material=True)
    assert r == {"FINISHED"}, r
    return ob.active_material


def render(scene, engine: str, path: str) -> dict:
    scene.render.engine = engine
    scene.render.filepath = path
    t = time.perf_counter()
    bpy.ops.render.render(write_still=True)
    return {"engine": engine, "file": path, "seconds": time.perf_counter() - t}


def sphere(scene, radius, location=(0.0, 0.0, 0.0)):
    bpy.ops.mesh.primitive_uv_sphere_add(segments=96, ring_count=48, radius=radius, location=location)
    ob = bpy.context.object
    bpy.ops.object.shade_smooth()
    return ob


def scene_compare(size, spp):
    scene = fresh_scene(size, spp)
    set_world(scene, (0.5, 0.5, 0.5))
    ball = sphere(scene, 0.05)
    add_camera(scene, (0.0, -0.5, 0.12), (0.0, 0.0, 0.0), lens=85.0)
    add_light(scene, "AREA", (-0.25, -0.3, 0.35), (0.0, 0.0, 0.0), energy=20.0, shape="RECTANGLE", size=0.2,
              size_y=0.1)
    mat = assign(ball, "gold_flake_8")
    return scene, {"gold_flake_8": mat}


def scene_density(size, spp, preset):
    scene = fresh_scene(size, spp)
    set_world(scene, (0.02, 0.02, 0.02))
    bpy.ops.mesh.primitive_plane_add(size=0.04, location=(0.0, 0.0, 0.0))
    plate = bpy.context.object
    # 2 cm across the frame: 36 mm sensor, lens f, distance d → d = f/36 mm × 2 cm.
    add_camera(scene, (0.0, 0.0, 0.5), (0.0, 0.0, 0.0), lens=900.0)
    sun_dir = (math.sin(math.radians(20.0)), 0.0, math.cos(math.radians(20.0)))
    add_light(scene, "SUN", sun_dir, (0.0, 0.0, 0.0), energy=3.0, angle=math.radians(0.5))
    mat = assign(plate, preset)
    return scene, {preset: mat}


#: Sparkle level of detail (scene_lod): camera distances in metres (lens 900 mm, 36 mm sensor:
#: 128 px see 0.04 × distance; pixel footprint 31 µm at 0.1 m, 1.25 mm at 4 m, for 25 µm flakes).
LOD_DISTANCES = (0.1, 4.0)


def scene_lod(size, spp, distance, lod):
    scene = fresh_scene(size, spp)
    set_world(scene, (0.02, 0.02, 0.02))
    bpy.ops.mesh.primitive_plane_add(size=0.5, location=(0.0, 0.0, 0.0))
    plate = bpy.context.object
    add_camera(scene, (0.0, 0.0, distance), (0.0, 0.0, 0.0), lens=900.0)
    sun_dir = (math.sin(math.radians(20.0)), 0.0, math.cos(math.radians(20.0)))
    add_light(scene, "SUN", sun_dir, (0.0, 0.0, 0.0), energy=3.0, angle=math.radians(0.5))
    mat = assign(plate, "gold_flake_8")
    mat.lacquer.sparkle_lod = lod
    return scene, {"gold_flake_8": mat}


def scene_readme(size, spp):
    scene = fresh_scene(size, spp)
    scene.render.film_transparent = False
    set_world(scene, (0.22, 0.24, 0.27))
    ball = sphere(scene, 0.05, (0.0, 0.0, 0.05))
    bpy.ops.mesh.primitive_plane_add(size=2.0, location=(0.0, 0.0, 0.0))
    floor = bpy.context.object
    fm = bpy.data.materials.new("Floor")
    fm.diffuse_color = (0.18, 0.18, 0.18, 1.0)
    if hasattr(fm, "use_nodes"):
        fm.use_nodes = True
    bsdf = fm.node_tree.nodes.get("Principled BSDF")
    bsdf.inputs["Base Color"].default_value = (0.18, 0.18, 0.18, 1.0)
    bsdf.inputs["Roughness"].default_value = 1.0
    bsdf.inputs["Specular IOR Level"].default_value = 0.0
    floor.data.materials.append(fm)
    add_camera(scene, (0.0, -0.45, 0.16), (0.0, 0.0, 0.045), lens=70.0)
    add_light(scene, "AREA", (-0.3, -0.25, 0.4), (0.0, 0.0, 0.05), energy=4.0, shape="RECTANGLE", size=0.3,
              size_y=0.15)
    add_light(scene, "AREA", (0.35, 0.2, 0.25), (0.0, 0.0, 0.05), energy=1.5, shape="SQUARE", size=0.2)
    mat = assign(ball, "gold_flake_8")
    return scene, {"gold_flake_8": mat}


def diffuse_material(color=(0.8, 0.8, 0.8)):
    m = bpy.data.materials.new("Diffuse")
    if hasattr(m, "use_nodes"):
        m.use_nodes = True
    nt = m.node_tree
    nt.nodes.clear()
    d = nt.nodes.new("ShaderNodeBsdfDiffuse")
    d.inputs["Color"].default_value = (*color, 1.0)
    o = nt.nodes.new("ShaderNodeOutputMaterial")
    nt.links.new(d.outputs[0], o.inputs["Surface"])
    return m


def env_image(path):
    """A small procedural lat-long HDRI (sky gradient, a bright sun patch), saved as .hdr."""
    import numpy as np

    w, h = 128, 64
    img = bpy.data.images.new("lacquer_test_env", w, h, float_buffer=True)
    v = (np.arange(h) + 0.5) / h  # bottom to top
    u = (np.arange(w) + 0.5) / w
    px = np.zeros((h, w, 4), np.float32)
    px[..., 0] = 0.2 + 0.6 * v[:, None]
    px[..., 1] = 0.3 + 0.5 * v[:, None]
    px[..., 2] = 0.5 + 0.4 * v[:, None] * (0.5 + 0.5 * np.cos(2 * np.pi * u[None, :]))
    px[44:52, 20:30, :3] = 20.0
    px[..., 3] = 1.0
    img.pixels.foreach_set(px.reshape(-1))
    img.filepath_raw = path
    img.file_format = "HDR"
    img.save()
    bpy.data.images.remove(img)
    return bpy.data.images.load(path)


LIGHT_CASES = ("point", "point_radius", "spot", "sun", "area", "area_disk", "area_ellipse", "world_color",
               "world_hdri")


def scene_lights(size, spp, case, out):
    scene = fresh_scene(size, spp)
    set_world(scene, (0.0, 0.0, 0.0), 0.0)
    bpy.ops.mesh.primitive_plane_add(size=4.0)
    plate = bpy.context.object
    plate.data.materials.append(diffuse_material())
    # Straight down on the plate; every light stays outside the view (LACQUER's area and sphere
    # lights are surfaces the camera would see, Cycles' are not).
    add_camera(scene, (0.0, 0.0, 3.0), (0.0, 0.0, 0.0), lens=50.0)
    if case == "point":
        add_light(scene, "POINT", (1.0, 0.2, 1.0), energy=100.0, shadow_soft_size=0.0)
    elif case == "point_radius":
        light = add_light(scene, "POINT", (1.0, 0.2, 1.0), energy=100.0, shadow_soft_size=0.15)
        light.data.use_soft_falloff = False
    elif case == "spot":
        add_light(scene, "SPOT", (0.9, 0.0, 1.2), (0.2, 0.1, 0.0), energy=150.0, shadow_soft_size=0.0,
                  spot_size=math.radians(70.0), spot_blend=0.3)
    elif case == "sun":
        add_light(scene, "SUN", (1.0, -0.5, 2.0), (0.0, 0.0, 0.0), energy=2.0, angle=math.radians(2.0))
    elif case == "area":
        add_light(scene, "AREA", (1.3, 0.5, 0.8), (0.0, 0.0, 0.0), energy=60.0, shape="RECTANGLE", size=0.6,
                  size_y=0.3)
    elif case == "area_disk":
        add_light(scene, "AREA", (1.3, 0.5, 0.8), (0.0, 0.0, 0.0), energy=60.0, shape="DISK", size=0.5)
    elif case == "area_ellipse":
        add_light(scene, "AREA", (-1.2, -0.6, 0.7), (0.0, 0.0, 0.0), energy=60.0, shape="ELLIPSE", size=0.7,
                  size_y=0.25)
    elif case == "world_color":
        set_world(scene, (0.3, 0.5, 0.7), 1.5)
    elif case == "world_hdri":
        w = scene.world
        nt = w.node_tree
        bg = next(n for n in nt.nodes if n.bl_idname == "ShaderNodeBackground")
        tex = nt.nodes.new("ShaderNodeTexEnvironment")
        tex.image = env_image(os.path.join(out, "lights_env.hdr"))
        tex.interpolation = "Closest"
        nt.links.new(tex.outputs["Color"], bg.inputs["Color"])
        bg.inputs["Strength"].default_value = 1.0
    else:
        raise SystemExit(f"unknown light case {case}")
    return scene, {}


def scene_instances(size, spp):
    """Collection instances with rotations and non-uniform scales, a two-material cube with a
    modifier and its linked duplicate: transforms, instancing, material slots, evaluated meshes."""
    scene = fresh_scene(size, spp)
    set_world(scene, (0.5, 0.5, 0.5))
    add_light(scene, "SUN", (1.0, -0.6, 1.5), (0.0, 0.0, 0.0), energy=2.0, angle=math.radians(1.0))
    add_camera(scene, (0.0, -9.0, 4.5), (0.0, 0.0, 0.3), lens=35.0)
    proto = bpy.data.collections.new("Proto")
    bpy.ops.mesh.primitive_uv_sphere_add(segments=32, ring_count=16, radius=0.6)
    ball = bpy.context.object
    bpy.ops.object.shade_smooth()
    for c in list(ball.users_collection):
        c.objects.unlink(ball)
    proto.objects.link(ball)
    ball.data.materials.append(diffuse_material((0.7, 0.15, 0.1)))
    for k, (loc, rot, scale) in enumerate((((-2.5, 0.0, 0.6), (0.0, 0.0, 0.0), (1.0, 1.0, 1.0)),
                                           ((-1.2, 1.5, 0.6), (0.4, 0.2, 0.7), (1.6, 0.7, 1.0)),
                                           ((-2.8, 2.2, 1.6), (0.0, 0.9, 0.0), (0.5, 0.5, 0.5)))):
        empty = bpy.data.objects.new(f"Instance{k}", None)
        empty.instance_type = "COLLECTION"
        empty.instance_collection = proto
        empty.location, empty.rotation_euler, empty.scale = loc, rot, scale
        scene.collection.objects.link(empty)
    bpy.ops.mesh.primitive_cube_add(size=1.2, location=(1.5, 0.0, 0.8), rotation=(0.3, 0.2, 0.6))
    cube = bpy.context.object
    cube.scale = (1.0, 1.5, 0.8)
    cube.data.materials.append(diffuse_material((0.1, 0.6, 0.2)))
    cube.data.materials.append(diffuse_material((0.15, 0.25, 0.8)))
    for poly in cube.data.polygons:
        poly.material_index = poly.index % 2
    bevel = cube.modifiers.new("Bevel", "BEVEL")
    bevel.width = 0.1
    bevel.segments = 3
    twin = cube.copy()  # linked duplicate: same mesh data
    twin.location = (2.8, 2.0, 0.9)
    twin.rotation_euler = (0.0, 0.0, -0.5)
    scene.collection.objects.link(twin)
    bpy.ops.mesh.primitive_plane_add(size=12.0)
    bpy.context.object.data.materials.append(diffuse_material((0.5, 0.5, 0.5)))
    return scene, {}


#: The flake-scale scene: (name, world centre x, world width in Blender units) of each plate.
#: Unit Scales (metres per Blender unit) the flake-scale scene is rendered with.
FLAKESCALE_UNITS = (1.0, 0.5)
FLAKESCALE_PLATES = (("fbx_child", -3.75, 2.0), ("plain", -1.25, 2.0), ("instance_half", 1.25, 2.0),
                     ("instance_quarter", 3.5, 1.0))


def scene_flakescale(size, spp, unit_scale):
    """Four plates seen from above by an orthographic camera, one gold_flake_8 material: a 200 cm
    mesh under an FBX-like root empty scaled 0.01 (and turned), a plain 2 m plate (scale 1), and
    two collection instances of one 4 m plate scaled 0.5 and 0.25 by their instancers; the
    scene's Unit Scale is ``unit_scale``. Every plate should get the same flakes per Blender unit."""
    scene = fresh_scene(size, spp)
    scene.unit_settings.scale_length = unit_scale
    set_world(scene, (0.5, 0.5, 0.5))
    cam = add_camera(scene, (0.0, 0.0, 5.0), (0.0, 0.0, 0.0))
    cam.data.type = "ORTHO"
    cam.data.ortho_scale = 10.0
    scene.render.resolution_x, scene.render.resolution_y = size, size // 4
    bpy.ops.mesh.primitive_plane_add(size=2.0, location=(-1.25, 0.0, 0.0))
    plain = bpy.context.object
    mat = assign(plain, "gold_flake_8")
    root = bpy.data.objects.new("FBX root", None)
    root.scale = (0.01, 0.01, 0.01)
    root.rotation_euler = (0.0, 0.0, 0.3)
    root.location = (-3.75, 0.0, 0.0)
    scene.collection.objects.link(root)
    bpy.ops.mesh.primitive_plane_add(size=200.0)  # centimetres, as an FBX in cm stores them
    child = bpy.context.object
    child.parent = root
    child.rotation_euler = (0.0, 0.0, -0.3)  # square to the camera again
    child.data.materials.append(mat)
    proto = bpy.data.collections.new("Plate proto")
    bpy.ops.mesh.primitive_plane_add(size=4.0)
    plate = bpy.context.object
    for c in list(plate.users_collection):
        c.objects.unlink(plate)
    proto.objects.link(plate)
    plate.data.materials.append(mat)
    for name, x, width in FLAKESCALE_PLATES[2:]:
        empty = bpy.data.objects.new(name, None)
        empty.instance_type = "COLLECTION"
        empty.instance_collection = proto
        empty.scale = (width / 4.0,) * 3
        empty.location = (x, 0.0, 0.0)
        scene.collection.objects.link(empty)
    return scene, {"gold_flake_8": mat}


def flake_coordinate_material(mat):
    """A copy of ``mat`` whose copy of the node group emits the metallic flakes' Voronoi input
    coordinate (metres on the object) instead of the paint: the cells Cycles cuts, readable."""
    probe = mat.copy()
    node = probe.node_tree.nodes["Lacquer Paint"]
    group = node.node_tree.copy()
    node.node_tree = group
    vors = [n for n in group.nodes if n.bl_idname == "ShaderNodeTexVoronoi"]
    # The metallic layer's Voronoi reads P itself; the pearls' reads P + an offset (ADD).
    flake = [v for v in vors if v.inputs["Vector"].links[0].from_node.operation != "ADD"]
    assert len(vors) == 2 and len(flake) == 1, [v.inputs["Vector"].links[0].from_node.operation for v in vors]
    coord = flake[0].inputs["Vector"].links[0].from_socket
    em = group.nodes.new("ShaderNodeEmission")
    group.links.new(coord, em.inputs["Color"])
    out = next(n for n in group.nodes if n.bl_idname == "NodeGroupOutput")
    group.links.new(em.outputs[0], out.inputs[0])
    return probe


def lacquer_flake_scale(scene) -> dict:
    """What LACQUER's export hands the renderer for each plate: the sparkle uv's metres per world
    Blender unit (the singular values of d uv / d world position on every triangle, × the
    material's surface_scale_mm / 1000 m). Plates are told apart by their world x."""
    import importlib

    export = importlib.import_module(ADDON + ".export")
    import numpy as np

    def arr(b64, dtype, cols):
        import base64

        return np.frombuffer(base64.b64decode(b64[len("base64:"):]), dtype=np.dtype(dtype).newbyteorder("<")) \
            .reshape(-1, cols).astype(np.float64)

    depsgraph = bpy.context.evaluated_depsgraph_get()
    desc = export.scene_desc(depsgraph, scene.render.resolution_x, scene.render.resolution_y, export.Report(), [])
    out = {}
    for ob in desc["objects"]:
        mesh = desc["meshes"][ob["mesh"]]
        m = np.array(ob["transform"]["matrix"], np.float64)
        p = arr(mesh["positions"], np.float32, 3) @ m[:3, :3].T + m[:3, 3]
        uv = arr(mesh["uvs"], np.float32, 2) * ob["material"]["surface_scale_mm"] / 1000.0
        p, uv = p.reshape(-1, 3, 3), uv.reshape(-1, 3, 2)
        sv = []
        for e, f in zip(p[:, 1:] - p[:, :1], uv[:, 1:] - uv[:, :1]):
            sv.extend(np.linalg.svd(f.T @ np.linalg.pinv(e.T), compute_uv=False).tolist())
        name = min(FLAKESCALE_PLATES, key=lambda t: abs(t[1] - p[..., 0].mean()))[0]  # renderer x = Blender x
        out[name] = {"metres_per_unit_min": min(sv), "metres_per_unit_max": max(sv)}
    return out


def scene_principled(size, spp):
    scene = fresh_scene(size, spp)
    set_world(scene, (0.5, 0.5, 0.5))
    add_camera(scene, (0.0, -0.5, 0.12), (0.0, 0.0, 0.0), lens=85.0)
    add_light(scene, "AREA", (-0.25, -0.3, 0.35), (0.0, 0.0, 0.0), energy=20.0, shape="RECTANGLE", size=0.2,
              size_y=0.1)
    ball = sphere(scene, 0.05)
    m = bpy.data.materials.new("Principled red coat")
    if hasattr(m, "use_nodes"):
        m.use_nodes = True
    p = m.node_tree.nodes.get("Principled BSDF")
    p.inputs["Base Color"].default_value = (0.6, 0.05, 0.04, 1.0)
    p.inputs["Roughness"].default_value = 0.35
    p.inputs["Coat Weight"].default_value = 1.0
    p.inputs["Coat Roughness"].default_value = 0.1
    ball.data.materials.append(m)
    return scene, {}


class _Layout:
    """Records what a panel draws (a stand-in for bpy's UILayout, which needs a window)."""

    def __init__(self, log):
        self.log = log
        self.use_property_split = False

    def _sub(self, *a, **k):
        return _Layout(self.log)

    row = column = box = _sub

    def prop(self, data, name, **k):
        getattr(data, name)  # raises if the property does not exist
        self.log.append(("prop", name))

    def label(self, text="", **k):
        self.log.append(("label", text))

    def menu(self, menu, **k):
        assert hasattr(bpy.types, menu), menu
        self.log.append(("menu", menu))

    def operator(self, op, **k):
        self.log.append(("operator", op))

        class _Props:
            pass

        return _Props()

    def separator(self, **k):
        pass


def ui_smoke(mat) -> dict:
    """Draws the extension's panels and menu into a recording layout: every property, menu and
    operator they name exists."""
    import importlib

    ui = importlib.import_module(ADDON + ".ui")
    ops = importlib.import_module(ADDON + ".operators")

    class Ctx:
        material = mat
        object = bpy.context.object
        scene = bpy.context.scene
        engine = "LACQUER"

    log: list = []
    for cls in (ui.MATERIAL_PT_lacquer, ui.RENDER_PT_lacquer, ops.LACQUER_MT_presets):
        cls.draw(type("P", (), {"layout": _Layout(log)})(), Ctx)
    return {"ui_items": len(log), "ui_props": sorted({n for k, n in log if k == "prop"})}


def auto_update_smoke(mat) -> dict:
    """Editing a paint parameter refits the node group (background mode: at once); re-applying
    the preset restores it."""
    node = mat.node_tree.nodes["Lacquer Paint"]
    before = node.inputs["Flake Coverage"].default_value
    preset = mat.lacquer.preset
    mat.lacquer.flake_density = 2.0
    after = node.inputs["Flake Coverage"].default_value
    modified = mat.lacquer.modified
    bpy.ops.lacquer.apply_preset(preset=preset, material=mat.name)
    return {"coverage_before": before, "coverage_after_edit": after, "modified": modified,
            "coverage_restored": node.inputs["Flake Coverage"].default_value,
            "modified_after_reapply": mat.lacquer.modified}


def _addon_module(name):
    return sys.modules[f"{ADDON}.{name}"]


def _stats(path):
    import numpy as np

    im = bpy.data.images.load(path)
    w, h = im.size
    px = np.empty(w * h * im.channels, np.float32)
    im.pixels.foreach_get(px)
    bpy.data.images.remove(im)
    return px.reshape(h, w, -1)


def compositor(scene, source: str, denoise: bool):
    """Render Layers → (Denoise with Image, Denoising Normal, Denoising Albedo) → the
    compositor's output (Blender 4.5: scene.node_tree and a Composite node; 5.0: a compositor
    node group), or the pass ``source`` straight to the output. Returns the Render Layers
    node's output names."""
    if bpy.app.version >= (5, 0, 0):
        tree = bpy.data.node_groups.new("Lacquer compositor", "CompositorNodeTree")
        tree.interface.new_socket("Image", in_out="OUTPUT", socket_type="NodeSocketColor")
        scene.compositing_node_group = tree
        out = tree.nodes.new("NodeGroupOutput")
    else:
        scene.use_nodes = True
        tree = scene.node_tree
        tree.nodes.clear()
        out = tree.nodes.new("CompositorNodeComposite")
    rl = tree.nodes.new("CompositorNodeRLayers")
    rl.scene = scene
    outputs = [o.name for o in rl.outputs]
    if denoise:
        dn = tree.nodes.new("CompositorNodeDenoise")
        tree.links.new(rl.outputs["Image"], dn.inputs["Image"])
        tree.links.new(rl.outputs["Denoising Normal"], dn.inputs["Normal"])
        tree.links.new(rl.outputs["Denoising Albedo"], dn.inputs["Albedo"])
        tree.links.new(dn.outputs[0], out.inputs[0])
    else:
        tree.links.new(rl.outputs[source], out.inputs[0])
    return outputs


def disable_compositor(scene):
    if bpy.app.version >= (5, 0, 0):
        scene.compositing_node_group = None
    else:
        scene.use_nodes = False


def engine_smoke(out: str, size: int) -> dict:
    """LACQUER as a production engine (issue 15 item 6): progressive rounds, passes in a
    multilayer EXR, the compositor's Denoise node on them, Esc (test_break) cancelling promptly,
    and the viewport's pixel buffer (view_draw needs a GPU context, which headless bpy lacks)."""
    engine = _addon_module("engine")
    viewport = _addon_module("viewport")
    export = _addon_module("export")
    rep: dict = {}
    scene, mats = scene_compare(size, 16)
    # Progressive render with passes, saved as a multilayer EXR.
    r = render(scene, "LACQUER", os.path.join(out, "engine_combined.exr"))
    rep["passes_render"] = dict(engine.LAST_RENDER, seconds_total=r["seconds"])
    # Each pass through the compositor to an EXR (Blender 5.0.1's multilayer EXR keeps only
    # Combined of a Python engine's result, 4.5 keeps them all: the compositor works in both).
    for name, tag in (("Denoising Albedo", "albedo"), ("Denoising Normal", "normal")):
        compositor(scene, name, denoise=False)
        render(scene, "LACQUER", os.path.join(out, f"engine_{tag}.exr"))
    disable_compositor(scene)
    # Diffuse Color and Glossy Color (the view layer's Cycles flags): gold_flake_8, then the
    # solid red (no flakes: its glossy colour is the clearcoat's reflection alone), each pass
    # through the compositor; Combined of a one-bounce render in a uniform world (no lamp)
    # for the Diffuse + Glossy = Combined check.
    vl = scene.view_layers[0]
    vl.use_pass_diffuse_color = vl.use_pass_glossy_color = True
    lamps = [o for o in scene.objects if o.type == "LIGHT"]
    for o in lamps:
        o.hide_render = True
    depth = scene.lacquer.max_depth
    scene.lacquer.max_depth = 1
    rep["lobe_passes"] = {}
    ball = next(o for o in scene.objects if o.type == "MESH")
    for preset in ("gold_flake_8", "solid_red"):
        assign(ball, preset)
        for name in ("DiffCol", "GlossCol"):
            compositor(scene, name, denoise=False)
            render(scene, "LACQUER", os.path.join(out, f"engine_{preset}_{name}.exr"))
        disable_compositor(scene)
        render(scene, "LACQUER", os.path.join(out, f"engine_{preset}_lobes_combined.exr"))
        rep["lobe_passes"][preset] = dict(engine.LAST_RENDER)
    for o in lamps:
        o.hide_render = False
    vl.use_pass_diffuse_color = vl.use_pass_glossy_color = False
    assign(ball, "gold_flake_8")
    scene.lacquer.max_depth = depth
    # The Denoise node on LACQUER's passes (noisy input at 4 spp), sparkle off: per-pixel flake
    # glints are image detail a denoiser should not be judged on; the MC noise of the mean lobe is.
    scene.lacquer.samples = 4
    scene.lacquer.sparkle = False
    r = render(scene, "LACQUER", os.path.join(out, "engine_noisy.exr"))
    scene.lacquer.samples = 256
    render(scene, "LACQUER", os.path.join(out, "engine_reference.exr"))
    scene.lacquer.samples = 4
    rep["rl_outputs"] = compositor(scene, "Image", denoise=True)
    r = render(scene, "LACQUER", os.path.join(out, "engine_denoised.exr"))
    rep["denoise_render"] = dict(engine.LAST_RENDER, seconds_total=r["seconds"])
    disable_compositor(scene)
    scene.lacquer.sparkle = True
    # Esc: test_break answering True from the start; a 4096-spp render must stop at once.
    scene.lacquer.samples = 4096
    # (Esc → test_break is Blender's; the engine asks through engine._break_requested)
    original = engine._break_requested
    engine._break_requested = lambda eng: True
    try:
        t = time.perf_counter()
        bpy.ops.render.render(write_still=False)
        rep["cancel"] = dict(engine.LAST_RENDER, wall_seconds=time.perf_counter() - t)
    finally:
        engine._break_requested = original
    scene.lacquer.samples = 16
    # The viewport: the job a viewport looking through the scene camera makes, rendered by the
    # worker in stages; the buffer view_draw uploads.
    scene.lacquer.preview_samples = 8
    depsgraph = bpy.context.evaluated_depsgraph_get()
    w, h = size, size * 3 // 4
    cam = scene.camera
    view = cam.matrix_world.inverted()
    proj = cam.calc_matrix_camera(depsgraph, x=w, y=h)
    job, temp = engine.viewport_job(depsgraph, w, h, view, proj, export.Report())
    render_cam = export.camera_desc(cam, w, h, export.Report())
    rep["viewport_camera"] = {"viewport": job["scene"]["camera"], "render": render_cam}
    t = time.perf_counter()
    v = viewport.ViewportRender(job, job["spp"]).start()
    first = None
    while first is None and time.perf_counter() - t < 30:
        first = v.latest()
        time.sleep(0.005)
    rep_first = time.perf_counter() - t
    v.wait(60)
    rgba, samples = v.latest()
    buf = viewport.display_buffer(rgba)
    rep["viewport"] = {"history": v.history, "error": v.error, "done": v.done, "first_image_seconds": rep_first,
                       "final_shape": list(rgba.shape), "final_samples": samples, "buffer_len": int(buf.size),
                       "buffer_mean": float(buf.reshape(-1, 4)[:, :3].mean()),
                       "buffer_finite": bool(__import__("numpy").isfinite(buf).all())}
    try:
        import gpu

        gpu.types.GPUTexture((w, h), format="RGBA16F", data=gpu.types.Buffer("FLOAT", buf.size, buf))
        rep["viewport"]["gpu"] = "texture created"
    except Exception as e:  # noqa: BLE001  (headless: no GPU context)
        rep["viewport"]["gpu"] = f"unavailable headless: {e}"
    # A stopped viewport render stops within the core's progress interval.
    v2 = viewport.ViewportRender(dict(job, spp=4096), 4096).start()
    time.sleep(0.3)
    t = time.perf_counter()
    v2.stop()
    rep["viewport"]["stop_seconds"] = time.perf_counter() - t
    for f in temp:
        os.remove(f)
    return rep


def _normal_map_image(n=64, waves=4, tilt=0.4):
    """A tangent-space normal map (Non-Color float image): stripes along u, the normal tilted
    toward the tangent by ``tilt · sin(2π waves u)`` radians."""
    import numpy as np

    u = (np.arange(n) + 0.5) / n
    theta = tilt * np.sin(2 * np.pi * waves * u)
    rgba = np.ones((n, n, 4), np.float32)
    rgba[..., 0] = 0.5 * (np.sin(theta)[None, :] + 1.0)
    rgba[..., 1] = 0.5
    rgba[..., 2] = 0.5 * (np.cos(theta)[None, :] + 1.0)
    img = bpy.data.images.new("lacquer test normal map", n, n, float_buffer=True, alpha=True)
    img.colorspace_settings.name = "Non-Color"
    img.pixels.foreach_set(rgba.reshape(-1))
    img.pack()
    return img


#: The two colours of the textured-parameter smoke's image (left half, right half; linear).
TEXTURE_COLORS = ((0.70, 0.12, 0.05), (0.06, 0.22, 0.60))


#: Lengths set through the metric properties: property → (metres, the core's name, core units).
LENGTH_CASES = {"flake_size": (23e-6, "flake_size_um", 23.0), "pearl_size": (17.5e-6, "pearl_size_um", 17.5),
                "pearl_film": (150e-9, "pearl_film_nm", 150.0),
                "coat_thickness": (41.3e-6, "coat_thickness_um", 41.3)}


def _lengths_smoke(scene, mat, node, export) -> dict:
    """Lengths are metric properties (DISTANCE / LENGTH) whatever the scene's unit system: set in
    metres under metric (adaptive) and imperial units, they reach the core's JSON, the LACQUER
    export and the node group in the core's units unchanged; the scene's units show them."""
    props = _addon_module("props")
    saved = {k: getattr(mat.lacquer, k) for k in LENGTH_CASES}
    saved_peel = (mat.lacquer.orange_peel, mat.lacquer.orange_peel_wavelength)
    units = scene.unit_settings
    before = (units.system, units.length_unit, units.scale_length)
    rep = {"subtypes": {k: [mat.lacquer.bl_rna.properties[k].subtype, mat.lacquer.bl_rna.properties[k].unit]
                        for k in list(LENGTH_CASES) + ["orange_peel", "orange_peel_wavelength"]},
           "old_names_gone": [k for _, k, _ in LENGTH_CASES.values() if k in mat.lacquer.bl_rna.properties],
           "systems": {}}
    for system, length_unit, scale in (("METRIC", "ADAPTIVE", 1.0), ("METRIC", "MICROMETERS", 1.0),
                                       ("IMPERIAL", "ADAPTIVE", 1.0), ("METRIC", "CENTIMETERS", 0.01)):
        units.system, units.length_unit, units.scale_length = system, length_unit, scale
        # In scene units, as the panel writes them (a typed "23 µm" is 23e-6 / Unit Scale).
        for k, (metres, _, _) in LENGTH_CASES.items():
            setattr(mat.lacquer, k, metres / scale)
        mat.lacquer.orange_peel = 0.75e-6 / scale
        mat.lacquer.orange_peel_wavelength = 4.5e-3 / scale
        desc = export.material_desc(mat, export.Report())
        js = props.material_json(mat.lacquer)
        rep["systems"][f"{system}/{length_unit}"] = {
            "json": {core: js[core] for _, core, _ in LENGTH_CASES.values()},
            "export": {core: desc[core] for _, core, _ in LENGTH_CASES.values()},
            "expected": {core: v for _, core, v in LENGTH_CASES.values()},
            "node_flake_size": node.inputs["Flake Size"].default_value,
            "node_orange_peel": [node.inputs["Orange Peel"].default_value,
                                 node.inputs["Orange Peel Wavelength"].default_value],
            # What the panel shows: the property (scene units) × Unit Scale in the unit system.
            "shown": bpy.utils.units.to_string(system, "LENGTH", mat.lacquer.flake_size * units.scale_length),
        }
        rep["systems"][f"{system}/{length_unit}"]["key"] = f"{system}/{length_unit}/{scale:g}"
    units.system, units.length_unit, units.scale_length = before
    for k, v in saved.items():
        setattr(mat.lacquer, k, v)
    mat.lacquer.orange_peel, mat.lacquer.orange_peel_wavelength = saved_peel
    rep["restored_flake_size_um"] = props.material_json(mat.lacquer)["flake_size_um"]
    return rep


def _texture_smoke(out, scene, mat, node, export) -> dict:
    """Textured parameters (issue 15 item 3): a two-colour Image Texture (left half, right half
    of the plate's UV map) on the Lacquer node's Base Color renders in LACQUER and Cycles; the
    same scene is rendered untextured with each colour as the paint's base colour, in both
    engines, for the test to compare the halves. Also the export: the image is a scene image,
    the material binds it, the mesh has texture uvs; and a link LACQUER cannot follow is named."""
    import numpy as np

    nodegroup = _addon_module("nodegroup")
    rep: dict = {}
    t = time.perf_counter()
    mat.lacquer.sparkle = False  # the mean lobe in both engines (Cycles per-cell flakes are noise at 16 spp)
    nodegroup.update_material(mat)
    n = 16
    rgba = np.ones((n, n, 4), np.float32)
    rgba[:, : n // 2, :3] = TEXTURE_COLORS[0]
    rgba[:, n // 2:, :3] = TEXTURE_COLORS[1]
    img = bpy.data.images.new("lacquer test halves", n, n, float_buffer=True, alpha=True)
    img.colorspace_settings.name = "Linear Rec.709" if bpy.app.version >= (4, 0, 0) else "Linear"
    img.pixels.foreach_set(rgba.reshape(-1))
    img.pack()
    tree = mat.node_tree
    tex = tree.nodes.new("ShaderNodeTexImage")
    tex.image = img
    tree.links.new(tex.outputs["Color"], node.inputs["Base Color"])
    report = export.Report()
    job = export.job(bpy.context.evaluated_depsgraph_get(), report, [])
    paint = [o["material"] for o in job["scene"]["objects"] if o["material"].get("model") == "coated_paint"]
    rep["exported"] = {"images": sorted(job["scene"].get("images", {})),
                       "textures": paint[0].get("textures") if paint else None,
                       "texture_uvs": any("texture_uvs" in m for m in job["scene"]["meshes"].values()),
                       "messages": report.lines()}
    for engine in ("LACQUER", "CYCLES"):
        render(scene, engine, os.path.join(out, f"texture_halves_{engine.lower()}.exr"))
    tree.links.remove(node.inputs["Base Color"].links[0])
    base = list(mat.lacquer.base_color)
    for k, color in enumerate(TEXTURE_COLORS):
        mat.lacquer.base_color = color
        nodegroup.update_material(mat)
        for engine in ("LACQUER", "CYCLES"):
            render(scene, engine, os.path.join(out, f"texture_plain{k}_{engine.lower()}.exr"))
    mat.lacquer.base_color = base
    # The same image on Flake Density and Coat Roughness (export only): Cycles' colour → float
    # (luminance), and Coat Roughness squared to α (or a message on a smooth coat).
    tree.links.new(tex.outputs["Color"], node.inputs["Flake Density"])
    tree.links.new(tex.outputs["Color"], node.inputs["Coat Roughness"])
    report = export.Report()
    job = export.job(bpy.context.evaluated_depsgraph_get(), report, [])
    paint = [o["material"] for o in job["scene"]["objects"] if o["material"].get("model") == "coated_paint"]
    textures = paint[0].get("textures", {})

    def first_texels(key):
        b = textures.get(key)
        if b is None:
            return None
        data = job["scene"]["images"][b["image"]]["pixels"]
        px = np.frombuffer(__import__("base64").b64decode(data[len("base64:"):]), "<f4").reshape(-1, 3)
        return [float(px[0, 0]), float(px[n // 2, 0]), float(px[n - 1, 0])]  # row 0: texels 0, 8 (right half), 15

    rep["scalars"] = {"keys": sorted(textures), "flake_density": first_texels("flake_density"),
                      "coat_roughness": first_texels("coat_roughness"), "paint_coat_roughness":
                      float(mat.lacquer.coat_roughness), "messages": report.lines()}
    tree.links.remove(node.inputs["Flake Density"].links[0])
    tree.links.remove(node.inputs["Coat Roughness"].links[0])
    # A link LACQUER does not follow (a colour node on Base Color) is reported, never dropped silently.
    rgb = tree.nodes.new("ShaderNodeRGB")
    tree.links.new(rgb.outputs[0], node.inputs["Base Color"])
    report = export.Report()
    export.job(bpy.context.evaluated_depsgraph_get(), report, [])
    rep["unfollowed_link_messages"] = report.lines()
    tree.links.remove(node.inputs["Base Color"].links[0])
    nodegroup.update_material(mat)
    rep["seconds"] = time.perf_counter() - t
    return rep


def artist_smoke(out: str, size: int) -> dict:
    """Artist controls (issue 15 item 2): a normal map on the node's Normal input renders in
    both engines (their shading normals compared through the Normal / Denoising Normal passes),
    orange peel tilts the coat (LACQUER's normal pass against the height field's predicted RMS
    slope; Cycles' image changes), Flake Scale reaches both engines, angles are shown in degrees
    and the fit error reads as text."""
    import numpy as np

    export = _addon_module("export")
    catalog = _addon_module("catalog")
    rep: dict = {}
    scene = fresh_scene(size, 16)
    set_world(scene, (0.3, 0.3, 0.3))
    bpy.ops.mesh.primitive_plane_add(size=0.04, location=(0.0, 0.0, 0.0))
    plate = bpy.context.object
    add_camera(scene, (0.0, 0.0, 0.5), (0.0, 0.0, 0.0), lens=900.0)  # 2 cm across the frame
    sun_dir = (math.sin(math.radians(20.0)), 0.0, math.cos(math.radians(20.0)))
    add_light(scene, "SUN", sun_dir, (0.0, 0.0, 0.0), energy=3.0, angle=math.radians(0.5))
    mat = assign(plate, "gold_flake_8")
    node = mat.node_tree.nodes["Lacquer Paint"]
    node.inputs["Sparkle"].default_value = 0.0  # mean lobe: flake normals = the paint's normal
    scene.lacquer.sparkle = False
    scene.view_layers[0].use_pass_normal = True

    def passes(tag, cycles=True):
        scene.render.engine = "LACQUER"  # the Render Layers node lists the engine's passes
        compositor(scene, "Denoising Normal", denoise=False)
        render(scene, "LACQUER", os.path.join(out, f"artist_{tag}_lacquer_normal.exr"))
        disable_compositor(scene)
        render(scene, "LACQUER", os.path.join(out, f"artist_{tag}_lacquer.exr"))
        if cycles:
            scene.render.engine = "CYCLES"
            compositor(scene, "Normal", denoise=False)
            render(scene, "CYCLES", os.path.join(out, f"artist_{tag}_cycles_normal.exr"))
            disable_compositor(scene)
            render(scene, "CYCLES", os.path.join(out, f"artist_{tag}_cycles.exr"))

    t = time.perf_counter()
    passes("plain")
    # Image Texture (Non-Color) → Normal Map (tangent space, the plane's UV map) → Normal.
    tree = mat.node_tree
    tex = tree.nodes.new("ShaderNodeTexImage")
    tex.image = _normal_map_image()
    nm = tree.nodes.new("ShaderNodeNormalMap")
    nm.space = "TANGENT"
    nm.uv_map = plate.data.uv_layers[0].name
    tree.links.new(tex.outputs["Color"], nm.inputs["Color"])
    tree.links.new(nm.outputs["Normal"], node.inputs["Normal"])
    report = export.Report()
    job = export.job(bpy.context.evaluated_depsgraph_get(), report, [])
    rep["normal_map_exported"] = any("normal_map" in m for m in job["scene"]["meshes"].values())
    rep["normal_map_messages"] = report.lines()
    passes("normalmap")
    tree.links.remove(node.inputs["Normal"].links[0])
    # The same map on Coat Normal only: LACQUER shades the coat's reflection in the mapped frame
    # and the paint under it in the plate's (two frames), as Cycles' Principled Coat Normal.
    tree.links.new(nm.outputs["Normal"], node.inputs["Coat Normal"])
    report = export.Report()
    job = export.job(bpy.context.evaluated_depsgraph_get(), report, [])
    rep["coat_normal_exported"] = [sorted(m.get("coat_normal", {})) for m in job["scene"]["meshes"].values()]
    rep["coat_normal_base_map"] = any("normal_map" in m for m in job["scene"]["meshes"].values())
    rep["coat_normal_messages"] = report.lines()
    passes("coatnormal")
    tree.links.remove(node.inputs["Coat Normal"].links[0])
    # Image Texture (Non-Color heights, stripes along u) → Bump (Height) → Normal: the plate is
    # 0.04 units across its UV map, h = ½ + ½ sin(2π 4 u) has slope up to 2π·2/0.04 = 314 per
    # unit, × Distance 0.001: tilts up to atan(0.314) = 17°.
    n = 64
    u = (np.arange(n) + 0.5) / n
    hgt = np.ones((n, n, 4), np.float32)
    hgt[..., :3] = (0.5 + 0.5 * np.sin(2 * np.pi * 4 * u))[None, :, None]
    himg = bpy.data.images.new("lacquer test heights", n, n, float_buffer=True, alpha=True)
    himg.colorspace_settings.name = "Non-Color"
    himg.pixels.foreach_set(hgt.reshape(-1))
    himg.pack()
    htex = tree.nodes.new("ShaderNodeTexImage")
    htex.image = himg
    bump = tree.nodes.new("ShaderNodeBump")
    bump.inputs["Distance"].default_value = 0.001
    tree.links.new(htex.outputs["Color"], bump.inputs["Height"])
    tree.links.new(bump.outputs["Normal"], node.inputs["Normal"])
    report = export.Report()
    job = export.job(bpy.context.evaluated_depsgraph_get(), report, [])
    rep["bump_exported"] = any("bump" in m for m in job["scene"]["meshes"].values())
    rep["bump_messages"] = report.lines()
    passes("bump")
    tree.links.remove(node.inputs["Normal"].links[0])
    # Orange peel: 50 µm RMS at 8 mm (exaggerated to be measurable at 64², 0.3 mm per pixel).
    mat.lacquer.orange_peel = 50e-6
    mat.lacquer.orange_peel_wavelength = 8e-3
    rep["peel_node_inputs"] = [node.inputs["Orange Peel"].default_value,
                               node.inputs["Orange Peel Wavelength"].default_value]
    job = export.job(bpy.context.evaluated_depsgraph_get(), export.Report(), [])
    rep["peel_exported"] = [{k: m["coat_normal"]["orange_peel"][k] for k in ("amplitude_um", "wavelength_mm")}
                            | {"follows_normal": m["coat_normal"]["follows_normal"], "base_keys": sorted(m)}
                            for m in job["scene"]["meshes"].values() if "coat_normal" in m]
    passes("peel")
    mat.lacquer.orange_peel = 0.0
    # The orange-peel waves' predicted RMS slope on this plane (the xy plane of the object):
    # A k √(Σ |d_xy|² / K) (each wave's gradient a k cos(·) d, a = A √(2/K)).
    ng = _addon_module("nodegroup")
    dxy2 = sum(d[0] ** 2 + d[1] ** 2 for d, _ in ng.PEEL_WAVES) / len(ng.PEEL_WAVES)
    rep["peel_predicted_rms_slope"] = 50e-6 * 2 * math.pi / 8e-3 * math.sqrt(dxy2)
    # Flake Scale: the node group's input and LACQUER's sparkle scale.
    mat.lacquer.flake_scale = 2.0
    job = export.job(bpy.context.evaluated_depsgraph_get(), export.Report(), [])
    paint = [o["material"] for o in job["scene"]["objects"] if o["material"].get("model") == "coated_paint"]
    rep["flake_scale"] = {"node": node.inputs["Flake Scale"].default_value,
                          "surface_scale_mm": paint[0]["surface_scale_mm"]}
    mat.lacquer.flake_scale = 1.0
    # Units and readable text.
    prop = mat.lacquer.bl_rna.properties["flake_orientation_deg"]
    rep["angle"] = {"subtype": prop.subtype, "unit": prop.unit,
                    "json_deg": _addon_module("props").material_json(mat.lacquer)["flake_orientation_deg"],
                    "preset_deg": catalog.preset("gold_flake_8")["flake_orientation_deg"]}
    rep["fit_text"] = catalog.fit_quality_lines(json.loads(mat.lacquer.fit_error))
    rep["lengths"] = _lengths_smoke(scene, mat, node, export)
    rep["texture"] = _texture_smoke(out, scene, mat, node, export)
    rep["seconds"] = time.perf_counter() - t
    del np
    return rep


def assets_smoke(out: str, size: int) -> dict:
    """The bundled asset library (issue 15 item 1): registered in the preferences, one asset per
    preset in its catalogue with a core-rendered preview, and an appended asset on an object is a
    working Lacquer paint (parameters, node group, LACQUER render)."""
    import numpy as np

    assets = _addon_module("assets")
    catalog = _addon_module("catalog")
    export = _addon_module("export")
    props = _addon_module("props")
    ng = _addon_module("nodegroup")
    rep: dict = {}
    lib = assets.find_library()
    rep["library"] = {"registered": lib is not None, "name": lib.name if lib else None,
                      "blend": assets.library_blend()}
    blend = assets.library_blend()
    with bpy.data.libraries.load(blend, assets_only=True) as (src, _dst):
        rep["asset_materials"] = sorted(src.materials)
    rep["preset_labels"] = sorted(label for _, label, _, _ in catalog.presets())
    cats = open(os.path.join(assets.library_dir(), "blender_assets.cats.txt")).read()
    rep["catalogs"] = [line.split(":")[1] for line in cats.splitlines() if line and line[0] not in "#V"]
    # Headless bpy makes no UI icons (icon_id 0); the previews' images load all the same.
    rep["previews"] = {name: list(assets.preview(name).image_size) if assets.preview(name) else None
                       for name, _, _, _ in catalog.presets()}
    rep["icon_ids"] = [assets.icon(name) for name, _, _, _ in catalog.presets()]
    rep["background"] = bpy.app.background
    scene = fresh_scene(size, 16)
    add_light(scene, "SUN", (0.3, -0.5, 1.0), (0.0, 0.0, 0.0), energy=3.0)
    set_world(scene, (0.2, 0.2, 0.2))
    ball = sphere(scene, 0.05)
    add_camera(scene, (0.0, -0.5, 0.12), (0.0, 0.0, 0.0), lens=85.0)
    per_preset = {}
    for name in ("gold_flake_8", "pearl_blue", "solid_red"):
        mat = assets.append_material(name)
        ball.data.materials.clear()
        ball.data.materials.append(mat)
        node = mat.node_tree.nodes.get(ng.NODE_NAME)
        got = props.material_json(mat.lacquer)
        want = dict(catalog.preset(name))
        same = all(abs(got[k] - v) < 1e-4 if isinstance(v, float) else
                   (np.allclose(got[k], v, atol=1e-4) if isinstance(v, list) else got[k] == v)
                   for k, v in want.items() if k in got)
        cat_path = next((p for p in catalog.ASSET_CATALOGS if mat.asset_data is not None and
                         catalog.catalog_uuid(p) == mat.asset_data.catalog_id), None)
        job = export.job(bpy.context.evaluated_depsgraph_get(), export.Report(), [])
        models = [o["material"].get("model") for o in job["scene"]["objects"]]
        path = os.path.join(out, f"assets_{name}_lacquer.exr")
        render(scene, "LACQUER", path)
        img = _stats(path)
        pv = mat.preview
        pix = np.empty(pv.image_size[0] * pv.image_size[1] * 4, np.float32)
        pv.image_pixels_float.foreach_get(pix)
        per_preset[name] = {
            "enabled": mat.lacquer.enabled, "preset": mat.lacquer.preset, "params_match": bool(same),
            "group": node.node_tree.name if node is not None else None,
            "group_version": node.node_tree.get("lacquer_version") if node is not None else None,
            "expected_group_version": _addon_module("nodegroup").NODE_GROUP_VERSION,
            "fit_inputs": bool(mat.lacquer.fit_inputs), "coverage": node.inputs["Flake Coverage"].default_value,
            "expected_coverage": json.loads(mat.lacquer.fit_inputs).get("Flake Coverage"),
            "catalog": cat_path, "expected_catalog": catalog.asset_catalog(name), "models": models,
            "lacquer_mean": float(img[..., :3].mean()), "preview_size": list(pv.image_size),
            "preview_mean": float(pix.reshape(-1, 4)[:, :3].mean()) if pix.size else 0.0}
    rep["applied"] = per_preset
    rep["local_groups"] = [g.name for g in bpy.data.node_groups if g.name.startswith(ng.GROUP_NAME)]
    return rep


def editing_smoke(out: str, size: int) -> dict:
    """Editing that does not freeze (issue 15 item 7) and errors that lose nothing (issue 16
    item 7): a refit on the worker thread applied by the timer, keyframed paint parameters
    refitted on frame change, old node groups upgraded on load, linked ones left alone, bad
    edits refused with the previous paint kept."""
    import threading

    props = _addon_module("props")
    nodegroup = _addon_module("nodegroup")
    export = _addon_module("export")
    import lacquer

    rep: dict = {}
    scene, mats = scene_compare(size, 4)
    mat = mats["gold_flake_8"]
    node = mat.node_tree.nodes["Lacquer Paint"]
    cov = lambda: node.inputs["Flake Coverage"].default_value  # noqa: E731

    def fitted(density):
        m = dict(json.loads(mat.lacquer.fit_material), flake_density=density)
        return lacquer.fit_node_group(m)["inputs"]["Flake Coverage"]

    # 1. Asynchronous refit: the edit returns at once, the fit runs on "lacquer-refit", the
    #    timer applies it (and pushes an undo step where an undo system exists).
    props.ASYNC_REFITS = True
    try:
        before = cov()
        t = time.perf_counter()
        mat.lacquer.flake_density = 3.7  # a value no earlier fit has cached
        edit_seconds = time.perf_counter() - t
        right_after = cov()
        finished = props.wait_for_refits(60)
        rep["async"] = {"edit_seconds": edit_seconds, "coverage_before": before, "coverage_right_after": right_after,
                        "coverage_applied": cov(), "coverage_expected": fitted(3.7), "finished": finished,
                        "main_thread": threading.current_thread().name,
                        "refit": props.LAST_REFITS.get(mat.name)}
        # Applying a preset in the UI fits on the worker thread too.
        props.LAST_REFITS.clear()
        t = time.perf_counter()
        bpy.ops.lacquer.apply_preset(preset="gold_flake_5", material=mat.name)
        op_seconds = time.perf_counter() - t
        finished = props.wait_for_refits(60)
        rep["async_preset"] = {"op_seconds": op_seconds, "finished": finished, "coverage": cov(),
                               "expected": lacquer.fit_node_group("gold_flake_5")["inputs"]["Flake Coverage"],
                               "refit": props.LAST_REFITS.get(mat.name)}
    finally:
        props.ASYNC_REFITS = None
    # 2. Keyframed paint parameters: frame changes refit the node group.
    mat.lacquer.flake_density = 8.0
    mat.keyframe_insert("lacquer.flake_density", frame=1)
    mat.lacquer.flake_density = 2.5
    mat.keyframe_insert("lacquer.flake_density", frame=11)
    # A length (a get/set property in scene units over the stored metres) animates too.
    saved_size = mat.lacquer.flake_size
    mat.lacquer.flake_size = 15e-6
    mat.keyframe_insert("lacquer.flake_size", frame=1)
    mat.lacquer.flake_size = 25e-6
    mat.keyframe_insert("lacquer.flake_size", frame=11)
    node = mat.node_tree.nodes["Lacquer Paint"]
    frames = {}
    for f in (1, 11, 6):
        scene.frame_set(f)
        frames[f] = {"density": mat.lacquer.flake_density, "coverage": cov(),
                     "expected": fitted(mat.lacquer.flake_density),
                     "flake_size_um": props.material_json(mat.lacquer)["flake_size_um"],
                     "node_flake_size": node.inputs["Flake Size"].default_value}
    rep["frames"] = frames
    mat.animation_data_clear()
    mat.lacquer.flake_size = saved_size
    scene.frame_set(1)
    # 3. Bad edits keep the previous valid paint (node group and LACQUER's export).
    mat.lacquer.flake_density = 8.0
    good = json.loads(mat.lacquer.fit_material)
    good_cov = cov()
    bad = {}
    for label, text in (("invalid_json", "{flake_density: 5"), ("out_of_range", '{"flake_density": 500}'),
                        ("unknown_parameter", '{"flake_densty": 5}'), ("wrong_model", '{"model": "lambert"}')):
        try:
            r = bpy.ops.lacquer.set_paint_json(json=text, material=mat.name)
            msg = str(r)
        except RuntimeError as e:  # bpy raises the operator's ERROR report
            msg = str(e)
        bad[label] = {"message": msg, "kept_settings": props.material_json(mat.lacquer) == good,
                      "kept_node": cov() == good_cov,
                      "kept_lacquer": export.material_desc(mat, export.Report()) == good}
    # A property edit the core refuses on refit (a fit failure, as a core error would be).
    fitmod = _addon_module("fit")
    real_fit = fitmod.fit

    def refusing_fit(material):
        if material["flake_density"] == 4.25:
            raise lacquer.InvalidMaterialError(3, "flake_density 4.25: refused (test)")
        return real_fit(material)

    fitmod.fit = refusing_fit
    try:
        mat.lacquer.flake_density = 4.25
    finally:
        fitmod.fit = real_fit
    bad["refused_by_refit"] = {"message": mat.lacquer.fit_message,
                               "kept_settings": props.material_json(mat.lacquer) == good,
                               "kept_node": cov() == good_cov,
                               "kept_lacquer": export.material_desc(mat, export.Report()) == good}
    ok = bpy.ops.lacquer.set_paint_json(json='{"flake_density": 5}', material=mat.name)
    bad["valid_json"] = {"result": str(ok), "density": mat.lacquer.flake_density, "coverage": cov(),
                         "expected": fitted(5.0)}
    rep["bad_edits"] = bad
    # 4. load_post: an old node group in a saved file is upgraded when the file is opened.
    name = mat.name  # the Python objects die with the file that is closed below
    group = node.node_tree
    group["lacquer_version"] = nodegroup.NODE_GROUP_VERSION - 1
    expected_cov = cov()
    node.inputs["Flake Coverage"].default_value = 0.99
    # ... saved by an extension before the metric lengths: flake_size_um / orange_peel_um in µm
    # (raw ID properties now), no metric properties.
    for k in ("flake_size", "orange_peel", "orange_peel_wavelength"):
        if k in mat.lacquer.keys():
            del mat.lacquer[k]
    mat.lacquer["flake_size_um"] = 25.0
    mat.lacquer["orange_peel_um"] = 0.75
    mat.lacquer["orange_peel_wavelength_mm"] = 4.5
    old = os.path.join(out, "old_group.blend")
    bpy.ops.wm.save_as_mainfile(filepath=old)
    bpy.ops.wm.open_mainfile(filepath=old)
    g = bpy.data.node_groups[nodegroup.GROUP_NAME]
    m = bpy.data.materials[name]
    js = props.material_json(m.lacquer)
    rep["lengths_migrated"] = {
        "flake_size_m": m.lacquer.flake_size, "orange_peel_m": m.lacquer.orange_peel,
        "orange_peel_wavelength_m": m.lacquer.orange_peel_wavelength,
        "json_flake_size_um": js["flake_size_um"],
        "old_keys_left": [k for k in m.lacquer.keys() if k.endswith(("_um", "_mm"))],
        "node": {k: m.node_tree.nodes["Lacquer Paint"].inputs[k].default_value
                 for k in ("Flake Size", "Orange Peel", "Orange Peel Wavelength")}}
    rep["load_post"] = {"upgrade": dict(props.LAST_UPGRADE), "version_after": g.get("lacquer_version"),
                        "coverage_after": m.node_tree.nodes["Lacquer Paint"].inputs["Flake Coverage"].default_value,
                        "coverage_expected": expected_cov}
    # 5. A linked (library) old group is left untouched, with a message.
    g["lacquer_version"] = nodegroup.NODE_GROUP_VERSION - 1
    lib_path = os.path.join(out, "paint_library.blend")
    bpy.data.libraries.write(lib_path, {bpy.data.materials[name]}, fake_user=True)
    scene = fresh_scene(size, 4)
    with bpy.data.libraries.load(lib_path, link=True) as (src, dst):
        dst.materials = [name]
    linked_mat = next(x for x in bpy.data.materials if x.library is not None)
    ball = sphere(scene, 0.05)
    ball.data.materials.append(linked_mat)
    shot = os.path.join(out, "uses_library.blend")
    bpy.ops.wm.save_as_mainfile(filepath=shot)
    bpy.ops.wm.open_mainfile(filepath=shot)
    lg = next(x for x in bpy.data.node_groups if x.name == nodegroup.GROUP_NAME)
    rep["linked"] = {"upgrade": dict(props.LAST_UPGRADE), "library": lg.library.filepath if lg.library else None,
                     "version_after": lg.get("lacquer_version"),
                     "local_groups": [x.name for x in bpy.data.node_groups if x.library is None]}
    return rep


def material_info(mat) -> dict:
    s = mat.lacquer
    return {"preset": s.preset, "fit_source": s.fit_message,
            "fit_error": json.loads(s.fit_error) if s.fit_error else None,
            "fit_inputs": json.loads(s.fit_inputs) if s.fit_inputs else None}


def side_by_side_png(left: str, right: str, out: str):
    """Cycles | LACQUER, view transform of the scene (Standard, sRGB), with a 4-px gap."""
    import numpy as np

    imgs = []
    for p in (left, right):
        im = bpy.data.images.load(p)
        w, h = im.size
        px = np.empty(w * h * 4, np.float32)
        im.pixels.foreach_get(px)
        imgs.append(px.reshape(h, w, 4))
    h, w, _ = imgs[0].shape
    gap = 4
    canvas = np.ones((h, 2 * w + gap, 4), np.float32)
    canvas[:, :w] = imgs[0]
    canvas[:, w + gap:] = imgs[1]
    canvas[..., 3] = 1.0
    # Scene-linear → sRGB (Standard view), as the PNG of a render would be.
    rgb = np.clip(canvas[..., :3], 0.0, 1.0)
    canvas[..., :3] = np.where(rgb <= 0.0031308, 12.92 * rgb, 1.055 * rgb ** (1 / 2.4) - 0.055)
    img = bpy.data.images.new("side_by_side", 2 * w + gap, h, alpha=False)
    img.colorspace_settings.name = "Non-Color"
    img.pixels.foreach_set(canvas.reshape(-1))
    img.filepath_raw = out
    img.file_format = "PNG"
    img.save()


# --- README screenshots (blender-addon/readme-image.sh: `--scenes shots --img-dir docs/img`) ----------
# Each shot builds on the test scenes' set-up (scene_readme, scene_density's plate and sun,
# _normal_map_image, TEXTURE_COLORS, compositor) and writes one small sRGB PNG of panels.


def _load_linear(path):
    """An EXR's RGBA as an (h, w, 4) float array, top row first."""
    import numpy as np

    im = bpy.data.images.load(path)
    w, h = im.size
    px = np.empty(w * h * 4, np.float32)
    im.pixels.foreach_get(px)
    bpy.data.images.remove(im)
    return px.reshape(h, w, 4)[::-1]


def _srgb(rgb):
    import numpy as np

    rgb = np.clip(rgb, 0.0, 1.0)
    return np.where(rgb <= 0.0031308, 12.92 * rgb, 1.055 * rgb ** (1 / 2.4) - 0.055)


def panels_png(panels, out: str, gap: int = 4, display=()):
    """Panels (h, w, ≥3 arrays, top row first, scene-linear except the indices in ``display``,
    which are already display values in [0, 1]) side by side with a white gap, written as an
    8-bit sRGB PNG (Standard view transform)."""
    import numpy as np

    h = max(p.shape[0] for p in panels)
    w = sum(p.shape[1] for p in panels) + gap * (len(panels) - 1)
    canvas = np.ones((h, w, 4), np.float32)
    x = 0
    for k, p in enumerate(panels):
        rgb = np.clip(p[..., :3], 0.0, 1.0) if k in display else _srgb(p[..., :3])
        canvas[: p.shape[0], x: x + p.shape[1], :3] = rgb
        x += p.shape[1] + gap
    img = bpy.data.images.new(os.path.basename(out), w, h, alpha=False)
    img.colorspace_settings.name = "Non-Color"
    img.pixels.foreach_set(canvas[::-1].reshape(-1))
    img.filepath_raw = out
    img.file_format = "PNG"
    img.save()
    bpy.data.images.remove(img)
    return {"file": out, "size": [w, h], "bytes": os.path.getsize(out)}


def _shot_render(scene, engine, out, tag):
    path = os.path.join(out, f"shot_{tag}.exr")
    r = render(scene, engine, path)
    print(f"rendered shot {tag} with {engine} in {r['seconds']:.2f} s", flush=True)
    return _load_linear(path), r


def shot_library(out, img_dir, size):
    """(a) The bundled asset library as a contact sheet: each preset's thumbnail (the core's
    shader ball, as the Asset Browser shows it) with its label, laid out by Blender itself (image
    planes and text objects, emission only, an orthographic camera, Cycles)."""
    assets = _addon_module("assets")
    catalog = _addon_module("catalog")
    scene = fresh_scene(size, 16)
    scene.render.film_transparent = False
    set_world(scene, (1.0, 1.0, 1.0))
    cols = 6
    presets = sorted(catalog.presets(), key=lambda p: (catalog.ASSET_CATALOGS.index(catalog.asset_catalog(p[0])), p[0]))
    rows = (len(presets) + cols - 1) // cols
    cell_w, cell_h = 1.0, 1.3  # a 0.8-unit thumbnail, two lines of label under it
    thumbs = os.path.join(assets.library_dir(), "thumbs")

    def emission(name, image=None, color=(0.0, 0.0, 0.0)):
        m = bpy.data.materials.new(name)
        if hasattr(m, "use_nodes"):
            m.use_nodes = True
        nt = m.node_tree
        nt.nodes.clear()
        em = nt.nodes.new("ShaderNodeEmission")
        if image is not None:
            tex = nt.nodes.new("ShaderNodeTexImage")
            tex.image = image
            nt.links.new(tex.outputs["Color"], em.inputs["Color"])
        else:
            em.inputs["Color"].default_value = (*color, 1.0)
        o = nt.nodes.new("ShaderNodeOutputMaterial")
        nt.links.new(em.outputs[0], o.inputs["Surface"])
        return m

    ink = emission("ink")
    for k, (name, label, _, _) in enumerate(presets):
        r, c = divmod(k, cols)
        x, y = (c + 0.5) * cell_w, -(r + 0.5) * cell_h
        bpy.ops.mesh.primitive_plane_add(size=0.8, location=(x, y + 0.2, 0.0))
        plane = bpy.context.object
        img = bpy.data.images.load(os.path.join(thumbs, name + ".png"))
        plane.data.materials.append(emission(name, img))
        words = label.replace(", ", ",\n") if len(label) > 16 else label
        for line, text in enumerate(words.split("\n")):
            curve = bpy.data.curves.new(f"{name} label {line}", "FONT")
            curve.body = text
            curve.size = 0.105
            curve.align_x = "CENTER"
            ob = bpy.data.objects.new(curve.name, curve)
            ob.location = (x, y - 0.31 - 0.13 * line, 0.0)
            curve.materials.append(ink)
            scene.collection.objects.link(ob)
    cam = add_camera(scene, (cols * cell_w / 2, -rows * cell_h / 2, 5.0), (cols * cell_w / 2, -rows * cell_h / 2, 0.0))
    cam.data.type = "ORTHO"
    cam.data.ortho_scale = cols * cell_w
    scene.render.resolution_x = size
    scene.render.resolution_y = round(size * rows * cell_h / (cols * cell_w))
    img, r = _shot_render(scene, "CYCLES", out, "library")
    png = panels_png([img], os.path.join(img_dir, "blender-library.png"))
    return {"presets": [p[0] for p in presets], "render": r, "png": png}


def _readme_ball():
    """scene_readme's set-up (gold_flake_8 sphere above a floor, two area lights); the ball."""
    scene, mats = scene_readme(SHOT_SIZE, SHOT_SPP)
    ball = next(o for o in scene.objects if o.type == "MESH" and o.active_material == mats["gold_flake_8"])
    return scene, mats["gold_flake_8"], ball


#: README screenshots: panel size and samples (set by shots() from --shot-size and --shot-spp).
SHOT_SIZE = 240
SHOT_SPP = 64


def shot_surface(out, img_dir):
    """(b) Orange peel and a normal map on the coat, LACQUER: plain | orange peel | normal map."""
    scene, mat, ball = _readme_ball()
    node = mat.node_tree.nodes["Lacquer Paint"]
    panels, rep = [], {}
    img, rep["plain"] = _shot_render(scene, "LACQUER", out, "surface_plain")
    panels.append(img)
    # Exaggerated 100× so that it shows at 0.4 mm per pixel (real paint: 0.1–1 µm over 1–10 mm).
    mat.lacquer.orange_peel = 100e-6
    mat.lacquer.orange_peel_wavelength = 6e-3
    img, rep["peel"] = _shot_render(scene, "LACQUER", out, "surface_peel")
    panels.append(img)
    mat.lacquer.orange_peel = 0.0
    tree = mat.node_tree
    tex = tree.nodes.new("ShaderNodeTexImage")
    tex.image = _normal_map_image(n=256, waves=24, tilt=0.25)
    nm = tree.nodes.new("ShaderNodeNormalMap")
    nm.space = "TANGENT"
    nm.uv_map = ball.data.uv_layers[0].name
    tree.links.new(tex.outputs["Color"], nm.inputs["Color"])
    tree.links.new(nm.outputs["Normal"], node.inputs["Normal"])
    img, rep["normal_map"] = _shot_render(scene, "LACQUER", out, "surface_normalmap")
    panels.append(img)
    rep["png"] = panels_png(panels, os.path.join(img_dir, "blender-surface.png"))
    return rep


def shot_texture(out, img_dir):
    """(c) An image texture (8 × 4 checker of TEXTURE_COLORS, linear) on the Lacquer node's
    Base Color, sphere UV map: Cycles | LACQUER."""
    import numpy as np

    scene, mat, ball = _readme_ball()
    node = mat.node_tree.nodes["Lacquer Paint"]
    n = 64
    i, j = np.meshgrid(np.arange(n) * 8 // n, np.arange(n) * 4 // n)
    rgba = np.ones((n, n, 4), np.float32)
    rgba[..., :3] = np.where(((i + j) % 2 == 0)[..., None], TEXTURE_COLORS[0], TEXTURE_COLORS[1])
    img = bpy.data.images.new("lacquer checker", n, n, float_buffer=True, alpha=True)
    img.colorspace_settings.name = "Linear Rec.709"
    img.pixels.foreach_set(rgba.reshape(-1))
    img.pack()
    tex = mat.node_tree.nodes.new("ShaderNodeTexImage")
    tex.image = img
    tex.interpolation = "Closest"
    mat.node_tree.links.new(tex.outputs["Color"], node.inputs["Base Color"])
    rep, panels = {}, []
    for engine in ("CYCLES", "LACQUER"):
        im, rep[engine] = _shot_render(scene, engine, out, f"texture_{engine.lower()}")
        panels.append(im)
    rep["png"] = panels_png(panels, os.path.join(img_dir, "blender-texture.png"))
    return rep


def shot_flakescale(out, img_dir):
    """(d) Flake size on a parented, scaled instance: scene_density's 2 cm view and sun; the
    left half a plain 1 cm plate, the right half a collection instance of a 100-unit plate whose
    instancer is parented under an FBX-like root scaled 0.01 and scaled 0.01 itself (1 cm again).
    Flake Scale 10 (250 µm flakes) so that single flakes are pixels wide. Cycles | LACQUER:
    the same flake size on both plates and in both engines."""
    scene = fresh_scene(SHOT_SIZE, SHOT_SPP)
    set_world(scene, (0.02, 0.02, 0.02))
    add_camera(scene, (0.0, 0.0, 0.5), (0.0, 0.0, 0.0), lens=900.0)
    sun_dir = (math.sin(math.radians(20.0)), 0.0, math.cos(math.radians(20.0)))
    add_light(scene, "SUN", sun_dir, (0.0, 0.0, 0.0), energy=3.0, angle=math.radians(0.5))
    bpy.ops.mesh.primitive_plane_add(size=1.0, location=(0.0, 0.0, 0.0))
    plain = bpy.context.object
    plain.scale = (0.009, 0.02, 1.0)
    plain.location = (-0.0055, 0.0, 0.0)
    mat = assign(plain, "gold_flake_8")
    mat.lacquer.flake_scale = 10.0
    proto = bpy.data.collections.new("Shot plate proto")
    bpy.ops.mesh.primitive_plane_add(size=90.0)
    plate = bpy.context.object
    plate.scale = (1.0, 2.0 / 0.9, 1.0)
    for c in list(plate.users_collection):
        c.objects.unlink(plate)
    proto.objects.link(plate)
    plate.data.materials.append(mat)
    root = bpy.data.objects.new("FBX root", None)
    root.scale = (0.01,) * 3
    root.location = (0.0055, 0.0, 0.0)
    scene.collection.objects.link(root)
    inst = bpy.data.objects.new("instance", None)
    inst.instance_type = "COLLECTION"
    inst.instance_collection = proto
    inst.scale = (0.01,) * 3
    inst.parent = root
    scene.collection.objects.link(inst)
    rep, panels = {}, []
    for engine in ("CYCLES", "LACQUER"):
        im, rep[engine] = _shot_render(scene, engine, out, f"flakescale_{engine.lower()}")
        panels.append(im)
    rep["png"] = panels_png(panels, os.path.join(img_dir, "blender-flake-scale.png"))
    return rep


def shot_passes(out, img_dir):
    """(e) LACQUER's passes at 16 spp, sparkle off: Combined, Denoising Albedo, Denoising Normal
    (shown as ½ + ½ n) and Render Layers → Denoise (Image, Normal, Albedo) → output."""
    scene, mat, ball = _readme_ball()
    scene.lacquer.samples = 16
    scene.lacquer.sparkle = False
    scene.render.engine = "LACQUER"
    rep, panels = {}, []
    img, rep["combined"] = _shot_render(scene, "LACQUER", out, "passes_combined")
    panels.append(img)
    for name, tag in (("Denoising Albedo", "albedo"), ("Denoising Normal", "normal")):
        compositor(scene, name, denoise=False)
        img, rep[tag] = _shot_render(scene, "LACQUER", out, f"passes_{tag}")
        if tag == "normal":
            img = img.copy()
            img[..., :3] = 0.5 + 0.5 * img[..., :3]  # a display value, not scene-linear
        panels.append(img)
    try:
        rep["rl_outputs"] = compositor(scene, "Image", denoise=True)
        img, rep["denoised"] = _shot_render(scene, "LACQUER", out, "passes_denoised")
        panels.append(img)
        rep["denoise"] = "ok"
    except Exception as e:  # noqa: BLE001  (reported, the strip is written without it)
        rep["denoise"] = f"unavailable: {e}"
        print(f"Denoise node unavailable: {e}", flush=True)
    disable_compositor(scene)
    rep["png"] = panels_png(panels, os.path.join(img_dir, "blender-passes.png"), display=(2,))
    return rep


def shots(out: str, img_dir: str, size: int, spp: int) -> dict:
    """All README screenshots; returns timings and the PNGs written."""
    global SHOT_SIZE, SHOT_SPP
    SHOT_SIZE, SHOT_SPP = size, spp
    os.makedirs(img_dir, exist_ok=True)
    rep = {}
    for name, fn in (("library", lambda: shot_library(out, img_dir, 640)),
                     ("surface", lambda: shot_surface(out, img_dir)),
                     ("texture", lambda: shot_texture(out, img_dir)),
                     ("flakescale", lambda: shot_flakescale(out, img_dir)),
                     ("passes", lambda: shot_passes(out, img_dir))):
        t = time.perf_counter()
        rep[name] = fn()
        rep[name]["seconds"] = time.perf_counter() - t
        print(f"shot {name}: {rep[name]['png']['file']} {rep[name]['png']['bytes']} bytes in "
              f"{rep[name]['seconds']:.1f} s", flush=True)
    return rep


def main(argv):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--zip", help="the extension zip (blender-addon/build.sh)")
    ap.add_argument("--render-blend", help="only render this .blend with Cycles (no extension)")
    ap.add_argument("--out", required=True, help="output folder")
    ap.add_argument("--size", type=int, default=128)
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--scenes", default="compare,density")
    ap.add_argument("--engines", default="CYCLES,LACQUER")
    ap.add_argument("--png", help="readme: the side-by-side PNG to write")
    ap.add_argument("--img-dir", help="shots: the folder for the README screenshots (PNG)")
    ap.add_argument("--shot-size", type=int, default=240, help="shots: panel size in pixels")
    ap.add_argument("--shot-spp", type=int, default=64, help="shots: samples per pixel")
    ap.add_argument("--blend", action="store_true", help="also save each scene as a .blend")
    ap.add_argument("--eevee", action="store_true", help="also render the compare scene with EEVEE")
    a = ap.parse_args(argv)
    if not os.environ.get("BLENDER_USER_RESOURCES"):
        raise SystemExit("set BLENDER_USER_RESOURCES to a temporary folder (before bpy starts)")
    os.makedirs(a.out, exist_ok=True)
    report = {"bpy": bpy.app.version_string, "size": a.size, "spp": a.spp, "renders": [], "materials": {}}
    if a.render_blend:
        bpy.ops.wm.open_mainfile(filepath=os.path.abspath(a.render_blend))
        name = os.path.splitext(os.path.basename(a.render_blend))[0]
        report["addon_enabled"] = ADDON in bpy.context.preferences.addons
        r = render(bpy.context.scene, "CYCLES", os.path.join(os.path.abspath(a.out), f"{name}_farm_cycles.exr"))
        report["renders"].append(r)
        with open(os.path.join(a.out, "report_farm.json"), "w") as f:
            json.dump(report, f, indent=1)
        return
    if not a.zip:
        raise SystemExit("--zip is required")
    report.update(install(a.zip))
    report["engine_registered"] = engine_registered()
    engines = a.engines.split(",")
    try:
        jobs = []
        smokes = []
        for name in a.scenes.split(","):
            if name == "compare":
                jobs.append(("compare", lambda: scene_compare(a.size, a.spp)))
            elif name == "density":
                for p in ("gold_flake_0", "gold_flake_2", "gold_flake_8"):
                    jobs.append((f"density_{p}", lambda p=p: scene_density(a.size, a.spp, p)))
            elif name == "lights":
                for c in LIGHT_CASES:
                    jobs.append((f"lights_{c}", lambda c=c: scene_lights(a.size, a.spp, c, os.path.abspath(a.out))))
            elif name == "principled":
                jobs.append(("principled", lambda: scene_principled(a.size, a.spp)))
            elif name == "instances":
                jobs.append(("instances", lambda: scene_instances(a.size, a.spp)))
            elif name == "readme":
                jobs.append(("readme", lambda: scene_readme(a.size, a.spp)))
            elif name == "shots":
                if not a.img_dir:
                    raise SystemExit("--scenes shots needs --img-dir")
            elif name in ("engine", "editing", "artist", "assets"):
                smokes.append(name)  # after the scenes: editing opens and saves files
            elif name == "lod":
                for dist in LOD_DISTANCES:
                    for lod in (True, False):
                        jobs.append((f"lod_{dist}_{'on' if lod else 'off'}",
                                     lambda dist=dist, lod=lod: scene_lod(a.size, a.spp, dist, lod)))
            elif name == "flakescale":
                for u in FLAKESCALE_UNITS:
                    jobs.append((f"flakescale_{u}", lambda u=u: scene_flakescale(a.size, a.spp, u)))
            else:
                raise SystemExit(f"unknown scene {name}")
        for name, build in jobs:
            t = time.perf_counter()
            scene, mats = build()
            setup = time.perf_counter() - t
            for k, m in mats.items():
                report["materials"][k] = material_info(m)
                if "ui" not in report:
                    report["ui"] = ui_smoke(m)
                    report["auto_update"] = auto_update_smoke(m)
            if a.blend:
                bpy.ops.wm.save_as_mainfile(filepath=os.path.join(os.path.abspath(a.out), f"{name}.blend"))
            this = [(e, e.lower()) for e in engines]
            if name.startswith("lod_") and name.endswith("_off"):
                this = [("CYCLES", "cycles")]  # LACQUER has no switch: rendered once, with "on"
            if name.startswith("lod_"):
                node = mats["gold_flake_8"].node_tree.nodes["Lacquer Paint"]
                report.setdefault("lod", {})[name] = {k: node.inputs[k].default_value
                                                      for k in ("Pixel Angle", "Sparkle Samples", "Flake Size")}
            if name.startswith("flakescale_"):
                # The cells' coordinate rendered by Cycles, and LACQUER's export read directly.
                this = [("CYCLES", "cycles_coord")]
                report.setdefault("flakescale", {})[name] = lacquer_flake_scale(scene)
                mat = mats["gold_flake_8"]
                probe = flake_coordinate_material(mat)
                for ob in bpy.data.objects:
                    if ob.type == "MESH":
                        ob.data.materials[0] = probe
            if name == "compare" and "CYCLES" in engines:
                this.append(("CYCLES", "cycles_mean"))  # Sparkle 0: the mean lobe the core fits
            if a.eevee and name == "compare":
                this.append((EEVEE, "eevee"))
            for engine, tag in this:
                for m in mats.values():
                    node = m.node_tree.nodes.get("Lacquer Paint")
                    if node is not None:
                        fitted = json.loads(m.lacquer.fit_inputs).get("Sparkle", 1.0)
                        node.inputs["Sparkle"].default_value = 0.0 if tag.endswith("_mean") else fitted
                path = os.path.join(os.path.abspath(a.out), f"{name}_{tag}.exr")
                if engine == EEVEE:  # needs an OpenGL context (software GL headless): optional
                    try:
                        r = render(scene, engine, path)
                    except RuntimeError as e:
                        report["eevee_error"] = str(e)
                        print(f"EEVEE could not render: {e}", flush=True)
                        continue
                else:
                    r = render(scene, engine, path)
                r.update(scene=name, tag=tag, setup_seconds=setup)
                report["renders"].append(r)
                print(f"rendered {name} with {engine} in {r['seconds']:.2f} s", flush=True)
        for name in smokes:
            t = time.perf_counter()
            smoke = {"engine": engine_smoke, "editing": editing_smoke, "artist": artist_smoke,
                     "assets": assets_smoke}[name]
            report[name] = smoke(os.path.abspath(a.out), a.size)
            report[name]["smoke_seconds"] = time.perf_counter() - t
            print(f"{name} smoke in {report[name]['smoke_seconds']:.2f} s", flush=True)
        if "shots" in a.scenes.split(","):
            report["shots"] = shots(os.path.abspath(a.out), os.path.abspath(a.img_dir), a.shot_size, a.shot_spp)
        if a.png and "readme" in a.scenes.split(","):
            out = os.path.abspath(a.out)
            side_by_side_png(os.path.join(out, "readme_cycles.exr"), os.path.join(out, "readme_lacquer.exr"), a.png)
    finally:
        report.update(uninstall())
        with open(os.path.join(a.out, "report.json"), "w") as f:
            json.dump(report, f, indent=1)


if __name__ == "__main__":
    main(sys.argv[1:])
