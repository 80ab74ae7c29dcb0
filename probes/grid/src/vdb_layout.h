// The layout of an OpenVDB file, checked before OpenVDB reads it, and a stream over one grid of it.
//
// OpenVDB 10 trusts the size fields in a file: it makes a string or vector as long as a field
// says (up to 4 GiB, filled with zeros) before it reads a byte of it (a corrupt 18 KB file cost
// 2.5 GB and 5 s before OpenVDB noticed the end of the file), and it reads an uncompressed block
// of the length the block's size field says into a buffer of the length the tree expects (a heap
// overflow). walk() reads the file's structure the way OpenVDB will (header, metadata, grid
// descriptors, each grid's metadata, transform, tree topology and leaf buffers) and checks every
// such size against the bytes left and against what OpenVDB will read it into, so OpenVDB is only
// handed files whose sizes fit. Each grid's walk must end at the offsets the file records for its
// buffers and its end. SpliceBuf then gives OpenVDB one grid's bytes at a time, from its
// descriptor to its recorded end, so OpenVDB reads exactly the bytes that were walked.
//
// Trees are walked for the value types of OpenVDB's standard 5-4-3 trees (float, double, int32,
// int64, vec3 of s, d, i); grids of other trees (bool and mask leaves, point data) are refused.
//
// No OpenVDB here: how a metadata type or transform map is read is asked of OpenVDB's registry by
// the caller.
#pragma once

#include <cstdint>
#include <functional>
#include <istream>
#include <streambuf>
#include <string>
#include <vector>

namespace prt::vdb_layout {

// How OpenVDB's MetaMap::readMeta reads a metadata value, after its byte count.
enum class MetaRead {
  Bytes,        // the byte count's bytes (strings; types OpenVDB does not know)
  Fixed,        // sizeof the value, which must equal the byte count
  DelayedLoad,  // io::DelayedLoadMetadata: its own counts inside (every grid io::File writes has one)
};
struct MetaType {
  MetaRead read = MetaRead::Bytes;
  uint32_t size = 0;  // Fixed only
};
using MetaTypeOf = std::function<MetaType(const std::string& typeName)>;
// The bytes a transform map of this type reads (math::MapBase::read); 0 for a type OpenVDB does
// not know (it then refuses the file itself).
using MapBytesOf = std::function<uint32_t(const std::string& mapType)>;

// One grid of the file: [begin, end) holds its descriptor (names and offsets) and its data.
struct GridSpan {
  uint64_t begin = 0;
  uint64_t end = 0;
};

struct Layout {
  uint64_t headerEnd = 0;    // [0, headerEnd): the header
  uint64_t metadataEnd = 0;  // [headerEnd, metadataEnd): the file's metadata; then the grid count
  std::vector<GridSpan> grids;
};

// Walks `in` (fileSize bytes, positioned anywhere). Throws prt::Error "path: corrupt or truncated
// VDB file (...)" naming the first size that does not fit, or "path: ..." for a file OpenVDB could
// read but prt does not take (a file format older than 222, or newer than maxVersion; a stream
// without grid offsets; an instanced grid). Grid counts and sizes are bounded by the file's bytes,
// so the walk's time and memory are too.
Layout walk(std::istream& in, uint64_t fileSize, const std::string& path, uint32_t maxVersion,
            const MetaTypeOf& metaType, const MapBytesOf& mapBytes);

// A read-only stream buffer: `prefix` (bytes in memory), then bytes [begin, end) of `file`. Reading
// past the end is the end of the stream. tellg works; other seeks fail.
class SpliceBuf final : public std::streambuf {
 public:
  SpliceBuf(std::string prefix, std::istream& file, uint64_t begin, uint64_t end);

 protected:
  int_type underflow() override;
  pos_type seekoff(off_type off, std::ios_base::seekdir dir, std::ios_base::openmode which) override;

 private:
  std::string prefix_;
  std::istream& file_;
  uint64_t next_, end_;
  uint64_t before_ = 0;  // stream bytes before the current buffer
  bool inFile_ = false;
  std::vector<char> buf_;
};

// The bytes a stream of the file's parts starts with, from fileStart (the file's first
// layout.metadataEnd bytes): the header, the file's metadata (or an empty map, so that a file of
// many grids does not have its metadata read once a grid), then a grid count.
std::string streamPrefix(const std::string& fileStart, const Layout& layout, bool metadata, int32_t gridCount);

}  // namespace prt::vdb_layout
