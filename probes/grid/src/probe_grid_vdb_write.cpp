// Writing the probe grid as an OpenVDB file (writeProbeGrid). One of the two translation units
// of prt that include OpenVDB (its headers cost ~30 s to compile); the reader is
// probe_grid_vdb.cpp and the format (versions, grid names, metadata keys) probe_file.h. Only
// standard grid types (float, vec3s) and standard metadata, so vdb_print, vdb_view, pyopenvdb,
// Houdini and Blender read the file as it is. Layout: docs/probes.md.
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <string>
#include <type_traits>
#include <vector>

#include <openvdb/openvdb.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "probe_file.h"
#include "prt/atomic_file.h"
#include "prt/error.h"
#include "prt/math.h"
#include "prt/probe_grid.h"

namespace prt {

namespace {

namespace vdb = openvdb;
using namespace probe_file;

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
                unsigned(h[0] & 0xffff), unsigned(h[1] >> 48),
                static_cast<unsigned long long>(h[1] & 0xffffffffffffull));
  f.clear();
  f.seekp(std::streamoff(kUuidOffset));
  f.write(uuid, std::streamsize(kUuidLength));
  if (!f.flush()) throw Error(cat(path, ": cannot write VDB file"));
}

vdb::Coord coordOf(const ProbeGrid& grid, size_t p) {
  return vdb::Coord(grid.coord[p].x, grid.coord[p].y, grid.coord[p].z);
}

void checkWritable(const ProbeGrid& grid) {
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
    PRT_CHECK(c.x >= 0 && c.y >= 0 && c.z >= 0 && c.x < grid.dims.x && c.y < grid.dims.y && c.z < grid.dims.z);
}

// Every grid gets a value at every active probe (setValue activates it even when it equals
// the background), so all grids share the validity grid's active topology.

// The n⁴ RGB transfer grids, (j, i) row by row, one per task.
std::vector<vdb::Vec3SGrid::Ptr> makeTransferGrids(const ProbeGrid& grid, const vdb::math::Transform::Ptr& xform,
                                                   bool half) {
  const int n2 = grid.coeffs();
  const size_t stride = grid.transferStride();
  std::vector<vdb::Vec3SGrid::Ptr> transfer(size_t(n2) * size_t(n2));
  tbb::parallel_for(tbb::blocked_range<size_t>(0, transfer.size(), 1), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t k = r.begin(); k < r.end(); ++k) {
      const int j = int(k) / n2, i = int(k) % n2;
      auto g = makeGrid<vdb::Vec3SGrid>(
          transferName(j, i), xform,
          cat("RGB transfer M_ji, j = ", j, ", i = ", i, ": incident radiance SH c_j = sum_i M_ji l_i"), half);
      g->setVectorType(vdb::VEC_INVARIANT);  // colours: not turned by the transform
      auto acc = g->getAccessor();
      for (size_t p = 0; p < grid.probeCount(); ++p) {
        const float* m = grid.transfer.data() + p * stride + k * 3;
        acc.setValue(coordOf(grid, p), vdb::Vec3s(m[0], m[1], m[2]));
      }
      transfer[k] = g;
    }
  });
  return transfer;
}

// The direct part's grids (the upper triangle j <= i, row by row), one per task; none without it.
std::vector<vdb::FloatGrid::Ptr> makeDirectGrids(const ProbeGrid& grid, const vdb::math::Transform::Ptr& xform,
                                                 bool half) {
  const int n2 = grid.coeffs();
  const size_t dstride = grid.directStride();
  std::vector<vdb::FloatGrid::Ptr> direct(grid.hasDirect() ? dstride : 0);
  tbb::parallel_for(tbb::blocked_range<size_t>(0, direct.size(), 1), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t k = r.begin(); k < r.end(); ++k) {
      int j = 0, first = 0;  // k is (j, i) of the upper triangle, row by row
      while (first + (n2 - j) <= int(k)) first += n2 - j++;
      const int i = j + (int(k) - first);
      auto g = makeGrid<vdb::FloatGrid>(directName(j, i), xform,
                                        cat("direct part M0_ji = M0_ij, j = ", j, ", i = ", i,
                                            ": bounce-0 transfer (first-hit visibility), colourless"),
                                        half);
      auto acc = g->getAccessor();
      for (size_t p = 0; p < grid.probeCount(); ++p) acc.setValue(coordOf(grid, p), grid.direct[p * dstride + k]);
      direct[k] = g;
    }
  });
  return direct;
}

// The grids of one value per probe.
struct ProbeGrids {
  vdb::FloatGrid::Ptr validity, sky;
  vdb::Vec3SGrid::Ptr irradiance, offset;
  std::vector<vdb::Vec3SGrid::Ptr> moments;  // as kMomentGrids
};

ProbeGrids makeProbeGrids(const vdb::math::Transform::Ptr& xform, bool half) {
  ProbeGrids out;
  out.validity =
      makeGrid<vdb::FloatGrid>(kValidityGrid, xform, "1 = valid probe, 0 = inside geometry (never interpolated)", half);
  out.sky = makeGrid<vdb::FloatGrid>(kSkyGrid, xform, "fraction of directions that escape to the sky (preview)", half);
  // Fog volume: values in [0, 1], 0 outside, which viewers (Blender, vdb_render) show as density.
  out.sky->setGridClass(vdb::GRID_FOG_VOLUME);
  out.irradiance = makeGrid<vdb::Vec3SGrid>(
      kIrradianceGrid, xform, "RGB irradiance at a +Y normal under a uniform sky of radiance 1 (preview)", half);
  out.irradiance->setVectorType(vdb::VEC_INVARIANT);
  // Offsets and moments stay 32-bit even with `half`: σ² = E[d²] − E[d]² cancels
  // catastrophically with 11-bit mantissas, and offsets are positions. They are 15 of the
  // 3n⁴ + 20 floats of a probe.
  out.offset = makeGrid<vdb::Vec3SGrid>(kOffsetGrid, xform, "world offset of the probe from its lattice point", false);
  out.offset->setVectorType(vdb::VEC_CONTRAVARIANT_RELATIVE);  // a displacement
  out.offset->setIsInWorldSpace(true);
  for (const MomentGrid& mg : kMomentGrids) {
    auto g = makeGrid<vdb::Vec3SGrid>(mg.name, xform, cat(mg.description, " (world units)"), false);
    g->setVectorType(vdb::VEC_INVARIANT);  // three scalars per voxel, not a vector
    out.moments.push_back(g);
  }
  return out;
}

// Irradiance preview, derived from the transfer: a uniform sky of radiance 1 has only
// l_0 = 2√π, so c_j = M_j0 · 2√π, and E(+Y) = Σ_j Â_l(j) c_j y_j(+Y). Returns the factors
// Â_l(j) · 2√π · y_j(+Y) of M_j0.
std::vector<float> irradianceFactors(int bands) {
  const int n2 = bands * bands;
  std::vector<float> yUp(static_cast<size_t>(n2));
  sh::evaluate(bands, glm::vec3(0.0f, 1.0f, 0.0f), yUp.data());
  std::vector<float> upFactor(static_cast<size_t>(n2));
  for (int j = 0; j < n2; ++j)
    upFactor[size_t(j)] = float(sh::clampedCosineFactor(sh::bandOf(j)) * 2.0 * std::sqrt(kPi)) * yUp[size_t(j)];
  return upFactor;
}

void fillProbeGrids(const ProbeGrid& grid, ProbeGrids& out) {
  const int n2 = grid.coeffs();
  const size_t stride = grid.transferStride();
  const std::vector<float> upFactor = irradianceFactors(grid.bands);
  auto va = out.validity->getAccessor();
  auto sa = out.sky->getAccessor();
  auto ia = out.irradiance->getAccessor();
  auto oa = out.offset->getAccessor();
  for (size_t p = 0; p < grid.probeCount(); ++p) {
    const vdb::Coord c = coordOf(grid, p);
    va.setValue(c, grid.validity[p]);
    sa.setValue(c, grid.skyVisibility[p]);
    oa.setValue(c, toVdb(grid.offset[p]));
    glm::vec3 e(0.0f);
    for (int j = 0; j < n2; ++j) {
      const float* m = grid.transfer.data() + p * stride + size_t(j) * n2 * 3;  // M_j0
      e += upFactor[size_t(j)] * glm::vec3(m[0], m[1], m[2]);
    }
    ia.setValue(c, toVdb(e));
    for (size_t k = 0; k < out.moments.size(); ++k) {
      const MomentGrid& mg = kMomentGrids[k];
      vdb::Vec3s v;
      for (int axis = 0; axis < 3; ++axis) v[axis] = grid.moments[p][size_t(2 * axis + mg.sign)][mg.component];
      out.moments[k]->tree().setValue(c, v);
    }
  }
}

// The file's metadata, from kMetaKeys (probe_file.h).
vdb::MetaMap metadataOf(const ProbeGrid& grid) {
  vdb::MetaMap meta;
  for (const MetaKey& k : kMetaKeys)
    withField(grid, k, [&](const auto& v) {
      using V = std::decay_t<decltype(v)>;
      if constexpr (std::is_same_v<V, FormatVersion>) {
        meta.insertMeta(k.key, vdb::Int32Metadata(formatVersion(grid)));
      } else if constexpr (std::is_same_v<V, int>) {
        meta.insertMeta(k.key, vdb::Int32Metadata(v));
      } else if constexpr (std::is_same_v<V, glm::ivec3>) {
        meta.insertMeta(k.key, vdb::Vec3IMetadata(vdb::Vec3i(v.x, v.y, v.z)));
      } else if constexpr (std::is_same_v<V, glm::dvec3>) {
        meta.insertMeta(k.key, vdb::Vec3DMetadata(vdb::Vec3d(v.x, v.y, v.z)));
      } else if constexpr (std::is_same_v<V, uint64_t>) {
        meta.insertMeta(k.key, vdb::StringMetadata(std::to_string(v)));
      } else if constexpr (std::is_same_v<V, std::string>) {
        if (!(k.use == MetaUse::OmittedIfEmpty && v.empty())) meta.insertMeta(k.key, vdb::StringMetadata(v));
      } else {  // the text of a Fixed key
        meta.insertMeta(k.key, vdb::StringMetadata(v));
      }
    });
  return meta;
}

// Writes the grids to a temporary file, stamps it and moves it to `path`.
void writeFile(const vdb::GridPtrVec& grids, const vdb::MetaMap& meta, const std::string& path) {
  AtomicFile out(path);
  try {
    vdb::io::File file(out.tempPath());
    // Blosc: about as small as ZIP for this data and ~8x faster to write (platform notes).
    file.setCompression(vdb::io::COMPRESS_ACTIVE_MASK |
                        (vdb::io::Archive::hasBloscCompression() ? vdb::io::COMPRESS_BLOSC : vdb::io::COMPRESS_ZIP));
    file.write(grids, meta);
    file.close();
  } catch (const std::exception& e) {
    throw Error(cat(path, ": cannot write VDB file (", e.what(), ")"));
  }
  stampContentUuid(out.tempPath(), path);
  out.commit();
}

}  // namespace

void writeProbeGrid(const ProbeGrid& grid, const std::string& path, bool half) {
  checkWritable(grid);
  probe_file::initOpenVdb();
  const vdb::math::Transform::Ptr xform = makeTransform(grid.origin, grid.spacing);
  const std::vector<vdb::Vec3SGrid::Ptr> transfer = makeTransferGrids(grid, xform, half);
  const std::vector<vdb::FloatGrid::Ptr> direct = makeDirectGrids(grid, xform, half);
  ProbeGrids perProbe = makeProbeGrids(xform, half);
  fillProbeGrids(grid, perProbe);
  PRT_CHECK_EQ(perProbe.validity->activeVoxelCount(), vdb::Index64(grid.probeCount()));  // no duplicate coordinates

  vdb::GridPtrVec grids(transfer.begin(), transfer.end());
  grids.insert(grids.end(), direct.begin(), direct.end());
  grids.push_back(perProbe.validity);
  grids.push_back(perProbe.offset);
  grids.push_back(perProbe.sky);
  grids.push_back(perProbe.irradiance);
  grids.insert(grids.end(), perProbe.moments.begin(), perProbe.moments.end());
  writeFile(grids, metadataOf(grid), path);
}

}  // namespace prt
