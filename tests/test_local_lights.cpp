// Lights inside the scene (prt/local_light.h, prt/bake/local_lights.h): a point light over a
// plane (I·cosθ/r², 0 behind it, the range window), the spot's falloff against the
// KHR_lights_punctual reference code, disk, rectangle and sphere lights against their form
// factors' closed forms, a closed white box lit by a lamp against the bounce series' sum
// (through the traced gather and through the bounce operator), rig and glTF errors, and
// determinism.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <memory>

#include "baked_scene.h"
#include "harness.h"
#include "prt/animation.h"
#include "prt/bake/bounce_operator.h"
#include "prt/bake/frame_lighting.h"
#include "prt/bake/local_lights.h"
#include "prt/bake/surface_bake.h"
#include "prt/light_rig.h"
#include "prt/local_light.h"
#include "prt/math.h"
#include "test_scenes.h"

namespace prt {
namespace {

using glm::dvec3;

LocalLight pointLight(const dvec3& p, const dvec3& intensity) {
  LocalLight l;
  l.type = LocalLight::Type::Point;
  l.position = p;
  l.intensity = intensity;
  return l;
}

// A plane at y = 0 facing +Y, baked without bounces so it counts as baked (transfer present).
Scene bakedPlane() {
  Scene s = test::makeScene({test::makePlane({0, 0, 0}, 2.0f, 8)}, 0.5f);
  bake::BakeSettings bs;
  bs.samples = 16;
  bs.bounces = 0;
  bake::SurfaceTransfer t = bake::bakeSurface(s, bs);
  bake::storeTransfer(s, std::move(t.perMesh), std::move(t.perMeshDirect));
  s.transferBands = 3;
  return s;
}

// A point light over a plane: I cos θ / r² at every vertex (nothing occludes it), times the
// range window where a range is given, and 0 once the light is below the plane. Float rounding
// only: 1e-5 relative.
TEST(BakeLocalLight, PointOverAPlaneIsInverseSquareCosine) {
  const Scene s = bakedPlane();
  const bake::RayScene rays(s);
  const dvec3 I(2.0, 1.0, 0.5);
  for (double range : {0.0, 1.6}) {
    LocalLight l = pointLight({0.3, 0.9, -0.2}, I);
    l.range = range;
    const bake::DirectIrradiance d = bake::shadowedLocalIrradiance(s, rays, {l});
    int windowed = 0;
    for (size_t v = 0; v < s.meshes[0].vertexCount(); ++v) {
      const dvec3 toL = l.position - dvec3(s.meshes[0].positions[v]);
      const double r = glm::length(toL), cosT = toL.y / r;
      const double q = range > 0.0 ? r / range : 0.0;
      const double window = std::clamp(1.0 - q * q * q * q, 0.0, 1.0);
      windowed += window < 1.0;
      for (int c = 0; c < 3; ++c)
        ASSERT_NEAR(d.front[0][v][c], I[c] * cosT / (r * r) * window, 1e-5 * I[c]) << "vertex " << v;
    }
    if (range > 0.0) {
      EXPECT_GT(windowed, 10);
    }  // the window is exercised, to 0 beyond the range
  }
  const bake::DirectIrradiance below = bake::shadowedLocalIrradiance(s, rays, {pointLight({0.1, -0.5, 0}, I)});
  for (const glm::vec3& e : below.front[0]) ASSERT_EQ(e, glm::vec3(0.0f));
}

// The spot's falloff between its cones against KHR_lights_punctual's reference code, written
// out here in float as the extension gives it; 1 inside the inner cone, 0 outside the outer.
TEST(LightLocal, SpotFalloffMatchesTheReferenceCode) {
  LocalLight spot;
  spot.type = LocalLight::Type::Spot;
  spot.direction = {0, -1, 0};
  spot.innerCone = glm::radians(20.0);
  spot.outerCone = glm::radians(35.0);
  const float scale = 1.0f / std::max(0.001f, float(std::cos(spot.innerCone) - std::cos(spot.outerCone)));
  const float offset = -float(std::cos(spot.outerCone)) * scale;
  int between = 0;
  for (double deg = 0.0; deg <= 60.0; deg += 0.5) {
    const double a = glm::radians(deg);
    const dvec3 w(std::sin(a), -std::cos(a), 0.0);
    const float cd = float(glm::dot(spot.direction, w));
    float ref = std::clamp(cd * scale + offset, 0.0f, 1.0f);
    ref *= ref;
    EXPECT_NEAR(spotFalloff(spot, w), ref, 2e-6) << deg << " degrees";
    if (deg <= 20.0) {
      EXPECT_NEAR(spotFalloff(spot, w), 1.0, 1e-12);
    }
    if (deg >= 35.0) {
      EXPECT_EQ(spotFalloff(spot, w), 0.0);
    }
    between += deg > 20.0 && deg < 35.0;
  }
  EXPECT_GT(between, 20);
  // Through the shadow rays: a spot over the plane lights each vertex with I cos θ / r² · falloff.
  const Scene s = bakedPlane();
  spot.position = {0.0, 1.0, 0.0};
  spot.intensity = dvec3(3.0);
  const bake::DirectIrradiance d = bake::shadowedLocalIrradiance(s, bake::RayScene(s), {spot});
  int partial = 0;
  for (size_t v = 0; v < s.meshes[0].vertexCount(); ++v) {
    const dvec3 toL = spot.position - dvec3(s.meshes[0].positions[v]);
    const double r = glm::length(toL), f = spotFalloff(spot, -toL / r);
    partial += f > 0.0 && f < 1.0;
    ASSERT_NEAR(d.front[0][v].g, 3.0 * (toL.y / r) / (r * r) * f, 3e-5) << "vertex " << v;
  }
  EXPECT_GT(partial, 4);
}

// Form factor from a point to a parallel disk of radius R at height h, offset a from its axis
// (the closed form for a differential element parallel to a disk).
double diskFormFactor(double R, double h, double a) {
  const double z = a * a + h * h + R * R;
  return 0.5 * (1.0 - (a * a + h * h - R * R) / std::sqrt(z * z - 4.0 * a * a * R * R));
}

// Form factor from a point to a parallel rectangle [0, a] × [0, b] at height c, the point
// under its corner.
double cornerFormFactor(double a, double b, double c) {
  const double A = a / c, B = b / c, sa = std::sqrt(1 + A * A), sb = std::sqrt(1 + B * B);
  return (A / sa * std::atan(B / sa) + B / sb * std::atan(A / sb)) / (2.0 * kPi);
}

// Disk and rectangle lights facing down on a receiver facing up, on axis and off it (light
// arriving obliquely), against E = π L F with F the closed-form form factor; a sphere against
// π L (R/d)². The rectangle is exact to rounding (1e-9); the disk is a 128-gon of the same area,
// measured within 2e-9 of E here, held to 1e-6; a wrong winding, clipping or area scale is off
// by percents.
TEST(LightLocal, AreaLightsMatchTheirFormFactors) {
  const dvec3 n(0, 1, 0), L(1.0, 2.0, 0.5);
  LocalLight disk;
  disk.type = LocalLight::Type::Disk;
  disk.position = {0, 1.5, 0};
  disk.direction = {0, -1, 0};
  disk.radius = 0.4;
  disk.radiance = L;
  for (double a : {0.0, 0.3, 1.0, 2.5}) {
    const double F = diskFormFactor(0.4, 1.5, a);
    const dvec3 e = localIrradiance(disk, {a, 0, 0}, n);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(e[c], kPi * L[c] * F, 1e-6 * kPi * L[c] * F) << "offset " << a;
  }
  LocalLight rect;
  rect.type = LocalLight::Type::Rectangle;
  rect.position = {0, 2, 0};
  rect.direction = {0, -1, 0};
  rect.up = {0, 0, 1};
  rect.width = 1.2;   // along x
  rect.height = 0.8;  // along z
  rect.radiance = L;
  // On axis: four corner rectangles of 0.6 × 0.4.
  const double Faxis = 4.0 * cornerFormFactor(0.6, 0.4, 2.0);
  EXPECT_NEAR(localIrradiance(rect, {0, 0, 0}, n).g, kPi * 2.0 * Faxis, 1e-9);
  // Under a corner, and outside the rectangle (a difference of corner rectangles).
  EXPECT_NEAR(localIrradiance(rect, {0.6, 0, 0.4}, n).r, kPi * cornerFormFactor(1.2, 0.8, 2.0), 1e-9);
  const double Fout = cornerFormFactor(1.6, 0.8, 2.0) - cornerFormFactor(0.4, 0.8, 2.0);
  EXPECT_NEAR(localIrradiance(rect, {1.0, 0, 0.4}, n).r, kPi * Fout, 1e-9);
  // Behind the emitting side: dark.
  EXPECT_EQ(localIrradiance(rect, {0, 3, 0}, -n), dvec3(0.0));
  LocalLight sphere;
  sphere.type = LocalLight::Type::Sphere;
  sphere.position = {0, 2, 0};
  sphere.radius = 0.5;
  sphere.radiance = L;
  EXPECT_NEAR(localIrradiance(sphere, {0, 0, 0}, n).g, kPi * 2.0 * 0.0625, 1e-12);
  // Power: a one-sided rectangle of Φ watts has radiance Φ / (π A).
  EXPECT_NEAR(localLightFromPower(rect, dvec3(10.0)).x, 10.0 / (kPi * 0.96), 1e-12);
}

// An area light over the plane through the shadow rays: unoccluded, the ratio estimator gives
// the closed form exactly (float rounding, 1e-5); and the result is the same bit for bit on 1
// and on 2 threads.
TEST(BakeLocalLight, AreaLightsUnoccludedAreExactAndDeterministic) {
  const Scene s = bakedPlane();
  const bake::RayScene rays(s);
  std::vector<LocalLight> lights(2);
  lights[0].type = LocalLight::Type::Rectangle;
  lights[0].position = {0.2, 0.8, 0.1};
  lights[0].direction = glm::normalize(dvec3(0.3, -1, 0));
  lights[0].up = glm::normalize(glm::cross(lights[0].direction, dvec3(1, 0, 0)));
  lights[0].width = 0.5;
  lights[0].height = 0.3;
  lights[0].radiance = dvec3(4.0);
  lights[1].type = LocalLight::Type::Sphere;
  lights[1].position = {-0.5, 0.6, 0.4};
  lights[1].radius = 0.2;
  lights[1].radiance = dvec3(2.0);
  bake::ShadowSettings one, two;
  one.threads = 1;
  two.threads = 2;
  const bake::DirectIrradiance a = bake::shadowedLocalIrradiance(s, rays, lights, one);
  const bake::DirectIrradiance b = bake::shadowedLocalIrradiance(s, rays, lights, two);
  ASSERT_EQ(a.front[0].size(), b.front[0].size());
  EXPECT_EQ(std::memcmp(a.front[0].data(), b.front[0].data(), a.front[0].size() * sizeof(glm::vec3)), 0);
  for (size_t v = 0; v < s.meshes[0].vertexCount(); ++v) {
    const dvec3 x(s.meshes[0].positions[v]);
    const double e = localIrradiance(lights[0], x, {0, 1, 0}).g + localIrradiance(lights[1], x, {0, 1, 0}).g;
    ASSERT_NEAR(a.front[0][v].g, e, 1e-5 * std::max(1.0, e)) << "vertex " << v;
  }
}

// An emissive quad (two triangles, emissiveFactor × strength) facing down over the plane lights
// it as the rectangle light of the same place, size and radiance: the two triangles' closed
// forms add up to the rectangle's, and the shadow rays stop short of the quad, so nothing
// occludes it (float rounding: 1e-5 relative). Through prt relight's path (sceneLights) too.
TEST(BakeLocalLight, EmissiveQuadMatchesTheRectangleLight) {
  MeshInstance quad = test::makePlane({0.1f, 1.0f, -0.1f}, 0.6f, 1);
  for (glm::vec3& n : quad.normals) n = -n;
  for (size_t t = 0; t < quad.indices.size(); t += 3) std::swap(quad.indices[t + 1], quad.indices[t + 2]);
  quad.name = "panel";
  Scene s = test::makeScene({test::makePlane({0, 0, 0}, 2.0f, 8), quad}, 0.5f);
  Material lamp = s.materials[0];
  lamp.emissiveFactor = {1.0f, 0.5f, 0.25f};
  lamp.emissiveStrength = 4.0f;
  s.materials.push_back(lamp);
  s.meshes[1].material = 1;
  bake::BakeSettings bs;
  bs.samples = 16;
  bs.bounces = 0;
  bake::SurfaceTransfer t = bake::bakeSurface(s, bs);
  bake::storeTransfer(s, std::move(t.perMesh), std::move(t.perMeshDirect));
  s.transferBands = 3;
  const std::vector<LocalLight> emitters = bake::emissiveLightsOf(s);
  ASSERT_EQ(emitters.size(), 1u);
  ASSERT_EQ(emitters[0].emitter->triangles.size(), 2u);
  EXPECT_EQ(emitters[0].emitter->triangles[0].direction, dvec3(0, -1, 0));
  EXPECT_NEAR(emitters[0].emitter->area, 0.36, 1e-6);
  // Its own vertices emit that radiance (what prt relight adds to theirs); the floor none.
  const bake::VertexEmission own = bake::emissionAtVertices(s);
  EXPECT_TRUE(own.front[0].empty());
  ASSERT_EQ(own.front[1].size(), s.meshes[1].vertexCount());
  EXPECT_EQ(own.front[1][0], glm::vec3(4.0f, 2.0f, 1.0f));
  EXPECT_TRUE(own.back[1].empty());  // one-sided
  LocalLight rect;
  rect.type = LocalLight::Type::Rectangle;
  rect.position = {0.1, 1.0, -0.1};
  rect.direction = {0, -1, 0};
  rect.width = rect.height = 0.6;
  rect.radiance = dvec3(4.0, 2.0, 1.0);
  LightRig rig;
  bake::FrameLightingSettings fs;
  fs.directAtVertices = true;
  fs.gatherSamples = 0;
  fs.sceneLights = true;
  bake::FrameLighting lighting(s, rig, fs);
  const bake::FrameLight light = lighting.at(0.0);
  ASSERT_NE(light.vertexLight, nullptr);
  for (size_t v = 0; v < s.meshes[0].vertexCount(); ++v) {
    const dvec3 e = localIrradiance(rect, dvec3(s.meshes[0].positions[v]), {0, 1, 0});
    for (int c = 0; c < 3; ++c)
      ASSERT_NEAR(light.vertexLight->front[0][v][c], e[c], 1e-5 * std::max(1.0, e[c])) << "vertex " << v;
  }
}

// A rectangle light's penumbra across a straight edge: a floor at y = 0 under a slab over x < 0
// (1 <= y <= 1.05), a 1 × 0.6 m rectangle light facing down at y = 2 centred over the edge. The
// shadowed irradiance at floor vertices across the penumbra against a 400 × 400 midpoint
// quadrature over the rectangle with the slab's analytic occlusion. 256 stratified samples
// estimate the visible share to a few 0.1% (measured: worst 0.37%, mean 0.05% of the
// unoccluded value); 1.5% and 0.3% bound that, while weighting the samples by cos θ alone
// (without cos θ' / r²) is off by 2.5% worst and 0.6% mean (measured).
TEST(BakeLocalLight, RectanglePenumbraMatchesQuadrature) {
  MeshInstance floor = test::makePlane({0, 0, 0}, 4.0f, 40);
  Scene s = test::makeScene({floor, test::makeSlab({-3.0f, 1.0f, -3.0f}, {0.0f, 1.05f, 3.0f})}, 0.5f);
  bake::BakeSettings bs;
  bs.samples = 16;
  bs.bounces = 0;
  bake::SurfaceTransfer t = bake::bakeSurface(s, bs);
  bake::storeTransfer(s, std::move(t.perMesh), std::move(t.perMeshDirect));
  s.transferBands = 3;
  LocalLight rect;
  rect.type = LocalLight::Type::Rectangle;
  rect.position = {0.0, 2.0, 0.0};
  rect.direction = {0, -1, 0};
  rect.up = {0, 0, 1};
  rect.width = 1.0;   // along x
  rect.height = 0.6;  // along z
  rect.radiance = dvec3(1.0);
  bake::ShadowSettings ss;
  ss.samples = 256;
  const bake::DirectIrradiance d = bake::shadowedLocalIrradiance(s, bake::RayScene(s), {rect}, ss);
  double worst = 0.0, meanError = 0.0;
  int penumbra = 0, checked = 0;
  for (size_t v = 0; v < s.meshes[0].vertexCount(); ++v) {
    const dvec3 p(s.meshes[0].positions[v]);
    if (std::fabs(p.z) > 0.5 || std::fabs(p.x) > 1.2) continue;
    const int n = 400;
    double ref = 0.0, open = 0.0;
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) {
        const dvec3 q(-0.5 + (i + 0.5) / n, 2.0, -0.3 + 0.6 * (j + 0.5) / n);
        const dvec3 w = q - p;
        const double r2 = glm::dot(w, w), c = w.y / std::sqrt(r2), g = c * c / r2;  // cos θ = cos θ'
        open += g;
        // The slab fills x < 0 for 1 <= y <= 1.05: the segment misses it iff it is at x >= 0 at
        // both heights (x is linear in y along it).
        const double xAt1 = p.x + w.x * (1.0 - p.y) / w.y, xAt105 = p.x + w.x * (1.05 - p.y) / w.y;
        if (xAt1 >= 0.0 && xAt105 >= 0.0) ref += g;
      }
    const double cell = 0.6 / (double(n) * n);
    ref *= cell;
    open *= cell;
    const double err = std::fabs(d.front[0][v].g - ref) / open;
    worst = std::max(worst, err);
    meanError += err;
    ++checked;
    penumbra += ref > 0.05 * open && ref < 0.95 * open;
  }
  meanError /= checked;
  EXPECT_GT(penumbra, 10);
  EXPECT_LT(worst, 0.015);
  EXPECT_LT(meanError, 0.003);
}

// The inside of a closed box [-1, 1]³, faces subdivided n × n, normals inwards.
MeshInstance insideOfABox(int n) {
  MeshInstance m;
  m.name = "box";
  for (int axis = 0; axis < 3; ++axis)
    for (int sign : {-1, 1}) {
      const int u = (axis + 1) % 3, w = (axis + 2) % 3;
      glm::vec3 inward(0.0f);
      inward[axis] = -float(sign);
      const uint32_t first = uint32_t(m.positions.size());
      for (int j = 0; j <= n; ++j)
        for (int i = 0; i <= n; ++i) {
          glm::vec3 p(0.0f);
          p[axis] = float(sign);
          p[u] = -1.0f + 2.0f * i / n;
          p[w] = -1.0f + 2.0f * j / n;
          m.positions.push_back(p);
          m.normals.push_back(inward);
        }
      for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
          const uint32_t a = first + j * (n + 1) + i, b = a + 1, c = a + (n + 1), d = c + 1;
          test::addTriangle(m, a, b, d, inward);
          test::addTriangle(m, a, d, c, inward);
        }
    }
  return m;
}

// Area-weighted mean of the irradiance at the vertices (a third of each triangle's area each).
double meanIrradiance(const MeshInstance& m, const std::vector<glm::vec3>& e) {
  double sum = 0.0, area = 0.0;
  for (size_t t = 0; t + 2 < m.indices.size(); t += 3) {
    const uint32_t* ix = &m.indices[t];
    const double a =
        0.5 * glm::length(glm::cross(m.positions[ix[1]] - m.positions[ix[0]], m.positions[ix[2]] - m.positions[ix[0]]));
    for (int k = 0; k < 3; ++k) sum += a / 3.0 * e[ix[k]].g;
    area += a;
  }
  return sum / area;
}

// A lamp of intensity I at the centre of a closed box of albedo ρ: its power 4πI lands on the
// walls, and each bounce sends on ρ of it, so the walls' mean irradiance after B bounces is
// (4πI / A) Σ_{k=0}^{B} ρ^k whatever the walls' shape. prt relight's path (FrameLighting,
// lights at the vertices) through the traced gather and through the bounce operator. The
// vertex-sampled mean of E⁰ is off by the tessellation (measured 0.25% low, held to 0.5%), the
// bounces by the gather's noise averaged over 1350 vertices (the total measured 0.7% low
// through the traced gather); 1.5% bounds it. The operator's rows (96 entries) stand for far
// clusters by their nodes' area-weighted mean, where the lamp's light falls off with distance
// and angle: measured 1.8% low with its default clusters of 4 (0.7% with clusters of 8, 0.3%
// with rows of 255), held to 3%. A missing or extra bounce is 20% off (ρ = 0.8).
TEST(BakeLocalLight, ClosedBoxLitByALampMatchesTheBounceSeries) {
  const float rho = 0.8f;
  const int B = 2;
  Scene s = test::makeScene({insideOfABox(14)}, rho);
  bake::BakeSettings bs;
  bs.samples = 256;
  bs.bounces = B;
  bs.seed = 3;
  bake::SurfaceTransfer t = bake::bakeSurface(s, bs);
  bake::storeTransfer(s, std::move(t.perMesh), std::move(t.perMeshDirect));
  s.transferBands = 3;
  BakeRecord record;
  record.bands = 3;
  record.samples = bs.samples;
  record.bounces = B;
  record.seed = bs.seed;
  s.bakeRecord = record;
  LightRig rig;
  RigLocalLight lamp;
  lamp.type = LocalLight::Type::Point;
  lamp.label = "lamp";
  lamp.position = Track::constant(glm::dvec3(0.1, -0.2, 0.05));
  lamp.color = Track::constant(1.0);
  rig.locals.push_back(lamp);
  rig.validate();
  const double e0 = 4.0 * kPi / 24.0;
  double series = 0.0;
  for (int k = 0; k <= B; ++k) series += e0 * std::pow(double(rho), k);
  for (bool op : {false, true}) {
    if (op) s.bounceOperator = std::make_shared<const BounceOperator>(bake::buildBounceOperator(s, {}, B, bs.seed));
    bake::FrameLightingSettings fs;
    fs.directAtVertices = true;
    fs.gatherSamples = bs.samples;
    fs.useOperator = op;
    fs.skyDetail = false;
    bake::FrameLighting lighting(s, rig, fs);
    const bake::FrameLight light = lighting.at(0.0);
    ASSERT_NE(light.vertexLight, nullptr);
    ASSERT_EQ(light.local.size(), 1u);
    EXPECT_EQ(lighting.usesOperator(), op);
    const double mean = meanIrradiance(s.meshes[0], light.vertexLight->front[0]);
    EXPECT_NEAR(mean / series, 1.0, op ? 0.03 : 0.015) << (op ? "through the operator" : "through the traced gather");
  }
  const bake::DirectIrradiance direct = bake::shadowedLocalIrradiance(s, bake::RayScene(s), {rig.locals[0].at(0.0)});
  EXPECT_NEAR(meanIrradiance(s.meshes[0], direct.front[0]) / e0, 1.0, 0.005);
}

// FrameLighting keeps the vertex sides' ray origins across frames; a baked file may hold an
// instance without transfer (prt render skips it) before the baked ones. A slab over a floor,
// the slab unbaked: the lamp's light at the floor's vertices through FrameLighting is the same
// as a direct call that finds the origins itself (the same rays from the same origins: 1e-6),
// I cos θ / r² where the slab's shadow (x < −0.33) is far (x > 0; 1e-4 for the origins' lift),
// and 0 deep in it (x < −1).
TEST(BakeLocalLight, FrameLightingOriginsSkipAnUnbakedInstance) {
  MeshInstance floor = test::makePlane({0, 0, 0}, 4.0f, 16);
  Scene s = test::makeScene({test::makeSlab({-2.0f, 1.0f, -2.0f}, {0.0f, 1.05f, 2.0f}), floor}, 0.5f);
  test::bakeInPlace(s, 16, 0, 1);
  s.meshes[0].transfer.clear();  // the slab: not baked, not a receiver
  s.meshes[0].transferDirect.clear();
  LightRig rig;
  RigLocalLight lamp;
  lamp.type = LocalLight::Type::Point;
  lamp.label = "lamp";
  lamp.position = Track::constant(glm::dvec3(0.3, 2.0, 0.1));
  lamp.color = Track::constant(1.0);
  rig.locals.push_back(lamp);
  rig.validate();
  bake::FrameLightingSettings fs;
  fs.directAtVertices = true;
  fs.gatherSamples = 0;
  fs.skyDetail = false;
  bake::FrameLighting lighting(s, rig, fs);
  const bake::FrameLight light = lighting.at(0.0);
  ASSERT_NE(light.vertexLight, nullptr);
  const bake::DirectIrradiance direct = bake::shadowedLocalIrradiance(s, bake::RayScene(s), {rig.locals[0].at(0.0)});
  ASSERT_EQ(direct.front[1].size(), s.meshes[1].vertexCount());
  ASSERT_EQ(light.vertexLight->front[1].size(), s.meshes[1].vertexCount());
  int lit = 0, dark = 0;
  for (size_t v = 0; v < s.meshes[1].vertexCount(); ++v) {
    for (int c = 0; c < 3; ++c)
      ASSERT_NEAR(light.vertexLight->front[1][v][c], direct.front[1][v][c], 1e-6) << "vertex " << v;
    const dvec3 p(s.meshes[1].positions[v]), toLamp = dvec3(0.3, 2.0, 0.1) - p;
    const double r2 = glm::dot(toLamp, toLamp), e = toLamp.y / std::sqrt(r2) / r2;
    if (p.x > 0.0) {
      ASSERT_NEAR(light.vertexLight->front[1][v].g, e, 1e-4 * e) << "vertex " << v;
      ++lit;
    }
    if (p.x < -1.0) {
      ASSERT_EQ(light.vertexLight->front[1][v].g, 0.0f) << "vertex " << v;
      ++dark;
    }
  }
  EXPECT_GT(lit, 20);
  EXPECT_GT(dark, 20);
}

// For the renderer (directAtVertices false), FrameLightingSettings::localPerPixel takes the lamp's
// own shadowed light out of the vertex light and keeps its bounces: the two vertex lights differ
// by the lamp's E⁰ at every vertex (float rounding: 1e-5 of the lamp's mean), and what is left
// is the bounce series less its first term, (4πI / A)(ρ + ρ²) within 1.5% (the test above). A rig
// without a map, uniform light or disk has no sky detail to gather.
TEST(BakeLocalLight, PerPixelLampLeavesOnlyItsBouncesAtTheVertices) {
  const float rho = 0.8f;
  const int B = 2;
  Scene s = test::makeScene({insideOfABox(14)}, rho);
  bake::BakeSettings bs;
  bs.samples = 256;
  bs.bounces = B;
  bs.seed = 3;
  bake::SurfaceTransfer t = bake::bakeSurface(s, bs);
  bake::storeTransfer(s, std::move(t.perMesh), std::move(t.perMeshDirect));
  s.transferBands = 3;
  BakeRecord record;
  record.bands = 3;
  record.samples = bs.samples;
  record.bounces = B;
  record.seed = bs.seed;
  s.bakeRecord = record;
  LightRig rig;
  RigLocalLight lamp;
  lamp.type = LocalLight::Type::Point;
  lamp.label = "lamp";
  lamp.position = Track::constant(glm::dvec3(0.1, -0.2, 0.05));
  lamp.color = Track::constant(1.0);
  rig.locals.push_back(lamp);
  rig.validate();
  std::vector<glm::vec3> light[2];
  for (bool perPixel : {false, true}) {
    bake::FrameLightingSettings fs;
    fs.gatherSamples = bs.samples;
    fs.useOperator = false;
    fs.localPerPixel = perPixel;
    bake::FrameLighting lighting(s, rig, fs);
    const bake::FrameLight l = lighting.at(0.0);
    ASSERT_NE(l.vertexLight, nullptr);
    EXPECT_FALSE(lighting.skyDetail());  // no sky in the rig: nothing beyond the band limit to gather
    light[perPixel] = l.vertexLight->front[0];
  }
  const bake::DirectIrradiance direct = bake::shadowedLocalIrradiance(s, bake::RayScene(s), {rig.locals[0].at(0.0)});
  const double e0 = 4.0 * kPi / 24.0;
  double worst = 0.0;
  for (size_t v = 0; v < light[0].size(); ++v)
    worst = std::max(worst, double(std::abs(light[0][v].g - light[1][v].g - direct.front[0][v].g)));
  EXPECT_LT(worst, 1e-5 * e0);
  EXPECT_NEAR(meanIrradiance(s.meshes[0], light[1]) / (e0 * (rho + rho * rho)), 1.0, 0.015);
}

// With localPerPixel the renderer lights an area light itself, so its E⁰ at the vertices only
// bounces: it takes the bounces' shadow rays (shadowSamples), not the vertex lights' many
// (localShadowSamples), which an emissive surface lit at the vertices keeps. The shadow rays of a
// sphere light in the box: 4 per vertex side with localShadowSamples 4 or 64 alike when per pixel,
// 64 when at the vertices (the counter-check).
TEST(BakeLocalLight, PerPixelAreaLightBouncesWithTheBounceShadowRays) {
  Scene s = test::makeScene({insideOfABox(6)}, 0.8f);
  bake::BakeSettings bs;
  bs.samples = 64;
  bs.bounces = 1;
  bake::SurfaceTransfer t = bake::bakeSurface(s, bs);
  bake::storeTransfer(s, std::move(t.perMesh), std::move(t.perMeshDirect));
  s.transferBands = 3;
  BakeRecord record;
  record.bands = 3;
  record.samples = bs.samples;
  record.bounces = 1;
  s.bakeRecord = record;
  LightRig rig;
  RigLocalLight globe;
  globe.type = LocalLight::Type::Sphere;
  globe.label = "globe";
  globe.position = Track::constant(glm::dvec3(0.1, -0.2, 0.05));
  globe.radius = Track::constant(0.1);
  globe.color = Track::constant(1.0);
  rig.locals.push_back(globe);
  rig.validate();
  auto rays = [&](bool perPixel, int localSamples) {
    bake::FrameLightingSettings fs;
    fs.gatherSamples = bs.samples;
    fs.useOperator = false;
    fs.localPerPixel = perPixel;
    fs.shadowSamples = 4;
    fs.localShadowSamples = localSamples;
    bake::FrameLighting lighting(s, rig, fs);
    lighting.at(0.0);
    return lighting.stats().shadowRays;
  };
  const uint64_t few = rays(true, 4);
  EXPECT_GT(few, 0u);
  EXPECT_EQ(rays(true, 64), few);
  EXPECT_EQ(rays(false, 64), 16 * few);
}

// For the renderer a frame that moves one lamp of two traces the moving lamp's shadow rays alone
// (the still lamp's E⁰ is kept from the frame before), and its vertex light is the one a fresh
// FrameLighting gives at that frame, bit for bit.
TEST(BakeLocalLight, PerPixelStillLampIsNotTracedAgain) {
  Scene s = test::makeScene({insideOfABox(6)}, 0.8f);
  bake::BakeSettings bs;
  bs.samples = 64;
  bs.bounces = 1;
  bake::SurfaceTransfer t = bake::bakeSurface(s, bs);
  bake::storeTransfer(s, std::move(t.perMesh), std::move(t.perMeshDirect));
  s.transferBands = 3;
  BakeRecord record;
  record.bands = 3;
  record.samples = bs.samples;
  record.bounces = 1;
  s.bakeRecord = record;
  LightRig rig;
  RigLocalLight still, moving;
  still.type = moving.type = LocalLight::Type::Point;
  still.label = "still";
  moving.label = "moving";
  still.position = Track::constant(glm::dvec3(0.1, 0.2, 0.05));
  moving.position.keys = {{0.0, glm::dvec3(-0.3, -0.2, 0.0)}, {1.0, glm::dvec3(0.3, -0.2, 0.1)}};
  still.color = moving.color = Track::constant(1.0);
  rig.locals = {still, moving};
  rig.validate();
  bake::FrameLightingSettings fs;
  fs.gatherSamples = bs.samples;
  fs.useOperator = false;
  fs.localPerPixel = true;
  bake::FrameLighting lighting(s, rig, fs);
  lighting.at(0.0);
  const uint64_t first = lighting.stats().shadowRays;
  const bake::FrameLight one = lighting.at(1.0);
  const uint64_t second = lighting.stats().shadowRays - first;
  LightRig alone;
  alone.locals = {moving};
  alone.validate();
  bake::FrameLighting justMoving(s, alone, fs);
  justMoving.at(1.0);
  EXPECT_GT(second, 0u);
  EXPECT_EQ(second, justMoving.stats().shadowRays);
  bake::FrameLighting fresh(s, rig, fs);
  const bake::FrameLight again = fresh.at(1.0);
  ASSERT_NE(one.vertexLight, nullptr);
  ASSERT_NE(again.vertexLight, nullptr);
  EXPECT_EQ(one.vertexLight->front, again.vertexLight->front);
}

// The file's own lamp on a node that a glTF animation moves: each frame of prt relight's
// lighting (frame / fps seconds into the animation) equals the static light at that frame's
// position, bit for bit; with sceneLights off the lamp is dark and nothing is gathered for it.
TEST(BakeLocalLight, AnimatedLampFramesMatchStaticLights) {
  Scene s = bakedPlane();
  s.path = "lamp.glb";
  Node node;
  node.name = "LampNode";
  node.translation = {0.0, 1.0, 0.0};
  s.nodes.push_back(node);
  AnimationChannel ch;
  ch.node = 0;
  ch.path = AnimationPath::Translation;
  ch.times = {0.0, 1.0};
  ch.values = {glm::dvec4(-0.5, 1.0, 0.0, 0.0), glm::dvec4(0.5, 0.6, 0.2, 0.0)};
  s.animations.push_back({"move", {ch}});
  PunctualLight p;
  p.name = "Lamp";
  p.node = 0;
  p.type = PunctualLight::Type::Point;
  p.color = {1.0f, 0.5f, 0.25f};
  p.intensity = 2.0f;
  p.position = {0.0f, 1.0f, 0.0f};  // the rest pose, which the animation replaces
  s.lights.push_back(p);
  LightRig rig;
  rig.fps = 10.0;
  bake::FrameLightingSettings fs;
  fs.directAtVertices = true;
  fs.gatherSamples = 0;
  fs.sceneLights = true;
  bake::FrameLighting lighting(s, rig, fs);
  const bake::RayScene rays(s);
  for (double frame : {0.0, 5.0, 10.0, 20.0}) {
    const bake::FrameLight light = lighting.at(frame);
    const double t = std::min(frame / 10.0, 1.0);
    const dvec3 at = glm::mix(dvec3(-0.5, 1.0, 0.0), dvec3(0.5, 0.6, 0.2), t);
    ASSERT_EQ(light.local.size(), 1u);
    EXPECT_NEAR(glm::length(light.local[0].position - at), 0.0, 1e-12) << "frame " << frame;
    const bake::DirectIrradiance ref = bake::shadowedLocalIrradiance(s, rays, {light.local[0]});
    ASSERT_NE(light.vertexLight, nullptr);
    EXPECT_EQ(light.vertexLight->front[0], ref.front[0]) << "frame " << frame;
    const dvec3 toL = at - dvec3(s.meshes[0].positions[0]);
    const double expected = 2.0 * 0.5 * toL.y / std::pow(glm::length(toL), 3.0);  // green: 0.5 × 2 cd
    EXPECT_NEAR(ref.front[0][0].g, expected, 1e-6 * expected) << "frame " << frame;
  }
  fs.sceneLights = false;
  bake::FrameLighting dark(s, rig, fs);
  const bake::FrameLight off = dark.at(5.0);
  EXPECT_TRUE(off.local.empty());
  EXPECT_EQ(off.vertexLight, nullptr);
}

// Rig errors name the file, the light and the field.
TEST(LightRigLocal, BadLightsAreRefusedWithTheirField) {
  auto message = [](const std::string& json) {
    try {
      parseLightRigFromMemory(json, "rig.json");
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  const std::string head = R"({"version": 1, "lights": [)";
  EXPECT_EQ(
      message(head + R"({"type": "spot", "position": [0,1,0], "intensity": 5, "inner_cone": 40, "outer_cone": 30}]})"),
      "rig.json: lights[0].inner_cone: the inner cone (40 degrees at frame 0) must be inside the outer cone (30)");
  EXPECT_EQ(message(head + R"({"type": "point", "position": [0,1,0], "intensity": -2}]})"),
            "rig.json: lights[0].intensity: must be >= 0 (got -2)");
  EXPECT_EQ(message(head + R"({"type": "area", "shape": "disk", "position": [0,1,0], "radius": 0, "radiance": 1}]})"),
            "rig.json: lights[0].radius: an area light needs a size > 0 (got 0)");
  EXPECT_EQ(
      message(head + R"({"type": "area", "shape": "rectangle", "position": [0,1,0], "width": 1, "radiance": 1}]})"),
      "rig.json: lights[0].height: missing (metres)");
  // A good rig: a keyframed point light, a spot and a rectangle on a node.
  const LightRig rig = parseLightRigFromMemory(
      head + R"({"type": "point", "position": [{"frame": 0, "value": [0,1,0]}, {"frame": 10, "value": [2,1,0]}],
                 "intensity": [1, 2, 3], "range": 5},
                {"type": "spot", "position": [0,2,0], "direction": [0,-1,0], "power": 100, "outer_cone": 30},
                {"type": "area", "shape": "rectangle", "node": "Lamp", "width": 1, "height": 0.5, "radiance": 2}]})",
      "rig.json");
  ASSERT_EQ(rig.locals.size(), 3u);
  EXPECT_TRUE(rig.animated());
  EXPECT_EQ(rig.locals[0].at(5.0).position, glm::dvec3(1, 1, 0));
  EXPECT_NEAR(rig.locals[1].at(0.0).intensity.x, 100.0 / (4.0 * kPi), 1e-12);
  EXPECT_EQ(rig.locals[2].node, "Lamp");
  // The scene lacks the node: one line naming the rig, the light and the scene.
  Scene s = test::makeScene({test::makePlane({0, 0, 0}, 1.0f, 1)}, 0.5f);
  s.path = "room.glb";
  try {
    bake::checkRigNodes(s, rig);
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(), "rig.json: lights[2].node: no node 'Lamp' in room.glb");
  }
}

}  // namespace
}  // namespace prt
