"""The paint's parameters on a Blender material (``material.lacquer``) and the LACQUER engine's
render settings (``scene.lacquer``).

The material's PropertyGroup is generated at registration from the core's parameter list
(``lacquer models``: name, kind, default, range, unit), so the panel, the saved .blend and the
JSON handed to the renderer use the core's names and units exactly.
"""

from __future__ import annotations

import json

import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, FloatVectorProperty, IntProperty, StringProperty

from . import catalog

_classes: list = []
_loading = False  # set while load_material_json writes many fields: no refit per field


_pending: set = set()  # materials waiting for a refit (names)


def _refit(name: str):
    from . import nodegroup

    mat = bpy.data.materials.get(name)
    if mat is None or not mat.lacquer.enabled:
        return
    try:
        nodegroup.update_material(mat)
    except Exception as e:  # a fit failure must not break the property edit
        mat.lacquer.fit_message = f"not updated: {e}"


def _refit_pending():
    while _pending:
        _refit(_pending.pop())
    return None  # one-shot timer


def _on_param_change(self, context):
    """A paint parameter changed: the preset no longer describes it; refit if asked to. In the
    UI the refit waits until the value has stopped changing for 0.25 s (dragging a slider does
    not fit at every step); in background mode (scripts, farms) it happens at once."""
    if _loading:
        return
    self.modified = True
    mat = self.id_data
    if not (self.auto_update and isinstance(mat, bpy.types.Material)):
        return
    if bpy.app.background:
        _refit(mat.name)
        return
    _pending.add(mat.name)
    if bpy.app.timers.is_registered(_refit_pending):
        bpy.app.timers.unregister(_refit_pending)
    bpy.app.timers.register(_refit_pending, first_interval=0.25)


def _prop_for(p: dict):
    name, kind, doc = p["name"], p["kind"], p.get("doc", "")
    label = catalog.LABELS.get(name, name.replace("_", " ").title())
    unit = p.get("unit") or ""
    if unit and f"({unit})" not in label:
        doc = f"{doc} [{unit}]"
    if kind == "scalar":
        lo, hi = float(p["min"]), float(p["max"])
        return FloatProperty(name=label, description=doc, default=float(p["default"]), min=lo, max=hi,
                             precision=3 if hi <= 10 else 1, update=_on_param_change)
    if kind == "color":
        lo, hi = float(p["min"]), float(p["max"])
        d = p["default"]
        d = tuple(float(x) for x in (d if isinstance(d, list) else [d, d, d]))
        return FloatVectorProperty(name=label, description=doc, default=d, size=3, min=lo, max=hi,
                                   subtype="COLOR" if hi <= 1.0 else "NONE", update=_on_param_change)
    if kind == "bool":
        return BoolProperty(name=label, description=doc, default=bool(p["default"]), update=_on_param_change)
    if isinstance(kind, dict) and "choice" in kind:
        items = [(c, c, "") for c in kind["choice"]]
        return EnumProperty(name=label, description=doc, items=items, default=str(p["default"]),
                            update=_on_param_change)
    raise RuntimeError(f"lacquer: unsupported parameter kind {kind!r} for {name}")


def _preset_items(self, context):
    # Blender keeps the strings alive only if we do: build once.
    global _PRESET_ITEMS
    if _PRESET_ITEMS is None:
        _PRESET_ITEMS = [(n, label, desc) for n, label, desc, _ in catalog.presets()]
    return _PRESET_ITEMS


_PRESET_ITEMS = None


def material_json(settings) -> dict:
    """The core's material JSON for these settings (every parameter of the model)."""
    out = {"model": catalog.MODEL}
    for p in catalog.params():
        v = getattr(settings, p["name"], None)
        if v is None:
            v = p["default"]
        elif p["kind"] == "color":
            v = [float(x) for x in v]
        elif p["kind"] == "scalar":
            v = float(v)
        elif p["kind"] == "bool":
            v = bool(v)
        out[p["name"]] = v
    return out


def load_material_json(settings, material: dict) -> None:
    """Sets the settings from material JSON (a preset's), without triggering refits per field."""
    global _loading
    _loading = True
    try:
        for p in catalog.params():
            if p["name"] in material:
                v = material[p["name"]]
                if p["kind"] == "color" and not isinstance(v, list):
                    v = [v, v, v]
                setattr(settings, p["name"], v)
    finally:
        _loading = False


def make_paint_class():
    ann = {p["name"]: _prop_for(p) for p in catalog.params()}
    ann.update(
        enabled=BoolProperty(name="Lacquer Paint", description="This material is a Lacquer paint", default=False),
        preset=StringProperty(name="Preset", description="The preset the parameters came from", default=""),
        modified=BoolProperty(name="Modified", description="Parameters changed since the preset was applied"),
        auto_update=BoolProperty(
            name="Auto Update", default=True,
            description="Refit the node group's inputs whenever a parameter changes"),
        fit_inputs=StringProperty(name="Fitted inputs", description="JSON of the node group inputs", default=""),
        fit_error=StringProperty(name="Fit error", description="JSON of the fit error", default=""),
        fit_material=StringProperty(name="Fitted material", description="material JSON the fit is for", default=""),
        fit_message=StringProperty(name="Fit message", default=""),
    )
    cls = type("LacquerPaintSettings", (bpy.types.PropertyGroup,), {"__annotations__": ann})
    return cls


class LacquerRenderSettings(bpy.types.PropertyGroup):
    """Settings of the LACQUER render engine (Render Properties)."""

    samples: IntProperty(name="Samples", description="Samples per pixel", default=64, min=1, max=1 << 16)
    preview_samples: IntProperty(name="Preview Samples", description="Samples per pixel for material previews",
                                 default=8, min=1, max=4096)
    max_depth: IntProperty(name="Max Bounces", description="Scattering events per path (1 = direct light only)",
                           default=8, min=1, max=64)
    seed: IntProperty(name="Seed", default=0, min=0)
    clamp: FloatProperty(name="Clamp", description="Path contribution clamp (0 = off)", default=0.0, min=0.0)
    sparkle: BoolProperty(name="Sparkle", description="Resolve individual flakes in each pixel's footprint",
                          default=True)


def register():
    paint = make_paint_class()
    for cls in (paint, LacquerRenderSettings):
        bpy.utils.register_class(cls)
        _classes.append(cls)
    bpy.types.Material.lacquer = bpy.props.PointerProperty(type=paint)
    bpy.types.Scene.lacquer = bpy.props.PointerProperty(type=LacquerRenderSettings)


def unregister():
    if bpy.app.timers.is_registered(_refit_pending):
        bpy.app.timers.unregister(_refit_pending)
    _pending.clear()
    for attr, owner in (("lacquer", bpy.types.Material), ("lacquer", bpy.types.Scene)):
        if hasattr(owner, attr):
            delattr(owner, attr)
    while _classes:
        bpy.utils.unregister_class(_classes.pop())


def material_json_text(settings) -> str:
    return json.dumps(material_json(settings), sort_keys=True)
