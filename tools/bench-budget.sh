#!/usr/bin/env bash
# How well `--time-budget` bounds a whole run, and how each phase grows
# with the scene: for each scene, one `nusselt solve SCENE --time-budget S`
# (outputs in a scratch folder); prints wall seconds (the run and each
# phase from report.json), output vertices and peak memory. Scenes: the
# fans and offices of `gen-scenes --fan N DIR` and `--scale N DIR`,
# smallest first. A refused run (a memory budget, say) prints its error.
# Usage: bash tools/bench-budget.sh SECONDS SCENE.gltf ...   (from the repository root;
# NUSSELT_BIN=PATH runs that binary instead of building one)
set -euo pipefail
budget="$1"
shift
bin="${NUSSELT_BIN:-target/release/nusselt}"
[ -n "${NUSSELT_BIN:-}" ] || cargo build --release --quiet
scratch="$(mktemp -d)"
trap 'rm -rf "$scratch"' EXIT
echo "| scene | triangles | budget | wall | load | occluder BVH | shadow lines | linking | refinement | solve | output mesh | render | write | output vertices | peak MiB |"
echo "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
for scene in "$@"; do
    out="$scratch/out"
    if ! /usr/bin/time -f "%e %M" -o "$scratch/time" "$bin" solve "$scene" \
        -o "$out" --quiet --time-budget "$budget" 2> "$scratch/err"; then
        echo "| $(basename "$scene") | | $budget | $(tail -1 "$scratch/err") |"
        continue
    fi
    read -r wall kb < <(tail -1 "$scratch/time")
    python3 - "$out/report.json" "$scene" "$budget" "$wall" "$kb" <<'PY'
import json, sys
report, scene, budget, wall, kb = sys.argv[1:]
r = json.load(open(report))
t, c = r["times"], r["counts"]
f = lambda k: f"{t[k]:.2f}" if t.get(k) is not None else "–"
print(f"| {scene.split('/')[-1]} | {c['input_triangles']:,} | {budget} | {float(wall):.1f} | "
      + " | ".join(f(k) for k in ["load", "bvh", "discontinuities", "linking", "refinement",
                                   "solve", "output_mesh", "render", "write"])
      + f" | {c['output_vertices']:,} | {int(kb) / 1024:.0f} |")
PY
    rm -rf "$out"
done
