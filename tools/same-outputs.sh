#!/usr/bin/env bash
# Byte-identity check for a change that must not change behaviour (a
# re-layout, a refactor): runs every subcommand of two nusselt binaries on
# every bundled scene and compares what they write.
#
#   bash tools/same-outputs.sh OLD_BINARY NEW_BINARY [WORKDIR]
#
# Compared byte for byte: solution.exr, baked.gltf/.bin, render.exr/.png,
# snapshots, reference images and noise images, compare's error images
# and metrics, formfactors CSV, chart SVG/PNG, study CSV and charts.
# report.json and the reference/study JSON sidecars are compared with
# their timing fields removed (every key naming seconds, times or rates).
# Exit 0 when everything matches; otherwise the differing files are listed.
# With KEEP_OLD=1 the old binary's outputs already in WORKDIR are reused.
set -euo pipefail
old=$(realpath "$1")
new=$(realpath "$2")
work=${3:-$(mktemp -d)}
here="$(cd "$(dirname "$0")/.." && pwd)"
cd "$here"

run_all() {
    local bin=$1 out=$2
    rm -rf "$out"
    mkdir -p "$out"
    local small=(--width 48 --height 36 --spp 4 --quiet --threads 2)
    # solve: every bundled scene with the default method and mesh.
    for scene in scenes/*.gltf scenes/stress/*.gltf scenes/scale/*.gltf; do
        local name
        name=$(basename "$scene" .gltf)
        "$bin" solve "$scene" -o "$out/solve-$name" "${small[@]}" 2>"$out/solve-$name.stderr" \
            || echo "exit $?" >>"$out/solve-$name.stderr"
    done
    # solve: the other methods, mesh modes and output options on small scenes.
    for scene in scenes/cornell-box.gltf scenes/goral-box.gltf scenes/penumbra.gltf; do
        local name
        name=$(basename "$scene" .gltf)
        for method in direct jacobi gauss-seidel shooting; do
            "$bin" solve "$scene" -o "$out/$method-$name" --method "$method" --snapshots 1,3 \
                "${small[@]}" 2>"$out/$method-$name.stderr" || echo "exit $?" >>"$out/$method-$name.stderr"
        done
        for kernel in polygon-polygon sampling hemicube; do
            "$bin" solve "$scene" -o "$out/gs-$kernel-$name" --method gauss-seidel --kernel "$kernel" \
                "${small[@]}" 2>"$out/gs-$kernel-$name.stderr" || echo "exit $?" >>"$out/gs-$kernel-$name.stderr"
        done
        for mesh in uniform quadtree; do
            "$bin" solve "$scene" -o "$out/mesh-$mesh-$name" --mesh "$mesh" "${small[@]}" \
                2>"$out/mesh-$mesh-$name.stderr" || echo "exit $?" >>"$out/mesh-$mesh-$name.stderr"
        done
        for accuracy in preview high; do
            "$bin" solve "$scene" -o "$out/acc-$accuracy-$name" --accuracy "$accuracy" "${small[@]}" \
                2>"$out/acc-$accuracy-$name.stderr" || echo "exit $?" >>"$out/acc-$accuracy-$name.stderr"
        done
        for oracle in ff power; do
            "$bin" solve "$scene" -o "$out/oracle-$oracle-$name" --oracle "$oracle" "${small[@]}" \
                2>"$out/oracle-$oracle-$name.stderr" || echo "exit $?" >>"$out/oracle-$oracle-$name.stderr"
        done
        "$bin" solve "$scene" -o "$out/extras-$name" --wireframe --importance --clustering on \
            --snapshots 2 "${small[@]}" 2>"$out/extras-$name.stderr" || echo "exit $?" >>"$out/extras-$name.stderr"
        # render: a new view of the solution.
        "$bin" render "$out/solve-$name/solution.exr" -o "$out/render-$name.exr" \
            --png "$out/render-$name.png" --width 40 --height 30 --spp 4 --quiet --threads 2 \
            2>"$out/render-$name.stderr" || echo "exit $?" >>"$out/render-$name.stderr"
        # reference, then compare the solve against it.
        "$bin" reference "$scene" -o "$out/reference-$name.exr" --png "$out/reference-$name.png" \
            "${small[@]}" 2>"$out/reference-$name.stderr" || echo "exit $?" >>"$out/reference-$name.stderr"
        "$bin" compare "$out/solve-$name/render.exr" "$out/reference-$name.exr" \
            -o "$out/compare-$name" >"$out/compare-$name.json" 2>"$out/compare-$name.stderr" \
            || echo "exit $?" >>"$out/compare-$name.stderr"
    done
    # formfactors: every method on every small bundled scene.
    for scene in scenes/cornell-box.gltf scenes/goral-box.gltf scenes/penumbra.gltf \
        scenes/two-squares.gltf scenes/stress/shared-edge.gltf; do
        local name
        name=$(basename "$scene" .gltf)
        for method in analytic sampling hemicube; do
            "$bin" formfactors "$scene" --method "$method" --quiet --threads 2 \
                >"$out/ff-$method-$name.csv" 2>"$out/ff-$method-$name.stderr" \
                || echo "exit $?" >>"$out/ff-$method-$name.stderr"
        done
    done
    # chart: convergence charts of a few solves.
    "$bin" chart "$out"/jacobi-cornell-box/report.json "$out"/shooting-cornell-box/report.json \
        "$out"/solve-cornell-box/report.json -o "$out/chart" 2>"$out/chart.stderr" \
        || echo "exit $?" >>"$out/chart.stderr"
    # study: a small sweep on the Cornell box.
    cat >"$out/study-config.json" <<'JSON'
{"width": 32, "height": 24, "reference_spp": 16, "render_spp": 4,
 "runs": [{"label": "h", "method": "hierarchical", "accuracy": ["preview", "default"]},
          {"label": "j", "method": "jacobi", "kernel": "point-polygon",
           "element_fractions": [0.2, 0.1]}]}
JSON
    "$bin" study scenes/cornell-box.gltf -o "$out/study" --config "$out/study-config.json" \
        --quiet --threads 2 >"$out/study.stdout" 2>"$out/study.stderr" || echo "exit $?" >>"$out/study.stderr"
    # Error paths: the one-line messages.
    "$bin" solve scenes/missing.gltf -o "$out/missing" --quiet 2>"$out/error-missing.stderr" \
        || echo "exit $?" >>"$out/error-missing.stderr"
    "$bin" solve scenes/cornell-box.gltf --bf-eps -1 --quiet 2>"$out/error-flag.stderr" \
        || echo "exit $?" >>"$out/error-flag.stderr"
}

normalise() {
    # Drop timing fields (and the thread-count-independent but time-bound
    # ones) from JSON files, print canonical JSON.
    python3 - "$1" "$work" <<'PY'
import json, sys
TIMING = ("time", "seconds", "per_second", "samples_per_second", "elapsed")
def strip(v):
    if isinstance(v, dict):
        return {k: strip(x) for k, x in v.items() if not any(t in k for t in TIMING)}
    if isinstance(v, list):
        return [strip(x) for x in v]
    return v
with open(sys.argv[1]) as f:
    text = json.dumps(strip(json.load(f)), sort_keys=True, indent=1)
print(text.replace(sys.argv[2] + "/old/", "OUT/").replace(sys.argv[2] + "/new/", "OUT/"))
PY
}

# Both binaries run under the same name, so that usage lines match.
mkdir -p "$work/old-bin" "$work/new-bin"
cp "$old" "$work/old-bin/nusselt"
cp "$new" "$work/new-bin/nusselt"
if [ -n "${KEEP_OLD:-}" ] && [ -d "$work/old" ]; then
    echo "== keeping the outputs of the old binary in $work/old"
else
    echo "== outputs of $old"
    run_all "$work/old-bin/nusselt" "$work/old"
fi
echo "== outputs of $new"
run_all "$work/new-bin/nusselt" "$work/new"

status=0
checked=0
while IFS= read -r -d '' f; do
    rel=${f#"$work/old/"}
    g="$work/new/$rel"
    checked=$((checked + 1))
    if [ ! -e "$g" ]; then
        echo "missing in new: $rel"
        status=1
        continue
    fi
    case "$rel" in
        *.json)
            if ! diff -q <(normalise "$f") <(normalise "$g") >/dev/null; then
                echo "differs (JSON without timings): $rel"
                status=1
            fi
            ;;
        study/results.csv)
            # Timing columns removed.
            if ! diff -q <(grep -v seconds "$f" | cut -d, -f1-6,9-) <(grep -v seconds "$g" | cut -d, -f1-6,9-) >/dev/null; then
                echo "differs (CSV without timings): $rel"
                status=1
            fi
            ;;
        study/*time* | chart/residual-time.*)
            # Charts against time: not comparable across runs.
            ;;
        *.stderr | *.stdout)
            # Summary lines carry times: compare them with numbers masked.
            if ! diff -q <(sed -E 's/[0-9]+\.[0-9]+ s/T s/g' "$f") \
                <(sed -E 's/[0-9]+\.[0-9]+ s/T s/g' "$g") >/dev/null; then
                echo "differs: $rel"
                status=1
            fi
            ;;
        *)
            if ! cmp -s "$f" "$g"; then
                echo "differs: $rel"
                status=1
            fi
            ;;
    esac
done < <(find "$work/old" -type f -print0 | sort -z)
extra=$(cd "$work/new" && find . -type f | sed 's|^\./||' | while read -r rel; do
    [ -e "$work/old/$rel" ] || echo "$rel"
done)
if [ -n "$extra" ]; then
    echo "only in new:"
    echo "$extra"
    status=1
fi
echo "compared $checked files in $work"
[ $status -eq 0 ] && echo "all outputs identical"
exit $status
