#!/usr/bin/env bash
# CliGltfValidator: every kind of glTF file prt writes passes the Khronos glTF Validator
# (tools/validation/gltf_validate.js, the npm package gltf-validator under Node) with 0 errors:
# scenes/cornell_open.gltf baked (.glb) and relit under a map (.glb) and under a map and a sun
# (.gltf); a floor under a lid (gltf_validator_scene.js) baked with refinement and flat-normal
# splits (.glb and .gltf) and relit; the room baked with its bounce operator (.glb, and relit
# through it). Few samples: the files matter, not the light.
#
# usage: cli_gltf_validator.sh PRT NODE NODE_MODULES SOURCE_DIR
# Writes into a fresh temporary folder, removed at the end unless a step failed.
# Exits 77, which ctest reports as skipped (SKIP_RETURN_CODE), where node or the package is
# missing; non-zero otherwise when a command fails or a file has an error.
set -euo pipefail
[ $# -eq 4 ] || { echo "usage: $0 PRT NODE NODE_MODULES SOURCE_DIR" >&2; exit 2; }
prt=$1 node=$2 modules=$3 src=$4

skip() { echo "SKIPPED: $*"; exit 77; }
[ -x "$node" ] || skip "node not found (Debian package nodejs; tools/setup.sh installs it)"
export NODE_PATH=$modules
"$node" -e "require('gltf-validator')" 2>/dev/null ||
  skip "the npm package gltf-validator is not in $modules (tools/setup.sh installs it there)"

work=$(mktemp -d "${TMPDIR:-/tmp}/prt_gltf_validator.XXXXXX")
trap 'status=$?; if [ $status -eq 0 ]; then rm -rf "$work"; else echo "outputs kept in $work"; fi' EXIT
cd "$work"
run() { echo "+ prt $*"; "$prt" "$@"; }
env=$src/scenes/env/royal_esplanade_128.hdr
bake=(--samples 32 --refine-samples 32 --threads 2)

run bake "$src/scenes/cornell_open.gltf" -o room.glb "${bake[@]}"
run relight room.glb --env "$env" --bounce-samples 16 --threads 2 -o room_lit.glb
run relight room.glb --env "$env" --sun-elevation 50 --sun-azimuth 30 --bounce-samples 16 --threads 2 \
  -o room_sun_lit.gltf

"$node" "$src/tests/gltf_validator_scene.js" lid.gltf
run bake lid.gltf -o lid_baked.glb "${bake[@]}" 2>&1 | tee lid_bake.log
if ! grep -q "refinement: 8 -> [0-9]" lid_bake.log || grep -q "refinement: 8 -> 8 " lid_bake.log; then
  echo "the bake of lid.gltf was expected to refine the floor (refinement: 8 -> more vertices)"
  exit 1
fi
run bake lid.gltf -o lid_baked.gltf "${bake[@]}"
run relight lid_baked.glb --env "$env" --bounce-samples 16 --threads 2 -o lid_lit.glb
run bake "$src/scenes/cornell_open.gltf" -o room_operator.glb "${bake[@]}" --operator
run relight room_operator.glb --env "$env" --threads 2 -o room_operator_lit.glb

"$node" "$src/tools/validation/gltf_validate.js" room.glb room_lit.glb room_sun_lit.gltf lid_baked.glb \
  lid_baked.gltf lid_lit.glb room_operator.glb room_operator_lit.glb
