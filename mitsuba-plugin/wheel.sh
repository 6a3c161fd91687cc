#!/usr/bin/env bash
# Builds the wheel `lacquer-mitsuba` into <repo>/dist/ (one command):
#   bash mitsuba-plugin/wheel.sh [--no-llvm]
# = build.sh (venv, liblacquer.a, the plugins, plugins/build_info.json) + `pip wheel` of
# mitsuba-plugin/python. Install it with `pip install dist/lacquer_mitsuba-*.whl` next to
# mitsuba==3.9.1 (a dependency of the wheel); then `import lacquer_mitsuba;
# lacquer_mitsuba.register()` (docs/mitsuba.md).
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
repo="$(cd "$here/.." && pwd)"
venv="${LACQUER_VENV:-$repo/.venv-mitsuba}"
out="${LACQUER_WHEEL_DIR:-$repo/dist}"
bash "$here/build.sh" "$@"
printf '\n==== mitsuba-plugin: wheel into %s\n' "$out"
mkdir -p "$out"
rm -rf "$here/python/build" "$here/python/lacquer_mitsuba.egg-info"
"$venv/bin/python" -m pip wheel -q --disable-pip-version-check --no-deps -w "$out" "$here/python"
rm -rf "$here/python/build" "$here/python/lacquer_mitsuba.egg-info"
ls -1 "$out"/lacquer_mitsuba-*.whl
