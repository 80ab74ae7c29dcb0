#include "checkpoint_log.h"

#include <algorithm>

namespace prt::bake::recordlog {

namespace {

constexpr char kMagic[8] = {'P', 'R', 'T', 'C', 'K', 'P', 'T', '\0'};
constexpr uint32_t kVersion = 1;
constexpr size_t kRecordHeader = 4 + 4 + 8 + 8;

uint64_t recordHash(uint32_t type, uint32_t stage, uint64_t chunk, uint64_t size, uint64_t payloadHash) {
  Hasher h(3);
  uint64_t v[5] = {type, stage, chunk, size, payloadHash};
  h.add(v, sizeof v);
  return h.digest();
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

// The record at `pos` if it is whole and its hash checks out.
bool readRecord(int fd, uint64_t pos, uint64_t fileSize, std::vector<char>& buf, RecordInfo& r) {
  char hdr[kRecordHeader];
  if (!readAt(fd, pos, hdr, kRecordHeader)) return false;
  std::memcpy(&r.type, hdr, 4);
  std::memcpy(&r.stage, hdr + 4, 4);
  std::memcpy(&r.chunk, hdr + 8, 8);
  std::memcpy(&r.size, hdr + 16, 8);
  if (r.type < kChunk || r.type > kCommit || r.size > fileSize - pos - kRecordHeader - 8) return false;
  r.offset = pos + kRecordHeader;
  Hasher h(0);
  for (uint64_t done = 0; done < r.size;) {
    size_t n = size_t(std::min<uint64_t>(buf.size(), r.size - done));
    if (!readAt(fd, r.offset + done, buf.data(), n)) return false;
    h.add(buf.data(), n);
    done += n;
  }
  uint64_t check = 0;
  return readAt(fd, r.offset + r.size, &check, 8) && check == recordHash(r.type, r.stage, r.chunk, r.size, h.digest());
}

}  // namespace

void appendRecord(FdWriter& w, uint32_t type, uint32_t stage, uint64_t chunk,
                  const std::function<void(ByteWriter&)>& body) {
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

Fingerprint readHeader(int fd, const std::string& path, uint64_t& firstRecord) {
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
  firstRecord = pos + 8;
  return old;
}

std::vector<std::string> fingerprintDiffs(const Fingerprint& now, const Fingerprint& old) {
  std::vector<std::string> diffs;
  for (const auto& [k, v] : now.entries) {
    auto it =
        std::find_if(old.entries.begin(), old.entries.end(), [&key = k](const auto& e) { return e.first == key; });
    if (it == old.entries.end())
      diffs.push_back(cat(k, " missing in the checkpoint"));
    else if (it->second != v)
      diffs.push_back(k.rfind("scene ", 0) == 0 ? cat(k, " differs (the scene or a file it references changed)")
                                                : cat(k, " ", it->second, " (checkpoint) vs ", v, " (now)"));
  }
  for (const auto& [k, v] : old.entries)
    if (std::none_of(now.entries.begin(), now.entries.end(), [&key = k](const auto& e) { return e.first == key; }))
      diffs.push_back(cat(k, " is not a setting of this bake"));
  return diffs;
}

Scan scanRecords(int fd, uint64_t pos, uint64_t fileSize) {
  Scan scan;
  scan.end = pos;
  std::vector<RecordInfo> uncommitted;
  std::vector<char> buf(size_t(1) << 20);
  RecordInfo r{};
  while (pos + kRecordHeader + 8 <= fileSize && readRecord(fd, pos, fileSize, buf, r)) {
    pos = r.offset + r.size + 8;
    if (r.type == kCommit) {
      scan.committed.insert(scan.committed.end(), uncommitted.begin(), uncommitted.end());
      uncommitted.clear();
      scan.end = pos;
      ++scan.commits;
    } else {
      uncommitted.push_back(r);
    }
  }
  return scan;
}

std::string readPayload(int fd, const RecordInfo& r, const std::string& path) {
  std::string data(r.size, '\0');
  if (!readAt(fd, r.offset, data.data(), data.size())) throw Error(cat(path, ": cannot read checkpoint: ", sysError()));
  return data;
}

}  // namespace prt::bake::recordlog
