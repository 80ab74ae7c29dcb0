// Lights inside the scene in the renderer (docs/render.md, "Lights inside the scene"): a floor
// under a slab, lit only by a point, a spot, a sphere, a disk or a rectangle light (the SH light
// zero), rendered per pixel with the lights' cube shadow maps and checked at pixel centres
// against probes/lights' localIrradiance (the closed form) times the visibility of the light's
// centre traced with Embree: ρ/π · E(x, n) where the centre is seen, 0 in the umbra. Pixels near a
// shadow's edge (the penumbra of an area light, the filter's 1.5 texels of a point light) are
// left out: every pixel whose 5 × 5 neighbourhood does not agree on the centre's visibility.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include <gtest/gtest.h>
#include <glm/gtc/matrix_transform.hpp>

#include "prt/bake/ray_scene.h"
#include "prt/local_light.h"
#include "prt/render/gl_context.h"
#include "prt/render/renderer.h"
#include "prt/scene.h"
#include "test_scenes.h"

namespace prt::render {
namespace {

constexpr double kInvPi = 0.31830988618379067;
constexpr int kW = 96, kH = 72;

using test::makeQuad;

// A 4 m floor and a 0.8 m square slab 0.5 m above it (facing up), albedo 0.8, baked
// with a transfer of zeros except its direct part (so that the renderer lights per pixel).
Scene floorAndSlab() {
  Scene s;
  s.path = "floor";
  Material grey;
  grey.baseColorFactor = glm::vec4(0.8f, 0.8f, 0.8f, 1.0f);
  grey.doubleSided = false;
  s.materials = {grey};
  s.meshes.push_back(makeQuad("floor", {-2.0f, 0.0f, 2.0f}, {4.0f, 0.0f, 0.0f}, {0.0f, 0.0f, -4.0f}, 8, 8));
  s.meshes.push_back(makeQuad("slab", {-0.4f, 0.5f, 0.4f}, {0.8f, 0.0f, 0.0f}, {0.0f, 0.0f, -0.8f}, 1, 1));
  for (MeshInstance& m : s.meshes) {
    m.material = 0;
    m.transfer.assign(m.vertexCount() * 9, glm::vec3(0.0f));
    m.transferDirect.assign(m.vertexCount() * 9, 0.0f);
  }
  s.transferBands = 3;
  s.boundsMin = glm::vec3(-2.0f, 0.0f, -2.0f);
  s.boundsMax = glm::vec3(2.0f, 0.5f, 2.0f);
  return s;
}

struct Hit {
  bool hit = false;
  uint32_t mesh = 0;
  glm::dvec3 x{0.0}, n{0.0};
  bool lit = false;  // the light's centre seen from x
};

// The pixel centre's ray (test_render.cpp's camera model) and the centre's visibility.
Hit trace(const bake::RayScene& rays, const Scene& s, const CameraView& c, int px, int py, const glm::dvec3& centre) {
  const double aspect = double(kW) / kH, t = std::tan(0.5 * c.yfov);
  const double sx = 2.0 * (px + 0.5) / kW - 1.0, sy = 1.0 - 2.0 * (py + 0.5) / kH;
  const glm::dvec3 dir = glm::normalize(glm::dvec3(c.cameraToWorld * glm::dvec4(sx * t * aspect, sy * t, -1.0, 0.0)));
  bake::Ray r;
  r.org = glm::vec3(glm::dvec3(c.cameraToWorld[3]));
  r.dir = glm::vec3(dir);
  r.tnear = 0.0f;
  r.tfar = 1e30f;
  rays.intersect(&r, 1, false);
  Hit h;
  if (!r.hit()) return h;
  h.hit = true;
  h.mesh = r.mesh;
  h.x = glm::dvec3(r.org) + double(r.tfar) * dir;
  h.n = glm::dvec3(s.meshes[r.mesh].normals[0]);
  const glm::dvec3 to = centre - h.x;
  bake::Ray sr;
  sr.org = glm::vec3(h.x + 1e-4 * h.n);
  sr.dir = glm::vec3(glm::normalize(to));
  sr.tnear = 0.0f;
  sr.tfar = float(glm::length(to) * (1.0 - 1e-4));
  rays.occluded(&sr, 1, false);
  h.lit = !sr.occludedHit();
  return h;
}

struct Result {
  int compared = 0, shadowed = 0;
  double maxError = 0.0;  // relative to the largest expected value
};

Result renderAndCompare(const LocalLight& light) {
  const Scene s = floorAndSlab();
  CameraView cam;
  cam.cameraToWorld = glm::inverse(glm::lookAt(glm::dvec3(0, 3.2, 2.6), glm::dvec3(0, 0, 0), glm::dvec3(0, 1, 0)));
  cam.yfov = glm::radians(55.0);
  cam.znear = 0.05;
  GlContext ctx(GlBackend::OSMesa, kW, kH);
  Renderer r(ctx, s);
  Frame f;
  f.camera = cam;
  f.light = sh::ShRgb(3);
  f.local = {light};
  const ImageRgb img = r.render(f);
  EXPECT_EQ(r.lastFrame().localLights, 1u);
  EXPECT_EQ(r.lastFrame().localShadowMaps, 6);
  const bake::RayScene rays(s);
  std::vector<Hit> hits(size_t(kW) * kH);
  for (int py = 0; py < kH; ++py)
    for (int px = 0; px < kW; ++px) hits[size_t(py) * kW + px] = trace(rays, s, cam, px, py, light.position);
  std::vector<glm::dvec3> want(hits.size(), glm::dvec3(0.0));
  double peak = 0.0;
  for (size_t i = 0; i < hits.size(); ++i)
    if (hits[i].hit) {
      want[i] = 0.8 * kInvPi * localIrradiance(light, hits[i].x, hits[i].n) * (hits[i].lit ? 1.0 : 0.0);
      peak = std::max({peak, want[i].x, want[i].y, want[i].z});
    }
  Result res;
  for (int py = 2; py + 2 < kH; ++py)
    for (int px = 2; px + 2 < kW; ++px) {
      const Hit& c = hits[size_t(py) * kW + px];
      if (!c.hit) continue;
      bool away = true;
      for (int dy = -2; dy <= 2 && away; ++dy)
        for (int dx = -2; dx <= 2 && away; ++dx) {
          const Hit& q = hits[size_t(py + dy) * kW + px + dx];
          away = q.hit && q.mesh == c.mesh && q.lit == c.lit;
        }
      if (!away) continue;
      const glm::dvec3 e = glm::abs(glm::dvec3(img.at(px, py)) - want[size_t(py) * kW + px]) / peak;
      res.maxError = std::max({res.maxError, e.x, e.y, e.z});
      ++res.compared;
      res.shadowed += c.lit ? 0 : 1;
    }
  return res;
}

LocalLight lightAbove(LocalLight::Type type) {
  LocalLight l;
  l.type = type;
  l.label = "test light";
  l.position = glm::dvec3(0.25, 1.3, 0.1);
  l.direction = glm::dvec3(0.0, -1.0, 0.0);
  l.up = glm::dvec3(0.0, 0.0, 1.0);
  l.intensity = glm::dvec3(2.0, 1.5, 1.0);
  l.radiance = glm::dvec3(8.0, 6.0, 4.0);
  l.innerCone = 0.3;
  l.outerCone = 0.7;
  l.radius = 0.05;
  l.width = 0.1;
  l.height = 0.06;
  return l;
}

// Away from the shadow's edges a pixel is the closed form times the centre's visibility: within
// 1% of the peak (measured: below 10⁻⁴ for every type; float arithmetic, the 32-gon disk against
// the 128-gon, and an area light's umbra, which at these sizes
// (≤ 0.1 m at 0.8 m above the slab) is where its centre is hidden but for a sliver of the
// filter's 1.5 texels at the rim, counted as edge by the 5 × 5 neighbourhood). Some pixels must
// be in the slab's shadow, so that a light that ignored its maps fails.
TEST(RenderLocalLights, MatchTheClosedFormTimesTheCentresVisibility) {
  for (LocalLight::Type type : {LocalLight::Type::Point, LocalLight::Type::Spot, LocalLight::Type::Sphere,
                                LocalLight::Type::Disk, LocalLight::Type::Rectangle}) {
    SCOPED_TRACE(localLightTypeName(type));
    const Result r = renderAndCompare(lightAbove(type));
    std::printf("%s: %d pixels compared, %d in the umbra, largest error %.4f of the peak\n", localLightTypeName(type),
                r.compared, r.shadowed, r.maxError);
    EXPECT_GT(r.compared, kW * kH / 3);
    EXPECT_GT(r.shadowed, 50);  // 80 at this size
    EXPECT_LT(r.maxError, 0.01);
  }
}

// Without shadow maps (Frame::shadows.enabled false) the slab casts nothing: the umbra's pixels
// get the closed form, so the comparison above fails there (the test's teeth).
TEST(RenderLocalLights, WithoutMapsTheUmbraIsLit) {
  const Scene s = floorAndSlab();
  CameraView cam;
  cam.cameraToWorld = glm::inverse(glm::lookAt(glm::dvec3(0, 3.2, 2.6), glm::dvec3(0, 0, 0), glm::dvec3(0, 1, 0)));
  cam.yfov = glm::radians(55.0);
  GlContext ctx(GlBackend::OSMesa, kW, kH);
  Renderer r(ctx, s);
  Frame f;
  f.camera = cam;
  f.light = sh::ShRgb(3);
  f.local = {lightAbove(LocalLight::Type::Point)};
  f.shadows.enabled = false;
  const ImageRgb unshadowed = r.render(f);
  f.shadows.enabled = true;
  const ImageRgb shadowed = r.render(f);
  // The floor straight under the slab, seen past it: the centre of the image's lower part is the
  // slab's top; look for pixels that differ by more than half their unshadowed value.
  int darker = 0;
  for (int py = 0; py < kH; ++py)
    for (int px = 0; px < kW; ++px) darker += shadowed.at(px, py).g < 0.5f * unshadowed.at(px, py).g ? 1 : 0;
  EXPECT_GT(darker, 100);
}

}  // namespace
}  // namespace prt::render
