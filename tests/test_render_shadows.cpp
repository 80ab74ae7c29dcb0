// Direct lights in the renderer (docs/render.md, "Direct lights and their shadows"): frames
// checked at pixel centres against a CPU ray tracer of the same formula,
//   L_o = ρ/π · (t·sh + (t − t⁰)·directSh + Σ_k E_k · directCosineFactor_k(n) · visibleShare_k(x)),
// whose visible share is traced with Embree shadow rays stratified over each light's cap; the
// plane under a sun in closed form; receivers casting on and shadowed by the baked scene.
#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include <gtest/gtest.h>
#include <glm/gtc/matrix_transform.hpp>

#include "prt/bake/probe_bake.h"
#include "prt/bake/ray_scene.h"
#include "prt/error.h"
#include "prt/light.h"
#include "prt/probe_grid.h"
#include "prt/render/gl_context.h"
#include "prt/render/renderer.h"
#include "prt/scene.h"
#include "test_scenes.h"

#include "shadow_pass.h"  // render/src: planShadows

namespace prt::render {
namespace {

constexpr double kInvPi = 0.31830988618379067;
constexpr int kW = 96, kH = 72;

CameraView lookAt(const glm::dvec3& eye, const glm::dvec3& target, double yfovDegrees) {
  CameraView c;
  c.cameraToWorld = glm::inverse(glm::lookAt(eye, target, glm::dvec3(0, 1, 0)));
  c.yfov = glm::radians(yfovDegrees);
  c.znear = 0.05;
  return c;
}

using test::makeQuad;

// An axis-aligned box as one instance of 6 faces (flat normals, outward).
MeshInstance box(const std::string& name, glm::vec3 lo, glm::vec3 hi) {
  MeshInstance m;
  m.name = name;
  const glm::vec3 s = hi - lo;
  auto add = [&](glm::vec3 p0, glm::vec3 du, glm::vec3 dv) {
    const MeshInstance f = makeQuad(name, p0, du, dv, 1, 1);
    const uint32_t base = uint32_t(m.positions.size());
    m.positions.insert(m.positions.end(), f.positions.begin(), f.positions.end());
    m.normals.insert(m.normals.end(), f.normals.begin(), f.normals.end());
    for (uint32_t i : f.indices) m.indices.push_back(base + i);
  };
  add(lo, {0, 0, s.z}, {0, s.y, 0});                  // -X
  add({hi.x, lo.y, lo.z}, {0, s.y, 0}, {0, 0, s.z});  // +X
  add(lo, {s.x, 0, 0}, {0, 0, s.z});                  // -Y
  add({lo.x, hi.y, lo.z}, {0, 0, s.z}, {s.x, 0, 0});  // +Y
  add(lo, {0, s.y, 0}, {s.x, 0, 0});                  // -Z
  add({lo.x, lo.y, hi.z}, {s.x, 0, 0}, {0, s.y, 0});  // +Z
  return m;
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

// Random transfer t (RGB, some negative) and direct part t⁰ (colourless), fixed seed: the SH
// part of the formula is checked for any values, not only physical ones.
void fillTransfer(MeshInstance& m, int bands, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-0.2f, 1.0f), d(0.0f, 0.6f);
  const size_t n = m.vertexCount() * size_t(bands) * bands;
  m.transfer.resize(n);
  for (glm::vec3& t : m.transfer) t = glm::vec3(u(rng), u(rng), u(rng));
  m.transferDirect.resize(n);
  for (float& t : m.transferDirect) t = d(rng);
}

sh::ShRgb randomLight(int bands, uint32_t seed, float ambient) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.0f, 0.3f);
  sh::ShRgb l(bands);
  for (glm::vec3& c : l.c) c = glm::vec3(u(rng), u(rng), u(rng));
  l.c[0] += glm::vec3(ambient);
  return l;
}

DirectLight sun(double elevationDegrees, double azimuthDegrees, double radiusDegrees, glm::dvec3 irradiance) {
  DirectLight l;
  l.direction = azimuthElevationDirection(azimuthDegrees, elevationDegrees);
  l.radius = glm::radians(radiusDegrees);
  l.irradiance = irradiance;
  return l;
}

// ---------------------------------------------------------------------------------------------
// The oracle: the pixel centre's ray (as in test_render.cpp) traced with Embree; the hit's
// barycentrics interpolate t, t⁰ and the normal; the visible share of each light is the
// cosine-weighted mean visibility of 16 × 16 directions stratified over its cap (uniform in
// solid angle), traced from the hit lifted 1e-4 along the normal.

struct PixelRay {
  glm::dvec3 origin, dir;
};

// The ray through (px + fx, py + fy): the pixel's centre by default.
PixelRay pixelRay(const CameraView& c, int w, int h, int px, int py, double fx = 0.5, double fy = 0.5) {
  const double aspect = double(w) / h;
  const double sx = 2.0 * (px + fx) / w - 1.0, sy = 1.0 - 2.0 * (py + fy) / h;
  const double t = std::tan(0.5 * c.yfov);
  return {glm::dvec3(c.cameraToWorld[3]),
          glm::normalize(glm::dvec3(c.cameraToWorld * glm::dvec4(sx * t * aspect, sy * t, -1.0, 0.0)))};
}

struct Surface {
  bool hit = false;
  uint32_t mesh = 0;
  glm::dvec3 x{0.0}, n{0.0};
  uint32_t v[3] = {0, 0, 0};
  double b[3] = {0, 0, 0};
  bool back = false;
};

Surface primary(const bake::RayScene& rays, const Scene& s, const PixelRay& pr) {
  bake::Ray r;
  r.org = glm::vec3(pr.origin);
  r.dir = glm::vec3(pr.dir);
  r.tnear = 0.0f;
  r.tfar = 1e30f;
  rays.intersect(&r, 1, false);
  Surface out;
  if (!r.hit()) return out;
  const MeshInstance& m = s.meshes[r.mesh];
  out.hit = true;
  out.mesh = r.mesh;
  out.back = r.backface();
  out.b[0] = 1.0 - r.u - r.v;
  out.b[1] = r.u;
  out.b[2] = r.v;
  glm::dvec3 n(0.0);
  for (int k = 0; k < 3; ++k) {
    out.v[k] = m.indices[3 * size_t(r.tri) + size_t(k)];
    out.x += out.b[k] * glm::dvec3(m.positions[out.v[k]]);
    n += out.b[k] * glm::dvec3(m.normals[out.v[k]]);
  }
  out.n = glm::normalize(n);
  if (out.back) out.n = -out.n;
  return out;
}

double visibleShare(const bake::RayScene& rays, const glm::dvec3& x, const glm::dvec3& n, const DirectLight& l) {
  const glm::dvec3 d = glm::normalize(l.direction);
  const glm::dvec3 helper = std::abs(d.y) < 0.9 ? glm::dvec3(0, 1, 0) : glm::dvec3(1, 0, 0);
  const glm::dvec3 t1 = glm::normalize(glm::cross(helper, d)), t2 = glm::cross(d, t1);
  constexpr int k = 16;
  std::vector<bake::Ray> batch;
  std::vector<double> weight;
  const bool delta = l.radius < kPointSunRadians;
  const double oneMinusCos = 1.0 - std::cos(l.radius);
  for (int i = 0; i < (delta ? 1 : k); ++i)
    for (int j = 0; j < (delta ? 1 : k); ++j) {
      const double cosT = 1.0 - (i + 0.5) / k * oneMinusCos, sinT = std::sqrt(std::max(0.0, 1.0 - cosT * cosT));
      const double phi = 2.0 * 3.14159265358979 * (j + 0.5) / k;
      const glm::dvec3 w = delta ? d : glm::normalize(cosT * d + sinT * (std::cos(phi) * t1 + std::sin(phi) * t2));
      const double c = glm::dot(n, w);
      if (c <= 0.0) continue;
      bake::Ray r;
      r.org = glm::vec3(x + 1e-4 * n);
      r.dir = glm::vec3(w);
      r.tnear = 0.0f;
      r.tfar = 1e30f;
      batch.push_back(r);
      weight.push_back(c);
    }
  if (batch.empty()) return 1.0;
  rays.occluded(batch.data(), batch.size(), false);
  double seen = 0.0, total = 0.0;
  for (size_t i = 0; i < batch.size(); ++i) {
    total += weight[i];
    if (!batch[i].occludedHit()) seen += weight[i];
  }
  return seen / total;
}

// Per pixel: the oracle's radiance split into its SH part and each light's direct part, and
// each light's visible share (-1 where no surface).
struct OraclePixel {
  Surface s;
  glm::dvec3 shPart{0.0};
  std::vector<glm::dvec3> direct;  // ρ/π E_k c_k(n) s_k(x)
  std::vector<double> share;
  bool terminator = false;  // some light's cap straddles the surface's horizon
};

std::vector<OraclePixel> oracleFrame(const Scene& scene, const bake::RayScene& rays, const CameraView& cam, int w,
                                     int h, const sh::ShRgb& light, const sh::ShRgb& directSh,
                                     const std::vector<DirectLight>& lights) {
  std::vector<OraclePixel> out(size_t(w) * h);
  const int bands = scene.transferBands, n2 = bands * bands;
  for (int py = 0; py < h; ++py)
    for (int px = 0; px < w; ++px) {
      OraclePixel& o = out[size_t(py) * w + px];
      o.s = primary(rays, scene, pixelRay(cam, w, h, px, py));
      if (!o.s.hit) continue;
      const MeshInstance& m = scene.meshes[o.s.mesh];
      const Material mat = m.material >= 0 ? scene.materials[size_t(m.material)] : Material{};
      const glm::dvec3 albedo(mat.baseColorFactor);
      if (!m.transfer.empty()) {
        glm::dvec3 e(0.0);
        for (int k = 0; k < 3; ++k) {
          const bool back = o.s.back && m.hasBackTransfer();
          const glm::vec3* t = back ? m.backTransferOf(o.s.v[k], bands) : m.transferOf(o.s.v[k], bands);
          const float* t0 = m.directTransferOf(o.s.v[k], bands, back);
          for (int i = 0; i < n2; ++i)
            e += o.s.b[k] * (glm::dvec3(t[i]) * glm::dvec3(light.c[size_t(i)] + directSh.c[size_t(i)]) -
                             double(t0[i]) * glm::dvec3(directSh.c[size_t(i)]));
        }
        o.shPart = albedo * kInvPi * e;
      }
      for (const DirectLight& l : lights) {
        const double c = directCosineFactor(l, o.s.n);
        o.terminator =
            o.terminator || std::abs(glm::dot(o.s.n, glm::normalize(l.direction))) < std::sin(l.radius) + 1e-3;
        const double share = c > 0.0 ? visibleShare(rays, o.s.x, o.s.n, l) : 1.0;
        o.share.push_back(share);
        o.direct.push_back(albedo * kInvPi * l.irradiance * (c * share));
      }
    }
  return out;
}

// Light l's visible share averaged over pixel (px, py)'s square, as a box-filtered pixel sees it:
// the oracle's share at sub × sub points stratified over the square; -1 where one of them does
// not see `mesh` (or, with `partOnMesh`, the mean over the points that do).
double footprintShare(const Scene& scene, const bake::RayScene& rays, const CameraView& cam, int w, int h, int px,
                      int py, uint32_t mesh, const DirectLight& l, int sub, bool partOnMesh = false) {
  double sum = 0.0;
  int n = 0;
  for (int j = 0; j < sub; ++j)
    for (int i = 0; i < sub; ++i) {
      const Surface q = primary(rays, scene, pixelRay(cam, w, h, px, py, (i + 0.5) / sub, (j + 0.5) / sub));
      if (!q.hit || q.mesh != mesh) {
        if (partOnMesh) continue;
        return -1.0;
      }
      sum += directCosineFactor(l, q.n) > 0.0 ? visibleShare(rays, q.x, q.n, l) : 1.0;
      ++n;
    }
  return n ? sum / n : -1.0;
}

// A pixel is away from shadow edges when every light's share is 0 or 1 at its centre and at the
// centres of its 8 neighbours, all on one instance (no silhouette either), and no light's cap
// straddles its horizon (the terminator: the surface lies edge-on in the shadow map there, and
// its own depth decides a share of the light that is at most sin r + 10⁻³ of E; measured on the
// cube of ReceiverCastsAndReceivesSunShadows: 6·10⁻⁴ of the peak).
bool awayFromEdges(const std::vector<OraclePixel>& o, int w, int h, int px, int py) {
  if (px < 1 || py < 1 || px + 1 >= w || py + 1 >= h) return false;
  const OraclePixel& c = o[size_t(py) * w + px];
  if (!c.s.hit || c.terminator) return false;
  for (int dy = -1; dy <= 1; ++dy)
    for (int dx = -1; dx <= 1; ++dx) {
      const OraclePixel& q = o[size_t(py + dy) * w + px + dx];
      if (!q.s.hit || q.s.mesh != c.s.mesh || q.s.back != c.s.back) return false;
      for (size_t k = 0; k < c.share.size(); ++k)
        if ((q.share[k] != 0.0 && q.share[k] != 1.0) || q.share[k] != c.share[k]) return false;
    }
  return true;
}

double peak(const std::vector<OraclePixel>& o) {
  double p = 0.0;
  for (const OraclePixel& q : o) {
    glm::dvec3 sum = q.shPart;
    for (const glm::dvec3& d : q.direct) sum += d;
    p = std::max({p, sum.x, sum.y, sum.z});
  }
  return p;
}

// `meshes` at 3 bands, all of one grey material (albedo 0.8).
Scene greyScene(const std::string& path, std::vector<MeshInstance> meshes) {
  Scene s;
  s.path = path;
  Material grey;
  grey.baseColorFactor = glm::vec4(0.8f, 0.8f, 0.8f, 1.0f);
  s.materials = {grey};
  for (MeshInstance& m : meshes) m.material = 0;
  s.meshes = std::move(meshes);
  s.transferBands = 3;
  updateBounds(s);
  return s;
}

// The test scene: a 3 m floor in 6 × 6 quads, a floating slab and a wall behind it, all baked
// (random transfer), grey materials of different albedo.
Scene slabScene(int bands) {
  Scene s;
  s.path = "slab";
  Material grey, warm;
  grey.baseColorFactor = glm::vec4(0.8f, 0.8f, 0.8f, 1.0f);
  warm.baseColorFactor = glm::vec4(0.9f, 0.6f, 0.4f, 1.0f);
  s.materials = {grey, warm};
  MeshInstance floor = makeQuad("floor", {-1.5f, 0.0f, 1.5f}, {3.0f, 0.0f, 0.0f}, {0.0f, 0.0f, -3.0f}, 6, 6);
  floor.material = 0;
  MeshInstance slab = box("slab", {-0.4f, 0.7f, -0.3f}, {0.4f, 0.8f, 0.4f});
  slab.material = 1;
  MeshInstance wall = makeQuad("wall", {-1.5f, 0.0f, -1.2f}, {3.0f, 0.0f, 0.0f}, {0.0f, 1.4f, 0.0f}, 3, 2);
  wall.material = 0;
  s.meshes = {floor, slab, wall};
  for (size_t k = 0; k < s.meshes.size(); ++k) fillTransfer(s.meshes[k], bands, uint32_t(11 + k));
  s.transferBands = bands;
  updateBounds(s);
  return s;
}

struct Check {
  int compared = 0, covered = 0, edge = 0;
  double maxError = 0.0;  // relative to the oracle's peak
};

Check compareAwayFromEdges(const ImageRgb& img, const std::vector<OraclePixel>& o, int w, int h) {
  const double p = peak(o);
  Check c;
  for (int py = 0; py < h; ++py)
    for (int px = 0; px < w; ++px) {
      const OraclePixel& q = o[size_t(py) * w + px];
      if (!q.s.hit) continue;
      ++c.covered;
      if (!awayFromEdges(o, w, h, px, py)) {
        ++c.edge;
        continue;
      }
      glm::dvec3 want = q.shPart;
      for (const glm::dvec3& d : q.direct) want += d;
      const glm::dvec3 e = glm::abs(glm::dvec3(img.at(px, py)) - want) / p;
      c.maxError = std::max({c.maxError, e.x, e.y, e.z});
      ++c.compared;
    }
  return c;
}

// The frame the renderer draws of `s` (1024² shadow maps) and the oracle's, under one lighting.
struct Rendered {
  std::vector<OraclePixel> oracle;
  ImageRgb image;
};

Rendered renderWithOracle(const Scene& s, const CameraView& cam, const sh::ShRgb& light, const sh::ShRgb& directSh,
                          const std::vector<DirectLight>& lights) {
  const bake::RayScene rays(s);
  Rendered out;
  out.oracle = oracleFrame(s, rays, cam, kW, kH, light, directSh, lights);
  GlContext ctx(GlBackend::OSMesa, kW, kH);
  Renderer r(ctx, s);
  Frame f;
  f.camera = cam;
  f.light = light;
  f.directLight = directSh;
  f.direct = lights;
  f.shadows.mapSize = 1024;
  out.image = r.render(f);
  return out;
}

// ---------------------------------------------------------------------------------------------

// An open plane under a sun: every pixel is ρ/π · E · directCosineFactor(n) (E cos θ above the
// horizon, the clipped cap across it, 0 below), with the SH light zero and t = t⁰ — the shadow
// map must not shadow the plane itself at any elevation (acne). Both sides of a double-sided
// plane: the back (seen from below) is lit by a sun below the plane.
TEST(RenderDirect, PlaneUnderSunIsRhoOverPiECosTheta) {
  Scene s;
  s.path = "plane";
  Material m;
  m.baseColorFactor = glm::vec4(0.7f, 0.5f, 0.3f, 1.0f);
  m.doubleSided = true;
  s.materials.push_back(m);
  MeshInstance plane = makeQuad("plane", {-2.0f, 0.0f, 2.0f}, {4.0f, 0.0f, 0.0f}, {0.0f, 0.0f, -4.0f}, 4, 4);
  plane.material = 0;
  fillTransfer(plane, 3, 5);
  plane.transferBack = plane.transfer;
  plane.transferDirectBack = plane.transferDirect;
  s.meshes.push_back(plane);
  s.transferBands = 3;
  updateBounds(s);
  GlContext ctx(GlBackend::OSMesa, kW, kH);
  Renderer r(ctx, s);
  ASSERT_TRUE(r.bakedDirectPart());
  const glm::dvec3 rho(0.7, 0.5, 0.3);
  struct Case {
    double elevation, radius;
    bool fromBelow;
  };
  // Elevations across the horizon for a 5° disk (−6 is wholly below, ±2 straddles), the sun
  // at 90° … 3°, and seen from below with the sun below the plane.
  const Case cases[] = {{90, 0.265, false}, {60, 0.265, false}, {30, 0.265, false}, {3, 0.265, false},
                        {-5, 0.265, false}, {2, 5.0, false},    {-2, 5.0, false},   {-6, 5.0, false},
                        {-40, 0.265, true}, {0, 0.0, false}};
  for (const Case& c : cases) {
    const DirectLight l = sun(c.elevation, 20.0, c.radius, {3.0, 2.0, 1.0});
    Frame f;
    f.camera =
        c.fromBelow ? lookAt({0.3, -2.0, 1.5}, {0.0, 0.0, 0.0}, 50.0) : lookAt({0.3, 2.0, 1.5}, {0.0, 0.0, 0.0}, 50.0);
    f.light = sh::ShRgb(3);
    f.directLight = sh::ShRgb(3);
    f.direct = {l};
    f.shadows.mapSize = 512;
    const ImageRgb img = r.render(f);
    const glm::dvec3 n(0.0, c.fromBelow ? -1.0 : 1.0, 0.0);
    const glm::dvec3 want = rho * kInvPi * l.irradiance * directCosineFactor(l, n);
    double worst = 0.0;
    int covered = 0;
    for (int y = 0; y < kH; ++y)
      for (int x = 0; x < kW; ++x) {
        const glm::dvec3 got(img.at(x, y));
        if (got == glm::dvec3(0.0) && want != glm::dvec3(0.0)) continue;  // background (the plane's edge is in view)
        ++covered;
        worst = std::max(worst, glm::length(got - want));
      }
    SCOPED_TRACE(testing::Message() << "elevation " << c.elevation << ", radius " << c.radius);
    EXPECT_GT(covered, kW * kH / 3);
    EXPECT_EQ(r.lastFrame().directBaked, 1u);
    // Float shading of a closed form: 2e-5 of the facing value ρ/π E (measured below).
    EXPECT_LE(worst, 2e-5 * glm::length(rho * kInvPi * l.irradiance))
        << "want " << want.x << " " << want.y << " " << want.z;
    if (c.elevation <= -c.radius - 1e-9 && !c.fromBelow) {
      EXPECT_EQ(want, glm::dvec3(0.0));
      EXPECT_EQ(worst, 0.0);  // below the horizon: exactly 0
    }
  }
}

// The slab scene under two direct lights (a sun and a 3° disk) and an SH light: every pixel away
// from shadow edges agrees with the ray-traced oracle; the pixels left out (penumbra band and
// silhouettes) are a bounded share.
TEST(RenderDirect, MatchesRayTracedOracleAwayFromShadowEdges) {
  const Scene s = slabScene(3);
  const CameraView cam = lookAt({0.6, 3.2, 3.0}, {0.0, 0.3, 0.0}, 50.0);
  // The sun's shadow falls towards −X and the camera, the disk's towards +X.
  const std::vector<DirectLight> lights = {sun(35.0, 120.0, 0.265, {4.0, 3.5, 3.0}),
                                           sun(35.0, 250.0, 3.0, {1.0, 1.5, 2.0})};
  const Rendered rendered = renderWithOracle(s, cam, randomLight(3, 3, 1.0f), randomLight(3, 4, 0.5f), lights);
  const std::vector<OraclePixel>& o = rendered.oracle;
  const Check c = compareAwayFromEdges(rendered.image, o, kW, kH);
  int shadowed = 0;
  for (int py = 0; py < kH; ++py)
    for (int px = 0; px < kW; ++px)
      if (awayFromEdges(o, kW, kH, px, py) && o[size_t(py) * kW + px].share[0] == 0.0) ++shadowed;
  std::printf(
      "[ measured ] %d of %d covered pixels compared (%d in the penumbra band or at silhouettes, %d in the "
      "sun's umbra), worst %.3g of the peak\n",
      c.compared, c.covered, c.edge, shadowed, c.maxError);
  EXPECT_GT(shadowed, 100);  // the slab's shadow is in view and checked
  // Away from edges the shadow map's answer is exactly 0 or 1 and the rest is float shading of
  // the same interpolation (test_render.cpp measures 7e-7 for the SH part): 1e-4 of the peak.
  EXPECT_LE(c.maxError, 1e-4);
  // The penumbra band of a 3° disk is wide: the band, the terminators and the silhouettes together
  // are 33% of the covered pixels at this size (measured); 40% bounds it.
  EXPECT_LT(c.edge, c.covered * 2 / 5);
}

// Per pixel of the floor (instance 0, albedo 0.8) lit by `l` alone (no SH light): the rendered
// share (the frame over ρ/π E_r · directCosineFactor(n)), the oracle's share at the pixel's
// centre and averaged over its square (4 × 4 points; the pixels whose square leaves the floor
// are left out).
struct FloorShare {
  double got, centre, square;
};

std::vector<FloorShare> floorShares(const Scene& s, const CameraView& cam, const Rendered& r, const DirectLight& l) {
  const bake::RayScene rays(s);
  std::vector<FloorShare> out;
  for (int py = 1; py + 1 < kH; ++py)
    for (int px = 1; px + 1 < kW; ++px) {
      const OraclePixel& q = r.oracle[size_t(py) * kW + px];
      if (!q.s.hit || q.s.mesh != 0) continue;
      const double square = footprintShare(s, rays, cam, kW, kH, px, py, 0, l, 4);
      const double unshadowed = 0.8 * kInvPi * l.irradiance.x * directCosineFactor(l, q.s.n);
      if (square < 0.0 || unshadowed <= 0.0) continue;
      out.push_back({double(r.image.at(px, py).x) / unshadowed, q.share[0], square});
    }
  return out;
}

// Inside the penumbra the filtered share follows the disk's: mean |rendered − traced| share over
// the band pixels, the traced share averaged over each pixel's square as the renderer filters it.
TEST(RenderDirect, PenumbraFollowsTheDisk) {
  const Scene s = slabScene(3);
  const CameraView cam = lookAt({0.0, 2.6, 1.6}, {0.0, 0.0, 0.0}, 45.0);
  const std::vector<DirectLight> lights = {sun(60.0, 200.0, 4.0, {2.0, 2.0, 2.0})};
  const Rendered rendered = renderWithOracle(s, cam, sh::ShRgb(3), sh::ShRgb(3), lights);
  double sum = 0.0, worst = 0.0, sumCentre = 0.0;
  int n = 0;
  for (const FloorShare& f : floorShares(s, cam, rendered, lights[0])) {
    if (f.centre <= 0.0 || f.centre >= 1.0) continue;  // the band: partly lit at the centre
    sum += std::abs(f.got - f.square);
    sumCentre += std::abs(f.got - f.centre);
    worst = std::max(worst, std::abs(f.got - f.square));
    ++n;
  }
  std::printf(
      "[ measured ] %d floor pixels in the penumbra: mean share error %.3f, worst %.3f (against the share at "
      "pixel centres: mean %.3f)\n",
      n, sum / n, worst, sumCentre / n);
  ASSERT_GT(n, 50);
  // PCSS takes the occluder as one plane at the blockers' mean depth and filters 16 samples
  // turned per pixel (binomial noise ≤ 0.125 per pixel): measured mean 0.042, worst 0.16.
  EXPECT_LT(sum / n, 0.05);
}

// A pixel straddling a hard shadow edge (a 0.265° sun) gets the share of its square, as a
// box-filtered reference (Cycles' box filter, --supersample) does, not the 0 or 1 at its centre:
// mean |rendered − traced| share over the floor pixels whose square the edge crosses.
TEST(RenderDirect, PixelsAcrossAHardShadowEdgeGetTheShareOfTheirSquare) {
  const Scene s = slabScene(3);
  const CameraView cam = lookAt({0.0, 2.6, 1.6}, {0.0, 0.0, 0.0}, 45.0);
  const std::vector<DirectLight> lights = {sun(50.0, 160.0, 0.265, {2.0, 2.0, 2.0})};
  const Rendered rendered = renderWithOracle(s, cam, sh::ShRgb(3), sh::ShRgb(3), lights);
  double sum = 0.0, sumCentre = 0.0;
  int n = 0;
  for (const FloorShare& f : floorShares(s, cam, rendered, lights[0])) {
    if (f.square <= 0.0 || f.square >= 1.0) continue;  // the edge misses the square
    sum += std::abs(f.got - f.square);
    sumCentre += std::abs(f.centre - f.square);
    ++n;
  }
  std::printf(
      "[ measured ] %d floor pixels across the edge: mean share error %.3f (the share at their centres: "
      "%.3f)\n",
      n, sum / n, sumCentre / n);
  ASSERT_GT(n, 40);
  // Sampling the centre alone is off by a quarter on average (a straight edge across a square);
  // 16 samples over the square less than a tenth.
  EXPECT_GT(sumCentre / n, 0.15);
  EXPECT_LT(sum / n, 0.08);
}

// A wall of no thickness standing on a floor, the sun high behind it: the floor along the
// contact line is in the wall's shadow, but the filter's samples beyond the line find nothing
// in the map (the floor's tangent plane runs on under the wall). They must not count as lit:
// every floor pixel whose square's floor part the oracle finds wholly shadowed gets no direct
// light, the pixels whose square the contact line crosses among them.
TEST(RenderDirect, NoLightLeaksAlongAContactLine) {
  // The floor ends at the wall, as in a room of single-sided walls: behind it the map is empty.
  MeshInstance floor = makeQuad("floor", {-1.5f, 0.0f, 1.5f}, {3.0f, 0.0f, 0.0f}, {0.0f, 0.0f, -1.5f}, 6, 3);
  MeshInstance wall = makeQuad("wall", {-1.5f, 0.0f, 0.0f}, {3.0f, 0.0f, 0.0f}, {0.0f, 1.2f, 0.0f}, 6, 2);  // faces +Z
  fillTransfer(floor, 3, 31);
  fillTransfer(wall, 3, 32);
  const Scene s = greyScene("contact", {floor, wall});
  const CameraView cam = lookAt({0.4, 1.0, 1.6}, {0.0, 0.1, 0.0}, 50.0);
  // From −Z, behind the wall; 1° wide, so that the blocker search reaches a few cm around a point.
  const std::vector<DirectLight> lights = {sun(75.0, 200.0, 1.0, {2.0, 2.0, 2.0})};
  const Rendered rendered = renderWithOracle(s, cam, sh::ShRgb(3), sh::ShRgb(3), lights);
  const bake::RayScene rays(s);
  const std::vector<OraclePixel>& o = rendered.oracle;
  const double unshadowed = 0.8 * kInvPi * 2.0 * directCosineFactor(lights[0], glm::dvec3(0.0, 1.0, 0.0));
  int umbra = 0, touching = 0;
  double worst = 0.0;
  for (int py = 1; py + 1 < kH; ++py)
    for (int px = 1; px + 1 < kW; ++px) {
      const OraclePixel& q = o[size_t(py) * kW + px];
      if (!q.s.hit || q.s.mesh != 0 || q.share[0] != 0.0) continue;
      if (footprintShare(s, rays, cam, kW, kH, px, py, 0, lights[0], 4, true) != 0.0) continue;
      ++umbra;
      touching += footprintShare(s, rays, cam, kW, kH, px, py, 0, lights[0], 4) < 0.0;  // the square holds wall too
      worst = std::max(worst, double(rendered.image.at(px, py).x) / unshadowed);
    }
  std::printf(
      "[ measured ] %d floor pixels wholly in the wall's shadow (%d across the contact line): largest share %.3g\n",
      umbra, touching, worst);
  ASSERT_GT(umbra, 200);
  ASSERT_GT(touching, 20);
  // Measured 0 (with the empty samples voting lit: 0.5 on the pixels across the line).
  EXPECT_LE(worst, 1e-6);
}

// A receiver (left out of the bake, lit from probes) casts its sun shadow on the baked floor and
// is shadowed by a baked wall: floor pixels agree with the oracle traced with the receiver in
// place; the receiver's direct term (its frame minus the frame without the direct light, the SH
// part being equal) agrees with the oracle's on the receiver, 0 in the wall's shadow.
TEST(RenderDirect, ReceiverCastsAndReceivesSunShadows) {
  MeshInstance floor = makeQuad("floor", {-1.5f, 0.0f, 1.5f}, {3.0f, 0.0f, 0.0f}, {0.0f, 0.0f, -3.0f}, 6, 6);
  MeshInstance wall = box("wall", {0.4f, 0.0f, -1.5f}, {0.5f, 1.5f, 0.0f});
  MeshInstance cube = box("cube", {-0.55f, 0.3f, -0.25f}, {-0.05f, 0.8f, 0.25f});
  fillTransfer(floor, 3, 1);
  fillTransfer(wall, 3, 2);
  cube.receiverOnly = true;
  const Scene s = greyScene("receiver", {floor, wall, cube});
  bake::ProbeSettings ps;
  ps.dims = glm::ivec3(4);
  ps.samples = 256;
  ps.bounces = 0;
  const ProbeGrid grid = bake::bakeProbes(s, {}, ps);
  ASSERT_TRUE(grid.hasDirect());

  // The oracle's scene: the cube in place as an occluder (it does not move here).
  Scene traced = s;
  traced.meshes[2].receiverOnly = false;
  const bake::RayScene rays(traced);
  const CameraView cam = lookAt({1.6, 2.0, 2.4}, {-0.3, 0.3, -0.1}, 50.0);
  const sh::ShRgb light = randomLight(3, 8, 1.0f), zero(3);
  // Sun from +X, 50° up: the wall (x = 0.4..0.5, z < 0, 1.5 m high) shadows the half z < 0 of
  // the cube's top and +X face; the cube's shadow falls on the floor between x ≈ −1.2 and −0.3,
  // its half z > 0 beside the wall's shadow.
  const std::vector<DirectLight> lights = {sun(50.0, 90.0, 0.265, {5.0, 5.0, 5.0})};
  const std::vector<OraclePixel> o = oracleFrame(traced, rays, cam, kW, kH, light, zero, lights);

  GlContext ctx(GlBackend::OSMesa, kW, kH);
  Renderer r(ctx, s);
  r.setProbes(grid);
  Frame f;
  f.camera = cam;
  f.light = light;
  f.directLight = zero;
  f.direct = lights;
  f.shadows.mapSize = 1024;
  const ImageRgb lit = r.render(f);
  EXPECT_EQ(r.lastFrame().directReceivers, 1u);
  Frame without = f;
  without.direct.clear();
  const ImageRgb sky = r.render(without);

  int floorCompared = 0, floorShadowedByCube = 0, cubeCompared = 0, cubeInShadow = 0;
  double floorWorst = 0.0, cubeWorst = 0.0;
  const double p = peak(o);
  const bake::RayScene withoutCube(s);  // the cube is a receiver there: not traced
  for (int py = 0; py < kH; ++py)
    for (int px = 0; px < kW; ++px) {
      if (!awayFromEdges(o, kW, kH, px, py)) continue;
      const OraclePixel& q = o[size_t(py) * kW + px];
      if (q.s.mesh == 0) {
        const glm::dvec3 want = q.shPart + q.direct[0];
        floorWorst = std::max(floorWorst, glm::length(glm::dvec3(lit.at(px, py)) - want) / p);
        ++floorCompared;
        // Shadowed by the cube: lit again when the cube is taken out of the traced scene.
        if (q.share[0] == 0.0 && visibleShare(withoutCube, q.s.x, q.s.n, lights[0]) == 1.0) ++floorShadowedByCube;
      } else if (q.s.mesh == 2) {
        const glm::dvec3 got = glm::dvec3(lit.at(px, py)) - glm::dvec3(sky.at(px, py));
        cubeWorst = std::max(cubeWorst, glm::length(got - q.direct[0]) / p);
        ++cubeCompared;
        if (q.share[0] == 0.0 && directCosineFactor(lights[0], q.s.n) > 0.0) ++cubeInShadow;
      }
    }
  std::printf(
      "[ measured ] floor: %d pixels, %d in the cube's shadow, worst %.3g; cube: %d pixels, %d in the "
      "wall's shadow, worst %.3g (of the peak)\n",
      floorCompared, floorShadowedByCube, floorWorst, cubeCompared, cubeInShadow, cubeWorst);
  EXPECT_GT(floorShadowedByCube, 20);
  EXPECT_GT(cubeInShadow, 5);
  EXPECT_GT(cubeCompared, 40);
  EXPECT_LE(floorWorst, 1e-4);  // as in MatchesRayTracedOracleAwayFromShadowEdges
  EXPECT_LE(cubeWorst, 1e-4);
}

// The same frame twice, and on a second renderer: bit-identical (the filter's rotation is a
// function of the pixel, not of time or threads).
TEST(RenderDirect, FramesAreDeterministic) {
  const Scene s = slabScene(3);
  const CameraView cam = lookAt({0.0, 2.6, 1.6}, {0.0, 0.0, 0.0}, 45.0);
  Frame f;
  f.camera = cam;
  f.light = randomLight(3, 1, 1.0f);
  f.directLight = randomLight(3, 2, 0.2f);
  f.direct = {sun(60.0, 200.0, 4.0, {2.0, 2.0, 2.0}), sun(40.0, 20.0, 0.265, {1.0, 1.0, 1.0})};
  f.shadows.mapSize = 512;
  GlContext ctx(GlBackend::OSMesa, kW, kH);
  Renderer a(ctx, s), b(ctx, s);
  const ImageRgb first = a.render(f), second = a.render(f), other = b.render(f);
  EXPECT_EQ(first.pixels, second.pixels);
  EXPECT_EQ(first.pixels, other.pixels);
}

// A bake without the direct part (an older prt): the direct lights go through SH (the frame
// equals the one with light + directSh and no direct light) and one warning says so, once.
TEST(RenderDirect, OlderBakeLightsDirectLightsThroughSh) {
  Scene s = slabScene(3);
  for (MeshInstance& m : s.meshes) m.transferDirect.clear();
  GlContext ctx(GlBackend::OSMesa, kW, kH);
  Renderer r(ctx, s);
  EXPECT_FALSE(r.bakedDirectPart());
  Frame f;
  f.camera = lookAt({0.0, 2.6, 1.6}, {0.0, 0.0, 0.0}, 45.0);
  f.light = randomLight(3, 1, 1.0f);
  f.directLight = randomLight(3, 2, 0.2f);
  f.direct = {sun(60.0, 200.0, 4.0, {2.0, 2.0, 2.0})};
  const size_t before = r.warnings().size();
  const ImageRgb split = r.render(f);
  r.render(f);
  EXPECT_EQ(r.warnings().size(), before + 1);
  EXPECT_NE(r.warnings().back().find("no direct part"), std::string::npos) << r.warnings().back();
  EXPECT_EQ(r.lastFrame().directBaked, 0u);
  Frame folded = f;
  folded.light += f.directLight;
  folded.directLight = sh::ShRgb();
  folded.direct.clear();
  EXPECT_EQ(split.pixels, r.render(folded).pixels);
}

// A gathered bounce (Frame::directBounce, prt::bake::DirectBounce) replaces the direct lights'
// bounce through SH: with it given, directLight no longer reaches the baked surfaces (a zero
// bounce gives the frame of a zero directLight, bit for bit), and a bounce of X at every vertex
// adds ρ/π · X to every pixel of the baked surfaces, whatever its material (0.8 grey or the
// warm slab); a bounce of the wrong size is an error naming the instance.
TEST(RenderDirect, GatheredBounceReplacesTheBounceThroughSh) {
  const Scene s = slabScene(3);
  GlContext ctx(GlBackend::OSMesa, kW, kH);
  Renderer r(ctx, s);
  Frame f;
  f.camera = lookAt({0.0, 2.6, 1.6}, {0.0, 0.0, 0.0}, 45.0);
  f.light = randomLight(3, 1, 1.0f);
  f.direct = {sun(60.0, 200.0, 4.0, {2.0, 2.0, 2.0})};
  f.shadows.mapSize = 512;
  f.directLight = sh::ShRgb(3);
  const ImageRgb plain = r.render(f);
  std::vector<std::vector<glm::vec3>> zeros, lifted, back(s.meshes.size());
  const glm::vec3 x(0.3f, 0.2f, 0.1f);
  for (const MeshInstance& m : s.meshes) {
    zeros.emplace_back(m.vertexCount(), glm::vec3(0.0f));
    lifted.emplace_back(m.vertexCount(), x);
  }
  f.directLight = randomLight(3, 2, 0.5f);
  const ImageRgb withSh = r.render(f);
  EXPECT_NE(withSh.pixels, plain.pixels);  // the bounce through SH shows
  f.directBounce = &zeros;
  f.directBounceBack = &back;
  EXPECT_EQ(r.render(f).pixels, plain.pixels);
  // The pixels of the baked surfaces (those that differ) of `more` against `base`: each ρ/π · x
  // more, ρ the grey or the warm albedo. Returns how many.
  auto addedPixels = [&](const ImageRgb& more, const ImageRgb& base) {
    int n = 0;
    for (int py = 0; py < kH; ++py)
      for (int px = 0; px < kW; ++px) {
        const glm::vec3 d = more.at(px, py) - base.at(px, py);
        if (d == glm::vec3(0.0f)) continue;  // background
        const glm::vec3 grey = glm::vec3(0.8f) * x * float(kInvPi),
                        warm = glm::vec3(0.9f, 0.6f, 0.4f) * x * float(kInvPi);
        EXPECT_LT(std::min(glm::length(d - grey), glm::length(d - warm)), 2e-5f)
            << "pixel " << px << "," << py << ": " << d.x << " " << d.y << " " << d.z;
        ++n;
      }
    return n;
  };
  f.directBounce = &lifted;
  EXPECT_GT(addedPixels(r.render(f), plain), kW * kH / 2);
  // Without direct lights (a sky whose detail is gathered: docs/lights.md, "Sky detail") the
  // gathered irradiance is added just the same: X more than the frame of the SH light alone.
  {
    Frame g = f;
    g.direct.clear();
    g.directLight = sh::ShRgb(3);
    g.directBounce = nullptr;
    const ImageRgb skyOnly = r.render(g);
    g.directBounce = &lifted;
    EXPECT_GT(addedPixels(r.render(g), skyOnly), kW * kH / 2);
    g.directBounce = &zeros;
    EXPECT_EQ(r.render(g).pixels, skyOnly.pixels);
  }
  f.directBounce = nullptr;  // no bounce given again: the buffers are zero, the plain frame
  f.directLight = sh::ShRgb(3);
  EXPECT_EQ(r.render(f).pixels, plain.pixels);
  std::vector<std::vector<glm::vec3>> shortOne = zeros;
  shortOne[1].pop_back();
  f.directBounce = &shortOne;
  try {
    r.render(f);
    FAIL() << "a bounce of the wrong size was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("instance 1"), std::string::npos) << e.what();
  }
}

// A MASK cutout casts the shadow of its solid part only: a floor under a 1.2 m quad whose alpha
// is a checker (2 × 2 texels repeated twice: 4 × 4 cells of 0.3 m, half of them cut), a sun
// overhead. The oracle's shadow rays go through the cuts (RayScene's alpha filter, as the
// bake's do); the shadow map must too: away from edges within 1e-4 of the peak, with floor
// pixels lit through the holes and others in the solid cells' shadow, both under the quad. A
// solid caster (the shadow map before cutouts) would leave every one of them dark.
TEST(RenderDirect, MaskCutoutsCastTheShadowOfTheirSolidPart) {
  Scene s;
  s.path = "cutout";
  Material grey, mask;
  grey.baseColorFactor = glm::vec4(0.8f, 0.8f, 0.8f, 1.0f);
  mask.baseColorFactor = glm::vec4(0.9f, 0.6f, 0.4f, 1.0f);
  mask.alphaMode = Material::AlphaMode::Mask;
  mask.baseColorTexture = 0;
  s.materials = {grey, mask};
  Texture checker;
  checker.name = "checker";
  checker.width = checker.height = 2;
  checker.texels = {glm::vec4(1, 1, 1, 1), glm::vec4(1, 1, 1, 0), glm::vec4(1, 1, 1, 0), glm::vec4(1, 1, 1, 1)};
  s.textures.push_back(checker);
  MeshInstance floor = makeQuad("floor", {-1.5f, 0.0f, 1.5f}, {3.0f, 0.0f, 0.0f}, {0.0f, 0.0f, -3.0f}, 6, 6);
  floor.material = 0;
  MeshInstance lid = makeQuad("lid", {-0.6f, 0.8f, 0.6f}, {1.2f, 0.0f, 0.0f}, {0.0f, 0.0f, -1.2f}, 1, 1);
  lid.material = 1;
  for (const glm::vec3& q : lid.positions) lid.texcoords.push_back({(q.x + 0.6f) / 0.6f, (q.z + 0.6f) / 0.6f});
  s.meshes = {floor, lid};
  for (size_t k = 0; k < s.meshes.size(); ++k) fillTransfer(s.meshes[k], 3, uint32_t(31 + k));
  s.transferBands = 3;
  updateBounds(s);
  const CameraView cam = lookAt({0.0, 2.4, 2.2}, {0.0, 0.0, 0.0}, 50.0);
  const std::vector<DirectLight> lights = {sun(80.0, 30.0, 0.265, {4.0, 3.5, 3.0})};
  const Rendered rendered = renderWithOracle(s, cam, randomLight(3, 5, 1.0f), randomLight(3, 6, 0.3f), lights);
  const std::vector<OraclePixel>& o = rendered.oracle;
  const Check c = compareAwayFromEdges(rendered.image, o, kW, kH);
  int throughHoles = 0, underSolid = 0;
  const glm::dvec3 d = glm::normalize(lights[0].direction);
  for (int py = 0; py < kH; ++py)
    for (int px = 0; px < kW; ++px) {
      const OraclePixel& q = o[size_t(py) * kW + px];
      if (!awayFromEdges(o, kW, kH, px, py) || q.s.mesh != 0) continue;
      const glm::dvec3 atLid = q.s.x + d * ((0.8 - q.s.x.y) / d.y);  // the shadow ray at the lid's height
      if (std::abs(atLid.x) > 0.6 || std::abs(atLid.z) > 0.6) continue;
      (q.share[0] == 1.0 ? throughHoles : underSolid)++;
    }
  std::printf(
      "[ measured ] %d pixels compared, worst %.3g of the peak; under the lid %d lit through its holes, %d "
      "in the shadow of its solid cells\n",
      c.compared, c.maxError, throughHoles, underSolid);
  EXPECT_GT(throughHoles, 30);
  EXPECT_GT(underSolid, 30);
  EXPECT_LE(c.maxError, 1e-4);
}

// A BLEND layer of opacity a casts a partial shadow of 1 − a of the light on average, as the
// bake's rays and the oracle's (a coin per ray) do: a 1.2 m lid of alpha 0.5 at 0.8 m over a
// floor, a disk light of 3° at 60°, the SH light zero, the camera below the lid (so no pixel is
// seen through it). The shadow map's per-texel coin (the depth pass's hash) and the PCSS filter
// (16 samples over a penumbra disk of about 4 cm, some 15 texels wide) give each pixel a noisy
// share; over the pixels whose shadow ray meets the lid at least 0.1 m from its edge (> 300),
// the mean share must be 0.5 within 0.03. Were each pixel a single coin, the mean's noise
// would be 0.5/√300 = 0.029; with 16 samples of distinct texels it is 0.007: 0.03 is 4σ of
// that, and allows for the hash's own bias. A BLEND caster that casts nothing (the maps before
// cutouts) gives 1, a solid one 0.
TEST(RenderDirect, BlendedLayerCastsThePartialShadowOfItsOpacity) {
  Scene s;
  s.path = "blend";
  Material grey, glass;
  grey.baseColorFactor = glm::vec4(0.8f, 0.8f, 0.8f, 1.0f);
  glass.baseColorFactor = glm::vec4(0.9f, 0.6f, 0.4f, 0.5f);
  glass.alphaMode = Material::AlphaMode::Blend;
  s.materials = {grey, glass};
  MeshInstance floor = makeQuad("floor", {-2.0f, 0.0f, 2.0f}, {4.0f, 0.0f, 0.0f}, {0.0f, 0.0f, -4.0f}, 8, 8);
  floor.material = 0;
  MeshInstance lid = makeQuad("lid", {-0.6f, 0.8f, 0.6f}, {1.2f, 0.0f, 0.0f}, {0.0f, 0.0f, -1.2f}, 1, 1);
  lid.material = 1;
  s.meshes = {floor, lid};
  for (size_t k = 0; k < s.meshes.size(); ++k) fillTransfer(s.meshes[k], 3, uint32_t(41 + k));
  s.transferBands = 3;
  updateBounds(s);
  const std::vector<DirectLight> lights = {sun(60.0, 30.0, 3.0, {4.0, 3.5, 3.0})};
  const glm::dvec3 d = glm::normalize(lights[0].direction);
  // The lid's shadow on the floor is centred at −d_xz · 0.8 / d_y; the camera looks at it from
  // 0.45 m high, on the side away from the sun.
  const glm::dvec3 away = glm::normalize(glm::dvec3(-d.x, 0.0, -d.z));
  const glm::dvec3 centre = away * (0.8 * glm::length(glm::dvec2(d.x, d.z)) / d.y);
  const CameraView cam = lookAt(centre + away * 1.8 + glm::dvec3(0.0, 0.45, 0.0), centre, 40.0);
  const Rendered rendered = renderWithOracle(s, cam, sh::ShRgb(3), sh::ShRgb(3), lights);
  const double unshadowed = 0.8 * kInvPi * 3.5 * directCosineFactor(lights[0], glm::dvec3(0.0, 1.0, 0.0));
  double sumRender = 0.0, sumOracle = 0.0, lo = 1e30, hi = -1e30;
  int n = 0;
  for (int py = 0; py < kH; ++py)
    for (int px = 0; px < kW; ++px) {
      const OraclePixel& q = rendered.oracle[size_t(py) * kW + px];
      if (!q.s.hit || q.s.mesh != 0) continue;
      const glm::dvec3 atLid = q.s.x + d * ((0.8 - q.s.x.y) / d.y);
      if (std::abs(atLid.x) > 0.5 || std::abs(atLid.z) > 0.5) continue;
      const double share = double(rendered.image.at(px, py).g) / unshadowed;
      sumRender += share;
      sumOracle += q.share[0];
      lo = std::min(lo, share);
      hi = std::max(hi, share);
      ++n;
    }
  ASSERT_GT(n, 0);
  std::printf(
      "[ measured ] %d floor pixels in the lid's shadow: mean share %.4f (oracle %.4f), per pixel %.3f .. %.3f\n", n,
      sumRender / n, sumOracle / n, lo, hi);
  EXPECT_GT(n, 300);
  EXPECT_NEAR(sumOracle / n, 0.5, 0.01);  // the oracle's coin: 256 rays a pixel
  EXPECT_NEAR(sumRender / n, 0.5, 0.03);
  EXPECT_GE(lo, -1e-4);
  EXPECT_LE(hi, 1.0 + 1e-4);
}

// Texel snapping (docs/render.md, "Shadow maps"): while the camera moves, each map's texel grid
// stays where it is in the world, so shadow edges do not crawl. A camera walking 12 steps of
// 1.3 cm and 0.4° through the slab scene, two suns: between consecutive frames a layer keeps
// its texel size except where its side crosses a step of the ladder (rare: at most 3 of the
// 11 × layers pairs), and where it keeps it, every world point lies a whole number of texels
// apart in the two maps (without snapping, a fraction: the camera's offset). And the maps still
// cover what they must: points of the casters' box that the view sees land in their cascade's
// map at least 4 texels inside its border.
TEST(RenderDirect, ShadowMapTexelsStayPutWhileTheCameraMoves) {
  const std::vector<DirectLight> lights = {sun(50.0, 30.0, 0.265, {1.0, 1.0, 1.0}),
                                           sun(70.0, 200.0, 2.0, {1.0, 1.0, 1.0})};
  const glm::dvec3 lo(-1.5, 0.0, -1.5), hi(1.5, 1.4, 1.5);
  const double aspect = 4.0 / 3.0;
  const int height = 720, mapSize = 1024;
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  ShadowPlan prev;
  int pairs = 0, kept = 0, covered = 0;
  double worstFraction = 0.0, worstInset = 1e30;
  for (int step = 0; step < 12; ++step) {
    // Inside the box, looking across it: two cascades.
    const double a = glm::radians(0.4 * step);
    const glm::dvec3 eye(0.2 + 0.013 * step, 0.6, 1.3);
    const CameraView cam = lookAt(eye, eye + glm::dvec3(std::sin(a) - 0.1, -0.25, -std::cos(a)), 60.0);
    const ShadowPlan plan = planShadows(lights, cam, aspect, height, lo, hi, mapSize, 4);
    ASSERT_EQ(plan.layers.size(), lights.size() * size_t(plan.cascades));
    EXPECT_GE(plan.cascades, 2);
    if (step > 0 && prev.cascades == plan.cascades)
      for (size_t l = 0; l < plan.layers.size(); ++l) {
        const ShadowLayer &p = prev.layers[l], &q = plan.layers[l];
        ++pairs;
        if (p.texel != q.texel) continue;
        ++kept;
        for (int k = 0; k < 16; ++k) {
          const glm::dvec4 x(lo + (hi - lo) * glm::dvec3(u(rng), u(rng), u(rng)), 1.0);
          const glm::dvec2 d = (glm::dvec2(p.worldToMap * x) - glm::dvec2(q.worldToMap * x)) / q.texel;
          worstFraction = std::max({worstFraction, std::abs(d.x - std::round(d.x)), std::abs(d.y - std::round(d.y))});
        }
      }
    // Coverage: box points in the view, in the map of their cascade.
    const glm::dmat4 toCamera = glm::inverse(cam.cameraToWorld);
    const double tanY = std::tan(0.5 * cam.yfov);
    for (int k = 0; k < 400; ++k) {
      const glm::dvec3 x = lo + (hi - lo) * glm::dvec3(u(rng), u(rng), u(rng));
      const glm::dvec3 c(toCamera * glm::dvec4(x, 1.0));
      const double depth = -c.z;
      if (depth <= cam.znear || std::abs(c.y) > depth * tanY || std::abs(c.x) > depth * tanY * aspect) continue;
      int cascade = 0;
      while (cascade + 1 < plan.cascades && depth >= plan.cascadeFar[cascade]) ++cascade;
      for (size_t l = 0; l < lights.size(); ++l) {
        const ShadowLayer& layer = plan.layers[l * size_t(plan.cascades) + size_t(cascade)];
        const glm::dvec3 m(layer.worldToMap * glm::dvec4(x, 1.0));
        worstInset = std::min({worstInset, m.x / layer.texel, m.y / layer.texel, (layer.side - m.x) / layer.texel,
                               (layer.side - m.y) / layer.texel});
        ++covered;
      }
    }
    prev = plan;
  }
  std::printf(
      "[ measured ] %d of %d consecutive layer pairs kept their texel; worst offset %.3g of a texel from a "
      "whole number; %d covered points, nearest %.1f texels from a map's border\n",
      kept, pairs, worstFraction, covered, worstInset);
  ASSERT_GT(pairs, 0);
  EXPECT_GE(kept, pairs - 3);
  EXPECT_LE(worstFraction, 1e-6);
  EXPECT_GT(covered, 200);
  EXPECT_GE(worstInset, 4.0);
}

TEST(RenderDirect, TooManyDirectLightsIsAnError) {
  const Scene s = slabScene(2);
  GlContext ctx(GlBackend::OSMesa, 16, 16);
  Renderer r(ctx, s);
  Frame f;
  f.camera = lookAt({0.0, 2.6, 1.6}, {0.0, 0.0, 0.0}, 45.0);
  f.light = sh::ShRgb(2);
  f.direct.assign(size_t(kMaxDirectLights) + 1, sun(60.0, 0.0, 0.265, {1.0, 1.0, 1.0}));
  EXPECT_THROW(r.render(f), Error);
  f.direct.resize(size_t(kMaxDirectLights));
  EXPECT_NO_THROW(r.render(f));
}

}  // namespace
}  // namespace prt::render
