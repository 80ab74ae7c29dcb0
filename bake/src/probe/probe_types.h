// The probe bake's private types (bake/src/probe/): the constants of its ray streams, the
// scratch and accumulators of a probe, where a lit hit's rows are, and the kernel table of each
// phase (prt/bake/kernels.h): directions.cpp, classify.cpp, products.cpp, lit_hits.cpp.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

#include <glm/glm.hpp>

#include "../half_rows.h"
#include "../kernel_tables.h"
#include "prt/bake/ray_scene.h"

namespace prt::bake::probe {

// Rays traced at a time (a stream), in packets of 8.
constexpr int kStream = 256;
// Rays of the quick inside/outside test (and of each relocation candidate).
constexpr uint32_t kProbeTestRays = 64;
// An axis of the probe bounds thinner than this share of the largest extent is flat (a floor
// plane's bounds have zero height): the lattice would have a spacing of ~1e-10 on it, or one
// layer of probes lying in the plane with half their rays on its back. Default bounds are padded
// (probeBounds), bounds the user gave are refused (validate).
constexpr double kFlatFraction = 1e-3;

// Columns of the lit hits' rows g (StreamRows) are padded with zeros to a multiple of kBlock floats.
constexpr int kBlock = 8;
constexpr int padded(int n) { return (n + kBlock - 1) / kBlock * kBlock; }

// Streams traced before their lit hits are summed (a group): the corners of every lit hit are
// prefetched as its stream is classified, and read after the group's last stream is traced;
// their rows are prefetched then, a few hits ahead of the one whose light is computed
// (Tracer::sumLit). A lit hit's data lies at random places in arrays larger than the caches: read
// at once, each hit waited for two misses in a row (its corners, then their rows).
constexpr int kGroupStreams = 4;
constexpr int kGroup = kStream * kGroupStreams;
// Lit hits whose light g is computed, then multiplied in, at a time (g stays in the L1 cache).
constexpr int kChunk = 64;

// Per instance (Tracer::meshFlags): both sides are baked (bakesBackSide); its hits send light
// (it has lower-order transfer).
constexpr uint32_t kTwoSided = 1, kLit = 2;

// In a lit hit's yOff (StreamRows::hitYOff): the ray hit a back side (of a double-sided surface).
constexpr uint32_t kBackBit = 1u << 31;

// Per instance with lower-order transfer (Tracer::litMeshes): where a lit hit's rows are (its
// corners: Tracer::cornerIndices).
struct LitMesh {
  const uint16_t* rows = nullptr;      // the front sides' rows (HalfRows), stride halves apart
  const uint16_t* backRows = nullptr;  // the back sides' (the front's where only one side is baked)
  size_t stride = 0;
  // One colour (AlbedoLookup::uniform): its rows hold ρ/π · t and its hits' ρ/π is 1
  // (StreamRows::rho); else ρ/π is looked up per hit.
  bool uniform = false;
};

// Scratch of one group of rays, sized for the bands once per probe's accumulator (the inside
// tests need none): the SH basis of every ray, packet by packet (n2 coefficients of 8 lanes a
// packet: ray j's coefficient a at ys[(j / 8 · n2 + a) · 8 + j % 8]); the lane sums of M⁰'s
// upper triangle for one stream (n2(n2+1)/2 pairs of 8 lanes); per ray that hit a lit surface,
// where (its instance, triangle and barycentrics, and the offset of its ray's SH values in ys,
// with kBackBit on a back side: written eight lanes at a time, so with 8 entries to spare) and
// its ρ/π; and the light of a chunk of them (ρ/π · t(h), padded(3·n2) floats: n2 RGB triples).
struct StreamRows {
  int n2 = 0;
  std::vector<float> ys, directSums, gHit;
  std::vector<uint32_t> hitMesh, hitTri, hitYOff;
  std::vector<float> hitU, hitV;
  std::vector<float> rho;  // per lit hit, ρ/π and a zero (Tracer::lookUpAlbedo)
  // The group's lit hits whose colour is looked up (AlbedoLookup::atMany): which hit, its
  // instance, triangle and barycentrics, and the colour.
  struct Lookups {
    std::vector<uint32_t> hit, mesh, tri;
    std::vector<float> b1, b2;
    std::vector<glm::vec3> rgb;
  } albedo;
  void reset(int bands) {
    if (n2 != bands * bands) {  // the padding columns of gHit are zero and never written
      n2 = bands * bands;
      for (auto* v : {&hitMesh, &hitTri, &hitYOff}) v->resize(kGroup + 8);
      for (auto* v : {&hitU, &hitV}) v->resize(kGroup + 8);
      rho.resize(4 * size_t(kGroup));
      for (auto* v : {&albedo.hit, &albedo.mesh, &albedo.tri}) v->resize(kGroup);
      for (auto* v : {&albedo.b1, &albedo.b2}) v->resize(kGroup);
      albedo.rgb.resize(kGroup);
      ys.assign(size_t(kGroup) * n2, 0.0f);
      directSums.assign(size_t(n2) * (n2 + 1) / 2 * 8, 0.0f);
      gHit.assign(size_t(kChunk) * padded(3 * n2), 0.0f);
    }
  }
};

struct ProbeAccum {
  int n2 = 0;
  std::vector<double> direct;    // n2 × n2, colourless
  std::vector<double> indirect;  // n2 × n2 RGB: row a holds n2 triples
  StreamRows stream;             // scratch of the stream being summed
  uint32_t rays = 0, backfaces = 0, escaped = 0;
  uint32_t backTwoSided = 0;                               // hits on the back of double-sided faces
  float nearest = std::numeric_limits<float>::infinity();  // of the hits (any face)
  // Per cube face and lane of a packet (face · 8 + lane), summed over the packets in ray order:
  // the vector and portable classifications add in the same order. Summed lane by lane at the end.
  std::array<double, 48> sumD{}, sumD2{};
  std::array<uint32_t, 6> count{};
};

// The lattice coordinate of linear index idx = x + dims.x·(y + dims.y·z).
inline glm::ivec3 latticeCoord(const glm::ivec3& dims, size_t idx) {
  return glm::ivec3(int(idx % dims.x), int((idx / dims.x) % dims.y), int(idx / (size_t(dims.x) * dims.y)));
}

// Back faces of any kind, one-sided or double-sided, on more than this share of a probe's rays:
// it is inside solid mass.
constexpr double kSolidShare = 0.75;

// Inside geometry: back faces of one-sided surfaces on more than `threshold` of the rays, or
// back faces of any kind on more than kSolidShare.
inline bool insideGeometry(const ProbeAccum& a, double threshold) {
  if (!a.rays) return false;
  return double(a.backfaces) > threshold * a.rays || double(a.backfaces + a.backTwoSided) > kSolidShare * a.rays;
}

// Storage for a stream of rays as packets of 8, left uninitialised (RayPacket8 is an
// implicit-lifetime aggregate, and SphereSet::fill starts every field of the lanes traced before
// Embree reads them): constructing 2 × 32 packets per trace would write more than the rays
// themselves for the inside test's 64.
static_assert(kStream % 8 == 0);
struct RayBuffer {
  alignas(64) std::byte bytes[sizeof(RayPacket8) * (kStream / 8)];
  RayPacket8* packets() { return reinterpret_cast<RayPacket8*>(bytes); }
};

// A group's lit hits as the classification listed them (StreamRows), and where their rows are.
struct LitHits {
  const uint32_t *mesh, *tri, *yOff;  // yOff with kBackBit on a back side
  const float *b1, *b2;
  const float*
      rho;  // 4 floats a hit (ρ/π, then a zero: StreamRows::rho; with AVX-512 read only where one was looked up)
  const LitMesh* meshes;
  const uint32_t* const* corners;
  const float* y;
  uint32_t count;
  // Hit h's corner rows.
  void rowsOf(uint32_t h, const uint16_t** t) const {
    const LitMesh& m = meshes[mesh[h]];
    const uint32_t* ix = corners[mesh[h]] + 3 * size_t(tri[h]);
    const uint16_t* base = (yOff[h] & kBackBit) ? m.backRows : m.rows;
    t[0] = base + ix[0] * m.stride;
    t[1] = base + ix[1] * m.stride;
    t[2] = base + ix[2] * m.stride;
  }
  // Always inlined, as prefetchLines says (GCC once deleted its calls, and the lit-hit kernels
  // prefetched no rows).
  [[gnu::always_inline]] void prefetchRows(uint32_t h) const {
    const uint16_t* t[3];
    rowsOf(h, t);
    const size_t bytes = meshes[mesh[h]].stride * sizeof(uint16_t);
    prefetchLines(t[0], bytes);  // not a loop over t: GCC would keep t on the stack for it
    prefetchLines(t[1], bytes);
    prefetchLines(t[2], bytes);
  }
};

// What a classification counts of a stream's rays.
struct StreamTally {
  uint32_t backs, backsTwoSided, escapes;
  float nearest;
};

// The sphere directions of one stream: scrambled Sobol points, one scramble per stream, so each
// probe's rays depend on (seed, stream) only and never on the thread that traces them; computed
// by the directions' kernels (directions.cpp).
struct DirectionKernels;
struct SphereSet {
  uint32_t s0, s1;
  const DirectionKernels& kernels;
  SphereSet(uint64_t seed, uint64_t stream, const DirectionKernels& k);
  // Rays first … first + count − 1 (count ≤ kStream) from x: into packets of 8 (lane j % 8 of
  // packet j / 8, as the bake traces them) or into Rays (the benches' list of the same rays),
  // field by field (RayPacket8::start, Ray::start). The directions are computed first, all
  // together.
  void fill(RayPacket8* p, const glm::vec3& x, uint32_t first, uint32_t count) const;
  // The same rays into packets that fill (from the same origin, at least as many rays) and a
  // trace have used since: RayPacket8::restart, which writes less than half of what a packet
  // holds. The last packet's lanes past the count keep the unit direction fill gave them.
  void refill(RayPacket8* p, uint32_t first, uint32_t count) const;
  void fill(Ray* r, const glm::vec3& x, uint32_t first, uint32_t count) const;
};

// ---- The kernel table of each phase: a portable, an AVX2 and an AVX-512 entry, all giving the
// same bits (tests/test_probe_bake.cpp compares them), picked once per bake (ProbeKernels).

// The unit directions of n rays (uniformSphereFromBits) from the bits (px[j] ^ kx) >> 8 and
// (py[j] ^ ky) >> 8: a stream's Sobol points and its scramble (SphereSet).
struct DirectionKernels {
  void (*directions)(const uint32_t* px, const uint32_t* py, uint32_t kx, uint32_t ky, uint32_t n, float* dx, float* dy,
                     float* dz);
};

// One stream's classification (Tracer::trace, the full set of rays): what it reads besides the
// rays, and where it writes.
struct Classification {
  const uint32_t* meshFlags;       // Tracer::meshFlags
  const uint32_t* const* corners;  // Tracer::cornerIndices
  uint32_t yBase, n2;              // the stream's SH values from rows.ys[yBase] (its first ray's place · n2)
  double cap;                      // the moments' depth cap (Tracer::maxDistance)
  StreamRows& rows;                // the lit hits' lists
  uint32_t& nLit;                  // the group's lit hits so far
  int32_t* escapedLanes;           // per ray: −1 where it escaped, else 0 (a partial packet's rest 0)
  ProbeAccum& acc;                 // the moments
};
struct ClassifyKernels {
  // The `count` rays of a stream (whole packets and a last partial one): the counts into t, the
  // lit hits listed (their corners prefetched), the escaped lanes and the moments.
  void (*classify)(const RayPacket8* batch, uint32_t count, const Classification& c, StreamTally& t);
  // The counts alone (the inside test).
  StreamTally (*tally)(const RayPacket8* batch, uint32_t count, const uint32_t* meshFlags);
};

// The products of M's two parts: M += Σ y gᵀ of the lit hits (products), and M⁰'s lane sums of
// a stream's escaped rays (directSums).
struct ProductKernels {
  // c[a·ldc + j] += Σ_k y[yOff[k] + a·8] · v[k·ldv + j] for a < rows, j < cols, k < n (n ≥ 1).
  void (*products)(const float* y, const uint32_t* yOff, const float* v, int ldv, int n, int rows, int cols, double* c,
                   int ldc);
  // sums[8p + l] = Σ ye_a · y_b over the listed packets, from zero, for the pairs p = (a ≤ b).
  void (*directSums)(const float* ys, const int32_t* escaped, const uint8_t* list, int packets, int n2, float* sums);
};

// The light of a group's lit hits: g = ρ/π · t(h) into rows (lights), or M += Σ y gᵀ with g in
// registers (listed: null where the set has none, and only up to kListedMaxN2 coefficients).
struct LitHitKernels {
  void (*lights)(const LitHits& in, uint32_t h0, uint32_t n, float* g, int ldg);
  void (*listed)(const LitHits& in, uint32_t h0, uint32_t n, int n2, bool rho, double* c);
};
constexpr int kListedMaxN2 = 9;  // 3 bands: 3·n2 ≤ 27 floats, one 64-byte row of halves

extern const KernelTables<DirectionKernels> kDirectionKernels;
extern const KernelTables<ClassifyKernels> kClassifyKernels;
extern const KernelTables<ProductKernels> kProductKernels;
extern const KernelTables<LitHitKernels> kLitHitKernels;

// The entries of the set in use, every phase's (prt/bake/kernels.h).
struct ProbeKernels {
  const DirectionKernels& directions;
  const ClassifyKernels& classify;
  const ProductKernels& products;
  const LitHitKernels& litHits;
  static ProbeKernels active();
};

}  // namespace prt::bake::probe
