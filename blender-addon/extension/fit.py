"""The node group's inputs for a paint, from the core's fit (``lacquer.fit_node_group``).

The core fits the `Lacquer Coated Paint` node group (modelled from its `principled` lobes exactly
as nodegroup.py mixes them) to the paint's mean BRDF and reports the error; this module only
calls it and caches the answer per material JSON.
"""

from __future__ import annotations

import json
import math

import lacquer

_cache: dict = {}


class FitUnavailable(RuntimeError):
    """The installed lacquer library has no node-group fit."""


def available() -> bool:
    return hasattr(lacquer, "fit_node_group")


def fit(material: dict) -> tuple[dict, dict | None, str]:
    """``(inputs, error, source)`` for a coated-paint material dict.

    ``inputs`` is keyed by the node group's socket names (colours ``[r, g, b]``), ``error`` the
    core's fit error (``albedo_rms``, ``brdf_rel_rms``, ...; None for the provisional mapping),
    ``source`` says which produced them.
    """
    key = json.dumps(material, sort_keys=True)
    if key not in _cache:
        if available():
            r = lacquer.fit_node_group(material)
            _cache[key] = (dict(r["inputs"]), dict(r.get("error") or {}), "lacquer.fit_node_group")
        else:
            _cache[key] = (_provisional_inputs(material), None, "provisional (no lacquer.fit_node_group)")
    inputs, error, source = _cache[key]
    return dict(inputs), (dict(error) if error is not None else None), source


# Normal-incidence reflectance of the flake metals, only for the provisional mapping below.
_F0 = {"Al": [0.913, 0.922, 0.924], "Ag": [0.972, 0.960, 0.915], "Au": [1.0, 0.766, 0.336],
       "Cu": [0.955, 0.638, 0.538]}


def _provisional_inputs(m: dict) -> dict:
    """A parameter-for-parameter translation used only while the library lacks the fit:
    no calibration, no error figures (the panel says so)."""
    spread = math.tan(math.radians(m["flake_orientation_deg"]))
    thickness_mm = m["coat_thickness_um"] / 1000.0
    absorb = m["coat_absorption"] if isinstance(m["coat_absorption"], list) else [m["coat_absorption"]] * 3
    return {
        "Pigment Color": list(m["base_color"]),
        "Flake Color": _F0.get(m["flake_material"], _F0["Al"]),
        "Flake Coverage": m["flake_density"] / 100.0,
        "Flake Roughness": 0.1,
        "Flake Spread": min(spread, 1.0),
        "Flake Size": m["flake_size_um"],
        "Pearl Coverage": m["pearl_density"] / 100.0,
        "Pearl Color": list(m["base_color"]),
        "Pearl Film Thickness": m["pearl_film_nm"],
        "Pearl Film IOR": m["pearl_film_ior"],
        "Pearl Spread": min(spread, 1.0),
        "Coat Weight": 1.0 if m["coat_ior"] > 1.0 else 0.0,
        "Coat Roughness": math.sqrt(m["coat_roughness"]),
        "Coat IOR": max(m["coat_ior"], 1.0),
        "Coat Tint": [math.exp(-a * thickness_mm) for a in absorb],
        "Sparkle": 1.0 if m.get("sparkle", True) else 0.0,
    }
