#!/usr/bin/env bash
# The front door (README): on a fresh Debian 12 machine, install and build everything,
# start the service on the default two-chamber heart with a live status line, record three
# beats into an archive, render an MP4 and a PNG strip of one beat from it, and say where
# they are. Everything stays on this machine (DDS on the loopback profile).
#
#   scripts/demo.sh                 outputs in out/
#   FIBERFEM_OUT=/tmp/x scripts/demo.sh
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$here"
t_start=$(date +%s)

FIBERFEM_BUILD_TARGETS=fiberfem scripts/setup.sh

export CYCLONEDDS_URI="${CYCLONEDDS_URI:-file://$here/configs/dds/loopback.xml}"
out="${FIBERFEM_OUT:-$here/out}"
mkdir -p "$out"
rm -f "$out/heart.h5" "$out/heart.xdmf" "$out/heart.mp4" "$out/heart-beat.png"
rm -rf "$out/frames"
bin="$here/build/release/service/fiberfem"
run="heart-demo-$$"

echo
echo "== 1. The service: the default heart (7,105 tetrahedra, 72 beats/min) in real time for"
echo "      three beats, publishing on DDS and recording to $out/heart.h5"
"$bin" serve --run-id "$run" --until 2.5 --archive "$out/heart.h5" &
serve_pid=$!
trap 'kill "$serve_pid" 2>/dev/null || true' EXIT
# A client on the bus while it runs: the run as the command-line client sees it.
sleep 1.5
"$bin" ctl --run "$run" topology || true
wait "$serve_pid"
trap - EXIT

echo
echo "== 2. The renderer: the recorded run, off-screen (OSMesa), to PNG frames, an MP4 and a"
echo "      strip of one beat"
"$bin" render "$out/heart.h5" --out "$out/frames" --every 2 --mp4 "$out/heart.mp4" --strip "$out/heart-beat.png"

echo
echo "== Done in $(( $(date +%s) - t_start )) s. What you have:"
echo "   archive      $out/heart.h5 (open $out/heart.xdmf in ParaView; replay: $bin replay $out/heart.h5)"
echo "   video        $out/heart.mp4"
echo "   beat strip   $out/heart-beat.png"
echo "   frames       $out/frames/frame-NNNNN.png"
