// Probe-bake benchmark: probes/s and rays/s of the probe bake next to an independent Embree
// ceiling for the same rays on the same scene, measured in the same process; the share of the
// bake that is not tracing; the share of time the indirect light (hits on lit surfaces) costs;
// the bytes per probe on disk (32- and 16-bit files) and in memory; peak memory.
//
//   prt_bench_probes [--scene scenes/cornell_open.gltf] [--dims 32] [--samples 1024]
//                    [--bounces 2] [--surface-samples 256] [--threads 0]
//                    [--ceiling-fraction 0.03] [--repeat 2] [--kernels auto|avx2|portable]
//                    [--json out.json]
//
// --dims N gives an N³ lattice over the scene's bounds. The surface bake (bands 3, --bounces,
// --surface-samples) supplies the transfer a probe ray sees where it hits a surface; it is timed
// but is not part of the probe numbers. The ceiling (embree_ceiling.h: its own BVH, every
// Embree 3 way of tracing closest hits, the fastest kept) traces exactly the rays the probe bake
// cast (ProbeStats::traced), a fraction of each class in runs of 16: the 64-ray inside tests
// (every point's, and relocation candidates': bake::probeTestRays) and the full sets
// (bake::probeFullRays), with nothing done per ray; prt's tracing alone traces them through
// RayScene as the bake calls it. The ratio is the ceiling's time for the bake's rays (each
// class's count at its rate) over the bake's time. Each round measures both
// and bakes; ratios are taken within a round and reported as the fastest bake's round and the
// range, and their median; besides, against the mode whose median over the rounds is best, in
// the same round (`bake_vs_median_best_mode`: each round's fastest mode is the largest of ~15
// noisy timings, above what any mode typically does); memory is the first round's. The share not tracing is measured in
// the bake itself
// (the time its threads spend inside Embree's calls) and, as a cross-check, estimated from
// prt's tracing rate (`_by_rate`). The lit hits' gather (their corners' transfer, the probe
// bake's counterpart of the surface bake's bounces, done per ray) is timed in the bake too: its
// share, and the bake without it against the ceiling (`bake_without_gather_*`), the comparison
// prt_bench_bake makes for the surface bake's direct pass with its bounces apart.
#include <malloc.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>

#include <tbb/global_control.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "bench_cli.h"
#include "cpu_clock.h"
#include "embree_ceiling.h"
#include "prt/bake/probe_bake.h"
#include "prt/bake/ray_scene.h"
#include "prt/bake/surface_bake.h"
#include "prt/error.h"
#include "prt/huge_pages.h"
#include "prt/probe_grid.h"
#include "prt/progress.h"
#include "prt/scene.h"

namespace {

using namespace prt;
using bench::Clock;
namespace fs = std::filesystem;

// A field of /proc/self/status in bytes ("VmHWM", "VmRSS"), or 0 where there is none.
uint64_t procStatusBytes(const char* key) {
  std::ifstream in("/proc/self/status");
  std::string line;
  const size_t n = std::strlen(key);
  while (std::getline(in, line))
    if (line.compare(0, n, key) == 0 && line.size() > n && line[n] == ':')
      return std::stoull(line.substr(n + 1)) * 1024u;  // "VmHWM:   123456 kB"
  return 0;
}

// Resets the kernel's peak-RSS mark (VmHWM) to the current RSS (Linux ≥ 4.0), so the peak of one
// stage can be read on its own. False where that is not possible.
bool resetPeakRss() {
  std::ofstream out("/proc/self/clear_refs");
  out << "5";
  out.flush();
  return bool(out);
}

uint64_t fnv1a(const void* data, size_t bytes, uint64_t h = 1469598103934665603ull) {
  const auto* p = static_cast<const unsigned char*>(data);
  for (size_t i = 0; i < bytes; ++i) h = (h ^ p[i]) * 1099511628211ull;
  return h;
}

}  // namespace

int main(int argc, char** argv) {
  prt::tuneHeap();  // as prt does (tools/main.cpp)
  std::string scenePath = PRT_SOURCE_DIR "/scenes/cornell_open.gltf", jsonPath;
  int dims = 32, threads = 0;
  bake::BakeSettings surface;
  surface.samples = 256;
  surface.bounces = 2;
  surface.keepLowerOrder = true;
  bake::ProbeSettings settings;
  settings.samples = 1024;
  double ceilingFraction = 0.03;
  int repeat = 2;
  CLI::App app{"Probe-bake benchmark: probes/s and rays/s next to the Embree ceiling, bytes per probe, peak memory",
               "prt_bench_probes"};
  app.add_option("--scene", scenePath, "Scene to bake (.gltf)")->capture_default_str();
  app.add_option("--dims", dims, "Probe lattice N³ over the scene's bounds")
      ->check(CLI::Range(1, 512))
      ->capture_default_str();
  app.add_option("--samples", settings.samples, "Sphere directions per probe")->capture_default_str();
  app.add_option("--bounces", surface.bounces, "Interreflection bounces (surface and probes)")->capture_default_str();
  app.add_option("--surface-samples", surface.samples, "Hemisphere directions per vertex of the surface bake")
      ->capture_default_str();
  app.add_option("--threads", threads, "Worker threads (0 = all cores)")->capture_default_str();
  app.add_option("--ceiling-fraction", ceilingFraction,
                 "Share of the full sets the ceiling traces (of the tests, up to as many rays)")
      ->check(CLI::Range(1e-6, 1.0))
      ->capture_default_str();
  app.add_option("--repeat", repeat, "Rounds; ratios are taken within each (the JSON gives their range and median)")
      ->check(CLI::Range(1, 1000))
      ->capture_default_str();
  app.add_option("--json", jsonPath, "Also write the results to this file");
  std::string kernels = "auto";
  bench::addKernelsOption(app, kernels);
  if (std::optional<int> status = bench::parseBenchOptions(app, "prt_bench_probes", argc, argv)) return *status;
  kernels = bench::applyKernels(kernels);
  try {
    settings.dims = glm::ivec3(dims);
    settings.bounces = surface.bounces;
    surface.threads = threads;
    std::unique_ptr<tbb::global_control> limit;
    if (threads > 0)
      limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, threads);

    const Scene scene = loadScene(scenePath);
    bake::SurfaceTransfer lit = bake::bakeSurface(scene, surface);
    std::vector<std::vector<glm::vec3>> lowerOrder = std::move(lit.perMeshLowerOrder);
    if (lowerOrder.empty()) lowerOrder.assign(scene.meshes.size(), {});

    // The rays: what the probe bake cast (ProbeStats::traced), in two classes, each sampled in
    // runs of 16 consecutive sets, every (1/fraction)-th run, picked after the first round's
    // bake and generated outside every timer: the 64-ray inside tests (every lattice point's,
    // and the relocation candidates' from their positions: bake::probeTestRays) and the full
    // sets (from the point, or the candidate a probe moved to: bake::probeFullRays). The
    // ceiling (embree_ceiling.h: its own BVH, every Embree 3 way of tracing, the fastest kept)
    // and prt's tracing alone (RayScene, called as the probe bake calls it: a test as one stream,
    // a full set as streams of 256) trace each class with nothing done per ray; their time for
    // the bake's rays is each class's count at its rate, summed. Times, not rates, are compared:
    // tests of open air or of solid space are cheaper than a full set from a probe in a room, and
    // a bake of many such (a closed map) would otherwise outrun its ceiling. The arrays are freed
    // before each bake so that they do not count in its memory.
    ProbeGrid layout;
    glm::dvec3 lo, hi;
    bake::probeBounds(settings, scene, lo, hi);  // the bake's bounds, flat axes padded
    bake::layoutGrid(settings, lo, hi, layout);
    const size_t total = size_t(dims) * dims * dims;
    const size_t every = std::max<size_t>(1, size_t(std::lround(1.0 / ceilingFraction)));
    std::vector<bake::ProbeRaySet> pickedTests, pickedFull;
    const bench::EmbreeCeiling embree(scene);
    const bake::RayScene rays(scene);
    bench::Ceiling ceilingTests, ceilingFull;
    std::vector<double> prtTestRates[2], prtFullRates[2];  // [Timing]
    // prt's own way, as the bake traces: a set's rays as streams of `stream` rays, each as
    // packets of 8 (RayScene::intersect8), laid out before the timer starts; rays/s, wall and CPU.
    auto tracePrt = [&](const std::vector<bake::Ray>& batch, size_t per, size_t stream, std::vector<double>* rates) {
      const size_t sets = batch.size() / per, streams = (per + stream - 1) / stream;
      auto countOf = [&](size_t q) { return std::min(stream, per - (q % streams) * stream); };  // stream q's rays
      std::vector<size_t> packetOf(sets * streams + 1, 0);
      for (size_t q = 0; q < sets * streams; ++q) packetOf[q + 1] = packetOf[q] + (countOf(q) + 7) / 8;
      std::vector<bake::RayPacket8> packets(packetOf.back());
      for (size_t q = 0; q < sets * streams; ++q) {
        const size_t first = (q / streams) * per + (q % streams) * stream, count = countOf(q);
        for (size_t j = 0; j < count; ++j) {
          const bake::Ray& r = batch[first + j];
          packets[packetOf[q] + j / 8].start(int(j % 8), r.org, r.dir, r.tnear, r.tfar);
        }
      }
      const double cpu0 = bench::processCpuSeconds();
      const auto t0 = Clock::now();
      tbb::parallel_for(tbb::blocked_range<size_t>(0, sets, 16), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i != r.end(); ++i)
          for (size_t q = i * streams; q < (i + 1) * streams; ++q) rays.intersect8(&packets[packetOf[q]], countOf(q));
      });
      rates[0].push_back(double(batch.size()) / std::chrono::duration<double>(Clock::now() - t0).count());
      rates[1].push_back(double(batch.size()) / (bench::processCpuSeconds() - cpu0));
    };
    const size_t perFull = size_t(settings.samples);
    auto measureTracing = [&]() {
      {
        const std::vector<bake::Ray> batch = bake::probeTestRays(layout, settings, pickedTests);
        bench::appendRounds(ceilingTests, embree.measure(batch, 64, 16, bench::RayKind::ClosestHit, 1));
        tracePrt(batch, 64, 64, prtTestRates);
      }
      const std::vector<bake::Ray> batch = bake::probeFullRays(layout, settings, pickedFull);
      bench::appendRounds(ceilingFull, embree.measure(batch, perFull, 16, bench::RayKind::ClosestHit, 1));
      tracePrt(batch, perFull, 256, prtFullRates);
    };

    // The probe bake as `prt bake --probes` runs it; its own peak memory is measured from here.
    // Freed heap (the rays, the surface bake's scratch) goes back to the system first, so that
    // the baseline is what is live and the bake's growth is all its own.
    malloc_trim(0);
    const uint64_t rssBefore = procStatusBytes("VmRSS");
    const bool peakReset = resetPeakRss();
    bake::ProbeStats stats;
    double cpu0 = bench::processCpuSeconds();
    ProbeGrid grid = bake::bakeProbes(scene, lowerOrder, settings, &stats);
    std::vector<double> bakeCpu{bench::processCpuSeconds() - cpu0};
    const uint64_t bakePeak = peakReset ? procStatusBytes("VmHWM") : 0;
    grid.info.scene = fs::path(scenePath).filename().string();

    // The same bake with surfaces that send nothing: what the indirect light costs.
    bake::ProbeStats directStats;
    const std::vector<std::vector<glm::vec3>> none(scene.meshes.size());
    (void)bake::bakeProbes(scene, none, settings, &directStats);

    // Round one's ray sets (the same every round: the bake is deterministic).
    std::vector<bake::ProbeRaySet> tests, fulls;
    bake::probeRaySets(stats, total, tests, fulls);
    const uint64_t testRays = uint64_t(tests.size()) * 64, fullRays = uint64_t(fulls.size()) * perFull;
    if (testRays + fullRays != stats.rays)
      throw Error(cat("the bake's rays (", stats.rays, ") are not its tests' and full sets' (", testRays, " + ",
                      fullRays, ")"));
    auto pick = [](const std::vector<bake::ProbeRaySet>& from, size_t step, std::vector<bake::ProbeRaySet>& into) {
      for (size_t run = 0; run * 16 < from.size(); run += step)
        for (size_t k = run * 16; k < std::min(from.size(), run * 16 + 16); ++k) into.push_back(from[k]);
    };
    // The full sets at the fraction; the tests at a larger one where they are fewer rays, up to
    // as many as the full sets' sample: at 2% a room's tests took 4 ms a mode, too short a
    // timing on a shared machine.
    const size_t everyTest = std::clamp<size_t>(
        size_t(std::llround(double(every) * double(testRays) / double(std::max<uint64_t>(fullRays, 1)))), 1, every);
    pick(tests, everyTest, pickedTests);
    pick(fulls, every, pickedFull);
    if (pickedFull.empty()) throw Error("the probe bake traced no probe in full: nothing to compare with the ceiling");
    measureTracing();
    // Further rounds (--repeat): tracing, bake, direct-only bake again, so that a burst of load
    // from other processes on a shared machine does not decide the ratios, which are taken
    // within a round. The result must be the same grid every time.
    std::vector<double> bakeSeconds{stats.seconds}, directSeconds{directStats.seconds};
    std::vector<double> traceSeconds{stats.traceSeconds};    // inside Embree's calls, all threads
    std::vector<double> gatherSeconds{stats.gatherSeconds};  // inside the lit hits' gather, all threads
    std::vector<double> directTrace{directStats.traceSeconds};
    for (int round = 1; round < repeat; ++round) {
      measureTracing();
      bake::ProbeStats again, directAgain;
      cpu0 = bench::processCpuSeconds();
      const ProbeGrid other = bake::bakeProbes(scene, lowerOrder, settings, &again);
      bakeCpu.push_back(bench::processCpuSeconds() - cpu0);
      if (other.transfer != grid.transfer) throw Error("the probe bake gave a different grid on a second run");
      (void)bake::bakeProbes(scene, none, settings, &directAgain);
      bakeSeconds.push_back(again.seconds);
      traceSeconds.push_back(again.traceSeconds);
      gatherSeconds.push_back(again.gatherSeconds);
      directSeconds.push_back(directAgain.seconds);
      directTrace.push_back(directAgain.traceSeconds);
    }
    // Per round and timing (wall clock, process CPU time: cpu_clock.h): the bake's rate
    // against that round's ceiling, and the share of the bake that is not tracing, two ways:
    // measured in the bake (ProbeStats::traceSeconds, the time its threads spent inside
    // Embree's calls, against threads × wall time, under both timings: a uniform load stretches
    // both alike, where against CPU time a call preempted on a loaded machine would count more
    // than its share), and estimated from
    // rates (its rays at prt's tracing rate of that round, against its time; that tracing runs
    // with warm caches and nothing between its calls, so this share comes out lower).
    const int used = tbb::this_task_arena::max_concurrency();
    // Seconds the bake's rays take at given rates of the two classes (rays/s).
    auto secondsAt = [&](double testRate, double fullRate) {
      return double(testRays) / testRate + double(fullRays) / fullRate;
    };
    auto ceilingSeconds = [&](size_t round, bench::Timing t) {
      return secondsAt(bench::roundRate(ceilingTests, round, t), bench::roundRate(ceilingFull, round, t));
    };
    auto prtFastestSeconds = [&](int t) {  // prt's tracing alone, each class at its fastest round
      return secondsAt(*std::max_element(prtTestRates[t].begin(), prtTestRates[t].end()),
                       *std::max_element(prtFullRates[t].begin(), prtFullRates[t].end()));
    };
    std::vector<double> vsCeiling[2], notTracingByRate[2], notTracing;  // notTracing: measured, per round
    std::vector<double> directVsCeiling, directNotTracing;  // wall clock: the same bake with no lit surfaces
    // The bake without its gather (its wall time less the gather's thread time over the threads),
    // as prt_bench_bake compares the surface bake's direct pass, its bounces apart; wall clock.
    std::vector<double> gatherShare, withoutGatherVsCeiling, withoutGatherNotTracing;
    for (int round = 0; round < repeat; ++round) {
      const size_t r = size_t(round);
      const double seconds = directSeconds[r];
      directVsCeiling.push_back(ceilingSeconds(r, bench::Timing::Wall) / seconds);  // the same rays
      directNotTracing.push_back(1.0 - directTrace[r] / (used * seconds));
      notTracing.push_back(1.0 - traceSeconds[r] / (used * bakeSeconds[r]));
      gatherShare.push_back(gatherSeconds[r] / (used * bakeSeconds[r]));
      const double without = bakeSeconds[r] - gatherSeconds[r] / used;
      withoutGatherVsCeiling.push_back(ceilingSeconds(r, bench::Timing::Wall) / without);
      withoutGatherNotTracing.push_back(1.0 - traceSeconds[r] / (used * without));
    }
    for (int t = 0; t < 2; ++t)
      for (int round = 0; round < repeat; ++round) {
        const double seconds = (t == 0 ? bakeSeconds : bakeCpu)[size_t(round)];
        vsCeiling[t].push_back(ceilingSeconds(size_t(round), bench::Timing(t)) / seconds);
        notTracingByRate[t].push_back(1.0 - secondsAt(prtTestRates[t][size_t(round)], prtFullRates[t][size_t(round)]) /
                                                seconds);
      }
    const size_t bestRound = size_t(std::min_element(bakeSeconds.begin(), bakeSeconds.end()) - bakeSeconds.begin());
    stats.seconds = bakeSeconds[bestRound];
    directStats.seconds = *std::min_element(directSeconds.begin(), directSeconds.end());
    auto range = [](const std::vector<double>& v) {
      const auto [a, b] = std::minmax_element(v.begin(), v.end());
      return nlohmann::json{*a, *b};
    };

    const fs::path dir = fs::temp_directory_path() / cat("prt_bench_probes_", getpid());
    fs::create_directories(dir);
    const std::string floatPath = (dir / "probes.vdb").string(), halfPath = (dir / "probes_half.vdb").string();
    writeProbeGrid(grid, floatPath, false);
    writeProbeGrid(grid, halfPath, true);
    const double floatBytes = double(fs::file_size(floatPath)), halfBytes = double(fs::file_size(halfPath));
    fs::remove_all(dir);

    const double active = double(grid.probeCount());
    // In memory: transfer, validity, offset, sky visibility, moments, lattice coordinate, plus
    // one int32 of the dense index per lattice point (spread over the active probes).
    const double memoryPerProbe = double(grid.transferStride() * sizeof(float) + sizeof(float) + sizeof(glm::vec3) +
                                         sizeof(float) + sizeof(std::array<glm::vec2, 6>) + sizeof(glm::ivec3)) +
                                  4.0 * double(total) / std::max(active, 1.0);
    // Fingerprints of the result, to check that a change to the bake leaves it bit for bit.
    auto hex = [](uint64_t h) {
      char buf[17];
      std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(h));
      return std::string(buf);
    };
    const std::string transferHash = hex(fnv1a(grid.transfer.data(), grid.transfer.size() * sizeof(float)));
    const std::string momentsHash = hex(fnv1a(grid.moments.data(), grid.moments.size() * sizeof(grid.moments[0])));

    nlohmann::json j;
    j["scene"] = scenePath;
    j["threads"] = threads;
    j["dims"] = dims;
    j["bands"] = settings.bands;
    j["samples"] = settings.samples;
    j["kernels"] = kernels;
    j["bounces"] = surface.bounces;
    j["surface_bake_seconds"] = lit.stats.seconds;
    j["lattice_points"] = stats.probes;
    j["active_probes"] = stats.active;
    j["invalid_probes"] = stats.invalid;
    j["moved_probes"] = stats.moved;
    j["probe_bake_seconds"] = stats.seconds;
    j["probes_per_s"] = double(stats.probes) / stats.seconds;
    j["rays"] = stats.rays;
    j["bake_rays_per_s"] = double(stats.rays) / stats.seconds;
    // Per class: the ceiling (every mode) and prt's tracing alone; and for the bake's rays, the
    // ceiling's rate (its rays over the ceiling's seconds, in the bake's fastest round).
    j["test_rays"] = testRays;
    j["full_set_rays"] = fullRays;
    j["ceiling_tests"] = bench::toJson(ceilingTests);
    j["ceiling_full_sets"] = bench::toJson(ceilingFull);
    j["ceiling_rays_per_s"] = double(stats.rays) / ceilingSeconds(bestRound, bench::Timing::Wall);
    j["ceiling_best_mode"] = ceilingFull.bestMode(bench::Timing::Wall).mode;  // of the full sets
    j["prt_trace_rays_per_s"] = double(stats.rays) / prtFastestSeconds(0);
    j["prt_trace_tests_rays_per_s_range"] = range(prtTestRates[0]);
    j["prt_trace_full_sets_rays_per_s_range"] = range(prtFullRates[0]);
    j["repeat"] = repeat;
    j["probe_bake_seconds_each"] = bakeSeconds;
    j["direct_only_bake_seconds_each"] = directSeconds;
    // Seconds inside Embree's calls, all threads together: the full bake's against the direct
    // part's (the same rays), which shows what the lit hits' work costs the tracing (caches).
    j["trace_thread_seconds_each"] = traceSeconds;
    j["direct_only_trace_thread_seconds_each"] = directTrace;
    j["ceiling_tests_sampled"] = pickedTests.size();
    j["ceiling_full_sets_sampled"] = pickedFull.size();
    j["bake_vs_ceiling"] = vsCeiling[0][bestRound];
    j["bake_vs_ceiling_range"] = range(vsCeiling[0]);
    {  // the same, per round, against the mode with the best median rate (Ceiling::bestMedianMode)
      const bench::ModeRate& mt = ceilingTests.bestMedianMode(bench::Timing::Wall);
      const bench::ModeRate& mf = ceilingFull.bestMedianMode(bench::Timing::Wall);
      std::vector<double> ratios;
      for (int round = 0; round < repeat; ++round)
        ratios.push_back(secondsAt(mt.raysPerSecond[0][size_t(round)], mf.raysPerSecond[0][size_t(round)]) /
                         bakeSeconds[size_t(round)]);
      j["bake_vs_ceiling_median"] = bench::median(vsCeiling[0]);
      j["ceiling_median_best_mode"] = mf.mode;  // of the full sets (the tests': mt.mode)
      j["ceiling_tests_median_best_mode"] = mt.mode;
      j["bake_vs_median_best_mode"] = bench::median(ratios);
      j["bake_vs_median_best_mode_range"] = range(ratios);
    }
    j["not_tracing_share"] = notTracing[bestRound];
    j["not_tracing_share_range"] = range(notTracing);
    j["not_tracing_share_by_rate"] = notTracingByRate[0][bestRound];
    j["not_tracing_share_by_rate_range"] = range(notTracingByRate[0]);
    j["threads_used"] = used;
    {  // the same figures by CPU time, the fastest round by CPU time
      const size_t r = size_t(std::min_element(bakeCpu.begin(), bakeCpu.end()) - bakeCpu.begin());
      nlohmann::json c;
      c["ceiling_rays_per_s"] = double(stats.rays) / ceilingSeconds(r, bench::Timing::Cpu);
      c["ceiling_best_mode"] = ceilingFull.bestMode(bench::Timing::Cpu).mode;
      c["prt_trace_rays_per_s"] = double(stats.rays) / prtFastestSeconds(1);
      c["probe_bake_cpu_seconds"] = bakeCpu[r];
      c["bake_rays_per_s"] = double(stats.rays) / bakeCpu[r];
      c["bake_vs_ceiling"] = vsCeiling[1][r];
      c["bake_vs_ceiling_range"] = range(vsCeiling[1]);
      c["not_tracing_share"] = notTracing[r];
      c["not_tracing_share_range"] = range(notTracing);
      c["not_tracing_share_by_rate"] = notTracingByRate[1][r];
      c["not_tracing_share_by_rate_range"] = range(notTracingByRate[1]);
      j["cpu"] = c;
    }
    // The lit hits' gather (ProbeStats::gatherSeconds): its share of the bake, and the bake
    // without it against the ceiling, as prt_bench_bake reports the surface bake's direct pass
    // with its bounces apart.
    j["gather_thread_seconds_each"] = gatherSeconds;
    j["gather_share_of_bake_range"] = range(gatherShare);
    j["gather_share_of_bake_median"] = bench::median(gatherShare);
    j["bake_without_gather_vs_ceiling_range"] = range(withoutGatherVsCeiling);
    j["bake_without_gather_vs_ceiling_median"] = bench::median(withoutGatherVsCeiling);
    j["bake_without_gather_not_tracing_share_range"] = range(withoutGatherNotTracing);
    j["direct_only_bake_seconds"] = directStats.seconds;
    j["indirect_time_share"] = 1.0 - directStats.seconds / stats.seconds;
    j["direct_only_vs_ceiling_range"] = range(directVsCeiling);
    j["direct_only_not_tracing_share_range"] = range(directNotTracing);
    j["surface_bake_share_of_total"] = lit.stats.seconds / (lit.stats.seconds + stats.seconds);
    j["file_bytes_float"] = floatBytes;
    j["file_bytes_half"] = halfBytes;
    j["file_bytes_per_probe_float"] = floatBytes / active;
    j["file_bytes_per_probe_half"] = halfBytes / active;
    j["raw_bytes_per_probe_float"] = double((grid.transferStride() + 20) * sizeof(float));
    j["memory_bytes_per_probe"] = memoryPerProbe;
    j["memory_bytes_grid"] = memoryPerProbe * active;
    j["bake_peak_rss_bytes"] = bakePeak;
    j["bake_rss_before_bytes"] = rssBefore;
    j["bake_peak_over_baseline_bytes"] = bakePeak > rssBefore ? bakePeak - rssBefore : 0;
    j["process_peak_rss_bytes"] = peakMemoryBytes();
    j["transfer_fnv1a"] = transferHash;
    j["moments_fnv1a"] = momentsHash;
    std::string text = j.dump(2);
    std::printf("%s\n", text.c_str());
    if (!jsonPath.empty()) std::ofstream(jsonPath) << text << "\n";
  } catch (const Error& e) {
    std::fprintf(stderr, "prt_bench_probes: %s\n", e.what());
    return 1;
  }
  return 0;
}
