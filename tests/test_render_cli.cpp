// `prt render` option handling, end to end through the real binary at tiny sizes on OSMesa:
// which camera is used (and where an orbit camera sits), what -o accepts, how a rig's frame
// range is bounded, loose option values, and probe grids from another bake (docs/render.md).
#include <gtest/gtest.h>

#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <glm/glm.hpp>
#include <nlohmann/json.hpp>

#include "prt/error.h"
#include "prt/image.h"
#include "prt/light.h"

namespace prt {
namespace {

namespace fs = std::filesystem;

struct Result {
  int status = -1;
  std::string err;
};

// A fresh folder for one test; `name` is unique per test, the pid per test process.
fs::path freshDir(const std::string& name) {
  fs::path d = fs::temp_directory_path() / cat("prt_render_cli_", name, "_", ::getpid());
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

// `prt ARGS`, stderr captured in a file beside (not inside) the folders the test inspects.
Result prt(const std::string& args, const fs::path& dir) {
  const fs::path errFile = dir.parent_path() / (dir.filename().string() + ".stderr");
  const int raw = std::system(cat(PRT_EXE, " ", args, " 2>", errFile.string()).c_str());
  Result r;
  r.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
  std::ifstream in(errFile);
  r.err.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  return r;
}

int lines(const std::string& text) { return int(std::count(text.begin(), text.end(), '\n')); }

std::string source(const std::string& relative) { return cat(PRT_SOURCE_DIR, "/", relative); }
std::string whiteSky() { return source("scenes/env/white_sky_64.hdr"); }

// Bakes `gltf` into dir/NAME.glb (and NAME.vdb with probes) and returns the .glb path.
std::string bake(const std::string& gltf, const fs::path& dir, const std::string& name, const std::string& extra = "") {
  const std::string glb = (dir / (name + ".glb")).string();
  const Result r = prt(cat("bake ", gltf, " -o ", glb, " --samples 16 --bounces 0 -q ", extra), dir);
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
TEST(RenderCli, OrbitOptionsPlaceTheCameraEvenWhenTheFileHasOne) {
  const fs::path d = freshDir("orbit");
  const std::string glb = bake(planeWithCamera(d), d, "plane_camera");
  const fs::path out = d / "out";
  const std::string common = cat("render ", glb, " --env ", whiteSky(), " --size 64x48 --frames 0 ");

  const Orbit o{glm::dvec3(0.3, 0.0, -0.2), 5.0, 30.0, 60.0, 30.0};
  const Result r = prt(cat(common, "--orbit-target 0.3,0,-0.2 --orbit-distance 5 --orbit-azimuth 30 ",
                        "--orbit-elevation 60 --orbit-fov 30 -o ", (out / "orbit.exr").string()),
                    d);
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.err.find("camera: orbit (target 0.3,0,-0.2, distance 5, azimuth 30, elevation 60, vertical fov 30"),
            std::string::npos)
      << r.err;
  EXPECT_GT(checkPlaneCoverage(loadHdrImage((out / "orbit.exr").string()), o), 3000);

  const Result file = prt(cat(common, "-o ", (out / "file.exr").string()), d);
  ASSERT_EQ(file.status, 0) << file.err;
  EXPECT_NE(file.err.find("camera: glTF camera 'Side'"), std::string::npos) << file.err;
  const Result named = prt(cat(common, "--camera Side -o ", (out / "named.exr").string()), d);
  ASSERT_EQ(named.status, 0) << named.err;
  EXPECT_NE(named.err.find("camera: glTF camera 'Side'"), std::string::npos) << named.err;
}

// Without a file camera and without --orbit-distance, the orbit looks at the bounds' centre
// from the distance at which the bounding sphere (radius √2 for the plane) touches the
// narrower field of view: r / sin(min(fov/2, atan(tan(fov/2) · aspect))).
TEST(RenderCli, DefaultOrbitDistanceFramesTheBounds) {
  const fs::path d = freshDir("orbit_default");
  const std::string glb = bake(source("scenes/plane.gltf"), d, "plane");
  const fs::path out = d / "out";
  for (const char* size : {"64x48", "40x60"}) {  // wide: the vertical fov limits; tall: the horizontal one
    const Result r = prt(cat("render ", glb, " --env ", whiteSky(), " --size ", size,
                          " --orbit-elevation 35 --orbit-fov 50 -o ", (out / "f.exr").string()),
                      d);
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
TEST(RenderCli, BackgroundSkyShowsTheMapAlongEachRay) {
  const fs::path d = freshDir("background");
  const std::string glb = bake(source("scenes/plane.gltf"), d, "plane");
  const fs::path out = d / "out";
  const std::string map = source("scenes/env/royal_esplanade_128.hdr");
  const std::string common = cat("render ", glb, " --env ", map, " --env-rotate 30 --env-intensity 0.5 --size 80x60 ",
                                 "--orbit-azimuth 20 --orbit-elevation 15 --orbit-distance 3 --orbit-fov 60 -o ");
  const Result black = prt(common + (out / "black.exr").string(), d);
  const Result sky = prt(common + (out / "sky.exr").string() + " --background sky", d);
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

// Frames are written on a thread of their own while the next one renders: a write that fails
// (frame 2's name is taken by a folder) stops the run with that one error, exit 1; the frames
// before it are whole, none after it is written, and no temporary file is left.
TEST(RenderCli, AFailedWriteStopsTheRunWithOneLine) {
  const fs::path d = freshDir("write_error");
  const std::string glb = bake(source("scenes/plane.gltf"), d, "plane");
  const fs::path out = d / "out";
  fs::create_directories(out / "f_02.exr");
  const Result r = prt(cat("render ", glb, " --env ", whiteSky(), " --frames 0-5 --size 48x32 --png -q -o ",
                           (out / "f_%02d.exr").string()),
                       d);
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
TEST(RenderCli, BadOptionsAreOneLineAndWriteNothing) {
  const fs::path d = freshDir("bad_options");
  const std::string glb = bake(planeWithCamera(d), d, "plane_camera");
  const fs::path out = d / "out";
  const std::string frames = (out / "f_%04d.exr").string();
  struct Case {
    std::string args, message;
    int status = 2;
  };
  const std::vector<Case> cases = {
      {"--frames 0-1junk -o " + frames, "--frames 0-1junk: expected A-B"},
      {"--frames 5-2 -o " + frames, "--frames 5-2: the last frame comes before the first"},
      {"--frames -1-2 -o " + frames, "--frames -1-2: expected A-B"},
      {"--frames 0-99999999999 -o " + frames, "--frames 0-99999999999: expected A-B"},
      {"--size 8x8x9 -o " + frames, "--size 8x8x9: expected WxH"},
      {"--size 0x10 -o " + frames, "--size 0x10: expected WxH"},
      {"--size 100000x100000 -o " + frames, "--size 100000x100000: expected WxH, each 1..16384"},
      {"--size 12000x12000 -o " + frames, "--size 12000x12000: 144000000 pixels, more than"},
      {"--frames 0-2 -o " + (out / "f.exr").string(), "3 frames need a frame-number field"},
      {"-o " + (out / "f.png").string(), "expected an .exr file name"},
      {"-o " + (out / "f_%04d").string(), "expected an .exr file name"},
      {"-o " + (out / "f_%5d.exr").string(), "bad frame field '%5d'"},
      {"-o " + (out / "f_%d_%d.exr").string(), "more than one '%'"},
      {"-o " + (out / "%d/f.exr").string(), "the frame field must be in the file name"},
      {"-o " + glb + "/f.exr", "is not a folder", 1},
      {"--contact-sheet " + glb + "/s.png -o " + frames, "--contact-sheet " + glb + "/s.png: '" + glb + "' is not a folder", 1},
      {"--camera Side --orbit-azimuth 10 -o " + frames, "--camera excludes --orbit-azimuth"},
      {"--orbit-fov 180 -o " + frames, "--orbit-fov: 180 is not a finite number between 0 and 180"},
      {"--orbit-elevation 90 -o " + frames, "--orbit-elevation: 90 is not a finite number within -89..89"},
      {"--orbit-distance 0 -o " + frames, "--orbit-distance: 0 is not a finite number > 0"},
      {"--orbit-target 1,nan,0 -o " + frames, "--orbit-target: nan is not a finite number"},
      {"--camera Front -o " + frames, "no camera named 'Front'", 1},
      {"--probe-lookup texel -o " + frames, "--probe-lookup: 'texel' is not pixel or vertex"},
      {"--background blue -o " + frames, "--background: 'blue' is not black or sky"},
      {"--msaa 3 -o " + frames, "--msaa: 3 is not a power of two: 1, 2, 4, 8"},
      {"--msaa 64 -o " + frames, "--msaa 64: llvmpipe", 1},
      {"--frames 0-20000 --size 100x100 --contact-sheet " + (out / "s.png").string() + " -o " + frames,
       "--contact-sheet " + (out / "s.png").string() + ": 20001 frames make a 14482x14380 sheet"},
  };
  for (const Case& c : cases) {
    const Result r = prt(cat("render ", glb, " --env ", whiteSky(), " ", c.args), d);
    EXPECT_EQ(r.status, c.status) << c.args << "\n" << r.err;
    EXPECT_EQ(lines(r.err), 1) << c.args << "\n" << r.err;
    EXPECT_NE(r.err.find(c.message), std::string::npos) << c.args << "\n" << r.err;
    EXPECT_FALSE(fs::exists(out)) << c.args << ": output folder created";
  }
}

bool onPath(const std::string& program) {
  return std::system(cat("command -v ", program, " >/dev/null 2>&1").c_str()) == 0;
}

std::vector<std::string> namesIn(const fs::path& dir) {
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(dir)) names.push_back(e.path().filename().string());
  std::sort(names.begin(), names.end());
  return names;
}

// One frame may have a plain name; missing output folders are created (with their parents),
// for the frames, the contact sheet and the video alike, and hold no temporary files after.
TEST(RenderCli, PlainNameForOneFrameAndFoldersAreCreated) {
  const fs::path d = freshDir("plain_name");
  const std::string glb = bake(source("scenes/plane.gltf"), d, "plane");
  const fs::path out = d / "new" / "sub";
  const bool ffmpeg = onPath("ffmpeg");
  const Result r = prt(cat("render ", glb, " --env ", whiteSky(), " --size 8x8 --frames 7 --png -o ",
                           (out / "still.exr").string(), " --contact-sheet ", (d / "sheets" / "s.png").string(),
                           ffmpeg ? cat(" --mp4 ", (d / "video" / "v.mp4").string()) : ""),
                       d);
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
TEST(RenderCli, FarRigKeyframeNeedsExplicitFrames) {
  const fs::path d = freshDir("far_rig");
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
  const std::string common = cat("render ", glb, " --size 8x8 -o ", (out / "f_%d.exr").string(), " --rig ");
  for (double key : {1e9, 100000.0}) {  // 100001 frames (0 .. 100000): one over the limit
    const std::string far = rig("far.json", 0.5, key);
    const Result r = prt(common + far, d);
    EXPECT_EQ(r.status, 1) << r.err;
    EXPECT_EQ(lines(r.err), 1) << r.err;
    EXPECT_NE(r.err.find(far + ": keyframes run from frame 0.5 to "), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("more than 100000 are rendered only with an explicit --frames A-B"), std::string::npos)
        << r.err;
    EXPECT_TRUE(fs::is_empty(out));
  }
  // Keys past ±1e9: the rig itself is refused, naming the key.
  const std::string late = rig("late.json", 3e9, 3e9 + 4.0);
  const Result lateRun = prt(common + late + " -q", d);
  EXPECT_EQ(lateRun.status, 1) << lateRun.err;
  EXPECT_EQ(lines(lateRun.err), 1) << lateRun.err;
  EXPECT_NE(lateRun.err.find(late + ": lights[0].rotation[0].frame: frame 3e+09 is beyond"), std::string::npos)
      << lateRun.err;
  const Result explicitFrames = prt(common + rig("far.json", 0.5, 1e9) + " --frames 2-3 -q", d);
  ASSERT_EQ(explicitFrames.status, 0) << explicitFrames.err;
  EXPECT_TRUE(fs::exists(out / "f_2.exr") && fs::exists(out / "f_3.exr"));
  EXPECT_EQ(std::distance(fs::directory_iterator(out), fs::directory_iterator()), 2);
  // Keys at 0.5 and 3.2: frames 0 to 4.
  const Result near = prt(common + rig("near.json", 0.5, 3.2) + " -q", d);
  ASSERT_EQ(near.status, 0) << near.err;
  EXPECT_TRUE(fs::exists(out / "f_0.exr") && fs::exists(out / "f_4.exr") && !fs::exists(out / "f_5.exr"));
}

// A probe grid must come from the same bake as the .glb: both store the bake's scene name and
// seed (docs/formats.md). Another scene or seed: a warning; other bands: an error.
TEST(RenderCli, ProbesFromAnotherBakeWarnOrFail) {
  const fs::path d = freshDir("probe_match");
  const std::string probeArgs = "--probe-dims 2,2,2 --probe-samples 16 --probes ";
  const std::string plane = source("scenes/plane.gltf");
  const std::string glb = bake(plane, d, "plane", probeArgs + (d / "plane.vdb").string());
  bake(plane, d, "reseeded", "--seed 9 " + probeArgs + (d / "reseeded.vdb").string());
  bake(source("scenes/cavity.gltf"), d, "cavity", probeArgs + (d / "cavity.vdb").string());
  bake(plane, d, "two_bands", "--bands 2 " + probeArgs + (d / "two_bands.vdb").string());
  const fs::path out = d / "out";
  fs::create_directories(out);
  auto render = [&](const std::string& vdb) {
    return prt(cat("render ", glb, " --env ", whiteSky(), " --size 8x8 -o ", (out / "f.exr").string(), " --probes ",
                   (d / vdb).string()),
               d);
  };
  const Result same = render("plane.vdb");
  EXPECT_EQ(same.status, 0) << same.err;
  EXPECT_EQ(same.err.find("warning"), std::string::npos) << same.err;
  const Result other = render("cavity.vdb");
  EXPECT_EQ(other.status, 0) << other.err;
  EXPECT_NE(other.err.find(cat("prt: warning: ", (d / "cavity.vdb").string(), " was baked from 'cavity.gltf' (seed 1), ",
                               glb, " from 'plane.gltf' (seed 1)")),
            std::string::npos)
      << other.err;
  const Result reseeded = render("reseeded.vdb");
  EXPECT_EQ(reseeded.status, 0) << reseeded.err;
  EXPECT_NE(reseeded.err.find("was baked from 'plane.gltf' (seed 9)"), std::string::npos) << reseeded.err;
  fs::remove(out / "f.exr");
  const Result bands = render("two_bands.vdb");
  EXPECT_EQ(bands.status, 1) << bands.err;
  EXPECT_EQ(lines(bands.err), 1) << bands.err;
  EXPECT_NE(bands.err.find("two_bands.vdb: 2 bands, but " + glb + " is baked with 3"), std::string::npos) << bands.err;
  EXPECT_TRUE(fs::is_empty(out));
}

// --probe-lookup vertex moves the receivers' probe lookup to their vertices: static surfaces are
// bit-identical, receiver pixels change a little (the lookup is interpolated across each
// triangle; the renderer's own tests compare each mode with its CPU oracle).
TEST(RenderCli, ProbeLookupVertexChangesOnlyTheReceivers) {
  const fs::path d = freshDir("probe_lookup");
  const std::string glb =
      bake(source("scenes/cornell_open.gltf"), d, "room", "--probe-dims 6,6,6 --probe-samples 64 --probes " + (d / "room.vdb").string());
  auto render = [&](const std::string& name, const std::string& probeArgs) {
    const fs::path out = d / (name + ".exr");
    const Result r = prt(cat("render ", glb, " --env ", whiteSky(), " --size 96x72 -q -o ", out.string(), probeArgs), d);
    EXPECT_EQ(r.status, 0) << r.err;
    return loadHdrImage(out.string());
  };
  const std::string probes = " --probes " + (d / "room.vdb").string();
  const ImageRgb pixel = render("pixel", probes + " --probe-lookup pixel");
  const ImageRgb vertex = render("vertex", probes + " --probe-lookup vertex");
  const ImageRgb room = render("room", "");  // without probes the receiver is not drawn
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

}  // namespace
}  // namespace prt
