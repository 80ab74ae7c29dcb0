// Reading the probe grid's OpenVDB file (readProbeGrid) and describing it (describeProbeFile,
// `prt info`). One of the two translation units of prt that include OpenVDB (its headers cost
// ~30 s to compile); the writer is probe_grid_vdb_write.cpp, the format (versions, grid names,
// metadata keys) is probe_file.h, and vdb_layout.cpp checks a file's structure before OpenVDB
// reads it. Only standard grid types (float, vec3s) and standard metadata, so vdb_print,
// vdb_view, pyopenvdb, Houdini and Blender read the file as it is. Layout: docs/probes.md.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <sstream>
#include <tuple>
#include <type_traits>

#include <openvdb/io/DelayedLoadMetadata.h>
#include <openvdb/io/Stream.h>
#include <openvdb/openvdb.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "probe_file.h"
#include "prt/error.h"
#include "prt/probe_grid.h"
#include "prt/progress.h"
#include "vdb_layout.h"

namespace prt {

namespace vdb = openvdb;

void probe_file::initOpenVdb() {
  static std::once_flag once;
  std::call_once(once, [] { vdb::initialize(); });
}

namespace {

namespace fs = std::filesystem;
using namespace probe_file;

// OpenVDB's file magic: the first 8 bytes of every .vdb file (an int64, little endian).
constexpr int64_t kVdbMagic = 0x56444220;

// ---- Reading

struct LoadedFile {
  vdb::MetaMap::Ptr meta;
  vdb::GridPtrVec grids;
  std::map<std::string, vdb::GridBase::Ptr> byName;
  uintmax_t fileSize = 0;
};

// How MetaMap::readMeta reads a value of this type, from OpenVDB's own registry (vdb_layout.h).
vdb_layout::MetaType metaTypeOf(const std::string& type) {
  using vdb_layout::MetaRead;
  if (!vdb::Metadata::isRegisteredType(type) || type == vdb::StringMetadata::staticTypeName()) return {MetaRead::Bytes};
  if (type == vdb::io::DelayedLoadMetadata::staticTypeName()) return {MetaRead::DelayedLoad};
  static std::mutex mutex;
  static std::map<std::string, uint32_t> sizes;
  std::lock_guard lock(mutex);
  auto it = sizes.find(type);
  if (it == sizes.end()) it = sizes.emplace(type, vdb::Metadata::createMetadata(type)->size()).first;
  return {MetaRead::Fixed, it->second};
}

// The bytes a transform map of this type reads: a default one written out (0 for unknown types).
uint32_t mapBytesOf(const std::string& type) {
  if (!vdb::math::MapRegistry::isRegistered(type)) return 0;
  static std::mutex mutex;
  static std::map<std::string, uint32_t> sizes;
  std::lock_guard lock(mutex);
  auto it = sizes.find(type);
  if (it == sizes.end()) {
    std::ostringstream os;
    vdb::math::MapRegistry::createMap(type)->write(os);
    it = sizes.emplace(type, uint32_t(os.str().size())).first;
  }
  return it->second;
}

// Reads every grid of the file. First vdb_layout::walk checks every size OpenVDB would trust
// before reading (a corrupt string length cost gigabytes, a corrupt block size overflowed a
// buffer). Then the file's metadata goes through one io::Stream, and each grid through its own
// over the file's header and that grid's bytes (vdb_layout::SpliceBuf), all read from our
// ifstream: OpenVDB does not check for the end of the stream everywhere, so a
// truncated file could come back as garbage (or a garbage size become a huge allocation); our
// stream throws on the first short read instead, and a corrupt tree ends at its own grid's end.
// io::File would also memory-map the file for delayed loading.
LoadedFile loadFile(const std::string& path) {
  std::error_code ec;
  if (!fs::exists(path, ec)) throw Error(cat(path, ": no such file"));
  if (fs::is_directory(path, ec)) throw Error(cat(path, ": is a directory, expected a .vdb file"));
  LoadedFile out;
  out.fileSize = fs::file_size(path, ec);
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error(cat(path, ": cannot read"));
  int64_t magic = 0;
  in.read(reinterpret_cast<char*>(&magic), sizeof magic);
  if (!in || magic != kVdbMagic) throw Error(cat(path, ": not an OpenVDB file"));
  in.seekg(0);
  // Reading past the end throws at once, before a truncated size field can be used as one.
  in.exceptions(std::ios::failbit | std::ios::badbit);
  initOpenVdb();
  try {
    const vdb_layout::Layout layout =
        vdb_layout::walk(in, out.fileSize, path, vdb::OPENVDB_FILE_VERSION, metaTypeOf, mapBytesOf);
    std::string start(layout.metadataEnd, '\0');
    in.seekg(0);
    in.read(start.data(), std::streamsize(start.size()));
    const auto readStream = [&](bool metadata, int32_t gridCount, uint64_t begin, uint64_t end) {
      vdb_layout::SpliceBuf buf(vdb_layout::streamPrefix(start, layout, metadata, gridCount), in, begin, end);
      std::istream gridIn(&buf);
      gridIn.exceptions(std::ios::failbit | std::ios::badbit);
      vdb::io::Stream stream(gridIn, /*delayLoad=*/false);
      if (metadata) out.meta = stream.getMetadata();
      if (vdb::GridPtrVecPtr grids = stream.getGrids()) out.grids.insert(out.grids.end(), grids->begin(), grids->end());
    };
    readStream(true, 0, 0, 0);  // the file's metadata, once
    for (const vdb_layout::GridSpan& g : layout.grids) readStream(false, 1, g.begin, g.end);
  } catch (const Error&) {
    throw;
  } catch (const std::ios::failure&) {
    // OpenVDB's readTopology is not exception-safe: the half-read tree leaks (a few MB per bad
    // file, found with ASan). Acceptable for a reader that reports the file and moves on.
    throw Error(cat(path, ": corrupt or truncated VDB file (unexpected end of file)"));
  } catch (const std::exception& e) {  // openvdb::Exception, std::bad_alloc, ...
    throw Error(cat(path, ": corrupt or truncated VDB file (", e.what(), ")"));
  }
  if (!out.meta) out.meta = std::make_shared<vdb::MetaMap>();
  for (const vdb::GridBase::Ptr& g : out.grids)
    if (g) out.byName[g->getName()] = g;
  return out;
}

class MetaReader {
 public:
  MetaReader(const std::string& path, const vdb::MetaMap& meta) : path_(path), meta_(meta) {}

  bool has(const std::string& key) const { return bool(meta_[key]); }

  int64_t integer(const std::string& key) const {
    vdb::Metadata::ConstPtr m = required(key);
    if (auto v = meta_.getMetadata<vdb::Int32Metadata>(key)) return v->value();
    if (auto v = meta_.getMetadata<vdb::Int64Metadata>(key)) return v->value();
    throw Error(cat(path_, ": metadata '", key, "' is ", printable(m->typeName()), ", expected an integer"));
  }

  std::string string(const std::string& key) const {
    vdb::Metadata::ConstPtr m = required(key);
    if (auto v = meta_.getMetadata<vdb::StringMetadata>(key)) return v->value();
    throw Error(cat(path_, ": metadata '", key, "' is ", printable(m->typeName()), ", expected a string"));
  }

  glm::ivec3 vec3i(const std::string& key) const {
    vdb::Metadata::ConstPtr m = required(key);
    if (auto v = meta_.getMetadata<vdb::Vec3IMetadata>(key)) {
      const vdb::Vec3i& x = v->value();
      return {x[0], x[1], x[2]};
    }
    throw Error(cat(path_, ": metadata '", key, "' is ", printable(m->typeName()), ", expected vec3i"));
  }

  glm::dvec3 vec3d(const std::string& key) const {
    vdb::Metadata::ConstPtr m = required(key);
    if (auto v = meta_.getMetadata<vdb::Vec3DMetadata>(key)) {
      const vdb::Vec3d& x = v->value();
      return {x[0], x[1], x[2]};
    }
    throw Error(cat(path_, ": metadata '", key, "' is ", printable(m->typeName()), ", expected vec3d"));
  }

 private:
  vdb::Metadata::ConstPtr required(const std::string& key) const {
    vdb::Metadata::ConstPtr m = meta_[key];
    if (!m) throw Error(cat(path_, ": metadata '", key, "' missing (not a prt probe file?)"));
    return m;
  }

  const std::string& path_;
  const vdb::MetaMap& meta_;
};

template <class GridT>
typename GridT::Ptr requireGrid(const std::string& path, const LoadedFile& file, const std::string& name,
                                const char* expectedType) {
  auto it = file.byName.find(name);
  if (it == file.byName.end()) throw Error(cat(path, ": grid '", name, "' missing"));
  typename GridT::Ptr g = vdb::gridPtrCast<GridT>(it->second);
  if (!g) throw Error(cat(path, ": grid '", name, "' is ", it->second->valueType(), ", expected ", expectedType));
  return g;
}

bool near(double a, double b) { return std::abs(a - b) <= 1e-9 * std::max({1.0, std::abs(a), std::abs(b)}); }

// Checks that `g` has the transform and the active voxels of the validity grid, so that every
// probe's values are really stored (not the background).
void checkLike(const std::string& path, const vdb::GridBase& g, const vdb::GridBase& validity) {
  if (g.activeVoxelCount() != validity.activeVoxelCount())
    throw Error(cat(path, ": grid '", g.getName(), "' has ", g.activeVoxelCount(),
                    " active voxels, grid 'validity' has ", validity.activeVoxelCount()));
  if (g.transform() != validity.transform())
    throw Error(cat(path, ": grid '", g.getName(), "' has a different transform from grid 'validity'"));
}

template <class GridT, class F>
void readProbes(const std::string& path, const GridT& g, const std::vector<glm::ivec3>& coord, F&& store) {
  auto acc = g.getConstAccessor();
  for (size_t p = 0; p < coord.size(); ++p) {
    typename GridT::ValueType v;
    if (!acc.probeValue(vdb::Coord(coord[p].x, coord[p].y, coord[p].z), v))
      throw Error(cat(path, ": grid '", g.getName(), "' has no active value at probe (", coord[p].x, ", ", coord[p].y,
                      ", ", coord[p].z, ")"));
    store(p, v);
  }
}

// ---- Metadata, through kMetaKeys (probe_file.h)

int64_t readVersion(const std::string& path, const MetaReader& meta) {
  const int64_t version = meta.integer(kVersionKey);
  if (version == kVersionWithRayLengths)
    throw Error(cat(path, ": ", kVersionKey, " ", version,
                    " is no longer read: its moment grids hold ray lengths, "
                    "version ",
                    kVersionWithoutDirect, " holds depths along the face axis; bake the probes again"));
  if (version != kFormatVersion && version != kVersionWithoutDirect)
    throw Error(cat(path, ": ", kVersionKey, " ", version, " is not supported (this prt reads ", kVersionWithoutDirect,
                    " and ", kFormatVersion, ")"));
  return version;
}

// Reads key `k` into its field of `grid` (the version and Fixed keys are not read here).
void readKey(const std::string& path, const MetaReader& meta, const MetaKey& k, ProbeGrid& grid) {
  withField(grid, k, [&](auto& v) {
    using V = std::decay_t<decltype(v)>;
    if constexpr (std::is_same_v<V, int>) {
      const int64_t x = meta.integer(k.key);
      if (x < k.lo || x > k.hi) throw Error(cat(path, ": ", k.key, " = ", x, ", expected ", k.lo, "..", k.hi));
      v = int(x);
    } else if constexpr (std::is_same_v<V, glm::ivec3>) {
      v = meta.vec3i(k.key);
    } else if constexpr (std::is_same_v<V, glm::dvec3>) {
      v = meta.vec3d(k.key);
    } else if constexpr (std::is_same_v<V, std::string>) {
      v = meta.string(k.key);
    } else if constexpr (std::is_same_v<V, uint64_t>) {
      const std::string s = meta.string(k.key);
      char* end = nullptr;
      v = std::strtoull(s.c_str(), &end, 10);
      if (s.empty() || *end != '\0') throw Error(cat(path, ": metadata '", k.key, "' = '", s, "' is not an integer"));
    }
  });
}

// The lattice the metadata gives, checked before any grid is read.
void checkLattice(const std::string& path, const ProbeGrid& grid) {
  for (int a = 0; a < 3; ++a) {
    if (grid.dims[a] < 1)
      throw Error(cat(path, ": dims (", grid.dims.x, ", ", grid.dims.y, ", ", grid.dims.z, ") must be >= 1"));
    if (!(grid.spacing[a] > 0.0) || !std::isfinite(grid.spacing[a]) || !std::isfinite(grid.origin[a]))
      throw Error(cat(path, ": spacing must be finite and > 0, origin finite"));
  }
  // find() keeps a dense int32 index over the whole lattice: refuse sizes it cannot hold (a
  // corrupt dims would otherwise become a huge allocation).
  const double lattice = double(grid.dims.x) * grid.dims.y * grid.dims.z;
  if (lattice > double(INT32_MAX))
    throw Error(
        cat(path, ": dims (", grid.dims.x, ", ", grid.dims.y, ", ", grid.dims.z, ") exceed 2^31 lattice points"));
}

// The metadata in the order of kMetaKeys: the version first, then the required keys, whose
// lattice is checked before anything else is read, then the optional ones. Returns the version.
int64_t readMetadata(const std::string& path, const vdb::MetaMap& map, ProbeGrid& grid) {
  const MetaReader meta(path, map);
  const int64_t version = readVersion(path, meta);
  for (const MetaKey& k : kMetaKeys)
    if (k.use == MetaUse::Required && !std::holds_alternative<FormatVersion>(k.field)) readKey(path, meta, k, grid);
  checkLattice(path, grid);
  for (const MetaKey& k : kMetaKeys)
    if ((k.use == MetaUse::Optional || k.use == MetaUse::OmittedIfEmpty) && meta.has(k.key))
      readKey(path, meta, k, grid);
  return version;
}

// ---- Grids

size_t gridsNamed(const LoadedFile& file, const char* prefix) {
  size_t count = 0;
  for (const auto& [name, g] : file.byName)
    if (name.rfind(prefix, 0) == 0) ++count;
  return count;
}

// The n⁴ transfer grids, (j, i) row by row. Extra transfer grids mean the file was written
// with more bands than its metadata says.
std::vector<vdb::Vec3SGrid::Ptr> transferGrids(const std::string& path, const LoadedFile& file, const ProbeGrid& grid) {
  const int n2 = grid.coeffs();
  std::vector<vdb::Vec3SGrid::Ptr> transfer(size_t(n2) * size_t(n2));
  for (int j = 0; j < n2; ++j)
    for (int i = 0; i < n2; ++i)
      transfer[size_t(j) * n2 + i] = requireGrid<vdb::Vec3SGrid>(path, file, transferName(j, i), "vec3s");
  const size_t found = gridsNamed(file, kTransferPrefix);
  if (found != transfer.size())
    throw Error(
        cat(path, ": bands = ", grid.bands, " needs ", transfer.size(), " transfer grids, the file holds ", found));
  return transfer;
}

// Version 3: the upper triangle of M⁰, in ProbeGrid::direct's order.
std::vector<vdb::FloatGrid::Ptr> directGrids(const std::string& path, const LoadedFile& file, const ProbeGrid& grid) {
  const int n2 = grid.coeffs();
  std::vector<vdb::FloatGrid::Ptr> direct;
  for (int j = 0; j < n2; ++j)
    for (int i = j; i < n2; ++i) direct.push_back(requireGrid<vdb::FloatGrid>(path, file, directName(j, i), "float"));
  const size_t found = gridsNamed(file, kDirectPrefix);
  if (found != direct.size())
    throw Error(cat(path, ": bands = ", grid.bands, " needs ", direct.size(), " direct grids, the file holds ", found));
  return direct;
}

// The probes: the active voxels of the validity grid, sorted, within dims. Its transform must
// be the metadata's origin and spacing.
void readCoords(const std::string& path, const vdb::FloatGrid& validity, ProbeGrid& grid) {
  const vdb::math::Transform& xform = validity.transform();
  if (!xform.isLinear()) throw Error(cat(path, ": grid '", kValidityGrid, "' has a non-linear transform"));
  const vdb::Vec3d o = xform.indexToWorld(vdb::Vec3d(0.0));
  const vdb::Vec3d step = xform.indexToWorld(vdb::Vec3d(1.0)) - o;
  for (int a = 0; a < 3; ++a)
    if (!near(o[a], grid.origin[a]) || !near(step[a], grid.spacing[a]))
      throw Error(cat(path, ": the grids' transform does not match metadata origin/spacing"));

  for (auto it = validity.cbeginValueOn(); it; ++it) {
    if (!it.isVoxelValue())
      throw Error(cat(path, ": grid '", kValidityGrid, "' holds an active tile, expected single probes"));
    const vdb::Coord c = it.getCoord();
    grid.coord.emplace_back(c.x(), c.y(), c.z());
  }
  std::sort(grid.coord.begin(), grid.coord.end(),
            [](const glm::ivec3& a, const glm::ivec3& b) { return std::tie(a.x, a.y, a.z) < std::tie(b.x, b.y, b.z); });
  for (const glm::ivec3& c : grid.coord)
    if (c.x < 0 || c.y < 0 || c.z < 0 || c.x >= grid.dims.x || c.y >= grid.dims.y || c.z >= grid.dims.z)
      throw Error(cat(path, ": probe (", c.x, ", ", c.y, ", ", c.z, ") lies outside dims (", grid.dims.x, ", ",
                      grid.dims.y, ", ", grid.dims.z, ")"));
}

// Validity, offset, sky visibility and the moments of every probe.
void readProbeValues(const std::string& path, const LoadedFile& file, const vdb::FloatGrid& validity, ProbeGrid& grid) {
  const size_t count = grid.coord.size();
  grid.validity.resize(count);
  readProbes(path, validity, grid.coord, [&](size_t p, float v) { grid.validity[p] = v; });

  const auto offset = requireGrid<vdb::Vec3SGrid>(path, file, kOffsetGrid, "vec3s");
  checkLike(path, *offset, validity);
  grid.offset.resize(count);
  readProbes(path, *offset, grid.coord,
             [&](size_t p, const vdb::Vec3s& v) { grid.offset[p] = glm::vec3(v[0], v[1], v[2]); });

  const auto sky = requireGrid<vdb::FloatGrid>(path, file, kSkyGrid, "float");
  checkLike(path, *sky, validity);
  grid.skyVisibility.resize(count);
  readProbes(path, *sky, grid.coord, [&](size_t p, float v) { grid.skyVisibility[p] = v; });

  grid.moments.resize(count);
  for (const MomentGrid& mg : kMomentGrids) {
    const auto g = requireGrid<vdb::Vec3SGrid>(path, file, mg.name, "vec3s");
    checkLike(path, *g, validity);
    readProbes(path, *g, grid.coord, [&](size_t p, const vdb::Vec3s& v) {
      for (int axis = 0; axis < 3; ++axis) grid.moments[p][size_t(2 * axis + mg.sign)][mg.component] = v[axis];
    });
  }
}

// The transfer and direct matrices of every probe, one grid per task: each writes its own
// (j, i) slot of every probe. A prt::Error thrown by a task (a probe missing from a grid)
// reaches the caller through TBB.
void readMatrices(const std::string& path, const std::vector<vdb::Vec3SGrid::Ptr>& transfer,
                  const std::vector<vdb::FloatGrid::Ptr>& direct, const vdb::FloatGrid& validity, ProbeGrid& grid) {
  const size_t count = grid.coord.size();
  for (const vdb::Vec3SGrid::Ptr& g : transfer) checkLike(path, *g, validity);
  const size_t stride = grid.transferStride();
  grid.transfer.resize(count * stride);
  tbb::parallel_for(tbb::blocked_range<size_t>(0, transfer.size(), 1), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t k = r.begin(); k < r.end(); ++k)
      readProbes(path, *transfer[k], grid.coord, [&](size_t p, const vdb::Vec3s& v) {
        float* dst = grid.transfer.data() + p * stride + k * 3;
        dst[0] = v[0];
        dst[1] = v[1];
        dst[2] = v[2];
      });
  });
  for (const vdb::FloatGrid::Ptr& g : direct) checkLike(path, *g, validity);
  const size_t dstride = grid.directStride();
  grid.direct.resize(direct.empty() ? 0 : count * dstride);
  tbb::parallel_for(tbb::blocked_range<size_t>(0, direct.size(), 1), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t k = r.begin(); k < r.end(); ++k)
      readProbes(path, *direct[k], grid.coord, [&](size_t p, float v) { grid.direct[p * dstride + k] = v; });
  });
}

ProbeGrid toProbeGrid(const std::string& path, const LoadedFile& file) {
  ProbeGrid grid;
  const int64_t version = readMetadata(path, *file.meta, grid);
  const std::vector<vdb::Vec3SGrid::Ptr> transfer = transferGrids(path, file, grid);
  const std::vector<vdb::FloatGrid::Ptr> direct =
      version >= kFormatVersion ? directGrids(path, file, grid) : std::vector<vdb::FloatGrid::Ptr>();
  const vdb::FloatGrid::Ptr validity = requireGrid<vdb::FloatGrid>(path, file, kValidityGrid, "float");
  readCoords(path, *validity, grid);
  readProbeValues(path, file, *validity, grid);
  readMatrices(path, transfer, direct, *validity, grid);
  grid.buildIndex();
  return grid;
}

std::string vec3Text(const glm::dvec3& v) { return cat("(", v.x, ", ", v.y, ", ", v.z, ")"); }

}  // namespace

ProbeGrid readProbeGrid(const std::string& path) {
  const LoadedFile file = loadFile(path);
  return toProbeGrid(path, file);
}

std::string describeProbeFile(const std::string& path) {
  const LoadedFile file = loadFile(path);
  const ProbeGrid grid = toProbeGrid(path, file);

  size_t valid = 0;
  for (float v : grid.validity) valid += v > 0.0f;
  const long long lattice = (long long)grid.dims.x * grid.dims.y * grid.dims.z;
  uintmax_t memory = 0;
  bool half = false;
  std::vector<std::string> others;
  std::string firstTransfer, lastTransfer;
  size_t transferGrids = 0, directGrids = 0;
  for (const auto& [name, g] : file.byName) {  // std::map: sorted like VDB's own listing
    memory += g->memUsage();
    half |= g->saveFloatAsHalf();
    if (name.rfind(kTransferPrefix, 0) == 0) {
      if (firstTransfer.empty()) firstTransfer = name;
      lastTransfer = name;
      ++transferGrids;
    } else if (name.rfind(kDirectPrefix, 0) == 0) {
      ++directGrids;
    } else {
      others.push_back(cat(name, " (", g->valueType() == "vec3s" ? "Vec3f" : g->valueType(), ")"));
    }
  }

  std::ostringstream os;
  os << path << "\n";
  os << "  format        prt probe grid v" << formatVersion(grid) << " (OpenVDB, "
     << (half ? "16-bit transfer" : "32-bit floats") << ")\n";
  os << "  bands         " << grid.bands << " (" << grid.coeffs() << " SH coefficients, "
     << grid.coeffs() * grid.coeffs() << " RGB transfer entries per probe)\n";
  os << "  dims          " << grid.dims.x << " x " << grid.dims.y << " x " << grid.dims.z << " (" << lattice
     << " lattice points)\n";
  os << "  spacing       " << vec3Text(grid.spacing) << "\n";
  os << "  origin        " << vec3Text(grid.origin) << "\n";
  glm::dvec3 domainLo, domainHi;
  probeDomain(grid, domainLo, domainHi);
  os << "  world bounds  " << vec3Text(grid.origin) << " .. "
     << vec3Text(grid.origin + grid.spacing * glm::dvec3(grid.dims - 1)) << " (probe positions)\n";
  os << "  domain        " << vec3Text(domainLo) << " .. " << vec3Text(domainHi)
     << " (half a cell more: queried here; beyond it receivers fade into the unoccluded light over one "
        "spacing)\n";
  os << "  probes        " << grid.probeCount() << " active of " << lattice << ", " << valid << " valid\n";
  os << "  grids         " << file.byName.size() << ": " << firstTransfer << " .. " << lastTransfer << " ("
     << transferGrids << " Vec3f grids)";
  if (directGrids)
    os << ", " << directName(0, 0) << " .. " << directName(grid.coeffs() - 1, grid.coeffs() - 1) << " (" << directGrids
       << " float grids: the direct part)";
  else
    os << ", no direct part (baked before prt kept it apart: suns are lit through the whole transfer)";
  for (const std::string& o : others) os << ", " << o;
  os << "\n";
  // What prt holds once read: the parallel arrays plus the dense index of find().
  const uintmax_t arrays =
      grid.probeCount() *
          (sizeof(glm::ivec3) +
           (grid.transferStride() + grid.direct.size() / std::max<size_t>(grid.probeCount(), 1)) * sizeof(float) +
           sizeof(float) * 2 + sizeof(glm::vec3) + sizeof(grid.moments[0])) +
      uintmax_t(lattice) * sizeof(int32_t);
  os << "  file size     " << formatBytes(file.fileSize) << " on disk\n";
  os << "  memory        " << formatBytes(arrays) << " once loaded by prt (probe arrays and lattice index)\n"
     << "                " << formatBytes(arrays + memory) << " at the peak while reading: the OpenVDB trees ("
     << formatBytes(memory) << ", mostly their internal nodes) are freed after conversion\n";
  os << "  bake          " << grid.info.bounces << " bounces, " << grid.info.samples << " samples, seed "
     << grid.info.seed << ", scene '" << grid.info.scene << "'\n";
  if (!grid.info.region.empty())
    os << "  region        "
       << (grid.info.region == "inside"       ? "inside: only space sealed in by the scene's surfaces"
           : grid.info.region == "everywhere" ? "everywhere outside solid geometry"
           : grid.info.region == "near" ? "near: near surfaces or surrounded by them (open air far from all not baked)"
                                        : grid.info.region)
       << "\n";
  return os.str();
}

}  // namespace prt
