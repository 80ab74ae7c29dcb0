// The receivers' shading: a port of the probe interpolation to GLSL (docs/render.md, "Receivers").
//
// Per pixel of a receiver, with x the world position and n the unit normal:
//   w_p  = probeWeights(x, n)                 (trilinear × validity × Chebyshev × back face)
//   c    = Σ_p w_p c_p                         (interpolateRadiance; c_p = M_p · l, relit per frame)
//   E    = Σ_j Â_l(j) y_j(n) c_j               (sh::irradiance)
//   L_o  = albedo / π · E
// computed as E = Σ_j (Â_l y_j(n)) Σ_p w_p c_p,j: the same sums in another order. Per frame the
// CPU packs each probe's c_p (from relightProbes) into RGBA texels, the RGB of the coefficients
// with Â_l ≠ 0 back to back (odd bands l > 1 drop out of irradiance): 7 texels per probe for 3
// bands instead of 9 RGB ones. Fetches dominate the receivers' cost on llvmpipe, and it reads
// RGBA32F buffer texels about twice as fast as RGB32F ones (measured, docs/render.md).
#include "probe_shading.h"

#include <algorithm>

#include <cctype>
#include <cmath>
#include <cstdio>
#include "direct_shading.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "prt/error.h"
#include "prt/math.h"
#include "prt/sh.h"
#include "render_shaders.h"
#include "shader_sources.h"

namespace prt::render {

namespace {

// Constants of prt::probeWeights (probes/grid/src/probe_grid.cpp), private there; the receiver tests
// (RenderReceivers.*) compare this port with the C++ function at pixel centres, so a change on
// one side without the other fails there.
constexpr double kVarianceFloorFraction = 0.01;  // kVarianceFloor
constexpr double kNearZeroFraction = 1e-6;       // r > 1e-6 · min spacing enables the back-face term

std::string glslFloat(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.9e", v);
  return buf;
}

double minSpacing(const ProbeGrid& grid) { return std::min({grid.spacing.x, grid.spacing.y, grid.spacing.z}); }

// ============================================================================================
// The probeWeights port (shaders/probe_weights.glsl, between BEGIN probeWeights port and END
// probeWeights port). Mirrors prt::probeWeights (probes/grid/src/probe_grid.cpp) step by step;
// the C++ works in double, this in float, and without branches: a corner without a valid probe
// reads the null probe 0 (all texels zero) and gets weight 0 instead of being skipped, so every
// pixel runs the same straight-line code (llvmpipe shades 8 pixels per SIMD instruction and
// pays for both sides of a divergent branch, plus the mask bookkeeping). The weights come back
// unnormalised, weight[c] = trilinear × validity × leakWeight (0 where the C++ leaves the corner
// out), and the function returns their sum: 0 where the C++ returns count = 0 (outside the
// domain, or no valid probe in the cell); the caller divides once by the sum. probe[c] is the
// corner's probe + 1 (0: none). leakWeight() is the per-probe factor max(w_v · w_b, kMinWeight):
// the part that changes when the visibility test changes. Its per-probe inputs come from
// probeStaticTexels() below. Its loops over the cell's corners c = 0..7 are emitted once per
// corner from shaders/probe_corner_*.glsl with C replaced by the corner's number (the loops of
// the C++ unrolled: llvmpipe keeps arrays indexed by constants in registers, but spills arrays
// indexed by a loop variable to memory, lane by lane).
// ============================================================================================

std::string perCorner(std::string_view body) {
  std::string out;
  for (int c = 0; c < 8; ++c) {
    std::string b(body);
    for (size_t at = b.find('C'); at != std::string::npos; at = b.find('C', at + 1))
      if ((at == 0 || !std::isalnum((unsigned char)b[at - 1])) && !std::isalnum((unsigned char)b[at + 1]))
        b.replace(at, 1, std::to_string(c));
    out += b;
  }
  return out;
}

std::string probeWeightsGlsl() {
  return fillShader(shaders::kProbeWeights, {{"CORNER_SETUP", perCorner(shaders::kProbeCornerSetup)},
                                             {"CORNER_WEIGHTS", perCorner(shaders::kProbeCornerWeight)}});
}

// Normalisation K_l^m of the real SH basis (as in probes/sh/src/sh.cpp): sqrt((2l+1)/(4π) ·
// (l−m)!/(l+m)!), times √2 for m > 0.
double shNorm(int l, int m) {
  double ratio = 1.0;
  for (int j = l - m + 1; j <= l + m; ++j) ratio /= j;
  const double v = std::sqrt((2.0 * l + 1.0) / (4.0 * kPi) * ratio);
  return m == 0 ? v : std::sqrt(2.0) * v;
}

// Straight-line GLSL that sets float b<j> = Â_l y_j(n) for every coefficient j of a band with
// Â_l ≠ 0, n = (px, py, pz) unit. Same polynomial recurrence as sh::evaluate (sh.cpp explains
// it): P_l^m = sin^m θ · Q_l^m(z), sin^m θ (cos mφ, sin mφ) = (Re, Im)(x + iy)^m.
std::string irradianceBasisGlsl(int bands) {
  std::string s;
  for (int m = 0; m < bands; ++m) {
    if (m == 1) s += "  float c1 = px, s1 = py;\n";
    if (m > 1)
      s += cat("  float c", m, " = c", m - 1, " * px - s", m - 1, " * py, s", m, " = c", m - 1, " * py + s", m - 1,
               " * px;\n");
    double qmm = 1.0;  // (2m − 1)!!
    for (int j = 1; j <= 2 * m - 1; j += 2) qmm *= j;
    for (int l = m; l < bands; ++l) {
      const std::string q = cat("q", l, "_", m);
      if (l == m)
        s += cat("  float ", q, " = ", glslFloat(qmm), ";\n");
      else if (l == m + 1)
        s += cat("  float ", q, " = ", glslFloat((2 * m + 1) * qmm), " * pz;\n");
      else
        s += cat("  float ", q, " = (", glslFloat(2 * l - 1), " * pz * q", l - 1, "_", m, " - ", glslFloat(l + m - 1),
                 " * q", l - 2, "_", m, ") / ", glslFloat(l - m), ";\n");
      const double a = sh::clampedCosineFactor(l);
      if (a == 0.0) continue;
      const std::string f = glslFloat(a * shNorm(l, m));
      if (m == 0) {
        s += cat("  float b", sh::index(l, 0), " = ", f, " * ", q, ";\n");
      } else {
        s += cat("  float b", sh::index(l, m), " = ", f, " * ", q, " * c", m, ";\n");
        s += cat("  float b", sh::index(l, -m), " = ", f, " * ", q, " * s", m, ";\n");
      }
    }
  }
  return s;
}

}  // namespace

std::vector<int> irradianceCoefficients(int bands) {
  std::vector<int> out;
  for (int j = 0; j < bands * bands; ++j)
    if (sh::clampedCosineFactor(sh::bandOf(j)) != 0.0) out.push_back(j);
  return out;
}

namespace {

// probe_lookup.glsl for `bands` bands: the probe weights, and incidentRadiance's sums unrolled
// over the packed texels T[i] (one line per texel in each).
std::string probeLookupGlsl(int bands) {
  PRT_CHECK(bands >= 1 && bands <= sh::kMaxBands);
  const int texels = radianceTexels(bands);
  std::string cleared, fetches, normalised;
  for (int i = 0; i < texels; ++i) {
    cleared += cat("  T[", i, "] = vec4(0.0);\n");
    fetches += cat("    T[", i, "] += w[C] * texelFetch(uProbeRadiance, base + ", i, ");\n");
    normalised +=
        cat("  T[", i, "] = sum > 0.0 ? mix(T[", i, "] / sum, uLightPacked[", i, "], fade) : uLightPacked[", i, "];\n");
  }
  return fillShader(shaders::kProbeLookup,
                    {{"STATIC_TEXELS", cat(kProbeStaticTexels)},
                     {"TEXELS", cat(texels)},
                     {"PROBE_WEIGHTS", probeWeightsGlsl()},
                     {"TEXELS_CLEARED", cleared},
                     {"CORNER_SUMS", perCorner(fillShader(shaders::kProbeCornerRadiance, {{"TEXEL_SUMS", fetches}}))},
                     {"TEXELS_NORMALISED", normalised}});
}

// irradiance.glsl's sums: e += c_j · b<j> per coefficient j with Â_l ≠ 0, c_j's RGB read from the
// packed texels' lanes.
std::string irradianceSumsGlsl(int bands) {
  std::string s;
  const std::vector<int> used = irradianceCoefficients(bands);
  const char* lane = "xyzw";
  for (size_t k = 0; k < used.size(); ++k) {
    std::string rgb;
    for (int c = 0; c < 3; ++c) {
      const size_t f = 3 * k + size_t(c);
      rgb += cat(c ? ", " : "", "T[", f / 4, "].", lane[f % 4]);
    }
    s += cat("  e += vec3(", rgb, ") * b", used[k], ";\n");
  }
  return s;
}

}  // namespace

std::string receiverVertexShader(int bands, ProbeLookup lookup) {
  const bool perVertex = lookup == ProbeLookup::PerVertex;
  return fillShader(shaders::kReceiverVertex,
                    {{"PER_VERTEX", cat(int(perVertex))}, {"PROBE_LOOKUP", perVertex ? probeLookupGlsl(bands) : ""}});
}

std::string receiverFragmentShader(int bands, ProbeLookup lookup, int envMaps) {
  const bool perVertex = lookup == ProbeLookup::PerVertex;
  return fillShader(shaders::kReceiverFragment, {{"PER_VERTEX", cat(int(perVertex))},
                                                 {"TEXELS", cat(radianceTexels(bands))},
                                                 {"PROBE_LOOKUP", perVertex ? "" : probeLookupGlsl(bands)},
                                                 {"IRRADIANCE_BASIS", irradianceBasisGlsl(bands)},
                                                 {"IRRADIANCE_SUMS", irradianceSumsGlsl(bands)},
                                                 {"DIRECT_LIGHTING", directLightingGlsl()},
                                                 {"MATERIAL_SHADING", materialShadingGlsl(envMaps)}});
}

int radianceTexels(int bands) { return int(3 * irradianceCoefficients(bands).size() + 3) / 4; }

void packRadiance(int bands, const std::vector<glm::vec3>& relit, std::vector<glm::vec4>& out) {
  const std::vector<int> used = irradianceCoefficients(bands);
  const size_t n2 = size_t(bands) * bands, texels = size_t(radianceTexels(bands));
  PRT_CHECK_EQ(relit.size() % n2, size_t(0));
  const size_t probes = relit.size() / n2;
  out.assign((probes + 1) * texels, glm::vec4(0.0f));
  tbb::parallel_for(tbb::blocked_range<size_t>(0, probes, 1024), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t p = r.begin(); p < r.end(); ++p) {
      float* dst = &out[(p + 1) * texels].x;
      for (size_t k = 0; k < used.size(); ++k) {
        const glm::vec3& c = relit[p * n2 + size_t(used[k])];
        dst[3 * k] = c.r;
        dst[3 * k + 1] = c.g;
        dst[3 * k + 2] = c.b;
      }
    }
  });
}

std::vector<glm::vec4> packLight(int bands, const sh::ShRgb& light) {
  const sh::ShRgb l = sh::resize(light, bands);
  std::vector<glm::vec4> packed;
  packRadiance(bands, l.c, packed);  // the null probe's texels, then the light's
  return std::vector<glm::vec4>(packed.begin() + radianceTexels(bands), packed.end());
}

std::vector<glm::vec4> probeStaticTexels(const ProbeGrid& grid) {
  const size_t count = grid.probeCount();
  PRT_CHECK_EQ(grid.validity.size(), count);
  PRT_CHECK_EQ(grid.offset.size(), count);
  PRT_CHECK_EQ(grid.moments.size(), count);
  const double floor = varianceFloor(grid);
  std::vector<glm::vec4> out((count + 1) * kProbeStaticTexels, glm::vec4(0.0f));
  for (size_t p = 0; p < count; ++p) {
    glm::vec4* t = &out[(p + 1) * kProbeStaticTexels];
    t[0] = glm::vec4(glm::vec3(grid.position(p)), grid.validity[p]);
    // Per face f = 2·axis + (negative side): (μ, σ²), σ² = max(m₂ − μ², floor) with μ, m₂ widened
    // to double first, as probeWeights does.
    glm::vec2 face[6];
    for (size_t f = 0; f < 6; ++f) {
      const glm::vec2 m = grid.moments[p][f];
      face[f] = glm::vec2(m.x, float(std::max(double(m.y) - double(m.x) * double(m.x), floor)));
    }
    for (int negY = 0; negY < 2; ++negY)
      for (int negX = 0; negX < 2; ++negX) t[1 + negX + 2 * negY] = glm::vec4(face[negX], face[2 + negY]);
    t[5] = glm::vec4(face[4], face[5]);
  }
  return out;
}

std::vector<int32_t> latticeIndex(const ProbeGrid& grid) {
  const size_t points = size_t(grid.dims.x) * size_t(grid.dims.y) * size_t(grid.dims.z);
  std::vector<int32_t> out(std::max<size_t>(points, 1), 0);
  for (size_t p = 0; p < grid.probeCount(); ++p) {
    const glm::ivec3 c = grid.coord[p];
    PRT_CHECK(c.x >= 0 && c.y >= 0 && c.z >= 0 && c.x < grid.dims.x && c.y < grid.dims.y && c.z < grid.dims.z);
    out[(size_t(c.z) * size_t(grid.dims.y) + size_t(c.y)) * size_t(grid.dims.x) + size_t(c.x)] = int32_t(p + 1);
  }
  return out;
}

double varianceFloor(const ProbeGrid& grid) {
  const double f = kVarianceFloorFraction * minSpacing(grid);
  return f * f;
}

double nearZero(const ProbeGrid& grid) { return kNearZeroFraction * minSpacing(grid); }

}  // namespace prt::render
