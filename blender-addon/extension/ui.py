"""Panels: the paint in Material Properties, the LACQUER engine's settings in Render Properties."""

from __future__ import annotations

import json

import bpy

from . import catalog, fit, nodegroup, props


class MATERIAL_PT_lacquer(bpy.types.Panel):
    bl_label = "Lacquer Paint"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "material"

    @classmethod
    def poll(cls, context):
        return context.object is not None

    def draw(self, context):
        layout = self.layout
        mat = context.material
        if mat is None or not mat.lacquer.enabled:
            layout.menu("LACQUER_MT_presets", text="Make Lacquer Paint", icon="MATERIAL")
            return
        s = mat.lacquer
        row = layout.row(align=True)
        label = catalog.preset_label(s.preset) if s.preset else "Custom"
        row.menu("LACQUER_MT_presets", text=label + (" (modified)" if s.modified else ""), icon="PRESET")
        row.operator("lacquer.update_paint", text="", icon="FILE_REFRESH").material = mat.name
        layout.prop(s, "auto_update")
        shown = set()
        for title, names in catalog.SECTIONS:
            box = layout.box()
            box.label(text=title)
            col = box.column(align=True)
            for name in names:
                if hasattr(s, props.prop_name(name)):
                    col.prop(s, props.prop_name(name))
                    shown.add(name)
        rest = [p["name"] for p in catalog.params() if p["name"] not in shown and p["name"] not in catalog.HIDDEN]
        if rest:
            box = layout.box()
            box.label(text="Other")
            for name in rest:
                box.prop(s, props.prop_name(name))
        box = layout.box()
        box.label(text="Surface (both engines)")
        col = box.column(align=True)
        for name in catalog.ARTIST:
            col.prop(s, props.prop_name(name))
        box.label(text="Normal maps, bump: connect them to the node's Normal / Coat Normal", icon="INFO")
        box = layout.box()
        box.label(text="Node group fit (Cycles / EEVEE)")
        if s.fit_error:
            err = json.loads(s.fit_error)
            col = box.column(align=True)
            for line in catalog.fit_quality_lines(err):
                col.label(text=line)
        elif s.fit_message:
            box.label(text=s.fit_message, icon="INFO")
        if not fit.available():
            box.label(text="This lacquer library has no node-group fit: reinstall the extension", icon="ERROR")
        if s.fit_message.startswith("rejected:"):
            box.label(text=s.fit_message, icon="ERROR")
        node = mat.node_tree.nodes.get(nodegroup.NODE_NAME) if mat.node_tree else None
        group = node.node_tree if node is not None and node.bl_idname == "ShaderNodeGroup" else None
        if group is not None and nodegroup.is_stale(group):
            if group.library is not None:
                box.label(text=f"Linked from {group.library.filepath}: left untouched (update it there)",
                          icon="LIBRARY_DATA_DIRECT")
            else:
                box.label(text="The node group is from another version: press Update", icon="ERROR")


class RENDER_PT_lacquer(bpy.types.Panel):
    bl_label = "Lacquer"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "render"
    COMPAT_ENGINES = {"LACQUER"}

    @classmethod
    def poll(cls, context):
        return context.engine in cls.COMPAT_ENGINES

    def draw(self, context):
        s = context.scene.lacquer
        layout = self.layout
        layout.use_property_split = True
        col = layout.column(align=True)
        col.prop(s, "samples")
        col.prop(s, "preview_samples")
        col = layout.column(align=True)
        col.prop(s, "max_depth")
        col.prop(s, "seed")
        col.prop(s, "clamp")
        layout.prop(s, "sparkle")
        layout.label(text="Threads: Performance › Threads; transparency: Film › Transparent")


classes = (MATERIAL_PT_lacquer, RENDER_PT_lacquer)


def register():
    for cls in classes:
        bpy.utils.register_class(cls)


def unregister():
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
