#!/usr/bin/env bash
# The one set-up script of prt, for a fresh Debian 12 machine:
#
#   bash tools/setup.sh demo   # install, build, bake and relight the default scene
#   bash tools/setup.sh test   # install, build, run the test suite (CI runs this)
#
# 1. installs the Debian packages prt needs (skipped when all are installed already), and
#    the Khronos glTF Validator (npm, pinned) into node_modules/ for the tests;
# 2. configures and builds Release with Ninja into build/;
# 3. demo: bakes scenes/cornell_open.gltf (surface + probes), relights it and renders frames
#    (a turning sky, then a lamp moving inside the room)
#    into out/;
#    test: checks the code's shape (tools/check_shape.sh: function and file lengths); runs
#    ctest in build/; then builds the suite with AddressSanitizer +
#    UndefinedBehaviorSanitizer (clang) in build-asan/ and runs ctest there; then builds the
#    libFuzzer targets in the same build-asan/ and runs each for PRT_FUZZ_SECONDS (default 10) on a
#    temporary copy of its seed corpus. Exits non-zero if any phase fails.
#    PRT_TEST_PHASES (default "shape release asan fuzz") picks phases.
# Run as root, or as a user with sudo (used for apt-get only). Under sudo, the build and the
# outputs belong to the user who ran sudo when that user owns the checkout.
set -euo pipefail

PACKAGES=(
  cmake ninja-build g++ pkg-config
  libopenvdb-dev libopenvdb-tools python3-openvdb libboost-iostreams-dev
  libembree-dev libglm-dev libopenexr-dev libtinygltf-dev nlohmann-json3-dev libstb-dev
  libtbb-dev libcli11-dev libosmesa6-dev libegl-dev libegl1-mesa-dev libgl1-mesa-dri
  libgtest-dev libdraco-dev libmeshoptimizer-dev libwebp-dev gltfpack
  libopenmpi-dev openmpi-bin
  clang-14 libclang-rt-14-dev llvm-14
  universal-ctags
)
# Node and npm run the Khronos glTF Validator in the tests: Debian's packages, unless a node
# with npm is there already (NodeSource's nodejs carries its own npm and conflicts with
# Debian's npm package).
if ! { command -v node && command -v npm; } >/dev/null 2>&1; then
  PACKAGES+=(nodejs npm)
fi

usage() {
  cat <<'EOF'
usage: bash tools/setup.sh demo|test

  demo   install dependencies, build, then bake scenes/cornell_open.gltf and relight it
         with scenes/env/royal_esplanade_128.hdr into out/
  test   install dependencies, build, check function and file lengths (tools/check_shape.sh),
         run the test suite (ctest); then the same suite
         built with ASan + UBSan (build-asan/), then each fuzz target for 10 s (also in build-asan/);
         exit non-zero if any phase fails

Installs Debian 12 packages with apt-get (as root, or through sudo) and the glTF Validator
with npm into node_modules/, and builds Release with Ninja into build/.
EOF
}

say() { printf '==> %s\n' "$*"; }
die() { printf 'setup.sh: error: %s\n' "$*" >&2; exit 1; }

if [ $# -ne 1 ]; then
  usage >&2
  exit 2
fi
case "$1" in
  demo | test) mode=$1 ;;
  -h | --help) usage; exit 0 ;;
  *) printf 'setup.sh: unknown command "%s"\n\n' "$1" >&2; usage >&2; exit 2 ;;
esac

root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
cd "$root"

# --- 1. Dependencies ---------------------------------------------------------------------
missing=()
for p in "${PACKAGES[@]}"; do
  status=$(dpkg-query -W -f='${Status}' "$p" 2>/dev/null || true)
  [ "$status" = "install ok installed" ] || missing+=("$p")
done

if [ ${#missing[@]} -eq 0 ]; then
  say "dependencies: all ${#PACKAGES[@]} packages already installed"
else
  command -v apt-get >/dev/null 2>&1 ||
    die "apt-get not found: prt is set up on Debian 12; missing packages: ${missing[*]}"
  if [ "$(id -u)" -eq 0 ]; then
    sudo_cmd=()
  elif command -v sudo >/dev/null 2>&1; then
    sudo_cmd=(sudo)
  else
    die "installing packages needs root: run as root or install sudo (missing: ${missing[*]})"
  fi
  say "dependencies: installing ${#missing[@]} missing packages: ${missing[*]}"
  "${sudo_cmd[@]}" env DEBIAN_FRONTEND=noninteractive apt-get update
  "${sudo_cmd[@]}" env DEBIAN_FRONTEND=noninteractive apt-get install -y "${PACKAGES[@]}"
fi

# Under sudo, build as the invoking user when they own the checkout, so build/ and out/ do
# not end up owned by root.
as_user=()
if [ "$(id -u)" -eq 0 ] && [ -n "${SUDO_USER:-}" ] && [ "$SUDO_USER" != root ] &&
   [ "$(stat -c %U "$root")" = "$SUDO_USER" ]; then
  as_user=(sudo -u "$SUDO_USER")
  say "building as $SUDO_USER (the owner of $root)"
fi
run() { "${as_user[@]}" "$@"; }

# The Khronos glTF Validator, which the test CliGltfValidator runs on prt's outputs: pinned,
# into the checkout's node_modules/ (git-ignored, the user's), where CMake and
# tools/validation/gltf_validate.js find it.
gltf_validator=2.0.0-dev.3.10
installed=$(node -p "require('./node_modules/gltf-validator/package.json').version" 2>/dev/null || true)
if [ "$installed" = "$gltf_validator" ]; then
  say "gltf-validator $gltf_validator already in node_modules/"
else
  say "installing gltf-validator $gltf_validator with npm into node_modules/"
  run npm install --prefix "$root" --no-save --no-audit --no-fund "gltf-validator@$gltf_validator" ||
    die "npm could not install gltf-validator@$gltf_validator (the tests need it: CliGltfValidator)"
fi

# --- 2. Build ----------------------------------------------------------------------------
if [ -f build/CMakeCache.txt ] && ! grep -q '^CMAKE_GENERATOR:INTERNAL=Ninja$' build/CMakeCache.txt; then
  die "build/ was configured with another generator than Ninja; remove it (rm -rf build) and rerun"
fi
build_start=$SECONDS
say "configuring (Release, Ninja) in build/"
run cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release
say "building"
run cmake --build build
build_seconds=$((SECONDS - build_start))

# --- 3. Demo or tests --------------------------------------------------------------------
case "$mode" in
  demo)
    run mkdir -p out
    say "baking scenes/cornell_open.gltf"
    run build/tools/prt bake scenes/cornell_open.gltf -o out/cornell.baked.glb \
      --probes out/cornell.probes.vdb --probe-dims 16,16,16
    say "relighting with scenes/env/royal_esplanade_128.hdr"
    run build/tools/prt relight out/cornell.baked.glb --env scenes/env/royal_esplanade_128.hdr \
      -o out/cornell.lit.glb --csv out/cornell.csv
    run build/tools/prt info out/cornell.probes.vdb
    say "rendering a turntable of the sky with the receiver moving, lit from the probes (8 frames)"
    run mkdir -p out/frames
    run build/tools/prt render out/cornell.baked.glb --probes out/cornell.probes.vdb \
      --env scenes/env/royal_esplanade_128.hdr --env-rotate 0:315 --frames 0-7 --fps 2 \
      --size 640x360 --gl osmesa --msaa 4 --png --exposure 1 --contact-sheet out/contact_sheet.png \
      -o out/frames/frame_%04d.exr
    say "rendering the room at night, lit only by a lamp circling under its ceiling (8 frames)"
    run mkdir -p out/lamp_frames
    run build/tools/prt render out/cornell.baked.glb --probes out/cornell.probes.vdb \
      --rig scenes/rigs/lamp_cornell.json --frames 0-7 \
      --size 640x360 --gl osmesa --msaa 4 --png --contact-sheet out/lamp_contact_sheet.png \
      -o out/lamp_frames/frame_%04d.exr
    say "done. Outputs in $root/out:"
    printf '    %s\n' \
      "out/cornell.baked.glb  the scene with per-vertex SH transfer (input of prt relight)" \
      "out/cornell.lit.glb    per-vertex radiance as _RADIANCE, clamped as COLOR_0 (open in any glTF viewer)" \
      "out/cornell.csv        the same per-vertex radiance as a table" \
      "out/cornell.probes.vdb the probe grid (OpenVDB: vdb_print, pyopenvdb, Blender)" \
      "out/frames/            relit frames, linear EXR and tone-mapped PNG" \
      "out/contact_sheet.png  all frames on one page" \
      "out/lamp_frames/       the room lit by a moving lamp (scenes/rigs/lamp_cornell.json)" \
      "out/lamp_contact_sheet.png  those frames on one page"
    ;;
  test)
    phases=${PRT_TEST_PHASES:-shape release asan fuzz}
    fuzz_seconds=${PRT_FUZZ_SECONDS:-10}
    status=0
    phase_times=()
    timed() {  # timed NAME COMMAND...: runs, records the seconds, keeps the first failure
      local name=$1 start=$SECONDS rc=0
      shift
      "$@" || rc=$?
      phase_times+=("$name $((SECONDS - start)) s$([ "$rc" -eq 0 ] || echo " (FAILED, status $rc)")")
      [ "$rc" -eq 0 ] || [ "$status" -ne 0 ] || status=$rc
    }
    shape_check() { run bash tools/check_shape.sh; }
    release_tests() { (cd build && run ctest --output-on-failure -j2); }
    # Sanitizers: clang, every target instrumented; options in tests/CMakeLists.txt.
    # Built without MPI (the MPI tests skip there): Open MPI under ASan is untested, and the
    # release phase runs the MPI tests.
    # One sanitizer build serves both phases: the tests and the fuzz targets, every object
    # with ASan + UBSan and the loaders (probes/) with the fuzzer's coverage as well (which
    # the tests do not notice), so CI compiles the library once with clang instead of twice.
    asan_configure() {
      run cmake -S . -B build-asan -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
        -DCMAKE_C_COMPILER=clang-14 -DCMAKE_CXX_COMPILER=clang++-14 \
        -DPRT_SANITIZE=address,undefined -DPRT_FUZZ=ON -DPRT_BUILD_BENCH=OFF -DPRT_MPI=OFF
    }
    asan_build() { asan_configure && run cmake --build build-asan; }
    asan_tests() { (cd build-asan && run ctest --output-on-failure -j2); }
    fuzz_build() { asan_configure && run cmake --build build-asan --target fuzz_gltf fuzz_image fuzz_vdb fuzz_rig; }
    fuzz_runs() { run bash tests/fuzz/run.sh build-asan "$fuzz_seconds"; }

    phase_times+=("release build $build_seconds s")
    for phase in $phases; do
      case "$phase" in
        shape) say "checking function and file lengths (tools/check_shape.sh)"; timed "shape check" shape_check ;;
        release) say "running the tests (ctest, Release)"; timed "release tests" release_tests ;;
        asan)
          say "building with AddressSanitizer + UndefinedBehaviorSanitizer in build-asan/"
          timed "asan build" asan_build
          say "running the tests under ASan + UBSan"
          timed "asan tests" asan_tests ;;
        fuzz)
          say "building the fuzz targets in build-asan/"
          timed "fuzz build" fuzz_build
          say "fuzzing each loader for $fuzz_seconds s"
          timed "fuzz runs" fuzz_runs ;;
        *) die "PRT_TEST_PHASES: unknown phase '$phase' (shape, release, asan, fuzz)" ;;
      esac
    done
    say "phase times:"
    printf '    %s\n' "${phase_times[@]}"
    if [ "$status" -eq 0 ]; then say "all tests passed"; else say "tests FAILED (exit status $status)"; fi
    exit "$status"
    ;;
esac
