// Interruption and resume of long bakes (docs/bake.md, "Interrupting and resuming").
//
// A bake is split into stages (the direct pass, each bounce pass, the probe pass), and each
// stage into chunks whose results are deterministic functions of the settings and the seed.
// The checkpoint is an append-only log of checksummed records, written from the bake's own
// buffers:
//   chunk records  the result of one finished chunk of a stage;
//   state records  what a stage starts from (e.g. the previous bounce and the running sum),
//                  written once, before the first chunk record of that stage;
//   commit marks   everything before a commit mark belongs to one consistent flush.
// On resume, records after the last valid commit mark (a torn write after kill -9 or a power
// cut) are dropped, the stage restores its state and finished chunks, and computes only the
// others: the result is bit-identical to an uninterrupted bake.
//
// Interruption (prt/bake/interrupt.h): work loops poll interruptRequested() between chunks
// and call Checkpoint::stopIfInterrupted(), which saves the checkpoint and throws
// prt::Interrupted. Records are written and read with prt/bake/serialize.h.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "prt/bake/interrupt.h"
#include "prt/bake/serialize.h"
#include "prt/error.h"
#include "prt/scene.h"

namespace prt::bake {

/// What must match for a checkpoint to be resumed: named values in a fixed order
/// ("samples" = "1024", "scene geometry" = "9f3a..."). Thread counts do not belong here.
struct Fingerprint {
  std::vector<std::pair<std::string, std::string>> entries;
  void add(const std::string& key, const std::string& value) { entries.emplace_back(key, value); }
};

/// Adds "scene geometry" and "scene materials": hashes of everything the bake reads from the
/// loaded scene (instances, receivers, positions, normals, indices, texture coordinates,
/// colours, materials, texels). A scene file, a buffer or a texture edited since the
/// checkpoint, or other --receiver nodes, change them. A scene with double-sided instances
/// also adds "two-sided vertices" (the back sides the bake adds as vertices).
void addSceneFingerprint(Fingerprint& fp, const Scene& scene);

/// Thrown by Checkpoint when a checkpoint exists where a fresh bake would start one.
class CheckpointExists : public Error {
 public:
  using Error::Error;
};

/// Thrown by mergeShards when shard `index` of `count` left no finished log (it was never run).
class ShardMissing : public Error {
 public:
  ShardMissing(const std::string& what, int index, int count) : Error(what), index(index), count(count) {}
  int index, count;
};

struct CheckpointOptions {
  std::string path;
  /// Seconds between periodic saves (at most one interval of work is lost to kill -9 or a
  /// power cut); 0: save only when interrupted and when a stage asks for it.
  double intervalSeconds = 60.0;
  /// Continue the checkpoint at `path` (it must exist and match); otherwise there must be none.
  bool resume = false;
  /// Tests: request an interrupt (SIGINT) once this many chunks have finished in this run, or,
  /// with interruptInStage, in that stage (its id) of this run, or at that stage's end where
  /// this run finished fewer there (a rank that a shared counter gave fewer chunks).
  uint64_t interruptAfterChunks = 0;
  uint32_t interruptInStage = 0;
  /// With resume: a missing file is a fresh checkpoint (a rank that never saved, ranks.h).
  bool missingIsFresh = false;
  /// A checkpoint read before this one's own records and never written (shards read the
  /// merged stages there, and save their own share at `path`); empty: none. Its fingerprint
  /// must match.
  std::string basePath;
};

/// One bake's checkpoint. Created before the bake; the file appears at the first save.
class Checkpoint {
 public:
  /// Without resume: throws prt::Error if a file exists at options.path (it may hold hours of
  /// work: --resume continues it). With resume: reads and validates it, and throws prt::Error
  /// naming what differs when it was made with another fingerprint, or when there is none.
  Checkpoint(CheckpointOptions options, Fingerprint fingerprint);
  ~Checkpoint();
  Checkpoint(const Checkpoint&) = delete;
  Checkpoint& operator=(const Checkpoint&) = delete;

  const std::string& path() const;
  /// Is there a file (made by this run or resumed)?
  bool exists() const;

  // ---- What was restored (empty when not resuming).
  /// The latest stage with a state record, or 0 if none. Stage ids grow with the bake.
  uint32_t restoredStateStage() const;
  /// Calls fn(reader) with the state record of `stage`; false if there is none.
  bool restoreState(uint32_t stage, const std::function<void(ByteReader&)>& fn) const;
  /// Calls fn(chunk, reader) for every restored chunk record of `stage`, in file order.
  /// Returns how many there were.
  uint64_t restoreChunks(uint32_t stage, const std::function<void(uint64_t, ByteReader&)>& fn) const;
  /// Whether this checkpoint's own file (not its base) holds chunk records of `stage`.
  bool ownChunks(uint32_t stage) const;

  // ---- Used by a running stage.
  struct StageIo {
    /// Serialises a finished chunk (called later, from whichever thread saves).
    std::function<void(uint64_t chunk, ByteWriter&)> writeChunk;
    /// Serialises the state the stage starts from; empty if it has none.
    std::function<void(ByteWriter&)> writeState;
    /// True: finished chunks stay needed after the stage (their records are saved even when
    /// the stage is over). False: a later stage's state supersedes them.
    bool chunksOutliveStage = false;
  };
  /// Starts stage `id` (> every earlier id) of `chunks` chunks, `restored` of them already
  /// done. `label` names it in messages ("direct pass").
  void beginStage(uint32_t id, const std::string& label, uint64_t chunks, uint64_t restored, StageIo io);
  /// A chunk of the current stage finished; may save (interval), from the calling thread.
  /// Thread-safe.
  void complete(uint64_t chunk);
  /// Ends the current stage. Pending chunk records are kept or dropped (chunksOutliveStage).
  void endStage();
  /// Saves every pending record and the current stage's state, and syncs the file.
  void save();
  /// If an interrupt was requested: saves, then throws prt::Interrupted.
  void stopIfInterrupted();
  /// The current stage's chunks are all taken: requests the interrupt of interruptInStage if
  /// this run finished fewer chunks there than interruptAfterChunks.
  void chunksTaken();
  /// Forgets every stage's writers and the records not yet saved: call when the function
  /// that owns the stages' buffers returns or unwinds (they would dangle).
  void releaseStages();
  /// "direct pass 37% done" (the current stage).
  std::string progressText() const;
  /// Deletes the file (after the outputs are in place).
  void remove();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// The file shard `index` of `count` saves its share of a stage into: "PATH.shard-I-of-N";
/// once its share is done it is renamed to that name + ".done".
std::string shardCheckpointPath(const std::string& path, int index, int count);

struct MergeStats {
  std::vector<uint32_t> stages;  // stage ids whose chunk records were merged
  uint64_t chunkRecords = 0, stateRecords = 0;
};

/// Joins the finished shards of a stage (every "PATH.shard-I-of-N.done", I < count) into the
/// checkpoint at `path` (created when missing): appends their state records of stages it has
/// none of and their chunk records it lacks, commits, syncs, then deletes the shard files. All
/// fingerprints must match. Throws prt::Error naming a missing or mismatched shard file.
MergeStats mergeShards(const std::string& path, int count);

}  // namespace prt::bake
