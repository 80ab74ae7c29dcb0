// The probe grid as an OpenVDB file: the only translation unit of prt that includes OpenVDB
// (its headers cost ~30 s to compile). Only standard grid types (float, vec3s) and standard
// metadata, so vdb_print, vdb_view, pyopenvdb, Houdini and Blender read the file as it is.
// Layout: docs/probes.md.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <sstream>
#include <tuple>

#include <openvdb/io/DelayedLoadMetadata.h>
#include <openvdb/io/Stream.h>
#include <openvdb/openvdb.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "prt/atomic_file.h"
#include "prt/error.h"
#include "prt/math.h"
#include "prt/probe_grid.h"
#include "prt/progress.h"
#include "vdb_layout.h"

namespace prt {

namespace {

namespace fs = std::filesystem;
namespace vdb = openvdb;

// 2: the moment grids hold depths along the face's axis. Version 1 held ray lengths, which the
// interpolation of version 2 would misread (it would let light through walls), so 1 is refused.
// 3: adds the direct part M⁰ (direct_JJ_II, j <= i). Version 2 files are read, without it.
constexpr int kFormatVersion = 3;
// OpenVDB's file magic: the first 8 bytes of every .vdb file (an int64, little endian).
constexpr int64_t kVdbMagic = 0x56444220;

constexpr const char* kShConvention =
    "real orthonormal SH, index l(l+1)+m, no Condon-Shortley phase, polar axis +Z, "
    "glTF frame (+Y up, right-handed), directions point towards the light";
constexpr const char* kUnits = "incident radiance SH = transfer · light SH; radiance";
constexpr const char* kLayout =
    "transfer_JJ_II vec3s: RGB of M_ji (c_j = sum_i M_ji l_i); direct_JJ_II float, JJ <= II: M0_ji = M0_ij, "
    "the direct (bounce 0, first-hit visibility) part of M, colourless and symmetric; validity float (1 valid, 0 inside "
    "geometry); offset vec3s: world offset of the probe from its lattice point; sky_visibility "
    "float; irradiance_preview vec3s: irradiance at a +Y normal under a uniform sky of radiance "
    "1; moments_mean_pos/neg vec3s: for the rays of the +X,+Y,+Z / -X,-Y,-Z cube faces, mean "
    "depth of the first hit along the face's axis (|t*dir_axis|, misses 2*max spacing); "
    "moments_sq_pos/neg vec3s: mean squared depth; index (i,j,k) is at world "
    "origin + spacing*(i,j,k)";

// The four moment grids: which faces each holds, and whether it is the mean or the mean square.
struct MomentGrid {
  const char* name;
  int sign;       // 0: +X,+Y,+Z; 1: -X,-Y,-Z (Face = 2·axis + sign)
  int component;  // 0: mean distance, 1: mean squared distance
  const char* description;
};
constexpr MomentGrid kMomentGrids[] = {
    {"moments_mean_pos", 0, 0, "mean depth of the first hit along the face axis, faces +X,+Y,+Z"},
    {"moments_mean_neg", 1, 0, "mean depth of the first hit along the face axis, faces -X,-Y,-Z"},
    {"moments_sq_pos", 0, 1, "mean squared depth of the first hit along the face axis, faces +X,+Y,+Z"},
    {"moments_sq_neg", 1, 1, "mean squared depth of the first hit along the face axis, faces -X,-Y,-Z"},
};

void initOpenVdb() {
  static std::once_flag once;
  std::call_once(once, [] { vdb::initialize(); });
}

std::string transferName(int j, int i) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "transfer_%02d_%02d", j, i);
  return buf;
}

std::string directName(int j, int i) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "direct_%02d_%02d", j, i);
  return buf;
}

vdb::math::Transform::Ptr makeTransform(const glm::dvec3& origin, const glm::dvec3& spacing) {
  const vdb::Vec3d t(origin.x, origin.y, origin.z);
  vdb::math::MapBase::Ptr map;
  // VDB voxel centres sit at integer index coordinates, so index (i, j, k) lands on
  // origin + spacing ⊙ (i, j, k): a probe is a voxel centre.
  if (spacing.x == spacing.y && spacing.y == spacing.z)
    map = std::make_shared<vdb::math::UniformScaleTranslateMap>(spacing.x, t);
  else
    map = std::make_shared<vdb::math::ScaleTranslateMap>(vdb::Vec3d(spacing.x, spacing.y, spacing.z), t);
  return std::make_shared<vdb::math::Transform>(map);
}

template <class GridT>
typename GridT::Ptr makeGrid(const std::string& name, const vdb::math::Transform::Ptr& xform,
                             const std::string& description, bool half) {
  typename GridT::Ptr g = GridT::create();
  g->setName(name);
  g->setTransform(xform);
  g->setCreator("prt");
  g->setSaveFloatAsHalf(half);
  g->insertMeta("description", vdb::StringMetadata(description));
  return g;
}

vdb::Vec3s toVdb(const glm::vec3& v) { return vdb::Vec3s(v.x, v.y, v.z); }

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
  if (!vdb::Metadata::isRegisteredType(type) || type == vdb::StringMetadata::staticTypeName())
    return {MetaRead::Bytes};
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
    const vdb_layout::Layout layout = vdb_layout::walk(in, out.fileSize, path, vdb::OPENVDB_FILE_VERSION, metaTypeOf, mapBytesOf);
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
  if (!g)
    throw Error(cat(path, ": grid '", name, "' is ", it->second->valueType(), ", expected ", expectedType));
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
      throw Error(cat(path, ": grid '", g.getName(), "' has no active value at probe (", coord[p].x, ", ",
                      coord[p].y, ", ", coord[p].z, ")"));
    store(p, v);
  }
}

ProbeGrid toProbeGrid(const std::string& path, const LoadedFile& file) {
  const MetaReader meta(path, *file.meta);
  const int64_t version = meta.integer("prt_format_version");
  if (version == 1)
    throw Error(cat(path, ": prt_format_version 1 is no longer read: its moment grids hold ray lengths, "
                    "version 2 holds depths along the face axis; bake the probes again"));
  if (version != kFormatVersion && version != 2)
    throw Error(cat(path, ": prt_format_version ", version, " is not supported (this prt reads 2 and ",
                    kFormatVersion, ")"));
  ProbeGrid grid;
  const int64_t bands = meta.integer("bands");
  if (bands < 1 || bands > sh::kMaxBands)
    throw Error(cat(path, ": bands = ", bands, ", expected 1..", sh::kMaxBands));
  grid.bands = int(bands);
  grid.dims = meta.vec3i("dims");
  grid.origin = meta.vec3d("origin");
  grid.spacing = meta.vec3d("spacing");
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
    throw Error(cat(path, ": dims (", grid.dims.x, ", ", grid.dims.y, ", ", grid.dims.z,
                    ") exceed 2^31 lattice points"));
  if (meta.has("bounces")) grid.info.bounces = int(meta.integer("bounces"));
  if (meta.has("samples")) grid.info.samples = int(meta.integer("samples"));
  if (meta.has("scene")) grid.info.scene = meta.string("scene");
  if (meta.has("probe_region")) grid.info.region = meta.string("probe_region");
  if (meta.has("seed")) {
    const std::string s = meta.string("seed");
    char* end = nullptr;
    grid.info.seed = std::strtoull(s.c_str(), &end, 10);
    if (s.empty() || *end != '\0') throw Error(cat(path, ": metadata 'seed' = '", s, "' is not an integer"));
  }

  const int n2 = grid.coeffs();
  std::vector<vdb::Vec3SGrid::Ptr> transfer(size_t(n2) * size_t(n2));
  for (int j = 0; j < n2; ++j)
    for (int i = 0; i < n2; ++i)
      transfer[size_t(j) * n2 + i] = requireGrid<vdb::Vec3SGrid>(path, file, transferName(j, i), "vec3s");
  // Extra transfer grids mean the file was written with more bands than its metadata says.
  size_t transferGrids = 0;
  for (const auto& [name, g] : file.byName)
    if (name.rfind("transfer_", 0) == 0) ++transferGrids;
  if (transferGrids != transfer.size())
    throw Error(cat(path, ": bands = ", bands, " needs ", transfer.size(), " transfer grids, the file holds ",
                    transferGrids));
  // Version 3: the upper triangle of M⁰, in ProbeGrid::direct's order.
  std::vector<vdb::FloatGrid::Ptr> direct;
  if (version >= 3) {
    for (int j = 0; j < n2; ++j)
      for (int i = j; i < n2; ++i) direct.push_back(requireGrid<vdb::FloatGrid>(path, file, directName(j, i), "float"));
    size_t directGrids = 0;
    for (const auto& [name, g] : file.byName)
      if (name.rfind("direct_", 0) == 0) ++directGrids;
    if (directGrids != direct.size())
      throw Error(cat(path, ": bands = ", bands, " needs ", direct.size(), " direct grids, the file holds ",
                      directGrids));
  }

  const vdb::FloatGrid::Ptr validity = requireGrid<vdb::FloatGrid>(path, file, "validity", "float");
  const vdb::math::Transform& xform = validity->transform();
  if (!xform.isLinear()) throw Error(cat(path, ": grid 'validity' has a non-linear transform"));
  const vdb::Vec3d o = xform.indexToWorld(vdb::Vec3d(0.0));
  const vdb::Vec3d step = xform.indexToWorld(vdb::Vec3d(1.0)) - o;
  for (int a = 0; a < 3; ++a)
    if (!near(o[a], grid.origin[a]) || !near(step[a], grid.spacing[a]))
      throw Error(cat(path, ": the grids' transform does not match metadata origin/spacing"));

  for (auto it = validity->cbeginValueOn(); it; ++it) {
    if (!it.isVoxelValue())
      throw Error(cat(path, ": grid 'validity' holds an active tile, expected single probes"));
    const vdb::Coord c = it.getCoord();
    grid.coord.emplace_back(c.x(), c.y(), c.z());
  }
  std::sort(grid.coord.begin(), grid.coord.end(), [](const glm::ivec3& a, const glm::ivec3& b) {
    return std::tie(a.x, a.y, a.z) < std::tie(b.x, b.y, b.z);
  });
  for (const glm::ivec3& c : grid.coord)
    if (c.x < 0 || c.y < 0 || c.z < 0 || c.x >= grid.dims.x || c.y >= grid.dims.y || c.z >= grid.dims.z)
      throw Error(cat(path, ": probe (", c.x, ", ", c.y, ", ", c.z, ") lies outside dims (", grid.dims.x,
                      ", ", grid.dims.y, ", ", grid.dims.z, ")"));
  const size_t count = grid.coord.size();

  grid.validity.resize(count);
  readProbes(path, *validity, grid.coord, [&](size_t p, float v) { grid.validity[p] = v; });

  const auto offset = requireGrid<vdb::Vec3SGrid>(path, file, "offset", "vec3s");
  checkLike(path, *offset, *validity);
  grid.offset.resize(count);
  readProbes(path, *offset, grid.coord,
             [&](size_t p, const vdb::Vec3s& v) { grid.offset[p] = glm::vec3(v[0], v[1], v[2]); });

  const auto sky = requireGrid<vdb::FloatGrid>(path, file, "sky_visibility", "float");
  checkLike(path, *sky, *validity);
  grid.skyVisibility.resize(count);
  readProbes(path, *sky, grid.coord, [&](size_t p, float v) { grid.skyVisibility[p] = v; });

  grid.moments.resize(count);
  for (const MomentGrid& mg : kMomentGrids) {
    const auto g = requireGrid<vdb::Vec3SGrid>(path, file, mg.name, "vec3s");
    checkLike(path, *g, *validity);
    readProbes(path, *g, grid.coord, [&](size_t p, const vdb::Vec3s& v) {
      for (int axis = 0; axis < 3; ++axis)
        grid.moments[p][size_t(2 * axis + mg.sign)][mg.component] = v[axis];
    });
  }

  // Transfer grids one per task: each writes its own (j, i) slot of every probe.
  for (const vdb::Vec3SGrid::Ptr& g : transfer) checkLike(path, *g, *validity);
  const size_t stride = grid.transferStride();
  grid.transfer.resize(count * stride);
  // A prt::Error thrown by a task (a probe missing from a grid) reaches the caller through TBB.
  tbb::parallel_for(tbb::blocked_range<size_t>(0, transfer.size(), 1), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t k = r.begin(); k < r.end(); ++k)
      readProbes(path, *transfer[k], grid.coord, [&](size_t p, const vdb::Vec3s& v) {
        float* dst = grid.transfer.data() + p * stride + k * 3;
        dst[0] = v[0];
        dst[1] = v[1];
        dst[2] = v[2];
      });
  });
  for (const vdb::FloatGrid::Ptr& g : direct) checkLike(path, *g, *validity);
  const size_t dstride = grid.directStride();
  grid.direct.resize(direct.empty() ? 0 : count * dstride);
  tbb::parallel_for(tbb::blocked_range<size_t>(0, direct.size(), 1), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t k = r.begin(); k < r.end(); ++k)
      readProbes(path, *direct[k], grid.coord, [&](size_t p, float v) { grid.direct[p * dstride + k] = v; });
  });

  grid.buildIndex();
  return grid;
}

std::string vec3Text(const glm::dvec3& v) { return cat("(", v.x, ", ", v.y, ", ", v.z, ")"); }

// OpenVDB stamps every file it writes with a random UUID (36 ASCII characters after the
// 21-byte header start: magic, file version, library version, grid-offsets flag), so two
// writes of the same grids differ. Readers only compare UUIDs to tell files apart, so one
// derived from the rest of the file serves as well and makes the bytes a function of the
// grids alone (the same seed gives the same file, whatever the thread count).
constexpr size_t kUuidOffset = 21, kUuidLength = 36;

void stampContentUuid(const std::string& tempPath, const std::string& path) {
  std::fstream f(tempPath, std::ios::in | std::ios::out | std::ios::binary);
  // Hashed in pieces: a grid of a few GB must not be held in memory twice over.
  std::vector<char> buf(size_t(1) << 20);
  f.read(buf.data(), std::streamsize(kUuidOffset + kUuidLength));
  auto isUuid = [&] {
    if (!f || f.gcount() != std::streamsize(kUuidOffset + kUuidLength)) return false;
    for (size_t i = 0; i < kUuidLength; ++i) {
      const char c = buf[kUuidOffset + i];
      const bool dash = i == 8 || i == 13 || i == 18 || i == 23;
      const bool hex = (c >= '0' && c <= '9') || (c >= 'a' && c <= 'f') || (c >= 'A' && c <= 'F');
      if (dash ? c != '-' : !hex) return false;
    }
    return true;
  };
  if (!isUuid()) throw Error(cat(path, ": cannot write VDB file (unexpected header layout)"));
  // Two FNV-1a 64-bit hashes (different offset bases) of everything but the UUID.
  uint64_t h[2] = {0xcbf29ce484222325ull, 0x84222325cbf29ce4ull};
  auto hash = [&](const char* p, size_t n) {
    for (size_t i = 0; i < n; ++i)
      for (uint64_t& x : h) x = (x ^ static_cast<unsigned char>(p[i])) * 0x100000001b3ull;
  };
  hash(buf.data(), kUuidOffset);
  while (f.read(buf.data(), std::streamsize(buf.size())) || f.gcount() > 0) hash(buf.data(), size_t(f.gcount()));
  if (f.bad()) throw Error(cat(path, ": cannot write VDB file (reading it back failed)"));
  char uuid[kUuidLength + 1];
  std::snprintf(uuid, sizeof uuid, "%08x-%04x-%04x-%04x-%012llx", unsigned(h[0] >> 32), unsigned(h[0] >> 16 & 0xffff),
                unsigned(h[0] & 0xffff), unsigned(h[1] >> 48), static_cast<unsigned long long>(h[1] & 0xffffffffffffull));
  f.clear();
  f.seekp(std::streamoff(kUuidOffset));
  f.write(uuid, std::streamsize(kUuidLength));
  if (!f.flush()) throw Error(cat(path, ": cannot write VDB file"));
}

}  // namespace

void writeProbeGrid(const ProbeGrid& grid, const std::string& path, bool half) {
  const size_t count = grid.probeCount();
  PRT_CHECK(grid.bands >= 1 && grid.bands <= sh::kMaxBands);
  PRT_CHECK(grid.dims.x >= 1 && grid.dims.y >= 1 && grid.dims.z >= 1);
  PRT_CHECK(grid.spacing.x > 0.0 && grid.spacing.y > 0.0 && grid.spacing.z > 0.0);
  PRT_CHECK_EQ(grid.transfer.size(), count * grid.transferStride());
  // Without a direct part (a grid made by hand, or read from version 2) the file is version 2.
  PRT_CHECK(grid.direct.empty() || grid.direct.size() == count * grid.directStride());
  PRT_CHECK_EQ(grid.validity.size(), count);
  PRT_CHECK_EQ(grid.offset.size(), count);
  PRT_CHECK_EQ(grid.skyVisibility.size(), count);
  PRT_CHECK_EQ(grid.moments.size(), count);
  for (const glm::ivec3& c : grid.coord)
    PRT_CHECK(c.x >= 0 && c.y >= 0 && c.z >= 0 && c.x < grid.dims.x && c.y < grid.dims.y &&
              c.z < grid.dims.z);
  initOpenVdb();

  const vdb::math::Transform::Ptr xform = makeTransform(grid.origin, grid.spacing);
  const int n2 = grid.coeffs();
  const size_t stride = grid.transferStride();
  auto at = [&](size_t p) { return vdb::Coord(grid.coord[p].x, grid.coord[p].y, grid.coord[p].z); };

  // Every grid gets a value at every active probe (setValue activates it even when it equals
  // the background), so all grids share the validity grid's active topology.
  std::vector<vdb::Vec3SGrid::Ptr> transfer(size_t(n2) * size_t(n2));
  tbb::parallel_for(
      tbb::blocked_range<size_t>(0, transfer.size(), 1), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t k = r.begin(); k < r.end(); ++k) {
          const int j = int(k) / n2, i = int(k) % n2;
          auto g = makeGrid<vdb::Vec3SGrid>(
              transferName(j, i), xform,
              cat("RGB transfer M_ji, j = ", j, ", i = ", i, ": incident radiance SH c_j = sum_i M_ji l_i"),
              half);
          g->setVectorType(vdb::VEC_INVARIANT);  // colours: not turned by the transform
          auto acc = g->getAccessor();
          for (size_t p = 0; p < count; ++p) {
            const float* m = grid.transfer.data() + p * stride + k * 3;
            acc.setValue(at(p), vdb::Vec3s(m[0], m[1], m[2]));
          }
          transfer[k] = g;
        }
      });
  const size_t dstride = grid.directStride();
  std::vector<vdb::FloatGrid::Ptr> direct(grid.hasDirect() ? dstride : 0);
  tbb::parallel_for(tbb::blocked_range<size_t>(0, direct.size(), 1), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t k = r.begin(); k < r.end(); ++k) {
      int j = 0, first = 0;  // k is (j, i) of the upper triangle, row by row
      while (first + (n2 - j) <= int(k)) first += n2 - j++;
      const int i = j + (int(k) - first);
      auto g = makeGrid<vdb::FloatGrid>(
          directName(j, i), xform,
          cat("direct part M0_ji = M0_ij, j = ", j, ", i = ", i, ": bounce-0 transfer (first-hit visibility), colourless"),
          half);
      auto acc = g->getAccessor();
      for (size_t p = 0; p < count; ++p) acc.setValue(at(p), grid.direct[p * dstride + k]);
      direct[k] = g;
    }
  });

  auto validity = makeGrid<vdb::FloatGrid>("validity", xform,
                                           "1 = valid probe, 0 = inside geometry (never interpolated)", half);
  auto sky = makeGrid<vdb::FloatGrid>("sky_visibility", xform,
                                      "fraction of directions that escape to the sky (preview)", half);
  // Fog volume: values in [0, 1], 0 outside, which viewers (Blender, vdb_render) show as density.
  sky->setGridClass(vdb::GRID_FOG_VOLUME);
  auto irradiance = makeGrid<vdb::Vec3SGrid>(
      "irradiance_preview", xform,
      "RGB irradiance at a +Y normal under a uniform sky of radiance 1 (preview)", half);
  irradiance->setVectorType(vdb::VEC_INVARIANT);
  // Offsets and moments stay 32-bit even with `half`: σ² = E[d²] − E[d]² cancels
  // catastrophically with 11-bit mantissas, and offsets are positions. They are 15 of the
  // 3n⁴ + 20 floats of a probe.
  auto offset =
      makeGrid<vdb::Vec3SGrid>("offset", xform, "world offset of the probe from its lattice point", false);
  offset->setVectorType(vdb::VEC_CONTRAVARIANT_RELATIVE);  // a displacement
  offset->setIsInWorldSpace(true);
  std::vector<vdb::Vec3SGrid::Ptr> moments;
  for (const MomentGrid& mg : kMomentGrids) {
    auto g = makeGrid<vdb::Vec3SGrid>(mg.name, xform, cat(mg.description, " (world units)"), false);
    g->setVectorType(vdb::VEC_INVARIANT);  // three scalars per voxel, not a vector
    moments.push_back(g);
  }

  // Irradiance preview, derived from the transfer: a uniform sky of radiance 1 has only
  // l_0 = 2√π, so c_j = M_j0 · 2√π, and E(+Y) = Σ_j Â_l(j) c_j y_j(+Y).
  std::vector<float> yUp(static_cast<size_t>(n2));
  sh::evaluate(grid.bands, glm::vec3(0.0f, 1.0f, 0.0f), yUp.data());
  std::vector<float> upFactor(static_cast<size_t>(n2));
  for (int j = 0; j < n2; ++j)
    upFactor[size_t(j)] =
        float(sh::clampedCosineFactor(sh::bandOf(j)) * 2.0 * std::sqrt(kPi)) * yUp[size_t(j)];

  {
    auto va = validity->getAccessor();
    auto sa = sky->getAccessor();
    auto ia = irradiance->getAccessor();
    auto oa = offset->getAccessor();
    for (size_t p = 0; p < count; ++p) {
      const vdb::Coord c = at(p);
      va.setValue(c, grid.validity[p]);
      sa.setValue(c, grid.skyVisibility[p]);
      oa.setValue(c, toVdb(grid.offset[p]));
      glm::vec3 e(0.0f);
      for (int j = 0; j < n2; ++j) {
        const float* m = grid.transfer.data() + p * stride + size_t(j) * n2 * 3;  // M_j0
        e += upFactor[size_t(j)] * glm::vec3(m[0], m[1], m[2]);
      }
      ia.setValue(c, toVdb(e));
      for (size_t k = 0; k < moments.size(); ++k) {
        const MomentGrid& mg = kMomentGrids[k];
        vdb::Vec3s v;
        for (int axis = 0; axis < 3; ++axis)
          v[axis] = grid.moments[p][size_t(2 * axis + mg.sign)][mg.component];
        moments[k]->tree().setValue(c, v);
      }
    }
  }

  PRT_CHECK_EQ(validity->activeVoxelCount(), vdb::Index64(count));  // no duplicate coordinates

  vdb::GridPtrVec grids(transfer.begin(), transfer.end());
  grids.insert(grids.end(), direct.begin(), direct.end());
  grids.push_back(validity);
  grids.push_back(offset);
  grids.push_back(sky);
  grids.push_back(irradiance);
  grids.insert(grids.end(), moments.begin(), moments.end());

  vdb::MetaMap meta;
  meta.insertMeta("prt_format_version", vdb::Int32Metadata(grid.hasDirect() ? kFormatVersion : 2));
  meta.insertMeta("bands", vdb::Int32Metadata(grid.bands));
  meta.insertMeta("sh_convention", vdb::StringMetadata(kShConvention));
  meta.insertMeta("units", vdb::StringMetadata(kUnits));
  meta.insertMeta("bounces", vdb::Int32Metadata(grid.info.bounces));
  meta.insertMeta("samples", vdb::Int32Metadata(grid.info.samples));
  // A string: the seed is a uint64 and metadata has no unsigned 64-bit type.
  meta.insertMeta("seed", vdb::StringMetadata(std::to_string(grid.info.seed)));
  meta.insertMeta("scene", vdb::StringMetadata(grid.info.scene));
  if (!grid.info.region.empty()) meta.insertMeta("probe_region", vdb::StringMetadata(grid.info.region));
  meta.insertMeta("dims", vdb::Vec3IMetadata(vdb::Vec3i(grid.dims.x, grid.dims.y, grid.dims.z)));
  meta.insertMeta("origin", vdb::Vec3DMetadata(vdb::Vec3d(grid.origin.x, grid.origin.y, grid.origin.z)));
  meta.insertMeta("spacing", vdb::Vec3DMetadata(vdb::Vec3d(grid.spacing.x, grid.spacing.y, grid.spacing.z)));
  meta.insertMeta("grid_layout", vdb::StringMetadata(kLayout));
  meta.insertMeta("creator", vdb::StringMetadata("prt"));

  AtomicFile out(path);
  try {
    vdb::io::File file(out.tempPath());
    // Blosc: about as small as ZIP for this data and ~8x faster to write (platform notes).
    file.setCompression(
        vdb::io::COMPRESS_ACTIVE_MASK |
        (vdb::io::Archive::hasBloscCompression() ? vdb::io::COMPRESS_BLOSC : vdb::io::COMPRESS_ZIP));
    file.write(grids, meta);
    file.close();
  } catch (const std::exception& e) {
    throw Error(cat(path, ": cannot write VDB file (", e.what(), ")"));
  }
  stampContentUuid(out.tempPath(), path);
  out.commit();
}

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
    if (name.rfind("transfer_", 0) == 0) {
      if (firstTransfer.empty()) firstTransfer = name;
      lastTransfer = name;
      ++transferGrids;
    } else if (name.rfind("direct_", 0) == 0) {
      ++directGrids;
    } else {
      others.push_back(cat(name, " (", g->valueType() == "vec3s" ? "Vec3f" : g->valueType(), ")"));
    }
  }

  std::ostringstream os;
  os << path << "\n";
  os << "  format        prt probe grid v" << (grid.hasDirect() ? kFormatVersion : 2) << " (OpenVDB, "
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
    os << ", direct_00_00 .. " << directName(grid.coeffs() - 1, grid.coeffs() - 1) << " (" << directGrids
       << " float grids: the direct part)";
  else
    os << ", no direct part (baked before prt kept it apart: suns are lit through the whole transfer)";
  for (const std::string& o : others) os << ", " << o;
  os << "\n";
  // What prt holds once read: the parallel arrays plus the dense index of find().
  const uintmax_t arrays =
      grid.probeCount() * (sizeof(glm::ivec3) + (grid.transferStride() + grid.direct.size() / std::max<size_t>(grid.probeCount(), 1)) * sizeof(float) + sizeof(float) * 2 +
                           sizeof(glm::vec3) + sizeof(grid.moments[0])) +
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
           : grid.info.region == "near"       ? "near: near surfaces or surrounded by them (open air far from all not baked)"
                                              : grid.info.region)
       << "\n";
  return os.str();
}

}  // namespace prt
