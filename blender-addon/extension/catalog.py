"""What the core says about the paint: its parameters and presets, read once from the `lacquer`
wheel (``lacquer.models()``, ``lacquer.presets()``), plus the display names of the presets.

Nothing here is physics; the ranges, defaults, units and preset values are the core's.
"""

from __future__ import annotations

import functools
import re

import lacquer

MODEL = "coated_paint"

#: Parameters the add-on sets itself rather than showing them (the LACQUER engine gives every
#: mesh a physical uv, see export.py, and sets the scale from it).
HIDDEN = {"surface_scale_mm"}

#: Panel sections, in order; every parameter of the model not listed lands in "Other".
SECTIONS = (
    ("Clearcoat", ("coat_ior", "coat_roughness", "coat_thickness_um", "coat_absorption")),
    ("Basecoat", ("base_color", "base_metallic", "base_roughness")),
    ("Metallic flakes", ("flake_density", "flake_size_um", "flake_orientation_deg", "flake_material")),
    ("Pearlescent flakes", ("pearl_density", "pearl_size_um", "pearl_film_nm", "pearl_film_ior",
                            "pearl_substrate_ior")),
    ("Sparkle", ("sparkle",)),
)

#: The artist controls on ``material.lacquer`` (not core parameters), shown in their own box.
ARTIST = ("orange_peel_um", "orange_peel_wavelength_mm", "flake_scale", "sparkle_lod")


def fit_quality_lines(err: dict) -> list:
    """The core's fit error (``albedo_rms``, ``brdf_rel_rms``, …) as sentences for the panel."""
    lines = []
    rel = err.get("brdf_rel_rms")
    if rel is not None:
        grade = "excellent" if rel < 0.03 else "good" if rel < 0.07 else "fair" if rel < 0.12 else "rough"
        lines.append(f"Match to the exact paint: {grade} (BRDF within {100 * rel:.1f} % RMS)")
    if "albedo_rms" in err:
        extra = f", worst {100 * err['albedo_max']:.1f} %" if "albedo_max" in err else ""
        lines.append(f"Brightness (albedo) off by {100 * err['albedo_rms']:.2f} % RMS{extra}")
    if "snr_db" in err:
        lines.append(f"Signal-to-noise of the fit: {err['snr_db']:.1f} dB")
    return lines

LABELS = {
    "base_color": "Pigment Color",
    "coat_ior": "Coat IOR",
    "coat_roughness": "Coat Roughness (α)",
    "coat_thickness_um": "Coat Thickness (µm)",
    "coat_absorption": "Coat Absorption (1/mm)",
    "flake_density": "Flake Density (%)",
    "flake_size_um": "Flake Size (µm)",
    "flake_orientation_deg": "Flake Orientation (°)",
    "flake_material": "Flake Metal",
    "base_metallic": "Metallic Base",
    "base_roughness": "Metallic Base Roughness (α)",
    "pearl_density": "Pearl Density (%)",
    "pearl_size_um": "Pearl Size (µm)",
    "pearl_film_nm": "Pearl Film (nm)",
    "pearl_film_ior": "Pearl Film IOR",
    "pearl_substrate_ior": "Pearl Substrate IOR",
    "sparkle": "Sparkle",
}


@functools.lru_cache(maxsize=None)
def params() -> tuple:
    """The coated-paint parameters as the core lists them (name, kind, default, min, max, unit, doc)."""
    for m in lacquer.models():
        if m["name"] == MODEL:
            return tuple(m["params"])
    raise RuntimeError(f"the lacquer library has no model {MODEL!r}")


@functools.lru_cache(maxsize=None)
def model_params(name: str) -> dict:
    """Parameters of any registered model by name (empty if the model does not exist)."""
    for m in lacquer.models():
        if m["name"] == name:
            return {p["name"]: p for p in m["params"]}
    return {}


@functools.lru_cache(maxsize=None)
def presets() -> tuple:
    """The coated-paint presets: (name, label, description, material dict)."""
    out = []
    for p in lacquer.presets():
        if p["material"].get("model") == MODEL:
            out.append((p["name"], preset_label(p["name"]), p.get("description", ""), p["material"]))
    return tuple(out)


def preset(name: str) -> dict:
    """The full material JSON of a preset."""
    for n, _, _, material in presets():
        if n == name:
            return dict(material)
    raise KeyError(f"no coated-paint preset named {name!r}")


def preset_label(name: str) -> str:
    """Display name: gold_flake_8 → "Gold metallic 8 %", gold_flake_8_size_15 → "Gold metallic 8 %, 15 µm"."""
    m = re.fullmatch(r"(gold|silver)_flake_(\d+)(?:_size_(\d+))?", name)
    if m:
        label = f"{m.group(1).capitalize()} metallic {m.group(2)} %"
        return label + (f", {m.group(3)} µm" if m.group(3) else "")
    return name.replace("_", " ").capitalize()


#: The asset library's catalogues (paths in the Asset Browser), in order.
ASSET_CATALOGS = ("Lacquer/Thesis series", "Lacquer/Solid", "Lacquer/Metallic", "Lacquer/Pearlescent")


def asset_catalog(name: str) -> str:
    """The asset catalogue of a preset: the thesis series first, then by what the paint holds."""
    if is_thesis(name):
        return "Lacquer/Thesis series"
    m = preset(name)
    if m.get("pearl_density", 0.0) > 0.0:
        return "Lacquer/Pearlescent"
    if m.get("flake_density", 0.0) > 0.0 or m.get("base_metallic", 0.0) > 0.0:
        return "Lacquer/Metallic"
    return "Lacquer/Solid"


def catalog_uuid(path: str) -> str:
    """A fixed UUID per catalogue path (the same in every build)."""
    import uuid

    return str(uuid.uuid5(uuid.NAMESPACE_URL, "lacquer-asset-catalog:" + path))


def is_thesis(name: str) -> bool:
    """The thesis' gold/silver series (density and size)."""
    return re.fullmatch(r"(gold|silver)_flake_\d+(_size_\d+)?", name) is not None
