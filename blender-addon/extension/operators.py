"""Operators (``bpy.ops.lacquer.*``): assign or update a Lacquer paint, apply a preset, refit."""

from __future__ import annotations

import bpy
from bpy.props import BoolProperty, EnumProperty, StringProperty

from . import assets, catalog, nodegroup, props


def _preset_items(self, context):
    return props._preset_items(self, context)


def apply_preset(mat, name: str):
    """Makes `mat` a Lacquer paint with the preset's parameters and the fitted node group (in
    the UI the fit runs on the worker thread and is applied when done; returns None then)."""
    settings = mat.lacquer
    props.load_material_json(settings, catalog.preset(name))
    settings.preset = name
    settings.modified = False
    settings.enabled = True
    if props.refits_async():
        # In the UI: the node group now, its fitted inputs when the worker thread has them.
        nodegroup.group_node(mat)
        props._start_refit(mat)
        return None
    return nodegroup.update_material(mat)


def _can_have_material(ob) -> bool:
    return ob is not None and ob.type in {"MESH", "CURVE", "SURFACE", "META", "FONT", "CURVES", "VOLUME",
                                          "POINTCLOUD"} and ob.data is not None


class LACQUER_OT_assign_paint(bpy.types.Operator):
    """Assign a Lacquer paint (from a preset) to the selected objects, or update their Lacquer paint"""

    bl_idname = "lacquer.assign_paint"
    bl_label = "Assign Lacquer Paint"
    bl_options = {"REGISTER", "UNDO"}

    preset: EnumProperty(name="Preset", items=_preset_items)
    new_material: BoolProperty(
        name="New Material", default=False,
        description="Always create a new material (otherwise an object's active Lacquer paint is updated)")

    @classmethod
    def poll(cls, context):
        return any(_can_have_material(ob) for ob in context.selected_objects or [context.object])

    def execute(self, context):
        objects = [ob for ob in (context.selected_objects or [context.object]) if _can_have_material(ob)]
        created = None
        label = catalog.preset_label(self.preset)
        updated = 0
        for ob in objects:
            mat = ob.active_material
            if mat is not None and mat.lacquer.enabled and not self.new_material:
                apply_preset(mat, self.preset)
                updated += 1
                continue
            if created is None:
                created = bpy.data.materials.new(f"Lacquer {label}")
                apply_preset(created, self.preset)
            if len(ob.material_slots) == 0:
                ob.data.materials.append(created)
            else:
                ob.material_slots[ob.active_material_index].material = created
        self.report({"INFO"}, f"Lacquer: {label} on {len(objects)} object(s)"
                    + (f", {updated} updated" if updated else ""))
        return {"FINISHED"}


class LACQUER_OT_apply_preset(bpy.types.Operator):
    """Set the active material's paint parameters from a preset and refit the node group"""

    bl_idname = "lacquer.apply_preset"
    bl_label = "Apply Lacquer Preset"
    bl_options = {"REGISTER", "UNDO"}

    preset: EnumProperty(name="Preset", items=_preset_items)
    material: StringProperty(name="Material", description="Material name (default: the active one)")

    def execute(self, context):
        mat = bpy.data.materials.get(self.material) if self.material else getattr(context, "material", None)
        if mat is None:
            ob = context.object
            if not _can_have_material(ob):
                self.report({"ERROR"}, "Lacquer: no material or object to apply the preset to")
                return {"CANCELLED"}
            bpy.ops.lacquer.assign_paint(preset=self.preset)
            return {"FINISHED"}
        apply_preset(mat, self.preset)
        self.report({"INFO"}, f"Lacquer: {catalog.preset_label(self.preset)} on \"{mat.name}\"")
        return {"FINISHED"}


class LACQUER_OT_update_paint(bpy.types.Operator):
    """Refit the node group's inputs from the paint parameters (and rebuild the node group if it is
    from an older version of the extension)"""

    bl_idname = "lacquer.update_paint"
    bl_label = "Update Lacquer Paint"
    bl_options = {"REGISTER", "UNDO"}

    material: StringProperty(name="Material", description="Material name (default: the active one)")
    all_materials: BoolProperty(name="All Materials", description="Every Lacquer paint in the file")

    def execute(self, context):
        if self.all_materials:
            mats = [m for m in bpy.data.materials if m.lacquer.enabled]
        else:
            m = bpy.data.materials.get(self.material) if self.material else getattr(context, "material", None)
            mats = [m] if m is not None else []
        if not mats:
            self.report({"ERROR"}, "Lacquer: no Lacquer material to update")
            return {"CANCELLED"}
        failed = []
        for m in mats:
            try:
                nodegroup.update_material(m)
            except nodegroup.PaintRejected as e:
                failed.append(f"\"{m.name}\": {e}")
        if failed:
            self.report({"ERROR"}, "Lacquer: " + "; ".join(failed))
        self.report({"INFO"}, f"Lacquer: {len(mats) - len(failed)} material(s) updated")
        return {"FINISHED"}


class LACQUER_OT_set_paint_json(bpy.types.Operator):
    """Set the paint from material JSON (from `lacquer presets`, a colleague or a script); invalid
    JSON or a paint the core refuses is reported and the current paint kept"""

    bl_idname = "lacquer.set_paint_json"
    bl_label = "Set Lacquer Paint from JSON"
    bl_options = {"REGISTER", "UNDO"}

    json: StringProperty(name="JSON", description="coated_paint material JSON (only the parameters to change)")
    material: StringProperty(name="Material", description="Material name (default: the active one)")

    def execute(self, context):
        import json

        import lacquer

        mat = bpy.data.materials.get(self.material) if self.material else getattr(context, "material", None)
        if mat is None:
            self.report({"ERROR"}, "Lacquer: no material")
            return {"CANCELLED"}
        settings = mat.lacquer
        try:
            data = json.loads(self.json)
        except ValueError as e:
            self.report({"ERROR"}, f"Lacquer: invalid JSON ({e}); \"{mat.name}\" kept its paint")
            return {"CANCELLED"}
        if not isinstance(data, dict) or data.get("model", catalog.MODEL) != catalog.MODEL:
            self.report({"ERROR"}, f"Lacquer: not a {catalog.MODEL} material; \"{mat.name}\" kept its paint")
            return {"CANCELLED"}
        current = props.material_json(settings)
        candidate = dict(current, **data)
        try:
            lacquer.Material(candidate)  # the core's validation: names, ranges, combinations
        except lacquer.LacquerError as e:
            self.report({"ERROR"}, f"Lacquer: {e}; \"{mat.name}\" kept its paint")
            return {"CANCELLED"}
        props.load_material_json(settings, candidate)
        settings.modified = True
        try:
            nodegroup.update_material(mat)
        except nodegroup.PaintRejected as e:
            self.report({"ERROR"}, f"Lacquer: {e}")
            return {"CANCELLED"}
        self.report({"INFO"}, f"Lacquer: paint of \"{mat.name}\" set from JSON")
        return {"FINISHED"}


class LACQUER_MT_presets(bpy.types.Menu):
    bl_idname = "LACQUER_MT_presets"
    bl_label = "Lacquer Presets"

    def draw(self, context):
        layout = self.layout
        op = "lacquer.apply_preset" if getattr(context, "material", None) is not None else "lacquer.assign_paint"
        thesis = [p for p in catalog.presets() if catalog.is_thesis(p[0])]
        other = [p for p in catalog.presets() if not catalog.is_thesis(p[0])]
        layout.label(text="Thesis series (flake density, flake size)")
        for name, label, _, _ in thesis:
            layout.operator(op, text=label, icon_value=assets.icon(name)).preset = name
        for title in catalog.ASSET_CATALOGS[1:]:
            group = [p for p in other if catalog.asset_catalog(p[0]) == title]
            if group:
                layout.separator()
                layout.label(text=title.split("/")[-1])
            for name, label, _, _ in group:
                layout.operator(op, text=label, icon_value=assets.icon(name)).preset = name


def _menu_assign(self, context):
    self.layout.operator_menu_enum("lacquer.assign_paint", "preset", text="Assign Lacquer Paint")


classes = (LACQUER_OT_assign_paint, LACQUER_OT_apply_preset, LACQUER_OT_update_paint, LACQUER_OT_set_paint_json,
           LACQUER_MT_presets)


def register():
    for cls in classes:
        bpy.utils.register_class(cls)
    bpy.types.VIEW3D_MT_object.append(_menu_assign)


def unregister():
    bpy.types.VIEW3D_MT_object.remove(_menu_assign)
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
