#!/usr/bin/env bash
# Renders the images of blender-addon/README.md through the installed extension, headless, as an
# artist would (docs/img/):
#   blender-cycles-vs-lacquer.png  gold_flake_8 ("Gold metallic 8 %") on a sphere: Cycles with the
#                                  fitted `Lacquer Coated Paint` node group | LACQUER (exact model)
#   blender-library.png            the asset library: every preset's thumbnail with its name
#   blender-surface.png            LACQUER: plain | orange peel (exaggerated) | a normal map
#   blender-texture.png            an Image Texture on Base Color: Cycles | LACQUER
#   blender-flake-scale.png        flakes on a plain plate and a parented, scaled instance:
#                                  Cycles | LACQUER
#   blender-passes.png             LACQUER at 16 spp: Combined | Denoising Albedo | Denoising
#                                  Normal | compositor Denoise node
# (scripts/scenes.py --scenes readme,shots; the scenes reuse the test scenes' set-up.)
#
#   bash blender-addon/readme-image.sh [SIZE] [SPP] [SHOT_SIZE] [SHOT_SPP]
#        # defaults 320 px, 256 spp (the side-by-side image); 240 px, 64 spp (the other panels)
#
# Builds the zip with the asset library (LACQUER_ASSETS=1: the contact sheet needs the
# thumbnails) and the bpy venv (scripts/blender-env.sh, honours LACQUER_BLENDER_VENV and
# LACQUER_BPY_VERSION). The EXRs and report.json go to a temporary folder, whose path it prints.
# Not a CI step: about 2–3 min on the 2-core machine once the zip is built.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
root="$(cd "$here/.." && pwd)"
size="${1:-320}" spp="${2:-256}" shot_size="${3:-240}" shot_spp="${4:-64}"
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$root/target}"
zip="$(LACQUER_ASSETS=1 bash "$here/build.sh")"
bpy_venv="$(bash "$root/scripts/blender-env.sh")"
out="$(mktemp -d "${TMPDIR:-/tmp}/lacquer-readme-image.XXXXXX")"
mkdir -p "$root/docs/img"
t0=$SECONDS
BLENDER_USER_RESOURCES="$out/user-resources" "$bpy_venv/bin/python" "$here/scripts/scenes.py" \
  --zip "$zip" --out "$out" --size "$size" --spp "$spp" --scenes readme,shots \
  --png "$root/docs/img/blender-cycles-vs-lacquer.png" \
  --img-dir "$root/docs/img" --shot-size "$shot_size" --shot-spp "$shot_spp" \
  | grep -E '^(rendered|Lacquer:|shot |Denoise)' || true
python3 -c "import json,sys; r=json.load(open(sys.argv[1])); [print(f\"readme {x['engine']}: {x['seconds']:.1f} s\") for x in r['renders']]; [print(f\"{k}: {v['png']['file']} {v['png']['size'][0]}x{v['png']['size'][1]} {v['png']['bytes']/1e3:.0f} kB, {v['seconds']:.1f} s\") for k, v in r.get('shots', {}).items()]" "$out/report.json"
echo "docs/img/blender-*.png in $((SECONDS - t0)) s (renders in $out)"
