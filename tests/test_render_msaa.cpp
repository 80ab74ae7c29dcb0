// Multisample anti-aliasing (Frame::samples, prt render --msaa): a pixel is the mean of its
// samples, pixels that one surface covers entirely are unchanged, and the image's total is the
// surface's projected area (computed here from the camera, not from GL).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "prt/render/gl_context.h"
#include "prt/render/renderer.h"
#include "prt/scene.h"
#include "test_util.h"

namespace prt::render {
namespace {

constexpr int kW = 80, kH = 60;

// A quad of constant radiance c: one coefficient of transfer (1 at every vertex), white albedo.
// Its corners at z = -3 in front of a camera at the origin looking down -Z.
const glm::vec3 kCorners[4] = {{-0.9f, -0.55f, -3.0f}, {1.1f, -0.7f, -3.0f}, {0.8f, 0.9f, -3.0f}, {-1.0f, 0.6f, -3.0f}};

Scene constantQuad() {
  Scene s;
  s.path = "constant-quad";
  MeshInstance m;
  m.name = "quad";
  m.positions.assign(std::begin(kCorners), std::end(kCorners));
  m.normals.assign(4, glm::vec3(0, 0, 1));
  m.indices = {0, 1, 2, 0, 2, 3};
  m.transfer.assign(4, glm::vec3(1.0f));
  s.meshes.push_back(m);
  s.transferBands = 1;
  s.boundsMin = glm::vec3(-1.0f, -0.7f, -3.0f);
  s.boundsMax = glm::vec3(1.1f, 0.9f, -3.0f);
  return s;
}

CameraView camera() {
  CameraView c;
  c.yfov = glm::radians(50.0);
  c.znear = 0.1;
  return c;
}

// The quad's area in pixels: its corners projected with the camera's definition, shoelace.
double projectedArea(const CameraView& c) {
  const double t = std::tan(0.5 * c.yfov), aspect = double(kW) / kH;
  glm::dvec2 p[4];
  for (int i = 0; i < 4; ++i) {
    const glm::dvec3 v(kCorners[i]);
    const double sx = v.x / -v.z / (t * aspect), sy = v.y / -v.z / t;  // in [-1, 1]
    p[i] = glm::dvec2((sx + 1.0) * 0.5 * kW, (sy + 1.0) * 0.5 * kH);
  }
  double a = 0.0;
  for (int i = 0; i < 4; ++i) a += p[i].x * p[(i + 1) % 4].y - p[(i + 1) % 4].x * p[i].y;
  return 0.5 * std::abs(a);
}

TEST(RenderMsaa, PixelsAreTheMeanOfTheirSamples) {
  const Scene s = constantQuad();
  sh::ShRgb light(1);
  light.c[0] = glm::vec3(2.0f, 3.0f, 4.0f);
  for (GlBackend backend : {GlBackend::OSMesa, GlBackend::Egl}) {
    GlContext ctx(backend, kW, kH);
    Renderer r(ctx, s);
    Frame f;
    f.camera = camera();
    f.light = light;
    const ImageRgb one = r.render(f);
    const glm::vec3 c = one.at(kW / 2, kH / 2);  // the quad's constant radiance
    ASSERT_GT(c.r, 0.0f);
    for (int samples = 2; samples <= ctx.maxSamples(); samples *= 2) {
      f.samples = samples;
      const ImageRgb aa = r.render(f);
      const int n = r.lastFrame().samples;  // the GL may give more (llvmpipe: 4 for 2)
      EXPECT_GE(n, samples);
      int interior = 0, edge = 0, wrong = 0;
      double total = 0.0;
      for (int y = 0; y < kH; ++y)
        for (int x = 0; x < kW; ++x) {
          const glm::vec3 p = aa.at(x, y);
          total += p.r / c.r;
          // Each pixel is k/n of the quad's radiance, in every channel alike.
          const double k = p.r / c.r * n;
          const bool fraction = std::abs(k - std::round(k)) < 1e-4 && std::abs(p.g / c.g * n - k) < 1e-4 &&
                                std::abs(p.b / c.b * n - k) < 1e-4;
          wrong += !fraction;
          EXPECT_TRUE(fraction || wrong > 3) << x << "," << y << ": " << k << " of " << n << " samples";
          edge += std::round(k) > 0 && std::round(k) < n;
          // A pixel whose 3×3 neighbourhood is all quad without multisampling is covered whole.
          bool covered = x > 0 && y > 0 && x + 1 < kW && y + 1 < kH;
          for (int dy = -1; dy <= 1 && covered; ++dy)
            for (int dx = -1; dx <= 1 && covered; ++dx) covered = one.at(x + dx, y + dy) == c;
          if (covered) {
            ++interior;
            EXPECT_EQ(p, c) << x << "," << y;
          }
        }
      const double area = projectedArea(f.camera);
      std::printf(
          "%s, %d samples (%d given): %d interior pixels unchanged, %d edge pixels, total %.2f pixels of quad vs %.2f "
          "projected\n",
          glBackendName(backend), samples, n, interior, edge, total, area);
      EXPECT_EQ(wrong, 0);
      EXPECT_GT(interior, 1000);
      EXPECT_GT(edge, 40);
      // The edges are sampled at `samples` points per pixel: ~one sample's worth per edge pixel.
      EXPECT_NEAR(total, area, 0.02 * area);
    }
  }
}

TEST(RenderMsaa, UnsupportedSampleCountsAreErrors) {
  const Scene s = constantQuad();
  GlContext ctx(GlBackend::OSMesa, 16, 16);
  Renderer r(ctx, s);
  Frame f;
  f.camera = camera();
  f.light = sh::ShRgb(1);
  for (int samples : {0, 3, 2 * ctx.maxSamples()}) {
    f.samples = samples;
    EXPECT_NE(test::errorOf([&] { r.render(f); }).find(cat("render: ", samples, " samples per pixel")),
              std::string::npos)
        << samples;
  }
  f.samples = 1;
  EXPECT_NO_THROW(r.render(f));
}

}  // namespace
}  // namespace prt::render
