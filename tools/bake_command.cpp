#include "bake_command.h"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iomanip>
#include <limits>
#include <optional>
#include <sstream>

#include "cli_checks.h"
#include "number_list.h"
#include "prt/atomic_file.h"
#include "prt/bake/checkpoint.h"
#include "prt/bake/memory_estimate.h"
#include "prt/bake/probe_bake.h"
#include "prt/bake/ranks.h"
#include "prt/error.h"
#include "prt/probe_grid.h"
#include "prt/progress.h"
#include "prt/version.h"
#include "scene_warnings.h"

namespace prt::tools {

namespace {

// Signals: the first SIGINT/SIGTERM asks the bake to stop (every stage, surface and probes,
// saves its checkpoint and unwinds to main); a second one exits at once without saving. Only
// async-signal-safe calls here. The handler's state (whether an interrupt was requested, and by
// which signal) is the bake library's process-wide flag: a signal handler can reach nothing else,
// and the stages poll it.
void onSignal(int sig) {
  if (bake::interruptRequested()) {
    const char msg[] = "prt: interrupted again: stopping without saving\n";
    ssize_t ignored = ::write(STDERR_FILENO, msg, sizeof msg - 1);
    (void)ignored;
    ::_exit(128 + sig);
  }
  bake::requestInterrupt(sig);
}

// Installs the handlers for the lifetime of a bake and restores the previous ones after.
// An MPI rank (docs/scale.md) stops and saves on SIGUSR1, which mpirun forwards to every rank:
// mpirun turns Ctrl-C into SIGTERM for all ranks, and also sends SIGTERM when a rank aborts
// the job on an error, so SIGTERM ends a rank at once (its checkpoint keeps the last
// periodic save) and the error stays the job's one line.
class SignalScope {
public:
  explicit SignalScope(bool mpiRank) : signals_(mpiRank ? std::vector<int>{SIGUSR1} : std::vector<int>{SIGINT, SIGTERM}) {
    struct sigaction sa{};
    sa.sa_handler = onSignal;
    sigemptyset(&sa.sa_mask);
    sa.sa_flags = SA_RESTART;
    old_.resize(signals_.size());
    for (size_t i = 0; i < signals_.size(); ++i) sigaction(signals_[i], &sa, &old_[i]);
  }
  ~SignalScope() {
    for (size_t i = 0; i < signals_.size(); ++i) sigaction(signals_[i], &old_[i], nullptr);
  }
  SignalScope(const SignalScope&) = delete;
  SignalScope& operator=(const SignalScope&) = delete;

private:
  std::vector<int> signals_;
  std::vector<struct sigaction> old_;
};

// What must match for a checkpoint to be resumed: the scene's content and every setting that
// changes the output bits (not --threads, not -q).
bake::Fingerprint bakeFingerprint(const Scene& scene, const BakeArgs& a, const bake::BakeSettings& s,
                                  const bake::RefineSettings& r, const bake::ProbeSettings* ps) {
  bake::Fingerprint fp;
  fp.add("prt", kVersion);
  bake::addSceneFingerprint(fp, scene);
  bake::addRefineFingerprint(fp, r, s);
  fp.add("bands", std::to_string(s.bands));
  fp.add("samples", std::to_string(s.samples));
  fp.add("bounces", std::to_string(s.bounces));
  fp.add("seed", std::to_string(s.seed));
  fp.add("direct part", "kept apart");  // records of prts before the transfer split lack it
  fp.add("probes", ps ? "yes" : "no");
  if (ps) {
    bake::addProbeFingerprint(fp, *ps);
    fp.add("probe half", a.probeHalf ? "yes" : "no");  // the .vdb written from the same results
  }
  return fp;
}

// The test suite interrupts bakes at chosen points with PRT_TEST_INTERRUPT_AFTER=N (an
// interrupt once N chunks have finished in this run), as a user's Ctrl-C would.
// The memory guard's refusal in this command's terms: the options that would make the bake fit.
void guardMemory(const bake::MemoryEstimate& e, const std::optional<bake::MemoryLimit>& limit, const Scene& scene,
                 const bake::BakeSettings& s, const bake::ProbeSettings* probes) {
  if (!limit) return;
  bake::MemoryAdviceNames flags;
  flags.samples = "--samples";
  flags.probeSpacing = "--probe-spacing";
  flags.probeDims = "--probe-dims";
  flags.bands = "--bands";
  flags.raiseLimit = "raise --max-memory";
  flags.givenLimit = "--max-memory";
  bake::checkMemory(e, *limit, scene, s, probes, flags);
}

// PRT_TEST_INTERRUPT_AFTER=N: interrupt after N chunks of this run; =S:N after N chunks of
// the stage whose checkpoint id is S (under MPI a rank's chunks per stage vary, ranks.h).
void testInterruptAfter(bake::CheckpointOptions& co) {
  const char* v = std::getenv("PRT_TEST_INTERRUPT_AFTER");
  if (!v) return;
  char* end = nullptr;
  co.interruptAfterChunks = std::strtoull(v, &end, 10);
  if (*end == ':') {
    co.interruptInStage = uint32_t(co.interruptAfterChunks);
    co.interruptAfterChunks = std::strtoull(end + 1, nullptr, 10);
  }
}

// The probe options of prt bake: each needs --probes (never silently ignored), --probe-dims and
// --probe-spacing exclude each other, and malformed values are one-line usage errors. Returns
// --probes.
CLI::Option* addProbeOptions(CLI::App& bake, BakeArgs& a) {
  CLI::Option* probes = bake.add_option("--probes", a.probes, "Also bake a probe grid into this OpenVDB file (.vdb)");
  CLI::Option* spacing = bake.add_option("--probe-spacing", a.probeSpacing, "Probe spacing in world units (else --probe-dims)")
                             ->check(CLI::PositiveNumber);
  CLI::Option* dims = bake.add_option_function<std::string>(
      "--probe-dims",
      [&a](const std::string& v) {
        std::vector<double> d = parseNumberList("--probe-dims", v, 3, true, "three integer counts X,Y,Z (e.g. 16,16,8)");
        a.probeDims.clear();
        for (double x : d) a.probeDims.push_back(int(x));
      },
      "Probe counts X,Y,Z (default 16,16,16)");
  CLI::Option* bounds = bake.add_option_function<std::string>(
      "--probe-bounds",
      [&a](const std::string& v) {
        a.probeBounds = parseNumberList("--probe-bounds", v, 6, false, "six numbers MINX,MINY,MINZ,MAXX,MAXY,MAXZ");
      },
      "Probe grid bounds MINX,MINY,MINZ,MAXX,MAXY,MAXZ (default: scene bounds, flat axes padded)");
  CLI::Option* samples = bake.add_option("--probe-samples", a.probeSamples, "Sphere directions per probe")
                             ->check(CLI::Range(1, bake::kMaxSamples))
                             ->capture_default_str();
  CLI::Option* half = bake.add_flag("--probe-half", a.probeHalf, "Store probe grids as 16-bit floats");
  using Region = bake::ProbeSettings::Region;
  CLI::Option* region =
      bake.add_option("--probe-region", a.probeRegion,
                      "Where probes go: inside (only space sealed in by the scene's surfaces), everywhere (all "
                      "space outside solid geometry), or auto (inside for a closed level, else near "
                      "surfaces or surrounded by them)")
          ->transform(choice<Region>({{"auto", Region::Auto}, {"everywhere", Region::Everywhere}, {"inside", Region::Inside}}))
          ->default_str("auto");
  CLI::Option* height =
      bake.add_option("--probe-height", a.probeHeight,
                      "auto: under open sky, keep probes at most this high above the surface below them (world "
                      "units; 0 = no limit): the void over a roofless level is left out")
          ->check(CLI::NonNegativeNumber)
          ->capture_default_str();
  dims->excludes(spacing);
  for (CLI::Option* o : {spacing, dims, bounds, samples, half, region, height}) o->needs(probes);
  return probes;
}

// Refinement before the bake (prt/bake/refine.h): on by default; --no-refine or
// --refine-tolerance 0 turn it off, and its options mean nothing without rays.
void addRefineOptions(CLI::App& bake, BakeArgs& a, CLI::Option* unshadowed) {
  CLI::Option* tolerance =
      bake.add_option("--refine-tolerance", a.refine.tolerance,
                      "Split mesh edges where shadowed transfer differs from its interpolation by more than this, "
                      "relative to unoccluded transfer (0 = no refinement)")
          ->check(finiteAtLeast(0.0))
          ->capture_default_str();
  CLI::Option* budget =
      bake.add_option("--refine-budget", a.refine.budget,
                      cat("Vertices refinement may add (0 = as many as the scene has, at least ", bake::kMinAutoBudget,
                          ")"))
          ->capture_default_str();
  CLI::Option* samples = bake.add_option("--refine-samples", a.refine.samples,
                                         "Directions per point when refinement estimates transfer (at most --samples)")
                             ->check(CLI::Range(1, bake::kMaxSamples))
                             ->capture_default_str();
  CLI::Option* off = bake.add_flag("--no-refine", a.noRefine, "Bake the meshes as they are (no refinement)");
  for (CLI::Option* o : {tolerance, budget, samples}) {
    o->excludes(off);
    o->excludes(unshadowed);
  }
}

}  // namespace

void addBake(CLI::App& bake, BakeArgs& a) {
  bake.add_option("scene", a.scene, "Input scene (.gltf or .glb)")->required();
  bake.add_option("-o,--output", a.output, "Output baked scene (.glb)")->required();
  bake.add_option("--bands", a.settings.bands, "SH bands (n bands = n² coefficients)")
      ->check(kBandsRange)
      ->capture_default_str();
  bake.add_option("--samples", a.settings.samples, "Hemisphere directions per vertex")
      ->check(CLI::Range(1, bake::kMaxSamples))
      ->capture_default_str();
  bake.add_option("--bounces", a.settings.bounces, "Interreflection bounces (0 = direct shadowed only)")
      ->check(CLI::Range(0, bake::kMaxBounces))
      ->capture_default_str();
  CLI::Option* unshadowed =
      bake.add_flag("--unshadowed", a.unshadowed, "Unshadowed transfer (closed form, no rays, no bounces)");
  bake.add_option("--seed", a.settings.seed, "Random seed (same seed, same output, any thread count)")
      ->capture_default_str();
  bake.add_option("--threads", a.settings.threads, "Worker threads (0 = all cores)")
      ->check(CLI::Range(0, std::numeric_limits<int>::max()))
      ->capture_default_str();
  bake.add_option("--receiver", a.load.receiverNodes, "Node (name or index) baked as receiver only; repeatable");
  bake.add_flag("--allow-degenerate", a.allowDegenerate,
                "Deprecated, no effect: zero-area triangles are always dropped with a warning");
  bake.add_flag("--allow-external-uris", a.load.allowExternalUris,
                "Read buffers and images outside the scene's folder (absolute paths, ..)");
  bake.add_flag("-q,--quiet", a.quiet, "No progress bar, no summary");
  addRefineOptions(bake, a, unshadowed);
  // Probes are baked with the bounces, and a checkpoint holds rays: neither exists unshadowed.
  addProbeOptions(bake, a)->excludes(unshadowed);
  bake.add_flag("--resume", a.resume, "Continue an interrupted bake from its checkpoint (same scene and settings)")
      ->excludes(unshadowed);
  bake.add_option("--checkpoint", a.checkpoint, "Checkpoint file (default: OUTPUT.prt-checkpoint)");
  bake.add_option("--checkpoint-interval", a.checkpointInterval,
                  "Seconds between checkpoint saves (0 = only when interrupted)")
      ->check(finiteAtLeast(0.0))
      ->capture_default_str();
  bake.add_option_function<std::string>(
      "--max-memory",
      [&a](const std::string& v) {
        try {
          a.maxMemory = bake::parseByteSize(v, "--max-memory");
        } catch (const Error& e) {
          throw CLI::ValidationError(e.what());
        }
      },
      "Refuse bakes estimated above this (e.g. 8G, 500M; default: available memory)");
  bake.add_option_function<std::string>(
          "--shard",
          [&a](const std::string& v) {
            const size_t slash = v.find('/');
            std::vector<double> n;
            if (slash != std::string::npos)
              n = {std::strtod(v.substr(0, slash).c_str(), nullptr), std::strtod(v.substr(slash + 1).c_str(), nullptr)};
            const bool ok = slash != std::string::npos && v.find_first_not_of("0123456789/") == std::string::npos &&
                            slash > 0 && slash + 1 < v.size() && n[1] >= 1 && n[1] <= 1e6 && n[0] < n[1];
            if (!ok) throw CLI::ValidationError("--shard", cat("'", v, "': give I/N with 0 <= I < N (e.g. 0/4)"));
            a.shardIndex = int(n[0]);
            a.shardCount = int(n[1]);
          },
          "Bake shard I of N of the next unfinished stage into CHECKPOINT.shard-I-of-N, for farms "
          "without MPI; join with prt merge (docs/scale.md)")
      ->excludes("--resume")
      ->excludes(unshadowed);
}

int runBake(const BakeArgs& a) {
  // The ranks of this bake (docs/scale.md): MPI's under mpirun, a shard's, or one process.
  std::unique_ptr<bake::Ranks> mpi;
  if (bake::launcherRank() >= 0) {
    if (!bake::mpiBuilt())
      throw Error("started as one of several MPI ranks, but this prt was built without MPI (install libopenmpi-dev "
                  "and build again, or use --shard)");
    if (a.shardCount > 0) throw UsageError("--shard: not under mpirun (MPI ranks share every stage themselves)");
    mpi = bake::startMpi();
  }
  std::unique_ptr<bake::Ranks> shard = a.shardCount > 0 ? bake::shardRanks(a.shardIndex, a.shardCount) : nullptr;
  const bake::RanksScope ranksScope(mpi ? mpi.get() : shard.get());
  bake::Ranks& ranks = bake::ranks();
  const bool writer = ranks.rank() == 0 && !shard;  // the one process that writes the outputs

  bake::BakeSettings s = a.settings;
  s.shadowed = !a.unshadowed;
  s.progress = !a.quiet && Progress::terminalDefault() && ranks.rank() == 0;
  bake::validate(s);
  std::optional<AtomicFile> probe;
  if (writer) probe.emplace(a.output);  // fail on an unwritable output before hours of work
  std::optional<AtomicFile> probeFile;
  bake::ProbeSettings ps;
  if (!a.probes.empty()) {
    if (writer) probeFile.emplace(a.probes);
    ps.bands = s.bands;
    ps.samples = a.probeSamples;
    ps.bounces = s.shadowed ? s.bounces : 0;
    ps.seed = s.seed;
    ps.progress = s.progress;
    ps.threads = s.threads;
    ps.spacing = a.probeSpacing;
    ps.region = a.probeRegion;
    ps.maxHeight = a.probeHeight;
    if (!a.probeDims.empty()) ps.dims = glm::ivec3(a.probeDims[0], a.probeDims[1], a.probeDims[2]);
    if (a.probeSpacing == 0.0 && a.probeDims.empty()) ps.dims = glm::ivec3(16);
    if (!a.probeBounds.empty()) {
      ps.boundsMin = glm::dvec3(a.probeBounds[0], a.probeBounds[1], a.probeBounds[2]);
      ps.boundsMax = glm::dvec3(a.probeBounds[3], a.probeBounds[4], a.probeBounds[5]);
    }
    bake::validate(ps);
    s.keepLowerOrder = true;
  }

  const bake::ProbeSettings* psp = a.probes.empty() ? nullptr : &ps;

  SignalScope signals(mpi != nullptr);
  Scene scene;
  try {
    scene = loadScene(a.scene, a.load);
  } catch (const ExternalUriRefused& e) {
    throw Error(cat(e.what(), " (--allow-external-uris)"));
  }
  if (a.allowDegenerate && !a.quiet)
    std::fprintf(stderr, "prt: warning: --allow-degenerate is deprecated and does nothing: every command drops "
                         "zero-area triangles with a warning\n");
  printWarnings(scene, a.quiet);
  bake::RefineSettings refine = a.refine;
  if (a.noRefine || !s.shadowed) refine.tolerance = 0.0;
  if (refine.tolerance > 0.0) s.refineVertices = bake::refineBudget(refine, scene);

  // Memory guard: first without the hit records (before the BVH is built) and with the
  // refinement's budget, then with the bound the bake measures on a pilot of its own rays on
  // the refined scene (BakeControl::checkMemory).
  // The probe stage's bound counts every lattice point as baked; where that bound is what does
  // not fit, the placement's own rays (about 64 a point, on the scene before refinement, whose
  // surfaces refinement keeps) count the points the bake keeps, and that count is checked.
  std::optional<bake::MemoryLimit> limit = bake::memoryLimit(a.maxMemory);
  bake::MemoryEstimate estimate = bake::estimateBakeMemory(scene, s, psp, 0.0);
  std::optional<bake::ProbePlacement> placement;
  const bool probesLargest =
      estimate.probePeak >= std::max({estimate.surfacePeak, estimate.writePeak, estimate.refinePeak});
  if (limit && psp && estimate.total > limit->bytes && probesLargest) {
    placement = bake::placeProbes(scene, *psp);
    estimate = bake::estimateBakeMemory(scene, s, psp, 0.0, &*placement);
  }
  guardMemory(estimate, limit, scene, s, psp);

  std::optional<bake::Checkpoint> checkpoint;
  const std::string checkpointPath = a.checkpoint.empty() ? a.output + ".prt-checkpoint" : a.checkpoint;
  std::error_code ec;
  if (s.shadowed) {
    bake::CheckpointOptions co;
    co.path = checkpointPath;
    co.intervalSeconds = a.checkpointInterval;
    co.resume = a.resume;
    testInterruptAfter(co);
    bake::Fingerprint fp = bakeFingerprint(scene, a, s, refine, psp);
    if (mpi) {
      // One file per rank, each holding the chunks its rank computed; they resume together.
      co.path = cat(checkpointPath, ".rank-", ranks.rank(), "-of-", ranks.size());
      co.missingIsFresh = true;  // a rank that never saved
      fp.add("ranks", std::to_string(ranks.size()));
    }
    if (shard) {
      // A shard reads the merged stages at the checkpoint's path and saves its share apart;
      // run again (preempted, or as a retry) it goes on from its own file.
      co.path = bake::shardCheckpointPath(checkpointPath, a.shardIndex, a.shardCount);
      if (std::filesystem::exists(co.path + ".done", ec)) {
        if (!a.quiet)
          std::fprintf(stderr, "prt bake: shard %d/%d: its share is done already (%s.done); run prt merge %s --shards %d\n",
                       a.shardIndex, a.shardCount, co.path.c_str(), checkpointPath.c_str(), a.shardCount);
        return 0;
      }
      co.resume = std::filesystem::exists(co.path, ec);
      if (std::filesystem::exists(checkpointPath, ec)) co.basePath = checkpointPath;
    }
    try {
      checkpoint.emplace(co, fp);
    } catch (const bake::CheckpointExists&) {
      throw Error(cat(co.path, ": a checkpoint of an interrupted bake exists; add --resume to continue it, "
                               "or delete it to start over"));
    }
    if (mpi && a.resume && ranks.sum(checkpoint->exists() ? 1 : 0) == 0)
      throw Error(cat(checkpointPath, ".rank-*-of-", ranks.size(), ": no checkpoint to resume (a bake writes one per "
                                      "rank when interrupted, or every checkpoint interval); start the bake afresh"));
  }
  bake::BakeControl control;
  control.checkpoint = checkpoint ? &*checkpoint : nullptr;
  // With probes, the direct pass's BVH is kept for the probe stage (one build, not two); it is
  // built after refinement, which changes the meshes, and freed once the probes are traced.
  std::optional<bake::SharedRayScene> sharedRays;
  if (!a.probes.empty()) control.rays = &sharedRays.emplace(scene);
  // The refinement phase is over when the bake checks again, but the estimate it reports
  // still bounds the whole run's peak: it keeps that phase.
  const uint64_t refinePeak = estimate.refinePeak;
  control.checkMemory = [&](double share) {
    estimate = bake::estimateBakeMemory(scene, s, psp, share, placement ? &*placement : nullptr);
    guardMemory(estimate, limit, scene, s, psp);
    estimate.keepRefinePhase(refinePeak);
  };
  // Runs a stage; an interruption names the checkpoint and how far the bake got.
  auto runStage = [&](auto&& run) {
    try {
      return run();
    } catch (const Interrupted&) {
      if (!checkpoint) throw;
      if (mpi)  // one line for all ranks (main prints rank 0's when every rank stops)
        throw Interrupted(cat("interrupted: checkpoints saved to ", checkpointPath, ".rank-*-of-", ranks.size(),
                              " (rank ", ranks.rank(), ": ", checkpoint->progressText(),
                              "); rerun with --resume to continue"));
      throw Interrupted(cat("interrupted: checkpoint saved to ", checkpoint->path(), " (",
                            checkpoint->progressText(), "); rerun with --resume to continue"));
    }
  };
  // Refinement is deterministic: a resumed bake refines again, to the same meshes, before it
  // restores the stages that follow (the checkpoint's fingerprint holds its settings).
  bake::RefineStats refined;
  bake::SurfaceTransfer result;
  std::string sceneName = std::filesystem::path(a.scene).filename().string();
  bake::ProbeStats probeStats;
  uintmax_t probeBytes = 0;
  try {
    refined = runStage([&] { return bake::refineScene(scene, refine, s, checkpoint ? &*checkpoint : nullptr); });
    s.refineVertices = 0;  // the scene holds them now
    result = runStage([&] { return bake::bakeSurface(scene, s, control); });
    if (!a.probes.empty()) {
      if (result.perMeshLowerOrder.empty()) result.perMeshLowerOrder.assign(scene.meshes.size(), {});
      ProbeGrid grid = runStage([&] {
        return bake::bakeProbes(scene, result.perMeshLowerOrder, ps, &probeStats, checkpoint ? &*checkpoint : nullptr,
                                control.rays);  // which it releases once traced
      });
      grid.info.scene = sceneName;
      if (writer) {
        writeProbeGrid(grid, a.probes, a.probeHalf);
        probeBytes = std::filesystem::file_size(a.probes);
      }
    }
  } catch (const bake::ShardDone& done) {
    // This shard's share of a stage is saved: mark its file finished for prt merge.
    const std::string file = checkpoint->path();
    std::filesystem::rename(file, file + ".done");
    if (!a.quiet)
      std::fprintf(stderr, "prt bake: %s -> %s.done; once all %d shards are done: prt merge %s --shards %d, then run "
                           "the shards again (or, after the last stage, prt bake --resume without --shard)\n",
                   done.what(), file.c_str(), a.shardCount, checkpointPath.c_str(), a.shardCount);
    return 0;
  }
  if (shard)
    throw Error(cat(checkpointPath, ": every stage is merged; write the outputs with the same prt bake command and "
                                    "--resume instead of --shard"));
  if (!writer) {
    // Rank 0 writes; the checkpoints go once the outputs are in place.
    ranks.barrier();
    if (checkpoint) checkpoint->remove();
    return 0;
  }
  bake::storeTransfer(scene, std::move(result.perMesh), std::move(result.perMeshDirect));
  scene.transferBands = s.bands;
  auto tWrite = std::chrono::steady_clock::now();
  BakeRecord record = bake::bakeRecord(s, sceneName, kVersion);
  if (refine.tolerance > 0.0)
    record.refinement = {refine.tolerance, refined.budget,      std::min(refine.samples, s.samples),
                         refined.verticesBefore, refined.verticesAfter, refined.residual};
  record.backTransfer = std::any_of(scene.meshes.begin(), scene.meshes.end(),
                                    [](const MeshInstance& m) { return m.hasBackTransfer(); });
  record.directTransfer = std::any_of(scene.meshes.begin(), scene.meshes.end(),
                                      [](const MeshInstance& m) { return m.hasDirectTransfer(); });
  writeBakedScene(a.scene, scene, &record, a.output);
  double writeSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - tWrite).count();
  // The outputs are in place: the checkpoint has served (every rank's, after the barrier).
  ranks.barrier();
  if (checkpoint) checkpoint->remove();

  if (a.quiet) return 0;
  const bake::BakeStats& st = result.stats;
  size_t receivers = 0;
  for (const MeshInstance& m : scene.meshes) receivers += m.receiverOnly;
  std::ostringstream stages;
  if (refined.seconds > 0) stages << "refine " << std::fixed << std::setprecision(2) << refined.seconds << " s, ";
  for (const bake::StageStats& stage : st.stages) stages << stage.name << " " << std::fixed
                                                         << std::setprecision(2) << stage.seconds << " s, ";
  double directSeconds = 0;
  for (const auto& stage : st.stages)
    if (stage.name == "direct") directSeconds = stage.seconds;
  std::fprintf(stderr,
               "prt bake: %s -> %s\n  %s vertices%s in %zu instances (%zu receivers skipped), %d bands, "
               "%d samples, %d bounces%s\n  %s rays (%s rays/s in the direct pass), %s hit records%s\n"
               "  time: %s write %.2f s; total %.2f s\n  memory: estimated %s, peak %s (estimated by phase: %s)\n",
               a.scene.c_str(), a.output.c_str(), formatCount(double(st.vertices)).c_str(),
               st.backVertices ? cat(" (", formatCount(double(st.backVertices)), " of them two-sided)").c_str() : "",
               scene.meshes.size() - receivers, receivers, s.bands, s.samples, s.shadowed ? s.bounces : 0,
               s.shadowed ? "" : " (unshadowed)", formatCount(double(st.rays)).c_str(),
               formatCount(directSeconds > 0 ? double(st.rays) / directSeconds : 0.0).c_str(),
               formatCount(double(st.hitRecords)).c_str(), st.resumed ? "; resumed from the checkpoint" : "",
               stages.str().c_str(), writeSeconds, refined.seconds + st.seconds + writeSeconds, formatBytes(estimate.total).c_str(),
               formatBytes(peakMemoryBytes()).c_str(), estimate.phases().c_str());
  if (refine.tolerance > 0.0)
    std::fprintf(stderr,
                 "  refinement: %s -> %s vertices, %s -> %s triangles in %d rounds (tolerance %g, budget %s%s), "
                 "residual %.3f; %s points, %s rays in %.2f s\n",
                 formatCount(double(refined.verticesBefore)).c_str(), formatCount(double(refined.verticesAfter)).c_str(),
                 formatCount(double(refined.trianglesBefore)).c_str(),
                 formatCount(double(refined.trianglesAfter)).c_str(), refined.rounds, refine.tolerance,
                 formatCount(double(refined.budget)).c_str(), refined.budgetReached ? ", reached" : "",
                 refined.residual, formatCount(double(refined.points)).c_str(),
                 formatCount(double(refined.rays)).c_str(), refined.seconds);
  for (const std::string& line : describeReceivers(scene, "--receiver")) std::fprintf(stderr, "  receiver %s\n", line.c_str());
  if (mpi)
    std::fprintf(stderr, "  ranks: %d (MPI%s); rank 0 received %s from the others in %llu exchanges\n", ranks.size(),
                 ranks.transportChoice().empty() ? "" : cat(": ", ranks.transportChoice()).c_str(),
                 formatBytes(ranks.bytesReceived()).c_str(), static_cast<unsigned long long>(ranks.gathers()));
  if (a.probes.empty()) return 0;
  const std::string restored =
      probeStats.restored ? cat("; ", formatCount(double(probeStats.restored)), " restored from the checkpoint") : "";
  const std::string outside =
      probeStats.outside
          ? cat(", ", formatCount(double(probeStats.outside)),
                probeStats.insideOnly ? " outside the closed level" : " in open air far from surfaces",
                probeStats.aboveLevel ? cat(" or over the level (", formatCount(double(probeStats.aboveLevel)),
                                            " more than ", a.probeHeight, " above the ground under open sky)")
                                      : std::string(),
                " (not baked; --probe-region everywhere bakes them)")
          : "";
  std::fprintf(stderr,
               "  probes: %s lattice points, %s active (%s valid), %s inside geometry, %s moved out%s; %s rays in "
               "%.2f s (%s probes/s, %s rays/s)%s -> %s\n",
               formatCount(double(probeStats.probes)).c_str(), formatCount(double(probeStats.active)).c_str(),
               formatCount(double(probeStats.valid)).c_str(), formatCount(double(probeStats.invalid)).c_str(),
               formatCount(double(probeStats.moved)).c_str(), outside.c_str(),
               formatCount(double(probeStats.rays)).c_str(), probeStats.seconds,
               formatCount(double(probeStats.probes - probeStats.restored) / std::max(probeStats.seconds, 1e-9)).c_str(),
               formatCount(probeStats.rays / std::max(probeStats.seconds, 1e-9)).c_str(), restored.c_str(),
               a.probes.c_str());
  // Per valid probe: what a level's probe budget is planned in.
  const double valid = double(std::max<uint64_t>(probeStats.valid, 1));
  std::fprintf(stderr, "  per valid probe: %s on disk, %.0f µs of bake (%s in the file, %.2f s)\n",
               formatBytes(uintmax_t(double(probeBytes) / valid)).c_str(), 1e6 * probeStats.seconds / valid,
               formatBytes(probeBytes).c_str(), probeStats.seconds);
  return 0;
}

}  // namespace prt::tools
