// The `prt` command end to end, as a user runs it: files in, files out, exit codes, one-line
// errors and no output left behind on failure.
#include <gtest/gtest.h>

#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <nlohmann/json.hpp>

#include "prt/image.h"

namespace prt {
namespace {

namespace fs = std::filesystem;

struct CliRun {
  int status = -1;
  std::string out, err;
};

// Runs `prt ARGS`, capturing stdout and stderr separately.
CliRun prt(const std::string& args) {
  // One capture folder per test process: ctest runs tests in parallel processes.
  fs::path dir = fs::path(::testing::TempDir()) / ("prt_cli_capture_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  std::string outFile = (dir / "stdout.txt").string(), errFile = (dir / "stderr.txt").string();
  std::string cmd = std::string(PRT_EXE) + " " + args + " >" + outFile + " 2>" + errFile;
  int rc = std::system(cmd.c_str());
  CliRun r;
  r.status = WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
  std::ifstream o(outFile), e(errFile);
  std::stringstream so, se;
  so << o.rdbuf();
  se << e.rdbuf();
  r.out = so.str();
  r.err = se.str();
  return r;
}

fs::path tempDir(const std::string& name) {
  fs::path d = fs::path(::testing::TempDir()) / ("prt_cli_" + name);
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

std::string scene(const std::string& name) { return std::string(PRT_SOURCE_DIR) + "/scenes/" + name; }

int lineCount(const std::string& s) {
  int n = 0;
  for (char c : s) n += c == '\n';
  return n;
}

// Only the requested output may exist in the directory: no temporary leftovers.
bool dirHoldsOnly(const fs::path& dir, const std::vector<std::string>& names) {
  size_t n = 0;
  for (const auto& e : fs::directory_iterator(dir)) {
    ++n;
    if (std::find(names.begin(), names.end(), e.path().filename().string()) == names.end()) return false;
  }
  return n == names.size();
}

void expectCleanFailure(const CliRun& r, const std::string& mention, const fs::path& dir, int status = 1) {
  EXPECT_EQ(r.status, status) << r.err;
  EXPECT_EQ(lineCount(r.err), 1) << r.err;
  EXPECT_NE(r.err.find(mention), std::string::npos) << r.err;
  EXPECT_TRUE(dirHoldsOnly(dir, {})) << "output left behind";
}

TEST(Cli, UsageErrorsExitTwo) {
  EXPECT_EQ(prt("").status, 2);
  EXPECT_EQ(prt("bake").status, 2);
  EXPECT_EQ(prt("bake x.gltf -o y.glb --no-such-option").status, 2);
  EXPECT_EQ(prt("frobnicate").status, 2);
  CliRun help = prt("bake --help");
  EXPECT_EQ(help.status, 0);
  EXPECT_NE(help.out.find("--samples"), std::string::npos);
  EXPECT_NE(help.out.find("1024"), std::string::npos);  // defaults are shown
}

TEST(Cli, MissingSceneIsOneLineAndNoOutput) {
  fs::path d = tempDir("missing");
  expectCleanFailure(prt("bake /nonexistent/scene.gltf -o " + (d / "out.glb").string()), "/nonexistent/scene.gltf", d);
}

TEST(Cli, MalformedSceneIsOneLineAndNoOutput) {
  fs::path d = tempDir("malformed");
  fs::path in = fs::path(::testing::TempDir()) / "prt_cli_malformed.gltf";
  std::ofstream(in) << "{ \"asset\": { \"version\": \"2.0\" }, \"meshes\": [ {";
  expectCleanFailure(prt("bake " + in.string() + " -o " + (d / "out.glb").string() + " -q"),
                     "prt_cli_malformed.gltf", d);
}

TEST(Cli, NanGeometryIsOneLineAndNoOutput) {
  fs::path d = tempDir("nan");
  fs::path in = fs::path(::testing::TempDir()) / "prt_cli_nan.gltf";
  // One triangle whose first vertex is (NaN, 0, 0), in an embedded base64 buffer.
  const float pos[9] = {std::nanf(""), 0, 0, 1, 0, 0, 0, 0, 1};
  std::string raw(reinterpret_cast<const char*>(pos), sizeof pos);
  static const char* b64 = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string enc;
  for (size_t i = 0; i < raw.size(); i += 3) {
    uint32_t v = uint8_t(raw[i]) << 16 | (i + 1 < raw.size() ? uint8_t(raw[i + 1]) << 8 : 0) |
                 (i + 2 < raw.size() ? uint8_t(raw[i + 2]) : 0);
    enc += b64[v >> 18 & 63];
    enc += b64[v >> 12 & 63];
    enc += i + 1 < raw.size() ? b64[v >> 6 & 63] : '=';
    enc += i + 2 < raw.size() ? b64[v & 63] : '=';
  }
  nlohmann::json j = {
      {"asset", {{"version", "2.0"}}},
      {"scene", 0},
      {"scenes", {{{"nodes", {0}}}}},
      {"nodes", {{{"mesh", 0}}}},
      {"meshes", {{{"primitives", {{{"attributes", {{"POSITION", 0}}}}}}}}},
      {"buffers", {{{"byteLength", 36}, {"uri", "data:application/octet-stream;base64," + enc}}}},
      {"bufferViews", {{{"buffer", 0}, {"byteLength", 36}}}},
      {"accessors", {{{"bufferView", 0}, {"componentType", 5126}, {"count", 3}, {"type", "VEC3"}}}}};
  std::ofstream(in) << j.dump();
  CliRun r = prt("bake " + in.string() + " -o " + (d / "out.glb").string() + " -q");
  expectCleanFailure(r, "prt_cli_nan.gltf", d);
  EXPECT_NE(r.err.find("finite"), std::string::npos) << r.err;
}

TEST(Cli, UnwritableOutputFailsBeforeBaking) {
  CliRun r = prt("bake " + scene("plane.gltf") + " -o /nonexistent/dir/out.glb -q");
  EXPECT_EQ(r.status, 1);
  EXPECT_EQ(lineCount(r.err), 1) << r.err;
  EXPECT_NE(r.err.find("/nonexistent/dir/out.glb"), std::string::npos) << r.err;
}

TEST(Cli, BakeThenRelightPlaneUnderUniformSkyGivesAlbedo) {
  fs::path d = tempDir("plane");
  std::string baked = (d / "plane.baked.glb").string(), lit = (d / "plane.lit.glb").string(),
              csv = (d / "plane.csv").string();
  CliRun b = prt("bake " + scene("plane.gltf") + " -o " + baked + " --samples 64 --bounces 1");
  ASSERT_EQ(b.status, 0) << b.err;
  EXPECT_NE(b.err.find("rays"), std::string::npos) << "summary expected: " << b.err;
  CliRun r = prt("relight " + baked + " --env " + scene("env/white_sky_64.hdr") + " -o " + lit + " --csv " + csv);
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_TRUE(dirHoldsOnly(d, {"plane.baked.glb", "plane.lit.glb", "plane.csv"}));

  std::ifstream in(csv);
  std::string header;
  std::getline(in, header);
  EXPECT_EQ(header, "node,primitive,vertex,px,py,pz,nx,ny,nz,r,g,b");
  int rows = 0;
  std::string line;
  while (std::getline(in, line)) {
    std::array<double, 12> v{};
    std::stringstream ss(line);
    for (double& x : v) {
      std::string cell;
      std::getline(ss, cell, ',');
      x = std::stod(cell);
    }
    // The plane (albedo 0.8) faces +Y with nothing above it: under a uniform sky of radiance 1
    // its exitant radiance is exactly ρ = 0.8. The map's RGBE encoding of 1.0 is exact and its
    // projection onto SH is exact for a constant up to float rounding (~1e-6); 2e-3 allows for
    // the float transfer sums over 64 samples.
    EXPECT_NEAR(v[9], 0.8, 2e-3) << line;
    EXPECT_NEAR(v[10], 0.8, 2e-3) << line;
    EXPECT_NEAR(v[11], 0.8, 2e-3) << line;
    EXPECT_NEAR(v[7], 1.0, 1e-6) << line;  // normal +Y
    ++rows;
  }
  EXPECT_EQ(rows, 1089);  // every vertex of the 33×33 grid
  CliRun info = prt("info " + baked);
  EXPECT_EQ(info.status, 0) << info.err;
  EXPECT_NE(info.out.find("3 bands"), std::string::npos) << info.out;
}

TEST(Cli, RelightRefusesBadMapAndLeavesNothing) {
  fs::path d = tempDir("badmap");
  fs::path baked = fs::path(::testing::TempDir()) / "prt_cli_badmap.glb";
  ASSERT_EQ(prt("bake " + scene("plane.gltf") + " -o " + baked.string() + " --samples 16 -q").status, 0);
  fs::path map = fs::path(::testing::TempDir()) / "prt_cli_not_a_map.hdr";
  std::ofstream(map) << "this is not an image";
  CliRun r = prt("relight " + baked.string() + " --env " + map.string() + " -o " + (d / "lit.glb").string() +
              " --csv " + (d / "lit.csv").string());
  expectCleanFailure(r, "prt_cli_not_a_map.hdr", d);
  CliRun r2 = prt("relight " + baked.string() + " -o " + (d / "lit.glb").string());
  EXPECT_EQ(r2.status, 2);
  EXPECT_NE(r2.err.find("no lighting"), std::string::npos) << r2.err;
  CliRun r3 = prt("relight " + baked.string() + " --env " + scene("env/white_sky_64.hdr") + " --window bogus -o " +
               (d / "lit.glb").string());
  expectCleanFailure(r3, "bogus", d, 2);
}

// Orientation through the whole chain: a map lit only around +X (u = 0.5) gives positive
// band-1 x coefficient; rotated by +90° about +Y, the light comes from −Z.
TEST(Cli, LightOrientationAndRotation) {
  fs::path d = tempDir("light");
  ImageRgb map(64, 32);
  for (int y = 0; y < 32; ++y)
    for (int x = 0; x < 64; ++x) {
      double u = (x + 0.5) / 64.0;
      map.at(x, y) = glm::vec3(std::fabs(u - 0.5) < 0.1 && std::abs(y - 16) < 4 ? 10.0f : 0.0f);
    }
  std::string exr = (d / "x.exr").string();
  writeExr(exr, map);
  auto coeffs = [&](const std::string& extra) {
    std::string out = (d / "light.json").string();
    CliRun r = prt("light " + exr + " --bands 2 -o " + out + " " + extra);
    EXPECT_EQ(r.status, 0) << r.err;
    nlohmann::json j = nlohmann::json::parse(std::ifstream(out));
    std::array<double, 4> c{};
    for (int i = 0; i < 4; ++i) c[i] = j["coefficients"][i][0].get<double>();
    return c;
  };
  auto c0 = coeffs("");
  EXPECT_GT(c0[3], 0.5 * c0[0]);          // y_3 ∝ x: light from +X
  EXPECT_LT(std::fabs(c0[2]), 0.01 * c0[0]);  // nothing along z
  auto c90 = coeffs("--env-rotate 90");
  EXPECT_LT(c90[2], -0.5 * c90[0]);        // y_2 ∝ z: light now from −Z
  EXPECT_LT(std::fabs(c90[3]), 0.01 * c90[0]);
  EXPECT_NEAR(c90[0], c0[0], 1e-4 * c0[0]);  // rotation keeps the DC term
}

}  // namespace
}  // namespace prt

namespace prt {
namespace {

// Probes through the command line: bake, inspect, query. Above the unoccluded plane, under a
// uniform sky of radiance 1, an upward receiver gets irradiance π (the plane is behind it).
TEST(CliProbes, BakeInfoAndPointsQuery) {
  fs::path d = tempDir("probes");
  std::string baked = (d / "p.glb").string(), vdb = (d / "p.vdb").string();
  CliRun b = prt("bake " + scene("plane.gltf") + " -o " + baked + " --samples 64 --probes " + vdb +
                 " --probe-dims 3,3,3 --probe-bounds -0.5,0.2,-0.5,0.5,1.2,0.5 --probe-samples 1024 -q");
  ASSERT_EQ(b.status, 0) << b.err;
  CliRun info = prt("info " + vdb);
  ASSERT_EQ(info.status, 0) << info.err;
  EXPECT_NE(info.out.find("27 active"), std::string::npos) << info.out;
  fs::path in = d / "in.csv";
  std::ofstream(in) << "x,y,z,nx,ny,nz\n0,0.5,0,0,1,0\n0.1,0.9,-0.2,0,1,0\n";
  CliRun q = prt("probe " + vdb + " --env " + scene("env/white_sky_64.hdr") + " --points " + in.string() + " -o " +
                 (d / "out.csv").string());
  ASSERT_EQ(q.status, 0) << q.err;
  std::ifstream out(d / "out.csv");
  std::string line;
  std::getline(out, line);
  EXPECT_EQ(line, "x,y,z,nx,ny,nz,E_r,E_g,E_b,status");
  int rows = 0;
  while (std::getline(out, line)) {
    EXPECT_EQ(line.substr(line.rfind(',') + 1), "lattice") << line;
    line.erase(line.rfind(','));
    double e = std::stod(line.substr(line.rfind(',') + 1));
    // The probes' direct part integrates y_j y_i with 1024 Sobol directions (~1e-3); the
    // 3-band irradiance of a constant sky is exact. 1% bounds it.
    EXPECT_NEAR(e, M_PI, 0.01 * M_PI) << line;
    ++rows;
  }
  EXPECT_EQ(rows, 2);
  // Outside the grid: the unoccluded light, as the renderer shows it, and said so.
  CliRun far = prt("probe " + vdb + " --env " + scene("env/white_sky_64.hdr") + " --at 0,100,0");
  EXPECT_EQ(far.status, 0) << far.err;
  EXPECT_NE(far.out.find("\"status\": \"outside\""), std::string::npos) << far.out;
  EXPECT_NE(far.err.find("outside"), std::string::npos) << far.err;
}

TEST(CliRender, FramesOnBothBackEndsAndCleanErrors) {
  fs::path d = tempDir("render");
  std::string baked = (d / "c.glb").string();
  ASSERT_EQ(prt("bake " + scene("plane.gltf") + " -o " + baked + " --samples 16 -q").status, 0);
  for (std::string gl : {"osmesa", "egl"}) {
    CliRun r = prt("render " + baked + " --env " + scene("env/white_sky_64.hdr") + " --frames 0-1 --size 32x24 --gl " +
                   gl + " --png -o " + (d / (gl + "_%02d.exr")).string());
    EXPECT_EQ(r.status, 0) << r.err;
    EXPECT_TRUE(fs::exists(d / (gl + "_00.exr")));
    EXPECT_TRUE(fs::exists(d / (gl + "_01.png")));
  }
  CliRun bad = prt("render " + baked + " --env " + scene("env/white_sky_64.hdr") + " --gl vulkan -o " +
                   (d / "x_%02d.exr").string());
  EXPECT_EQ(bad.status, 2);
  EXPECT_EQ(lineCount(bad.err), 1) << bad.err;
  EXPECT_FALSE(fs::exists(d / "x_00.exr"));
}

}  // namespace
}  // namespace prt

// ---- Light rigs, videos and contact sheets through `prt render` (docs/lights.md, docs/render.md)
#include <stb_image.h>

#include "prt/error.h"

namespace prt {
namespace {

// The bundled Cornell scene baked once per test process (16 samples, 1 bounce: about a second).
const std::string& bakedCornell() {
  static const std::string path = [] {
    fs::path d = tempDir(cat("rig_cornell_", ::getpid()));
    std::string out = (d / "cornell.glb").string();
    CliRun r = prt("bake " + scene("cornell_open.gltf") + " -o " + out + " --samples 16 --bounces 1 -q");
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

bool onPath(const std::string& program) {
  return std::system(("command -v " + program + " >/dev/null 2>&1").c_str()) == 0;
}

// A full turn of the sky about a tilted axis: the last frame is the first one again. Given by
// the shortcuts and by a rig file, which must agree frame by frame (one code path).
TEST(CliRig, FullTurnRendersTheFirstFrameAgain) {
  fs::path d = tempDir("rig_turn");
  CliRun s = prt("render " + bakedCornell() + " --env " + esplanade() +
                 " --env-rotate 0:360 --env-axis 1,2,-0.5 --frames 0-4 --size 64x36 -o " + (d / "s_%d.exr").string());
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
  std::ofstream(rig) << R"({"version": 1, "lights": [{"type": "environment", "file": ")" << esplanade()
                     << R"(", "axis": [1, 2, -0.5], "rotation": [{"frame": 0, "value": 0}, {"frame": 4, "value": 360}]}]})";
  // No --frames: the rig's keyframe range, 0-4.
  CliRun r = prt("render " + bakedCornell() + " --rig " + rig.string() + " --size 64x36 -o " + (d / "r_%d.exr").string());
  ASSERT_EQ(r.status, 0) << r.err;
  for (int f = 0; f <= 4; ++f) {
    auto [df, pf] = frameDiff((d / cat("s_", f, ".exr")).string(), (d / cat("r_", f, ".exr")).string());
    EXPECT_LE(df, 1e-6 * pf) << f;
  }
  EXPECT_FALSE(fs::exists(d / "r_5.exr"));
}

TEST(CliRig, LightAtAFrameEqualsTheShortcut) {
  fs::path d = tempDir("rig_light");
  fs::path rig = d / "turn.json";
  std::ofstream(rig) << R"({"version": 1, "window": "hann", "lights": [{"type": "environment", "file": ")" << esplanade()
                     << R"(", "axis": [1, 2, -0.5], "rotation": [{"frame": 0, "value": 0}, {"frame": 4, "value": 360}]},
                          {"type": "sun", "azimuth": 90, "elevation": [{"frame": 0, "value": 0}, {"frame": 2, "value": 90}]}]})";
  auto coeffs = [&](const std::string& args) {
    std::string out = (d / "light.json").string();
    CliRun r = prt("light " + args + " --bands 4 -o " + out);
    EXPECT_EQ(r.status, 0) << r.err;
    nlohmann::json j = nlohmann::json::parse(std::ifstream(out));
    std::vector<double> c;
    for (const auto& v : j["coefficients"])
      for (const auto& x : v) c.push_back(x.get<double>());
    return c;
  };
  // Frame 1 of the rig: a 90° turn, the sun at elevation 45 towards +X.
  std::vector<double> a = coeffs("--rig " + rig.string() + " --frame 1");
  std::vector<double> b = coeffs(esplanade() + " --env-rotate 90 --env-axis 1,2,-0.5 --sun-elevation 45 "
                                 "--sun-azimuth 90 --window hann");
  ASSERT_EQ(a.size(), b.size());
  double peak = 0;
  for (double x : a) peak = std::max(peak, std::fabs(x));
  // The same rig built two ways: equal up to the float output (and 9-digit JSON).
  for (size_t i = 0; i < a.size(); ++i) EXPECT_NEAR(a[i], b[i], 1e-6 * peak) << i;
}

TEST(CliRig, BadRigMapCameraOrBackEndIsOneLineAndWritesNothing) {
  fs::path d = tempDir("rig_errors");
  fs::path out = d / "out";
  fs::create_directories(out);
  fs::path bad = d / "bad.json", missingMap = d / "missing_map.json";
  std::ofstream(bad) << R"({"version": 1, "lights": [{"type": "environment", "file": "x.hdr", "rotaton": 3}]})";
  std::ofstream(missingMap) << R"({"version": 1, "lights": [{"type": "environment", "file": "missing.hdr"}]})";
  const std::string render = "render " + bakedCornell() + " --size 16x16 --frames 0-1 -o " + (out / "f_%d.exr").string();
  expectCleanFailure(prt(render + " --rig /nonexistent/rig.json"), "/nonexistent/rig.json", out);
  expectCleanFailure(prt(render + " --rig " + bad.string()), "bad.json: lights[0].rotaton: unknown key", out);
  expectCleanFailure(prt(render + " --rig " + missingMap.string()), "lights[0].file: " + (d / "missing.hdr").string(),
                     out);
  expectCleanFailure(prt(render + " --env /nonexistent/sky.hdr"), "/nonexistent/sky.hdr", out);
  expectCleanFailure(prt(render + " --env " + esplanade() + " --camera nope"), "no camera named 'nope'", out);
  expectCleanFailure(prt(render + " --env " + esplanade() + " --gl vulkan"), "vulkan", out, 2);
  expectCleanFailure(prt(render + " --env " + esplanade() + " --exr-compression lzma"),
                     "--exr-compression: 'lzma' is not zip, piz or none", out, 2);
  expectCleanFailure(prt(render + " --rig " + bad.string() + " --env " + esplanade()), "--rig excludes --env", out, 2);
  // A GL back end that cannot start: libglvnd finds no EGL vendor library.
  ::setenv("__EGL_VENDOR_LIBRARY_FILENAMES", "/nonexistent/vendor.json", 1);
  CliRun noEgl = prt(render + " --env " + esplanade() + " --gl egl");
  ::unsetenv("__EGL_VENDOR_LIBRARY_FILENAMES");
  expectCleanFailure(noEgl, "EGL: no display", out);
  expectCleanFailure(prt(render + " --env " + esplanade() + " --env-rotate 1:x"), "--env-rotate 1:x", out, 2);
  expectCleanFailure(prt(render + " --sun-elevation 100"), "--sun-elevation: elevation must be in [-90, 90]", out);
  expectCleanFailure(prt(render + " --env " + esplanade() + " --env-axis 0,0,0"), "--env-axis: direction is zero", out);
  // Stills: --frame without a rig, and START:END without a frame range.
  expectCleanFailure(prt("light --env " + esplanade() + " --frame 2 -o " + (out / "l.json").string()), "--frame", out, 2);
  expectCleanFailure(prt("light --env " + esplanade() + " --env-rotate 0:90 -o " + (out / "l.json").string()),
                     "START:END needs a frame range", out, 2);
}

TEST(CliRender, Mp4ThroughFfmpeg) {
  if (!onPath("ffmpeg") || !onPath("ffprobe")) GTEST_SKIP() << "ffmpeg/ffprobe not installed";
  fs::path d = tempDir("mp4");
  // An odd width: yuv420p needs even sizes, so ffmpeg pads to 34.
  CliRun r = prt("render " + bakedCornell() + " --rig " + scene("rigs/sun_day.json") +
                 " --frames 0-5 --size 33x24 --fps 12 --exposure 1 -o " + (d / "f_%d.exr").string() + " --mp4 " +
                 (d / "day.mp4").string());
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.err.find("video"), std::string::npos) << r.err;
  std::vector<std::string> expected = {"day.mp4"};
  for (int f = 0; f <= 5; ++f) expected.push_back(cat("f_", f, ".exr"));
  EXPECT_TRUE(dirHoldsOnly(d, expected));  // no temporary file left
  fs::path probe = d / "probe.json";
  ASSERT_EQ(std::system(("ffprobe -v error -select_streams v:0 -count_frames -show_entries "
                         "stream=codec_name,pix_fmt,width,height,nb_read_frames,r_frame_rate -of json " +
                         (d / "day.mp4").string() + " > " + probe.string())
                            .c_str()),
            0);
  nlohmann::json j = nlohmann::json::parse(std::ifstream(probe));
  const nlohmann::json& s = j["streams"][0];
  EXPECT_EQ(s["codec_name"], "h264");
  EXPECT_EQ(s["pix_fmt"], "yuv420p");
  EXPECT_EQ(s["width"], 34);
  EXPECT_EQ(s["height"], 24);
  EXPECT_EQ(s["nb_read_frames"], "6");
  EXPECT_EQ(s["r_frame_rate"], "12/1");
}

TEST(CliRender, Mp4WithoutFfmpegIsAClearErrorBeforeRendering) {
  fs::path d = tempDir("mp4_missing"), out = d / "out";
  fs::create_directories(out);
  // prt is started by its absolute path, with a PATH that holds no ffmpeg.
  const std::string cmd = "env PATH=/nonexistent " + std::string(PRT_EXE) + " render " + bakedCornell() + " --env " +
                          esplanade() + " --frames 0-2 --size 16x16 -o " + (out / "f_%d.exr").string() + " --mp4 " +
                          (out / "v.mp4").string() + " 2>" + (d / "err.txt").string();
  int rc = std::system(cmd.c_str());
  EXPECT_EQ(WIFEXITED(rc) ? WEXITSTATUS(rc) : -1, 1);
  std::ifstream e(d / "err.txt");
  std::stringstream err;
  err << e.rdbuf();
  EXPECT_EQ(lineCount(err.str()), 1) << err.str();
  EXPECT_NE(err.str().find("--mp4 " + (out / "v.mp4").string() + ": ffmpeg not found on PATH"), std::string::npos)
      << err.str();
  EXPECT_TRUE(dirHoldsOnly(out, {})) << "frames rendered before the error";
}

TEST(CliRender, ContactSheetTilesAreTheDownscaledFrames) {
  fs::path d = tempDir("sheet");
  const float exposure = 1.5f;
  CliRun r = prt("render " + bakedCornell() + " --rig " + scene("rigs/colored_disks.json") +
                 " --frames 0-4 --size 40x30 --exposure 1.5 --contact-sheet " + (d / "sheet.png").string() +
                 " --sheet-tile 16 --sheet-columns 2 -o " + (d / "f_%d.exr").string());
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

}  // namespace
}  // namespace prt

namespace prt {
namespace {

std::string fileBytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

// Same seed, any thread count: the baked .glb and the probe .vdb are the same bytes. The
// cornell box has occlusion and interreflection, so every stage of both bakes runs (rays,
// bounces, probe relocation), and an 8x8x8 probe grid (8 chunks of 64, so threads share the
// probe stage) has probes inside and outside the walls.
TEST(CliDeterminism, ThreadCountDoesNotChangeTheBytes) {
  fs::path d = tempDir("determinism");
  std::string reference;
  std::string referenceVdb;
  for (int threads : {1, 2, 8}) {
    std::string name = "threads_";
    name += std::to_string(threads);  // (not "t" + to_string: GCC 12 warns, -Wrestrict false positive)
    std::string glb = (d / (name + ".glb")).string(), vdb = (d / (name + ".vdb")).string();
    CliRun r = prt("bake " + scene("cornell_open.gltf") + " -o " + glb + " --probes " + vdb +
                   " --probe-dims 8,8,8 --probe-samples 64 --samples 32 --bounces 2 --seed 7 -q --threads " +
                   std::to_string(threads));
    ASSERT_EQ(r.status, 0) << r.err;
    std::string bytes = fileBytes(glb), vdbBytes = fileBytes(vdb);
    ASSERT_GT(bytes.size(), 1000u);
    ASSERT_GT(vdbBytes.size(), 1000u);
    if (threads == 1) {
      reference = bytes;
      referenceVdb = vdbBytes;
      continue;
    }
    EXPECT_TRUE(bytes == reference) << "--threads " << threads << ": the .glb differs from --threads 1";
    EXPECT_TRUE(vdbBytes == referenceVdb) << "--threads " << threads << ": the .vdb differs from --threads 1";
  }
}

// A hostile rig (tests/test_hostile_input.cpp has each limit): one line, exit 1, nothing written.
TEST(CliRig, HostileRigIsOneLineAndWritesNothing) {
  fs::path d = tempDir("rig_hostile");
  fs::path out = d / "out";
  fs::create_directories(out);
  fs::path deep = d / "deep.json", huge = d / "huge.json";
  std::ofstream(deep) << "{\"version\": 1, \"lights\": " << std::string(100, '[') << std::string(100, ']') << "}";
  std::ofstream(huge) << R"({"version": 1, "lights": [{"type": "uniform", "radiance": [{"frame": 0, "value": 1}, {"frame": 2e9, "value": 2}]}]})";
  expectCleanFailure(prt("render " + bakedCornell() + " --rig " + deep.string() + " --size 16x16 -o " + (out / "f_%d.exr").string()),
                     "deep.json: JSON nested deeper than 64 levels", out);
  expectCleanFailure(prt("light --rig " + huge.string() + " -o " + (out / "l.json").string()),
                     "huge.json: lights[0].radiance[1].frame: frame 2e+09 is beyond ±1e+09", out);
}

}  // namespace
}  // namespace prt
