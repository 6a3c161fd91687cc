"""The `LACQUER` render engine: the scene rendered by lacquer's reference path tracer through the
C ABI (``lacquer.render``), with Blender's progress, cancel and stats."""

from __future__ import annotations

import os
import time

import bpy
import numpy as np

import lacquer

from . import export


class LacquerRenderEngine(bpy.types.RenderEngine):
    bl_idname = "LACQUER"
    bl_label = "Lacquer"
    bl_use_preview = True
    bl_use_postprocess = True
    # Materials keep their Cycles/EEVEE node trees (the node group is the everyday path).
    bl_use_shading_nodes_custom = False
    bl_use_eevee_viewport = True

    def render(self, depsgraph):
        scene = depsgraph.scene
        report = export.Report()
        temp_files: list = []
        t0 = time.perf_counter()
        try:
            self.update_stats("", "Lacquer: exporting the scene")
            job = export.job(depsgraph, report, temp_files, preview=self.is_preview)
            job["transparent"] = bool(scene.render.film_transparent)
            for line in report.lines():
                print(f"Lacquer: {line}")
                if not self.is_preview:
                    self.report({"WARNING"}, line)
            width, height = job["width"], job["height"]
            t_export = time.perf_counter() - t0
            spp = job["spp"]
            start = time.perf_counter()

            def progress(fraction):
                self.update_progress(fraction)
                done = int(round(fraction * spp))
                elapsed = time.perf_counter() - start
                self.update_stats("", f"Lacquer: path tracing {width}×{height}, {done}/{spp} spp, {elapsed:.1f} s")
                return not self.test_break()

            try:
                out = lacquer.render(job, progress)
            except lacquer.CancelledError:
                self.update_stats("", "Lacquer: cancelled")
                return
            rgba = out["rgba"][::-1]  # the renderer writes rows top first, Blender bottom first
            if not scene.render.film_transparent:
                rgba = rgba.copy()
                rgba[..., 3] = 1.0
            # A native-endian float buffer: foreach_set refuses the ctypes array's explicit "<f".
            pixels = np.empty(width * height * 4, np.float32)
            pixels[:] = rgba.reshape(-1)
            result = self.begin_result(0, 0, width, height)
            result.layers[0].passes["Combined"].rect.foreach_set(pixels)
            self.end_result(result)
            seconds = time.perf_counter() - start
            paths = width * height * spp
            msg = (f"Lacquer: {width}×{height}, {spp} spp in {seconds:.2f} s "
                   f"({paths / max(seconds, 1e-9) / 1e6:.2f} M paths/s; export {t_export:.2f} s)")
            self.update_stats("", msg)
            if not self.is_preview:
                print(msg)
        except Exception as e:  # noqa: BLE001  (shown to the user, never a crash of Blender)
            self.report({"ERROR"}, f"Lacquer: {e}")
            print(f"Lacquer: render failed: {e}")
        finally:
            for f in temp_files:
                try:
                    os.remove(f)
                except OSError:
                    pass


#: EEVEE panels whose settings LACQUER reads too: material slots and surface (the node tree),
#: the world's surface, the light's settings, the material preview.
_EEVEE_PANELS = {
    "EEVEE_MATERIAL_PT_context_material", "EEVEE_MATERIAL_PT_surface", "MATERIAL_PT_preview",
    "EEVEE_WORLD_PT_surface",
}


def _compatible_panels():
    """Blender's own panels that work with any engine (as the custom engine template does), and
    the few EEVEE ones that show what LACQUER renders."""
    exclude = {"VIEWLAYER_PT_filter", "VIEWLAYER_PT_layer_passes"}
    for panel in bpy.types.Panel.__subclasses__():
        engines = getattr(panel, "COMPAT_ENGINES", None)
        if engines is None or panel.__name__ in exclude:
            continue
        if "BLENDER_RENDER" in engines or panel.__name__ in _EEVEE_PANELS:
            yield panel


def register():
    bpy.utils.register_class(LacquerRenderEngine)
    for panel in _compatible_panels():
        panel.COMPAT_ENGINES.add("LACQUER")


def unregister():
    for panel in _compatible_panels():
        panel.COMPAT_ENGINES.discard("LACQUER")
    bpy.utils.unregister_class(LacquerRenderEngine)
