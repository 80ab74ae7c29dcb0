// The bounce operator's one-byte weights (prt/bounce_operator.h; docs/formats.md, "The bounce
// operator"): row weights q = w · 65535 and gradient weights g · 16384, each a code of a table
// that is exact for small values and grows geometrically above.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <numeric>

#include "prt/bounce_operator.h"

namespace prt {

namespace {

// N ascending values: 0 … linear − 1 themselves, then geometric from `linear` to `top`, rounded.
template <size_t N>
std::array<uint16_t, N> codeTable(int linear, double top) {
  std::array<uint16_t, N> t{};
  for (int c = 0; c < int(N); ++c) {
    const double v = c < linear ? c : linear * std::pow(top / linear, double(c - linear) / double(int(N) - 1 - linear));
    t[size_t(c)] = uint16_t(std::min(std::lround(v), std::lround(top)));
  }
  return t;
}

const std::array<uint16_t, 256>& rowTable() {
  static const std::array<uint16_t, 256> t = codeTable<256>(32, BounceOperator::kWeightOne);
  return t;
}

// Gradient magnitudes: codes 0 … 127 (the sign is the code's).
const std::array<uint16_t, 128>& gradientTable() {
  static const std::array<uint16_t, 128> t = codeTable<128>(16, 32767.0);
  return t;
}

// The code of the table value nearest x (the lower on a tie).
template <size_t N>
int nearest(const std::array<uint16_t, N>& t, double x) {
  const auto above = std::lower_bound(t.begin(), t.end(), x);
  if (above == t.end()) return int(N) - 1;
  if (above == t.begin()) return 0;
  const auto below = above - 1;
  return int((x - *below <= *above - x ? below : above) - t.begin());
}

// The table values just below and just above x ≥ 0 (equal where x is one, or beyond the ends).
template <size_t N>
std::pair<uint16_t, uint16_t> bracket(const std::array<uint16_t, N>& t, double x) {
  const auto above = std::lower_bound(t.begin(), t.end(), x);
  const uint16_t hi = above == t.end() ? t.back() : *above;
  const uint16_t lo = above == t.begin() || above == t.end() ? hi : *(above - 1);
  return {lo, hi};
}

// Which of a row's entries take their second value (b instead of a) so that the row's sum is
// nearest `target` (an integer, the exact sum less Σ a): subset sums over the differences b − a,
// reachable sums marked entry by entry, each with the entry that first reached it (which, taken
// back, leads to a sum reached before that entry). Returns false (and changes nothing) when the
// sums span more than kMaxSpan, or the search would take more than kMaxWork steps.
constexpr int64_t kMaxSpan = 1 << 16, kMaxWork = int64_t(1) << 22;
bool nearestSubset(const std::vector<int64_t>& diff, int64_t target, std::vector<bool>& useB) {
  int64_t lo = 0, hi = 0;
  for (int64_t d : diff) (d < 0 ? lo : hi) += d;
  if (hi - lo > kMaxSpan || (hi - lo) * int64_t(diff.size()) > kMaxWork) return false;
  std::vector<int32_t> from(size_t(hi - lo + 1), -2);  // -2: not reached; -1: the empty set
  from[size_t(-lo)] = -1;
  for (size_t i = 0; i < diff.size(); ++i) {
    const int64_t d = diff[i];
    if (d == 0) continue;
    // Sums reached before entry i, each once: walk away from the shift.
    for (int64_t s = d > 0 ? hi : lo; d > 0 ? s >= lo + d : s <= hi + d; s += d > 0 ? -1 : 1)
      if (from[size_t(s - lo)] == -2 && from[size_t(s - d - lo)] != -2) from[size_t(s - lo)] = int32_t(i);
  }
  int64_t best = 0;
  for (int64_t s = lo; s <= hi; ++s)
    if (from[size_t(s - lo)] != -2 && std::llabs(s - target) < std::llabs(best - target)) best = s;
  useB.assign(diff.size(), false);
  for (int64_t s = best; from[size_t(s - lo)] >= 0;) {
    const int32_t i = from[size_t(s - lo)];
    useB[size_t(i)] = true;
    s -= diff[size_t(i)];
  }
  return true;
}

// Each of `scaled` (signed where `table` holds magnitudes of signed values) on the value of the
// table just below or just above its magnitude, so that the sum stays what it was: from the
// largest magnitude down, each the one that keeps the running sum nearest; where that leaves
// the sum off by more than a unit (a short row of coarse entries: the smallest entry's half step
// bounds it, and the larger ones' choices may already have gone past), the choices whose sum is
// nearest (nearestSubset). `exact`: each rounded to the nearest integer instead (within ±top).
template <size_t N, class T>
std::vector<T> heldValues(const std::vector<double>& scaled, const std::array<uint16_t, N>& table, double top,
                          bool exact) {
  if (exact) {
    std::vector<T> out(scaled.size());
    for (size_t i = 0; i < scaled.size(); ++i) out[i] = T(std::lround(std::clamp(scaled[i], -top, top)));
    return out;
  }
  std::vector<size_t> order(scaled.size());
  std::iota(order.begin(), order.end(), size_t(0));
  std::stable_sort(order.begin(), order.end(),
                   [&](size_t a, size_t b) { return std::fabs(scaled[a]) > std::fabs(scaled[b]); });
  std::vector<T> out(scaled.size(), 0);
  std::vector<int64_t> a(scaled.size()), diff(scaled.size());
  double owed = 0.0, exactSum = 0.0;  // the exact sum so far less the held one; the exact sum
  for (size_t i : order) {
    const double x = std::clamp(scaled[i], -top, top);
    const double sign = x < 0.0 ? -1.0 : 1.0;
    const auto [lo, hi] = bracket(table, std::fabs(x));
    a[i] = int64_t(sign * lo), diff[i] = int64_t(sign * hi) - a[i];
    const double v = std::fabs(owed + x - double(a[i])) < std::fabs(owed + x - double(a[i] + diff[i]))
                         ? double(a[i])
                         : double(a[i] + diff[i]);
    out[i] = T(v);
    owed += x - v;
    exactSum += x;
  }
  std::vector<bool> useB;
  if (std::fabs(owed) > 1.0) {
    int64_t base = 0;
    for (int64_t v : a) base += v;
    if (nearestSubset(diff, std::llround(exactSum) - base, useB))
      for (size_t i = 0; i < out.size(); ++i) out[i] = T(a[i] + (useB[i] ? diff[i] : 0));
  }
  return out;
}

}  // namespace

uint16_t BounceOperator::weightOfCode(uint8_t code) { return rowTable()[code]; }

uint8_t BounceOperator::codeOfWeight(uint16_t q) { return uint8_t(nearest(rowTable(), q)); }

std::vector<uint16_t> BounceOperator::storedWeights(const std::vector<double>& scaled, bool exact) {
  std::vector<double> nonNegative(scaled.size());
  for (size_t i = 0; i < scaled.size(); ++i) nonNegative[i] = std::max(scaled[i], 0.0);
  return heldValues<256, uint16_t>(nonNegative, rowTable(), kWeightOne, exact);
}

int16_t BounceOperator::gradientOfCode(int8_t code) {
  const int m = std::min(std::abs(int(code)), 127);
  return int16_t(code < 0 ? -gradientTable()[size_t(m)] : gradientTable()[size_t(m)]);
}

int8_t BounceOperator::codeOfGradient(int16_t g) {
  const int m = nearest(gradientTable(), std::fabs(double(g)));
  return int8_t(g < 0 ? -m : m);
}

std::vector<int16_t> BounceOperator::storedGradients(const std::vector<double>& scaled, bool exact) {
  return heldValues<128, int16_t>(scaled, gradientTable(), 32767.0, exact);
}

}  // namespace prt
