// The environment prefiltered by GGX roughness (environment_prefilter.h derives it).
#include "environment_prefilter.h"

#include <algorithm>
#include <cmath>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "prt/brdf.h"
#include "prt/error.h"
#include "prt/light.h"
#include "prt/math.h"
#include "prt/tangents.h"

namespace prt::render {

namespace {

// The source's box mip chain: level j + 1 averages level j's 2 × 2 blocks (the last row or
// column repeated where a side is odd), down to one texel across.
std::vector<ImageRgb> boxChain(const ImageRgb& map) {
  std::vector<ImageRgb> chain{map};
  while (chain.back().width > 1 || chain.back().height > 1) {
    const ImageRgb& a = chain.back();
    ImageRgb b(std::max(1, a.width / 2), std::max(1, a.height / 2));
    for (int y = 0; y < b.height; ++y)
      for (int x = 0; x < b.width; ++x) {
        const int x0 = std::min(2 * x, a.width - 1), x1 = std::min(2 * x + 1, a.width - 1);
        const int y0 = std::min(2 * y, a.height - 1), y1 = std::min(2 * y + 1, a.height - 1);
        b.at(x, y) = 0.25f * (a.at(x0, y0) + a.at(x1, y0) + a.at(x0, y1) + a.at(x1, y1));
      }
    chain.push_back(std::move(b));
  }
  return chain;
}

// Van der Corput's radical inverse in base 2: the second coordinate of Hammersley's points.
double radicalInverse(uint32_t i) {
  i = (i << 16u) | (i >> 16u);
  i = ((i & 0x55555555u) << 1u) | ((i & 0xAAAAAAAAu) >> 1u);
  i = ((i & 0x33333333u) << 2u) | ((i & 0xCCCCCCCCu) >> 2u);
  i = ((i & 0x0F0F0F0Fu) << 4u) | ((i & 0xF0F0F0F0u) >> 4u);
  i = ((i & 0x00FF00FFu) << 8u) | ((i & 0xFF00FF00u) >> 8u);
  return double(i) * 2.3283064365386963e-10;
}

// sampleEquirect in float, inlined: the prefilter's inner loop (its lookups are most of its cost).
inline glm::vec3 lookup(const ImageRgb& m, const glm::vec3& d) {
  const float u = 0.5f + std::atan2(d.z, d.x) * (0.5f / kPiF);
  const float v = std::acos(std::clamp(d.y, -1.0f, 1.0f)) * (1.0f / kPiF);
  const float x = u * m.width - 0.5f, y = v * m.height - 0.5f;
  const float x0 = std::floor(x), y0 = std::floor(y), fx = x - x0, fy = y - y0;
  auto wrap = [&](int i) { return ((i % m.width) + m.width) % m.width; };
  const int xa = wrap(int(x0)), xb = wrap(int(x0) + 1);
  const int ya = std::clamp(int(y0), 0, m.height - 1), yb = std::clamp(int(y0) + 1, 0, m.height - 1);
  return (1.0f - fy) * ((1.0f - fx) * m.at(xa, ya) + fx * m.at(xb, ya)) +
         fy * ((1.0f - fx) * m.at(xa, yb) + fx * m.at(xb, yb));
}

// Trilinear lookup in the box chain.
inline glm::vec3 chainLookup(const std::vector<ImageRgb>& chain, float lod, const glm::vec3& d) {
  const int a = int(lod), b = std::min(a + 1, int(chain.size()) - 1);
  const float f = lod - float(a);
  const glm::vec3 la = lookup(chain[size_t(a)], d);
  return f > 0.0f ? la + f * (lookup(chain[size_t(b)], d) - la) : la;
}

// Direction of pixel (x, y)'s centre of a width × height equirectangular image.
glm::dvec3 pixelDirection(int x, int y, int width, int height) {
  return equirectDirection((x + 0.5) / width, (y + 0.5) / height);
}

// Direction of texel (x, y)'s centre of a size × size octahedral image.
glm::dvec3 octahedralTexelDirection(int x, int y, int size) {
  return octahedralDirection(glm::dvec2((x + 0.5) / size, (y + 0.5) / size));
}

// The equirectangular box chain trilinear at fractional `lod` (level 0's resampling).
glm::dvec3 sampleChain(const std::vector<ImageRgb>& chain, double lod, const glm::dvec3& d) {
  lod = std::clamp(lod, 0.0, double(chain.size() - 1));
  const int a = int(std::floor(lod)), b = std::min(a + 1, int(chain.size()) - 1);
  const double f = lod - a;
  const glm::dvec3 la = sampleEquirect(chain[size_t(a)], d);
  return f > 0.0 ? (1.0 - f) * la + f * sampleEquirect(chain[size_t(b)], d) : la;
}

// An octahedral level bilinear at direction d, as GL_LINEAR with GL_CLAMP_TO_EDGE reads it.
glm::dvec3 sampleOctahedral(const ImageRgb& level, const glm::dvec3& d) {
  const glm::dvec2 uv = octahedralUv(d);
  const double x = uv.x * level.width - 0.5, y = uv.y * level.height - 0.5;
  const double x0 = std::floor(x), y0 = std::floor(y), fx = x - x0, fy = y - y0;
  const int xa = std::clamp(int(x0), 0, level.width - 1), xb = std::clamp(int(x0) + 1, 0, level.width - 1);
  const int ya = std::clamp(int(y0), 0, level.height - 1), yb = std::clamp(int(y0) + 1, 0, level.height - 1);
  const auto at = [&](int i, int j) { return glm::dvec3(level.at(i, j)); };
  return (1.0 - fy) * ((1.0 - fx) * at(xa, ya) + fx * at(xb, ya)) + fy * ((1.0 - fx) * at(xa, yb) + fx * at(xb, yb));
}

// Level k ≥ 1: the GGX lobe of roughness `roughness` around each pixel's direction (n = v = r).
void filterLevel(const std::vector<ImageRgb>& chain, double roughness, int samples, ImageRgb& out) {
  const double alpha = roughness * roughness;
  const ImageRgb& source = chain.front();
  // The coarsest mip read keeps 32 texels across (or the map's own): coarser ones cannot hold
  // even a linear function of direction (a 4 × 2 map is 10% off one), which the widest lobes'
  // samples would otherwise read.
  const double maxLod = std::max(0.0, std::floor(std::log2(std::max(1.0, source.width / 32.0))));
  tbb::parallel_for(tbb::blocked_range<int>(0, out.height), [&](const tbb::blocked_range<int>& rows) {
    for (int y = rows.begin(); y < rows.end(); ++y)
      for (int x = 0; x < out.width; ++x) {
        const glm::dvec3 r = pixelDirection(x, y, out.width, out.height);
        const glm::dvec3 t0(anyTangent(glm::vec3(r)));
        const glm::dvec3 t = glm::normalize(t0 - r * glm::dot(r, t0)), b = glm::cross(r, t);
        glm::dvec3 sum(0.0);
        double weight = 0.0;
        for (int i = 0; i < samples; ++i) {
          const glm::dvec3 hl = brdf::sampleGgxHalfVector({(i + 0.5) / samples, radicalInverse(uint32_t(i))}, alpha);
          const glm::dvec3 h = hl.x * t + hl.y * b + hl.z * r;
          const double rh = glm::dot(r, h);
          const glm::dvec3 l = 2.0 * rh * h - r;
          const double nl = glm::dot(r, l);
          if (nl <= 0.0) continue;
          // pdf(l) = D(h)(n·h)/(4 v·h) = D(h)/4 with n = v; Ω_p of a level-0 texel at l.
          const double pdf = brdf::ggxD(rh, alpha) / 4.0;
          const double sinTheta = std::max(std::sqrt(std::max(0.0, 1.0 - l.y * l.y)), 1e-3);
          const double omegaP = (2.0 * kPi / source.width) * (kPi / source.height) * sinTheta;
          const double omegaS = 1.0 / (samples * std::max(pdf, 1e-12));
          const double lod = std::clamp(0.5 * std::log2(omegaS / omegaP) + 1.0, 0.0, maxLod);
          sum += nl * glm::dvec3(chainLookup(chain, float(lod), glm::vec3(l)));
          weight += nl;
        }
        out.at(x, y) = glm::vec3(weight > 0.0 ? sum / weight : glm::dvec3(0.0));
      }
  });
}

}  // namespace

glm::dvec2 octahedralUv(const glm::dvec3& d) {
  glm::dvec2 p = glm::dvec2(d.x, d.z) / (std::abs(d.x) + std::abs(d.y) + std::abs(d.z));
  if (d.y < 0.0) {  // the lower hemisphere folds out into the corners
    const glm::dvec2 sign(p.x >= 0.0 ? 1.0 : -1.0, p.y >= 0.0 ? 1.0 : -1.0);
    p = (1.0 - glm::abs(glm::dvec2(p.y, p.x))) * sign;
  }
  return 0.5 * p + 0.5;
}

glm::dvec3 octahedralDirection(const glm::dvec2& uv) {
  glm::dvec2 p = 2.0 * uv - 1.0;
  const double y = 1.0 - std::abs(p.x) - std::abs(p.y);
  if (y < 0.0) {
    const glm::dvec2 sign(p.x >= 0.0 ? 1.0 : -1.0, p.y >= 0.0 ? 1.0 : -1.0);
    p = (1.0 - glm::abs(glm::dvec2(p.y, p.x))) * sign;
  }
  return glm::normalize(glm::dvec3(p.x, y, p.y));
}

glm::dvec3 samplePrefiltered(const std::vector<ImageRgb>& levels, double lod, const glm::dvec3& d) {
  PRT_CHECK(!levels.empty());
  lod = std::clamp(lod, 0.0, double(levels.size() - 1));
  const int a = int(std::floor(lod)), b = std::min(a + 1, int(levels.size()) - 1);
  const double f = lod - a;
  const glm::dvec3 la = sampleOctahedral(levels[size_t(a)], d);
  return f > 0.0 ? (1.0 - f) * la + f * sampleOctahedral(levels[size_t(b)], d) : la;
}

std::vector<ImageRgb> prefilterEnvironment(const ImageRgb& map, int levels, int samples) {
  PRT_CHECK(levels >= 1 && samples >= 1);
  if (map.width < 1 || map.height < 1) throw Error("environment map: empty, nothing to reflect");
  const int w0 = kPrefilterWidth;
  const std::vector<ImageRgb> chain = boxChain(map);
  std::vector<ImageRgb> out;
  for (int k = 0; k < levels; ++k) {
    ImageRgb level(w0, w0);
    if (k == 0) {
      // The mirror: the map averaged down to the level's texels (the equator runs 2√2·W₀
      // octahedral texels around, against the map's width).
      const double lod = std::max(0.0, std::log2(double(map.width) / (2.0 * std::sqrt(2.0) * w0)));
      for (int y = 0; y < level.height; ++y)
        for (int x = 0; x < level.width; ++x)
          level.at(x, y) = glm::vec3(sampleChain(chain, lod, octahedralTexelDirection(x, y, w0)));
    } else {
      // Rougher lobes are smoother: level k is filtered on an equirectangular grid of width
      // W₀ / 2^(k−1) (no fewer than 64 texels across, 5.6° texels against the ≥ 40° lobe of
      // roughness 0.6), a third of the lookups, and resampled bilinearly to the octahedral level.
      ImageRgb coarse(std::max(64, w0 >> (k - 1)), std::max(32, (w0 / 2) >> (k - 1)));
      filterLevel(chain, double(k) / (levels - 1), samples, coarse);
      for (int y = 0; y < level.height; ++y)
        for (int x = 0; x < level.width; ++x)
          level.at(x, y) = glm::vec3(sampleEquirect(coarse, octahedralTexelDirection(x, y, w0)));
    }
    out.push_back(std::move(level));
  }
  return out;
}

}  // namespace prt::render
