// Checkpoint log (format in docs/bake.md, "Interrupting and resuming"):
//
//   header   "PRTCKPT\0", u32 version, u32 n, n × (u32 len, key, u32 len, value), u64 hash
//            written once, atomically (temp + rename), at the first save
//   record   u32 type, u32 stage, u64 chunk, u64 size, size bytes of payload,
//            u64 hash(type, stage, chunk, size, payload)        type 1 chunk, 2 state, 3 commit
//
// Records are appended, never rewritten: each chunk's result is written once, so a save
// costs the work done since the previous one, not the whole state (hit records alone can be
// gigabytes). A save ends with a commit record and fsync; on resume, everything after the
// last commit whose records all check out is cut off (ftruncate) before appending again.
#include "prt/bake/checkpoint.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <map>
#include <mutex>

#include "prt/atomic_file.h"
#include "prt/error.h"

namespace prt::bake {

namespace {

std::atomic<bool> gInterrupt{false};
std::atomic<int> gSignal{0};
static_assert(std::atomic<bool>::is_always_lock_free && std::atomic<int>::is_always_lock_free,
              "the interrupt flag is set from a signal handler");

constexpr char kMagic[8] = {'P', 'R', 'T', 'C', 'K', 'P', 'T', '\0'};
constexpr uint32_t kVersion = 1;
enum RecordType : uint32_t { kChunk = 1, kState = 2, kCommit = 3 };
constexpr size_t kRecordHeader = 4 + 4 + 8 + 8;

inline uint64_t rotl(uint64_t x, int r) { return (x << r) | (x >> (64 - r)); }
constexpr uint64_t kP1 = 0x9E3779B185EBCA87ull, kP2 = 0xC2B2AE3D27D4EB4Full;

std::string sysError() { return std::strerror(errno); }

}  // namespace

void requestInterrupt(int signal) noexcept {
  gSignal.store(signal, std::memory_order_relaxed);
  gInterrupt.store(true, std::memory_order_release);
}
bool interruptRequested() noexcept { return gInterrupt.load(std::memory_order_acquire); }
int interruptSignal() noexcept { return gSignal.load(std::memory_order_relaxed); }
void clearInterrupt() noexcept {
  gInterrupt.store(false);
  gSignal.store(0);
}

// ---- Hasher: 64-bit words mixed xxHash-style; enough to catch torn writes and edits.
Hasher::Hasher(uint64_t seed) : h_(seed ^ kP1) {}

void Hasher::add(const void* data, size_t bytes) {
  const auto* p = static_cast<const unsigned char*>(data);
  length_ += bytes;
  while (bytes > 0 && tailBytes_ != 0) {
    tail_ |= uint64_t(*p++) << (8 * tailBytes_);
    --bytes;
    if (++tailBytes_ == 8) {
      h_ = rotl(h_ ^ (tail_ * kP2), 31) * kP1;
      tail_ = 0;
      tailBytes_ = 0;
    }
  }
  for (; bytes >= 8; bytes -= 8, p += 8) {
    uint64_t w;
    std::memcpy(&w, p, 8);
    h_ = rotl(h_ ^ (w * kP2), 31) * kP1;
  }
  // Here bytes < 8, and the tail is empty unless bytes is 0.
  for (size_t i = 0; i < bytes; ++i) tail_ |= uint64_t(p[i]) << (8 * i);
  if (bytes > 0) tailBytes_ = int(bytes);
}

uint64_t Hasher::digest() const {
  uint64_t h = h_ ^ (tail_ * kP2) ^ length_;
  h ^= h >> 33;
  h *= kP2;
  h ^= h >> 29;
  h *= kP1;
  return h ^ (h >> 32);
}

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
  }
  for (const Material& m : scene.materials) {
    materials.add(&m.baseColorFactor, sizeof m.baseColorFactor);
    int32_t v[4] = {m.baseColorTexture, m.baseColorTexCoord, m.doubleSided, m.unlit};
    materials.add(v, sizeof v);
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
}

void ByteReader::read(void* out, size_t bytes) {
  if (bytes > data_.size() - pos_) fail("record shorter than its contents");
  if (bytes > 0) std::memcpy(out, data_.data() + pos_, bytes);  // out may be null when empty
  pos_ += bytes;
}

void ByteReader::fail(const std::string& what) const {
  throw Error(cat(where_, ": corrupt checkpoint (", what, "); delete it to start over"));
}

// ---- Checkpoint
namespace {

struct RecordInfo {
  uint32_t type, stage;
  uint64_t chunk, offset, size;  // offset of the payload
};

struct Pending {
  uint32_t stage;
  uint64_t chunk;
};

// Buffered appends to a file descriptor, hashing what passes through.
class FdWriter final : public ByteWriter {
public:
  FdWriter(int fd, uint64_t offset, const std::string& path) : fd_(fd), offset_(offset), path_(path) {
    buf_.reserve(kBuffer);
  }
  void write(const void* data, size_t bytes) override {
    hash_.add(data, bytes);
    size_ += bytes;
    const auto* p = static_cast<const char*>(data);
    if (buf_.size() + bytes > kBuffer) flush();
    if (bytes >= kBuffer) {
      writeAll(p, bytes);
    } else {
      buf_.insert(buf_.end(), p, p + bytes);
    }
  }
  // Raw bytes outside a payload (record headers and hashes): not hashed.
  void raw(const void* data, size_t bytes) {
    const auto* p = static_cast<const char*>(data);
    if (buf_.size() + bytes > kBuffer) flush();
    buf_.insert(buf_.end(), p, p + bytes);
  }
  void flush() {
    if (!buf_.empty()) writeAll(buf_.data(), buf_.size());
    buf_.clear();
  }
  void startPayload() {
    hash_ = Hasher(0);
    size_ = 0;
  }
  uint64_t payloadSize() const { return size_; }
  uint64_t payloadHash() const { return hash_.digest(); }
  uint64_t offset() const { return offset_ + buf_.size(); }
  // Overwrites bytes already written at an absolute offset (the size field of a record).
  void patch(uint64_t at, const void* data, size_t bytes) {
    flush();
    if (::pwrite(fd_, data, bytes, off_t(at)) != ssize_t(bytes))
      throw Error(cat(path_, ": cannot write checkpoint: ", sysError()));
  }

private:
  static constexpr size_t kBuffer = size_t(4) << 20;
  void writeAll(const char* p, size_t n) {
    while (n > 0) {
      ssize_t w = ::pwrite(fd_, p, n, off_t(offset_));
      if (w < 0 && errno == EINTR) continue;
      if (w <= 0) throw Error(cat(path_, ": cannot write checkpoint: ", sysError()));
      p += w;
      n -= size_t(w);
      offset_ += uint64_t(w);
    }
  }
  int fd_;
  uint64_t offset_;
  const std::string& path_;
  std::vector<char> buf_;
  Hasher hash_{0};
  uint64_t size_ = 0;
};

uint64_t recordHash(uint32_t type, uint32_t stage, uint64_t chunk, uint64_t size, uint64_t payloadHash) {
  Hasher h(3);
  uint64_t v[5] = {type, stage, chunk, size, payloadHash};
  h.add(v, sizeof v);
  return h.digest();
}

std::string headerBytes(const Fingerprint& fp) {
  std::string s(kMagic, sizeof kMagic);
  auto put32 = [&](uint32_t v) { s.append(reinterpret_cast<const char*>(&v), 4); };
  put32(kVersion);
  put32(uint32_t(fp.entries.size()));
  for (const auto& [k, v] : fp.entries) {
    put32(uint32_t(k.size()));
    s += k;
    put32(uint32_t(v.size()));
    s += v;
  }
  Hasher h(4);
  h.add(s.data(), s.size());
  uint64_t d = h.digest();
  s.append(reinterpret_cast<const char*>(&d), 8);
  return s;
}

bool readAt(int fd, uint64_t offset, void* out, size_t n) {
  auto* p = static_cast<char*>(out);
  while (n > 0) {
    ssize_t r = ::pread(fd, p, n, off_t(offset));
    if (r < 0 && errno == EINTR) continue;
    if (r <= 0) return false;
    p += r;
    n -= size_t(r);
    offset += uint64_t(r);
  }
  return true;
}

}  // namespace

struct Checkpoint::Impl {
  CheckpointOptions opt;
  Fingerprint fp;
  int fd = -1;
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
  std::chrono::steady_clock::time_point lastSave = std::chrono::steady_clock::now();

  std::string where() const { return opt.path; }

  void openExisting();
  void create();
  void saveLocked();
};

void Checkpoint::Impl::openExisting() {
  const std::string& path = opt.path;
  fd = ::open(path.c_str(), O_RDWR | O_CLOEXEC);
  if (fd < 0) {
    if (errno == ENOENT)
      throw Error(cat(path, ": no checkpoint to resume (a bake writes one when interrupted, or every "
                            "--checkpoint-interval seconds); run without --resume"));
    throw Error(cat(path, ": cannot open checkpoint: ", sysError()));
  }
  struct stat st{};
  if (::fstat(fd, &st) != 0) throw Error(cat(path, ": cannot read checkpoint: ", sysError()));
  const uint64_t fileSize = uint64_t(st.st_size);
  // Header.
  auto bad = [&](const std::string& what) {
    return Error(cat(path, ": not a prt checkpoint or corrupt (", what, "); delete it to start over"));
  };
  char magic[8];
  uint32_t version = 0, count = 0;
  if (!readAt(fd, 0, magic, 8) || std::memcmp(magic, kMagic, 8) != 0) throw bad("no PRTCKPT signature");
  if (!readAt(fd, 8, &version, 4)) throw bad("truncated header");
  if (version != kVersion)
    throw Error(cat(path, ": checkpoint format version ", version, ", this prt reads version ", kVersion,
                    "; delete it to start over"));
  if (!readAt(fd, 12, &count, 4) || count > 1000) throw bad("header");
  uint64_t pos = 16;
  Fingerprint old;
  for (uint32_t i = 0; i < count; ++i) {
    std::string kv[2];
    for (std::string& s : kv) {
      uint32_t len = 0;
      if (!readAt(fd, pos, &len, 4) || len > 4096) throw bad("header");
      s.resize(len);
      if (!readAt(fd, pos + 4, s.data(), len)) throw bad("header");
      pos += 4 + len;
    }
    old.add(kv[0], kv[1]);
  }
  uint64_t stored = 0;
  std::string head(pos, '\0');
  if (!readAt(fd, 0, head.data(), pos) || !readAt(fd, pos, &stored, 8)) throw bad("header");
  Hasher hh(4);
  hh.add(head.data(), head.size());
  if (hh.digest() != stored) throw bad("header checksum");
  pos += 8;

  // The fingerprint, entry by entry, so the message names what differs.
  std::vector<std::string> diffs;
  for (const auto& [k, v] : fp.entries) {
    auto it = std::find_if(old.entries.begin(), old.entries.end(), [&key = k](const auto& e) { return e.first == key; });
    if (it == old.entries.end())
      diffs.push_back(cat(k, " missing in the checkpoint"));
    else if (it->second != v)
      diffs.push_back(k.rfind("scene ", 0) == 0 ? cat(k, " differs (the scene or a file it references changed)")
                                                : cat(k, " ", it->second, " (checkpoint) vs ", v, " (now)"));
  }
  for (const auto& [k, v] : old.entries)
    if (std::none_of(fp.entries.begin(), fp.entries.end(), [&key = k](const auto& e) { return e.first == key; }))
      diffs.push_back(cat(k, " is not a setting of this bake"));
  if (!diffs.empty()) {
    std::string list;
    for (const std::string& d : diffs) list += (list.empty() ? "" : "; ") + d;
    throw Error(cat(path, ": checkpoint is from another bake: ", list,
                    ". Resume with the same scene and settings, or delete it to start over"));
  }

  // Records, up to the last commit whose records all check out.
  std::vector<RecordInfo> uncommitted;
  std::vector<char> buf(size_t(1) << 20);
  uint64_t committedEnd = pos;
  while (pos + kRecordHeader + 8 <= fileSize) {
    char hdr[kRecordHeader];
    if (!readAt(fd, pos, hdr, kRecordHeader)) break;
    RecordInfo r{};
    std::memcpy(&r.type, hdr, 4);
    std::memcpy(&r.stage, hdr + 4, 4);
    std::memcpy(&r.chunk, hdr + 8, 8);
    std::memcpy(&r.size, hdr + 16, 8);
    if (r.type < kChunk || r.type > kCommit || r.size > fileSize - pos - kRecordHeader - 8) break;
    r.offset = pos + kRecordHeader;
    Hasher h(0);
    bool ok = true;
    for (uint64_t done = 0; done < r.size && ok;) {
      size_t n = size_t(std::min<uint64_t>(buf.size(), r.size - done));
      ok = readAt(fd, r.offset + done, buf.data(), n);
      h.add(buf.data(), n);
      done += n;
    }
    uint64_t check = 0;
    if (!ok || !readAt(fd, r.offset + r.size, &check, 8) ||
        check != recordHash(r.type, r.stage, r.chunk, r.size, h.digest()))
      break;
    pos = r.offset + r.size + 8;
    if (r.type == kCommit) {
      restored.insert(restored.end(), uncommitted.begin(), uncommitted.end());
      uncommitted.clear();
      committedEnd = pos;
      ++commits;
    } else {
      uncommitted.push_back(r);
    }
  }
  // Cut a torn or uncommitted tail, so new records follow committed ones.
  if (committedEnd < fileSize && ::ftruncate(fd, off_t(committedEnd)) != 0)
    throw Error(cat(path, ": cannot truncate checkpoint: ", sysError()));
  end = committedEnd;
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
  if (impl_->opt.path.empty()) throw Error("--checkpoint: path is empty");
  if (!(impl_->opt.intervalSeconds >= 0.0)) throw Error("--checkpoint-interval: must be 0 or more seconds");
  if (impl_->opt.resume) {
    impl_->openExisting();
  } else {
    std::error_code ec;
    if (std::filesystem::exists(impl_->opt.path, ec))
      throw Error(cat(impl_->opt.path, ": a checkpoint of an interrupted bake exists; add --resume to continue it, "
                                       "or delete it to start over"));
    AtomicFile probe(impl_->opt.path);  // fail now on an unwritable directory
  }
}

Checkpoint::~Checkpoint() {
  if (impl_->fd >= 0) ::close(impl_->fd);
}

const std::string& Checkpoint::path() const { return impl_->opt.path; }
bool Checkpoint::exists() const { return impl_->fd >= 0; }

uint32_t Checkpoint::restoredStateStage() const {
  uint32_t s = 0;
  for (const RecordInfo& r : impl_->restored)
    if (r.type == kState) s = std::max(s, r.stage);
  return s;
}

namespace {
std::string readPayload(int fd, const RecordInfo& r, const std::string& path) {
  std::string data(r.size, '\0');
  if (!readAt(fd, r.offset, data.data(), data.size()))
    throw Error(cat(path, ": cannot read checkpoint: ", sysError()));
  return data;
}
}  // namespace

bool Checkpoint::restoreState(uint32_t stage, const std::function<void(ByteReader&)>& fn) const {
  for (auto it = impl_->restored.rbegin(); it != impl_->restored.rend(); ++it) {
    if (it->type != kState || it->stage != stage) continue;
    std::string data = readPayload(impl_->fd, *it, impl_->opt.path);
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
    std::string data = readPayload(impl_->fd, rec, impl_->opt.path);
    ByteReader r(data, impl_->opt.path);
    fn(rec.chunk, r);
    if (!r.atEnd()) r.fail("chunk record longer than its contents");
    ++n;
  }
  return n;
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
  const uint64_t n = m.completedThisRun.fetch_add(1) + 1;
  if (m.opt.interruptAfterChunks > 0 && n == m.opt.interruptAfterChunks) requestInterrupt(SIGINT);
  if (m.opt.intervalSeconds <= 0.0 || interruptRequested()) return;
  std::unique_lock lock(m.saveMutex, std::try_to_lock);
  if (!lock.owns_lock()) return;  // another thread is saving
  if (std::chrono::duration<double>(std::chrono::steady_clock::now() - m.lastSave).count() < m.opt.intervalSeconds)
    return;
  m.saveLocked();
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
    const uint64_t at = w.offset();
    uint64_t zero = 0;
    w.raw(&type, 4);
    w.raw(&stage, 4);
    w.raw(&chunk, 8);
    w.raw(&zero, 8);
    w.startPayload();
    if (body) body(w);
    const uint64_t size = w.payloadSize();
    const uint64_t hash = recordHash(type, stage, chunk, size, w.payloadHash());
    w.raw(&hash, 8);
    w.patch(at + 16, &size, 8);
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

}  // namespace prt::bake
