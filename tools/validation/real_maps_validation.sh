#!/usr/bin/env bash
# prt against Blender Cycles under real HDR maps, per vertex and per frame (docs/validation.md,
# "Real maps, per vertex and per frame"; issue 12).
#
#   tools/validation/real_maps_validation.sh [--glossy] OUTDIR MAP [MAP...]
#   tools/validation/real_maps_validation.sh OUTDIR --lamp
#       OUTDIR: where everything is written (e.g. build/real_validation); MAP: equirectangular
#       .hdr/.exr maps (e.g. Poly Haven's royal_esplanade_1k.hdr and venice_sunset_1k.hdr; nothing
#       is copied into the repository). Relative paths are taken from the current folder.
#       --lamp: instead of maps, the closed room lit only by its own point light and emissive
#       ceiling panel (validation_room.py --lamp; docs/validation.md, "Lights inside the scene"),
#       no environment, at 8 bounces and at 0 (direct light only: the units).
#
# The scene is the Cornell-style room of tools/validation/validation_room.py (2 x 2 x 2 m, a 0.8 m skylight,
# the front side open, vertices 0.1 m apart), written into OUTDIR. For every map:
#   Cycles (Blender 3.4): tools/validation/cycles_vertex_reference.py bakes the exitant radiance at every
#     vertex (8 diffuse bounces, VSAMPLES samples for each of 2 seeds; CSAMPLES for the
#     controls), and
#     tools/validation/cycles_reference.py renders the camera outside the open side (8 bounces, FSAMPLES, SIZE,
#     a box pixel filter one pixel wide: each pixel the mean over its square);
#   prt: `prt bake --bounces 8` at 3 bands, `prt relight --csv` and `prt render` (at SIZE, whose
#     shadows are filtered over each pixel's square; at SUPERSAMPLE > 1 rendered that many times
#     larger and averaged down by the comparison: the same mean over each pixel's square), "before"
#     (--no-direct-lights, and with the map's sun extraction off where prt has that option) and
#     "after" (default options);
#   tools/validation/vertex_compare.py (per vertex: median, p95 of the relative error, Cycles' noise) and
#     tools/validation/cycles_compare.py (per face and tile, eroded away from edges; RMS over regions).
# Controls: the uniform white sky (band 0: prt exact; checks units rho E / pi) at 8 and at 0
# bounces (the bounce count), and the lobes sky (bands 0-4) at 6 bands (orientation; exact) and
# at 3 bands.
# Only reports: no exit status depends on the numbers. Cycles results in OUTDIR are reused when
# their .json matches (delete them to redo).
#
# --glossy (docs/validation.md, "Glossy materials"; issue 42): frames only, of the same room with
# a glossy floor and a copper short box (tools/validation/glossy_room.py --validation-room): Cycles
# with the Principled BSDF (`cycles_reference.py --materials principled`: GGX, specular 0.5,
# glossy bounces and reflective caustics on; MATERIALS=gltf: glTF's BRDF, Lambertian diffuse plus
# the GGX lobe, as prt evaluates it; MATERIALS=gltf-bake: that BRDF where the camera looks and a
# Lambertian of prt's bounce albedo on every later bounce, prt's light transport; CAUSTICS=0: no
# glossy reflection after a diffuse bounce), prt baked at 3 bands
# and 8 bounces and rendered with --materials full and --materials diffuse, compared over the
# whole frame and over the floor's and the box's pixels apart (`cycles_compare.py --objects`).
# Only reports: no exit status depends on the numbers. Cycles results in OUTDIR are reused when
# their .json matches (delete them to redo).
#
# Environment: MATERIALS and CAUSTICS (--glossy, above), VSAMPLES (per seed, default 1024), CSAMPLES (per seed, controls, default 128),
# FSAMPLES (default 1024), SIZE (default 160x90), SUPERSAMPLE (default 1: prt's defaults),
# BAKE_SAMPLES (default 4096), BAKE_ARGS (more `prt bake` options, e.g. --operator: then each map is
# also lit with --no-operator, the gather traced again, for comparison), BLENDER, PRT, THREADS, NO_SUN_OPTION (the prt option that turns
# the map's sun extraction off; default: found in `prt relight --help`, else none).
set -euo pipefail

GLOSSY=0
[ "${1:-}" != --glossy ] || { GLOSSY=1; shift; }
if [ $# -lt 2 ]; then
  echo "usage: tools/validation/real_maps_validation.sh [--glossy] OUTDIR MAP [MAP...] | OUTDIR --lamp   (docs/validation.md)" >&2
  exit 2
fi
OUT=$(realpath -m -- "$1")
shift
LAMP=0
MAPS=()
if [ "$1" = --lamp ]; then LAMP=1; shift; fi
for m in "$@"; do MAPS+=("$(realpath -m -- "$m")"); done
cd "$(dirname "$0")/../.."
VSAMPLES=${VSAMPLES:-1024}
CSAMPLES=${CSAMPLES:-128}
FSAMPLES=${FSAMPLES:-1024}
SIZE=${SIZE:-160x90}
SUPERSAMPLE=${SUPERSAMPLE:-1}
PRT_SIZE="$((${SIZE%x*} * SUPERSAMPLE))x$((${SIZE#*x} * SUPERSAMPLE))"
BAKE_SAMPLES=${BAKE_SAMPLES:-4096}
BLENDER=${BLENDER:-blender}
PRT=${PRT:-build/tools/prt}
THREADS=${THREADS:-0}
PY=/usr/bin/python3
WHITE=scenes/env/white_sky_64.hdr
BOUNCES=8

command -v "$BLENDER" >/dev/null || { echo "real_maps_validation.sh: $BLENDER not found" >&2; exit 1; }
[ -x "$PRT" ] || { echo "real_maps_validation.sh: $PRT not found (build prt first)" >&2; exit 1; }
for m in "${MAPS[@]}"; do [ -f "$m" ] || { echo "real_maps_validation.sh: $m: no such map" >&2; exit 1; }; done
NO_SUN_OPTION=${NO_SUN_OPTION-$("$PRT" relight --help | grep -oE -- '--no-[a-z-]*(sun|extract)[a-z-]*' | head -1 || true)}
mkdir -p "$OUT"
CAUSTICS=${CAUSTICS:-1}
MATERIALS=${MATERIALS:-principled}
BAKE_PREFIX=""
CYCLES_ARGS=()  # more cycles_reference.py options (--glossy: the materials)
CYCLES_KEYS=()  # the .json keys they set
if [ $GLOSSY -eq 1 ]; then
  SCENE="$OUT/room_glossy.gltf"
  BAKE_PREFIX=glossy_
  "$PY" tools/validation/glossy_room.py --validation-room "$OUT" >/dev/null
  CYCLES_ARGS=(--materials "$MATERIALS")
  CYCLES_KEYS=(materials="$MATERIALS" caustics=$([ "$CAUSTICS" = 1 ] && echo True || echo False))
  [ "$CAUSTICS" = 1 ] || CYCLES_ARGS+=(--no-caustics)
elif [ $LAMP = 1 ]; then
  "$PY" tools/validation/validation_room.py "$OUT" --lamp >/dev/null
  SCENE="$OUT/lamp_room.gltf"
else
  SCENE="$OUT/room.gltf"
  "$PY" tools/validation/validation_room.py "$OUT" >/dev/null
  "$PY" tools/validation/cycles_compare.py lobes "$OUT/lobes_256.exr"
fi

# env_arg MAP: --env MAP, nothing for no map (the lamp room: a black world).
env_arg() { [ -z "$1" ] || printf -- '--env %s' "$1"; }

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

# cycles_vertex NAME MAP SAMPLES [BOUNCES]: Cycles' per-vertex reference.
cycles_vertex() {
  local csv="$OUT/cyc_v_$1.csv" k=${4:-$BOUNCES}
  if matches "$csv" env="${2:-None}" scene="$SCENE" samples="$3" bounces="$k"; then echo "reusing $csv"; return; fi
  rm -f "$csv" "$csv.json"
  "$BLENDER" -b --factory-startup --python tools/validation/cycles_vertex_reference.py -- --scene "$SCENE" $(env_arg "$2") \
    --bounces "$k" --samples "$3" --seeds 1,2 --threads "$THREADS" -o "$csv" | grep -E '^(cycles_|Error)' || true
  [ -f "$csv" ] || { echo "real_maps_validation.sh: Cycles bake $csv failed" >&2; exit 1; }
}

# cycles_frame NAME MAP: Cycles' frame of the room's camera.
cycles_frame() {
  local exr="$OUT/cycles_$1.exr"
  if matches "$exr" env="${2:-None}" scene="$SCENE" samples="$FSAMPLES" bounces="$BOUNCES" size="[${SIZE/x/, }]" \
    pixel_filter=box ${CYCLES_KEYS[@]+"${CYCLES_KEYS[@]}"}; then echo "reusing $exr"; return; fi
  rm -f "$exr" "$exr.json"
  "$BLENDER" -b --factory-startup --python tools/validation/cycles_reference.py -- --scene "$SCENE" $(env_arg "$2") \
    --bounces "$BOUNCES" --samples "$FSAMPLES" --size "$SIZE" --camera Camera --pixel-filter box --threads "$THREADS" \
    ${CYCLES_ARGS[@]+"${CYCLES_ARGS[@]}"} -o "$exr" \
    | grep -E '^(cycles_|Error)' || true
  [ -f "$exr" ] || { echo "real_maps_validation.sh: Cycles render $exr failed" >&2; exit 1; }
}

# bake BANDS [BOUNCES]: prt's bake of the room (default options otherwise).
bake() {
  local k=${2:-$BOUNCES} tag=""
  [ -z "${BAKE_ARGS:-}" ] || tag="_$(echo "$BAKE_ARGS" | tr -c 'a-z0-9' '_')"
  [ $LAMP = 0 ] || tag="_lamp$tag"
  local glb="$OUT/prt_${BAKE_PREFIX}b$1_k${k}_s$BAKE_SAMPLES$tag.glb"
  # shellcheck disable=SC2086 # BAKE_ARGS is a list of options
  [ -f "$glb" ] || "$PRT" bake "$SCENE" -o "$glb" --bands "$1" --bounces "$k" --samples "$BAKE_SAMPLES" ${BAKE_ARGS:-} -q
  echo "$glb"
}

# case_ NAME BANDS MAP REF [prt lighting options]: relight CSV, frame (when Cycles has one for
# REF), and both comparisons. BANDS may be B:K for K bounces.
case_() {
  local name=$1 spec=$2 bands=${2%%:*} k=${2#*:} map=$3 ref=$4; shift 4
  [ "$k" != "$spec" ] || k=$BOUNCES
  local glb; glb=$(bake "$bands" "$k")
  # shellcheck disable=SC2046 # env_arg is one option and its value, or nothing
  "$PRT" relight "$glb" $(env_arg "$map") "$@" -o "$OUT/prt_$name.glb" --csv "$OUT/prt_$name.csv" -q
  "$PY" tools/validation/vertex_compare.py "$OUT/cyc_v_$ref.csv" "$OUT/prt_$name.csv" --name "$name: Cycles $ref vs prt $bands bands $*" \
    --json "$OUT/vertex_$name.json"
  if [ -f "$OUT/cycles_$ref.exr" ]; then
    # shellcheck disable=SC2046
    "$PRT" render "$glb" $(env_arg "$map") "$@" --size "$PRT_SIZE" --camera Camera --exr-compression none -q -o "$OUT/prt_$name.exr"
    "$PY" tools/validation/cycles_compare.py compare "$OUT/cycles_$ref.exr" "$OUT/prt_$name.exr" --min-pixels 30 \
      --name "frame $name: Cycles $ref vs prt $bands bands $*" || true
  fi
  echo
}

# glossy_case NAME BANDS MAP REF [prt render options]: prt's frame of the glossy room against Cycles'.
glossy_case() {
  local name=$1 bands=$2 map=$3 ref=$4; shift 4
  local glb; glb=$(bake "$bands")
  "$PRT" render "$glb" --env "$map" "$@" --size "$PRT_SIZE" --camera Camera --exr-compression none -q -o "$OUT/prt_$name.exr"
  "$PY" tools/validation/cycles_compare.py compare "$OUT/cycles_$ref.exr" "$OUT/prt_$name.exr" --min-pixels 30 \
    --objects Floor,ShortBox --name "frame $name: Cycles $ref vs prt $bands bands $*" || true
  echo
}

if [ $GLOSSY -eq 1 ]; then
  rows=()
  for m in "${MAPS[@]}"; do
    n=$(basename "$m"); n=${n%%_*}
    [ "$MATERIALS" = principled ] || n=${n}_$MATERIALS
    [ "$CAUSTICS" = 1 ] || n=${n}_nocaustics
    cycles_frame "$n" "$m"
    echo "Map $m, glossy room, 3 bands, $BOUNCES bounces, Cycles $MATERIALS, reflective caustics $([ "$CAUSTICS" = 1 ] && echo on || echo off)."
    glossy_case "${n}_diffuse" 3 "$m" "$n" --materials diffuse
    glossy_case "${n}_full" 3 "$m" "$n" --materials full
    rows+=("$OUT/cycles_$n.exr,$OUT/prt_${n}_diffuse.exr,$OUT/prt_${n}_full.exr")
  done
  "$PY" tools/validation/cycles_compare.py sheet "$OUT/validation_glossy_${MATERIALS}_c$CAUSTICS.png" --exposure 1.0 "${rows[@]}"
  echo "real_maps_validation.sh --glossy: done (reports only)"
  exit 0
fi

if [ $LAMP = 1 ]; then
  cycles_vertex lamp "" "$VSAMPLES"
  cycles_vertex lamp_k0 "" "$CSAMPLES" 0
  cycles_frame lamp ""
  echo "The closed room lit by its own point light and emissive panel, 3 bands."
  case_ lamp_k0 3:0 "" lamp_k0
  case_ lamp 3 "" lamp
  # The same frame with every material Lambertian (Cycles' materials), no dielectric highlight.
  "$PRT" render "$(bake 3)" --materials diffuse --size "$PRT_SIZE" --camera Camera --exr-compression none -q \
    -o "$OUT/prt_lamp_diffuse.exr"
  "$PY" tools/validation/cycles_compare.py compare "$OUT/cycles_lamp.exr" "$OUT/prt_lamp_diffuse.exr" --min-pixels 30 \
    --name "frame lamp_diffuse: Cycles lamp vs prt 3 bands --materials diffuse" || true
  "$PY" tools/validation/cycles_compare.py sheet "$OUT/validation_lamp.png" --exposure 0 \
    "$OUT/cycles_lamp.exr,$OUT/prt_lamp.exr"
  echo "real_maps_validation.sh: done (reports only)"
  exit 0
fi
cycles_vertex white "$WHITE" "$CSAMPLES"
cycles_vertex white_k0 "$WHITE" "$CSAMPLES" 0
cycles_vertex lobes "$OUT/lobes_256.exr" "$CSAMPLES"
names=()
for m in "${MAPS[@]}"; do
  n=$(basename "$m"); n=${n%%_*}; names+=("$n")
  cycles_vertex "$n" "$m" "$VSAMPLES"
  cycles_frame "$n" "$m"
done

echo "Controls (prt exact up to its bake noise): units, bounces, orientation."
case_ white_b3 3 "$WHITE" white
case_ white_b3_k0 3:0 "$WHITE" white_k0
case_ lobes_b6 6 "$OUT/lobes_256.exr" lobes
case_ lobes_b3 3 "$OUT/lobes_256.exr" lobes
i=0
for m in "${MAPS[@]}"; do
  n=${names[$i]}; i=$((i + 1))
  echo "Map $m, 3 bands, $BOUNCES bounces."
  case_ "${n}_before" 3 "$m" "$n" --no-direct-lights
  [ -z "$NO_SUN_OPTION" ] || case_ "${n}_nosun" 3 "$m" "$n" "$NO_SUN_OPTION"
  case_ "${n}_after" 3 "$m" "$n"
  case " ${BAKE_ARGS:-} " in *" --operator "*) case_ "${n}_traced" 3 "$m" "$n" --no-operator ;; esac
done

rows=()
for n in "${names[@]}"; do
  [ -f "$OUT/prt_${n}_after.exr" ] && rows+=("$OUT/cycles_$n.exr,$OUT/prt_${n}_before.exr,$OUT/prt_${n}_after.exr")
done
[ ${#rows[@]} -eq 0 ] || "$PY" tools/validation/cycles_compare.py sheet "$OUT/validation_real_maps.png" --exposure 1.0 "${rows[@]}"
echo "real_maps_validation.sh: done (reports only)"
