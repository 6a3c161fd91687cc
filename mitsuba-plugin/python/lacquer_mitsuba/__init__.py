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
was compiled for (scalar_rgb, scalar_spectral, llvm_ad_rgb). For any other variant, or when
the native plugin was not built, it registers a pure-Python fallback BSDF (``LacquerPyBSDF``)
that calls the Lacquer C library through the ``lacquer`` ctypes package, if that is installed.

JIT variants (llvm_ad_*): the plugin calls a host library, which Dr.Jit cannot trace into its
symbolic kernels. Render in wavefront mode: ``wavefront()`` switches
``dr.JitFlag.SymbolicLoops`` and ``dr.JitFlag.SymbolicCalls`` off (``with wavefront(): ...``
restores them afterwards).
"""

from __future__ import annotations

import contextlib
import json
import os

__all__ = ["register", "install", "uninstall", "mitsuba_plugin_dir", "plugin_dir", "plugin_path", "build_info", "native_variants",
           "wavefront", "LacquerError"]

#: Variants the native plugin registers (when built with the llvm variant).
native_variants = ("scalar_rgb", "scalar_spectral", "llvm_ad_rgb")

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
