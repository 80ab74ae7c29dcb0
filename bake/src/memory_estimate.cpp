// Peak memory of `prt bake`, phase by phase (sizes in bytes; V vertices, T triangles of the
// baked instances, the back sides of double-sided ones counted as vertices too, n2 = bands²,
// N samples, B = V·n2·12 one transfer buffer, D = B/3 its colourless direct part):
//
//   surface  scene + layout + BVH + hit records + 2B (t^{k-1} overwritten by t^k, running sum) + D
//            + the bounces' gather tables (t^{k-1} as halves, 3·n2 padded to 64-byte lines
//            a vertex, and 16 bytes of corners per triangle) + the bounce operator's kept rays'
//            escape and record bits (2 bits a kept ray)
//            (+ B for the lower-order sum when probes follow; the BVH then stays for them, so
//            the per-instance copies of the sums after the last bounce count it too)
//   probes   scene + 2B (transfer and lower-order sum) + the lower-order sum as halves (the lit
//            hits' rows, 3·n2 padded to 64-byte lines a vertex), then the largest of
//              trace     BVH + per lattice point a slot and its n2²·3 floats + per thread the
//                        double accumulators + the checkpoint's save/read buffers
//              assemble  slots and lattice transfer + the grid (its transfer copied out of
//                        the lattice's, its attribute vectors, its dense index) + the list of
//                        active points
//              write     the grid + its OpenVDB copy (whole 8³ leaves) + OpenVDB's buffers +
//                        the written file read back whole for its content UUID
//   write    scene + B (transfer in the scene) [+ B lower-order sum] + the glTF writer: copies
//            of the input's buffers (reloaded, packed, serialised) and of the transfer (staging,
//            packed, serialised), as measured; with the bounce operator, its kept rays, its rows
//            and the writer's copies of its packed bytes
//
// Hit records: 8 bytes per front-face hit, bounded by share·V·N; the share comes from a pilot
// (surface_bake.cpp) or is 1. Embree's bytes per triangle were measured on this machine
// (Embree 3.13, high-quality build, robust flag): see kBvhBytesPerTriangle. Everything is
// rounded up and the sum gets kSlack on top, so the estimate is a bound, not a guess: the
// table in docs/bake.md compares it with measured peaks.
#include "prt/bake/memory_estimate.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <thread>

#include "prt/error.h"
#include "prt/progress.h"

namespace prt::bake {

namespace {

// Measured: `prt bake` of the 1089-vertex plane peaks at 84-94 MiB before any real work (code
// and data of the linked libraries, TBB and Embree threads, allocator arenas); rounded up.
constexpr uint64_t kBaseBytes = uint64_t(100) << 20;
// Measured with RayScene on 146k- and 582k-triangle scenes: Embree's vertex/index copies and
// BVH take 67-71 bytes per triangle once built and 99-103 at the peak of the build; rounded
// up for less regular meshes than those boxes.
constexpr uint64_t kBvhBytesPerTriangle = 128;
// The glTF writer (writeBakedScene: reloaded input, staging buffer, packed buffer, tinygltf's
// serialisation) measured at 4.7 transfer buffers and 2.5 input copies on top of the scene.
constexpr uint64_t kWriteTransferCopies = 5, kWriteInputCopies = 3;
// Layout tables of the surface bake: per vertex mesh id, origin and pull (4 + 12 + 12), per
// triangle three vertex ids and a mesh id (16).
constexpr uint64_t kLayoutPerVertex = 28, kLayoutPerTriangle = 16;
// One hit record, and the CSR offset per vertex.
constexpr uint64_t kHitBytes = 8, kHitOffsetBytes = 4;
// Probe bake (probe_bake.cpp): a 72-byte slot per lattice point, and per valid point its
// transfer (kept per chunk, as the checkpoint's chunk records hold them); per worker thread one
// set of accumulators (n2² doubles and n2² double RGB), a chunk's transfer being baked
// (kProbeChunk points) and the scratch of a group of 1024 rays
// (StreamRows: their SH values, n2 floats a ray; per lit hit its lists' 20 bytes and a 48-byte
// record, and for a colour looked up its index, instance, triangle, barycentrics and RGB, 32;
// g of a chunk of 64 hits); per active probe the grid's
// attributes: coordinate 12, validity 4, offset 12, moments 48, sky 4 (80), and a 4-byte
// dense index entry per lattice point; and ProbeStats::traced, 16 bytes per lattice point
// (reserved for all), from the end of the trace on.
constexpr uint64_t kProbeSlotBytes = 72, kProbeAttributeBytes = 80, kProbeIndexBytes = 4, kAllocOverhead = 32;
constexpr uint64_t kProbeTracedBytes = 16;
// The .vdb's grids: n2² Vec3s transfer grids, irradiance preview, offset and four moment grids
// (Vec3s), validity and sky visibility (float). An OpenVDB 10 tree (5-4-3) has one 32³ upper
// node (the lattice, at most 512 per axis from 0, lies within its 4096³ span), a 16³ lower
// node per 128³ block and a leaf of 8³ voxels per 8³ block, whole; a node entry is a union of
// a child pointer and a value (16 bytes for Vec3s, 8 for float). The upper node alone is
// 512 KiB per Vec3s grid: measured 0.49, 0.55, 0.58, 0.59 MiB per grid at bands 2-5 for a
// 2³ lattice (24 to 633 grids), whatever the lattice's size.
constexpr uint64_t kVdbVec3Grids = 6, kVdbFloatGrids = 2;
constexpr uint64_t kVdbUpperEntries = 32768, kVdbLowerEntries = 4096, kVdbLeafVoxels = 512;
constexpr uint64_t kVdbNodeOverhead = 8192, kVdbLeafOverhead = 256;
// The written .vdb is hashed for its UUID (probe_grid_vdb.cpp, stampContentUuid) in 1 MiB
// pieces while the grids are alive; the file's size no longer enters the peak.
constexpr uint64_t kVdbHashBuffer = uint64_t(1) << 20;
// The checkpoint's save buffer (checkpoint.cpp FdWriter) and its read buffer on resume.
constexpr uint64_t kCheckpointBuffers = uint64_t(5) << 20;
// Writing the .vdb besides the trees: OpenVDB's registries, Blosc and stream buffers.
constexpr uint64_t kVdbWriteBytes = uint64_t(8) << 20;
// Refinement (refine.cpp): a refined vertex in the scene (position, normal, texture
// coordinate, colour, two triangles' indices, its file blend: 12+12+8+16+24+24) and, while it
// runs, per vertex of the refined mesh: about 6 estimated points (the vertex, three edges'
// midpoints, two centroids: V + E + T ≈ 6V), each a normal, a score and one bit per direction;
// the edge and centroid maps, the per-round adjacency (two hash maps of small vectors per
// position edge) and candidate lists: about 1.5 KiB per vertex, counted from the node and
// vector sizes of libstdc++ and rounded up (zdm2, 116 k refined vertices: 243 MiB peak in all).
constexpr uint64_t kRefinedVertexBytes = 96, kRefinePointsPerVertex = 6, kRefineBytesPerVertex = 1536;
// The bounce operator (BakeSettings::keepGatherRays > 0), built after the bakes, then packed and
// copied by the glTF writer: per vertex side its cluster and gradient rows, tree, members and
// training (measured 88 bytes on the bundled room, 82 on pandora; 128 counted), per probe row
// entry a node, a weight and n2 − 1 shape bytes held (and n2 + 2 bytes packed, bits of the walk
// included), and the writer's copies of the packed bytes (4.6 measured with a 32³ grid's rows).
constexpr uint64_t kOperatorBytesPerSide = 128, kWriteOperatorCopies = 5;
// On top of the sum: allocator rounding, the hit records' scratch of each thread (surface_bake.cpp, at
// most 8 MiB a thread) and its bounces' colour lookups (VaryingColours, 128 KiB).
constexpr double kSlack = 1.10;

uint64_t sceneBytes(const Scene& scene) {
  uint64_t b = 0;
  for (const MeshInstance& m : scene.meshes)
    b += m.positions.capacity() * 12 + m.normals.capacity() * 12 + m.texcoords.capacity() * 8 +
         m.colors.capacity() * 16 + m.indices.capacity() * 4 + m.tangents.capacity() * 16 +
         m.moreTexcoords.size() * m.texcoords.capacity() * 8 +
         (m.transfer.capacity() + m.transferBack.capacity()) * 12 + 256;
  for (const Texture& t : scene.textures) b += t.texels.capacity() * 16 + t.texels8.capacity() * 4;
  return b;
}

// The glTF input as the loader and the writer read it: the buffers (the vertex data in the
// file's types, at most as large as the float copies) and images (encoded and RGBA8).
uint64_t gltfInputBytes(const Scene& scene) {
  uint64_t b = 0;
  for (const MeshInstance& m : scene.meshes)
    b += m.positions.size() * 12 + m.normals.size() * 12 + m.texcoords.size() * 8 + m.colors.size() * 16 +
         m.indices.size() * 4;
  for (const Texture& t : scene.textures) b += uint64_t(t.width) * t.height * 4 * 2;  // encoded + decoded
  return b;
}

std::string mib(uint64_t b) { return formatBytes(b); }

// One OpenVDB tree over the lattice (see kVdbUpperEntries): values of `valueBytes`, node
// entries of `entryBytes`, with `lower` 128³ nodes and `leaves` 8³ leaves.
uint64_t vdbTreeBytes(uint64_t valueBytes, uint64_t entryBytes, uint64_t lower, uint64_t leaves) {
  return kVdbUpperEntries * entryBytes + kVdbNodeOverhead + lower * (kVdbLowerEntries * entryBytes + kVdbNodeOverhead) +
         leaves * (kVdbLeafVoxels * valueBytes + kVdbLeafOverhead);
}

// The probe stage on top of the scene and the surface transfer: the largest of its trace,
// assembly and write. Without a measured placement every lattice point is counted as valid
// and active (the bound); with one, its baked points as valid and the points next to them as
// active, in the blocks they fill. Sets `lattice` to the bytes of the lattice's own results
// (slots and transfer).
// Also sets `latticePoints`, the points counted as valid (each gets a bounce operator row), and
// `gridOut`, the bytes of the assembled grid (which the operator's probe rows read after the
// probe stage).
uint64_t probeStagePeak(const Scene& scene, const ProbeSettings& p, uint64_t triangles, const ProbePlacement* placed,
                        uint64_t& lattice, uint64_t& latticePoints, uint64_t& gridOut) {
  ProbeGrid grid;
  glm::dvec3 lo, hi;
  probeBounds(p, scene, lo, hi);
  layoutGrid(p, lo, hi, grid);
  const glm::u64vec3 dims(grid.dims);
  const uint64_t points = dims.x * dims.y * dims.z;
  auto blocks = [&](uint64_t side) {
    return ((dims.x + side - 1) / side) * ((dims.y + side - 1) / side) * ((dims.z + side - 1) / side);
  };
  if (placed) PRT_CHECK_EQ(placed->points, points);  // measured for these settings
  const uint64_t valid = placed ? placed->baked : points, active = placed ? placed->activeBound : points;
  latticePoints = valid;  // the probes that get operator rows
  const uint64_t lower = placed ? placed->lowerBlocks : blocks(128), leaves = placed ? placed->leafBlocks : blocks(8);
  const uint64_t pn2 = uint64_t(p.bands) * p.bands;
  const uint64_t matrix = pn2 * pn2 * 12 + pn2 * (pn2 + 1) / 2 * 4;  // M and M⁰'s triangle
  const uint64_t threads = std::max(1u, p.threads > 0 ? unsigned(p.threads) : std::thread::hardware_concurrency());
  const uint64_t scratch = 1024 * (pn2 * 4 + 20 + 48 + 32) + 64 * ((3 * pn2 + 7) / 8 * 8) * 4;
  const uint64_t accum = pn2 * pn2 * (8 + 24) + scratch + kProbeChunk * matrix + 8 * kAllocOverhead;
  lattice = points * kProbeSlotBytes + valid * matrix;
  const uint64_t trace =
      triangles * kBvhBytesPerTriangle + lattice + threads * accum + kCheckpointBuffers + points * kProbeTracedBytes;
  // The assembly copies the valid points' transfer out of the chunks' into the grid's arrays,
  // each allocated once at its size, with a list of the active points (8 bytes each, up to
  // twice that while the list grows).
  const uint64_t gridBytes = active * (matrix + kProbeAttributeBytes) + points * kProbeIndexBytes;
  gridOut = gridBytes;
  const uint64_t assemble = lattice + gridBytes + active * 16 + points * kProbeTracedBytes;
  const uint64_t trees = (pn2 * pn2 + kVdbVec3Grids) * vdbTreeBytes(12, 16, lower, leaves) +
                         (kVdbFloatGrids + pn2 * (pn2 + 1) / 2) * vdbTreeBytes(4, 8, lower, leaves);
  const uint64_t write = gridBytes + trees + kVdbHashBuffer + kVdbWriteBytes;
  return std::max({trace, assemble, write});
}

}  // namespace

MemoryEstimate estimateBakeMemory(const Scene& scene, const BakeSettings& s, const ProbeSettings* probes,
                                  double frontHitShare, const ProbePlacement* placement) {
  MemoryEstimate e;
  if (probes && placement) e.placement = *placement;
  uint64_t vertices = 0, triangles = 0;
  uint64_t backVertices = 0, backTriangles = 0;  // the back sides of double-sided instances
  for (const MeshInstance& m : scene.meshes) {
    if (m.receiverOnly) continue;
    vertices += m.vertexCount();
    triangles += m.triangleCount();
    if (!bakesBackSide(scene, m)) continue;
    backVertices += m.vertexCount();
    backTriangles += m.triangleCount();
  }
  // A back side is a vertex of the bake like any other (its transfer, rays, hit records and
  // layout entries); the BVH holds each triangle once.
  vertices += backVertices;
  const uint64_t n2 = uint64_t(s.bands) * s.bands;
  const uint64_t original = vertices;
  vertices += s.refineVertices;
  triangles += 2 * s.refineVertices;
  e.base = kBaseBytes;
  e.scene = sceneBytes(scene) + s.refineVertices * kRefinedVertexBytes;
  e.transfer = vertices * n2 * 12;
  const bool shadowed = s.shadowed;
  const bool bounces = shadowed && s.bounces > 0;
  // A share that is not a number (no vertices to measure it on) counts as the worst case.
  e.frontHitShare = !bounces ? 0.0 : std::isfinite(frontHitShare) ? std::clamp(frontHitShare, 0.0, 1.0) : 1.0;
  e.bvh = shadowed ? triangles * kBvhBytesPerTriangle : 0;
  // With the bounces' gather tables too: the previous bounce as halves, 3·n2 padded to whole
  // 64-byte lines a vertex, and one 16-byte corner entry per triangle (surface_bake.cpp).
  const uint64_t gatherTables = vertices * ((3 * n2 + 31) / 32 * 64) + (triangles + backTriangles) * 16;
  // Hit records of `rays` rays a vertex, with their CSR offsets.
  auto records = [&](uint64_t rays) {
    return uint64_t(std::ceil(e.frontHitShare * double(vertices) * double(rays))) * kHitBytes +
           vertices * kHitOffsetBytes;
  };
  const uint64_t keptRays = uint64_t(std::clamp(s.keepGatherRays, 0, s.samples));
  const uint64_t keptBits = vertices * 2 * ((keptRays + 63) / 64) * 8;
  e.hits = bounces ? records(uint64_t(s.samples)) + gatherTables + keptBits : 0;
  const uint64_t layout = shadowed ? vertices * kLayoutPerVertex + (triangles + backTriangles) * kLayoutPerTriangle : 0;
  const uint64_t lower = probes ? e.transfer : 0;
  const uint64_t direct = e.transfer / 3;  // the direct part, kept to the end of the bake
  // Surface stage: during the last bounce (or the direct pass and its copy without bounces),
  // then the per-instance copies of the sums.
  // With probes to follow, the BVH stays for them (SharedRayScene) through the copies too.
  e.surfacePeak = e.scene + std::max(layout + e.bvh + e.hits + 2 * e.transfer + direct + lower,
                                     2 * (e.transfer + direct + lower) + (probes ? e.bvh : 0));
  const uint64_t lowerHalves = vertices * ((3 * n2 + 31) / 32 * 64);  // probe_bake.cpp: the lit hits' rows
  uint64_t latticePoints = 0, gridBytes = 0;
  if (probes)
    e.probePeak = e.scene + 2 * e.transfer + direct + lowerHalves +
                  probeStagePeak(scene, *probes, triangles, placement, e.probes, latticePoints, gridBytes);
  e.writePeak = e.scene + e.transfer + direct + lower + kWriteInputCopies * gltfInputBytes(scene) +
                kWriteTransferCopies * (e.transfer + direct);
  if (bounces && keptRays > 0) {
    const uint64_t probeEntries = latticePoints * uint64_t(std::max(s.operatorProbeRowLength, 0));
    const uint64_t held = vertices * kOperatorBytesPerSide + probeEntries * (n2 + 6);
    const uint64_t packed = vertices * kOperatorBytesPerSide + probeEntries * (n2 + 2);
    e.writePeak += gridBytes + records(keptRays) + keptBits + held + kWriteOperatorCopies * packed;
  }
  if (s.refineVertices > 0 && shadowed)
    e.refinePeak = e.scene + original * kLayoutPerVertex + (triangles - 2 * s.refineVertices) * kBvhBytesPerTriangle +
                   vertices * (kRefineBytesPerVertex + kRefinePointsPerVertex * ((uint64_t(s.samples) + 63) / 64 * 8));
  e.total = e.base + uint64_t(double(std::max({e.surfacePeak, e.probePeak, e.writePeak, e.refinePeak})) * kSlack);
  return e;
}

void MemoryEstimate::keepRefinePhase(uint64_t peak) {
  refinePeak = std::max(refinePeak, peak);
  total = std::max(total, base + uint64_t(double(refinePeak) * kSlack));
}

std::string MemoryEstimate::describe() const {
  std::ostringstream os;
  os << mib(total) << " (";
  if (hits) os << "hit records " << mib(hits) << ", ";
  os << "transfer " << mib(transfer) << " per buffer, ";
  if (bvh) os << "BVH " << mib(bvh) << ", ";
  if (probes) os << "probe lattice " << mib(probes) << ", ";
  os << "scene " << mib(scene) << ")";
  return os.str();
}

std::string MemoryEstimate::phases() const {
  auto bound = [&](uint64_t peak) { return mib(base + uint64_t(double(peak) * kSlack)); };
  std::ostringstream os;
  os << "surface " << bound(surfacePeak);
  if (probePeak) os << ", probes " << bound(probePeak);
  os << ", write " << bound(writePeak);
  if (refinePeak) os << ", refine " << bound(refinePeak);
  return os.str();
}

uint64_t parseByteSize(const std::string& text, const std::string& option) {
  auto bad = [&] {
    return Error(cat(option, " ", text, ": expected a size such as 8G, 500M or 64k (bytes without a suffix)"));
  };
  size_t pos = 0;
  double v = 0;
  try {
    v = std::stod(text, &pos);
  } catch (const std::exception&) {
    throw bad();
  }
  std::string unit = text.substr(pos);
  if (!unit.empty() && (unit.back() == 'B' || unit.back() == 'b')) unit.pop_back();
  if (unit.size() == 2 && (unit[1] == 'i' || unit[1] == 'I')) unit.pop_back();
  double mult = 1;
  if (unit.empty())
    mult = 1;
  else if (unit == "k" || unit == "K")
    mult = 1024.0;
  else if (unit == "m" || unit == "M")
    mult = 1024.0 * 1024;
  else if (unit == "g" || unit == "G")
    mult = 1024.0 * 1024 * 1024;
  else if (unit == "t" || unit == "T")
    mult = 1024.0 * 1024 * 1024 * 1024;
  else
    throw bad();
  if (!std::isfinite(v) || v <= 0 || v * mult > 1.8e19) throw bad();
  return uint64_t(v * mult);
}

namespace {

std::optional<uint64_t> readNumber(const std::string& path) {
  std::ifstream in(path);
  std::string s;
  if (!(in >> s) || s == "max") return std::nullopt;
  try {
    return std::stoull(s);
  } catch (const std::exception&) {
    return std::nullopt;
  }
}

uint64_t residentBytes() {
  std::ifstream in("/proc/self/statm");
  uint64_t size = 0, rss = 0;
  in >> size >> rss;
  return rss * uint64_t(::sysconf(_SC_PAGESIZE));
}

}  // namespace

std::optional<MemoryLimit> memoryLimit(std::optional<uint64_t> maxMemory) {
  if (maxMemory) return MemoryLimit{*maxMemory, kGivenLimit};
  std::optional<MemoryLimit> best;
  auto consider = [&](uint64_t free, const std::string& source) {
    // What this process holds already counts towards its peak, so it is available to it.
    uint64_t bytes = free + residentBytes();
    if (!best || bytes < best->bytes) best = MemoryLimit{bytes, source};
  };
  {
    std::ifstream in("/proc/meminfo");
    std::string key;
    uint64_t kb = 0;
    std::string unit;
    while (in >> key >> kb) {
      std::getline(in, unit);
      if (key == "MemAvailable:") consider(kb * 1024, "the available memory (MemAvailable)");
    }
  }
  // cgroup v2, then v1: the limit minus what the group already uses.
  if (auto max = readNumber("/sys/fs/cgroup/memory.max")) {
    uint64_t used = readNumber("/sys/fs/cgroup/memory.current").value_or(0);
    consider(*max > used ? *max - used : 0, "the cgroup limit (memory.max)");
  } else if (auto max1 = readNumber("/sys/fs/cgroup/memory/memory.limit_in_bytes");
             max1 && *max1 < (uint64_t(1) << 60)) {
    uint64_t used = readNumber("/sys/fs/cgroup/memory/memory.usage_in_bytes").value_or(0);
    consider(*max1 > used ? *max1 - used : 0, "the cgroup limit (memory.limit_in_bytes)");
  }
  return best;
}

std::optional<MemoryAdvice> memoryShortfall(const MemoryEstimate& e, const MemoryLimit& limit, const Scene& scene,
                                            const BakeSettings& s, const ProbeSettings* probes) {
  if (e.total <= limit.bytes) return std::nullopt;
  // A concrete way out: the largest power-of-two sample count that fits, else a coarser probe
  // lattice, else fewer bands. The placement measured for this lattice holds for other sample
  // counts and bands (its rays are fixed); a coarser lattice is counted whole.
  const ProbePlacement* placed = e.placement ? &*e.placement : nullptr;
  MemoryAdvice advice;
  if (e.hits > 0) {
    for (int n = 1 << 20; n >= 16; n /= 2) {
      if (n >= s.samples) continue;
      BakeSettings t = s;
      t.samples = n;
      if (estimateBakeMemory(scene, t, probes, e.frontHitShare, placed).total <= limit.bytes) {
        advice.samples = n;
        break;
      }
    }
  }
  if (probes && e.probePeak >= e.surfacePeak) {
    ProbeSettings p = *probes;
    for (int step = 0; step < 6; ++step) {
      if (p.spacing > 0)
        p.spacing *= 1.5;
      else
        p.dims = glm::max(glm::ivec3(1), (p.dims * 2 + 2) / 3);
      if (estimateBakeMemory(scene, s, &p, e.frontHitShare).total <= limit.bytes) {
        advice.probes = p;
        break;
      }
    }
  }
  for (int b = s.bands - 1; !advice.samples && !advice.probes && !advice.bands && b >= 1; --b) {
    BakeSettings t = s;
    t.bands = b;
    ProbeSettings p = probes ? *probes : ProbeSettings{};
    p.bands = b;
    if (estimateBakeMemory(scene, t, probes ? &p : nullptr, e.frontHitShare, placed).total <= limit.bytes)
      advice.bands = b;
  }
  return advice;
}

void checkMemory(const MemoryEstimate& e, const MemoryLimit& limit, const Scene& scene, const BakeSettings& s,
                 const ProbeSettings* probes, const MemoryAdviceNames& names) {
  const std::optional<MemoryAdvice> advice = memoryShortfall(e, limit, scene, s, probes);
  if (!advice) return;
  std::vector<std::string> ways;
  if (advice->samples) ways.push_back(cat(names.samples, " ", *advice->samples));
  if (const auto& p = advice->probes)
    ways.push_back(p->spacing > 0 ? cat(names.probeSpacing, " ", p->spacing)
                                  : cat(names.probeDims, " ", p->dims.x, ",", p->dims.y, ",", p->dims.z));
  if (advice->bands) ways.push_back(cat(names.bands, " ", *advice->bands));
  std::string how;
  for (const std::string& w : ways) how += (how.empty() ? "" : " or ") + w;
  how += how.empty() ? cat(names.raiseLimit, " above ", formatBytes(e.total)) : cat(", or ", names.raiseLimit);
  const std::string& source = limit.source == kGivenLimit ? names.givenLimit : limit.source;
  throw Error(cat("not enough memory: the bake needs up to ", e.describe(), ", more than the ",
                  formatBytes(limit.bytes), " allowed by ", source, "; use ", how));
}

}  // namespace prt::bake
