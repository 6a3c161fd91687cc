"""Loading liblacquer and declaring every C function's argtypes and restype.

Search order: $LACQUER_LIBRARY (a path; nothing else is tried when it is set), then the
package folder (where the wheel puts the library), then the system loader
(`liblacquer.so.0`, then ctypes.util.find_library("lacquer")). The ABI version is checked
before anything else is used.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import sys
from ctypes import CFUNCTYPE, POINTER, c_bool, c_char_p, c_double, c_float, c_int32, c_size_t, c_uint8, c_uint32, c_void_p
from pathlib import Path

#: The ABI this package was written for: major must match, library minor must be >= this.
ABI_MAJOR = 0
ABI_MINOR = 8

_LIB_FILES = {"darwin": ["liblacquer.dylib"], "win32": ["lacquer.dll"]}.get(
    sys.platform, ["liblacquer.so", "liblacquer.so.0"]
)


def _candidates() -> list[str]:
    env = os.environ.get("LACQUER_LIBRARY")
    if env:
        return [env]
    here = Path(__file__).resolve().parent
    found = [str(here / name) for name in _LIB_FILES if (here / name).is_file()]
    found += [str(p) for p in sorted(here.glob("liblacquer.so.*"))]
    found.append("liblacquer.so.0" if sys.platform.startswith("linux") else _LIB_FILES[0])
    system = ctypes.util.find_library("lacquer")
    if system:
        found.append(system)
    return found


def _load() -> tuple[ctypes.CDLL, str]:
    errors = []
    for path in _candidates():
        try:
            return ctypes.CDLL(path), path
        except OSError as e:
            errors.append(f"{path}: {e}")
    raise ImportError(
        "lacquer: cannot load liblacquer (set LACQUER_LIBRARY to its path). Tried:\n  "
        + "\n  ".join(errors)
    )


lib, library_path = _load()

F32 = POINTER(c_float)
F64 = POINTER(c_double)
U32 = POINTER(c_uint32)
_STR_OUT = POINTER(c_void_p)  # char ** (kept as void* so we can free the exact pointer)

# bool (*)(float progress, void *user): return False to cancel a render.
PROGRESS_FN = CFUNCTYPE(c_bool, c_float, c_void_p)

_SIGNATURES = {
    "lq_abi_version": (c_uint32, []),
    "lq_version": (c_char_p, []),
    "lq_set_thread_count": (None, [c_uint32]),
    "lq_simd_level": (c_char_p, []),
    "lq_last_error": (c_char_p, []),
    "lq_status_name": (c_char_p, [c_int32]),
    "lq_string_free": (None, [c_void_p]),
    "lq_material_from_json": (c_int32, [c_char_p, POINTER(c_void_p)]),
    "lq_material_from_preset": (c_int32, [c_char_p, POINTER(c_void_p)]),
    "lq_material_free": (None, [c_void_p]),
    "lq_material_to_json": (c_int32, [c_void_p, _STR_OUT]),
    "lq_material_lobes": (c_int32, [c_void_p, U32]),
    "lq_material_diffuse_reflectance": (c_int32, [c_void_p, F32]),
    "lq_eval": (c_int32, [c_void_p, c_size_t, F32, F32, F32]),
    "lq_pdf": (c_int32, [c_void_p, c_size_t, F32, F32, F32]),
    "lq_eval_pdf": (c_int32, [c_void_p, c_size_t, F32, F32, F32, F32]),
    "lq_sample": (c_int32, [c_void_p, c_size_t, F32, F32, F32, F32, F32]),
    "lq_eval_f64": (c_int32, [c_void_p, c_size_t, F64, F64, F64]),
    "lq_pdf_f64": (c_int32, [c_void_p, c_size_t, F64, F64, F64]),
    "lq_eval_pdf_f64": (c_int32, [c_void_p, c_size_t, F64, F64, F64, F64]),
    "lq_sample_f64": (c_int32, [c_void_p, c_size_t, F64, F64, F64, F64, F64, U32]),
    "lq_eval_spatial": (c_int32, [c_void_p, c_size_t, F32, F32, F32, F32, F32]),
    "lq_pdf_spatial": (c_int32, [c_void_p, c_size_t, F32, F32, F32, F32, F32]),
    "lq_eval_pdf_spatial": (c_int32, [c_void_p, c_size_t, F32, F32, F32, F32, F32, F32]),
    "lq_sample_spatial": (c_int32, [c_void_p, c_size_t, F32, F32, F32, F32, F32, F32, F32, U32]),
    "lq_eval_spectral": (c_int32, [c_void_p, c_size_t, F32, F32, F32, F32, F32, F32]),
    "lq_sample_spectral": (c_int32, [c_void_p, c_size_t, F32, F32, F32, F32, F32, F32, F32, F32, U32]),
    "lq_eval_pdf_varying": (c_int32, [c_void_p, c_size_t] + [F32] * 11 + [POINTER(c_uint8)] + [F32] * 4),
    "lq_sample_varying": (c_int32, [c_void_p, c_size_t] + [F32] * 11 + [POINTER(c_uint8)] + [F32] * 7 + [U32]),
    "lq_eval_one": (c_int32, [c_void_p, F32, F32, F32]),
    "lq_pdf_one": (c_int32, [c_void_p, F32, F32, F32]),
    "lq_eval_pdf_one": (c_int32, [c_void_p, F32, F32, F32, F32]),
    "lq_sample_one": (c_int32, [c_void_p, F32, F32, F32, F32, F32, U32]),
    "lq_models_json": (c_int32, [_STR_OUT]),
    "lq_presets_json": (c_int32, [_STR_OUT]),
    "lq_check_material": (c_int32, [c_void_p, c_int32, _STR_OUT, POINTER(c_bool)]),
    "lq_check_model": (c_int32, [c_char_p, c_int32, _STR_OUT, POINTER(c_bool)]),
    "lq_fit_node_group": (c_int32, [c_char_p, _STR_OUT]),
    "lq_choose_configuration": (c_int32, [c_void_p, c_double, c_size_t, _STR_OUT]),
    "lq_render": (c_int32, [c_char_p, PROGRESS_FN, c_void_p, POINTER(c_void_p)]),
    "lq_image_width": (c_uint32, [c_void_p]),
    "lq_image_height": (c_uint32, [c_void_p]),
    "lq_image_rgba": (c_void_p, [c_void_p]),
    "lq_image_albedo": (c_void_p, [c_void_p]),
    "lq_image_normal": (c_void_p, [c_void_p]),
    "lq_image_diffuse_color": (c_void_p, [c_void_p]),
    "lq_image_glossy_color": (c_void_p, [c_void_p]),
    "lq_image_free": (None, [c_void_p]),
    "lq_render_session_new": (c_int32, [c_char_p, POINTER(c_void_p)]),
    "lq_render_session_advance": (c_int32, [c_void_p, c_uint32, PROGRESS_FN, c_void_p, POINTER(c_uint32)]),
    "lq_render_session_samples": (c_uint32, [c_void_p]),
    "lq_render_session_target": (c_uint32, [c_void_p]),
    "lq_render_session_image": (c_int32, [c_void_p, POINTER(c_void_p)]),
    "lq_render_session_free": (None, [c_void_p]),
    # Lobe selection (ABI 0.7).
    "lq_material_lobe_part_count": (c_int32, [c_void_p, POINTER(c_size_t)]),
    "lq_material_lobe_part": (c_int32, [c_void_p, c_size_t, U32, U32]),
    "lq_eval_pdf_lobes": (c_int32, [c_void_p, c_size_t, F32, F32, F32, F32, c_uint32, F32, F32]),
    "lq_sample_lobes": (c_int32, [c_void_p, c_size_t, F32, F32, F32, F32, c_uint32, F32, F32, F32, U32]),
}

for _name, (_restype, _argtypes) in _SIGNATURES.items():
    try:
        _fn = getattr(lib, _name)
    except AttributeError as e:  # an older library than this package
        raise ImportError(f"lacquer: {library_path} lacks {_name}: {e}") from None
    _fn.restype = _restype
    _fn.argtypes = _argtypes

abi_version = int(lib.lq_abi_version())
if abi_version >> 16 != ABI_MAJOR or abi_version & 0xFFFF < ABI_MINOR:
    raise ImportError(
        f"lacquer: {library_path} has ABI {abi_version >> 16}.{abi_version & 0xFFFF}, "
        f"this package needs {ABI_MAJOR}.{ABI_MINOR} or a later {ABI_MAJOR}.x"
    )

# Status codes (lacquer.h, lq_status).
LQ_OK = 0
LQ_ERR_NULL = 1
LQ_ERR_INVALID_JSON = 2
LQ_ERR_INVALID_MATERIAL = 3
LQ_ERR_UNKNOWN_NAME = 4
LQ_ERR_INVALID_ARGUMENT = 5
LQ_ERR_INVALID_DIRECTION = 6
LQ_ERR_INVALID_ELEMENT = 7
LQ_ERR_PANIC = 8
LQ_ERR_CANCELLED = 9

# Sample flags and check levels.
LQ_SAMPLE_DELTA = 1
LQ_SAMPLE_FAILED = 2
LQ_SAMPLE_INVALID_INPUT = 4
LQ_CHECK_QUICK = 0
LQ_CHECK_STANDARD = 1


def take_string(ptr: c_void_p) -> str:
    """Copies a library-allocated string and frees it."""
    if not ptr.value:
        return ""
    try:
        return ctypes.string_at(ptr.value).decode("utf-8")
    finally:
        lib.lq_string_free(ptr)
