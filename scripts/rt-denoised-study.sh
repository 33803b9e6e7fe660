#!/usr/bin/env bash
# rt_denoised's quality against cost beside every other algorithm, one scene per family:
# per scene, scenarios/rt-denoised-quality.json with every algorithm (rt_denoised at 1 ray a
# pixel, denoised), then rt_denoised alone at 2, 4 and 8 rays denoised and at 1, 2, 4 and 8 raw,
# each into its own folder, joined by `report --combine` into OUT/<scene>/index.html (each
# rt_denoised variant a series of its own: `rt_denoised (4 spp raw)`).
#
#   scripts/rt-denoised-study.sh OUT [SCENE ...]
#
# SCENE defaults to sphere-on-plane box-on-plane room torus-on-plane. Uses the release build
# (cargo run --release).
set -euo pipefail

if [[ $# -lt 1 ]]; then
    echo "usage: $0 OUT [SCENE ...]" >&2
    exit 2
fi
out=$1
shift
scenes=("$@")
[[ ${#scenes[@]} -gt 0 ]] || scenes=(sphere-on-plane box-on-plane room torus-on-plane)
scenario=scenarios/rt-denoised-quality.json
sb=(cargo run --release --quiet --)

for scene in "${scenes[@]}"; do
    dirs=()
    "${sb[@]}" run "$scenario" --quiet --out "$out/runs/$scene/all" --set "scene.generator=$scene"
    dirs+=("$out/runs/$scene/all/results.json")
    for variant in 2:true 4:true 8:true 1:false 2:false 4:false 8:false; do
        spp=${variant%%:*}
        denoise=${variant##*:}
        dir="$out/runs/$scene/rt-$spp-$denoise"
        "${sb[@]}" run "$scenario" --quiet --out "$dir" --only rt_denoised \
            --set "scene.generator=$scene" --set "options.rt_denoised.spp=$spp" \
            --set "options.rt_denoised.denoise=$denoise"
        dirs+=("$dir/results.json")
    done
    "${sb[@]}" report --combine "${dirs[@]}" --out "$out/$scene"
    echo "$scene: $out/$scene/index.html"
done
