// The probe grid's .vdb format in one place: its versions, its grid names and its metadata keys
// ({key, type, field}), which the writer (probe_grid_vdb_write.cpp), the reader and
// describeProbeFile (probe_grid_vdb.cpp) all go through, as bake_record.cpp keeps the .glb's
// record. The layout is described in docs/probes.md. No OpenVDB here: the two .cpp files map
// the types below to OpenVDB's standard metadata (int32, string, vec3i, vec3d), which every VDB
// tool reads.
#pragma once

#include <cstdint>
#include <cstdio>
#include <limits>
#include <string>
#include <type_traits>
#include <variant>

#include <glm/glm.hpp>

#include "prt/probe_grid.h"
#include "prt/sh.h"

namespace prt::probe_file {

// 2: the moment grids hold depths along the face's axis. Version 1 held ray lengths, which the
// interpolation of version 2 would misread (it would let light through walls), so 1 is refused.
// 3: adds the direct part M⁰ (direct_JJ_II, j <= i). Version 2 files are read, without it.
constexpr int kFormatVersion = 3;
constexpr int kVersionWithoutDirect = 2;
constexpr int kVersionWithRayLengths = 1;

/// The version a grid is written as: without a direct part (a grid made by hand, or read from
/// version 2) the file is version 2.
inline int formatVersion(const ProbeGrid& grid) { return grid.hasDirect() ? kFormatVersion : kVersionWithoutDirect; }

// ---------------------------------------------------------------------------------------------
// Grids

constexpr const char* kTransferPrefix = "transfer_";
constexpr const char* kDirectPrefix = "direct_";
constexpr const char* kValidityGrid = "validity";
constexpr const char* kOffsetGrid = "offset";
constexpr const char* kSkyGrid = "sky_visibility";
constexpr const char* kIrradianceGrid = "irradiance_preview";

/// transfer_JJ_II: the RGB of M_ji.
inline std::string transferName(int j, int i) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%s%02d_%02d", kTransferPrefix, j, i);
  return buf;
}

/// direct_JJ_II, j <= i: M⁰_ji.
inline std::string directName(int j, int i) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%s%02d_%02d", kDirectPrefix, j, i);
  return buf;
}

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

// ---------------------------------------------------------------------------------------------
// Metadata

constexpr const char* kShConvention =
    "real orthonormal SH, index l(l+1)+m, no Condon-Shortley phase, polar axis +Z, "
    "glTF frame (+Y up, right-handed), directions point towards the light";
constexpr const char* kUnits = "incident radiance SH = transfer · light SH; radiance";
constexpr const char* kLayout =
    "transfer_JJ_II vec3s: RGB of M_ji (c_j = sum_i M_ji l_i); direct_JJ_II float, JJ <= II: M0_ji = M0_ij, "
    "the direct (bounce 0, first-hit visibility) part of M, colourless and symmetric; validity float (1 valid, 0 "
    "inside "
    "geometry); offset vec3s: world offset of the probe from its lattice point; sky_visibility "
    "float; irradiance_preview vec3s: irradiance at a +Y normal under a uniform sky of radiance "
    "1; moments_mean_pos/neg vec3s: for the rays of the +X,+Y,+Z / -X,-Y,-Z cube faces, mean "
    "depth of the first hit along the face's axis (|t*dir_axis|, misses 2*max spacing); "
    "moments_sq_pos/neg vec3s: mean squared depth; index (i,j,k) is at world "
    "origin + spacing*(i,j,k)";

/// The type a key is stored as: OpenVDB's int32 (the reader also takes int64), string, vec3i
/// and vec3d metadata.
enum class MetaType { Int32, Text, Vec3i, Vec3d };

/// How a key is written and read.
enum class MetaUse {
  Required,        // always written; a file without it is refused
  Optional,        // always written; older files may lack it
  OmittedIfEmpty,  // written when its text is not empty; read if present
  Fixed,           // a constant text for other tools: written, never read
};

/// The format version: formatVersion() written, checked first when read.
struct FormatVersion {};

/// Where a key's value lives: a field of ProbeGrid or of its ProbeGridInfo, the format version,
/// or (Fixed keys) the text itself. The seed, a uint64, is stored as decimal text: metadata
/// has no unsigned 64-bit type.
using Field =
    std::variant<FormatVersion, const char*, int ProbeGrid::*, glm::ivec3 ProbeGrid::*, glm::dvec3 ProbeGrid::*,
                 int ProbeGridInfo::*, uint64_t ProbeGridInfo::*, std::string ProbeGridInfo::*>;

struct MetaKey {
  const char* key;
  MetaType type;
  Field field;
  MetaUse use;
  int64_t lo = std::numeric_limits<int64_t>::min();  // Int32 keys: the values read
  int64_t hi = std::numeric_limits<int64_t>::max();
};

/// Every metadata key of a probe file, in the order the reader takes them: the version, the
/// lattice, then what describes the bake.
constexpr MetaKey kMetaKeys[] = {
    {"prt_format_version", MetaType::Int32, FormatVersion{}, MetaUse::Required},
    {"bands", MetaType::Int32, &ProbeGrid::bands, MetaUse::Required, 1, sh::kMaxBands},
    {"dims", MetaType::Vec3i, &ProbeGrid::dims, MetaUse::Required},
    {"origin", MetaType::Vec3d, &ProbeGrid::origin, MetaUse::Required},
    {"spacing", MetaType::Vec3d, &ProbeGrid::spacing, MetaUse::Required},
    {"bounces", MetaType::Int32, &ProbeGridInfo::bounces, MetaUse::Optional},
    {"samples", MetaType::Int32, &ProbeGridInfo::samples, MetaUse::Optional},
    {"scene", MetaType::Text, &ProbeGridInfo::scene, MetaUse::Optional},
    {"probe_region", MetaType::Text, &ProbeGridInfo::region, MetaUse::OmittedIfEmpty},
    {"seed", MetaType::Text, &ProbeGridInfo::seed, MetaUse::Optional},
    {"sh_convention", MetaType::Text, kShConvention, MetaUse::Fixed},
    {"units", MetaType::Text, kUnits, MetaUse::Fixed},
    {"grid_layout", MetaType::Text, kLayout, MetaUse::Fixed},
    {"creator", MetaType::Text, "prt", MetaUse::Fixed},
};

/// The key of the format version (the table's first).
constexpr const char* kVersionKey = kMetaKeys[0].key;

/// The type of the value a Field alternative holds: the member's type, or the alternative itself.
template <class F>
struct FieldValue {
  using type = F;
};
template <class C, class T>
struct FieldValue<T C::*> {
  using type = T;
};

/// The type a value of C++ type V is stored as.
template <class V>
constexpr MetaType storedAs() {
  if constexpr (std::is_same_v<V, int> || std::is_same_v<V, FormatVersion>)
    return MetaType::Int32;
  else if constexpr (std::is_same_v<V, glm::ivec3>)
    return MetaType::Vec3i;
  else if constexpr (std::is_same_v<V, glm::dvec3>)
    return MetaType::Vec3d;
  else
    return MetaType::Text;  // std::string, uint64_t (decimal), const char*
}

constexpr bool typesMatchFields() {
  for (const MetaKey& k : kMetaKeys)
    if (std::visit([](auto f) { return storedAs<typename FieldValue<decltype(f)>::type>(); }, k.field) != k.type)
      return false;
  return true;
}
static_assert(typesMatchFields(), "kMetaKeys: a key's type is not the one its field is stored as");

/// Calls f with `key`'s value in `grid`: a reference to its field (int, glm::ivec3, glm::dvec3,
/// uint64_t or std::string; const where `grid` is), the text of a Fixed key, or FormatVersion{}.
template <class Grid, class F>
void withField(Grid& grid, const MetaKey& key, F&& f) {
  std::visit(
      [&](auto field) {
        using M = decltype(field);
        if constexpr (std::is_same_v<M, FormatVersion> || std::is_same_v<M, const char*>)
          f(field);
        else if constexpr (std::is_invocable_v<M, Grid&>)
          f(grid.*field);  // a member of ProbeGrid
        else
          f(grid.info.*field);
      },
      key.field);
}

/// Initialises OpenVDB once (its registries of types and maps); defined in probe_grid_vdb.cpp.
void initOpenVdb();

}  // namespace prt::probe_file
