#!/usr/bin/env bash
# Tests of the Blender extension (what scripts/test.sh and so CI run):
#   1. build the extension zip (blender-addon/build.sh: liblacquer release build, the lacquer
#      wheel, the zip in dist/)
#   2. the bpy venv (scripts/blender-env.sh: bpy 4.5 LTS from PyPI, numpy 1.26) and the tests
#      venv (scripts/python-env.sh: numpy 2, OpenImageIO 3, pytest; or $LACQUER_VENV)
#   3. pytest blender-addon/tests: install the zip into a temporary BLENDER_USER_RESOURCES,
#      enable, assign presets, render 128² with Cycles and LACQUER, compare the EXRs with
#      OpenImageIO (per-region means, lights, sparkle vs flake density, a farm render of the
#      saved .blend without the extension, clean unregistration).
# Runs on bpy 4.5.15 (LTS, .venv-blender) and 5.0.1 (.venv-blender-5.0.1); LACQUER_BPY_VERSIONS
# picks others ("4.5.15" alone skips 5.0).
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
root="$(cd "$here/.." && pwd)"
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$root/target}"

echo "=== build the extension zip (with the asset library, built by bpy 4.5)"
LACQUER_BLENDER_VENV="$root/.venv-blender" LACQUER_BPY_VERSION=4.5.15 bash "$root/scripts/blender-env.sh" >/dev/null
zip="$(LACQUER_BLENDER_VENV="$root/.venv-blender" LACQUER_BPY_VERSION=4.5.15 bash "$here/build.sh")"
echo "$zip"
echo "=== tests venv"
tests_venv="${LACQUER_VENV:-$(bash "$root/scripts/python-env.sh")}"
cd "$root"
# -rs lists every skip; the lacquer_no_skip plugin (scripts/pytest/) makes a skip (no bpy, no
# zip, EEVEE unable to render) a failure; LACQUER_ALLOW_SKIP=1 allows skips outside CI.
export PYTHONPATH="$root/scripts/pytest${PYTHONPATH:+:$PYTHONPATH}"
status=0
for version in ${LACQUER_BPY_VERSIONS:-4.5.15 5.0.1}; do
  echo "=== bpy $version venv"
  venv_dir="$root/.venv-blender"
  case "$version" in 4.5.*) ;; *) venv_dir="$root/.venv-blender-$version" ;; esac
  bpy_venv="$(LACQUER_BPY_VERSION="$version" LACQUER_BLENDER_VENV="$venv_dir" bash "$root/scripts/blender-env.sh")"
  "$bpy_venv/bin/python" -c 'import bpy; print("bpy", bpy.app.version_string)'
  echo "=== pytest blender-addon/tests (bpy $version)"
  LACQUER_BLENDER_ZIP="$zip" LACQUER_BLENDER_VENV="$bpy_venv" \
    "$tests_venv/bin/python" -m pytest -q -s -rs -p lacquer_no_skip -p no:cacheprovider blender-addon/tests || status=1
done
exit $status
