// Surface-bake benchmark: the bake's rays/s next to the raw Embree ceiling for the same rays on
// the same scene, measured in the same process, and the cost of every bounce.
//
//   prt_bench_bake [--scene scenes/cornell_open.gltf] [--min-vertices 100000] [--samples 256]
//                  [--bounces 2] [--threads 0] [--ceiling-fraction 0.1] [--json out.json]
//
// The scene is refined (each triangle split into 4, repeatedly) until it has at least
// --min-vertices baked vertices. The ceiling traces exactly the rays the bake casts (same
// origins, directions and streams of 256 per vertex, generated beforehand, outside the timer)
// for a fraction of the vertices, with nothing done per ray: the rate the bake could reach if
// SH evaluation, accumulation and hit bookkeeping cost nothing.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <map>
#include <string>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>

#include "bench_cli.h"
#include "prt/bake/ray_scene.h"
#include "prt/bake/surface_bake.h"
#include "prt/error.h"
#include "prt/progress.h"
#include "prt/scene.h"

namespace {

using namespace prt;
using Clock = std::chrono::steady_clock;

// Splits every triangle into 4 (midpoints shared through an edge map), interpolating normals,
// texture coordinates and colours.
void refine(MeshInstance& m) {
  std::map<std::pair<uint32_t, uint32_t>, uint32_t> mid;
  auto midpoint = [&](uint32_t a, uint32_t b) {
    auto key = std::minmax(a, b);
    auto it = mid.find(key);
    if (it != mid.end()) return it->second;
    uint32_t i = uint32_t(m.positions.size());
    m.positions.push_back(0.5f * (m.positions[a] + m.positions[b]));
    m.normals.push_back(glm::normalize(m.normals[a] + m.normals[b]));
    if (!m.texcoords.empty()) m.texcoords.push_back(0.5f * (m.texcoords[a] + m.texcoords[b]));
    if (!m.colors.empty()) m.colors.push_back(0.5f * (m.colors[a] + m.colors[b]));
    mid.emplace(key, i);
    return i;
  };
  std::vector<uint32_t> out;
  out.reserve(m.indices.size() * 4);
  for (size_t t = 0; t < m.triangleCount(); ++t) {
    uint32_t a = m.indices[3 * t], b = m.indices[3 * t + 1], c = m.indices[3 * t + 2];
    uint32_t ab = midpoint(a, b), bc = midpoint(b, c), ca = midpoint(c, a);
    out.insert(out.end(), {a, ab, ca, ab, b, bc, ca, bc, c, ab, bc, ca});
  }
  m.indices = std::move(out);
}

size_t bakedVertices(const Scene& s) {
  size_t n = 0;
  for (const MeshInstance& m : s.meshes) n += m.receiverOnly ? 0 : m.vertexCount();
  return n;
}

}  // namespace

int main(int argc, char** argv) {
  std::string scenePath = PRT_SOURCE_DIR "/scenes/cornell_open.gltf", jsonPath;
  size_t minVertices = 100000;
  bake::BakeSettings settings;
  settings.samples = 256;
  settings.bounces = 2;
  double ceilingFraction = 0.1;
  CLI::App app{"Surface-bake benchmark: the bake's rays/s next to the Embree ceiling for the same rays",
               "prt_bench_bake"};
  app.add_option("--scene", scenePath, "Scene to bake (.gltf)")->capture_default_str();
  app.add_option("--min-vertices", minVertices, "Refine the scene until it has at least this many baked vertices")
      ->capture_default_str();
  app.add_option("--samples", settings.samples, "Hemisphere directions per vertex")->capture_default_str();
  app.add_option("--bounces", settings.bounces, "Interreflection bounces")->capture_default_str();
  app.add_option("--threads", settings.threads, "Worker threads (0 = all cores)")->capture_default_str();
  app.add_option("--ceiling-fraction", ceilingFraction, "Share of the vertices the ceiling traces")
      ->check(CLI::Range(1e-6, 1.0))
      ->capture_default_str();
  app.add_option("--json", jsonPath, "Also write the results to this file");
  if (std::optional<int> status = bench::parseBenchOptions(app, "prt_bench_bake", argc, argv)) return *status;
  try {
    Scene scene = loadScene(scenePath);
    while (bakedVertices(scene) < minVertices)
      for (MeshInstance& m : scene.meshes)
        if (!m.receiverOnly) refine(m);
    std::unique_ptr<tbb::global_control> limit;
    if (settings.threads > 0)
      limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, settings.threads);

    // The ceiling: the same rays, pre-generated into one array, traced with nothing else to do.
    // Vertices are taken in runs of 64 consecutive ones (the bake's unit of work, so the same
    // BVH locality), every (1/fraction)-th run. Measured twice, before and after the bake, and
    // the faster kept: the machine is shared, and noise must not flatter the bake.
    bake::RayScene rays(scene);
    const size_t V = bakedVertices(scene);
    const size_t every = std::max<size_t>(1, size_t(std::lround(1.0 / ceilingFraction)));
    std::vector<size_t> picked;
    for (size_t run = 0; run * 64 < V; run += every)
      for (size_t v = run * 64; v < std::min(V, run * 64 + 64); ++v) picked.push_back(v);
    std::vector<bake::Ray> ceilingRays = bake::surfaceBakeRays(scene, settings, rays.sceneExtent(), picked);
    const std::vector<bake::Ray> pristine = ceilingRays;
    const size_t S = size_t(settings.samples);
    auto traceAll = [&]() {
      ceilingRays = pristine;
      auto t0 = Clock::now();
      tbb::parallel_for(tbb::blocked_range<size_t>(0, picked.size(), 64), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i != r.end(); ++i)
          for (size_t first = 0; first < S; first += 256) {
            size_t n = std::min<size_t>(256, S - first);
            if (settings.bounces > 0)
              rays.intersect(ceilingRays.data() + i * S + first, n);
            else
              rays.occluded(ceilingRays.data() + i * S + first, n);
          }
      });
      return double(picked.size() * S) / std::chrono::duration<double>(Clock::now() - t0).count();
    };
    const double ceilingBefore = traceAll();

    // The bake, as `prt bake` runs it.
    bake::SurfaceTransfer result = bake::bakeSurface(scene, settings);
    std::map<std::string, double> stage;
    for (const auto& s : result.stats.stages) stage[s.name] = s.seconds;
    const double directSeconds = stage["direct"];
    const double bakeRate = double(result.stats.rays) / directSeconds;
    const double ceilingAfter = traceAll();
    const double ceilingRate = std::max(ceilingBefore, ceilingAfter);

    nlohmann::json j;
    j["scene"] = scenePath;
    j["vertices"] = V;
    j["samples"] = settings.samples;
    j["bounces"] = settings.bounces;
    j["threads"] = settings.threads;
    j["ray_kind"] = settings.bounces > 0 ? "closest-hit" : "occlusion";
    j["bake_rays_per_s"] = bakeRate;
    j["ceiling_rays_per_s"] = ceilingRate;
    j["ceiling_rays_per_s_before_after"] = {ceilingBefore, ceilingAfter};
    j["ceiling_vertices"] = picked.size();
    j["bake_vs_ceiling"] = bakeRate / ceilingRate;
    j["direct_seconds"] = directSeconds;
    for (int k = 1; k <= settings.bounces; ++k) {
      std::string name = cat("bounce ", k);
      j["bounce_seconds"].push_back(stage[name]);
      j["bounce_vs_bake_time"].push_back(stage[name] / result.stats.seconds);
    }
    j["bake_seconds"] = result.stats.seconds;
    j["bvh_seconds"] = stage["bvh"];
    j["hit_records"] = result.stats.hitRecords;
    j["peak_memory_bytes"] = peakMemoryBytes();
    std::string text = j.dump(2);
    std::printf("%s\n", text.c_str());
    if (!jsonPath.empty()) std::ofstream(jsonPath) << text << "\n";
  } catch (const Error& e) {
    std::fprintf(stderr, "prt_bench_bake: %s\n", e.what());
    return 1;
  }
  return 0;
}
