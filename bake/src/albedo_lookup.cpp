// AlbedoLookup (prt/bake/albedo_lookup.h): the per-instance tables, and atMany's AVX-512 kernel, which
// gives albedoAt's bits (probes/scene/src/material.cpp) eight hits at a time.
//
// The bits: albedoAt rounds every float and double operation on its own (the scalar code is
// built for baseline x86-64, which has no FMA), and this file is compiled with
// -ffp-contract=off (bake/CMakeLists.txt), so each intrinsic below is one rounded operation in
// the scalar code's order. Texture::sample's fast path (both texels inside) is not taken: for
// texel indices inside, every wrap mode returns them unchanged, so the general path gives the
// same indices.
#include "prt/bake/albedo_lookup.h"

#include <immintrin.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>

#include "half_rows.h"  // PRT_AVX512_BEGIN
#include "kernel_tables.h"

namespace prt::bake {

namespace {

using Batched = AlbedoLookup::Batched;
static_assert(sizeof(Batched) == 64);

constexpr int kWrapShiftS = 8, kWrapShiftT = 10;

// Texture::sample's wrap: 0 REPEAT (any mode it does not name), 1 CLAMP_TO_EDGE, 2 MIRRORED_REPEAT.
uint32_t wrapKind(int mode) { return mode == Texture::kClampToEdge ? 1u : mode == Texture::kMirroredRepeat ? 2u : 0u; }

PRT_AVX512_BEGIN
#define PRT_TARGET __attribute__((target("avx512f,avx512vl,avx512dq,avx512bw"), always_inline)) inline

PRT_TARGET __m512d floor8(__m512d x) { return _mm512_roundscale_pd(x, _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC); }

// Texture::sample's wrap(i, n, mode) and the clamp around it, per lane: i a texel index (a whole
// number, as a double), n the size (as double and int), kind as wrapKind.
PRT_TARGET __m256i wrap8(__m512d i, __m512d n, __m256i size, __m256i kind) {
  const __m512d one = _mm512_set1_pd(1.0);
  const __m512d repeat = _mm512_sub_pd(i, _mm512_mul_pd(n, floor8(_mm512_div_pd(i, n))));
  const __m512d clamp = _mm512_min_pd(_mm512_max_pd(i, _mm512_setzero_pd()), _mm512_sub_pd(n, one));
  const __m512d n2 = _mm512_mul_pd(_mm512_set1_pd(2.0), n);
  const __m512d m = _mm512_sub_pd(i, _mm512_mul_pd(n2, floor8(_mm512_div_pd(i, n2))));  // in [0, 2n)
  const __m512d mirror =
      _mm512_mask_blend_pd(_mm512_cmp_pd_mask(m, n, _CMP_LT_OQ), _mm512_sub_pd(_mm512_sub_pd(n2, one), m), m);
  __m512d r = _mm512_mask_mov_pd(repeat, _mm256_cmpeq_epi32_mask(kind, _mm256_set1_epi32(1)), clamp);
  r = _mm512_mask_mov_pd(r, _mm256_cmpeq_epi32_mask(kind, _mm256_set1_epi32(2)), mirror);
  const __m256i v = _mm512_cvttpd_epi32(r);
  return _mm256_max_epi32(_mm256_min_epi32(v, _mm256_sub_epi32(size, _mm256_set1_epi32(1))), _mm256_setzero_si256());
}

// Texture::sample's axis(): the two texels along one axis and the second one's weight.
PRT_TARGET void axis8(__m256 t, __m256i size, __m256i kind, __m256i& i0, __m256i& i1, __m512d& f) {
  const __m512d n = _mm512_cvtepi32_pd(size);
  const __mmask8 finite = _mm256_cmp_ps_mask(_mm256_andnot_ps(_mm256_set1_ps(-0.0f), t),
                                             _mm256_set1_ps(std::numeric_limits<float>::infinity()), _CMP_LT_OQ);
  const __m512d d = _mm512_min_pd(_mm512_max_pd(_mm512_cvtps_pd(t), _mm512_set1_pd(-1e6)), _mm512_set1_pd(1e6));
  const __m512d x = _mm512_maskz_mov_pd(finite, _mm512_sub_pd(_mm512_mul_pd(d, n), _mm512_set1_pd(0.5)));
  const __m512d x0 = floor8(x);
  f = _mm512_sub_pd(x, x0);
  i0 = wrap8(x0, n, size, kind);
  i1 = wrap8(_mm512_add_pd(x0, _mm512_set1_pd(1.0)), n, size, kind);
}

// 64-bit addresses base + (index << shift), index unsigned 32-bit.
PRT_TARGET __m512i address8(__m512i base, __m256i index, int shift) {
  return _mm512_add_epi64(base, _mm512_sll_epi64(_mm512_cvtepu32_epi64(index), _mm_cvtsi32_si128(shift)));
}

// Channel c of 8-bit texels p decoded (levels[table + byte]), as doubles.
PRT_TARGET __m512d decode8(__m256i p, int c, __m256i table, const float* levels, __mmask8 lanes) {
  const __m256i byte = _mm256_and_si256(_mm256_srl_epi32(p, _mm_cvtsi32_si128(8 * c)), _mm256_set1_epi32(255));
  return _mm512_cvtps_pd(
      _mm256_mmask_i32gather_ps(_mm256_setzero_ps(), lanes, _mm256_add_epi32(table, byte), levels, 4));
}

// A batch of eight hits: their instances' lines and flags, and, where the colour varies over
// the triangle (textured or coloured), the barycentrics and corners.
struct Lanes {
  __mmask8 fast, tex, col;  // fast: the kernel's instances; tex, col: textured, coloured
  __m256i line, flags;
  __m256 w[3];    // b0, b1, b2
  __m256i ix[3];  // the corners' vertex indices
};

// What pass 1 found of eight hits, for pass 2: the texels' addresses and filter weights, the
// base colour factor and the interpolated vertex colour.
struct alignas(64) Staged {
  __m512i texel[4];  // (x0, y0), (x1, y0), (x0, y1), (x1, y1)
  __m512d fx, fy;
  __m256 factor[3], color[3];
  __m256i table;  // the decode table's offset in levels
  __mmask8 fast, tex, col;
};

// Pass 0: prefetches the corners' texture coordinates and colours of hits [s, end).
PRT_TARGET void prefetchCorners(const Batched* table, const uint32_t* mesh, const uint32_t* tri, uint32_t s,
                                uint32_t end) {
  for (uint32_t k = s; k < end; ++k) {
    const Batched& b = table[mesh[k]];
    if (!(b.flags & AlbedoLookup::kKernel)) continue;
    const uint32_t* ix = b.indices + 3 * size_t(tri[k]);
    for (int c = 0; c < 3; ++c) {
      if (b.flags & AlbedoLookup::kTextured) __builtin_prefetch(b.texcoords + ix[c]);
      if (b.flags & AlbedoLookup::kColoured) __builtin_prefetch(b.colors + ix[c]);
    }
  }
}

// The instances' lines and flags of the eight hits from k0 (`valid` lanes), and their factors
// into st.
PRT_TARGET Lanes laneLines(const char* lines, const uint32_t* mesh, uint32_t k0, __mmask8 valid, Staged& st) {
  Lanes l;
  l.line = _mm256_slli_epi32(_mm256_maskz_loadu_epi32(valid, mesh + k0), 6);  // × sizeof(Batched)
  l.flags = _mm256_mmask_i32gather_epi32(_mm256_setzero_si256(), valid, l.line, lines + offsetof(Batched, flags), 1);
  l.fast = valid & _mm256_test_epi32_mask(l.flags, _mm256_set1_epi32(int(AlbedoLookup::kKernel)));
  l.tex = l.fast & _mm256_test_epi32_mask(l.flags, _mm256_set1_epi32(int(AlbedoLookup::kTextured)));
  l.col = l.fast & _mm256_test_epi32_mask(l.flags, _mm256_set1_epi32(int(AlbedoLookup::kColoured)));
  st.fast = l.fast, st.tex = l.tex, st.col = l.col;
  for (int c = 0; c < 3; ++c)
    st.factor[c] =
        _mm256_mmask_i32gather_ps(_mm256_setzero_ps(), l.fast, l.line, lines + offsetof(Batched, factor) + 4 * c, 1);
  return l;
}

// Where the colour varies over the triangle: the barycentrics and the corners, indices[3·tri + c].
PRT_TARGET void cornersOf(const char* lines, const uint32_t* tri, const float* b1, const float* b2, uint32_t k0,
                          Lanes& l) {
  const __mmask8 varies = l.tex | l.col;
  l.w[1] = _mm256_maskz_loadu_ps(varies, b1 + k0);
  l.w[2] = _mm256_maskz_loadu_ps(varies, b2 + k0);
  l.w[0] = _mm256_sub_ps(_mm256_sub_ps(_mm256_set1_ps(1.0f), l.w[1]), l.w[2]);  // b0 = 1 − b1 − b2
  const __m512i indices =
      _mm512_mask_i32gather_epi64(_mm512_setzero_si512(), varies, l.line, lines + offsetof(Batched, indices), 1);
  const __m256i tri3 = _mm256_mullo_epi32(_mm256_maskz_loadu_epi32(varies, tri + k0), _mm256_set1_epi32(3));
  const __m512i first = address8(indices, tri3, 2);
  for (int c = 0; c < 3; ++c)
    l.ix[c] = _mm512_mask_i64gather_epi32(_mm256_setzero_si256(), varies,
                                          _mm512_add_epi64(first, _mm512_set1_epi64(4 * c)), nullptr, 1);
}

// The vertex colour b0 c0 + b1 c1 + b2 c2 of the coloured lanes into st.color.
PRT_TARGET void vertexColours(const char* lines, const Lanes& l, Staged& st) {
  const __m256 zerof = _mm256_setzero_ps();
  const __m512i colors =
      _mm512_mask_i32gather_epi64(_mm512_setzero_si512(), l.col, l.line, lines + offsetof(Batched, colors), 1);
  for (int c = 0; c < 3; ++c) {
    __m256 sum = zerof;
    for (int k = 0; k < 3; ++k) {
      const __m512i at = _mm512_add_epi64(address8(colors, l.ix[k], 4), _mm512_set1_epi64(4 * c));
      const __m256 ck = _mm512_mask_i64gather_ps(zerof, l.col, at, nullptr, 1);
      sum = k == 0 ? _mm256_mul_ps(l.w[0], ck) : _mm256_add_ps(sum, _mm256_mul_ps(l.w[k], ck));
    }
    st.color[c] = sum;
  }
}

// The textured lanes' four texels (addresses and filter weights) into st, and prefetched.
PRT_TARGET void texelsOf(const char* lines, const Lanes& l, Staged& st) {
  const __m256i zero = _mm256_setzero_si256(), three = _mm256_set1_epi32(3);
  const __m512i zero64 = _mm512_setzero_si512();
  const __m256 zerof = _mm256_setzero_ps();
  st.table = _mm256_mmask_i32gather_epi32(zero, l.tex, l.line, lines + offsetof(Batched, levels), 1);
  // uv = b0 uv0 + b1 uv1 + b2 uv2, each (u, v) pair one 64-bit gather.
  const __m512i tc = _mm512_mask_i32gather_epi64(zero64, l.tex, l.line, lines + offsetof(Batched, texcoords), 1);
  __m256 u = zerof, v = zerof;
  for (int c = 0; c < 3; ++c) {
    const __m512i uv = _mm512_mask_i64gather_epi64(zero64, l.tex, address8(tc, l.ix[c], 3), nullptr, 1);
    const __m256 uc = _mm256_castsi256_ps(_mm512_cvtepi64_epi32(uv));
    const __m256 vc = _mm256_castsi256_ps(_mm512_cvtepi64_epi32(_mm512_srli_epi64(uv, 32)));
    u = c == 0 ? _mm256_mul_ps(l.w[0], uc) : _mm256_add_ps(u, _mm256_mul_ps(l.w[c], uc));
    v = c == 0 ? _mm256_mul_ps(l.w[0], vc) : _mm256_add_ps(v, _mm256_mul_ps(l.w[c], vc));
  }
  const __m256i width = _mm256_mmask_i32gather_epi32(zero, l.tex, l.line, lines + offsetof(Batched, width), 1);
  const __m256i height = _mm256_mmask_i32gather_epi32(zero, l.tex, l.line, lines + offsetof(Batched, height), 1);
  const __m256i wrapS = _mm256_and_si256(_mm256_srli_epi32(l.flags, kWrapShiftS), three);
  const __m256i wrapT = _mm256_and_si256(_mm256_srli_epi32(l.flags, kWrapShiftT), three);
  __m256i x0, x1, y0, y1;
  axis8(u, width, wrapS, x0, x1, st.fx);
  axis8(v, height, wrapT, y0, y1, st.fy);
  // texels8[y · width + x].
  const __m512i texels = _mm512_mask_i32gather_epi64(zero64, l.tex, l.line, lines + offsetof(Batched, texels8), 1);
  const __m512i w64 = _mm512_cvtepu32_epi64(width);
  const __m512i row0 = _mm512_mul_epu32(_mm512_cvtepu32_epi64(y0), w64);
  const __m512i row1 = _mm512_mul_epu32(_mm512_cvtepu32_epi64(y1), w64);
  st.texel[0] = address8(_mm512_add_epi64(texels, _mm512_slli_epi64(row0, 2)), x0, 2);
  st.texel[1] = address8(_mm512_add_epi64(texels, _mm512_slli_epi64(row0, 2)), x1, 2);
  st.texel[2] = address8(_mm512_add_epi64(texels, _mm512_slli_epi64(row1, 2)), x0, 2);
  st.texel[3] = address8(_mm512_add_epi64(texels, _mm512_slli_epi64(row1, 2)), x1, 2);
  alignas(64) const char* at[4][8];
  for (int q = 0; q < 4; ++q) _mm512_store_si512(at[q], st.texel[q]);
  for (uint32_t lane = 0; lane < 8; ++lane)
    if ((l.tex >> lane) & 1u)
      for (int q = 0; q < 4; ++q) __builtin_prefetch(at[q][lane]);
}

// Pass 2 for the `count` hits from k0: the texels filtered, times the factor and the colours;
// the hits the kernel does not take looked up one by one.
PRT_TARGET void finishBatch(const AlbedoLookup& lookup, const Staged& st, const float* levels, const uint32_t* mesh,
                            const uint32_t* tri, const float* b1, const float* b2, uint32_t k0, uint32_t count,
                            glm::vec3* out) {
  __m256 rgb[3] = {st.factor[0], st.factor[1], st.factor[2]};
  if (st.tex) {
    __m256i p[4];
    for (int q = 0; q < 4; ++q)
      p[q] = _mm512_mask_i64gather_epi32(_mm256_setzero_si256(), st.tex, st.texel[q], nullptr, 1);
    const __m512d one = _mm512_set1_pd(1.0), gx = _mm512_sub_pd(one, st.fx), gy = _mm512_sub_pd(one, st.fy);
    for (int c = 0; c < 3; ++c) {
      const __m512d top = _mm512_add_pd(_mm512_mul_pd(decode8(p[0], c, st.table, levels, st.tex), gx),
                                        _mm512_mul_pd(decode8(p[1], c, st.table, levels, st.tex), st.fx));
      const __m512d bottom = _mm512_add_pd(_mm512_mul_pd(decode8(p[2], c, st.table, levels, st.tex), gx),
                                           _mm512_mul_pd(decode8(p[3], c, st.table, levels, st.tex), st.fx));
      const __m256 sample = _mm512_cvtpd_ps(_mm512_add_pd(_mm512_mul_pd(top, gy), _mm512_mul_pd(bottom, st.fy)));
      rgb[c] = _mm256_mask_mul_ps(rgb[c], st.tex, rgb[c], sample);
    }
  }
  if (st.col)
    for (int c = 0; c < 3; ++c) rgb[c] = _mm256_mask_mul_ps(rgb[c], st.col, rgb[c], st.color[c]);
  alignas(32) float r[8], g[8], b[8];
  _mm256_store_ps(r, rgb[0]);
  _mm256_store_ps(g, rgb[1]);
  _mm256_store_ps(b, rgb[2]);
  for (uint32_t lane = 0, k = k0; lane < count; ++lane, ++k)
    out[k] = (st.fast >> lane) & 1u ? glm::vec3(r[lane], g[lane], b[lane]) : lookup.at(mesh[k], tri[k], b1[k], b2[k]);
}

#undef PRT_TARGET

// In blocks of kBlock hits, three passes, each fetching what the next reads so that the loads
// of a batch do not wait on each other's: 0 prefetches the corners' texture coordinates and
// colours; 1 interpolates the coordinates, wraps them to texels and prefetches those; 2 filters
// the texels and multiplies in the factor and the colours.
__attribute__((target("avx512f,avx512vl,avx512dq,avx512bw"))) void atManyAvx512(
    const AlbedoLookup& lookup, const Batched* table, const float* levels, const uint32_t* mesh, const uint32_t* tri,
    const float* b1, const float* b2, uint32_t n, glm::vec3* out) {
  constexpr uint32_t kBlock = 256;
  const char* lines = reinterpret_cast<const char*>(table);
  Staged staged[kBlock / 8];
  for (uint32_t s = 0; s < n; s += kBlock) {
    const uint32_t end = std::min(n, s + kBlock);
    prefetchCorners(table, mesh, tri, s, end);
    for (uint32_t k0 = s; k0 < end; k0 += 8) {  // pass 1
      Staged& st = staged[(k0 - s) / 8];
      Lanes l = laneLines(lines, mesh, k0, __mmask8((1u << std::min<uint32_t>(8, end - k0)) - 1u), st);
      if (!(l.tex | l.col)) continue;
      cornersOf(lines, tri, b1, b2, k0, l);
      if (l.col) vertexColours(lines, l, st);
      if (l.tex) texelsOf(lines, l, st);
    }
    for (uint32_t k0 = s; k0 < end; k0 += 8)  // pass 2
      finishBatch(lookup, staged[(k0 - s) / 8], levels, mesh, tri, b1, b2, k0, std::min<uint32_t>(8, end - k0), out);
  }
}
PRT_AVX512_END

// atMany's kernels: AVX-512 only; without it, at() hit by hit.
const KernelTables<AlbedoLookup::ManyKernels> kAlbedoKernels{{nullptr}, {nullptr}, {atManyAvx512}};

}  // namespace

AlbedoLookup::AlbedoLookup(const Scene& s) : scene(s) {
  levels_.resize(s.textures.size() * 256);
  for (size_t t = 0; t < s.textures.size(); ++t)
    std::copy(s.textures[t].levels8[0].begin(), s.textures[t].levels8[0].end(), levels_.begin() + 256 * t);
  batched_.resize(s.meshes.size());
  bool batched = false;  // some instance is
  for (size_t k = 0; k < s.meshes.size(); ++k) {
    const MeshInstance& m = s.meshes[k];
    const bool metallicTexture = readsMetallicTexture(s, m);  // metallic varies: looked up one by one
    const bool textured = (m.material >= 0 && s.materials[size_t(m.material)].baseColorTexture >= 0) || metallicTexture;
    const bool uni = !textured && m.colors.empty();
    uniform.push_back(uni);
    varies = varies || !uni;
    constant.push_back(uni && m.triangleCount() ? albedoAtVertex(s, m, m.indices[0]) : glm::vec3(0));
    // What albedoAt does at a hit on this instance, as the kernel's table says it.
    Batched& b = batched_[k];
    b.indices = m.indices.data();
    b.flags = kKernel;
    if (m.material >= 0) {
      const Material& mat = s.materials[size_t(m.material)];
      const float scale = diffuseScale(s, m);  // albedoAt's first product, rounded as it rounds it
      for (int c = 0; c < 3; ++c) b.factor[c] = mat.baseColorFactor[c] * scale;
      if (mat.baseColorTexture >= 0 && !m.texcoords.empty()) {
        const Texture& t = s.textures[size_t(mat.baseColorTexture)];
        if (t.width > 0 && t.height > 0 && !t.texels.empty()) {  // else sample() gives 1: the factor alone
          if (t.texels8.size() == t.texels.size()) {
            b.flags |= kTextured | wrapKind(t.wrapS) << kWrapShiftS | wrapKind(t.wrapT) << kWrapShiftT;
            b.texcoords = m.texcoords.data();
            b.texels8 = t.texels8.data();
            b.width = t.width, b.height = t.height;
            b.levels = int32_t(256 * size_t(mat.baseColorTexture));
          } else {
            b.flags = 0;  // float texels: looked up one by one
          }
        }
      }
    }
    if (metallicTexture || bouncesSpecular(s, m)) b.flags = 0;  // looked up one by one
    if (!m.colors.empty()) {
      b.flags |= kColoured;
      b.colors = m.colors.data();
    }
    batched = batched || (b.flags & kKernel);
  }
  // The kernel indexes instances' lines and the decode tables with 32-bit offsets.
  const bool kernel = batched && s.meshes.size() < (size_t(1) << 25) && s.textures.size() < (size_t(1) << 22);
  many_ = kernel ? kAlbedoKernels.active().many : nullptr;
}

void AlbedoLookup::atMany(const uint32_t* mesh, const uint32_t* tri, const float* b1, const float* b2, uint32_t n,
                          glm::vec3* out) const {
  if (many_) {
    many_(*this, batched_.data(), levels_.data(), mesh, tri, b1, b2, n, out);
    return;
  }
  for (uint32_t k = 0; k < n; ++k) out[k] = at(mesh[k], tri[k], b1[k], b2[k]);
}

}  // namespace prt::bake
