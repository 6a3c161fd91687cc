"""The node group's inputs for a paint, from the core's fit (``lacquer.fit_node_group``).

The core fits the `Lacquer Coated Paint` node group (modelled from its `principled` lobes exactly
as nodegroup.py mixes them, docs/blender-fit.md) to the paint's mean BRDF and reports the error;
this module only calls it and caches the answer per material JSON (a fit takes 0.05–1.4 s).
"""

from __future__ import annotations

import json

import lacquer

_cache: dict = {}


#: The base colours of the core's base colour map (``BASE_COLOR_GRID`` in
#: rust-core/src/fit/node_group.rs), baked into the node group's Map Range nodes.
BASE_COLOR_GRID = (0.0, 0.125, 0.25, 0.375, 0.5, 0.625, 0.75, 0.875, 1.0)


def map_socket(k: int) -> str:
    """The node group input holding the base colour map's ratio at ``BASE_COLOR_GRID[k]``."""
    return f"Base Color Map {k}"


def map_inputs(result: dict) -> dict:
    """The node group inputs of the fit's ``base_color_map`` (the core's per-channel ratio
    pigment / base colour on ``BASE_COLOR_GRID``, docs/blender-fit.md): ``{"Base Color Map k":
    [r, g, b]}``. Raises ``FitUnavailable`` when the library's map is missing or on another grid."""
    m = result.get("base_color_map")
    if not m:
        raise FitUnavailable(f"the lacquer library {lacquer.__version__} returns no base_color_map "
                             "(the extension bundles one that does: reinstall it)")
    grid = tuple(float(v) for v in m["base_color"])
    if grid != BASE_COLOR_GRID:
        raise FitUnavailable(f"the lacquer library's base colour grid {grid} is not the node group's "
                             f"{BASE_COLOR_GRID} (mismatched extension and library)")
    return {map_socket(k): [float(v) for v in ratio] for k, ratio in enumerate(m["ratio"])}


class FitUnavailable(RuntimeError):
    """The installed lacquer library has no node-group fit."""


def available() -> bool:
    return hasattr(lacquer, "fit_node_group")


def fit(material: dict) -> tuple[dict, dict, str]:
    """``(inputs, error, source)`` for a coated-paint material dict.

    ``inputs`` is keyed by the node group's socket names (colours ``[r, g, b]``; the base colour
    map as ``Base Color Map k``, see :func:`map_inputs`), ``error`` the
    core's fit error (``albedo_rms``, ``albedo_max``, ``brdf_rel_rms``, ``brdf_cos_rms``,
    ``snr_db``, ``seconds``), ``source`` names what produced them.
    """
    if not available():
        raise FitUnavailable(f"the lacquer library {lacquer.__version__} has no fit_node_group "
                             "(the extension bundles one that has: reinstall it)")
    key = json.dumps(material, sort_keys=True)
    if key not in _cache:
        r = lacquer.fit_node_group(material)
        inputs = dict(r["inputs"])
        inputs.update(map_inputs(r))
        _cache[key] = (inputs, dict(r.get("error") or {}), f"lacquer.fit_node_group ({lacquer.__version__})")
    inputs, error, source = _cache[key]
    return dict(inputs), dict(error), source
