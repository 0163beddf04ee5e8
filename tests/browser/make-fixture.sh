#!/usr/bin/env bash
# Builds the small corpus, model and trait set the browser tests serve, in $1 (made fresh):
# ten shared MERL materials (links to their neural-BRDF weights, nothing copied), a 9-component
# log-space PCA model of them (no chart), and three traits (glossiness, roughness, specularness)
# fitted by SVM on the project's own labels restricted to these materials.
# With a third argument N, N more materials join: brass (a metal), then the first shared MERL
# materials in name order, and the model keeps min(45, materials − 1) components (the real-time
# view's tests: 46 materials, 45 components).
set -euo pipefail
OUT="$1"; GANTRY="$2"; EXTRA="${3:-0}"
# BRDF_DATA_DIR, else shared/data beside the checkout or any of its ancestors (as brdf::data_dir).
DATA="${BRDF_DATA_DIR:-}"
if [ -z "$DATA" ]; then
  d="$(cd "$(dirname "$0")/../.." && pwd)"
  while [ "$d" != "/" ]; do
    if [ -d "$d/../shared/data" ]; then DATA="$(cd "$d/../shared/data" && pwd)"; break; fi
    d="$(dirname "$d")"
  done
fi
SRC="$DATA/nbrdf/merl"
if [ ! -d "$SRC" ]; then
  echo "error: shared data not found at $SRC (set BRDF_DATA_DIR)" >&2; exit 1
fi
MATERIALS=(blue-acrylic specular-red-phenolic black-obsidian red-metallic-paint specular-blue-phenolic
           pink-felt blue-fabric white-paint light-red-paint yellow-matte-plastic)
if [ "$EXTRA" -gt 0 ]; then
  MORE=(brass)
  for f in "$SRC"/*_fc1.npy; do
    [ "${#MORE[@]}" -ge "$EXTRA" ] && break
    m="$(basename "$f" _fc1.npy)"
    case " ${MATERIALS[*]} ${MORE[*]} " in *" $m "*) continue ;; esac
    MORE+=("$m")
  done
  MATERIALS+=("${MORE[@]:0:$EXTRA}")
fi
K=$(( ${#MATERIALS[@]} - 1 )); [ "$K" -gt 45 ] && K=45
rm -rf "$OUT"; mkdir -p "$OUT/corpus"
for m in "${MATERIALS[@]}"; do
  for part in fc1 b1 fc2 b2 fc3 b3; do ln -s "$SRC/${m}_${part}.npy" "$OUT/corpus/${m}_${part}.npy"; done
done
LABELS="$(cd "$(dirname "$0")/../.." && pwd)/crates/traits/data/thesis_traits.csv"
python3 - "$LABELS" "$OUT/labels.csv" "${MATERIALS[@]}" <<'PY'
import csv, sys
src, dst, keep = sys.argv[1], sys.argv[2], set(sys.argv[3:])
rows = [r for r in open(src) if not r.startswith('#')]
cols = ['material', 'glossiness', 'roughness', 'specularness']
with open(dst, 'w', newline='') as f:
    w = csv.writer(f)
    w.writerow(cols)
    for r in csv.DictReader(rows):
        if r['material'] in keep:
            w.writerow([r[c] for c in cols])
PY
"$GANTRY" model build --corpus "$OUT/corpus" --out "$OUT/model.bin" --components "$K" --chart-dim 0 >/dev/null
"$GANTRY" traits fit --labels "$OUT/labels.csv" --model "$OUT/model.bin" --space linear --method svm --dim "$K" --out "$OUT/traits.json" >/dev/null
echo "fixture: $OUT (${#MATERIALS[@]} materials, $K components, 3 traits)"
