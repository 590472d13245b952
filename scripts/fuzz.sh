#!/usr/bin/env bash
# Fuzz the readers of outside input with libFuzzer and keep what it finds.
#
#   scripts/fuzz.sh [SECONDS_PER_TARGET] [TARGET ...]     (default 60 s; every target:
#       gmsh vtk tetgen scene fiber cycle command archive)
#   FIBERFEM_FUZZ_KEEP=0 ...   do not merge new inputs into tests/fuzz/corpus (the CI job)
#   FIBERFEM_FUZZ_DIR=DIR ...  build and work there (default build/fuzz)
#   FIBERFEM_SKIP_APT=1 ...    fail if clang is missing instead of installing it
#
# Installs clang and libomp (Debian), builds the fuzz targets with ASan and UBSan in
# $FIBERFEM_FUZZ_DIR, runs each for the given time starting from tests/fuzz/corpus/TARGET, and
# merges the new coverage-increasing inputs back into that directory (commit them: the
# regular test suite replays the corpus with any compiler). A crash leaves its input in
# $FIBERFEM_FUZZ_DIR/artifacts/ and fails the script.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$here"
seconds="${1:-60}"
shift || true
targets=("$@")
[[ ${#targets[@]} -gt 0 ]] || targets=(gmsh vtk tetgen scene fiber cycle command archive)

need=()
for p in clang libclang-rt-14-dev libomp-14-dev; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || need+=("$p")
done
if [[ ${#need[@]} -gt 0 && "${FIBERFEM_SKIP_APT:-0}" == 1 ]]; then
  echo "fuzz: missing Debian packages ${need[*]} (scripts/setup.sh installs them)" >&2
  exit 2
fi
if [[ ${#need[@]} -gt 0 ]]; then
  sudo_cmd=()
  [[ $(id -u) -eq 0 ]] || sudo_cmd=(sudo)
  DEBIAN_FRONTEND=noninteractive "${sudo_cmd[@]}" apt-get install -y -q --no-install-recommends "${need[@]}"
fi

launcher=()
if command -v ccache >/dev/null; then
  launcher=(-DCMAKE_C_COMPILER_LAUNCHER=ccache -DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
fi
fuzz_dir="${FIBERFEM_FUZZ_DIR:-build/fuzz}"
cmake -S . -B "$fuzz_dir" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo "${launcher[@]}" \
  -DCMAKE_C_COMPILER=clang -DCMAKE_CXX_COMPILER=clang++ -DFIBERFEM_NATIVE=OFF \
  -DCMAKE_CXX_FLAGS="-fsanitize=fuzzer-no-link,address,undefined -fno-sanitize-recover=undefined" \
  -DFIBERFEM_FUZZ=ON -DFIBERFEM_WITH_AMGCL=OFF >/dev/null  # the command fuzzer's set_solver amg is then refused with a message (the refusal path); the build skips AMGCL's templates
ninja -C "$fuzz_dir" "${targets[@]/#/fuzz_}"
mkdir -p "$fuzz_dir"/artifacts
failed=()
for t in "${targets[@]}"; do
  corpus="tests/fuzz/corpus/$t"
  work="$fuzz_dir/work-$t"
  rm -rf "$work" && mkdir -p "$work"
  echo "fuzz: $t for ${seconds}s"
  log="$fuzz_dir/fuzz-$t.log"
  # Every input in the corpus runs first; then new ones for the given time. -timeout: an
  # input that takes longer (a hang) is a finding; -rss_limit_mb: so is one that makes a
  # reader allocate without bound.
  if ! LSAN_OPTIONS="suppressions=$here/tests/fuzz/lsan.supp" "$fuzz_dir"/tests/fuzz/fuzz_"$t" "$work" "$corpus" -max_total_time="$seconds" -max_len=8192 \
    -rss_limit_mb=2048 -timeout=10 -artifact_prefix="$fuzz_dir"/artifacts/"$t"- -print_final_stats=1 >"$log" 2>&1; then
    failed+=("$t")
    grep -E "ERROR|SUMMARY|Test unit written|==[0-9]+==" "$log" | head -n 20
  fi
  # Executions, speed and coverage for docs/bad-input.md.
  grep -E "^stat::(number_of_executed_units|average_exec_per_sec|new_units_added|peak_rss_mb)" "$log" | tr '\n' ' '
  echo
  grep -E "^#[0-9]+ +DONE" "$log" | tail -n 1 || true
  if [[ "${FIBERFEM_FUZZ_KEEP:-1}" == 1 ]]; then
    # Keep only inputs that add coverage to what the corpus already has.
    "$fuzz_dir"/tests/fuzz/fuzz_"$t" -merge=1 "$corpus" "$work" 2>&1 | grep -E "MERGE-OUTER: [0-9]+ new files" || true
  fi
done
if [[ ${#failed[@]} -gt 0 ]]; then
  echo "fuzz: findings in ${failed[*]} (inputs in $fuzz_dir/artifacts/)"
  exit 1
fi
echo "fuzz: no findings in ${targets[*]}"
