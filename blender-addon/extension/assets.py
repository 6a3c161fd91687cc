"""The bundled asset library (``assets/lacquer_paints.blend``: one Lacquer material per core
preset, catalogued, thumbnails rendered by the core; built by blender-addon/scripts/build_assets.py)
and the preset previews the menus show (``bpy.utils.previews``).

Registering adds the folder as the asset library "Lacquer Paints" to the preferences (removed
again on unregistering), so its materials appear in the Asset Browser and can be dragged onto
objects: an appended material carries its node group and its paint parameters.
"""

from __future__ import annotations

import os

import bpy

LIBRARY_NAME = "Lacquer Paints"
BLEND = "lacquer_paints.blend"

_previews = None
_added_library = False


def library_dir() -> str:
    """The extension's asset folder."""
    return os.path.join(os.path.dirname(os.path.abspath(__file__)), "assets")


def library_blend() -> str | None:
    """The bundled library file, or None when this build has none."""
    path = os.path.join(library_dir(), BLEND)
    return path if os.path.isfile(path) else None


def _libraries():
    return bpy.context.preferences.filepaths.asset_libraries


def find_library():
    """The preferences' entry for the bundled library, or None."""
    d = os.path.normpath(library_dir())
    for lib in _libraries():
        if os.path.normpath(bpy.path.abspath(lib.path)) == d:
            return lib
    return None


def preview(preset: str):
    """The preset's thumbnail (an ImagePreview of ``bpy.utils.previews``), or None."""
    return _previews.get(preset) if _previews is not None else None


def icon(preset: str) -> int:
    """The preview icon id of a preset's thumbnail (0 when there is none)."""
    if _previews is None:
        return 0
    item = _previews.get(preset)
    return item.icon_id if item is not None else 0


def append_material(preset: str):
    """Appends the library's material for ``preset`` (as dragging the asset does) and returns it."""
    from . import catalog, nodegroup

    path = library_blend()
    if path is None:
        raise RuntimeError("this build of the extension has no asset library")
    label = catalog.preset_label(preset)
    with bpy.data.libraries.load(path, link=False, assets_only=True) as (src, dst):
        if label not in src.materials:
            raise KeyError(f"no asset \"{label}\" in {path}")
        dst.materials = [label]
    mat = dst.materials[0]
    node = mat.node_tree.nodes.get(nodegroup.NODE_NAME)
    appended = node.node_tree if node is not None else None
    nodegroup.group_node(mat)  # the file's own node group (a duplicate appended one is replaced)
    if appended is not None and appended is not node.node_tree and appended.users == 0:
        bpy.data.node_groups.remove(appended)
    return mat


def register():
    global _previews, _added_library
    import bpy.utils.previews

    _previews = bpy.utils.previews.new()
    thumbs = os.path.join(library_dir(), "thumbs")
    if os.path.isdir(thumbs):
        for f in sorted(os.listdir(thumbs)):
            if f.endswith(".png"):
                _previews.load(f[:-4], os.path.join(thumbs, f), "IMAGE")
    if library_blend() is not None and find_library() is None:
        try:
            libs = _libraries()
            if hasattr(libs, "new"):
                lib = libs.new(name=LIBRARY_NAME, directory=library_dir())
            else:
                bpy.ops.preferences.asset_library_add(directory=library_dir())
                lib = find_library()
                if lib is not None:
                    lib.name = LIBRARY_NAME
            if lib is not None:
                lib.import_method = "APPEND_REUSE"
            _added_library = lib is not None
        except (RuntimeError, AttributeError, TypeError) as e:  # no preferences (rare): previews still work
            print(f"Lacquer: could not add the asset library: {e}")


def unregister():
    global _previews, _added_library
    if _previews is not None:
        bpy.utils.previews.remove(_previews)
        _previews = None
    if _added_library:
        lib = find_library()
        if lib is not None:
            try:
                libs = _libraries()
                if hasattr(libs, "remove"):
                    libs.remove(lib)
                else:
                    bpy.ops.preferences.asset_library_remove(index=list(libs).index(lib))
            except (RuntimeError, ValueError, TypeError) as e:
                print(f"Lacquer: could not remove the asset library: {e}")
        _added_library = False
