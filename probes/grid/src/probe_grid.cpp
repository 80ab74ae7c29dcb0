// The probe grid in memory: index, per-frame relighting and the interpolation with leak
// prevention. The method and its limits are written up in docs/probes.md; OpenVDB I/O lives in
// probe_grid_vdb.cpp so that only one translation unit pays for OpenVDB's headers.
#include "prt/probe_grid.h"

#include <algorithm>
#include <cmath>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "prt/error.h"

namespace prt {

namespace {

// How far (in lattice units) the grid's domain reaches beyond the lattice's bounding box: half
// a cell, so the domain is the union of the probes' cells. prt bake puts probes at the cell
// centres of the bake bounds, so a receiver on a floor at the bounds' edge (half a spacing
// below the lowest probes) is still lit by its nearest probes, clamped.
constexpr double kDomainMargin = 0.5;
// Points within this distance (in lattice units) outside the domain still count as inside: a
// receiver lying exactly on the boundary must not flicker in and out because of float rounding
// of its world position.
constexpr double kBoundaryTolerance = 1e-4;
// Beyond the domain the probes' answer fades into the unoccluded light over this many spacings
// (per axis, the farthest axis decides), so that a receiver leaving the grid does not jump.
constexpr double kFadeSpacings = 1.0;
// Floor of the variance in the Chebyshev test, as a fraction of the smallest spacing. Without
// it a face whose rays all hit at one distance (σ² = 0, or slightly negative from rounding)
// would divide by zero; with it the visibility falls to ~1e-6 within 0.1 spacing past μ.
constexpr double kVarianceFloor = 0.01;
// Weight kept by a probe that the visibility and back-face tests reject, relative to its
// trilinear weight. If every probe is rejected, these floors alone remain and normalise to plain
// trilinear over the valid probes (the fallback), instead of 0/0.
constexpr double kMinWeight = 1e-6;
// Per-axis floor of the trilinear factors in the second pass, used only when every probe with
// a non-zero trilinear weight is invalid (x on a lattice plane whose probes are all inside
// geometry): the valid probes of the cell then share the weight, nearest first.
constexpr double kTrilinearFloor = 1e-3;

size_t linearIndex(const glm::ivec3& c, const glm::ivec3& dims) {
  return (size_t(c.z) * size_t(dims.y) + size_t(c.y)) * size_t(dims.x) + size_t(c.x);
}

bool insideDims(const glm::ivec3& c, const glm::ivec3& dims) {
  return c.x >= 0 && c.y >= 0 && c.z >= 0 && c.x < dims.x && c.y < dims.y && c.z < dims.z;
}

}  // namespace

void ProbeGrid::buildIndex() {
  PRT_CHECK(dims.x >= 0 && dims.y >= 0 && dims.z >= 0);
  dense_.assign(size_t(dims.x) * size_t(dims.y) * size_t(dims.z), -1);
  for (size_t p = 0; p < coord.size(); ++p) {
    PRT_CHECK(insideDims(coord[p], dims));
    int32_t& slot = dense_[linearIndex(coord[p], dims)];
    PRT_CHECK_EQ(slot, -1);  // two probes at one lattice point
    slot = int32_t(p);
  }
}

int ProbeGrid::find(const glm::ivec3& c) const {
  if (!insideDims(c, dims)) return -1;
  // An empty index here means buildIndex() was not called after filling `coord`.
  PRT_CHECK_EQ(dense_.size(), size_t(dims.x) * size_t(dims.y) * size_t(dims.z));
  return dense_[linearIndex(c, dims)];
}

namespace {

// c_p = M_p · l − M⁰_p · d for every probe (d = null: no direct part), each probe summed by one
// thread in a fixed order, so the result does not depend on how TBB splits the range.
std::vector<glm::vec3> relight(const ProbeGrid& grid, const sh::ShRgb& light, const sh::ShRgb* direct) {
  const int n2 = grid.coeffs();
  const size_t stride = grid.transferStride(), dstride = grid.directStride();
  PRT_CHECK_EQ(grid.transfer.size(), grid.probeCount() * stride);
  if (direct) PRT_CHECK_EQ(grid.direct.size(), grid.probeCount() * dstride);
  const sh::ShRgb l = sh::resize(light, grid.bands);
  const sh::ShRgb d = direct ? sh::resize(*direct, grid.bands) : sh::ShRgb();
  std::vector<glm::vec3> out(grid.probeCount() * size_t(n2));
  auto relightOne = [&](size_t p) {
    const float* m = grid.transfer.data() + p * stride;
    glm::vec3* c = out.data() + p * size_t(n2);
    for (int j = 0; j < n2; ++j) {
      glm::vec3 acc(0.0f);
      for (int i = 0; i < n2; ++i) {
        const float* rgb = m + (size_t(j) * n2 + i) * 3;
        acc += glm::vec3(rgb[0], rgb[1], rgb[2]) * l.c[size_t(i)];
      }
      c[j] = acc;
    }
    if (!direct) return;
    const float* m0 = grid.direct.data() + p * dstride;  // upper triangle, row by row
    for (int j = 0; j < n2; ++j)
      for (int i = j; i < n2; ++i) {
        const float v = *m0++;
        c[j] -= v * d.c[size_t(i)];
        if (i != j) c[i] -= v * d.c[size_t(j)];
      }
  };
  tbb::parallel_for(tbb::blocked_range<size_t>(0, grid.probeCount(), 256), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t p = r.begin(); p < r.end(); ++p) relightOne(p);
  });
  return out;
}

}  // namespace

std::vector<glm::vec3> relightProbes(const ProbeGrid& grid, const sh::ShRgb& light) {
  return relight(grid, light, nullptr);
}

std::vector<glm::vec3> relightProbes(const ProbeGrid& grid, const sh::ShRgb& light, const sh::ShRgb& directLight) {
  PRT_CHECK(grid.hasDirect());
  sh::ShRgb all = sh::resize(light, grid.bands);
  all += sh::resize(directLight, grid.bands);
  return relight(grid, all, &directLight);
}

namespace {

// The weight of one corner probe for a receiver: the whole formula of docs/probes.md
// ("Interpolation"), in one place because the renderer's shader ports it line by line.
//   wt: trilinear weight × validity (> 0); d = x − P (receiver minus the probe's position);
//   m: the probe's moments; n: the receiver's unit normal or null; s: the smallest spacing.
double cornerWeight(double wt, const glm::dvec3& d, const std::array<glm::vec2, 6>& m, const glm::dvec3* n, double s) {
  // Visibility. Face f = 2a + (d_a < 0) of axis a stores the mean μ and mean square of the depth
  // along a, |t · ω_a|, of the surfaces its rays hit (misses count as 2 spacings). A wall
  // perpendicular to a at depth D gives μ = D exactly, whatever the ray's angle, so a receiver
  // with |d_a| > D is behind it. Chebyshev's one-sided inequality bounds the chance that the
  // probe's surface on that side lies beyond |d_a|: P(depth ≥ |d_a|) ≤ σ² / (σ² + (|d_a| − μ)²);
  // cubed as in DDGI, so the cut-off behind a surface is sharp while w = 1 in front of μ. All
  // three axes must pass: a receiver offset sideways more than forwards is still behind the wall.
  const double floor2 = (kVarianceFloor * s) * (kVarianceFloor * s);
  double wv = 1.0;
  for (int a = 0; a < 3; ++a) {
    const glm::vec2 ma = m[size_t(2 * a + (d[a] < 0.0 ? 1 : 0))];
    const double depth = std::fabs(d[a]), mu = ma.x;
    if (depth <= mu) continue;
    const double var = std::max(double(ma.y) - mu * mu, floor2);
    const double cheb = var / (var + (depth - mu) * (depth - mu));
    wv *= cheb * cheb * cheb;
  }
  // DDGI's soft back-face weight: probes behind the surface (seen against the normal) count less
  // but never zero, so thin geometry between x and every probe still gets light.
  double wb = 1.0;
  const double r = glm::length(d);
  if (n && r > 1e-6 * s) {
    const double h = (glm::dot(-d / r, *n) + 1.0) * 0.5;
    wb = h * h + 0.2;
  }
  return wt * std::max(wv * wb, kMinWeight);
}

}  // namespace

ProbeWeights probeWeights(const ProbeGrid& grid, const glm::vec3& x, const glm::vec3* normal) {
  ProbeWeights out;
  const size_t count = grid.probeCount();
  if (count == 0) return out;
  PRT_CHECK_EQ(grid.validity.size(), count);
  PRT_CHECK_EQ(grid.offset.size(), count);
  PRT_CHECK_EQ(grid.moments.size(), count);

  // Cell of x and its fractional position t in it, x clamped to the lattice's box (a point in
  // the half-cell shell takes the values of the box's nearest face). An axis with one lattice
  // point has a cell of zero width: t = 0 there.
  // Beyond the domain (by `over` spacings on the farthest axis) the share of the unoccluded
  // light rises linearly from 0 at the domain's edge (plus the boundary tolerance) to 1 one
  // fade width further, where the probes stop.
  const glm::dvec3 u = (glm::dvec3(x) - grid.origin) / grid.spacing;
  glm::ivec3 base;
  glm::dvec3 t;
  bool shell = false;
  double over = 0.0;
  for (int a = 0; a < 3; ++a) {
    const double hi = double(grid.dims[a] - 1), margin = kDomainMargin + kFadeSpacings + kBoundaryTolerance;
    if (!(u[a] > -margin && u[a] < hi + margin)) return out;  // NaN too
    shell |= u[a] < -kBoundaryTolerance || u[a] > hi + kBoundaryTolerance;
    over = std::max({over, -kDomainMargin - u[a], u[a] - (hi + kDomainMargin)});
    const double v = std::clamp(u[a], 0.0, hi);
    base[a] = std::min(int(std::floor(v)), std::max(grid.dims[a] - 2, 0));
    t[a] = v - base[a];
  }
  const double fade = std::clamp((over - kBoundaryTolerance) / kFadeSpacings, 0.0, 1.0);
  out.cover = ProbeCover::NoValidProbe;

  glm::dvec3 n(0.0);
  const bool useNormal = normal != nullptr && glm::dot(*normal, *normal) > 0.0f;
  if (useNormal) n = glm::normalize(glm::dvec3(*normal));
  const double minSpacing = std::min({grid.spacing.x, grid.spacing.y, grid.spacing.z});

  struct Corner {
    int probe = -1;
    glm::dvec3 lerp{0.0};  // per-axis trilinear factors
  };
  std::array<Corner, 8> corners;
  bool anyTrilinear = false;
  for (int c = 0; c < 8; ++c) {
    const glm::ivec3 off(c & 1, (c >> 1) & 1, (c >> 2) & 1);
    const int p = grid.find(base + off);
    if (p < 0 || !(grid.validity[size_t(p)] > 0.0f)) continue;  // invalid probes are never read
    corners[c].probe = p;
    for (int a = 0; a < 3; ++a) corners[c].lerp[a] = off[a] ? t[a] : 1.0 - t[a];
    anyTrilinear |= corners[c].lerp.x * corners[c].lerp.y * corners[c].lerp.z > 0.0;
  }

  std::array<double, 8> weight{};
  double sum = 0.0;
  for (int c = 0; c < 8; ++c) {
    const int p = corners[c].probe;
    if (p < 0) continue;
    glm::dvec3 f = corners[c].lerp;
    if (!anyTrilinear) f = glm::max(f, glm::dvec3(kTrilinearFloor));
    const double wt = f.x * f.y * f.z * double(grid.validity[size_t(p)]);
    if (wt <= 0.0) continue;
    const glm::dvec3 d = glm::dvec3(x) - grid.position(size_t(p));
    weight[size_t(c)] = cornerWeight(wt, d, grid.moments[size_t(p)], useNormal ? &n : nullptr, minSpacing);
    sum += weight[size_t(c)];
  }
  if (!(sum > 0.0)) return out;
  out.cover = fade > 0.0 ? ProbeCover::Fade : shell ? ProbeCover::Shell : ProbeCover::Lattice;
  out.fade = float(fade);
  for (int c = 0; c < 8; ++c) {
    if (weight[size_t(c)] <= 0.0) continue;
    out.probe[size_t(out.count)] = corners[c].probe;
    out.weight[size_t(out.count)] = float(weight[size_t(c)] / sum);
    ++out.count;
  }
  return out;
}

const char* probeCoverName(ProbeCover c) {
  switch (c) {
    case ProbeCover::Lattice:
      return "lattice";
    case ProbeCover::Shell:
      return "shell";
    case ProbeCover::Fade:
      return "fade";
    case ProbeCover::Outside:
      return "outside";
    case ProbeCover::NoValidProbe:
      return "no_valid_probe";
  }
  return "?";
}

void probeDomain(const ProbeGrid& grid, glm::dvec3& lo, glm::dvec3& hi) {
  lo = grid.origin - kDomainMargin * grid.spacing;
  hi = grid.origin + grid.spacing * (glm::dvec3(grid.dims - 1) + kDomainMargin);
}

namespace {

// Σ_p w_p c_p over the probes of one interpolation.
sh::ShRgb blend(const ProbeGrid& grid, const std::vector<glm::vec3>& relit, const ProbeWeights& w) {
  const int n2 = grid.coeffs();
  PRT_CHECK_EQ(relit.size(), grid.probeCount() * size_t(n2));
  sh::ShRgb out(grid.bands);
  for (int k = 0; k < w.count; ++k) {
    const glm::vec3* c = relit.data() + size_t(w.probe[size_t(k)]) * size_t(n2);
    for (int i = 0; i < n2; ++i) out.c[size_t(i)] += w.weight[size_t(k)] * c[i];
  }
  return out;
}

}  // namespace

sh::ShRgb interpolateRadiance(const ProbeGrid& grid, const std::vector<glm::vec3>& relit, const glm::vec3& x,
                              const glm::vec3* normal) {
  return blend(grid, relit, probeWeights(grid, x, normal));
}

sh::ShRgb receiverRadiance(const ProbeGrid& grid, const std::vector<glm::vec3>& relit, const sh::ShRgb& light,
                           const glm::vec3& x, const glm::vec3* normal, ProbeCover* cover) {
  const ProbeWeights w = probeWeights(grid, x, normal);
  if (cover) *cover = w.cover;
  return receiverRadiance(grid, relit, light, w);
}

sh::ShRgb receiverRadiance(const ProbeGrid& grid, const std::vector<glm::vec3>& relit, const sh::ShRgb& light,
                           const ProbeWeights& w) {
  const sh::ShRgb l = sh::resize(light, grid.bands);
  if (w.count == 0) return l;
  sh::ShRgb out = blend(grid, relit, w);
  if (w.fade > 0.0f)
    for (size_t i = 0; i < out.c.size(); ++i) out.c[i] = (1.0f - w.fade) * out.c[i] + w.fade * l.c[i];
  return out;
}

}  // namespace prt
