// Constants that more than one library needs, defined once. std::numbers (C++20) rather than
// POSIX M_PI, which the C++ standard does not promise: the values are the same
// (std::numbers::pi == M_PI, and pi_v<float> is the float nearest to both).
#pragma once

#include <numbers>

namespace prt {

inline constexpr double kPi = std::numbers::pi_v<double>;
inline constexpr float kPiF = std::numbers::pi_v<float>;

/// The Rec. 709 luminance of a linear RGB colour (glm::vec3 or glm::dvec3: any type with
/// value_type and .r, .g, .b), in its own precision.
template <class Rgb>
constexpr typename Rgb::value_type luminance(const Rgb& c) {
  using T = typename Rgb::value_type;
  return T(0.2126) * c.r + T(0.7152) * c.g + T(0.0722) * c.b;
}

}  // namespace prt
