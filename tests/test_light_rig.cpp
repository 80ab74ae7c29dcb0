// Light rigs (prt/light_rig.h): keyframes, rotation of maps about any axis, analytic lights,
// sums, the JSON reader's errors, and every bundled rig and documented example.
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <random>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "harness.h"
#include "prt/atomic_file.h"
#include "prt/error.h"
#include "prt/image.h"
#include "prt/light.h"
#include "prt/light_rig.h"
#include "prt/math.h"
#include "prt/sh.h"
#include "test_util.h"

namespace {

using prt::test::errorOf;

namespace fs = std::filesystem;
using prt::LightRig;
using prt::RigLight;
using prt::Track;

using prt::kPi;

std::string sourceFile(const std::string& rel) { return std::string(PRT_SOURCE_DIR) + "/" + rel; }
const std::string kEsplanade = sourceFile("scenes/env/royal_esplanade_128.hdr");

using prt::test::TempDir;

// A double written for JSON without losing digits (prt::cat keeps only 6).
std::string num(double v) {
  std::ostringstream os;
  os.precision(17);
  os << v;
  return os.str();
}

// The rig parsed from JSON text (maps relative to `base`), named "rig.json" in messages.
LightRig rigOf(const std::string& json, const std::string& base = ".") {
  return prt::parseLightRig(json, "rig.json", base);
}

double maxAbsDiff(const prt::sh::ShRgb& a, const prt::sh::ShRgb& b) {
  EXPECT_EQ(a.size(), b.size());
  double m = 0.0;
  for (int i = 0; i < std::min(a.size(), b.size()); ++i)
    for (int c = 0; c < 3; ++c) m = std::max(m, double(std::fabs(a.c[i][c] - b.c[i][c])));
  return m;
}

double maxAbs(const prt::sh::ShRgb& a) {
  double m = 0.0;
  for (const glm::vec3& v : a.c)
    for (int c = 0; c < 3; ++c) m = std::max(m, double(std::fabs(v[c])));
  return m;
}

std::string envJson(const std::string& file, const std::string& axis, const std::string& rotation,
                    const std::string& extra = "") {
  return "{\"version\": 1, \"lights\": [{\"type\": \"environment\", \"file\": \"" + file + "\", \"axis\": " + axis +
         ", \"rotation\": " + rotation + extra + "}]}";
}

// ---------------------------------------------------------------------------------------------
// Keyframes

TEST(RigTrack, LinearIsExactAtKeysBetweenThemAndHeldOutside) {
  Track t;
  t.keys = {{0.0, glm::dvec3(0.0)}, {10.0, glm::dvec3(5.0)}, {20.0, glm::dvec3(-5.0)}};
  // Every value below is exact in binary floating point: (1 - t)·a + t·b with t = k/4, k/2.
  EXPECT_EQ(t.scalarAt(0.0), 0.0);
  EXPECT_EQ(t.scalarAt(10.0), 5.0);
  EXPECT_EQ(t.scalarAt(20.0), -5.0);
  EXPECT_EQ(t.scalarAt(5.0), 2.5);
  EXPECT_EQ(t.scalarAt(2.5), 1.25);  // fractional frames
  EXPECT_EQ(t.scalarAt(15.0), 0.0);
  EXPECT_EQ(t.scalarAt(17.5), -2.5);
  EXPECT_EQ(t.scalarAt(-3.0), 0.0);  // before the first key: the first value
  EXPECT_EQ(t.scalarAt(1e9), -5.0);  // after the last key: the last value
}

TEST(RigTrack, StepHoldsTheLastKeyAtOrBeforeTheFrame) {
  Track t;
  t.interp = Track::Interp::Step;
  t.keys = {{0.0, glm::dvec3(1.0)}, {10.0, glm::dvec3(2.0)}, {20.0, glm::dvec3(3.0)}};
  EXPECT_EQ(t.scalarAt(-1.0), 1.0);
  EXPECT_EQ(t.scalarAt(0.0), 1.0);
  EXPECT_EQ(t.scalarAt(9.999), 1.0);
  EXPECT_EQ(t.scalarAt(10.0), 2.0);
  EXPECT_EQ(t.scalarAt(19.5), 2.0);
  EXPECT_EQ(t.scalarAt(20.0), 3.0);
  EXPECT_EQ(t.scalarAt(100.0), 3.0);
}

TEST(RigTrack, ConstantAndRamp) {
  EXPECT_EQ(Track::constant(7.0).scalarAt(-100.0), 7.0);
  EXPECT_FALSE(Track::constant(7.0).animated());
  Track r = Track::ramp(2, 10.0, 6, 30.0);
  EXPECT_TRUE(r.animated());
  EXPECT_EQ(r.scalarAt(4.0), 20.0);
  EXPECT_EQ(r.scalarAt(0.0), 10.0);
  EXPECT_FALSE(Track::ramp(3, 1.0, 3, 2.0).animated());  // one frame: the start value
  EXPECT_EQ(Track::ramp(3, 1.0, 3, 2.0).scalarAt(3.0), 1.0);
}

TEST(RigTrack, JsonKeysStepAndBareListForms) {
  LightRig rig = rigOf(R"({"version": 1, "lights": [
      {"type": "uniform", "radiance": {"interpolation": "step", "keys": [{"frame": 0, "value": 1}, {"frame": 4, "value": [2, 3, 4]}]}},
      {"type": "uniform", "radiance": [{"frame": 0, "value": 0}, {"frame": 8, "value": [8, 4, 2]}]}]})");
  const Track& step = rig.lights[0].color;
  EXPECT_EQ(step.interp, Track::Interp::Step);
  EXPECT_EQ(step.at(3.99), glm::dvec3(1.0));  // a scalar colour is grey
  EXPECT_EQ(step.at(4.0), glm::dvec3(2, 3, 4));
  const Track& lin = rig.lights[1].color;
  EXPECT_EQ(lin.interp, Track::Interp::Linear);
  EXPECT_EQ(lin.at(2.0), glm::dvec3(2, 1, 0.5));
  // The sum of two uniform skies: l_0 = 2√π (L₁ + L₂) at frame 2: (1 + 2, 1 + 1, 1 + 0.5).
  prt::sh::ShRgb l = rig.evaluate(2.0, 1);
  const double k = 2.0 * std::sqrt(kPi);
  EXPECT_NEAR(l.c[0].r, k * 3.0, 1e-6 * k * 3.0);  // float output
  EXPECT_NEAR(l.c[0].g, k * 2.0, 1e-6 * k * 2.0);
  EXPECT_NEAR(l.c[0].b, k * 1.5, 1e-6 * k * 1.5);
}

TEST(RigTrack, DirectionsSlerpAlongTheGreatCircle) {
  LightRig rig = rigOf(R"({"version": 1, "lights": [{"type": "sun", "radius": 0,
      "direction": [{"frame": 0, "value": [2, 0, 0]}, {"frame": 10, "value": [0, 0, 5]}]}]})");
  const RigLight& sun = rig.lights[0];
  // Keys are normalised; the direction turns at a constant rate: 9° per frame here.
  for (double f : {0.0, 2.5, 5.0, 7.5, 10.0}) {
    const double a = f * 9.0 * kPi / 180.0;
    glm::dvec3 d = sun.directionAt(f);
    EXPECT_NEAR(d.x, std::cos(a), 1e-14) << f;
    EXPECT_NEAR(d.y, 0.0, 1e-14) << f;
    EXPECT_NEAR(d.z, std::sin(a), 1e-14) << f;
  }
}

// ---------------------------------------------------------------------------------------------
// Suns and disks

TEST(RigSun, AzimuthElevationEqualsTheSameSunAsAVector) {
  // az 30°, el 40°: (cos 40 sin 30, sin 40, cos 40 cos 30), the orbit camera's convention.
  const double az = 30.0 * kPi / 180.0, el = 40.0 * kPi / 180.0;
  const glm::dvec3 d(std::cos(el) * std::sin(az), std::sin(el), std::cos(el) * std::cos(az));
  LightRig byAngles = rigOf(R"({"version": 1, "lights": [{"type": "sun", "azimuth": 30, "elevation": 40,
                                "radius": 2, "irradiance": [3, 2, 1]}]})");
  LightRig byVector =
      rigOf(prt::cat(R"({"version": 1, "lights": [{"type": "sun", "direction": [)", num(d.x * 7), ", ", num(d.y * 7),
                     ", ", num(d.z * 7), R"(], "radius": 2, "irradiance": [3, 2, 1]}]})"));
  prt::sh::ShRgb a = byAngles.evaluate(0, 8), b = byVector.evaluate(0, 8);
  // Both directions agree to ~1e-16; the coefficients are rounded to float (relative 6e-8).
  EXPECT_LT(maxAbsDiff(a, b), 1e-6 * maxAbs(a));
  // Azimuth 90°, elevation 0° is +X; elevation 90° is +Y.
  glm::dvec3 x = prt::azimuthElevationDirection(90, 0), y = prt::azimuthElevationDirection(123, 90);
  EXPECT_NEAR(glm::distance(x, glm::dvec3(1, 0, 0)), 0.0, 1e-15);
  EXPECT_NEAR(glm::distance(y, glm::dvec3(0, 1, 0)), 0.0, 1e-15);
}

TEST(RigSun, KeyedAnglesInterpolateAsAngles) {
  LightRig rig = rigOf(R"({"version": 1, "lights": [{"type": "sun", "radius": 0.5,
      "azimuth": [{"frame": 0, "value": 0}, {"frame": 10, "value": 90}],
      "elevation": [{"frame": 0, "value": 10}, {"frame": 10, "value": 50}]}]})");
  // Frame 5: azimuth 45°, elevation 30° (not the slerp of the end directions).
  prt::sh::ShRgb expected =
      prt::projectSun(4, prt::azimuthElevationDirection(45, 30), 0.5 * kPi / 180.0, glm::dvec3(1.0));
  EXPECT_LT(maxAbsDiff(rig.evaluate(5, 4), expected), 1e-6 * maxAbs(expected));
}

TEST(RigDisk, IrradianceOnItsAxisIsPiSin2RTimesRadiance) {
  // A cap of radiance L and radius r < 90° gives E = π sin² r · L on a surface facing it. With 8
  // unwindowed bands the SH irradiance is that of the degree-7 Legendre partial sum of
  // max(t, 0), which differs from the exact value by -0.12%, -0.23%, +0.28%, -0.38% at these
  // radii (computed independently by Simpson quadrature of Σ Â_l (2l+1)/4π ∫ P_l): 0.5% bounds it.
  const glm::dvec3 axis = glm::normalize(glm::dvec3(0.3, 0.8, -0.5));
  for (double r : {30.0, 45.0, 60.0, 80.0}) {
    LightRig rig =
        rigOf(prt::cat(R"({"version": 1, "lights": [{"type": "disk", "direction": [)", num(axis.x), ", ", num(axis.y),
                       ", ", num(axis.z), R"(], "radius": [{"frame": 0, "value": 1}, {"frame": 10, "value": )",
                       1 + 2 * (r - 1), R"(}], "radiance": [2, 1, 0.5]}]})"));
    prt::sh::ShRgb l = rig.evaluate(5, 8);  // the radius is r halfway
    glm::vec3 e = prt::sh::irradiance(l, glm::vec3(axis));
    const double s2 = std::pow(std::sin(r * kPi / 180.0), 2);
    EXPECT_NEAR(e.r, kPi * s2 * 2.0, 0.005 * kPi * s2 * 2.0) << r;
    EXPECT_NEAR(e.b, kPi * s2 * 0.5, 0.005 * kPi * s2 * 0.5) << r;
    // Bands 0 and 1 in closed form, exact for any radius (docs/lights.md):
    // l_00 = y_00 L 2π (1 - cos r), l_1m = √(3/4π) L π sin² r d_m.
    const double c = std::cos(r * kPi / 180.0);
    EXPECT_NEAR(l.c[0].r, 0.5 / std::sqrt(kPi) * 2.0 * 2 * kPi * (1 - c), 1e-6);
    const double b1 = std::sqrt(3.0 / (4 * kPi)) * 2.0 * kPi * s2;
    EXPECT_NEAR(l.c[1].r, b1 * axis.y, 1e-6);
    EXPECT_NEAR(l.c[2].r, b1 * axis.z, 1e-6);
    EXPECT_NEAR(l.c[3].r, b1 * axis.x, 1e-6);
  }
}

TEST(RigDisk, IrradianceFormIsTheDiskOfMatchingRadiance) {
  // "irradiance": E means radiance E / (π sin² r) inside the disk.
  LightRig a = rigOf(R"({"version": 1, "lights": [{"type": "disk", "azimuth": 200, "elevation": 45, "radius": 20,
                         "irradiance": [0.2, 1.5, 0.3]}]})");
  const double s2 = std::pow(std::sin(20 * kPi / 180.0), 2);
  prt::sh::ShRgb expected = prt::projectDiskRadiance(6, prt::azimuthElevationDirection(200, 45), 20 * kPi / 180.0,
                                                     glm::dvec3(0.2, 1.5, 0.3) / (kPi * s2));
  EXPECT_LT(maxAbsDiff(a.evaluate(0, 6), expected), 1e-6 * maxAbs(expected));
}

TEST(RigLights, SeveralLightsSumLinearlyAndTheWindowAppliesToTheSum) {
  TempDir dir;
  const std::string env =
      R"({"type": "environment", "file": ")" + kEsplanade +
      R"(", "axis": [1, 1, 0], "rotation": [{"frame": 0, "value": 0}, {"frame": 8, "value": 80}], "intensity": [1, 0.5, 2]})";
  const std::string sun =
      R"({"type": "sun", "azimuth": 10, "elevation": [{"frame": 0, "value": 5}, {"frame": 8, "value": 85}], "radius": 1, "irradiance": 3})";
  const std::string disk = R"({"type": "disk", "direction": [0, 0.2, 1], "radius": 25, "radiance": [0.5, 0.1, 0.1]})";
  const std::string sky = R"({"type": "uniform", "radiance": [0.1, 0.2, 0.3]})";
  auto rig = [](const std::vector<std::string>& lights, const std::string& window) {
    std::string list;
    for (const std::string& l : lights) list += (list.empty() ? "" : ", ") + l;
    return rigOf("{\"version\": 1, \"window\": \"" + window + "\", \"lights\": [" + list + "]}");
  };
  for (const char* window : {"none", "hann"}) {
    prt::sh::ShRgb all = rig({env, sun, disk, sky}, window).evaluate(3.5, 5);
    prt::sh::ShRgb sum(5);
    for (const std::string& l : {env, sun, disk, sky}) sum += rig({l}, window).evaluate(3.5, 5);
    // Float sums of the same terms in another order: a few float ulps of the largest term.
    EXPECT_LT(maxAbsDiff(all, sum), 1e-6 * maxAbs(all)) << window;
  }
  // The window is really applied: Hann scales band 4 of 5 by (1 + cos(4π/5))/2 ≈ 0.095.
  prt::sh::ShRgb none = rig({disk}, "none").evaluate(0, 5), hann = rig({disk}, "hann").evaluate(0, 5);
  const float w4 = float((1 + std::cos(kPi * 4 / 5)) / 2);
  EXPECT_NEAR(hann.c[prt::sh::index(4, 0)].r, w4 * none.c[prt::sh::index(4, 0)].r, 1e-6);
  EXPECT_EQ(hann.c[0], none.c[0]);
}

// ---------------------------------------------------------------------------------------------
// Environment maps turned about any axis

TEST(RigEnvironment, FullTurnAboutAnyAxisReproducesTheFirstFrame) {
  const std::string axes[] = {"[0, 1, 0]", "[1, 2, -0.5]", "[-0.3, 0.1, 0.9]"};
  for (const std::string& axis : axes) {
    LightRig rig = rigOf(envJson(kEsplanade, axis, R"([{"frame": 0, "value": 0}, {"frame": 48, "value": 360}])"));
    prt::sh::ShRgb first = rig.evaluate(0, 8), last = rig.evaluate(48, 8), half = rig.evaluate(24, 8);
    // D(R(360°)) is the identity to ~1e-15 (sin 2π ≈ -2.4e-16); the rotation's output is rounded
    // to float: at most a float ulp of the largest coefficient (6e-8). Measured: 0, bit-identical.
    EXPECT_LT(maxAbsDiff(first, last), 1e-6 * maxAbs(first)) << axis;
    // Half a turn changes the light (the test can fail): more than 5% of the largest coefficient.
    EXPECT_GT(maxAbsDiff(first, half), 0.05 * maxAbs(first)) << axis;
    // Rotation keeps the power in each band.
    EXPECT_NEAR(half.c[0].r, first.c[0].r, 1e-6 * first.c[0].r);
  }
}

// The SH of a band-limited environment (bands 0..3, random coefficients) written as a map.
prt::ImageRgb bandLimitedMap(int width, int height, const std::function<glm::dvec3(const glm::dvec3&)>& turnBack,
                             const std::vector<glm::dvec3>& coeffs) {
  prt::ImageRgb map(width, height);
  double y[16];
  for (int row = 0; row < height; ++row)
    for (int x = 0; x < width; ++x) {
      glm::dvec3 d = prt::equirectDirection((x + 0.5) / width, (row + 0.5) / height);
      prt::sh::evaluate(4, turnBack(d), y);
      glm::dvec3 v(0.0);
      for (int i = 0; i < 16; ++i) v += coeffs[i] * y[i];
      map.at(x, row) = glm::vec3(v);
    }
  return map;
}

TEST(RigEnvironment, RotatingTheShEqualsProjectingTheRotatedMap) {
  // f = Σ c_i y_i over bands 0..3. The rig turns f's projection by R; brute force writes the
  // map of the turned function, g(ω) = f(R⁻¹ ω), pixel by pixel and projects that. Both go
  // through projectEnvironment, whose error for a smooth map is the second-order term
  // (Δθ²/24)(F(0) + F(π) - l_i) of docs/lights.md: Δθ = π/256 gives 6.3e-6 times values of
  // order |f| ≤ 4 here, for each map. 2e-4 bounds the difference of the two (measured 3.9e-5).
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-0.5, 0.5);
  std::vector<glm::dvec3> c(16);
  for (glm::dvec3& v : c) v = glm::dvec3(u(rng), u(rng), u(rng));
  c[0] += glm::dvec3(3.0);
  TempDir dir;
  const std::string file = dir.file("band_limited.exr");
  prt::writeExr(file, bandLimitedMap(
                          512, 256, [](const glm::dvec3& d) { return d; }, c));
  const glm::dvec3 axis(1.0, 2.0, -0.5);
  LightRig rig =
      rigOf(envJson("band_limited.exr", "[1, 2, -0.5]", R"([{"frame": 0, "value": 0}, {"frame": 10, "value": 100}])"),
            dir.file(""));
  const double angle = 75.0;  // frame 7.5
  const glm::dmat3 R = prt::sh::rotationAxis(axis, angle);
  prt::sh::ShRgb rotated = rig.evaluate(7.5, 4);
  prt::sh::ShRgb brute =
      prt::projectEnvironment(bandLimitedMap(
                                  512, 256, [&](const glm::dvec3& d) { return glm::transpose(R) * d; }, c),
                              4);
  EXPECT_LT(maxAbsDiff(rotated, brute), 2e-4);
  // The opposite turn is far off, so a sign error in the convention fails.
  prt::sh::ShRgb wrongWay = prt::projectEnvironment(bandLimitedMap(
                                                        512, 256, [&](const glm::dvec3& d) { return R * d; }, c),
                                                    4);
  EXPECT_GT(maxAbsDiff(rotated, wrongWay), 0.05);
}

TEST(RigEnvironment, MapIsLoadedOnceAndProjectedOncePerBandCount) {
  TempDir dir;
  const std::string map = dir.file("sky.hdr");
  fs::copy_file(kEsplanade, map);
  LightRig rig = prt::loadLightRig(dir.write("rig.json", envJson("sky.hdr", "[0, 1, 0]", "30")));
  prt::sh::ShRgb before = rig.evaluate(0, 3);
  fs::remove(map);  // loaded at load time: evaluating at any band count still works
  EXPECT_EQ(maxAbsDiff(rig.evaluate(0, 3), before), 0.0);
  prt::sh::ShRgb five = rig.evaluate(0, 5);
  EXPECT_EQ(maxAbsDiff(prt::sh::resize(five, 3), before), 0.0);  // same projection, truncated
  LightRig copy = rig;                                           // copies share the cache
  EXPECT_EQ(maxAbsDiff(copy.evaluate(0, 5), five), 0.0);
}

TEST(RigEnvironment, MatchesTheRelightShortcutConvention) {
  // Rotation about +Y by θ is sh::rotationY(θ), the rotation of `prt relight --env-rotate θ`.
  LightRig rig = rigOf(envJson(kEsplanade, "[0, 1, 0]", "90", R"(, "intensity": 2)"));
  prt::sh::ShRgb expected =
      prt::sh::Rotation(4, prt::sh::rotationY(90)).apply(prt::projectEnvironment(prt::loadHdrImage(kEsplanade), 4));
  expected *= 2.0f;
  EXPECT_LT(maxAbsDiff(rig.evaluate(0, 4), expected), 1e-6 * maxAbs(expected));
}

// ---------------------------------------------------------------------------------------------
// Errors: one line, naming the file and the JSON path

void expectRigError(const std::string& json, const std::string& mention, const std::string& base = ".") {
  std::string e = errorOf([&] { rigOf(json, base); });
  EXPECT_EQ(e.rfind("rig.json: ", 0), 0u) << e;
  EXPECT_EQ(e.find('\n'), std::string::npos) << e;
  EXPECT_NE(e.find(mention), std::string::npos) << "expected '" << mention << "' in: " << e;
}

TEST(RigErrors, MissingAndMalformedFiles) {
  std::string e = errorOf([] { prt::loadLightRig("/nonexistent/rig.json"); });
  EXPECT_EQ(e.rfind("/nonexistent/rig.json: ", 0), 0u) << e;
  expectRigError("{\"version\": 1, \"lights\": [", "invalid JSON");
  expectRigError("{\"version\": 1, \"lights\": [{\"type\": \"uniform\", \"radiance\": NaN}]}", "invalid JSON");
  expectRigError("{\"version\": 1, \"lights\": [{\"type\": \"uniform\", \"radiance\": 1e999}]}", "invalid JSON");
  expectRigError("[1, 2]", "expected a JSON object");
  expectRigError("{\"lights\": []}", "version: missing");
  expectRigError("{\"version\": 2, \"lights\": []}", "version: 2 is not supported");
  expectRigError("{\"version\": 1, \"lights\": []}", "lights: empty");
  expectRigError("{\"version\": 1}", "lights: missing");
  expectRigError("{\"version\": 1, \"window\": \"gauss\", \"lights\": []}", "window: 'gauss'");
  expectRigError("{\"version\": 1, \"fps\": 0, \"lights\": []}",
                 "fps: must be in [0.001, 10000] frames per second (got 0)");
}

TEST(RigErrors, UnknownKeysAndTypes) {
  expectRigError(envJson(kEsplanade, "[0, 1, 0]", "0", ", \"rotaton\": 3"),
                 "lights[0].rotaton: unknown key (did you mean 'rotation'?)");
  expectRigError("{\"version\": 1, \"lihgts\": []}", "lihgts: unknown key (did you mean 'lights'?)");
  expectRigError("{\"version\": 1, \"lights\": [{\"type\": \"uniform\", \"radiance\": 1, \"zzzzzzzz\": 2}]}",
                 "lights[0].zzzzzzzz: unknown key (expected one of: type, name, radiance)");
  expectRigError("{\"version\": 1, \"lights\": [{\"type\": \"spotlight\"}]}",
                 "lights[0].type: 'spotlight' is not a light type");
  expectRigError("{\"version\": 1, \"lights\": [{\"radiance\": 1}]}", "lights[0].type: missing");
  expectRigError(
      "{\"version\": 1, \"lights\": [{\"type\": \"uniform\", \"radiance\": {\"keys\": [{\"frame\": 0, "
      "\"valeu\": 1}]}}]}",
      "lights[0].radiance.keys[0].valeu: unknown key (did you mean 'value'?)");
}

TEST(RigErrors, KeyframesAndValues) {
  expectRigError(R"({"version": 1, "lights": [{"type": "uniform", "radiance": 1},
      {"type": "sun", "direction": [0, 1, 0], "radius": {"keys": [{"frame": 0, "value": 1}, {"frame": 12, "value": 2}, {"frame": 10, "value": 3}]}}]})",
                 "rig.json: lights[1].radius.keys[2].frame: frames must increase (10 after 12)");
  expectRigError(
      R"({"version": 1, "lights": [{"type": "uniform", "radiance": [{"frame": 3, "value": 1}, {"frame": 3, "value": 2}]}]})",
      "lights[0].radiance[1].frame: frames must increase");
  expectRigError(R"({"version": 1, "lights": [{"type": "uniform", "radiance": -1}]})",
                 "lights[0].radiance: must be >= 0");
  expectRigError(R"({"version": 1, "lights": [{"type": "uniform", "radiance": [1, 2]}]})",
                 "lights[0].radiance: expected a number or [R, G, B]");
  expectRigError(R"({"version": 1, "lights": [{"type": "sun", "direction": [0, 1, 0], "radius": [1, 2, 3]}]})",
                 "lights[0].radius: expected a number");
  expectRigError(R"({"version": 1, "lights": [{"type": "sun", "direction": [0, 1, 0], "radius": 90}]})",
                 "lights[0].radius: sun radius must be in [0, 90)");
  expectRigError(
      R"({"version": 1, "lights": [{"type": "sun", "azimuth": 0, "elevation": [{"frame": 0, "value": 10}, {"frame": 5, "value": 95}]}]})",
      "lights[0].elevation[1].value: elevation must be in [-90, 90]");
  expectRigError(R"({"version": 1, "lights": [{"type": "sun", "azimuth": 0}]})", "lights[0].elevation: missing");
  expectRigError(R"({"version": 1, "lights": [{"type": "sun", "direction": [0, 1, 0], "azimuth": 0, "elevation": 3}]})",
                 "lights[0]: give either \"direction\" or \"azimuth\" + \"elevation\", not both");
  expectRigError(R"({"version": 1, "lights": [{"type": "sun", "direction": [0, 0, 0]}]})",
                 "lights[0].direction: direction is zero");
  expectRigError(
      R"({"version": 1, "lights": [{"type": "sun", "direction": [{"frame": 0, "value": [0, 1, 0]}, {"frame": 9, "value": [0, -2, 0]}]}]})",
      "lights[0].direction[1].value: opposite to the previous key");
  expectRigError(R"({"version": 1, "lights": [{"type": "disk", "direction": [0, 1, 0], "radiance": 1}]})",
                 "lights[0].radius: missing");
  expectRigError(
      R"({"version": 1, "lights": [{"type": "disk", "direction": [0, 1, 0], "radius": 5, "radiance": 1, "irradiance": 1}]})",
      "not both");
  expectRigError(
      R"({"version": 1, "lights": [{"type": "disk", "direction": [0, 1, 0], "radius": 120, "irradiance": 1}]})",
      "lights[0].radius: a disk given by irradiance needs a radius in (0, 90)");
  expectRigError(
      R"({"version": 1, "lights": [{"type": "uniform", "radiance": {"interpolation": "cubic", "keys": [{"frame": 0, "value": 1}]}}]})",
      "lights[0].radiance.interpolation: 'cubic': expected linear or step");
  expectRigError(R"({"version": 1, "lights": [{"type": "uniform", "radiance": {"keys": []}}]})",
                 "lights[0].radiance.keys: empty");
  expectRigError(R"({"version": 1, "lights": [{"type": "uniform", "radiance": [{"frame": "a", "value": 1}]}]})",
                 "lights[0].radiance[0].frame: expected a number");
}

TEST(RigErrors, EnvironmentMapAndAxis) {
  expectRigError(envJson("/nonexistent/sky.hdr", "[0, 1, 0]", "0"), "lights[0].file: /nonexistent/sky.hdr: ");
  expectRigError(envJson("relative/sky.exr", "[0, 1, 0]", "0"), "lights[0].file: /base/relative/sky.exr", "/base");
  expectRigError(envJson(kEsplanade, "[0, 0, 0]", "0"), "lights[0].axis: direction is zero");
  expectRigError(envJson(kEsplanade, R"([{"frame": 0, "value": [0, 1, 0]}, {"frame": 1, "value": [0, 0, 0]}])", "0"),
                 "lights[0].axis[1].value: direction is zero");
  expectRigError("{\"version\": 1, \"lights\": [{\"type\": \"environment\"}]}", "lights[0].file: missing");
  expectRigError(envJson(kEsplanade, "[0, 1, 0]", "0", R"(, "intensity": [1, -1, 1])"),
                 "lights[0].intensity: must be >= 0");
}

// ---------------------------------------------------------------------------------------------
// Bundled rigs and the examples of docs/lights.md

TEST(RigFiles, EveryBundledRigLoadsAndEvaluates) {
  int count = 0;
  for (const auto& entry : fs::directory_iterator(sourceFile("scenes/rigs"))) {
    if (entry.path().extension() != ".json") continue;
    SCOPED_TRACE(entry.path().string());
    LightRig rig = prt::loadLightRig(entry.path().string());
    EXPECT_TRUE(rig.animated());
    EXPECT_TRUE(rig.fps.has_value());
    auto [lo, hi] = rig.keyRange();
    EXPECT_LT(lo, hi);
    for (double f = lo - 1; f <= hi + 1; f += 0.5) {
      prt::sh::ShRgb l = rig.evaluate(f, 3);
      for (const glm::vec3& c : l.c) EXPECT_TRUE(std::isfinite(c.r + c.g + c.b));
      // Every bundled rig of distant lights lights from above at some time: the +Y irradiance
      // is positive. A rig of lamps alone (lamps_*.json) has no distant light: its lamps shine.
      if (!rig.lights.empty()) EXPECT_GT(prt::sh::irradiance(l, glm::vec3(0, 1, 0)).g, 0.0f) << f;
      for (const prt::RigLocalLight& lamp : rig.locals) {
        const prt::LocalLight at = lamp.at(f);
        EXPECT_NO_THROW(prt::validate(at));
        EXPECT_GT(at.punctual() ? at.intensity.g : at.radiance.g, 0.0) << f;
      }
    }
    EXPECT_FALSE(rig.lights.empty() && rig.locals.empty());
    ++count;
  }
  EXPECT_GE(count, 3);
}

TEST(RigFiles, EveryExampleInTheDocsLoads) {
  std::ifstream in(sourceFile("docs/lights.md"));
  std::stringstream ss;
  ss << in.rdbuf();
  const std::string doc = ss.str();
  std::regex block("```json\\n([\\s\\S]*?)```");
  int count = 0;
  for (auto it = std::sregex_iterator(doc.begin(), doc.end(), block); it != std::sregex_iterator(); ++it) {
    const std::string json = (*it)[1];
    if (json.find("\"version\"") == std::string::npos) continue;  // fragments
    SCOPED_TRACE(json.substr(0, 200));
    // Map paths in the examples are relative to scenes/rigs/, where the bundled copies live.
    LightRig rig = prt::parseLightRig(json, "docs/lights.md", sourceFile("scenes/rigs"));
    EXPECT_EQ(rig.evaluate(1.5, 3).bands, 3);
    ++count;
  }
  EXPECT_GE(count, 3);
}

}  // namespace
