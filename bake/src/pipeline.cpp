// A whole bake in one call (prt/bake/pipeline.h): the processes, the checkpoint, the memory
// guard, the stages in order and the outputs.
#include "prt/bake/pipeline.h"

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <memory>
#include <optional>
#include <utility>

#include "prt/atomic_file.h"
#include "prt/bake/ranks.h"
#include "prt/probe_grid.h"
#include "prt/version.h"

namespace prt::bake {

Fingerprint bakeFingerprint(const Scene& scene, const BakeSettings& s, const RefineSettings& r, const ProbeSettings* ps,
                            bool probeHalf) {
  Fingerprint fp;
  fp.add("prt", kVersion);
  addSceneFingerprint(fp, scene);
  addRefineFingerprint(fp, r, s);
  fp.add("bands", std::to_string(s.bands));
  fp.add("samples", std::to_string(s.samples));
  fp.add("bounces", std::to_string(s.bounces));
  fp.add("seed", std::to_string(s.seed));
  fp.add("direct part", "kept apart");  // records of prts before the transfer split lack it
  fp.add("probes", ps ? "yes" : "no");
  if (ps) {
    addProbeFingerprint(fp, *ps);
    fp.add("probe half", probeHalf ? "yes" : "no");  // the .vdb written from the same results
  }
  return fp;
}

namespace {

// The processes of this bake (docs/scale.md): MPI's ranks under a launcher, a shard's, or one
// process (neither).
struct Processes {
  std::unique_ptr<Ranks> mpi, shard;
  Ranks* active() const { return mpi ? mpi.get() : shard.get(); }
};

Processes startProcesses(const BakeJob& job) {
  Processes p;
  if (launcherRank() >= 0) {
    if (!mpiBuilt())
      throw BakeRefused(BakeRefused::Reason::MpiNotBuilt, "",
                        "started as one of several MPI ranks, but this prt was built without MPI (install "
                        "libopenmpi-dev and build again, or bake in shards)");
    if (job.shardCount > 0)
      throw BakeRefused(BakeRefused::Reason::ShardUnderMpi, "",
                        "shard: not under mpirun (MPI ranks share every stage themselves)");
    p.mpi = startMpi();
  }
  if (job.shardCount > 0) p.shard = shardRanks(job.shardIndex, job.shardCount);
  return p;
}

// The probe settings of a bake: the job's placement and samples, the surface bake's bands,
// bounces (none unshadowed), seed, threads and progress.
ProbeSettings probeSettings(const ProbeSettings& job, const BakeSettings& s) {
  ProbeSettings ps = job;
  ps.bands = s.bands;
  ps.bounces = s.shadowed ? s.bounces : 0;
  ps.seed = s.seed;
  ps.progress = s.progress;
  ps.threads = s.threads;
  validate(ps);
  return ps;
}

// The settings as baked, checked, and the outputs checked writable before hours of work (by the
// one process that writes them).
struct Plan {
  BakeSettings settings;
  std::optional<ProbeSettings> probes;
  const ProbeSettings* probesOrNull() const { return probes ? &*probes : nullptr; }
};

Plan planJob(const BakeJob& job, bool writer) {
  Plan plan;
  plan.settings = job.settings;
  plan.settings.progress = job.settings.progress && ranks().rank() == 0;
  validate(plan.settings);
  if (writer) AtomicFile probe(job.outputs.scene);
  if (job.probes) {
    if (writer) AtomicFile probe(job.outputs.probes);
    plan.probes = probeSettings(*job.probes, plan.settings);
    plan.settings.keepLowerOrder = true;
  }
  // The operator's rays are the bake's first ones: kept from its direct pass, not traced again.
  if (job.bounceOperator) plan.settings.keepGatherRays = std::min(job.bounceOperator->samples, plan.settings.samples);
  if (job.bounceOperator && job.probes) plan.settings.operatorProbeRowLength = job.bounceOperator->probeRowLength;
  return plan;
}

// The memory guard (docs/bake.md, "Memory"): first without the hit records (before the BVH is
// built) and with the refinement's budget, then with the bound the bake measures on a pilot of
// its own rays on the refined scene (BakeControl::checkMemory). The probe stage's bound counts
// every lattice point as baked; where that bound is what does not fit, the placement's own rays
// (about 64 a point, on the scene before refinement, whose surfaces refinement keeps) count the
// points the bake keeps, and that count is checked.
class MemoryGuard {
 public:
  MemoryGuard(const BakeJob& job, const Scene& scene, const BakeSettings& s, const ProbeSettings* ps)
      : names_(job.memoryNames), scene_(scene), s_(s), ps_(ps), limit_(memoryLimit(job.maxMemory)) {
    estimate_ = estimateBakeMemory(scene, s, ps, 0.0);
    const MemoryEstimate& e = estimate_;
    // The probe stage, or the write with the bounce operator's probe rows, as the largest phase.
    const bool probesLargest = e.probePeak >= std::max({e.surfacePeak, e.writePeak, e.refinePeak}) ||
                               (s.operatorProbeRowLength > 0 && e.writePeak >= std::max(e.surfacePeak, e.refinePeak));
    if (limit_ && ps && e.total > limit_->bytes && probesLargest) {
      placement_ = placeProbes(scene, *ps);
      estimate_ = estimateBakeMemory(scene, s, ps, 0.0, &*placement_);
    }
    check();
    refinePeak_ = estimate_.refinePeak;
  }
  /// The second check, on the pilot's share of hit records. The refinement phase is over by
  /// then, but the estimate it reports still bounds the whole run's peak: it keeps that phase.
  void recheck(double frontHitShare) {
    estimate_ = estimateBakeMemory(scene_, s_, ps_, frontHitShare, placement_ ? &*placement_ : nullptr);
    check();
    estimate_.keepRefinePhase(refinePeak_);
  }
  const MemoryEstimate& estimate() const { return estimate_; }

 private:
  void check() const {
    if (limit_) checkMemory(estimate_, *limit_, scene_, s_, ps_, names_);
  }
  const MemoryAdviceNames& names_;
  const Scene& scene_;
  const BakeSettings& s_;  // read at each check: refinement's budget is dropped once it ran
  const ProbeSettings* ps_;
  std::optional<MemoryLimit> limit_;
  MemoryEstimate estimate_;
  std::optional<ProbePlacement> placement_;
  uint64_t refinePeak_ = 0;
};

// The checkpoint of this process. Under MPI one file per rank, each holding the chunks its rank
// computed; they resume together. A shard reads the merged stages at the checkpoint's path and
// saves its share apart; run again (preempted, or as a retry) it goes on from its own file.
CheckpointOptions checkpointOptions(const BakeJob& job, const std::string& path, bool mpi, bool shard) {
  CheckpointOptions co;
  co.path = path;
  co.intervalSeconds = job.checkpoint.intervalSeconds;
  co.resume = job.checkpoint.resume;
  co.interruptAfterChunks = job.checkpoint.interruptAfterChunks;
  co.interruptInStage = job.checkpoint.interruptInStage;
  std::error_code ec;
  if (mpi) {
    co.path = cat(path, ".rank-", ranks().rank(), "-of-", ranks().size());
    co.missingIsFresh = true;  // a rank that never saved
  }
  if (shard) {
    co.path = shardCheckpointPath(path, job.shardIndex, job.shardCount);
    co.resume = std::filesystem::exists(co.path, ec);
    if (std::filesystem::exists(path, ec)) co.basePath = path;
  }
  return co;
}

void openCheckpoint(std::optional<Checkpoint>& checkpoint, const CheckpointOptions& co, Fingerprint fp, bool mpi) {
  if (mpi) fp.add("ranks", std::to_string(ranks().size()));
  try {
    checkpoint.emplace(co, fp);
  } catch (const CheckpointExists& e) {
    throw BakeRefused(BakeRefused::Reason::CheckpointFound, co.path, e.what());
  }
}

// Runs a stage; an interruption names the checkpoint and how far the bake got (under MPI one
// line for all ranks: the tool prints rank 0's when every rank stops).
template <class Run>
auto savingOnInterrupt(Checkpoint* checkpoint, const std::string& path, bool mpi, Run&& run) {
  try {
    return run();
  } catch (const Interrupted&) {
    if (!checkpoint) throw;
    if (mpi)
      throw InterruptedAndSaved(cat("interrupted: checkpoints saved to ", path, ".rank-*-of-", ranks().size(),
                                    " (rank ", ranks().rank(), ": ", checkpoint->progressText(), ")"));
    throw InterruptedAndSaved(
        cat("interrupted: checkpoint saved to ", checkpoint->path(), " (", checkpoint->progressText(), ")"));
  }
}

// The stages in order. Refinement is deterministic: a resumed bake refines again, to the same
// meshes, before it restores the stages that follow (the checkpoint's fingerprint holds its
// settings). With probes, the direct pass's BVH is kept for the probe stage (one build, not
// two); it is built after refinement, which changes the meshes, and freed once the probes are
// traced.
struct Stages {
  SurfaceTransfer surface;
  std::optional<ProbeGrid> grid;
};

Stages runStages(const BakeJob& job, Plan& plan, BakeReport& report, MemoryGuard& guard, Checkpoint* checkpoint,
                 bool mpi) {
  Scene& scene = report.scene;
  auto stage = [&](auto&& run) { return savingOnInterrupt(checkpoint, report.checkpointPath, mpi, run); };
  BakeControl control;
  control.checkpoint = checkpoint;
  std::optional<SharedRayScene> sharedRays;
  if (plan.probes) control.rays = &sharedRays.emplace(scene);
  control.checkMemory = [&](double share) { guard.recheck(share); };
  Stages out;
  report.refined = stage([&] { return refineScene(scene, report.refine, plan.settings, checkpoint); });
  plan.settings.refineVertices = 0;  // the scene holds them now
  out.surface = stage([&] { return bakeSurface(scene, plan.settings, control); });
  if (!plan.probes) return out;
  if (out.surface.perMeshLowerOrder.empty()) out.surface.perMeshLowerOrder.assign(scene.meshes.size(), {});
  out.grid = stage([&] {
    return bakeProbes(scene, out.surface.perMeshLowerOrder, *plan.probes, &report.probes, checkpoint,
                      control.rays);  // which it releases once traced
  });
  out.grid->info.scene = std::filesystem::path(job.scenePath).filename().string();
  return out;
}

// The bounce operator of the baked scene, from the bake's own rays (the first of each vertex's).
// With the probe grid, the probes' rows too (made by this process alone under MPI).
void buildOperator(OperatorSettings os, const BakeSettings& s, const ProbeGrid* grid, const GatherRecords& kept,
                   BakeReport& report) {
  const auto t0 = std::chrono::steady_clock::now();
  os.samples = std::min(os.samples, s.samples);
  os.threads = s.threads;
  auto op = std::make_shared<BounceOperator>(
      buildBounceOperator(report.scene, os, s.bounces, s.seed, false, grid, nullptr, &kept));
  BakeReport::Operator& r = report.bounceOperator;
  r.built = true;
  r.bytes = packOperator(*op).bytes.size();
  r.clusters = op->clusters;
  r.vertexEntries = op->vertexRows.entries();
  r.clusterEntries = op->clusterRows.entries();
  r.probeEntries = op->probeRows.rows.entries();
  report.scene.bounceOperator = std::move(op);
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// The bounce operator is built when it is asked for and the scene has baked surfaces (a scene of
// receivers only has none to cluster).
bool buildsOperator(const BakeJob& job, const BakeReport& report) {
  if (!job.bounceOperator || !report.settings.shadowed) return false;
  return std::any_of(report.scene.meshes.begin(), report.scene.meshes.end(),
                     [](const MeshInstance& m) { return !m.transfer.empty(); });
}

// Under MPI every rank builds its share of the bounce operator's rows (build.cpp sends them to
// rank 0, whose writeOutputs builds the rest): the ranks other than the writer call this.
void buildOperatorShare(const BakeJob& job, Stages& stages, BakeReport& report) {
  const BakeSettings& s = report.settings;
  storeTransfer(report.scene, std::move(stages.surface.perMesh), std::move(stages.surface.perMeshDirect));
  report.scene.transferBands = s.bands;
  if (!buildsOperator(job, report)) return;
  OperatorSettings os = *job.bounceOperator;
  os.samples = std::min(os.samples, s.samples);
  os.threads = s.threads;
  buildBounceOperator(report.scene, os, s.bounces, s.seed, false, nullptr, nullptr, &stages.surface.gather);
}

// The baked scene with its record, and the probe grid (written first, as the bake finishes it).
void writeOutputs(const BakeJob& job, Stages& stages, BakeReport& report) {
  if (stages.grid) {
    writeProbeGrid(*stages.grid, job.outputs.probes, job.outputs.probeHalf);
    report.probeBytes = std::filesystem::file_size(job.outputs.probes);
  }
  Scene& scene = report.scene;
  const BakeSettings& s = report.settings;
  storeTransfer(scene, std::move(stages.surface.perMesh), std::move(stages.surface.perMeshDirect));
  scene.transferBands = s.bands;
  if (buildsOperator(job, report))
    buildOperator(*job.bounceOperator, s, stages.grid ? &*stages.grid : nullptr, stages.surface.gather, report);
  stages.surface.gather = {};
  const auto t0 = std::chrono::steady_clock::now();
  BakeRecord record = bakeRecord(s, std::filesystem::path(job.scenePath).filename().string(), kVersion);
  const RefineSettings& refine = report.refine;
  const RefineStats& refined = report.refined;
  if (refine.tolerance > 0.0)
    record.refinement = {refine.tolerance,       refined.budget,        std::min(refine.samples, s.samples),
                         refined.verticesBefore, refined.verticesAfter, refined.residual};
  record.backTransfer =
      std::any_of(scene.meshes.begin(), scene.meshes.end(), [](const MeshInstance& m) { return m.hasBackTransfer(); });
  record.directTransfer = std::any_of(scene.meshes.begin(), scene.meshes.end(),
                                      [](const MeshInstance& m) { return m.hasDirectTransfer(); });
  writeBakedScene(job.scenePath, scene, &record, job.outputs.scene);
  report.writeSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

void reportRanks(BakeReport& report, bool mpi) {
  Ranks& r = ranks();
  report.mpi = mpi;
  report.ranks = r.size();
  report.transportChoice = r.transportChoice();
  report.bytesReceived = r.bytesReceived();
  report.gathers = r.gathers();
}

}  // namespace

BakeReport runPipeline(const BakeJob& job) {
  const Processes processes = startProcesses(job);
  const RanksScope ranksScope(processes.active());
  const bool mpi = processes.mpi != nullptr, shard = processes.shard != nullptr;
  if (job.started) job.started(mpi);
  const bool writer = ranks().rank() == 0 && !shard;  // the one process that writes the outputs
  Plan plan = planJob(job, writer);
  BakeReport report;
  report.scene = loadScene(job.scenePath, job.load);
  if (job.loaded) job.loaded(report.scene);
  Scene& scene = report.scene;
  report.refine = job.refine;
  if (!plan.settings.shadowed) report.refine.tolerance = 0.0;
  if (report.refine.tolerance > 0.0) plan.settings.refineVertices = refineBudget(report.refine, scene);
  MemoryGuard guard(job, scene, plan.settings, plan.probesOrNull());

  report.checkpointPath = job.checkpoint.path.empty() ? job.outputs.scene + ".prt-checkpoint" : job.checkpoint.path;
  std::optional<Checkpoint> checkpoint;
  if (plan.settings.shadowed) {
    const CheckpointOptions co = checkpointOptions(job, report.checkpointPath, mpi, shard);
    report.shardFile = co.path;
    std::error_code ec;
    if (shard && std::filesystem::exists(co.path + ".done", ec)) {
      report.outcome = BakeReport::Outcome::ShardAlreadyDone;
      return report;
    }
    const Fingerprint fp =
        bakeFingerprint(scene, plan.settings, report.refine, plan.probesOrNull(), job.outputs.probeHalf);
    openCheckpoint(checkpoint, co, fp, mpi);
    if (mpi && job.checkpoint.resume && ranks().sum(checkpoint->exists() ? 1 : 0) == 0)
      throw Error(cat(report.checkpointPath, ".rank-*-of-", ranks().size(),
                      ": no checkpoint to resume (a bake writes one per rank when interrupted, or every checkpoint "
                      "interval); start the bake afresh"));
  }
  Stages stages;
  try {
    stages = runStages(job, plan, report, guard, checkpoint ? &*checkpoint : nullptr, mpi);
  } catch (const ShardDone& done) {
    // This shard's share of a stage is saved: its file is marked finished for the merge.
    std::filesystem::rename(checkpoint->path(), checkpoint->path() + ".done");
    report.outcome = BakeReport::Outcome::ShardSaved;
    report.shardStage = done.what();
    return report;
  }
  if (shard)
    throw BakeRefused(BakeRefused::Reason::ShardsMerged, report.checkpointPath,
                      cat(report.checkpointPath,
                          ": every stage is merged; write the outputs with the same bake "
                          "resumed, not as a shard"));
  report.settings = plan.settings;
  report.surface = stages.surface.stats;
  report.memory = guard.estimate();
  if (writer)
    writeOutputs(job, stages, report);
  else if (mpi && job.bounceOperator && report.settings.shadowed)
    buildOperatorShare(job, stages, report);
  // The outputs are in place: the checkpoint has served (every rank's, after the barrier).
  ranks().barrier();
  if (checkpoint) checkpoint->remove();
  reportRanks(report, mpi);
  report.outcome = writer ? BakeReport::Outcome::Written : BakeReport::Outcome::OtherRank;
  return report;
}

}  // namespace prt::bake
