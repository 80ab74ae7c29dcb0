// Nodes moved by glTF animations are receivers without being marked (prt/scene.h,
// docs/render.md "Animation"): the surface bake leaves them out, as vertices and as occluders
// (a baked shadow would stay where the object was at rest), and the renderer draws them where
// the animation puts them at each frame's time, lit per pixel from the probe grid. Checked on a
// static floor with a cube sliding over it: the floor under the cube's rest pose keeps the
// unoccluded plane's closed-form transfer, and the cube's top face matches the CPU probe
// oracle (prt::interpolateRadiance + sh::irradiance) at its animated position, in process and
// through `prt bake` + `prt render`.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "gltf_file.h"
#include "harness.h"
#include "prt/bake/probe_bake.h"
#include "prt/bake/surface_bake.h"
#include "prt/image.h"
#include "prt/light_rig.h"
#include "prt/math.h"
#include "prt/probe_grid.h"
#include "prt/render/gl_context.h"
#include "prt/render/renderer.h"
#include "prt/scene.h"
#include "prt/sh.h"
#include "test_scenes.h"

namespace prt {
namespace {

namespace fs = std::filesystem;
using Json = nlohmann::json;
using test::GltfFile;

// ---------------------------------------------------------------------------------------------
// The scene: a floor (2 m square at y = 0, facing up, 16 × 16 cells) and a cube of side 0.4 m
// whose node rests at (0, 0.3, 0), 0.1 m above the floor's centre, and slides LINEAR from
// kStart at 0 s to kEnd at 2 s. An orthographic camera 'Top' looks straight down on it.

constexpr float kHalf = 0.2f;  // the cube's half side
const glm::dvec3 kRest(0.0, 0.3, 0.0);
const glm::dvec3 kStart(-0.5, 0.3, -0.1), kEnd(0.5, 0.5, 0.2);
const glm::vec3 kCubeAlbedo(0.8f, 0.6f, 0.4f);
constexpr double kInvPi = 0.31830988618379067;

glm::dvec3 cubeCentreAt(double t) { return kStart + std::clamp(t / 2.0, 0.0, 1.0) * (kEnd - kStart); }

/// Writes the scene into `dir`; `cubeExtras` go on the cube's node (null: none).
std::string writeCubeScene(const fs::path& dir, const std::string& name, bool withFloor, Json cubeExtras = nullptr) {
  GltfFile f;
  f.j["materials"] = Json::array(
      {{{"pbrMetallicRoughness",
         {{"baseColorFactor", {kCubeAlbedo.r, kCubeAlbedo.g, kCubeAlbedo.b, 1.0}}, {"metallicFactor", 0.0}}}}});
  if (withFloor) f.node({{"name", "Floor"}, {"mesh", f.mesh(test::makePlane({0, 0, 0}, 2.0f, 16))}}, true);
  Json cube = {{"name", "Cube"},
               {"mesh", f.mesh(test::makeSlab(glm::vec3(-kHalf), glm::vec3(kHalf)), 0)},
               {"translation", {kRest.x, kRest.y, kRest.z}}};
  if (!cubeExtras.is_null()) cube["extras"] = cubeExtras;
  const int node = f.node(cube, true);
  f.animation("Slide",
              {{node,
                "translation",
                {0.0f, 2.0f},
                {float(kStart.x), float(kStart.y), float(kStart.z), float(kEnd.x), float(kEnd.y), float(kEnd.z)}}});
  // Looking down −Y: the glTF camera's −Z turned by −90° about X (image up is −Z).
  f.j["cameras"] =
      Json::array({{{"type", "orthographic"},
                    {"orthographic", {{"xmag", 1.25 * 4 / 3}, {"ymag", 1.25}, {"znear", 0.1}, {"zfar", 10.0}}}}});
  f.node({{"name", "Top"},
          {"camera", 0},
          {"translation", {0.0, 3.0, 0.0}},
          {"rotation", {-std::sqrt(0.5), 0.0, 0.0, std::sqrt(0.5)}}},
         true);
  return f.write(name, dir);
}

const MeshInstance& instanceOf(const Scene& s, const std::string& node) {
  for (const MeshInstance& m : s.meshes)
    if (m.node >= 0 && s.nodes[size_t(m.node)].name == node) return m;
  throw Error(cat("no instance of node ", node));
}

// ---------------------------------------------------------------------------------------------
// Loading and baking

TEST(SceneAnimatedReceivers, AnimatedNodeIsAReceiverWithItsReason) {
  const test::TempDir tmp("load");
  const fs::path dir = tmp.path();
  const Scene s = loadScene(writeCubeScene(dir, "scene", true));
  EXPECT_TRUE(s.warnings.empty()) << s.warnings.front();
  EXPECT_FALSE(instanceOf(s, "Floor").receiverOnly);
  const MeshInstance& cube = instanceOf(s, "Cube");
  EXPECT_TRUE(cube.receiverOnly);
  EXPECT_EQ(cube.receiverReason, ReceiverReason::Animated);
  EXPECT_EQ(describeReceivers(s), std::vector<std::string>{"node 1 'Cube': animated (translation)"});

  // An explicit mark comes first and the animation is still named; --receiver on another node.
  LoadOptions named;
  named.receiverNodes = {"Floor"};
  const Scene marked = loadScene(writeCubeScene(dir, "marked", true, {{"prt", {{"receiver", true}}}}), named);
  EXPECT_EQ(instanceOf(marked, "Cube").receiverReason, ReceiverReason::Extras);
  EXPECT_EQ(instanceOf(marked, "Floor").receiverReason, ReceiverReason::Option);
  EXPECT_EQ(describeReceivers(marked),
            (std::vector<std::string>{"node 0 'Floor': named in LoadOptions::receiverNodes",
                                      "node 1 'Cube': extras.prt.receiver, animated (translation)"}));
}

// Transfer of the floor's vertices under the cube's rest pose (|x|, |z| < half side).
std::vector<size_t> verticesUnderTheCube(const MeshInstance& floor) {
  std::vector<size_t> under;
  for (size_t v = 0; v < floor.vertexCount(); ++v)
    if (std::abs(floor.positions[v].x) < kHalf && std::abs(floor.positions[v].z) < kHalf) under.push_back(v);
  return under;
}

TEST(SceneAnimatedReceivers, BakeLeavesTheMovingCubeOut) {
  const test::TempDir tmp("bake");
  const fs::path dir = tmp.path();
  const Scene s = loadScene(writeCubeScene(dir, "scene", true));
  bake::BakeSettings set;
  set.samples = 1024;
  set.bounces = 1;
  const bake::SurfaceTransfer t = bake::bakeSurface(s, set);
  const size_t floor = size_t(&instanceOf(s, "Floor") - s.meshes.data());
  const size_t cube = size_t(&instanceOf(s, "Cube") - s.meshes.data());
  EXPECT_TRUE(t.perMesh[cube].empty());  // not baked
  const std::vector<size_t> under = verticesUnderTheCube(s.meshes[floor]);
  ASSERT_EQ(under.size(), 9u);  // 0.125 m cells: x, z ∈ {−0.125, 0, 0.125}

  // Not an occluder either: every floor vertex has the unoccluded plane's transfer Â_l y_lm(+Y).
  // Coefficient 0 is exact (each cosine-weighted sample adds π y_0 / N whatever its direction:
  // float rounding only, 1e-5); the others are the quasi-Monte Carlo estimate over 1024
  // scrambled Sobol directions, within 1e-2 (as BakeSurface.UnoccludedPlaneMatchesClosedForm).
  float y[9];
  sh::evaluate(3, glm::vec3(0, 1, 0), y);
  for (size_t v : under)
    for (int i = 0; i < 9; ++i) {
      const float expected = float(sh::clampedCosineFactor(sh::bandOf(i))) * y[i];
      EXPECT_NEAR(t.perMesh[floor][v * 9 + i].g, expected, i == 0 ? 1e-5f * expected : 1e-2f)
          << "vertex " << v << " coefficient " << i;
    }

  // The control: the same cube marked static is baked in its rest pose and shadows the floor
  // (it covers most of the cosine lobe of the vertex 0.1 m under its centre).
  const Scene pinned = loadScene(writeCubeScene(dir, "pinned", true, {{"prt", {{"receiver", false}}}}));
  ASSERT_FALSE(instanceOf(pinned, "Cube").receiverOnly);
  const bake::SurfaceTransfer shadowed = bake::bakeSurface(pinned, set);
  const size_t centre = under[4];
  const float ratio = shadowed.perMesh[floor][centre * 9].g / t.perMesh[floor][centre * 9].g;
  std::printf("  coefficient 0 under the cube's centre, cube baked static / receiver: %.3f\n", ratio);
  EXPECT_LT(ratio, 0.5f);
}

// ---------------------------------------------------------------------------------------------
// Rendering: the cube's top face (normal +Y) seen from straight above.

// Where pixel (px, py)'s ray from the orthographic camera meets the plane y = height (the ray
// through the pixel centre, as in docs/render.md "Cameras").
glm::dvec3 hitOnPlane(const render::CameraView& c, int w, int h, int px, int py, double height) {
  const double sx = 2.0 * (px + 0.5) / w - 1.0, sy = 1.0 - 2.0 * (py + 0.5) / h;
  const glm::dvec3 origin(c.cameraToWorld * glm::dvec4(sx * c.ymag * w / h, sy * c.ymag, 0.0, 1.0));
  const glm::dvec3 dir(c.cameraToWorld * glm::dvec4(0.0, 0.0, -1.0, 0.0));
  return origin + (height - origin.y) / dir.y * dir;
}

// The CPU probe oracle for a receiver point x with normal n: ρ/π · E with E the irradiance of
// prt::interpolateRadiance at x (the light itself where no probe applies).
glm::dvec3 probeOracle(const ProbeGrid& g, const std::vector<glm::vec3>& relit, const sh::ShRgb& light,
                       const glm::vec3& x, const glm::vec3& n) {
  const sh::ShRgb incident = probeWeights(g, x, &n).count > 0 ? interpolateRadiance(g, relit, x, &n) : light;
  return glm::dvec3(kCubeAlbedo) * kInvPi * glm::dvec3(sh::irradiance(incident, n));
}

struct TopFace {
  int pixels = 0;
  double maxError = 0.0;  // against the oracle, relative to the largest oracle value
  glm::ivec2 centre{-1};  // the pixel nearest the face's centre
};

// Compares the pixels whose ray meets the top face at `time` at least 1.5 pixels inside its
// edges (silhouette pixels depend on the rasterizer's snapping) with `expected(x)`.
template <typename Expected>
TopFace compareTopFace(const ImageRgb& img, const render::CameraView& cam, double time, Expected expected) {
  const glm::dvec3 c = cubeCentreAt(time);
  const double top = c.y + kHalf, margin = kHalf - 1.5 * 2.0 * cam.ymag / img.height;
  TopFace out;
  double peak = 0.0, worst = 0.0, nearest = 1e30;
  for (int py = 0; py < img.height; ++py)
    for (int px = 0; px < img.width; ++px) {
      const glm::dvec3 x = hitOnPlane(cam, img.width, img.height, px, py, top);
      if (std::abs(x.x - c.x) > margin || std::abs(x.z - c.z) > margin) continue;
      const glm::dvec3 want = expected(glm::vec3(x));
      const glm::dvec3 d = glm::abs(glm::dvec3(img.at(px, py)) - want);
      peak = std::max({peak, want.x, want.y, want.z});
      worst = std::max({worst, d.x, d.y, d.z});
      ++out.pixels;
      const double r = glm::length(glm::dvec2(x.x - c.x, x.z - c.z));
      if (r < nearest) {
        nearest = r;
        out.centre = glm::ivec2(px, py);
      }
    }
  out.maxError = peak > 0.0 ? worst / peak : 1.0;
  return out;
}

// 3-band light with every coefficient that +Y irradiance sees, and others it must ignore.
sh::ShRgb testLight() {
  sh::ShRgb l(3);
  l.c[0] = glm::vec3(2.0f, 1.8f, 1.5f);
  l.c[1] = glm::vec3(0.9f, 0.7f, 0.5f);   // y
  l.c[3] = glm::vec3(0.4f, -0.2f, 0.1f);  // x: zero at +Y
  l.c[6] = glm::vec3(-0.3f, 0.2f, 0.1f);
  l.c[8] = glm::vec3(0.2f, -0.1f, 0.3f);
  return l;
}

// Irradiance at normal +Y written out from the real SH basis at (0, 1, 0) (prt/sh.h: y_1 = 0.488603 y,
// y_6 = 0.315392 (3z² − 1), y_8 = 0.546274 (x² − y²); the others vanish) and the clamped-cosine
// factors π, 2π/3, π/4: no prt code involved.
glm::dvec3 upIrradiance(const sh::ShRgb& l) {
  return prt::kPi * 0.282095 * glm::dvec3(l.c[0]) + 2 * prt::kPi / 3 * 0.488603 * glm::dvec3(l.c[1]) +
         prt::kPi / 4 * (-0.315392 * glm::dvec3(l.c[6]) - 0.546274 * glm::dvec3(l.c[8]));
}

// Relative tolerance against the probe oracle: as test_render.cpp's kReceiverTolerance (the
// shader's float weights and position against the oracle's double; measured a few 1e-7 there).
constexpr double kOracleTolerance = 1e-4;

// The cube alone: the probe grid of an empty scene is M = I up to the bake's quadrature, so the
// top face is lit like an unoccluded upward surface, ρ/π · E(+Y), wherever the cube is.
TEST(RenderAnimatedReceivers, MovingCubeMatchesTheProbeOracleAndTheClosedForm) {
  const test::TempDir tmp("render");
  const fs::path dir = tmp.path();
  const Scene s = loadScene(writeCubeScene(dir, "scene", false));
  ASSERT_TRUE(instanceOf(s, "Cube").receiverOnly);
  ASSERT_EQ(s.cameras.size(), 1u);
  const bake::ProbeSettings ps{.samples = 1024,
                               .bounces = 0,
                               .dims = glm::ivec3(4, 3, 4),
                               .boundsMin = glm::dvec3(-1.2, 0.0, -1.2),
                               .boundsMax = glm::dvec3(1.2, 1.2, 1.2)};
  const ProbeGrid grid = bake::bakeProbes(s, {}, ps);  // nothing to hit: the cube is a receiver
  const sh::ShRgb light = testLight();
  const std::vector<glm::vec3> relit = relightProbes(grid, light);
  const glm::vec3 up(0, 1, 0);
  const glm::dvec3 closedForm = glm::dvec3(kCubeAlbedo) * kInvPi * upIrradiance(light);

  const int w = 64, h = 48;
  render::GlContext ctx(render::GlBackend::OSMesa, w, h);
  render::Renderer r(ctx, s);
  r.setProbes(grid);
  const render::CameraView cam = render::cameraView(s.cameras[0]);
  std::vector<ImageRgb> frames;
  std::vector<glm::ivec2> centres;
  for (double time : {0.5, 1.5}) {
    SCOPED_TRACE(cat("t = ", time));
    render::Frame f;
    f.camera = cam;
    f.light = light;
    f.time = time;
    frames.push_back(r.render(f));
    const TopFace oracle = compareTopFace(frames.back(), cam, time,
                                          [&](const glm::vec3& x) { return probeOracle(grid, relit, light, x, up); });
    // Empty-scene probes: M = I within 1e-2 per element (ProbeBake.EmptySceneGivesIdentity).
    const TopFace exact = compareTopFace(frames.back(), cam, time, [&](const glm::vec3&) { return closedForm; });
    std::printf("  t = %.1f s: %d top-face pixels, probe oracle %.3g, closed form %.3g of the peak\n", time,
                oracle.pixels, oracle.maxError, exact.maxError);
    EXPECT_GE(oracle.pixels, 9);
    EXPECT_LT(oracle.maxError, kOracleTolerance);
    EXPECT_LT(exact.maxError, 1e-2);
    centres.push_back(oracle.centre);
  }
  // It moved: where the cube's top was at 0.5 s there is nothing at 1.5 s (background is 0).
  ASSERT_NE(centres[0], centres[1]);
  EXPECT_GT(frames[0].at(centres[0].x, centres[0].y).g, 0.1f);
  EXPECT_EQ(frames[1].at(centres[0].x, centres[0].y), glm::vec3(0.0f));
}

// ---------------------------------------------------------------------------------------------
// The command line: prt bake names the receiver and leaves it out; prt render moves it with the
// rig's fps (frame f at f / fps seconds) and lights it from the baked probe grid.

using test::runPrt;
using test::RunResult;

TEST(RenderAnimatedReceivers, BakeAndRenderCommandsMoveTheCube) {
  const test::TempDir tmp("cli");
  const fs::path dir = tmp.path();
  const std::string scene = writeCubeScene(dir, "scene", true);
  const fs::path rig = dir / "rig.json";
  std::ofstream(rig) << R"({"version": 1, "fps": 2, "lights": [
      {"type": "uniform", "radiance": [0.4, 0.45, 0.5]},
      {"type": "sun", "direction": [0.3, 1, 0.2], "radius": 3, "irradiance": [2.0, 1.8, 1.5]}]})";
  const std::string baked = (dir / "b.glb").string(), probes = (dir / "p.vdb").string();
  const RunResult bakeRun =
      runPrt({"bake", scene, "-o", baked, "--samples", "64", "--bounces", "1", "--probes", probes, "--probe-dims",
              "4,3,4", "--probe-bounds", "-1.2,0.05,-1.2,1.2,1.2,1.2", "--probe-samples", "256", "--no-operator"});
  ASSERT_EQ(bakeRun.status, 0) << bakeRun.err;
  EXPECT_NE(bakeRun.err.find("(1 receivers skipped)"), std::string::npos) << bakeRun.err;
  EXPECT_NE(bakeRun.err.find("receiver node 1 'Cube': animated (translation)"), std::string::npos) << bakeRun.err;

  const RunResult renderRun = runPrt({"render", baked, "--rig", rig.string(), "--probes", probes, "--camera", "Top",
                                      "--frames", "0-2", "--size", "64x48", "--exr-compression", "none", "-q",
                                      "--materials", "diffuse", "-o", (dir / "f_%d.exr").string()});
  ASSERT_EQ(renderRun.status, 0) << renderRun.err;

  // The oracle from the files the command read (the Lambertian formula: --materials diffuse; the
  // probes through their SH, as the bake stores no bounce operator):
  // the receiver survives the baked file.
  const Scene file = loadScene(baked);
  ASSERT_TRUE(instanceOf(file, "Cube").receiverOnly);
  const ProbeGrid grid = readProbeGrid(probes);
  const LightRig lights = loadLightRig(rig.string());
  const render::CameraView cam = render::cameraView(file.cameras[0]);
  std::vector<glm::ivec2> centres;
  std::vector<ImageRgb> frames;
  for (int frame : {1, 2}) {
    SCOPED_TRACE(cat("frame ", frame));
    const double time = frame / 2.0;
    // The 3° sun is a direct light (docs/render.md, "Direct lights and their shadows"): its SH
    // only through the probes' bounced part, its own light per pixel, unshadowed on the top face
    // (nothing above it).
    const RigLighting lighting = lights.evaluateLighting(frame, grid.bands);
    ASSERT_EQ(lighting.direct.size(), 1u);
    ASSERT_TRUE(grid.hasDirect());
    const std::vector<glm::vec3> relit = relightProbes(grid, lighting.sh, lighting.directSh);
    const glm::dvec3 direct =
        lighting.direct[0].irradiance * directCosineFactor(lighting.direct[0], glm::dvec3(0, 1, 0));
    frames.push_back(loadHdrImage((dir / cat("f_", frame, ".exr")).string()));
    const TopFace got = compareTopFace(frames.back(), cam, time, [&](const glm::vec3& x) {
      return probeOracle(grid, relit, lighting.sh, x, glm::vec3(0, 1, 0)) + glm::dvec3(kCubeAlbedo) * kInvPi * direct;
    });
    std::printf("  frame %d (t = %.1f s): %d top-face pixels, max error %.3g of the peak\n", frame, time, got.pixels,
                got.maxError);
    EXPECT_GE(got.pixels, 9);
    EXPECT_LT(got.maxError, kOracleTolerance);
    centres.push_back(got.centre);
  }
  // Between the frames the cube moved off: the floor shows there at frame 2, lit differently.
  ASSERT_NE(centres[0], centres[1]);
  const glm::vec3 a = frames[0].at(centres[0].x, centres[0].y), b = frames[1].at(centres[0].x, centres[0].y);
  EXPECT_GT(std::abs(a.g - b.g), 0.01f * a.g) << a.g << " vs " << b.g;
}

// A scene whose every mesh moves bakes no transfer at all (only the settings and the probes);
// prt render still lights the receivers from the grid, with the bands of the bake record:
// here an empty scene, so the top face is the unoccluded closed form ρ/π · E(+Y).
TEST(RenderAnimatedReceivers, SceneOfReceiversOnlyRendersFromTheProbes) {
  const test::TempDir tmp("cli_receivers_only");
  const fs::path dir = tmp.path();
  const std::string scene = writeCubeScene(dir, "scene", false);
  const fs::path rig = dir / "rig.json";
  std::ofstream(rig) << R"({"version": 1, "fps": 2, "lights": [{"type": "uniform", "radiance": [0.4, 0.45, 0.5]}]})";
  const std::string baked = (dir / "b.glb").string(), probes = (dir / "p.vdb").string();
  const RunResult bakeRun = runPrt({"bake", scene, "-o", baked, "--samples", "16", "--probes", probes, "--probe-dims",
                                    "4,3,4", "--probe-bounds", "-1.2,0.05,-1.2,1.2,1.2,1.2", "-q"});
  ASSERT_EQ(bakeRun.status, 0) << bakeRun.err;
  for (const MeshInstance& m : loadScene(baked).meshes)
    ASSERT_TRUE(m.transfer.empty() && m.receiverOnly);  // nothing baked: the case under test
  ASSERT_EQ(loadScene(baked).transferBands, 3);         // the bake record's bands (prt bake's default)
  const RunResult renderRun =
      runPrt({"render", baked, "--rig", rig.string(), "--probes", probes, "--camera", "Top", "--frames", "1", "--size",
              "64x48", "-q", "--materials", "diffuse", "-o", (dir / "f.exr").string()});
  ASSERT_EQ(renderRun.status, 0) << renderRun.err;
  const Scene file = loadScene(baked);
  const sh::ShRgb light = loadLightRig(rig.string()).evaluate(1, 3);
  const glm::dvec3 closedForm = glm::dvec3(kCubeAlbedo) * kInvPi * upIrradiance(light);
  const TopFace got = compareTopFace(loadHdrImage((dir / "f.exr").string()), render::cameraView(file.cameras[0]), 0.5,
                                     [&](const glm::vec3&) { return closedForm; });
  EXPECT_GE(got.pixels, 9);
  EXPECT_LT(got.maxError, 1e-2);
  // Without --probes the receivers are not drawn, as in any scene, and the run says so.
  const RunResult noProbes =
      runPrt({"render", baked, "--rig", rig.string(), "--size", "8x8", "-o", (dir / "g.exr").string()});
  EXPECT_EQ(noProbes.status, 0) << noProbes.err;
  EXPECT_NE(noProbes.err.find("warning"), std::string::npos) << noProbes.err;
}

}  // namespace
}  // namespace prt
