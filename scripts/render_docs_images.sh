#!/usr/bin/env bash
# Regenerates the pictures in docs/images/ with `fiberfem render` (docs/rendering.md): one
# frame of every shipped scene (docs/images/<scene>.png, also the README's heart.png) and a
# strip of one heart beat (docs/images/heart-beat-strip.png). 960x540, 2x supersampled,
# PNG level 9. Takes about three minutes (the palm scenes simulate 1.5 s each).
#
#   scripts/render_docs_images.sh            all scenes
#   scripts/render_docs_images.sh heart      only the named scenes (the strip with heart)
#   FIBERFEM_BIN=path/to/fiberfem ...        another binary (default build/release/service/fiberfem)
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bin="${FIBERFEM_BIN:-$here/build/release/service/fiberfem}"
out="$here/docs/images"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
mkdir -p "$out"
[[ -x "$bin" ]] || { echo "render_docs_images: $bin not built (cmake --build build/release --target fiberfem)" >&2; exit 1; }

common=(--width 960 --height 540 --supersample 2 --png-level 9)

# What to show of each scene: the time (or the static equilibrium), the field, the camera.
declare -A opts=(
  [heart]="--at 0.1 --field activation"
  [lv-beat]="--at 0.15 --field fiber_strain"
  [land-ventricle-p2]="--field displacement --fit frame --camera iso"
  [land-ventricle-p3]="--field displacement --fit frame --camera iso"
  [beam-demo]="--field displacement --fit frame --camera front --fibers"
  [box-gravity]="--field displacement --fit frame --camera iso"
  [cantilever-across]="--field displacement --fit frame --camera iso --fibers"
  [cantilever-along]="--field displacement --fit frame --camera iso --fibers"
  [demo-cantilever]="--field displacement --fit frame --camera front"
  [land-beam]="--field displacement --fit frame --camera iso"
  [palm-drag]="--field displacement --fit frame --camera iso"
  [palm-fibers]="--field displacement --fit frame --camera iso --fibers"
  [palm-heterogeneous]="--field region --fit frame --camera iso"
  [palm-isotropic]="--field displacement --fit frame --camera iso"
)

scenes=("$@")
if [[ ${#scenes[@]} -eq 0 ]]; then
  for f in "$here"/configs/scenes/*.yaml; do scenes+=("$(basename "$f" .yaml)"); done
fi

for name in "${scenes[@]}"; do
  scene="$here/configs/scenes/$name.yaml"
  [[ -f "$scene" ]] || { echo "render_docs_images: no scene $scene" >&2; exit 1; }
  # shellcheck disable=SC2086 # the per-scene options are words
  extra=(${opts[$name]:---fit frame})
  # Without --at: the last frame of the run (dynamic) or the equilibrium (static).
  if [[ " ${extra[*]} " != *" --at "* ]]; then extra+=(--last); fi
  echo "render_docs_images: $name"
  rm -rf "$tmp/$name"
  "$bin" render "$scene" --out "$tmp/$name" "${common[@]}" "${extra[@]}" > "$tmp/$name.log" 2>&1 ||
    { cat "$tmp/$name.log" >&2; exit 1; }
  last="$(ls "$tmp/$name"/frame-*.png | tail -1)"
  cp "$last" "$out/$name.png"
done

if [[ " ${scenes[*]} " == *" heart "* ]]; then
  echo "render_docs_images: heart beat strip"
  "$bin" render "$here/configs/scenes/heart.yaml" --no-png --until 0.8334 --strip "$out/heart-beat-strip.png" \
    --strip-panels 8 --strip-width 240 --width 960 --height 540 > "$tmp/strip.log" 2>&1 || { cat "$tmp/strip.log" >&2; exit 1; }
fi
ls -l "$out"
