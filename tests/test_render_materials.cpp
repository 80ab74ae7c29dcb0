// render/: the glTF metallic-roughness material (MaterialShading::Full; docs/render.md,
// "Materials") checked against prt::brdf, the CPU maths of the same BRDF: the split sum under a
// uniform sky (a white furnace) against Monte Carlo integration, the prefiltered map against the
// GGX lobe's average, a sun's highlight on a plane against the formula at every pixel centre, a
// normal map against the same normal as geometry, bad material input, determinism, OSMesa = EGL.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>

#include <gtest/gtest.h>
#include <glm/gtc/matrix_transform.hpp>

#include "environment_prefilter.h"
#include "prt/brdf.h"
#include "prt/light.h"
#include "prt/math.h"
#include "prt/render/gl_context.h"
#include "prt/render/renderer.h"

namespace prt::render {
namespace {

constexpr double kY00 = 0.28209479177387814;  // the constant SH basis function, 1/(2√π)

// A square of side 2·half in the plane y = 0, facing +y (counter-clockwise seen from above),
// baked with 3 bands as an unoccluded plane: t₀ = t⁰₀ = π Y₀₀ (the cosine lobe's constant
// coefficient), so a uniform sky of radiance L gives e = πL and an ambient visibility of 1.
MeshInstance plane(double half, const glm::vec3& normal = glm::vec3(0, 1, 0)) {
  MeshInstance m;
  m.name = "plane";
  const float h = float(half);
  m.positions = {{-h, 0, -h}, {h, 0, -h}, {h, 0, h}, {-h, 0, h}};
  m.normals.assign(4, glm::normalize(normal));
  m.texcoords = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
  m.indices = {0, 3, 2, 0, 2, 1};
  m.material = 0;
  m.transfer.assign(4 * 9, glm::vec3(0.0f));
  m.transferDirect.assign(4 * 9, 0.0f);
  for (size_t v = 0; v < 4; ++v) {
    m.transfer[v * 9] = glm::vec3(float(kPi * kY00));
    m.transferDirect[v * 9] = float(kPi * kY00);
  }
  return m;
}

Scene sceneOf(const MeshInstance& m, const Material& mat) {
  Scene s;
  s.path = "material-plane";
  s.meshes.push_back(m);
  s.materials.push_back(mat);
  s.transferBands = 3;
  s.boundsMin = glm::vec3(-2.0f, -0.1f, -2.0f);
  s.boundsMax = glm::vec3(2.0f, 0.1f, 2.0f);
  return s;
}

Material metal(const glm::vec3& base, float roughness) {
  Material mat;
  mat.name = "metal";
  mat.baseColorFactor = glm::vec4(base, 1.0f);
  mat.metallicFactor = 1.0f;
  mat.roughnessFactor = roughness;
  return mat;
}

// The SH of a uniform sky of radiance L: l₀ = L / Y₀₀.
sh::ShRgb uniformSky(double radiance) {
  sh::ShRgb l(3);
  l.c[0] = glm::vec3(float(radiance / kY00));
  return l;
}

// An orthographic view of the plane's centre from direction v (unit, towards the camera).
CameraView orthoFrom(const glm::dvec3& v) {
  CameraView c;
  const glm::dvec3 up = std::abs(v.y) > 0.99 ? glm::dvec3(0, 0, -1) : glm::dvec3(0, 1, 0);
  c.cameraToWorld = glm::inverse(glm::lookAt(3.0 * v, glm::dvec3(0.0), up));
  c.perspective = false;
  c.ymag = 0.25;
  c.znear = 0.1;
  c.zfar = 10.0;
  return c;
}

// ∫ f_spec(l, v) (n·l) dl for uniform radiance 1, n = (0, 0, 1), by importance sampling the GGX
// reflection (prt::brdf's sampler triplet), `samples` draws with a fixed seed.
glm::dvec3 specularAlbedo(const brdf::MetallicRoughness& m, double nDotV, int samples) {
  const glm::dvec3 n(0, 0, 1), v(std::sqrt(1.0 - nDotV * nDotV), 0.0, nDotV);
  const double alpha = m.roughness * m.roughness;
  std::mt19937_64 rng(42);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  glm::dvec3 sum(0.0);
  for (int i = 0; i < samples; ++i) {
    const glm::dvec3 l = brdf::sampleGgxReflection({u(rng), u(rng)}, v, alpha);
    if (l.z <= 0.0) continue;
    sum += brdf::evaluate(m, n, l, v).specular * l.z / brdf::pdfGgxReflection(l, v, alpha);
  }
  return sum / double(samples);
}

glm::dvec3 centre(const ImageRgb& img) { return glm::dvec3(img.at(img.width / 2, img.height / 2)); }

// White furnace: a white rough metal plane under a uniform sky of radiance 1 reflects its
// directional albedo ∫ V D (n·l) dl, which the split sum gives exactly up to its DFG table
// (uniform light: the prefiltered factor is 1 whatever the lobe). Monte Carlo with 200k GGX
// samples has a relative standard error under 0.2% (the weight 4 V (n·l)(v·h)/(n·h) varies little
// over the lobe); the table's bilinear interpolation between 32² entries adds up to ~0.5% where
// A changes fastest (grazing views): 1.5% bounds both with a margin. No pixel exceeds 1 (energy).
TEST(MaterialRender, WhiteFurnaceMetalMatchesMonteCarlo) {
  GlContext ctx(GlBackend::OSMesa, 16, 16);
  for (double roughness : {0.3, 0.6, 1.0}) {
    const Scene scene = sceneOf(plane(2.0), metal(glm::vec3(1.0f), float(roughness)));
    Renderer r(ctx, scene);
    RigBackground sky;
    sky.uniform = glm::dvec3(1.0);
    for (double degrees : {0.0, 45.0, 70.0}) {
      const double th = glm::radians(degrees);
      Frame f;
      f.camera = orthoFrom({std::sin(th), std::cos(th), 0.0});
      f.light = uniformSky(1.0);
      f.materials = MaterialShading::Full;
      f.environment = &sky;
      const glm::dvec3 got = centre(r.render(f));
      brdf::MetallicRoughness m;
      m.baseColor = glm::dvec3(1.0);
      m.metallic = 1.0;
      m.roughness = roughness;
      const glm::dvec3 want = specularAlbedo(m, std::cos(th), 200000);
      std::printf("  roughness %.1f, view %2.0f deg: split sum %.4f, Monte Carlo %.4f\n", roughness, degrees, got.x,
                  want.x);
      EXPECT_NEAR(got.x, want.x, 0.015 * want.x) << roughness << " " << degrees;
      EXPECT_LE(got.x, 1.0 + 1e-3);
    }
  }
}

// A grey dielectric under the same sky: the diffuse lobe gives baseColor·L (e = πL, albedo/π),
// the specular lobe s·(F0·A + B)·L; the specular part against Monte Carlo as above (1.5%: the
// same estimator and table), the sum within 1.5% of the specular part's share.
TEST(MaterialRender, WhiteFurnaceDielectricAddsItsSpecularLobe) {
  GlContext ctx(GlBackend::OSMesa, 16, 16);
  Material mat;
  mat.name = "grey";
  mat.baseColorFactor = glm::vec4(0.5f, 0.5f, 0.5f, 1.0f);
  mat.metallicFactor = 0.0f;
  mat.roughnessFactor = 0.5f;
  const Scene scene = sceneOf(plane(2.0), mat);
  Renderer r(ctx, scene);
  RigBackground sky;
  sky.uniform = glm::dvec3(1.0);
  Frame f;
  f.camera = orthoFrom({std::sin(0.6), std::cos(0.6), 0.0});
  f.light = uniformSky(1.0);
  f.materials = MaterialShading::Full;
  f.environment = &sky;
  const double got = centre(r.render(f)).x;
  brdf::MetallicRoughness m;
  m.baseColor = glm::dvec3(0.5);
  m.metallic = 0.0;
  m.roughness = 0.5;
  const double spec = specularAlbedo(m, std::cos(0.6), 200000).x;
  std::printf("  dielectric: rendered %.4f, diffuse 0.5 + specular %.4f\n", got, spec);
  EXPECT_NEAR(got, 0.5 + spec, 0.015 * spec + 1e-4);
  // The diffuse-only frame is the base colour alone.
  f.materials = MaterialShading::Diffuse;
  EXPECT_NEAR(centre(r.render(f)).x, 0.5, 1e-4);
}

// The prefiltered map against its definition: for a smooth map L(d) = 1 + 0.5 d_y + 0.3 d_x, the
// n·l-weighted mean of L over the GGX reflection lobe around r (n = v = r), by 100k GGX samples
// of the analytic L (standard error < 0.1%). The filtered importance sampling reads the map's
// box mips, exact for a linear function up to the equirectangular texels' curvature and the
// bilinear lookups: 1% bounds it (measured below 0.35% on the octahedral levels, poles included).
TEST(MaterialRender, PrefilteredMapIsTheLobeAverage) {
  ImageRgb map(128, 64);
  auto radiance = [](const glm::dvec3& d) { return 1.0 + 0.5 * d.y + 0.3 * d.x; };
  for (int y = 0; y < map.height; ++y)
    for (int x = 0; x < map.width; ++x)
      map.at(x, y) = glm::vec3(float(radiance(equirectDirection((x + 0.5) / map.width, (y + 0.5) / map.height))));
  const std::vector<ImageRgb> levels = prefilterEnvironment(map);
  ASSERT_EQ(levels.size(), size_t(kPrefilterLevels));
  EXPECT_EQ(levels[0].width, kPrefilterWidth);
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int k = 1; k < kPrefilterLevels; ++k) {
    const double alpha = std::pow(double(k) / (kPrefilterLevels - 1), 2.0);
    for (const glm::dvec3& r :
         {glm::dvec3(0, 1, 0), glm::normalize(glm::dvec3(1, 0.3, 0.2)), glm::normalize(glm::dvec3(-0.2, -0.5, 0.8))}) {
      const glm::dvec3 t =
          glm::normalize(glm::cross(std::abs(r.y) < 0.9 ? glm::dvec3(0, 1, 0) : glm::dvec3(1, 0, 0), r));
      const glm::dvec3 b = glm::cross(r, t);
      double sum = 0.0, weight = 0.0;
      for (int i = 0; i < 100000; ++i) {
        const glm::dvec3 hl = brdf::sampleGgxHalfVector({u(rng), u(rng)}, alpha);
        const glm::dvec3 h = hl.x * t + hl.y * b + hl.z * r;
        const glm::dvec3 l = 2.0 * glm::dot(r, h) * h - r;
        const double nl = glm::dot(r, l);
        if (nl <= 0.0) continue;
        sum += nl * radiance(l);
        weight += nl;
      }
      const double want = sum / weight, got = samplePrefiltered(levels, double(k), r).x;
      std::printf("  level %d, r (%.2f, %.2f, %.2f): prefiltered %.4f, lobe average %.4f\n", k, r.x, r.y, r.z, got,
                  want);
      EXPECT_NEAR(got, want, 0.01 * want) << "level " << k << " r " << r.x << "," << r.y << "," << r.z;
    }
  }
}

// The environment's reflection in the shader against the CPU's lookup of the same levels: a white
// metal plane (roughness 0.5) seen at 50° under two maps, the second turned and scaled (both
// compiled in: ENV_MAPS 2), then under one (the programs linked again). The pixel is
// (A + B)(n·v, roughness) × Σ scale · samplePrefiltered(levels, roughness · 5, world-to-map · r);
// (A, B) by prt::brdf::integrateDfg at the pixel's exact arguments, which the shader's 32² table
// interpolates to within 1% (the furnace above): 1.5%.
TEST(MaterialRender, EnvironmentReflectionMatchesTheCpuLookup) {
  GlContext ctx(GlBackend::OSMesa, 16, 16);
  ImageRgb map(64, 32);
  for (int y = 0; y < map.height; ++y)
    for (int x = 0; x < map.width; ++x) {
      const glm::dvec3 d = equirectDirection((x + 0.5) / map.width, (y + 0.5) / map.height);
      map.at(x, y) = glm::vec3(float(1.0 + d.y + 0.5 * d.x * d.z), 0.5f, float(0.2 + 0.1 * d.x));
    }
  auto image = std::make_shared<const ImageRgb>(map);
  const std::vector<ImageRgb> levels = prefilterEnvironment(map);
  RigBackground env;
  const glm::dmat3 turn = glm::dmat3(glm::rotate(glm::dmat4(1.0), 0.7, glm::dvec3(0, 1, 0)));
  env.maps = {{image, glm::dmat3(1.0), glm::dvec3(1.0)}, {image, turn, glm::dvec3(0.5, 1.0, 2.0)}};
  env.uniform = glm::dvec3(0.1);
  const Scene scene = sceneOf(plane(2.0), metal(glm::vec3(1.0f), 0.5f));
  Renderer r(ctx, scene);
  const double th = glm::radians(50.0);
  const glm::dvec3 v(0.0, std::cos(th), std::sin(th)), n(0, 1, 0), refl = 2.0 * glm::dot(n, v) * n - v;
  const glm::dvec2 ab = brdf::integrateDfg(std::cos(th), 0.5, 4096);
  for (size_t maps : {size_t(2), size_t(1)}) {
    env.maps.resize(maps);
    Frame f;
    f.camera = orthoFrom(v);
    f.light = sh::ShRgb(3);
    f.materials = MaterialShading::Full;
    f.environment = &env;
    const glm::dvec3 got = centre(r.render(f));
    glm::dvec3 want = env.uniform;
    for (const RigBackground::Map& m : env.maps) want += m.scale * samplePrefiltered(levels, 2.5, m.worldToMap * refl);
    want *= ab.x + ab.y;
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(got[c], want[c], 0.015 * want[c]) << maps << " maps, channel " << c;
  }
}

// From roughness 0.9 (shader_variants.h, kRoughSpecularRoughness) a material's environment
// specular is (A + B) · e/π, the diffuse light's mean radiance, not the prefiltered map: a white
// metal plane under an SH sky of radiance 1 (e/π = 1) and an environment of radiance 3 reflects 1
// at roughness 0.9 and 1, and 3 at roughness 0.85 (its specular occlusion is 1: nothing hides
// the plane's sky). (A + B) from integrateDfg with 4096 samples; 1.5% bounds the table's
// bilinear interpolation as in the white furnace.
TEST(MaterialRender, RoughLobesReflectTheDiffuseLight) {
  GlContext ctx(GlBackend::OSMesa, 16, 16);
  RigBackground env;
  env.uniform = glm::dvec3(3.0);
  const double th = glm::radians(40.0);
  for (double roughness : {0.85, 0.9, 1.0}) {
    const Scene scene = sceneOf(plane(2.0), metal(glm::vec3(1.0f), float(roughness)));
    Renderer r(ctx, scene);
    Frame f;
    f.camera = orthoFrom({std::sin(th), std::cos(th), 0.0});
    f.light = uniformSky(1.0);
    f.materials = MaterialShading::Full;
    f.environment = &env;
    const glm::dvec2 ab = brdf::integrateDfg(std::cos(th), roughness, 4096);
    const double want = (ab.x + ab.y) * (roughness < 0.9 ? 3.0 : 1.0);
    EXPECT_NEAR(centre(r.render(f)).x, want, 0.015 * want) << roughness;
  }
}

// The lobe's hidden share reflects what hides the sky at its mean radiance: a white metal plane
// (roughness 0.5) whose transfer says half its cosine-weighted sky is hidden (t⁰₀ = 0.5 π Y₀₀)
// and the surroundings send 0.3 of an unoccluded plane's light (t₀ = 0.8 π Y₀₀), under a sky
// and an environment of radiance 1: fill = (0.8 − 0.5) / (1 − 0.5) = 0.6, the pixel
// (A + B)(so + (1 − so) 0.6) with so Lagarde's at ao = 0.5 (e/π = 0.8 in the fill would be 10%
// more). 1.5%: the DFG table's interpolation, as in the white furnace.
TEST(MaterialRender, HiddenLobeReflectsWhatHidesTheSky) {
  GlContext ctx(GlBackend::OSMesa, 16, 16);
  MeshInstance m = plane(2.0);
  for (size_t v = 0; v < 4; ++v) {
    m.transfer[v * 9] = glm::vec3(float(0.8 * kPi * kY00));
    m.transferDirect[v * 9] = float(0.5 * kPi * kY00);
  }
  const Scene scene = sceneOf(m, metal(glm::vec3(1.0f), 0.5f));
  Renderer r(ctx, scene);
  RigBackground env;
  env.uniform = glm::dvec3(1.0);
  const double th = glm::radians(40.0), nv = std::cos(th), alpha = 0.25;
  Frame f;
  f.camera = orthoFrom({std::sin(th), nv, 0.0});
  f.light = uniformSky(1.0);
  f.materials = MaterialShading::Full;
  f.environment = &env;
  const glm::dvec2 ab = brdf::integrateDfg(nv, 0.5, 4096);
  const double so = std::clamp(std::pow(nv + 0.5, std::exp2(-16.0 * alpha - 1.0)) - 1.0 + 0.5, 0.0, 1.0);
  const double want = (ab.x + ab.y) * (so + (1.0 - so) * 0.6);
  EXPECT_NEAR(centre(r.render(f)).x, want, 0.015 * want);
}

// A sun's highlight on a copper plane (roughness 0.3, no sky): every pixel against
// E·(n·d)·f_spec(d, v) at its centre's ray (the formula, prt::brdf), the peak where that formula
// peaks (near the mirror point of the sun), its value within 1% (float maths on both sides; the
// pixel's world position is interpolated exactly on a plane).
struct Highlight {
  ImageRgb image;
  ImageRgb oracle;
};

constexpr int kHw = 96, kHh = 72;
const glm::dvec3 kEye(0.0, 1.5, 2.5), kSun = glm::normalize(glm::dvec3(0.0, 1.0, -0.8));

CameraView highlightCamera() {
  CameraView c;
  c.cameraToWorld = glm::inverse(glm::lookAt(kEye, glm::dvec3(0.0, 0.0, 0.3), glm::dvec3(0, 1, 0)));
  c.yfov = 0.9;
  c.znear = 0.1;
  return c;
}

Frame sunFrame() {
  Frame f;
  f.camera = highlightCamera();
  f.light = sh::ShRgb(3);
  f.directLight = sh::ShRgb(3);
  f.direct = {DirectLight{kSun, 0.0, glm::dvec3(2.0)}};
  f.shadows.enabled = false;
  f.materials = MaterialShading::Full;
  f.width = kHw;
  f.height = kHh;
  return f;
}

// Per pixel of the highlight camera that sees the plane (|x|, |z| <= 2): f(p, v), p where its
// centre's ray meets the plane and v the unit vector from p to the eye; 0 elsewhere.
template <class F>
ImageRgb overThePlane(F&& f) {
  ImageRgb out(kHw, kHh);
  const CameraView c = highlightCamera();
  const double t = std::tan(c.yfov / 2.0), aspect = double(kHw) / kHh;
  for (int y = 0; y < kHh; ++y)
    for (int x = 0; x < kHw; ++x) {
      const glm::dvec3 dirCam(((x + 0.5) / kHw * 2.0 - 1.0) * t * aspect, (1.0 - (y + 0.5) / kHh * 2.0) * t, -1.0);
      const glm::dvec3 dir = glm::dmat3(c.cameraToWorld) * dirCam;
      if (dir.y >= 0.0) continue;
      const glm::dvec3 p = kEye - dir * (kEye.y / dir.y);
      if (std::abs(p.x) > 2.0 || std::abs(p.z) > 2.0) continue;
      out.at(x, y) = glm::vec3(f(p, glm::normalize(kEye - p)));
    }
  return out;
}

ImageRgb highlightOracle(const brdf::MetallicRoughness& m) {
  const glm::dvec3 n(0, 1, 0);
  return overThePlane([&](const glm::dvec3&, const glm::dvec3& v) {
    return 2.0 * glm::dot(n, kSun) * brdf::evaluate(m, n, kSun, v).sum();
  });
}

// `got` against `want`: the peak on the same pixel (±1), its value within 1%, every pixel within
// 1% of the peak.
void expectHighlight(const ImageRgb& got, const ImageRgb& want, const char* what) {
  int gotPeak = 0, wantPeak = 0;
  for (size_t i = 0; i < got.pixels.size(); ++i) {
    if (got.pixels[i].x > got.pixels[size_t(gotPeak)].x) gotPeak = int(i);
    if (want.pixels[i].x > want.pixels[size_t(wantPeak)].x) wantPeak = int(i);
  }
  const double peak = want.pixels[size_t(wantPeak)].x;
  double maxError = 0.0;
  for (size_t i = 0; i < got.pixels.size(); ++i)
    maxError = std::max(maxError, double(glm::length(got.pixels[i] - want.pixels[i])) / peak);
  std::printf("  %s: peak at (%d, %d), formula's at (%d, %d): %.4f vs %.4f; max error %.2g of the peak\n", what,
              gotPeak % kHw, gotPeak / kHw, wantPeak % kHw, wantPeak / kHw, got.pixels[size_t(gotPeak)].x, peak,
              maxError);
  EXPECT_GT(peak, 0.1);
  EXPECT_LE(std::abs(gotPeak % kHw - wantPeak % kHw), 1);
  EXPECT_LE(std::abs(gotPeak / kHw - wantPeak / kHw), 1);
  EXPECT_NEAR(got.pixels[size_t(gotPeak)].x, peak, 0.01 * peak);
  EXPECT_LT(maxError, 0.01);
}

TEST(MaterialRender, SunHighlightOnAPlaneMatchesTheFormula) {
  GlContext ctx(GlBackend::OSMesa, kHw, kHh);
  const glm::vec3 copper(0.95f, 0.64f, 0.54f);
  const Scene scene = sceneOf(plane(2.0), metal(copper, 0.3f));
  Renderer r(ctx, scene);
  const ImageRgb got = r.render(sunFrame());
  brdf::MetallicRoughness m;
  m.baseColor = glm::dvec3(copper);
  m.metallic = 1.0;
  m.roughness = 0.3;
  expectHighlight(got, highlightOracle(m), "sun");
  // The closed form's peak: the mirror point of the sun seen from the eye, P = eye + (y/d_y)(d_x, −d_y, d_z).
  const glm::dvec3 mirror = kEye + (kEye.y / kSun.y) * glm::dvec3(kSun.x, -kSun.y, kSun.z);
  std::printf("  mirror point (%.3f, %.3f, %.3f)\n", mirror.x, mirror.y, mirror.z);
  // Determinism: the same frame twice, bit for bit.
  const ImageRgb again = r.render(sunFrame());
  EXPECT_EQ(got.pixels, again.pixels);
}

// A point lamp's highlight on the same copper plane (no sky, no sun, no shadows): every pixel
// against I (n·l) / r² · f_spec(l, v), l towards the lamp from the pixel's centre ray's point
// (the formula, prt::brdf), the peak on the formula's pixel, its value within 1%.
TEST(MaterialRender, PointLampHighlightOnAPlaneMatchesTheFormula) {
  GlContext ctx(GlBackend::OSMesa, kHw, kHh);
  const glm::vec3 copper(0.95f, 0.64f, 0.54f);
  const Scene scene = sceneOf(plane(2.0), metal(copper, 0.3f));
  Renderer r(ctx, scene);
  const glm::dvec3 lamp(0.2, 0.9, -0.7), intensity(1.5);
  Frame f = sunFrame();
  f.direct.clear();
  LocalLight point;
  point.type = LocalLight::Type::Point;
  point.position = lamp;
  point.intensity = intensity;
  f.local = {point};
  const ImageRgb got = r.render(f);
  brdf::MetallicRoughness m;
  m.baseColor = glm::dvec3(copper);
  m.metallic = 1.0;
  m.roughness = 0.3;
  const glm::dvec3 n(0, 1, 0);
  const ImageRgb want = overThePlane([&](const glm::dvec3& p, const glm::dvec3& v) {
    const glm::dvec3 d = lamp - p, l = glm::normalize(d);
    return intensity.x * glm::dot(n, l) / glm::dot(d, d) * brdf::evaluate(m, n, l, v).sum();
  });
  expectHighlight(got, want, "lamp");
}

// The same frame on EGL (surfaceless): both drive llvmpipe here, so the frames agree to float
// rounding (1e-5 of the peak).
// Screen-space reflections (Frame::screenReflections): a smooth white metal floor in front of a
// low grey wall (albedo 0.3), under a uniform sky of radiance 1 that lights both unoccluded (the
// planes' transfer holds no occlusion). Without the pass the floor reflects the sky: its pixels
// hold the lobe's weight W. With it, the floor's pixels whose mirror direction meets the wall
// reflect the wall as the bake's transport re-emits it, ρ E / π = 0.3 (E = π): their ratio to
// the frame without the pass is 0.3, within 2% (the footprint's mean is taken over the surfaces
// in it alone). Pixels whose mirror direction passes over the wall keep the sky, to float
// rounding. OSMesa and EGL agree.
TEST(MaterialRender, ScreenReflectionsShowTheWallTheMirrorDirectionMeets) {
  MeshInstance wall = plane(0.5, glm::vec3(0, 0, 1));
  wall.name = "wall";
  wall.material = 1;
  // The square turned upright into the plane z = −1, y ∈ [0, 1].
  for (glm::vec3& p : wall.positions) p = glm::vec3(p.x, p.z + 0.5f, -1.0f);
  wall.indices = {0, 2, 3, 0, 1, 2};  // counter-clockwise seen from +z
  Scene scene = sceneOf(plane(2.0), metal(glm::vec3(1.0f), 0.05f));
  Material grey;
  grey.name = "grey";
  grey.baseColorFactor = glm::vec4(0.3f, 0.3f, 0.3f, 1.0f);
  grey.metallicFactor = 0.0f;
  scene.materials.push_back(grey);
  scene.meshes.push_back(wall);
  scene.boundsMax.y = 1.0f;
  RigBackground sky;
  sky.uniform = glm::dvec3(1.0);
  Frame f;
  f.camera.cameraToWorld = glm::inverse(glm::lookAt(glm::dvec3(0, 1.2, 3.0), glm::dvec3(0, 0.6, -1.0), {0, 1, 0}));
  f.camera.yfov = glm::radians(50.0);
  f.camera.znear = 0.05;
  f.light = uniformSky(1.0);
  f.materials = MaterialShading::Full;
  f.environment = &sky;
  ImageRgb frames[3];
  for (int i = 0; i < 3; ++i) {
    GlContextOptions o;
    o.eglPlatform = EglPlatform::Surfaceless;
    GlContext ctx(i == 2 ? GlBackend::Egl : GlBackend::OSMesa, 96, 96, o);
    Renderer r(ctx, scene);
    f.screenReflections = i > 0;
    frames[i] = r.render(f);
  }
  const ImageRgb &off = frames[0], &on = frames[1];
  // The wall's radiance at its centre, and the floor's pixels along the image's middle column.
  const int x = 48;
  const double wallRadiance = 0.3;
  int reflected = 0, sky_ = 0;
  for (int y = 0; y < 96; ++y) {
    const double a = off.at(x, y).x, b = on.at(x, y).x;
    EXPECT_NEAR(on.at(x, y).x, frames[2].at(x, y).x, 1e-5) << y;
    if (a <= 0.0) continue;
    // The pixel's world point: on the floor when its ray from the camera goes down to y = 0.
    const glm::dvec3 eye(0, 1.2, 3.0);
    const glm::dvec4 ndc(0.0, 1.0 - 2.0 * (y + 0.5) / 96.0, 0.5, 1.0);
    const glm::dmat4 proj = glm::perspective(f.camera.yfov, 1.0, 0.05, 100.0);
    glm::dvec4 p = glm::inverse(proj * glm::inverse(f.camera.cameraToWorld)) * ndc;
    const glm::dvec3 dir = glm::normalize(glm::dvec3(p) / p.w - eye);
    if (dir.y >= 0.0) continue;
    const glm::dvec3 hit = eye + dir * (-eye.y / dir.y);
    if (hit.z < -0.95 || hit.z > 1.9) continue;  // on the floor, in front of the wall
    // Its mirror direction's height where it reaches the wall's plane z = −1.
    const glm::dvec3 r(dir.x, -dir.y, dir.z);
    const double yWall = hit.y + r.y * ((-1.0 - hit.z) / r.z);
    if (yWall > 0.1 && yWall < 0.85) {
      ++reflected;
      EXPECT_NEAR(b / a, wallRadiance, 0.02 * wallRadiance) << "row " << y << ", mirror meets the wall at " << yWall;
    } else if (yWall > 1.15) {
      ++sky_;
      EXPECT_NEAR(b, a, 1e-5 * a) << "row " << y << ": the mirror direction passes over the wall";
    }
  }
  std::printf("  %d floor pixels reflect the wall, %d the sky\n", reflected, sky_);
  EXPECT_GT(reflected, 5);
  EXPECT_GT(sky_, 1);
}

TEST(MaterialRender, OsMesaEqualsEgl) {
  const glm::vec3 copper(0.95f, 0.64f, 0.54f);
  const Scene scene = sceneOf(plane(2.0), metal(copper, 0.3f));
  ImageRgb frames[2];
  for (int i = 0; i < 2; ++i) {
    GlContextOptions o;
    o.eglPlatform = EglPlatform::Surfaceless;
    GlContext ctx(i ? GlBackend::Egl : GlBackend::OSMesa, kHw, kHh, o);
    Renderer r(ctx, scene);
    frames[i] = r.render(sunFrame());
  }
  double peak = 0.0, diff = 0.0;
  for (size_t i = 0; i < frames[0].pixels.size(); ++i) {
    peak = std::max(peak, double(frames[0].pixels[i].x));
    diff = std::max(diff, double(glm::length(frames[0].pixels[i] - frames[1].pixels[i])));
  }
  EXPECT_GT(peak, 0.1);
  EXPECT_LE(diff, 1e-5 * peak);
}

// A normal map holding one tilted normal, tangent-space (0.3, 0.4, √0.75), on a plane with
// tangent +x (handedness +1, so the bitangent is n × t = −z), against the same plane whose vertex
// normals are that normal, 0.3 x − 0.4 z + √0.75 y: the sun's light and highlight and the sky's
// reflection see one normal, so the frames agree to float rounding (1e-4 of the peak; the map's
// texel goes through 2x − 1).
TEST(MaterialRender, NormalMapTurnsTheShadingNormalAsGeometryWould) {
  GlContext ctx(GlBackend::OSMesa, kHw, kHh);
  Material mat;
  mat.name = "bumpy";
  mat.baseColorFactor = glm::vec4(0.6f, 0.6f, 0.6f, 1.0f);
  mat.metallicFactor = 0.0f;
  mat.roughnessFactor = 0.4f;
  const glm::dvec3 tn(0.3, 0.4, std::sqrt(0.75));
  const glm::dvec3 geometric =
      glm::normalize(tn.x * glm::dvec3(1, 0, 0) + tn.y * glm::dvec3(0, 0, -1) + tn.z * glm::dvec3(0, 1, 0));
  Scene mapped = sceneOf(plane(2.0), mat);
  Texture t;
  t.name = "normal";
  t.width = t.height = 1;
  t.texels = {glm::vec4(glm::vec3(0.5 * tn + 0.5), 1.0f)};
  mapped.textures.push_back(t);
  mapped.materials[0].normalTexture.texture = 0;
  mapped.meshes[0].tangents.assign(4, glm::vec4(1, 0, 0, 1));
  const Scene tilted = sceneOf(plane(2.0, glm::vec3(geometric)), mat);
  RigBackground sky;
  sky.uniform = glm::dvec3(0.5);
  Frame f = sunFrame();
  f.environment = &sky;
  ImageRgb a, b;
  {
    Renderer r(ctx, mapped);
    a = r.render(f);
    EXPECT_TRUE(r.warnings().empty());
  }
  {
    Renderer r(ctx, tilted);
    b = r.render(f);
  }
  double peak = 0.0, diff = 0.0;
  for (size_t i = 0; i < a.pixels.size(); ++i) {
    peak = std::max(peak, double(b.pixels[i].x));
    diff = std::max(diff, double(glm::length(a.pixels[i] - b.pixels[i])));
  }
  std::printf("  normal map vs tilted geometry: max difference %.2g of the peak %.3f\n", diff / peak, peak);
  EXPECT_GT(peak, 0.1);
  EXPECT_LE(diff, 1e-4 * peak);
}

// Bad material input: a normal map on an instance without tangents, a texture without texels.
// Each is one warning naming the material and what was done instead, and the frame is the one
// without that texture (the vertex normal, the factor alone): never black.
TEST(MaterialRender, BadTexturesWarnAndFallBackToTheFactor) {
  GlContext ctx(GlBackend::OSMesa, kHw, kHh);
  Material mat = metal(glm::vec3(0.9f, 0.8f, 0.7f), 0.5f);
  const Scene plain = sceneOf(plane(2.0), mat);
  Scene bad = plain;
  Texture empty;
  empty.name = "broken.png";
  bad.textures.push_back(empty);
  Texture normal;
  normal.name = "normal.png";
  normal.width = normal.height = 1;
  normal.texels = {glm::vec4(0.8f, 0.5f, 0.6f, 1.0f)};
  bad.textures.push_back(normal);
  bad.materials[0].metallicRoughnessTexture.texture = 0;
  bad.materials[0].normalTexture.texture = 1;  // and no tangents
  RigBackground sky;
  sky.uniform = glm::dvec3(0.5);
  Frame f = sunFrame();
  f.environment = &sky;
  f.light = uniformSky(0.5);
  ImageRgb want, got;
  {
    Renderer r(ctx, plain);
    want = r.render(f);
  }
  Renderer r(ctx, bad);
  got = r.render(f);
  const std::vector<std::string> w = r.warnings();
  ASSERT_EQ(w.size(), 2u);
  EXPECT_NE(w[0].find("material 'metal': metallicRoughnessTexture 'broken.png' holds no texels: its factor alone"),
            std::string::npos)
      << w[0];
  EXPECT_NE(w[1].find("material 'metal': normalTexture without tangents on instance 'plane': the vertex normal"),
            std::string::npos)
      << w[1];
  EXPECT_EQ(got.pixels, want.pixels);
  double mean = 0.0;
  for (const glm::vec3& p : got.pixels) mean += p.x;
  EXPECT_GT(mean / double(got.pixels.size()), 0.01);
}

// An instance without a material (and a plain one) under MaterialShading::Full is Lambertian:
// the same frame as Diffuse to float rounding.
TEST(MaterialRender, NoMaterialIsLambertianInFull) {
  GlContext ctx(GlBackend::OSMesa, kHw, kHh);
  MeshInstance m = plane(2.0);
  m.material = -1;
  Scene s = sceneOf(m, Material{});
  Renderer r(ctx, s);
  Frame f = sunFrame();
  f.light = uniformSky(0.7);
  const ImageRgb full = r.render(f);
  f.materials = MaterialShading::Diffuse;
  const ImageRgb diffuse = r.render(f);
  double diff = 0.0;
  for (size_t i = 0; i < full.pixels.size(); ++i)
    diff = std::max(diff, double(glm::length(full.pixels[i] - diffuse.pixels[i])));
  EXPECT_LE(diff, 1e-5);
}

}  // namespace
}  // namespace prt::render
