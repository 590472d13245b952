#!/usr/bin/env bash
# Threads on a quiet and on a shared machine (docs/performance.md, "Threads and a shared
# machine"): the paper-size beam, the default heart and a beating left ventricle of the
# accurate tier (Guccione law; a 25th of the steps), batch runs of `fiberfem run` with
# 1 thread, 2 threads and the automatic count (--threads 0), first on a quiet machine, then
# beside one busy core. The busy core is another process: a peer finite-element run (a
# 264,000-tet beam of fiberfem on one thread, memory-bound like a peer code) or a plain spin
# loop (nice 0, or nice 19 for "spin19"). Each case is one run per round; its report gives
# the mean steps/s, the median and the longest step. With FIBERFEM_OLD_BIN set, every case
# runs that binary too, alternated with the new (which goes first swaps each round).
#
#   scripts/bench_threads.sh [--steps N] [--loads "none fe spin spin19"] [--rounds N] [--out FILE.md]
#   FIBERFEM_OLD_BIN=/path/to/old/fiberfem scripts/bench_threads.sh
set -euo pipefail
cd "$(dirname "$0")/.."
steps=1000
out=""
loads="none fe spin"
rounds=1
while [[ $# -gt 0 ]]; do
  case "$1" in
    --steps) steps="$2"; shift 2 ;;
    --out) out="$2"; shift 2 ;;
    --loads) loads="$2"; shift 2 ;;
    --rounds) rounds="$2"; shift 2 ;;
    *) echo "bench_threads: unknown option $1 (--steps N, --loads LIST, --rounds N, --out FILE.md)" >&2; exit 2 ;;
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
    spin19) timeout 900 nice -n 19 sh -c 'while :; do :; done' &
        busy_pid=$! ;;
  esac
  sleep 3  # let it reach its steady state
}
stop_load() {
  [[ -n "$busy_pid" ]] && { kill -- "$busy_pid" 2>/dev/null || true; wait "$busy_pid" 2>/dev/null || true; }
  busy_pid=""
}

# The accurate tier's row: lv-beat's ventricle and contraction with the Guccione law.
cat >"$tmp/lv-guccione.yaml" <<'EOF'
name: lv-guccione-threads
mesh:
  generator: lv_ellipsoid
  resolution: {circumferential: 24, longitudinal: 10, transmural: 3}
regions:
  - name: myocardium
    select: all
    material: {law: guccione, C: 880, b_f: 18.48, b_t: 3.58, b_fs: 1.627, density: 1060.0}
    damping: {mass: 20.0, stiffness: 0.0}
fibers:
  rule: {endo_angle: 60, epi_angle: -60}
fixed:
  - node_set: base
contraction:
  peak_tension: 40.0e3
  heart_rate: 72
  twitch: {shape: biexponential, tau1: 0.05, tau2: 0.11}
  pacing: {at: [0.0, 0.0, -0.02], speed: 0.6}
solver:
  dt: 0.0166667
EOF

# case_row BIN WHICH LOAD SCENE THREADS: one run, one table row.
case_row() {
  local bin="$1" which="$2" load="$3" scene="$4" threads="$5" args n="$steps"
  case "$scene" in
    beam) args=(--builtin cantilever --cells 48 5 4) ;;
    heart) args=(--builtin heart) ;;
    lv-guccione) args=("$tmp/lv-guccione.yaml"); n=$(( (steps + 24) / 25 )) ;;
  esac
  "$bin" run "${args[@]}" --steps "$n" --threads "$threads" --report "$tmp/r.json" >/dev/null 2>&1
  "$py" - "$tmp/r.json" "$which" "$load" "$scene" "$threads" <<'EOF'
import json, sys
report = json.load(open(sys.argv[1]))
r = report["timing"]
which, load, scene, threads = sys.argv[2:6]
label = {"0": "auto", "1": "1", "2": "2"}[threads]
if "steps_per_s" in r:
    print(f"| {scene} | {load} | {label} | {which} | {r['steps_per_s']:.0f} | {r['median_step_s'] * 1e3:.2f} | {r['max_step_s'] * 1e3:.1f} |")
else:  # the accurate tier reports wall and phase times
    n = report["steps"]["completed"]
    print(f"| {scene} | {load} | {label} | {which} | {n / r['wall_s']:.2f} | element loop {r['assembly_s'] / n * 1e3:.1f} | |")
EOF
}

{
  echo "Made by \`scripts/bench_threads.sh --steps $steps\` on $(date -u +%Y-%m-%d), $(nproc) cores ($(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs)). Batch runs of $steps steps (\`fiberfem run\`): the paper-size beam (5,760 tets, PCG 1e-6) and the default heart (7,105 tets, contracting); $(( (steps + 24) / 25 )) steps of a beating left ventricle on the accurate tier (Guccione, lv-beat's mesh; its row gives the mean element-loop time per step instead of the median step). Threads: auto is \`--threads 0\`."
  echo
  echo "| scene | other load | threads | binary | mean steps/s | median step ms | longest step ms |"
  echo "|---|---|---|---|---|---|---|"
  for load in $loads; do
    [[ "$load" != none ]] && start_load "$load"
    for ((round = 1; round <= rounds; ++round)); do
      for scene in beam heart lv-guccione; do
        for threads in 1 2 0; do
          if [[ -z "$old" ]]; then
            case_row "$new" this "$load" "$scene" "$threads"
          elif (( round % 2 )); then
            case_row "$old" old "$load" "$scene" "$threads"
            case_row "$new" new "$load" "$scene" "$threads"
          else
            case_row "$new" new "$load" "$scene" "$threads"
            case_row "$old" old "$load" "$scene" "$threads"
          fi
        done
      done
    done
    stop_load
  done
} | tee "${out:-/dev/null}"
