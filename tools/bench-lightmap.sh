#!/usr/bin/env bash
# Lightmap cost against resolution: for each scene and atlas side, one
# default `nusselt solve --lightmap RES` (render 32², outputs in a scratch
# folder); prints the lightmap phase's seconds, the run's peak memory, the
# charts, texels per metre and texel efficiency (covered / all texels).
# Usage: bash tools/bench-lightmap.sh [SCENE.gltf ...]   (run from the repository root)
set -euo pipefail
scenes=("$@")
[ ${#scenes[@]} -gt 0 ] || scenes=(scenes/three-rooms.gltf scenes/scale/office-10k.gltf)
cargo build --release --quiet
scratch="$(mktemp -d)"
trap 'rm -rf "$scratch"' EXIT
echo "| scene | lightmap | lightmap s | run s | peak MiB | charts | texels/m | efficiency |"
echo "|---|---:|---:|---:|---:|---:|---:|---:|"
for scene in "${scenes[@]}"; do
    for res in 512 1024 2048 4096; do
        out="$scratch/out"
        /usr/bin/time -f "%e %M" -o "$scratch/time" target/release/nusselt solve "$scene" \
            -o "$out" --quiet --width 32 --height 32 --lightmap "$res" 2>/dev/null
        read -r wall kb < "$scratch/time"
        python3 - "$out/report.json" "$scene" "$res" "$wall" "$kb" <<'PY'
import json, sys
report, scene, res, wall, kb = sys.argv[1:]
r = json.load(open(report))
lm = r["lightmap"]
print(f"| {scene.split('/')[-1]} | {res}² | {r['times']['lightmap']:.2f} | {float(wall):.1f} | "
      f"{int(kb) / 1024:.0f} | {lm['charts']} | {lm['texels_per_metre']:.1f} | {lm['efficiency']:.3f} |")
PY
        rm -rf "$out"
    done
done
