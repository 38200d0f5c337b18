#!/usr/bin/env bash
# The lit example scenes against the path tracer: for the spot-lit room
# (point and spot lights, closed) and the courtyard (sun and a uniform
# sky, open), a point table of 200 random surface points path traced at
# 16384 paths each (`nusselt probe`, cached in target/bench-lights/), then
# one solve per preset (render 64 × 36): wall seconds, the point error
# (median, 90th percentile, mean bias, power bias) and absorbed / emitted.
# Usage: bash tools/bench-lights.sh        (run from the repository root)
set -euo pipefail
cargo build --release --quiet
cache=target/bench-lights
mkdir -p "$cache"
scratch="$(mktemp -d)"
trap 'rm -rf "$scratch"' EXIT
sky=(--sky 0.25,0.32,0.45)
echo "| scene | preset | solve s | median | p90 | mean bias | power bias | absorbed / emitted |"
echo "|---|---|---:|---:|---:|---:|---:|---:|"
for scene in spot-room courtyard; do
    args=()
    [ "$scene" = courtyard ] && args=("${sky[@]}")
    table="$cache/$scene.points.csv"
    if [ ! -f "$table" ]; then
        target/release/nusselt probe "scenes/$scene.gltf" "${args[@]}" --random 200 \
            --spp 16384 -o "$table" --quiet
    fi
    for preset in preview default high; do
        out="$scratch/$scene-$preset"
        start=$(date +%s.%N)
        target/release/nusselt solve "scenes/$scene.gltf" "${args[@]}" --accuracy "$preset" \
            --width 64 --height 36 -o "$out" --quiet 2>/dev/null
        end=$(date +%s.%N)
        target/release/nusselt compare "$out/solution.exr" "$table" > "$out/points.json"
        python3 - "$scene" "$preset" "$start" "$end" "$out" <<'PY'
import json, sys
scene, preset, start, end, out = sys.argv[1:]
p = json.load(open(f"{out}/points.json"))
s = p.get("score", p)
power = json.load(open(f"{out}/report.json"))["power"]
ratio = sum(power["absorbed"]) / sum(power["emitted"])
print(f"| {scene} | {preset} | {float(end) - float(start):.1f} | {s['median']:.2%} | {s['p90']:.2%} | "
      f"{s['mean_bias']:+.2%} | {s['power_bias']:+.2%} | {ratio:.4f} |")
PY
    done
done
