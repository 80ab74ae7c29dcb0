// Surface-bake benchmark: the bake's rays/s next to an independent Embree ceiling for the same
// rays on the same scene, measured in the same process, for both kinds of ray the direct pass
// casts (occlusion without bounces, closest hits with them), the share of the bake that is not
// tracing, and the cost of every bounce.
//
//   prt_bench_bake [--scene scenes/cornell_open.gltf] [--min-vertices 100000] [--samples 256]
//                  [--bounces 2] [--threads 0] [--ceiling-fraction 0.04] [--rounds 3]
//                  [--kernels auto|avx2|portable] [--json out.json]
//
// The scene is refined (each triangle split into 4, repeatedly) until it has at least
// --min-vertices baked vertices (0: as it is). The ceiling (embree_ceiling.h: its own BVH,
// every Embree 3 way of tracing, the fastest kept) traces exactly the rays the bake casts
// (bake::surfaceBakeRays: same origins and directions), generated beforehand, outside the
// timer, for a fraction of the vertices, with nothing done per ray. "prt tracing" traces the
// same rays through prt's RayScene as the direct pass calls it, also with nothing done per ray.
// What is not tracing (ray generation, SH evaluation, hit records) is measured in the bake: 1 −
// the time its threads spent inside Embree's calls (StageStats::traceSeconds) / (threads × its
// wall time), the same figure under both timings; `_by_rate`: estimated instead as the bake's
// time beyond rays / prt's tracing rate, which runs with warm caches (lower, at times
// negative). Every round measures the ceiling, prt's tracing, the bake without bounces
// (occlusion rays) and the bake with --bounces (closest hits, then the bounces); ratios are
// taken within a round, and reported as the best round's and the range.
#include <algorithm>
#include <array>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <map>
#include <string>

#include <tbb/global_control.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "bench_cli.h"
#include "cpu_clock.h"
#include "embree_ceiling.h"
#include "prt/bake/ray_scene.h"
#include "prt/bake/surface_bake.h"
#include "prt/error.h"
#include "prt/huge_pages.h"
#include "prt/progress.h"
#include "prt/scene.h"

namespace {

using namespace prt;
using bench::Clock;

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

// Fastest and slowest of a series.
nlohmann::json range(const std::vector<double>& v) {
  const auto [lo, hi] = std::minmax_element(v.begin(), v.end());
  return {*lo, *hi};
}

using bench::Timing;

// One bake's figures per round, each timed by the wall clock and by the process's CPU time.
struct BakeRounds {
  std::vector<double> rate[2], direct[2], total[2], notTracing[2], bakeNotTracing[2], vsCeiling[2];
  std::vector<double> notTracingByRate[2], bakeNotTracingByRate[2];
  std::vector<std::vector<double>> bounce[2];  // per round, per bounce: seconds
  uint64_t rays = 0, hitRecords = 0;
  double bvh = 0.0;
};

}  // namespace

int main(int argc, char** argv) {
  prt::tuneHeap();  // as prt does (tools/main.cpp)
  std::string scenePath = PRT_SOURCE_DIR "/scenes/cornell_open.gltf", jsonPath;
  size_t minVertices = 100000;
  bake::BakeSettings settings;
  settings.samples = 256;
  settings.bounces = 2;
  double ceilingFraction = 0.04;
  int rounds = 3;
  CLI::App app{"Surface-bake benchmark: the bake's rays/s next to an independent Embree ceiling for the same rays",
               "prt_bench_bake"};
  app.add_option("--scene", scenePath, "Scene to bake (.gltf)")->capture_default_str();
  app.add_option("--min-vertices", minVertices,
                 "Refine the scene until it has at least this many baked vertices (0: as it is)")
      ->capture_default_str();
  app.add_option("--samples", settings.samples, "Hemisphere directions per vertex")->capture_default_str();
  app.add_option("--bounces", settings.bounces, "Interreflection bounces of the closest-hit bake")
      ->check(CLI::Range(1, bake::kMaxBounces))
      ->capture_default_str();
  app.add_option("--threads", settings.threads, "Worker threads (0 = all cores)")->capture_default_str();
  app.add_option("--ceiling-fraction", ceilingFraction, "Share of the vertices the ceiling traces")
      ->check(CLI::Range(1e-6, 1.0))
      ->capture_default_str();
  app.add_option("--rounds", rounds, "Rounds of ceiling, prt tracing and both bakes")
      ->check(CLI::Range(1, 1000))
      ->capture_default_str();
  app.add_option("--json", jsonPath, "Also write the results to this file");
  std::string kernels = "auto";
  bench::addKernelsOption(app, kernels);
  if (std::optional<int> status = bench::parseBenchOptions(app, "prt_bench_bake", argc, argv)) return *status;
  kernels = bench::applyKernels(kernels);
  try {
    Scene scene = loadScene(scenePath);
    while (minVertices > 0 && bakedVertices(scene) < minVertices)
      for (MeshInstance& m : scene.meshes)
        if (!m.receiverOnly) refine(m);
    std::unique_ptr<tbb::global_control> limit;
    if (settings.threads > 0)
      limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, settings.threads);

    // The rays: runs of 64 consecutive vertices (the bake's chunk, so the same BVH locality),
    // every (1/fraction)-th run, generated by the bake's own generator.
    const bench::EmbreeCeiling ceiling(scene);
    const size_t V = bakedVertices(scene);
    const size_t every = std::max<size_t>(1, size_t(std::lround(1.0 / ceilingFraction)));
    std::vector<size_t> picked;
    for (size_t run = 0; run * 64 < V; run += every)
      for (size_t v = run * 64; v < std::min(V, run * 64 + 64); ++v) picked.push_back(v);
    const bake::RayScene prtRays(scene);
    const std::vector<bake::Ray> sample = bake::surfaceBakeRays(scene, settings, prtRays, picked);
    const size_t S = size_t(settings.samples);

    // prt's tracing alone: the same rays through RayScene, called as the direct pass calls it
    // (one vertex's rays in streams of 256), nothing done per ray. Rates by wall and CPU time.
    auto prtTrace = [&](bench::RayKind kind) {
      std::vector<bake::Ray> batch = sample;
      const double cpu0 = bench::processCpuSeconds();
      const auto t0 = Clock::now();
      tbb::parallel_for(tbb::blocked_range<size_t>(0, picked.size(), 64), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i != r.end(); ++i)
          for (size_t first = 0; first < S; first += 256) {
            const size_t n = std::min<size_t>(256, S - first);
            if (kind == bench::RayKind::ClosestHit)
              prtRays.intersect(batch.data() + i * S + first, n);
            else
              prtRays.occluded(batch.data() + i * S + first, n);
          }
      });
      const double wall = std::chrono::duration<double>(Clock::now() - t0).count();
      const double cpu = bench::processCpuSeconds() - cpu0;
      return std::array<double, 2>{double(batch.size()) / wall, double(batch.size()) / cpu};
    };

    const bench::RayKind kinds[2] = {bench::RayKind::Occlusion, bench::RayKind::ClosestHit};
    bench::Ceiling ceil[2];
    std::vector<double> prtRate[2][2];  // [kind][timing]
    BakeRounds bakes[2];
    bake::BakeSettings occlusionSettings = settings;
    occlusionSettings.bounces = 0;
    std::vector<std::vector<glm::vec3>> first[2];
    bench::CpuTimeline timeline;
    const int used = tbb::this_task_arena::max_concurrency();  // the threads the bake may use
    for (int round = 0; round < rounds; ++round)
      for (int k = 0; k < 2; ++k) {
        bench::appendRounds(ceil[k], ceiling.measure(sample, S, 64, kinds[k], 1));
        const std::array<double, 2> prt = prtTrace(kinds[k]);
        // The bake, as `prt bake` runs it. Its stages run one after the other from its start,
        // with gaps of milliseconds (layout, copies): their wall-clock intervals are placed so,
        // and their CPU time read off the timeline.
        const auto t0 = Clock::now();
        bake::SurfaceTransfer result = bake::bakeSurface(scene, k == 0 ? occlusionSettings : settings);
        const auto t1 = Clock::now();
        if (round == 0)
          first[k] = std::move(result.perMesh);
        else if (result.perMesh != first[k])
          throw Error("the bake gave different transfer in another round");
        std::map<std::string, std::array<double, 2>> stage;
        double inEmbree = 0.0;  // the direct pass's threads inside Embree's calls, measured in the bake
        auto at = t0;
        for (const auto& st : result.stats.stages) {
          if (st.name == "direct") inEmbree = st.traceSeconds;
          const auto end = at + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(st.seconds));
          stage[st.name] = {st.seconds, timeline.cpuSeconds(at, end)};
          at = end;
        }
        const std::array<double, 2> total{std::chrono::duration<double>(t1 - t0).count(), timeline.cpuSeconds(t0, t1)};
        BakeRounds& b = bakes[k];
        b.rays = result.stats.rays;
        b.hitRecords = result.stats.hitRecords;
        b.bvh = stage["bvh"][0];
        for (int t = 0; t < 2; ++t) {
          prtRate[k][t].push_back(prt[size_t(t)]);
          const double traceSeconds = double(b.rays) / prt[size_t(t)];  // at prt's tracing rate
          const double direct = stage["direct"][size_t(t)];
          // Measured on the wall clock in both timings: the threads' time inside Embree's calls
          // against threads × the wall time (a uniform load stretches both alike; against CPU
          // time, a call preempted on a loaded machine would count more than its share).
          const double wallDirect = stage["direct"][0];
          b.direct[t].push_back(direct);
          b.total[t].push_back(total[size_t(t)]);
          b.rate[t].push_back(double(b.rays) / direct);
          b.notTracing[t].push_back(1.0 - inEmbree / (used * wallDirect));
          b.bakeNotTracing[t].push_back(1.0 - inEmbree / (used * total[0]));
          b.notTracingByRate[t].push_back(1.0 - traceSeconds / direct);
          b.bakeNotTracingByRate[t].push_back(1.0 - traceSeconds / total[size_t(t)]);
          b.vsCeiling[t].push_back(b.rate[t].back() / bench::roundRate(ceil[k], size_t(round), Timing(t)));
          b.bounce[t].emplace_back();
          for (int i = 1; i <= (k == 0 ? 0 : settings.bounces); ++i)
            b.bounce[t].back().push_back(stage[cat("bounce ", i)][size_t(t)]);
        }
      }

    nlohmann::json j;
    j["scene"] = scenePath;
    j["vertices"] = V;
    j["triangles"] = ceiling.triangles();
    j["samples"] = settings.samples;
    j["kernels"] = kernels;
    j["threads"] = settings.threads;
    j["threads_used"] = used;
    j["rounds"] = rounds;
    j["ceiling_vertices"] = picked.size();
    j["ceiling_bvh_seconds"] = ceiling.buildSeconds();
    for (int k = 0; k < 2; ++k) {
      const BakeRounds& b = bakes[k];
      nlohmann::json o;
      o["bounces"] = k == 0 ? 0 : settings.bounces;
      o["ceiling"] = bench::toJson(ceil[k]);
      o["rays"] = b.rays;
      o["bvh_seconds"] = b.bvh;
      if (k == 1) o["hit_records"] = b.hitRecords;
      for (int t = 0; t < 2; ++t) {
        // The best round: the fastest direct pass (its ratios are of that round's own ceiling).
        const size_t r = size_t(std::max_element(b.rate[t].begin(), b.rate[t].end()) - b.rate[t].begin());
        nlohmann::json f;
        f["ceiling_rays_per_s"] = ceil[k].rate(Timing(t));
        f["ceiling_best_mode"] = ceil[k].bestMode(Timing(t)).mode;
        f["prt_trace_rays_per_s"] = *std::max_element(prtRate[k][t].begin(), prtRate[k][t].end());
        f["prt_trace_rays_per_s_range"] = range(prtRate[k][t]);
        f["direct_rays_per_s"] = b.rate[t][r];
        f["direct_rays_per_s_range"] = range(b.rate[t]);
        f["direct_vs_ceiling"] = b.vsCeiling[t][r];
        f["direct_vs_ceiling_range"] = range(b.vsCeiling[t]);
        f["direct_seconds"] = b.direct[t][r];
        f["direct_not_tracing_share"] = b.notTracing[t][r];
        f["direct_not_tracing_share_range"] = range(b.notTracing[t]);
        f["bake_seconds"] = b.total[t][r];
        f["bake_not_tracing_share"] = b.bakeNotTracing[t][r];
        f["bake_not_tracing_share_range"] = range(b.bakeNotTracing[t]);
        f["direct_not_tracing_share_by_rate_range"] = range(b.notTracingByRate[t]);
        f["bake_not_tracing_share_by_rate_range"] = range(b.bakeNotTracingByRate[t]);
        for (size_t i = 0; i < b.bounce[t][r].size(); ++i) {
          std::vector<double> share;
          for (size_t q = 0; q < b.bounce[t].size(); ++q) share.push_back(b.bounce[t][q][i] / b.total[t][q]);
          f["bounce_seconds"].push_back(b.bounce[t][r][i]);
          f["bounce_share_of_bake"].push_back(b.bounce[t][r][i] / b.total[t][r]);
          f["bounce_share_of_bake_range"].push_back(range(share));
        }
        o[t == 0 ? "wall" : "cpu"] = f;
      }
      j[k == 0 ? "occlusion" : "closest_hit"] = o;
    }
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
