// Backgrounds (Frame::background, prt render --background sky): every pixel that no instance
// covers shows RigBackground::radiance along the pixel's centre ray. The rays are traced here in
// double from the camera's definition (docs/render.md, Cameras), not from the renderer's
// matrices; the radiance comes from the rig (sampleEquirect and the caps), which the renderer's
// shader ports to GLSL.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <string>

#include <glm/gtc/matrix_transform.hpp>

#include "prt/light.h"
#include "prt/light_rig.h"
#include "prt/render/gl_context.h"
#include "prt/render/renderer.h"
#include "prt/scene.h"
#include "test_util.h"

namespace prt::render {
namespace {

// Neighbouring texels differ by up to 1.5: a lookup in the wrong place or orientation shows.
ImageRgb randomMap(int width, int height, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.2f, 1.7f);
  ImageRgb m(width, height);
  for (glm::vec3& p : m.pixels) p = glm::vec3(u(rng), u(rng), u(rng));
  return m;
}

// The centre ray of pixel (x, y), row 0 at the top, as docs/render.md defines the cameras.
glm::dvec3 pixelRay(const CameraView& c, int width, int height, int x, int y) {
  const glm::dmat3 rotation(c.cameraToWorld);
  if (!c.perspective) return glm::normalize(rotation * glm::dvec3(0.0, 0.0, -1.0));
  const double t = std::tan(0.5 * c.yfov);
  const glm::dvec3 camera((2.0 * (x + 0.5) / width - 1.0) * t * width / height, (1.0 - 2.0 * (y + 0.5) / height) * t,
                          -1.0);
  return glm::normalize(rotation * camera);
}

// A small baked quad in the middle of the view, so that some pixels are covered.
Scene smallQuad() {
  Scene s;
  s.path = "small-quad";
  MeshInstance m;
  m.name = "quad";
  m.positions = {{-0.5f, -0.35f, -3.0f}, {0.5f, -0.35f, -3.0f}, {0.5f, 0.35f, -3.0f}, {-0.5f, 0.35f, -3.0f}};
  m.normals.assign(4, glm::vec3(0, 0, 1));
  m.indices = {0, 1, 2, 0, 2, 3};
  m.transfer.assign(4 * 4, glm::vec3(0.0f));
  for (size_t v = 0; v < 4; ++v) m.transfer[v * 4] = glm::vec3(1.0f);
  s.meshes.push_back(m);
  s.transferBands = 2;
  s.boundsMin = glm::vec3(-0.5f, -0.35f, -3.0f);
  s.boundsMax = glm::vec3(0.5f, 0.35f, -3.0f);
  return s;
}

// Two maps (one turned about a tilted axis, both scaled), a disk given by its radiance, a
// sun of 6° given by its irradiance, a point sun (not seen) and a uniform fill.
LightRig testRig(const ImageRgb& a, const ImageRgb& b) {
  RigReadOptions o;
  o.maps["a.hdr"] = a;
  o.maps["b.hdr"] = b;
  const std::string json = R"({"version": 1, "window": "hann", "lights": [
    {"type": "environment", "file": "a.hdr", "axis": [0.3, 1, 0.2], "rotation": 40, "intensity": [0.5, 0.7, 1.0]},
    {"type": "environment", "file": "b.hdr", "intensity": 0.25},
    {"type": "disk", "direction": [0.35, 0.15, -1], "radius": 9, "radiance": [3, 2, 1]},
    {"type": "sun", "direction": [-0.3, -0.12, -1], "radius": 6, "irradiance": [2, 1.5, 1]},
    {"type": "sun", "direction": [0, 0, -1], "radius": 0, "irradiance": 5},
    {"type": "uniform", "radiance": 0.1}]})";
  return parseLightRigFromMemory(json, "rig.json", o);
}

struct BackgroundCheck {
  int compared = 0, covered = 0, inCaps = 0;
  double maxError = 0.0;  // absolute, per channel (the maps' texels lie in 0.05..1.7)
};

// Compares every uncovered pixel with the oracle; covered pixels must equal `plain` (the same
// frame without a background). Pixels whose ray lies within 1e-4 (in cosine) of a cap's edge
// are skipped: float and double may put them on either side.
BackgroundCheck check(const ImageRgb& img, const ImageRgb& plain, const CameraView& camera, const RigBackground& bg) {
  BackgroundCheck c;
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x) {
      if (plain.at(x, y) != glm::vec3(0.0f)) {
        ++c.covered;
        EXPECT_EQ(img.at(x, y), plain.at(x, y)) << x << "," << y;
        continue;
      }
      const glm::dvec3 d = pixelRay(camera, img.width, img.height, x, y);
      bool edge = false, inCap = false;
      for (const RigBackground::Cap& cap : bg.caps) {
        const double t = glm::dot(d, cap.direction) - cap.cosRadius;
        edge |= std::abs(t) < 1e-4;
        inCap |= t >= 0.0;
      }
      if (edge) continue;
      c.inCaps += inCap;
      const glm::dvec3 want = bg.radiance(d), got(img.at(x, y));
      const glm::dvec3 e = glm::abs(got - want) / glm::max(glm::dvec3(1.0), want);  // relative inside the suns
      c.maxError = std::max({c.maxError, e.r, e.g, e.b});
      ++c.compared;
    }
  return c;
}

// Float rounding of the ray, the rotation and the texture coordinates (measured: 2.8e-6 on
// llvmpipe): a lookup misplaced by 1e-5 texel changes a pixel by at most 1.5e-5 here, since
// neighbouring texels differ by up to 1.5. GLSL's own acos, 1e-4 rad off, failed this by 100×.
constexpr double kBackgroundTolerance = 2e-5;

TEST(RenderBackground, EveryUncoveredPixelShowsTheLightsAlongItsRay) {
  const ImageRgb a = randomMap(64, 32, 1), b = randomMap(40, 20, 2);
  const LightRig rig = testRig(a, b);
  const RigBackground bg = rig.background(0.0);
  ASSERT_EQ(bg.maps.size(), 2u);
  ASSERT_EQ(bg.caps.size(), 2u);  // the point sun is a delta: not seen
  const Scene s = smallQuad();
  for (GlBackend backend : {GlBackend::OSMesa, GlBackend::Egl}) {
    GlContext ctx(backend, 96, 64);
    Renderer r(ctx, s);
    // Down -Z at the quad, the disks and the suns; down -X across the maps' seam (u = 0 | 1);
    // up +Y at the top rows around the pole.
    const glm::dmat4 views[3] = {glm::dmat4(1.0), glm::rotate(glm::dmat4(1.0), glm::radians(90.0), glm::dvec3(0, 1, 0)),
                                 glm::rotate(glm::dmat4(1.0), glm::radians(80.0), glm::dvec3(1, 0, 0))};
    for (int v = 0; v < 3; ++v) {
      Frame f;
      f.camera.cameraToWorld = views[v];
      f.camera.yfov = glm::radians(70.0);
      f.camera.znear = 0.1;
      f.light = rig.evaluate(0.0, 2);
      const ImageRgb plain = r.render(f);
      f.background = &bg;
      const ImageRgb img = r.render(f);
      const BackgroundCheck c = check(img, plain, f.camera, bg);
      std::printf("%s, view %d: %d background pixels compared (%d in the disks), %d covered, max error %.3g\n",
                  glBackendName(backend), v, c.compared, c.inCaps, c.covered, c.maxError);
      EXPECT_GT(c.compared, 5000);
      if (v == 0) {
        EXPECT_GT(c.inCaps, 200);
        EXPECT_GT(c.covered, 100);
      }
      EXPECT_LT(c.maxError, kBackgroundTolerance);
    }
  }
}

TEST(RenderBackground, AFullTurnOfTheSkyAndAnOrthographicCamera) {
  // The map turned by 360° about a tilted axis shows the first frame again; half a turn does
  // not. An orthographic camera sees one direction: every uncovered pixel is the same.
  const ImageRgb a = randomMap(64, 32, 3);
  RigReadOptions o;
  o.maps["a.hdr"] = a;
  const LightRig rig = parseLightRigFromMemory(
      R"({"version": 1, "lights": [{"type": "environment", "file": "a.hdr", "axis": [1, 2, 0.5],
          "rotation": [{"frame": 0, "value": 0}, {"frame": 2, "value": 360}]}]})",
      "turn.json", o);
  const Scene s = smallQuad();
  GlContext ctx(GlBackend::OSMesa, 64, 48);
  Renderer r(ctx, s);
  Frame f;
  f.camera.yfov = glm::radians(90.0);
  f.light = rig.evaluate(0.0, 2);
  const RigBackground b0 = rig.background(0.0), b1 = rig.background(1.0), b2 = rig.background(2.0);
  f.background = &b0;
  const ImageRgb i0 = r.render(f);
  f.background = &b1;
  const ImageRgb i1 = r.render(f);
  f.background = &b2;
  const ImageRgb i2 = r.render(f);
  double full = 0.0, half = 0.0;
  for (size_t k = 0; k < i0.pixels.size(); ++k) {
    full = std::max<double>(full, glm::length(i2.pixels[k] - i0.pixels[k]));
    half = std::max<double>(half, glm::length(i1.pixels[k] - i0.pixels[k]));
  }
  EXPECT_LT(full, 1e-5);
  EXPECT_GT(half, 0.1);

  f.camera.perspective = false;
  f.camera.ymag = 1.0;
  f.background = nullptr;
  const ImageRgb orthoPlain = r.render(f);
  f.background = &b1;
  const ImageRgb ortho = r.render(f);
  const glm::dvec3 want = b1.radiance(pixelRay(f.camera, 64, 48, 0, 0));
  int uncovered = 0;
  for (size_t k = 0; k < ortho.pixels.size(); ++k) {
    if (orthoPlain.pixels[k] != glm::vec3(0.0f)) continue;  // the quad
    const glm::vec3 p = ortho.pixels[k];
    ++uncovered;
    EXPECT_NEAR(p.r, want.r, kBackgroundTolerance);
    EXPECT_NEAR(p.g, want.g, kBackgroundTolerance);
    EXPECT_NEAR(p.b, want.b, kBackgroundTolerance);
  }
  EXPECT_GT(uncovered, 64 * 48 / 2);
}

TEST(RenderBackground, TooManyMapsIsAnError) {
  RigBackground bg;
  const auto image = std::make_shared<ImageRgb>(randomMap(8, 4, 4));
  for (int i = 0; i <= kMaxBackgroundMaps; ++i) bg.maps.push_back({image, glm::dmat3(1.0), glm::dvec3(1.0)});
  const Scene s = smallQuad();
  GlContext ctx(GlBackend::OSMesa, 16, 16);
  Renderer r(ctx, s);
  Frame f;
  f.background = &bg;
  EXPECT_EQ(
      test::errorOf([&] { r.render(f); }),
      cat("background: ", kMaxBackgroundMaps + 1, " environment maps, at most ", kMaxBackgroundMaps, " can be drawn"));
}

}  // namespace
}  // namespace prt::render
