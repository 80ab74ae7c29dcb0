// The bake's transfer rows as halves (prt/bake/half.h), and what the kernels that read them
// share: prefetching a row, and the guard around AVX-512 intrinsics.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <glm/glm.hpp>

#include "prt/bake/half.h"

namespace prt::bake {

// GCC 12 warns that the AVX-512 intrinsics' own _mm512_undefined_* values may be used
// uninitialised; around the AVX-512 kernels, that warning is off.
#if defined(__GNUC__) && !defined(__clang__)
#define PRT_AVX512_BEGIN _Pragma("GCC diagnostic push") _Pragma("GCC diagnostic ignored \"-Wmaybe-uninitialized\"")
#define PRT_AVX512_END _Pragma("GCC diagnostic pop")
#else
#define PRT_AVX512_BEGIN
#define PRT_AVX512_END
#endif

/// Prefetches the `bytes` from p, a row of HalfRows (one 64-byte line up to 3 bands, so the first
/// straight and the others only beyond). Always inlined, as every helper that does nothing but
/// prefetch must be: GCC 12 finds such a function free of side effects and deletes its calls
/// (docs/bake.md, "Probe bake: the prefetches that were not there"; tests/check_prefetches.cmake).
[[gnu::always_inline]] inline void prefetchLines(const void* p, size_t bytes) {
  const char* c = static_cast<const char*>(p);
  __builtin_prefetch(c);
  for (size_t o = 64; o < bytes; o += 64) __builtin_prefetch(c + o);
}

/// RGB SH transfer rows (3·n2 floats each) as halves, each row padded with zeros to whole 64-byte
/// lines (one line at 3 bands instead of two): for gathers that read rows at random, where the
/// lines read are the cost.
struct HalfRows {
  size_t stride = 0;  // halves per row: 3·n2, padded to a multiple of 32 (a 64-byte line)
  std::vector<uint16_t> storage;
  uint16_t* rows = nullptr;  // 64-byte aligned, inside storage
  /// Rows 0 .. count−1 of t (count · n2 RGB triples), each channel times `scale`'s (in float),
  /// rounded to nearest even.
  void assign(const std::vector<glm::vec3>& t, size_t count, int n2, const glm::vec3& scale = glm::vec3(1.0f)) {
    stride = (size_t(3 * n2) + 31) / 32 * 32;
    if (storage.size() != count * stride + 32) storage.assign(count * stride + 32, 0);  // padding stays 0
    rows = reinterpret_cast<uint16_t*>((reinterpret_cast<uintptr_t>(storage.data()) + 63) & ~uintptr_t(63));
    tbb::parallel_for(tbb::blocked_range<size_t>(0, count, 1024), [&](const tbb::blocked_range<size_t>& r) {
      for (size_t v = r.begin(); v != r.end(); ++v) {
        const float* src = &t[v * size_t(n2)].x;
        uint16_t* dst = rows + v * stride;
        for (int i = 0; i < 3 * n2; ++i) dst[i] = halfFromFloat(src[i] * scale[i % 3]);
      }
    });
  }
  const uint16_t* row(size_t v) const { return rows + v * stride; }
  bool empty() const { return rows == nullptr; }
};

}  // namespace prt::bake
