#include "bake_command.h"

#include <unistd.h>

#include <algorithm>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <iomanip>
#include <limits>
#include <optional>
#include <sstream>

#include "cli_checks.h"
#include "number_list.h"
#include "prt/bake/interrupt.h"
#include "prt/bake/pipeline.h"
#include "prt/error.h"
#include "prt/progress.h"
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
  explicit SignalScope(bool mpiRank)
      : signals_(mpiRank ? std::vector<int>{SIGUSR1} : std::vector<int>{SIGINT, SIGTERM}) {
    struct sigaction sa {};
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

// PRT_TEST_INTERRUPT_AFTER=N: interrupt after N chunks of this run; =S:N after N chunks of
// the stage whose checkpoint id is S, or at its end on a rank that finished fewer there (under
// MPI a rank's chunks per stage vary, ranks.h). The test suite interrupts bakes at chosen
// points with it, as a user's Ctrl-C would.
void testInterruptAfter(bake::JobCheckpoint& c) {
  const char* v = std::getenv("PRT_TEST_INTERRUPT_AFTER");
  if (!v) return;
  char* end = nullptr;
  c.interruptAfterChunks = std::strtoull(v, &end, 10);
  if (*end == ':') {
    c.interruptInStage = uint32_t(c.interruptAfterChunks);
    c.interruptAfterChunks = std::strtoull(end + 1, nullptr, 10);
  }
}

// The probe grid of --probes: --probe-dims 16,16,16 unless a spacing or counts are given.
bake::ProbeSettings probeSettings(const BakeArgs& a) {
  bake::ProbeSettings ps;
  ps.samples = a.probeSamples;
  ps.spacing = a.probeSpacing;
  ps.region = a.probeRegion;
  ps.maxHeight = a.probeHeight;
  if (!a.probeDims.empty()) ps.dims = glm::ivec3(a.probeDims[0], a.probeDims[1], a.probeDims[2]);
  if (a.probeSpacing == 0.0 && a.probeDims.empty()) ps.dims = glm::ivec3(16);
  if (!a.probeBounds.empty()) {
    ps.boundsMin = glm::dvec3(a.probeBounds[0], a.probeBounds[1], a.probeBounds[2]);
    ps.boundsMax = glm::dvec3(a.probeBounds[3], a.probeBounds[4], a.probeBounds[5]);
  }
  return ps;
}

// The bake the options describe; the memory guard's refusal names these options.
bake::BakeJob bakeJob(const BakeArgs& a) {
  bake::BakeJob job;
  job.scenePath = a.scene;
  job.load = a.load;
  job.settings = a.settings;
  job.settings.shadowed = !a.unshadowed;
  job.settings.progress = !a.quiet && Progress::terminalDefault();
  job.refine = a.refine;
  if (a.noRefine) job.refine.tolerance = 0.0;
  if (!a.probes.empty()) job.probes = probeSettings(a);
  if (!a.noOperator && !a.unshadowed) job.bounceOperator = a.bounceOperator;
  job.outputs = {a.output, a.probes, a.probeHalf};
  job.checkpoint.path = a.checkpoint;
  job.checkpoint.intervalSeconds = a.checkpointInterval;
  job.checkpoint.resume = a.resume;
  testInterruptAfter(job.checkpoint);
  job.maxMemory = a.maxMemory;
  job.shardIndex = a.shardIndex;
  job.shardCount = a.shardCount;
  job.memoryNames.samples = "--samples";
  job.memoryNames.probeSpacing = "--probe-spacing";
  job.memoryNames.probeDims = "--probe-dims";
  job.memoryNames.bands = "--bands";
  job.memoryNames.raiseLimit = "raise --max-memory";
  job.memoryNames.givenLimit = "--max-memory";
  return job;
}

// The pipeline's refusals whose remedy is an option of prt bake, said in its options; anything
// else as it is.
[[noreturn]] void rethrowInOptions() {
  using Reason = bake::BakeRefused::Reason;
  try {
    throw;
  } catch (const bake::BakeRefused& e) {
    switch (e.reason()) {
      case Reason::MpiNotBuilt:
        throw Error(
            "started as one of several MPI ranks, but this prt was built without MPI (install "
            "libopenmpi-dev and build again, or use --shard)");
      case Reason::ShardUnderMpi:
        throw UsageError("--shard: not under mpirun (MPI ranks share every stage themselves)");
      case Reason::CheckpointFound:
        throw Error(cat(e.path(),
                        ": a checkpoint of an interrupted bake exists; add --resume to continue it, "
                        "or delete it to start over"));
      case Reason::ShardsMerged:
        throw Error(cat(e.path(),
                        ": every stage is merged; write the outputs with the same prt bake command and "
                        "--resume instead of --shard"));
    }
    throw;
  } catch (const bake::InterruptedAndSaved& e) {
    throw Interrupted(cat(e.what(), "; rerun with --resume to continue"));
  } catch (const ExternalUriRefused& e) {
    throw Error(cat(e.what(), " (--allow-external-uris)"));
  }
}

// A shard's share of a stage, saved now or before: what to run next.
void printShard(const BakeArgs& a, const bake::BakeReport& r) {
  if (a.quiet) return;
  if (r.outcome == bake::BakeReport::Outcome::ShardAlreadyDone)
    std::fprintf(stderr, "prt bake: shard %d/%d: its share is done already (%s.done); run prt merge %s --shards %d\n",
                 a.shardIndex, a.shardCount, r.shardFile.c_str(), r.checkpointPath.c_str(), a.shardCount);
  else
    std::fprintf(stderr,
                 "prt bake: %s -> %s.done; once all %d shards are done: prt merge %s --shards %d, then run "
                 "the shards again (or, after the last stage, prt bake --resume without --shard)\n",
                 r.shardStage.c_str(), r.shardFile.c_str(), a.shardCount, r.checkpointPath.c_str(), a.shardCount);
}

// The summary's first lines: what was baked, rays, time and memory.
void printBake(const BakeArgs& a, const bake::BakeReport& r) {
  const bake::BakeStats& st = r.surface;
  const bake::BakeSettings& s = r.settings;
  size_t receivers = 0;
  for (const MeshInstance& m : r.scene.meshes) receivers += m.receiverOnly;
  std::ostringstream stages;
  if (r.refined.seconds > 0) stages << "refine " << std::fixed << std::setprecision(2) << r.refined.seconds << " s, ";
  for (const bake::StageStats& stage : st.stages)
    stages << stage.name << " " << std::fixed << std::setprecision(2) << stage.seconds << " s, ";
  double directSeconds = 0;
  for (const auto& stage : st.stages)
    if (stage.name == "direct") directSeconds = stage.seconds;
  std::fprintf(stderr,
               "prt bake: %s -> %s\n  %s vertices%s in %zu instances (%zu receivers skipped), %d bands, "
               "%d samples, %d bounces%s\n  %s rays (%s rays/s in the direct pass), %s hit records%s\n"
               "  time: %s write %.2f s; total %.2f s\n  memory: estimated %s, peak %s (estimated by phase: %s)\n",
               a.scene.c_str(), a.output.c_str(), formatCount(double(st.vertices)).c_str(),
               st.backVertices ? cat(" (", formatCount(double(st.backVertices)), " of them two-sided)").c_str() : "",
               r.scene.meshes.size() - receivers, receivers, s.bands, s.samples, s.shadowed ? s.bounces : 0,
               s.shadowed ? "" : " (unshadowed)", formatCount(double(st.rays)).c_str(),
               formatCount(directSeconds > 0 ? double(st.rays) / directSeconds : 0.0).c_str(),
               formatCount(double(st.hitRecords)).c_str(), st.resumed ? "; resumed from the checkpoint" : "",
               stages.str().c_str(), r.writeSeconds, r.refined.seconds + st.seconds + r.writeSeconds,
               formatBytes(r.memory.total).c_str(), formatBytes(peakMemoryBytes()).c_str(), r.memory.phases().c_str());
}

// The refinement's line, the receivers' and the ranks'.
void printRefinementAndRanks(const bake::BakeReport& r) {
  const bake::RefineStats& refined = r.refined;
  if (r.refine.tolerance > 0.0)
    std::fprintf(
        stderr,
        "  refinement: %s -> %s vertices, %s -> %s triangles in %d rounds (tolerance %g, budget %s%s), "
        "residual %.3f; %s points, %s rays in %.2f s\n",
        formatCount(double(refined.verticesBefore)).c_str(), formatCount(double(refined.verticesAfter)).c_str(),
        formatCount(double(refined.trianglesBefore)).c_str(), formatCount(double(refined.trianglesAfter)).c_str(),
        refined.rounds, r.refine.tolerance, formatCount(double(refined.budget)).c_str(),
        refined.budgetReached ? ", reached" : "", refined.residual, formatCount(double(refined.points)).c_str(),
        formatCount(double(refined.rays)).c_str(), refined.seconds);
  for (const std::string& line : describeReceivers(r.scene, "--receiver"))
    std::fprintf(stderr, "  receiver %s\n", line.c_str());
  if (r.mpi)
    std::fprintf(stderr, "  ranks: %d (MPI%s); rank 0 received %s from the others in %llu exchanges\n", r.ranks,
                 r.transportChoice.empty() ? "" : cat(": ", r.transportChoice).c_str(),
                 formatBytes(r.bytesReceived).c_str(), static_cast<unsigned long long>(r.gathers));
}

// The probe grid's lines: what was placed and baked, and per valid probe.
void printProbes(const BakeArgs& a, const bake::BakeReport& r) {
  const bake::ProbeStats& ps = r.probes;
  const std::string restored =
      ps.restored ? cat("; ", formatCount(double(ps.restored)), " restored from the checkpoint") : "";
  const std::string outside =
      ps.outside ? cat(", ", formatCount(double(ps.outside)),
                       ps.insideOnly ? " outside the closed level" : " in open air far from surfaces",
                       ps.aboveLevel ? cat(" or over the level (", formatCount(double(ps.aboveLevel)), " more than ",
                                           a.probeHeight, " above the ground under open sky)")
                                     : std::string(),
                       " (not baked; --probe-region everywhere bakes them)")
                 : "";
  std::fprintf(stderr,
               "  probes: %s lattice points, %s active (%s valid), %s inside geometry, %s moved out%s; %s rays in "
               "%.2f s (%s probes/s, %s rays/s)%s -> %s\n",
               formatCount(double(ps.probes)).c_str(), formatCount(double(ps.active)).c_str(),
               formatCount(double(ps.valid)).c_str(), formatCount(double(ps.invalid)).c_str(),
               formatCount(double(ps.moved)).c_str(), outside.c_str(), formatCount(double(ps.rays)).c_str(), ps.seconds,
               formatCount(double(ps.probes - ps.restored) / std::max(ps.seconds, 1e-9)).c_str(),
               formatCount(ps.rays / std::max(ps.seconds, 1e-9)).c_str(), restored.c_str(), a.probes.c_str());
  // Per valid probe: what a level's probe budget is planned in.
  const double valid = double(std::max<uint64_t>(ps.valid, 1));
  std::fprintf(stderr, "  per valid probe: %s on disk, %.0f µs of bake (%s in the file, %.2f s)\n",
               formatBytes(uintmax_t(double(r.probeBytes) / valid)).c_str(), 1e6 * ps.seconds / valid,
               formatBytes(r.probeBytes).c_str(), ps.seconds);
}
// The probe options of prt bake: each needs --probes (never silently ignored), --probe-dims and
// --probe-spacing exclude each other, and malformed values are one-line usage errors. Returns
// --probes.
CLI::Option* addProbeOptions(CLI::App& bake, BakeArgs& a) {
  CLI::Option* probes = bake.add_option("--probes", a.probes, "Also bake a probe grid into this OpenVDB file (.vdb)");
  CLI::Option* spacing =
      bake.add_option("--probe-spacing", a.probeSpacing, "Probe spacing in world units (else --probe-dims)")
          ->check(CLI::PositiveNumber);
  CLI::Option* dims = bake.add_option_function<std::string>(
      "--probe-dims",
      [&a](const std::string& v) {
        std::vector<double> d =
            parseNumberList("--probe-dims", v, 3, true, "three integer counts X,Y,Z (e.g. 16,16,8)");
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
          ->transform(
              choice<Region>({{"auto", Region::Auto}, {"everywhere", Region::Everywhere}, {"inside", Region::Inside}}))
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
  CLI::Option* budget = bake.add_option("--refine-budget", a.refine.budget,
                                        cat("Vertices refinement may add (0 = as many as the scene has, at least ",
                                            bake::kMinAutoBudget, ")"))
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

// The bounce operator's options (docs/lights.md, "Their bounces"; docs/formats.md).
void addOperatorOptions(CLI::App& bake, BakeArgs& a, CLI::Option* unshadowed) {
  bake::OperatorSettings& o = a.bounceOperator;
  CLI::Option* rays = bake.add_option("--operator-samples", o.samples,
                                      "Gather rays per vertex side that build the bounce operator (the bake's first "
                                      "ones; at most --samples)")
                          ->check(CLI::Range(1, bake::kMaxSamples))
                          ->capture_default_str();
  CLI::Option* cluster = bake.add_option("--operator-cluster", o.clusterSize,
                                         cat("Vertex sides per surface cluster of the bounce operator, at most (0: ",
                                             bake::kSmallClusterSize, " in scenes of up to ", bake::kSmallScenesSides,
                                             " vertex sides, else ", bake::kLargeClusterSize, ")"))
                             ->check(CLI::Range(0, 65536))
                             ->capture_default_str();
  CLI::Option* row =
      bake.add_option("--operator-row", o.rowLength,
                      "Entries per vertex side's own row of the bounce operator, at most (0: none, each takes its "
                      "cluster's light)")
          ->check(CLI::Range(0, BounceOperator::kMaxRowLength))
          ->capture_default_str();
  CLI::Option* clusterRow = bake.add_option("--operator-cluster-row", o.clusterRowLength,
                                            "Entries per cluster's row of the bounce operator (what its vertex sides "
                                            "gather, and the bounces after the first), on average over its rows (each "
                                            "at most 255; the longer ones where a shorter cut would merge more light)")
                                ->check(CLI::Range(1, BounceOperator::kMaxRowLength))
                                ->capture_default_str();
  CLI::Option* gradient =
      bake.add_option("--operator-gradient", o.gradientRowLength,
                      "Entries per row of each of a cluster's two gradients (how its vertex sides' light changes "
                      "across it), at most (0: none, each takes its cluster's mean)")
          ->check(CLI::Range(0, BounceOperator::kMaxRowLength))
          ->capture_default_str();
  CLI::Option* points = bake.add_option("--operator-points", o.samplePoints,
                                        "Shadow-ray points per cluster with which `prt render` takes the direct "
                                        "lights' light at the clusters (one ray per light and point)")
                            ->check(CLI::Range(1, 64))
                            ->capture_default_str();
  CLI::Option* probeRow =
      bake.add_option("--operator-probe-row", o.probeRowLength,
                      "With --probes: entries per probe's row of the bounce operator (the bounced light of the "
                      "direct lights, the sky detail and the lights inside the scene at the probe), at most")
          ->check(CLI::Range(1, BounceOperator::kMaxRowLength))
          ->capture_default_str();
  CLI::Option* probeRays = bake.add_option("--operator-probe-samples", o.probeSamples,
                                           "With --probes: gather rays per probe that make its row (the probe "
                                           "bake's first ones; at most --probe-samples)")
                               ->check(CLI::Range(1, bake::kMaxSamples))
                               ->capture_default_str();
  CLI::Option* off =
      bake.add_flag("--no-operator", a.noOperator,
                    "Leave out the bounce operator (docs/lights.md, \"The bounce operator\"), which `prt render` "
                    "and `prt relight` use to light the direct lights' bounces and the sky detail by sparse "
                    "products: without it they trace the bake's rays again (seconds a light change)");
  bake.add_flag("--operator", a.withOperator, "Deprecated, no effect: the bounce operator is stored by default")
      ->excludes(off);
  for (CLI::Option* x : {rays, cluster, row, clusterRow, gradient, points, probeRow, probeRays}) {
    x->excludes(off);
    x->excludes(unshadowed);
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
  addOperatorOptions(bake, a, unshadowed);
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
  // Signals (installed once the pipeline knows whether this process is an MPI rank) save the
  // checkpoint and stop the bake; warnings are printed before the work.
  std::optional<SignalScope> signals;
  bake::BakeJob job = bakeJob(a);
  job.started = [&](bool mpiRank) { signals.emplace(mpiRank); };
  job.loaded = [&](const Scene& scene) {
    if (a.allowDegenerate && !a.quiet)
      std::fprintf(stderr,
                   "prt: warning: --allow-degenerate is deprecated and does nothing: every command drops "
                   "zero-area triangles with a warning\n");
    printWarnings(scene, a.quiet);
  };
  bake::BakeReport report;
  try {
    report = bake::runPipeline(job);
  } catch (...) {
    rethrowInOptions();
  }
  using Outcome = bake::BakeReport::Outcome;
  if (report.outcome == Outcome::ShardSaved || report.outcome == Outcome::ShardAlreadyDone) printShard(a, report);
  if (report.outcome != Outcome::Written || a.quiet) return 0;
  printBake(a, report);
  printRefinementAndRanks(report);
  if (!a.probes.empty()) printProbes(a, report);
  if (report.bounceOperator.built) {
    const auto& o = report.bounceOperator;
    std::fprintf(stderr,
                 "  bounce operator: %s clusters, %s vertex entries, %s cluster entries, %s probe entries, %s in the "
                 "file, built in %.2f s\n",
                 formatCount(double(o.clusters)).c_str(), formatCount(double(o.vertexEntries)).c_str(),
                 formatCount(double(o.clusterEntries)).c_str(), formatCount(double(o.probeEntries)).c_str(),
                 formatBytes(o.bytes).c_str(), o.seconds);
  }
  return 0;
}

}  // namespace prt::tools
