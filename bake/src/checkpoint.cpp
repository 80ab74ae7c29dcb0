// Checkpoint: the stage semantics over the record log of checkpoint_log.h. Each chunk's
// result is written once, so a save costs the work done since the previous one, not the
// whole state (hit records alone can be gigabytes). A save ends with a commit record and
// fsync; on resume, everything after the last commit whose records all check out is cut off
// (ftruncate) before appending again.
#include "prt/bake/checkpoint.h"
#include "prt/bake/surface_layout.h"  // bakesBackSide

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <map>
#include <mutex>
#include <set>

#include "checkpoint_log.h"
#include "prt/atomic_file.h"
#include "prt/error.h"

namespace prt::bake {

using namespace recordlog;

void addSceneFingerprint(Fingerprint& fp, const Scene& scene) {
  Hasher geometry(1), materials(2);
  uint64_t n = scene.meshes.size();
  geometry.add(&n, sizeof n);
  for (const MeshInstance& m : scene.meshes) {
    int32_t ids[4] = {m.node, m.mesh, m.primitive, m.receiverOnly ? 1 : 0};
    geometry.add(ids, sizeof ids);
    geometry.addVector(m.positions);
    geometry.addVector(m.normals);
    geometry.addVector(m.indices);
    int32_t mat = m.material;
    materials.add(&mat, sizeof mat);
    materials.addVector(m.texcoords);
    materials.addVector(m.colors);
    for (const std::vector<glm::vec2>& set : m.moreTexcoords) materials.addVector(set);
  }
  for (const Material& m : scene.materials) {
    materials.add(&m.baseColorFactor, sizeof m.baseColorFactor);
    int32_t v[4] = {m.baseColorTexture, m.baseColorTexCoord, m.doubleSided, m.unlit};
    materials.add(v, sizeof v);
    // Alpha and transmission only where they let light through, so an opaque scene keeps the
    // fingerprint of the bakes before they were read.
    if (m.alphaMode != Material::AlphaMode::Opaque || m.transmissionFactor > 0.0f) {
      const float f[2] = {m.alphaCutoff, m.transmissionFactor};
      const int32_t w[2] = {int32_t(m.alphaMode), m.transmissionTexture};
      materials.add(f, sizeof f);
      materials.add(w, sizeof w);
    }
    // What the diffuse albedo takes of the metallic-roughness model, only where it is not the
    // default dielectric's (metallic 0, ior 1.5, no KHR_materials_specular), so such scenes keep
    // the fingerprint of the bakes before they were read.
    const bool dielectric = m.metallicFactor == 0.0f && m.metallicRoughnessTexture.texture < 0 && m.ior == 1.5f &&
                            m.specularFactor == 1.0f && m.specularColorFactor == glm::vec3(1.0f);
    if (!dielectric && !m.specularGlossiness) {
      const float f[7] = {m.metallicFactor,        m.ior,
                          m.specularFactor,        m.specularColorFactor.x,
                          m.specularColorFactor.y, m.specularColorFactor.z,
                          m.roughnessFactor};  // a metal's bounced lobe depends on it
      const int32_t w[2] = {m.metallicRoughnessTexture.texture, m.metallicRoughnessTexture.uvSet};
      materials.add(f, sizeof f);
      materials.add(w, sizeof w);
    }
  }
  for (const Texture& t : scene.textures) {
    int32_t v[4] = {t.width, t.height, t.wrapS, t.wrapT};
    materials.add(v, sizeof v);
    materials.addVector(t.texels);
  }
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(geometry.digest()));
  fp.add("scene geometry", buf);
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(materials.digest()));
  fp.add("scene materials", buf);
  // The back sides of double-sided instances are vertices of the bake (surface_bake.cpp): a
  // checkpoint of a prt that baked one side only does not fit. One-sided scenes add nothing,
  // so their checkpoints stay valid.
  uint64_t backVertices = 0;
  for (const MeshInstance& m : scene.meshes)
    if (bakesBackSide(scene, m)) backVertices += m.vertexCount();
  if (backVertices) fp.add("two-sided vertices", std::to_string(backVertices));
}

namespace {

struct Pending {
  uint32_t stage;
  uint64_t chunk;
};

}  // namespace

struct Checkpoint::Impl {
  CheckpointOptions opt;
  Fingerprint fp;
  int fd = -1;
  int baseFd = -1;   // CheckpointOptions::basePath, read only
  uint64_t end = 0;  // where the next record goes
  uint64_t commits = 0;
  std::vector<RecordInfo> restored;  // committed records found on resume

  struct Stage {
    std::string label;
    uint64_t chunks = 0, done = 0;
    StageIo io;
    bool stateSaved = false;
  };
  std::map<uint32_t, Stage> stages;  // stages whose records may still be written
  uint32_t current = 0;
  bool haveStage = false;

  std::mutex pendingMutex;
  std::vector<Pending> pending;
  std::mutex saveMutex;
  std::atomic<uint64_t> completedThisRun{0};
  std::atomic<uint64_t> completedInStage{0};  // of opt.interruptInStage, this run
  std::chrono::steady_clock::time_point lastSave = std::chrono::steady_clock::now();

  std::string where() const { return opt.path; }
  std::string payload(const RecordInfo& r) const {
    return r.source == 1 ? readPayload(baseFd, r, opt.basePath) : readPayload(fd, r, opt.path);
  }

  void openExisting();
  void openBase();
  void create();
  void saveLocked();
};

namespace {

// The fingerprint, entry by entry, so the message names what differs.
void checkFingerprint(const Fingerprint& now, const Fingerprint& old, const std::string& path) {
  const std::vector<std::string> diffs = fingerprintDiffs(now, old);
  if (diffs.empty()) return;
  std::string list;
  for (const std::string& d : diffs) list += (list.empty() ? "" : "; ") + d;
  throw Error(cat(path, ": checkpoint is from another bake: ", list,
                  ". Resume with the same scene and settings, or delete it to start over"));
}

uint64_t fileSizeOf(int fd, const std::string& path) {
  struct stat st {};
  if (::fstat(fd, &st) != 0) throw Error(cat(path, ": cannot read checkpoint: ", sysError()));
  return uint64_t(st.st_size);
}

}  // namespace

// The base's committed records come first; its torn tail, if any, is left as it is.
void Checkpoint::Impl::openBase() {
  const std::string& path = opt.basePath;
  baseFd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (baseFd < 0) throw Error(cat(path, ": cannot open checkpoint: ", sysError()));
  uint64_t firstRecord = 0;
  checkFingerprint(fp, readHeader(baseFd, path, firstRecord), path);
  Scan scan = scanRecords(baseFd, firstRecord, fileSizeOf(baseFd, path));
  for (RecordInfo& r : scan.committed) r.source = 1;
  restored.insert(restored.begin(), scan.committed.begin(), scan.committed.end());
}

void Checkpoint::Impl::openExisting() {
  const std::string& path = opt.path;
  fd = ::open(path.c_str(), O_RDWR | O_CLOEXEC);
  if (fd < 0) {
    if (errno == ENOENT)
      throw Error(cat(path,
                      ": no checkpoint to resume (a bake writes one when interrupted, or every "
                      "checkpoint interval); start the bake afresh instead of resuming"));
    throw Error(cat(path, ": cannot open checkpoint: ", sysError()));
  }
  const uint64_t fileSize = fileSizeOf(fd, path);
  uint64_t firstRecord = 0;
  checkFingerprint(fp, readHeader(fd, path, firstRecord), path);
  // Records, up to the last commit whose records all check out.
  Scan scan = scanRecords(fd, firstRecord, fileSize);
  restored.insert(restored.end(), scan.committed.begin(), scan.committed.end());
  commits = scan.commits;
  // Cut a torn or uncommitted tail, so new records follow committed ones.
  if (scan.end < fileSize && ::ftruncate(fd, off_t(scan.end)) != 0)
    throw Error(cat(path, ": cannot truncate checkpoint: ", sysError()));
  end = scan.end;
}

void Checkpoint::Impl::create() {
  // The header goes in atomically: a file at the checkpoint path is always a valid log.
  writeFileAtomic(opt.path, headerBytes(fp));
  fd = ::open(opt.path.c_str(), O_RDWR | O_CLOEXEC);
  if (fd < 0) throw Error(cat(opt.path, ": cannot open checkpoint: ", sysError()));
  end = uint64_t(::lseek(fd, 0, SEEK_END));
}

Checkpoint::Checkpoint(CheckpointOptions options, Fingerprint fingerprint) : impl_(std::make_unique<Impl>()) {
  impl_->opt = std::move(options);
  impl_->fp = std::move(fingerprint);
  if (impl_->opt.path.empty()) throw Error("checkpoint path: empty");
  if (!(impl_->opt.intervalSeconds >= 0.0)) throw Error("checkpoint interval: must be 0 or more seconds");
  std::error_code ec;
  if (!impl_->opt.basePath.empty()) impl_->openBase();
  if (impl_->opt.resume && impl_->opt.missingIsFresh && !std::filesystem::exists(impl_->opt.path, ec)) {
    AtomicFile probe(impl_->opt.path);  // fail now on an unwritable directory
  } else if (impl_->opt.resume) {
    impl_->openExisting();
  } else {
    if (std::filesystem::exists(impl_->opt.path, ec))
      throw CheckpointExists(cat(impl_->opt.path,
                                 ": a checkpoint of an interrupted bake exists; resume it to continue, "
                                 "or delete it to start over"));
    AtomicFile probe(impl_->opt.path);  // fail now on an unwritable directory
  }
}

Checkpoint::~Checkpoint() {
  if (impl_->fd >= 0) ::close(impl_->fd);
  if (impl_->baseFd >= 0) ::close(impl_->baseFd);
}

const std::string& Checkpoint::path() const { return impl_->opt.path; }
bool Checkpoint::exists() const { return impl_->fd >= 0 || impl_->baseFd >= 0; }

uint32_t Checkpoint::restoredStateStage() const {
  uint32_t s = 0;
  for (const RecordInfo& r : impl_->restored)
    if (r.type == kState) s = std::max(s, r.stage);
  return s;
}

bool Checkpoint::restoreState(uint32_t stage, const std::function<void(ByteReader&)>& fn) const {
  for (auto it = impl_->restored.rbegin(); it != impl_->restored.rend(); ++it) {
    if (it->type != kState || it->stage != stage) continue;
    std::string data = impl_->payload(*it);
    ByteReader r(data, impl_->opt.path);
    fn(r);
    if (!r.atEnd()) r.fail("state record longer than its contents");
    return true;
  }
  return false;
}

uint64_t Checkpoint::restoreChunks(uint32_t stage, const std::function<void(uint64_t, ByteReader&)>& fn) const {
  uint64_t n = 0;
  for (const RecordInfo& rec : impl_->restored) {
    if (rec.type != kChunk || rec.stage != stage) continue;
    std::string data = impl_->payload(rec);
    ByteReader r(data, impl_->opt.path);
    fn(rec.chunk, r);
    if (!r.atEnd()) r.fail("chunk record longer than its contents");
    ++n;
  }
  return n;
}

bool Checkpoint::ownChunks(uint32_t stage) const {
  return std::any_of(impl_->restored.begin(), impl_->restored.end(),
                     [&](const RecordInfo& r) { return r.type == kChunk && r.stage == stage && r.source == 0; });
}

void Checkpoint::beginStage(uint32_t id, const std::string& label, uint64_t chunks, uint64_t restored, StageIo io) {
  Impl& m = *impl_;
  if (m.haveStage) PRT_CHECK_GT(id, m.current);
  Impl::Stage& s = m.stages[id];
  s.label = label;
  s.chunks = chunks;
  s.done = restored;
  s.io = std::move(io);
  // A state restored from the file is already there.
  for (const RecordInfo& r : m.restored) s.stateSaved |= r.type == kState && r.stage == id;
  m.current = id;
  m.haveStage = true;
}

void Checkpoint::complete(uint64_t chunk) {
  Impl& m = *impl_;
  {
    std::lock_guard lock(m.pendingMutex);
    m.pending.push_back({m.current, chunk});
    ++m.stages.find(m.current)->second.done;
  }
  uint64_t n = m.completedThisRun.fetch_add(1) + 1;
  if (m.opt.interruptInStage != 0) n = m.current == m.opt.interruptInStage ? m.completedInStage.fetch_add(1) + 1 : 0;
  if (m.opt.interruptAfterChunks > 0 && n == m.opt.interruptAfterChunks) requestInterrupt(SIGINT);
  if (m.opt.intervalSeconds <= 0.0 || interruptRequested()) return;
  std::unique_lock lock(m.saveMutex, std::try_to_lock);
  if (!lock.owns_lock()) return;  // another thread is saving
  if (std::chrono::duration<double>(std::chrono::steady_clock::now() - m.lastSave).count() < m.opt.intervalSeconds)
    return;
  m.saveLocked();
}

void Checkpoint::chunksTaken() {
  const Impl& m = *impl_;
  if (m.haveStage && m.opt.interruptInStage != 0 && m.opt.interruptInStage == m.current &&
      m.opt.interruptAfterChunks > 0 && m.completedInStage.load() < m.opt.interruptAfterChunks)
    requestInterrupt(SIGINT);
}

void Checkpoint::endStage() {
  Impl& m = *impl_;
  std::lock_guard lock(m.pendingMutex);
  auto it = m.stages.find(m.current);
  if (it == m.stages.end() || it->second.io.chunksOutliveStage) return;
  std::erase_if(m.pending, [&](const Pending& p) { return p.stage == m.current; });
  // Its chunk records can no longer be written; its state may be (save() in the stage).
}

void Checkpoint::save() {
  std::lock_guard lock(impl_->saveMutex);
  impl_->saveLocked();
}

void Checkpoint::Impl::saveLocked() {
  if (fd < 0) create();
  std::vector<Pending> todo;
  {
    std::lock_guard lock(pendingMutex);
    todo.swap(pending);
  }
  FdWriter w(fd, end, opt.path);
  auto record = [&](uint32_t type, uint32_t stage, uint64_t chunk, const std::function<void(ByteWriter&)>& body) {
    appendRecord(w, type, stage, chunk, body);
  };
  if (haveStage) {
    Stage& s = stages.find(current)->second;
    if (!s.stateSaved && s.io.writeState) {
      record(kState, current, 0, s.io.writeState);
      s.stateSaved = true;
    }
  }
  for (const Pending& p : todo) {
    const Stage& s = stages.find(p.stage)->second;
    if (!s.io.writeChunk) continue;
    record(kChunk, p.stage, p.chunk, [&](ByteWriter& out) { s.io.writeChunk(p.chunk, out); });
  }
  record(kCommit, 0, commits++, nullptr);
  w.flush();
  end = w.offset();
  if (::fsync(fd) != 0) throw Error(cat(opt.path, ": cannot sync checkpoint: ", sysError()));
  lastSave = std::chrono::steady_clock::now();
}

void Checkpoint::releaseStages() {
  Impl& m = *impl_;
  std::lock_guard saveLock(m.saveMutex);
  std::lock_guard lock(m.pendingMutex);
  m.pending.clear();
  for (auto& [id, s] : m.stages) s.io = StageIo{};
}

void Checkpoint::stopIfInterrupted() {
  if (!interruptRequested()) return;
  save();
  throw Interrupted(cat("interrupted (", progressText(), ")"));
}

std::string Checkpoint::progressText() const {
  const Impl& m = *impl_;
  if (!m.haveStage) return "nothing done yet";
  auto it = m.stages.find(m.current);
  const Impl::Stage& s = it->second;
  if (s.chunks == 0) return cat(s.label, " done");
  char pct[16];
  std::snprintf(pct, sizeof pct, "%.0f%%", 100.0 * double(s.done) / double(s.chunks));
  return cat(s.label, " ", pct, " done");
}

void Checkpoint::remove() {
  if (impl_->fd >= 0) ::close(impl_->fd);
  impl_->fd = -1;
  std::error_code ec;
  std::filesystem::remove(impl_->opt.path, ec);
}

std::string shardCheckpointPath(const std::string& path, int index, int count) {
  return cat(path, ".shard-", index, "-of-", count);
}

namespace {

// One finished shard's checkpoint: its committed records.
struct ShardLog {
  std::string path;
  int fd = -1;
  std::vector<RecordInfo> records;
};

// The checkpoint the shards merge into: its committed records, where it ends and its commits.
struct MergedLog {
  int fd = -1;
  uint64_t end = 0, commits = 0;
  std::vector<RecordInfo> have;
};

// Closes every file the merge opened, however it ends.
struct MergeFiles {
  std::vector<ShardLog> shards;
  MergedLog merged;
  ~MergeFiles() {
    for (ShardLog& s : shards)
      if (s.fd >= 0) ::close(s.fd);
    if (merged.fd >= 0) ::close(merged.fd);
  }
};

// Opens the finished shards ("PATH.shard-I-of-N.done") and reads their committed records; their
// fingerprints must agree. Returns it.
Fingerprint openShards(const std::string& path, int count, std::vector<ShardLog>& shards) {
  Fingerprint fp;
  shards.resize(static_cast<size_t>(count));
  for (int i = 0; i < count; ++i) {
    ShardLog& sh = shards[size_t(i)];
    sh.path = shardCheckpointPath(path, i, count) + ".done";
    sh.fd = ::open(sh.path.c_str(), O_RDONLY | O_CLOEXEC);
    if (sh.fd < 0) {
      const int err = errno;
      std::error_code ec;
      if (err != ENOENT) throw Error(cat(sh.path, ": ", std::strerror(err)));
      if (std::filesystem::exists(shardCheckpointPath(path, i, count), ec))
        throw Error(cat(sh.path, ": shard not finished (its checkpoint is there: run it again to finish its share)"));
      throw ShardMissing(cat(sh.path, ": no such shard (shard ", i, "/", count, " has not been baked)"), i, count);
    }
    uint64_t first = 0;
    const Fingerprint f = readHeader(sh.fd, sh.path, first);
    if (i == 0)
      fp = f;
    else
      checkFingerprint(fp, f, sh.path);
    sh.records = scanRecords(sh.fd, first, fileSizeOf(sh.fd, sh.path)).committed;
  }
  return fp;
}

// The merged checkpoint: opened (and checked, a torn tail cut off) or created with the shards'
// fingerprint.
void openMerged(const std::string& path, const Fingerprint& fp, MergedLog& m) {
  std::error_code ec;
  if (std::filesystem::exists(path, ec)) {
    m.fd = ::open(path.c_str(), O_RDWR | O_CLOEXEC);
    if (m.fd < 0) throw Error(cat(path, ": cannot open checkpoint: ", sysError()));
    uint64_t first = 0;
    checkFingerprint(fp, readHeader(m.fd, path, first), path);
    Scan scan = scanRecords(m.fd, first, fileSizeOf(m.fd, path));
    if (scan.end < fileSizeOf(m.fd, path) && ::ftruncate(m.fd, off_t(scan.end)) != 0)
      throw Error(cat(path, ": cannot truncate checkpoint: ", sysError()));
    m.have = std::move(scan.committed);
    m.end = scan.end;
    m.commits = scan.commits;
  } else {
    writeFileAtomic(path, headerBytes(fp));
    m.fd = ::open(path.c_str(), O_RDWR | O_CLOEXEC);
    if (m.fd < 0) throw Error(cat(path, ": cannot open checkpoint: ", sysError()));
    m.end = uint64_t(::lseek(m.fd, 0, SEEK_END));
  }
}

// Appends the shards' state records of stages the merged checkpoint has none of and their chunk
// records it lacks, then a commit, and syncs.
MergeStats appendMissing(const std::string& path, const std::vector<ShardLog>& shards, MergedLog& m) {
  std::set<std::pair<uint32_t, uint64_t>> chunks;  // (stage, chunk) present
  std::set<uint32_t> states;
  for (const RecordInfo& r : m.have) {
    if (r.type == kChunk) chunks.insert({r.stage, r.chunk});
    if (r.type == kState) states.insert(r.stage);
  }
  MergeStats stats;
  std::set<uint32_t> merged;
  FdWriter w(m.fd, m.end, path);
  for (const ShardLog& sh : shards)
    for (const RecordInfo& r : sh.records) {
      const bool fresh = r.type == kChunk ? chunks.insert({r.stage, r.chunk}).second
                                          : r.type == kState && states.insert(r.stage).second;
      if (!fresh) continue;
      const std::string data = readPayload(sh.fd, r, sh.path);
      appendRecord(w, r.type, r.stage, r.chunk, [&](ByteWriter& out) { out.write(data.data(), data.size()); });
      if (r.type == kChunk) {
        ++stats.chunkRecords;
        merged.insert(r.stage);
      } else {
        ++stats.stateRecords;
      }
    }
  appendRecord(w, kCommit, 0, m.commits, nullptr);
  w.flush();
  if (::fsync(m.fd) != 0) throw Error(cat(path, ": cannot sync checkpoint: ", sysError()));
  stats.stages.assign(merged.begin(), merged.end());
  return stats;
}

}  // namespace

MergeStats mergeShards(const std::string& path, int count) {
  if (count < 1) throw Error(cat("shards ", count, ": must be 1 or more"));
  MergeFiles files;
  const Fingerprint fp = openShards(path, count, files.shards);
  openMerged(path, fp, files.merged);
  const MergeStats stats = appendMissing(path, files.shards, files.merged);
  std::error_code ec;
  for (const ShardLog& sh : files.shards) std::filesystem::remove(sh.path, ec);
  return stats;
}

}  // namespace prt::bake
