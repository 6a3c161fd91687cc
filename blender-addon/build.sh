#!/usr/bin/env bash
# Builds the installable Blender extension zip: dist/lacquer-<version>-<platform>.zip (repository
# root), named as `blender --command extension build --split-platforms` names a platform's zip
# (e.g. lacquer-0.1.0-linux_x64.zip).
#
#   bash blender-addon/build.sh            # prints the zip's path on stdout
#   bash blender-addon/build.sh --out DIR  # another output folder
#
# The asset library (extension/assets/: one material per preset, catalogues, thumbnails
# rendered by `lacquer render`) needs headless bpy: with LACQUER_BLENDER_VENV (a venv from
# scripts/blender-env.sh; blender-addon/test.sh sets it) or LACQUER_ASSETS=1 (makes that venv)
# the zip includes it; without, the zip has no asset library (the preset menus still work).
# Thumbnails are cached in $CARGO_TARGET_DIR/lacquer-thumbs.
#
# Other platforms: run this script natively there (Git Bash or WSL-less MSYS2 on Windows,
# bash on macOS) with Rust and python3: cargo builds that platform's library
# (lacquer.dll / liblacquer.dylib), the wheel gets the platform tag and the manifest the
# matching `platforms` entry (windows-x64, macos-arm64, macos-x64, linux-arm64).
#
# Steps: release build of liblacquer (cargo, honours CARGO_TARGET_DIR), the `lacquer` Python
# wheel built from c-api/python exactly as c-api/test.sh does (pinned build + setuptools in
# .venv-build), then the extension folder blender-addon/extension/ staged with the wheel in
# wheels/ and its blender_manifest.toml pointing at it, zipped in the layout
# `blender --command extension build` produces (manifest at the zip's root).
# Works from a fresh clone with a Rust toolchain and python3; no Blender is needed.
# Progress goes to stderr; stdout is only the zip's path.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
root="$(cd "$here/.." && pwd)"
out="$root/dist"
while [ $# -gt 0 ]; do
  case "$1" in
    --out) out="$2"; shift 2 ;;
    *) echo "build.sh: unknown option $1" >&2; exit 2 ;;
  esac
done
log() { printf '%s\n' "$*" >&2; }
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$root/target}"

log "=== cargo build --release -p lacquer-capi"
# With the CLI, to share its build (same dependency features; docs/reliability.md).
(cd "$root" && cargo build --release -q -p lacquer-capi -p lacquer-cli) >&2
case "$(uname -s)" in
  Darwin) libname=liblacquer.dylib ;;
  MINGW*|MSYS*|CYGWIN*) libname=lacquer.dll ;;
  *) libname=liblacquer.so ;;
esac
lib="$CARGO_TARGET_DIR/release/$libname"
[ -f "$lib" ] || { log "build.sh: $lib not found"; exit 1; }

venv="${LACQUER_BUILD_VENV:-$root/.venv-build}"
pins="build==1.6.1 setuptools==84.2.1"
if ! [ -f "$venv/.lacquer-pins" ] || [ "$(cat "$venv/.lacquer-pins")" != "$pins" ]; then
  log "=== build venv $venv ($pins)"
  if ! python3 -c 'import venv, ensurepip' >/dev/null 2>&1; then
    if [ "$(id -u)" = 0 ]; then sudo_=""; else sudo_="sudo"; fi
    $sudo_ apt-get update -qq >&2 && DEBIAN_FRONTEND=noninteractive $sudo_ apt-get install -y -qq python3-venv >&2
  fi
  python3 -m venv "$venv" >&2
  # shellcheck disable=SC2086
  "$venv/bin/python" -m pip install -q --disable-pip-version-check $pins >&2
  echo "$pins" >"$venv/.lacquer-pins"
fi

work="$(mktemp -d "${TMPDIR:-/tmp}/lacquer-ext-build.XXXXXX")"
trap 'rm -rf "$work"' EXIT
# The release profile keeps debug info (for profiling); the wheel does not need it.
cp "$lib" "$work/$libname"
if [ "$libname" = liblacquer.so ] && command -v strip >/dev/null 2>&1; then strip --strip-debug "$work/$libname"; fi
lib="$work/$libname"
log "=== lacquer wheel"
cp -r "$root/c-api/python" "$work/pysrc"
rm -rf "$work/pysrc/tests" "$work/pysrc/build" "$work/pysrc/dist" "$work/pysrc"/*.egg-info
LACQUER_BUILD_LIBRARY="$lib" "$venv/bin/python" -m build --wheel --no-isolation --outdir "$work/wheels" "$work/pysrc" >&2
wheel="$(cd "$work/wheels" && ls lacquer-*.whl)"
[ "$(printf '%s\n' "$wheel" | wc -l)" = 1 ] || { log "build.sh: expected one wheel, got: $wheel"; exit 1; }

zip_extension() {  # zip_extension OUT_DIR [ASSETS_DIR]
"$venv/bin/python" - "$here/extension" "$work/wheels/$wheel" "$@" <<'PY'
import pathlib, re, shutil, sys, zipfile

src, wheel, out = (pathlib.Path(a) for a in sys.argv[1:4])
assets = pathlib.Path(sys.argv[4]) if len(sys.argv) > 4 else None
# lacquer-<version>-py3-none-<platform>.whl
_, version, _, _, platform = wheel.name[: -len(".whl")].split("-")
blender_platform = {"linux_x86_64": "linux-x64", "linux_aarch64": "linux-arm64", "win_amd64": "windows-x64",
                    "macosx_11_0_arm64": "macos-arm64", "macosx_10_12_x86_64": "macos-x64"}.get(platform)
if blender_platform is None and platform.startswith("manylinux"):
    blender_platform = "linux-x64" if platform.endswith("x86_64") else "linux-arm64"
if blender_platform is None:
    sys.exit(f"build.sh: unknown wheel platform {platform}")
manifest = (src / "blender_manifest.toml").read_text()
for key, value in (("version", f'"{version}"'), ("platforms", f'["{blender_platform}"]'),
                   ("wheels", f'["./wheels/{wheel.name}"]')):
    manifest, n = re.subn(rf"(?m)^{key} = .*$", f"{key} = {value}", manifest)
    assert n == 1, key
out.mkdir(parents=True, exist_ok=True)
zip_path = out / f"lacquer-{version}-{blender_platform.replace('-', '_')}.zip"
skip = re.compile(r"(__pycache__|\.pyc$|^wheels/)")
with zipfile.ZipFile(zip_path, "w", zipfile.ZIP_DEFLATED) as z:
    z.writestr("blender_manifest.toml", manifest)
    for f in sorted(src.rglob("*")):
        rel = f.relative_to(src).as_posix()
        if f.is_file() and rel != "blender_manifest.toml" and not skip.search(rel):
            z.write(f, rel)
    z.write(wheel, f"wheels/{wheel.name}")
    if assets is not None:
        for f in sorted(assets.rglob("*")):
            if f.is_file():
                z.write(f, "assets/" + f.relative_to(assets).as_posix())
print(zip_path.resolve())
PY
}

log "=== stage and zip the extension"
if [ -n "${LACQUER_BLENDER_VENV:-}" ] || [ "${LACQUER_ASSETS:-0}" = 1 ]; then
  bpy_venv="$(bash "$root/scripts/blender-env.sh")"
  first="$(zip_extension "$work/first")"
  log "=== asset library (bpy $("$bpy_venv/bin/python" -c 'import bpy; print(bpy.app.version_string)' 2>/dev/null))"
  mkdir -p "$work/assets" "$work/user"
  cli="$CARGO_TARGET_DIR/release/lacquer"
  [ -x "$cli" ] || cli="$CARGO_TARGET_DIR/release/lacquer.exe"
  BLENDER_USER_RESOURCES="$work/user" "$bpy_venv/bin/python" "$here/scripts/build_assets.py" --zip "$first" \
    --lacquer-cli "$cli" --out "$work/assets" --thumbs "$CARGO_TARGET_DIR/lacquer-thumbs" >&2
  zip_extension "$out" "$work/assets"
else
  log "(no asset library: set LACQUER_BLENDER_VENV or LACQUER_ASSETS=1)"
  zip_extension "$out"
fi
