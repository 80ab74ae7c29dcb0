// glTF animation (prt/scene.h): sampling against hand-computed values for LINEAR, STEP and
// CUBICSPLINE (glTF 2.0, Appendix C), parent-child composition through a loaded file, clamping
// outside the key range, and bad animations rejected with one clear line. Animated nodes as
// receivers through the bake and the renderer: test_animated_receivers.cpp.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/quaternion.hpp>
#include <nlohmann/json.hpp>

#include "gltf_file.h"
#include "prt/error.h"
#include "prt/math.h"
#include "prt/scene.h"

namespace prt {
namespace {

using Json = nlohmann::json;
using test::GltfFile;
namespace fs = std::filesystem;

// Values are computed in double from float-exact inputs; 1e-12 is rounding only.
constexpr double kExact = 1e-12;

AnimationChannel channel(AnimationPath path, Interpolation interpolation, std::vector<double> times,
                         std::vector<glm::dvec4> values) {
  AnimationChannel c;
  c.node = 0;
  c.path = path;
  c.interpolation = interpolation;
  c.times = std::move(times);
  c.values = std::move(values);
  return c;
}

void expectNear(const glm::dvec4& a, const glm::dvec4& b, double tol, const char* what) {
  for (int i = 0; i < 4; ++i) EXPECT_NEAR(a[i], b[i], tol) << what << " component " << i;
}

TEST(AnimationSample, LinearTranslationAndClamping) {
  const AnimationChannel c = channel(AnimationPath::Translation, Interpolation::Linear, {1.0, 3.0},
                                     {glm::dvec4(0, 0, 0, 0), glm::dvec4(2, 4, -6, 0)});
  expectNear(sampleChannel(c, 2.0), glm::dvec4(1, 2, -3, 0), kExact, "middle");
  expectNear(sampleChannel(c, 1.5), glm::dvec4(0.5, 1, -1.5, 0), kExact, "quarter");
  expectNear(sampleChannel(c, 0.0), glm::dvec4(0, 0, 0, 0), 0.0, "before the first key");
  expectNear(sampleChannel(c, -4.0), glm::dvec4(0, 0, 0, 0), 0.0, "negative time");
  expectNear(sampleChannel(c, 3.0), glm::dvec4(2, 4, -6, 0), 0.0, "last key");
  expectNear(sampleChannel(c, 10.0), glm::dvec4(2, 4, -6, 0), 0.0, "after the last key");
}

TEST(AnimationSample, StepHoldsEachKeyUntilTheNext) {
  const AnimationChannel c = channel(AnimationPath::Scale, Interpolation::Step, {0.0, 1.0, 2.0},
                                     {glm::dvec4(1, 1, 1, 0), glm::dvec4(2, 3, 4, 0), glm::dvec4(5, 6, 7, 0)});
  expectNear(sampleChannel(c, 0.99), glm::dvec4(1, 1, 1, 0), 0.0, "just before key 1");
  expectNear(sampleChannel(c, 1.0), glm::dvec4(2, 3, 4, 0), 0.0, "at key 1");
  expectNear(sampleChannel(c, 1.7), glm::dvec4(2, 3, 4, 0), 0.0, "between 1 and 2");
  expectNear(sampleChannel(c, 2.5), glm::dvec4(5, 6, 7, 0), 0.0, "after the last");
}

glm::dvec4 quatY(double degrees) {  // glTF order (x, y, z, w)
  const double h = glm::radians(degrees) / 2;
  return glm::dvec4(0, std::sin(h), 0, std::cos(h));
}

TEST(AnimationSample, LinearRotationIsShortestPathSlerp) {
  AnimationChannel c = channel(AnimationPath::Rotation, Interpolation::Linear, {0.0, 1.0}, {quatY(0), quatY(90)});
  // Slerp moves at constant angular speed: a quarter of the time is a quarter of the angle
  // (a normalised lerp would give 24.6° at s = ¼, not 22.5°).
  expectNear(sampleChannel(c, 0.25), quatY(22.5), kExact, "s = 1/4");
  expectNear(sampleChannel(c, 0.5), quatY(45), kExact, "s = 1/2");
  // −q is the same rotation; slerp must take the short way (not through 270°).
  c.values[1] = -quatY(90);
  const glm::dvec4 q = sampleChannel(c, 0.5);
  const double sign = q.w < 0 ? -1.0 : 1.0;
  expectNear(sign * q, quatY(45), kExact, "negated end key");
  // Keys stored off unit length still give unit rotations.
  c.values = {2.0 * quatY(0), 0.5 * quatY(60)};
  EXPECT_NEAR(glm::length(sampleChannel(c, 0.3)), 1.0, kExact);
  expectNear(sampleChannel(c, 0.5), quatY(30), kExact, "scaled keys");
}

TEST(AnimationSample, CubicSplineIsTheSpecsHermite) {
  // Keys at t = 0 and 2 (t_d = 2): v0 = 0, out-tangent b0 = (1, 0, 0); v1 = (4, 0, 0), in-tangent
  // a1 = (0, 3, 0). At s = ½: h00 = h01 = ½, h10 = s³ − 2s² + s = ⅛, h11 = s³ − s² = −⅛, so
  // p = ½ v0 + 2·⅛ b0 + ½ v1 − 2·⅛ a1 = (0.25 + 2, −0.75, 0) = (2.25, −0.75, 0).
  const glm::dvec4 zero(0.0);
  AnimationChannel c = channel(AnimationPath::Translation, Interpolation::CubicSpline, {0.0, 2.0},
                               {glm::dvec4(9, 9, 9, 0), zero, glm::dvec4(1, 0, 0, 0),  // a0 (unused), v0, b0
                                glm::dvec4(0, 3, 0, 0), glm::dvec4(4, 0, 0, 0), glm::dvec4(7, 7, 7, 0)});
  expectNear(sampleChannel(c, 1.0), glm::dvec4(2.25, -0.75, 0, 0), kExact, "s = 1/2");
  // s = ¼ (t = 0.5): h00 = 27/32, h10 = 9/64, h01 = 5/32, h11 = −3/64.
  expectNear(sampleChannel(c, 0.5), glm::dvec4(2 * 9.0 / 64 + 4 * 5.0 / 32, -2 * 3 * 3.0 / 64, 0, 0), kExact,
             "s = 1/4");
  // Outside the range: the key values, not the tangents.
  expectNear(sampleChannel(c, -1.0), zero, 0.0, "before");
  expectNear(sampleChannel(c, 3.0), glm::dvec4(4, 0, 0, 0), 0.0, "after");
  // Rotations come back normalised.
  AnimationChannel r = channel(AnimationPath::Rotation, Interpolation::CubicSpline, {0.0, 1.0},
                               {zero, quatY(0), zero, zero, quatY(80), zero});
  const glm::dvec4 q = sampleChannel(r, 0.5);
  EXPECT_NEAR(glm::length(q), 1.0, kExact);
  expectNear(q, quatY(40), kExact, "symmetric Hermite between two rotations about Y");
}

TEST(AnimationFile, ParentAnimationComposesWithTheChild) {
  // Parent: translation animated (LINEAR) over a rest translation; child: rest rotation 90°
  // about Y and translation (1, 0, 0) in the parent, scale animated (STEP). The child carries
  // the mesh and is a receiver.
  GltfFile f;
  const int parent = f.node({{"name", "Parent"}, {"translation", {0, 1, 0}}}, true);
  const int child = f.node({{"name", "Child"},
                            {"mesh", 0},
                            {"translation", {1, 0, 0}},
                            {"rotation", {0, std::sin(prt::kPi / 4), 0, std::cos(prt::kPi / 4)}},
                            {"extras", {{"prt", {{"receiver", true}}}}}},
                           false);
  f.j["nodes"][parent]["children"] = Json::array({child});
  f.animation("Move", {{parent, "translation", {0.0f, 2.0f}, {0, 1, 0, 4, 1, 0}},
                       {child, "scale", {0.0f, 1.0f}, {1, 1, 1, 2, 2, 2}, "STEP"}});
  const std::string path = f.write("compose");
  const Scene s = loadScene(path);
  fs::remove(path);
  ASSERT_EQ(s.nodes.size(), 2u);
  EXPECT_EQ(s.nodes[size_t(child)].parent, parent);
  ASSERT_EQ(s.animations.size(), 1u);
  EXPECT_EQ(s.animations[0].name, "Move");
  ASSERT_EQ(s.animations[0].channels.size(), 2u);
  EXPECT_DOUBLE_EQ(animationDuration(s), 2.0);
  EXPECT_TRUE(isAnimated(s, child));  // through its parent and itself
  ASSERT_EQ(s.meshes.size(), 1u);
  const MeshInstance& m = s.meshes[0];
  EXPECT_TRUE(m.receiverOnly);
  EXPECT_TRUE(s.warnings.empty()) << s.warnings.front();
  EXPECT_EQ(describeReceivers(s),
            std::vector<std::string>{
                "node 1 'Child': extras.prt.receiver, animated (scale, translation of node 0 'Parent')"});

  // At t = 1.5: parent at (3, 1, 0); child scaled 2, turned 90° about Y (x -> -z), at +1 x.
  // Mesh vertex (1, 0, 0) -> scale (2, 0, 0) -> rotate (0, 0, -2) -> +(1, 0, 0) -> +(3, 1, 0).
  const glm::dmat4 world = nodeWorldAt(s, child, 1.5);
  const glm::dvec3 p(world * glm::dvec4(1, 0, 0, 1));
  EXPECT_NEAR(p.x, 4.0, kExact);
  EXPECT_NEAR(p.y, 1.0, kExact);
  EXPECT_NEAR(p.z, -2.0, kExact);
  // The motion takes the stored rest-pose (world) vertices there: rest vertex 1 = (1, 1, -1).
  const glm::dvec3 rest(m.positions[1]);
  EXPECT_NEAR(rest.x, 1.0, 1e-6);
  EXPECT_NEAR(rest.z, -1.0, 1e-6);
  const glm::dvec3 moved(instanceMotion(s, m, 1.5) * glm::dvec4(rest, 1.0));
  EXPECT_NEAR(glm::length(moved - p), 0.0, 1e-6);  // rest positions are float
  // Clamped: before 0 the first keys (rest translation here), after 2 the last.
  EXPECT_NEAR(glm::length(glm::dvec3(nodeWorldAt(s, parent, -1.0)[3]) - glm::dvec3(0, 1, 0)), 0.0, kExact);
  EXPECT_NEAR(glm::length(glm::dvec3(nodeWorldAt(s, parent, 9.0)[3]) - glm::dvec3(4, 1, 0)), 0.0, kExact);
}

TEST(AnimationFile, StaticNodesHaveIdentityMotionAndAnimatedNodesAreReceivers) {
  GltfFile f;
  const int still = f.node({{"name", "Still"}, {"mesh", 0}, {"translation", {0, 0, 2}}}, true);
  const int moving = f.node({{"name", "Wall"}, {"mesh", 0}}, true);
  f.animation("", {{moving, "translation", {0.0f, 1.0f}, {0, 0, 0, 1, 0, 0}}});
  const std::string path = f.write("baked");
  const Scene s = loadScene(path);
  ASSERT_EQ(s.meshes.size(), 2u);
  EXPECT_EQ(instanceMotion(s, s.meshes[0], 0.7), glm::dmat4(1.0));  // exactly
  EXPECT_FALSE(isAnimated(s, still));
  EXPECT_FALSE(s.meshes[0].receiverOnly);
  EXPECT_TRUE(s.meshes[1].receiverOnly);
  EXPECT_EQ(s.meshes[1].receiverReason, ReceiverReason::Animated);
  EXPECT_TRUE(s.warnings.empty()) << s.warnings.front();

  // Marked static explicitly: baked in its rest pose, with a warning that says so.
  f.j["nodes"][moving]["extras"] = {{"prt", {{"receiver", false}}}};
  const std::string pinnedPath = f.write("pinned");
  const Scene pinned = loadScene(pinnedPath);
  fs::remove(path);
  fs::remove(pinnedPath);
  ASSERT_EQ(pinned.meshes.size(), 2u);
  EXPECT_FALSE(pinned.meshes[1].receiverOnly);
  ASSERT_EQ(pinned.warnings.size(), 1u);
  EXPECT_NE(pinned.warnings[0].find("'Wall' is animated but marked static"), std::string::npos) << pinned.warnings[0];
  EXPECT_NE(pinned.warnings[0].find("ignored"), std::string::npos) << pinned.warnings[0];
}

// Loads a file with one broken animation; the error must be one line naming the file, the
// animation, the channel, and `what`.
void expectBad(GltfFile& f, const std::string& name, const std::string& what) {
  const std::string path = f.write(name);
  try {
    loadScene(path);
    ADD_FAILURE() << name << ": loaded without error (expected '" << what << "')";
  } catch (const Error& e) {
    const std::string msg = e.what();
    EXPECT_EQ(msg.rfind(path + ": animation 0 'Bad' / channel 0", 0), 0u) << msg;
    EXPECT_NE(msg.find(what), std::string::npos) << name << ": " << msg;
    EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
  }
  fs::remove(path);
}

GltfFile withTarget(Json extra = Json::object()) {
  GltfFile f;
  Json n = {{"name", "Target"}, {"mesh", 0}};
  n.update(extra);
  f.node(n, true);
  return f;
}

TEST(AnimationFile, BadAnimationsAreOneClearLine) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  struct Case {
    std::string name;
    std::function<void(GltfFile&)> build;
    std::string what;
  };
  const std::vector<Case> cases = {
      {"decreasing",
       [](GltfFile& f) {
         f.animation("Bad", {{0, "translation", {0, 2, 1}, std::vector<float>(9, 0)}});
       },
       "key times not strictly increasing (key 2 at 1 s after 2 s)"},
      {"repeated",
       [](GltfFile& f) {
         f.animation("Bad", {{0, "translation", {0, 1, 1}, std::vector<float>(9, 0)}});
       },
       "not strictly increasing"},
      {"nan-time",
       [&](GltfFile& f) {
         f.animation("Bad", {{0, "scale", {0, nan}, std::vector<float>(6, 1)}});
       },
       "input: key time 1 is not finite"},
      {"nan-value",
       [&](GltfFile& f) {
         f.animation("Bad", {{0, "translation", {0, 1}, {0, 0, 0, 0, nan, 0}}});
       },
       "output: value 1 is not finite"},
      {"count",
       [](GltfFile& f) {
         f.animation("Bad", {{0, "translation", {0, 1, 2}, std::vector<float>(6, 0)}});
       },
       "2 values, expected 3"},
      {"cubic-count",
       [](GltfFile& f) {
         f.animation("Bad", {{0, "translation", {0, 1}, std::vector<float>(6, 0), "CUBICSPLINE"}});
       },
       "2 values, expected 6"},
      {"cubic-one-key",
       [](GltfFile& f) {
         f.animation("Bad", {{0, "translation", {0}, std::vector<float>(9, 0), "CUBICSPLINE"}});
       },
       "CUBICSPLINE needs at least 2"},
      {"interpolation",
       [](GltfFile& f) {
         f.animation("Bad", {{0, "translation", {0, 1}, std::vector<float>(6, 0), "SMOOTH"}});
       },
       "unknown interpolation 'SMOOTH'"},
      {"zero-quaternion",
       [](GltfFile& f) {
         f.animation("Bad", {{0, "rotation", {0, 1}, {0, 0, 0, 1, 0, 0, 0, 0}}});
       },
       "value 1 is a zero quaternion"},
      {"vec2-translation",
       [](GltfFile& f) {
         f.animation("Bad", {{0, "translation", {0, 1}, std::vector<float>(6, 0)}});
         f.j["accessors"][f.j["animations"][0]["samplers"][0]["output"].get<int>()]["type"] = "VEC2";
         f.j["accessors"][f.j["animations"][0]["samplers"][0]["output"].get<int>()]["count"] = 3;
       },
       "translation values must be VEC3 float"},
      {"vec-times",
       [](GltfFile& f) {
         f.animation("Bad", {{0, "translation", {0, 1, 2}, std::vector<float>(3, 0)}});
         f.j["accessors"][f.j["animations"][0]["samplers"][0]["input"].get<int>()]["type"] = "VEC3";
         f.j["accessors"][f.j["animations"][0]["samplers"][0]["input"].get<int>()]["count"] = 1;
       },
       "key times must be SCALAR float"},
      {"sampler",
       [](GltfFile& f) {
         f.animation("Bad", {{0, "translation", {0, 1}, std::vector<float>(6, 0)}});
         f.j["animations"][0]["channels"][0]["sampler"] = 4;
       },
       "sampler 4 does not exist"},
      {"node",
       [](GltfFile& f) {
         f.animation("Bad", {{7, "translation", {0, 1}, std::vector<float>(6, 0)}});
       },
       "target node 7 does not exist"},
      {"path",
       [](GltfFile& f) {
         f.animation("Bad", {{0, "translation", {0, 1}, std::vector<float>(6, 0)}});
         f.j["animations"][0]["channels"][0]["target"]["path"] = "position";
       },
       "unknown target path 'position'"},
      {"twice",
       [](GltfFile& f) {
         f.animation("Bad",
                     {{0, "scale", {0, 1}, std::vector<float>(6, 1)}, {0, "scale", {0, 1}, std::vector<float>(6, 1)}});
       },
       "second channel of this animation targets the same node property"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    GltfFile f = withTarget();
    c.build(f);
    if (c.name == "twice") {
      // The first channel is fine; the error names channel 1.
      const std::string path = f.write(c.name);
      try {
        loadScene(path);
        ADD_FAILURE() << "loaded";
      } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("animation 0 'Bad' / channel 1 (node 0 'Target' scale)"),
                  std::string::npos)
            << e.what();
        EXPECT_NE(std::string(e.what()).find(c.what), std::string::npos) << e.what();
      }
      fs::remove(path);
      continue;
    }
    expectBad(f, c.name, c.what);
  }
  // A node given by a matrix cannot be animated (glTF: only TRS nodes are targets).
  GltfFile m = withTarget({{"matrix", {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1}}});
  m.animation("Bad", {{0, "translation", {0, 1}, std::vector<float>(6, 0)}});
  expectBad(m, "matrix", "node 0 has a matrix");
}

TEST(AnimationFile, WeightsChannelsAreSkippedWithAWarning) {
  GltfFile f = withTarget();
  f.animation("Morph", {{0, "translation", {0, 1}, std::vector<float>(6, 0)}});
  f.j["animations"][0]["channels"][0]["target"]["path"] = "weights";
  const std::string path = f.write("weights");
  const Scene s = loadScene(path);
  fs::remove(path);
  ASSERT_EQ(s.animations.size(), 1u);
  EXPECT_TRUE(s.animations[0].channels.empty());
  ASSERT_EQ(s.warnings.size(), 1u);
  EXPECT_NE(s.warnings[0].find("morph target weights are not supported"), std::string::npos) << s.warnings[0];
  // Nothing moves the node: it stays static (baked), not a receiver.
  ASSERT_EQ(s.meshes.size(), 1u);
  EXPECT_FALSE(s.meshes[0].receiverOnly);
}

}  // namespace
}  // namespace prt
