"""Lacquer: physically checked BRDFs, from Python.

A ctypes + numpy wrapper over liblacquer's C ABI; every number comes from the library.

Conventions: directions are in the local shading frame (z = normal, x = tangent), ``wi``
toward the light and ``wo`` toward the viewer, both pointing away from the surface.
``eval`` returns f_r in 1/sr WITHOUT the cosine, linear Rec.709 RGB; ``pdf`` is the
solid-angle density of ``sample``; ``sample`` returns ``weight = f cos(theta_i) / pdf``.

Arrays have shape ``(n, 3)`` (or ``(3,)`` for one direction; leading dimensions broadcast).
Results are float32 when every input is float32, float64 otherwise (the library's f64
reference path). The GIL is released during library calls, and a Material may be used from
many threads at once.
"""

from __future__ import annotations

import ctypes
import json as _json
from ctypes import byref, c_bool, c_size_t, c_uint32, c_void_p
from typing import Any, NamedTuple, Optional, Union

import numpy as np

from . import _native
from ._native import (
    LQ_SAMPLE_DELTA,
    LQ_SAMPLE_FAILED,
    LQ_SAMPLE_INVALID_INPUT,
    abi_version,
    library_path,
)

__version__ = _native.lib.lq_version().decode()

__all__ = [
    "Material",
    "Sample",
    "CheckResult",
    "LacquerError",
    "NullPointerError",
    "InvalidJSONError",
    "InvalidMaterialError",
    "UnknownNameError",
    "InvalidArgumentError",
    "InvalidDirectionError",
    "InvalidElementError",
    "PanicError",
    "models",
    "presets",
    "check_model",
    "fit_node_group",
    "render",
    "RenderSession",
    "CancelledError",
    "abi_version",
    "LOBE_DIFFUSE",
    "LOBE_GLOSSY",
    "LOBE_DELTA",
    "LOBE_ANISOTROPIC",
    "LOBE_NON_RECIPROCAL",
    "LOBE_SPATIALLY_VARYING",
    "LOBE_SPECTRAL",
    "LOBE_COAT",
    "LOBES_SELECTABLE",
    "set_thread_count",
    "choose_configuration",
    "simd_level",
    "library_path",
    "LQ_SAMPLE_DELTA",
    "LQ_SAMPLE_FAILED",
    "LQ_SAMPLE_INVALID_INPUT",
]


# --- errors ------------------------------------------------------------------------------


class LacquerError(Exception):
    """A library call failed. ``status`` is the lq_status code, ``status_name`` its name."""

    def __init__(self, status: int, message: str):
        self.status = status
        self.status_name = _native.lib.lq_status_name(status).decode()
        self.message = message
        #: For per-element errors: the fully written result (invalid elements are zero).
        self.result: Any = None
        super().__init__(f"{self.status_name}: {message}")


class NullPointerError(LacquerError):
    """LQ_ERR_NULL (cannot normally happen through this package)."""


class InvalidJSONError(LacquerError, ValueError):
    """LQ_ERR_INVALID_JSON: not JSON (NaN and Infinity are not JSON either)."""


class InvalidMaterialError(LacquerError, ValueError):
    """LQ_ERR_INVALID_MATERIAL: unknown key, wrong type, value out of range..."""


class UnknownNameError(LacquerError, LookupError):
    """LQ_ERR_UNKNOWN_NAME: no model or preset has this name."""


class InvalidArgumentError(LacquerError, ValueError):
    """LQ_ERR_INVALID_ARGUMENT (or an array shape this package rejects)."""


class InvalidDirectionError(LacquerError, ValueError):
    """LQ_ERR_INVALID_DIRECTION: some directions are not finite or have zero length."""


class InvalidElementError(LacquerError, ValueError):
    """LQ_ERR_INVALID_ELEMENT: some u, uv or footprint values are not finite."""


class PanicError(LacquerError, RuntimeError):
    """LQ_ERR_PANIC: a bug inside the library, caught at its boundary."""


class CancelledError(LacquerError):
    """LQ_ERR_CANCELLED: the progress callback of :func:`render` returned False."""


_ERRORS = {
    _native.LQ_ERR_NULL: NullPointerError,
    _native.LQ_ERR_INVALID_JSON: InvalidJSONError,
    _native.LQ_ERR_INVALID_MATERIAL: InvalidMaterialError,
    _native.LQ_ERR_UNKNOWN_NAME: UnknownNameError,
    _native.LQ_ERR_INVALID_ARGUMENT: InvalidArgumentError,
    _native.LQ_ERR_INVALID_DIRECTION: InvalidDirectionError,
    _native.LQ_ERR_INVALID_ELEMENT: InvalidElementError,
    _native.LQ_ERR_PANIC: PanicError,
    _native.LQ_ERR_CANCELLED: CancelledError,
}

_PER_ELEMENT = (_native.LQ_ERR_INVALID_DIRECTION, _native.LQ_ERR_INVALID_ELEMENT)


def _error(status: int) -> LacquerError:
    message = _native.lib.lq_last_error().decode("utf-8", "replace")
    return _ERRORS.get(status, LacquerError)(status, message)


def _check(status: int) -> None:
    if status != _native.LQ_OK:
        raise _error(status)


# --- results -----------------------------------------------------------------------------


class Sample(NamedTuple):
    """Result of :meth:`Material.sample`."""

    wi: np.ndarray  #: (..., 3) sampled directions toward the light
    weight: np.ndarray  #: (..., 3) f cos(theta_i) / pdf
    pdf: np.ndarray  #: (...) solid-angle density; 0 for a failed sample
    flags: np.ndarray  #: (...) uint32 LQ_SAMPLE_* bits


class CheckResult(NamedTuple):
    """Result of the shipped checks."""

    passed: bool  #: every claimed property held
    report: dict  #: the full report (verdicts, reciprocity, furnace, chi2, ...)


_LEVELS = {"quick": _native.LQ_CHECK_QUICK, "standard": _native.LQ_CHECK_STANDARD}


def _level(level: Union[str, int]) -> int:
    if isinstance(level, str):
        if level not in _LEVELS:
            raise InvalidArgumentError(
                _native.LQ_ERR_INVALID_ARGUMENT, f"check level must be 'quick' or 'standard', not {level!r}"
            )
        return _LEVELS[level]
    return int(level)


# --- arrays ------------------------------------------------------------------------------


def _shape_error(message: str) -> InvalidArgumentError:
    return InvalidArgumentError(_native.LQ_ERR_INVALID_ARGUMENT, message)


def _vectors(*arrays, names, widths, dtype=None):
    """Broadcasts (..., k) arrays against each other; returns contiguous (n, k) arrays of one
    dtype, the leading shape, and the dtype."""
    arrs = []
    for a, name, k in zip(arrays, names, widths):
        a = np.asarray(a)
        if a.ndim == 0 or a.shape[-1] != k:
            raise _shape_error(f"`{name}` must have shape (..., {k}), got {a.shape}")
        if not (np.issubdtype(a.dtype, np.floating) or np.issubdtype(a.dtype, np.integer)):
            raise _shape_error(f"`{name}` must be numeric, got dtype {a.dtype}")
        arrs.append(a)
    if dtype is None:
        dtype = np.float32 if all(a.dtype == np.float32 for a in arrs) else np.float64
    try:
        lead = np.broadcast_shapes(*(a.shape[:-1] for a in arrs))
    except ValueError:
        shapes = ", ".join(f"{n} {a.shape}" for n, a in zip(names, arrs))
        raise _shape_error(f"array shapes do not broadcast: {shapes}") from None
    out = [
        np.ascontiguousarray(np.broadcast_to(a, lead + (k,)), dtype=dtype).reshape(-1, k)
        for a, k in zip(arrs, widths)
    ]
    return out, lead, dtype


def _ptr(a: Optional[np.ndarray]):
    if a is None:
        return None
    ctype = ctypes.c_float if a.dtype == np.float32 else (ctypes.c_double if a.dtype == np.float64 else ctypes.c_uint32)
    return a.ctypes.data_as(ctypes.POINTER(ctype))


# --- materials ---------------------------------------------------------------------------


#: Lobe bits of :meth:`Material.lobes` (the C ABI's ``LQ_LOBE_*``).
LOBE_DIFFUSE, LOBE_GLOSSY, LOBE_DELTA = 1, 2, 4
LOBE_ANISOTROPIC, LOBE_NON_RECIPROCAL, LOBE_SPATIALLY_VARYING = 8, 16, 32
#: Lobe bit: spectral physics (thin film, HTSG; the C ABI's lq_eval_spectral, ABI 0.6).
LOBE_SPECTRAL = 64
#: Lobe-mask bit (ABI 0.7): the clearcoat's top reflection, selected on its own
#: (:meth:`Material.lobe_parts`, :meth:`Material.eval_pdf_lobes`).
LOBE_COAT = 128
#: Every bit a lobe mask may hold: ``LOBE_DIFFUSE | LOBE_GLOSSY | LOBE_COAT``.
LOBES_SELECTABLE = 131


class Material:
    """An immutable material from the library.

    ``Material(spec)`` accepts a dict (material JSON as a Python object), a JSON string
    (starting with ``{``), a preset name, or another Material.
    """

    __slots__ = ("_handle", "__weakref__")

    def __init__(self, spec: Union[str, bytes, dict, "Material"]):
        self._handle = None
        if isinstance(spec, Material):
            spec = spec.to_json()
        if isinstance(spec, dict):
            # NaN/Infinity become the non-JSON tokens NaN/Infinity: the library rejects them.
            self._create_json(_json.dumps(spec))
        elif isinstance(spec, (str, bytes)):
            text = spec.decode("utf-8") if isinstance(spec, bytes) else spec
            if text.lstrip().startswith("{"):
                self._create_json(text)
            else:
                self._create(_native.lib.lq_material_from_preset, text)
        else:
            raise TypeError(
                f"Material() takes a dict, a JSON string, a preset name or a Material, not {type(spec).__name__}"
            )

    @classmethod
    def from_json(cls, text: Union[str, bytes]) -> "Material":
        """Parses material JSON text (``{"model": ...}`` or ``{"preset": ...}``)."""
        self = cls.__new__(cls)
        self._handle = None
        self._create_json(text)
        return self

    @classmethod
    def preset(cls, name: str) -> "Material":
        """A named preset (see :func:`presets`)."""
        self = cls.__new__(cls)
        self._handle = None
        self._create(_native.lib.lq_material_from_preset, name)
        return self

    def _create_json(self, text: Union[str, bytes]) -> None:
        self._create(_native.lib.lq_material_from_json, text)

    def _create(self, fn, text: Union[str, bytes]) -> None:
        if isinstance(text, str):
            text = text.encode("utf-8")
        if b"\0" in text:
            raise InvalidJSONError(_native.LQ_ERR_INVALID_JSON, "text contains a NUL character")
        handle = c_void_p()
        _check(fn(text, byref(handle)))
        self._handle = handle

    def __del__(self):
        handle = getattr(self, "_handle", None)
        if handle is not None and _native is not None and _native.lib is not None:
            _native.lib.lq_material_free(handle)
            self._handle = None

    def _h(self) -> c_void_p:
        if self._handle is None:
            raise InvalidArgumentError(_native.LQ_ERR_NULL, "Material was not created")
        return self._handle

    def to_json(self) -> str:
        """Canonical JSON text: the model and every parameter, defaults included."""
        out = c_void_p()
        _check(_native.lib.lq_material_to_json(self._h(), byref(out)))
        return _native.take_string(out)

    def lobes(self) -> int:
        """The kinds of lobes (``lq_material_lobes``): a bit set of :data:`LOBE_DIFFUSE`,
        :data:`LOBE_GLOSSY`, :data:`LOBE_DELTA`, :data:`LOBE_ANISOTROPIC`,
        :data:`LOBE_NON_RECIPROCAL`, :data:`LOBE_SPATIALLY_VARYING`, :data:`LOBE_SPECTRAL`."""
        out = c_uint32()
        _check(_native.lib.lq_material_lobes(self._h(), byref(out)))
        return int(out.value)

    def diffuse_reflectance(self) -> np.ndarray:
        """The diffuse / pigment albedo, linear Rec.709 (3 floats; zero without a diffuse
        lobe), ``lq_material_diffuse_reflectance``."""
        out = np.zeros(3, dtype=np.float32)
        _check(_native.lib.lq_material_diffuse_reflectance(self._h(), _ptr(out)))
        return out

    def to_dict(self) -> dict:
        """:meth:`to_json` parsed."""
        return _json.loads(self.to_json())

    @property
    def model(self) -> str:
        """The model's name."""
        return self.to_dict()["model"]

    def __repr__(self) -> str:
        return f"lacquer.Material({self.to_json()})"

    def __reduce__(self):
        return (Material, (self.to_dict(),))

    # ---- evaluation

    def _finish(self, status: int, result, strict: bool):
        if status == _native.LQ_OK:
            return result
        if status in _PER_ELEMENT and not strict:
            return result
        err = _error(status)
        if status in _PER_ELEMENT:
            err.result = result
        raise err

    def _eval_pdf(self, wi, wo, uv, duv, want_f, want_pdf, strict):
        spatial = uv is not None or duv is not None
        arrays, names, widths = [wi, wo], ["wi", "wo"], [3, 3]
        if uv is not None:
            arrays.append(uv), names.append("uv"), widths.append(2)
        if duv is not None:
            arrays.append(duv), names.append("duv"), widths.append(4)
        vecs, lead, dtype = _vectors(*arrays, names=names, widths=widths, dtype=np.float32 if spatial else None)
        wi_, wo_ = vecs[0], vecs[1]
        uv_ = vecs[2] if uv is not None else None
        duv_ = vecs[-1] if duv is not None else None
        n = wi_.shape[0]
        f = np.zeros((n, 3), dtype) if want_f else None
        p = np.zeros(n, dtype) if want_pdf else None
        lib = _native.lib
        h = self._h()
        if spatial:
            if want_f and want_pdf:
                s = lib.lq_eval_pdf_spatial(h, n, _ptr(wi_), _ptr(wo_), _ptr(uv_), _ptr(duv_), _ptr(f), _ptr(p))
            elif want_f:
                s = lib.lq_eval_spatial(h, n, _ptr(wi_), _ptr(wo_), _ptr(uv_), _ptr(duv_), _ptr(f))
            else:
                s = lib.lq_pdf_spatial(h, n, _ptr(wi_), _ptr(wo_), _ptr(uv_), _ptr(duv_), _ptr(p))
        elif dtype == np.float32:
            if want_f and want_pdf:
                s = lib.lq_eval_pdf(h, n, _ptr(wi_), _ptr(wo_), _ptr(f), _ptr(p))
            elif want_f:
                s = lib.lq_eval(h, n, _ptr(wi_), _ptr(wo_), _ptr(f))
            else:
                s = lib.lq_pdf(h, n, _ptr(wi_), _ptr(wo_), _ptr(p))
        else:
            if want_f and want_pdf:
                s = lib.lq_eval_pdf_f64(h, n, _ptr(wi_), _ptr(wo_), _ptr(f), _ptr(p))
            elif want_f:
                s = lib.lq_eval_f64(h, n, _ptr(wi_), _ptr(wo_), _ptr(f))
            else:
                s = lib.lq_pdf_f64(h, n, _ptr(wi_), _ptr(wo_), _ptr(p))
        f = f.reshape(lead + (3,)) if f is not None else None
        p = p.reshape(lead) if p is not None else None
        result = (f, p) if (want_f and want_pdf) else (f if want_f else p)
        return self._finish(s, result, strict)

    def eval(self, wi, wo, uv=None, duv=None, *, strict: bool = True) -> np.ndarray:
        """BRDF values f_r(wi, wo), shape (..., 3).

        ``uv`` (..., 2) and ``duv`` (..., 4: du/dx, dv/dx, du/dy, dv/dy) are the surface
        position and footprint for spatially varying materials; they select the float32
        path and currently do not change results (no model is spatially varying yet).
        A non-finite or zero-length direction raises InvalidDirectionError whose ``result``
        holds the output (zero there); with ``strict=False`` the output is returned instead.
        """
        return self._eval_pdf(wi, wo, uv, duv, True, False, strict)

    def pdf(self, wi, wo, uv=None, duv=None, *, strict: bool = True) -> np.ndarray:
        """Solid-angle density of :meth:`sample` choosing ``wi`` given ``wo``, shape (...)."""
        return self._eval_pdf(wi, wo, uv, duv, False, True, strict)

    def eval_pdf(self, wi, wo, uv=None, duv=None, *, strict: bool = True):
        """``(eval(wi, wo), pdf(wi, wo))`` in one library call."""
        return self._eval_pdf(wi, wo, uv, duv, True, True, strict)

    def sample(self, wo, u, uv=None, duv=None, *, strict: bool = True) -> Sample:
        """Importance-samples ``wi`` for each ``wo`` with ``u`` (..., 3) uniform in [0, 1).

        Returns a :class:`Sample` (wi, weight, pdf, flags). A failed sample (e.g. wo below
        the surface) has pdf 0 and flag LQ_SAMPLE_FAILED; it is not an error.
        """
        spatial = uv is not None or duv is not None
        arrays, names, widths = [wo, u], ["wo", "u"], [3, 3]
        if uv is not None:
            arrays.append(uv), names.append("uv"), widths.append(2)
        if duv is not None:
            arrays.append(duv), names.append("duv"), widths.append(4)
        vecs, lead, dtype = _vectors(*arrays, names=names, widths=widths, dtype=np.float32 if spatial else None)
        wo_, u_ = vecs[0], vecs[1]
        uv_ = vecs[2] if uv is not None else None
        duv_ = vecs[-1] if duv is not None else None
        n = wo_.shape[0]
        wi = np.zeros((n, 3), dtype)
        weight = np.zeros((n, 3), dtype)
        pdf = np.zeros(n, dtype)
        flags = np.zeros(n, np.uint32)
        lib = _native.lib
        if dtype == np.float32:
            s = lib.lq_sample_spatial(
                self._h(), n, _ptr(wo_), _ptr(u_), _ptr(uv_), _ptr(duv_), _ptr(wi), _ptr(weight), _ptr(pdf), _ptr(flags)
            )
        else:
            s = lib.lq_sample_f64(self._h(), n, _ptr(wo_), _ptr(u_), _ptr(wi), _ptr(weight), _ptr(pdf), _ptr(flags))
        result = Sample(wi.reshape(lead + (3,)), weight.reshape(lead + (3,)), pdf.reshape(lead), flags.reshape(lead))
        return self._finish(s, result, strict)

    # ---- lobe selection (ABI 0.7)

    def lobe_parts(self) -> list:
        """The lobe groups a lobe mask selects (``lq_material_lobe_part``): a list of
        ``(select, kinds)``: the mask bits that enable the group (:data:`LOBE_DIFFUSE`,
        :data:`LOBE_GLOSSY`, :data:`LOBE_COAT`) and what it is (:data:`LOBE_DIFFUSE`,
        :data:`LOBE_GLOSSY`, :data:`LOBE_DELTA`). ``coated_paint`` has up to three (pigment,
        glossy base lobes, coat); other models one, whose mask bits must be set together."""
        n = c_size_t(0)
        _check(_native.lib.lq_material_lobe_part_count(self._h(), byref(n)))
        out = []
        for i in range(n.value):
            sel, kinds = c_uint32(0), c_uint32(0)
            _check(_native.lib.lq_material_lobe_part(self._h(), i, byref(sel), byref(kinds)))
            out.append((sel.value, kinds.value))
        return out

    def eval_pdf_lobes(self, wi, wo, lobes: int, uv=None, duv=None, *, strict: bool = True):
        """``(f, pdf)`` restricted to the lobes of the mask ``lobes`` (float32,
        ``lq_eval_pdf_lobes``): the pdf is that of :meth:`sample_lobes` with the same mask. A
        mask with other bits, or one splitting the lobes of a model that evaluates them
        together, raises InvalidArgumentError."""
        arrays, names, widths = [wi, wo], ["wi", "wo"], [3, 3]
        if uv is not None:
            arrays.append(uv), names.append("uv"), widths.append(2)
        if duv is not None:
            arrays.append(duv), names.append("duv"), widths.append(4)
        vecs, lead, _ = _vectors(*arrays, names=names, widths=widths, dtype=np.float32)
        uv_ = vecs[2] if uv is not None else None
        duv_ = vecs[-1] if duv is not None else None
        n = vecs[0].shape[0]
        f, p = np.zeros((n, 3), np.float32), np.zeros(n, np.float32)
        s = _native.lib.lq_eval_pdf_lobes(
            self._h(), n, _ptr(vecs[0]), _ptr(vecs[1]), _ptr(uv_), _ptr(duv_), int(lobes), _ptr(f), _ptr(p)
        )
        return self._finish(s, (f.reshape(lead + (3,)), p.reshape(lead)), strict)

    def sample_lobes(self, wo, u, lobes: int, uv=None, duv=None, *, strict: bool = True) -> Sample:
        """:meth:`sample` among the lobes of the mask ``lobes`` (their selection renormalised;
        float32, ``lq_sample_lobes``)."""
        arrays, names, widths = [wo, u], ["wo", "u"], [3, 3]
        if uv is not None:
            arrays.append(uv), names.append("uv"), widths.append(2)
        if duv is not None:
            arrays.append(duv), names.append("duv"), widths.append(4)
        vecs, lead, _ = _vectors(*arrays, names=names, widths=widths, dtype=np.float32)
        uv_ = vecs[2] if uv is not None else None
        duv_ = vecs[-1] if duv is not None else None
        n = vecs[0].shape[0]
        wi, weight = np.zeros((n, 3), np.float32), np.zeros((n, 3), np.float32)
        pdf, flags = np.zeros(n, np.float32), np.zeros(n, np.uint32)
        s = _native.lib.lq_sample_lobes(
            self._h(), n, _ptr(vecs[0]), _ptr(vecs[1]), _ptr(uv_), _ptr(duv_), int(lobes),
            _ptr(wi), _ptr(weight), _ptr(pdf), _ptr(flags),
        )
        result = Sample(wi.reshape(lead + (3,)), weight.reshape(lead + (3,)), pdf.reshape(lead), flags.reshape(lead))
        return self._finish(s, result, strict)

    # ---- spectral (ABI 0.6)

    def _spectral_inputs(self, first, second, names, wavelengths, uv, duv):
        arrays, nm, widths = [first, second, wavelengths], list(names) + ["wavelengths"], [3, 3, 4]
        if uv is not None:
            arrays.append(uv), nm.append("uv"), widths.append(2)
        if duv is not None:
            arrays.append(duv), nm.append("duv"), widths.append(4)
        vecs, lead, _ = _vectors(*arrays, names=nm, widths=widths, dtype=np.float32)
        uv_ = vecs[3] if uv is not None else None
        duv_ = vecs[-1] if duv is not None else None
        return vecs[0], vecs[1], vecs[2], uv_, duv_, lead

    def eval_spectral(self, wi, wo, wavelengths, uv=None, duv=None, *, strict: bool = True) -> np.ndarray:
        """BRDF values f_r(wi, wo) at four wavelengths per element (``lq_eval_spectral``):
        ``wavelengths`` (..., 4) in nm, result (..., 4) float32, 1/sr, no cosine.

        Materials with spectral physics (:data:`LOBE_SPECTRAL`: the pearl paint's thin film,
        HTSG) are evaluated at each wavelength; every other material returns its RGB value
        upsampled (three box bands 360-490-590-830 nm that integrate back to the RGB value).
        Wavelengths outside 360-830 nm are clamped; a non-finite one raises
        InvalidElementError (``result``: zero there). ``uv`` / ``duv`` as in :meth:`eval`.
        The pdf does not depend on wavelength: use :meth:`pdf`.
        """
        wi_, wo_, lam, uv_, duv_, lead = self._spectral_inputs(wi, wo, ("wi", "wo"), wavelengths, uv, duv)
        n = wi_.shape[0]
        f = np.zeros((n, 4), np.float32)
        s = _native.lib.lq_eval_spectral(self._h(), n, _ptr(wi_), _ptr(wo_), _ptr(uv_), _ptr(duv_), _ptr(lam), _ptr(f))
        return self._finish(s, f.reshape(lead + (4,)), strict)

    def sample_spectral(self, wo, u, wavelengths, uv=None, duv=None, *, strict: bool = True) -> Sample:
        """:meth:`sample` with the weight at four wavelengths per element
        (``lq_sample_spectral``): ``wavelengths`` (..., 4) in nm; the :class:`Sample`'s
        ``weight`` is (..., 4), f_r cos(theta_i) / pdf at each wavelength; ``wi``, ``pdf`` and
        ``flags`` are those of :meth:`sample` with the same float32 inputs.
        """
        wo_, u_, lam, uv_, duv_, lead = self._spectral_inputs(wo, u, ("wo", "u"), wavelengths, uv, duv)
        n = wo_.shape[0]
        wi = np.zeros((n, 3), np.float32)
        weight = np.zeros((n, 4), np.float32)
        pdf = np.zeros(n, np.float32)
        flags = np.zeros(n, np.uint32)
        s = _native.lib.lq_sample_spectral(
            self._h(), n, _ptr(wo_), _ptr(u_), _ptr(uv_), _ptr(duv_), _ptr(lam), _ptr(wi), _ptr(weight), _ptr(pdf),
            _ptr(flags)
        )
        result = Sample(wi.reshape(lead + (3,)), weight.reshape(lead + (4,)), pdf.reshape(lead), flags.reshape(lead))
        return self._finish(s, result, strict)

    # ---- per-element paint parameters (textures; ABI 0.6)

    @staticmethod
    def _paint_params(lead, base_color, flake_density, coat_roughness):
        """The per-element parameter arrays broadcast to the elements (``lead`` shape): three
        float32 colour columns (or None) and two float32 arrays (or None)."""
        n = int(np.prod(lead, dtype=np.int64))
        cols = [None, None, None]
        if base_color is not None:
            c = np.asarray(base_color, dtype=np.float32)
            if c.ndim == 0 or c.shape[-1] != 3:
                raise _shape_error(f"`base_color` must have shape (..., 3), got {c.shape}")
            try:
                c = np.broadcast_to(c, tuple(lead) + (3,)).reshape(n, 3)
            except ValueError:
                raise _shape_error(f"`base_color` {c.shape} does not broadcast to the elements {tuple(lead)}") from None
            cols = [np.ascontiguousarray(c[:, k]) for k in range(3)]
        out = []
        for name, v in (("flake_density", flake_density), ("coat_roughness", coat_roughness)):
            if v is None:
                out.append(None)
                continue
            a = np.asarray(v, dtype=np.float32)
            try:
                out.append(np.ascontiguousarray(np.broadcast_to(a, tuple(lead)).reshape(n)))
            except ValueError:
                raise _shape_error(f"`{name}` {a.shape} does not broadcast to the elements {tuple(lead)}") from None
        return cols, out[0], out[1]

    def eval_pdf_varying(self, wi, wo, base_color=None, flake_density=None, coat_roughness=None, *,
                         strict: bool = True):
        """``(f, pdf)`` of a ``coated_paint`` whose parameters vary per element
        (``lq_eval_pdf_varying``): element i is evaluated as the material with
        ``base_color[i]`` ((..., 3), linear RGB in [0, 1]), ``flake_density[i]`` (%) and
        ``coat_roughness[i]`` (GGX alpha in [0.001, 0.5]); a parameter left None keeps the
        material's value. Each broadcasts against the directions. float32; the mean lobe (no
        sparkle). An out-of-range or non-finite parameter makes its element zero and raises
        InvalidElementError (``result`` holds the outputs; ``strict=False`` returns them).
        Another model with a parameter given: InvalidArgumentError.
        """
        (wi_, wo_), lead, _ = _vectors(wi, wo, names=["wi", "wo"], widths=[3, 3], dtype=np.float32)
        (r, g, b), d, a = self._paint_params(lead, base_color, flake_density, coat_roughness)
        n = wi_.shape[0]
        f = np.zeros((3, n), np.float32)
        pdf = np.zeros(n, np.float32)
        s = _native.lib.lq_eval_pdf_varying(
            self._h(), n, *(_ptr(np.ascontiguousarray(x[:, k])) for x in (wi_, wo_) for k in range(3)),
            _ptr(r), _ptr(g), _ptr(b), _ptr(d), _ptr(a), None, _ptr(f[0]), _ptr(f[1]), _ptr(f[2]), _ptr(pdf)
        )
        return self._finish(s, (f.T.reshape(tuple(lead) + (3,)), pdf.reshape(lead)), strict)

    def sample_varying(self, wo, u, base_color=None, flake_density=None, coat_roughness=None, *,
                       strict: bool = True) -> Sample:
        """:meth:`sample` of a ``coated_paint`` whose parameters vary per element
        (``lq_sample_varying``; parameters as :meth:`eval_pdf_varying`). An invalid element
        is a failed sample (flags ``LQ_SAMPLE_FAILED | LQ_SAMPLE_INVALID_INPUT``) and raises
        InvalidElementError unless ``strict=False``."""
        (wo_, u_), lead, _ = _vectors(wo, u, names=["wo", "u"], widths=[3, 3], dtype=np.float32)
        (r, g, b), d, a = self._paint_params(lead, base_color, flake_density, coat_roughness)
        n = wo_.shape[0]
        wi = np.zeros((3, n), np.float32)
        weight = np.zeros((3, n), np.float32)
        pdf = np.zeros(n, np.float32)
        flags = np.zeros(n, np.uint32)
        s = _native.lib.lq_sample_varying(
            self._h(), n, *(_ptr(np.ascontiguousarray(x[:, k])) for x in (wo_, u_) for k in range(3)),
            _ptr(r), _ptr(g), _ptr(b), _ptr(d), _ptr(a), None, *(_ptr(x) for x in (*wi, *weight)), _ptr(pdf),
            _ptr(flags)
        )
        result = Sample(wi.T.reshape(tuple(lead) + (3,)), weight.T.reshape(tuple(lead) + (3,)), pdf.reshape(lead),
                        flags.reshape(lead))
        return self._finish(s, result, strict)

    def check(self, level: Union[str, int] = "quick") -> CheckResult:
        """Runs the shipped checks (reciprocity, furnace, chi2, hard cases, precision)."""
        out = c_void_p()
        passed = c_bool(False)
        _check(_native.lib.lq_check_material(self._h(), _level(level), byref(out), byref(passed)))
        return CheckResult(bool(passed.value), _json.loads(_native.take_string(out)))


# --- catalogue ---------------------------------------------------------------------------


def models() -> list:
    """Every registered model: name, summary, reference, claims, params."""
    out = c_void_p()
    _check(_native.lib.lq_models_json(byref(out)))
    return _json.loads(_native.take_string(out))


def presets() -> list:
    """Every preset: name, description, material (full JSON)."""
    out = c_void_p()
    _check(_native.lib.lq_presets_json(byref(out)))
    return _json.loads(_native.take_string(out))


def set_thread_count(n: int) -> None:
    """Threads a large batch call (n >= 32768) uses: 1 = the calling thread only, 0 = every
    core (the default). Process-wide; results do not depend on it. Batch calls release the GIL."""
    if n < 0:
        raise ValueError("thread count must be >= 0")
    _native.lib.lq_set_thread_count(int(n))


def simd_level() -> str:
    """The instruction set the batch kernels use on this CPU: "avx512", "avx2" or "scalar"."""
    return _native.lib.lq_simd_level().decode()


def choose_configuration(material: Union[str, bytes, dict, "Material"], max_error: float, n: int = 0) -> dict:
    """The cheapest configuration of ``material`` whose maximum relative error of f·cos θi
    against its f64 reference stays within ``max_error`` ("model only what a scene needs",
    measured): ``{"max_error", "picked": {"name", "material", "path", "ns_per_eval", "error":
    {"max", "rms"}}, "candidates": [...]}``. ``n`` direction pairs (0: 65536). Takes 0.05–2 s."""
    m = material if isinstance(material, Material) else Material(material)
    out = c_void_p()
    _check(_native.lib.lq_choose_configuration(m._h(), float(max_error), int(n), byref(out)))
    return _json.loads(_native.take_string(out))


def check_model(name: str, level: Union[str, int] = "quick") -> CheckResult:
    """Runs every check on a registered model (defaults, check sets, random sets, extremes)."""
    out = c_void_p()
    passed = c_bool(False)
    _check(_native.lib.lq_check_model(name.encode("utf-8"), _level(level), byref(out), byref(passed)))
    return CheckResult(bool(passed.value), _json.loads(_native.take_string(out)))


def fit_node_group(material_or_preset: Union[str, bytes, dict, Material]) -> dict:
    """Fits the Blender node group ``Lacquer Coated Paint`` (its mean lobe, built from
    Principled BSDFs) to a coated_paint material.

    ``material_or_preset`` is a preset name, a material dict, material JSON text or a
    :class:`Material`. Returns ``{"inputs": {socket name: value}, "error": {"albedo_rms",
    "albedo_max", "brdf_rel_rms", "brdf_cos_rms", "snr_db", "seconds"}, "fit": {...}}``
    (colours as ``[r, g, b]`` lists). Raises :class:`InvalidMaterialError` for a material
    that is not a coated_paint, :class:`UnknownNameError` for an unknown preset.
    """
    spec = material_or_preset
    if isinstance(spec, Material):
        spec = spec.to_json()
    if isinstance(spec, dict):
        text = _json.dumps(spec)
    elif isinstance(spec, (str, bytes)):
        text = spec.decode("utf-8") if isinstance(spec, bytes) else spec
        if not text.lstrip().startswith("{"):
            text = _json.dumps({"preset": text})
    else:
        raise TypeError(
            "fit_node_group() takes a preset name, a material dict, JSON text or a Material, "
            f"not {type(spec).__name__}"
        )
    if "\0" in text:
        raise InvalidJSONError(_native.LQ_ERR_INVALID_JSON, "text contains a NUL character")
    out = c_void_p()
    _check(_native.lib.lq_fit_node_group(text.encode("utf-8"), byref(out)))
    return _json.loads(_native.take_string(out))


def _progress_callback(progress):
    def _trampoline(fraction, _user):
        try:
            return bool(progress(float(fraction))) if progress is not None else True
        except Exception:  # an exception cannot cross C frames: cancel instead
            return False

    return _native.PROGRESS_FN(_trampoline)


def _image_dict(handle) -> dict:
    w, h = _native.lib.lq_image_width(handle), _native.lib.lq_image_height(handle)

    def _array(ptr, channels):
        if not ptr:
            return None
        buf = (ctypes.c_float * (w * h * channels)).from_address(ptr)
        return np.ctypeslib.as_array(buf).reshape(h, w, channels).copy()

    return {
        "rgba": _array(_native.lib.lq_image_rgba(handle), 4),
        "albedo": _array(_native.lib.lq_image_albedo(handle), 3),
        "normal": _array(_native.lib.lq_image_normal(handle), 3),
        "diffuse_color": _array(_native.lib.lq_image_diffuse_color(handle), 3),
        "glossy_color": _array(_native.lib.lq_image_glossy_color(handle), 3),
    }


def render(job, progress=None) -> dict:
    """Renders a job with the reference renderer (docs/render.md lists the keys).

    ``job`` is a dict or a JSON string (``{"preset": "gold_flake_8", "width": 256, ...}``);
    ``progress(fraction) -> bool`` is called on this thread; returning False cancels
    (:class:`CancelledError`). Returns ``{"rgba": (h, w, 4) float32, "albedo": (h, w, 3) or
    None, "normal": (h, w, 3) or None, "diffuse_color", "glossy_color": (h, w, 3) with
    ``"lobe_aovs": True`` in the job, else None}``, rows top first, linear Rec.709.
    """
    text = job if isinstance(job, str) else _json.dumps(job)
    callback = _progress_callback(progress)
    handle = ctypes.c_void_p()
    _check(_native.lib.lq_render(text.encode(), callback, None, ctypes.byref(handle)))
    try:
        return _image_dict(handle)
    finally:
        _native.lib.lq_image_free(handle)


class RenderSession:
    """A render job refined in rounds, for progressive display (``lq_render_session_*``).

    ``RenderSession(job)`` parses the job and builds its scene (:class:`InvalidArgumentError`
    if invalid); :meth:`advance` adds samples per pixel; :meth:`image` is the mean so far (the
    dict :func:`render` returns). Any split of the job's ``spp`` into rounds gives
    :func:`render`'s image bit for bit. Use from one thread at a time; the GIL is released
    while a round renders.
    """

    def __init__(self, job):
        text = job if isinstance(job, str) else _json.dumps(job)
        handle = ctypes.c_void_p()
        _check(_native.lib.lq_render_session_new(text.encode(), ctypes.byref(handle)))
        self._handle = handle

    def _h(self):
        if not self._handle:
            raise ValueError("the render session is closed")
        return self._handle

    @property
    def samples(self) -> int:
        """Samples per pixel done so far."""
        return int(_native.lib.lq_render_session_samples(self._h()))

    @property
    def target(self) -> int:
        """The job's samples per pixel (the render is complete when ``samples == target``)."""
        return int(_native.lib.lq_render_session_target(self._h()))

    def advance(self, samples: int, progress=None) -> int:
        """Adds up to ``samples`` samples per pixel (never beyond the target) and returns how
        many. ``progress(fraction of this round) -> bool`` runs on this thread about ten times a
        second; returning False cancels the round (:class:`CancelledError`), which leaves the
        session as it was."""
        added = ctypes.c_uint32(0)
        callback = _progress_callback(progress)
        _check(_native.lib.lq_render_session_advance(self._h(), int(samples), callback, None, ctypes.byref(added)))
        return int(added.value)

    def image(self) -> dict:
        """The image so far: ``{"rgba", "albedo", "normal"}`` as :func:`render` returns."""
        handle = ctypes.c_void_p()
        _check(_native.lib.lq_render_session_image(self._h(), ctypes.byref(handle)))
        try:
            return _image_dict(handle)
        finally:
            _native.lib.lq_image_free(handle)

    def close(self) -> None:
        """Frees the session (also done when it is garbage-collected)."""
        if self._handle:
            _native.lib.lq_render_session_free(self._handle)
            self._handle = None

    def __del__(self):
        try:
            self.close()
        except Exception:  # noqa: BLE001  (interpreter shutdown)
            pass
