// Probe transfer (docs/prt-math.md, docs/probes.md):
//   M_ji(p) = ∫ y_j(ω) [ V(p,ω) y_i(ω) + (1 − V(p,ω)) (ρ(h)/π) t_i(h(ω)) ] dω
// estimated with N uniform sphere directions (pdf 1/4π): each ray adds (4π/N) y_j(ω) [...].
// A ray that hits the back of a one-sided surface sends nothing, and counts towards the probe's
// back-face share: a probe that sees mostly back faces is inside geometry. The back of a
// double-sided surface is a lit surface like any front: it sends its back side's transfer
// (the second half of lowerOrder[k], surface_bake.h) and is a sign of being inside only where
// back faces of any kind surround the probe (more than kSolidShare of its rays: solid mass
// bounded by double-sided faces, as maps exported with every material double-sided have; a
// probe under a double-sided roof sees them over half its sphere at most). Per cube face the
// probe also keeps the mean and mean square of its hits' depth along the face's axis, for the
// interpolation's visibility test.
#include "prt/bake/probe_bake.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstddef>
#include <cstring>
#include <iomanip>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <type_traits>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <immintrin.h>

#include "albedo_lookup.h"
#include "half.h"
#include "prt/bake/ray_scene.h"
#include "prt/bake/sampling.h"
#include "prt/error.h"
#include "prt/huge_pages.h"
#include "prt/sh.h"
#include "stage_runner.h"
#include "trace_clock.h"

namespace prt::bake {

namespace {

constexpr int kStream = 256;
// Rays of the quick inside/outside test (and of each relocation candidate).
constexpr uint32_t kProbeTestRays = 64;
// An axis of the probe bounds thinner than this share of the largest extent is flat (a floor
// plane's bounds have zero height): the lattice would have a spacing of ~1e-10 on it, or one
// layer of probes lying in the plane with half their rays on its back. Default bounds are padded
// (probeBounds), bounds the user gave are refused (validate).
constexpr double kFlatFraction = 1e-3;

// uniformSphereFromBits of each (bx, by), into dx, dy, dz: with AVX2 eight at a time, the same
// operations in the same order, so both give the same bits (where sincosf was a call per ray).
void sphereDirectionsPortable(const uint32_t* bx, const uint32_t* by, uint32_t n, float* dx, float* dy, float* dz) {
  for (uint32_t j = 0; j < n; ++j) {
    const glm::vec3 d = uniformSphereFromBits(bx[j], by[j]);
    dx[j] = d.x;
    dy[j] = d.y;
    dz[j] = d.z;
  }
}

__attribute__((target("avx2"))) void sphereDirectionsAvx2(const uint32_t* bx, const uint32_t* by, uint32_t n,
                                                          float* dx, float* dy, float* dz) {
  const __m256 one = _mm256_set1_ps(1.0f), two = _mm256_set1_ps(2.0f), zero = _mm256_setzero_ps();
  const __m256 half = _mm256_set1_ps(0.5f), unit = _mm256_set1_ps(0x1p-24f);
  const __m256 angle = _mm256_set1_ps(0x1p-22f * 0.5f * kPi);
  const __m256 s1 = _mm256_set1_ps(kSinS1), s2 = _mm256_set1_ps(kSinS2), s3 = _mm256_set1_ps(kSinS3);
  const __m256 c1 = _mm256_set1_ps(kCosC1), c2 = _mm256_set1_ps(kCosC2), c3 = _mm256_set1_ps(kCosC3);
  const __m256 sign = _mm256_set1_ps(-0.0f);
  uint32_t j = 0;
  for (; j + 8 <= n; j += 8) {
    const __m256i ix = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(bx + j));
    const __m256i iy = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(by + j));
    const __m256 z = _mm256_sub_ps(one, _mm256_mul_ps(two, _mm256_mul_ps(_mm256_cvtepi32_ps(ix), unit)));
    const __m256 r = _mm256_sqrt_ps(_mm256_max_ps(_mm256_sub_ps(one, _mm256_mul_ps(z, z)), zero));
    const __m256i q = _mm256_srli_epi32(_mm256_add_epi32(iy, _mm256_set1_epi32(1 << 21)), 22);
    const __m256 a = _mm256_mul_ps(_mm256_cvtepi32_ps(_mm256_sub_epi32(iy, _mm256_slli_epi32(q, 22))), angle);
    const __m256 a2 = _mm256_mul_ps(a, a);
    const __m256 sn = _mm256_add_ps(
        a, _mm256_mul_ps(_mm256_mul_ps(a, a2),
                         _mm256_add_ps(s1, _mm256_mul_ps(a2, _mm256_add_ps(s2, _mm256_mul_ps(a2, s3))))));
    const __m256 cs = _mm256_add_ps(
        _mm256_sub_ps(one, _mm256_mul_ps(half, a2)),
        _mm256_mul_ps(_mm256_mul_ps(a2, a2), _mm256_add_ps(c1, _mm256_mul_ps(a2, _mm256_add_ps(c2, _mm256_mul_ps(a2, c3))))));
    // Quarter turn k: (cos, sin) → k 0: (c, s), 1: (−s, c), 2: (−c, −s), 3: (s, −c).
    const __m256i k = _mm256_and_si256(q, _mm256_set1_epi32(3));
    const __m256 odd = _mm256_castsi256_ps(_mm256_slli_epi32(k, 31));  // k = 1, 3: swap
    const __m256 negX = _mm256_castsi256_ps(_mm256_slli_epi32(_mm256_add_epi32(k, _mm256_set1_epi32(1)), 30));
    const __m256 negY = _mm256_castsi256_ps(_mm256_slli_epi32(k, 30));
    const __m256 x = _mm256_blendv_ps(cs, sn, odd), y = _mm256_blendv_ps(sn, cs, odd);
    _mm256_storeu_ps(dx + j, _mm256_mul_ps(r, _mm256_xor_ps(x, _mm256_and_ps(negX, sign))));
    _mm256_storeu_ps(dy + j, _mm256_mul_ps(r, _mm256_xor_ps(y, _mm256_and_ps(negY, sign))));
    _mm256_storeu_ps(dz + j, z);
  }
  sphereDirectionsPortable(bx + j, by + j, n - j, dx + j, dy + j, dz + j);
}

// sphereDirectionsAvx2 sixteen at a time with AVX-512, from the bits (px[j] ^ kx) >> 8 and
// (py[j] ^ ky) >> 8 (a stream's points and scrambles: SphereSet) made in the same pass: the same
// operations, each rounded on its own (an explicit rounding mode: never contracted into a fused
// multiply-add), so the same bits.
PRT_AVX512_BEGIN
__attribute__((target("avx512f,avx512dq"))) void sphereDirectionsAvx512(const uint32_t* px, const uint32_t* py,
                                                                       uint32_t kx, uint32_t ky, uint32_t n,
                                                                       float* dx, float* dy, float* dz) {
  constexpr int kRound = _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC;
#define MUL(a, b) _mm512_mul_round_ps(a, b, kRound)
#define ADD(a, b) _mm512_add_round_ps(a, b, kRound)
#define SUB(a, b) _mm512_sub_round_ps(a, b, kRound)
  const __m512 one = _mm512_set1_ps(1.0f), two = _mm512_set1_ps(2.0f), zero = _mm512_setzero_ps();
  const __m512 half = _mm512_set1_ps(0.5f), unit = _mm512_set1_ps(0x1p-24f);
  const __m512 angle = _mm512_set1_ps(0x1p-22f * 0.5f * kPi);
  const __m512 s1 = _mm512_set1_ps(kSinS1), s2 = _mm512_set1_ps(kSinS2), s3 = _mm512_set1_ps(kSinS3);
  const __m512 c1 = _mm512_set1_ps(kCosC1), c2 = _mm512_set1_ps(kCosC2), c3 = _mm512_set1_ps(kCosC3);
  const __m512i sign = _mm512_set1_epi32(int(0x80000000u));
  uint32_t j = 0;
  for (; j + 16 <= n; j += 16) {
    const __m512i ix = _mm512_srli_epi32(_mm512_xor_si512(_mm512_loadu_si512(px + j), _mm512_set1_epi32(int(kx))), 8);
    const __m512i iy = _mm512_srli_epi32(_mm512_xor_si512(_mm512_loadu_si512(py + j), _mm512_set1_epi32(int(ky))), 8);
    const __m512 z = SUB(one, MUL(two, MUL(_mm512_cvtepi32_ps(ix), unit)));
    const __m512 r = _mm512_sqrt_round_ps(_mm512_max_ps(SUB(one, MUL(z, z)), zero), kRound);
    const __m512i q = _mm512_srli_epi32(_mm512_add_epi32(iy, _mm512_set1_epi32(1 << 21)), 22);
    const __m512 a = MUL(_mm512_cvtepi32_ps(_mm512_sub_epi32(iy, _mm512_slli_epi32(q, 22))), angle);
    const __m512 a2 = MUL(a, a);
    const __m512 sn = ADD(a, MUL(MUL(a, a2), ADD(s1, MUL(a2, ADD(s2, MUL(a2, s3))))));
    const __m512 cs = ADD(SUB(one, MUL(half, a2)), MUL(MUL(a2, a2), ADD(c1, MUL(a2, ADD(c2, MUL(a2, c3))))));
    // Quarter turn k: (cos, sin) → k 0: (c, s), 1: (−s, c), 2: (−c, −s), 3: (s, −c).
    const __m512i k = _mm512_and_si512(q, _mm512_set1_epi32(3));
    const __mmask16 odd = _mm512_test_epi32_mask(k, _mm512_set1_epi32(1));  // k = 1, 3: swap
    const __m512i negX = _mm512_and_si512(_mm512_slli_epi32(_mm512_add_epi32(k, _mm512_set1_epi32(1)), 30), sign);
    const __m512i negY = _mm512_and_si512(_mm512_slli_epi32(k, 30), sign);
    const __m512 x = _mm512_mask_blend_ps(odd, cs, sn), y = _mm512_mask_blend_ps(odd, sn, cs);
    _mm512_storeu_ps(dx + j, MUL(r, _mm512_castsi512_ps(_mm512_xor_si512(_mm512_castps_si512(x), negX))));
    _mm512_storeu_ps(dy + j, MUL(r, _mm512_castsi512_ps(_mm512_xor_si512(_mm512_castps_si512(y), negY))));
    _mm512_storeu_ps(dz + j, z);
  }
#undef MUL
#undef ADD
#undef SUB
  alignas(32) uint32_t bx[16], by[16];
  for (uint32_t i = j; i < n; ++i) bx[i - j] = (px[i] ^ kx) >> 8, by[i - j] = (py[i] ^ ky) >> 8;
  sphereDirectionsAvx2(bx, by, n - j, dx + j, dy + j, dz + j);
}
PRT_AVX512_END

void sphereDirections(const uint32_t* bx, const uint32_t* by, uint32_t n, float* dx, float* dy, float* dz) {
  if (useVectorKernels())
    sphereDirectionsAvx2(bx, by, n, dx, dy, dz);
  else
    sphereDirectionsPortable(bx, by, n, dx, dy, dz);
}

// The 32-bit points j < kStream of both Sobol dimensions, unscrambled.
struct StreamPoints {
  uint32_t x[kStream], y[kStream];
  constexpr StreamPoints() : x{}, y{} {
    for (uint32_t j = 0; j < uint32_t(kStream); ++j) {
      x[j] = sobol0Point(j);
      y[j] = sobol1Point(j);
    }
  }
};
constexpr StreamPoints kStreamPoints{};

// The sphere directions of one stream: scrambled Sobol points, one scramble per stream, so each
// probe's rays depend on (seed, stream) only and never on the thread that traces them.
struct SphereSet {
  uint32_t s0, s1;
  SphereSet(uint64_t seed, uint64_t stream) {
    const uint64_t h = splitMix64(seed ^ splitMix64(stream));
    s0 = uint32_t(h);
    s1 = uint32_t(h >> 32);
  }
  // Rays first … first + count − 1 (count ≤ kStream) from x: into packets of 8 (lane j % 8 of
  // packet j / 8, as the bake traces them) or into Rays (the benches' list of the same rays),
  // field by field (RayPacket8::start, Ray::start). The directions are computed first, all
  // together (sphereDirections).
  void fill(RayPacket8* p, const glm::vec3& x, uint32_t first, uint32_t count) const {
    Directions d(*this, first, count);
    constexpr float inf = std::numeric_limits<float>::infinity();
    uint32_t j = 0;
    for (; j + 8 <= count; j += 8) p[j >> 3].startAll(x, d.x + j, d.y + j, d.z + j, 0.0f, inf);
    for (; j < count; ++j) p[j >> 3].start(int(j & 7), x, {d.x[j], d.y[j], d.z[j]}, 0.0f, inf);
    // The last packet's lanes past the count are not traced, but their SH values are computed
    // with the packet's (Tracer::trace): a unit direction, not whatever the buffer held.
    for (; j % 8 != 0; ++j) p[j >> 3].start(int(j & 7), x, {0.0f, 0.0f, 1.0f}, 0.0f, inf);
  }
  // The same rays into packets that fill (from the same origin, at least as many rays) and a
  // trace have used since: RayPacket8::restart, which writes less than half of what a packet
  // holds. The last packet's lanes past the count keep the unit direction fill gave them.
  void refill(RayPacket8* p, uint32_t first, uint32_t count) const {
    Directions d(*this, first, count);
    constexpr float inf = std::numeric_limits<float>::infinity();
    uint32_t j = 0;
    for (; j + 8 <= count; j += 8) p[j >> 3].restart(d.x + j, d.y + j, d.z + j, inf);
    if (j == count) return;
    alignas(32) float x[8], y[8], z[8];
    for (uint32_t l = 0; l < 8; ++l) {
      const bool ray = j + l < count;
      x[l] = ray ? d.x[j + l] : 0.0f, y[l] = ray ? d.y[j + l] : 0.0f, z[l] = ray ? d.z[j + l] : 1.0f;
    }
    p[j >> 3].restart(x, y, z, inf);
  }
  void fill(Ray* r, const glm::vec3& x, uint32_t first, uint32_t count) const {
    Directions d(*this, first, count);
    for (uint32_t j = 0; j < count; ++j)
      r[j].start(x, {d.x[j], d.y[j], d.z[j]}, 0.0f, std::numeric_limits<float>::infinity());
  }

private:
  struct Directions {
    alignas(32) float x[kStream], y[kStream], z[kStream];
    Directions(const SphereSet& s, uint32_t first, uint32_t count) {
      // Both dimensions are linear over GF(2) and a stream starts at a multiple of kStream (a
      // power of two): point first + j (j < kStream) is point first XOR point j, the scramble
      // folded into the first. The same bits as sobol0Bits and sobol1Bits of first + j.
      static_assert((kStream & (kStream - 1)) == 0);
      PRT_CHECK_EQ(first % kStream, 0u);
      const uint32_t x0 = sobol0Point(first) ^ s.s0, y0 = sobol1Point(first) ^ s.s1;
      PRT_CHECK(count <= uint32_t(kStream));
      if (useAvx512Kernels()) {  // the bits and directions in one pass
        sphereDirectionsAvx512(kStreamPoints.x, kStreamPoints.y, x0, y0, count, x, y, z);
        return;
      }
      alignas(32) uint32_t bx[kStream], by[kStream];  // every entry written: no zeroing per stream
      for (uint32_t j = 0; j < uint32_t(kStream); ++j) {
        bx[j] = (kStreamPoints.x[j] ^ x0) >> 8;
        by[j] = (kStreamPoints.y[j] ^ y0) >> 8;
      }
      sphereDirections(bx, by, count, x, y, z);
    }
  };
};

// Columns of the lit hits' rows g (StreamRows) are padded with zeros to a multiple of kBlock floats.
constexpr int kBlock = 8;
constexpr int padded(int n) { return (n + kBlock - 1) / kBlock * kBlock; }

// c[a·ldc + j] += Σ_k y[yOff[k] + a·8] · v[k·ldv + j] for a < rows, j < cols, k < n: one
// stream's lit hits summed in float, then added to the double matrix c; hit k's SH values lie
// in the stream's packet-major table (StreamRows::ys), 8 floats apart, from yOff[k]. Every
// element adds its hits in ray order, one fused multiply-add each (rounded once), so the AVX2
// kernel and the portable loop (std::fma, exact in software where the CPU has no FMA) give the
// same bits. ldv is a multiple of kBlock and v's padding columns are zero.
void addProductsPortable(const float* y, const uint32_t* yOff, const float* v, int ldv, int n, int rows, int cols,
                         double* c, int ldc) {
  for (int a = 0; a < rows; ++a)
    for (int j = 0; j < cols; ++j) {
      float s = 0.0f;
      for (int k = 0; k < n; ++k) s = std::fma(y[yOff[k] + size_t(a) * 8], v[size_t(k) * ldv + j], s);
      c[size_t(a) * ldc + j] += double(s);
    }
}

// R rows from a0 by B vectors of 8 columns from j0, the R·B sums held in registers over the
// ray loop (each v vector loaded once for R rows). R·B = 8 sums hide the FMA's latency (4 cycles
// on two ports).
template <int R, int B>
__attribute__((target("avx2,fma"), always_inline)) inline void productBlockAvx2(const float* y, const uint32_t* yOff,
                                                                             const float* v, int ldv, int n, int a0,
                                                                             int j0, int cols, double* c, int ldc) {
  // The unroll pragmas (at least R and B) let the sums live in registers only: unrolled later,
  // GCC keeps the array in memory too and stores every sum on every ray (a store-port bound,
  // twice the FMAs' time). Until session 26 the rows' pragmas said 4, and the 3-band block of all
  // nine rows (the last 8 columns) kept its sums in memory.
  __m256 s[R][B];
#pragma GCC unroll 16
  for (int r = 0; r < R; ++r)
#pragma GCC unroll 4
    for (int b = 0; b < B; ++b) s[r][b] = _mm256_setzero_ps();
  for (int k = 0; k < n; ++k) {
    const float* vk = v + size_t(k) * ldv + j0;
    __m256 w[B];
#pragma GCC unroll 4
    for (int b = 0; b < B; ++b) w[b] = _mm256_loadu_ps(vk + 8 * b);
#pragma GCC unroll 16
    for (int r = 0; r < R; ++r) {
      const __m256 ya = _mm256_broadcast_ss(y + yOff[k] + size_t(a0 + r) * 8);
#pragma GCC unroll 4
      for (int b = 0; b < B; ++b) s[r][b] = _mm256_fmadd_ps(ya, w[b], s[r][b]);
    }
  }
#pragma GCC unroll 16
  for (int r = 0; r < R; ++r) {
    double* crow = c + size_t(a0 + r) * ldc;
#pragma GCC unroll 4
    for (int b = 0; b < B; ++b) {
      alignas(32) float t[8];
      _mm256_store_ps(t, s[r][b]);
      for (int l = 0; l < 8 && j0 + 8 * b + l < cols; ++l) crow[j0 + 8 * b + l] += double(t[l]);
    }
  }
}

// Rows [a, rows) of columns [j0, j0 + 8B) in blocks of R rows, the last block smaller.
template <int R, int B>
__attribute__((target("avx2,fma"), always_inline)) inline void productRowsAvx2(const float* y, const uint32_t* yOff,
                                                                            const float* v, int ldv, int n, int rows,
                                                                            int a, int j0, int cols, double* c,
                                                                            int ldc) {
  for (; a + R <= rows; a += R) productBlockAvx2<R, B>(y, yOff, v, ldv, n, a, j0, cols, c, ldc);
  if constexpr (R > 1)
    if (a < rows) productRowsAvx2<R - 1, B>(y, yOff, v, ldv, n, rows, a, j0, cols, c, ldc);
}

// Column vectors three at a time with 3 rows (9 sums), the rest one or two at a time with up to
// 9 or 4 rows: at least 8 sums in flight to hide the FMA's latency (4 cycles on two ports) within
// 16 ymm registers (the sums, B column vectors and a broadcast). The indirect part's 27 columns
// at 3 bands: 24 in 3 blocks of 3 rows, then 3 (padded to 8) in one block of all 9 rows.
__attribute__((target("avx2,fma"))) void addProductsAvx2(const float* y, const uint32_t* yOff, const float* v, int ldv,
                                                     int n, int rows, int cols, double* c, int ldc) {
  int j0 = 0;
  for (; j0 + 3 * kBlock <= ldv; j0 += 3 * kBlock) productRowsAvx2<3, 3>(y, yOff, v, ldv, n, rows, 0, j0, cols, c, ldc);
  switch ((ldv - j0) / kBlock) {
    case 2: productRowsAvx2<4, 2>(y, yOff, v, ldv, n, rows, 0, j0, cols, c, ldc); break;
    case 1: productRowsAvx2<9, 1>(y, yOff, v, ldv, n, rows, 0, j0, cols, c, ldc); break;
    default: break;
  }
}

void addProducts(const float* y, const uint32_t* yOff, const float* v, int ldv, int n, int rows, int cols, double* c,
                 int ldc) {
  if (n == 0) return;
  if (useVectorKernels())
    addProductsAvx2(y, yOff, v, ldv, n, rows, cols, c, ldc);
  else
    addProductsPortable(y, yOff, v, ldv, n, rows, cols, c, ldc);
}

// M⁰'s upper triangle from one packet's escaped rays, lane by lane: sums[p][l] += ye_a · y_b for
// the pairs p = (a ≤ b) in row order, where y_a is coefficient a of the eight lanes (ys, 8 floats
// apart) and ye_a the same with zeros in the lanes that did not escape (their SH values are
// finite: every lane's direction is a unit vector). One fused multiply-add per lane and pair in
// both paths, so they give the same bits.
void addDirectPortable(const float* ys, const int32_t* escaped, int n2, float* sums) {
  for (int a = 0, p = 0; a < n2; ++a)
    for (int b = a; b < n2; ++b, ++p)
      for (int l = 0; l < 8; ++l)
        sums[8 * p + l] = std::fma(escaped[l] ? ys[8 * a + l] : 0.0f, ys[8 * b + l], sums[8 * p + l]);
}

// addDirectPortable of the packets in `list` (ys: n2 · 8 floats a packet, escaped: 8 a packet),
// sums starting at zero: the same fused multiply-adds in the same order, lane by lane, but pair
// by pair over the packets with NB pairs' sums in registers, where packet by packet every sum is
// loaded and stored again. Packets with no escaped ray are left out of the list: they add
// zeros, which leave every sum as it is (sums from +0 never become −0).
template <int NB>
__attribute__((target("avx2,fma"))) void directPairsAvx2(const float* ys, const int32_t* escaped, const uint8_t* list,
                                                       int packets, int n2, int a, int b0, float* sums) {
  __m256 s[NB];
#pragma GCC unroll 8
  for (int i = 0; i < NB; ++i) s[i] = _mm256_setzero_ps();
  for (int k = 0; k < packets; ++k) {
    const int q = list[k];
    const float* y = ys + size_t(q) * n2 * 8;
    const __m256 mask = _mm256_castsi256_ps(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(escaped + 8 * q)));
    const __m256 ya = _mm256_and_ps(mask, _mm256_loadu_ps(y + 8 * a));
#pragma GCC unroll 8
    for (int i = 0; i < NB; ++i) s[i] = _mm256_fmadd_ps(ya, _mm256_loadu_ps(y + 8 * (b0 + i)), s[i]);
  }
  // Pair (a, b) is number a·n2 − a(a−1)/2 + (b − a) in row order.
  const int p0 = a * n2 - a * (a - 1) / 2 + (b0 - a);
#pragma GCC unroll 8
  for (int i = 0; i < NB; ++i) _mm256_storeu_ps(sums + 8 * (p0 + i), s[i]);
}

// M⁰'s upper triangle in blocks of at most 8 pairs (a, b0) … (a, b0 + NB − 1), row by row:
// block.template operator()<NB>(a, b0) for each (a call per block, a few per stream).
template <class Block>
void forPairBlocks(int n2, const Block& block) {
  for (int a = 0; a < n2; ++a)
    for (int b0 = a; b0 < n2; b0 += 8) {
      switch (std::min(8, n2 - b0)) {
        case 1: block.template operator()<1>(a, b0); break;
        case 2: block.template operator()<2>(a, b0); break;
        case 3: block.template operator()<3>(a, b0); break;
        case 4: block.template operator()<4>(a, b0); break;
        case 5: block.template operator()<5>(a, b0); break;
        case 6: block.template operator()<6>(a, b0); break;
        case 7: block.template operator()<7>(a, b0); break;
        default: block.template operator()<8>(a, b0); break;
      }
    }
}

void addDirectAvx2(const float* ys, const int32_t* escaped, const uint8_t* list, int packets, int n2, float* sums) {
  forPairBlocks(n2, [&]<int NB>(int a, int b0) { directPairsAvx2<NB>(ys, escaped, list, packets, n2, a, b0, sums); });
}

// directPairsAvx2 with AVX-512: two pairs (a, b) and (a, b + 1) in one sixteen-lane register
// (coefficients b and b + 1 of a packet lie side by side), the eight lanes of ye_a in both halves;
// the same fused multiply-add per lane and pair in the same order, so the same bits.
PRT_AVX512_BEGIN
template <int NB>
__attribute__((target("avx512f,fma"))) void directPairsAvx512(const float* ys, const int32_t* escaped,
                                                              const uint8_t* list, int packets, int n2, int a,
                                                              int b0, float* sums) {
  constexpr int NV = NB / 2;
  __m512 s[NV > 0 ? NV : 1];
  __m256 last = _mm256_setzero_ps();
#pragma GCC unroll 4
  for (int i = 0; i < NV; ++i) s[i] = _mm512_setzero_ps();
  for (int k = 0; k < packets; ++k) {
    const int q = list[k];
    const float* y = ys + size_t(q) * n2 * 8;
    const __m256 mask = _mm256_castsi256_ps(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(escaped + 8 * q)));
    const __m256 ya = _mm256_and_ps(mask, _mm256_loadu_ps(y + 8 * a));
    const __m512 ya2 = _mm512_castpd_ps(
        _mm512_insertf64x4(_mm512_castpd256_pd512(_mm256_castps_pd(ya)), _mm256_castps_pd(ya), 1));
#pragma GCC unroll 4
    for (int i = 0; i < NV; ++i) s[i] = _mm512_fmadd_ps(ya2, _mm512_loadu_ps(y + 8 * (b0 + 2 * i)), s[i]);
    if constexpr (NB % 2) last = _mm256_fmadd_ps(ya, _mm256_loadu_ps(y + 8 * (b0 + NB - 1)), last);
  }
  const int p0 = a * n2 - a * (a - 1) / 2 + (b0 - a);  // pair (a, b0)'s number in row order
#pragma GCC unroll 4
  for (int i = 0; i < NV; ++i) _mm512_storeu_ps(sums + 8 * (p0 + 2 * i), s[i]);
  if constexpr (NB % 2) _mm256_storeu_ps(sums + 8 * (p0 + NB - 1), last);
}
PRT_AVX512_END

void addDirectAvx512(const float* ys, const int32_t* escaped, const uint8_t* list, int packets, int n2, float* sums) {
  forPairBlocks(n2, [&]<int NB>(int a, int b0) { directPairsAvx512<NB>(ys, escaped, list, packets, n2, a, b0, sums); });
}

// Per instance with lower-order transfer (Tracer::litMeshes): where a lit hit's rows are (its
// corners: Tracer::cornerIndices).
struct LitMesh {
  const uint16_t* rows = nullptr;     // the front sides' rows (HalfRows), stride halves apart
  const uint16_t* backRows = nullptr;  // the back sides' (the front's where only one side is baked)
  size_t stride = 0;
  // One colour (AlbedoLookup::uniform): its rows hold ρ/π · t and its hits' ρ/π is 1
  // (StreamRows::rho); else ρ/π is looked up per hit.
  bool uniform = false;
};

// Streams traced before their lit hits are summed (a group): the corners of every lit hit are
// prefetched as its stream is classified, and read after the group's last stream is traced;
// their rows are prefetched then, a few hits ahead of the one whose light is computed
// (Tracer::sumLit). A lit hit's data lies at random places in arrays larger than the caches: read
// at once, each hit waited for two misses in a row (its corners, then their rows).
constexpr int kGroupStreams = 4;
constexpr int kGroup = kStream * kGroupStreams;
// Lit hits whose light g is computed, then multiplied in, at a time (g stays in the L1 cache).
constexpr int kChunk = 64;

// In a lit hit's yOff (StreamRows::hitYOff): the ray hit a back side (of a double-sided surface).
constexpr uint32_t kBackBit = 1u << 31;

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

// Storage for a stream of rays as packets of 8, left uninitialised (RayPacket8 is an
// implicit-lifetime aggregate, and SphereSet::fill starts every field of the lanes traced before
// Embree reads them): constructing 2 × 32 packets per trace would write more than the rays
// themselves for the inside test's 64.
static_assert(kStream % 8 == 0);
struct RayBuffer {
  alignas(64) std::byte bytes[sizeof(RayPacket8) * (kStream / 8)];
  RayPacket8* packets() { return reinterpret_cast<RayPacket8*>(bytes); }
};

struct ProbeAccum {
  int n2 = 0;
  std::vector<double> direct;    // n2 × n2, colourless
  std::vector<double> indirect;  // n2 × n2 RGB: row a holds n2 triples
  StreamRows stream;             // scratch of the stream being summed
  uint32_t rays = 0, backfaces = 0, escaped = 0;
  uint32_t backTwoSided = 0;  // hits on the back of double-sided faces
  float nearest = std::numeric_limits<float>::infinity();  // of the hits (any face)
  // Per cube face and lane of a packet (face · 8 + lane), summed over the packets in ray order:
  // the vector and portable classifications add in the same order. Summed lane by lane at the end.
  std::array<double, 48> sumD{}, sumD2{};
  std::array<uint32_t, 6> count{};
};

// A group's lit hits as the classification listed them (StreamRows), and where their rows are.
struct LitHits {
  const uint32_t *mesh, *tri, *yOff;  // yOff with kBackBit on a back side
  const float *b1, *b2;
  const float* rho;  // 4 floats a hit (ρ/π, then a zero: StreamRows::rho; with AVX-512 read only where one was looked up)
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
  // Always inlined, as prefetchLines says (until session 26 GCC deleted its calls, and the
  // kernels below prefetched no rows).
  [[gnu::always_inline]] void prefetchRows(uint32_t h) const {
    const uint16_t* t[3];
    rowsOf(h, t);
    const size_t bytes = meshes[mesh[h]].stride * sizeof(uint16_t);
    prefetchLines(t[0], bytes);  // not a loop over t: GCC would keep t on the stack for it
    prefetchLines(t[1], bytes);
    prefetchLines(t[2], bytes);
  }
};
// How many hits ahead of the one whose light is computed the rows are prefetched: with AVX-512,
// 4, 8, 16 and 32 measured alike, and so did the corner indices prefetched again 16 hits ahead
// (session 26; the measurements before it compared builds without any row prefetch).
constexpr uint32_t kRowsAhead = 8;

// The light a lit hit sends, g = ρ/π · (b0 t0 + b1 t1 + b2 t2), from its corners' transfer rows
// as halves (HalfRows: one 64-byte line a corner at 3 bands, where the floats took two: the
// reads of the rows are most of what a lit hit costs). g's `lanes` floats (3·n2 padded to
// whole 8-float vectors; the rows' padding is zero, so g's is too). The weighted sum is
// b2 t2 + (b1 t1 + b0 t0) in two fused multiply-adds, then one multiply by ρ/π, which is 1 for
// an instance of one colour (its rows hold ρ/π · t already: Tracer::LitMesh). Without F16C the
// same operations lane by lane (std::fma; lane i is RGB channel i % 3), so both give the same bits.
void litLightPortable(const uint16_t* t0, const uint16_t* t1, const uint16_t* t2, float b0, float b1, float b2,
                      const glm::vec3& rho, int lanes, float* g) {
  for (int i = 0; i < lanes; ++i) {
    const float s = std::fma(b2, floatFromHalf(t2[i]), std::fma(b1, floatFromHalf(t1[i]), b0 * floatFromHalf(t0[i])));
    g[i] = rho[i % 3] * s;
  }
}

// litLightPortable of hits h0 … h0 + n − 1 of the lists, each into a row of ldg floats (3·n2
// padded to whole vectors).
void litLightsPortable(const LitHits& in, uint32_t h0, uint32_t n, float* g, int ldg) {
  for (uint32_t h = h0; h < h0 + n; ++h) {
    const uint16_t* t[3];
    in.rowsOf(h, t);
    const float b1 = in.b1[h], b2 = in.b2[h], *rho = in.rho + 4 * size_t(h);
    litLightPortable(t[0], t[1], t[2], 1.0f - b1 - b2, b1, b2, glm::vec3(rho[0], rho[1], rho[2]), ldg,
                     g + size_t(h - h0) * ldg);
  }
}

// The same with F16C, as one call, the rows of the hit kRowsAhead further on prefetched. K is
// ldg / 8 where it is known at compile time (1, 2, 4 and 6: one to four bands), so that the loop
// over a row's vectors unrolls and ρ's permutation for each is a register; 0 reads it from ldg.
template <int K>
__attribute__((target("avx2,f16c,fma"))) void litLightsF16c(const LitHits& in, uint32_t h0, uint32_t n, float* g,
                                                           int ldg) {
  const int vectors = K ? K : ldg / 8;
  // ρ's channels in the lanes of vectors k % 3 = 0, 1, 2 (lane i of vector k is channel (8k + i) % 3).
  const __m256i order[3] = {_mm256_setr_epi32(0, 1, 2, 0, 1, 2, 0, 1), _mm256_setr_epi32(2, 0, 1, 2, 0, 1, 2, 0),
                            _mm256_setr_epi32(1, 2, 0, 1, 2, 0, 1, 2)};
  for (uint32_t h = h0; h < h0 + n; ++h) {
    if (h + kRowsAhead < in.count) in.prefetchRows(h + kRowsAhead);
    const uint16_t* t[3];
    in.rowsOf(h, t);
    const float b1 = in.b1[h], b2 = in.b2[h];
    const __m256 rho = _mm256_castps128_ps256(_mm_loadu_ps(in.rho + 4 * size_t(h)));
    const __m256 rp[3] = {_mm256_permutevar8x32_ps(rho, order[0]), _mm256_permutevar8x32_ps(rho, order[1]),
                          _mm256_permutevar8x32_ps(rho, order[2])};
    const __m256 w0 = _mm256_set1_ps(1.0f - b1 - b2), w1 = _mm256_set1_ps(b1), w2 = _mm256_set1_ps(b2);
    float* out = g + size_t(h - h0) * ldg;
#pragma GCC unroll 8
    for (int k = 0; k < vectors; ++k) {
      const __m256 f0 = _mm256_cvtph_ps(_mm_load_si128(reinterpret_cast<const __m128i*>(t[0]) + k));
      const __m256 f1 = _mm256_cvtph_ps(_mm_load_si128(reinterpret_cast<const __m128i*>(t[1]) + k));
      const __m256 f2 = _mm256_cvtph_ps(_mm_load_si128(reinterpret_cast<const __m128i*>(t[2]) + k));
      const __m256 sum = _mm256_fmadd_ps(w2, f2, _mm256_fmadd_ps(w1, f1, _mm256_mul_ps(w0, f0)));
      _mm256_storeu_ps(out + 8 * k, _mm256_mul_ps(rp[k % 3], sum));
    }
  }
}


// M += Σ y gᵀ over hits h0 … h0 + n − 1 of the lists, for R = n2 ≤ 9 (3·n2 ≤ 32 columns: V
// vectors of 16 floats; rows of 32 halves), straight from the classification's lists: each hit's
// rows are found as it is multiplied in (their corner indices were prefetched as it was
// classified), and the rows of the hit kRowsAhead further on are prefetched. Its light g is
// computed in registers, and the R × V sums over the hits stay in registers. The same operations
// per element in the same order as litLightsF16c then addProducts (a multiply, two fused
// multiply-adds and the multiply by ρ/π, then one fused multiply-add per hit into sums from zero,
// added to c at the end), so the same bits. Rho = false leaves out the multiply by ρ/π, where
// every hit's is 1 (x · 1 is x): the same bits again. (A first pass that wrote each hit's row
// pointers into a record, the rows prefetched there, then this loop over the records, spent
// about a quarter more time on the lit hits: session 25, docs/bake.md.)
PRT_AVX512_BEGIN
template <int R, bool Rho>
__attribute__((target("avx512f"))) void litListedAvx512(const LitHits& in, uint32_t h0, uint32_t n, double* c) {
  constexpr int V = (3 * R + 15) / 16, cols = 3 * R;
  constexpr int kRound = _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC;  // explicit: never contracted into FMAs
  // ρ's channels in the lanes of vector v (lane i is channel (16v + i) % 3).
  const __m512i order[2] = {_mm512_setr_epi32(0, 1, 2, 0, 1, 2, 0, 1, 2, 0, 1, 2, 0, 1, 2, 0),
                            _mm512_setr_epi32(1, 2, 0, 1, 2, 0, 1, 2, 0, 1, 2, 0, 1, 2, 0, 1)};
  __m512 s[R][V];
#pragma GCC unroll 16
  for (int a = 0; a < R; ++a)
#pragma GCC unroll 2
    for (int v = 0; v < V; ++v) s[a][v] = _mm512_setzero_ps();
  for (uint32_t h = h0; h < h0 + n; ++h) {
    if (h + kRowsAhead < in.count) in.prefetchRows(h + kRowsAhead);
    const uint16_t* t[3];
    in.rowsOf(h, t);
    const float b1 = in.b1[h], b2 = in.b2[h];
    const __m512 w0 = _mm512_set1_ps(1.0f - b1 - b2), w1 = _mm512_set1_ps(b1), w2 = _mm512_set1_ps(b2);
    const __m512 rho = Rho ? _mm512_castps128_ps512(_mm_loadu_ps(in.rho + 4 * size_t(h))) : _mm512_setzero_ps();
    __m512 g[V];
#pragma GCC unroll 2
    for (int v = 0; v < V; ++v) {
      const __m512 f0 = _mm512_cvtph_ps(_mm256_load_si256(reinterpret_cast<const __m256i*>(t[0]) + v));
      const __m512 f1 = _mm512_cvtph_ps(_mm256_load_si256(reinterpret_cast<const __m256i*>(t[1]) + v));
      const __m512 f2 = _mm512_cvtph_ps(_mm256_load_si256(reinterpret_cast<const __m256i*>(t[2]) + v));
      const __m512 sum = _mm512_fmadd_ps(w2, f2, _mm512_fmadd_ps(w1, f1, _mm512_mul_round_ps(w0, f0, kRound)));
      g[v] = Rho ? _mm512_mul_round_ps(_mm512_permutexvar_ps(order[v], rho), sum, kRound) : sum;
    }
    const float* yh = in.y + (in.yOff[h] & ~kBackBit);
#pragma GCC unroll 16
    for (int a = 0; a < R; ++a) {
      const __m512 ya = _mm512_set1_ps(yh[size_t(a) * 8]);
#pragma GCC unroll 2
      for (int v = 0; v < V; ++v) s[a][v] = _mm512_fmadd_ps(ya, g[v], s[a][v]);
    }
  }
#pragma GCC unroll 16
  for (int a = 0; a < R; ++a)
#pragma GCC unroll 2
    for (int v = 0; v < V; ++v) {
      alignas(64) float t[16];
      _mm512_store_ps(t, s[a][v]);
      for (int l = 0; l < 16 && 16 * v + l < cols; ++l) c[size_t(a) * cols + 16 * v + l] += double(t[l]);
    }
}
PRT_AVX512_END

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

// What classifyAvx512 counts of a stream's rays.
struct StreamTally {
  uint32_t backs, backsTwoSided, escapes;
  float nearest;
};

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

// The per-ray classification of Tracer::trace (the full set of rays) for `packets` whole packets
// with AVX2: what a packet hit, its counts and its lit-hit entries eight lanes at once; its
// moments lane by lane, as the portable loop adds them (so the same bits). The lit hits' corners
// are left to Tracer::trace to prefetch.
__attribute__((target("avx2"))) void classifyAvx2(const RayPacket8* batch, uint32_t packets,
                                                  const uint32_t* meshFlags, uint32_t yBase, uint32_t n2, double cap,
                                                  StreamRows& rows, uint32_t& nLit, int32_t* escapedLanes,
                                                  ProbeAccum& acc, StreamTally& t);

// The per-ray classification of Tracer::trace (the full set of rays) for `packets` whole packets,
// eight lanes at once with AVX-512: the same counts, lit-hit entries in the same order, the same
// escaped lanes, and the same moments (each face and lane's sums in the same order, the
// multiplies and adds rounded one by one as the portable loop's).
PRT_AVX512_BEGIN
__attribute__((target("avx512f,avx512vl,avx512dq,avx512bw"))) void classifyAvx512(
    const RayPacket8* batch, uint32_t packets, const uint32_t* meshFlags, const uint32_t* const* corners, uint32_t yBase,
    uint32_t n2, double cap, StreamRows& rows, uint32_t& nLit, int32_t* escapedLanes, ProbeAccum& acc, StreamTally& t);
// The counts alone (the inside test), with AVX-512: the same as Tracer::trace's loop.
__attribute__((target("avx512f,avx512vl,avx512dq,avx512bw"))) StreamTally tallyAvx512(const RayPacket8* batch,
                                                                                    uint32_t packets,
                                                                                    const uint32_t* meshFlags);
PRT_AVX512_END

struct Tracer {
  const Scene& scene;
  const RayScene& rays;
  // The lower-order surface transfer as halves, per instance (its rows: vertex × side; empty
  // where the instance has none, and no entries without bounces): what litMeshes points into.
  const std::vector<HalfRows>& lowerHalf;
  const AlbedoLookup& albedo;
  int bands;
  uint64_t seed;
  float maxDistance;
  std::vector<char> twoSided;  // per Scene::meshes entry: bakesBackSide
  // Per Scene::meshes entry (at least one entry): kTwoSided, and kLit where its hits send light
  // (it has lower-order transfer).
  static constexpr uint8_t kTwoSided = 1, kLit = 2;
  std::vector<uint32_t> meshFlags;  // 32-bit: the vector classifications gather them
  // Per Scene::meshes entry with lower-order transfer: where a lit hit's rows are (its corners:
  // cornerIndices).
  std::vector<LitMesh> litMeshes;
  // Per Scene::meshes entry: its triangles' corners, 3 per triangle, where it sends light; else null.
  // An array of their own, which classifyAvx512 reads.
  std::vector<const uint32_t*> cornerIndices;
  bool allLitUniform = true;  // every instance in litMeshes has one colour: no ρ/π is looked up
  mutable TraceClock inEmbree;  // all threads' time inside Embree's calls (ProbeStats::traceSeconds)
  mutable TraceClock inGather;  // and inside the lit hits' gather, sumLit (ProbeStats::gatherSeconds)

  void intersect8(RayPacket8* p, size_t n) const { inEmbree.time([&] { rays.intersect8(p, n); }); }
  void occluded(Ray* r, size_t n) const { inEmbree.time([&] { rays.occluded(r, n); }); }

  // Traces `n` sphere directions from x. full = reset acc, then accumulate M and moments;
  // otherwise only count rays and back faces into acc (the inside test). False when an
  // interrupt was requested before it finished (polled per stream of rays, so a probe with
  // millions of samples still stops at once); acc is then incomplete.
  bool trace(const glm::vec3& x, uint32_t n, uint64_t stream, bool full, ProbeAccum& acc) const {
    const int n2 = bands * bands;
    if (full) {  // start afresh, keeping the matrices' storage
      acc.n2 = n2;
      acc.direct.assign(size_t(n2) * n2, 0.0);
      acc.indirect.assign(size_t(n2) * n2 * 3, 0.0);
      acc.rays = acc.backfaces = acc.escaped = acc.backTwoSided = 0;
      acc.nearest = std::numeric_limits<float>::infinity();
      acc.sumD = {};
      acc.sumD2 = {};
      acc.count = {};
      acc.stream.reset(bands);
    }
    const SphereSet set(seed, stream);
    StreamRows& rows = acc.stream;
    const bool vector = useVectorKernels();
    RayBuffer buffer;
    RayPacket8* batch = buffer.packets();
    alignas(32) int32_t escapedLanes[kStream];  // per ray of the stream: −1 where it escaped, else 0
    // The group's lit hits so far (rows.hitMesh …).
    uint32_t nLit = 0;
    for (uint32_t first = 0; first < n; first += kStream) {
      if (interruptRequested()) return false;
      const uint32_t count = std::min<uint32_t>(kStream, n - first);
      const uint32_t inGroup = first % kGroup;  // the stream's first ray within its group
      if (first == 0)
        set.fill(batch, x, first, count);
      else  // the first stream's packets, all of them (it was the longest), from the same origin
        set.refill(batch, first, count);
      intersect8(batch, count);
      // Per ray, without branches on what it hit (which no predictor guesses): counts, the
      // moments of its face, and its place in the list of lit hits (written, the list's length
      // advanced where it belongs). A ray that escapes keeps tfar = ∞ and ng = 0, so it is
      // nearer than nothing and never a back face, and its depth is the cap. A packet's faces,
      // SH values and M⁰ sums are computed eight lanes at once.
      uint32_t backs = 0, backsTwoSided = 0, escapes = 0;
      const uint32_t litBefore = nLit;
      float nearest = acc.nearest;
      const double cap = maxDistance;
      float* groupYs = full ? rows.ys.data() + size_t(inGroup) * n2 : nullptr;  // the stream's packets
      if (full && !vector) std::fill(rows.directSums.begin(), rows.directSums.end(), 0.0f);
      uint32_t p0 = 0;  // the packets before p0 are classified
      uint32_t litPrefetched = litBefore;  // the lit hits before it have their corners fetched
      auto addTally = [&](const StreamTally& t) {  // of the whole packets, counted by a kernel
        p0 = count / 8 * 8;
        backs += t.backs;
        backsTwoSided += t.backsTwoSided;
        escapes += t.escapes;
        nearest = std::min(nearest, t.nearest);
      };
      if (full) {
        for (uint32_t q = 0; q < count; q += 8) {
          const RayPacket8& r = batch[q >> 3];
          sh::evaluate8(bands, r.dirX, r.dirY, r.dirZ, groupYs + size_t(q) * n2);
        }
        // The whole packets with AVX-512 or AVX2; a last, partial one lane by lane below.
        const uint32_t packets = count / 8, yBase = inGroup * uint32_t(n2);
        StreamTally t{};
        if (useAvx512Kernels()) {
          classifyAvx512(batch, packets, meshFlags.data(), cornerIndices.data(), yBase, uint32_t(n2), cap, rows, nLit,
                         escapedLanes, acc, t);
          litPrefetched = nLit;
          addTally(t);
        } else if (vector) {
          classifyAvx2(batch, packets, meshFlags.data(), yBase, uint32_t(n2), cap, rows, nLit, escapedLanes, acc, t);
          addTally(t);
        }
      } else if (useAvx512Kernels()) {  // the inside test: the whole packets' counts
        addTally(tallyAvx512(batch, count / 8, meshFlags.data()));
      }
      for (; p0 < count; p0 += 8) {
        const RayPacket8& r = batch[p0 >> 3];
        const int lanes = int(std::min<uint32_t>(8, count - p0));
        alignas(32) int32_t faces[8];
        int32_t* escaped = escapedLanes + p0;  // this packet's 8 lanes
        alignas(32) float axis[8];  // |the direction's component along its face's axis|
        if (full) packetFaces(r, faces, axis);
        for (int l = 0; l < lanes; ++l) {
          const bool hit = r.hit(l);
          const uint32_t flags = meshFlags[hit ? r.mesh[l] : 0];
          const bool backside = r.backface(l);
          const bool back = backside && !(flags & kTwoSided);
          backs += back;
          backsTwoSided += backside && !back;
          const float tfar = r.tfar[l];
          nearest = std::min(nearest, tfar);
          escapes += !hit;
          if (!full) continue;  // the inside test: counts only
          rows.hitMesh[nLit] = r.mesh[l];
          rows.hitTri[nLit] = r.tri[l];
          rows.hitU[nLit] = r.u[l];
          rows.hitV[nLit] = r.v[l];
          rows.hitYOff[nLit] = ((inGroup + p0) * uint32_t(n2) + uint32_t(l)) | (backside ? kBackBit : 0u);
          nLit += hit && !back && (flags & kLit);
          escaped[l] = -int32_t(!hit);  // lanes past the count stay 0 (zeroed below)
          addMoment(acc, faces[l], l, tfar, axis[l], cap);
        }
        if (!full) continue;
        for (int l = lanes; l < 8; ++l) escaped[l] = 0;
      }
      acc.rays += count;
      acc.backfaces += backs;
      acc.backTwoSided += backsTwoSided;
      acc.escaped += escapes;
      acc.nearest = nearest;
      if (!full) continue;
      // The corners of the stream's lit hits (those classifyAvx512 has not fetched), fetched while
      // the group's other streams trace.
      for (uint32_t h = litPrefetched; h < nLit; ++h)
        __builtin_prefetch(cornerIndices[rows.hitMesh[h]] + 3 * size_t(rows.hitTri[h]));
      // The direct part of the escaped rays, M⁰ += Σ y yᵀ, over the packets with one (a packet
      // whose rays all hit adds zeros, which leave the sums as they are): lane by lane, or with
      // AVX2 pair by pair over the packets.
      uint8_t escapedPackets[kStream / 8];
      int nEscaped = 0;
      for (uint32_t q = 0; q < (count + 7) / 8; ++q) {
        const int32_t* e = escapedLanes + 8 * q;
        escapedPackets[nEscaped] = uint8_t(q);
        nEscaped += (e[0] | e[1] | e[2] | e[3] | e[4] | e[5] | e[6] | e[7]) != 0;
      }
      if (vector && nEscaped) {
        if (useAvx512Kernels())
          addDirectAvx512(groupYs, escapedLanes, escapedPackets, nEscaped, n2, rows.directSums.data());
        else
          addDirectAvx2(groupYs, escapedLanes, escapedPackets, nEscaped, n2, rows.directSums.data());
      }
      for (int k = 0; !vector && k < nEscaped; ++k) {
        const uint32_t q = escapedPackets[k];
        addDirectPortable(groupYs + size_t(q) * 8 * n2, escapedLanes + 8 * q, n2, rows.directSums.data());
      }
      // The stream's M⁰ sums into the double matrix's upper triangle, lane by lane in order
      // (nothing to add where no ray escaped).
      for (int a = 0, p = 0; nEscaped && a < n2; ++a)
        for (int b = a; b < n2; ++b, ++p) {
          const float* lane = &rows.directSums[size_t(8 * p)];
          double sum = 0.0;
          for (int l = 0; l < 8; ++l) sum += double(lane[l]);
          acc.direct[size_t(a) * n2 + b] += sum;
        }
      // The indirect part of the group's lit hits, once its last stream is traced: M += Σ y gᵀ.
      if (inGroup + count == uint32_t(kGroup) || first + count == n) {
        if (nLit) inGather.time([&] { sumLit(rows, nLit, acc.indirect.data()); });
        nLit = 0;
      }
    }
    if (full)  // M⁰ is symmetric: its lower triangle from the upper
      for (int a = 0; a < n2; ++a)
        for (int b = 0; b < a; ++b) acc.direct[size_t(a) * n2 + b] = acc.direct[size_t(b) * n2 + a];
    return true;
  }

  // ρ/π of each of a group's lit hits into rows.rho: looked up (eight at a time where AVX-512 is)
  // on textured or vertex-coloured instances, 1 on an instance of one colour (its rows hold ρ/π · t
  // already). Returns how many were looked up.
  uint32_t lookUpAlbedo(StreamRows& rows, uint32_t hits) const {
    StreamRows::Lookups& a = rows.albedo;
    uint32_t n = 0;
    for (uint32_t h = 0; h < hits; ++h) {
      const uint32_t mesh = rows.hitMesh[h];
      static constexpr float kInTheRows[4] = {1.0f, 1.0f, 1.0f, 0.0f};  // ρ/π, then a zero
      std::memcpy(&rows.rho[4 * size_t(h)], kInTheRows, sizeof kInTheRows);
      if (litMeshes[mesh].uniform) continue;
      a.hit[n] = h, a.mesh[n] = mesh, a.tri[n] = rows.hitTri[h], a.b1[n] = rows.hitU[h], a.b2[n] = rows.hitV[h];
      ++n;
    }
    albedo.atMany(a.mesh.data(), a.tri.data(), a.b1.data(), a.b2.data(), n, a.rgb.data());
    for (uint32_t k = 0; k < n; ++k) {
      const glm::vec3 rho = a.rgb[k] * float(1.0 / M_PI);
      float* r = &rows.rho[4 * size_t(a.hit[k])];
      r[0] = rho.r, r[1] = rho.g, r[2] = rho.b, r[3] = 0.0f;
    }
    return n;
  }

  // M += Σ y gᵀ over a group's lit hits, g = ρ/π · t(h), chunk by chunk (kChunk hits summed in
  // float, then added to M), reading the hits from the classification's lists and prefetching
  // their rows a few hits ahead. With AVX-512 up to 3 bands (rows of 32 halves: HalfRows pads
  // 3·n2 ≤ 27 to one line), g and its products in registers (litListedAvx512); else g of a chunk
  // into rows.gHit, then its products (addProducts).
  void sumLit(StreamRows& rows, uint32_t hits, double* indirect) const {
    const int n2 = rows.n2, ldg = padded(3 * n2);
    const bool avx512 = useAvx512Kernels() && n2 <= 9;
    // With AVX-512, without a hit on a textured or vertex-coloured instance, every ρ/π is 1 and
    // goes unread; the other paths multiply by it.
    const uint32_t looked = avx512 && allLitUniform ? 0 : lookUpAlbedo(rows, hits);
    const LitHits in{rows.hitMesh.data(), rows.hitTri.data(), rows.hitYOff.data(), rows.hitU.data(),
                     rows.hitV.data(),    rows.rho.data(),    litMeshes.data(),     cornerIndices.data(),
                     rows.ys.data(),      hits};
    for (uint32_t h = 0; h < std::min(hits, kRowsAhead); ++h) in.prefetchRows(h);
    for (uint32_t h0 = 0; h0 < hits; h0 += kChunk) {
      const uint32_t k = std::min<uint32_t>(kChunk, hits - h0);
      if (avx512) {
        auto products = [&]<bool Rho>() {
          switch (n2) {
            case 1: return litListedAvx512<1, Rho>(in, h0, k, indirect);
            case 4: return litListedAvx512<4, Rho>(in, h0, k, indirect);
            default: return litListedAvx512<9, Rho>(in, h0, k, indirect);
          }
        };
        if (looked)
          products.template operator()<true>();
        else
          products.template operator()<false>();
        continue;
      }
      if (useVectorKernels())
        switch (ldg / 8) {
          case 1: litLightsF16c<1>(in, h0, k, rows.gHit.data(), ldg); break;
          case 2: litLightsF16c<2>(in, h0, k, rows.gHit.data(), ldg); break;
          case 4: litLightsF16c<4>(in, h0, k, rows.gHit.data(), ldg); break;
          case 6: litLightsF16c<6>(in, h0, k, rows.gHit.data(), ldg); break;
          default: litLightsF16c<0>(in, h0, k, rows.gHit.data(), ldg);
        }
      else
        litLightsPortable(in, h0, k, rows.gHit.data(), ldg);
      uint32_t* yOff = rows.hitYOff.data() + h0;  // read: from here the products' offsets
      for (uint32_t h = 0; h < k; ++h) yOff[h] &= ~kBackBit;
      addProducts(rows.ys.data(), yOff, rows.gHit.data(), ldg, int(k), n2, 3 * n2, indirect, 3 * n2);
    }
  }
};

// A lane mask's sign bits, lane l at bit l.
__attribute__((target("avx2"), always_inline)) inline uint32_t laneBits(__m256i m) {
  return uint32_t(_mm256_movemask_ps(_mm256_castsi256_ps(m)));
}
// v's lanes in the order `pack` gives (kPacking), stored at `to` (8 lanes: room to spare).
__attribute__((target("avx2"), always_inline)) inline void packLanes(void* to, __m256i v, __m256i pack) {
  _mm256_storeu_si256(static_cast<__m256i*>(to), _mm256_permutevar8x32_epi32(v, pack));
}
__attribute__((target("avx2"))) void classifyAvx2(const RayPacket8* batch, uint32_t packets,
                                                  const uint32_t* meshFlags, uint32_t yBase, uint32_t n2, double cap,
                                                  StreamRows& rows, uint32_t& nLit, int32_t* escapedLanes,
                                                  ProbeAccum& acc, StreamTally& t) {
  const __m256i ones = _mm256_set1_epi32(-1), zero = _mm256_setzero_si256();
  const __m256i invalid = _mm256_set1_epi32(int(Ray::kInvalid)), lanes = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
  const __m256i twoSidedBit = _mm256_set1_epi32(Tracer::kTwoSided), litBit = _mm256_set1_epi32(Tracer::kLit);
  const __m256i backBit = _mm256_set1_epi32(int(kBackBit));
  __m256 nearest = _mm256_set1_ps(std::numeric_limits<float>::infinity());
  uint32_t n = nLit, backs = 0, backsTwoSided = 0, escapes = 0;
  for (uint32_t p = 0; p < packets; ++p) {
    const RayPacket8& r = batch[p];
    const __m256i mesh = _mm256_load_si256(reinterpret_cast<const __m256i*>(r.mesh));
    const __m256i hit = _mm256_xor_si256(_mm256_cmpeq_epi32(mesh, invalid), ones);
    const __m256i flags =
        _mm256_mask_i32gather_epi32(zero, reinterpret_cast<const int*>(meshFlags), mesh, hit, 4);
    // Ray::backface: ng · d > 0, as glm::dot: (x·x' + y·y') + z·z', each rounded (no FMA here).
    const __m256 dot = _mm256_add_ps(
        _mm256_add_ps(_mm256_mul_ps(_mm256_load_ps(r.ngX), _mm256_load_ps(r.dirX)),
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
  h.twoSided = _mm256_test_epi32_mask(flags, _mm256_set1_epi32(Tracer::kTwoSided));
  h.lit = _mm256_test_epi32_mask(flags, _mm256_set1_epi32(Tracer::kLit));
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
__attribute__((target("avx512f,avx512vl,avx512dq,avx512bw"), always_inline)) inline void addToTally(PacketTally& a,
                                                                                                  const PacketHits& h) {
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

__attribute__((target("avx512f,avx512vl,avx512dq,avx512bw"))) StreamTally tallyAvx512(const RayPacket8* batch,
                                                                                    uint32_t packets,
                                                                                    const uint32_t* meshFlags) {
  PacketTally a = startTally();
  for (uint32_t p = 0; p < packets; ++p) addToTally(a, packetHitsAvx512(batch[p], meshFlags));
  return finishTally(a);
}

__attribute__((target("avx512f,avx512vl,avx512dq,avx512bw"))) void classifyAvx512(
    const RayPacket8* batch, uint32_t packets, const uint32_t* meshFlags, const uint32_t* const* corners, uint32_t yBase,
    uint32_t n2, double cap, StreamRows& rows, uint32_t& nLit, int32_t* escapedLanes, ProbeAccum& acc, StreamTally& t) {
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
    const __mmask8 face[6] = {__mmask8(onX & posX), __mmask8(onX & ~posX), __mmask8(onY & posY),
                              __mmask8(onY & ~posY), __mmask8(onZ & posZ), __mmask8(onZ & ~posZ)};
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

// Back faces of any kind, one-sided or double-sided, on more than this share of a probe's rays:
// it is inside solid mass.
constexpr double kSolidShare = 0.75;

// Inside geometry: back faces of one-sided surfaces on more than `threshold` of the rays, or
// back faces of any kind on more than kSolidShare.
bool insideGeometry(const ProbeAccum& a, double threshold) {
  if (!a.rays) return false;
  return double(a.backfaces) > threshold * a.rays || double(a.backfaces + a.backTwoSided) > kSolidShare * a.rays;
}

// What the assembly needs of one lattice point besides its transfer; the checkpoint stores it
// as is (no padding, so the record holds no undefined bytes).
struct ProbeSlot {
  uint8_t valid = 0, moved = 0;
  uint8_t outside = 0;  // free, but where no receiver goes: not baked (ProbeSettings::region)
  uint8_t reserved = 0;
  uint32_t traced = 0;  // rays cast for this lattice point: tests, candidates, full set
  glm::vec3 offset{0.0f};
  float skyVisibility = 0.0f;
  std::array<glm::vec2, 6> moments{};
};
static_assert(sizeof(ProbeSlot) == 72 && std::is_trivially_copyable_v<ProbeSlot>);

// The results of every lattice point, in lattice order: what the checkpoint's chunk records
// are written from. Shared with the checkpoint's writer, so a save can never read freed
// memory, whenever it happens.
struct LatticeResults {
  std::vector<ProbeSlot> slots;
  // Per chunk (kProbeChunk points), the transfer of its valid points in lattice order, stride
  // floats each: M (n2² RGB triples), then the upper triangle of its direct part M⁰
  // (n2(n2+1)/2 floats, ProbeGrid::direct's layout). Only valid points hold one: on a sparse
  // level (a closed map keeps a few percent of its lattice) a matrix for every point, written
  // at a few of them, had most of its pages faulted in all the same.
  std::vector<std::vector<float>> chunks;
  size_t stride = 0;
};

// Chunk record: the chunk's slots, then the transfer of its valid points only.
void writeProbeChunk(const LatticeResults& res, const Chunk& c, ByteWriter& w) {
  w.putArray(res.slots.data() + c.begin, c.end - c.begin);
  const std::vector<float>& records = res.chunks[c.index];
  size_t valid = 0;
  for (size_t i = c.begin; i < c.end; ++i) valid += res.slots[i].valid;
  PRT_CHECK_EQ(records.size(), valid * res.stride);
  if (!records.empty()) w.write(records.data(), records.size() * sizeof(float));
}

void readProbeChunk(LatticeResults& res, const Chunk& c, ByteReader& r) {
  r.getArray(res.slots.data() + c.begin, c.end - c.begin);
  size_t valid = 0;
  for (size_t i = c.begin; i < c.end; ++i) {
    const ProbeSlot& slot = res.slots[i];
    if (slot.valid > 1 || slot.moved > 1 || slot.outside > 1 || (slot.valid && slot.outside)) r.fail("probe record");
    valid += slot.valid;
  }
  std::vector<float>& records = res.chunks[c.index];
  records.resize(valid * res.stride);  // read even when empty: a record too short fails
  r.read(records.data(), records.size() * sizeof(float));
}

// The lattice coordinate of linear index idx = x + dims.x·(y + dims.y·z).
glm::ivec3 latticeCoord(const glm::ivec3& dims, size_t idx) {
  return glm::ivec3(int(idx % dims.x), int((idx / dims.x) % dims.y), int(idx / (size_t(dims.x) * dims.y)));
}

// Relocation candidates, in a fixed order, as fractions of the spacing: along the axes, then
// towards the corners; all inside the probe's cell.
std::vector<glm::dvec3> relocationCandidates() {
  std::vector<glm::dvec3> candidates;
  for (double f : {0.25, 0.45})
    for (int axis = 0; axis < 3; ++axis)
      for (double sgn : {1.0, -1.0}) {
        glm::dvec3 o(0.0);
        o[axis] = sgn * f;
        candidates.push_back(o);
      }
  for (int c = 0; c < 8; ++c)
    candidates.push_back(glm::dvec3(c & 1 ? 0.3 : -0.3, c & 2 ? 0.3 : -0.3, c & 4 ? 0.3 : -0.3));
  return candidates;
}

// Bakes lattice points one at a time: the inside test, relocation, the full set of rays.
struct ProbeBaker {
  const Tracer& tracer;
  const ProbeGrid& grid;
  const ProbeSettings& settings;
  std::vector<glm::dvec3> candidates;

  ProbeBaker(const Tracer& t, const ProbeGrid& g, const ProbeSettings& s)
      : tracer(t), grid(g), settings(s), candidates(relocationCandidates()) {}

  // Lattice point idx into slot and out (n2² RGB floats, then M⁰'s upper triangle); quickFree: its quick inside test
  // (classifyLattice) passed. The double accumulators `acc` live only during this point's
  // trace: the matrix is converted to float at once, with the same per-probe arithmetic in a
  // fixed order, so the result does not depend on threads. False when interrupted first (slot
  // and out are then incomplete).
  bool bake(size_t idx, bool quickFree, ProbeAccum& acc, ProbeSlot& slot, float* out) const {
    const glm::ivec3 dims = grid.dims;
    const glm::ivec3 c = latticeCoord(dims, idx);
    const glm::dvec3 base = grid.latticePosition(c);
    slot = ProbeSlot{};
    glm::dvec3 offset(0.0);
    bool ok = quickFree;  // the quick test, traced by classifyLattice
    for (size_t k = 0; !ok && k < candidates.size(); ++k) {
      ProbeAccum cand;
      glm::dvec3 o = candidates[k] * grid.spacing;
      if (!tracer.trace(glm::vec3(base + o), kProbeTestRays, 2 * idx, false, cand)) return false;
      slot.traced += cand.rays;
      // A moved probe must be clearly outside: half the threshold.
      if (!insideGeometry(cand, 0.5 * settings.insideThreshold)) {
        ok = true;
        offset = o;
        slot.moved = 1;
      }
    }
    const float maxD = tracer.maxDistance;
    slot.moments.fill(glm::vec2(maxD, maxD * maxD));  // "nothing hit", kept by invalid probes
    if (ok) {
      if (!tracer.trace(glm::vec3(base + offset), uint32_t(settings.samples), 2 * idx + 1, true, acc)) return false;
      slot.traced += acc.rays;
      // The full set of rays decides too: the quick test can miss a thin enclosure.
      ok = !insideGeometry(acc, settings.insideThreshold);
    }
    slot.valid = ok;
    slot.offset = glm::vec3(offset);
    if (!ok) return true;
    for (int f = 0; f < 6; ++f)
      if (const uint32_t n = acc.count[f]) {
        double d = 0.0, d2 = 0.0;
        for (int l = 0; l < 8; ++l) {
          d += acc.sumD[size_t(8 * f + l)];
          d2 += acc.sumD2[size_t(8 * f + l)];
        }
        slot.moments[f] = glm::vec2(float(d / n), float(d2 / n));
      }
    slot.skyVisibility = acc.rays ? float(double(acc.escaped) / acc.rays) : 0.0f;
    const double w = 4.0 * M_PI / settings.samples;
    const size_t n2 = size_t(acc.n2);
    for (size_t k = 0; k < n2 * n2; ++k) {
      const glm::dvec3 v = w * (glm::dvec3(acc.direct[k]) + glm::dvec3(acc.indirect[3 * k], acc.indirect[3 * k + 1],
                                                                        acc.indirect[3 * k + 2]));
      out[3 * k] = float(v.r);
      out[3 * k + 1] = float(v.g);
      out[3 * k + 2] = float(v.b);
    }
    float* direct = out + 3 * n2 * n2;  // M⁰ is symmetric: its upper triangle, row by row
    for (size_t j = 0; j < n2; ++j)
      for (size_t i = j; i < n2; ++i) *direct++ = float(w * acc.direct[j * n2 + i]);
    return true;
  }
};


// ---- Where probes go (ProbeSettings::region, docs/probes.md "Where probes go").
// A lattice point is free when its quick test (kProbeTestRays sphere directions, stream 2·idx)
// sees back faces for at most the inside threshold. Of the free points, Auto keeps those where
// a receiver can be: near a surface (a hit within kNearSpacings spacings) or surrounded (surfaces
// fill more than kOpenAirShare of the sphere around it: rooms, streets, the air over a ground),
// and their neighbours. It drops open air far from everything (the void around a floating
// level, the sky high above a town), where a receiver gets the unoccluded light: there the
// scene fills at most kOpenAirShare of the sphere, which bounds what that light gets wrong.
// A scene with no surface near any lattice point (an empty scene) keeps every free point.
// Inside keeps only sealed space: two neighbouring free points are joined when the segment
// between them hits nothing; free points on the lattice's boundary whose ray outwards along
// that axis escapes touch the outside; what the flood from them does not reach is sealed in by
// the scene's surfaces.
constexpr double kNearSpacings = 2.0;
constexpr double kOpenAirShare = 0.2;

struct LatticeRegion {
  std::vector<uint8_t> free;  // per lattice point: the quick test passed
  std::vector<uint8_t> skip;  // per lattice point: not baked
  uint64_t freeCount = 0, sealed = 0, outside = 0, aboveLevel = 0;
  bool insideOnly = false;   // only sealed space is kept
  uint64_t rays = 0;
  bool interrupted = false;  // an interrupt was requested before the quick tests finished
};

// The free points of the lattice that the flood from outside (the comment above LatticeRegion) does not reach.
std::vector<uint8_t> sealedSpace(const Tracer& tracer, const ProbeGrid& grid, LatticeRegion& reg) {
  const glm::ivec3 dims = grid.dims;
  const size_t total = size_t(dims.x) * dims.y * dims.z;
  const size_t sy = size_t(dims.x), sz = size_t(dims.x) * dims.y;
  const size_t step[3] = {1, sy, sz};
  // Segments to the +x, +y, +z free neighbours, and outward rays of boundary points.
  std::vector<uint8_t> links(total, 0);  // bit a: joined to the +a neighbour; bit 3: touches the outside
  tbb::parallel_for(tbb::blocked_range<size_t>(0, total, 256), [&](const tbb::blocked_range<size_t>& r) {
    alignas(64) Ray batch[9];
    uint8_t bitOf[9];
    for (size_t idx = r.begin(); idx != r.end(); ++idx) {
      if (!reg.free[idx]) continue;
      const glm::ivec3 c = latticeCoord(dims, idx);
      const glm::vec3 x(grid.latticePosition(c));
      int n = 0;
      auto add = [&](int a, float sign, float tfar, uint8_t bit) {
        Ray& ray = batch[n];
        ray = Ray{};
        ray.org = x;
        ray.dir = glm::vec3(0.0f);
        ray.dir[a] = sign;
        ray.tfar = tfar;
        bitOf[n++] = bit;
      };
      for (int a = 0; a < 3; ++a) {
        if (c[a] + 1 < dims[a] && reg.free[idx + step[a]]) add(a, 1.0f, float(grid.spacing[a]), uint8_t(1u << a));
        if (c[a] == 0) add(a, -1.0f, std::numeric_limits<float>::infinity(), 8u);
        if (c[a] == dims[a] - 1) add(a, 1.0f, std::numeric_limits<float>::infinity(), 8u);
      }
      if (n == 0) continue;
      tracer.occluded(batch, size_t(n));
      for (int k = 0; k < n; ++k)
        if (!batch[k].occludedHit()) links[idx] |= bitOf[k];
    }
  });
  for (size_t idx = 0; idx < total; ++idx) {
    if (!reg.free[idx]) continue;
    const glm::ivec3 c = latticeCoord(dims, idx);
    for (int a = 0; a < 3; ++a)
      reg.rays += uint64_t(c[a] + 1 < dims[a] && reg.free[idx + step[a]]) + (c[a] == 0) + (c[a] == dims[a] - 1);
  }
  // The flood from the outside: sequential, in lattice order, the same for any thread count.
  std::vector<uint8_t> out(total, 0);
  std::vector<size_t> queue;
  for (size_t idx = 0; idx < total; ++idx)
    if (reg.free[idx] && (links[idx] & 8u)) {
      out[idx] = 1;
      queue.push_back(idx);
    }
  for (size_t head = 0; head < queue.size(); ++head) {
    const size_t idx = queue[head];
    const glm::ivec3 c = latticeCoord(dims, idx);
    for (int a = 0; a < 3; ++a) {
      if (c[a] + 1 < dims[a] && (links[idx] & (1u << a)) && !out[idx + step[a]]) {
        out[idx + step[a]] = 1;
        queue.push_back(idx + step[a]);
      }
      if (c[a] > 0 && (links[idx - step[a]] & (1u << a)) && !out[idx - step[a]]) {
        out[idx - step[a]] = 1;
        queue.push_back(idx - step[a]);
      }
    }
  }
  std::vector<uint8_t> sealed(total, 0);
  for (size_t idx = 0; idx < total; ++idx) {
    sealed[idx] = reg.free[idx] && !out[idx];
    reg.sealed += sealed[idx];
  }
  return sealed;
}

// Above the level: open sky straight up (+Y, glTF's up) and nothing within `height` straight
// down. Where a roofless level's walls surround a point, a receiver still stands on something:
// what lies higher above the ground than any receiver reaches is the void over the level.
bool aboveTheLevel(const Tracer& tracer, const glm::vec3& x, float height) {
  alignas(64) Ray batch[2];
  for (int k = 0; k < 2; ++k) {
    batch[k] = Ray{};
    batch[k].org = x;
    batch[k].dir = glm::vec3(0.0f, k == 0 ? 1.0f : -1.0f, 0.0f);
    batch[k].tfar = k == 0 ? std::numeric_limits<float>::infinity() : height;
  }
  tracer.occluded(batch, 2);
  return !batch[0].occludedHit() && !batch[1].occludedHit();
}

// The tracer's per-instance flags: which instances bake their back sides (twoSided), then
// meshFlags from them and from which instances send light (lowerHalf).
void setTwoSided(Tracer& tracer) {
  for (const MeshInstance& m : tracer.scene.meshes) tracer.twoSided.push_back(bakesBackSide(tracer.scene, m));
}
void setMeshFlags(Tracer& tracer) {
  const size_t n = tracer.scene.meshes.size();
  tracer.meshFlags.assign(std::max<size_t>(n, 1), 0);
  for (size_t k = 0; k < n; ++k)
    tracer.meshFlags[k] = uint32_t((tracer.twoSided[k] ? Tracer::kTwoSided : 0) |
                                   (k < tracer.lowerHalf.size() && !tracer.lowerHalf[k].empty() ? Tracer::kLit : 0));
}

// Whether f(j) holds for one of the 26 neighbours j of lattice point idx inside the lattice
// (linear indices, as latticeCoord's), stopping at the first.
template <class F>
bool anyNeighbour(const glm::ivec3& dims, size_t idx, F&& f) {
  const size_t sy = size_t(dims.x), sz = size_t(dims.x) * dims.y;
  const glm::ivec3 c = latticeCoord(dims, idx);
  for (int d = 0; d < 27; ++d) {
    const glm::ivec3 q = c + glm::ivec3(d % 3 - 1, (d / 3) % 3 - 1, d / 9 - 1);
    if (d == 13 || glm::any(glm::lessThan(q, glm::ivec3(0))) || glm::any(glm::greaterThanEqual(q, dims))) continue;
    if (f(size_t(q.x) + sy * size_t(q.y) + sz * size_t(q.z))) return true;
  }
  return false;
}

// alone: this process tests every point itself, even under MPI (placeProbes).
LatticeRegion classifyLattice(const Tracer& tracer, const ProbeGrid& grid, const ProbeSettings& settings,
                              bool alone = false) {
  using Region = ProbeSettings::Region;
  const glm::ivec3 dims = grid.dims;
  const size_t total = size_t(dims.x) * dims.y * dims.z;
  LatticeRegion reg;
  reg.free.assign(total, 0);
  reg.skip.assign(total, 0);
  reg.rays = uint64_t(total) * kProbeTestRays;
  std::vector<uint8_t> wanted(total, 0);  // free, and near a surface or enclosed
  std::vector<float> nearest(total, 0.0f);  // the quick test's nearest hit
  std::vector<uint8_t> high(total, 0);      // surrounded, but above the level (aboveTheLevel)
  const float nearDistance = float(kNearSpacings * std::max({grid.spacing.x, grid.spacing.y, grid.spacing.z}));
  // MPI ranks (ranks.h) test their share of the points, point i on rank i mod N, and trade
  // the outcomes (what the rest of the classification reads of a point), as refinement trades
  // its points; shards, which run apart, each test the whole lattice.
  Ranks& spread = ranks();
  const bool shared = !alone && spread.exchanges();
  std::atomic<bool> stopped{false};
  tbb::parallel_for(tbb::blocked_range<size_t>(0, total, 256), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t idx = r.begin(); idx != r.end(); ++idx) {
      if (stopped.load(std::memory_order_relaxed)) return;
      if (shared && !spread.owns(idx)) continue;
      ProbeAccum test;
      const glm::vec3 x(grid.latticePosition(latticeCoord(dims, idx)));
      if (!tracer.trace(x, kProbeTestRays, 2 * idx, false, test)) {
        stopped = true;
        return;
      }
      reg.free[idx] = !insideGeometry(test, settings.insideThreshold);
      nearest[idx] = test.nearest;
      const bool nearSurface = test.nearest <= nearDistance;
      bool surrounded = double(test.rays - test.escaped) > kOpenAirShare * double(test.rays);
      if (reg.free[idx] && !nearSurface && surrounded && settings.maxHeight > 0.0 && settings.region == Region::Auto &&
          aboveTheLevel(tracer, x, float(settings.maxHeight))) {
        surrounded = false;
        high[idx] = 1;
      }
      wanted[idx] = reg.free[idx] && (nearSurface || surrounded);
    }
  });
  if (stopped) {
    reg.interrupted = true;
    return reg;
  }
  if (shared) {
    struct Outcome {
      float nearest;
      uint8_t free, wanted, high, unused;
    };
    static_assert(sizeof(Outcome) == 8 && std::is_trivially_copyable_v<Outcome>);
    std::string mine;
    mine.reserve((total / size_t(spread.size()) + 1) * sizeof(Outcome));
    for (size_t idx = 0; idx < total; ++idx) {
      if (!spread.owns(idx)) continue;
      const Outcome o{nearest[idx], reg.free[idx], wanted[idx], high[idx], 0};
      mine.append(reinterpret_cast<const char*>(&o), sizeof o);
    }
    const std::vector<std::string> all = spread.gather(std::move(mine), true);
    std::vector<size_t> at(all.size(), 0);
    for (size_t idx = 0; idx < total; ++idx) {
      const size_t from = idx % all.size();
      if (int(from) == spread.rank()) continue;
      if (at[from] + sizeof(Outcome) > all[from].size())
        throw Error(cat("rank exchange of the probe placement: rank ", from, " sent too few points"));
      Outcome o;
      std::memcpy(&o, all[from].data() + at[from], sizeof o);
      at[from] += sizeof o;
      nearest[idx] = o.nearest;
      reg.free[idx] = o.free;
      wanted[idx] = o.wanted;
      high[idx] = o.high;
    }
  }
  for (uint8_t f : reg.free) reg.freeCount += f;
  const bool anyWanted = std::find(wanted.begin(), wanted.end(), uint8_t(1)) != wanted.end();
  const bool everywhere = settings.region == Region::Everywhere || (settings.region == Region::Auto && !anyWanted);
  std::vector<uint8_t> keep(total, 0);
  if (everywhere) {
    keep = reg.free;
  } else if (settings.region == Region::Auto) {
    for (size_t idx = 0; idx < total; ++idx)
      keep[idx] = reg.free[idx] && (wanted[idx] || anyNeighbour(dims, idx, [&](size_t j) { return wanted[j] != 0; }));
  } else {
    keep = sealedSpace(tracer, grid, reg);
    reg.insideOnly = true;
  }
  // A point in geometry is tried for relocation unless it borders only free points left out
  // (and geometry), or lies deep in solid: no free neighbour and no surface within a spacing,
  // so that no candidate (all within 0.52 spacing of it) can leave the solid it is in.
  const float solidDistance = float(std::max({grid.spacing.x, grid.spacing.y, grid.spacing.z}));
  for (size_t idx = 0; idx < total; ++idx) {
    if (reg.free[idx]) {
      reg.skip[idx] = !keep[idx];
      reg.outside += !keep[idx];
      reg.aboveLevel += !keep[idx] && high[idx];
      continue;
    }
    const bool nearFree = anyNeighbour(dims, idx, [&](size_t j) { return reg.free[j] != 0; });
    const bool nearKept = anyNeighbour(dims, idx, [&](size_t j) { return keep[j] != 0; });
    reg.skip[idx] = nearFree ? !nearKept : nearest[idx] > solidDistance;
  }
  return reg;
}


}  // namespace

ProbePlacement placeProbes(const Scene& scene, const ProbeSettings& settings) {
  validate(settings);
  const ThreadLimit threadLimit(settings.threads);
  ProbeGrid grid;
  glm::dvec3 lo, hi;
  probeBounds(settings, scene, lo, hi);
  layoutGrid(settings, lo, hi, grid);
  const RayScene rays(scene);
  const AlbedoLookup albedo(scene);
  const std::vector<HalfRows> none;  // the placement's rays gather no light
  const double maxSpacing = std::max(grid.spacing.x, std::max(grid.spacing.y, grid.spacing.z));
  Tracer tracer{scene, rays, none, albedo, settings.bands, settings.seed, float(2.0 * maxSpacing), {}};
  setTwoSided(tracer);
  setMeshFlags(tracer);
  const LatticeRegion region = classifyLattice(tracer, grid, settings, true);
  if (region.interrupted) throw Interrupted("interrupted (probe placement)");

  const glm::ivec3 dims = grid.dims;
  const size_t total = size_t(dims.x) * dims.y * dims.z;
  ProbePlacement out;
  out.points = total;
  std::vector<uint8_t> near(total, 0);  // baked, or next to a baked point (as assembleGrid's active)
  for (size_t idx = 0; idx < total; ++idx) {
    out.baked += !region.skip[idx];
    near[idx] = !region.skip[idx] || anyNeighbour(dims, idx, [&](size_t j) { return !region.skip[j]; });
  }
  auto countBlocks = [&](int side) {  // blocks of side³ points, from the origin, holding a near point
    const glm::ivec3 b = (dims + side - 1) / side;
    std::vector<uint8_t> held(size_t(b.x) * b.y * b.z, 0);
    for (size_t idx = 0; idx < total; ++idx) {
      if (!near[idx]) continue;
      const glm::ivec3 c = latticeCoord(dims, idx) / side;
      held[size_t(c.x) + size_t(b.x) * (size_t(c.y) + size_t(b.y) * c.z)] = 1;
    }
    return uint64_t(std::count(held.begin(), held.end(), uint8_t(1)));
  };
  out.activeBound = uint64_t(std::count(near.begin(), near.end(), uint8_t(1)));
  out.leafBlocks = countBlocks(8);
  out.lowerBlocks = countBlocks(128);
  return out;
}

void validate(const ProbeSettings& s) {
  validateBands(s.bands);
  if (s.samples < 1 || s.samples > kMaxSamples)
    throw Error(cat("probe samples ", s.samples, ": must be between 1 and ", kMaxSamples));
  if (!(s.spacing >= 0.0) || !std::isfinite(s.spacing)) throw Error("probe spacing: must be a positive number");
  if (s.spacing == 0.0 && (s.dims.x < 1 || s.dims.y < 1 || s.dims.z < 1))
    throw Error("probe dims: give three positive counts (or a probe spacing)");
  if (s.spacing == 0.0 && double(s.dims.x) * s.dims.y * s.dims.z > 512.0 * 512 * 512)
    throw Error("probe dims: more than 512³ probes");
  if (s.threads < 0) throw Error(cat("threads ", s.threads, ": must be 0 (all cores) or more"));
  if (!(s.maxHeight >= 0.0) || !std::isfinite(s.maxHeight))
    throw Error(cat("probe height ", s.maxHeight, ": must be 0 (no limit) or a positive number"));
  if (s.boundsMin && s.boundsMax) {
    glm::dvec3 lo = *s.boundsMin, hi = *s.boundsMax;
    if (!(lo.x < hi.x && lo.y < hi.y && lo.z < hi.z) || !std::isfinite(lo.x + lo.y + lo.z + hi.x + hi.y + hi.z))
      throw Error("probe bounds: the minimum must be below the maximum on every axis");
    const glm::dvec3 size = hi - lo;
    const double largest = std::max({size.x, size.y, size.z});
    for (int a = 0; a < 3; ++a)
      if (size[a] < kFlatFraction * largest)
        throw Error(cat("probe bounds: the box is flat (", "xyz"[a], " extent ", size[a], " against ", largest,
                        "): give the probes a volume, at least ", kFlatFraction, " of the largest extent on every axis"));
  }
}

void probeBounds(const ProbeSettings& s, const Scene& scene, glm::dvec3& lo, glm::dvec3& hi) {
  lo = s.boundsMin.value_or(glm::dvec3(scene.boundsMin));
  hi = s.boundsMax.value_or(glm::dvec3(scene.boundsMax));
  if (s.boundsMin) return;  // given bounds were checked by validate()
  const glm::dvec3 size = hi - lo;
  const double largest = std::max({size.x, size.y, size.z});
  if (!(largest > 0.0)) throw Error("the scene's bounds are a single point: give probe bounds");
  for (int a = 0; a < 3; ++a)
    if (size[a] < kFlatFraction * largest) {  // pad symmetrically: the scene may lie on either side
      const double mid = 0.5 * (lo[a] + hi[a]);
      lo[a] = mid - 0.5 * largest;
      hi[a] = mid + 0.5 * largest;
    }
}

void layoutGrid(const ProbeSettings& s, const glm::dvec3& lo, const glm::dvec3& hi, ProbeGrid& grid) {
  glm::dvec3 size = glm::max(hi - lo, glm::dvec3(1e-9));
  if (s.spacing > 0.0) {
    glm::dvec3 n = glm::ceil(size / s.spacing);
    if (n.x * n.y * n.z > 512.0 * 512 * 512)
      throw Error(cat("probe spacing ", s.spacing, ": gives ", n.x, "×", n.y, "×", n.z, " probes (at most 512³)"));
    grid.dims = glm::max(glm::ivec3(n), glm::ivec3(1));
    grid.spacing = glm::dvec3(s.spacing);
    // Centre the lattice on the bounds.
    glm::dvec3 span = glm::dvec3(grid.dims) * s.spacing;
    grid.origin = lo + (size - span) * 0.5 + 0.5 * s.spacing;
  } else {
    grid.dims = s.dims;
    grid.spacing = size / glm::dvec3(s.dims);
    grid.origin = lo + 0.5 * grid.spacing;
  }
}

void addProbeFingerprint(Fingerprint& fp, const ProbeSettings& s) {
  auto num = [](double v) { return cat(std::setprecision(17), v); };
  auto vec = [&](const std::optional<glm::dvec3>& v) {
    return v ? cat(num(v->x), ",", num(v->y), ",", num(v->z)) : std::string("scene");
  };
  fp.add("probe bands", std::to_string(s.bands));
  fp.add("probe samples", std::to_string(s.samples));
  fp.add("probe bounces", std::to_string(s.bounces));
  fp.add("probe seed", std::to_string(s.seed));
  fp.add("probe spacing", num(s.spacing));
  fp.add("probe dims", cat(s.dims.x, ",", s.dims.y, ",", s.dims.z));
  fp.add("probe bounds min", vec(s.boundsMin));
  fp.add("probe bounds max", vec(s.boundsMax));
  fp.add("probe inside threshold", num(s.insideThreshold));
  fp.add("probe region", s.region == ProbeSettings::Region::Auto         ? "auto"
                         : s.region == ProbeSettings::Region::Everywhere ? "everywhere"
                                                                         : "inside");
  fp.add("probe max height", num(s.maxHeight));
  // Raised whenever the probe bake's arithmetic changes its bits (2: ρ/π in the rows, session
  // 23), so that a checkpoint of an earlier build is refused rather than resumed into a grid
  // whose chunks were computed two ways.
  fp.add("probe arithmetic", "2");
}

namespace {

// v.resize(n) on huge pages, the new storage faulted in by the workers side by side first: one
// thread's first writes would fault it in alone, a page at a time, while the others wait (on the
// VMs prt is measured on, fresh memory costs about 2 ms a MiB to fault in, on huge pages too).
template <class T>
void resizeFaultedInParallel(std::vector<T>& v, size_t n) {
  PRT_CHECK(v.empty());
  v.reserve(n);
  const size_t bytes = n * sizeof(T), kBlock = size_t(2) << 20;
  char* p = reinterpret_cast<char*>(v.data());
  adviseHugePages(p, bytes);
  tbb::parallel_for(tbb::blocked_range<size_t>(0, (bytes + kBlock - 1) / kBlock, 1), [&](const tbb::blocked_range<size_t>& r) {
    const size_t begin = r.begin() * kBlock;
    populatePages(p + begin, std::min(bytes, r.end() * kBlock) - begin);
  });
  v.resize(n);
}

// Active: valid probes, and invalid ones next to a valid probe (so the file shows where
// interpolation must not read); solid interiors far from free space are not stored. Copies the
// chunks' records into the grid, compacted to the active probes in lattice order: M into
// grid.transfer, M⁰'s triangle into grid.direct (zeros for invalid probes, which have no
// record), each array allocated once at its size, on huge pages, and
// faulted in by the workers together.
void assembleGrid(const std::vector<ProbeSlot>& slots, const std::vector<std::vector<float>>& chunks, size_t stride,
                  ProbeGrid& grid, ProbeStats& stats) {
  const glm::ivec3 dims = grid.dims;
  auto validAt = [&](const glm::ivec3& c) {
    if (glm::any(glm::lessThan(c, glm::ivec3(0))) || glm::any(glm::greaterThanEqual(c, dims))) return false;
    return slots[size_t(c.x) + size_t(dims.x) * (size_t(c.y) + size_t(dims.y) * c.z)].valid != 0;
  };
  std::vector<size_t> activeIdx;  // lattice indices of the active points, in lattice order
  for (int z = 0; z < dims.z; ++z)
    for (int y = 0; y < dims.y; ++y)
      for (int x = 0; x < dims.x; ++x) {
        const glm::ivec3 c(x, y, z);
        const size_t idx = size_t(x) + size_t(dims.x) * (size_t(y) + size_t(dims.y) * z);
        bool isActive = slots[idx].valid;
        for (int d = 0; d < 27 && !isActive; ++d)
          isActive = validAt(c + glm::ivec3(d % 3 - 1, (d / 3) % 3 - 1, d / 9 - 1));
        if (isActive) activeIdx.push_back(idx);
      }
  const size_t active = activeIdx.size(), rgb = grid.transferStride(), tri = stride - rgb;
  PRT_CHECK_EQ(tri, ProbeGrid::directStride(grid.bands));
  resizeFaultedInParallel(grid.transfer, active * rgb);  // zeros, kept by invalid probes
  resizeFaultedInParallel(grid.direct, active * tri);
  grid.coord.reserve(active);
  grid.validity.reserve(active);
  grid.offset.reserve(active);
  grid.moments.reserve(active);
  grid.skyVisibility.reserve(active);
  size_t chunk = chunks.size(), at = 0;  // the next valid point's record: chunks[chunk][at]
  for (size_t p = 0; p < active; ++p) {
    const size_t idx = activeIdx[p];
    const ProbeSlot& slot = slots[idx];
    grid.coord.push_back(latticeCoord(dims, idx));
    grid.validity.push_back(slot.valid ? 1.0f : 0.0f);
    grid.offset.push_back(slot.offset);
    grid.moments.push_back(slot.moments);
    grid.skyVisibility.push_back(slot.skyVisibility);
    if (slot.valid) {  // valid points are active: each chunk's records are met in their order
      if (idx / kProbeChunk != chunk) chunk = idx / kProbeChunk, at = 0;
      PRT_CHECK_LE(at + stride, chunks[chunk].size());
      const float* record = chunks[chunk].data() + at;
      at += stride;
      std::copy_n(record, rgb, grid.transfer.begin() + ptrdiff_t(p * rgb));
      std::copy_n(record + rgb, tri, grid.direct.begin() + ptrdiff_t(p * tri));
    }
    stats.active += 1;
    stats.invalid += !slot.valid && !slot.outside;
    stats.valid += slot.valid;
    stats.moved += slot.valid && slot.moved;
  }
  grid.buildIndex();
}

}  // namespace

// Checkpointing (checkpoint.h): one stage, kProbeStage, of kProbeChunk lattice points per
// chunk in lattice order; a chunk record holds its points' slots and transfer, the very values
// the grid is assembled from, so a resumed bake assembles the same bits.
ProbeGrid bakeProbes(const Scene& scene, const std::vector<std::vector<glm::vec3>>& lowerOrder,
                     const ProbeSettings& settings, ProbeStats* statsOut, Checkpoint* cp, SharedRayScene* shared) {
  validate(settings);
  const auto t0 = std::chrono::steady_clock::now();
  const ThreadLimit threadLimit(settings.threads);
  ProbeGrid grid;
  grid.bands = settings.bands;
  grid.info.bounces = settings.bounces;
  grid.info.samples = settings.samples;
  grid.info.seed = settings.seed;
  glm::dvec3 lo, hi;
  probeBounds(settings, scene, lo, hi);
  layoutGrid(settings, lo, hi, grid);
  if (!lowerOrder.empty()) PRT_CHECK_EQ(lowerOrder.size(), scene.meshes.size());

  const size_t total = size_t(grid.dims.x) * grid.dims.y * grid.dims.z;
  const int n2 = settings.bands * settings.bands;
  const size_t stride = size_t(n2) * n2 * 3 + ProbeGrid::directStride(settings.bands);
  auto res = std::make_shared<LatticeResults>();
  res->slots.resize(total);
  res->chunks.resize((total + kProbeChunk - 1) / kProbeChunk);
  res->stride = stride;

  // The stage's writer holds `res`; forget it however this function ends, so that the
  // checkpoint does not keep the lattice alive (or save chunks of it) after the stage.
  const StageRelease release(cp);
  // Only rank 0 assembles and writes the grid: the other ranks send it their chunks.
  ChunkedStage stage({kProbeStage, "probe stage", "probes", "probes", total, kProbeChunk, settings.progress, false}, cp);
  stage.restore([&](const Chunk& c, ByteReader& r) { readProbeChunk(*res, c, r); }, "probe chunk index");
  Checkpoint::StageIo io;
  io.chunksOutliveStage = true;
  io.writeChunk = [res, total](uint64_t c, ByteWriter& w) {
    writeProbeChunk(*res, chunkOf(total, kProbeChunk, c), w);
  };
  stage.begin(std::move(io));

  ProbeStats stats;
  stats.probes = total;
  {
    std::optional<RayScene> own;  // without a shared one (BakeControl::rays), built here
    const RayScene& rays = shared ? shared->get() : own.emplace(scene);
    AlbedoLookup albedo(scene);
    const double maxSpacing = std::max(grid.spacing.x, std::max(grid.spacing.y, grid.spacing.z));
    std::vector<HalfRows> lowerHalf(lowerOrder.size());
    Tracer tracer{scene, rays, lowerHalf, albedo, settings.bands, settings.seed, float(2.0 * maxSpacing), {}};
    setTwoSided(tracer);
    for (size_t k = 0; k < lowerOrder.size(); ++k) {  // both sides' transfer where both are baked
      if (lowerOrder[k].empty()) continue;
      const size_t rows = (tracer.twoSided[k] ? 2 : 1) * scene.meshes[k].vertexCount();
      PRT_CHECK_EQ(lowerOrder[k].size(), rows * size_t(n2));
      // ρ/π of an instance of one colour (AlbedoLookup::at's, as a lit hit's) folded into its
      // rows: a lit hit's light is then the rows' weighted sum alone (Tracer::LitMesh).
      const glm::vec3 rhoPi = albedo.uniform[k] ? albedo.constant[k] * float(1.0 / M_PI) : glm::vec3(1.0f);
      lowerHalf[k].assign(lowerOrder[k], rows, n2, rhoPi);
    }
    tracer.litMeshes.resize(scene.meshes.size());
    tracer.cornerIndices.assign(scene.meshes.size(), nullptr);
    for (size_t k = 0; k < lowerHalf.size(); ++k) {
      if (lowerHalf[k].empty()) continue;
      LitMesh& m = tracer.litMeshes[k];
      tracer.cornerIndices[k] = scene.meshes[k].indices.data();
      m.stride = lowerHalf[k].stride;
      m.rows = lowerHalf[k].row(0);
      m.backRows = tracer.twoSided[k] ? lowerHalf[k].row(scene.meshes[k].vertexCount()) : m.rows;
      m.uniform = albedo.uniform[k];
      tracer.allLitUniform = tracer.allLitUniform && m.uniform;
    }
    setMeshFlags(tracer);
    const ProbeBaker baker(tracer, grid, settings);
    // Deterministic and cheap (about kProbeTestRays per point of the lattice, a few percent of
    // the bake), so a resumed bake classifies again rather than storing it.
    const LatticeRegion region = classifyLattice(tracer, grid, settings);
    if (region.interrupted) {
      if (cp) cp->stopIfInterrupted();
      throw Interrupted("interrupted (probe placement)");
    }
    stats.outside = region.outside;
    stats.aboveLevel = region.aboveLevel;
    stats.sealed = region.sealed;
    stats.insideOnly = region.insideOnly;
    grid.info.region = region.insideOnly                                 ? "inside"
                       : settings.region == ProbeSettings::Region::Everywhere ? "everywhere"
                                                                              : "near";
    stats.rays = region.rays;
    stats.rays += stage
                      .run([&](const Chunk& c) {
                        ProbeAccum acc;  // reused by the probes of this chunk
                        ChunkOutcome outcome;
                        std::vector<float> records;  // of its valid points (LatticeResults::chunks)
                        records.reserve((c.end - c.begin) * stride);
                        for (size_t idx = c.begin; outcome.finished && idx < c.end; ++idx) {
                          ProbeSlot& slot = res->slots[idx];
                          if (region.skip[idx]) {
                            slot = ProbeSlot{};
                            slot.outside = region.free[idx];
                            slot.moments.fill(glm::vec2(tracer.maxDistance, tracer.maxDistance * tracer.maxDistance));
                            continue;
                          }
                          const size_t at = records.size();
                          records.resize(at + stride);
                          outcome.finished = baker.bake(idx, region.free[idx] != 0, acc, slot, records.data() + at);
                          if (!slot.valid) records.resize(at);
                          outcome.rays += slot.traced;
                        }
                        if (outcome.finished) {
                          records.shrink_to_fit();
                          res->chunks[c.index] = std::move(records);
                        }
                        return outcome;
                      })
                      .rays;
    stats.traceSeconds = tracer.inEmbree.seconds();
    stats.gatherSeconds = tracer.inGather.seconds();
    // What each point traced beyond its test (ProbeBaker::bake): a free point its full set; any
    // other its candidates' tests until one was free (moved: then its full set from there).
    const uint32_t samples = uint32_t(settings.samples);
    static_assert(sizeof(ProbeStats::Traced) == 16);  // as the memory estimate counts it
    stats.traced.reserve(total);
    for (size_t idx = 0; idx < total; ++idx) {
      if (region.skip[idx]) continue;
      const ProbeSlot& slot = res->slots[idx];
      ProbeStats::Traced t;
      t.lattice = idx;
      t.full = region.free[idx] || slot.moved;
      t.candidates = region.free[idx] ? 0 : (slot.traced - (t.full ? samples : 0)) / kProbeTestRays;
      stats.traced.push_back(t);
    }
  }
  if (shared) shared->release();  // the last stage that traces: the assembly needs its memory
  if (cp) cp->releaseStages();
  stats.restored = stage.restoredItems();
  if (ranks().rank() != 0) return grid;  // the lattice holds this rank's chunks only
  assembleGrid(res->slots, res->chunks, stride, grid, stats);
  stats.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (statsOut) *statsOut = stats;
  return grid;
}

namespace {

// The origin of a ray set: the lattice point, or its relocation candidate's position, as the
// bake computes it (ProbeBaker::bake, classifyLattice).
glm::vec3 raySetOrigin(const ProbeGrid& layout, const std::vector<glm::dvec3>& candidates, const ProbeRaySet& set) {
  const glm::ivec3 dims = layout.dims;
  const size_t idx = size_t(set.lattice);
  const glm::ivec3 c = latticeCoord(dims, idx);
  const glm::dvec3 base = layout.latticePosition(c);
  if (set.candidate < 0) return glm::vec3(base);
  PRT_CHECK_LT(size_t(set.candidate), candidates.size());
  return glm::vec3(base + candidates[size_t(set.candidate)] * layout.spacing);
}

}  // namespace

void probeRaySets(const ProbeStats& stats, uint64_t points, std::vector<ProbeRaySet>& tests,
                  std::vector<ProbeRaySet>& fulls) {
  size_t next = 0;  // stats.traced is in lattice order
  for (uint64_t idx = 0; idx < points; ++idx) {
    tests.push_back({idx, -1});
    if (next == stats.traced.size() || stats.traced[next].lattice != idx) continue;
    const ProbeStats::Traced& t = stats.traced[next++];
    for (uint32_t c = 0; c < t.candidates; ++c) tests.push_back({idx, int(c)});
    if (t.full) fulls.push_back({idx, int(t.candidates) - 1});  // −1 when none was tested
  }
  PRT_CHECK_EQ(next, stats.traced.size());
}

std::vector<Ray> probeTestRays(const ProbeGrid& layout, const ProbeSettings& settings,
                               const std::vector<ProbeRaySet>& sets) {
  const std::vector<glm::dvec3> candidates = relocationCandidates();
  std::vector<Ray> out(sets.size() * kProbeTestRays);
  for (size_t k = 0; k < sets.size(); ++k)
    SphereSet(settings.seed, 2 * sets[k].lattice)
        .fill(out.data() + k * kProbeTestRays, raySetOrigin(layout, candidates, sets[k]), 0, kProbeTestRays);
  return out;
}

std::vector<Ray> probeFullRays(const ProbeGrid& layout, const ProbeSettings& settings,
                               const std::vector<ProbeRaySet>& sets) {
  const std::vector<glm::dvec3> candidates = relocationCandidates();
  const size_t per = size_t(settings.samples);
  std::vector<Ray> out(sets.size() * per);
  for (size_t k = 0; k < sets.size(); ++k) {
    const SphereSet full(settings.seed, 2 * sets[k].lattice + 1);
    const glm::vec3 x = raySetOrigin(layout, candidates, sets[k]);
    for (uint32_t first = 0; first < uint32_t(per); first += kStream)
      full.fill(out.data() + k * per + first, x, first, std::min<uint32_t>(kStream, uint32_t(per) - first));
  }
  return out;
}

}  // namespace prt::bake
