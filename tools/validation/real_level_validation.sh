#!/usr/bin/env bash
# A real level's frame against Blender Cycles (docs/validation.md, "Real levels"; issue 43).
#
#   tools/validation/real_level_validation.sh OUTDIR REAL_DIR [SCENE...]
#       OUTDIR: where everything is written (e.g. build/real_levels); REAL_DIR: the folder of real
#       scenes (../shared/real: zdm2/zdm2.glb, truck_town/town_model.gltf; not in the repository);
#       SCENE: names from the table below (default: all). Relative paths are taken from the
#       current folder.
#
# For every scene, tools/validation/real_level_scene.py writes OUTDIR/NAME/NAME.gltf: the level's
# geometry as it is, every material one grey double-sided Lambertian (albedo 0.8, no texture) and
# a camera `Camera` placed where contact shadows fill the view. The sky is the coloured lobes
# sky of degree 2 (`cycles_compare.py lobes --degree 2`: exactly bands 0-2, which prt's default
# 3 bands hold exactly), turned ROTATE degrees about +Y in both renderers. Then
#   Cycles (Blender 3.4, tools/validation/cycles_reference.py): 8 diffuse bounces, FSAMPLES per
#     pixel for each of seeds 1 and 2 (their mean is the reference; half their difference its
#     noise), SIZE, a box pixel filter one pixel wide;
#   prt: for every route of ROUTES, `prt bake --bounces 8 ROUTE_OPTIONS` (default options
#     otherwise), `prt render --materials diffuse` from the same camera at SIZE;
#   tools/validation/cycles_compare.py compare --curved: the luminance's relative RMS over the
#     pixels away from edges and silhouettes ("frame"), and in Cycles' darkest quarter of them
#     ("dark": relative RMS, and the median of prt / Cycles), with Cycles' noise.
# Prints a table (also OUTDIR/table.md) with the bake's wall time, the .glb's size and its
# vertices, and writes OUTDIR/NAME/diff_ROUTE.png (prt / Cycles per pixel: red brighter, blue
# darker) and OUTDIR/real_levels.png (Cycles, then each route, one row per scene).
# Only reports: no exit status depends on the numbers. Cycles results are reused when their
# .json matches, prt bakes when their file exists (delete them to redo).
#
# Environment: FSAMPLES (Cycles samples per seed, default 256), SIZE (default 240x135), ROTATE
# (default 30), ROUTES (space-separated LABEL=OPTIONS, options joined by commas; default
# "default= no-refine=--no-refine"), BLENDER, PRT, THREADS.
set -euo pipefail
if [ $# -lt 2 ]; then
  echo "usage: tools/validation/real_level_validation.sh OUTDIR REAL_DIR [SCENE...]   (docs/validation.md)" >&2
  exit 2
fi
OUT=$(realpath -m -- "$1")
REAL=$(realpath -m -- "$2")
shift 2
cd "$(dirname "$0")/../.."
FSAMPLES=${FSAMPLES:-256}
SIZE=${SIZE:-240x135}
ROTATE=${ROTATE:-30}
ROUTES=${ROUTES:-"default= no-refine=--no-refine"}
BLENDER=${BLENDER:-blender}
PRT=${PRT:-build/tools/prt}
THREADS=${THREADS:-0}
PY=/usr/bin/python3
BOUNCES=8

# name|file in REAL_DIR|camera eye|camera target|vertical field of view (degrees)
SCENES=(
  "truck_town|truck_town/town_model.gltf|19.91,11.66,1.78|16,10,-5|60"     # a house's corner on the grass
  "zdm2|zdm2/zdm2.glb|28.9,-0.2,17.4|28.9,-1.0,12.4|60"                   # a corridor lit from above
)

command -v "$BLENDER" >/dev/null || { echo "real_level_validation.sh: $BLENDER not found" >&2; exit 1; }
[ -x "$PRT" ] || { echo "real_level_validation.sh: $PRT not found (build prt first)" >&2; exit 1; }
mkdir -p "$OUT"
SKY="$OUT/sky_degree2.exr"
[ -f "$SKY" ] || "$PY" tools/validation/cycles_compare.py lobes "$SKY" --degree 2

# matches FILE.json KEY=VALUE...: the Cycles result's settings are these.
matches() {
  local f=$1; shift
  [ -f "$f" ] && [ -f "$f.json" ] && "$PY" - "$f.json" "$@" <<'PY'
import json, sys
m = json.load(open(sys.argv[1]))
for kv in sys.argv[2:]:
    k, v = kv.split("=", 1)
    if str(m.get(k)) != v:
        sys.exit(1)
PY
}

# cycles_frame SCENE.gltf EXR SEED
cycles_frame() {
  if matches "$2" scene="$1" env="$SKY" env_rotate_deg="$ROTATE.0" samples="$FSAMPLES" seed="$3" bounces="$BOUNCES" \
    size="[${SIZE/x/, }]" pixel_filter=box; then echo "reusing $2"; return; fi
  rm -f "$2" "$2.json"
  "$BLENDER" -b --factory-startup --python tools/validation/cycles_reference.py -- --scene "$1" --env "$SKY" \
    --env-rotate "$ROTATE" --bounces "$BOUNCES" --samples "$FSAMPLES" --seed "$3" --size "$SIZE" --camera Camera \
    --pixel-filter box --threads "$THREADS" -o "$2" | grep -E '^(cycles_|Error)' || true
  [ -f "$2" ] || { echo "real_level_validation.sh: Cycles render $2 failed" >&2; exit 1; }
}

rows=()
table="| scene | route | bake s | file MiB | vertices | frame RMS | dark RMS | dark median | bright median | Cycles noise (dark) |"
table+=$'\n|---|---|---:|---:|---:|---:|---:|---:|---:|---:|'
for entry in "${SCENES[@]}"; do
  IFS='|' read -r name file eye target fov <<<"$entry"
  if [ $# -gt 0 ] && [[ " $* " != *" $name "* ]]; then continue; fi
  dir="$OUT/$name"
  mkdir -p "$dir"
  scene="$dir/$name.gltf"
  "$PY" tools/validation/real_level_scene.py "$REAL/$file" "$scene" --eye "$eye" --target "$target" --yfov "$fov" >/dev/null
  cycles_frame "$scene" "$dir/cycles_s1.exr" 1
  cycles_frame "$scene" "$dir/cycles_s2.exr" 2
  row="$dir/cycles_s1.exr"
  for route in $ROUTES; do
    label=${route%%=*}
    opts=${route#*=}
    opts=${opts//,/ }
    glb="$dir/prt_$label.glb"
    if [ ! -f "$glb" ]; then
      t0=$(date +%s.%N)
      # shellcheck disable=SC2086 # opts is a list of options
      "$PRT" bake "$scene" -o "$glb" --bounces "$BOUNCES" $opts -q
      t1=$(date +%s.%N)
      echo "$t0 $t1" | awk '{printf "%.1f\n", $2 - $1}' >"$glb.seconds"
    fi
    "$PRT" render "$glb" --env "$SKY" --env-rotate "$ROTATE" --materials diffuse --size "$SIZE" --camera Camera \
      --exr-compression none -q -o "$dir/prt_$label.exr"
    "$PY" tools/validation/cycles_compare.py compare "$dir/cycles_s1.exr" "$dir/prt_$label.exr" --second "$dir/cycles_s2.exr" \
      --curved --min-pixels 60 --summary "$dir/summary_$label.json" --diff "$dir/diff_$label.png" \
      --name "$name, $label: Cycles (2 seeds x $FSAMPLES) vs prt bake --bounces $BOUNCES $opts" || true
    echo
    verts=$("$PRT" info "$glb" | awk '$1 == "vertices" {print $2}')
    table+=$'\n'$("$PY" - "$dir/summary_$label.json" "$name" "$label $opts" "$(cat "$glb.seconds")" \
      "$(stat -c %s "$glb")" "$verts" <<'PY'
import json, sys
s = json.load(open(sys.argv[1]))
name, label, secs, size, verts = sys.argv[2:]
print(f"| {name} | {label.strip()} | {float(secs):.1f} | {int(size) / 2**20:.1f} | {verts} | {100 * s['frame_rms']:.1f}% | "
      f"{100 * s['dark']['rms']:.1f}% | {s['dark']['median_ratio']:.3f} | {s['bright']['median_ratio']:.3f} | "
      f"{100 * s['cycles_noise']:.1f}% ({100 * s['cycles_noise_dark']:.1f}%) |")
PY
    )
    row+=",$dir/prt_$label.exr"
  done
  rows+=("$row")
done
echo "$table" | tee "$OUT/table.md"
[ ${#rows[@]} -eq 0 ] || "$PY" tools/validation/cycles_compare.py sheet "$OUT/real_levels.png" --exposure -1 "${rows[@]}"
echo "real_level_validation.sh: done (reports only)"
