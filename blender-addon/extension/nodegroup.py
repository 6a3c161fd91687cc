"""The `Lacquer Coated Paint` node group (Cycles and EEVEE nodes only) and the materials using it.

Structure (version ``NODE_GROUP_VERSION``; the core's fit, docs/blender-fit.md, models exactly
this in the mean-lobe limit):

* Three Principled BSDFs share the clearcoat (Coat Weight, Coat Roughness, Coat IOR, Coat Tint,
  Coat Normal = the surface's shading normal N):

  - **base**: Base Color = Pigment Color, Metallic 0, Specular IOR Level 0 (pigment in binder:
    no interface of its own), so a Lambert diffuse under the coat;
  - **flake**: Base Color = Flake Color, Metallic 1, Normal = the flake normal;
  - **pearl**: Base Color = Pearl Color, Metallic 0, IOR 1.5, Thin Film Thickness / IOR =
    Pearl Film Thickness / IOR, Normal = the pearl flake normal.

* Mixed as ``Mix(Mix(base, pearl, c_p / (1 − c_f)), flake, c_f)`` (c_f = Flake Coverage,
  c_p = Pearl Coverage): weights flake ``c_f``, pearl ``c_p``, base ``1 − c_f − c_p``, as the
  core's fit (docs/blender-fit.md) models the group.

* **Sparkle = 1** (per-cell flakes): the surface is cut into Voronoi cells (3D, F1, randomness 1)
  of object coordinates × the per-axis scale of the object's world transform (parents and
  instances included) × the scene's Unit Scale, i.e. metres on the object, as LACQUER's export
  computes them (``export._mesh_arrays``). The cell scale is
  ``0.937 / Flake Size`` (per metre): a plane through such a Voronoi diagram has cells of mean
  area ``0.69 / scale²`` = one flake's area ``π (Flake Size)² / 4`` (measured by Monte Carlo on
  Blender's jittered-grid Voronoi). Each cell's three random values (the Voronoi Color r, g, b)
  sample its flake normal m from GGX(α = Flake Spread) around N (``tan²θ = α² g / (1 − g)``,
  ``φ = 2π b``) and decide whether it holds a flake: ``r < c_f · G1(I) (I·m) / ((I·N)(N·m))``,
  the visible-normal weighting of a tilted flake (I toward the viewer, G1 Smith GGX masking),
  so that the flake weight, 1 or 0 per cell, averages to the mean flake lobe's. The flake's own
  roughness is Flake Roughness. Pearl flakes use an independent Voronoi (shifted coordinates,
  Pearl Size, probability from ``c_p / (1 − c_f)``, Pearl Spread).

* **Sparkle = 0** (the mean lobe): every point gets ``f_flake = Flake Coverage`` with Normal = N
  and Principled roughness ``(Flake Spread² + Flake Roughness⁴)^¼`` (GGX α of the flake-normal
  distribution combined with the flakes' own α = roughness²), and likewise for pearls.
  Values between 0 and 1 interpolate the weights, roughness and normal (use 0 or 1).

* **Textured Base Color** (version 7): the base Principled's Base Color is
  ``clamp(Pigment Color + (B·q(B) − F·q(F)), 0, 1)`` with B = Base Color (a texture), F = Fit
  Base Color and q the core's base colour map (the hidden ``Base Color Map k`` inputs,
  interpolated linearly on ``fit.BASE_COLOR_GRID``): per channel the pigment the fitted group
  needs for each base colour, computed by the core's fit (the paint is nonlinear in its pigment
  albedo, the group linear). Untextured (B = F) it is the fitted Pigment Color bit for bit.
"""

from __future__ import annotations

import json
import math

import bpy

from . import fit as fitmod
from . import props

GROUP_NAME = "Lacquer Coated Paint"
NODE_NAME = "Lacquer Paint"
NODE_GROUP_VERSION = 7

#: Cells per metre × flake diameter (µm → m below) so that a planar section of the 3D
#: Voronoi diagram has cells of one flake's area (measured: mean section area 0.69 / scale²).
CELL_SCALE_FACTOR = 0.937

#: Group inputs: (name, socket type, default, min, max, description). The first sixteen are the
#: contract with the core's fit (docs/blender-fit.md, ../shared/CONTRACT.md); "Pearl Size" is set from the paint directly.
INPUTS = (
    ("Pigment Color", "NodeSocketColor", (0.5, 0.03, 0.03), None, None,
     "Diffuse colour of the basecoat as seen through Principled's coat"),
    ("Flake Color", "NodeSocketColor", (0.91, 0.92, 0.92), None, None, "Base Color of the metallic flakes"),
    ("Flake Coverage", "NodeSocketFloat", 0.03, 0.0, 1.0, "Area fraction of metallic flakes"),
    ("Flake Roughness", "NodeSocketFloat", 0.05, 0.0, 1.0, "Principled roughness of one flake's surface"),
    ("Flake Spread", "NodeSocketFloat", 0.21, 0.0, 1.0, "GGX α of the distribution of flake normals"),
    ("Flake Size", "NodeSocketFloat", 20.0, 0.1, 10000.0,
     "Flake diameter in µm (world metres: Blender units × the scene's Unit Scale)"),
    ("Pearl Coverage", "NodeSocketFloat", 0.0, 0.0, 1.0, "Area fraction of pearlescent flakes"),
    ("Pearl Color", "NodeSocketColor", (0.8, 0.8, 0.8), None, None, "Base Color of the pearl flakes"),
    ("Pearl Film Thickness", "NodeSocketFloat", 120.0, 0.0, 100000.0, "Thin film thickness on pearls (nm)"),
    ("Pearl Film IOR", "NodeSocketFloat", 2.6, 1.0, 3.0, "Thin film IOR on pearls"),
    ("Pearl Spread", "NodeSocketFloat", 0.21, 0.0, 1.0, "GGX α of the distribution of pearl normals"),
    ("Coat Weight", "NodeSocketFloat", 1.0, 0.0, 1.0, "Principled Coat Weight"),
    ("Coat Roughness", "NodeSocketFloat", 0.14, 0.0, 1.0, "Principled Coat Roughness"),
    ("Coat IOR", "NodeSocketFloat", 1.5, 1.0, 4.0, "Principled Coat IOR"),
    ("Coat Tint", "NodeSocketColor", (1.0, 1.0, 1.0), None, None, "Principled Coat Tint"),
    ("Sparkle", "NodeSocketFloat", 1.0, 0.0, 1.0, "1 = individual flakes at their true size, 0 = the mean lobe"),
    ("Pearl Size", "NodeSocketFloat", 15.0, 0.1, 10000.0, "Pearl flake diameter in µm"),
    # Artist controls (version 5), not fitted: set from the material's Lacquer settings or linked.
    ("Normal", "NodeSocketVector", (0.0, 0.0, 0.0), None, None,
     "Shading normal of the whole paint (Normal Map or Bump output); unconnected: the surface's"),
    ("Coat Normal", "NodeSocketVector", (0.0, 0.0, 0.0), None, None,
     "Normal of the clearcoat's surface; unconnected: Normal"),
    ("Orange Peel", "NodeSocketFloat", 0.0, 0.0, 1000.0,
     "RMS height of the clearcoat's waviness in µm (0 = a perfectly flat coat)"),
    ("Orange Peel Wavelength", "NodeSocketFloat", 3.0, 0.01, 1000.0, "Wavelength of the orange peel in mm"),
    ("Flake Scale", "NodeSocketFloat", 1.0, 0.01, 100.0,
     "Multiplier on flake and pearl size (1 = the paint's physical size)"),
    ("Pixel Angle", "NodeSocketFloat", 0.0, 0.0, 1.0,
     "Radians per pixel of the render camera (set by the extension; 0 = no level of detail)"),
    ("Sparkle Samples", "NodeSocketFloat", 64.0, 1.0, 1e6,
     "Samples per pixel of the render (set by the extension): a pixel footprint holding more flake "
     "cells than this fades them into the mean lobe"),
    # Textured parameters (version 6): set to the paint's values by the extension; link an Image
    # Texture to texture them (both engines; LACQUER exports the image, see export.py).
    ("Base Color", "NodeSocketColor", (0.5, 0.03, 0.03), None, None,
     "Pigment albedo of the paint (base_color); link an Image Texture to texture it"),
    ("Flake Density", "NodeSocketFloat", 3.0, 0.0, 100.0,
     "Metallic flake coverage in % (flake_density); link a texture (values in %) to vary it"),
    ("Fit Base Color", "NodeSocketColor", (0.5, 0.03, 0.03), None, None,
     "The base colour the fit used (set by the extension): the base colour map's reference"),
    ("Fit Flake Density", "NodeSocketFloat", 3.0, 0.0, 100.0,
     "The flake density the fit used (set by the extension): Flake Coverage scales by Flake Density / this"),
)

# The base colour map (version 7): the core's ratio q = (pigment − pigment(0)) / base colour per
# channel at each base colour of fit.BASE_COLOR_GRID (rust-core/src/fit/node_group.rs,
# BaseColorMap), set by the extension from the fit. Defaults: q = 1 (pigment follows the texel).
INPUTS = INPUTS + tuple(
    (fitmod.map_socket(k), "NodeSocketVector", (1.0, 1.0, 1.0), None, None,
     f"Base colour map (set by the extension): pigment per unit base colour at {t:g}, per channel")
    for k, t in enumerate(fitmod.BASE_COLOR_GRID))

#: Inputs the extension sets and hides on the material's node (not for artists to edit).
HIDDEN_INPUTS = ("Fit Base Color", "Fit Flake Density") + tuple(
    fitmod.map_socket(k) for k in range(len(fitmod.BASE_COLOR_GRID)))

#: Orange-peel waves: (unit direction in the object's metric coordinates, phase). The render
#: crate's table (rust-core/render/src/perturb.rs, ``PEEL_WAVES``), which LACQUER evaluates; the
#: test ``test_orange_peel_tilts_the_coat_in_both_engines`` checks the tilt LACQUER renders.
PEEL_WAVES = (
    ((0.347985273, 0.000000000, 0.937500000), 0.0),
    ((-0.429857439, 0.393784626, 0.812500000), 1.3),
    ((0.063487195, -0.723403847, 0.687500000), 2.6),
    ((0.503055598, 0.656146946, 0.562500000), 3.9),
    ((-0.885472495, -0.156627617, 0.437500000), 0.7),
    ((0.801498139, -0.509847509, 0.312500000), 2.0),
    ((-0.255000119, 0.948587734, 0.187500000), 3.3),
    ((-0.460005935, -0.885713436, 0.062500000), 4.6),
)


class _Builder:
    """Small helpers to wire math nodes: arguments are sockets or numbers."""

    def __init__(self, tree):
        self.tree = tree
        self.nodes = tree.nodes
        self.links = tree.links
        self.column = 0

    def node(self, kind, x, y, **attrs):
        n = self.nodes.new(kind)
        n.location = (x, y)
        for k, v in attrs.items():
            setattr(n, k, v)
        return n

    def feed(self, socket, value):
        if isinstance(value, bpy.types.NodeSocket):
            self.links.new(value, socket)
        elif isinstance(value, (tuple, list)) and len(socket.default_value) == 4 and len(value) == 3:
            socket.default_value = (*value, 1.0)
        else:
            socket.default_value = value

    def math(self, op, a, b=None, x=0, y=0, clamp=False):
        n = self.node("ShaderNodeMath", x, y, operation=op, use_clamp=clamp)
        self.feed(n.inputs[0], a)
        if b is not None:
            self.feed(n.inputs[1], b)
        n.hide = True
        return n.outputs[0]

    def vmath(self, op, a, b=None, scale=None, x=0, y=0):
        n = self.node("ShaderNodeVectorMath", x, y, operation=op)
        self.feed(n.inputs[0], a)
        if b is not None:
            self.feed(n.inputs[1], b)
        if scale is not None:
            self.feed(n.inputs["Scale"], scale)
        n.hide = True
        return n.outputs["Value"] if op in {"DOT_PRODUCT", "LENGTH", "DISTANCE"} else n.outputs["Vector"]

    def mix(self, data_type, fac, a, b, x=0, y=0):
        n = self.node("ShaderNodeMix", x, y, data_type=data_type)
        if data_type == "VECTOR":
            n.factor_mode = "UNIFORM"
        ins = [s for s in n.inputs if s.enabled]
        self.feed(ins[0], fac)
        self.feed(ins[1], a)
        self.feed(ins[2], b)
        n.hide = True
        return next(s for s in n.outputs if s.enabled)


def _new_interface(group):
    for name, stype, default, lo, hi, desc in INPUTS:
        s = group.interface.new_socket(name=name, in_out="INPUT", socket_type=stype)
        s.description = desc
        if stype == "NodeSocketColor":
            s.default_value = (*default, 1.0)
        elif stype == "NodeSocketVector":
            s.default_value = default
            s.hide_value = True  # a normal is connected, not typed
        else:
            s.default_value = default
            s.min_value, s.max_value = lo, hi
    group.interface.new_socket(name="BSDF", in_out="OUTPUT", socket_type="NodeSocketShader")


def _build(group):
    b = _Builder(group)
    gi = b.node("NodeGroupInput", -1800, 0)
    go = b.node("NodeGroupOutput", 1400, 0)
    I = gi.outputs  # noqa: E741  (group inputs by name)

    geo = b.node("ShaderNodeNewGeometry", -1800, 600)

    def linked_or(vec, fallback, x, y):
        """``normalize(vec)`` where a normal is connected (non-zero), else ``fallback``."""
        use = b.math("GREATER_THAN", b.vmath("LENGTH", vec, x=x, y=y), 1e-6, x=x + 100, y=y)
        return b.vmath("NORMALIZE", b.mix("VECTOR", use, fallback, vec, x=x + 200, y=y), x=x + 300, y=y)

    # The paint's normal: the Normal input when connected (normal map, bump), else the surface's.
    N = linked_or(I["Normal"], geo.outputs["Normal"], -2200, 600)
    incoming = geo.outputs["Incoming"]
    texco = b.node("ShaderNodeTexCoord", -1800, 900)
    # Object coordinates in metres on the object, so flakes stick to it: object coordinates ×
    # the per-axis scale of the object → world transform × the scene's metres per unit.
    # The world scale is the length of each object axis mapped to world space by a Vector
    # Transform (Object → World, type Vector: the 3×3 of the render's own object matrix, not
    # normalised). Cycles and EEVEE evaluate it per object *and per instance* with the matrix
    # they render (parents, collection and geometry-node instances included), which is what
    # LACQUER's export uses (``matrix_world.to_scale()``: the same column lengths). Rejected: the
    # object's ``scale`` (an Object attribute, or Object Info) is the local scale, blind to
    # parents and instancers; drivers or a custom property refreshed from ``matrix_world`` live
    # on the shared node group or on the object, so they cannot differ per instance, go stale
    # under animation and need the extension at render time (farms render without it).
    axes = []
    for k, axis in enumerate(((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))):
        vt = b.node("ShaderNodeVectorTransform", -1800, 1300 + 120 * k, vector_type="VECTOR",
                    convert_from="OBJECT", convert_to="WORLD")
        vt.inputs["Vector"].default_value = axis
        axes.append(b.vmath("LENGTH", vt.outputs["Vector"], x=-1650, y=1300 + 120 * k))
    world_scale = b.node("ShaderNodeCombineXYZ", -1500, 1400)
    for k in range(3):
        b.feed(world_scale.inputs[k], axes[k])
    # Metres per Blender unit: the scene's Unit Scale, read live by a View Layer attribute (an
    # RNA path the renderer resolves on the view layer, then the scene), so changing it needs no
    # refit; a physical flake keeps its size in metres, i.e. covers 1/scale_length more units.
    unit = b.node("ShaderNodeAttribute", -1800, 1100, attribute_type="VIEW_LAYER",
                  attribute_name="unit_settings.scale_length")
    metres = b.vmath("SCALE", world_scale.outputs["Vector"], scale=unit.outputs["Fac"], x=-1400, y=1300)
    P = b.vmath("MULTIPLY", texco.outputs["Object"], metres, x=-1600, y=1000)

    # A tangent frame around N (the helper axis switches near the poles).
    nz = b.node("ShaderNodeSeparateXYZ", -1600, 700)
    b.feed(nz.inputs[0], N)
    polar = b.math("GREATER_THAN", b.math("ABSOLUTE", nz.outputs["Z"], x=-1450, y=700), 0.99, x=-1300, y=700)
    helper = b.mix("VECTOR", polar, (0.0, 0.0, 1.0), (1.0, 0.0, 0.0), x=-1150, y=700)
    T = b.vmath("NORMALIZE", b.vmath("CROSS_PRODUCT", N, helper, x=-1000, y=700), x=-850, y=700)
    Bt = b.vmath("CROSS_PRODUCT", N, T, x=-700, y=700)
    # Level of detail: the pixel footprint's side in metres, view distance × Pixel Angle / √(I·N)
    # (the footprint stretches as 1/cos along the view on a tilted surface; ≥ 0.05 clamps the
    # grazing limit), as Cycles has no ray differentials in shader nodes.
    cam = b.node("ShaderNodeCameraData", -2200, 1600)
    view_m = b.math("MULTIPLY", cam.outputs["View Distance"], unit.outputs["Fac"], x=-2000, y=1600)
    cos_v = b.math("MAXIMUM", b.vmath("DOT_PRODUCT", geo.outputs["Incoming"], N, x=-2000, y=1650), 0.05,
                   x=-1900, y=1650)
    footprint = b.math("DIVIDE", b.math("MULTIPLY", view_m, I["Pixel Angle"], x=-1800, y=1600),
                       b.math("SQRT", cos_v, x=-1800, y=1650), x=-1700, y=1600)

    def layer(size, coverage, spread, offset, y0):
        """Voronoi flake cells → (weight, shading normal, roughness) of one flake population."""
        scaled = b.math("MULTIPLY", size, I["Flake Scale"], x=-1500, y=y0 + 150)
        # Cells per footprint n = (footprint / diameter)²; the cells keep the weight
        # w = min(1, √(S / n)) (S = Sparkle Samples) and the mean lobe takes the rest. A pixel's S
        # samples see S random cells: their mean varies as σ²/S where the footprint's true mean
        # varies as σ²/n; with w² σ²/S = σ²/n the pixel keeps the physical glint variance of n
        # cells (LACQUER's, whose sparkle counts the flakes in each footprint) and converges to
        # the mean lobe as the footprint grows, instead of showing sampling noise.
        n_cells = b.math("POWER", b.math("DIVIDE", footprint, b.math("MULTIPLY", scaled, 1e-6, x=-1600, y=y0 + 250),
                                         x=-1500, y=y0 + 250), 2.0, x=-1400, y=y0 + 250)
        lod = b.math("MINIMUM", b.math("SQRT", b.math("DIVIDE", I["Sparkle Samples"],
                                                      b.math("MAXIMUM", n_cells, 1e-12, x=-1300, y=y0 + 250),
                                                      x=-1200, y=y0 + 250), x=-1100, y=y0 + 250), 1.0,
                     x=-1000, y=y0 + 250)
        sparkle = b.math("MULTIPLY", I["Sparkle"], lod, x=-900, y=y0 + 250)
        cell_scale = b.math("DIVIDE", CELL_SCALE_FACTOR * 1e6, scaled, x=-1400, y=y0 + 150)
        coords = b.vmath("ADD", P, offset, x=-1400, y=y0 + 100) if offset else P
        vor = b.node("ShaderNodeTexVoronoi", -1250, y0, voronoi_dimensions="3D", feature="F1")
        b.feed(vor.inputs["Vector"], coords)
        b.feed(vor.inputs["Scale"], cell_scale)
        b.feed(vor.inputs["Randomness"], 1.0)
        rnd = b.node("ShaderNodeSeparateColor", -1050, y0)
        b.feed(rnd.inputs[0], vor.outputs["Color"])
        r, g, bl = rnd.outputs[0], rnd.outputs[1], rnd.outputs[2]
        # Flake normal ~ GGX(α): tan²θ = α² g / (1 − g), φ = 2π b.
        a2 = b.math("MULTIPLY", spread, spread, x=-850, y=y0 - 50)
        odds = b.math("DIVIDE", g, b.math("ADD", b.math("MULTIPLY", g, -1.0, x=-1000, y=y0 - 120), 1.0 + 1e-6,
                                           x=-900, y=y0 - 120), x=-800, y=y0 - 120)
        t2 = b.math("MULTIPLY", a2, odds, x=-700, y=y0 - 80)
        cos_t = b.math("POWER", b.math("ADD", t2, 1.0, x=-600, y=y0 - 80), -0.5, x=-500, y=y0 - 80)
        sin_t = b.math("MULTIPLY", b.math("SQRT", t2, x=-600, y=y0 - 140), cos_t, x=-500, y=y0 - 140)
        phi = b.math("MULTIPLY", bl, 2.0 * math.pi, x=-800, y=y0 - 200)
        lx = b.math("MULTIPLY", sin_t, b.math("COSINE", phi, x=-700, y=y0 - 200), x=-400, y=y0 - 160)
        ly = b.math("MULTIPLY", sin_t, b.math("SINE", phi, x=-700, y=y0 - 240), x=-400, y=y0 - 200)
        m = b.vmath("ADD",
                    b.vmath("ADD", b.vmath("SCALE", T, scale=lx, x=-300, y=y0 - 120),
                            b.vmath("SCALE", Bt, scale=ly, x=-300, y=y0 - 160), x=-200, y=y0 - 140),
                    b.vmath("SCALE", N, scale=cos_t, x=-300, y=y0 - 200), x=-100, y=y0 - 160)
        normal = b.vmath("NORMALIZE", b.mix("VECTOR", sparkle, N, m, x=0, y=y0 - 160), x=100, y=y0 - 160)
        # Weight: 1 in a flake cell, 0 elsewhere (Sparkle 1); the coverage everywhere (Sparkle 0).
        # Cells draw normals m from D(m) cos θm, but the viewer sees the normals' visible
        # distribution G1(I) (I·m) D(m) / (I·N): a flake tilted to m shows its projected area
        # (I·m)/(N·m) per unit of surface (a Principled closure with Normal = m shades the cell as
        # if it covered the cell's own projected area I·N), and Smith masking G1(I) (GGX, α =
        # spread) hides some. So a cell is a flake with probability coverage × G1(I) (I·m) /
        # ((I·N)(N·m)); the mean over cells is then the mean flake lobe but for the shadowing
        # toward the light.
        i_m = b.math("MAXIMUM", b.vmath("DOT_PRODUCT", incoming, m, x=-200, y=y0 + 200), 0.0, x=-100, y=y0 + 200)
        i_n = b.math("MAXIMUM", b.vmath("DOT_PRODUCT", incoming, N, x=-200, y=y0 + 250), 1e-3, x=-100, y=y0 + 250)
        # Λ = (√(1 + α² tan²θ) − 1)/2, tan²θ = 1/cos²θ − 1; G1 = 1/(1 + Λ).
        tan2 = b.math("SUBTRACT", b.math("DIVIDE", 1.0, b.math("MULTIPLY", i_n, i_n, x=-100, y=y0 + 300),
                                         x=0, y=y0 + 300), 1.0, x=100, y=y0 + 300)
        lam = b.math("MULTIPLY", b.math("SUBTRACT", b.math("SQRT", b.math("ADD", b.math(
            "MULTIPLY", a2, tan2, x=200, y=y0 + 300), 1.0, x=300, y=y0 + 300), x=400, y=y0 + 300), 1.0,
            x=500, y=y0 + 300), 0.5, x=600, y=y0 + 300)
        g1 = b.math("DIVIDE", 1.0, b.math("ADD", lam, 1.0, x=700, y=y0 + 300), x=800, y=y0 + 300)
        proj = b.math("MULTIPLY", g1, b.math("DIVIDE", i_m, b.math("MULTIPLY", i_n, cos_t, x=0, y=y0 + 250),
                                             x=100, y=y0 + 220), x=200, y=y0 + 250)
        present = b.math("LESS_THAN", r, b.math("MULTIPLY", coverage, proj, x=200, y=y0 + 200), x=300, y=y0 + 150)
        weight = b.mix("FLOAT", sparkle, coverage, present, x=400, y=y0 + 100)
        # Roughness: the flake's own (Sparkle 1) or the whole distribution's (Sparkle 0).
        fr = I["Flake Roughness"]
        fr4 = b.math("POWER", fr, 4.0, x=-850, y=y0 - 300)
        mean_rough = b.math("POWER", b.math("ADD", a2, fr4, x=-700, y=y0 - 300), 0.25, x=-550, y=y0 - 300)
        rough = b.mix("FLOAT", sparkle, mean_rough, fr, x=-400, y=y0 - 300)
        return weight, normal, rough

    # Textured Base Color (version 7): the core's base colour map (BaseColorMap in
    # rust-core/src/fit/node_group.rs) gives per channel the ratio q(t) = (p(t) − p(0)) / t of the
    # pigment p the fitted group needs for base colour t, on fit.BASE_COLOR_GRID; the pigment is
    # Pigment Color + (B·q(B) − F·q(F)) with B = Base Color, F = Fit Base Color and q linear
    # between the grid's values (q_0 + Σ_k clamp((x − t_{k−1}) / (t_k − t_{k−1}), 0, 1)·Δq_k,
    # one Map Range per interval; constant beyond the grid), clamped to [0, 1]. Unlinked, B = F:
    # the bracket is exactly 0 and the pigment is the fitted Pigment Color bit for bit.
    grid = fitmod.BASE_COLOR_GRID
    qs = [I[fitmod.map_socket(k)] for k in range(len(grid))]
    dq = [b.vmath("SUBTRACT", qs[k], qs[k - 1], x=-2600, y=-700 - 40 * k) for k in range(1, len(grid))]

    def mapped(x, y):
        """x · q(x), q interpolated on the grid (per channel)."""
        q = qs[0]
        for k in range(1, len(grid)):
            mr = b.node("ShaderNodeMapRange", -2500 + 60 * k, y, data_type="FLOAT_VECTOR",
                        interpolation_type="LINEAR", clamp=True)
            vec, lo, hi, to_lo, to_hi = [sk for sk in mr.inputs if sk.enabled][:5]
            b.feed(vec, x)
            lo.default_value = (grid[k - 1],) * 3
            hi.default_value = (grid[k],) * 3
            to_lo.default_value = (0.0, 0.0, 0.0)
            to_hi.default_value = (1.0, 1.0, 1.0)
            mr.hide = True
            fma = b.node("ShaderNodeVectorMath", -2470 + 60 * k, y - 30, operation="MULTIPLY_ADD")
            b.feed(fma.inputs[0], next(o for o in mr.outputs if o.enabled))
            b.feed(fma.inputs[1], dq[k - 1])
            b.feed(fma.inputs[2], q)
            fma.hide = True
            q = fma.outputs["Vector"]
        return b.vmath("MULTIPLY", x, q, x=-1950, y=y)

    shift = b.vmath("SUBTRACT", mapped(I["Base Color"], -700), mapped(I["Fit Base Color"], -760), x=-1900, y=-700)
    pigment = b.vmath("MAXIMUM", b.vmath("MINIMUM", b.vmath("ADD", I["Pigment Color"], shift, x=-1850, y=-700),
                                         (1.0, 1.0, 1.0), x=-1800, y=-700), (0.0, 0.0, 0.0), x=-1750, y=-700)
    # Flake Coverage scales with Flake Density / Fit Flake Density (1 when nothing is linked).
    coverage = b.math("MULTIPLY", I["Flake Coverage"],
                      b.math("DIVIDE", I["Flake Density"], b.math("MAXIMUM", I["Fit Flake Density"], 1e-6,
                                                                  x=-2200, y=-800), x=-2100, y=-800),
                      x=-2000, y=-800, clamp=True)
    flake_w, flake_n, flake_r = layer(I["Flake Size"], coverage, I["Flake Spread"], None, 300)
    # Pearls share the area the metal flakes leave: weight c_p / (1 − c_f) under the flake mix,
    # so that the weights are (1 − c_f − c_p, c_f, c_p) (per cell: that probability).
    free = b.math("MAXIMUM", b.math("SUBTRACT", 1.0, coverage, x=-1600, y=-350), 1e-4, x=-1500, y=-350)
    pearl_cov = b.math("MINIMUM", b.math("DIVIDE", I["Pearl Coverage"], free, x=-1400, y=-350), 1.0, x=-1300, y=-350)
    pearl_w, pearl_n, pearl_r = layer(I["Pearl Size"], pearl_cov, I["Pearl Spread"], (37.11, 53.71, 19.31), -500)

    # The coat's normal: Coat Normal when connected, else Normal; tilted by orange peel, the
    # height field h(c) = A √(2/K) Σ_k sin(2π d_k·c/λ + φ_k) over the metric coordinates c = P
    # (metres on the object): ∂h/∂c = A √(2/K) (2π/λ) Σ_k cos(…) d_k, taken to world space as
    # R ∂h/∂c = M S⁻¹ ∂h/∂c (M the object's matrix, S its per-axis scale; c = S·p·unit), and
    # n' = normalize(n − (G − (G·n) n)) with the world gradient G (metres per metre).
    coat_n = linked_or(I["Coat Normal"], N, -2200, 400)
    k = b.math("DIVIDE", 2.0 * math.pi * 1e3, I["Orange Peel Wavelength"], x=-1400, y=2000)  # 1/m
    ak = b.math("MULTIPLY", b.math("MULTIPLY", I["Orange Peel"], 1e-6 * math.sqrt(2.0 / len(PEEL_WAVES)),
                                   x=-1400, y=2050), k, x=-1300, y=2050)
    grad = None
    for j, (d, phi) in enumerate(PEEL_WAVES):
        y = 2100 + 60 * j
        arg = b.math("ADD", b.math("MULTIPLY", b.vmath("DOT_PRODUCT", P, d, x=-1200, y=y), k, x=-1100, y=y), phi,
                     x=-1000, y=y)
        term = b.vmath("SCALE", d, scale=b.math("MULTIPLY", b.math("COSINE", arg, x=-900, y=y), ak, x=-800, y=y),
                       x=-700, y=y)
        grad = term if grad is None else b.vmath("ADD", grad, term, x=-600, y=y)
    g_obj = b.vmath("DIVIDE", grad, world_scale.outputs["Vector"], x=-500, y=2100)
    gt = b.node("ShaderNodeVectorTransform", -400, 2100, vector_type="VECTOR", convert_from="OBJECT",
                convert_to="WORLD")
    b.feed(gt.inputs["Vector"], g_obj)
    G = gt.outputs["Vector"]
    tangential = b.vmath("SUBTRACT", G, b.vmath("SCALE", coat_n, scale=b.vmath("DOT_PRODUCT", G, coat_n, x=-300,
                                                                                    y=2000), x=-200, y=2000),
                         x=-100, y=2000)
    coat_n = b.vmath("NORMALIZE", b.vmath("SUBTRACT", coat_n, tangential, x=0, y=2000), x=100, y=2000)

    def principled(x, y, label):
        p = b.node("ShaderNodeBsdfPrincipled", x, y)
        p.label = label
        for name in ("Coat Weight", "Coat Roughness", "Coat IOR", "Coat Tint"):
            b.feed(p.inputs[name], I[name])
        b.feed(p.inputs["Coat Normal"], coat_n)
        return p

    base = principled(500, 900, "Basecoat (pigment)")
    b.feed(base.inputs["Base Color"], pigment)
    b.feed(base.inputs["Metallic"], 0.0)
    b.feed(base.inputs["Specular IOR Level"], 0.0)
    b.feed(base.inputs["Roughness"], 0.5)
    b.feed(base.inputs["Normal"], N)

    flake = principled(500, 300, "Metallic flakes")
    b.feed(flake.inputs["Base Color"], I["Flake Color"])
    b.feed(flake.inputs["Metallic"], 1.0)
    b.feed(flake.inputs["Roughness"], flake_r)
    b.feed(flake.inputs["Normal"], flake_n)

    pearl = principled(500, -400, "Pearlescent flakes")
    b.feed(pearl.inputs["Base Color"], I["Pearl Color"])
    b.feed(pearl.inputs["Metallic"], 0.0)
    b.feed(pearl.inputs["IOR"], 1.5)
    b.feed(pearl.inputs["Roughness"], pearl_r)
    b.feed(pearl.inputs["Normal"], pearl_n)
    b.feed(pearl.inputs["Thin Film Thickness"], I["Pearl Film Thickness"])
    b.feed(pearl.inputs["Thin Film IOR"], I["Pearl Film IOR"])

    mix1 = b.node("ShaderNodeMixShader", 1000, 300)
    b.feed(mix1.inputs[0], pearl_w)
    b.feed(mix1.inputs[1], base.outputs[0])
    b.feed(mix1.inputs[2], pearl.outputs[0])
    mix2 = b.node("ShaderNodeMixShader", 1200, 0)
    b.feed(mix2.inputs[0], flake_w)
    b.feed(mix2.inputs[1], mix1.outputs[0])
    b.feed(mix2.inputs[2], flake.outputs[0])
    b.feed(go.inputs[0], mix2.outputs[0])


def _local_group():
    """The file's own (not linked) `Lacquer Coated Paint` group, or None."""
    for g in bpy.data.node_groups:
        if g.name == GROUP_NAME and g.library is None:
            return g
    return None


def ensure_node_group():
    """The file's `Lacquer Coated Paint` group, built or rebuilt in place if older than this add-on's.
    Linked (library) groups are never edited: a local group is made instead."""
    group = _local_group()
    if group is not None and group.bl_idname == "ShaderNodeTree" and group.get("lacquer_version") == NODE_GROUP_VERSION:
        return group
    if group is None or group.bl_idname != "ShaderNodeTree":
        group = bpy.data.node_groups.new(GROUP_NAME, "ShaderNodeTree")
    else:
        # Rebuild in place so that every material using it picks up the new version.
        group.nodes.clear()
        group.interface.clear()
    _new_interface(group)
    _build(group)
    group["lacquer_version"] = NODE_GROUP_VERSION
    group.use_fake_user = False
    return group


def is_stale(group) -> bool:
    """A Lacquer node group from another version of the extension."""
    return group is not None and group.get("lacquer_version") != NODE_GROUP_VERSION


def linked_message(group) -> str:
    """What the panel and the console say about a linked group that is not this version's."""
    lib = group.library.filepath if group.library is not None else "?"
    return (f"node group \"{group.name}\" is linked from {lib} (version {group.get('lacquer_version')}, "
            f"this extension makes {NODE_GROUP_VERSION}): left untouched; open that file and press "
            f"Update there, or make the group local")


def upgrade_file() -> dict:
    """Upgrades the open file's old Lacquer node groups in place (the load_post handler) and
    refits every local Lacquer material, whose group inputs a rebuild resets; linked groups are
    left untouched with a message. Returns ``{"upgraded": [...], "linked": [messages], "refit": n}``."""
    out = {"upgraded": [], "linked": [], "refit": 0, "errors": []}
    groups = [g for g in bpy.data.node_groups if g.name.startswith(GROUP_NAME) and "lacquer_version" in g]
    for g in groups:
        if not is_stale(g):
            continue
        if g.library is not None:
            out["linked"].append(linked_message(g))
            continue
        out["upgraded"].append(f"{g.name} {g.get('lacquer_version')} -> {NODE_GROUP_VERSION}")
    if out["upgraded"]:
        ensure_node_group()
        for m in bpy.data.materials:
            if m.library is None and m.lacquer.enabled:
                try:
                    update_material(m)
                    out["refit"] += 1
                except Exception as e:  # noqa: BLE001  (one bad material must not stop the others)
                    out["errors"].append(f"{m.name}: {e}")
    for line in out["linked"] + out["errors"]:
        print(f"Lacquer: {line}")
    return out


def _material_output(tree):
    for n in tree.nodes:
        if n.bl_idname == "ShaderNodeOutputMaterial" and n.is_active_output:
            return n
    out = tree.nodes.new("ShaderNodeOutputMaterial")
    out.location = (300, 0)
    return out


def group_node(mat, create=True):
    """The material's `Lacquer Paint` group node (created and linked to the output if asked)."""
    if hasattr(mat, "use_nodes") and not mat.use_nodes:
        mat.use_nodes = True
    tree = mat.node_tree
    node = tree.nodes.get(NODE_NAME)
    if node is None or node.bl_idname != "ShaderNodeGroup":
        if not create:
            return None
        node = tree.nodes.new("ShaderNodeGroup")
        node.name = NODE_NAME
        node.label = "Lacquer Coated Paint"
        node.location = (0, 0)
        node.width = 240
    current = node.node_tree
    if current is not None and current.library is not None and current.name == GROUP_NAME:
        pass  # a linked group: never replaced or edited (the panel says when it is stale)
    else:
        group = ensure_node_group()
        if current is not group:
            node.node_tree = group
    out = _material_output(tree)
    if not any(link.from_node == node for link in out.inputs["Surface"].links):
        tree.links.new(node.outputs[0], out.inputs["Surface"])
    return node


def texture_inputs(material: dict) -> dict:
    """The textured parameters' inputs for a paint: Base Color and Flake Density hold the paint's
    values (what a linked texture replaces), Fit Base Color and Fit Flake Density the values the
    fit used."""
    color = [float(v) for v in (material["base_color"] if isinstance(material["base_color"], list)
                                else [material["base_color"]] * 3)]
    density = float(material["flake_density"])
    return {"Base Color": color, "Fit Base Color": color, "Flake Density": density, "Fit Flake Density": density}


def artist_inputs(settings) -> dict:
    """The node group inputs set from the material's artist controls (not fitted)."""
    return {"Orange Peel": props.core_value(settings, "orange_peel_um"),
            "Orange Peel Wavelength": props.core_value(settings, "orange_peel_wavelength_mm"),
            "Flake Scale": float(settings.flake_scale)}


def lod_inputs(scene) -> dict:
    """The level-of-detail inputs for a scene's render: the camera's radians per pixel (0 without
    a perspective camera) and Cycles' samples per pixel."""
    angle = 0.0
    cam = scene.camera
    r = scene.render
    width = r.resolution_x * r.resolution_percentage / 100.0
    height = r.resolution_y * r.resolution_percentage / 100.0
    if cam is not None and cam.type == "CAMERA" and cam.data.type == "PERSP" and width > 0 and height > 0:
        fit = cam.data.sensor_fit
        horizontal = fit == "HORIZONTAL" or (fit == "AUTO" and width >= height)
        fov = cam.data.angle_x if horizontal else cam.data.angle_y
        angle = 2.0 * math.tan(0.5 * fov) / (width if horizontal else height)
    # Cycles' samples whatever the current engine (the cells are sampled per path in Cycles;
    # the value must not change when another engine renders the same file).
    samples = scene.cycles.samples if hasattr(scene, "cycles") else 64
    return {"Pixel Angle": float(angle), "Sparkle Samples": float(max(1, samples))}


def write_lod_inputs(scene, materials=None) -> None:
    """Writes :func:`lod_inputs` to the Lacquer nodes of ``materials`` (default: every local one)."""
    values = lod_inputs(scene)
    for mat in materials if materials is not None else bpy.data.materials:
        if mat.library is not None or not getattr(mat, "node_tree", None) or not mat.lacquer.enabled:
            continue
        values["Pixel Angle"] = lod_inputs(scene)["Pixel Angle"] if mat.lacquer.sparkle_lod else 0.0
        node = mat.node_tree.nodes.get(NODE_NAME)
        if node is None or node.bl_idname != "ShaderNodeGroup":
            continue
        for name, value in values.items():
            sock = node.inputs.get(name)
            if sock is not None and not sock.is_linked and sock.default_value != value:
                sock.default_value = value


def write_artist_inputs(mat) -> None:
    """Writes the artist controls to the material's group node (no refit: nothing is fitted)."""
    if bpy.context.scene is not None:
        write_lod_inputs(bpy.context.scene, [mat])
    node = mat.node_tree.nodes.get(NODE_NAME) if mat.node_tree else None
    if node is None or node.bl_idname != "ShaderNodeGroup":
        return
    for name, value in artist_inputs(mat.lacquer).items():
        sock = node.inputs.get(name)
        if sock is not None and not sock.is_linked:
            sock.default_value = value


class PaintRejected(ValueError):
    """A paint edit the core refused; the previous valid paint was kept."""


def update_material(mat):
    """Refits the node group's inputs from the material's paint parameters and writes them.
    A paint the core refuses raises :class:`PaintRejected` after restoring the previous valid
    paint (its parameters, node group inputs and so what LACQUER renders)."""
    material = props.material_json(mat.lacquer)
    try:
        result = fitmod.fit(material)
    except fitmod.FitUnavailable:
        raise
    except Exception as e:  # noqa: BLE001  (the core's error, shown to the artist)
        return apply_fit(mat, material, None, e)
    return apply_fit(mat, material, result, None)


def apply_fit(mat, material: dict, result, error):
    """Writes a fit ``(inputs, error, source)`` of ``material`` to the material, or, when the fit
    failed with ``error``, restores the last valid paint and raises :class:`PaintRejected`."""
    settings = mat.lacquer
    if error is not None:
        previous = settings.fit_material
        if previous:
            props.load_material_json(settings, json.loads(previous))
            kept = "kept the previous paint"
        else:
            kept = "no previous paint to keep"
        settings.fit_message = f"rejected: {error} ({kept})"
        print(f"Lacquer: material \"{mat.name}\": {settings.fit_message}")
        raise PaintRejected(settings.fit_message) from error
    inputs, fit_error, source = result
    inputs = dict(inputs)
    inputs.setdefault("Flake Size", material["flake_size_um"])
    inputs.setdefault("Sparkle", 1.0 if material.get("sparkle", True) else 0.0)
    inputs["Pearl Size"] = material["pearl_size_um"]
    inputs.update(artist_inputs(settings))
    inputs.update(texture_inputs(material))
    node = group_node(mat)
    for name in HIDDEN_INPUTS:
        if node.inputs.get(name) is not None:
            node.inputs[name].hide = True
    for name, value in inputs.items():
        sock = node.inputs.get(name)
        if sock is None:
            continue
        if isinstance(value, (list, tuple)):
            rgb = [float(v) for v in value[:3]]
            sock.default_value = (*rgb, 1.0) if len(sock.default_value) == 4 else rgb
        else:
            sock.default_value = float(value)
    settings.enabled = True
    settings.fit_inputs = json.dumps(inputs, sort_keys=True)
    settings.fit_error = json.dumps(fit_error, sort_keys=True)
    settings.fit_material = json.dumps(material, sort_keys=True)
    settings.fit_message = source
    if bpy.context.scene is not None:
        write_lod_inputs(bpy.context.scene, [mat])
    pig = inputs.get("Pigment Color", material["base_color"])
    mat.diffuse_color = (*[float(v) for v in pig[:3]], 1.0)  # solid-mode viewport colour
    return inputs, fit_error
