// One runner for every chunked stage of a bake (the direct pass, each bounce, the probe
// stage), in the spirit of pbrt-v4's ImageTileIntegrator::Render beside Li: the runner owns
// everything that is not physics (deterministic chunks, TBB threads, restoring finished chunks
// from the checkpoint, registering the stage with it, interrupt polling, progress and timing),
// and a stage hands it a per-chunk function that holds only the estimator.
//
// Determinism: a chunk's result must depend on the chunk alone (its items, the settings and
// the seed), never on the thread that computes it or on the other chunks. The runner may then
// run chunks in any order, restore some from a checkpoint, and take them from other processes
// (ranks.h: ranks on one host take chunks from a shared counter as they come free, elsewhere
// chunk c is computed by rank c mod N; at the end of the stage the ranks trade chunk records
// and apply them as a restore does), and the stage's buffers end up with the same bits.
#pragma once

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <tbb/global_control.h>

#include "prt/bake/checkpoint.h"
#include "prt/bake/ranks.h"
#include "prt/bake/stats.h"

namespace prt {
class Progress;
}

namespace prt::bake {

/// Seconds of the steady clock since t0.
inline double secondsSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

/// Caps the TBB threads of all work done while it lives; 0 leaves every core to TBB.
class ThreadLimit {
 public:
  explicit ThreadLimit(int threads);

 private:
  std::unique_ptr<tbb::global_control> control_;
};

/// Forgets the checkpoint's stage writers when it goes out of scope: they point into buffers
/// of the function that owns it, which would dangle once it returns or unwinds.
class StageRelease {
 public:
  explicit StageRelease(Checkpoint* cp) : cp_(cp) {}
  ~StageRelease() {
    if (cp_) cp_->releaseStages();
  }
  StageRelease(const StageRelease&) = delete;
  StageRelease& operator=(const StageRelease&) = delete;

 private:
  Checkpoint* cp_;
};

/// If an interrupt was requested: saves the checkpoint (if any), then throws prt::Interrupted.
void stopIfInterrupted(Checkpoint* cp);

/// Chunk `index` of a stage: its items [begin, end).
struct Chunk {
  uint64_t index = 0;
  size_t begin = 0, end = 0;
};

/// What a chunk function reports: finished = false when it saw an interrupt and gave up (its
/// buffers are then incomplete and the chunk is computed again on resume); the rays it cast.
struct ChunkOutcome {
  bool finished = true;
  uint64_t rays = 0;
};

/// Chunk `index` when `items` fall into chunks of `chunkSize`: items [index·chunkSize,
/// min(items, (index + 1)·chunkSize)). The split depends on nothing else, so a chunk means the
/// same items in every run and on every thread count.
inline Chunk chunkOf(size_t items, size_t chunkSize, uint64_t index) {
  return Chunk{index, size_t(index) * chunkSize, std::min(items, size_t(index + 1) * chunkSize)};
}

struct StageSpec {
  uint32_t id = 0;    // checkpoint stage id
  std::string label;  // names the stage in checkpoint messages: "direct pass"
  std::string name;   // progress bar and StageStats: "direct", "bounce 1"
  std::string unit;   // what the items are: "vertices"
  size_t items = 0;
  size_t chunkSize = 0;   // items per chunk; the last chunk may hold fewer
  bool progress = false;  // progress bar on stderr
  /// Other ranks' chunks: every rank needs them (false: only rank 0, which writes the outputs).
  bool everyRankNeedsChunks = true;
  /// The chunks this rank computes (nonzero entries), whatever the ranks' split: a bounce
  /// gathers where the direct pass's hit records are (SurfaceBake::holds). Null: the ranks'
  /// split (Ranks::chunkCounter, or Ranks::owns).
  const std::vector<uint8_t>* computes = nullptr;
};

/// One stage's chunks: which are done, and running the rest.
class ChunkedStage {
 public:
  /// Reads one restored chunk record into the stage's buffers.
  using RestoreFn = std::function<void(const Chunk&, ByteReader&)>;
  /// Writes what other ranks need of a finished chunk.
  using WriteFn = std::function<void(uint64_t chunk, ByteWriter&)>;
  /// Computes one chunk (called from TBB worker threads, each chunk once).
  using ChunkFn = std::function<ChunkOutcome(const Chunk&)>;

  /// `cp` may be null: no records are restored or written, and an interrupt still stops it.
  ChunkedStage(StageSpec spec, Checkpoint* cp);

  size_t chunks() const { return done_.size(); }
  Chunk chunk(uint64_t index) const { return chunkOf(spec_.items, spec_.chunkSize, index); }
  /// Reads the checkpoint's chunk records of this stage with `fn` (a record whose index is out
  /// of range is a corrupt checkpoint, reported as `what`) and marks them done. `fn` also
  /// reads the records other ranks send (unless exchangeWith() says otherwise).
  void restore(const RestoreFn& fn, const std::string& what = "chunk index");
  uint64_t restoredChunks() const { return restoredChunks_; }
  /// Items of the restored chunks.
  size_t restoredItems() const { return restoredItems_; }
  /// Chunks not done yet that this rank may compute: its own (split statically, or
  /// StageSpec::computes), or, taken from a shared counter, those no rank has done.
  size_t chunksLeft() const;
  /// The chunks this process computes, in increasing order, where they are known before the
  /// stage runs: StageSpec::computes, or the chunks of its rank (Ranks::owns, every chunk for
  /// one process), not done yet. With a shared counter (Ranks::chunkCounter), run() takes them
  /// as they come instead. Here and in run() chunks meet ranks.
  std::vector<uint64_t> assignedChunks() const;
  /// What ranks trade at the end of the stage, when it is not the checkpoint's chunk record
  /// (StageIo::writeChunk) read back by the restore function: the direct pass sends its
  /// transfer without the hit records, which only the chunk's own rank gathers.
  void exchangeWith(WriteFn write, RestoreFn read);
  /// MPI ranks (collective): trades the chunks done so far, as run() does at its end, for a
  /// stage restored but not run (the direct pass of a bake resumed in a bounce, whose transfer
  /// every rank needs). Nothing for one process or shards.
  void share();

  /// Registers the stage with the checkpoint (Checkpoint::beginStage); `io` writes its state
  /// and finished chunks. Call after restore(), before run().
  void begin(Checkpoint::StageIo io);
  /// Runs `fn` on every assigned chunk on TBB threads, skipping all once an interrupt is
  /// requested; reports each finished chunk to the checkpoint and the progress bar. Then stops
  /// if interrupted (saving). With several ranks it then saves the checkpoint (so that every
  /// rank's file holds all its chunks of a stage before any rank goes on) and trades chunk
  /// records with the other ranks, or, a shard, stops with ShardDone while other shards' chunks
  /// are missing. Ends the stage. The seconds and rays (of all ranks) of this run.
  StageStats run(const ChunkFn& fn);

 private:
  void exchange();
  void runShared(const ChunkFn& fn, std::atomic<uint64_t>& rays, Progress& progress);
  void runAssigned(const ChunkFn& fn, std::atomic<uint64_t>& rays, Progress& progress);
  void finishChunk(const Chunk& c, uint64_t rays, std::atomic<uint64_t>& total);

  StageSpec spec_;
  Checkpoint* cp_;
  uint64_t* counter_ = nullptr;  // Ranks::chunkCounter of this stage, or null
  std::vector<uint8_t> done_;    // done by any rank (as far as this rank knows)
  std::vector<uint8_t> mine_;    // computed by this rank, or restored from its checkpoint: what it sends
  WriteFn write_;
  RestoreFn read_;
  bool exchangeSet_ = false;
  uint64_t restoredChunks_ = 0;
  size_t restoredItems_ = 0;
};

/// Calls fn(i) on TBB threads for this rank's share of the indices [0, count) of a loop the MPI
/// ranks split (Ranks::exchanges): taken from `counter` (Ranks::chunkCounter) as this rank's
/// threads come free, or, without one, the indices the rank owns (Ranks::owns). Stops taking
/// once an interrupt is requested.
void forRankShare(uint64_t* counter, uint64_t count, const std::function<void(uint64_t)>& fn);

/// A stage whose restored chunks need nothing before it runs: restore, begin, run.
StageStats runChunkedStage(StageSpec spec, Checkpoint* cp, const ChunkedStage::RestoreFn& restore,
                           Checkpoint::StageIo io, const ChunkedStage::ChunkFn& fn);

}  // namespace prt::bake
