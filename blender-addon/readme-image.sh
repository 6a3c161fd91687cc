#!/usr/bin/env bash
# Renders the README's side-by-side image: gold_flake_8 ("Gold metallic 8 %") on a sphere, in
# Cycles through the fitted `Lacquer Coated Paint` node group (left) and in the LACQUER engine
# with the exact model (right), through the installed extension, as an artist would.
#
#   bash blender-addon/readme-image.sh [SIZE] [SPP]      # default 320 px, 256 spp
#
# Writes docs/img/blender-cycles-vs-lacquer.png (and the EXRs and report.json in a temporary
# folder, whose path it prints).
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
root="$(cd "$here/.." && pwd)"
size="${1:-320}" spp="${2:-256}"
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$root/target}"
zip="$(bash "$here/build.sh")"
bpy_venv="$(bash "$root/scripts/blender-env.sh")"
out="$(mktemp -d "${TMPDIR:-/tmp}/lacquer-readme-image.XXXXXX")"
mkdir -p "$root/docs/img"
BLENDER_USER_RESOURCES="$out/user-resources" "$bpy_venv/bin/python" "$here/scripts/scenes.py" \
  --zip "$zip" --out "$out" --size "$size" --spp "$spp" --scenes readme \
  --png "$root/docs/img/blender-cycles-vs-lacquer.png" | grep -E '^(rendered|Lacquer:)' || true
python3 -c "import json,sys; r=json.load(open(sys.argv[1])); [print(f\"{x['engine']}: {x['seconds']:.1f} s\") for x in r['renders']]" "$out/report.json"
echo "docs/img/blender-cycles-vs-lacquer.png (renders in $out)"
