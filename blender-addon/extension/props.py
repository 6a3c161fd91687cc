"""The paint's parameters on a Blender material (``material.lacquer``) and the LACQUER engine's
render settings (``scene.lacquer``).

The material's PropertyGroup is generated at registration from the core's parameter list
(``lacquer models``: name, kind, default, range, unit), so the panel, the saved .blend and the
JSON handed to the renderer use the core's names and units exactly — but for angles (Blender's
ANGLE subtype, radians) and lengths: a parameter in µm, nm or mm (``flake_size_um``, …) is a
Blender length (``flake_size``: subtype DISTANCE, unit LENGTH, shown in the scene's unit
system) under the name without the unit suffix, its metres kept in ``flake_size_m`` and
converted back to the core's unit exactly (see :func:`core_value`). Files saved before
(properties ``flake_size_um`` … in the core's units) are migrated when they load
(:func:`migrate_lengths`).
"""

from __future__ import annotations

import json
import math
import time

import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, FloatVectorProperty, IntProperty, StringProperty

from . import catalog

_classes: list = []
_loading = False  # set while load_material_json writes many fields: no refit per field


_pending: set = set()  # materials waiting for a refit (names)

#: Refits run on a worker thread ("lacquer-refit") and are applied by a timer on the main thread
#: (with an undo step) when True; at once on the calling thread when False. None: asynchronous
#: in the UI, synchronous in background mode (scripts, farms), where nothing could freeze.
ASYNC_REFITS = None
_jobs: dict = {}  # material name -> the refit running for it
#: The last applied refits (name → {"thread", "seconds", "undo_pushed"}); read by the tests.
LAST_REFITS: dict = {}


def refits_async() -> bool:
    """Whether refits run off the main thread (see ``ASYNC_REFITS``)."""
    return (not bpy.app.background) if ASYNC_REFITS is None else bool(ASYNC_REFITS)


def _refit(name: str):
    from . import nodegroup

    mat = bpy.data.materials.get(name)
    if mat is None or not mat.lacquer.enabled:
        return
    if refits_async():
        _start_refit(mat)
        return
    try:
        nodegroup.update_material(mat)
    except Exception as e:  # a fit failure must not break the property edit (the paint is kept)
        if not mat.lacquer.fit_message.startswith("rejected:"):
            mat.lacquer.fit_message = f"not updated: {e}"


def _start_refit(mat):
    """Fits the material's current paint on a worker thread; ``apply_finished_refits`` (a timer)
    writes the result. An older refit of the same material still running is superseded."""
    import threading

    from . import fit as fitmod

    material = material_json(mat.lacquer)
    job = {"material": material, "done": False, "result": None, "error": None, "thread": None,
           "t0": time.perf_counter()}

    def work():
        job["thread"] = threading.current_thread().name
        try:
            job["result"] = fitmod.fit(material)
        except Exception as e:  # noqa: BLE001  (applied as a rejected edit on the main thread)
            job["error"] = e
        job["seconds"] = time.perf_counter() - job["t0"]
        job["done"] = True

    _jobs[mat.name] = job
    mat.lacquer.fit_message = "refitting…"
    threading.Thread(target=work, name="lacquer-refit", daemon=True).start()
    if not bpy.app.timers.is_registered(apply_finished_refits):
        bpy.app.timers.register(apply_finished_refits, first_interval=0.05)


def apply_finished_refits():
    """Timer (main thread): applies finished refits, with an undo step, and refits again the
    materials edited while their fit ran. Returns the next interval (None when idle)."""
    from . import nodegroup

    for name, job in list(_jobs.items()):
        if not job["done"]:
            continue
        del _jobs[name]
        mat = bpy.data.materials.get(name)
        if mat is None or not mat.lacquer.enabled:
            continue
        if material_json(mat.lacquer) != job["material"]:
            _start_refit(mat)  # edited while fitting: this fit is out of date
            continue
        try:
            nodegroup.apply_fit(mat, job["material"], job["result"], job["error"])
        except nodegroup.PaintRejected:
            pass  # the message is on the material; the previous paint is back
        undo = False
        try:
            undo = bpy.ops.ed.undo_push(message=f"Lacquer refit \"{name}\"") == {"FINISHED"}
        except RuntimeError:  # no undo system (background mode without a window)
            undo = False
        LAST_REFITS[name] = {"thread": job["thread"], "seconds": job.get("seconds"), "undo_pushed": undo,
                             "rejected": job["error"] is not None}
    return 0.05 if _jobs else None


def wait_for_refits(timeout: float = 60.0) -> bool:
    """Runs ``apply_finished_refits`` until no refit is running (scripts and tests, where no
    event loop runs Blender's timers). True when all finished within ``timeout`` seconds."""
    end = time.perf_counter() + timeout
    while _jobs and time.perf_counter() < end:
        apply_finished_refits()
        time.sleep(0.01)
    return not _jobs


def _refit_pending():
    while _pending:
        _refit(_pending.pop())
    return None  # one-shot timer


def _on_param_change(self, context):
    """A paint parameter changed: the preset no longer describes it; refit if asked to. In the
    UI the refit waits until the value has stopped changing for 0.25 s (dragging a slider does
    not fit at every step) and then runs on a worker thread; in background mode (scripts,
    farms) it happens at once."""
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


@bpy.app.handlers.persistent
def on_frame_change(scene, depsgraph=None):
    """frame_change_post: Lacquer materials whose paint parameters are animated (keyframes or
    drivers on ``material.lacquer.*``) get the node group refitted for the new frame (at once
    when rendering or in background mode, so every frame of an animation render is right; on
    the worker thread during interactive playback)."""
    from . import nodegroup

    for mat in bpy.data.materials:
        if mat.library is not None or not mat.lacquer.enabled or mat.animation_data is None:
            continue
        if json.dumps(material_json(mat.lacquer), sort_keys=True) == mat.lacquer.fit_material:
            continue
        if refits_async() and not _rendering():
            if mat.name not in _jobs:
                _start_refit(mat)
            continue
        try:
            nodegroup.update_material(mat)
        except Exception as e:  # noqa: BLE001
            print(f"Lacquer: frame {scene.frame_current}: material \"{mat.name}\": {e}")


def _rendering() -> bool:
    return bool(getattr(bpy.app, "is_job_running", None) and bpy.app.is_job_running("RENDER"))


@bpy.app.handlers.persistent
def on_render_pre(scene, *_args):
    """render_pre: the node groups' level-of-detail inputs (camera pixel angle, samples) for
    this render's camera and resolution."""
    from . import nodegroup

    try:
        nodegroup.write_lod_inputs(scene)
    except Exception as e:  # noqa: BLE001  (a handler must not stop the render)
        print(f"Lacquer: level of detail not updated: {e}")


#: What the last load_post upgrade did (the panel and the tests read it).
LAST_UPGRADE: dict = {}


@bpy.app.handlers.persistent
def on_load_post(*_args):
    """load_post: upgrades the opened file's old Lacquer node groups (linked ones are left
    untouched, with a message)."""
    from . import nodegroup

    LAST_UPGRADE.clear()
    try:
        LAST_UPGRADE["lengths_migrated"] = migrate_file()
        LAST_UPGRADE.update(nodegroup.upgrade_file())
    except Exception as e:  # noqa: BLE001  (a handler must not break loading the file)
        LAST_UPGRADE["errors"] = [str(e)]
        print(f"Lacquer: upgrading the node groups failed: {e}")


def _on_artist_change(self, context):
    """An artist control changed: written to the node group at once (nothing to fit)."""
    from . import nodegroup

    mat = self.id_data
    if isinstance(mat, bpy.types.Material) and self.enabled:
        nodegroup.write_artist_inputs(mat)


#: Metres per core unit, by the suffix of a length's name.
LENGTH_SUFFIXES = {"_um": 1e-6, "_nm": 1e-9, "_mm": 1e-3}

#: The artist controls that are lengths: old property name (the core's unit) → metres per unit.
ARTIST_LENGTHS = {"orange_peel_um": 1e-6, "orange_peel_wavelength_mm": 1e-3}


def length_scale(name: str):
    """Metres per unit of a parameter (or artist control) named with a length suffix, else None."""
    for suffix, scale in LENGTH_SUFFIXES.items():
        if name.endswith(suffix):
            return scale
    return None


def prop_name(name: str) -> str:
    """The ``material.lacquer`` property of a core parameter or artist control: the name
    without its unit suffix for lengths (stored in metres), the name itself otherwise."""
    return name[:-3] if length_scale(name) is not None else name


def store_key(name: str) -> str:
    """The ID property holding a length's metres (``flake_size_um`` → ``flake_size_m``)."""
    return prop_name(name) + "_m"


def scene_unit_scale() -> float:
    """Metres per Blender unit of the current scene (its Unit Scale; 1 without units or a scene)."""
    try:
        units = bpy.context.scene.unit_settings
        return float(units.scale_length) if units.system != "NONE" and units.scale_length > 0 else 1.0
    except (AttributeError, TypeError):
        return 1.0


def to_core_units(metres: float, scale: float) -> float:
    """Metres in the core's unit (``scale`` metres per unit), rounded to the shortest decimal
    within float32 precision (2⁻²³ relative: a value typed in the panel passes through float32),
    so that 20 µm typed or loaded comes back as 20.0 exactly."""
    v = float(metres) / scale
    for digits in range(1, 18):
        d = float(f"{v:.{digits}g}")
        if abs(d - v) <= abs(v) * 2.0 ** -23:
            return d
    return v


def core_value(settings, name: str):
    """A length parameter or artist control of ``settings`` in the core's unit (µm, nm, mm),
    from the metres it stores, or from the unmigrated property of an older file."""
    old = settings.get(name)  # the ID property an older extension saved, if not migrated yet
    if old is not None:
        return float(old)  # (a linked material, or a file opened before the extension was enabled)
    metres = settings.get(store_key(name))
    if metres is None:
        return float(_LENGTH_DEFAULTS[name])
    return to_core_units(metres, length_scale(name))


#: Core unit defaults of the lengths (filled by :func:`_length_property`).
_LENGTH_DEFAULTS: dict = {}


def _length_property(name: str, label: str, doc: str, default: float, lo: float, hi: float, update):
    """A length (``name`` in the core's unit: µm, nm or mm) as a Blender length property.

    Blender shows a LENGTH property's value × the scene's Unit Scale (it holds scene units), so
    the property reads and writes scene units through ``get``/``set``: the metres are kept in
    the ID property :func:`store_key` (a double), the panel shows metres in the scene's unit
    system whatever its Unit Scale, and the core's value does not depend on the scene. Out of
    range values are clamped to the core's range on writing."""
    scale = length_scale(name)
    key = store_key(name)
    _LENGTH_DEFAULTS[name] = default

    def get(self):
        return self.get(key, default * scale) / scene_unit_scale()

    def set_(self, value):
        self[key] = min(max(float(value) * scene_unit_scale(), lo * scale), hi * scale)

    return FloatProperty(name=label, description=doc, default=default * scale, subtype="DISTANCE", unit="LENGTH",
                         precision=3, get=get, set=set_, update=update)


def migrate_lengths(settings) -> list:
    """Moves lengths saved by extensions before the metric properties (``flake_size_um`` = 20
    in µm …) to the metric ones (``flake_size``, metres in ``flake_size_m``) and drops the old
    keys; returns the names moved. Idempotent (the old keys are gone after the first call)."""
    moved = []
    names = [p["name"] for p in catalog.params() if length_scale(p["name"]) is not None] + list(ARTIST_LENGTHS)
    for name in names:
        if name in settings.keys():
            value = float(settings[name])
            del settings[name]
            settings[store_key(name)] = value * length_scale(name)
            moved.append(name)
    return moved


def migrate_file() -> dict:
    """:func:`migrate_lengths` on every local Lacquer material of the open file (load_post)."""
    out = {}
    for mat in bpy.data.materials:
        if mat.library is None and hasattr(mat, "lacquer"):
            moved = migrate_lengths(mat.lacquer)
            if moved:
                out[mat.name] = moved
    return out


def is_angle(p: dict) -> bool:
    """A paint parameter in degrees (shown with Blender's angle unit, stored in radians)."""
    return p["kind"] == "scalar" and (p["name"].endswith("_deg") or p.get("unit") in ("°", "deg"))


def _prop_for(p: dict):
    name, kind, doc = p["name"], p["kind"], p.get("doc", "")
    label = catalog.LABELS.get(name, name.replace("_", " ").title())
    unit = p.get("unit") or ""
    if unit and f"({unit})" not in label:
        doc = f"{doc} [{unit}]"
    if kind == "scalar" and is_angle(p):
        # Degrees in the core; Blender's ANGLE subtype stores radians and shows them in the
        # scene's rotation unit (degrees by default). material_json converts back.
        label = label.replace(" (°)", "")
        return FloatProperty(name=label, description=doc, default=math.radians(float(p["default"])),
                             min=math.radians(float(p["min"])), max=math.radians(float(p["max"])),
                             subtype="ANGLE", unit="ROTATION", precision=1, update=_on_param_change)
    scale = length_scale(name) if kind == "scalar" else None
    if scale is not None:
        # A length: metres, shown in the scene's unit system (µm, nm, thou …); material_json
        # converts back to the core's unit.
        for u in ("µm", "nm", "mm", unit):
            label = label.replace(f" ({u})", "") if u else label
        return _length_property(name, label, doc, float(p["default"]), float(p["min"]), float(p["max"]),
                                _on_param_change)
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
        if length_scale(p["name"]) is not None and p["kind"] == "scalar":
            out[p["name"]] = core_value(settings, p["name"])
            continue
        v = getattr(settings, p["name"], None)
        if v is None:
            v = p["default"]
        elif p["kind"] == "color":
            v = [float(x) for x in v]
        elif is_angle(p):
            v = round(math.degrees(float(v)), 4)  # float32 storage: 20° reads 19.9999995
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
                elif is_angle(p):
                    v = math.radians(float(v))
                elif length_scale(p["name"]) is not None and p["kind"] == "scalar":
                    settings[store_key(p["name"])] = float(v) * length_scale(p["name"])
                    if p["name"] in settings.keys():
                        del settings[p["name"]]  # an unmigrated old value would win
                    continue
                setattr(settings, p["name"], v)
    finally:
        _loading = False


def make_paint_class():
    ann = {prop_name(p["name"]): _prop_for(p) for p in catalog.params()}
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
        # Artist controls: not paint parameters of the core; the node group and LACQUER's export
        # read them (orange peel: rust-core/render/src/perturb.rs; flake scale: the sparkle's
        # surface scale).
        # Lengths (the scene's unit system shows them); core_value gives µm / mm.
        orange_peel=_length_property(
            "orange_peel_um", "Orange Peel", "RMS height of the clearcoat's waviness (0 = a perfectly flat coat)",
            0.0, 0.0, 1000.0, _on_artist_change),
        orange_peel_wavelength=_length_property(
            "orange_peel_wavelength_mm", "Peel Wavelength", "Wavelength of the orange peel", 3.0, 0.01, 1000.0,
            _on_artist_change),
        sparkle_lod=BoolProperty(
            name="Sparkle Level of Detail", default=True, update=_on_artist_change,
            description="In Cycles, fade flake cells into the mean lobe where a pixel covers more cells than "
                        "it has samples (as LACQUER's footprint sparkle converges); off: cells at any distance"),
        flake_scale=FloatProperty(
            name="Flake Scale", default=1.0, min=0.01, max=100.0, soft_max=10.0, precision=2,
            description="Multiplier on the size of flakes and pearls (1 = the paint's physical size; an "
                        "artistic exaggeration, in both Cycles and LACQUER)", update=_on_artist_change),
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
    bpy.app.handlers.frame_change_post.append(on_frame_change)
    bpy.app.handlers.load_post.append(on_load_post)
    bpy.app.handlers.render_pre.append(on_render_pre)


def unregister():
    for handlers, fn in ((bpy.app.handlers.frame_change_post, on_frame_change),
                         (bpy.app.handlers.load_post, on_load_post),
                       (bpy.app.handlers.render_pre, on_render_pre)):
        while fn in handlers:
            handlers.remove(fn)
    for timer in (_refit_pending, apply_finished_refits):
        if bpy.app.timers.is_registered(timer):
            bpy.app.timers.unregister(timer)
    _pending.clear()
    _jobs.clear()
    for attr, owner in (("lacquer", bpy.types.Material), ("lacquer", bpy.types.Scene)):
        if hasattr(owner, attr):
            delattr(owner, attr)
    while _classes:
        bpy.utils.unregister_class(_classes.pop())


def material_json_text(settings) -> str:
    return json.dumps(material_json(settings), sort_keys=True)
