// The walk mirrors OpenVDB 10's readers, each step named after the function it mirrors:
// io::Archive::readHeader, MetaMap::readMeta, io::GridDescriptor::read, io::Archive::readGrid
// (up to the transform), math::Transform::read (its map's name) and
// io::DelayedLoadMetadata::readValue. Layouts: docs/robustness.md, "VDB files".
#include "vdb_layout.h"

#include <algorithm>
#include <cstring>

#include "prt/error.h"

namespace prt::vdb_layout {

namespace {

constexpr uint32_t kOldestVersion = 222;  // OPENVDB_FILE_VERSION_NODE_MASK_COMPRESSION (2013)
constexpr uint64_t kUuidBytes = 36;       // the header's UUID, as text with its 4 hyphens
constexpr uint32_t kNoCompressedSizes = 0xffffffffu;

// Reads forward through [pos, limit) of the file: every size is checked against what is left
// before anything of that size is read.
class Cursor {
 public:
  Cursor(std::istream& in, uint64_t fileSize, const std::string& path)
      : in_(in), limit_(fileSize), fileSize_(fileSize), path_(path) {}

  uint64_t pos() const { return pos_; }
  uint64_t left() const { return limit_ - pos_; }
  void setLimit(uint64_t limit) { limit_ = limit; }
  void seek(uint64_t pos) {
    in_.seekg(std::streamoff(pos));
    pos_ = pos;
  }

  [[noreturn]] void corrupt(const std::string& what) const {
    throw Error(cat(path_, ": corrupt or truncated VDB file (", what, ")"));
  }

  void need(uint64_t n, const std::string& what) const {
    if (n > left())
      corrupt(cat(what, " of ", n, " bytes at byte ", pos_, ", ", left() == 0 ? "none" : std::to_string(left()),
                  " left", limit_ == fileSize() ? "" : " in its grid"));
  }

  template <class T>
  T read(const char* what) {
    need(sizeof(T), what);
    T v{};
    in_.read(reinterpret_cast<char*>(&v), sizeof v);
    pos_ += sizeof v;
    return v;
  }

  std::string string(const std::string& what) {
    const uint32_t n = read<uint32_t>(what.c_str());
    need(n, what);
    std::string s(n, '\0');
    in_.read(s.data(), std::streamsize(n));
    pos_ += n;
    return s;
  }

  void skip(uint64_t n, const std::string& what) {
    need(n, what);
    in_.seekg(std::streamoff(n), std::ios::cur);
    pos_ += n;
  }

  uint64_t fileSize() const { return fileSize_; }

 private:
  std::istream& in_;
  uint64_t pos_ = 0;
  uint64_t limit_;
  const uint64_t fileSize_;
  const std::string& path_;
};

// A Blosc buffer of `bytes` bytes that OpenVDB decompresses into `expected` bytes: Blosc trusts
// the sizes in its own 16-byte header (uncompressed size at byte 4, compressed size at byte 12).
// OpenVDB pads arrays shorter than 128 bytes with zeros to 128 before compressing them
// (points/StreamCompression.h, BLOSC_PAD_BYTES).
void bloscBuffer(Cursor& c, uint32_t bytes, uint64_t expected, const std::string& what) {
  if (bytes < 16) c.corrupt(cat(what, ": a compressed buffer of ", bytes, " bytes, shorter than its header"));
  c.need(bytes, what);
  const uint64_t start = c.pos();
  c.skip(4, what);
  const uint32_t nbytes = c.read<uint32_t>(what.c_str());
  c.skip(4, what);
  const uint32_t cbytes = c.read<uint32_t>(what.c_str());
  constexpr uint64_t kPadBytes = 128;
  if ((nbytes != expected && !(expected < kPadBytes && nbytes == kPadBytes)) || cbytes != bytes)
    c.corrupt(cat(what, ": a compressed buffer says ", nbytes, " bytes from ", cbytes, ", expected ", expected,
                  expected < kPadBytes ? " (or 128, padded)" : "", " from ", bytes));
  c.skip(bytes - (c.pos() - start), what);
}

// io::DelayedLoadMetadata::readValue: a count, a mask of `count` bytes, then (unless the size
// field is all ones) `count` compressed sizes of 8 bytes, each raw or Blosc-compressed, then
// anything up to numBytes. `count` sizes vectors before they are read, so it is bounded by the
// grid's bytes (a grid's tree stores at least 64 bytes a leaf; there is one entry a leaf).
void delayedLoad(Cursor& c, uint32_t numBytes, uint64_t regionBytes, const std::string& what) {
  if (numBytes == 0) return;
  const uint64_t end = c.pos() + numBytes;  // numBytes was checked against what is left
  const uint32_t count = c.read<uint32_t>(what.c_str());
  if (uint64_t(count) * 8 > regionBytes)
    c.corrupt(cat(what, ": ", count, " leaf entries in a grid of ", regionBytes, " bytes"));
  const uint32_t maskBytes = c.read<uint32_t>(what.c_str());
  if (maskBytes > 0)
    bloscBuffer(c, maskBytes, count, what);
  else
    c.skip(count, what);
  const uint32_t sizeBytes = c.read<uint32_t>(what.c_str());
  if (sizeBytes == kNoCompressedSizes) {
  } else if (sizeBytes > 0) {
    bloscBuffer(c, sizeBytes, uint64_t(count) * 8, what);
  } else {
    c.skip(uint64_t(count) * 8, what);
  }
  if (c.pos() > end) c.corrupt(cat(what, ": ", c.pos() - (end - numBytes), " bytes read from a value of ", numBytes));
  c.skip(end - c.pos(), what);
}

// MetaMap::readMeta: a count, then per item its name, its type name, a byte count and the value.
void metaMap(Cursor& c, const MetaTypeOf& metaType, uint64_t regionBytes, const std::string& where) {
  const uint32_t count = c.read<uint32_t>(cat(where, " metadata count").c_str());
  for (uint32_t i = 0; i < count; ++i) {
    const std::string item = cat(where, " metadata item ", i);
    const std::string name = c.string(cat(item, "'s name"));
    const std::string what = cat(where, " metadata '", printable(name, 64), "'");
    const std::string type = c.string(cat(what, "'s type name"));
    const uint32_t numBytes = c.read<uint32_t>(what.c_str());
    c.need(numBytes, cat(what, " (", printable(type, 64), ")"));
    const MetaType t = metaType(type);
    switch (t.read) {
      case MetaRead::Bytes:
        c.skip(numBytes, what);
        break;
      case MetaRead::Fixed:
        if (numBytes != t.size) c.corrupt(cat(what, " (", printable(type, 64), ") holds ", numBytes, " bytes, expected ", t.size));
        c.skip(numBytes, what);
        break;
      case MetaRead::DelayedLoad:
        delayedLoad(c, numBytes, regionBytes, what);
        break;
    }
  }
}

}  // namespace

Layout walk(std::istream& in, uint64_t fileSize, const std::string& path, uint32_t maxVersion,
            const MetaTypeOf& metaType) {
  Layout out;
  Cursor c(in, fileSize, path);
  c.seek(0);
  // io::Archive::readHeader, for versions 222 and later.
  c.skip(8, "the header's magic number");  // checked by the caller
  out.fileVersion = c.read<uint32_t>("the header's file format version");
  if (out.fileVersion < kOldestVersion)
    throw Error(cat(path, ": VDB file format version ", out.fileVersion, " is older than prt reads (", kOldestVersion,
                    ", OpenVDB 2.0, and later); write it again with a current OpenVDB"));
  if (out.fileVersion > maxVersion)
    throw Error(cat(path, ": VDB file format version ", out.fileVersion, " is newer than this OpenVDB reads (",
                    maxVersion, ")"));
  c.skip(8, "the header's library version");
  const uint8_t hasGridOffsets = c.read<uint8_t>("the header's grid offsets flag");
  if (hasGridOffsets == 0)
    throw Error(cat(path, ": a VDB stream without grid offsets (written by io::Stream); prt reads probe files "
                          "written as files (io::File, as prt bake and pyopenvdb write them)"));
  c.skip(kUuidBytes, "the header's UUID");
  metaMap(c, metaType, fileSize, "the file's");
  out.prefixEnd = c.pos();

  const int32_t gridCount = c.read<int32_t>("the grid count");
  if (gridCount < 0) c.corrupt(cat("a grid count of ", gridCount));
  for (int32_t g = 0; g < gridCount; ++g) {
    // io::GridDescriptor::read
    GridSpan span;
    span.begin = c.pos();
    span.name = c.string(cat("grid ", g, "'s name"));
    const std::string what = cat("grid '", printable(span.name, 64), "'");
    c.string(cat(what, "'s type name"));
    const std::string parent = c.string(cat(what, "'s instance parent name"));
    if (!parent.empty())
      throw Error(cat(path, ": grid '", printable(span.name, 64), "' is an instance of '", printable(parent, 64),
                      "' (it shares that grid's tree); prt probe files have no instanced grids"));
    const auto gridPos = c.read<int64_t>(what.c_str());
    const auto blockPos = c.read<int64_t>(what.c_str());
    const auto endPos = c.read<int64_t>(what.c_str());
    if (gridPos != int64_t(c.pos()) || blockPos < gridPos || endPos < blockPos || uint64_t(endPos) > fileSize)
      c.corrupt(cat(what, "'s offsets ", gridPos, ", ", blockPos, ", ", endPos, " do not fit its descriptor's end ",
                    c.pos(), " and the file's ", fileSize, " bytes"));
    span.end = uint64_t(endPos);
    // io::Archive::readGrid up to the tree, within the grid's own bytes.
    c.setLimit(span.end);
    c.read<uint32_t>(cat(what, "'s compression flags").c_str());
    metaMap(c, metaType, span.end - span.begin, what);
    c.string(cat(what, "'s transform type name"));  // math::Transform::read; the map is fixed-size
    c.setLimit(fileSize);
    c.seek(span.end);
    out.grids.push_back(std::move(span));
  }
  return out;
}

std::string gridStreamPrefix(const std::string& headerAndMetadata, int32_t gridCount) {
  std::string out = headerAndMetadata;
  char bytes[sizeof gridCount];
  std::memcpy(bytes, &gridCount, sizeof gridCount);
  out.append(bytes, sizeof bytes);
  return out;
}

SpliceBuf::SpliceBuf(std::string prefix, std::istream& file, uint64_t begin, uint64_t end)
    : prefix_(std::move(prefix)), file_(file), next_(begin), end_(std::max(begin, end)) {
  setg(prefix_.data(), prefix_.data(), prefix_.data() + prefix_.size());
}

SpliceBuf::int_type SpliceBuf::underflow() {
  if (gptr() < egptr()) return traits_type::to_int_type(*gptr());
  before_ += uint64_t(egptr() - eback());
  if (!inFile_) {
    inFile_ = true;
    file_.seekg(std::streamoff(next_));
    buf_.resize(1 << 16);
  }
  const uint64_t n = std::min<uint64_t>(buf_.size(), end_ - next_);
  if (n == 0) {
    setg(buf_.data(), buf_.data(), buf_.data());
    return traits_type::eof();
  }
  file_.read(buf_.data(), std::streamsize(n));  // the file's stream throws on a short read
  next_ += n;
  setg(buf_.data(), buf_.data(), buf_.data() + n);
  return traits_type::to_int_type(*gptr());
}

SpliceBuf::pos_type SpliceBuf::seekoff(off_type off, std::ios_base::seekdir dir, std::ios_base::openmode which) {
  if (off != 0 || dir != std::ios_base::cur || !(which & std::ios_base::in)) return pos_type(off_type(-1));
  return pos_type(off_type(before_ + uint64_t(gptr() - eback())));
}

}  // namespace prt::vdb_layout
