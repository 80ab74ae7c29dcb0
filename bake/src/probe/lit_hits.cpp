// The light of a probe's lit hits (Tracer::sumLit): each hit's g = ρ/π · t(h) interpolated
// from its corners' transfer rows as halves, and M += Σ y gᵀ, by the portable loops, F16C, or
// AVX-512 with g and the sums in registers; the same operations in the same order, so the same bits.
#include <algorithm>
#include <cmath>
#include <cstring>

#include <immintrin.h>

#include "prt/math.h"
#include "tracer.h"

namespace prt::bake::probe {

namespace {

// How many hits ahead of the one whose light is computed the rows are prefetched: with AVX-512,
// 4, 8, 16 and 32 measured alike, and so did the corner indices prefetched again 16 hits ahead
// (docs/bake.md: the measurements before compared builds without any row prefetch).
constexpr uint32_t kRowsAhead = 8;

// The light a lit hit sends, g = ρ/π · (b0 t0 + b1 t1 + b2 t2), from its corners' transfer rows
// as halves (HalfRows: one 64-byte line a corner at 3 bands, where the floats took two: the
// reads of the rows are most of what a lit hit costs). g's `lanes` floats (3·n2 padded to
// whole 8-float vectors; the rows' padding is zero, so g's is too). The weighted sum is
// b2 t2 + (b1 t1 + b0 t0) in two fused multiply-adds, then one multiply by ρ/π, which is 1 for
// an instance of one colour (its rows hold ρ/π · t already: LitMesh). Without F16C the
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
// about a quarter more time on the lit hits: docs/bake.md.)
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

// litLightsF16c with K known for one to four bands.
void litLightsAvx2(const LitHits& in, uint32_t h0, uint32_t n, float* g, int ldg) {
  switch (ldg / 8) {
    case 1:
      litLightsF16c<1>(in, h0, n, g, ldg);
      break;
    case 2:
      litLightsF16c<2>(in, h0, n, g, ldg);
      break;
    case 4:
      litLightsF16c<4>(in, h0, n, g, ldg);
      break;
    case 6:
      litLightsF16c<6>(in, h0, n, g, ldg);
      break;
    default:
      litLightsF16c<0>(in, h0, n, g, ldg);
  }
}

// litListedAvx512 for n2 = 1, 4 or 9 (up to kListedMaxN2), with or without ρ/π.
void litListedAvx512For(const LitHits& in, uint32_t h0, uint32_t n, int n2, bool rho, double* c) {
  auto products = [&]<bool Rho>() {
    switch (n2) {
      case 1:
        return litListedAvx512<1, Rho>(in, h0, n, c);
      case 4:
        return litListedAvx512<4, Rho>(in, h0, n, c);
      default:
        return litListedAvx512<9, Rho>(in, h0, n, c);
    }
  };
  if (rho)
    products.template operator()<true>();
  else
    products.template operator()<false>();
}

}  // namespace

const KernelTables<LitHitKernels> kLitHitKernels{
    {litLightsPortable, nullptr}, {litLightsAvx2, nullptr}, {litLightsAvx2, litListedAvx512For}};

uint32_t Tracer::lookUpAlbedo(StreamRows& rows, uint32_t hits) const {
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
    const glm::vec3 rho = a.rgb[k] * float(1.0 / kPi);
    float* r = &rows.rho[4 * size_t(a.hit[k])];
    r[0] = rho.r, r[1] = rho.g, r[2] = rho.b, r[3] = 0.0f;
  }
  return n;
}

void Tracer::sumLit(StreamRows& rows, uint32_t hits, double* indirect) const {
  const int n2 = rows.n2, ldg = padded(3 * n2);
  const LitHitKernels& lit = kernels.litHits;
  const bool listed = lit.listed && n2 <= kListedMaxN2;
  // Listed, without a hit on a textured or vertex-coloured instance, every ρ/π is 1 and goes
  // unread; the other kernels multiply by it.
  const uint32_t looked = listed && allLitUniform ? 0 : lookUpAlbedo(rows, hits);
  const LitHits in{rows.hitMesh.data(), rows.hitTri.data(), rows.hitYOff.data(),  rows.hitU.data(), rows.hitV.data(),
                   rows.rho.data(),     litMeshes.data(),   cornerIndices.data(), rows.ys.data(),   hits};
  for (uint32_t h = 0; h < std::min(hits, kRowsAhead); ++h) in.prefetchRows(h);
  for (uint32_t h0 = 0; h0 < hits; h0 += kChunk) {
    const uint32_t k = std::min<uint32_t>(kChunk, hits - h0);
    if (listed) {
      lit.listed(in, h0, k, n2, looked != 0, indirect);
      continue;
    }
    lit.lights(in, h0, k, rows.gHit.data(), ldg);
    uint32_t* yOff = rows.hitYOff.data() + h0;  // read: from here the products' offsets
    for (uint32_t h = 0; h < k; ++h) yOff[h] &= ~kBackBit;
    kernels.products.products(rows.ys.data(), yOff, rows.gHit.data(), ldg, int(k), n2, 3 * n2, indirect, 3 * n2);
  }
}

}  // namespace prt::bake::probe
