// The products of the probe transfer's two parts (probe_types.h: ProductKernels): M += Σ y gᵀ
// over a stream's lit hits, and M⁰'s lane sums over its escaped rays, by portable loops (one
// std::fma per term), AVX2 or AVX-512: the same fused multiply-adds in the same order, so the
// same bits.
#include <algorithm>
#include <cmath>

#include <immintrin.h>

#include "probe_types.h"

namespace prt::bake::probe {

namespace {

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
  // twice the FMAs' time). With pragmas of 4 for the rows, the 3-band block of all nine rows
  // (the last 8 columns) kept its sums in memory.
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
    case 2:
      productRowsAvx2<4, 2>(y, yOff, v, ldv, n, rows, 0, j0, cols, c, ldc);
      break;
    case 1:
      productRowsAvx2<9, 1>(y, yOff, v, ldv, n, rows, 0, j0, cols, c, ldc);
      break;
    default:
      break;
  }
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
        case 1:
          block.template operator()<1>(a, b0);
          break;
        case 2:
          block.template operator()<2>(a, b0);
          break;
        case 3:
          block.template operator()<3>(a, b0);
          break;
        case 4:
          block.template operator()<4>(a, b0);
          break;
        case 5:
          block.template operator()<5>(a, b0);
          break;
        case 6:
          block.template operator()<6>(a, b0);
          break;
        case 7:
          block.template operator()<7>(a, b0);
          break;
        default:
          block.template operator()<8>(a, b0);
          break;
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
                                                              const uint8_t* list, int packets, int n2, int a, int b0,
                                                              float* sums) {
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
    const __m512 ya2 =
        _mm512_castpd_ps(_mm512_insertf64x4(_mm512_castpd256_pd512(_mm256_castps_pd(ya)), _mm256_castps_pd(ya), 1));
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

// addDirectPortable of the packets in `list`, sums starting at zero (as the vector kernels').
void directSumsPortable(const float* ys, const int32_t* escaped, const uint8_t* list, int packets, int n2,
                        float* sums) {
  std::fill_n(sums, size_t(n2) * (n2 + 1) / 2 * 8, 0.0f);
  for (int k = 0; k < packets; ++k) {
    const uint32_t q = list[k];
    addDirectPortable(ys + size_t(q) * 8 * n2, escaped + 8 * q, n2, sums);
  }
}

}  // namespace

const KernelTables<ProductKernels> kProductKernels{
    {addProductsPortable, directSumsPortable}, {addProductsAvx2, addDirectAvx2}, {addProductsAvx2, addDirectAvx512}};

}  // namespace prt::bake::probe
