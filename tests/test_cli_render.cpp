// `prt render` end to end through the real binary at tiny sizes: which camera is used (and where
// an orbit camera sits), what -o accepts, how a rig's frame range is bounded, loose option values,
// probe grids from another bake (docs/render.md); both GL back ends, light rigs, videos and contact
// sheets (docs/lights.md). Every test here starts prt processes that open GL contexts: label gl.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <stb_image.h>
#include <glm/glm.hpp>
#include <nlohmann/json.hpp>

#include "cli_expect.h"
#include "gltf_file.h"
#include "harness.h"
#include "prt/brdf.h"
#include "prt/error.h"
#include "prt/image.h"
#include "prt/light.h"

namespace prt {
namespace {

namespace fs = std::filesystem;

using test::plus;
using test::RunResult;
using test::TempDir;
using Args = std::vector<std::string>;

RunResult prt(const Args& args) { return test::runPrt(args); }

int lines(const std::string& text) { return test::lineCount(text); }

std::string source(const std::string& relative) { return test::sourcePath(relative); }
std::string whiteSky() { return source("scenes/env/white_sky_64.hdr"); }

// Bakes `gltf` into dir/NAME.glb (and NAME.vdb with probes) and returns the .glb path.
std::string bake(const std::string& gltf, const fs::path& dir, const std::string& name, const Args& extra = {}) {
  const std::string glb = (dir / (name + ".glb")).string();
  const RunResult r = prt(plus({"bake", gltf, "-o", glb, "--samples", "16", "--bounces", "0", "-q"}, extra));
  EXPECT_EQ(r.status, 0) << r.err;
  return glb;
}

// The bundled plane ([-1, 1]² at y = 0, facing +Y) with a glTF camera added that looks at it
// edge-on from (0, 0.5, 3), written next to a copy of its buffer.
std::string planeWithCamera(const fs::path& dir) {
  fs::copy_file(source("scenes/plane.bin"), dir / "plane.bin", fs::copy_options::overwrite_existing);
  nlohmann::json j = nlohmann::json::parse(std::ifstream(source("scenes/plane.gltf")));
  j["cameras"] = {{{"name", "Side"}, {"type", "perspective"}, {"perspective", {{"yfov", 0.6}, {"znear", 0.01}}}}};
  j["nodes"].push_back({{"name", "SideCamera"}, {"camera", 0}, {"translation", {0.0, 0.5, 3.0}}});
  j["scenes"][0]["nodes"].push_back(int(j["nodes"].size()) - 1);
  const fs::path out = dir / "plane_camera.gltf";
  std::ofstream(out) << j.dump();
  return out.string();
}

// The orbit camera of docs/render.md, written out independently of the renderer.
struct Orbit {
  glm::dvec3 target{0.0};
  double distance = 0.0, azimuth = 0.0, elevation = 20.0, fov = 45.0;  // degrees
};

// Pixels whose centre ray hits the plane [-1, 1]² (y = 0) must be lit and all others exactly 0.
// Returns the number of pixels compared; pixels whose hit lies within 1e-3 of the plane's edge
// are skipped (float rounding in GL may put the centre on either side).
int checkPlaneCoverage(const ImageRgb& image, const Orbit& o) {
  const double az = glm::radians(o.azimuth), el = glm::radians(o.elevation);
  const glm::dvec3 back(std::cos(el) * std::sin(az), std::sin(el), std::cos(el) * std::cos(az));
  const glm::dvec3 right = glm::normalize(glm::cross(glm::dvec3(0, 1, 0), back)), up = glm::cross(back, right);
  const glm::dvec3 eye = o.target + o.distance * back;
  const double t = std::tan(0.5 * glm::radians(o.fov)), aspect = double(image.width) / image.height;
  int compared = 0, wrong = 0;
  for (int y = 0; y < image.height; ++y)
    for (int x = 0; x < image.width; ++x) {
      const double sx = 2.0 * (x + 0.5) / image.width - 1.0, sy = 1.0 - 2.0 * (y + 0.5) / image.height;
      const glm::dvec3 dir = -back + sx * t * aspect * right + sy * t * up;
      bool hit = false;
      if (dir.y < 0.0) {
        const glm::dvec3 p = eye - eye.y / dir.y * dir;
        const double inside = std::min(1.0 - std::fabs(p.x), 1.0 - std::fabs(p.z));
        if (std::fabs(inside) < 1e-3) continue;
        hit = inside > 0.0;
      }
      const float v = image.at(x, y).g;
      // Lit: the plane (albedo 0.8) under a uniform sky of radiance 1 shows 0.8; 0.4 separates
      // it from the background, which is exactly 0.
      const bool ok = hit ? v > 0.4f : v == 0.0f;
      wrong += !ok;
      EXPECT_TRUE(ok || wrong > 5) << "pixel " << x << "," << y << (hit ? " should show the plane" : " should be 0")
                                   << ", got " << v;
      ++compared;
    }
  EXPECT_EQ(wrong, 0);
  return compared;
}

// Any --orbit-* option selects the orbit camera even when the file has a camera, and the
// orbit sits where docs/render.md says: target + distance · (cos el sin az, sin el, cos el cos az),
// vertical field of view --orbit-fov. Without options the file's camera is used.
TEST(CliRender, OrbitOptionsPlaceTheCameraEvenWhenTheFileHasOne) {
  const TempDir tmp("orbit");
  const fs::path& d = tmp.path();
  const std::string glb = bake(planeWithCamera(d), d, "plane_camera");
  const fs::path out = d / "out";
  const Args common = {"render", glb, "--env", whiteSky(), "--size", "64x48", "--frames", "0"};

  const Orbit o{glm::dvec3(0.3, 0.0, -0.2), 5.0, 30.0, 60.0, 30.0};
  const RunResult r =
      prt(plus(common, {"--orbit-target", "0.3,0,-0.2", "--orbit-distance", "5", "--orbit-azimuth", "30",
                        "--orbit-elevation", "60", "--orbit-fov", "30", "-o", (out / "orbit.exr").string()}));
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.err.find("camera: orbit (target 0.3,0,-0.2, distance 5, azimuth 30, elevation 60, vertical fov 30"),
            std::string::npos)
      << r.err;
  EXPECT_GT(checkPlaneCoverage(loadHdrImage((out / "orbit.exr").string()), o), 3000);

  const RunResult file = prt(plus(common, {"-o", (out / "file.exr").string()}));
  ASSERT_EQ(file.status, 0) << file.err;
  EXPECT_NE(file.err.find("camera: glTF camera 'Side'"), std::string::npos) << file.err;
  const RunResult named = prt(plus(common, {"--camera", "Side", "-o", (out / "named.exr").string()}));
  ASSERT_EQ(named.status, 0) << named.err;
  EXPECT_NE(named.err.find("camera: glTF camera 'Side'"), std::string::npos) << named.err;
}

// Without a file camera and without --orbit-distance, the orbit looks at the bounds' centre
// from the distance at which the bounding sphere (radius √2 for the plane) touches the
// narrower field of view: r / sin(min(fov/2, atan(tan(fov/2) · aspect))).
TEST(CliRender, DefaultOrbitDistanceFramesTheBounds) {
  const TempDir tmp("orbit_default");
  const fs::path& d = tmp.path();
  const std::string glb = bake(source("scenes/plane.gltf"), d, "plane");
  const fs::path out = d / "out";
  for (const char* size : {"64x48", "40x60"}) {  // wide: the vertical fov limits; tall: the horizontal one
    const RunResult r = prt({"render", glb, "--env", whiteSky(), "--size", size, "--orbit-elevation", "35",
                             "--orbit-fov", "50", "-o", (out / "f.exr").string()});
    ASSERT_EQ(r.status, 0) << r.err;
    ImageRgb image = loadHdrImage((out / "f.exr").string());
    const double half = glm::radians(25.0), aspect = double(image.width) / image.height;
    Orbit o;
    o.elevation = 35.0;
    o.fov = 50.0;
    o.distance = std::sqrt(2.0) / std::sin(std::min(half, std::atan(std::tan(half) * aspect)));
    EXPECT_GT(checkPlaneCoverage(image, o), 2000) << size;
  }
}

// --background sky: every pixel that misses the plane shows the rotated, scaled map along its
// centre ray (the orbit camera and the rotation written out here, the map looked up with
// sampleEquirect); pixels on the plane are those of the default black background's frame.
TEST(CliRender, BackgroundSkyShowsTheMapAlongEachRay) {
  const TempDir tmp("background");
  const fs::path& d = tmp.path();
  const std::string glb = bake(source("scenes/plane.gltf"), d, "plane");
  const fs::path out = d / "out";
  const std::string map = source("scenes/env/royal_esplanade_128.hdr");
  const Args common = {"render",
                       glb,
                       "--env",
                       map,
                       "--env-rotate",
                       "30",
                       "--env-intensity",
                       "0.5",
                       "--size",
                       "80x60",
                       "--orbit-azimuth",
                       "20",
                       "--orbit-elevation",
                       "15",
                       "--orbit-distance",
                       "3",
                       "--orbit-fov",
                       "60",
                       "-o"};
  const RunResult black = prt(plus(common, {(out / "black.exr").string()}));
  const RunResult sky = prt(plus(common, {(out / "sky.exr").string(), "--background", "sky"}));
  ASSERT_EQ(black.status, 0) << black.err;
  ASSERT_EQ(sky.status, 0) << sky.err;
  EXPECT_NE(sky.err.find("background sky"), std::string::npos) << sky.err;
  const ImageRgb plain = loadHdrImage((out / "black.exr").string()), img = loadHdrImage((out / "sky.exr").string());
  const ImageRgb env = loadHdrImage(map);
  const Orbit o{glm::dvec3(0.0), 3.0, 20.0, 15.0, 60.0};
  const double az = glm::radians(o.azimuth), el = glm::radians(o.elevation);
  const glm::dvec3 back(std::cos(el) * std::sin(az), std::sin(el), std::cos(el) * std::cos(az));
  const glm::dvec3 right = glm::normalize(glm::cross(glm::dvec3(0, 1, 0), back)), up = glm::cross(back, right);
  const double t = std::tan(0.5 * glm::radians(o.fov)), aspect = double(img.width) / img.height;
  // Turned 30° about +Y (right-handed), the map lights d with what it held at R⁻¹ d.
  const double c = std::cos(glm::radians(30.0)), s30 = std::sin(glm::radians(30.0));
  auto unturn = [&](const glm::dvec3& v) { return glm::dvec3(c * v.x - s30 * v.z, v.y, s30 * v.x + c * v.z); };
  int sky0 = 0, plane = 0;
  double worst = 0.0;
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x) {
      if (plain.at(x, y) != glm::vec3(0.0f)) {
        ++plane;
        EXPECT_EQ(img.at(x, y), plain.at(x, y)) << x << "," << y;
        continue;
      }
      const double sx = 2.0 * (x + 0.5) / img.width - 1.0, sy = 1.0 - 2.0 * (y + 0.5) / img.height;
      const glm::dvec3 dir = glm::normalize(-back + sx * t * aspect * right + sy * t * up);
      const glm::dvec3 want = 0.5 * sampleEquirect(env, unturn(dir)), got(img.at(x, y));
      worst = std::max(worst, glm::length(got - want) / std::max(1.0, glm::length(want)));
      ++sky0;
    }
  std::printf("[ measured ] --background sky: %d sky pixels, worst error %.3g; %d plane pixels unchanged\n", sky0,
              worst, plane);
  EXPECT_GT(sky0, 2000);
  EXPECT_GT(plane, 300);
  EXPECT_LT(worst, 2e-5);  // float rays and texture coordinates (measured 4e-6)
}

// --supersample N renders N x N pixels per output pixel and writes their box mean: the frame is
// downsampleBox of the same view rendered N times larger (bit for bit), the plane's edge against
// the black background becomes partial pixels (so the comparison is not of flat images), the
// summary says so, and a size beyond the limits or N = 0 is refused, writing nothing.
TEST(CliRender, SupersampleWritesTheMeanOfTheLargerFrame) {
  const TempDir tmp("supersample");
  const fs::path& d = tmp.path();
  const std::string glb = bake(planeWithCamera(d), d, "plane");
  const fs::path out = d / "out";
  const Args common = {"render",
                       glb,
                       "--env",
                       whiteSky(),
                       "--sun-elevation",
                       "30",
                       "--sun-azimuth",
                       "10",
                       "--orbit-azimuth",
                       "20",
                       "--orbit-elevation",
                       "35",
                       "--orbit-distance",
                       "3",
                       "-q",
                       "-o"};
  const RunResult big = prt(plus(common, {(out / "big.exr").string(), "--size", "96x64"}));
  const RunResult ss = prt(plus(common, {(out / "ss.exr").string(), "--size", "24x16", "--supersample", "4"}));
  ASSERT_EQ(big.status, 0) << big.err;
  ASSERT_EQ(ss.status, 0) << ss.err;
  Args loud = common;
  loud.erase(std::find(loud.begin(), loud.end(), "-q"));
  const RunResult said = prt(plus(loud, {(out / "said.exr").string(), "--size", "24x16", "--supersample", "4"}));
  ASSERT_EQ(said.status, 0) << said.err;
  EXPECT_NE(said.err.find("1 sample per pixel, supersampled 4x4 (rendered 96x64, averaged down)"), std::string::npos)
      << said.err;
  EXPECT_NE(said.err.find("1 frame 24x16 written"), std::string::npos) << said.err;
  const ImageRgb large = loadHdrImage((out / "big.exr").string()), img = loadHdrImage((out / "ss.exr").string());
  ASSERT_EQ(img.width, 24);
  ASSERT_EQ(img.height, 16);
  const ImageRgb want = downsampleBox(large, 4);
  int mixed = 0;
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x) {
      EXPECT_EQ(img.at(x, y), want.at(x, y)) << x << "," << y;
      // A pixel the plane's edge crosses is a mean of plane and black background.
      const glm::vec3 p = img.at(x, y);
      float lo = 1e30f, hi = 0.0f;
      for (int j = 0; j < 4; ++j)
        for (int i = 0; i < 4; ++i) {
          const float v = large.at(4 * x + i, 4 * y + j).g;
          lo = std::min(lo, v), hi = std::max(hi, v);
        }
      if (hi > 0.0f && lo == 0.0f && p.g > 0.0f && p.g < hi) ++mixed;
    }
  EXPECT_GT(mixed, 8);
  EXPECT_THROW(downsampleBox(large, 5), Error);
  const RunResult tooBig = prt(plus(common, {(out / "x.exr").string(), "--size", "4096x4096", "--supersample", "4"}));
  EXPECT_EQ(tooBig.status, 2) << tooBig.err;
  EXPECT_EQ(lines(tooBig.err), 1) << tooBig.err;
  EXPECT_NE(tooBig.err.find("--supersample 4 with --size 4096x4096: renders 16384x16384"), std::string::npos)
      << tooBig.err;
  const RunResult zero = prt(plus(common, {(out / "x.exr").string(), "--supersample", "0"}));
  EXPECT_EQ(zero.status, 2) << zero.err;
  EXPECT_NE(zero.err.find("--supersample"), std::string::npos) << zero.err;
  EXPECT_FALSE(fs::exists(out / "x.exr"));
}

// Frames are written on a thread of their own while the next one renders: a write that fails
// (frame 2's name is taken by a folder) stops the run with that one error, exit 1; the frames
// before it are whole, none after it is written, and no temporary file is left.
TEST(CliRender, AFailedWriteStopsTheRunWithOneLine) {
  const TempDir tmp("write_error");
  const fs::path& d = tmp.path();
  const std::string glb = bake(source("scenes/plane.gltf"), d, "plane");
  const fs::path out = d / "out";
  fs::create_directories(out / "f_02.exr");
  const RunResult r = prt({"render", glb, "--env", whiteSky(), "--frames", "0-5", "--size", "48x32", "--png", "-q",
                           "-o", (out / "f_%02d.exr").string()});
  EXPECT_EQ(r.status, 1) << r.err;
  EXPECT_EQ(lines(r.err), 1) << r.err;
  EXPECT_NE(r.err.find("f_02.exr"), std::string::npos) << r.err;
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(out)) names.push_back(e.path().filename().string());
  std::sort(names.begin(), names.end());
  EXPECT_EQ(names, (std::vector<std::string>{"f_00.exr", "f_00.png", "f_01.exr", "f_01.png", "f_02.exr"}));
  EXPECT_EQ(loadHdrImage((out / "f_01.exr").string()).width, 48);
}

// Each bad value is one line, exit 2 for a usage error and 1 for bad input (a file, a folder, the
// GL), and nothing written (the output folder stays absent: -o's folder is created only when
// the first frame is written).
TEST(CliRender, BadOptionsAreOneLineAndWriteNothing) {
  const TempDir tmp("bad_options");
  const fs::path& d = tmp.path();
  const std::string glb = bake(planeWithCamera(d), d, "plane_camera");
  const fs::path out = d / "out";
  const std::string frames = (out / "f_%04d.exr").string();
  struct Case {
    Args args;
    std::string message;
    int status = 2;
  };
  const std::vector<Case> cases = {
      {{"--frames", "0-1junk", "-o", frames}, "--frames 0-1junk: expected A-B"},
      {{"--frames", "5-2", "-o", frames}, "--frames 5-2: the last frame comes before the first"},
      {{"--frames", "-1-2", "-o", frames}, "--frames -1-2: expected A-B"},
      {{"--frames", "0-99999999999", "-o", frames}, "--frames 0-99999999999: expected A-B"},
      {{"--size", "8x8x9", "-o", frames}, "--size 8x8x9: expected WxH"},
      {{"--size", "0x10", "-o", frames}, "--size 0x10: expected WxH"},
      {{"--size", "100000x100000", "-o", frames}, "--size 100000x100000: expected WxH, each 1..16384"},
      {{"--size", "12000x12000", "-o", frames}, "--size 12000x12000: 144000000 pixels, more than"},
      {{"--frames", "0-2", "-o", (out / "f.exr").string()}, "3 frames need a frame-number field"},
      {{"-o", (out / "f.png").string()}, "expected an .exr file name"},
      {{"-o", (out / "f_%04d").string()}, "expected an .exr file name"},
      {{"-o", (out / "f_%5d.exr").string()}, "bad frame field '%5d'"},
      {{"-o", (out / "f_%d_%d.exr").string()}, "more than one '%'"},
      {{"-o", (out / "%d/f.exr").string()}, "the frame field must be in the file name"},
      {{"-o", glb + "/f.exr"}, "is not a folder", 1},
      {{"--contact-sheet", glb + "/s.png", "-o", frames},
       "--contact-sheet " + glb + "/s.png: '" + glb + "' is not a folder",
       1},
      {{"--camera", "Side", "--orbit-azimuth", "10", "-o", frames}, "--camera excludes --orbit-azimuth"},
      {{"--orbit-fov", "180", "-o", frames}, "--orbit-fov: 180 is not a finite number between 0 and 180"},
      {{"--orbit-elevation", "90", "-o", frames}, "--orbit-elevation: 90 is not a finite number within -89..89"},
      {{"--orbit-distance", "0", "-o", frames}, "--orbit-distance: 0 is not a finite number > 0"},
      {{"--orbit-target", "1,nan,0", "-o", frames}, "--orbit-target: nan is not a finite number"},
      {{"--camera", "Front", "-o", frames}, "no camera named 'Front'", 1},
      {{"--probe-lookup", "texel", "-o", frames}, "--probe-lookup: 'texel' is not pixel or vertex"},
      {{"--background", "blue", "-o", frames}, "--background: 'blue' is not black or sky"},
      {{"--msaa", "3", "-o", frames}, "--msaa: 3 is not a power of two: 1, 2, 4, 8"},
      {{"--msaa", "64", "-o", frames}, "--msaa 64: llvmpipe", 1},
      {{"--frames", "0-20000", "--size", "100x100", "--contact-sheet", (out / "s.png").string(), "-o", frames},
       "--contact-sheet " + (out / "s.png").string() + ": 20001 frames make a 14482x14380 sheet"},
  };
  for (const Case& c : cases) {
    const RunResult r = prt(plus({"render", glb, "--env", whiteSky()}, c.args));
    std::string args;
    for (const std::string& a : c.args) args += a + " ";
    EXPECT_EQ(r.status, c.status) << args << "\n" << r.err;
    EXPECT_EQ(lines(r.err), 1) << args << "\n" << r.err;
    EXPECT_NE(r.err.find(c.message), std::string::npos) << args << "\n" << r.err;
    EXPECT_FALSE(fs::exists(out)) << args << ": output folder created";
  }
}

std::vector<std::string> namesIn(const fs::path& dir) {
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(dir)) names.push_back(e.path().filename().string());
  std::sort(names.begin(), names.end());
  return names;
}

// One frame may have a plain name; missing output folders are created (with their parents),
// for the frames, the contact sheet and the video alike, and hold no temporary files after.
TEST(CliRender, PlainNameForOneFrameAndFoldersAreCreated) {
  const TempDir tmp("plain_name");
  const fs::path& d = tmp.path();
  const std::string glb = bake(source("scenes/plane.gltf"), d, "plane");
  const fs::path out = d / "new" / "sub";
  const bool ffmpeg = test::onPath("ffmpeg");
  const RunResult r = prt(plus({"render", glb, "--env", whiteSky(), "--size", "8x8", "--frames", "7", "--png", "-o",
                                (out / "still.exr").string(), "--contact-sheet", (d / "sheets" / "s.png").string()},
                               ffmpeg ? Args{"--mp4", (d / "video" / "v.mp4").string()} : Args{}));
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(namesIn(out), (std::vector<std::string>{"still.exr", "still.png"}));
  EXPECT_EQ(namesIn(d / "sheets"), std::vector<std::string>{"s.png"});
  if (ffmpeg) {
    EXPECT_EQ(namesIn(d / "video"), std::vector<std::string>{"v.mp4"});
  }
  EXPECT_NE(r.err.find("1 frame 8x8 written"), std::string::npos) << r.err;
}

// A rig's keyframe range is the default frame range, rounded outwards. A key far away (the rig
// loader allows keys up to frame 1e9) makes a range too long to render by accident: refused
// unless --frames is given, which then renders just those frames. Keys beyond ±1e9 (where a
// frame number would no longer fit an int) are refused by the rig loader itself.
TEST(CliRender, FarRigKeyframeNeedsExplicitFrames) {
  const TempDir tmp("far_rig");
  const fs::path& d = tmp.path();
  const std::string glb = bake(source("scenes/plane.gltf"), d, "plane");
  const fs::path out = d / "out";
  fs::create_directories(out);
  auto rig = [&](const std::string& name, double firstKey, double lastKey) {
    const fs::path p = d / name;
    std::ofstream(p) << nlohmann::json{
        {"version", 1},
        {"lights",
         {{{"type", "environment"},
           {"file", whiteSky()},
           {"rotation", {{{"frame", firstKey}, {"value", 0}}, {{"frame", lastKey}, {"value", 360}}}}}}}};
    return p.string();
  };
  const Args common = {"render", glb, "--size", "8x8", "-o", (out / "f_%d.exr").string(), "--rig"};
  for (double key : {1e9, 100000.0}) {  // 100001 frames (0 .. 100000): one over the limit
    const std::string far = rig("far.json", 0.5, key);
    const RunResult r = prt(plus(common, {far}));
    EXPECT_EQ(r.status, 1) << r.err;
    EXPECT_EQ(lines(r.err), 1) << r.err;
    EXPECT_NE(r.err.find(far + ": keyframes run from frame 0.5 to "), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("more than 100000 are rendered only with an explicit --frames A-B"), std::string::npos)
        << r.err;
    EXPECT_TRUE(fs::is_empty(out));
  }
  // Keys past ±1e9: the rig itself is refused, naming the key.
  const std::string late = rig("late.json", 3e9, 3e9 + 4.0);
  const RunResult lateRun = prt(plus(common, {late, "-q"}));
  EXPECT_EQ(lateRun.status, 1) << lateRun.err;
  EXPECT_EQ(lines(lateRun.err), 1) << lateRun.err;
  EXPECT_NE(lateRun.err.find(late + ": lights[0].rotation[0].frame: frame 3e+09 is beyond"), std::string::npos)
      << lateRun.err;
  const RunResult explicitFrames = prt(plus(common, {rig("far.json", 0.5, 1e9), "--frames", "2-3", "-q"}));
  ASSERT_EQ(explicitFrames.status, 0) << explicitFrames.err;
  EXPECT_TRUE(fs::exists(out / "f_2.exr") && fs::exists(out / "f_3.exr"));
  EXPECT_EQ(std::distance(fs::directory_iterator(out), fs::directory_iterator()), 2);
  // Keys at 0.5 and 3.2: frames 0 to 4.
  const RunResult near = prt(plus(common, {rig("near.json", 0.5, 3.2), "-q"}));
  ASSERT_EQ(near.status, 0) << near.err;
  EXPECT_TRUE(fs::exists(out / "f_0.exr") && fs::exists(out / "f_4.exr") && !fs::exists(out / "f_5.exr"));
}

// A probe grid must come from the same bake as the .glb: both store the bake's scene name and
// seed (docs/formats.md). Another scene or seed: a warning; other bands: an error. A .glb whose
// bounce operator holds rows for its own probes (the default bake) refuses any other grid.
TEST(CliRender, ProbesFromAnotherBakeWarnOrFail) {
  const TempDir tmp("probe_match");
  const fs::path& d = tmp.path();
  const Args probeArgs = {"--no-operator", "--probe-dims", "2,2,2", "--probe-samples", "16", "--probes"};
  const std::string plane = source("scenes/plane.gltf");
  const std::string glb = bake(plane, d, "plane", plus(probeArgs, {(d / "plane.vdb").string()}));
  const std::string withRows =
      bake(plane, d, "plane_rows",
           {"--probe-dims", "2,2,2", "--probe-samples", "16", "--probes", (d / "plane_rows.vdb").string()});
  bake(plane, d, "reseeded", plus(plus({"--seed", "9"}, probeArgs), {(d / "reseeded.vdb").string()}));
  bake(source("scenes/cavity.gltf"), d, "cavity", plus(probeArgs, {(d / "cavity.vdb").string()}));
  bake(plane, d, "two_bands", plus(plus({"--bands", "2"}, probeArgs), {(d / "two_bands.vdb").string()}));
  const fs::path out = d / "out";
  fs::create_directories(out);
  auto render = [&](const std::string& vdb) {
    return prt({"render", glb, "--env", whiteSky(), "--size", "8x8", "-o", (out / "f.exr").string(), "--probes",
                (d / vdb).string()});
  };
  const RunResult same = render("plane.vdb");
  EXPECT_EQ(same.status, 0) << same.err;
  EXPECT_EQ(same.err.find("warning"), std::string::npos) << same.err;
  const RunResult other = render("cavity.vdb");
  EXPECT_EQ(other.status, 0) << other.err;
  EXPECT_NE(other.err.find(cat("prt: warning: ", (d / "cavity.vdb").string(),
                               " was baked from 'cavity.gltf' (seed 1), ", glb, " from 'plane.gltf' (seed 1)")),
            std::string::npos)
      << other.err;
  const RunResult refused = prt({"render", withRows, "--env", whiteSky(), "--size", "8x8", "-o",
                                 (out / "refused.exr").string(), "--probes", (d / "cavity.vdb").string()});
  EXPECT_EQ(refused.status, 1) << refused.err;
  EXPECT_EQ(lines(refused.err), 1) << refused.err;
  EXPECT_NE(refused.err.find("probe rows: made for a 2 x 2 x 2 lattice"), std::string::npos) << refused.err;
  EXPECT_FALSE(fs::exists(out / "refused.exr"));
  const RunResult reseeded = render("reseeded.vdb");
  EXPECT_EQ(reseeded.status, 0) << reseeded.err;
  EXPECT_NE(reseeded.err.find("was baked from 'plane.gltf' (seed 9)"), std::string::npos) << reseeded.err;
  fs::remove(out / "f.exr");
  const RunResult bands = render("two_bands.vdb");
  EXPECT_EQ(bands.status, 1) << bands.err;
  EXPECT_EQ(lines(bands.err), 1) << bands.err;
  EXPECT_NE(bands.err.find("two_bands.vdb: 2 bands, but " + glb + " is baked with 3"), std::string::npos) << bands.err;
  EXPECT_TRUE(fs::is_empty(out));
}

// A file with a zero-area triangle goes through every command with default options: each one
// that reads a scene drops the triangle with the same one warning, and what prt bake wrote is
// read by prt relight, prt render and prt info.
TEST(CliRender, DegenerateTrianglesAreDroppedByEveryCommand) {
  const TempDir tmp("degenerate");
  const fs::path& d = tmp.path();
  test::GltfFile f;
  // The floor [-1, 1]² facing +Y, and triangle 2: three points on its edge z = -1.
  const int floor = f.mesh({-1, 0, -1, 1, 0, -1, 1, 0, 1, -1, 0, 1, 0, 0, -1},
                           {0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1, 0}, {0, 2, 1, 0, 3, 2, 0, 1, 4});
  f.node({{"mesh", floor}}, true);
  const std::string gltf = f.write("degenerate", d);
  const std::string warning = "mesh 1 / primitive 0: dropped 1 degenerate (zero-area) triangle (triangle 2) of 3";
  auto warnsOnce = [&](const std::string& text) {
    const size_t at = text.find(warning);
    return at != std::string::npos && text.find(warning, at + 1) == std::string::npos;
  };

  const std::string glb = (d / "floor.glb").string(), vdb = (d / "floor.vdb").string();
  const RunResult baked = prt({"bake", gltf, "-o", glb, "--samples", "16", "--bounces", "1", "--probes", vdb,
                               "--probe-dims", "2,2,2", "--probe-samples", "16"});
  ASSERT_EQ(baked.status, 0) << baked.err;
  EXPECT_TRUE(warnsOnce(baked.err)) << baked.err;
  const RunResult relit = prt({"relight", glb, "--env", whiteSky(), "-o", (d / "lit.glb").string()});
  EXPECT_EQ(relit.status, 0) << relit.err;
  EXPECT_TRUE(warnsOnce(relit.err)) << relit.err;
  const RunResult rendered = prt(
      {"render", glb, "--probes", vdb, "--env", whiteSky(), "--size", "16x8", "-o", (d / "f.exr").string(), "--png"});
  EXPECT_EQ(rendered.status, 0) << rendered.err;
  EXPECT_TRUE(warnsOnce(rendered.err)) << rendered.err;
  EXPECT_TRUE(fs::exists(d / "f.png"));
  const RunResult info = prt({"info", glb, vdb});
  EXPECT_EQ(info.status, 0) << info.err;
  EXPECT_TRUE(warnsOnce(info.out)) << info.out;
  EXPECT_NE(info.out.find("triangles   2"), std::string::npos) << info.out;

  // The old option is accepted and says it does nothing.
  const RunResult old = prt({"bake", gltf, "-o", (d / "old.glb").string(), "--samples", "4", "--allow-degenerate"});
  EXPECT_EQ(old.status, 0) << old.err;
  EXPECT_NE(old.err.find("--allow-degenerate is deprecated and does nothing"), std::string::npos) << old.err;
}

// --probe-lookup vertex moves the receivers' probe lookup to their vertices: static surfaces are
// bit-identical, receiver pixels change a little (the lookup is interpolated across each
// triangle; the renderer's own tests compare each mode with its CPU oracle).
TEST(CliRender, ProbeLookupVertexChangesOnlyTheReceivers) {
  const TempDir tmp("probe_lookup");
  const fs::path& d = tmp.path();
  const std::string glb =
      bake(source("scenes/cornell_open.gltf"), d, "room",
           {"--probe-dims", "6,6,6", "--probe-samples", "64", "--probes", (d / "room.vdb").string()});
  auto render = [&](const std::string& name, const Args& probeArgs) {
    const fs::path out = d / (name + ".exr");
    const RunResult r =
        prt(plus({"render", glb, "--env", whiteSky(), "--size", "96x72", "-q", "-o", out.string()}, probeArgs));
    EXPECT_EQ(r.status, 0) << r.err;
    return loadHdrImage(out.string());
  };
  const Args probes = {"--probes", (d / "room.vdb").string()};
  const ImageRgb pixel = render("pixel", plus(probes, {"--probe-lookup", "pixel"}));
  const ImageRgb vertex = render("vertex", plus(probes, {"--probe-lookup", "vertex"}));
  const ImageRgb room = render("room", {});  // without probes the receiver is not drawn
  ASSERT_EQ(pixel.width, vertex.width);
  float peak = 0.0f;
  for (const glm::vec3& p : pixel.pixels) peak = std::max(peak, p.g);
  int receiver = 0, changed = 0, staticChanged = 0;
  float worst = 0.0f;
  for (size_t i = 0; i < pixel.pixels.size(); ++i) {
    const glm::vec3 a = pixel.pixels[i], b = vertex.pixels[i];
    const float diff = std::max({std::fabs(a.r - b.r), std::fabs(a.g - b.g), std::fabs(a.b - b.b)});
    const bool isStatic = a == room.pixels[i];  // the receiver does not cover this pixel
    receiver += !isStatic;
    changed += diff > 0.0f;
    staticChanged += isStatic && diff > 0.0f;
    worst = std::max(worst, diff);
  }
  std::printf("[ measured ] --probe-lookup vertex vs pixel: %d of %d receiver pixels differ, worst %.4g of peak %.4g\n",
              changed, receiver, worst, peak);
  EXPECT_GT(receiver, 20);  // the receiver sphere covers some hundred pixels
  EXPECT_GT(changed, receiver / 4);
  EXPECT_EQ(staticChanged, 0);  // static surfaces are bit-identical
  EXPECT_LT(worst, 0.05f * peak);
}

// ---- Frames, back ends, light rigs, videos and contact sheets (docs/lights.md, docs/render.md)

std::string scene(const std::string& name) { return source("scenes/" + name); }
using test::lineCount;

using test::dirHoldsOnly;
using test::expectCleanFailure;

// The bundled Cornell scene baked once per test process (16 samples, 1 bounce: about a second).
const std::string& bakedCornell() {
  static const std::string path = [] {
    static const TempDir d("rig_cornell");
    std::string out = d.file("cornell.glb");
    RunResult r = prt({"bake", scene("cornell_open.gltf"), "-o", out, "--samples", "16", "--bounces", "1", "-q"});
    EXPECT_EQ(r.status, 0) << r.err;
    return out;
  }();
  return path;
}

std::string esplanade() { return scene("env/royal_esplanade_128.hdr"); }

// Largest |a - b| over all pixels and channels, and the peak of a.
std::pair<double, double> frameDiff(const std::string& a, const std::string& b) {
  ImageRgb x = loadHdrImage(a), y = loadHdrImage(b);
  EXPECT_EQ(x.width, y.width);
  EXPECT_EQ(x.height, y.height);
  double diff = 0.0, peak = 0.0;
  for (size_t i = 0; i < std::min(x.pixels.size(), y.pixels.size()); ++i)
    for (int c = 0; c < 3; ++c) {
      diff = std::max(diff, double(std::fabs(x.pixels[i][c] - y.pixels[i][c])));
      peak = std::max(peak, double(x.pixels[i][c]));
    }
  return {diff, peak};
}

// A full turn of the sky about a tilted axis: the last frame is the first one again. Given by
// the shortcuts and by a rig file, which must agree frame by frame (one code path).
TEST(CliRig, FullTurnRendersTheFirstFrameAgain) {
  const TempDir tmp("rig_turn");
  const fs::path& d = tmp.path();
  RunResult s = prt({"render", bakedCornell(), "--env", esplanade(), "--env-rotate", "0:360", "--env-axis", "1,2,-0.5",
                     "--frames", "0-4", "--size", "64x36", "-o", (d / "s_%d.exr").string()});
  ASSERT_EQ(s.status, 0) << s.err;
  // The summary: frames written, per-frame and per-light-update cost, total.
  EXPECT_NE(s.err.find("5 frames 64x36 written"), std::string::npos) << s.err;
  EXPECT_NE(s.err.find("ms per light update"), std::string::npos) << s.err;
  EXPECT_NE(s.err.find("total"), std::string::npos) << s.err;
  // D(R(360°)) is the identity to ~1e-15 and its float output equals the unrotated light (the
  // library test measures 0 difference); the same light through the same GL pipeline gives the
  // same frame. 1e-6 of the peak allows for nothing more than float rounding.
  auto [diff, peak] = frameDiff((d / "s_0.exr").string(), (d / "s_4.exr").string());
  EXPECT_GT(peak, 0.0);
  EXPECT_LE(diff, 1e-6 * peak);
  auto [half, peak2] = frameDiff((d / "s_0.exr").string(), (d / "s_2.exr").string());
  EXPECT_GT(half, 0.01 * peak2);  // half a turn does change the picture

  fs::path rig = d / "turn.json";
  std::ofstream(rig)
      << R"({"version": 1, "lights": [{"type": "environment", "file": ")" << esplanade()
      << R"(", "axis": [1, 2, -0.5], "rotation": [{"frame": 0, "value": 0}, {"frame": 4, "value": 360}]}]})";
  // No --frames: the rig's keyframe range, 0-4.
  RunResult r =
      prt({"render", bakedCornell(), "--rig", rig.string(), "--size", "64x36", "-o", (d / "r_%d.exr").string()});
  ASSERT_EQ(r.status, 0) << r.err;
  for (int f = 0; f <= 4; ++f) {
    auto [df, pf] = frameDiff((d / cat("s_", f, ".exr")).string(), (d / cat("r_", f, ".exr")).string());
    EXPECT_LE(df, 1e-6 * pf) << f;
  }
  EXPECT_FALSE(fs::exists(d / "r_5.exr"));
}

TEST(CliRig, LightAtAFrameEqualsTheShortcut) {
  const TempDir tmp("rig_light");
  const fs::path& d = tmp.path();
  fs::path rig = d / "turn.json";
  std::ofstream(rig) << R"({"version": 1, "window": "hann", "lights": [{"type": "environment", "file": ")"
                     << esplanade()
                     << R"(", "axis": [1, 2, -0.5], "rotation": [{"frame": 0, "value": 0}, {"frame": 4, "value": 360}]},
                          {"type": "sun", "azimuth": 90, "elevation": [{"frame": 0, "value": 0}, {"frame": 2, "value": 90}]}]})";
  auto coeffs = [&](const Args& args) {
    std::string out = (d / "light.json").string();
    RunResult r = prt(plus(plus({"light"}, args), {"--bands", "4", "-o", out}));
    EXPECT_EQ(r.status, 0) << r.err;
    nlohmann::json j = nlohmann::json::parse(std::ifstream(out));
    std::vector<double> c;
    for (const auto& v : j["coefficients"])
      for (const auto& x : v) c.push_back(x.get<double>());
    return c;
  };
  // Frame 1 of the rig: a 90° turn, the sun at elevation 45 towards +X.
  std::vector<double> a = coeffs({"--rig", rig.string(), "--frame", "1"});
  std::vector<double> b = coeffs({esplanade(), "--env-rotate", "90", "--env-axis", "1,2,-0.5", "--sun-elevation", "45",
                                  "--sun-azimuth", "90", "--window", "hann"});
  ASSERT_EQ(a.size(), b.size());
  double peak = 0;
  for (double x : a) peak = std::max(peak, std::fabs(x));
  // The same rig built two ways: equal up to the float output (and 9-digit JSON).
  for (size_t i = 0; i < a.size(); ++i) EXPECT_NEAR(a[i], b[i], 1e-6 * peak) << i;
}

TEST(CliRig, BadRigMapCameraOrBackEndIsOneLineAndWritesNothing) {
  const TempDir tmp("rig_errors");
  const fs::path& d = tmp.path();
  fs::path out = d / "out";
  fs::create_directories(out);
  fs::path bad = d / "bad.json", missingMap = d / "missing_map.json";
  std::ofstream(bad) << R"({"version": 1, "lights": [{"type": "environment", "file": "x.hdr", "rotaton": 3}]})";
  std::ofstream(missingMap) << R"({"version": 1, "lights": [{"type": "environment", "file": "missing.hdr"}]})";
  const Args render = {"render",   bakedCornell(), "--size", "16x16",
                       "--frames", "0-1",          "-o",     (out / "f_%d.exr").string()};
  expectCleanFailure(prt(plus(render, {"--rig", "/nonexistent/rig.json"})), "/nonexistent/rig.json", out);
  expectCleanFailure(prt(plus(render, {"--rig", bad.string()})), "bad.json: lights[0].rotaton: unknown key", out);
  expectCleanFailure(prt(plus(render, {"--rig", missingMap.string()})),
                     "lights[0].file: " + (d / "missing.hdr").string(), out);
  expectCleanFailure(prt(plus(render, {"--env", "/nonexistent/sky.hdr"})), "/nonexistent/sky.hdr", out);
  expectCleanFailure(prt(plus(render, {"--env", esplanade(), "--camera", "nope"})), "no camera named 'nope'", out);
  expectCleanFailure(prt(plus(render, {"--env", esplanade(), "--gl", "vulkan"})), "vulkan", out, 2);
  expectCleanFailure(prt(plus(render, {"--env", esplanade(), "--exr-compression", "lzma"})),
                     "--exr-compression: 'lzma' is not zip, piz or none", out, 2);
  expectCleanFailure(prt(plus(render, {"--rig", bad.string(), "--env", esplanade()})), "--rig excludes --env", out, 2);
  // A GL back end that cannot start: libglvnd finds no EGL vendor library.
  RunResult noEgl = test::runPrt(plus(render, {"--env", esplanade(), "--gl", "egl"}),
                                 {.env = {{"__EGL_VENDOR_LIBRARY_FILENAMES", "/nonexistent/vendor.json"}}});
  expectCleanFailure(noEgl, "EGL: no display", out);
  expectCleanFailure(prt(plus(render, {"--env", esplanade(), "--env-rotate", "1:x"})), "--env-rotate 1:x", out, 2);
  expectCleanFailure(prt(plus(render, {"--sun-elevation", "100"})), "--sun-elevation: elevation must be in [-90, 90]",
                     out);
  expectCleanFailure(prt(plus(render, {"--env", esplanade(), "--env-axis", "0,0,0"})), "--env-axis: direction is zero",
                     out);
  // Stills: --frame without a rig, and START:END without a frame range.
  expectCleanFailure(prt({"light", "--env", esplanade(), "--frame", "2", "-o", (out / "l.json").string()}), "--frame",
                     out, 2);
  expectCleanFailure(prt({"light", "--env", esplanade(), "--env-rotate", "0:90", "-o", (out / "l.json").string()}),
                     "START:END needs a frame range", out, 2);
}

TEST(CliRender, Mp4ThroughFfmpeg) {
  if (!test::onPath("ffmpeg") || !test::onPath("ffprobe")) GTEST_SKIP() << "ffmpeg/ffprobe not installed";
  const TempDir tmp("mp4");
  const fs::path& d = tmp.path();
  // An odd width: yuv420p needs even sizes, so ffmpeg pads to 34.
  RunResult r =
      prt({"render", bakedCornell(), "--rig", scene("rigs/sun_day.json"), "--frames", "0-5", "--size", "33x24", "--fps",
           "12", "--exposure", "1", "-o", (d / "f_%d.exr").string(), "--mp4", (d / "day.mp4").string()});
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.err.find("video"), std::string::npos) << r.err;
  std::vector<std::string> expected = {"day.mp4"};
  for (int f = 0; f <= 5; ++f) expected.push_back(cat("f_", f, ".exr"));
  EXPECT_TRUE(dirHoldsOnly(d, expected));  // no temporary file left
  const RunResult probe =
      test::run("ffprobe", {"-v", "error", "-select_streams", "v:0", "-count_frames", "-show_entries",
                            "stream=codec_name,pix_fmt,width,height,nb_read_frames,r_frame_rate", "-of", "json",
                            (d / "day.mp4").string()});
  ASSERT_EQ(probe.status, 0) << probe.err;
  nlohmann::json j = nlohmann::json::parse(probe.out);
  const nlohmann::json& s = j["streams"][0];
  EXPECT_EQ(s["codec_name"], "h264");
  EXPECT_EQ(s["pix_fmt"], "yuv420p");
  EXPECT_EQ(s["width"], 34);
  EXPECT_EQ(s["height"], 24);
  EXPECT_EQ(s["nb_read_frames"], "6");
  EXPECT_EQ(s["r_frame_rate"], "12/1");
}

TEST(CliRender, Mp4WithoutFfmpegIsAClearErrorBeforeRendering) {
  const TempDir tmp("mp4_missing");
  const fs::path out = tmp.path() / "out";
  fs::create_directories(out);
  // prt is started by its absolute path, with a PATH that holds no ffmpeg.
  const RunResult r = test::runPrt({"render", bakedCornell(), "--env", esplanade(), "--frames", "0-2", "--size",
                                    "16x16", "-o", (out / "f_%d.exr").string(), "--mp4", (out / "v.mp4").string()},
                                   {.env = {{"PATH", "/nonexistent"}}});
  EXPECT_EQ(r.status, 1);
  EXPECT_EQ(lineCount(r.err), 1) << r.err;
  EXPECT_NE(r.err.find("--mp4 " + (out / "v.mp4").string() + ": ffmpeg not found on PATH"), std::string::npos) << r.err;
  EXPECT_TRUE(dirHoldsOnly(out, {})) << "frames rendered before the error";
}

TEST(CliRender, ContactSheetTilesAreTheDownscaledFrames) {
  const TempDir tmp("sheet");
  const fs::path& d = tmp.path();
  const float exposure = 1.5f;
  RunResult r = prt({"render", bakedCornell(), "--rig", scene("rigs/colored_disks.json"), "--frames", "0-4", "--size",
                     "40x30", "--exposure", "1.5", "--contact-sheet", (d / "sheet.png").string(), "--sheet-tile", "16",
                     "--sheet-columns", "2", "-o", (d / "f_%d.exr").string()});
  ASSERT_EQ(r.status, 0) << r.err;
  // 40x30 into tiles of at most 16: factor k = 3, tiles ceil(40/3) x ceil(30/3) = 14 x 10;
  // 2 columns, 3 rows, 2-pixel gaps: 30 x 34.
  const int k = 3, tw = 14, th = 10, gap = 2;
  int w = 0, h = 0, channels = 0;
  unsigned char* png = stbi_load((d / "sheet.png").c_str(), &w, &h, &channels, 3);
  ASSERT_NE(png, nullptr);
  EXPECT_EQ(w, 2 * tw + gap);
  EXPECT_EQ(h, 3 * th + 2 * gap);
  int worst = 0;
  for (int f = 0; f < 5 && w == 2 * tw + gap && h == 3 * th + 2 * gap; ++f) {
    ImageRgb frame = loadHdrImage((d / cat("f_", f, ".exr")).string());
    const int x0 = (f % 2) * (tw + gap), y0 = (f / 2) * (th + gap);
    for (int ty = 0; ty < th; ++ty)
      for (int tx = 0; tx < tw; ++tx) {
        // The mean over the k × k box (cut at the frame's edge), tone-mapped as --png does.
        glm::dvec3 sum(0.0);
        int count = 0;
        for (int y = ty * k; y < std::min((ty + 1) * k, 30); ++y)
          for (int x = tx * k; x < std::min((tx + 1) * k, 40); ++x, ++count) sum += glm::dvec3(frame.at(x, y));
        glm::vec3 mean(sum / double(count));
        for (int c = 0; c < 3; ++c) {
          float v = std::clamp(mean[c] * std::exp2(exposure), 0.0f, 1.0f);
          int expected = int(std::lround(linearToSrgb(v) * 255.0f));
          int got = png[3 * ((y0 + ty) * w + x0 + tx) + c];
          worst = std::max(worst, std::abs(got - expected));
        }
      }
  }
  // The same double mean rounded to float, the same tone curve: equal bytes; 1 allows for a
  // different summation order landing on the other side of a rounding boundary.
  EXPECT_LE(worst, 1);
  // Gaps and the empty sixth cell are black.
  EXPECT_EQ(png[3 * (0 * w + tw)], 0);
  EXPECT_EQ(png[3 * ((2 * (th + gap) + 1) * w + tw + gap + 1)], 0);
  stbi_image_free(png);
}

TEST(CliRender, FramesOnBothBackEndsAndCleanErrors) {
  const TempDir tmp("render");
  const fs::path& d = tmp.path();
  std::string baked = (d / "c.glb").string();
  ASSERT_EQ(prt({"bake", scene("plane.gltf"), "-o", baked, "--samples", "16", "-q"}).status, 0);
  for (std::string gl : {"osmesa", "egl"}) {
    RunResult r = prt({"render", baked, "--env", scene("env/white_sky_64.hdr"), "--frames", "0-1", "--size", "32x24",
                       "--gl", gl, "--png", "-o", (d / (gl + "_%02d.exr")).string()});
    EXPECT_EQ(r.status, 0) << r.err;
    EXPECT_TRUE(fs::exists(d / (gl + "_00.exr")));
    EXPECT_TRUE(fs::exists(d / (gl + "_01.png")));
  }
  RunResult bad = prt(
      {"render", baked, "--env", scene("env/white_sky_64.hdr"), "--gl", "vulkan", "-o", (d / "x_%02d.exr").string()});
  EXPECT_EQ(bad.status, 2);
  EXPECT_EQ(lineCount(bad.err), 1) << bad.err;
  EXPECT_FALSE(fs::exists(d / "x_00.exr"));
}

// A hostile rig (tests/test_hostile_input.cpp has each limit): one line, exit 1, nothing written.
TEST(CliRig, HostileRigIsOneLineAndWritesNothing) {
  const TempDir tmp("rig_hostile");
  const fs::path& d = tmp.path();
  fs::path out = d / "out";
  fs::create_directories(out);
  fs::path deep = d / "deep.json", huge = d / "huge.json";
  std::ofstream(deep) << "{\"version\": 1, \"lights\": " << std::string(100, '[') << std::string(100, ']') << "}";
  std::ofstream(huge)
      << R"({"version": 1, "lights": [{"type": "uniform", "radiance": [{"frame": 0, "value": 1}, {"frame": 2e9, "value": 2}]}]})";
  expectCleanFailure(
      prt({"render", bakedCornell(), "--rig", deep.string(), "--size", "16x16", "-o", (out / "f_%d.exr").string()}),
      "deep.json: JSON nested deeper than 64 levels", out);
  expectCleanFailure(prt({"light", "--rig", huge.string(), "-o", (out / "l.json").string()}),
                     "huge.json: lights[0].radiance[1].frame: frame 2e+09 is beyond ±1e+09", out);
}

// The bundled real scene (scenes/real/dutch_ship: a third-party model with JPEG textures,
// double-sided materials and MASK sails) through every command, at low sample counts. Under a
// uniform sky of radiance 1 no vertex can send more than 1 (albedo ≤ 1, energy conserved over
// any number of bounces) and none much below 0 (3 bands ring by a few percent at most), and the
// ship covers part of the frame, not all of it (black background). Refinement and the sky detail
// gather run with small budgets: at the defaults this one test took 216 s of the ASan suite.
TEST(CliRealScene, DutchShipGoesThroughEveryCommand) {
  const TempDir tmp("real_ship");
  const fs::path& d = tmp.path();
  const std::string glb = (d / "ship.glb").string(), vdb = (d / "ship.vdb").string();
  RunResult r = prt({"bake", source("scenes/real/dutch_ship/dutch_ship.gltf"), "-o", glb, "--samples", "32",
                     "--bounces", "1", "--refine-budget", "4000", "--refine-samples", "16", "--probes", vdb,
                     "--probe-spacing", "2", "--probe-samples", "64", "-q"});
  ASSERT_EQ(r.status, 0) << r.err;
  const std::string csv = (d / "ship.csv").string();
  r = prt(
      {"relight", glb, "--env", whiteSky(), "--bounce-samples", "16", "-o", (d / "lit.glb").string(), "--csv", csv});
  ASSERT_EQ(r.status, 0) << r.err;
  std::ifstream in(csv);
  std::string line;
  std::getline(in, line);
  size_t rows = 0;
  double sum = 0.0;
  while (std::getline(in, line)) {
    std::vector<double> v;
    std::stringstream ss(line);
    for (std::string f; std::getline(ss, f, ',');) v.push_back(std::stod(f));
    ASSERT_EQ(v.size(), 12u) << line;
    for (int c = 9; c < 12; ++c) {
      ASSERT_TRUE(std::isfinite(v[size_t(c)])) << line;
      EXPECT_LE(v[size_t(c)], 1.0) << line;
      EXPECT_GE(v[size_t(c)], -0.1) << line;
      sum += v[size_t(c)];
    }
    ++rows;
  }
  EXPECT_GE(rows, 64544u);                  // the file's vertices (double-sided ones may add their back side)
  EXPECT_GT(sum / double(3 * rows), 0.01);  // not black: measured 0.037 (dark wood, much of it in shade)
  r = prt({"render", glb, "--env", whiteSky(), "--bounce-samples", "16", "--probes", vdb, "--size", "96x64", "-o",
           (d / "f.exr").string()});
  ASSERT_EQ(r.status, 0) << r.err;
  const ImageRgb image = loadHdrImage((d / "f.exr").string());
  size_t lit = 0;
  for (const glm::vec3& p : image.pixels) lit += p.r + p.g + p.b > 0.0f;
  EXPECT_GT(lit, image.pixels.size() / 20);
  EXPECT_LT(lit, image.pixels.size() * 4 / 5);
  r = prt({"info", glb, vdb});
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.out.find("3 with transfer"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("region        near"), std::string::npos) << r.out;
}

// A sun is a direct light: prt render lights it per pixel with its shadow map and says so. On the
// open plane baked without bounces (t = t⁰) every covered pixel is ρ/π · E · sin(elevation)
// exactly (docs/render.md, "Direct lights and their shadows"; the diffuse material, as the full
// one adds the plane's highlight); --no-direct-lights puts it back into SH and says that instead.
TEST(CliRender, SunIsLitPerPixelAndNamedInTheSummary) {
  const TempDir tmp("sun");
  const fs::path& d = tmp.path();
  const std::string glb = bake(planeWithCamera(d), d, "plane_camera");
  const fs::path out = d / "out";
  const Args common = {"render", glb,      "--sun-elevation", "40",          "--sun-irradiance",
                       "2",      "--size", "64x48",           "--materials", "diffuse"};
  const RunResult r = prt(plus(common, {"-o", (out / "sun.exr").string()}));
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.err.find("direct lights (frame 0; per pixel, exactly, with PCSS shadow maps of 1024x1024"),
            std::string::npos)
      << r.err;
  EXPECT_NE(r.err.find("elevation 40.0°, azimuth 0.0°, radius 0.265°, irradiance (2, 2, 2)"), std::string::npos)
      << r.err;
  const ImageRgb img = loadHdrImage((out / "sun.exr").string());
  const double want = 0.8 / 3.14159265358979 * 2.0 * std::sin(40.0 * 3.14159265358979 / 180.0);
  int covered = 0;
  double worst = 0.0;
  for (const glm::vec3& p : img.pixels)
    if (p != glm::vec3(0.0f)) {
      ++covered;
      worst = std::max(worst, std::abs(double(p.g) - want) / want);
    }
  EXPECT_GT(covered, 300);
  EXPECT_LT(worst, 1e-4);  // float shading of a closed form

  const RunResult sh = prt(plus(common, {"--no-direct-lights", "-o", (out / "sh.exr").string()}));
  ASSERT_EQ(sh.status, 0) << sh.err;
  EXPECT_NE(sh.err.find("direct lights: none apart (--no-direct-lights"), std::string::npos) << sh.err;
}

// `prt render` lights a scene with its own point light by default, per pixel, and needs no other
// light: the plane's centre under a lamp of 3 cd 1 m above it is ρ/π · I / h² (albedo 0.8: 0.764;
// the mean of the 4 pixels around the image's centre, seen from 3 m above with a 10° field of
// view, within 1%: their centres lie 6 mm from the plane's, where E falls by 0.01%; a lamp
// at the wrong height or with a factor such as π or 4π is far off), with --materials diffuse;
// with the full material (the default) its highlight on the rough dielectric is added,
// I / h² · f_spec(n, n) (prt::brdf's specular lobe: F0 0.04, roughness 1, 3.2·10⁻³ sr⁻¹; within
// 5% of it, 6·10⁻⁴ of the pixel). The summary says where
// the light is lit. --no-scene-lights leaves it dark, and then another light is needed.
TEST(CliRender, TheScenesOwnLampLightsItPerPixel) {
  const TempDir tmp("lamp");
  const fs::path& d = tmp.path();
  const std::string glb = bake(test::planeWithLamp(d, 3.0), d, "plane_lamp");
  const fs::path out = d / "lamp.exr";
  const std::vector<std::string> view = {"--size",      "64x48", "--orbit-elevation", "89",  "--orbit-distance", "3",
                                         "--orbit-fov", "10",    "--exr-compression", "none"};
  auto centreOf = [&](const std::vector<std::string>& more) {
    std::vector<std::string> args = {"render", glb, "-o", out.string()};
    args.insert(args.end(), view.begin(), view.end());
    args.insert(args.end(), more.begin(), more.end());
    const RunResult r = prt(args);
    EXPECT_EQ(r.status, 0) << r.err;
    EXPECT_NE(r.err.find("lights inside the scene: 1 (1 per pixel with cube shadow maps"), std::string::npos) << r.err;
    const ImageRgb img = loadHdrImage(out.string());
    return 0.25f * (img.at(31, 23).g + img.at(32, 23).g + img.at(31, 24).g + img.at(32, 24).g);
  };
  const double diffuse = centreOf({"--materials", "diffuse"});
  EXPECT_NEAR(diffuse, 0.8 / 3.14159265358979 * 3.0, 0.01 * 0.764);
  brdf::MetallicRoughness plane;
  plane.baseColor = glm::dvec3(0.8);
  plane.metallic = 0.0;
  plane.roughness = 1.0;
  const glm::dvec3 up(0.0, 1.0, 0.0);
  const double highlight = 3.0 * brdf::evaluate(plane, up, up, up).specular.y;  // 9.5e-3
  EXPECT_NEAR(centreOf({}) - diffuse, highlight, 0.05 * highlight);
  const RunResult dark = prt({"render", glb, "--size", "64x48", "--no-scene-lights", "-o", (d / "dark.exr").string()});
  EXPECT_NE(dark.status, 0);
}

// With lamps alone (no sun), the summary still says how their bounces are lit and what each
// frame's update cost: through the bounce operator (the default bake) its shadow rays and
// products, through the traced gather (a bake without the operator) the gather's rays.
TEST(CliRender, TheSummaryGivesTheLampsBounceCost) {
  const TempDir tmp("lampbounce");
  const fs::path& d = tmp.path();
  const std::string scene = test::planeWithLamp(d, 3.0);
  for (const bool withOperator : {true, false}) {
    const std::string glb = (d / (withOperator ? "op.glb" : "traced.glb")).string();
    Args bakeArgs = {"bake", scene, "-o", glb, "--samples", "16", "--bounces", "1", "--no-refine", "-q"};
    if (!withOperator) bakeArgs.push_back("--no-operator");
    const RunResult b = prt(bakeArgs);
    ASSERT_EQ(b.status, 0) << b.err;
    const RunResult r = prt({"render", glb, "--size", "32x24", "-o", (d / "lamp.exr").string()});
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_NE(r.err.find(withOperator ? "their bounces on baked surfaces through the bake's bounce operator"
                                      : "their bounces on baked surfaces gathered with 256 rays per vertex"),
              std::string::npos)
        << r.err;
    EXPECT_NE(r.err.find("shadow rays "), std::string::npos) << r.err;
    EXPECT_NE(r.err.find(withOperator ? ", products " : ", gather "), std::string::npos) << r.err;
  }
}

}  // namespace
}  // namespace prt
