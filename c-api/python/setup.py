"""Builds a platform wheel of `lacquer` that carries liblacquer.so.

The shared library is taken from $LACQUER_BUILD_LIBRARY, else from
$CARGO_TARGET_DIR/release (default: <repo>/target/release), so build it first:
    cargo build --release -p lacquer-capi
    python -m build --wheel c-api/python
The wheel is tagged py3-none-<platform>: it contains no Python extension, only a C library
loaded with ctypes, so it works with any CPython 3 on that platform.
"""

import os
import shutil
import sys
from pathlib import Path

from setuptools import setup
from setuptools.command.bdist_wheel import bdist_wheel
from setuptools.command.build_py import build_py

HERE = Path(__file__).resolve().parent
LIB_NAME = {"darwin": "liblacquer.dylib", "win32": "lacquer.dll"}.get(sys.platform, "liblacquer.so")


def find_library() -> Path:
    explicit = os.environ.get("LACQUER_BUILD_LIBRARY")
    if explicit:
        return Path(explicit)
    target = Path(os.environ.get("CARGO_TARGET_DIR", HERE.parent.parent / "target"))
    return target / "release" / LIB_NAME


class BuildPyWithLibrary(build_py):
    """Copies the shared library into the package folder of the build."""

    def run(self):
        super().run()
        lib = find_library()
        if not lib.is_file():
            raise SystemExit(
                f"lacquer: {lib} not found. Build it with `cargo build --release -p lacquer-capi` "
                "or point LACQUER_BUILD_LIBRARY at it."
            )
        dest = Path(self.build_lib) / "lacquer" / LIB_NAME
        dest.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(lib, dest)


class PlatformWheel(bdist_wheel):
    """A wheel for one platform (it carries a native library) but any Python 3."""

    def finalize_options(self):
        super().finalize_options()
        self.root_is_pure = False

    def get_tag(self):
        _, _, plat = super().get_tag()
        return "py3", "none", plat


setup(cmdclass={"build_py": BuildPyWithLibrary, "bdist_wheel": PlatformWheel})
