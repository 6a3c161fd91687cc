"""Pure-Python fallback of the `lacquer` BSDF, for users without a compiler and for variants the
native plugin does not serve (e.g. llvm_ad_mono, cuda_ad_rgb): a ``mi.BSDF`` subclass that
evaluates whole arrays through the ``lacquer`` ctypes package (c-api/python) over
liblacquer.so. Same parameters and conventions as the native plugin (``model`` / ``preset`` /
``material`` with typed properties for the model's parameters, ``tint``), without the
sparkle footprint and ``mi.traverse`` editing. RGB and monochrome variants only
(spectral variants need the native plugin).

In JIT variants it needs wavefront mode, like the native plugin (traced symbolically it returns
zero and warns once; ``lacquer_mitsuba.render`` switches to wavefront mode for scenes using it). In scalar variants Mitsuba
calls it once per interaction, through Python: correct but slow (use the native plugin there).
"""

from __future__ import annotations

import json
import os
import sys

import numpy as np

import drjit as dr
import mitsuba as mi

#: What the BSDF logs (once per object) when traced symbolically; the native plugin says the same.
_SYMBOLIC_WARNING = (
    "lacquer (Python fallback): the lacquer BSDF \"{}\" is being traced inside a symbolic Dr.Jit loop or call "
    "(Mitsuba's default in JIT variants), where it evaluates to zero (black) and its samples are "
    "invalid. Harmless if the scene being rendered does not use it (a symbolic call traces every "
    "live BSDF). To render a scene that uses it, use wavefront mode: lacquer_mitsuba.render(scene, ...), "
    "or `with lacquer_mitsuba.wavefront(): mi.render(scene)` (docs/mitsuba.md). Shown once per object.")

_LQ_SAMPLE_DELTA = 1
_LQ_SAMPLE_FAILED = 2


def _lacquer():
    try:
        import lacquer  # noqa: F401
    except ImportError:
        repo = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..", ".."))
        sys.path.append(os.path.join(repo, "c-api", "python"))
        if not os.environ.get("LACQUER_LIBRARY"):
            for d in (os.environ.get("CARGO_TARGET_DIR"), os.path.join(repo, "target")):
                if d and os.path.isfile(os.path.join(d, "release", "liblacquer.so")):
                    os.environ["LACQUER_LIBRARY"] = os.path.join(d, "release", "liblacquer.so")
                    break
        import lacquer  # noqa: F401
    return sys.modules["lacquer"]


def _is_jit():
    return dr.is_jit_v(mi.Float)


def _to_np3(v):
    """(n, 3) float32 array from a Mitsuba 3-vector (scalar or JIT)."""
    a = np.array(v, dtype=np.float32)
    return a.reshape(1, 3) if a.ndim == 1 else np.ascontiguousarray(a.T)


def _vec3(a):
    a = np.asarray(a, dtype=np.float32)
    if not _is_jit():
        return mi.Vector3f(float(a[0, 0]), float(a[0, 1]), float(a[0, 2]))
    return mi.Vector3f(a[:, 0], a[:, 1], a[:, 2])


def _float(a):
    a = np.asarray(a, dtype=np.float32)
    return mi.Float(float(a[0])) if not _is_jit() else mi.Float(a)


def _spectrum(rgb):
    rgb = np.asarray(rgb, dtype=np.float32)
    if dr.size_v(mi.Spectrum) == 1:  # monochrome variants: luminance
        y = rgb @ np.array([0.2126, 0.7152, 0.0722], dtype=np.float32)
        return mi.Spectrum(float(y[0])) if not _is_jit() else mi.Spectrum(mi.Float(y))
    return mi.Spectrum(_vec3(rgb))


#: Plugin properties that are not material parameters.
_PLUGIN_KEYS = ("model", "preset", "material", "tint", "footprint")


def _property_value(props, key):
    """A Mitsuba property as a JSON value: colours as [r, g, b], numbers, booleans, strings."""
    v = props[key]
    if isinstance(v, (bool, int, float, str)):
        return v
    if isinstance(v, mi.Object):
        raise RuntimeError(
            f'lacquer: property "{key}" is a texture or object: the Python fallback (variant {mi.variant()}) '
            "takes plain values only; textured base_color, flake_density and coat_roughness need the "
            "native plugin (scalar_rgb, scalar_spectral, llvm_ad_rgb, llvm_ad_spectral; docs/mitsuba.md, \"Textures\")")
    a = np.array(v, dtype=np.float64).ravel()
    if a.size == 3:
        return [float(x) for x in a]
    if a.size == 1:
        return float(a[0])
    raise RuntimeError(f'lacquer: property "{key}" has a type the plugin cannot use ({type(v).__name__})')


def material_from_properties(lq, props) -> dict:
    """The material JSON of the plugin's properties, as the native plugin reads them: exactly
    one of ``model`` / ``preset`` / ``material`` gives the starting values, and every other
    property names a parameter of that model (typed: <float>, <integer>, <rgb>, <boolean>,
    <string>) and overrides it. Unknown names are an error naming the model's parameters; the
    core's validation names the range of a bad value."""
    base = [k for k in ("model", "preset", "material") if k in props]
    if len(base) != 1:
        raise RuntimeError('lacquer: give exactly one of "model", "preset" or "material"')
    if "material" in props:
        material = json.loads(props["material"])
    elif "preset" in props:
        found = [p for p in lq.presets() if p["name"] == props["preset"]]
        if not found:
            raise RuntimeError(f'lacquer: unknown preset "{props["preset"]}"')
        material = dict(found[0]["material"])
    else:
        material = {"model": props["model"]}
    model = material.get("model")
    infos = {m["name"]: m for m in lq.models()}
    if model not in infos:
        raise RuntimeError(f'lacquer: unknown model "{model}" (lacquer models lists {", ".join(infos)})')
    names = [p["name"] for p in infos[model]["params"]]
    for key in props.keys():
        if key in _PLUGIN_KEYS:
            continue
        if key not in names:
            raise RuntimeError(f'lacquer: unknown property "{key}": model "{model}" has the parameters '
                               f'{", ".join(names)}')
        material[key] = _property_value(props, key)
    return material


_CLASSES = {}


def bsdf_class():
    """The fallback class for the current variant (mi.BSDF differs per variant)."""
    variant = mi.variant()
    if variant not in _CLASSES:
        _CLASSES[variant] = _make_class()
    return _CLASSES[variant]


def _make_class():
    class LacquerPyBSDF(mi.BSDF):
        def __init__(self, props):
            mi.BSDF.__init__(self, props)
            if mi.is_spectral or mi.is_polarized:
                raise RuntimeError("lacquer (Python fallback): RGB and monochrome variants only; spectral "
                                   "variants need the native plugin (mitsuba-plugin/build.sh)")
            lq = _lacquer()
            self.material = lq.Material(material_from_properties(lq, props))
            self.tint = props.get_texture("tint", 1.0) if "tint" in props else None
            # Flags from the core (lq_material_lobes), as the native plugin sets them.
            lobes = self.material.lobes()
            smooth = 0
            if lobes & lq.LOBE_DIFFUSE:
                smooth |= int(mi.BSDFFlags.DiffuseReflection)
            if lobes & lq.LOBE_GLOSSY:
                smooth |= int(mi.BSDFFlags.GlossyReflection)
            self.smooth = smooth
            self.has_delta = bool(lobes & lq.LOBE_DELTA)
            self.delta_component = 1 if smooth else 0
            comps = []
            if smooth:
                aniso = int(mi.BSDFFlags.Anisotropic) if lobes & lq.LOBE_ANISOTROPIC else 0
                comps.append(smooth | aniso | int(mi.BSDFFlags.FrontSide))
            if self.has_delta:
                comps.append(int(mi.BSDFFlags.DeltaReflection | mi.BSDFFlags.FrontSide))
            self.m_components = comps
            flags = 0
            for c in self.m_components:
                flags |= c
            if lobes & lq.LOBE_NON_RECIPROCAL:
                flags |= int(mi.BSDFFlags.NonSymmetric)
            if lobes & lq.LOBE_SPATIALLY_VARYING:
                flags |= int(mi.BSDFFlags.SpatiallyVarying)
            self.m_flags = flags

        def _symbolic(self):
            """True when traced in a symbolic Dr.Jit loop or call, where the ctypes calls cannot
            run: eval/pdf return zero and sample an invalid sample (as the native plugin), with
            one warning per object. A symbolic virtual call traces every live BSDF, so objects
            that the rendered scene does not use get here too, harmlessly."""
            if not dr.flag(dr.JitFlag.SymbolicScope):
                return False
            if not getattr(self, "_warned_symbolic", False):
                self._warned_symbolic = True
                mi.Log(mi.LogLevel.Warn, _SYMBOLIC_WARNING.format(self.id() or "(no id)"))
            return True

        def _tinted(self, value, si, active):
            return value * self.tint.eval(si, active) if self.tint is not None else value

        def _smooth_on(self, ctx):
            return any(self.smooth & int(b) and ctx.is_enabled(b, 0)
                       for b in (mi.BSDFFlags.DiffuseReflection, mi.BSDFFlags.GlossyReflection))

        def eval_pdf(self, ctx, si, wo, active=True):
            if self._symbolic() or not self._smooth_on(ctx):
                return mi.Spectrum(0.0), mi.Float(0.0)
            f, p = self.material.eval_pdf(_to_np3(wo), _to_np3(si.wi), strict=False)
            value = _spectrum(f) * dr.maximum(wo.z, 0.0)
            value = self._tinted(value, si, active)
            return dr.select(active, value, 0.0), dr.select(active, _float(p), 0.0)

        def eval(self, ctx, si, wo, active=True):
            return self.eval_pdf(ctx, si, wo, active)[0]

        def pdf(self, ctx, si, wo, active=True):
            return self.eval_pdf(ctx, si, wo, active)[1]

        def sample(self, ctx, si, sample1, sample2, active=True):
            if self._symbolic():
                return dr.zeros(mi.BSDFSample3f), mi.Spectrum(0.0)
            n = dr.width(si.wi) if _is_jit() else 1
            u = np.stack([np.broadcast_to(np.array(x, dtype=np.float32), (n,))
                          for x in (sample1, sample2.x, sample2.y)], axis=1)
            s = self.material.sample(_to_np3(si.wi), u, strict=False)
            delta = (s.flags & _LQ_SAMPLE_DELTA) != 0
            ok = ((s.flags & _LQ_SAMPLE_FAILED) == 0) & (s.pdf > 0)
            if not (self.has_delta and ctx.is_enabled(mi.BSDFFlags.DeltaReflection, self.delta_component)):
                ok &= ~delta
            if not self._smooth_on(ctx):
                ok &= delta
            bs = dr.zeros(mi.BSDFSample3f)
            bs.wo = _vec3(np.where(ok[:, None], s.wi, 0))
            bs.pdf = _float(np.where(ok, s.pdf, 0))
            bs.eta = 1.0
            dflag, sflag = int(mi.BSDFFlags.DeltaReflection), int(self.smooth)
            if _is_jit():
                bs.sampled_type = mi.UInt32(np.where(delta, dflag, sflag).astype(np.uint32))
                bs.sampled_component = mi.UInt32(np.where(delta, self.delta_component, 0).astype(np.uint32))
            else:
                bs.sampled_type = dflag if delta[0] else sflag
                bs.sampled_component = self.delta_component if delta[0] else 0
            w = self._tinted(_spectrum(np.where(ok[:, None], s.weight, 0)), si, active)
            return bs, dr.select(active, w, 0.0)

        def traverse(self, callback):
            if self.tint is not None:
                callback.put("tint", self.tint, mi.ParamFlags.NonDifferentiable)

        def to_string(self):
            return f"LacquerPyBSDF[material = {self.material.to_json()}]"

    return LacquerPyBSDF


def register_python_bsdf(name: str = "lacquer") -> None:
    """Registers the fallback under `name` in the current variant."""
    cls = bsdf_class()
    mi.register_bsdf(name, lambda props: cls(props))
