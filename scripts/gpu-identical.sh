#!/usr/bin/env bash
# Every wgpu run of a fixed set (examples/gpu_fingerprint.rs: each algorithm with a wgpu
# execution on its default options and every option set, two scenes, a textured light) from
# two builds of that example (say the commit before a change to the GPU code and after it),
# compared to the byte: the visibility (and RGB) buffers and every counter of each run and phase.
# Usage: scripts/gpu-identical.sh BEFORE_BIN AFTER_BIN OUT_DIR   (writes only under OUT_DIR)
set -euo pipefail
before=${1:?usage: scripts/gpu-identical.sh BEFORE_BIN AFTER_BIN OUT_DIR}
after=${2:?usage: scripts/gpu-identical.sh BEFORE_BIN AFTER_BIN OUT_DIR}
out=${3:?usage: scripts/gpu-identical.sh BEFORE_BIN AFTER_BIN OUT_DIR}
mkdir -p "$out"
"$before" "$out/before" 2>/dev/null
"$after" "$out/after" 2>/dev/null
if diff -r "$out/before" "$out/after" >"$out/diff.txt"; then
  echo "identical: $(wc -l <"$out/after/counters.txt") runs, $(ls "$out/after" | wc -l) files"
else
  echo "DIFFERENT (see $out/diff.txt):"; head -c 2000 "$out/diff.txt"; exit 1
fi
