#!/usr/bin/env bash
# One and two threads and the automatic count on the beams of the Vega comparison
# (docs/vega-comparison.md, "Threads"): `fiberfem run` of each beam scene that
# scripts/vega/compare.sh wrote to build/vega-compare/, 60 steps from rest, --threads 1,
# 2 and 0 (automatic) alternated, --repeat times; the table gives the medians of the
# report's steps/s (every step counted, the first factorisation included), median and
# longest step.
#
#   scripts/vega/threads.sh [--sizes "5600 8100 50000 250000"] [--steps 60] [--repeat 3]
set -euo pipefail
cd "$(dirname "$0")/../.."
sizes="5600 8100 50000 250000"
steps=60
repeat=3
while [[ $# -gt 0 ]]; do
  case "$1" in
    --sizes) sizes="$2"; shift 2 ;;
    --steps) steps="$2"; shift 2 ;;
    --repeat) repeat="$2"; shift 2 ;;
    *) echo "threads.sh: unknown option $1 (--sizes LIST, --steps N, --repeat N)" >&2; exit 2 ;;
  esac
done
bin="${FIBERFEM_BIN:-build/release/service/fiberfem}"
work=build/vega-compare
for s in $sizes; do
  [[ -f "$work/beam-$s.yaml" ]] || { echo "threads.sh: no $work/beam-$s.yaml (scripts/vega/compare.sh --sizes $s writes it)" >&2; exit 1; }
done
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
echo "| tets | threads | steps/s | median step ms | longest step ms |"
echo "|---:|---|---:|---:|---:|"
for s in $sizes; do
  for ((r = 1; r <= repeat; r++)); do
    for t in 1 2 0; do
      "$bin" run "$work/beam-$s.yaml" --steps "$steps" --threads "$t" --report "$tmp/$s-$t-$r.json" >/dev/null
    done
  done
  python3 - "$tmp" "$s" "$repeat" "$work/beam-$s.1.ele" <<'PY'
import json, statistics, sys
tmp, size, repeat, ele = sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4]
tets = int(open(ele).readline().split()[0])
for t, name in (("1", "1"), ("2", "2"), ("0", "automatic")):
    rs = [json.load(open(f"{tmp}/{size}-{t}-{r}.json"))["timing"] for r in range(1, repeat + 1)]
    print(f"| {tets:,} | {name} | {statistics.median(x['steps_per_s'] for x in rs):.1f} | "
          f"{1e3 * statistics.median(x['median_step_s'] for x in rs):.2f} | {1e3 * statistics.median(x['max_step_s'] for x in rs):.0f} |")
PY
done
