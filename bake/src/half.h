// IEEE 754 binary16 ("half") conversions, exact and portable: the bounces read the previous
// order's transfer as halves (surface_bake.cpp), the probes their lit hits' transfer
// (probe_bake.cpp), and every build and CPU must round the same way. halfFromFloat rounds to
// nearest, ties to even, as F16C's vcvtps2ph with imm 0; floatFromHalf is exact, as vcvtph2ps
// (both checked against F16C in tests/test_bake.cpp where the CPU has it).
#pragma once

#include <cpuid.h>

#include <atomic>
#include <cstdint>
#include <cstring>
#include <vector>

#include <glm/glm.hpp>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

namespace prt::bake {

inline uint16_t halfFromFloat(float f) {
  uint32_t x;
  std::memcpy(&x, &f, sizeof x);
  const uint16_t sign = uint16_t((x >> 16) & 0x8000u);
  x &= 0x7fffffffu;
  if (x >= 0x7f800000u) return uint16_t(sign | 0x7c00u | (x > 0x7f800000u ? 0x200u : 0u));  // inf, NaN
  if (x >= 0x477ff000u) return uint16_t(sign | 0x7c00u);  // from 65520 up: rounds to infinity
  if (x < 0x38800000u) {                                   // below 2^-14: a subnormal half (or 0)
    if (x <= 0x33000000u) return sign;                     // up to 2^-25 (a tie, to even): 0
    const uint32_t m = (x & 0x7fffffu) | 0x800000u;
    const uint32_t shift = 126u - (x >> 23);  // value = m · 2^(e−150); in units of 2^-24: m >> shift
    uint32_t r = m >> shift;
    const uint32_t rem = m & ((1u << shift) - 1u), half = 1u << (shift - 1u);
    if (rem > half || (rem == half && (r & 1u))) ++r;  // may carry into the smallest normal
    return uint16_t(sign | r);
  }
  uint32_t r = (x >> 13) - (112u << 10);  // exponent rebiased from 127 to 15
  const uint32_t rem = x & 0x1fffu;
  if (rem > 0x1000u || (rem == 0x1000u && (r & 1u))) ++r;  // a carry into the exponent is right
  return uint16_t(sign | r);
}

inline float floatFromHalf(uint16_t h) {
  const uint32_t sign = uint32_t(h & 0x8000u) << 16, e = (h >> 10) & 0x1fu, m = h & 0x3ffu;
  uint32_t x;
  if (e == 0x1fu)
    x = sign | 0x7f800000u | (m << 13);
  else if (e != 0)
    x = sign | ((e + 112u) << 23) | (m << 13);
  else {
    const float s = float(m) * 0x1p-24f;  // exact: m < 2^10
    std::memcpy(&x, &s, sizeof x);
    x |= sign;
  }
  float f;
  std::memcpy(&f, &x, sizeof f);
  return f;
}

/// Whether the CPU converts halves in hardware (F16C, CPUID leaf 1, ECX bit 29). Not
/// __builtin_cpu_supports("f16c"): clang 14 (the sanitizer build) does not know that name.
inline bool cpuHasF16c() {
  unsigned a = 0, b = 0, c = 0, d = 0;
  return __get_cpuid(1, &a, &b, &c, &d) && (c & bit_F16C) != 0;
}

/// Whether the bake's vector kernels (the gathers over halves, the probe rays' directions and
/// products) take their AVX2 + FMA + F16C paths: all three on this CPU, unless forcePortableKernels() is
/// set (tests compare the two paths, which must give the same bits).
inline std::atomic<bool>& forcePortableKernels() {
  static std::atomic<bool> force{false};
  return force;
}
inline bool useVectorKernels() {
  static const bool hardware = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma") && cpuHasF16c();
  return hardware && !forcePortableKernels().load(std::memory_order_relaxed);
}

/// Whether the probe bake's lit-hit products and ray classification take their AVX-512 paths
/// (AVX-512 F, VL, DQ and BW, as well as the vector kernels), unless forceAvx2Kernels() is set:
/// the tests compare them with the AVX2 and the portable paths, which all give the same bits.
inline std::atomic<bool>& forceAvx2Kernels() {
  static std::atomic<bool> force{false};
  return force;
}
inline bool useAvx512Kernels() {
  static const bool hardware = __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512vl") &&
                              __builtin_cpu_supports("avx512dq") && __builtin_cpu_supports("avx512bw");
  return hardware && useVectorKernels() && !forceAvx2Kernels().load(std::memory_order_relaxed);
}

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
