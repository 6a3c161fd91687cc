"""Blender scene → lacquer render job (docs/render.md, rust-core/render/src/desc.rs).

Everything the LACQUER engine hands the renderer goes through here: the evaluated depsgraph's
meshes (loop triangles, corner normals, foreach_get into numpy) and their instances, the camera,
point/spot/sun/area lights, the world, and the materials. The conversions:

* **Axes** (the only place): Blender is z-up, the renderer y-up; ``Y_UP`` maps Blender
  (x, y, z) to renderer (x, z, −y), a rotation, applied to every matrix, point and direction.
* **Lights** are not surfaces, as in Cycles: the camera does not see area and sphere lights and
  they cast no shadows; rays that reach them collect their emission (``"surface": false``).
* **Units**: geometry, camera and lights in Blender units, as Cycles renders them (Cycles
  ignores the scene's Unit Scale; only the flakes' physical size uses it, below). Lights
  follow Cycles: a point light of power P watts has intensity P/(4π) W/sr (a sphere of
  radiance P/(4π²r²) when its radius r > 0), a spot is a point light masked by its cone
  (blend = the smooth fraction of the cone), a sun's strength is its irradiance in W/m², an
  area light of power P and area A has radiance P/(πA).
* **Sparkle uv**: the renderer's sparkle needs uv in physical units. Every triangle gets its own
  planar uv: its corners' object coordinates × the per-axis scale of the instance's world matrix
  (parents and instancers included) × the scene's Unit Scale (metres per Blender unit) — metres
  on the object, as the node group's Voronoi cells use — in an orthonormal frame of its plane.
  One uv unit is one metre everywhere, whatever UV map the mesh has (``surface_scale_mm`` =
  1000), so flakes have their true size and stick to the object.
* **Materials**: a Lacquer material is its paint parameters exactly; any other material is
  read from its Principled BSDF into ``{"model": "principled", ...}`` (a Diffuse BSDF into
  ``lambert``), with a message naming what was approximated.
"""

from __future__ import annotations

import base64
import math
import os
import tempfile

import bpy
import numpy as np
from mathutils import Matrix, Vector

from . import catalog, props

#: Blender (z-up) → renderer (y-up): (x, y, z) → (x, z, −y).
Y_UP = Matrix(((1.0, 0.0, 0.0, 0.0), (0.0, 0.0, 1.0, 0.0), (0.0, -1.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0)))

GEOMETRY_TYPES = {"MESH", "CURVE", "CURVES", "SURFACE", "META", "FONT"}

DEFAULT_GREY = [0.8, 0.8, 0.8]  # Blender's default surface (no material)


class Report:
    """Messages for the user: what was approximated or left out (deduplicated, counted)."""

    def __init__(self):
        self.items: dict[str, int] = {}

    def warn(self, message: str):
        self.items[message] = self.items.get(message, 0) + 1

    def lines(self) -> list[str]:
        return [m if n == 1 else f"{m} (×{n})" for m, n in self.items.items()]


def _vec(v) -> list:
    return [float(x) for x in v]


def _point(p) -> list:
    return _vec((Y_UP @ Vector((p[0], p[1], p[2], 1.0)))[:3])


def _dir(d) -> list:
    return _vec(Y_UP.to_3x3() @ Vector(d))


def _b64(a: np.ndarray, dtype) -> str:
    """Little-endian base64 array, the compact form the scene format accepts for mesh arrays."""
    data = np.ascontiguousarray(a, dtype=np.dtype(dtype).newbyteorder("<")).tobytes()
    return "base64:" + base64.b64encode(data).decode()


# --- meshes ----------------------------------------------------------------------------------


def _mesh_arrays(mesh, axis_scale) -> dict:
    """Unwelded triangle arrays of an evaluated mesh: per-corner positions and normals (object
    space), planar uv in metres (object space × ``axis_scale``, metres per object unit along
    each axis), and the material index of each triangle."""
    mesh.calc_loop_triangles()
    tris = mesh.loop_triangles
    n = len(tris)
    if n == 0:
        return {}
    verts = np.empty(n * 3, np.int32)
    loops = np.empty(n * 3, np.int32)
    mat_index = np.empty(n, np.int32)
    tris.foreach_get("vertices", verts)
    tris.foreach_get("loops", loops)
    tris.foreach_get("material_index", mat_index)
    co = np.empty(len(mesh.vertices) * 3, np.float32)
    mesh.vertices.foreach_get("co", co)
    co = co.reshape(-1, 3)
    corner_n = np.empty(len(mesh.loops) * 3, np.float32)
    if hasattr(mesh, "corner_normals"):  # Blender 4.1+
        mesh.corner_normals.foreach_get("vector", corner_n)
    else:  # pragma: no cover (4.0)
        mesh.loops.foreach_get("normal", corner_n)
    corner_n = corner_n.reshape(-1, 3)
    p_obj = co[verts].reshape(n, 3, 3)
    nrm = corner_n[loops].reshape(n, 3, 3)
    # Planar uv per triangle: coordinates (metres) in an orthonormal frame (t, b) of its plane.
    p = p_obj.astype(np.float64) * np.asarray(axis_scale, np.float64)
    ng = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    length = np.linalg.norm(ng, axis=1, keepdims=True)
    ok = length[:, 0] > 0
    ng = np.where(ok[:, None], ng / np.where(length > 0, length, 1.0), [0.0, 0.0, 1.0])
    helper = np.where((np.abs(ng[:, 0]) < 0.9)[:, None], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    t = np.cross(helper, ng)
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    bt = np.cross(ng, t)
    uv = np.stack([np.einsum("tkc,tc->tk", p, t), np.einsum("tkc,tc->tk", p, bt)], axis=-1)
    return {
        "positions": p_obj.reshape(-1, 3),
        "normals": nrm.reshape(-1, 3),
        "uvs": uv.reshape(-1, 2).astype(np.float32),
        "coords": p.reshape(-1, 3).astype(np.float32),
        "loops": loops,
        "material_index": mat_index,
    }


# --- normal maps and orange peel (rust-core/render/src/perturb.rs) ---------------------------


def _linked_from(sock):
    """The node feeding a socket (through reroutes), or None."""
    if sock is None or not sock.is_linked:
        return None
    node = sock.links[0].from_node
    while node.bl_idname == "NodeReroute" and node.inputs[0].is_linked:
        node = node.inputs[0].links[0].from_node
    return node


def _lacquer_node(mat):
    """The material's Lacquer node, or None."""
    from . import nodegroup

    return mat.node_tree.nodes.get(nodegroup.NODE_NAME) if getattr(mat, "node_tree", None) else None


def coat_normal_mode(mat) -> str:
    """How the coat's normal relates to Normal in the node group (the Principled BSDF's Coat
    Normal): ``"follows"`` (Coat Normal not connected, or connected to what Normal is: the coat
    follows Normal, then orange peel tilts it) or ``"own"`` (its own normal map or bump, which
    replaces Normal for the coat; LACQUER then shades the paint in two frames)."""
    node = _lacquer_node(mat)
    if node is None:
        return "follows"
    coat = _link_from(node.inputs.get("Coat Normal"))
    if coat is None or coat == _link_from(node.inputs.get("Normal")):
        return "follows"
    return "own"


def normal_source(mat, report: Report, input_name: str = "Normal"):
    """The Normal Map node (tangent space, fed by an Image Texture) connected to the Lacquer
    node's ``input_name`` input (Normal or Coat Normal): ``(image, uv_map, strength)``, or None
    with a message for anything LACQUER cannot follow."""
    node = _lacquer_node(mat)
    if node is None:
        return None
    src = _linked_from(node.inputs.get(input_name))
    if src is None or src.bl_idname == "ShaderNodeBump":  # a Bump node: bump_source
        return None
    if src.bl_idname != "ShaderNodeNormalMap" or src.space != "TANGENT":
        report.warn(f"material \"{mat.name}\": the {input_name} input comes from {src.bl_idname}"
                    f"{' (' + src.space.lower() + ' space)' if src.bl_idname == 'ShaderNodeNormalMap' else ''}; "
                    f"LACQUER follows a tangent-space Normal Map node fed by an Image Texture (ignored)")
        return None
    tex = _linked_from(src.inputs["Color"])
    if tex is None or tex.bl_idname != "ShaderNodeTexImage" or tex.image is None:
        report.warn(f"material \"{mat.name}\": the Normal Map's Color is not an Image Texture with an image (ignored)")
        return None
    if tex.inputs["Vector"].is_linked:
        report.warn(f"material \"{mat.name}\": the normal map's texture coordinates are connected; LACQUER reads "
                    f"the UV map directly")
    if src.inputs["Strength"].is_linked:
        report.warn(f"material \"{mat.name}\": Normal Map Strength is connected; LACQUER uses its value")
    return tex.image, src.uv_map, float(src.inputs["Strength"].default_value)


def bump_source(mat, report: Report, input_name: str = "Normal"):
    """The Bump node (its Height fed by an Image Texture) connected to the Lacquer node's
    ``input_name`` input (Normal or Coat Normal): ``(texture node, output name, uv_map, strength,
    distance)`` with the distance negated by Invert, or None with a message for anything LACQUER
    cannot follow."""
    node = _lacquer_node(mat)
    if node is None:
        return None
    src = _linked_from(node.inputs.get(input_name))
    if src is None or src.bl_idname != "ShaderNodeBump":
        return None
    height = _link_from(src.inputs["Height"])
    if height is None or height[0].bl_idname != "ShaderNodeTexImage" or height[0].image is None:
        kind = height[0].bl_idname if height is not None else "nothing"
        report.warn(f"material \"{mat.name}\": the Bump node's Height comes from {kind}; LACQUER follows an Image "
                    f"Texture with an image there (bump ignored)")
        return None
    tex, out = height
    for name in ("Strength", "Distance"):
        if src.inputs[name].is_linked:
            report.warn(f"material \"{mat.name}\": Bump {name} is connected; LACQUER uses its value")
    if src.inputs["Normal"].is_linked:
        report.warn(f"material \"{mat.name}\": the Bump node's Normal input is connected; LACQUER bumps the "
                    f"surface's normal")
    distance = float(src.inputs["Distance"].default_value) * (-1.0 if src.invert else 1.0)
    return (tex, out.name, _texture_uv_map(tex, mat.name, report), float(src.inputs["Strength"].default_value),
            distance)


def _image_rgb(image) -> tuple[int, int, np.ndarray]:
    """An image's pixels as (width, height, linear RGB float32 rows bottom first)."""
    w, h = image.size
    if w == 0 or h == 0:
        raise ValueError(f"image \"{image.name}\" has no pixels")
    px = np.empty(w * h * image.channels, np.float32)
    image.pixels.foreach_get(px)
    px = px.reshape(h * w, image.channels)
    rgb = np.zeros((h * w, 3), np.float32)
    rgb[:, :min(3, image.channels)] = px[:, :3]
    if image.colorspace_settings.name.lower() in ("srgb", "srgb - texture") and not image.is_float:
        rgb = _srgb_to_linear(rgb).astype(np.float32)  # as Cycles decodes a colour image
    return w, h, rgb


def _tangent_arrays(mesh, uv_map: str, loops):
    """Per-corner uv, tangent and bitangent (object space, MikkTSpace as Cycles) for ``loops``."""
    layers = mesh.uv_layers
    name = uv_map or (next((u.name for u in layers if u.active_render), None) if len(layers) else None)
    if not name or name not in layers:
        raise ValueError(f"no UV map \"{uv_map}\"" if uv_map else "no UV map")
    mesh.calc_tangents(uvmap=name)
    nl = len(mesh.loops)
    uv = np.empty(nl * 2, np.float32)
    layers[name].data.foreach_get("uv", uv)
    t = np.empty(nl * 3, np.float32)
    bt = np.empty(nl * 3, np.float32)
    mesh.loops.foreach_get("tangent", t)
    mesh.loops.foreach_get("bitangent", bt)
    return uv.reshape(-1, 2)[loops], t.reshape(-1, 3)[loops], bt.reshape(-1, 3)[loops]


def perturb_arrays(mesh, arrays: dict, materials: list, unit_m: float, report: Report, images: dict,
                   bindings=None) -> dict:
    """Per material index: the normal map, orange peel and texture coordinates (``bindings(mat)``:
    the material's textures and UV map) of a Lacquer material's mesh part, as the scene format's
    per-corner arrays (before selecting the part's corners)."""
    out = {}
    for idx, mat in enumerate(materials):
        settings = getattr(mat, "lacquer", None) if mat is not None else None
        if settings is None or not settings.enabled:
            continue
        extra = _normal_arrays(mesh, arrays, mat, report, images, "Normal")
        # The coat's own normal (Coat Normal, orange peel on the coat): LACQUER shades the
        # clearcoat's reflection in its frame, the paint under it in Normal's (two frames).
        coat = {"follows_normal": True}
        if coat_normal_mode(mat) == "own":
            coat = dict(_normal_arrays(mesh, arrays, mat, report, images, "Coat Normal"), follows_normal=False)
        if settings.orange_peel > 0.0:
            coat["orange_peel"] = {"amplitude_um": props.core_value(settings, "orange_peel_um"),
                                   "wavelength_mm": props.core_value(settings, "orange_peel_wavelength_mm"),
                                   "metres_per_unit": unit_m, "coords": arrays["coords"]}
        if len(coat) > 1 or not coat["follows_normal"]:
            extra["coat_normal"] = coat
        if bindings is not None:
            textures, uv_map = bindings(mat)
            if textures:
                extra["texture_uvs"] = _uv_array(mesh, uv_map, arrays["loops"], report, mat.name)
                if "coat_normal" in extra:
                    report.warn(f"material \"{mat.name}\": a textured paint shades in one frame in LACQUER: "
                                f"Coat Normal / orange peel tilt the whole paint there")
        if extra:
            out[idx] = extra
    return out


def _normal_arrays(mesh, arrays: dict, mat, report: Report, images: dict, input_name: str) -> dict:
    """The normal map and bump map connected to the Lacquer node's ``input_name`` input (Normal
    or Coat Normal), as the scene format's per-corner arrays (before selecting a part's corners)."""
    extra = {}
    src = normal_source(mat, report, input_name)
    if src is not None:
        image, uv_map, strength = src
        try:
            uv, t, bt = _tangent_arrays(mesh, uv_map, arrays["loops"])
            if image.name not in images:
                images[image.name] = _image_rgb(image)
            w, h, rgb = images[image.name]
            extra["normal_map"] = {"width": w, "height": h, "pixels": rgb, "strength": strength,
                                   "uvs": uv, "tangents": t, "bitangents": bt}
        except (RuntimeError, ValueError) as e:
            report.warn(f"material \"{mat.name}\": normal map not exported ({e})")
    bump = bump_source(mat, report, input_name)
    if bump is not None:
        tex, out_name, uv_map, strength, distance = bump
        try:
            if ("rgba", tex.image.name) not in images:
                images[("rgba", tex.image.name)] = _image_rgba(tex.image)
            w, h, rgb, alpha = images[("rgba", tex.image.name)]
            heights = alpha if out_name == "Alpha" else rgb @ GREY  # Cycles' colour → float
            extra["bump"] = {"width": w, "height": h, "pixels": heights.astype(np.float32),
                             "strength": strength, "distance": distance,
                             "uvs": _uv_array(mesh, uv_map, arrays["loops"], report, mat.name)}
        except (RuntimeError, ValueError) as e:
            report.warn(f"material \"{mat.name}\": bump map not exported ({e})")
    return extra


def _select_perturb(extra: dict, corner) -> dict:
    """A part's perturbation JSON: per-corner arrays cut to ``corner`` and base64-packed."""
    out = {}
    if "normal_map" in extra:
        m = extra["normal_map"]
        out["normal_map"] = {"width": m["width"], "height": m["height"], "pixels": _b64(m["pixels"], np.float32),
                             "strength": m["strength"], "uvs": _b64(m["uvs"][corner], np.float32),
                             "tangents": _b64(m["tangents"][corner], np.float32),
                             "bitangents": _b64(m["bitangents"][corner], np.float32)}
    if "orange_peel" in extra:
        p = extra["orange_peel"]
        out["orange_peel"] = dict(p, coords=_b64(p["coords"][corner], np.float32))
    if "texture_uvs" in extra:
        out["texture_uvs"] = _b64(extra["texture_uvs"][corner], np.float32)
    if "bump" in extra:
        m = extra["bump"]
        out["bump"] = {"width": m["width"], "height": m["height"], "pixels": _b64(m["pixels"], np.float32),
                       "strength": m["strength"], "distance": m["distance"],
                       "uvs": _b64(m["uvs"][corner], np.float32)}
    if "coat_normal" in extra:
        c = extra["coat_normal"]
        out["coat_normal"] = dict(_select_perturb({k: v for k, v in c.items() if k != "follows_normal"}, corner),
                                  follows_normal=c["follows_normal"])
    return out


# --- textured parameters (rust-core/render/src/texture.rs) ------------------------------------

#: Lacquer node inputs LACQUER exports when an Image Texture is linked: input → paint parameter.
TEXTURED_INPUTS = {"Base Color": "base_color", "Flake Density": "flake_density", "Coat Roughness": "coat_roughness"}
#: Linked inputs followed by :func:`normal_source`.
NORMAL_INPUTS = ("Normal", "Coat Normal")
#: Cycles' colour → float conversion of a linked socket (linear Rec.709 luminance).
GREY = np.array([0.2126, 0.7152, 0.0722], np.float32)


def _link_from(sock):
    """``(node, output socket)`` feeding a socket through reroutes, or None."""
    if sock is None or not sock.is_linked:
        return None
    link = sock.links[0]
    while link.from_node.bl_idname == "NodeReroute" and link.from_node.inputs[0].is_linked:
        link = link.from_node.inputs[0].links[0]
    return link.from_node, link.from_socket


def _image_rgba(image) -> tuple[int, int, np.ndarray, np.ndarray]:
    """An image's pixels as (width, height, linear RGB, alpha), float32 rows bottom first."""
    w, h, rgb = _image_rgb(image)
    px = np.empty(w * h * image.channels, np.float32)
    image.pixels.foreach_get(px)
    alpha = px.reshape(h * w, image.channels)[:, 3] if image.channels == 4 else np.ones(h * w, np.float32)
    return w, h, rgb, alpha


def _texture_uv_map(tex, mat_name: str, report: Report) -> str:
    """The UV map an Image Texture reads ("" = the mesh's active render UV map, as Cycles)."""
    src = _link_from(tex.inputs["Vector"])
    if src is None:
        return ""
    node, out = src
    if node.bl_idname == "ShaderNodeUVMap":
        return node.uv_map
    if node.bl_idname == "ShaderNodeTexCoord" and out.name == "UV":
        return ""
    report.warn(f"material \"{mat_name}\": the texture \"{tex.name}\" reads coordinates from {node.bl_idname}; "
                f"LACQUER uses the UV map")
    return ""


def texture_bindings(mat, report: Report, scene_images: dict, cache: dict, images: dict):
    """A Lacquer material's linked inputs: ``(textures JSON, UV map name)`` for the renderer
    (images baked into ``scene_images``), with a message for every link LACQUER cannot follow.
    Cached per material in ``cache``; ``images`` caches decoded Blender images."""
    from . import nodegroup

    if mat.name in cache:
        return cache[mat.name]
    node = mat.node_tree.nodes.get(nodegroup.NODE_NAME) if getattr(mat, "node_tree", None) else None
    textures: dict = {}
    uv_maps: list = []
    paint = props.material_json(mat.lacquer)
    for sock in node.inputs if node is not None else []:
        if not sock.is_linked or sock.name in NORMAL_INPUTS:
            continue
        key = TEXTURED_INPUTS.get(sock.name)
        src = _link_from(sock)
        if key is None:
            report.warn(f"material \"{mat.name}\": {sock.name} is connected; LACQUER renders the paint's own value "
                        f"(it exports links on {', '.join(TEXTURED_INPUTS)} and Normal)")
            continue
        if src is None or src[0].bl_idname != "ShaderNodeTexImage" or src[0].image is None:
            kind = src[0].bl_idname if src is not None else "nothing"
            report.warn(f"material \"{mat.name}\": {sock.name} comes from {kind}; LACQUER exports an Image Texture "
                        f"with an image there (the paint's value is used)")
            continue
        tex, out = src
        if paint.get("pigment_model", "lambert") != "lambert":
            report.warn(f"material \"{mat.name}\": textured parameters need the Lambert pigment in LACQUER "
                        f"(ignored: {sock.name})")
            continue
        if key == "coat_roughness" and not float(paint["coat_roughness"]) > 0.0:
            report.warn(f"material \"{mat.name}\": a Coat Roughness texture needs a rough coat (coat roughness > 0) "
                        f"in LACQUER (ignored)")
            continue
        try:
            if ("rgba", tex.image.name) not in images:
                images[("rgba", tex.image.name)] = _image_rgba(tex.image)
            w, h, rgb, alpha = images[("rgba", tex.image.name)]
        except (RuntimeError, ValueError) as e:
            report.warn(f"material \"{mat.name}\": {sock.name} texture not exported ({e})")
            continue
        if key == "base_color":
            values = np.repeat(alpha[:, None], 3, 1) if out.name == "Alpha" else rgb
            lo, hi = 0.0, 1.0
        else:
            grey = alpha if out.name == "Alpha" else rgb @ GREY
            # Coat Roughness is Principled's (√α, the fit's convention); Flake Density is in %.
            values = np.repeat((grey * grey if key == "coat_roughness" else grey)[:, None], 3, 1)
            lo, hi = (0.001, 0.5) if key == "coat_roughness" else (0.0, 100.0)
        clipped = np.clip(values, lo, hi).astype(np.float32)
        if not np.array_equal(clipped, values):
            report.warn(f"material \"{mat.name}\": {sock.name} texture \"{tex.image.name}\" has values outside "
                        f"[{lo:g}, {hi:g}] for LACQUER (clipped)")
        name = f"{tex.image.name}|{key}|{out.name}"
        scene_images[name] = {"width": w, "height": h, "pixels": _b64(clipped, np.float32)}
        binding = {"image": name, "interpolation": "closest" if tex.interpolation == "Closest" else "linear"}
        if tex.interpolation not in ("Closest", "Linear"):
            report.warn(f"material \"{mat.name}\": {tex.interpolation} interpolation rendered as Linear by LACQUER")
        if tex.extension != "REPEAT" or tex.projection != "FLAT":
            report.warn(f"material \"{mat.name}\": texture \"{tex.name}\" is rendered with Flat projection and "
                        f"Repeat extension by LACQUER")
        textures[key] = binding
        uv_maps.append(_texture_uv_map(tex, mat.name, report))
    if len(set(uv_maps)) > 1:
        report.warn(f"material \"{mat.name}\": its textures read different UV maps; LACQUER uses "
                    f"\"{uv_maps[0] or 'the active render UV map'}\" for all")
    if textures and paint.get("sparkle", True):
        report.warn(f"material \"{mat.name}\": textured paint renders the mean flake lobe in LACQUER "
                    f"(no per-flake sparkle)")
    cache[mat.name] = (textures, uv_maps[0] if uv_maps else "")
    return cache[mat.name]


def _uv_array(mesh, uv_map: str, loops, report: Report, mat_name: str) -> np.ndarray:
    """Per-corner texture coordinates of ``uv_map`` ("" = the active render UV map); zeros with a
    message without one (Cycles then reads (0, 0))."""
    layers = mesh.uv_layers
    name = uv_map or (next((u.name for u in layers if u.active_render), None) if len(layers) else None)
    if not name or name not in layers:
        report.warn(f"material \"{mat_name}\": no UV map \"{uv_map or '(active)'}\" on mesh \"{mesh.name}\"; "
                    f"its textures read uv (0, 0)")
        return np.zeros((len(loops), 2), np.float32)
    uv = np.empty(len(mesh.loops) * 2, np.float32)
    layers[name].data.foreach_get("uv", uv)
    return uv.reshape(-1, 2)[loops]


# --- materials -------------------------------------------------------------------------------


def _principled_params() -> dict:
    return catalog.model_params("principled")


def _clamp_to(params: dict, name: str, value):
    p = params.get(name)
    if p is None:
        return value
    lo, hi = float(p["min"]), float(p["max"])
    if isinstance(value, list):
        return [min(max(float(v), lo), hi) for v in value]
    return min(max(float(value), lo), hi)


def _socket_value(node, name, report, mat_name):
    sock = node.inputs.get(name)
    if sock is None:
        return None
    if sock.is_linked:
        report.warn(f"material \"{mat_name}\": {node.name}.{name} is connected to nodes; LACQUER uses its "
                    f"unconnected value")
    v = sock.default_value
    try:
        return [float(x) for x in v][:3]
    except TypeError:
        return float(v)


def _surface_node(mat):
    if not getattr(mat, "node_tree", None):
        return None
    out = next((n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial" and n.is_active_output),
               None)
    if out is None or not out.inputs["Surface"].is_linked:
        return None
    node = out.inputs["Surface"].links[0].from_node
    while node.bl_idname == "NodeReroute" and node.inputs[0].is_linked:
        node = node.inputs[0].links[0].from_node
    return node


#: Principled BSDF socket → `principled` model parameter (contract §1).
PRINCIPLED_SOCKETS = (
    ("Base Color", "base_color"), ("Metallic", "metallic"), ("Roughness", "roughness"), ("IOR", "ior"),
    ("Specular IOR Level", "specular_ior_level"), ("Specular Tint", "specular_tint"),
    ("Coat Weight", "coat_weight"), ("Coat Roughness", "coat_roughness"), ("Coat IOR", "coat_ior"),
    ("Coat Tint", "coat_tint"), ("Thin Film Thickness", "thin_film_thickness"), ("Thin Film IOR", "thin_film_ior"),
)

#: Principled inputs the `principled` model does not have: warn when they are in use.
PRINCIPLED_IGNORED = (("Subsurface Weight", 0.0), ("Transmission Weight", 0.0), ("Sheen Weight", 0.0),
                      ("Emission Strength", 0.0), ("Anisotropic", 0.0), ("Alpha", 1.0), ("Diffuse Roughness", 0.0))


def material_desc(mat, report: Report) -> dict:
    """Material JSON for a Blender material (None → Blender's default grey)."""
    if mat is None:
        return {"model": "lambert", "albedo": DEFAULT_GREY}
    settings = getattr(mat, "lacquer", None)
    if settings is not None and settings.enabled:
        return props.material_json(settings)
    node = _surface_node(mat)
    principled = _principled_params()
    name = mat.name
    if node is not None and node.bl_idname == "ShaderNodeBsdfDiffuse":
        color = _socket_value(node, "Color", report, name)
        if (node.inputs["Roughness"].default_value or 0) > 0:
            report.warn(f"material \"{name}\": Diffuse BSDF roughness ignored (Lambert)")
        return {"model": "lambert", "albedo": _clamp_to(catalog.model_params("lambert"), "albedo", color)}
    if node is not None and node.bl_idname == "ShaderNodeBsdfPrincipled":
        if not principled:
            report.warn(f"material \"{name}\": this lacquer library has no `principled` model; rendered as "
                        f"Lambert with its Base Color")
            color = _socket_value(node, "Base Color", report, name)
            return {"model": "lambert", "albedo": _clamp_to(catalog.model_params("lambert"), "albedo", color)}
        out = {"model": "principled"}
        for sock, param in PRINCIPLED_SOCKETS:
            if param in principled:
                v = _socket_value(node, sock, report, name)
                if v is not None:
                    out[param] = _clamp_to(principled, param, v)
        for sock, neutral in PRINCIPLED_IGNORED:
            s = node.inputs.get(sock)
            if s is not None and (s.is_linked or abs(float(s.default_value) - neutral) > 1e-6):
                report.warn(f"material \"{name}\": Principled {sock} is not supported by LACQUER (ignored)")
        report.warn(f"material \"{name}\" is not a Lacquer paint: approximated by the `principled` model from "
                    f"its Principled BSDF inputs")
        return out
    # Anything else: the diffuse colour Blender shows in solid mode.
    color = [float(c) for c in mat.diffuse_color[:3]]
    kind = node.bl_idname if node is not None else "no surface shader"
    report.warn(f"material \"{name}\" ({kind}) has no Principled BSDF at its output: rendered as a diffuse "
                f"surface of its viewport colour")
    if principled:
        return {"model": "principled", "base_color": color}
    return {"model": "lambert", "albedo": color}


# --- lights ----------------------------------------------------------------------------------


def light_desc(light, matrix, report: Report) -> list:
    """Renderer lights for a Blender light at `matrix` (world)."""
    color = _vec(light.color)
    power = float(light.energy)
    pos = matrix.to_translation()
    down = (matrix.to_3x3() @ Vector((0.0, 0.0, -1.0))).normalized()  # lights shine along their −Z
    if light.type == "SUN":
        return [{"type": "sun", "direction": _dir(-down), "irradiance": [power * c for c in color],
                 "angle_deg": math.degrees(float(light.angle))}]
    if light.type in {"POINT", "SPOT"}:
        radius = float(getattr(light, "shadow_soft_size", 0.0))
        intensity = [power / (4.0 * math.pi) * c for c in color]
        if light.type == "POINT":
            if radius > 0:
                radiance = [i / (math.pi * radius * radius) for i in intensity]
                return [{"type": "sphere", "center": _point(pos), "radius": radius, "radiance": radiance,
                         "surface": False}]
            return [{"type": "point", "position": _point(pos), "intensity": intensity}]
        if radius > 0:
            report.warn(f"light \"{light.name}\": spot radius {radius:g} m rendered as a point (sharp shadows)")
        # Cycles: smoothstep over cos θ from cos(half) to cos(half) + (1 − cos(half))·blend.
        half = 0.5 * float(light.spot_size)
        cos_outer = math.cos(half)
        inner = math.acos(min(1.0, cos_outer + (1.0 - cos_outer) * float(light.spot_blend)))
        return [{"type": "spot", "position": _point(pos), "target": _point(pos + down), "intensity": intensity,
                 "cone_deg": math.degrees(half), "blend_deg": math.degrees(half - inner)}]
    if light.type == "AREA":
        sx = float(light.size)
        sy = float(light.size_y) if light.shape in {"RECTANGLE", "ELLIPSE"} else sx
        ellipse = light.shape in {"DISK", "ELLIPSE"}  # the ellipse inscribed in sx × sy
        if float(getattr(light, "spread", math.pi)) < math.pi - 1e-4:
            report.warn(f"light \"{light.name}\": area light spread ignored (180°)")
        m3 = matrix.to_3x3()
        ex, ey = m3 @ Vector((1.0, 0.0, 0.0)), m3 @ Vector((0.0, 1.0, 0.0))
        area = (ex * sx).cross(ey * sy).length * (math.pi / 4.0 if ellipse else 1.0)
        if area <= 0:
            return []
        radiance = [power / (math.pi * area) * c for c in color]
        corner = pos - ex * (sx / 2) - ey * (sy / 2)
        # Front side = edge_u × edge_v must face the light's −Z: edge_u = y, edge_v = x.
        return [{"type": "rectangle", "corner": _point(corner), "edge_u": _dir(ey * sy), "edge_v": _dir(ex * sx),
                 "radiance": radiance, "ellipse": ellipse, "surface": False}]
    report.warn(f"light \"{light.name}\": type {light.type} not supported (left out)")
    return []


# --- world -----------------------------------------------------------------------------------


def _write_hdr(path: str, rgb: np.ndarray):
    """Radiance RGBE (flat scanlines), rows top first."""
    h, w, _ = rgb.shape
    rgb = np.maximum(np.nan_to_num(rgb.astype(np.float64), nan=0.0, posinf=0.0), 0.0)
    m = rgb.max(axis=2)
    e = np.zeros(m.shape, np.int32)
    mant, exp = np.frexp(m)
    ok = m > 1e-32
    e[ok] = exp[ok]
    scale = np.where(ok, mant * 256.0 / np.where(m > 0, m, 1.0), 0.0)
    out = np.zeros((h, w, 4), np.uint8)
    out[..., :3] = np.clip(rgb * scale[..., None], 0, 255).astype(np.uint8)
    out[..., 3] = np.where(ok, e + 128, 0).astype(np.uint8)
    with open(path, "wb") as f:
        f.write(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n" + f"-Y {h} +X {w}\n".encode())
        f.write(out.tobytes())


def _srgb_to_linear(c: np.ndarray) -> np.ndarray:
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def _environment_file(image, report: Report) -> str | None:
    """A lat-long file the renderer can read for a Blender image: the image's own .hdr/.exr, or
    its pixels written to a temporary .hdr."""
    path = bpy.path.abspath(image.filepath, library=image.library) if image.filepath else ""
    if path and not image.packed_file and os.path.splitext(path)[1].lower() in {".hdr", ".exr"} \
            and os.path.isfile(path) and not image.is_dirty:
        return os.path.abspath(path)
    w, h = image.size
    if w == 0 or h == 0:
        report.warn(f"world image \"{image.name}\" has no pixels (left out)")
        return None
    px = np.empty(w * h * image.channels, np.float32)
    image.pixels.foreach_get(px)
    px = px.reshape(h, w, image.channels)[::-1, :, :3]  # Blender rows are bottom first
    if not image.is_float and image.colorspace_settings.name in {"sRGB", "sRGB EOTF"}:
        px = _srgb_to_linear(px)
    fd, tmp = tempfile.mkstemp(prefix="lacquer-env-", suffix=".hdr")
    os.close(fd)
    _write_hdr(tmp, px)
    return tmp


def world_desc(world, report: Report, temp_files: list) -> list:
    """The environment light for the world (constant colour or an equirectangular image)."""
    if world is None:
        return []
    if not world.use_nodes or world.node_tree is None:
        return [{"type": "environment", "radiance": _vec(world.color)}]
    out = next((n for n in world.node_tree.nodes if n.bl_idname == "ShaderNodeOutputWorld" and n.is_active_output),
               None)
    if out is None or not out.inputs["Surface"].is_linked:
        return []
    bg = out.inputs["Surface"].links[0].from_node
    if bg.bl_idname != "ShaderNodeBackground":
        report.warn(f"world \"{world.name}\": {bg.bl_idname} at the output is not supported (no environment)")
        return []
    strength = float(bg.inputs["Strength"].default_value)
    if bg.inputs["Strength"].is_linked:
        report.warn(f"world \"{world.name}\": Strength is connected to nodes; its unconnected value is used")
    color_in = bg.inputs["Color"]
    if not color_in.is_linked:
        return [{"type": "environment", "radiance": [strength * c for c in _vec(color_in.default_value)[:3]]}]
    src = color_in.links[0].from_node
    if src.bl_idname == "ShaderNodeTexEnvironment" and src.image is not None:
        if src.projection != "EQUIRECTANGULAR":
            report.warn(f"world \"{world.name}\": {src.projection} projection not supported (equirectangular used)")
        rotation = 0.0
        vec_in = src.inputs["Vector"]
        if vec_in.is_linked:
            mapping = vec_in.links[0].from_node
            if mapping.bl_idname == "ShaderNodeMapping":
                rot = mapping.inputs["Rotation"].default_value
                if abs(rot[0]) > 1e-6 or abs(rot[1]) > 1e-6:
                    report.warn(f"world \"{world.name}\": mapping rotation about X/Y ignored (Z kept)")
                rotation = math.degrees(rot[2])
            else:
                report.warn(f"world \"{world.name}\": environment vector from {mapping.bl_idname} ignored")
        path = _environment_file(src.image, report)
        if path is None:
            return []
        if path.startswith(tempfile.gettempdir()) and os.path.basename(path).startswith("lacquer-env-"):
            temp_files.append(path)
        # Blender's lat-long u = 1/2 − atan2(y, x)/2π; the renderer's u = 1/2 + atan2(x, −z)/2π
        # in its y-up frame: a quarter turn apart, plus the mapping's Z rotation.
        return [{"type": "environment", "map": path, "scale": strength,
                 "rotation_deg": ENV_ROTATION_OFFSET_DEG + rotation}]
    report.warn(f"world \"{world.name}\": {src.bl_idname} into the Background is not supported; using the "
                f"Background's colour value")
    return [{"type": "environment", "radiance": [strength * c for c in _vec(color_in.default_value)[:3]]}]


#: Rotation (degrees about up) that aligns the renderer's lat-long convention with Blender's
#: (measured: background pixels in six directions, with and without a Mapping rotation, agree).
ENV_ROTATION_OFFSET_DEG = 90.0


# --- camera ----------------------------------------------------------------------------------


def camera_desc(cam_obj, width: int, height: int, report: Report) -> dict:
    cam = cam_obj.data
    m = cam_obj.matrix_world
    if cam.type != "PERSP":
        report.warn(f"camera \"{cam_obj.name}\": {cam.type} projection not supported (perspective used)")
    if abs(cam.shift_x) > 1e-6 or abs(cam.shift_y) > 1e-6:
        report.warn(f"camera \"{cam_obj.name}\": lens shift ignored")
    if cam.dof.use_dof:
        report.warn(f"camera \"{cam_obj.name}\": depth of field ignored (pinhole)")
    # Sensor fit: the sensor size applies to the larger image side (AUTO) or the chosen one.
    fit = cam.sensor_fit
    if fit == "AUTO":
        fit = "HORIZONTAL" if width >= height else "VERTICAL"
    sensor = cam.sensor_height if (fit == "VERTICAL" and cam.sensor_fit == "VERTICAL") else cam.sensor_width
    half = math.atan(0.5 * sensor / cam.lens)
    if fit == "HORIZONTAL":
        vhalf = math.atan(math.tan(half) * height / width)
    else:
        vhalf = half
    pos = m.to_translation()
    fwd = (m.to_3x3() @ Vector((0.0, 0.0, -1.0))).normalized()
    up = (m.to_3x3() @ Vector((0.0, 1.0, 0.0))).normalized()
    return {"position": _point(pos), "look_at": _point(pos + fwd), "up": _dir(up), "fov_deg": math.degrees(2 * vhalf)}


# --- the whole scene ---------------------------------------------------------------------------


def view_camera_desc(view_matrix, window_matrix) -> dict:
    """A 3D viewport's view as the renderer's camera: the inverse view matrix places it, the
    projection matrix gives the vertical field of view (perspective only)."""
    inv = view_matrix.inverted()
    pos = inv.to_translation()
    fwd = (inv.to_3x3() @ Vector((0.0, 0.0, -1.0))).normalized()
    up = (inv.to_3x3() @ Vector((0.0, 1.0, 0.0))).normalized()
    vhalf = math.atan(1.0 / float(window_matrix[1][1]))
    return {"position": _point(pos), "look_at": _point(pos + fwd), "up": _dir(up), "fov_deg": math.degrees(2 * vhalf)}


def normals_to_blender(n):
    """World normals from the renderer's y-up frame back to Blender's z-up (the inverse of Y_UP)."""
    out = np.empty_like(n)
    out[..., 0], out[..., 1], out[..., 2] = n[..., 0], -n[..., 2], n[..., 1]
    return out


def scene_desc(depsgraph, width: int, height: int, report: Report, temp_files: list, camera: dict | None = None) -> dict:
    """The scene of an evaluated depsgraph as the renderer's JSON scene (``camera``: a camera
    description to use instead of the scene's camera, e.g. a viewport's)."""
    scene = depsgraph.scene
    cam_obj = scene.camera
    if cam_obj is None and camera is None:
        raise ValueError("the scene has no camera")
    if cam_obj is not None:
        cam_obj = cam_obj.evaluated_get(depsgraph)
    meshes: dict = {}
    objects: list = []
    lights: list = []
    mesh_cache: dict = {}
    images: dict = {}  # normal-map and texture images read once per render
    scene_images: dict = {}  # baked textures (the scene's "images")
    tex_cache: dict = {}

    def bindings(mat):
        return texture_bindings(mat, report, scene_images, tex_cache, images)
    unit_m = float(scene.unit_settings.scale_length)  # metres per Blender unit
    if not unit_m > 0.0:
        raise ValueError(f"the scene's Unit Scale is {unit_m}: it must be positive")
    for inst in depsgraph.object_instances:
        ob = inst.instance_object if inst.is_instance else inst.object
        matrix = inst.matrix_world.copy()
        if ob.type == "LIGHT":
            lights.extend(light_desc(ob.data, matrix, report))
            continue
        if ob.type not in GEOMETRY_TYPES:
            if ob.type in {"VOLUME", "POINTCLOUD", "GPENCIL", "GREASEPENCIL"}:
                report.warn(f"object \"{ob.name}\": {ob.type.lower()} objects are not rendered by LACQUER")
            continue
        # Metres per object unit along each object axis: the world transform's column lengths
        # (parents and instancers included; the node group's Vector Transform Object → World
        # measures the same) × the scene's metres per Blender unit.
        # 7 significant digits: the mesh cache's key (relative, so tiny scales do not round to 0).
        axis_scale = tuple(float(f"{float(x) * unit_m:.7g}") for x in matrix.to_scale())
        key = (ob.name, ob.data.name if ob.data else "", ob.type, axis_scale)
        if ob.type == "MESH" and ob.data is not None:
            # Instances and linked duplicates share the evaluated mesh: export it once per
            # (mesh, materials, scale) and instance it by matrix.
            slots = tuple(s.material.name if s.material else "" for s in ob.material_slots)
            key = ("data", ob.data.as_pointer(), slots, axis_scale)
        entry = mesh_cache.get(key)
        if entry is None:
            mesh = None
            slots = [s.material for s in ob.material_slots]
            perturb = {}
            try:
                mesh = ob.to_mesh() if ob.type != "MESH" else ob.data
                arrays = _mesh_arrays(mesh, axis_scale) if mesh is not None else {}
                if arrays:
                    perturb = perturb_arrays(mesh, arrays, slots, unit_m, report, images, bindings)
            except RuntimeError as e:  # e.g. hair curves, which have no mesh
                report.warn(f"object \"{ob.name}\": no triangles to render ({e})")
                arrays = {}
            finally:
                if ob.type != "MESH" and mesh is not None:
                    ob.to_mesh_clear()
            parts = []
            if arrays:
                mi = arrays["material_index"]
                for idx in np.unique(mi):
                    sel = np.nonzero(mi == idx)[0]
                    corner = (sel[:, None] * 3 + np.arange(3)).reshape(-1)
                    name = f"m{len(meshes)}"
                    meshes[name] = {
                        "positions": _b64(arrays["positions"][corner], np.float32),
                        "triangles": _b64(np.arange(len(corner), dtype=np.uint32).reshape(-1, 3), np.uint32),
                        "normals": _b64(arrays["normals"][corner], np.float32),
                        "uvs": _b64(arrays["uvs"][corner], np.float32),
                        **_select_perturb(perturb.get(int(idx), {}), corner),
                    }
                    mat = slots[idx] if 0 <= idx < len(slots) else None
                    parts.append((name, mat))
            entry = mesh_cache[key] = parts
        world = Y_UP @ matrix
        for name, mat in entry:
            desc = material_desc(mat, report)
            if desc.get("model") == "coated_paint":
                # uv in metres (see _mesh_arrays); Flake Scale k makes flakes k× larger: a metre of
                # surface is then 1/k metre of the paint's sparkle pattern.
                k = float(mat.lacquer.flake_scale) if mat is not None else 1.0
                desc = dict(desc, surface_scale_mm=1000.0 / k)
                textures = bindings(mat)[0] if mat is not None else {}
                if textures:
                    desc["textures"] = textures
            objects.append({"type": "mesh", "mesh": name, "material": desc,
                            "transform": {"matrix": [_vec(row) for row in world]}})
    lights.extend(world_desc(scene.world, report, temp_files))
    if scene.render.use_border:
        report.warn("render region (border) ignored: the whole frame is rendered")
    if scene.render.use_motion_blur:
        report.warn("motion blur ignored")
    if not objects:
        report.warn("the scene has no visible geometry")
    out = {"camera": camera if camera is not None else camera_desc(cam_obj, width, height, report),
           "meshes": meshes, "objects": objects, "lights": lights}
    if scene_images:
        out["images"] = scene_images
    return out


def render_size(scene) -> tuple[int, int]:
    r = scene.render
    return max(1, int(r.resolution_x * r.resolution_percentage / 100)), \
        max(1, int(r.resolution_y * r.resolution_percentage / 100))


def job(depsgraph, report: Report, temp_files: list, preview: bool = False, size: tuple | None = None,
        camera: dict | None = None) -> dict:
    """The whole render job for the depsgraph's scene (``size``, ``camera``: a viewport's)."""
    scene = depsgraph.scene
    width, height = size if size is not None else render_size(scene)
    s = scene.lacquer
    return {
        "scene": scene_desc(depsgraph, width, height, report, temp_files, camera=camera),
        "width": width,
        "height": height,
        "spp": int(s.preview_samples if preview else s.samples),
        "max_depth": int(s.max_depth),
        "seed": int(s.seed),
        "threads": int(scene.render.threads) if scene.render.threads_mode == "FIXED" else 0,
        "aovs": False,
        "sparkle": bool(s.sparkle),
        "clamp": float(s.clamp),
    }
