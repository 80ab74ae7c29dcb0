// Alpha in the renderer (docs/render.md, "Alpha and transmission"): a MASK quad's cut-out
// pixels show what lies behind (here the background), its solid pixels the lit quad; BLEND
// and transmissive quads are blended over the opaque instances and the background with their
// opacity. Every pixel is compared with the value computed here at its centre.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>

#include "prt/light_rig.h"
#include "prt/math.h"
#include "prt/render/gl_context.h"
#include "prt/render/renderer.h"
#include "prt/scene.h"
#include "prt/sh.h"

namespace prt::render {
namespace {

constexpr int kSize = 64;
// The quads' half-side: with kSize pixels over [−1, 1], every cell edge (multiples of
// kHalf / 2) lies exactly 1/kSize from the nearest pixel centres, far from the 1/256 steps of
// a rasterizer's bilinear weights.
constexpr float kHalf = 0.75f;

// A square [x0, x1] × [−kHalf, kHalf] at depth z facing the camera (+Z), transfer t_00 = 1, and
// texture coordinates (x + kHalf, kHalf − y) / kHalf: a 2×2 texture repeated twice each way
// (4 × 4 cells of side kHalf / 2).
MeshInstance quad(float x0, float x1, float z, int material) {
  MeshInstance m;
  m.name = "quad";
  m.positions = {{x0, -kHalf, z}, {x1, -kHalf, z}, {x1, kHalf, z}, {x0, kHalf, z}};
  m.normals.assign(4, glm::vec3(0, 0, 1));
  for (const glm::vec3& p : m.positions) m.texcoords.push_back({(p.x + kHalf) / kHalf, (kHalf - p.y) / kHalf});
  m.indices = {0, 1, 2, 0, 2, 3};
  m.transfer.assign(4 * 4, glm::vec3(0.0f));
  for (size_t v = 0; v < 4; ++v) m.transfer[v * 4] = glm::vec3(1.0f);
  m.material = material;
  return m;
}

Scene sceneOf(std::vector<MeshInstance> meshes, std::vector<Material> materials) {
  Scene s;
  s.path = "alpha";
  s.transferBands = 2;
  s.meshes = std::move(meshes);
  s.materials = std::move(materials);
  // Alpha checker: texels (0,0) and (1,1) solid, the others clear; RGB white.
  Texture t;
  t.name = "checker";
  t.width = t.height = 2;
  t.texels = {glm::vec4(1, 1, 1, 1), glm::vec4(1, 1, 1, 0), glm::vec4(1, 1, 1, 0), glm::vec4(1, 1, 1, 1)};
  s.textures.push_back(t);
  s.boundsMin = glm::vec3(-1.0f, -1.0f, -4.0f);
  s.boundsMax = glm::vec3(1.0f, 1.0f, -3.0f);
  return s;
}

// Light l_00 = π: a quad of transfer t_00 = 1 shows exactly its albedo.
sh::ShRgb light() {
  sh::ShRgb l(2);
  l.c[0] = glm::vec3(float(prt::kPi));
  return l;
}

// Renders the scene orthographically down −Z over a uniform background and compares every
// pixel with want(x, y) at its centre (world x, y); pixels within 0.01 of an edge at
// x or y = multiples of kHalf / 2 are left out.
void expectPixels(const Scene& s, const RigBackground& bg, const std::function<glm::vec3(double, double)>& want,
                  const char* what) {
  for (GlBackend backend : {GlBackend::OSMesa, GlBackend::Egl}) {
    GlContext ctx(backend, kSize, kSize);
    Renderer r(ctx, s);
    Frame f;
    f.camera.perspective = false;
    f.camera.ymag = 1.0;
    f.light = light();
    f.background = &bg;
    const ImageRgb img = r.render(f);
    int compared = 0;
    double maxError = 0.0;
    for (int py = 0; py < kSize; ++py)
      for (int px = 0; px < kSize; ++px) {
        const double x = 2.0 * (px + 0.5) / kSize - 1.0, y = 1.0 - 2.0 * (py + 0.5) / kSize;
        const double cell = kHalf / 2.0;
        auto nearEdge = [&](double c) { return std::abs(c / cell - std::round(c / cell)) * cell < 0.01; };
        if (nearEdge(x) || nearEdge(y)) continue;
        const glm::vec3 w = want(x, y), got = img.at(px, py);
        for (int c = 0; c < 3; ++c) {
          EXPECT_NEAR(got[c], w[c], 1e-5f) << what << " pixel " << px << "," << py;
          maxError = std::max(maxError, double(std::abs(got[c] - w[c])));
        }
        ++compared;
      }
    std::printf("%s, %s: %d pixels compared, max error %.2g\n", what, glBackendName(backend), compared, maxError);
    EXPECT_GT(compared, kSize * kSize / 2);
  }
}

RigBackground uniformBackground() {
  RigBackground bg;
  bg.uniform = glm::dvec3(0.2, 0.3, 0.4);
  return bg;
}

bool insideQuad(double x, double y, double x0, double x1) { return x > x0 && x < x1 && std::abs(y) < kHalf; }

TEST(RenderAlpha, MaskCutoutsShowTheBackground) {
  Material mask;
  mask.baseColorFactor = glm::vec4(0.5f, 0.7f, 0.9f, 1.0f);
  mask.baseColorTexture = 0;
  mask.alphaMode = Material::AlphaMode::Mask;
  const Scene s = sceneOf({quad(-kHalf, kHalf, -3.0f, 0)}, {mask});
  const RigBackground bg = uniformBackground();
  int solid = 0, cut = 0;
  expectPixels(
      s, bg,
      [&](double x, double y) {
        if (!insideQuad(x, y, -kHalf, kHalf)) return glm::vec3(bg.uniform);
        // Cell (i, j) in texture space; texel (i mod 2, j mod 2) is solid where i + j is even.
        const int i = int(std::floor((x + kHalf) / (kHalf / 2))), j = int(std::floor((kHalf - y) / (kHalf / 2)));
        const bool isSolid = (i + j) % 2 == 0;
        (isSolid ? solid : cut)++;
        return isSolid ? glm::vec3(mask.baseColorFactor) : glm::vec3(bg.uniform);
      },
      "mask");
  EXPECT_GT(solid, 500);
  EXPECT_GT(cut, 500);
}

// A front quad of opacity α (first in the scene, so drawn blended after the opaque pass, not in
// list order) over the right half of an opaque back quad: α c_front + (1 − α) (c_back or the
// background).
struct BlendCase {
  const char* name;
  Material::AlphaMode mode;
  float alpha, transmission, opacity;
};

void PrintTo(const BlendCase& c, std::ostream* os) { *os << c.name; }

class RenderAlphaBlend : public ::testing::TestWithParam<BlendCase> {};

TEST_P(RenderAlphaBlend, IsBlendedOverWhatLiesBehind) {
  const BlendCase& c = GetParam();
  Material front, back;
  front.baseColorFactor = glm::vec4(0.9f, 0.6f, 0.1f, c.alpha);
  front.alphaMode = c.mode;
  front.transmissionFactor = c.transmission;
  back.baseColorFactor = glm::vec4(0.1f, 0.8f, 0.3f, 1.0f);
  const Scene s = sceneOf({quad(-kHalf, kHalf, -3.0f, 0), quad(0.0f, 0.9375f, -3.5f, 1)}, {front, back});
  const RigBackground bg = uniformBackground();
  expectPixels(
      s, bg,
      [&](double x, double y) {
        const glm::vec3 behind =
            insideQuad(x, y, 0.0, 0.9375) ? glm::vec3(back.baseColorFactor) : glm::vec3(bg.uniform);
        if (!insideQuad(x, y, -kHalf, kHalf)) return behind;
        return c.opacity * glm::vec3(front.baseColorFactor) + (1.0f - c.opacity) * behind;
      },
      c.name);
}

INSTANTIATE_TEST_SUITE_P(Materials, RenderAlphaBlend,
                         ::testing::Values(BlendCase{"blend", Material::AlphaMode::Blend, 0.3f, 0.0f, 0.3f},
                                           BlendCase{"transmission", Material::AlphaMode::Opaque, 0.3f, 0.25f, 0.75f},
                                           BlendCase{"blend_transmission", Material::AlphaMode::Blend, 0.5f, 0.5f,
                                                     0.25f}),
                         [](const ::testing::TestParamInfo<BlendCase>& c) { return std::string(c.param.name); });

// KHR_materials_transmission with a texture: the transmission is factor × the texture's R
// (not G or B), so factor 0.8 and a texture of R = 0.25 (G = B = 1) let 20% of the background
// through: opacity 0.8, where the factor alone would give 0.2. (One texel: the bilinear
// filter's 8-bit weights would blur a checker's cells beyond the 1e-5 compared here.)
TEST(RenderAlpha, TransmissionTextureScalesTheTransmission) {
  Material glass;
  glass.baseColorFactor = glm::vec4(0.5f, 0.7f, 0.9f, 1.0f);
  glass.transmissionFactor = 0.8f;
  glass.transmissionTexture = 1;
  Scene s = sceneOf({quad(-kHalf, kHalf, -3.0f, 0)}, {glass});
  Texture r;
  r.name = "transmission";
  r.width = r.height = 1;
  r.texels = {glm::vec4(0.25f, 1.0f, 1.0f, 1.0f)};
  s.textures.push_back(r);
  const RigBackground bg = uniformBackground();
  expectPixels(
      s, bg,
      [&](double x, double y) {
        if (!insideQuad(x, y, -kHalf, kHalf)) return glm::vec3(bg.uniform);
        return 0.8f * glm::vec3(glass.baseColorFactor) + 0.2f * glm::vec3(bg.uniform);
      },
      "transmission texture");
}

// Two blended layers drawn back to front whatever their order in the scene: the near quad
// (opacity 0.4, first in the scene) and a far one (opacity 0.6) over the right half, over the
// background: α_n c_n + (1 − α_n)(α_f c_f + (1 − α_f) bg) where they overlap. Drawn in scene
// order instead, the far layer would cover the near one: off by tens of percent.
TEST(RenderAlpha, BlendedLayersAreDrawnBackToFront) {
  Material nearM, farM;
  nearM.baseColorFactor = glm::vec4(0.9f, 0.6f, 0.1f, 0.4f);
  nearM.alphaMode = Material::AlphaMode::Blend;
  farM.baseColorFactor = glm::vec4(0.1f, 0.3f, 0.8f, 0.6f);
  farM.alphaMode = Material::AlphaMode::Blend;
  const Scene s = sceneOf({quad(-kHalf, kHalf, -3.0f, 0), quad(0.0f, 0.9375f, -3.5f, 1)}, {nearM, farM});
  const RigBackground bg = uniformBackground();
  expectPixels(
      s, bg,
      [&](double x, double y) {
        glm::vec3 c(bg.uniform);
        if (insideQuad(x, y, 0.0, 0.9375)) c = 0.6f * glm::vec3(farM.baseColorFactor) + 0.4f * c;
        if (insideQuad(x, y, -kHalf, kHalf)) c = 0.4f * glm::vec3(nearM.baseColorFactor) + 0.6f * c;
        return c;
      },
      "two layers");
}

}  // namespace
}  // namespace prt::render
