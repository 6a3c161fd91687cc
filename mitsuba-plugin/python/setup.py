"""Builds the `lacquer-mitsuba` wheel: `lacquer_mitsuba` with the compiled plugins of
mitsuba-plugin/build.sh. Use `bash mitsuba-plugin/wheel.sh` (it builds the plugins first and
writes dist/lacquer_mitsuba-*.whl). The wheel is tagged py3-none-<platform>: the plugins link
libmitsuba (from the mitsuba wheel), not the Python C API."""

from pathlib import Path

from setuptools import setup
from setuptools.command.bdist_wheel import bdist_wheel

HERE = Path(__file__).resolve().parent
for need in ("lacquer.so", "lacquer_path.so", "build_info.json"):
    if not (HERE / "lacquer_mitsuba" / "plugins" / need).is_file():
        raise SystemExit(f"lacquer-mitsuba: plugins/{need} is missing: run mitsuba-plugin/build.sh first "
                         "(or mitsuba-plugin/wheel.sh, which does)")


class PlatformWheel(bdist_wheel):
    """A wheel for one platform (it carries native plugins) but any Python 3."""

    def finalize_options(self):
        super().finalize_options()
        self.root_is_pure = False

    def get_tag(self):
        _, _, plat = super().get_tag()
        return "py3", "none", plat


setup(cmdclass={"bdist_wheel": PlatformWheel})
