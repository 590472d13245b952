#!/usr/bin/env bash
# Fuzz the mesh readers with libFuzzer and keep what it finds.
#
#   scripts/fuzz.sh [SECONDS_PER_TARGET] [TARGET ...]     (default 60 s; gmsh vtk tetgen)
#
# Installs clang and libomp (Debian), builds the fuzz targets with ASan and UBSan in
# build/fuzz, runs each for the given time starting from tests/fuzz/corpus/TARGET, and
# merges the new coverage-increasing inputs back into that directory (commit them: the
# regular test suite replays the corpus with any compiler). A crash leaves its input in
# build/fuzz/artifacts/ and fails the script.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$here"
seconds="${1:-60}"
shift || true
targets=("$@")
[[ ${#targets[@]} -gt 0 ]] || targets=(gmsh vtk tetgen)

need=()
for p in clang libclang-rt-14-dev libomp-14-dev; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || need+=("$p")
done
if [[ ${#need[@]} -gt 0 ]]; then
  sudo_cmd=()
  [[ $(id -u) -eq 0 ]] || sudo_cmd=(sudo)
  DEBIAN_FRONTEND=noninteractive "${sudo_cmd[@]}" apt-get install -y -q --no-install-recommends "${need[@]}"
fi

cmake -S . -B build/fuzz -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCMAKE_C_COMPILER=clang -DCMAKE_CXX_COMPILER=clang++ -DFIBERFEM_NATIVE=OFF \
  -DCMAKE_CXX_FLAGS="-fsanitize=fuzzer-no-link,address,undefined -fno-sanitize-recover=undefined" \
  -DFIBERFEM_FUZZ=ON >/dev/null
ninja -C build/fuzz "${targets[@]/#/fuzz_}"
mkdir -p build/fuzz/artifacts
for t in "${targets[@]}"; do
  corpus="tests/fuzz/corpus/$t"
  work="build/fuzz/work-$t"
  rm -rf "$work" && mkdir -p "$work"
  echo "fuzz: $t for ${seconds}s"
  build/fuzz/tests/fuzz/fuzz_"$t" "$work" "$corpus" -max_total_time="$seconds" -max_len=8192 \
    -rss_limit_mb=2048 -timeout=10 -artifact_prefix=build/fuzz/artifacts/"$t"- -print_final_stats=1 2>&1 | tail -n 12
  # Keep only inputs that add coverage to what the corpus already has.
  build/fuzz/tests/fuzz/fuzz_"$t" -merge=1 "$corpus" "$work" 2>&1 | grep -E "MERGE-OUTER: [0-9]+ new files" || true
done
