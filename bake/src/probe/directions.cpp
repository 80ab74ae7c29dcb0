// Probe rays' directions (probe_types.h: SphereSet): uniform sphere directions from scrambled
// Sobol points, by the portable loop, AVX2 eight at a time or AVX-512 sixteen at a time, each
// giving uniformSphereFromBits' bits.
#include <limits>

#include <immintrin.h>

#include "probe_types.h"
#include "prt/bake/sampling.h"
#include "prt/error.h"

namespace prt::bake::probe {

namespace {

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

__attribute__((target("avx2"))) void sphereDirectionsAvx2(const uint32_t* bx, const uint32_t* by, uint32_t n, float* dx,
                                                          float* dy, float* dz) {
  const __m256 one = _mm256_set1_ps(1.0f), two = _mm256_set1_ps(2.0f), zero = _mm256_setzero_ps();
  const __m256 half = _mm256_set1_ps(0.5f), unit = _mm256_set1_ps(0x1p-24f);
  const __m256 angle = _mm256_set1_ps(0x1p-22f * 0.5f * kPiF);
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
    const __m256 sn =
        _mm256_add_ps(a, _mm256_mul_ps(_mm256_mul_ps(a, a2),
                                       _mm256_add_ps(s1, _mm256_mul_ps(a2, _mm256_add_ps(s2, _mm256_mul_ps(a2, s3))))));
    const __m256 cs =
        _mm256_add_ps(_mm256_sub_ps(one, _mm256_mul_ps(half, a2)),
                      _mm256_mul_ps(_mm256_mul_ps(a2, a2),
                                    _mm256_add_ps(c1, _mm256_mul_ps(a2, _mm256_add_ps(c2, _mm256_mul_ps(a2, c3))))));
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
                                                                        uint32_t kx, uint32_t ky, uint32_t n, float* dx,
                                                                        float* dy, float* dz) {
  constexpr int kRound = _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC;
#define MUL(a, b) _mm512_mul_round_ps(a, b, kRound)
#define ADD(a, b) _mm512_add_round_ps(a, b, kRound)
#define SUB(a, b) _mm512_sub_round_ps(a, b, kRound)
  const __m512 one = _mm512_set1_ps(1.0f), two = _mm512_set1_ps(2.0f), zero = _mm512_setzero_ps();
  const __m512 half = _mm512_set1_ps(0.5f), unit = _mm512_set1_ps(0x1p-24f);
  const __m512 angle = _mm512_set1_ps(0x1p-22f * 0.5f * kPiF);
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

// The bits (px[j] ^ kx) >> 8, (py[j] ^ ky) >> 8 of n rays, then their directions by `kernel`.
template <void (*kernel)(const uint32_t*, const uint32_t*, uint32_t, float*, float*, float*)>
void directionsFromBits(const uint32_t* px, const uint32_t* py, uint32_t kx, uint32_t ky, uint32_t n, float* dx,
                        float* dy, float* dz) {
  alignas(32) uint32_t bx[kStream], by[kStream];  // the n entries read written: no zeroing per stream
  for (uint32_t j = 0; j < n; ++j) {
    bx[j] = (px[j] ^ kx) >> 8;
    by[j] = (py[j] ^ ky) >> 8;
  }
  kernel(bx, by, n, dx, dy, dz);
}

// A stream's directions, kStream at most, computed together.
struct Directions {
  alignas(32) float x[kStream], y[kStream], z[kStream];
  Directions(const SphereSet& s, uint32_t first, uint32_t count) {
    // Both dimensions are linear over GF(2) and a stream starts at a multiple of kStream (a
    // power of two): point first + j (j < kStream) is point first XOR point j, the scramble
    // folded into the first. The same bits as sobol0Bits and sobol1Bits of first + j.
    static_assert((kStream & (kStream - 1)) == 0);
    PRT_CHECK_EQ(first % kStream, 0u);
    PRT_CHECK(count <= uint32_t(kStream));
    const uint32_t x0 = sobol0Point(first) ^ s.s0, y0 = sobol1Point(first) ^ s.s1;
    s.kernels.directions(kStreamPoints.x, kStreamPoints.y, x0, y0, count, x, y, z);
  }
};

}  // namespace

const KernelTables<DirectionKernels> kDirectionKernels{{directionsFromBits<sphereDirectionsPortable>},
                                                       {directionsFromBits<sphereDirectionsAvx2>},
                                                       {sphereDirectionsAvx512}};

SphereSet::SphereSet(uint64_t seed, uint64_t stream, const DirectionKernels& k) : kernels(k) {
  const uint64_t h = splitMix64(seed ^ splitMix64(stream));
  s0 = uint32_t(h);
  s1 = uint32_t(h >> 32);
}

void SphereSet::fill(RayPacket8* p, const glm::vec3& x, uint32_t first, uint32_t count) const {
  Directions d(*this, first, count);
  constexpr float inf = std::numeric_limits<float>::infinity();
  uint32_t j = 0;
  for (; j + 8 <= count; j += 8) p[j >> 3].startAll(x, d.x + j, d.y + j, d.z + j, 0.0f, inf);
  for (; j < count; ++j) p[j >> 3].start(int(j & 7), x, {d.x[j], d.y[j], d.z[j]}, 0.0f, inf);
  // The last packet's lanes past the count are not traced, but their SH values are computed
  // with the packet's (Tracer::trace): a unit direction, not whatever the buffer held.
  for (; j % 8 != 0; ++j) p[j >> 3].start(int(j & 7), x, {0.0f, 0.0f, 1.0f}, 0.0f, inf);
}

void SphereSet::refill(RayPacket8* p, uint32_t first, uint32_t count) const {
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

void SphereSet::fill(Ray* r, const glm::vec3& x, uint32_t first, uint32_t count) const {
  Directions d(*this, first, count);
  for (uint32_t j = 0; j < count; ++j)
    r[j].start(x, {d.x[j], d.y[j], d.z[j]}, 0.0f, std::numeric_limits<float>::infinity());
}

}  // namespace prt::bake::probe
