#!/usr/bin/env bash
# fiberfem against Vega FEM 4.0 on the same TetGen beams (docs/vega-comparison.md).
#
#   scripts/vega/compare.sh [--vega-dir DIR] [--sizes "5600 8100 50000 250000"] [--steps 60]
#                           [--repeat 1] [--scale 1] [--warp 2] [--jobs 1] [--out FILE.md]
#                           [--fiberfem-set KEY=VALUE ...]
#
# Generates a 10 x 1 x 1 box beam per size with TetGen (Debian package `tetgen`), builds
# scripts/vega/vega_beam against the Vega checkout (--vega-dir or $VEGA_DIR), writes the
# fiberfem scene of the same problem, then per size runs, in turn, Vega (one thread),
# fiberfem with --threads 1 and fiberfem with its default thread count, --repeat times
# (the table gives each column's median). Prints a markdown table; --out also writes it.
# --fiberfem-set (repeatable) passes a scene override to every fiberfem run (for example
# solver.preconditioner=block_jacobi); the table's first line names it.
# Work files go to build/vega-compare/ (FIBERFEM_BIN overrides the fiberfem binary).
set -euo pipefail
caller_dir="$PWD"
cd "$(dirname "$0")/../.."
vega_dir="${VEGA_DIR:-}"
sizes="5600 8100 50000 250000"
steps=60
repeat=1
scale=1
warp=2
jobs=1
out=""
fiberfem_sets=()
while [[ $# -gt 0 ]]; do
  case "$1" in
    --vega-dir) vega_dir="$2"; shift 2 ;;
    --sizes) sizes="${2//,/ }"; shift 2 ;;
    --steps) steps="$2"; shift 2 ;;
    --repeat) repeat="$2"; shift 2 ;;
    --scale) scale="$2"; shift 2 ;;
    --warp) warp="$2"; shift 2 ;;
    --jobs) jobs="$2"; shift 2 ;;
    --out) out="$2"; shift 2 ;;
    --fiberfem-set) fiberfem_sets+=(--set "$2"); shift 2 ;;
    *) echo "compare.sh: unknown option $1 (--vega-dir DIR, --sizes LIST, --steps N, --repeat N, --scale M, --warp W, --jobs N, --out FILE, --fiberfem-set KEY=VALUE)" >&2
       exit 2 ;;
  esac
done
absolute() { [[ -z "$1" || "$1" == /* ]] && echo "$1" || echo "$caller_dir/$1"; }
vega_dir="$(absolute "$vega_dir")"
out="$(absolute "$out")"
fiberfem="$(absolute "${FIBERFEM_BIN:-}")"
fiberfem="${fiberfem:-build/release/service/fiberfem}"
work="build/vega-compare"
[[ -n "$vega_dir" ]] || { echo "compare.sh: no Vega checkout: pass --vega-dir DIR or set VEGA_DIR (docs/vega-comparison.md)" >&2; exit 1; }
[[ -x "$fiberfem" ]] || { echo "compare.sh: no $fiberfem (scripts/setup.sh builds it)" >&2; exit 1; }
command -v tetgen >/dev/null || { echo "compare.sh: tetgen not found (Debian: apt-get install tetgen)" >&2; exit 1; }
mkdir -p "$work"

# max_volume TARGET: TetGen's volume constraint (-a, mesh units^3) that gives about TARGET
# tetrahedra with radius-edge bound 2.0 (-q2.0), read off TetGen 1.5.0's counts.
max_volume() {
  case "$1" in
    5600) echo 0.0044 ;;
    8100) echo 0.003 ;;
    50000) echo 0.00043 ;;
    250000) echo 0.00008 ;;
    *) echo "compare.sh: size $1 is not one of 5600 8100 50000 250000" >&2; exit 2 ;;
  esac
}

# make_beam TARGET: build/vega-compare/beam-TARGET.1.{node,ele}, the 10 x 1 x 1 box with
# its faces as six facets; reports TetGen's tetrahedron count.
make_beam() {
  local target="$1" poly="$work/beam-$1.poly" count
  cat >"$poly" <<'EOF'
# 10 x 1 x 1 box: 8 corners, 6 faces, no holes, no regions
8 3 0 0
1 0 0 0
2 10 0 0
3 10 1 0
4 0 1 0
5 0 0 1
6 10 0 1
7 10 1 1
8 0 1 1
6 0
1
4 1 2 3 4
1
4 5 6 7 8
1
4 1 2 6 5
1
4 2 3 7 6
1
4 3 4 8 7
1
4 4 1 5 8
0
0
EOF
  count=$(tetgen -pq2.0a"$(max_volume "$target")"F "$poly" | awk '/Mesh tetrahedra:/ {print $3}')
  echo "compare.sh: $work/beam-$target.1.node: $count tetrahedra" >&2
  if (( count < target * 9 / 10 || count > target * 11 / 10 )); then
    echo "compare.sh: warning: $count is not within 10% of $target (another TetGen version?)" >&2
  fi
}

build_driver() {
  cmake -S scripts/vega -B "$work/driver" -DVEGA_DIR="$vega_dir" -DCMAKE_BUILD_TYPE=Release >"$work/driver-configure.log"
  cmake --build "$work/driver" -j "$jobs" >"$work/driver-build.log" ||
    { echo "compare.sh: vega_beam did not build: $work/driver-build.log" >&2; exit 1; }
}

# write_scene TARGET X Y Z: the fiberfem scene of the Vega run, its probe on the tip node
# Vega reports (metres), so both sides report the same node's displacement.
write_scene() {
  cat >"$work/beam-$1.yaml" <<EOF
name: vega-beam-$1
mesh:
  file: beam-$1.1.node
  scale: $scale
regions:
  - name: beam
    select: all
    material: {E: 1.0e5, nu: 0.45, density: 1000.0}
    damping: {mass: 0.0, stiffness: 0.01}
fixed:
  - plane: {axis: x, value: 0.0}
loads:
  gravity: [0, 0, -9.81]
solver:
  mode: dynamic
  dt: 0.016666666666666666
  method: pcg
  tolerance: 1.0e-6
probes:
  tip: [$2, $3, $4]
EOF
}

run_vega() {
  "$work/driver/vega_beam" "$work/beam-$1.1.node" --steps "$steps" --scale "$scale" --warp "$warp" \
    >"$work/vega-$1-$2.txt"
}

run_fiberfem() {  # TARGET THREADS(1|default) REPEAT
  local threads=()
  # One thread, one core: the first factor waited for, not made on a thread beside.
  [[ "$2" == 1 ]] && threads=(--threads 1 --set solver.first_factorisation=wait)
  "$fiberfem" run "$work/beam-$1.yaml" --steps "$steps" "${threads[@]}" ${fiberfem_sets[@]+"${fiberfem_sets[@]}"} --report "$work/fiberfem-$1-$2-$3.json" >/dev/null
}

run_size() {
  local target="$1" r tip
  for ((r = 1; r <= repeat; r++)); do
    run_vega "$target" "$r"
    if [[ $r == 1 ]]; then
      read -r -a tip < <(awk '/^tip_rest_m/ {print $2, $3, $4}' "$work/vega-$target-1.txt")
      write_scene "$target" "${tip[@]}"
    fi
    run_fiberfem "$target" 1 "$r"
    run_fiberfem "$target" default "$r"
  done
}

for target in $sizes; do max_volume "$target" >/dev/null; done  # refuse unknown sizes first
for target in $sizes; do make_beam "$target"; done
build_driver
for target in $sizes; do run_size "$target"; done
vega_commit=$(git -C "$vega_dir" rev-parse --short HEAD 2>/dev/null || echo "unknown commit")

sets_text=""
for ((k = 1; k < ${#fiberfem_sets[@]}; k += 2)); do sets_text+=" --fiberfem-set ${fiberfem_sets[k]}"; done
python3 - "$work" "$steps" "$repeat" "$scale --warp $warp$sets_text" "$vega_commit" $sizes <<'EOF' | tee "${out:-/dev/null}"
# The two tables from the runs' outputs: vega-T-R.txt (`key value` lines of vega_beam) and
# fiberfem-T-{1,default}-R.json (docs/report-format.md); each figure is the median over
# the --repeat runs.
import json, math, os, platform, statistics, subprocess, sys, time

work, steps, repeat, options, vega_commit = sys.argv[1:6]
sizes, repeat = sys.argv[6:], int(repeat)

def vega_run(target, r):
    out = {}
    for line in open(f"{work}/vega-{target}-{r}.txt"):
        key, *values = line.split()
        out[key] = [float(v) for v in values] if len(values) > 1 else float(values[0])
    return out

def fiberfem_run(target, threads, r):
    return json.load(open(f"{work}/fiberfem-{target}-{threads}-{r}.json"))

def med(values):
    return statistics.median(values)

def norm(v):
    return math.sqrt(sum(c * c for c in v))

cpu = next((l.split(":", 1)[1].strip() for l in open("/proc/cpuinfo") if l.startswith("model name")), platform.machine())
ours = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True).stdout.strip()
print(f"Made by `scripts/vega/compare.sh --steps {steps} --repeat {repeat} --scale {options}` on "
      f"{time.strftime('%Y-%m-%d', time.gmtime())}, {os.cpu_count()} cores ({cpu}); fiberfem {ours}, "
      f"Vega {vega_commit}. {steps} steps from rest per run, every step counted; medians of {repeat} "
      "alternated run(s). Tip: the node nearest (10, 0.5, 0.5) mesh units, its displacement after the last step.")
print()
print("| tets | Vega steps/s (1 thread) | fiberfem 1 thread | fiberfem default threads | ratio 1 thread | ratio default threads | Vega tip displacement m | fiberfem tip displacement m | tip difference |")
print("|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
details = []
for t in sizes:
    runs = range(1, repeat + 1)
    vega = [vega_run(t, r) for r in runs]
    one = [fiberfem_run(t, 1, r) for r in runs]
    auto = [fiberfem_run(t, "default", r) for r in runs]
    v_rate = med([v["steps_per_s"] for v in vega])
    one_rate = med([f["timing"]["steps_per_s"] for f in one])
    auto_rate = med([f["timing"]["steps_per_s"] for f in auto])
    u_v = vega[0]["tip_displacement_m"]
    u_f = one[0]["probes"][0]["displacement_m"]
    diff = norm([a - b for a, b in zip(u_f, u_v)]) / norm(u_v)
    print(f"| {int(vega[0]['tets']):,} | {v_rate:.1f} | {one_rate:.1f} | {auto_rate:.1f} | {one_rate / v_rate:.2g} | "
          f"{auto_rate / v_rate:.2g} | {norm(u_v):.4g} | {norm(u_f):.4g} | {100 * diff:.2f}% |")
    phase = lambda f, k: 1e3 * med([x["timing"]["mean_per_step_s"][k] for x in f])
    details.append(
        f"| {int(vega[0]['tets']):,} | {1e3 * med([v['median_step_s'] for v in vega]):.2f} | "
        f"{1e3 * med([v['mean_assembly_s'] for v in vega]):.2f} / {1e3 * med([v['mean_solve_s'] for v in vega]):.2f} | "
        f"{med([v['cg_iterations_mean'] for v in vega]):.1f} | {med([v['setup_s'] for v in vega]):.2f} | "
        f"{1e3 * med([f['timing']['median_step_s'] for f in one]):.2f} | {phase(one, 'assembly'):.2f} / {phase(one, 'solve'):.2f} | "
        f"{med([f['solver']['iterations_mean'] for f in one]):.1f} | "
        f"{med([f['steps']['recovered'] for f in one]):.0f} | "
        f"{med([f['timing']['wall_s'] - f['timing']['engine_s'] for f in one]):.2f} |")
print()
print("| tets | Vega median step ms | Vega assembly / solve ms | Vega CG iterations | Vega setup s | fiberfem 1 thread median step ms | fiberfem assembly / solve ms | fiberfem PCG iterations | fiberfem steps with substeps | fiberfem setup s |")
print("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
print("\n".join(details))
EOF
