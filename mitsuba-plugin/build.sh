#!/usr/bin/env bash
# Builds the Mitsuba 3 plugin `lacquer` (idempotent; runs nothing else):
#   1. a venv ($LACQUER_VENV, default <repo>/.venv-mitsuba) with the pinned mitsuba, nanobind,
#      numpy and pytest;
#   2. liblacquer.a (cargo build --release -p lacquer-capi);
#   3. mitsuba-plugin/python/lacquer_mitsuba/plugins/lacquer.so (the BSDF), compiled against the
#      wheel's headers and libmitsuba, linking liblacquer.a statically, and lacquer_path.so (a
#      path tracer that keeps camera ray differentials, for sparkle);
#   4. plugins/build_info.json (the mitsuba / drjit versions and variants built for) and a .pth
#      file so that `import lacquer_mitsuba` works in the venv.
# mitsuba-plugin/wheel.sh packs the result into a wheel (dist/lacquer_mitsuba-*.whl).
# Options: --no-llvm  (scalar variants only: faster to compile, no llvm_ad_rgb / llvm_ad_spectral).
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
repo="$(cd "$here/.." && pwd)"
venv="${LACQUER_VENV:-$repo/.venv-mitsuba}"
target="${CARGO_TARGET_DIR:-$repo/target}"
with_llvm=1
for a in "$@"; do
  case "$a" in
    --no-llvm) with_llvm=0 ;;
    *) echo "build.sh: unknown option $a" >&2; exit 2 ;;
  esac
done

MITSUBA_VERSION=3.9.1
NANOBIND_VERSION=2.14.0
NUMPY_VERSION=2.4.6
PYTEST_VERSION=9.2.0

step() { printf '\n==== mitsuba-plugin: %s\n' "$*"; }

step "venv $venv"
if [ ! -x "$venv/bin/python" ]; then
  python3 -m venv "$venv" 2>/dev/null || {
    command -v apt-get >/dev/null && { apt-get update -qq && apt-get install -y -qq python3-venv; }
    python3 -m venv "$venv"
  }
fi
py="$venv/bin/python"
if ! "$py" - <<PYEOF 2>/dev/null
import importlib.metadata as m, sys
want = {"mitsuba": "$MITSUBA_VERSION", "nanobind": "$NANOBIND_VERSION", "numpy": "$NUMPY_VERSION",
        "pytest": "$PYTEST_VERSION"}
sys.exit(0 if all(m.version(k) == v for k, v in want.items()) else 1)
PYEOF
then
  "$py" -m pip install -q --disable-pip-version-check \
    "mitsuba==$MITSUBA_VERSION" "nanobind==$NANOBIND_VERSION" "numpy==$NUMPY_VERSION" "pytest==$PYTEST_VERSION"
fi
site="$("$py" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')"

step "liblacquer.a"
# With the CLI, to share its build (same dependency features; docs/reliability.md).
(cd "$repo" && cargo build --release -q -p lacquer-capi -p lacquer-cli)
lib="$target/release/liblacquer.a"
[ -f "$lib" ] || { echo "build.sh: $lib not found (CARGO_TARGET_DIR?)" >&2; exit 1; }

step "plugins/lacquer.so, plugins/lacquer_path.so"
command -v g++ >/dev/null || { apt-get update -qq && apt-get install -y -qq g++; }
out_dir="$here/python/lacquer_mitsuba/plugins"
mkdir -p "$out_dir"
flags=(-std=c++17 -O2 -march=haswell -fPIC -shared -fvisibility=hidden
       -DMI_ENABLE_LLVM=1 -DMI_ENABLE_CUDA=1 -DMI_ENABLE_AUTODIFF=1 -DMI_ENABLE_EMBREE=1
       -I"$site/mitsuba/include" -I"$site/drjit/include"
       -I"$site/nanobind/include" -I"$site/nanobind/ext/robin_map/include"
       -I"$repo/c-api/include")
[ "$with_llvm" = 1 ] && flags+=(-DLACQUER_WITH_LLVM=1)
mlibs=(-L"$site/mitsuba" -L"$site/drjit" -lmitsuba -ldrjit-core -ldrjit-extra -lnanothread)
rpath=(-Wl,-rpath,'$ORIGIN/../../mitsuba' -Wl,-rpath,"$site/mitsuba" -Wl,-rpath,"$site/drjit")

# build NAME SOURCE EXTRA_LIBS...: rebuilds plugins/NAME.so only when the source, the header,
# the Rust library or the flags changed.
build() {
  local name="$1" src="$here/src/$2" out key stamp
  shift 2
  out="$out_dir/$name.so"
  stamp="$out_dir/.$name.stamp"
  key="$(cat "$src" "$repo/c-api/include/lacquer.h" | sha256sum | cut -c1-16) $(sha256sum "$lib" | cut -c1-16) ${flags[*]} $*"
  if [ -f "$out" ] && [ -f "$stamp" ] && [ "$(cat "$stamp")" = "$key" ]; then
    echo "up to date: $out"
  else
    g++ "${flags[@]}" "$src" -o "$out.tmp" "${mlibs[@]}" "$@" "${rpath[@]}"
    mv "$out.tmp" "$out"
    echo "$key" > "$stamp"
    echo "built: $out"
  fi
}
# The BSDF links the Rust core statically (its symbols stay private); the integrator needs
# only Mitsuba.
build lacquer lacquer_bsdf.cpp "$lib" -Wl,--exclude-libs,ALL -lgcc_s -lutil -lrt -lpthread -lm -ldl
build lacquer_path lacquer_path.cpp

# What the plugins were built for: register() refuses to load them into another Mitsuba.
"$py" - "$out_dir/build_info.json" "$with_llvm" <<'PYEOF'
import importlib.metadata as m, json, sys
variants = ["scalar_rgb", "scalar_spectral"] + (["llvm_ad_rgb", "llvm_ad_spectral"] if sys.argv[2] == "1" else [])
info = {"mitsuba": m.version("mitsuba"), "drjit": m.version("drjit"), "variants": variants}
with open(sys.argv[1], "w") as f:
    json.dump(info, f, indent=1)
PYEOF

step "lacquer_mitsuba on the venv's path"
echo "$here/python" > "$site/lacquer_mitsuba.pth"
echo "ok: $py -c 'import lacquer_mitsuba; lacquer_mitsuba.register()'"
