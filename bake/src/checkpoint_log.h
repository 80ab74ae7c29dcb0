// The checkpoint's record log: the file format of checkpoint.cpp, without what the records
// mean (format in docs/bake.md, "Interrupting and resuming"):
//
//   header   "PRTCKPT\0", u32 version, u32 n, n × (u32 len, key, u32 len, value), u64 hash
//            written once, atomically (temp + rename), at the first save
//   record   u32 type, u32 stage, u64 chunk, u64 size, size bytes of payload,
//            u64 hash(type, stage, chunk, size, payload)        type 1 chunk, 2 state, 3 commit
//
// Records are appended, never rewritten. A save ends with a commit record; on resume,
// everything after the last commit whose records all check out is dropped.
#pragma once

#include <unistd.h>

#include <cerrno>
#include <cstdint>
#include <cstring>
#include <functional>
#include <string>
#include <vector>

#include "prt/bake/checkpoint.h"
#include "prt/error.h"

namespace prt::bake::recordlog {

enum RecordType : uint32_t { kChunk = 1, kState = 2, kCommit = 3 };

struct RecordInfo {
  uint32_t type, stage;
  uint64_t chunk, offset, size;  // offset of the payload
  uint32_t source = 0;           // which file (Checkpoint: 0 its own, 1 its base)
};

inline std::string sysError() { return std::strerror(errno); }

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

/// Appends one record (header, the payload `body` writes, hash) at the writer's position.
void appendRecord(FdWriter& w, uint32_t type, uint32_t stage, uint64_t chunk,
                  const std::function<void(ByteWriter&)>& body);

/// The header of a new log made with `fp`.
std::string headerBytes(const Fingerprint& fp);

/// Reads the header of the log at fd: the fingerprint it was made with. Sets `firstRecord` to
/// the offset after it. Throws prt::Error naming `path` when it is not a valid header.
Fingerprint readHeader(int fd, const std::string& path, uint64_t& firstRecord);

/// One line per entry in which `now` and the log's `old` fingerprint differ; empty if none.
std::vector<std::string> fingerprintDiffs(const Fingerprint& now, const Fingerprint& old);

struct Scan {
  std::vector<RecordInfo> committed;  // records before the last valid commit, in file order
  uint64_t end = 0;                   // offset after that commit
  uint64_t commits = 0;
};
/// Reads the records from `pos` up to the first torn or invalid one.
Scan scanRecords(int fd, uint64_t pos, uint64_t fileSize);

/// The payload of a record; throws prt::Error naming `path` if it cannot be read.
std::string readPayload(int fd, const RecordInfo& r, const std::string& path);

}  // namespace prt::bake::recordlog
