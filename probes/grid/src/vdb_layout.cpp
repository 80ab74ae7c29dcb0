// The walk mirrors OpenVDB 10.0.1's readers, each step named after the function it mirrors:
// io::Archive::readHeader, MetaMap::readMeta, io::DelayedLoadMetadata::readValue,
// io::GridDescriptor::read, io::Archive::readGrid, math::Transform::read (and
// NonlinearFrustumMap::read), Tree/RootNode/InternalNode/LeafNode::readTopology and readBuffers,
// io::readCompressedValues, io::HalfReader and io::readData (bloscFromStream, unzipFromStream).
// What it checks and why: docs/robustness.md (the probe VDB row and the fuzz_vdb findings).
#include "vdb_layout.h"

#include <algorithm>
#include <array>
#include <cstring>
#include <limits>
#include <map>
#include <string_view>
#include <type_traits>

#include "prt/error.h"

namespace prt::vdb_layout {

namespace {

constexpr uint32_t kOldestVersion = 222;  // OPENVDB_FILE_VERSION_NODE_MASK_COMPRESSION (2013)
constexpr uint64_t kUuidBytes = 36;       // the header's UUID, as text with its 4 hyphens
constexpr uint32_t kNoCompressedSizes = 0xffffffffu;

// What a size is for, in a message: a string, or a function that makes one (walking a big file
// makes millions of checks and only a failed one needs its words).
std::string describe(const std::string& what) { return what; }
std::string describe(const char* what) { return what; }
template <class F>
requires std::is_invocable_r_v<std::string, const F&> std::string describe(const F& what) { return what(); }

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

  template <class W>
  void need(uint64_t n, const W& what) const {
    if (n > left())
      corrupt(cat(describe(what), " of ", n, " bytes at byte ", pos_, ", ",
                  left() == 0 ? "none" : std::to_string(left()), " left", limit_ == fileSize_ ? "" : " in its grid"));
  }

  template <class T, class W>
  T read(const W& what) {
    need(sizeof(T), what);
    T v{};
    in_.read(reinterpret_cast<char*>(&v), sizeof v);
    pos_ += sizeof v;
    return v;
  }

  template <class W>
  std::string string(const W& what) {
    const uint32_t n = read<uint32_t>(what);
    need(n, what);
    std::string s(n, '\0');
    in_.read(s.data(), std::streamsize(n));
    pos_ += n;
    return s;
  }

  // Short skips through the stream's buffer (a seek would drop it), long ones by seeking.
  template <class W>
  void skip(uint64_t n, const W& what) {
    need(n, what);
    if (n <= 4096)
      in_.ignore(std::streamsize(n));
    else
      in_.seekg(std::streamoff(n), std::ios::cur);
    pos_ += n;
  }

 private:
  std::istream& in_;
  uint64_t pos_ = 0;
  uint64_t limit_;
  const uint64_t fileSize_;
  const std::string& path_;
};

// A Blosc buffer of `bytes` bytes that OpenVDB decompresses into `expected` bytes: Blosc trusts
// the sizes in its own 16-byte header (uncompressed size at byte 4, compressed size at byte 12).
// `padded`: compressed by points/StreamCompression (DelayedLoadMetadata), which pads arrays
// shorter than 128 bytes with zeros to 128 first (BLOSC_PAD_BYTES); trees' blocks never are.
void bloscBuffer(Cursor& c, uint32_t bytes, uint64_t expected, bool padded, const std::string& what) {
  if (bytes < 16) c.corrupt(cat(what, ": a compressed buffer of ", bytes, " bytes, shorter than its header"));
  c.need(bytes, what);
  const uint64_t start = c.pos();
  c.skip(4, what);
  const uint32_t nbytes = c.read<uint32_t>(what);
  c.skip(4, what);
  const uint32_t cbytes = c.read<uint32_t>(what);
  constexpr uint64_t kPadBytes = 128;
  const bool pad = padded && expected < kPadBytes;
  if ((nbytes != expected && !(pad && nbytes == kPadBytes)) || cbytes != bytes)
    c.corrupt(cat(what, ": a compressed buffer says ", nbytes, " bytes from ", cbytes, ", expected ", expected,
                  pad ? " (or 128, padded)" : "", " from ", bytes));
  c.skip(bytes - (c.pos() - start), what);
}

// io::DelayedLoadMetadata::readValue: a count, a mask of `count` bytes, then (unless the size
// field is all ones) `count` compressed sizes of 8 bytes, each raw or Blosc-compressed, then
// anything up to numBytes. `count` sizes vectors before they are read, so it is bounded by the
// grid's bytes (a grid's tree stores at least 64 bytes a leaf; there is one entry a leaf).
void delayedLoad(Cursor& c, uint32_t numBytes, uint64_t regionBytes, const std::string& what) {
  if (numBytes == 0) return;
  const uint64_t end = c.pos() + numBytes;  // numBytes was checked against what is left
  const uint32_t count = c.read<uint32_t>(what);
  if (uint64_t(count) * 8 > regionBytes)
    c.corrupt(cat(what, ": ", count, " leaf entries in a grid of ", regionBytes, " bytes"));
  const uint32_t maskBytes = c.read<uint32_t>(what);
  if (maskBytes > 0)
    bloscBuffer(c, maskBytes, count, true, what);
  else
    c.skip(count, what);
  const uint32_t sizeBytes = c.read<uint32_t>(what);
  if (sizeBytes == kNoCompressedSizes) {
  } else if (sizeBytes > 0) {
    bloscBuffer(c, sizeBytes, uint64_t(count) * 8, true, what);
  } else {
    c.skip(uint64_t(count) * 8, what);
  }
  if (c.pos() > end) c.corrupt(cat(what, ": ", c.pos() - (end - numBytes), " bytes read from a value of ", numBytes));
  c.skip(end - c.pos(), what);
}

// MetaMap::readMeta: a count, then per item its name, its type name, a byte count and the value.
void metaMap(Cursor& c, const MetaTypeOf& metaType, uint64_t regionBytes, const std::string& where) {
  const uint32_t count = c.read<uint32_t>(cat(where, " metadata count"));
  for (uint32_t i = 0; i < count; ++i) {
    const std::string item = cat(where, " metadata item ", i);
    const std::string name = c.string(cat(item, ", name"));
    const std::string what = cat(where, " metadata '", printable(name, 64), "'");
    const std::string type = c.string(cat(what, ", type name"));
    const uint32_t numBytes = c.read<uint32_t>(what);
    c.need(numBytes, cat(what, " (", printable(type, 64), ")"));
    const MetaType t = metaType(type);
    switch (t.read) {
      case MetaRead::Bytes:
        c.skip(numBytes, what);
        break;
      case MetaRead::Fixed:
        if (numBytes != t.size)
          c.corrupt(cat(what, " (", printable(type, 64), ") holds ", numBytes, " bytes, expected ", t.size));
        c.skip(numBytes, what);
        break;
      case MetaRead::DelayedLoad:
        delayedLoad(c, numBytes, regionBytes, what);
        break;
    }
  }
}

// ---- Trees (tree/Tree.h, RootNode.h, InternalNode.h, LeafNode.h and io/Compression.h)

constexpr uint32_t kZip = 0x1, kActiveMask = 0x2, kBlosc = 0x4;  // io::COMPRESS_*

// A standard 5-4-3 tree's values: bytes of a value, and of the value saved as half (0: not a
// floating-point type, which is never saved as half). The grid types OpenVDB 10 registers, less
// bool and mask trees (other leaf layouts) and point grids.
struct TreeValues {
  uint32_t bytes = 0, halfBytes = 0;
};

TreeValues treeValues(const std::string& gridType) {
  static const std::pair<const char*, TreeValues> kTypes[] = {
      {"Tree_float_5_4_3", {4, 2}},  {"Tree_double_5_4_3", {8, 2}}, {"Tree_int32_5_4_3", {4, 0}},
      {"Tree_int64_5_4_3", {8, 0}},  {"Tree_vec3s_5_4_3", {12, 6}}, {"Tree_vec3d_5_4_3", {24, 6}},
      {"Tree_vec3i_5_4_3", {12, 0}},
  };
  for (const auto& [name, values] : kTypes)
    if (gridType == name) return values;
  return {};
}

// The walk of one grid's tree. Where it is (top node or leaf) is kept as numbers and put into
// words only for a message.
class TreeWalk {
 public:
  TreeWalk(Cursor& c, const std::string& grid, uint32_t compression, TreeValues values, bool half)
      : c_(c), grid_(grid), compression_(compression), values_(values), half_(half && values.halfBytes > 0) {}

  // Where the walk is, in words (for a message only).
  std::string here() const { return cat(grid_, inBuffers_ ? ", leaf " : ", top node ", node_); }
  auto at(const char* part) const {
    return [this, part] { return cat(here(), ", ", part); };
  }

  // Tree::readTopology and RootNode::readTopology (file format 213 and later); the leaves' count.
  uint64_t topology() {
    c_.skip(4, at("buffer count"));
    c_.skip(values_.bytes, at("background"));
    const uint32_t tiles = c_.read<uint32_t>(at("tile count"));
    const uint32_t children = c_.read<uint32_t>(at("child count"));
    c_.skip(uint64_t(tiles) * (12 + values_.bytes + 1), [&] { return cat(grid_, ", ", tiles, " tiles"); });
    // The root's table is a std::map by origin: a child read later replaces one read earlier at
    // the same origin (and its leaves' buffers are never read).
    std::map<std::array<int32_t, 3>, uint64_t> leaves;
    for (uint32_t n = 0; n < children; ++n) {
      node_ = n;
      std::array<int32_t, 3> origin{};
      for (int32_t& o : origin) o = c_.read<int32_t>(at("origin"));
      leaves[origin] = internal(5);
    }
    uint64_t total = 0;
    for (const auto& entry : leaves) total += entry.second;
    return total;
  }

  // The leaves' buffers (LeafNode::readBuffers, format 222 and later): value mask, then values.
  void buffers(uint64_t leaves) {
    inBuffers_ = true;
    for (uint64_t n = 0; n < leaves; ++n) {
      node_ = n;
      values(3, readMask(3));
    }
  }

 private:
  std::vector<uint64_t> readMask(int log2Dim) {
    const size_t words = (size_t(1) << (3 * log2Dim)) / 64;
    c_.need(words * 8, at("mask"));
    std::vector<uint64_t> mask(words);
    for (uint64_t& w : mask) w = c_.read<uint64_t>(at("mask"));
    return mask;
  }

  // InternalNode::readTopology: child and value masks, the node's values, then its children
  // in the order of the child mask; leaves (LeafNode::readTopology) store their value mask.
  uint64_t internal(int log2Dim) {
    const std::vector<uint64_t> childMask = readMask(log2Dim);
    const std::vector<uint64_t> valueMask = readMask(log2Dim);
    values(log2Dim, valueMask);
    uint64_t leaves = 0;
    for (uint64_t word : childMask)
      for (; word; word &= word - 1) {
        if (log2Dim == 5) {
          leaves += internal(4);
        } else {
          c_.skip(64, at("leaf mask"));
          ++leaves;
        }
      }
    return leaves;
  }

  // io::readCompressedValues for a node of 2^(3·log2Dim) values and this value mask.
  void values(int log2Dim, const std::vector<uint64_t>& valueMask) {
    const uint64_t size = uint64_t(1) << (3 * log2Dim);
    const int8_t meta = c_.read<int8_t>(at("compression metadata"));
    enum { kNoMaskOneInactive = 2, kMaskNoInactive = 3, kMaskOneInactive = 4, kMaskTwoInactive = 5, kAllValues = 6 };
    if (meta == kNoMaskOneInactive || meta == kMaskOneInactive || meta == kMaskTwoInactive)
      c_.skip(uint64_t(values_.bytes) * (meta == kMaskTwoInactive ? 2 : 1), at("inactive values"));
    if (meta == kMaskNoInactive || meta == kMaskOneInactive || meta == kMaskTwoInactive)
      c_.skip(size / 8, at("selection mask"));
    uint64_t count = size;
    if ((compression_ & kActiveMask) && meta != kAllValues) {
      count = 0;
      for (uint64_t w : valueMask) count += uint64_t(__builtin_popcountll(w));
    }
    if (half_ && count == 0) return;  // io::HalfReader reads nothing for no values
    block(count * (half_ ? values_.halfBytes : values_.bytes));
  }

  // io::readData: Blosc's or zlib's block (a signed size first: negative for bytes stored as
  // they are), or the bytes themselves.
  void block(uint64_t bytes) {
    if (!(compression_ & (kBlosc | kZip))) {
      c_.skip(bytes, at("values"));
      return;
    }
    const int64_t n = c_.read<int64_t>(at("block size"));
    if (n <= 0) {
      const uint64_t stored = uint64_t(0) - uint64_t(n);
      if (stored != bytes) c_.corrupt(cat(here(), ": a block of ", stored, " bytes as they are, expected ", bytes));
      c_.skip(stored, at("values"));
    } else if (compression_ & kBlosc) {
      // io::bloscToStream writes Blosc's int-sized result: a larger block is corrupt.
      if (n > std::numeric_limits<int32_t>::max()) c_.corrupt(cat(here(), ": a compressed block of ", n, " bytes"));
      bloscBuffer(c_, uint32_t(n), bytes, false, cat(here(), ", values"));
    } else {
      c_.skip(uint64_t(n), at("values"));  // zlib's uncompress stops at the buffer's end
    }
  }

  Cursor& c_;
  const std::string& grid_;
  uint32_t compression_;
  TreeValues values_;
  bool half_;
  bool inBuffers_ = false;
  uint64_t node_ = 0;
};

// math::Transform::read: the map's type name, then the map. A frustum map holds a second map,
// named again (math::NonlinearFrustumMap::read: its box, taper and depth, then that map).
void transform(Cursor& c, const MapBytesOf& mapBytes, const std::string& what, const std::string& path) {
  constexpr const char* kFrustum = "NonlinearFrustumMap";
  std::string map = c.string(cat(what, ", transform type name"));
  if (map == kFrustum) {
    c.skip(2 * 24 + 8 + 8, cat(what, ", frustum"));
    map = c.string(cat(what, ", frustum's second map type name"));
    if (map == kFrustum) c.corrupt(cat(what, ": a frustum map inside a frustum map"));
  }
  const uint32_t bytes = mapBytes(map);
  if (bytes == 0)
    throw Error(cat(path, ": ", what, ": transform map '", printable(map, 64), "' is not one OpenVDB knows"));
  c.skip(bytes, cat(what, ", transform"));
}

}  // namespace

Layout walk(std::istream& in, uint64_t fileSize, const std::string& path, uint32_t maxVersion,
            const MetaTypeOf& metaType, const MapBytesOf& mapBytes) {
  Layout out;
  Cursor c(in, fileSize, path);
  c.seek(0);
  // io::Archive::readHeader, for versions 222 and later.
  c.skip(8, "the header's magic number");  // checked by the caller
  const uint32_t version = c.read<uint32_t>("the header's file format version");
  if (version < kOldestVersion)
    throw Error(cat(path, ": VDB file format version ", version, " is older than prt reads (", kOldestVersion,
                    ", OpenVDB 2.0, and later); write it again with a current OpenVDB"));
  if (version > maxVersion)
    throw Error(
        cat(path, ": VDB file format version ", version, " is newer than this OpenVDB reads (", maxVersion, ")"));
  c.skip(8, "the header's library version");
  const uint8_t hasGridOffsets = c.read<uint8_t>("the header's grid offsets flag");
  if (hasGridOffsets == 0)
    throw Error(cat(path,
                    ": a VDB stream without grid offsets (written by io::Stream); prt reads probe files "
                    "written as files (io::File, as prt bake and pyopenvdb write them)"));
  c.skip(kUuidBytes, "the header's UUID");
  out.headerEnd = c.pos();
  metaMap(c, metaType, fileSize, "the file's");
  out.metadataEnd = c.pos();

  const int32_t gridCount = c.read<int32_t>("the grid count");
  if (gridCount < 0) c.corrupt(cat("a grid count of ", gridCount));
  for (int32_t g = 0; g < gridCount; ++g) {
    // io::GridDescriptor::read
    GridSpan span;
    span.begin = c.pos();
    const std::string what = cat("grid '", printable(c.string(cat("grid ", g, ", name")), 64), "'");
    std::string type = c.string(cat(what, ", type name"));
    constexpr std::string_view kHalf = "_HalfFloat";  // io::GridDescriptor's suffix for half floats
    const bool half = type.size() > kHalf.size() && type.compare(type.size() - kHalf.size(), kHalf.size(), kHalf) == 0;
    if (half) type.resize(type.size() - kHalf.size());
    // Trees the walk does not know are refused, not handed to OpenVDB unchecked: bool and mask
    // trees reach the same unchecked block reads, point grids trust their own counts.
    const TreeValues values = treeValues(type);
    if (values.bytes == 0)
      throw Error(cat(path, ": ", what, " is a ", printable(type, 64),
                      " grid, which prt does not read (a probe file holds float and vec3s grids; prt reads "
                      "trees of float, double, int32, int64 and vec3 values)"));
    const std::string parent = c.string(cat(what, ", instance parent name"));
    if (!parent.empty())
      throw Error(cat(path, ": ", what, " is an instance of '", printable(parent, 64),
                      "' (it shares that grid's tree); prt probe files have no instanced grids"));
    const auto gridPos = c.read<int64_t>(what);
    const auto blockPos = c.read<int64_t>(what);
    const auto endPos = c.read<int64_t>(what);
    if (gridPos != int64_t(c.pos()) || blockPos < gridPos || endPos < blockPos || uint64_t(endPos) > fileSize)
      c.corrupt(cat(what, ", offsets ", gridPos, ", ", blockPos, ", ", endPos, " do not fit its descriptor's end ",
                    c.pos(), " and the file's ", fileSize, " bytes"));
    span.end = uint64_t(endPos);
    // io::Archive::readGrid, within the grid's own bytes.
    c.setLimit(span.end);
    const uint32_t compression = c.read<uint32_t>(cat(what, ", compression flags"));
    metaMap(c, metaType, span.end - span.begin, what);
    transform(c, mapBytes, what, path);
    TreeWalk tree(c, what, compression, values, half);
    const uint64_t leaves = tree.topology();
    if (c.pos() != uint64_t(blockPos))
      c.corrupt(cat(what, ", topology ends at byte ", c.pos(), ", where the file says ", blockPos));
    tree.buffers(leaves);
    if (c.pos() != span.end)
      c.corrupt(cat(what, ", buffers end at byte ", c.pos(), ", where the file says ", span.end));
    c.setLimit(fileSize);  // the walk ended at span.end, where the next descriptor begins
    out.grids.push_back(span);
  }
  return out;
}

std::string streamPrefix(const std::string& fileStart, const Layout& layout, bool metadata, int32_t gridCount) {
  std::string out = fileStart.substr(0, metadata ? layout.metadataEnd : layout.headerEnd);
  const auto append = [&](auto v) { out.append(reinterpret_cast<const char*>(&v), sizeof v); };
  if (!metadata) append(uint32_t(0));  // an empty metadata map
  append(gridCount);
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
