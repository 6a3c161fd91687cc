#!/usr/bin/env bash
# Fits every model in MODELS to MERL tables generated from paint presets (and, when Mitsuba is
# importable, to tables sampled from Mitsuba 3's roughplastic and roughconductor) and prints a
# markdown table per material: the comparison of docs/fitting.md (thesis figure 5.2 style).
#
#   bash scripts/fit_comparison.sh [OUTDIR]      (tables and JSON reports go to OUTDIR)
#
# Environment: LACQUER (binary; default: build the release CLI), PYTHON (with mitsuba and
# numpy; default .venv-tests/bin/python), MODELS (comma-separated fit models; default: every
# model lacquer::fit::fittable_models lists but coated_paint, plus lambert+ward+ward), PRESETS, EXTRA_ARGS (for fit).
set -euo pipefail
cd "$(dirname "$0")/.."
out="${1:-target/fit-comparison}"
mkdir -p "$out"
if [ -z "${LACQUER:-}" ]; then
  cargo build --release -q -p lacquer-cli
  LACQUER="${CARGO_TARGET_DIR:-target}/release/lacquer"
fi
PYTHON="${PYTHON:-.venv-tests/bin/python}"
if [ -z "${MODELS:-}" ]; then
  MODELS="$("$LACQUER" models --json | python3 -c '
import json, sys
names = [m["name"] for m in json.load(sys.stdin)
         # measured: nothing to fit; coated_paint: its build takes 30-130 ms per evaluation of
         # the objective; poulin_fournier, stam: no isotropic configuration, and a MERL table is
         # isotropic (lacquer::fit::NO_ISOTROPIC_CONFIGURATION).
         if m["name"] not in ("measured", "coated_paint", "poulin_fournier", "stam")
         and any(p["kind"] in ("scalar", "color") and p["max"] > p["min"] for p in m["params"])]
print(",".join(names + ["lambert+ward+ward"]))')"
fi
PRESETS="${PRESETS:-gold_flake_8 silver_flake_2 solid_red automotive_silver_metallic pearl_blue}"

tables=()
for p in $PRESETS; do
  "$LACQUER" fit --generate "$p" --out "$out/$p.binary" >/dev/null
  tables+=("$p")
done
if "$PYTHON" -c 'import mitsuba, numpy' 2>/dev/null; then
  for b in roughplastic roughconductor; do
    "$PYTHON" tests/test_fit_mitsuba.py "$out/mitsuba_$b.binary" "$b" >/dev/null
    tables+=("mitsuba_$b")
  done
else
  echo "(mitsuba not importable with $PYTHON: Mitsuba-sampled tables skipped)" >&2
fi

for t in "${tables[@]}"; do
  # shellcheck disable=SC2086
  "$LACQUER" fit --table "$out/$t.binary" --model "$MODELS" --json ${EXTRA_ARGS:-} >"$out/$t.json"
  python3 - "$out/$t.json" "$t" <<'EOF'
import json, sys
r = json.load(open(sys.argv[1]))
print(f"\n**{sys.argv[2]}** ({r['entries']} entries, table read in {r['load_seconds']:.2f} s, "
      f"all fits {r['total_seconds']:.1f} s)\n")
print("| model | vars | SNR R / G / B (dB) | SNR (dB) | SNRw (dB) | cos-RMS | Ngan | iters | time (s) |")
print("|---|---|---|---|---|---|---|---|---|")
for f in r["fits"]:
    m = f["metrics"]
    rgb = " / ".join(f"{x:.1f}" for x in m["snr_db"])
    print(f"| {f['model']} | {len(f['parameters'])} | {rgb} | {m['snr_db_mean']:.1f} | "
          f"{m['snr_weighted_db']:.1f} | {m['rms_cos']:.3g} | {m['ngan']:.3g} | {f['iterations']} | {f['seconds']:.2f} |")
EOF
done
