// render/: headless contexts, and frames checked against a CPU evaluation of the same formula
// at pixel centres (STYLE.md: renders are checked against the formula before any golden).
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <optional>
#include <random>

#include <glm/gtc/matrix_transform.hpp>
#include <gtest/gtest.h>

#include <unistd.h>

#include "prt/error.h"
#include "prt/render/gl_context.h"
#include "prt/render/renderer.h"

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
  m.transferBands = bands;
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
  m.colors = {{1.0f, 0.5f, 0.25f, 1.0f}, {0.2f, 1.0f, 0.6f, 1.0f}, {0.9f, 0.9f, 0.1f, 1.0f},
              {0.4f, 0.3f, 1.0f, 1.0f}};
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
};

Hit oracle(const Scene& s, const CameraView& c, const sh::ShRgb& light, int width, int height,
           int px, int py) {
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
  for (const MeshInstance& m : s.meshes) {
    if (m.transferBands == 0) continue;
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
      glm::dvec3 e(0.0), color(1.0);
      glm::vec2 uv(0.0f);
      if (!m.colors.empty()) color = glm::dvec3(0.0);
      for (int k = 0; k < 3; ++k) {
        e += b[k] * glm::dvec3(sh::dot(m.transferOf(v[k]), light.c.data(), light.size()));
        if (!m.colors.empty()) color += b[k] * glm::dvec3(m.colors[v[k]]);
        if (!m.texcoords.empty()) uv += float(b[k]) * m.texcoords[v[k]];
      }
      glm::dvec3 albedo = glm::dvec3(mat.baseColorFactor) * color;
      // Texture::sample is the project's bilinear lookup (texel centres at (i + ½)/size, glTF
      // wrap modes), the one the bake uses for albedo: GL_LINEAR must agree with it.
      if (mat.baseColorTexture >= 0 && !m.texcoords.empty())
        albedo *= glm::dvec3(s.textures[size_t(mat.baseColorTexture)].sample(uv));
      bestT = t;
      best.hit = true;
      best.radiance = albedo * kInvPi * e;
    }
  }
  return best;
}

struct Comparison {
  int compared = 0;
  int background = 0;
  double maxError = 0.0;  // relative to the image's largest oracle value
  double maxBackground = 0.0;
};

// Compares pixels whose 3×3 neighbourhood lies wholly inside or wholly outside the geometry in
// the oracle: at silhouettes, coverage of a pixel whose centre is within a subpixel step of an
// edge legitimately depends on the rasterizer's snapping, which the oracle does not model.
Comparison compare(const ImageRgb& image, const Scene& s, const CameraView& c, const sh::ShRgb& light) {
  const int w = image.width, h = image.height;
  std::vector<Hit> ref(size_t(w) * h);
  double scale = 0.0;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      ref[size_t(y) * w + x] = oracle(s, c, light, w, h, x, y);
      const glm::dvec3 r = glm::abs(ref[size_t(y) * w + x].radiance);
      scale = std::max({scale, r.x, r.y, r.z});
    }
  Comparison out;
  for (int y = 1; y + 1 < h; ++y)
    for (int x = 1; x + 1 < w; ++x) {
      const bool hit = ref[size_t(y) * w + x].hit;
      bool uniform = true;
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) uniform &= ref[size_t(y + dy) * w + x + dx].hit == hit;
      if (!uniform) continue;
      const glm::dvec3 got(image.at(x, y));
      if (hit) {
        const glm::dvec3 d = glm::abs(got - ref[size_t(y) * w + x].radiance) / scale;
        out.maxError = std::max({out.maxError, d.x, d.y, d.z});
        ++out.compared;
      } else {
        const glm::dvec3 a = glm::abs(got);
        out.maxBackground = std::max({out.maxBackground, a.x, a.y, a.z});
        ++out.background;
      }
    }
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
double shadingTolerance(const GlContext& c) {
  return c.renderer().find("llvmpipe") != std::string::npos ? 1e-5 : 1e-3;
}
double textureTolerance(const GlContext& c) {
  return c.renderer().find("llvmpipe") != std::string::npos ? 1e-5 : 4e-3;
}

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
  const std::string cmd =
      "__EGL_VENDOR_LIBRARY_FILENAMES=/nonexistent.json PRT_RENDER_TEST_CHILD=1 /proc/" +
      std::to_string(::getpid()) + "/exe --gtest_also_run_disabled_tests --gtest_filter=RenderContext.DISABLED_EglFailureChild 2>&1";
  std::FILE* p = ::popen(cmd.c_str(), "r");
  ASSERT_NE(p, nullptr);
  std::string out;
  char buf[256];
  while (std::fgets(buf, sizeof buf, p)) out += buf;
  const int status = ::pclose(p);
  EXPECT_EQ(status, 0) << out;
  EXPECT_NE(out.find("[  PASSED  ] 1 test"), std::string::npos) << out;
}

TEST(RenderContext, RejectsBadFrameSize) {
  EXPECT_THROW(GlContext(GlBackend::OSMesa, 0, 10), Error);
}

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
      EXPECT_LT(compare(r.render(frontCamera(), light), s, frontCamera(), light).maxError,
                shadingTolerance(ctx));
  }
}

TEST(RenderShading, LightOfFewerBandsIsZeroPadded) {
  const Scene s = tiltedQuad(3);
  const sh::ShRgb light1 = randomLight(1, 3);
  GlContext ctx(GlBackend::OSMesa, kWidth, kHeight);
  Renderer r(ctx, s);
  const sh::ShRgb padded = sh::resize(light1, 3);
  EXPECT_LT(compare(r.render(frontCamera(), light1), s, frontCamera(), padded).maxError,
            shadingTolerance(ctx));
}

TEST(RenderShading, TexturedQuadAlbedoPerPixel) {
  // A 4×3 texture with distinct texels over a quad facing the camera, transfer·light = π
  // everywhere, so each pixel shows albedo = factor × bilinear texture lookup exactly.
  Scene s;
  s.path = "textured-quad";
  Texture t;
  t.name = "checker";
  t.width = 4;
  t.height = 3;
  for (int y = 0; y < t.height; ++y)
    for (int x = 0; x < t.width; ++x)
      t.texels.push_back(glm::vec4(0.1f + 0.25f * x, 0.15f + 0.4f * y, ((x + y) & 1) ? 0.9f : 0.05f, 1));
  s.textures.push_back(t);
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
  m.transferBands = 1;
  m.transfer.assign(4, glm::vec3(float(M_PI / 0.2820947917738781)));
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

TEST(RenderShading, ReceiversSkippedWithWarning) {
  Scene s = tiltedQuad(2);
  MeshInstance receiver = s.meshes[0];
  receiver.name = "mover";
  receiver.receiverOnly = true;
  receiver.transferBands = 0;
  receiver.transfer.clear();
  for (glm::vec3& p : receiver.positions) p.z += 1.0f;  // in front: would hide the quad if drawn
  s.meshes.push_back(receiver);
  GlContext ctx(GlBackend::OSMesa, kWidth, kHeight);
  Renderer r(ctx, s);
  ASSERT_EQ(r.warnings().size(), 1u);
  EXPECT_NE(r.warnings()[0].find("mover"), std::string::npos);
  const sh::ShRgb light = randomLight(2, 1);
  EXPECT_LT(compare(r.render(frontCamera(), light), s, frontCamera(), light).maxError,
            shadingTolerance(ctx));
}

TEST(RenderShading, SceneWithoutTransferIsAnError) {
  Scene s = tiltedQuad(2);
  s.transferBands = 0;
  GlContext ctx(GlBackend::OSMesa, kWidth, kHeight);
  EXPECT_THROW(Renderer(ctx, s), Error);
  s = tiltedQuad(2);
  s.meshes[0].receiverOnly = true;
  EXPECT_THROW(Renderer(ctx, s), Error);  // nothing left to draw
}

TEST(RenderShading, BakedFileOfTheDemoSceneMatchesOracle) {
  // The path bake → file → render: the Cornell scene with unshadowed diffuse transfer
  // (t_i = Â_l y_i(N), so t · l is the irradiance of the light at the vertex normal) written as
  // a baked .glb, loaded back and seen through the scene's own camera. Checks that world
  // transforms, materials and the baked attributes reach the renderer as the loader means them.
  const std::string input = std::string(PRT_SOURCE_DIR) + "/scenes/cornell_open.gltf";
  Scene scene = loadScene(input);
  ASSERT_FALSE(scene.cameras.empty());
  const int bands = 3;
  for (MeshInstance& m : scene.meshes) {
    if (m.receiverOnly) continue;
    m.transferBands = bands;
    m.transfer.clear();
    for (const glm::vec3& n : m.normals) {
      float y[bands * bands];
      sh::evaluate(bands, n, y);
      for (int i = 0; i < bands * bands; ++i)
        m.transfer.push_back(glm::vec3(float(sh::clampedCosineFactor(sh::bandOf(i))) * y[i]));
    }
  }
  scene.transferBands = bands;
  const std::filesystem::path out =
      std::filesystem::temp_directory_path() / cat("prt_test_render_", ::getpid(), ".glb");
  writeBakedScene(input, scene, "{}", out.string());
  const Scene baked = loadScene(out.string());
  std::filesystem::remove(out);
  ASSERT_EQ(baked.transferBands, bands);

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

}  // namespace
}  // namespace prt::render
