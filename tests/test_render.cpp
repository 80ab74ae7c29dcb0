// render/: headless contexts, and frames checked against a CPU evaluation of the same formula
// at pixel centres (STYLE.md: renders are checked against the formula before any golden).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <optional>
#include <random>

#include <gtest/gtest.h>
#include <glm/gtc/matrix_transform.hpp>

#include <unistd.h>

#include "harness.h"
#include "prt/bake/probe_bake.h"
#include "prt/bake/surface_bake.h"
#include "prt/error.h"
#include "prt/math.h"
#include "prt/probe_grid.h"
#include "prt/render/gl_context.h"
#include "prt/render/renderer.h"
#include "test_scenes.h"
#include "test_util.h"

namespace prt::render {
namespace {

constexpr int kWidth = 64, kHeight = 48;
constexpr double kInvPi = 0.31830988618379067;

GlContextOptions surfaceless() {
  GlContextOptions o;
  o.eglPlatform = EglPlatform::Surfaceless;
  return o;
}

// ---------------------------------------------------------------------------------------------
// Test scenes, built in memory.

// Random transfer and light, fixed seed. Transfer values in [-0.2, 1] so some products are
// negative, as real transfer of higher bands is.
void fillTransfer(MeshInstance& m, int bands, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-0.2f, 1.0f);
  m.transfer.resize(m.vertexCount() * size_t(bands) * bands);
  for (glm::vec3& t : m.transfer) t = glm::vec3(u(rng), u(rng), u(rng));
}

sh::ShRgb randomLight(int bands, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  sh::ShRgb l(bands);
  for (glm::vec3& c : l.c) c = glm::vec3(u(rng), u(rng), u(rng));
  l.c[0] += glm::vec3(2.0f);  // a dominant ambient term keeps most pixels positive
  return l;
}

void updateBounds(Scene& s) {
  s.boundsMin = glm::vec3(1e30f);
  s.boundsMax = glm::vec3(-1e30f);
  for (const MeshInstance& m : s.meshes)
    for (const glm::vec3& p : m.positions) {
      s.boundsMin = glm::min(s.boundsMin, p);
      s.boundsMax = glm::max(s.boundsMax, p);
    }
}

// A non-planar, tilted quad in front of a camera at +Z: perspective-correct interpolation of
// transfer·light, COLOR_0 and a base colour factor all show in the pixels.
Scene tiltedQuad(int bands) {
  Scene s;
  s.path = "tilted-quad";
  MeshInstance m;
  m.name = "quad";
  m.positions = {{-1.0f, -0.8f, 0.3f}, {1.1f, -0.7f, -0.6f}, {1.0f, 0.9f, -0.2f}, {-1.2f, 0.8f, 0.5f}};
  m.normals.assign(4, glm::vec3(0, 0, 1));
  m.colors = {{1.0f, 0.5f, 0.25f, 1.0f}, {0.2f, 1.0f, 0.6f, 1.0f}, {0.9f, 0.9f, 0.1f, 1.0f}, {0.4f, 0.3f, 1.0f, 1.0f}};
  m.indices = {0, 1, 2, 0, 2, 3};
  m.material = 0;
  fillTransfer(m, bands, 7);
  Material mat;
  mat.baseColorFactor = glm::vec4(0.8f, 0.6f, 0.9f, 1.0f);
  s.materials.push_back(mat);
  s.meshes.push_back(m);
  s.transferBands = bands;
  updateBounds(s);
  return s;
}

CameraView frontCamera() {
  CameraView c;
  c.cameraToWorld = glm::translate(glm::dmat4(1.0), glm::dvec3(0.1, 0.05, 3.0));
  c.yfov = glm::radians(50.0);
  c.znear = 0.1;
  return c;
}

// ---------------------------------------------------------------------------------------------
// The CPU oracle: trace the pixel centre's ray, interpolate with the hit's barycentrics.
// Ray-hit barycentrics are exactly what perspective-correct interpolation computes, so the
// oracle shares no code with the renderer (no matrices, no rasterization).

struct Hit {
  glm::dvec3 radiance{0.0};
  bool hit = false;
  bool receiver = false;
  bool ambiguous = false;    // a receiver point where the probe weights jump (see nearJump)
  glm::dvec3 normal{0.0};    // receivers: the unit normal at the hit
  glm::dvec3 position{0.0};  // receivers: the hit point
};

// Receivers' lighting for the oracle: the grid, its relit probes under `light`, the time.
struct ProbeLighting {
  const ProbeGrid* grid = nullptr;
  std::vector<glm::vec3> relit;
  sh::ShRgb light;
  double time = 0.0;
  // ProbeLookup::PerVertex: the lookup at the triangle's vertices, its result interpolated.
  bool perVertex = false;
};

ProbeLighting probeLighting(const ProbeGrid& grid, const sh::ShRgb& light, double time = 0.0) {
  ProbeLighting p;
  p.grid = &grid;
  p.light = sh::resize(light, grid.bands);
  p.relit = relightProbes(grid, p.light);
  p.time = time;
  return p;
}

// Whether x lies where probeWeights is discontinuous, within rounding of the GPU's float
// position: at the lattice box's edge (inside/outside), or where d = x − P of a weighted probe
// is near a tie between two axes (faceOf switches to another face's moments). The GPU computes
// x from float vertex positions and interpolation weights (relative error ~1e-6), so such
// pixels may legitimately fall on the other side.
bool nearJump(const ProbeGrid& g, const glm::dvec3& x, const glm::vec3& n) {
  constexpr double kMargin = 1e-4;
  const glm::dvec3 u = (x - g.origin) / g.spacing;
  for (int a = 0; a < 3; ++a) {
    const double hi = g.dims[a] - 1;
    if (std::abs(u[a] + 1.5 + 1e-4) < kMargin || std::abs(u[a] - hi - 1.5 - 1e-4) < kMargin) return true;
  }
  const ProbeWeights w = probeWeights(g, glm::vec3(x), &n);
  for (int k = 0; k < w.count; ++k) {
    const glm::dvec3 d = glm::abs(x - g.position(size_t(w.probe[size_t(k)])));
    const double big = std::max({d.x, d.y, d.z});
    const double mid = d.x + d.y + d.z - big - std::min({d.x, d.y, d.z});
    if (big - mid < kMargin * std::max(big, 1e-9)) return true;
  }
  return false;
}

// Vertices and normals of a receiver where the animation puts it at `time` (the renderer does
// this in its vertex shader with the same motion matrix, in float).
MeshInstance placed(const Scene& s, const MeshInstance& m, double time) {
  MeshInstance out = m;
  const glm::dmat4 motion = instanceMotion(s, m, time);
  const glm::dmat3 inverseTranspose = glm::transpose(glm::inverse(glm::dmat3(motion)));
  for (size_t v = 0; v < m.positions.size(); ++v) {
    out.positions[v] = glm::vec3(motion * glm::dvec4(glm::dvec3(m.positions[v]), 1.0));
    out.normals[v] = glm::vec3(glm::normalize(inverseTranspose * glm::dvec3(m.normals[v])));
  }
  if (glm::determinant(glm::dmat3(motion)) < 0.0)  // a mirror turns the winding around
    for (size_t t = 0; t < out.triangleCount(); ++t) std::swap(out.indices[3 * t + 1], out.indices[3 * t + 2]);
  return out;
}

Hit oracle(const Scene& s, const CameraView& c, const sh::ShRgb& light, int width, int height, int px, int py,
           const ProbeLighting* probes = nullptr) {
  const double aspect = double(width) / height;
  const double sx = 2.0 * (px + 0.5) / width - 1.0, sy = 1.0 - 2.0 * (py + 0.5) / height;
  glm::dvec3 origin, dir;
  if (c.perspective) {
    const double t = std::tan(0.5 * c.yfov);
    origin = glm::dvec3(c.cameraToWorld[3]);
    dir = glm::dvec3(c.cameraToWorld * glm::dvec4(sx * t * aspect, sy * t, -1.0, 0.0));
  } else {
    origin = glm::dvec3(c.cameraToWorld * glm::dvec4(sx * c.ymag * aspect, sy * c.ymag, 0.0, 1.0));
    dir = glm::dvec3(c.cameraToWorld * glm::dvec4(0.0, 0.0, -1.0, 0.0));
  }
  Hit best;
  double bestT = 1e300;
  for (const MeshInstance& original : s.meshes) {
    const bool receiver = original.receiverOnly;
    if (receiver ? probes == nullptr : original.transfer.empty()) continue;
    const MeshInstance moved = receiver ? placed(s, original, probes->time) : MeshInstance{};
    const MeshInstance& m = receiver ? moved : original;
    const Material mat = m.material >= 0 ? s.materials[size_t(m.material)] : Material{};
    for (size_t tri = 0; tri < m.triangleCount(); ++tri) {
      const uint32_t i0 = m.indices[3 * tri], i1 = m.indices[3 * tri + 1], i2 = m.indices[3 * tri + 2];
      const glm::dvec3 p0(m.positions[i0]), e1 = glm::dvec3(m.positions[i1]) - p0,
                                            e2 = glm::dvec3(m.positions[i2]) - p0;
      // Möller-Trumbore; det > 0 means the ray sees the counter-clockwise (front) side.
      const glm::dvec3 pv = glm::cross(dir, e2);
      const double det = glm::dot(e1, pv);
      if (det == 0.0 || (det < 0.0 && !mat.doubleSided)) continue;
      const glm::dvec3 tv = origin - p0;
      const double b1 = glm::dot(tv, pv) / det;
      const glm::dvec3 qv = glm::cross(tv, e1);
      const double b2 = glm::dot(dir, qv) / det;
      const double t = glm::dot(e2, qv) / det;
      if (b1 < 0 || b2 < 0 || b1 + b2 > 1 || t <= 0 || t >= bestT) continue;
      const double b0 = 1.0 - b1 - b2;
      const uint32_t v[3] = {i0, i1, i2};
      const double b[3] = {b0, b1, b2};
      glm::dvec3 e(0.0), color(1.0), normal(0.0);
      glm::vec2 uv(0.0f);
      if (!m.colors.empty()) color = glm::dvec3(0.0);
      for (int k = 0; k < 3; ++k) {
        // A double-sided instance with back-side transfer shows the side the ray sees.
        const bool backSide = det < 0.0 && m.hasBackTransfer();
        if (!receiver)
          e += b[k] * glm::dvec3(sh::dot(
                          backSide ? m.backTransferOf(v[k], s.transferBands) : m.transferOf(v[k], s.transferBands),
                          light.c.data(), light.size()));
        if (receiver) normal += b[k] * glm::dvec3(m.normals[v[k]]);
        if (!m.colors.empty()) color += b[k] * glm::dvec3(m.colors[v[k]]);
        if (!m.texcoords.empty()) uv += float(b[k]) * m.texcoords[v[k]];
      }
      best.ambiguous = false;
      if (receiver) {
        // The probe path: prt::receiverRadiance at the hit point and the interpolated normal
        // (the probes, the light itself where none applies, the two blended beyond the domain),
        // irradiance at that normal (sh::irradiance).
        const glm::dvec3 x = origin + t * dir;
        const glm::vec3 n(glm::normalize(normal));
        const ProbeGrid& g = *probes->grid;
        auto lookup = [&](const glm::vec3& at, const glm::vec3& nAt) {
          return receiverRadiance(g, probes->relit, probes->light, at, &nAt);
        };
        sh::ShRgb incident(g.bands);
        best.ambiguous = false;
        if (probes->perVertex) {
          // Per vertex: the lookup at the vertices (moved, unit normals), interpolated with the
          // hit's barycentrics (what perspective-correct interpolation of varyings computes).
          for (int k = 0; k < 3; ++k) {
            const sh::ShRgb atVertex = lookup(m.positions[v[k]], m.normals[v[k]]);
            for (size_t j = 0; j < atVertex.c.size(); ++j) incident.c[j] += float(b[k]) * atVertex.c[j];
            best.ambiguous = best.ambiguous || nearJump(g, glm::dvec3(m.positions[v[k]]), m.normals[v[k]]);
          }
        } else {
          incident = lookup(glm::vec3(x), n);
          best.ambiguous = nearJump(g, x, n);
        }
        e = glm::dvec3(sh::irradiance(incident, n));
        best.normal = glm::dvec3(n);
        best.position = x;
      }
      glm::dvec3 albedo = glm::dvec3(mat.baseColorFactor) * color;
      // Texture::sample is the project's bilinear lookup (texel centres at (i + ½)/size, glTF
      // wrap modes), the one the bake uses for albedo: GL_LINEAR must agree with it.
      if (mat.baseColorTexture >= 0 && !m.texcoords.empty())
        albedo *= glm::dvec3(s.textures[size_t(mat.baseColorTexture)].sample(uv));
      bestT = t;
      best.hit = true;
      best.receiver = receiver;
      best.radiance = albedo * kInvPi * e;
    }
  }
  return best;
}

struct Comparison {
  int compared = 0;
  int background = 0;
  int receiver = 0;       // compared pixels showing a receiver
  int ambiguous = 0;      // receiver pixels left out (nearJump)
  double maxError = 0.0;  // relative to the image's largest oracle value
  double maxReceiverError = 0.0;
  double meanReceiverError = 0.0;
  double maxBackground = 0.0;
};

// Compares pixels whose 3×3 neighbourhood lies wholly inside or wholly outside the geometry in
// the oracle: at silhouettes, coverage of a pixel whose centre is within a subpixel step of an
// edge legitimately depends on the rasterizer's snapping, which the oracle does not model. The
// neighbourhood must also show one kind of surface (baked or receiver) throughout.
Comparison compare(const ImageRgb& image, const Scene& s, const CameraView& c, const sh::ShRgb& light,
                   const ProbeLighting* probes = nullptr) {
  const int w = image.width, h = image.height;
  std::vector<Hit> ref(size_t(w) * h);
  double scale = 0.0;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      ref[size_t(y) * w + x] = oracle(s, c, light, w, h, x, y, probes);
      const glm::dvec3 r = glm::abs(ref[size_t(y) * w + x].radiance);
      scale = std::max({scale, r.x, r.y, r.z});
    }
  Comparison out;
  for (int y = 1; y + 1 < h; ++y)
    for (int x = 1; x + 1 < w; ++x) {
      const Hit& centre = ref[size_t(y) * w + x];
      bool uniform = true;
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const Hit& o = ref[size_t(y + dy) * w + x + dx];
          uniform &= o.hit == centre.hit && o.receiver == centre.receiver;
        }
      if (!uniform) continue;
      const glm::dvec3 got(image.at(x, y));
      if (centre.hit) {
        if (centre.ambiguous) {
          ++out.ambiguous;
          continue;
        }
        const glm::dvec3 d = glm::abs(got - centre.radiance) / scale;
        const double e = std::max({d.x, d.y, d.z});
        out.maxError = std::max(out.maxError, e);
        ++out.compared;
        if (centre.receiver) {
          out.maxReceiverError = std::max(out.maxReceiverError, e);
          out.meanReceiverError += e;
          ++out.receiver;
        }
      } else {
        const glm::dvec3 a = glm::abs(got);
        out.maxBackground = std::max({out.maxBackground, a.x, a.y, a.z});
        ++out.background;
      }
    }
  if (out.receiver > 0) out.meanReceiverError /= out.receiver;
  return out;
}

double maxDifference(const ImageRgb& a, const ImageRgb& b) {
  double d = 0.0;
  for (size_t i = 0; i < a.pixels.size(); ++i) {
    const glm::vec3 e = glm::abs(a.pixels[i] - b.pixels[i]);
    d = std::max({d, double(e.x), double(e.y), double(e.z)});
  }
  return d;
}

// Relative tolerance (of the frame's peak) of renders against the oracle.
// llvmpipe: the renderer works in float32 (a dot product of <= 64 terms, interpolation from
// float plane equations, float texture weights), about 2^-24 per operation; the largest error
// measured over every test here is 7e-7. 1e-5 leaves a margin of 15 and still catches any
// wrong factor, channel, coefficient or interpolation (affine instead of perspective-correct
// interpolation is off by several % on the tilted quad).
// Hardware (Mesa's surfaceless platform picks a GPU's render node where there is one): vertex
// positions snap to 1/256 pixel and texture weights are 8-bit fractions, so a value can be off
// by its change across a pixel / 256 (≤ 5% of the range here → 2e-4) and a texture lookup by a
// texel step / 512 (≈ 2e-3 with these texels).
double shadingTolerance(const GlContext& c) { return c.renderer().find("llvmpipe") != std::string::npos ? 1e-5 : 1e-3; }
double textureTolerance(const GlContext& c) { return c.renderer().find("llvmpipe") != std::string::npos ? 1e-5 : 4e-3; }

// ---------------------------------------------------------------------------------------------

TEST(RenderBackend, ParsesNamesAndRejectsOthers) {
  EXPECT_EQ(parseGlBackend("osmesa"), GlBackend::OSMesa);
  EXPECT_EQ(parseGlBackend("egl"), GlBackend::Egl);
  EXPECT_STREQ(glBackendName(GlBackend::Egl), "egl");
  EXPECT_THROW(parseGlBackend("vulkan"), Error);
  EXPECT_THROW(parseGlBackend("OSMesa "), Error);
  EXPECT_THROW(parseGlBackend(""), Error);
}

void expectCore45(const GlContext& c) {
  EXPECT_FALSE(c.renderer().empty());
  EXPECT_EQ(c.version().rfind("4.5", 0), 0u) << c.version();
  EXPECT_NE(c.version().find("Core"), std::string::npos) << c.version();
}

TEST(RenderContext, OpensOnOSMesa) {
  GlContext c(GlBackend::OSMesa, kWidth, kHeight);
  EXPECT_EQ(c.platform(), "OSMesa");
  EXPECT_EQ(c.backend(), GlBackend::OSMesa);
  expectCore45(c);
}

TEST(RenderContext, OpensOnEglSurfaceless) {
  GlContext c(GlBackend::Egl, kWidth, kHeight, surfaceless());
  EXPECT_EQ(c.platform(), "EGL surfaceless");
  expectCore45(c);
}

TEST(RenderContext, EglAutoPicksAPlatform) {
  // Surfaceless on machines without a GPU, the device platform where a hardware device exists.
  GlContext c(GlBackend::Egl, kWidth, kHeight);
  EXPECT_EQ(c.platform().rfind("EGL ", 0), 0u) << c.platform();
  expectCore45(c);
  std::printf("  %s\n", c.description().c_str());
}

TEST(RenderContext, OpensOnEglDevicePlatform) {
  // With no GPU the device platform still lists Mesa's software device, which Device accepts.
  GlContextOptions o;
  o.eglPlatform = EglPlatform::Device;
  GlContext c(GlBackend::Egl, kWidth, kHeight, o);
  EXPECT_EQ(c.platform().rfind("EGL device (", 0), 0u) << c.platform();
  expectCore45(c);
}

// Runs in a child process (below) where GLVND finds no EGL vendor: context creation must fail
// with one line naming EGL, not crash or print.
// DISABLED_: gtest runs it only when asked (--gtest_also_run_disabled_tests).
TEST(RenderContext, DISABLED_EglFailureChild) {
  ASSERT_NE(std::getenv("PRT_RENDER_TEST_CHILD"), nullptr) << "runs as a child of EglFailureIsOneLine";
  try {
    GlContext c(GlBackend::Egl, kWidth, kHeight);
    ADD_FAILURE() << "a context opened without any EGL vendor";
  } catch (const Error& e) {
    const std::string what = e.what();
    EXPECT_EQ(what.rfind("EGL: no display", 0), 0u) << what;
    EXPECT_EQ(what.find('\n'), std::string::npos) << what;
  }
  GlContext osmesa(GlBackend::OSMesa, kWidth, kHeight);  // OSMesa does not need EGL
  expectCore45(osmesa);
}

TEST(RenderContext, EglFailureIsOneLine) {
  // GLVND reads its vendor list once per process, hence the child process.
  const test::RunResult child =
      test::run(cat("/proc/", ::getpid(), "/exe"),
                {"--gtest_also_run_disabled_tests", "--gtest_filter=RenderContext.DISABLED_EglFailureChild"},
                {.env = {{"__EGL_VENDOR_LIBRARY_FILENAMES", "/nonexistent.json"}, {"PRT_RENDER_TEST_CHILD", "1"}},
                 .mergeOutput = true});
  EXPECT_EQ(child.status, 0) << child.out;
  EXPECT_NE(child.out.find("[  PASSED  ] 1 test"), std::string::npos) << child.out;
}

TEST(RenderContext, RejectsBadFrameSize) { EXPECT_THROW(GlContext(GlBackend::OSMesa, 0, 10), Error); }

TEST(RenderShading, QuadMatchesCpuOracleOnBothBackends) {
  const Scene s = tiltedQuad(3);
  const sh::ShRgb light = randomLight(3, 11);
  for (GlBackend b : {GlBackend::OSMesa, GlBackend::Egl}) {
    GlContext ctx(b, kWidth, kHeight, surfaceless());
    Renderer r(ctx, s);
    const ImageRgb img = r.render(frontCamera(), light);
    ASSERT_EQ(img.width, kWidth);
    ASSERT_EQ(img.height, kHeight);
    const Comparison c = compare(img, s, frontCamera(), light);
    SCOPED_TRACE(glBackendName(b));
    EXPECT_GT(c.compared, 600);    // the quad covers a good part of the frame
    EXPECT_GT(c.background, 100);  // and leaves background around it
    EXPECT_LT(c.maxError, shadingTolerance(ctx));
    EXPECT_EQ(c.maxBackground, 0.0);  // cleared to exactly 0
  }
}

TEST(RenderShading, EveryBandCountUsesEveryCoefficient) {
  // 1..4 bands read transfer from vertex attributes, 5..8 from a storage buffer (up to 64
  // coefficients, the largest the format allows). A light with only its last coefficient set
  // catches an off-by-one or a truncated loop; one with only the first, a misplaced channel.
  GlContext ctx(GlBackend::OSMesa, kWidth, kHeight);
  for (int bands = 1; bands <= sh::kMaxBands; ++bands) {
    SCOPED_TRACE(cat(bands, " bands"));
    const Scene s = tiltedQuad(bands);
    Renderer r(ctx, s);
    EXPECT_EQ(r.bands(), bands);
    sh::ShRgb first(bands), last(bands);
    first.c.front() = glm::vec3(3.0f, 2.0f, 1.0f);
    last.c.back() = glm::vec3(1.0f, 3.0f, 2.0f);
    for (const sh::ShRgb& light : {randomLight(bands, 5), first, last})
      EXPECT_LT(compare(r.render(frontCamera(), light), s, frontCamera(), light).maxError, shadingTolerance(ctx));
  }
}

TEST(RenderShading, LightOfFewerBandsIsZeroPadded) {
  const Scene s = tiltedQuad(3);
  const sh::ShRgb light1 = randomLight(1, 3);
  GlContext ctx(GlBackend::OSMesa, kWidth, kHeight);
  Renderer r(ctx, s);
  const sh::ShRgb padded = sh::resize(light1, 3);
  EXPECT_LT(compare(r.render(frontCamera(), light1), s, frontCamera(), padded).maxError, shadingTolerance(ctx));
}

// A 4×3 texture with distinct texels: red grows with x, green with y, blue alternates.
Texture checker() {
  Texture t;
  t.name = "checker";
  t.width = 4;
  t.height = 3;
  for (int y = 0; y < t.height; ++y)
    for (int x = 0; x < t.width; ++x)
      t.texels.push_back(glm::vec4(0.1f + 0.25f * x, 0.15f + 0.4f * y, ((x + y) & 1) ? 0.9f : 0.05f, 1));
  return t;
}

TEST(RenderShading, TexturedQuadAlbedoPerPixel) {
  // A 4×3 texture with distinct texels over a quad facing the camera, transfer·light = π
  // everywhere, so each pixel shows albedo = factor × bilinear texture lookup exactly.
  Scene s;
  s.path = "textured-quad";
  s.textures.push_back(checker());
  Material mat;
  mat.baseColorFactor = glm::vec4(0.9f, 0.8f, 1.0f, 1.0f);
  mat.baseColorTexture = 0;
  s.materials.push_back(mat);
  MeshInstance m;
  m.name = "quad";
  m.positions = {{-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}};
  m.texcoords = {{0, 1}, {1, 1}, {1, 0}, {0, 0}};  // glTF: v = 0 at the top of the image
  m.indices = {0, 1, 2, 0, 2, 3};
  m.material = 0;
  m.transfer.assign(4, glm::vec3(float(prt::kPi / 0.2820947917738781)));
  s.meshes.push_back(m);
  s.transferBands = 1;
  updateBounds(s);
  sh::ShRgb light(1);
  light.c[0] = glm::vec3(0.2820947917738781f);  // transfer·light = π

  CameraView cam;
  cam.cameraToWorld = glm::translate(glm::dmat4(1.0), glm::dvec3(0.0, 0.0, 2.5));
  cam.yfov = glm::radians(60.0);
  GlContext ctx(GlBackend::Egl, kWidth, kHeight, surfaceless());
  Renderer r(ctx, s);
  const ImageRgb img = r.render(cam, light);
  const Comparison c = compare(img, s, cam, light);
  EXPECT_GT(c.compared, 500);
  EXPECT_LT(c.maxError, textureTolerance(ctx));
  // Orientation: the top-left pixel inside the quad shows the top-left texel's colour family
  // (texel (0, 0): blue 0.05), the bottom-left the bottom row (y = 2: blue 0.05, green high).
  const Hit topLeft = oracle(s, cam, light, kWidth, kHeight, 20, 10);
  ASSERT_TRUE(topLeft.hit);
  EXPECT_NEAR(img.at(20, 10).y, topLeft.radiance.y, textureTolerance(ctx));
  EXPECT_LT(img.at(20, 10).y, img.at(20, kHeight - 11).y);  // green grows downwards (v)
}

TEST(RenderShading, MirroringWorldTransformKeepsFrontFaces) {
  // The loader leaves every instance wound counter-clockwise in world space, also under a
  // mirroring node transform (it swaps two corners), so such an instance must render exactly
  // like the same world-space triangles without the mirror.
  Scene s = tiltedQuad(2);
  s.meshes[0].world = glm::scale(glm::dmat4(1.0), glm::dvec3(-1.0, 1.0, 1.0));
  const sh::ShRgb light = randomLight(2, 6);
  GlContext ctx(GlBackend::OSMesa, kWidth, kHeight);
  Renderer r(ctx, s);
  const Comparison c = compare(r.render(frontCamera(), light), s, frontCamera(), light);
  EXPECT_GT(c.compared, 600);
  EXPECT_LT(c.maxError, shadingTolerance(ctx));
}

TEST(RenderShading, BackFacesCulledUnlessDoubleSided) {
  Scene s = tiltedQuad(2);
  for (size_t i = 0; i < s.meshes[0].indices.size(); i += 3)
    std::swap(s.meshes[0].indices[i + 1], s.meshes[0].indices[i + 2]);  // now faces away
  const sh::ShRgb light = randomLight(2, 9);
  GlContext ctx(GlBackend::OSMesa, kWidth, kHeight);
  {
    Renderer r(ctx, s);
    const ImageRgb img = r.render(frontCamera(), light);
    EXPECT_EQ(maxDifference(img, ImageRgb(kWidth, kHeight)), 0.0);
  }
  s.materials[0].doubleSided = true;
  Renderer r(ctx, s);
  const Comparison c = compare(r.render(frontCamera(), light), s, frontCamera(), light);
  EXPECT_GT(c.compared, 600);
  EXPECT_LT(c.maxError, shadingTolerance(ctx));
}

TEST(RenderShading, DoubleSidedQuadSeenFromBehindShowsItsBackSide) {
  // Front and back transfer differ (random, two seeds); the quad is wound to face away from the
  // camera, so every pixel shows the back side: its transfer·light, not the front's and not
  // black. 2 bands read the front from attributes, 5 from a storage buffer; the back always
  // comes from a storage buffer. The same quad turned to face the camera shows the front.
  GlContext ctx(GlBackend::OSMesa, kWidth, kHeight);
  for (int bands : {2, 5}) {
    SCOPED_TRACE(cat(bands, " bands"));
    Scene s = tiltedQuad(bands);
    s.materials[0].doubleSided = true;
    MeshInstance& m = s.meshes[0];
    MeshInstance back = m;
    fillTransfer(back, bands, 1234);
    m.transferBack = back.transfer;
    const sh::ShRgb light = randomLight(bands, 21);
    Scene facing = s;
    for (size_t i = 0; i < m.indices.size(); i += 3) std::swap(m.indices[i + 1], m.indices[i + 2]);  // faces away
    Renderer r(ctx, s);
    const ImageRgb img = r.render(frontCamera(), light);
    const Comparison c = compare(img, s, frontCamera(), light);
    EXPECT_GT(c.compared, 600);
    EXPECT_LT(c.maxError, shadingTolerance(ctx));
    // The oracle with the back transfer dropped (the front's values) is far from the frame.
    Scene frontOnly = s;
    frontOnly.meshes[0].transferBack.clear();
    EXPECT_GT(compare(img, frontOnly, frontCamera(), light).maxError, 100 * shadingTolerance(ctx));
    Renderer rf(ctx, facing);
    const Comparison cf = compare(rf.render(frontCamera(), light), facing, frontCamera(), light);
    EXPECT_GT(cf.compared, 600);
    EXPECT_LT(cf.maxError, shadingTolerance(ctx));
  }
}

TEST(RenderShading, DoubleSidedPlaneLitFromBelowShowsEachSidesHemisphere) {
  // bake → render: a lone double-sided plane (albedo 0.8, facing +Y) under a sky of radiance 1
  // above and 0.25 below. Each side's irradiance is its hemisphere's, π·L (exact at the poles
  // for the band-limited step), so seen from above the plane leaves ρ·1, seen from below ρ·0.25:
  // not black, and not the front's. The light: the step projected by a midpoint rule in
  // (y, φ) with the horizon on a cell boundary.
  Scene s = test::makeScene({test::makePlane(glm::vec3(0.0f), 2.0f, 4)}, 0.8f);
  s.materials[0].doubleSided = true;
  bake::BakeSettings bs;
  bs.samples = 1024;
  bs.bounces = 1;
  bake::storeTransfer(s, bake::bakeSurface(s, bs).perMesh);
  s.transferBands = bs.bands;
  ASSERT_TRUE(s.meshes[0].hasBackTransfer());
  sh::ShRgb sky(bs.bands);
  {
    const int ny = 400, nphi = 400;
    float y[sh::kMaxBands * sh::kMaxBands];
    for (int i = 0; i < ny; ++i) {
      const double cy = -1.0 + (i + 0.5) * 2.0 / ny, r = std::sqrt(1.0 - cy * cy);
      for (int k = 0; k < nphi; ++k) {
        const double phi = (k + 0.5) * 2.0 * prt::kPi / nphi;
        sh::evaluate(bs.bands, glm::vec3(float(r * std::cos(phi)), float(cy), float(r * std::sin(phi))), y);
        const double w = (cy > 0.0 ? 1.0 : 0.25) * (2.0 / ny) * (2.0 * prt::kPi / nphi);
        for (int j = 0; j < bs.bands * bs.bands; ++j) sky.c[size_t(j)] += glm::vec3(float(w * y[j]));
      }
    }
  }
  auto looking = [](double fromY) {  // at the origin along ∓Y, image up along ±Z
    CameraView c;
    const glm::dvec3 back(0.0, fromY > 0 ? 1.0 : -1.0, 0.0), right(1.0, 0.0, 0.0);
    c.cameraToWorld = glm::dmat4(glm::dvec4(right, 0), glm::dvec4(glm::cross(back, right), 0), glm::dvec4(back, 0),
                                 glm::dvec4(0.0, fromY, 0.0, 1.0));
    c.yfov = glm::radians(40.0);
    c.znear = 0.1;
    return c;
  };
  GlContext ctx(GlBackend::OSMesa, kWidth, kHeight);
  Renderer r(ctx, s);
  for (double fromY : {3.0, -3.0}) {
    SCOPED_TRACE(fromY > 0 ? "from above" : "from below");
    const ImageRgb img = r.render(looking(fromY), sky);
    const double expected = 0.8 * (fromY > 0 ? 1.0 : 0.25);
    for (int dy = -4; dy <= 4; dy += 4)
      for (int dx = -4; dx <= 4; dx += 4)
        EXPECT_NEAR(img.at(kWidth / 2 + dx, kHeight / 2 + dy).g, expected, 0.01 * expected);
    // And every pixel matches the oracle, which shades the side the ray sees.
    const Comparison c = compare(img, s, looking(fromY), sky);
    EXPECT_GT(c.compared, 600);
    EXPECT_LT(c.maxError, shadingTolerance(ctx));
  }
}

TEST(RenderShading, OcclusionByDepth) {
  // A second, nearer quad of the same shape hides part of the first; the oracle keeps the
  // nearest hit, the renderer its depth test (reversed Z, infinite far plane).
  Scene s = tiltedQuad(2);
  MeshInstance front = s.meshes[0];
  front.name = "front";
  for (glm::vec3& p : front.positions) p = p * 0.4f + glm::vec3(0.3f, 0.1f, 1.0f);
  fillTransfer(front, 2, 99);
  front.material = -1;  // glTF default material: white, single-sided
  front.colors.clear();
  s.meshes.push_back(front);
  updateBounds(s);
  const sh::ShRgb light = randomLight(2, 4);
  GlContext ctx(GlBackend::Egl, kWidth, kHeight, surfaceless());
  Renderer r(ctx, s);
  const Comparison c = compare(r.render(frontCamera(), light), s, frontCamera(), light);
  EXPECT_GT(c.compared, 600);
  EXPECT_LT(c.maxError, shadingTolerance(ctx));
}

TEST(RenderShading, BackendsAgreeOneAfterAnother) {
  // OSMesa and EGL drive the same llvmpipe here and the frames match to the bit (measured
  // difference 0). Each is within the shading tolerance of the oracle, so they may differ by
  // that much where EGL reaches a GPU. Contexts are interleaved to show that switching back and
  // forth keeps each context's GL table working, and a repeated frame is identical.
  const Scene s = tiltedQuad(3);
  const sh::ShRgb light = randomLight(3, 21);
  GlContext a(GlBackend::OSMesa, kWidth, kHeight);
  Renderer ra(a, s);
  GlContext b(GlBackend::Egl, kWidth, kHeight, surfaceless());
  Renderer rb(b, s);
  const ImageRgb ia = ra.render(frontCamera(), light);
  const ImageRgb ib = rb.render(frontCamera(), light);
  const ImageRgb ia2 = ra.render(frontCamera(), light);
  double peak = 0.0;
  for (const glm::vec3& p : ia.pixels) peak = std::max({peak, double(p.x), double(p.y), double(p.z)});
  ASSERT_GT(peak, 0.0);
  EXPECT_LE(maxDifference(ia, ib), std::max(shadingTolerance(a), shadingTolerance(b)) * peak);
  EXPECT_EQ(maxDifference(ia, ia2), 0.0);
}

TEST(RenderShading, ReceiversWithoutProbesSkippedWithWarning) {
  Scene s = tiltedQuad(2);
  MeshInstance receiver = s.meshes[0];
  receiver.name = "mover";
  receiver.receiverOnly = true;
  receiver.transfer.clear();
  for (glm::vec3& p : receiver.positions) p.z += 1.0f;  // in front: would hide the quad if drawn
  s.meshes.push_back(receiver);
  GlContext ctx(GlBackend::OSMesa, kWidth, kHeight);
  Renderer r(ctx, s);
  ASSERT_EQ(r.warnings().size(), 1u);
  EXPECT_NE(r.warnings()[0].find("mover"), std::string::npos);
  const sh::ShRgb light = randomLight(2, 1);
  EXPECT_LT(compare(r.render(frontCamera(), light), s, frontCamera(), light).maxError, shadingTolerance(ctx));
}

TEST(RenderShading, SceneWithoutTransferIsAnError) {
  Scene s = tiltedQuad(2);
  s.transferBands = 0;
  GlContext ctx(GlBackend::OSMesa, kWidth, kHeight);
  EXPECT_THROW(Renderer(ctx, s), Error);
  s = tiltedQuad(2);
  s.meshes[0].transfer.clear();  // unbaked and not a receiver: skipped, nothing left to draw
  EXPECT_THROW(Renderer(ctx, s), Error);
}

// The demo scene with unshadowed diffuse transfer on its baked instances (t_i = Â_l y_i(N), so
// t · l is the irradiance of the light at the vertex normal).
Scene unshadowedCornell(const std::string& input, int bands) {
  Scene scene = loadScene(input);
  for (MeshInstance& m : scene.meshes) {
    if (m.receiverOnly) continue;
    m.transfer.clear();
    for (const glm::vec3& n : m.normals) {
      std::vector<float> y(size_t(bands) * bands);
      sh::evaluate(bands, n, y.data());
      for (int i = 0; i < bands * bands; ++i)
        m.transfer.push_back(glm::vec3(float(sh::clampedCosineFactor(sh::bandOf(i))) * y[size_t(i)]));
    }
  }
  scene.transferBands = bands;
  return scene;
}

TEST(RenderShading, BakedFileOfTheDemoSceneMatchesOracle) {
  // The path bake → file → render: the Cornell scene with unshadowed diffuse transfer
  // (t_i = Â_l y_i(N), so t · l is the irradiance of the light at the vertex normal) written as
  // a baked .glb, loaded back and seen through the scene's own camera. Checks that world
  // transforms, materials and the baked attributes reach the renderer as the loader means them.
  const std::string input = test::sourcePath("scenes/cornell_open.gltf");
  const int bands = 3;
  Scene scene = unshadowedCornell(input, bands);
  const std::filesystem::path out =
      std::filesystem::temp_directory_path() / cat("prt_test_render_", ::getpid(), ".glb");
  writeBakedScene(input, scene, nullptr, out.string());
  const Scene baked = loadScene(out.string());
  std::filesystem::remove(out);
  ASSERT_EQ(baked.transferBands, bands);
  ASSERT_FALSE(baked.cameras.empty());

  sh::ShRgb light(bands);  // a sky brighter overhead, warmer from +X
  light.c[0] = glm::vec3(1.0f, 0.9f, 0.8f);
  light.c[1] = glm::vec3(0.5f);
  light.c[3] = glm::vec3(0.3f, 0.1f, 0.0f);
  GlContext ctx(GlBackend::Egl, kWidth, kHeight, surfaceless());
  Renderer r(ctx, baked);
  EXPECT_EQ(r.warnings().size(), 1u);  // the receiver sphere
  const CameraView cam = cameraView(baked.cameras[0]);
  const Comparison c = compare(r.render(cam, light), baked, cam, light);
  EXPECT_GT(c.compared, kWidth * kHeight / 2);
  EXPECT_LT(c.maxError, shadingTolerance(ctx));
}

TEST(RenderCamera, OrbitLooksAtTheTarget) {
  const Scene s = tiltedQuad(1);
  OrbitCamera o;
  o.target = glm::vec3(0.5f, 0.0f, 0.0f);
  o.distance = 4.0;
  o.azimuthDegrees = 90.0;
  o.elevationDegrees = 30.0;
  const CameraView v = orbitView(s, o, 4.0 / 3.0);
  const glm::dvec3 eye(v.cameraToWorld[3]);
  // Azimuth 90° puts the camera on +X; elevation 30° raises it by distance·sin 30°.
  EXPECT_NEAR(eye.x, 0.5 + 4.0 * std::cos(glm::radians(30.0)), 1e-12);
  EXPECT_NEAR(eye.y, 2.0, 1e-12);
  EXPECT_NEAR(eye.z, 0.0, 1e-12);
  const glm::dvec3 forward = -glm::dvec3(v.cameraToWorld[2]);
  EXPECT_NEAR(glm::dot(forward, glm::normalize(glm::dvec3(0.5, 0, 0) - eye)), 1.0, 1e-12);
  EXPECT_NEAR(glm::dvec3(v.cameraToWorld[0]).y, 0.0, 1e-12);  // horizon stays level
}

// The default orbit frames where the geometry is: 1000 vertices in a 1 m cube at (10, 0, 0)
// standing on a 2 km ground of 4 vertices are framed by the cube's box (the 1st–99th
// percentiles), not by the ground; without the ground the bounds are kept.
TEST(RenderCamera, DefaultOrbitFramesWhereTheGeometryIs) {
  Scene s;
  MeshInstance cube, ground;
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  for (int i = 0; i < 1000; ++i) cube.positions.push_back(glm::vec3(10.0f + u(rng), u(rng), u(rng)));
  for (float x : {-1000.0f, 1000.0f})
    for (float z : {-1000.0f, 1000.0f}) ground.positions.push_back(glm::vec3(x, 0.0f, z));
  s.meshes = {cube, ground};
  s.boundsMin = glm::vec3(-1000.0f, 0.0f, -1000.0f);
  s.boundsMax = glm::vec3(1000.0f, 1.0f, 1000.0f);
  glm::dvec3 lo, hi;
  orbitFraming(s, lo, hi);
  EXPECT_GT(lo.x, 9.99);
  EXPECT_LT(hi.x, 11.01);
  EXPECT_GT(lo.z, -0.01);
  EXPECT_LT(hi.z, 1.01);
  const glm::dvec3 target = orbitTarget(s, OrbitCamera{});
  EXPECT_NEAR(target.x, 10.5, 0.05);
  const CameraView v = orbitView(s, OrbitCamera{}, 1.0);
  EXPECT_LT(glm::length(glm::dvec3(v.cameraToWorld[3]) - target), 10.0);  // not kilometres away

  s.meshes = {cube};
  s.boundsMin = glm::vec3(10.0f, 0.0f, 0.0f);
  s.boundsMax = glm::vec3(11.0f, 1.0f, 1.0f);
  orbitFraming(s, lo, hi);
  EXPECT_EQ(lo, glm::dvec3(s.boundsMin));
  EXPECT_EQ(hi, glm::dvec3(s.boundsMax));
}

TEST(RenderCamera, OrbitFramesTheSceneAndMatchesOracle) {
  const Scene s = tiltedQuad(2);
  OrbitCamera o;
  o.azimuthDegrees = 20.0;
  o.elevationDegrees = 15.0;
  const CameraView v = orbitView(s, o, double(kWidth) / kHeight);
  const sh::ShRgb light = randomLight(2, 8);
  GlContext ctx(GlBackend::OSMesa, kWidth, kHeight);
  Renderer r(ctx, s);
  const Comparison c = compare(r.render(v, light), s, v, light);
  EXPECT_GT(c.compared, 300);
  EXPECT_LT(c.maxError, shadingTolerance(ctx));
}

TEST(RenderCamera, OrthographicAndOtherSizes) {
  // A second frame size on the same renderer rebuilds the framebuffer; ymag is half the height.
  const Scene s = tiltedQuad(2);
  CameraView v = frontCamera();
  v.perspective = false;
  v.ymag = 1.2;
  const sh::ShRgb light = randomLight(2, 2);
  GlContext ctx(GlBackend::OSMesa, kWidth, kHeight);
  Renderer r(ctx, s);
  const ImageRgb img = r.render(v, light, 40, 30);
  EXPECT_EQ(img.width, 40);
  const Comparison c = compare(img, s, v, light);
  EXPECT_GT(c.compared, 200);
  EXPECT_LT(c.maxError, shadingTolerance(ctx));
}

TEST(RenderCamera, GltfCameraDropsScale) {
  Camera cam;
  cam.world = glm::scale(glm::translate(glm::dmat4(1.0), glm::dvec3(1, 2, 3)), glm::dvec3(2.0));
  cam.yfov = 0.5;
  const CameraView v = cameraView(cam);
  EXPECT_NEAR(glm::length(glm::dvec3(v.cameraToWorld[0])), 1.0, 1e-12);
  EXPECT_EQ(glm::dvec3(v.cameraToWorld[3]), glm::dvec3(1, 2, 3));
  EXPECT_EQ(v.yfov, 0.5);
}

// ---------------------------------------------------------------------------------------------
// Receivers: lit per pixel from a probe grid, checked against prt::interpolateRadiance +
// sh::irradiance at pixel centres (the oracle above with ProbeLighting).

// Relative tolerance (of the frame's peak) for receiver pixels against the oracle. The shader
// evaluates the weights in float where probeWeights uses double: x − P and the Chebyshev term
// (r − μ)² lose ~1e-7 relative, amplified where the cubed Chebyshev factor falls steeply behind
// a surface (d w_v / dr ~ 6/σ with σ down to 0.01 spacing), and the GPU's x itself comes from
// float interpolation. Measured worst over these tests: see docs/render.md (a few 1e-6);
// 1e-4 leaves a wide margin and still catches any wrong corner, face, factor or coefficient
// (each moves pixels by 1e-2 or more).
constexpr double kReceiverTolerance = 1e-4;

// A UV sphere with outward normals and counter-clockwise front faces, centred at `centre`.
MeshInstance sphere(const glm::vec3& centre, float radius, int segments, int rings) {
  MeshInstance m;
  m.name = "sphere";
  auto add = [&](const glm::vec3& n) {
    m.positions.push_back(centre + radius * n);
    m.normals.push_back(n);
  };
  add({0, 1, 0});
  for (int r = 1; r < rings; ++r)
    for (int s = 0; s < segments; ++s) {
      const double th = prt::kPi * r / rings, ph = 2.0 * prt::kPi * s / segments;
      add(glm::vec3(float(std::sin(th) * std::cos(ph)), float(std::cos(th)), float(-std::sin(th) * std::sin(ph))));
    }
  add({0, -1, 0});
  const uint32_t bottom = uint32_t(m.positions.size() - 1);
  auto ring = [&](int r, int s) { return uint32_t(1 + (r - 1) * segments + (s % segments)); };
  for (int s = 0; s < segments; ++s) {
    m.indices.insert(m.indices.end(), {0, ring(1, s), ring(1, s + 1)});
    for (int r = 1; r + 1 < rings; ++r) {
      m.indices.insert(m.indices.end(), {ring(r, s), ring(r + 1, s), ring(r + 1, s + 1)});
      m.indices.insert(m.indices.end(), {ring(r, s), ring(r + 1, s + 1), ring(r, s + 1)});
    }
    m.indices.insert(m.indices.end(), {ring(rings - 1, s), bottom, ring(rings - 1, s + 1)});
  }
  return m;
}

// A plane of side 2 subdivided n×n, through `centre`, spanned by u and v (u × v = its normal).
MeshInstance wall(const std::string& name, const glm::vec3& centre, const glm::vec3& u, const glm::vec3& v, int n) {
  MeshInstance m;
  m.name = name;
  const glm::vec3 normal = glm::normalize(glm::cross(u, v));
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i) {
      m.positions.push_back(centre + (2.0f * i / n - 1.0f) * u + (2.0f * j / n - 1.0f) * v);
      m.normals.push_back(normal);
    }
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const uint32_t a = uint32_t(j * (n + 1) + i), b = a + 1, c = a + uint32_t(n + 1), d = c + 1;
      m.indices.insert(m.indices.end(), {a, b, d, a, d, c});
    }
  return m;
}

sh::ShRgb skyLight(int bands) {
  sh::ShRgb l(bands);  // brighter overhead, warmer from +X, some band-2 structure
  l.c[0] = glm::vec3(2.0f, 1.9f, 1.7f);
  if (bands > 1) {
    l.c[1] = glm::vec3(1.0f, 1.0f, 1.1f);
    l.c[3] = glm::vec3(0.5f, 0.3f, 0.1f);
  }
  if (bands > 2) {
    l.c[4] = glm::vec3(0.2f, -0.1f, 0.1f);
    l.c[6] = glm::vec3(0.3f, 0.25f, 0.2f);
  }
  return l;
}

CameraView lookAt(const glm::dvec3& eye, const glm::dvec3& target, double yfovDegrees) {
  CameraView c;
  c.cameraToWorld = glm::inverse(glm::lookAt(eye, target, glm::dvec3(0, 1, 0)));
  c.yfov = glm::radians(yfovDegrees);
  c.znear = 0.05;
  return c;
}

// A corner of a room open to the sky (floor, back wall, red left wall) with baked transfer,
// a white receiver sphere in it, and a probe grid baked around it with bake::bakeProbes.
struct BakedRoom {
  Scene scene;
  ProbeGrid grid;
};

const BakedRoom& bakedRoom() {
  static const BakedRoom room = [] {
    BakedRoom r;
    Scene& s = r.scene;
    s.path = "room";
    for (const glm::vec3 albedo : {glm::vec3(0.7f), glm::vec3(0.6f, 0.1f, 0.08f), glm::vec3(0.85f, 0.8f, 0.7f)}) {
      Material m;
      m.baseColorFactor = glm::vec4(albedo, 1.0f);
      s.materials.push_back(m);
    }
    s.meshes.push_back(wall("floor", {0, 0, 0}, {1, 0, 0}, {0, 0, -1}, 8));
    s.meshes.push_back(wall("back", {0, 1, -1}, {1, 0, 0}, {0, 1, 0}, 8));
    s.meshes.push_back(wall("left", {-1, 1, 0}, {0, 0, 1}, {0, 1, 0}, 8));
    s.meshes[1].material = 0;
    s.meshes[0].material = 0;
    s.meshes[2].material = 1;
    MeshInstance ball = sphere({0.15f, 0.45f, 0.05f}, 0.35f, 32, 16);
    ball.name = "ball";
    ball.material = 2;
    ball.receiverOnly = true;
    s.meshes.push_back(ball);
    updateBounds(s);
    bake::BakeSettings bs;
    bs.samples = 128;
    bs.bounces = 1;
    bs.keepLowerOrder = true;
    const bake::SurfaceTransfer t = bake::bakeSurface(s, bs);
    for (size_t k = 0; k < s.meshes.size(); ++k) {
      if (s.meshes[k].receiverOnly) continue;
      s.meshes[k].transfer = t.perMesh[k];
    }
    s.transferBands = 3;
    bake::ProbeSettings ps;
    ps.dims = glm::ivec3(5, 4, 5);
    ps.boundsMin = glm::dvec3(-0.98, 0.0, -0.98);
    ps.boundsMax = glm::dvec3(0.98, 1.2, 0.98);
    ps.samples = 512;
    ps.bounces = 1;
    r.grid = bake::bakeProbes(s, t.perMeshLowerOrder, ps);
    return r;
  }();
  return room;
}

CameraView roomCamera() { return lookAt({0.5, 0.9, 2.2}, {0.0, 0.45, 0.0}, 45.0); }

TEST(RenderReceivers, BakedGridMatchesOracleOnBothBackends) {
  const BakedRoom& room = bakedRoom();
  ASSERT_GT(room.grid.probeCount(), 50u);
  const sh::ShRgb light = skyLight(3);
  const ProbeLighting probes = probeLighting(room.grid, light);
  const int w = 96, h = 72;
  std::vector<ImageRgb> frames;
  for (GlBackend b : {GlBackend::OSMesa, GlBackend::Egl}) {
    SCOPED_TRACE(glBackendName(b));
    GlContext ctx(b, w, h, surfaceless());
    Renderer r(ctx, room.scene);
    EXPECT_EQ(r.receiverCount(), 1u);
    r.setProbes(room.grid);
    EXPECT_TRUE(r.warnings().empty());
    frames.push_back(r.render(roomCamera(), light));
    EXPECT_GT(r.lastFrame().receiverTriangles, 0u);
    const Comparison c = compare(frames.back(), room.scene, roomCamera(), light, &probes);
    std::printf("  %s: %d receiver pixels (%d near a weight jump, skipped), max error %.3g, mean %.3g\n",
                glBackendName(b), c.receiver, c.ambiguous, c.maxReceiverError, c.meanReceiverError);
    EXPECT_GT(c.receiver, 400);  // the ball fills a good part of the frame
    EXPECT_LT(c.ambiguous, c.receiver / 10);
    EXPECT_LT(c.maxReceiverError,
              ctx.renderer().find("llvmpipe") != std::string::npos ? kReceiverTolerance : 10 * kReceiverTolerance);
    EXPECT_LT(c.maxError, std::max(shadingTolerance(ctx), kReceiverTolerance));
  }
  // OSMesa and EGL: both within the tolerance of the oracle, so within twice it of each other
  // (identical on llvmpipe).
  double peak = 0.0;
  for (const glm::vec3& p : frames[0].pixels) peak = std::max({peak, double(p.x), double(p.y), double(p.z)});
  const double diff = maxDifference(frames[0], frames[1]) / peak;
  std::printf("  OSMesa vs EGL: max difference %.3g of the peak\n", diff);
  EXPECT_LE(diff, 2 * 10 * kReceiverTolerance);
}

// Irradiance of 3-band SH radiance l at unit normal n, written out from the Cartesian basis of
// prt/sh.h and the clamped-cosine factors π, 2π/3, π/4 (no prt code involved).
glm::dvec3 closedFormIrradiance(const sh::ShRgb& l, const glm::dvec3& n) {
  const double x = n.x, y = n.y, z = n.z;
  const double basis[9] = {0.282095,
                           0.488603 * y,
                           0.488603 * z,
                           0.488603 * x,
                           1.092548 * x * y,
                           1.092548 * y * z,
                           0.315392 * (3 * z * z - 1),
                           1.092548 * x * z,
                           0.546274 * (x * x - y * y)};
  const double a[9] = {prt::kPi,     2 * prt::kPi / 3, 2 * prt::kPi / 3, 2 * prt::kPi / 3, prt::kPi / 4,
                       prt::kPi / 4, prt::kPi / 4,     prt::kPi / 4,     prt::kPi / 4};
  glm::dvec3 e(0.0);
  for (int i = 0; i < 9; ++i) e += a[i] * basis[i] * glm::dvec3(l.c[size_t(i)]);
  return e;
}

// A receiver alone in an empty scene is lit like an unoccluded surface: L = ρ/π · E(n) with E
// the closed-form irradiance of the light at the pixel's normal. Checked with the identity grid
// (M = I exactly) and with a real bake of the empty scene (M = I up to the bake's quadrature).
TEST(RenderReceivers, EmptySceneLitLikeAnUnoccludedSurface) {
  Scene s;
  s.path = "empty";
  Material white;
  white.baseColorFactor = glm::vec4(0.9f, 0.75f, 0.6f, 1.0f);
  s.materials.push_back(white);
  MeshInstance ball = sphere({0.1f, 0.0f, -0.05f}, 0.6f, 32, 16);
  ball.material = 0;
  ball.receiverOnly = true;
  s.meshes.push_back(ball);
  updateBounds(s);
  ASSERT_EQ(s.transferBands, 0);  // nothing baked: the renderer draws receivers only

  bake::ProbeSettings ps;
  ps.dims = glm::ivec3(3);
  ps.boundsMin = glm::dvec3(-1.0);
  ps.boundsMax = glm::dvec3(1.0);
  ps.samples = 1024;
  const ProbeGrid baked = bake::bakeProbes(s, {}, ps);
  const ProbeGrid identity = test::identityProbeGrid(3, glm::ivec3(4), glm::dvec3(-1.0), glm::dvec3(2.0 / 3.0));
  const sh::ShRgb light = skyLight(3);
  const CameraView cam = lookAt({0.3, 0.4, 2.5}, {0.1, 0.0, -0.05}, 35.0);
  GlContext ctx(GlBackend::OSMesa, kWidth, kHeight);
  Renderer r(ctx, s);
  EXPECT_EQ(r.bands(), 0);
  // Tolerances (of the frame's peak): the identity grid is float arithmetic only (weights sum to
  // 1 within 1e-7, normals interpolated in float; measured 1e-6); the empty bake's matrices are
  // identity within 1e-2 per element and measured ≲ 1e-3 (ProbeBake.EmptySceneGivesIdentity,
  // 1024 Sobol directions): measured 1.2e-3 here, 1e-2 allows the element tolerance.
  for (const auto& [grid, tolerance] : {std::pair{&identity, 1e-5}, std::pair{&baked, 1e-2}}) {
    r.setProbes(*grid);
    const ImageRgb img = r.render(cam, light);
    const ProbeLighting pl = probeLighting(*grid, light);
    std::vector<Hit> hits(size_t(kWidth) * kHeight);
    for (int y = 0; y < kHeight; ++y)
      for (int x = 0; x < kWidth; ++x) hits[size_t(y) * kWidth + x] = oracle(s, cam, light, kWidth, kHeight, x, y, &pl);
    double peak = 0.0, worst = 0.0;
    int compared = 0;
    for (int y = 1; y + 1 < kHeight; ++y)
      for (int x = 1; x + 1 < kWidth; ++x) {
        bool interior = true;
        for (int dy = -1; dy <= 1; ++dy)
          for (int dx = -1; dx <= 1; ++dx) interior &= hits[size_t(y + dy) * kWidth + x + dx].hit;
        if (!interior) continue;
        // The closed form at the normal the oracle's ray hit (barycentric vertex normals).
        const Hit& h = hits[size_t(y) * kWidth + x];
        const glm::dvec3 expected = glm::dvec3(white.baseColorFactor) * kInvPi * closedFormIrradiance(light, h.normal);
        const glm::dvec3 got(img.at(x, y));
        peak = std::max({peak, expected.x, expected.y, expected.z});
        const glm::dvec3 d = glm::abs(got - expected);
        worst = std::max({worst, d.x, d.y, d.z});
        ++compared;
      }
    std::printf("  %s grid: %d pixels, max error %.3g of the peak\n", grid == &identity ? "identity" : "baked",
                compared, worst / peak);
    EXPECT_GT(compared, kWidth * kHeight / 4);
    EXPECT_LT(worst / peak, tolerance);
  }
}

// Points outside the grid's domain (the lattice's box grown by half a cell) get no probe and are
// lit by the light itself (M = I). With M = ½ I inside, the half of the ball inside the domain is
// half as bright as the other half.
TEST(RenderReceivers, BeyondTheDomainFadesIntoTheLight) {
  Scene s;
  s.path = "half-inside";
  MeshInstance ball = sphere({0.0f, 0.0f, 0.0f}, 0.8f, 32, 16);
  ball.receiverOnly = true;
  s.meshes.push_back(ball);
  updateBounds(s);
  // The lattice covers x ≤ −0.25 only, its domain x ≤ 0.
  const ProbeGrid half = test::identityProbeGrid(3, glm::ivec3(3, 4, 4), glm::dvec3(-1.25, -1.0, -1.0),
                                                 glm::dvec3(0.5, 2.0 / 3.0, 2.0 / 3.0), 0.5f);
  const sh::ShRgb light = skyLight(3);
  const ProbeLighting pl = probeLighting(half, light);
  const CameraView cam = lookAt({0.0, 0.0, 3.0}, {0.0, 0.0, 0.0}, 40.0);
  GlContext ctx(GlBackend::OSMesa, kWidth, kHeight);
  Renderer r(ctx, s);
  r.setProbes(half);
  const ImageRgb img = r.render(cam, light);
  const Comparison c = compare(img, s, cam, light, &pl);
  EXPECT_GT(c.receiver, 500);
  EXPECT_LT(c.maxReceiverError, kReceiverTolerance);
  // Directly, along the middle row, against the closed form: the probes give half the
  // unoccluded light up to the domain's edge x = 0; beyond it their share fades linearly into
  // the light's over one spacing (0.5), f = 2x − 10⁻⁴ (docs/probes.md), to the whole light
  // from x = 0.5 on (x of the hit point on the tessellated ball).
  int inside = 0, fading = 0, beyond = 0;
  for (int px = 0; px < kWidth; ++px) {
    const Hit h = oracle(s, cam, light, kWidth, kHeight, px, kHeight / 2, &pl);
    if (!h.hit || h.ambiguous) continue;
    const double x = h.position.x;
    const double f = std::clamp(2.0 * x - 1e-4, 0.0, 1.0);
    const double unoccluded = kInvPi * closedFormIrradiance(light, h.normal).y;
    EXPECT_NEAR(img.at(px, kHeight / 2).y, ((1.0 - f) * 0.5 + f) * unoccluded, 1e-5 * unoccluded) << px << " x " << x;
    inside += f == 0.0;
    fading += f > 0.0 && f < 1.0;
    beyond += f == 1.0;
  }
  EXPECT_GT(inside, 5);
  EXPECT_GT(fading, 5);
  EXPECT_GT(beyond, 2);
}

// A small random grid (random M, validity, offsets, moments) for every band count: each
// coefficient the shader reads, the SH basis it generates for 1..8 bands, invalid probes,
// offsets and non-uniform spacing all show in the comparison with interpolateRadiance.
ProbeGrid randomGrid(int bands, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  ProbeGrid g;
  g.bands = bands;
  g.dims = glm::ivec3(3, 3, 3);
  g.origin = glm::dvec3(-1.0, -0.9, -1.1);
  g.spacing = glm::dvec3(1.0, 0.9, 1.1);
  for (int z = 0; z < 3; ++z)
    for (int y = 0; y < 3; ++y)
      for (int x = 0; x < 3; ++x)
        if (!(x == 2 && y == 2 && z == 0)) g.coord.emplace_back(x, y, z);  // one inactive point
  const size_t count = g.coord.size();
  g.transfer.resize(count * g.transferStride());
  for (float& v : g.transfer) v = u(rng) * 1.2f - 0.2f;
  g.validity.assign(count, 1.0f);
  g.validity[5] = 0.0f;
  g.offset.resize(count);
  for (glm::vec3& o : g.offset) o = 0.1f * glm::vec3(u(rng) - 0.5f, u(rng) - 0.5f, u(rng) - 0.5f);
  g.skyVisibility.assign(count, 1.0f);
  g.moments.resize(count);
  for (auto& faces : g.moments)
    for (glm::vec2& m : faces) {
      const float mu = 0.3f + 1.2f * u(rng), sigma = 0.3f * u(rng);
      m = glm::vec2(mu, mu * mu + sigma * sigma);
    }
  g.buildIndex();
  return g;
}

// A receiver ball inside randomGrid's lattice.
Scene randomGridBall() {
  Scene s;
  s.path = "random-grid";
  Material mat;
  mat.baseColorFactor = glm::vec4(0.8f, 0.7f, 0.9f, 1.0f);
  s.materials.push_back(mat);
  MeshInstance ball = sphere({0.05f, 0.0f, 0.0f}, 0.75f, 32, 16);
  ball.material = 0;
  ball.receiverOnly = true;
  s.meshes.push_back(ball);
  updateBounds(s);
  return s;
}

TEST(RenderReceivers, EveryBandCountMatchesOracleOnARandomGrid) {
  const Scene s = randomGridBall();
  const CameraView cam = lookAt({0.4, 0.5, 3.0}, {0.05, 0.0, 0.0}, 40.0);
  GlContext ctx(GlBackend::OSMesa, kWidth, kHeight);
  Renderer r(ctx, s);
  for (int bands = 1; bands <= sh::kMaxBands; ++bands) {
    SCOPED_TRACE(cat(bands, " bands"));
    const ProbeGrid g = randomGrid(bands, 100 + uint32_t(bands));
    r.setProbes(g);
    sh::ShRgb last(bands);
    last.c.back() = glm::vec3(1.0f, 3.0f, 2.0f);
    for (const sh::ShRgb& light : {randomLight(bands, 40), last}) {
      const ProbeLighting pl = probeLighting(g, light);
      const Comparison c = compare(r.render(cam, light), s, cam, light, &pl);
      EXPECT_GT(c.receiver, 500);
      EXPECT_LT(c.maxReceiverError, kReceiverTolerance) << "mean " << c.meanReceiverError;
    }
  }
}

// Frame::probeBounce (the bake's operator at the probes, docs/lights.md, "Probes through the
// operator") is added to the relit probes before the receivers read them: the oracle with the
// same values added matches, the oracle without them does not.
TEST(RenderReceivers, ProbeBounceIsAddedToTheRelitProbes) {
  const Scene s = randomGridBall();
  const CameraView cam = lookAt({0.4, 0.5, 3.0}, {0.05, 0.0, 0.0}, 40.0);
  GlContext ctx(GlBackend::OSMesa, kWidth, kHeight);
  Renderer r(ctx, s);
  const ProbeGrid g = randomGrid(3, 77);
  r.setProbes(g);
  const sh::ShRgb light = randomLight(3, 41);
  std::vector<glm::vec3> bounce(g.probeCount() * 9);
  for (size_t i = 0; i < bounce.size(); ++i)
    bounce[i] = glm::vec3(0.3f + 0.1f * float(i % 9 == 0), 0.2f, 0.25f) * (i % 9 == 0 ? 1.0f : 0.2f);
  Frame frame;
  frame.camera = cam;
  frame.light = light;
  frame.probeBounce = &bounce;
  const ImageRgb img = r.render(frame);
  ProbeLighting with = probeLighting(g, light);
  for (size_t i = 0; i < bounce.size(); ++i) with.relit[i] += bounce[i];
  const Comparison c = compare(img, s, cam, light, &with);
  EXPECT_GT(c.receiver, 500);
  EXPECT_LT(c.maxReceiverError, kReceiverTolerance) << "mean " << c.meanReceiverError;
  const ProbeLighting without = probeLighting(g, light);
  EXPECT_GT(compare(img, s, cam, light, &without).maxReceiverError, 10 * kReceiverTolerance);
}

// Every material variant of the shaders (renderer: compiled with HAS_TEXTURE / HAS_COLOR as the
// material has a base colour texture / the mesh COLOR_0) on receivers and baked instances in
// one frame: plain, COLOR_0 only, texture only, both; each matches the oracle.
TEST(RenderReceivers, MaterialVariantsMatchOracle) {
  Scene s;
  s.path = "variants";
  s.textures.push_back(checker());
  Material plain;
  plain.baseColorFactor = glm::vec4(0.8f, 0.7f, 0.9f, 1.0f);
  Material textured = plain;
  textured.baseColorTexture = 0;
  s.materials = {plain, textured};
  // Texcoords and colours from the position.
  auto decorate = [](MeshInstance& m, int material, bool texcoords, bool colors) {
    m.material = material;
    for (const glm::vec3& p : m.positions) {
      if (texcoords) m.texcoords.emplace_back(0.5f + 0.8f * p.x, 0.5f - 0.9f * p.y + 0.3f * p.z);
      if (colors)
        m.colors.emplace_back(0.5f + 0.4f * std::sin(3.0f * p.x), 0.6f, 0.5f + 0.4f * std::cos(2.0f * p.y), 1.0f);
    }
  };
  const glm::vec3 centres[4] = {{-0.5f, 0.4f, 0.0f}, {0.5f, 0.4f, 0.0f}, {-0.5f, -0.4f, 0.0f}, {0.5f, -0.4f, 0.0f}};
  for (int v = 0; v < 4; ++v) {
    MeshInstance ball = sphere(centres[v], 0.33f, 24, 12);
    ball.name = cat("ball", v);
    ball.receiverOnly = true;
    decorate(ball, v & 1 ? 1 : 0, v & 1, v & 2);
    s.meshes.push_back(ball);
    // A baked quad behind each ball, of the same variant.
    MeshInstance quad = wall(cat("quad", v), centres[v] - glm::vec3(0.0f, 0.0f, 0.6f), {0.45f, 0, 0}, {0, 0.38f, 0}, 2);
    quad.normals.clear();
    decorate(quad, v & 1 ? 1 : 0, v & 1, v & 2);
    fillTransfer(quad, 3, 70 + uint32_t(v));
    s.meshes.push_back(quad);
  }
  s.transferBands = 3;
  updateBounds(s);
  const CameraView cam = lookAt({0.1, 0.2, 3.2}, {0.0, 0.0, -0.2}, 40.0);
  const ProbeGrid g = randomGrid(3, 77);
  const sh::ShRgb light = randomLight(3, 41);
  const ProbeLighting pl = probeLighting(g, light);
  const int w = 128, h = 96;
  GlContext ctx(GlBackend::OSMesa, w, h);
  Renderer r(ctx, s);
  r.setProbes(g);
  const Comparison c = compare(r.render(cam, light), s, cam, light, &pl);
  std::printf("  %d pixels (%d receiver), max receiver error %.3g, max error %.3g\n", c.compared, c.receiver,
              c.maxReceiverError, c.maxError);
  EXPECT_GT(c.receiver, 1500);              // four balls
  EXPECT_GT(c.compared - c.receiver, 400);  // and the quads' rims around them
  EXPECT_LT(c.maxReceiverError, kReceiverTolerance) << "mean " << c.meanReceiverError;
  EXPECT_LT(c.maxError, std::max(textureTolerance(ctx), kReceiverTolerance));
}

// ProbeLookup::PerVertex: the lookup at the vertices, interpolated, matches an oracle that does
// the same in double (C++ interpolateRadiance at each vertex, barycentric interpolation, the
// irradiance at the pixel's normal): the baked room, and a random grid at two band counts.
TEST(RenderReceivers, PerVertexLookupMatchesItsOracle) {
  const BakedRoom& room = bakedRoom();
  const sh::ShRgb light = skyLight(3);
  ProbeLighting probes = probeLighting(room.grid, light);
  probes.perVertex = true;
  const int w = 96, h = 72;
  GlContext ctx(GlBackend::OSMesa, w, h);
  Renderer r(ctx, room.scene);
  r.setProbes(room.grid);
  Frame f;
  f.camera = roomCamera();
  f.light = light;
  const ImageRgb perPixel = r.render(f);
  f.probeLookup = ProbeLookup::PerVertex;
  const ImageRgb perVertex = r.render(f);
  const Comparison c = compare(perVertex, room.scene, roomCamera(), light, &probes);
  double peak = 0.0;
  for (const glm::vec3& p : perPixel.pixels) peak = std::max({peak, double(p.x), double(p.y), double(p.z)});
  std::printf(
      "  room: %d receiver pixels (%d skipped), max error %.3g, mean %.3g; per vertex vs per pixel: %.3g of the peak\n",
      c.receiver, c.ambiguous, c.maxReceiverError, c.meanReceiverError, maxDifference(perPixel, perVertex) / peak);
  EXPECT_GT(c.receiver, 400);
  EXPECT_LT(c.ambiguous, c.receiver / 5);
  EXPECT_LT(c.maxReceiverError, kReceiverTolerance);
  EXPECT_GT(maxDifference(perPixel, perVertex), 0.0);  // a different lookup, not the per-pixel one
  {
    // EGL gives the same frame (identical on llvmpipe; within the oracle tolerance twice on hardware).
    GlContext egl(GlBackend::Egl, w, h, surfaceless());
    Renderer re(egl, room.scene);
    re.setProbes(room.grid);
    EXPECT_LE(maxDifference(re.render(f), perVertex) / peak, 2 * 10 * kReceiverTolerance);
  }

  const Scene s = randomGridBall();
  const CameraView cam = lookAt({0.4, 0.5, 3.0}, {0.05, 0.0, 0.0}, 40.0);
  Renderer rs(ctx, s);
  for (int bands : {2, 5}) {
    SCOPED_TRACE(cat(bands, " bands"));
    const ProbeGrid g = randomGrid(bands, 300 + uint32_t(bands));
    rs.setProbes(g);
    const sh::ShRgb l = randomLight(bands, 50);
    ProbeLighting pl = probeLighting(g, l);
    pl.perVertex = true;
    Frame fs;
    fs.camera = cam;
    fs.light = l;
    fs.width = w;
    fs.height = h;
    fs.probeLookup = ProbeLookup::PerVertex;
    const Comparison cs = compare(rs.render(fs), s, cam, l, &pl);
    std::printf("  random grid, %d bands: %d receiver pixels (%d skipped), max error %.3g\n", bands, cs.receiver,
                cs.ambiguous, cs.maxReceiverError);
    EXPECT_GT(cs.receiver, 1000);
    EXPECT_LT(cs.maxReceiverError, kReceiverTolerance) << "mean " << cs.meanReceiverError;
  }
}

// A receiver moved by a glTF animation (translation LINEAR, scale STEP: the normals change
// with the non-uniform scale): each frame matches the oracle at the animated position, and
// the frames differ.
TEST(RenderReceivers, MovingReceiverFollowsItsAnimation) {
  const BakedRoom& room = bakedRoom();
  Scene s = room.scene;
  const glm::dvec3 rest(0.15, 0.45, 0.05);
  Node node;
  node.name = "ball";
  node.translation = rest;
  s.nodes.push_back(node);
  for (MeshInstance& m : s.meshes)
    if (m.receiverOnly) {
      m.node = 0;
      m.world = glm::translate(glm::dmat4(1.0), rest);
    }
  AnimationChannel move;
  move.node = 0;
  move.path = AnimationPath::Translation;
  move.times = {0.0, 2.0};
  move.values = {glm::dvec4(-0.3, 0.4, -0.2, 0.0), glm::dvec4(0.4, 0.7, 0.2, 0.0)};
  AnimationChannel squash;
  squash.node = 0;
  squash.path = AnimationPath::Scale;
  squash.interpolation = Interpolation::Step;
  squash.times = {0.0, 1.0};
  squash.values = {glm::dvec4(1.0, 1.0, 1.0, 0.0), glm::dvec4(1.2, 0.6, 0.9, 0.0)};
  s.animations.push_back(Animation{"move", {move, squash}});

  const sh::ShRgb light = skyLight(3);
  const int w = 80, h = 60;
  GlContext ctx(GlBackend::Egl, w, h, surfaceless());
  Renderer r(ctx, s);
  r.setProbes(room.grid);
  std::vector<ImageRgb> frames;
  for (double time : {0.0, 1.5}) {
    SCOPED_TRACE(cat("t = ", time));
    Frame f;
    f.camera = roomCamera();
    f.light = light;
    f.time = time;
    f.width = w;
    f.height = h;
    frames.push_back(r.render(f));
    const ProbeLighting pl = probeLighting(room.grid, light, time);
    const Comparison c = compare(frames.back(), s, f.camera, light, &pl);
    EXPECT_GT(c.receiver, 200);
    EXPECT_LT(c.maxReceiverError, kReceiverTolerance);
    EXPECT_LT(c.maxError, std::max(shadingTolerance(ctx), kReceiverTolerance));
    EXPECT_GT(r.lastFrame().lightMs, 0.0);
  }
  EXPECT_GT(maxDifference(frames[0], frames[1]), 0.05);
}

// The command line: `prt render --probes --fps` on the demo scene written as a baked file, with a
// probe grid file. Without --probes: one warning and the receiver is not drawn.
using test::runPrt;
using test::RunResult;

TEST(CliRender, ProbesLightTheMovingReceiver) {
  const test::TempDir tmp("render_cmd");
  const std::filesystem::path& dir = tmp.path();
  const std::string input = test::sourcePath("scenes/cornell_open.gltf");
  const std::string baked = (dir / "c.glb").string(), probes = (dir / "p.vdb").string();
  writeBakedScene(input, unshadowedCornell(input, 3), nullptr, baked);
  writeProbeGrid(test::identityProbeGrid(3, glm::ivec3(5), glm::dvec3(-1.0, 0.0, -1.0), glm::dvec3(0.5)), probes);
  const Scene file = loadScene(baked);
  ASSERT_EQ(file.animations.size(), 1u);  // the receiver's path survives the baked file
  ASSERT_GT(animationDuration(file), 2.0);

  const std::vector<std::string> common = {"render", baked,  "--env", test::sourcePath("scenes/env/white_sky_64.hdr"),
                                           "--size", "64x36"};
  const RunResult none = runPrt(test::plus(common, {"--frames", "0-0", "-o", (dir / "n_%02d.exr").string()}));
  EXPECT_EQ(none.status, 0) << none.err;
  size_t warnings = 0;
  for (size_t p = none.err.find("warning"); p != std::string::npos; p = none.err.find("warning", p + 1)) ++warnings;
  EXPECT_EQ(warnings, 1u) << none.err;
  EXPECT_NE(none.err.find("receiver instance ('Receiver"), std::string::npos) << none.err;

  // --fps 0.5: frame 1 is at t = 2 s, where the receiver has moved up and right.
  const RunResult lit = runPrt(
      test::plus(common, {"--probes", probes, "--fps", "0.5", "--frames", "0-1", "-o", (dir / "f_%02d.exr").string()}));
  EXPECT_EQ(lit.status, 0) << lit.err;
  EXPECT_EQ(lit.err.find("warning"), std::string::npos) << lit.err;
  const ImageRgb unlit = loadHdrImage((dir / "n_00.exr").string());
  const ImageRgb f0 = loadHdrImage((dir / "f_00.exr").string());
  const ImageRgb f1 = loadHdrImage((dir / "f_01.exr").string());
  EXPECT_GT(maxDifference(f0, unlit), 0.1);  // the receiver is drawn
  EXPECT_GT(maxDifference(f0, f1), 0.1);     // and moves

  const RunResult bad = runPrt(test::plus(common, {"--fps", "0", "-o", (dir / "b_%02d.exr").string()}));
  EXPECT_EQ(bad.status, 2);
  EXPECT_NE(bad.err.find("--fps"), std::string::npos) << bad.err;
  EXPECT_EQ(std::count(bad.err.begin(), bad.err.end(), '\n'), 1) << bad.err;
}

}  // namespace
}  // namespace prt::render
