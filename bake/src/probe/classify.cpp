// The classification of a stream's rays (probe_types.h: ClassifyKernels): what each ray hit,
// counted (back faces, escapes, the nearest hit), its lit hits listed for the gather, and the
// moments of its depth per cube face; lane by lane, with AVX2 or with AVX-512, the same counts,
// lists and sums in the same order.
#include <algorithm>
#include <cstring>
#include <limits>

#include <immintrin.h>

#include "probe_types.h"

namespace prt::bake::probe {

namespace {

// faceOf and |d[faceOf(d) / 2]| of a packet's eight directions, lane by lane (GCC's vector
// extension: compares and selects, where faceOf's branches on random directions are
// mispredicted about half the time).
void packetFaces(const RayPacket8& r, int32_t* faces, float* axis) {
  typedef float F8 __attribute__((vector_size(32)));
  typedef int32_t I8 __attribute__((vector_size(32)));
  F8 x, y, z;
  std::memcpy(&x, r.dirX, sizeof x);
  std::memcpy(&y, r.dirY, sizeof y);
  std::memcpy(&z, r.dirZ, sizeof z);
  const F8 zero{};
  const I8 magnitude = I8{} + 0x7fffffff;  // |v|: the sign bit cleared, as fabs
  const F8 ax = F8(I8(x) & magnitude), ay = F8(I8(y) & magnitude), az = F8(I8(z) & magnitude);
  const I8 onX = (ax >= ay) & (ax >= az), onY = ay >= az;  // ties go to the earlier axis, as faceOf
  const I8 one = I8{} + 1, two = I8{} + 2, four = I8{} + 4;
  // Face::PosX … NegZ = 2·axis + (component < 0).
  const I8 fx = x >= zero ? I8{} : one, fy = y >= zero ? two : two + 1, fz = z >= zero ? four : four + 1;
  const I8 face = onX ? fx : (onY ? fy : fz);
  const F8 a = onX ? ax : (onY ? ay : az);
  std::memcpy(faces, &face, sizeof face);
  std::memcpy(axis, &a, sizeof a);
}

// A ray's depth along its face's axis, capped, into the moments of its face and lane. The depth
// along the axis, not the ray's length: a wall perpendicular to the axis then has one depth for
// every ray of the face (docs/probes.md, "Visibility").
inline void addMoment(ProbeAccum& acc, int face, int lane, float tfar, float axis, double cap) {
  const double d = std::min(double(tfar) * double(axis), cap);
  acc.sumD[size_t(8 * face + lane)] += d;
  acc.sumD2[size_t(8 * face + lane)] += d * d;
  ++acc.count[size_t(face)];
}

// For each 8-bit mask, the indices of its set lanes in order (the rest 0): the permutation that
// packs a packet's chosen lanes to its front, as AVX-512's compress does.
struct PackingTable {
  alignas(32) uint32_t lanes[256][8];
  constexpr PackingTable() : lanes{} {
    for (uint32_t m = 0; m < 256; ++m)
      for (uint32_t l = 0, k = 0; l < 8; ++l)
        if (m & (1u << l)) lanes[m][k++] = l;
  }
};
constexpr PackingTable kPacking{};

// A lane mask's sign bits, lane l at bit l.
__attribute__((target("avx2"), always_inline)) inline uint32_t laneBits(__m256i m) {
  return uint32_t(_mm256_movemask_ps(_mm256_castsi256_ps(m)));
}
// v's lanes in the order `pack` gives (kPacking), stored at `to` (8 lanes: room to spare).
__attribute__((target("avx2"), always_inline)) inline void packLanes(void* to, __m256i v, __m256i pack) {
  _mm256_storeu_si256(static_cast<__m256i*>(to), _mm256_permutevar8x32_epi32(v, pack));
}
// The classification of `packets` whole packets with AVX2: what a packet hit, its counts and its
// lit-hit entries eight lanes at once; its moments lane by lane, as the portable loop adds them
// (so the same bits). The lit hits' corners are left to classifyRest to prefetch.
__attribute__((target("avx2"))) void classifyAvx2(const RayPacket8* batch, uint32_t packets, const uint32_t* meshFlags,
                                                  uint32_t yBase, uint32_t n2, double cap, StreamRows& rows,
                                                  uint32_t& nLit, int32_t* escapedLanes, ProbeAccum& acc,
                                                  StreamTally& t) {
  const __m256i ones = _mm256_set1_epi32(-1), zero = _mm256_setzero_si256();
  const __m256i invalid = _mm256_set1_epi32(int(Ray::kInvalid)), lanes = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
  const __m256i twoSidedBit = _mm256_set1_epi32(kTwoSided), litBit = _mm256_set1_epi32(kLit);
  const __m256i backBit = _mm256_set1_epi32(int(kBackBit));
  __m256 nearest = _mm256_set1_ps(std::numeric_limits<float>::infinity());
  uint32_t n = nLit, backs = 0, backsTwoSided = 0, escapes = 0;
  for (uint32_t p = 0; p < packets; ++p) {
    const RayPacket8& r = batch[p];
    const __m256i mesh = _mm256_load_si256(reinterpret_cast<const __m256i*>(r.mesh));
    const __m256i hit = _mm256_xor_si256(_mm256_cmpeq_epi32(mesh, invalid), ones);
    const __m256i flags = _mm256_mask_i32gather_epi32(zero, reinterpret_cast<const int*>(meshFlags), mesh, hit, 4);
    // Ray::backface: ng · d > 0, as glm::dot: (x·x' + y·y') + z·z', each rounded (no FMA here).
    const __m256 dot = _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(_mm256_load_ps(r.ngX), _mm256_load_ps(r.dirX)),
                                                   _mm256_mul_ps(_mm256_load_ps(r.ngY), _mm256_load_ps(r.dirY))),
                                     _mm256_mul_ps(_mm256_load_ps(r.ngZ), _mm256_load_ps(r.dirZ)));
    const __m256i backside = _mm256_castps_si256(_mm256_cmp_ps(dot, _mm256_setzero_ps(), _CMP_GT_OQ));
    const __m256i oneSided = _mm256_cmpeq_epi32(_mm256_and_si256(flags, twoSidedBit), zero);
    const __m256i back = _mm256_and_si256(backside, oneSided);
    const __m256i litMesh = _mm256_xor_si256(_mm256_cmpeq_epi32(_mm256_and_si256(flags, litBit), zero), ones);
    const uint32_t hitBits = laneBits(hit), backBits = laneBits(back), backsideBits = laneBits(backside);
    backs += uint32_t(__builtin_popcount(backBits));
    backsTwoSided += uint32_t(__builtin_popcount(backsideBits & ~backBits));
    escapes += uint32_t(__builtin_popcount(~hitBits & 0xffu));
    nearest = _mm256_min_ps(nearest, _mm256_load_ps(r.tfar));
    // The lit hits, packed in lane order.
    const uint32_t take = hitBits & ~backBits & laneBits(litMesh);
    const __m256i pack = _mm256_load_si256(reinterpret_cast<const __m256i*>(kPacking.lanes[take]));
    const __m256i offsets = _mm256_add_epi32(_mm256_set1_epi32(int(yBase + 8 * p * n2)), lanes);
    const __m256i yOff = _mm256_or_si256(offsets, _mm256_and_si256(backside, backBit));
    packLanes(rows.hitMesh.data() + n, mesh, pack);
    packLanes(rows.hitTri.data() + n, _mm256_load_si256(reinterpret_cast<const __m256i*>(r.tri)), pack);
    packLanes(rows.hitU.data() + n, _mm256_castps_si256(_mm256_load_ps(r.u)), pack);
    packLanes(rows.hitV.data() + n, _mm256_castps_si256(_mm256_load_ps(r.v)), pack);
    packLanes(rows.hitYOff.data() + n, yOff, pack);
    n += uint32_t(__builtin_popcount(take));
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(escapedLanes + 8 * p), _mm256_xor_si256(hit, ones));
    // The moments lane by lane, as the portable loop.
    alignas(32) int32_t faces[8];
    alignas(32) float axis[8];
    packetFaces(r, faces, axis);
    for (int l = 0; l < 8; ++l) addMoment(acc, faces[l], l, r.tfar[l], axis[l], cap);
  }
  alignas(32) float lanesNearest[8];
  _mm256_store_ps(lanesNearest, nearest);
  t = {backs, backsTwoSided, escapes, *std::min_element(lanesNearest, lanesNearest + 8)};
  nLit = n;
}

PRT_AVX512_BEGIN
// What a packet's eight lanes hit, as masks: a hit, on a back side (Ray::backface: ng · d > 0,
// as glm::dot: (x·x' + y·y') + z·z', each rounded), of a double-sided instance, of one that
// sends light; with the instances and tfar.
struct PacketHits {
  __m256i mesh;
  __m256 tfar;
  __mmask8 hit, backside, twoSided, lit;
};
__attribute__((target("avx512f,avx512vl,avx512dq,avx512bw"), always_inline)) inline PacketHits packetHitsAvx512(
    const RayPacket8& r, const uint32_t* meshFlags) {
  constexpr int kRound = _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC;  // explicit: never contracted into FMAs
  PacketHits h;
  h.mesh = _mm256_load_si256(reinterpret_cast<const __m256i*>(r.mesh));
  h.hit = _mm256_cmpneq_epu32_mask(h.mesh, _mm256_set1_epi32(int(Ray::kInvalid)));
  const __m256i flags = _mm256_mmask_i32gather_epi32(_mm256_setzero_si256(), h.hit, h.mesh, meshFlags, 4);
  // (In 512-bit registers: only they take an explicit rounding.)
  const __m512 dx = _mm512_zextps256_ps512(_mm256_load_ps(r.dirX)), dy = _mm512_zextps256_ps512(_mm256_load_ps(r.dirY)),
               dz = _mm512_zextps256_ps512(_mm256_load_ps(r.dirZ));
  const __m512 nx = _mm512_zextps256_ps512(_mm256_load_ps(r.ngX)), ny = _mm512_zextps256_ps512(_mm256_load_ps(r.ngY)),
               nz = _mm512_zextps256_ps512(_mm256_load_ps(r.ngZ));
  __m512 dot = _mm512_add_round_ps(_mm512_mul_round_ps(nx, dx, kRound), _mm512_mul_round_ps(ny, dy, kRound), kRound);
  dot = _mm512_add_round_ps(dot, _mm512_mul_round_ps(nz, dz, kRound), kRound);
  h.backside = __mmask8(_mm512_cmp_ps_mask(dot, _mm512_setzero_ps(), _CMP_GT_OQ));
  h.twoSided = _mm256_test_epi32_mask(flags, _mm256_set1_epi32(kTwoSided));
  h.lit = _mm256_test_epi32_mask(flags, _mm256_set1_epi32(kLit));
  h.tfar = _mm256_load_ps(r.tfar);
  return h;
}

// StreamTally's counts over packets, with each lane's nearest hit until finishTally.
struct PacketTally {
  StreamTally t{};
  __m256 nearest;
};
__attribute__((target("avx512f,avx512vl,avx512dq,avx512bw"), always_inline)) inline PacketTally startTally() {
  return {{}, _mm256_set1_ps(std::numeric_limits<float>::infinity())};
}
__attribute__((target("avx512f,avx512vl,avx512dq,avx512bw"), always_inline)) inline void addToTally(
    PacketTally& a, const PacketHits& h) {
  a.t.backs += uint32_t(__builtin_popcount(__mmask8(h.backside & ~h.twoSided)));
  a.t.backsTwoSided += uint32_t(__builtin_popcount(__mmask8(h.backside & h.twoSided)));
  a.t.escapes += uint32_t(__builtin_popcount(__mmask8(~h.hit)));
  a.nearest = _mm256_min_ps(a.nearest, h.tfar);
}
__attribute__((target("avx512f,avx512vl,avx512dq,avx512bw"), always_inline)) inline StreamTally finishTally(
    const PacketTally& a) {
  alignas(32) float lanesNearest[8];
  _mm256_store_ps(lanesNearest, a.nearest);
  StreamTally t = a.t;
  t.nearest = *std::min_element(lanesNearest, lanesNearest + 8);
  return t;
}

// The counts alone (the inside test) of `packets` whole packets, with AVX-512: the same as tallyLanes'.
__attribute__((target("avx512f,avx512vl,avx512dq,avx512bw"))) StreamTally tallyAvx512(const RayPacket8* batch,
                                                                                      uint32_t packets,
                                                                                      const uint32_t* meshFlags) {
  PacketTally a = startTally();
  for (uint32_t p = 0; p < packets; ++p) addToTally(a, packetHitsAvx512(batch[p], meshFlags));
  return finishTally(a);
}

// The classification of `packets` whole packets, eight lanes at once with AVX-512: the same
// counts, lit-hit entries in the same order, the same escaped lanes, and the same moments (each
// face and lane's sums in the same order, the multiplies and adds rounded one by one as the
// portable loop's).
__attribute__((target("avx512f,avx512vl,avx512dq,avx512bw"))) void classifyAvx512(
    const RayPacket8* batch, uint32_t packets, const uint32_t* meshFlags, const uint32_t* const* corners,
    uint32_t yBase, uint32_t n2, double cap, StreamRows& rows, uint32_t& nLit, int32_t* escapedLanes, ProbeAccum& acc,
    StreamTally& t) {
  constexpr int kRound = _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC;  // explicit: never contracted into FMAs
  // Each face's sums of the eight lanes, in registers over the stream.
  __m512d sumD[6], sumD2[6];
  uint32_t count[6] = {};
  for (int f = 0; f < 6; ++f) {
    sumD[f] = _mm512_loadu_pd(&acc.sumD[size_t(8 * f)]);
    sumD2[f] = _mm512_loadu_pd(&acc.sumD2[size_t(8 * f)]);
  }
  const __m256i lanes = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
  const __m256 zero = _mm256_setzero_ps();
  const __m512d capV = _mm512_set1_pd(cap);
  PacketTally tally = startTally();
  uint32_t n = nLit;
  for (uint32_t p = 0; p < packets; ++p) {
    const RayPacket8& r = batch[p];
    const PacketHits ph = packetHitsAvx512(r, meshFlags);
    addToTally(tally, ph);
    const __m256i mesh = ph.mesh;
    const __mmask8 hit = ph.hit, backside = ph.backside, litMesh = ph.lit;
    const __m256 dx = _mm256_load_ps(r.dirX), dy = _mm256_load_ps(r.dirY), dz = _mm256_load_ps(r.dirZ);
    const __mmask8 back = backside & ~ph.twoSided;
    const __m256 tfar = ph.tfar;
    // The lit hits, packed in lane order.
    const __mmask8 take = hit & ~back & litMesh;
    const __m256i offsets = _mm256_add_epi32(_mm256_set1_epi32(int(yBase + 8 * p * n2)), lanes);
    const __m256i yOff = _mm256_mask_or_epi32(offsets, backside, offsets, _mm256_set1_epi32(int(kBackBit)));
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(&rows.hitMesh[n]), _mm256_maskz_compress_epi32(take, mesh));
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(&rows.hitTri[n]),
                        _mm256_maskz_compress_epi32(take, _mm256_load_si256(reinterpret_cast<const __m256i*>(r.tri))));
    _mm256_storeu_ps(&rows.hitU[n], _mm256_maskz_compress_ps(take, _mm256_load_ps(r.u)));
    _mm256_storeu_ps(&rows.hitV[n], _mm256_maskz_compress_ps(take, _mm256_load_ps(r.v)));
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(&rows.hitYOff[n]), _mm256_maskz_compress_epi32(take, yOff));
    // Their corners, fetched while the group's other streams trace: a packet's few at a time, as
    // they are found (a stream's all at once stalled on the fill buffers).
    for (const uint32_t end = n + uint32_t(__builtin_popcount(take)); n < end; ++n)
      __builtin_prefetch(corners[rows.hitMesh[n]] + 3 * size_t(rows.hitTri[n]));
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(escapedLanes + 8 * p), _mm256_movm_epi32(__mmask8(~hit)));
    // packetFaces: the face (ties to the earlier axis) and |the direction along its axis|.
    const __m256 sign = _mm256_set1_ps(-0.0f);
    const __m256 ax = _mm256_andnot_ps(sign, dx), ay = _mm256_andnot_ps(sign, dy), az = _mm256_andnot_ps(sign, dz);
    const __mmask8 onX = _mm256_cmp_ps_mask(ax, ay, _CMP_GE_OQ) & _mm256_cmp_ps_mask(ax, az, _CMP_GE_OQ);
    const __mmask8 onY = __mmask8(~onX) & _mm256_cmp_ps_mask(ay, az, _CMP_GE_OQ);
    const __mmask8 onZ = __mmask8(~(onX | onY));
    const __mmask8 posX = _mm256_cmp_ps_mask(dx, zero, _CMP_GE_OQ), posY = _mm256_cmp_ps_mask(dy, zero, _CMP_GE_OQ),
                   posZ = _mm256_cmp_ps_mask(dz, zero, _CMP_GE_OQ);
    const __mmask8 face[6] = {__mmask8(onX & posX),  __mmask8(onX & ~posX), __mmask8(onY & posY),
                              __mmask8(onY & ~posY), __mmask8(onZ & posZ),  __mmask8(onZ & ~posZ)};
    const __m256 a = _mm256_mask_blend_ps(onX, _mm256_mask_blend_ps(onY, az, ay), ax);
    // Depth along the face's axis, capped; float × float is exact in double.
    const __m512d d = _mm512_min_pd(_mm512_mul_round_pd(_mm512_cvtps_pd(tfar), _mm512_cvtps_pd(a), kRound), capV);
    const __m512d d2 = _mm512_mul_round_pd(d, d, kRound);
    for (int f = 0; f < 6; ++f) {
      sumD[f] = _mm512_mask_add_round_pd(sumD[f], face[f], sumD[f], d, kRound);
      sumD2[f] = _mm512_mask_add_round_pd(sumD2[f], face[f], sumD2[f], d2, kRound);
      count[f] += uint32_t(__builtin_popcount(face[f]));
    }
  }
  for (int f = 0; f < 6; ++f) {
    _mm512_storeu_pd(&acc.sumD[size_t(8 * f)], sumD[f]);
    _mm512_storeu_pd(&acc.sumD2[size_t(8 * f)], sumD2[f]);
    acc.count[size_t(f)] += count[f];
  }
  t = finishTally(tally);
  nLit = n;
}
PRT_AVX512_END

// What a packet's first `lanes` rays hit, counted into t.
void tallyLanes(const RayPacket8& r, int lanes, const uint32_t* meshFlags, StreamTally& t) {
  for (int l = 0; l < lanes; ++l) {
    const bool hit = r.hit(l);
    const uint32_t flags = meshFlags[hit ? r.mesh[l] : 0];
    const bool backside = r.backface(l);
    const bool back = backside && !(flags & kTwoSided);
    t.backs += back;
    t.backsTwoSided += backside && !back;
    t.nearest = std::min(t.nearest, r.tfar[l]);
    t.escapes += !hit;
  }
}

// Packet p's first `lanes` rays, lane by lane and without branches on what they hit (which no
// predictor guesses): the counts, their places in the list of lit hits (written, the list's
// length advanced where one belongs), the escaped lanes and the moments. A ray that escapes keeps
// tfar = ∞ and ng = 0, so it is nearer than nothing and never a back face, and its depth is
// the cap.
void classifyLanes(const RayPacket8* batch, uint32_t p, int lanes, const Classification& c, StreamTally& t) {
  const RayPacket8& r = batch[p];
  tallyLanes(r, lanes, c.meshFlags, t);
  alignas(32) int32_t faces[8];
  alignas(32) float axis[8];  // |the direction's component along its face's axis|
  packetFaces(r, faces, axis);
  int32_t* escaped = c.escapedLanes + 8 * p;
  StreamRows& rows = c.rows;
  uint32_t& n = c.nLit;
  for (int l = 0; l < lanes; ++l) {
    const bool hit = r.hit(l);
    const uint32_t flags = c.meshFlags[hit ? r.mesh[l] : 0];
    const bool backside = r.backface(l);
    const bool back = backside && !(flags & kTwoSided);
    rows.hitMesh[n] = r.mesh[l];
    rows.hitTri[n] = r.tri[l];
    rows.hitU[n] = r.u[l];
    rows.hitV[n] = r.v[l];
    rows.hitYOff[n] = (c.yBase + 8 * p * c.n2 + uint32_t(l)) | (backside ? kBackBit : 0u);
    n += hit && !back && (flags & kLit);
    escaped[l] = -int32_t(!hit);
    addMoment(c.acc, faces[l], l, r.tfar[l], axis[l], c.cap);
  }
  for (int l = lanes; l < 8; ++l) escaped[l] = 0;
}

// The packets from p of a stream of `count` rays lane by lane (the last one may be partial), then
// the corners of the lit hits from `fetched` on prefetched, to be read once the group is traced.
void classifyRest(const RayPacket8* batch, uint32_t p, uint32_t count, const Classification& c, StreamTally& t,
                  uint32_t fetched) {
  for (; 8 * p < count; ++p) classifyLanes(batch, p, int(std::min<uint32_t>(8, count - 8 * p)), c, t);
  for (uint32_t h = fetched; h < c.nLit; ++h)
    __builtin_prefetch(c.corners[c.rows.hitMesh[h]] + 3 * size_t(c.rows.hitTri[h]));
}

void classifyPortable(const RayPacket8* batch, uint32_t count, const Classification& c, StreamTally& t) {
  classifyRest(batch, 0, count, c, t, c.nLit);
}

void classifyStreamAvx2(const RayPacket8* batch, uint32_t count, const Classification& c, StreamTally& t) {
  const uint32_t before = c.nLit;
  classifyAvx2(batch, count / 8, c.meshFlags, c.yBase, c.n2, c.cap, c.rows, c.nLit, c.escapedLanes, c.acc, t);
  classifyRest(batch, count / 8, count, c, t, before);
}

void classifyStreamAvx512(const RayPacket8* batch, uint32_t count, const Classification& c, StreamTally& t) {
  classifyAvx512(batch, count / 8, c.meshFlags, c.corners, c.yBase, c.n2, c.cap, c.rows, c.nLit, c.escapedLanes, c.acc,
                 t);
  classifyRest(batch, count / 8, count, c, t, c.nLit);  // the kernel fetched its own hits' corners
}

// The counts of the packets from p lane by lane, added to t.
StreamTally tallyRest(const RayPacket8* batch, uint32_t p, uint32_t count, const uint32_t* meshFlags, StreamTally t) {
  for (; 8 * p < count; ++p) tallyLanes(batch[p], int(std::min<uint32_t>(8, count - 8 * p)), meshFlags, t);
  return t;
}

StreamTally tallyPortable(const RayPacket8* batch, uint32_t count, const uint32_t* meshFlags) {
  return tallyRest(batch, 0, count, meshFlags, {0, 0, 0, std::numeric_limits<float>::infinity()});
}

StreamTally tallyStreamAvx512(const RayPacket8* batch, uint32_t count, const uint32_t* meshFlags) {
  return tallyRest(batch, count / 8, count, meshFlags, tallyAvx512(batch, count / 8, meshFlags));
}

}  // namespace

const KernelTables<ClassifyKernels> kClassifyKernels{
    {classifyPortable, tallyPortable}, {classifyStreamAvx2, tallyPortable}, {classifyStreamAvx512, tallyStreamAvx512}};

}  // namespace prt::bake::probe
