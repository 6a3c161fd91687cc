#!/usr/bin/env bash
# Builds the plugins with CMake (mitsuba-plugin/CMakeLists.txt) against the venv's mitsuba
# wheel and the liblacquer.a build.sh uses, then checks that the CMake-built lacquer.so loads
# from Mitsuba's file resolver without register() (the working directory is searched first) and
# evaluates exactly as build.sh's plugin. Not part of CI (compiling the plugin twice costs about
# two minutes on 2 cores); run it after changing CMakeLists.txt:
#   bash mitsuba-plugin/cmake_check.sh
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
repo="$(dirname "$here")"
venv="${LACQUER_VENV:-$repo/.venv-mitsuba}"
bash "$here/build.sh" >/dev/null
py="$venv/bin/python"
target="${CARGO_TARGET_DIR:-$repo/target}"
command -v cmake >/dev/null || { apt-get update -qq && apt-get install -y -qq cmake; }
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
start=$(date +%s)
cmake -S "$here" -B "$work/build" -DPython3_EXECUTABLE="$py" \
      -DLACQUER_LIBRARY="$target/release/liblacquer.a" >/dev/null
cmake --build "$work/build" -j2 >/dev/null
echo "cmake build: $(( $(date +%s) - start )) s"
mkdir -p "$work/run"
ln -s "$work/build/plugins" "$work/run/plugins"
cd "$work/run"
"$py" - "$here/python" <<'PYEOF'
import os, subprocess, sys
import mitsuba as mi
mi.set_variant("scalar_rgb")
# The CMake-built plugin, found through the working directory's plugins/ (no register()).
bsdf = mi.load_dict({"type": "lacquer", "preset": "pearl_blue"})
ctx, si = mi.BSDFContext(), mi.SurfaceInteraction3f()
si.wi = mi.Vector3f(0.3, 0.1, 0.9487)
wo = mi.Vector3f(0.5, 0.2, 0.8426)
a = list(bsdf.eval(ctx, si, wo))
# build.sh's plugin in a fresh process.
code = ("import sys, mitsuba as mi; mi.set_variant('scalar_rgb'); sys.path.insert(0, sys.argv[1]); "
        "import lacquer_mitsuba; lacquer_mitsuba.register(fallback=False); "
        "b = mi.load_dict({'type': 'lacquer', 'preset': 'pearl_blue'}); "
        "si = mi.SurfaceInteraction3f(); si.wi = mi.Vector3f(0.3, 0.1, 0.9487); "
        "print(list(b.eval(mi.BSDFContext(), si, mi.Vector3f(0.5, 0.2, 0.8426))))")
b = eval(subprocess.run([sys.executable, "-c", code, sys.argv[1]], cwd="/", capture_output=True, text=True,
                        check=True).stdout)
assert a == b, (a, b)
print("cmake plugin == build.sh plugin:", a)
PYEOF
