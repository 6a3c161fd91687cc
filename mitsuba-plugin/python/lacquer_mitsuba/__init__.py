"""Lacquer materials inside Mitsuba 3.

    import mitsuba as mi
    mi.set_variant("scalar_rgb")
    import lacquer_mitsuba
    lacquer_mitsuba.register()
    bsdf = mi.load_dict({"type": "lacquer", "preset": "gold_flake_8"})

Or, once per environment, ``python -m lacquer_mitsuba install`` (``install()``) links the
native plugins into Mitsuba's own plugin folder: then ``mi.load_file`` / XML find ``lacquer``
in every process with no ``register()`` call (native variants only; no Python fallback).

`register()` adds this package's folder to Mitsuba's file resolver, so that Mitsuba finds the
native plugin ``plugins/lacquer.so`` (built by ``mitsuba-plugin/build.sh``) for the variants it
was compiled for (scalar_rgb, scalar_spectral, llvm_ad_rgb, llvm_ad_spectral). For any other variant, or when
the native plugin was not built, it registers a pure-Python fallback BSDF (``LacquerPyBSDF``)
that calls the Lacquer C library through the ``lacquer`` ctypes package, if that is installed.

JIT variants (llvm_ad_*): the plugin calls a host library, which Dr.Jit cannot trace into its
symbolic kernels; traced symbolically it evaluates to zero and warns once per object. Render
scenes that use it with ``render(scene, ...)`` (``mi.render`` in wavefront mode when the scene
holds a lacquer BSDF, ``uses_lacquer``), or inside ``with wavefront(): ...``, which switches
``dr.JitFlag.SymbolicLoops`` and ``dr.JitFlag.SymbolicCalls`` off and restores them afterwards.
"""

from __future__ import annotations

import contextlib
import json
import logging
import os

__all__ = ["register", "install", "uninstall", "mitsuba_plugin_dir", "plugin_dir", "plugin_path", "build_info", "native_variants",
           "wavefront", "render", "uses_lacquer", "LacquerError"]

#: Variants the native plugin registers (when built with the llvm variant).
native_variants = ("scalar_rgb", "scalar_spectral", "llvm_ad_rgb", "llvm_ad_spectral")

_HERE = os.path.dirname(os.path.abspath(__file__))


class LacquerError(RuntimeError):
    """The plugin is missing or cannot serve the current variant."""


def plugin_dir() -> str:
    """The folder that holds ``plugins/lacquer.so`` (what is added to the file resolver)."""
    return _HERE


def plugin_path() -> str:
    """Path of the native plugin (it may not exist if build.sh has not run)."""
    return os.path.join(_HERE, "plugins", "lacquer.so")


def build_info() -> dict:
    """What the native plugin was built for (``plugins/build_info.json``, written by build.sh):
    ``{"mitsuba": "3.9.1", "drjit": ..., "variants": [...]}``; ``{}`` when it is not built."""
    path = os.path.join(_HERE, "plugins", "build_info.json")
    if not os.path.exists(path):
        return {}
    with open(path) as f:
        return json.load(f)


def _version_mismatch(mi) -> str | None:
    """A message when the plugin was built for another Mitsuba than the one imported (loading
    it there could crash: C++ classes and their layout change between releases)."""
    built = build_info().get("mitsuba")
    running = getattr(mi, "__version__", None)
    if built and running and built != running:
        return (f"the native lacquer plugin was built for Mitsuba {built}, but Mitsuba {running} is "
                f"imported: install mitsuba=={built} (the wheel lacquer-mitsuba depends on it) or "
                "rebuild the plugin against this Mitsuba (mitsuba-plugin/build.sh, docs/mitsuba.md)")
    return None


def _native_has_variant(mi, variant: str) -> bool:
    if not os.path.exists(plugin_path()):
        return False
    try:
        mi.load_dict({"type": "lacquer", "material": '{"model": "lambert"}'})
        return True
    except Exception as e:  # noqa: BLE001 - Mitsuba raises RuntimeError subclasses
        if "could not be found" in str(e) or "not found" in str(e):
            return False
        raise


def register(fallback: bool = True, python_name: str | None = None) -> str:
    """Makes the BSDF type ``lacquer`` available in the current Mitsuba variant.

    Returns ``"native"`` when the C++ plugin serves this variant, ``"python"`` when the Python
    fallback was registered. Raises ``LacquerError`` when neither is possible. With
    ``python_name`` the Python fallback is also registered under that name (e.g.
    ``"lacquer_py"``, to compare it with the native plugin).
    """
    import mitsuba as mi

    variant = mi.variant()
    if variant is None:
        raise LacquerError("set a Mitsuba variant first (mi.set_variant(...))")
    mismatch = _version_mismatch(mi) if os.path.exists(plugin_path()) else None
    if mismatch and not fallback:
        raise LacquerError(mismatch)
    fr = mi.file_resolver()
    if not mismatch and not any(os.path.abspath(str(p)) == _HERE for p in fr):
        fr.prepend(_HERE)
    if python_name:
        from . import fallback as fb

        fb.register_python_bsdf(python_name)
    if not mismatch and _native_has_variant(mi, variant):
        return "native"
    if not fallback:
        raise LacquerError(_missing_message(variant))
    if mismatch:
        import warnings

        warnings.warn(mismatch + "; using the Python fallback", stacklevel=2)
    try:
        from . import fallback as fb
    except ImportError as e:
        raise LacquerError(_missing_message(variant) + f" (Python fallback unavailable: {e})") from e
    fb.register_python_bsdf()
    return "python"


#: The native plugins ``install`` links into Mitsuba's own plugin folder.
_PLUGINS = ("lacquer.so", "lacquer_path.so")


def mitsuba_plugin_dir() -> str:
    """Mitsuba's own plugin folder (``<site-packages>/mitsuba/plugins``), which Mitsuba's file
    resolver searches in every process without any registration."""
    try:
        import mitsuba
    except ImportError as e:
        raise LacquerError("mitsuba is not installed in this Python (pip install mitsuba==3.9.1)") from e
    return os.path.join(os.path.dirname(os.path.abspath(mitsuba.__file__)), "plugins")


def install(target: str | None = None) -> list:
    """The one step that lets ``mi.load_file`` / XML / ``mi.load_dict`` find ``lacquer`` (and
    the ``lacquer_path`` integrator) in every later process without ``register()``: symbolic
    links to this package's native plugins in Mitsuba's plugin folder (``target`` overrides
    it). Refuses (``LacquerError``, naming both versions) when the plugins were built for
    another Mitsuba. Returns the links made. Shell: ``python -m lacquer_mitsuba install``.
    ``uninstall()`` removes them."""
    import importlib.metadata

    target = target or mitsuba_plugin_dir()
    built = build_info().get("mitsuba")
    if not os.path.exists(plugin_path()) or not built:
        raise LacquerError(_missing_message("any"))
    try:
        running = importlib.metadata.version("mitsuba")
    except importlib.metadata.PackageNotFoundError:
        running = None
    if running and running != built:
        raise LacquerError(f"the native lacquer plugin was built for Mitsuba {built}, but Mitsuba {running} is "
                           f"installed: install mitsuba=={built} or rebuild the plugin against this Mitsuba")
    if not os.path.isdir(target):
        raise LacquerError(f"Mitsuba's plugin folder {target} does not exist")
    made = []
    for name in _PLUGINS:
        src, dst = os.path.join(_HERE, "plugins", name), os.path.join(target, name)
        if os.path.lexists(dst):
            if os.path.islink(dst):
                os.remove(dst)
            else:
                raise LacquerError(f"{dst} exists and is not a link made by lacquer_mitsuba: not replaced")
        os.symlink(src, dst)
        made.append(dst)
    return made


def uninstall(target: str | None = None) -> list:
    """Removes the links ``install()`` made (only symbolic links to lacquer plugins)."""
    target = target or mitsuba_plugin_dir()
    removed = []
    for name in _PLUGINS:
        dst = os.path.join(target, name)
        if os.path.islink(dst):
            os.remove(dst)
            removed.append(dst)
    return removed


def _missing_message(variant: str) -> str:
    if not os.path.exists(plugin_path()):
        return (f"the native plugin {plugin_path()} is not built: run mitsuba-plugin/build.sh "
                "(see docs/mitsuba.md)")
    return (f"the native lacquer plugin does not support the variant {variant!r} "
            f"(it supports {', '.join(native_variants)})")


@contextlib.contextmanager
def wavefront():
    """Context manager: Dr.Jit wavefront mode (symbolic loops and calls off), as the JIT
    variants of the plugin need; the previous flags are restored on exit."""
    import drjit as dr

    flags = (dr.JitFlag.SymbolicLoops, dr.JitFlag.SymbolicCalls)
    old = [dr.flag(f) for f in flags]
    try:
        for f in flags:
            dr.set_flag(f, False)
        yield
    finally:
        for f, v in zip(flags, old):
            dr.set_flag(f, v)


#: Class names of the lacquer BSDFs: the native plugin and the Python fallback.
_LACQUER_CLASSES = ("LacquerBSDF", "LacquerPyBSDF")

_log = logging.getLogger("lacquer_mitsuba")


def uses_lacquer(node) -> bool:
    """True when the Mitsuba object ``node`` (a scene, shape, BSDF, ...) is or holds a lacquer
    BSDF (native or Python fallback), found by walking the objects its ``traverse`` reports:
    the shapes' BSDFs, BSDFs nested in ``twosided``/``blendbsdf``/``mask``, shape groups and
    instances, emitters, sensors."""
    import mitsuba as mi

    seen = set()
    found = []

    def is_lacquer(obj):
        return obj.class_name() in _LACQUER_CLASSES or type(obj).__name__ in _LACQUER_CLASSES

    class Walk(mi.TraversalCallback):
        def put(self, name, value, flags, cpptype=None):
            if isinstance(value, mi.Object):
                visit(value)

    def visit(obj):
        if found or obj is None or obj.ptr in seen:
            return
        seen.add(obj.ptr)
        if is_lacquer(obj):
            found.append(obj)
            return
        obj.traverse(Walk())

    visit(node)
    return bool(found)


def render(scene, *args, **kwargs):
    """``mi.render(scene, *args, **kwargs)``, in wavefront mode (``wavefront()``) when the
    variant is a JIT one, Dr.Jit's symbolic loops or calls are on (Mitsuba's default) and the
    scene holds a lacquer BSDF (``uses_lacquer``): there the plugin cannot run symbolically and
    would render black. Logs what it did (logger ``lacquer_mitsuba``, level INFO) when it switches.
    Other scenes and scalar variants render exactly as ``mi.render`` renders them."""
    import drjit as dr
    import mitsuba as mi

    variant = mi.variant() or ""
    symbolic = dr.flag(dr.JitFlag.SymbolicLoops) or dr.flag(dr.JitFlag.SymbolicCalls)
    if variant.startswith(("llvm_", "cuda_")) and symbolic and uses_lacquer(scene):
        _log.info("lacquer_mitsuba.render: the scene uses a lacquer BSDF, which cannot run inside "
                  "Dr.Jit's symbolic loops and calls: rendering in wavefront mode (SymbolicLoops and "
                  "SymbolicCalls off for this call; variant %s)", variant)
        with wavefront():
            return mi.render(scene, *args, **kwargs)
    return mi.render(scene, *args, **kwargs)
