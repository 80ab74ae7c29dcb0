// The layout of an OpenVDB file, checked before OpenVDB reads it, and a stream over one grid of it.
//
// OpenVDB 10 trusts the size fields that precede its strings and metadata values: it makes a
// string or vector as long as the field says (up to 4 GiB, filled with zeros) before it reads a
// byte of it. A corrupt 18 KB file cost 2.5 GB and 5 s before OpenVDB noticed the end of the
// file. walkVdb reads the file's structure (header, metadata, grid descriptors, each grid's
// metadata and transform name) the way OpenVDB will, and checks every such size against the bytes
// that are left, so OpenVDB is only handed files whose sizes fit. The trees (topology and values)
// it does not parse: GridStream gives OpenVDB one grid's bytes at a time, from its descriptor to the
// end offset the file records for it, so a corrupt tree reaches the end of its own bytes (a short
// read, which throws) instead of running on into the next grid's descriptor.
//
// No OpenVDB here: how a metadata type is read is asked of OpenVDB's registry by the caller.
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

// One grid of the file: [begin, end) holds its descriptor (names and offsets) and its data.
struct GridSpan {
  std::string name;
  uint64_t begin = 0;
  uint64_t end = 0;
};

struct Layout {
  uint32_t fileVersion = 0;
  uint64_t prefixEnd = 0;  // the header and the file's metadata: [0, prefixEnd), then the grid count
  std::vector<GridSpan> grids;
};

// Walks `in` (fileSize bytes, positioned anywhere). Throws prt::Error "path: corrupt or truncated
// VDB file (...)" naming the first size that does not fit, or "path: ..." for a file OpenVDB could
// read but prt does not take (a file format older than 222, or newer than maxVersion; a stream
// without grid offsets; an instanced grid).
Layout walk(std::istream& in, uint64_t fileSize, const std::string& path, uint32_t maxVersion,
            const MetaTypeOf& metaType);

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

// The bytes a grid stream starts with: the file's header and metadata, then a grid count.
std::string gridStreamPrefix(const std::string& headerAndMetadata, int32_t gridCount);

}  // namespace prt::vdb_layout
