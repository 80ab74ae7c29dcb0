// The sun inside an environment map: region, in-painting, cap model. docs/lights.md ("Suns in
// environment maps: extractSun") has the method, the criterion and the measurements.
#include "prt/sun_extract.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <unordered_map>
#include <vector>

#include "prt/error.h"
#include "prt/light.h"
#include "prt/math.h"

namespace prt {

namespace {

// Rec. 709 / sRGB primaries: the luminance that ranks pixels and weighs the direction.
double luminance(const glm::dvec3& c) { return prt::luminance(c); }
double luminance(const glm::vec3& c) { return luminance(glm::dvec3(c)); }

double degrees(double radians) { return radians * 180.0 / kPi; }

// The lat-long grid: per-row and per-column tables, neighbours, pixel moments, and the weights
// of the Laplacian that in-paints.
class Grid {
 public:
  Grid(int w, int h)
      : w_(w), h_(h), sinT_(h), cosT_(h), dOmega_(h), ax_(h), ay_(h), wH_(h), wV_(h + 1, 0.0), cosP_(w), sinP_(w) {
    const double dTheta = kPi / h, dPhi = 2.0 * kPi / w;
    for (int y = 0; y < h; ++y) {
      const double t = kPi * ((y + 0.5) / h);
      sinT_[y] = std::sin(t);
      cosT_[y] = std::cos(t);
      dOmega_[y] = equirectPixelSolidAngle(y, w, h);
      // Note 1: the pixel's first moment m = ∫_pixel ω dω over θ ∈ [θ₀, θ₁], φ ∈ [φ₀, φ₁]:
      //   m_x = (sin φ₁ − sin φ₀) · A,  m_z = (cos φ₀ − cos φ₁) · A,  A = ∫ sin²θ dθ
      //       = (Δθ − cos 2θ_c sin Δθ) / 2,   m_y = Δφ ∫ cos θ sin θ dθ = Δφ sin 2θ_c sin Δθ / 2,
      // with sin φ₁ − sin φ₀ = 2 cos φ_c sin(Δφ/2) and cos φ₀ − cos φ₁ = 2 sin φ_c sin(Δφ/2).
      // Summing e·m rather than e·ΔΩ·(centre direction) gives the exact moments of a map that
      // is constant over each pixel: no bias in θ from the pixel's sin θ weighting (up to
      // Δθ² cot θ / 12 with centres, 0.03° at 5° from the pole of a 256×128 map).
      const double a = (dTheta - std::cos(2.0 * t) * std::sin(dTheta)) / 2.0;
      ax_[y] = 2.0 * std::sin(dPhi / 2.0) * a;
      ay_[y] = dPhi * std::sin(2.0 * t) * std::sin(dTheta) / 2.0;
      // Note 2: the in-painting Laplacian is the finite-volume Laplace-Beltrami operator of the
      // sphere on this grid: an edge's weight is the length of the face two pixels share over
      // the distance between their centres. Along a row: Δθ / (sin θ_c Δφ); between rows y−1
      // and y: sin θ_e Δφ / Δθ, θ_e = π y / H, which is 0 at the poles (the pixels of the first
      // row meet there in a point). Any positive weights obey the maximum principle; these
      // make the fill isotropic on the sphere, so a hole near a pole is not smeared along u.
      wH_[y] = dTheta / (sinT_[y] * dPhi);
    }
    for (int e = 1; e < h; ++e) wV_[e] = std::sin(kPi * e / h) * dPhi / dTheta;
    for (int x = 0; x < w; ++x) {
      const double p = 2.0 * kPi * ((x + 0.5) / w - 0.5);
      cosP_[x] = std::cos(p);
      sinP_[x] = std::sin(p);
    }
  }

  int width() const { return w_; }
  int height() const { return h_; }
  size_t id(int x, int y) const { return static_cast<size_t>(y) * w_ + x; }
  int xOf(size_t id) const { return static_cast<int>(id % w_); }
  int yOf(size_t id) const { return static_cast<int>(id / w_); }
  double solidAngle(int y) const { return dOmega_[y]; }

  // The direction of pixel (x, y)'s centre: equirectDirection((x + ½)/W, (y + ½)/H).
  glm::dvec3 direction(int x, int y) const { return {sinT_[y] * cosP_[x], cosT_[y], sinT_[y] * sinP_[x]}; }
  // ∫_pixel ω dω (Note 1).
  glm::dvec3 moment(int x, int y) const { return {ax_[y] * cosP_[x], ay_[y], ax_[y] * sinP_[x]}; }

  // The 8 neighbours of a pixel, wrapping in u; across a pole the neighbour is in the same row
  // on the opposite meridian (half a turn away).
  template <class F>
  void forNeighbours8(int x, int y, F&& f) const {
    for (int dy = -1; dy <= 1; ++dy)
      for (int dx = -1; dx <= 1; ++dx) {
        if (dx == 0 && dy == 0) continue;
        int nx = x + dx, ny = y + dy;
        if (ny < 0 || ny >= h_) {
          ny = ny < 0 ? 0 : h_ - 1;
          nx += w_ / 2;
        }
        nx = ((nx % w_) + w_) % w_;
        if (nx == x && ny == y) continue;
        f(nx, ny);
      }
  }

  // The Laplacian's neighbours (Note 2) with their weights; none across a pole (weight 0).
  template <class F>
  void forLaplaceNeighbours(int x, int y, F&& f) const {
    const int left = (x + w_ - 1) % w_, right = (x + 1) % w_;
    if (left != x) f(left, y, wH_[y]);
    if (right != x) f(right, y, wH_[y]);
    if (y > 0) f(x, y - 1, wV_[y]);
    if (y + 1 < h_) f(x, y + 1, wV_[y + 1]);
  }

 private:
  int w_, h_;
  std::vector<double> sinT_, cosT_, dOmega_, ax_, ay_, wH_, wV_, cosP_, sinP_;
};

// Σ L ΔΩ of a map, per channel: each row in double, the rows added in order.
glm::dvec3 mapPower(const ImageRgb& image, const Grid& grid) {
  glm::dvec3 total(0.0);
  for (int y = 0; y < image.height; ++y) {
    glm::dvec3 row(0.0);
    for (int x = 0; x < image.width; ++x) row += glm::dvec3(image.at(x, y));
    total += row * grid.solidAngle(y);
  }
  return total;
}

enum Mark : uint8_t { kNone = 0, kCore = 1, kRegion = 2, kBoundary = 3 };

// Grows the 8-connected set of pixels with luminance >= threshold from `seed`, keeping it
// within the cap of cos-radius `cosMax` around `centre`. Returns false, with `marks` cleared,
// when a pixel of the set lies outside the cap (the bright region is not compact).
bool growRegion(const ImageRgb& image, const Grid& grid, size_t seed, const glm::dvec3& centre, double cosMax,
                double threshold, std::vector<uint8_t>& marks, std::vector<size_t>& region) {
  region.clear();
  region.push_back(seed);
  marks[seed] = kCore;
  bool compact = true;
  for (size_t i = 0; i < region.size() && compact; ++i) {
    const int x = grid.xOf(region[i]), y = grid.yOf(region[i]);
    grid.forNeighbours8(x, y, [&](int nx, int ny) {
      const size_t n = grid.id(nx, ny);
      if (!compact || marks[n] != kNone || luminance(image.at(nx, ny)) < threshold) return;
      if (glm::dot(grid.direction(nx, ny), centre) < cosMax) {
        compact = false;
        return;
      }
      marks[n] = kCore;
      region.push_back(n);
    });
  }
  if (!compact) {
    for (size_t id : region) marks[id] = kNone;
    region.clear();
  }
  return compact;
}

// Note 3: the in-painted background b is harmonic inside the region (Δb = 0 with the Laplacian
// of Note 2) and equals the map on the pixels around it (Dirichlet). The system
//   (Σ_j w_ij) b_i − Σ_{j in region} w_ij b_j = Σ_{j outside} w_ij L_j
// is symmetric positive definite (every connected part of the region touches its boundary), so
// it is solved by preconditioned conjugate gradients, sequentially, in a fixed order:
// deterministic. Near a pole the weights along a row exceed those between rows by 1/sin²θ
// (3·10⁴ in the first row of a 512-row map), which a diagonal preconditioner leaves to the
// iteration (2253 iterations for a disk over the pole of a 1024×512 map); the preconditioner
// is instead the tridiagonal part along rows: the unknowns are in row order, and each run of
// horizontally adjacent ones is solved exactly (Thomas algorithm, one factorization). A run
// that closes around the u seam is cut there; CG takes the few modes that leaves.
struct Laplace {
  struct Edge {
    int j;     // unknown index, or -1 for a boundary pixel
    double w;  // weight
  };
  std::vector<double> diag;
  std::vector<std::array<Edge, 4>> edges;
  std::vector<int> edgeCount;
  std::vector<double> lower;               // weight between unknowns i − 1 and i of one run, else 0
  std::vector<double> denom, upperFactor;  // the Thomas factorization of the row-tridiagonal part

  void factor() {
    const size_t n = diag.size();
    denom.assign(n, 0.0);
    upperFactor.assign(n, 0.0);
    for (size_t i = 0; i < n; ++i) {
      // Row i of the tridiagonal part: −lower[i] b_{i−1} + diag[i] b_i − lower[i+1] b_{i+1}.
      denom[i] = diag[i] - (i > 0 ? lower[i] * lower[i] / denom[i - 1] : 0.0);
      upperFactor[i] = i + 1 < n ? -lower[i + 1] / denom[i] : 0.0;
    }
  }
  // z = M⁻¹ r for the tridiagonal part M.
  void precondition(const std::vector<double>& r, std::vector<double>& z) const {
    const size_t n = r.size();
    for (size_t i = 0; i < n; ++i) z[i] = (r[i] + (i > 0 ? lower[i] * z[i - 1] : 0.0)) / denom[i];
    for (size_t i = n - 1; i-- > 0;) z[i] -= upperFactor[i] * z[i + 1];
  }
};

std::vector<double> solveChannel(const Laplace& a, const std::vector<double>& rhs, double initial) {
  const size_t n = rhs.size();
  auto apply = [&](const std::vector<double>& v, std::vector<double>& out) {
    for (size_t i = 0; i < n; ++i) {
      double s = a.diag[i] * v[i];
      for (int k = 0; k < a.edgeCount[i]; ++k)
        if (a.edges[i][k].j >= 0) s -= a.edges[i][k].w * v[static_cast<size_t>(a.edges[i][k].j)];
      out[i] = s;
    }
  };
  std::vector<double> b(n, initial), r(n), z(n), p(n), q(n);
  apply(b, q);
  double rhsNorm = 0.0;
  for (size_t i = 0; i < n; ++i) {
    r[i] = rhs[i] - q[i];
    rhsNorm += rhs[i] * rhs[i];
  }
  // Relative residual 1e-12: far below float rounding of the stored residual map.
  const double tol2 = 1e-24 * std::max(rhsNorm, 1e-300);
  a.precondition(r, z);
  p = z;
  double rz = 0.0;
  for (size_t i = 0; i < n; ++i) rz += r[i] * z[i];
  const size_t maxIterations = 4 * n + 100;
  for (size_t it = 0; it < maxIterations; ++it) {
    double rr = 0.0;
    for (size_t i = 0; i < n; ++i) rr += r[i] * r[i];
    if (rr <= tol2) break;
    apply(p, q);
    double pq = 0.0;
    for (size_t i = 0; i < n; ++i) pq += p[i] * q[i];
    if (!(pq > 0.0)) break;
    const double alpha = rz / pq;
    for (size_t i = 0; i < n; ++i) {
      b[i] += alpha * p[i];
      r[i] -= alpha * q[i];
    }
    a.precondition(r, z);
    double rzNew = 0.0;
    for (size_t i = 0; i < n; ++i) rzNew += r[i] * z[i];
    const double beta = rzNew / rz;
    rz = rzNew;
    for (size_t i = 0; i < n; ++i) p[i] = z[i] + beta * p[i];
  }
  return b;
}

void checkInput(const ImageRgb& image, const SunExtractOptions& o) {
  if (image.width <= 0 || image.height <= 0)
    throw Error(cat("sun extraction: environment map of ", image.width, "x", image.height, " pixels is empty"));
  if (image.pixels.size() != static_cast<size_t>(image.width) * image.height)
    throw Error(cat("sun extraction: environment map of ", image.width, "x", image.height, " holds ",
                    image.pixels.size(), " pixels"));
  for (int y = 0; y < image.height; ++y)
    for (int x = 0; x < image.width; ++x) {
      const glm::vec3& c = image.at(x, y);
      if (!std::isfinite(c.r) || !std::isfinite(c.g) || !std::isfinite(c.b))
        throw Error(cat("sun extraction: environment map pixel (", x, ", ", y, ") is not finite"));
    }
  if (!(o.maxRadius > 0.0 && o.maxRadius < kPi / 2.0))
    throw Error(cat("sun extraction: maximum radius ", o.maxRadius, " rad is outside (0, π/2)"));
  if (!(o.peakFraction > 0.0 && o.peakFraction < 1.0))
    throw Error(cat("sun extraction: peak fraction ", o.peakFraction, " is outside (0, 1)"));
  if (!(o.minContrast >= 1.0 && std::isfinite(o.minContrast)))
    throw Error(cat("sun extraction: minimum contrast ", o.minContrast, " is not a finite number >= 1"));
  if (!(o.minPowerShare >= 0.0 && o.minPowerShare <= 1.0))
    throw Error(cat("sun extraction: minimum power share ", o.minPowerShare, " is outside [0, 1]"));
  if (o.marginPixels < 0 || o.marginPixels > 64)
    throw Error(cat("sun extraction: margin of ", o.marginPixels, " pixels is outside [0, 64]"));
}

// The steps of extractSun, in order.

// Step 1, the peak: the brightest pixel (the first one in row order on a tie).
struct Peak {
  size_t id = 0;
  double luminance = -1.0;
};

Peak findPeak(const ImageRgb& image) {
  Peak peak;
  for (size_t i = 0; i < image.pixels.size(); ++i) {
    const double l = luminance(image.pixels[i]);
    if (l > peak.luminance) {
      peak.luminance = l;
      peak.id = i;
    }
  }
  return peak;
}

// The region to in-paint: the core found by region growth, then its margin.
struct Region {
  std::vector<uint8_t> marks;  // Mark per pixel
  std::vector<size_t> pixels;  // the core first, then the margin layer by layer
  size_t corePixels = 0;
  double threshold = 0.0;  // the luminance threshold the core was grown with
};

// Step 2, region growth: pixels above a threshold, connected to the peak, within maxRadius of
// it. The threshold starts at peakFraction · peak and doubles while the region is not compact,
// up to peak / minContrast (a core standing out of a broad glow is still a source; a smooth sky
// is not compact at any threshold a sun would pass). False if no threshold gives a compact core.
bool growCore(const ImageRgb& image, const Grid& grid, const Peak& peak, const SunExtractOptions& options,
              Region& region) {
  const glm::dvec3 peakDir = grid.direction(grid.xOf(peak.id), grid.yOf(peak.id));
  region.marks.assign(image.pixels.size(), kNone);
  const double cosMax = std::cos(options.maxRadius);
  const double highest = peak.luminance / options.minContrast;
  region.threshold = options.peakFraction * peak.luminance;
  bool compact = growRegion(image, grid, peak.id, peakDir, cosMax, region.threshold, region.marks, region.pixels);
  while (!compact && region.threshold * 2.0 <= highest) {
    region.threshold *= 2.0;
    compact = growRegion(image, grid, peak.id, peakDir, cosMax, region.threshold, region.marks, region.pixels);
  }
  region.corePixels = region.pixels.size();
  return compact;
}

// Step 3, dilation: the margin, marginPixels steps of 8-neighbour dilation.
void addMargin(const Grid& grid, int marginPixels, Region& region) {
  std::vector<size_t>& pixels = region.pixels;
  size_t layerBegin = 0;
  for (int step = 0; step < marginPixels; ++step) {
    const size_t layerEnd = pixels.size();
    for (size_t i = layerBegin; i < layerEnd; ++i)
      grid.forNeighbours8(grid.xOf(pixels[i]), grid.yOf(pixels[i]), [&](int nx, int ny) {
        const size_t n = grid.id(nx, ny);
        if (region.marks[n] != kNone) return;
        region.marks[n] = kRegion;
        pixels.push_back(n);
      });
    layerBegin = layerEnd;
  }
}

// The pixels around the region and the map's values there.
struct Ring {
  std::vector<size_t> pixels;
  glm::dvec3 min{std::numeric_limits<double>::max()}, max{std::numeric_limits<double>::lowest()};
  glm::dvec3 mean{0.0};
  double skyLevel = 0.0;  // the median luminance
};

// Step 4, the boundary level: the pixels outside the region that the Laplacian couples to it;
// their median luminance is the sky level around the source. Empty when nothing is left around
// the region.
Ring boundaryRing(const ImageRgb& image, const Grid& grid, Region& region) {
  Ring ring;
  for (size_t id : region.pixels)
    grid.forLaplaceNeighbours(grid.xOf(id), grid.yOf(id), [&](int nx, int ny, double) {
      const size_t n = grid.id(nx, ny);
      if (region.marks[n] != kNone) return;
      region.marks[n] = kBoundary;
      ring.pixels.push_back(n);
    });
  if (ring.pixels.empty()) return ring;
  std::vector<double> ringLuminance;
  ringLuminance.reserve(ring.pixels.size());
  for (size_t id : ring.pixels) {
    const glm::dvec3 c(image.pixels[id]);
    ringLuminance.push_back(luminance(c));
    ring.min = glm::min(ring.min, c);
    ring.max = glm::max(ring.max, c);
  }
  std::nth_element(ringLuminance.begin(), ringLuminance.begin() + ringLuminance.size() / 2, ringLuminance.end());
  ring.skyLevel = ringLuminance[ringLuminance.size() / 2];
  for (size_t id : ring.pixels) ring.mean += glm::dvec3(image.pixels[id]);
  ring.mean /= double(ring.pixels.size());
  return ring;
}

// The system of Note 3 over the region's pixels (`region` sorted: the unknowns in row order),
// factored, with its right-hand side per channel.
Laplace laplaceSystem(const ImageRgb& image, const Grid& grid, const std::vector<size_t>& region,
                      std::array<std::vector<double>, 3>& rhs) {
  std::unordered_map<size_t, int> index;
  index.reserve(region.size() * 2);
  for (size_t i = 0; i < region.size(); ++i) index.emplace(region[i], static_cast<int>(i));
  Laplace lap;
  const size_t n = region.size();
  lap.diag.assign(n, 0.0);
  lap.edges.resize(n);
  lap.edgeCount.assign(n, 0);
  lap.lower.assign(n, 0.0);
  for (auto& v : rhs) v.assign(n, 0.0);
  for (size_t i = 0; i < n; ++i) {
    grid.forLaplaceNeighbours(grid.xOf(region[i]), grid.yOf(region[i]), [&](int nx, int ny, double wgt) {
      const size_t pixel = grid.id(nx, ny);
      const auto it = index.find(pixel);
      const int j = it == index.end() ? -1 : it->second;
      lap.edges[i][static_cast<size_t>(lap.edgeCount[i]++)] = {j, wgt};
      lap.diag[i] += wgt;
      if (j >= 0 && static_cast<size_t>(j) + 1 == i && ny == grid.yOf(region[i])) lap.lower[i] = wgt;
      if (j < 0)
        for (int c = 0; c < 3; ++c) rhs[c][i] += wgt * double(image.pixels[pixel][c]);
    });
  }
  lap.factor();
  return lap;
}

// What the in-painting took out of the map: ∫ e dω per channel and ∫ e ω dω in luminance.
struct Excess {
  glm::dvec3 power{0.0}, moment{0.0};
};

// Step 5, in-paint (Note 3): the region's pixels of `residual` become min(map, background).
// The excess map − residual is never negative, and the two add up to the map pixel by pixel
// (the float rounding of the background is taken by the excess, computed from the stored
// residual). The clamp to the boundary's range is what the maximum principle gives the exact
// solution; it guards the solver's last digits. Sorts `region`.
Excess inpaint(const ImageRgb& image, const Grid& grid, std::vector<size_t>& region, const Ring& ring,
               ImageRgb& residual) {
  std::sort(region.begin(), region.end());
  std::array<std::vector<double>, 3> rhs;
  const Laplace lap = laplaceSystem(image, grid, region, rhs);
  std::vector<double> background[3];
  for (int c = 0; c < 3; ++c) background[c] = solveChannel(lap, rhs[c], ring.mean[c]);
  Excess e;
  for (size_t i = 0; i < region.size(); ++i) {
    const size_t id = region[i];
    const int x = grid.xOf(id), y = grid.yOf(id);
    const glm::dvec3 map(image.pixels[id]);
    glm::dvec3 b(background[0][i], background[1][i], background[2][i]);
    b = glm::clamp(b, ring.min, ring.max);
    const glm::vec3 kept(glm::min(map, b));
    residual.pixels[id] = kept;
    const glm::dvec3 excess = map - glm::dvec3(kept);
    e.power += excess * grid.solidAngle(y);
    e.moment += luminance(excess) * grid.moment(x, y);
  }
  return e;
}

// Step 6, the cap fit. Note 4: the excess e has power P = ∫ e dω and first moment M = ∫ e ω dω;
// its direction is d = M / |M| (the power-weighted centroid, in luminance), and a surface
// facing d receives E = ∫ e (d·ω) dω = |M| (every ω of the region is within maxRadius + the
// margin of d, so d·ω > 0). A uniform cap of radius r and radiance L has P = 2π L (1 − cos r)
// and E = π L sin² r, so E / P = (1 + cos r) / 2 and
//   sin²(r/2) = (1 − cos r) / 2 = 1 − E / P.
// The cap of that radius with L = P / (2π(1 − cos r)) has the excess's power and its vector
// irradiance E·d exactly (SH bands 0 and 1), and its mean 1 − d·ω (about half the mean
// squared angle to d), so its penumbrae have the width the excess's spread gives. The
// radius is one number, from luminance; per channel the cap keeps the power (which keeps the
// conservation exact) and E_c = P_c (1 + cos r) / 2.
ExtractedSun fitCap(const Excess& e, double share, size_t pixels) {
  ExtractedSun sun;
  const double momentLength = glm::length(e.moment);
  sun.direction = e.moment / momentLength;
  const double oneMinusRatio = std::max(0.0, 1.0 - momentLength / luminance(e.power));
  sun.radius = 2.0 * std::asin(std::min(1.0, std::sqrt(oneMinusRatio)));
  if (sun.radius < kPointSunRadians) sun.radius = 0.0;
  sun.power = e.power;
  sun.irradiance = e.power * (1.0 + std::cos(sun.radius)) / 2.0;
  sun.powerShare = share;
  sun.pixels = pixels;
  return sun;
}

}  // namespace

SunExtraction extractSun(const ImageRgb& equirect, const SunExtractOptions& options) {
  checkInput(equirect, options);
  const Grid grid(equirect.width, equirect.height);

  SunExtraction out;
  out.residual = equirect;
  out.mapPower = mapPower(equirect, grid);
  out.residualPower = out.mapPower;
  const double mapLuminance = luminance(out.mapPower);
  if (!(mapLuminance > 0.0)) {
    out.reason = "no sun: the map carries no power";
    return out;
  }

  const Peak peak = findPeak(equirect);
  Region region;
  if (!growCore(equirect, grid, peak, options, region)) {
    out.reason =
        cat("no sun: the pixels brighter than ", region.threshold / peak.luminance, " of the brightest (",
            peak.luminance, ") reach beyond ", degrees(options.maxRadius), " degrees of it: no compact source");
    return out;
  }
  addMargin(grid, options.marginPixels, region);
  const Ring ring = boundaryRing(equirect, grid, region);
  if (ring.pixels.empty()) {
    out.reason = "no sun: the region with its margin covers the whole map, nothing is left around it";
    return out;
  }
  if (peak.luminance < options.minContrast * ring.skyLevel) {
    out.reason = cat("no sun: the brightest pixel (", peak.luminance, ") is only ", peak.luminance / ring.skyLevel,
                     " times the sky around its region (", ring.skyLevel, "), below ", options.minContrast);
    return out;
  }

  const Excess excess = inpaint(equirect, grid, region.pixels, ring, out.residual);
  const double sunLuminance = luminance(excess.power);
  const double share = sunLuminance / mapLuminance;
  if (!(sunLuminance > 0.0) || share < options.minPowerShare) {
    out.residual = equirect;
    out.reason = cat("no sun: the compact source around the brightest pixel (", peak.luminance, "; ", region.corePixels,
                     " pixels above ", region.threshold / peak.luminance, " of it) carries ", 100.0 * share,
                     "% of the map's power, below ", 100.0 * options.minPowerShare, "%");
    return out;
  }

  const ExtractedSun sun = fitCap(excess, share, region.pixels.size());
  out.residualPower = mapPower(out.residual, grid);
  const double elevation = degrees(std::asin(std::clamp(sun.direction.y, -1.0, 1.0)));
  const double azimuth = degrees(std::atan2(sun.direction.x, sun.direction.z));
  out.reason = cat("sun at elevation ", elevation, " degrees, azimuth ", azimuth, " degrees, radius ",
                   degrees(sun.radius), " degrees, ", 100.0 * share, "% of the map's power; ", region.corePixels,
                   " pixels above ", region.threshold / peak.luminance, " of the peak (", peak.luminance, "), ",
                   region.pixels.size(), " with the margin, sky around it ", ring.skyLevel);
  out.sun = sun;
  return out;
}

}  // namespace prt
