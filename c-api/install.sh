#!/usr/bin/env bash
# Installs liblacquer into a prefix, like `cmake --install`:
#   PREFIX/include/lacquer.h, lacquer.hpp
#   PREFIX/lib/liblacquer.so.X.Y.Z, liblacquer.so.X -> , liblacquer.so -> , liblacquer.a
#   PREFIX/lib/pkgconfig/lacquer.pc, lacquer-static.pc
#   PREFIX/lib/cmake/lacquer/lacquerConfig.cmake, lacquerConfigVersion.cmake
#
# Usage: c-api/install.sh [--prefix DIR] [--libdir NAME] [--no-build]
#   --prefix   install prefix (default /usr/local; $PREFIX also works)
#   --libdir   library folder under the prefix (default lib)
#   --no-build use the library already built in $CARGO_TARGET_DIR/release
#   $DESTDIR   staged install: files go to $DESTDIR$PREFIX, paths inside name $PREFIX
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
root="$(cd "$here/.." && pwd)"
prefix="${PREFIX:-/usr/local}"
libdir_name="lib"
build=1
while [ $# -gt 0 ]; do
    case "$1" in
        --prefix) prefix="$2"; shift 2 ;;
        --prefix=*) prefix="${1#*=}"; shift ;;
        --libdir) libdir_name="$2"; shift 2 ;;
        --no-build) build=0; shift ;;
        -h|--help) sed -n '2,15p' "$0"; exit 0 ;;
        *) echo "install.sh: unknown argument $1" >&2; exit 2 ;;
    esac
done
case "$prefix" in /*) ;; *) prefix="$(pwd)/$prefix" ;; esac

target_dir="${CARGO_TARGET_DIR:-$root/target}"
if [ "$build" = 1 ]; then
    # With the CLI, to share its build (same dependency features; docs/reliability.md).
    (cd "$root" && cargo build --release -p lacquer-capi -p lacquer-cli)
fi
rel="$target_dir/release"
for f in liblacquer.so liblacquer.a; do
    [ -f "$rel/$f" ] || { echo "install.sh: $rel/$f missing (build first)" >&2; exit 1; }
done

version="$(sed -n 's/^version = "\(.*\)"/\1/p' "$root/Cargo.toml" | head -1)"
abi_major="$(sed -n 's/^pub const LQ_ABI_VERSION_MAJOR: u32 = \([0-9]*\);/\1/p' "$here/src/lib.rs")"
[ -n "$version" ] && [ -n "$abi_major" ] || { echo "install.sh: cannot read versions" >&2; exit 1; }

dest="${DESTDIR:-}$prefix"
inc="$dest/include"
lib="$dest/$libdir_name"
install -d "$inc" "$lib/pkgconfig" "$lib/cmake/lacquer"
install -m 644 "$here/include/lacquer.h" "$here/include/lacquer.hpp" "$inc/"
install -m 755 "$rel/liblacquer.so" "$lib/liblacquer.so.$version"
ln -sfn "liblacquer.so.$version" "$lib/liblacquer.so.$abi_major"
ln -sfn "liblacquer.so.$abi_major" "$lib/liblacquer.so"
install -m 644 "$rel/liblacquer.a" "$lib/liblacquer.a"

subst() {
    sed -e "s|@PREFIX@|$prefix|g" -e "s|@LIBDIR@|$libdir_name|g" \
        -e "s|@VERSION@|$version|g" -e "s|@ABI_MAJOR@|$abi_major|g" "$1" > "$2"
    chmod 644 "$2"
}
subst "$here/packaging/lacquer.pc.in" "$lib/pkgconfig/lacquer.pc"
subst "$here/packaging/lacquer-static.pc.in" "$lib/pkgconfig/lacquer-static.pc"
subst "$here/packaging/lacquerConfig.cmake.in" "$lib/cmake/lacquer/lacquerConfig.cmake"
subst "$here/packaging/lacquerConfigVersion.cmake.in" "$lib/cmake/lacquer/lacquerConfigVersion.cmake"
echo "installed liblacquer $version (ABI major $abi_major) into ${DESTDIR:-}$prefix"
