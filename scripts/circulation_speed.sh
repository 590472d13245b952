#!/usr/bin/env bash
# Engine steps per second of the default heart without and with the closed-loop circulation
# (docs/circulation.md): each scene run REPEATS times for SECONDS of simulated time, the
# median of the summary's "steps/s of engine time". Usage:
#   scripts/circulation_speed.sh [REPEATS=5] [SECONDS=4.1667] [THREADS=1]
set -euo pipefail
cd "$(dirname "$0")/.."
repeats=${1:-5}
until_s=${2:-4.1667}
threads=${3:-1}
bin=build/release/service/fiberfem
for scene in heart heart-circulation-realtime; do
  rates=()
  for _ in $(seq "$repeats"); do
    rate=$("$bin" run "configs/scenes/$scene.yaml" --until "$until_s" --set solver.threads="$threads" 2>&1 |
      sed -n 's/.*wall (\([0-9.]*\) steps\/s of engine time).*/\1/p')
    rates+=("$rate")
  done
  median=$(printf '%s\n' "${rates[@]}" | sort -n | awk '{a[NR]=$1} END {print (NR % 2) ? a[(NR+1)/2] : (a[NR/2] + a[NR/2+1]) / 2}')
  echo "$scene: median $median steps/s of engine time over $repeats runs (${rates[*]}), threads $threads"
done
