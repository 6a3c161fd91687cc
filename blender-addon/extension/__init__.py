"""Lacquer for Blender: physically checked coated car paint (flakes, sparkle, pearlescent).

Two render paths: the `Lacquer Coated Paint` node group (Cycles and EEVEE; its inputs fitted
by the lacquer core to the reference model; everything lives in the .blend, so farms render
it without the extension), and the `LACQUER` render engine (lacquer's reference path tracer
through its C ABI). See blender-addon/README.md.
"""

from __future__ import annotations

import atexit

_registered = False
_modules = None


def _load():
    from . import assets, engine, operators, props, ui

    return (props, assets, operators, ui, engine)


def register():
    global _registered, _modules
    if _registered:
        return
    _modules = _load()
    for m in _modules:
        m.register()
    _registered = True


def unregister():
    global _registered
    if not _registered:
        return
    for m in reversed(_modules):
        m.unregister()
    _registered = False


def _unregister_at_exit():
    # bpy 4.5 (as a Python module) can hang at interpreter exit while operators are still
    # registered: unregister first.
    try:
        unregister()
    except Exception:  # noqa: BLE001
        pass


atexit.register(_unregister_at_exit)
