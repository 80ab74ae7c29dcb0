// What adaptive refinement measures (refine_estimator.h).
//
// Per point x with normal N the direct pass's estimator (vertex_rays.h, the bake's ray origins
// and cosine-weighted Sobol directions) gives the blocked transfer
//   b_i(x) = t^unocc_i − t⁰_i ≈ (π/n) Σ_s (1 − V_s) y_i(ω_s),
// with per coefficient the sample variance of the mean, s²_i = (π² Σ_s (1−V_s) y_i² / n − b_i²) / n.
// Measuring b rather than t⁰ leaves out the unoccluded part, whose interpolation across a
// triangle is the normals' (the mesh as its author shaded it), and makes an unoccluded point
// exactly zero with zero variance: noise cannot split a surface that sees the whole sky.
// Every point uses the same scramble (common random numbers), so neighbouring points with one
// normal see the same directions and their differences carry little noise.
//
// The error of an edge (a, b) with midpoint m is e = b(m) − (b(a) + b(b))/2, with
// σ² = Σ_i s²_i(m) + (s²_i(a) + s²_i(b))/4 (as if independent: a bound for correlated
// estimates); of a triangle with centroid c, e = b(c) − (b(a) + b(b) + b(c'))/3, σ² = s²(c) +
// Σ s²(corners)/9. The score is (|e| − kNoiseSigmas·σ) / R, R = |t^unocc| = (Σ_l Â_l² (2l+1)/4π)^½
// (the same for every normal): the worst irradiance error over lights of unit norm, relative
// to the best unoccluded irradiance over them. refine.cpp splits the scores above the
// tolerance, largest first, until the budget is spent.
//
// Every estimate is a function of its point alone: the same for any thread count or rank.
#include "refine_estimator.h"

#include <algorithm>
#include <bit>
#include <cmath>

#include "prt/sh.h"
#include "unbury.h"
#include "vertex_rays.h"

namespace prt::bake::refinement {

namespace {

// How many standard errors of Monte Carlo noise an error must exceed before it counts.
constexpr double kNoiseSigmas = 2.0;
// The scramble of every refinement point (common random numbers), a "vertex index" no bake uses
// for anything else.
constexpr size_t kRefineStream = 0x7265666eu;
// Rays traced as one stream.
constexpr int kStream = 256;

}  // namespace

Estimator::Estimator(const RayScene& rays, int bands, uint32_t samples, uint64_t seed, float extent)
    : rays_(rays),
      bands_(bands),
      n2_(bands * bands),
      samples_(samples),
      seed_(seed),
      extent_(extent),
      tnear_(tnearFor(extent)),
      local_(samples) {
  const VertexSampler up(glm::vec3(0.0f), glm::vec3(0, 0, 1), seed_, kRefineStream, tnear_);
  Ray ray;
  for (uint32_t j = 0; j < samples_; ++j) {
    up.make(j, ray);
    local_[j] = ray.dir;
  }
  reference_ = 0.0;
  for (int l = 0; l < bands_; ++l) {
    const double a = sh::clampedCosineFactor(l);
    reference_ += a * a * (2 * l + 1) / (4.0 * kPi);
  }
  reference_ = std::sqrt(reference_);
}

void Estimator::trace(const Point& p, Estimates& out, uint32_t slot) const {
  const glm::vec3 origin =
      unburiedOrigin(rays_, p.position, p.normal, liftedOrigin(p.position, p.normal, p.pull, extent_),
                     {p.target.data(), size_t(p.targets)}, extent_);
  const VertexSampler sampler(origin, p.normal, seed_, kRefineStream, tnear_);
  out.normal[slot] = p.normal;
  uint64_t* bits = &out.blocked[slot * out.words];
  alignas(64) Ray batch[kStream];
  for (uint32_t first = 0; first < samples_; first += kStream) {
    const uint32_t count = std::min<uint32_t>(kStream, samples_ - first);
    for (uint32_t j = 0; j < count; ++j) sampler.make(first + j, batch[j]);
    rays_.occluded(batch, count);
    for (uint32_t j = 0; j < count; ++j)
      if (batch[j].occludedHit()) bits[(first + j) / 64] |= uint64_t(1) << ((first + j) % 64);
  }
}

// The score of a candidate: point 0 (a midpoint or centroid) against the mean of points
// 1..n-1 (the corners that interpolate there). Direction s of every point is the same sample
// about its own normal, so per direction the paired difference of the visible light
//   D_i,s = π [U_0,s y_i(ω_0,s) − Σ_c U_c,s y_i(ω_c,s) / (n−1)]     (U = unblocked)
// has mean e_i, the interpolation error of the direct transfer t⁰, and its sample variance
// gives e's standard error with the correlation of the shared directions included. The sum
// runs over the directions some point sees, or (fewer to evaluate where most are seen) over
// the blocked ones: e = e_unoccluded − (the same sum over B = 1 − U), e_unoccluded the
// closed form. What is scored is e − v̄ e_unoccluded, v̄ the points' mean visible share:
// the error visibility adds to the normals' own interpolation (the mesh as its author
// shaded it), zero on a surface that sees the whole sky or none of it, whatever its
// curvature, and zero where the points' visibility agrees on a flat surface.
double Estimator::score(const Estimates& est, const uint32_t* pts, int n) const {
  bool same = true;
  for (int c = 1; c < n; ++c) same = same && est.normal[pts[c]] == est.normal[pts[0]];
  Frame frame[4];
  double eu[sh::kMaxBands * sh::kMaxBands] = {};  // closed-form interpolation error of t_unoccluded
  unoccludedError(est, pts, n, same, frame, eu);
  const double seen = meanSeenShare(est, pts, n);
  const bool overBlocked = fewerBlocked(est, pts, n);  // sum over B, e = e_u − Σ
  double sum[sh::kMaxBands * sh::kMaxBands] = {}, sum2[sh::kMaxBands * sh::kMaxBands] = {};
  sumDifferences(est, pts, n, same, overBlocked, frame, sum, sum2);
  const double ns = samples_;
  double err2 = 0.0, var = 0.0;
  for (int i = 0; i < n2_; ++i) {
    const double mean = kPi * sum[i] / ns;
    const double e = (overBlocked ? eu[i] - mean : mean) - seen * eu[i];
    err2 += e * e;
    var += std::max(0.0, (kPi * kPi * sum2[i] / ns - mean * mean) / ns);
  }
  return (std::sqrt(err2) - kNoiseSigmas * std::sqrt(var)) / reference_;
}

// The bits of word `word` that stand for directions (the last word's tail holds none).
uint64_t Estimator::validBits(size_t word, size_t words) const {
  const uint64_t tail = samples_ % 64 ? (uint64_t(1) << (samples_ % 64)) - 1 : ~uint64_t(0);
  return word + 1 == words ? tail : ~uint64_t(0);
}

// Each point's frame, and unless all points share one normal, the closed-form interpolation
// error `eu` of t_unoccluded (point 0 against the mean of the others).
void Estimator::unoccludedError(const Estimates& est, const uint32_t* pts, int n, bool same, Frame* frame,
                                double* eu) const {
  const double w = 1.0 / (n - 1);
  float y[sh::kMaxBands * sh::kMaxBands];
  for (int c = 0; c < n; ++c) {
    frame[c] = Frame::fromNormal(est.normal[pts[c]]);
    if (same) continue;
    sh::evaluate(bands_, est.normal[pts[c]], y);
    for (int l = 0; l < bands_; ++l)
      for (int m = -l; m <= l; ++m)
        eu[sh::index(l, m)] += (c == 0 ? 1.0 : -w) * sh::clampedCosineFactor(l) * y[sh::index(l, m)];
  }
}

// The points' mean visible share of the directions.
double Estimator::meanSeenShare(const Estimates& est, const uint32_t* pts, int n) const {
  double seen = 0.0;
  for (int c = 0; c < n; ++c) {
    uint64_t b = 0;
    for (size_t word = 0; word < est.words; ++word)
      b += uint64_t(std::popcount(est.blocked[pts[c] * est.words + word]));
    seen += double(samples_ - b) / samples_;
  }
  return seen / n;
}

// Whether the directions some point finds blocked are no more than those some point sees:
// then the differences are summed over the blocked ones.
bool Estimator::fewerBlocked(const Estimates& est, const uint32_t* pts, int n) const {
  uint64_t unionBlocked = 0, unionSeen = 0;
  for (size_t word = 0; word < est.words; ++word) {
    const uint64_t valid = validBits(word, est.words);
    uint64_t any = 0, none = 0;
    for (int c = 0; c < n; ++c) {
      any |= est.blocked[pts[c] * est.words + word];
      none |= ~est.blocked[pts[c] * est.words + word] & valid;
    }
    unionBlocked += uint64_t(std::popcount(any));
    unionSeen += uint64_t(std::popcount(none));
  }
  return unionBlocked <= unionSeen;
}

// Sums D_i,s / π and its square over the directions of the chosen set (blocked or seen) in
// which the points differ.
void Estimator::sumDifferences(const Estimates& est, const uint32_t* pts, int n, bool same, bool overBlocked,
                               const Frame* frame, double* sum, double* sum2) const {
  const double w = 1.0 / (n - 1);
  float y[sh::kMaxBands * sh::kMaxBands];
  double d[sh::kMaxBands * sh::kMaxBands];
  for (size_t word = 0; word < est.words; ++word) {
    const uint64_t valid = validBits(word, est.words);
    uint64_t bits[4], any = 0, all = valid;
    for (int c = 0; c < n; ++c) {
      bits[c] = overBlocked ? est.blocked[pts[c] * est.words + word] : ~est.blocked[pts[c] * est.words + word] & valid;
      any |= bits[c];
      all &= bits[c];
    }
    if (same) any &= ~all;  // one direction for all points, in the set for all: no difference
    while (any) {
      const int s = int(word * 64) + std::countr_zero(any);
      const uint64_t bit = uint64_t(1) << (s % 64);
      any &= any - 1;
      if (same) {
        double k = bits[0] & bit ? 1.0 : 0.0;
        for (int c = 1; c < n; ++c) k -= bits[c] & bit ? w : 0.0;
        if (k == 0.0) continue;
        sh::evaluate(bands_, frame[0].toWorld(local_[size_t(s)]), y);
        for (int i = 0; i < n2_; ++i) d[i] = k * y[i];
      } else {
        std::fill_n(d, n2_, 0.0);
        for (int c = 0; c < n; ++c) {
          if (!(bits[c] & bit)) continue;
          sh::evaluate(bands_, frame[c].toWorld(local_[size_t(s)]), y);
          const double k = c == 0 ? 1.0 : -w;
          for (int i = 0; i < n2_; ++i) d[i] += k * y[i];
        }
      }
      for (int i = 0; i < n2_; ++i) {
        sum[i] += d[i];
        sum2[i] += d[i] * d[i];
      }
    }
  }
}

}  // namespace prt::bake::refinement
