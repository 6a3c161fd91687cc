"""The `LACQUER` render engine: the scene rendered by lacquer's reference path tracer through the
C ABI (``lacquer.render``), with Blender's progress, cancel and stats."""

from __future__ import annotations

import os
import time

import bpy
import numpy as np

import lacquer

from . import export, viewport


#: Passes the engine fills besides Combined: (name, channels, chan_id, type). The albedo and
#: normal are the first hit's (the core's AOVs), in Blender's world space: what the compositor's
#: Denoise node (OIDN) takes.
PASSES = (("Denoising Albedo", 3, "RGB", "COLOR"), ("Denoising Normal", 3, "XYZ", "VECTOR"))

#: Colour passes declared when the view layer enables them (Cycles' names and flags): the first
#: hit's diffuse and glossy lobe groups' directional albedo (the job's "lobe_aovs": the mean of
#: the core's per-lobe sample weights; glossy = flakes, metallic base and the clearcoat).
#: (pass name, view layer flag, lacquer image key).
LOBE_PASSES = (("DiffCol", "use_pass_diffuse_color", "diffuse_color"),
               ("GlossCol", "use_pass_glossy_color", "glossy_color"))


def lobe_passes(view_layer) -> list:
    """The colour passes (:data:`LOBE_PASSES`) a view layer asks for."""
    return [p for p in LOBE_PASSES if view_layer is not None and getattr(view_layer, p[1], False)]

#: What the last final render did (rounds shown with update_result, passes written, whether it
#: was cancelled, spp reached); read by the tests and useful from the Python console.
LAST_RENDER: dict = {}


def rounds(spp: int):
    """Samples per round of a progressive render: 1, 1, 2, 4, … doubling, each at most
    max(4, spp / 8), so an image shows after one sample and then every few samples."""
    done, cap = 0, max(4, spp // 8)
    while done < spp:
        n = min(spp - done, max(1, min(done, cap)))
        yield n
        done += n


def viewport_job(depsgraph, width: int, height: int, view_matrix, window_matrix, report):
    """The render job of a 3D viewport: its view and projection, the region's size, the
    scene's viewport samples (Preview Samples)."""
    temp: list = []
    cam = export.view_camera_desc(view_matrix, window_matrix)
    job = export.job(depsgraph, report, temp, preview=True, size=(width, height), camera=cam)
    job["transparent"] = bool(depsgraph.scene.render.film_transparent)
    return job, temp


def _break_requested(engine) -> bool:
    """Esc (the engine's test_break); one place, so that scripts can stop renders too."""
    return engine.test_break()


def _native_floats(a) -> np.ndarray:
    """A flat native-endian float32 copy: foreach_set refuses the ctypes arrays' explicit "<f"."""
    out = np.empty(a.size, np.float32)
    out[:] = a.reshape(-1)
    return out


class LacquerRenderEngine(bpy.types.RenderEngine):
    bl_idname = "LACQUER"
    bl_label = "Lacquer"
    bl_use_preview = True
    bl_use_postprocess = True
    # Materials keep their Cycles/EEVEE node trees (the node group is the everyday path).
    bl_use_shading_nodes_custom = False
    # The Rendered viewport is LACQUER's own (view_update / view_draw), not EEVEE's.
    bl_use_eevee_viewport = False

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._view = None
        self._view_key = None
        self._view_temp: list = []
        self._texture = None
        self._texture_version = -1

    def __del__(self):
        view = getattr(self, "_view", None)
        if view is not None:
            view.stop(wait=False)

    def update_render_passes(self, scene=None, renderlayer=None):
        self.register_pass(scene, renderlayer, "Combined", 4, "RGBA", "COLOR")
        for name, channels, chan_id, kind in PASSES:
            self.register_pass(scene, renderlayer, name, channels, chan_id, kind)
        for name, _, _ in lobe_passes(renderlayer):
            self.register_pass(scene, renderlayer, name, 3, "RGB", "COLOR")

    def render(self, depsgraph):
        scene = depsgraph.scene
        report = export.Report()
        temp_files: list = []
        t0 = time.perf_counter()
        LAST_RENDER.clear()
        try:
            self.update_stats("", "Lacquer: exporting the scene")
            job = export.job(depsgraph, report, temp_files, preview=self.is_preview)
            job["transparent"] = bool(scene.render.film_transparent)
            job["aovs"] = not self.is_preview
            lobes = [] if self.is_preview else lobe_passes(depsgraph.view_layer)
            job["lobe_aovs"] = bool(lobes)
            for line in report.lines():
                print(f"Lacquer: {line}")
                if not self.is_preview:
                    self.report({"WARNING"}, line)
            width, height = job["width"], job["height"]
            t_export = time.perf_counter() - t0
            session = lacquer.RenderSession(job)
            spp = session.target
            start = time.perf_counter()

            done_before = 0

            def progress(fraction):
                done = done_before + fraction * step
                self.update_progress(done / spp)
                elapsed = time.perf_counter() - start
                self.update_stats("", f"Lacquer: path tracing {width}×{height}, {int(done)}/{spp} spp, "
                                      f"{elapsed:.1f} s")
                return not _break_requested(self)

            result = self.begin_result(0, 0, width, height)
            layer = result.layers[0]
            written: list = []
            shown = 0
            cancelled = False
            try:
                for step in rounds(spp):
                    try:
                        session.advance(step, progress)
                    except lacquer.CancelledError:
                        cancelled = True
                        break
                    done_before += step
                    written = self._write(layer, session.image(), scene)
                    self.update_result(result)
                    shown += 1
                    if _break_requested(self):
                        cancelled = True
                        break
            finally:
                self.end_result(result)
            seconds = time.perf_counter() - start
            LAST_RENDER.update(rounds=shown, passes=written, cancelled=cancelled, spp=session.samples,
                               target=spp, seconds=seconds)
            if cancelled:
                self.update_stats("", f"Lacquer: cancelled at {session.samples}/{spp} spp")
                return
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

    @staticmethod
    def _write(layer, img, scene) -> list:
        """Writes an image (lacquer's dict, rows top first) into the render layer's passes;
        returns the names of the passes written."""
        rgba = img["rgba"][::-1]  # the renderer writes rows top first, Blender bottom first
        if not scene.render.film_transparent:
            rgba = rgba.copy()
            rgba[..., 3] = 1.0
        # Native-endian float buffers: foreach_set refuses the ctypes array's explicit "<f".
        layer.passes["Combined"].rect.foreach_set(_native_floats(rgba))
        written = ["Combined"]
        extra = {"Denoising Albedo": img.get("albedo"), "Denoising Normal": img.get("normal")}
        extra.update({name: img.get(key) for name, _, key in LOBE_PASSES})
        for name, data in extra.items():
            p = layer.passes.find(name) if hasattr(layer.passes, "find") else -1
            if data is None or p < 0:
                continue
            if name == "Denoising Normal":
                data = export.normals_to_blender(data)
            layer.passes[p].rect.foreach_set(_native_floats(data[::-1]))
            written.append(name)
        return written

    # --- the Rendered viewport ----------------------------------------------------------------

    def _restart_view(self, context, depsgraph):
        if self._view is not None:
            self._view.stop()
        for f in self._view_temp:
            try:
                os.remove(f)
            except OSError:
                pass
        region, rv3d = context.region, context.region_data
        report = export.Report()
        try:
            job, self._view_temp = viewport_job(depsgraph, region.width, region.height, rv3d.view_matrix,
                                                rv3d.window_matrix, report)
        except Exception as e:  # noqa: BLE001
            self._view = None
            self.update_stats("", f"Lacquer: {e}")
            return
        if not rv3d.is_perspective:
            report.warn("orthographic viewport: rendered in perspective")
        self._view = viewport.ViewportRender(job, job["spp"]).start()
        self._view_key = self._key(context)

    @staticmethod
    def _key(context):
        rv3d = context.region_data
        return (context.region.width, context.region.height, tuple(tuple(r) for r in rv3d.view_matrix),
                tuple(tuple(r) for r in rv3d.window_matrix))

    def view_update(self, context, depsgraph):
        self._restart_view(context, depsgraph)

    def view_draw(self, context, depsgraph):
        if self._view is None or self._key(context) != self._view_key:
            self._restart_view(context, depsgraph)
        if self._view is None:
            return
        latest = self._view.latest()
        if latest is not None:
            import gpu
            from gpu_extras.presets import draw_texture_2d

            rgba, samples = latest
            h, w = rgba.shape[:2]
            if self._texture is None or self._texture_version != self._view.version:
                buf = gpu.types.Buffer("FLOAT", w * h * 4, viewport.display_buffer(rgba))
                self._texture = gpu.types.GPUTexture((w, h), format="RGBA16F", data=buf)
                self._texture_version = self._view.version
            gpu.state.blend_set("ALPHA_PREMULT")
            self.bind_display_space_shader(depsgraph.scene)
            draw_texture_2d(self._texture, (0, 0), context.region.width, context.region.height)
            self.unbind_display_space_shader()
            gpu.state.blend_set("NONE")
            state = "done" if self._view.done else "refining"
            self.update_stats("", f"Lacquer viewport: {w}×{h}, {samples} spp ({state})")
        if self._view.error:
            self.update_stats("", f"Lacquer viewport: {self._view.error}")
        elif not self._view.done:
            self.tag_redraw()


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
