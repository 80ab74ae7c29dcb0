// IEEE 754 binary16 ("half") conversions, exact and portable: the bounces read the previous
// order's transfer as halves (bake/src/surface_bake.cpp), the probes their lit hits' transfer
// (bake/src/probe/lit_hits.cpp), and every build and CPU must round the same way. halfFromFloat
// rounds to nearest, ties to even, as F16C's vcvtps2ph with imm 0; floatFromHalf is exact, as
// vcvtph2ps (both checked against F16C in tests/test_bake.cpp where the CPU has it).
#pragma once

#include <cstdint>
#include <cstring>

namespace prt::bake {

inline uint16_t halfFromFloat(float f) {
  uint32_t x;
  std::memcpy(&x, &f, sizeof x);
  const uint16_t sign = uint16_t((x >> 16) & 0x8000u);
  x &= 0x7fffffffu;
  if (x >= 0x7f800000u) return uint16_t(sign | 0x7c00u | (x > 0x7f800000u ? 0x200u : 0u));  // inf, NaN
  if (x >= 0x477ff000u) return uint16_t(sign | 0x7c00u);  // from 65520 up: rounds to infinity
  if (x < 0x38800000u) {                                  // below 2^-14: a subnormal half (or 0)
    if (x <= 0x33000000u) return sign;                    // up to 2^-25 (a tie, to even): 0
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

}  // namespace prt::bake
