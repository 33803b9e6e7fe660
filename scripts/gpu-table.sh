#!/usr/bin/env bash
# The wgpu execution beside cpu-native, 640x480 sphere-on-plane (docs/gpu.md): every algorithm
# with a wgpu execution, map 512, tile 32, accum_hard with 256 samples, no reference; the
# repeats interleave a run with the instrumented replay and one `--gpu-counters off`; the table
# gives the median wall time of each and its ratio to cpu-native's, and the median gpu_ms.
# Usage: scripts/gpu-table.sh OUT_DIR [REPEATS=3] [ADAPTER]   (writes only under OUT_DIR)
set -euo pipefail
out=${1:?usage: scripts/gpu-table.sh OUT_DIR [REPEATS] [ADAPTER]}
repeats=${2:-3}
adapter=(); [ -n "${3:-}" ] && adapter=(--adapter "$3")
bin=${SHADOWBENCH:-target/release/shadowbench}
mkdir -p "$out"
# Every registered algorithm with a wgpu execution, from the binary's own list.
algorithms=$("$bin" list | awk '/^algorithms:/ {a = 1; next} /^[^ ]/ {a = 0}
  a && /\[[^]]*wgpu[^]]*\]/ {printf "%s\"%s\"", (n++ ? ", " : ""), $1}')
[ -n "$algorithms" ] || { echo "error: $bin list names no algorithm with a wgpu execution" >&2; exit 2; }
cat > "$out/table.json" <<J
{"name": "gpu-table", "description": "wgpu beside cpu-native at 640x480 (docs/gpu.md)",
 "scene": {"generator": "sphere-on-plane"},
 "algorithms": [$algorithms],
 "backends": ["cpu-native", "wgpu"],
 "params": {"image": [640, 480], "map_resolution": 512, "tile_size": 32},
 "options": {"accum_hard": {"samples": 256}},
 "reference": {"enabled": false}}
J
uptime > "$out/load.txt"
for i in $(seq "$repeats"); do
  "$bin" run "$out/table.json" --out "$out/on$i" -q "${adapter[@]}" >/dev/null
  "$bin" run "$out/table.json" --out "$out/off$i" -q --backend wgpu --gpu-counters off \
    "${adapter[@]}" >/dev/null
done
uptime >> "$out/load.txt"
python3 - "$out" "$repeats" <<'P'
import collections, json, statistics as st, sys
out, n = sys.argv[1], int(sys.argv[2])
wall, gpu = collections.defaultdict(list), collections.defaultdict(list)
adapter = None
for mode in ("on", "off"):
    for i in range(1, n + 1):
        for r in json.load(open(f"{out}/{mode}{i}/results.json"))["runs"]:
            key = (r["algorithm"], r["backend"] if r["backend"] != "wgpu" else "wgpu-" + mode)
            if r.get("failure"):
                print("FAILED", key, r["failure"][:200])
                continue
            wall[key].append(r["wall_ms"])
            if r["backend"] == "wgpu":
                adapter = r["execution"].get("adapter", adapter)
                if r.get("gpu_ms") is not None and mode == "on":
                    gpu[key].append(r["gpu_ms"])
print(f"adapter: {adapter}")
print("| algorithm | cpu-native ms | wgpu ms | x | wgpu ms (counters off) | x | gpu_ms |")
print("|---|---|---|---|---|---|---|")
for a in sorted({k[0] for k in wall}):
    native = st.median(wall[(a, "cpu-native")])
    on, off = st.median(wall[(a, "wgpu-on")]), st.median(wall[(a, "wgpu-off")])
    g = st.median(gpu[(a, "wgpu-on")]) if gpu[(a, "wgpu-on")] else float("nan")
    print(f"| {a} | {native:.1f} | {on:.1f} | {on / native:.2f} | {off:.1f} | {off / native:.2f} | {g:.1f} |")
P
