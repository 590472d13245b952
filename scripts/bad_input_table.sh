#!/usr/bin/env bash
# Regenerates the tables of docs/bad-input.md from the tests' real output: runs
# tests/service/bad_input_test.cpp (every file and command-line entry point of the real
# binary) and tests/service/bad_command_test.cpp (bad commands to a live service on
# loopback DDS) with FIBERFEM_BAD_INPUT_TABLE / FIBERFEM_BAD_COMMAND_TABLE set, and puts
# what they observed between the markers in docs/bad-input.md.
#
#   scripts/bad_input_table.sh            (after a build of the release preset)
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$here"
build=build/release
cmake --build --preset release --target fiberfem test_service_bad_input_test test_service_bad_command_test >/dev/null
out="$(mktemp -d)"
trap 'rm -rf "$out"' EXIT
FIBERFEM_BAD_INPUT_TABLE="$out/files.md" "$build/tests/test_service_bad_input_test" >/dev/null
CYCLONEDDS_URI="file://$here/configs/dds/loopback.xml" FIBERFEM_BAD_COMMAND_TABLE="$out/commands.md" \
  "$build/tests/test_service_bad_command_test" >/dev/null
python3 - "$out" <<'PY'
import re, sys
out = sys.argv[1]
doc = open("docs/bad-input.md").read()
for name in ("files", "commands"):
    table = open(f"{out}/{name}.md").read().rstrip("\n")
    doc, n = re.subn(rf"(<!-- begin generated {name} table -->\n).*?(<!-- end generated {name} table -->)",
                     lambda m: m.group(1) + table + "\n" + m.group(2), doc, flags=re.S)
    assert n == 1, f"docs/bad-input.md: no markers for the {name} table"
open("docs/bad-input.md", "w").write(doc)
PY
echo "docs/bad-input.md: tables regenerated"
