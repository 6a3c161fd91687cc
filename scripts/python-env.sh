#!/usr/bin/env bash
# Creates (idempotently) the Python environment the image tests use, and prints its path.
#
#   venv="$(bash scripts/python-env.sh)" && "$venv/bin/python" -m pytest tests/
#
# The venv lives in .venv-tests at the repository root (override: LACQUER_TEST_VENV) with
# pinned numpy, pytest, OpenImageIO (the PyPI wheel bundles the library; no system OIIO) and
# Mitsuba 3.9.1 (independent BSDFs for the fitting and plugin tests).
# On a fresh Debian machine it installs python3-venv with apt-get when `python3 -m venv`
# cannot work. All progress goes to stderr; stdout is only the venv path.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
venv="${LACQUER_TEST_VENV:-$root/.venv-tests}"
pins=(numpy==2.4.6 pytest==9.2.0 OpenImageIO==3.2.2.0 mitsuba==3.9.1)
stamp="$venv/.lacquer-pins"

log() { printf '%s\n' "$*" >&2; }

if ! command -v python3 >/dev/null 2>&1; then
  log "python3 not found: installing it with apt-get"
  apt-get update -qq >&2 && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq python3 >&2
fi

if [ -x "$venv/bin/python" ] && [ -f "$stamp" ] && [ "$(cat "$stamp")" = "${pins[*]}" ] &&
  "$venv/bin/python" -c 'import numpy, pytest, OpenImageIO, mitsuba' >/dev/null 2>&1; then
  echo "$venv"
  exit 0
fi

if ! python3 -c 'import venv, ensurepip' >/dev/null 2>&1; then
  log "python3 -m venv needs ensurepip: installing python3-venv with apt-get"
  ver="$(python3 -c 'import sys; print(f"{sys.version_info[0]}.{sys.version_info[1]}")')"
  apt-get update -qq >&2
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq python3-venv >&2 ||
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "python${ver}-venv" >&2
fi

if [ ! -x "$venv/bin/python" ]; then
  log "creating $venv"
  python3 -m venv "$venv" >&2
fi
log "installing ${pins[*]}"
"$venv/bin/python" -m pip install -q --disable-pip-version-check "${pins[@]}" >&2
"$venv/bin/python" -c 'import numpy, pytest, OpenImageIO, mitsuba' >&2
echo "${pins[*]}" >"$stamp"
echo "$venv"
