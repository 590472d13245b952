#!/usr/bin/env bash
# Threads on a quiet and on a shared machine (docs/performance.md, "Threads and a shared
# machine"): the paper-size beam and the default heart, batch runs of `fiberfem run` with
# 1 thread, 2 threads and the automatic count (--threads 0), first on a quiet machine, then
# beside one busy core. The busy core is another process: a peer finite-element run (a
# 264,000-tet beam of fiberfem on one thread, memory-bound like a peer code) or a plain spin
# loop. Each case is one run; its report gives the mean steps/s, the median and the longest
# step. With FIBERFEM_OLD_BIN set, every case runs that binary too, alternated with the new.
#
#   scripts/bench_threads.sh [--steps N] [--out FILE.md]
#   FIBERFEM_OLD_BIN=/path/to/old/fiberfem scripts/bench_threads.sh
set -euo pipefail
cd "$(dirname "$0")/.."
steps=1000
out=""
while [[ $# -gt 0 ]]; do
  case "$1" in
    --steps) steps="$2"; shift 2 ;;
    --out) out="$2"; shift 2 ;;
    *) echo "bench_threads: unknown option $1 (--steps N, --out FILE.md)" >&2; exit 2 ;;
  esac
done
new="${FIBERFEM_BIN:-build/release/service/fiberfem}"
old="${FIBERFEM_OLD_BIN:-}"
[[ -x "$new" ]] || { echo "bench_threads: no $new (scripts/setup.sh builds it)" >&2; exit 1; }
py=python3
tmp="$(mktemp -d)"
busy_pid=""
cleanup() {
  [[ -n "$busy_pid" ]] && kill -- "$busy_pid" 2>/dev/null || true
  rm -rf "$tmp"
}
trap cleanup EXIT

# start_load KIND: one busy process beside the benchmark (bounded: it ends by itself).
start_load() {
  case "$1" in
    fe) timeout 900 "$new" run --builtin cantilever --cells 100 22 20 --steps 1000000000 --threads 1 >/dev/null 2>&1 &
        busy_pid=$! ;;
    spin) timeout 900 sh -c 'while :; do :; done' &
        busy_pid=$! ;;
  esac
  sleep 3  # let it reach its steady state
}
stop_load() {
  [[ -n "$busy_pid" ]] && { kill -- "$busy_pid" 2>/dev/null || true; wait "$busy_pid" 2>/dev/null || true; }
  busy_pid=""
}

# case_row BIN WHICH LOAD SCENE THREADS: one run, one table row.
case_row() {
  local bin="$1" which="$2" load="$3" scene="$4" threads="$5" args
  case "$scene" in
    beam) args=(--builtin cantilever --cells 48 5 4) ;;
    heart) args=(--builtin heart) ;;
  esac
  "$bin" run "${args[@]}" --steps "$steps" --threads "$threads" --report "$tmp/r.json" >/dev/null 2>&1
  "$py" - "$tmp/r.json" "$which" "$load" "$scene" "$threads" <<'EOF'
import json, sys
r = json.load(open(sys.argv[1]))["timing"]
which, load, scene, threads = sys.argv[2:6]
label = {"0": "auto", "1": "1", "2": "2"}[threads]
print(f"| {scene} | {load} | {label} | {which} | {r['steps_per_s']:.0f} | {r['median_step_s'] * 1e3:.2f} | {r['max_step_s'] * 1e3:.1f} |")
EOF
}

{
  echo "Made by \`scripts/bench_threads.sh --steps $steps\` on $(date -u +%Y-%m-%d), $(nproc) cores ($(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs)). Batch runs of $steps steps (\`fiberfem run\`): the paper-size beam (5,760 tets, PCG 1e-6) and the default heart (7,105 tets, contracting). Threads: auto is \`--threads 0\`."
  echo
  echo "| scene | other load | threads | binary | mean steps/s | median step ms | longest step ms |"
  echo "|---|---|---|---|---|---|---|"
  for load in none fe spin; do
    [[ "$load" != none ]] && start_load "$load"
    for scene in beam heart; do
      for threads in 1 2 0; do
        [[ -n "$old" ]] && case_row "$old" old "$load" "$scene" "$threads"
        case_row "$new" "$([[ -n "$old" ]] && echo new || echo this)" "$load" "$scene" "$threads"
      done
    done
    stop_load
  done
} | tee "${out:-/dev/null}"
