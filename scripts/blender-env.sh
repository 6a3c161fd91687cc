#!/usr/bin/env bash
# Creates (idempotently) the Python environment with Blender as a module (bpy from PyPI) that
# the Blender extension's tests and README image use, and prints its path.
#
#   bpy_venv="$(bash scripts/blender-env.sh)" && "$bpy_venv/bin/python" -c 'import bpy'
#
# The venv lives in .venv-blender at the repository root (override: LACQUER_BLENDER_VENV).
# bpy 4.5 (LTS) and 5.0 require numpy < 2, so this venv pins numpy 1.26.4; it is separate from
# .venv-tests (scripts/python-env.sh: numpy 2, OpenImageIO 3), which the comparisons run in.
# LACQUER_BPY_VERSION selects another bpy (e.g. 5.0.1, with LACQUER_BLENDER_VENV elsewhere).
# On a fresh Debian machine it installs what headless bpy needs with apt-get (python3-venv,
# and the X/GL client libraries the bpy wheel links against even when rendering headless).
# All progress goes to stderr; stdout is only the venv path.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
venv="${LACQUER_BLENDER_VENV:-$root/.venv-blender}"
bpy_version="${LACQUER_BPY_VERSION:-4.5.15}"
pins=("bpy==$bpy_version" "numpy==1.26.4")
stamp="$venv/.lacquer-pins"

log() { printf '%s\n' "$*" >&2; }

apt_install() {
  log "installing with apt-get: $*"
  if [ "$(id -u)" = 0 ]; then sudo_=""; else sudo_="sudo"; fi
  $sudo_ apt-get update -qq >&2
  DEBIAN_FRONTEND=noninteractive $sudo_ apt-get install -y -qq "$@" >&2
}

if [ -x "$venv/bin/python" ] && [ -f "$stamp" ] && [ "$(cat "$stamp")" = "${pins[*]}" ] &&
  "$venv/bin/python" -c 'import bpy' >/dev/null 2>&1; then
  echo "$venv"
  exit 0
fi

command -v python3 >/dev/null 2>&1 || apt_install python3
if ! python3 -c 'import venv, ensurepip' >/dev/null 2>&1; then
  ver="$(python3 -c 'import sys; print(f"{sys.version_info[0]}.{sys.version_info[1]}")')"
  apt_install python3-venv || apt_install "python${ver}-venv"
fi
pyver="$(python3 -c 'import sys; print(f"{sys.version_info[0]}.{sys.version_info[1]}")')"
case "$bpy_version" in
  4.5.*|5.0.*) [ "$pyver" = 3.11 ] || log "warning: bpy $bpy_version wheels are for Python 3.11, python3 is $pyver" ;;
esac

if [ ! -x "$venv/bin/python" ]; then
  log "creating $venv"
  python3 -m venv "$venv" >&2
fi
log "installing ${pins[*]} (bpy is a large download)"
"$venv/bin/python" -m pip install -q --disable-pip-version-check "${pins[@]}" >&2

# bpy links against a few system libraries (X11 client, xkbcommon, GL loader, SM/ICE) even
# headless; install the ones a minimal Debian lacks.
if ! err="$("$venv/bin/python" -c 'import bpy' 2>&1)"; then
  log "import bpy failed: $err"
  apt_install libx11-6 libxrender1 libxxf86vm1 libxfixes3 libxi6 libxkbcommon0 libsm6 libice6 libgl1 libegl1 libglx0 libgomp1 libxext6
  "$venv/bin/python" -c 'import bpy' >&2
fi
echo "${pins[*]}" >"$stamp"
echo "$venv"
