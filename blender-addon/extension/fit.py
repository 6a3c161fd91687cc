"""The node group's inputs for a paint, from the core's fit (``lacquer.fit_node_group``).

The core fits the `Lacquer Coated Paint` node group (modelled from its `principled` lobes exactly
as nodegroup.py mixes them, docs/blender-fit.md) to the paint's mean BRDF and reports the error;
this module only calls it and caches the answer per material JSON (a fit takes 0.05–1.4 s).
"""

from __future__ import annotations

import json

import lacquer

_cache: dict = {}


class FitUnavailable(RuntimeError):
    """The installed lacquer library has no node-group fit."""


def available() -> bool:
    return hasattr(lacquer, "fit_node_group")


def fit(material: dict) -> tuple[dict, dict, str]:
    """``(inputs, error, source)`` for a coated-paint material dict.

    ``inputs`` is keyed by the node group's socket names (colours ``[r, g, b]``), ``error`` the
    core's fit error (``albedo_rms``, ``albedo_max``, ``brdf_rel_rms``, ``brdf_cos_rms``,
    ``snr_db``, ``seconds``), ``source`` names what produced them.
    """
    if not available():
        raise FitUnavailable(f"the lacquer library {lacquer.__version__} has no fit_node_group "
                             "(the extension bundles one that has: reinstall it)")
    key = json.dumps(material, sort_keys=True)
    if key not in _cache:
        r = lacquer.fit_node_group(material)
        _cache[key] = (dict(r["inputs"]), dict(r.get("error") or {}), f"lacquer.fit_node_group ({lacquer.__version__})")
    inputs, error, source = _cache[key]
    return dict(inputs), dict(error), source
