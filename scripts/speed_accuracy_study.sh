#!/usr/bin/env bash
# The speed-against-accuracy study in one command (docs/speed-accuracy.md): makes the heart
# mesh levels (cached in build/study/meshes), builds and runs bench_accuracy (references
# cached in build/study), writes docs/speed-accuracy-results.md, the stability table
# docs/speed-accuracy-stability.md and the plots in docs/images/speed-accuracy-*.png.
#   scripts/speed_accuracy_study.sh [bench_accuracy options, e.g. --scene heart]
set -euo pipefail
cd "$(dirname "$0")/.."
out=build/study
mkdir -p "$out/meshes"
for size in 0.008 0.006 0.003; do
  mesh="$out/meshes/biventricle-$size.msh"
  [ -f "$mesh" ] || .venv/bin/python scripts/make_biventricle.py --size "$size" --out "$mesh"
done
cmake --build --preset release --target bench_accuracy
bin=build/release/tests/bench/bench_accuracy
"$bin" --out-dir "$out" --markdown docs/speed-accuracy-results.md "$@"
"$bin" --stability --stability-markdown docs/speed-accuracy-stability.md
.venv/bin/python scripts/plot_speed_accuracy.py "$out/results.csv" --out docs/images
