#include "stage_runner.h"

#include <algorithm>
#include <atomic>
#include <chrono>

#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include "prt/error.h"
#include "prt/progress.h"

namespace prt::bake {

ThreadLimit::ThreadLimit(int threads) {
  if (threads > 0)
    control_ = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, size_t(threads));
}

void stopIfInterrupted(Checkpoint* cp) {
  if (cp) cp->stopIfInterrupted();
  if (interruptRequested()) throw Interrupted("interrupted");
}

ChunkedStage::ChunkedStage(StageSpec spec, Checkpoint* cp) : spec_(std::move(spec)), cp_(cp) {
  PRT_CHECK_GT(spec_.chunkSize, size_t(0));
  done_.assign((spec_.items + spec_.chunkSize - 1) / spec_.chunkSize, 0);
  mine_.assign(done_.size(), 0);
  if (spec_.computes) {
    PRT_CHECK_EQ(spec_.computes->size(), done_.size());
  } else if (ranks().exchanges()) {
    counter_ = ranks().chunkCounter(stageCounterSlot(spec_.id));
  }
}

void ChunkedStage::restore(const RestoreFn& fn, const std::string& what) {
  if (!exchangeSet_) read_ = fn;
  if (!cp_) return;
  restoredChunks_ = cp_->restoreChunks(spec_.id, [&](uint64_t c, ByteReader& r) {
    if (c >= chunks()) r.fail(what);
    const Chunk ch = chunk(c);
    fn(ch, r);
    if (!done_[c]) restoredItems_ += ch.end - ch.begin;
    done_[c] = 1;
    mine_[c] = 1;  // a rank's checkpoint holds the chunks it computed
  });
  // Taken from a shared counter, the chunks restored on other ranks are skipped too: every
  // rank learns which they are (collective; on every rank alike, as the counter is).
  Ranks& r = ranks();
  if (counter_ && r.sum(restoredChunks_) > 0) {
    const std::vector<std::string> all = r.gather(std::string(done_.begin(), done_.end()), true);
    for (const std::string& done : all)
      for (size_t c = 0; c < done.size() && c < done_.size(); ++c) done_[c] |= uint8_t(done[c]);
  }
}

size_t ChunkedStage::chunksLeft() const {
  if (counter_) return size_t(std::count(done_.begin(), done_.end(), 0));
  return assignedChunks().size();
}

std::vector<uint64_t> ChunkedStage::assignedChunks() const {
  const Ranks& r = ranks();
  std::vector<uint64_t> mine;
  for (uint64_t c = 0; c < done_.size(); ++c)
    if (!done_[c] && (spec_.computes ? (*spec_.computes)[c] != 0 : r.owns(c))) mine.push_back(c);
  return mine;
}

void ChunkedStage::exchangeWith(WriteFn write, RestoreFn read) {
  write_ = std::move(write);
  read_ = std::move(read);
  exchangeSet_ = true;
}

void ChunkedStage::share() {
  if (ranks().exchanges()) exchange();
}

void ChunkedStage::begin(Checkpoint::StageIo io) {
  if (!exchangeSet_) write_ = io.writeChunk;
  const uint64_t done = uint64_t(std::count(done_.begin(), done_.end(), 1));
  if (cp_) cp_->beginStage(spec_.id, spec_.label, chunks(), done, std::move(io));
}

namespace {

// Appends to a string: what a rank sends.
class StringWriter final : public ByteWriter {
 public:
  explicit StringWriter(std::string& out) : out_(out) {}
  void write(const void* data, size_t bytes) override { out_.append(static_cast<const char*>(data), bytes); }

 private:
  std::string& out_;
};

}  // namespace

// Every rank sends its chunks that are done (computed now or restored from its checkpoint),
// each as u64 chunk, u64 size, the record; and applies every other rank's with read_, as a
// resume applies restored records. A rank never sends a chunk it does not own, so no chunk
// arrives twice.
void ChunkedStage::exchange() {
  PRT_CHECK(write_ && read_);
  Ranks& r = ranks();
  std::string mine;
  StringWriter out(mine);
  std::string record;
  StringWriter rec(record);
  for (uint64_t c = 0; c < done_.size(); ++c) {
    if (!mine_[c]) continue;
    record.clear();
    write_(c, rec);
    out.put(c);
    out.put(uint64_t(record.size()));
    out.write(record.data(), record.size());
  }
  const std::vector<std::string> all = r.gather(std::move(mine), spec_.everyRankNeedsChunks);
  const std::string where = cat("rank exchange of the ", spec_.label);
  for (size_t from = 0; from < all.size(); ++from) {
    if (int(from) == r.rank()) continue;
    ByteReader in(all[from], where);
    while (!in.atEnd()) {
      const uint64_t c = in.get<uint64_t>();
      const uint64_t size = in.get<uint64_t>();
      if (c >= chunks() || size > all[from].size()) in.fail("chunk index");
      record.resize(size_t(size));
      in.read(record.data(), record.size());
      ByteReader one(record, where);
      read_(chunk(c), one);
      if (!one.atEnd()) one.fail("chunk record longer than its contents");
      done_[c] = 1;
    }
  }
}

void ChunkedStage::finishChunk(const Chunk& c, uint64_t rays, std::atomic<uint64_t>& total) {
  done_[c.index] = 1;
  mine_[c.index] = 1;
  total += rays;
  if (cp_) cp_->complete(c.index);
}

void forRankShare(uint64_t* counter, uint64_t count, const std::function<void(uint64_t)>& fn) {
  if (!counter) {
    const Ranks& r = ranks();
    tbb::parallel_for(uint64_t(0), count, [&](uint64_t i) {
      if (r.owns(i) && !interruptRequested()) fn(i);
    });
    return;
  }
  std::atomic_ref<uint64_t> next(*counter);
  const size_t threads = size_t(std::max(1, tbb::this_task_arena::max_concurrency()));
  tbb::parallel_for(tbb::blocked_range<size_t>(0, threads, 1), [&](const tbb::blocked_range<size_t>&) {
    while (!interruptRequested()) {
      const uint64_t i = next.fetch_add(1, std::memory_order_relaxed);
      if (i >= count) return;
      fn(i);
    }
  });
}

// Ranks on one host: each of this rank's threads takes the next chunk from the counter all
// ranks share until none is left, so the ranks finish within about a chunk of each other
// however their cores are slowed. The progress bar shows the chunks taken by all ranks.
void ChunkedStage::runShared(const ChunkFn& fn, std::atomic<uint64_t>& rays, Progress& progress) {
  std::atomic_ref<uint64_t> next(*counter_);
  std::atomic<uint64_t> shown{0};
  forRankShare(counter_, done_.size(), [&](uint64_t index) {
    if (done_[index]) return;  // restored, here or on another rank
    const Chunk c = chunk(index);
    const ChunkOutcome outcome = fn(c);
    if (!outcome.finished) return;  // interrupted: the chunk is done again on resume
    finishChunk(c, outcome.rays, rays);
    const uint64_t taken = std::min<uint64_t>(spec_.items, next.load(std::memory_order_relaxed) * spec_.chunkSize);
    uint64_t before = shown.load();
    while (before < taken && !shown.compare_exchange_weak(before, taken)) {}
    if (before < taken) progress.add(taken - before);
  });
}

// Split statically (one process, shards, ranks on several hosts), or by StageSpec::computes:
// this rank's chunks, known before the stage runs.
void ChunkedStage::runAssigned(const ChunkFn& fn, std::atomic<uint64_t>& rays, Progress& progress) {
  const std::vector<uint64_t> mine = assignedChunks();
  size_t left = 0;
  for (uint64_t c : mine) left += chunk(c).end - chunk(c).begin;
  progress.add(spec_.items - left);  // the chunks restored, and other ranks'
  tbb::parallel_for(tbb::blocked_range<size_t>(0, mine.size(), 1), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i != r.end(); ++i) {
      if (interruptRequested()) continue;
      const Chunk c = chunk(mine[i]);
      const ChunkOutcome outcome = fn(c);
      if (!outcome.finished) continue;  // interrupted: the chunk is done again on resume
      finishChunk(c, outcome.rays, rays);
      progress.add(c.end - c.begin);
    }
  });
}

StageStats ChunkedStage::run(const ChunkFn& fn) {
  const auto t0 = std::chrono::steady_clock::now();
  // A shard goes past a stage only when the merged shards hold all of it; a stage it works on
  // (or worked on, before it was stopped) ends its run.
  const bool merged = std::find(done_.begin(), done_.end(), 0) == done_.end() && !(cp_ && cp_->ownChunks(spec_.id));
  std::atomic<uint64_t> rays{0};
  if (chunksLeft() > 0) {
    Progress progress(spec_.name, spec_.items, spec_.unit, spec_.progress);
    if (counter_)
      runShared(fn, rays, progress);
    else
      runAssigned(fn, rays, progress);
    progress.finish();
  }
  if (cp_) cp_->chunksTaken();
  stopIfInterrupted(cp_);
  Ranks& r = ranks();
  if (r.size() > 1) {
    // Once any rank has a file, every rank's file holds all its chunks of this stage before
    // any rank goes on, so the ranks' checkpoints can always resume together from the earliest
    // of them. While no rank has one (a bake shorter than the checkpoint interval, as one
    // process writes none), the ranks save nothing here: a rank that saves later (its interval,
    // an interrupt) holds the state of its stage and the direct pass's chunks, and a rank
    // without a file makes the ranks resume from the direct pass (docs/scale.md, "Checkpoints").
    // A shard always saves: its file is its share.
    if (cp_ && (r.exchanges() ? r.sum(cp_->exists() ? 1 : 0) > 0 : !merged)) cp_->save();
    if (r.exchanges()) {
      exchange();
    } else if (!merged) {
      throw ShardDone(cat("shard ", r.rank(), "/", r.size(), " of the ", spec_.label, " done"));
    }
  }
  if (cp_) cp_->endStage();
  return StageStats{spec_.name, secondsSince(t0), r.sum(rays.load())};
}

StageStats runChunkedStage(StageSpec spec, Checkpoint* cp, const ChunkedStage::RestoreFn& restore,
                           Checkpoint::StageIo io, const ChunkedStage::ChunkFn& fn) {
  const auto t0 = std::chrono::steady_clock::now();
  ChunkedStage stage(std::move(spec), cp);
  stage.restore(restore);
  stage.begin(std::move(io));
  StageStats stats = stage.run(fn);
  stats.seconds = secondsSince(t0);
  return stats;
}

}  // namespace prt::bake
