// Light-update benchmark of the bounce operator (docs/lights.md, "The bounce operator"): what
// `prt render` does on the CPU when a light changes, next to the SH product alone, measured in
// the same run, in wall and process CPU time (CLOCK_PROCESS_CPUTIME_ID, all threads: on a shared
// machine the CPU time per update compares runs made under different load).
//
//   prt_bench_operator [--baked FILE.glb] [--frames 8] [--threads 2] [--json out.json]
//
// FILE.glb: a scene baked by `prt bake` (which stores the operator unless --no-operator). Without
// it, the bundled room (scenes/cornell_open.gltf) is baked in the process with `prt bake`'s
// defaults (1024 samples, 2 bounces, 3 bands) but without refinement, which takes a few seconds:
// the JSON's `bake` gives the surface bake's and the operator's build times (wall, the same
// threads) and the operator's packed bytes next to the transfer's (RGB and direct part, as
// floats). With FILE.glb it gives the operator's packed bytes and the file's size.
// The light: scenes/env/royal_esplanade_128.hdr, turned 0° → 315° over the frames, its suns split
// off as `prt render --env` splits them (each frame moves them, so each frame is a light
// change). Each frame is one bake::FrameLighting::at, as in `prt render`: the rig, the shadow
// rays at the clusters' sample points, the sky bins and the sparse products; the renderer's
// own share (uniforms, probe upload) is not in it. The SH product alone is the per-vertex dot
// product of every baked vertex side's transfer with the frame's SH (relightVertices and
// relightBackVertices), the floor a light update through SH alone costs.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <optional>
#include <string>
#include <vector>

#include <tbb/global_control.h>
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "bench_cli.h"
#include "cpu_clock.h"
#include "prt/bake/bounce_operator.h"
#include "prt/bake/frame_lighting.h"
#include "prt/bake/surface_bake.h"
#include "prt/bounce_operator.h"
#include "prt/error.h"
#include "prt/huge_pages.h"
#include "prt/light_rig.h"
#include "prt/relight.h"
#include "prt/scene.h"

namespace prt {
namespace {

using bench::Clock;
using bench::median;
using bench::msSince;

// The bundled room as `prt bake` bakes it with its defaults (no refinement), and what its
// bake and its operator cost.
Scene bakeRoom(int threads, nlohmann::json& cost) {
  Scene scene = loadScene(PRT_SOURCE_DIR "/scenes/cornell_open.gltf");
  bake::BakeSettings bs;
  bs.threads = threads;
  bs.keepLowerOrder = false;
  bake::OperatorSettings os;
  os.samples = std::min(os.samples, bs.samples);
  os.threads = threads;
  bs.keepGatherRays = os.samples;  // as the pipeline keeps them for the operator
  const auto t0 = Clock::now();
  bake::SurfaceTransfer t = bake::bakeSurface(scene, bs);
  const double surfaceMs = msSince(t0);
  scene.transferBands = t.bands;
  size_t transferBytes = 0;
  for (const auto& m : t.perMesh) transferBytes += m.size() * sizeof(glm::vec3);
  for (const auto& m : t.perMeshDirect) transferBytes += m.size() * sizeof(float);
  bake::storeTransfer(scene, t.perMesh, t.perMeshDirect);
  scene.bakeRecord = bake::bakeRecord(bs, "cornell_open.gltf", "bench");
  const auto t1 = Clock::now();
  scene.bounceOperator = std::make_shared<BounceOperator>(
      bake::buildBounceOperator(scene, os, bs.bounces, bs.seed, false, nullptr, nullptr, &t.gather));
  const double operatorMs = msSince(t1);
  const size_t operatorBytes = packOperator(*scene.bounceOperator).bytes.size();
  cost = {{"surface_bake_ms", surfaceMs},
          {"operator_build_ms", operatorMs},
          {"operator_over_surface_bake", operatorMs / std::max(surfaceMs, 1e-9)},
          {"operator_bytes", operatorBytes},
          {"transfer_bytes", transferBytes},
          {"operator_over_transfer", double(operatorBytes) / double(std::max<size_t>(transferBytes, 1))}};
  return scene;
}

LightRig turningMap(int frames) {
  LightRig rig;
  RigLight env;
  env.type = RigLight::Type::Environment;
  env.file = PRT_SOURCE_DIR "/scenes/env/royal_esplanade_128.hdr";
  env.rotation = Track::ramp(0.0, 0.0, std::max(frames - 1, 1), 315.0);
  rig.lights = {env};
  rig.validate();
  return rig;
}

nlohmann::json run(const Scene& scene, int frames, int threads) {
  const BounceOperator& op = *scene.bounceOperator;
  LightRig rig = turningMap(frames);
  rig.prepare(scene.transferBands);
  bake::FrameLightingSettings settings;
  settings.shadowSamples = 4;  // as prt render
  settings.threads = threads;
  bake::FrameLighting lighting(scene, rig, settings);
  std::optional<tbb::global_control> limit;  // the SH product on as many threads
  if (threads > 0) limit.emplace(tbb::global_control::max_allowed_parallelism, size_t(threads));
  std::vector<double> wall, cpu, sh, shCpu;
  size_t suns = 0;
  for (int i = -1; i < frames; ++i) {  // frame -1: warm-up, not timed
    const double c0 = bench::processCpuSeconds();
    const auto t0 = Clock::now();
    bake::FrameLight light = lighting.at(std::max(i, 0));
    const double ms = msSince(t0), cpuMs = 1e3 * (bench::processCpuSeconds() - c0);
    const double c1 = bench::processCpuSeconds();
    const auto t1 = Clock::now();
    {
      const auto front = relightVertices(scene, light.rig.sh);
      const auto back = relightBackVertices(scene, light.rig.sh);
      PRT_CHECK(front.size() == scene.meshes.size() && back.size() == scene.meshes.size());
    }
    const double shMs = msSince(t1), shCpuMs = 1e3 * (bench::processCpuSeconds() - c1);
    if (i < 0 && !lighting.usesOperator()) throw Error("the light update does not go through the bounce operator");
    if (i < 0) continue;
    wall.push_back(ms), cpu.push_back(cpuMs), sh.push_back(shMs), shCpu.push_back(shCpuMs);
    suns = light.rig.direct.size();
  }
  const bake::FrameLightingStats& st = lighting.stats();
  const double updates = std::max(st.updates, 1);
  return {{"vertex_sides", op.vertexSides},
          {"clusters", op.clusters},
          {"cluster_entries", op.clusterRows.entries()},
          {"gradient_entries", op.clusterGradients.entries()},
          {"bounces", op.bounces},
          {"direct_lights", suns},
          {"frames", frames},
          {"threads", threads},
          {"light_update_ms", median(wall)},
          {"light_update_cpu_ms", median(cpu)},
          {"shadow_ms", 1e3 * st.shadowSeconds / updates},
          {"products_ms", 1e3 * st.gatherSeconds / updates},
          {"sky_bins_ms", 1e3 * st.skySeconds / updates},
          {"cluster_products_ms", 1e3 * st.clusterSeconds / updates},
          {"vertex_products_ms", 1e3 * st.vertexSeconds / updates},
          {"sh_product_ms", median(sh)},
          {"sh_product_cpu_ms", median(shCpu)},
          {"update_over_sh_product", median(cpu) / std::max(median(shCpu), 1e-9)}};
}

}  // namespace
}  // namespace prt

int main(int argc, char** argv) {
  using namespace prt;
  tuneHeap();
  std::string bakedPath, jsonPath;
  int frames = 8, threads = 2;
  CLI::App app{"Bounce operator benchmark: the light update of prt render next to the SH product alone",
               "prt_bench_operator"};
  app.add_option("--baked", bakedPath,
                 "Scene baked by prt bake with its operator (default: the bundled room, baked here)");
  app.add_option("--frames", frames, "Timed light changes")->check(CLI::Range(1, 10000))->capture_default_str();
  app.add_option("--threads", threads, "Threads (0: all cores)")->check(CLI::Range(0, 1024))->capture_default_str();
  app.add_option("--json", jsonPath, "Also write the results to this file");
  if (std::optional<int> status = bench::parseBenchOptions(app, "prt_bench_operator", argc, argv)) return *status;
  try {
    nlohmann::json cost;
    Scene scene = bakedPath.empty() ? bakeRoom(threads, cost) : loadScene(bakedPath);
    if (!scene.bounceOperator)
      throw Error(bakedPath + ": no bounce operator in this file (baked with prt bake --no-operator?)");
    if (!bakedPath.empty())
      cost = {{"operator_bytes", packOperator(*scene.bounceOperator).bytes.size()},
              {"file_bytes", std::filesystem::file_size(bakedPath)}};
    nlohmann::json j = run(scene, frames, threads);
    j["bake"] = cost;
    j["scene"] = bakedPath.empty() ? std::string("scenes/cornell_open.gltf (baked here)") : bakedPath;
    const std::string text = j.dump(2);
    std::printf("%s\n", text.c_str());
    if (!jsonPath.empty()) std::ofstream(jsonPath) << text << "\n";
  } catch (const Error& e) {
    std::fprintf(stderr, "prt_bench_operator: %s\n", e.what());
    return 1;
  }
  return 0;
}
