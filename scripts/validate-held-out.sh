#!/usr/bin/env bash
# The host model's held-out validation (docs/model.md, "Held-out validation"): calibrate this
# machine (kernels, then the issue costs fitted to the training sweep: every algorithm on
# box-on-plane, cylinder-on-plane and sphere-grid at 240x180 and 480x360), then validate-model on
# scenes and an image size the fit never saw: sphere-on-plane, room and torus-on-plane at 400x300,
# for hard_shadow_map, pcss, penumbra_map, soft_izb, soft_shadow_volume and dbuffer. cpu-native
# is measured on the CPU clock (the default) in both.
#
#   scripts/validate-held-out.sh OUT_DIR [BUSY]
#
# BUSY (default 0) busy-looping processes run beside the calibration only, to calibrate on a
# loaded machine. Writes OUT_DIR/machine.json (the calibration), OUT_DIR/calibrate.log,
# OUT_DIR/validation/ (validate-model's files: summary.txt holds the figures) and OUT_DIR/load.txt
# (`uptime` before and after each step). Takes about 2 minutes on 2 cores.
set -euo pipefail

if [[ $# -lt 1 || $# -gt 2 ]]; then
    echo "usage: $0 OUT_DIR [BUSY]" >&2
    exit 2
fi
out=$1
busy=${2:-0}
[[ "$busy" =~ ^[0-9]+$ ]] || { echo "error: BUSY must be a whole number, got '$busy'" >&2; exit 2; }
cd "$(dirname "$0")/.."
bin=./target/release/shadowbench
[[ -x "$bin" ]] || { echo "error: $bin missing: run cargo build --release first" >&2; exit 2; }
mkdir -p "$out"

pids=()
stop_busy() {
    for p in "${pids[@]}"; do
        kill "$p" 2>/dev/null || true
    done
    pids=()
}
trap stop_busy EXIT
for _ in $(seq 1 "$busy"); do
    bash -c 'while :; do :; done' &
    pids+=("$!")
done

{ echo "calibrate start ($busy busy processes): $(uptime)"; } > "$out/load.txt"
"$bin" calibrate --out "$out/machine.json" | tee "$out/calibrate.log"
echo "calibrate end: $(uptime)" >> "$out/load.txt"
stop_busy

echo "validate start: $(uptime)" >> "$out/load.txt"
"$bin" validate-model --machine "$out/machine.json" \
    --only hard_shadow_map,pcss,penumbra_map,soft_izb,soft_shadow_volume,dbuffer \
    --scenes sphere-on-plane,room,torus-on-plane --images 400x300 \
    --out "$out/validation"
echo "validate end: $(uptime)" >> "$out/load.txt"
cat "$out/load.txt"
