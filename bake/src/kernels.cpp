// The choice of the bake's kernel set (prt/bake/kernels.h): the CPU's features, read once, and
// the set asked for.
#include "prt/bake/kernels.h"

#include <cpuid.h>

#include <atomic>

namespace prt::bake {

namespace {

/// Whether the CPU converts halves in hardware (F16C, CPUID leaf 1, ECX bit 29). Not
/// __builtin_cpu_supports("f16c"): clang 14 (the sanitizer build) does not know that name.
bool cpuHasF16c() {
  unsigned a = 0, b = 0, c = 0, d = 0;
  return __get_cpuid(1, &a, &b, &c, &d) && (c & bit_F16C) != 0;
}

Kernels detectKernels() {
  const bool avx2 = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma") && cpuHasF16c();
  const bool avx512 = __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512vl") &&
                      __builtin_cpu_supports("avx512dq") && __builtin_cpu_supports("avx512bw");
  return !avx2 ? Kernels::Portable : avx512 ? Kernels::Avx512 : Kernels::Avx2;
}

std::atomic<Kernels>& requested() {
  static std::atomic<Kernels> kernels{Kernels::Auto};
  return kernels;
}

}  // namespace

Kernels bestKernels() {
  static const Kernels best = detectKernels();
  return best;
}

void setKernels(Kernels kernels) { requested().store(kernels, std::memory_order_relaxed); }

Kernels activeKernels() {
  // The enumerators run from the most demanding set to the least: the slower of the two.
  const Kernels asked = requested().load(std::memory_order_relaxed), best = bestKernels();
  return asked == Kernels::Auto || int(asked) < int(best) ? best : asked;
}

const char* kernelsName(Kernels kernels) {
  switch (kernels) {
    case Kernels::Avx512:
      return "avx512";
    case Kernels::Avx2:
      return "avx2";
    case Kernels::Portable:
      return "portable";
    default:
      return "auto";
  }
}

}  // namespace prt::bake
