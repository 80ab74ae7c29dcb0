// Constants that more than one library needs, defined once. std::numbers (C++20) rather than
// POSIX M_PI, which the C++ standard does not promise: the values are the same
// (std::numbers::pi == M_PI, and pi_v<float> is the float nearest to both).
#pragma once

#include <numbers>

namespace prt {

inline constexpr double kPi = std::numbers::pi_v<double>;
inline constexpr float kPiF = std::numbers::pi_v<float>;

}  // namespace prt
