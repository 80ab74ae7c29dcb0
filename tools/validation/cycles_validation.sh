#!/usr/bin/env bash
# End-to-end check of prt's radiance against Blender Cycles (docs/validation.md).
#
#   tools/validation/cycles_validation.sh [OUTDIR]   (default build/validation in the repository;
#                                                     a relative OUTDIR is taken from the current folder)
#
# Needs build/tools/prt (bash tools/setup.sh demo, or any build) and Blender 3.4
# (`apt-get install blender`: a validation tool, not a dependency of the build or the tests).
# For each case Cycles renders scenes/cornell_open.gltf without its receiver
# (tools/validation/cycles_reference.py) and prt bakes and renders the same camera; the two linear EXRs are
# compared region by region (object faces from Cycles' object-index and normal passes, and a
# 4x3 grid of image tiles; every mask eroded by 2 pixels away from edges) by
# tools/validation/cycles_compare.py (python3, standard library only).
#
# Skies: white_sky_64.hdr (uniform, band 0 only) and a generated "lobes" sky (one positive
# polynomial lobe of degree 4 per colour channel, towards +X, +Z and -X: exactly bands 0-4, so
# prt at 6 bands must match a path tracer up to noise, and any error in the map's orientation
# shows as swapped colours); the Royal Esplanade map only to report the band-limit error.
#
# Exit status 0 when every expectation holds: the band-limited skies agree on every region
# within TOL plus two standard errors of Cycles' noise (0 and 2 bounces; the lobes sky also
# turned 90 degrees in both renderers); the deliberately wrong settings (a bounce short or one
# too many, prt's sky turned 90 degrees and Cycles' not) fail. Anything else exits 1. The
# band-limit report changes no exit status.
#
# Environment: SAMPLES (Cycles samples per pixel, default 1024), BAKE_SAMPLES (prt bake
# --samples, default 4096), SIZE (default 160x90), TOL (default 0.03), BLENDER, PRT, THREADS.
# Existing Cycles renders in OUTDIR are reused when their .json matches (delete them to redo).
set -euo pipefail
[ $# -le 1 ] || { echo "usage: tools/validation/cycles_validation.sh [OUTDIR]" >&2; exit 2; }
OUT=$(realpath -m -- "${1:-$(dirname "$0")/../../build/validation}")
cd "$(dirname "$0")/../.."
SAMPLES=${SAMPLES:-1024}
BAKE_SAMPLES=${BAKE_SAMPLES:-4096}
SIZE=${SIZE:-160x90}
TOL=${TOL:-0.03}
BLENDER=${BLENDER:-blender}
PRT=${PRT:-build/tools/prt}
THREADS=${THREADS:-0}
PY=/usr/bin/python3
SCENE=scenes/cornell_open.gltf
CAMERA=Camera
WHITE=scenes/env/white_sky_64.hdr
ROYAL=scenes/env/royal_esplanade_128.hdr
BOUNCES=2

command -v "$BLENDER" >/dev/null || { echo "cycles_validation.sh: $BLENDER not found (apt-get install blender)" >&2; exit 1; }
[ -x "$PRT" ] || { echo "cycles_validation.sh: $PRT not found (build prt first)" >&2; exit 1; }
mkdir -p "$OUT"

COMPARE_PY=$(cat tools/validation/cycles_compare.py)  # compare | sheet | lobes (standard library only)

# cycles NAME ENV ROTATE [BOUNCES]: Cycles reference of the scene, reused if its settings match.
cycles() {
  local exr="$OUT/cycles_$1.exr" k=${4:-$BOUNCES}
  if [ -f "$exr.json" ] && "$PY" -c "import json,sys; m=json.load(open('$exr.json')); \
sys.exit(0 if (m['env'],m['env_rotate_deg'],m['samples'],m['bounces'],m['size'])==('$2',float('$3'),$SAMPLES,$k,[int(v) for v in '$SIZE'.split('x')]) else 1)"; then
    echo "reusing $exr"
  else
    rm -f "$exr" "$exr.json"
    nice "$BLENDER" -b --factory-startup --python tools/validation/cycles_reference.py -- --scene "$SCENE" \
      --remove Receiver --env "$2" --env-rotate "$3" --bounces "$k" --samples "$SAMPLES" \
      --size "$SIZE" --camera "$CAMERA" --threads "$THREADS" -o "$exr" | grep -E '^(cycles_reference|Error)' || true
    [ -f "$exr" ] || { echo "cycles_validation.sh: Cycles render $exr failed" >&2; exit 1; }
  fi
}

# bake BANDS BOUNCES: prt bake of the scene (the receiver is left out of the bake by its extras).
bake() {
  local glb="$OUT/prt_b$1_k$2_s$BAKE_SAMPLES.glb"
  [ -f "$glb" ] || nice "$PRT" bake "$SCENE" -o "$glb" --bands "$1" --bounces "$2" --samples "$BAKE_SAMPLES" -q
}

# render NAME BANDS BOUNCES ENV ROTATE: prt render of the baked scene (no probes: no receiver drawn).
render() {
  nice "$PRT" render "$OUT/prt_b$2_k$3_s$BAKE_SAMPLES.glb" --env "$4" --env-rotate "$5" --size "$SIZE" --camera "$CAMERA" \
    --exr-compression none -q -o "$OUT/prt_$1.exr"
}

# compare CYCLES PRT [compare options]: prints the table; returns 0 (within TOL) or 3.
compare() {
  local c="$1" p="$2"; shift 2
  "$PY" -c "$COMPARE_PY" compare "$OUT/cycles_$c.exr" "$OUT/prt_$p.exr" --tol "$TOL" --name "Cycles $c vs prt $p" "$@"
}

status=0
# check pass|fail CYCLES PRT WHAT: compare, and record whether the outcome is the expected one.
check() {
  local rc=0; compare "$2" "$3" || rc=$?
  [ $rc -eq 0 ] || [ $rc -eq 3 ] || exit $rc
  if { [ "$1" = pass ] && [ $rc -eq 0 ]; } || { [ "$1" = fail ] && [ $rc -eq 3 ]; }; then
    echo "   as expected ($1): $4"
  else
    echo "   UNEXPECTED (expected $1): $4"; status=1
  fi
  echo
}
# report CYCLES PRT: compare, whatever the outcome.
report() { local rc=0; compare "$1" "$2" || rc=$?; [ $rc -eq 0 ] || [ $rc -eq 3 ] || exit $rc; echo; }

"$PY" -c "$COMPARE_PY" lobes "$OUT/lobes_256.exr"
LOBES="$OUT/lobes_256.exr"

cycles white "$WHITE" 0
cycles white_k0 "$WHITE" 0 0
cycles lobes "$LOBES" 0
cycles lobes_r90 "$LOBES" 90
cycles royal "$ROYAL" 0
bake 3 "$BOUNCES"; bake 3 $((BOUNCES - 1)); bake 3 0; bake 6 "$BOUNCES"; bake 8 "$BOUNCES"
render white_b3 3 "$BOUNCES" "$WHITE" 0
render white_b3_short 3 $((BOUNCES - 1)) "$WHITE" 0
render white_b3_k0 3 0 "$WHITE" 0
render lobes_b6 6 "$BOUNCES" "$LOBES" 0
render lobes_b6_r90 6 "$BOUNCES" "$LOBES" 90
render lobes_b3 3 "$BOUNCES" "$LOBES" 0
for b in 3 6 8; do render royal_b$b $b "$BOUNCES" "$ROYAL" 0; done

echo "1. Band-limited skies: prt must agree with Cycles on every region (TOL $TOL plus 2 noise)."
check pass white white_b3 "uniform sky (band 0 only: exact at any band count), $BOUNCES bounces"
check pass white_k0 white_b3_k0 "uniform sky, 0 bounces (direct light only: Cycles diffuse bounces 0)"
check pass lobes lobes_b6 "coloured lobes sky (bands 0-4) at 6 bands: the map's orientation"
check pass lobes_r90 lobes_b6_r90 "the same sky turned 90 degrees about +Y in both (Cycles: Mapping node about Blender +Z)"

echo "2. Teeth: deliberately wrong prt settings must fail."
check fail white white_b3_short "prt baked with $((BOUNCES - 1)) bounces against Cycles with $BOUNCES"
check fail white_k0 white_b3_short "prt baked with $((BOUNCES - 1)) bounces against Cycles with 0 (one too many)"
check fail lobes lobes_b6_r90 "prt's sky turned 90 degrees, Cycles' not"

echo "3. Band limit, reported (not pass/fail): the lobes sky at 3 bands, the Royal Esplanade map at 3, 6, 8."
report lobes lobes_b3
for b in 3 6 8; do report royal royal_b$b; done

"$PY" -c "$COMPARE_PY" sheet "$OUT/validation_cycles.png" --exposure 1.5 \
  "$OUT/cycles_lobes.exr,$OUT/prt_lobes_b6.exr,$OUT/prt_lobes_b6_r90.exr" \
  "$OUT/cycles_royal.exr,$OUT/prt_royal_b3.exr,$OUT/prt_royal_b8.exr"
[ $status -eq 0 ] && echo "cycles_validation.sh: every expectation held" || echo "cycles_validation.sh: some expectation failed"
exit $status
