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

void expectCleanFailure(const CliRun& r, const std::string& mention, const fs::path& dir) {
  EXPECT_EQ(r.status, 1) << r.err;
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
  EXPECT_EQ(r2.status, 1);
  EXPECT_NE(r2.err.find("no lighting"), std::string::npos) << r2.err;
  CliRun r3 = prt("relight " + baked.string() + " --env " + scene("env/white_sky_64.hdr") + " --window bogus -o " +
               (d / "lit.glb").string());
  expectCleanFailure(r3, "bogus", d);
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
  EXPECT_EQ(line, "x,y,z,nx,ny,nz,E_r,E_g,E_b");
  int rows = 0;
  while (std::getline(out, line)) {
    double e = std::stod(line.substr(line.rfind(',') + 1));
    // The probes' direct part integrates y_j y_i with 1024 Sobol directions (~1e-3); the
    // 3-band irradiance of a constant sky is exact. 1% bounds it.
    EXPECT_NEAR(e, M_PI, 0.01 * M_PI) << line;
    ++rows;
  }
  EXPECT_EQ(rows, 2);
  CliRun bad = prt("probe " + vdb + " --env " + scene("env/white_sky_64.hdr") + " --at 0,100,0");
  EXPECT_EQ(bad.status, 1);
  EXPECT_NE(bad.err.find("outside"), std::string::npos) << bad.err;
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
  EXPECT_EQ(bad.status, 1);
  EXPECT_EQ(lineCount(bad.err), 1) << bad.err;
  EXPECT_FALSE(fs::exists(d / "x_00.exr"));
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
// bounces, probe relocation), and a 4x4x4 probe grid has probes inside and outside the walls.
TEST(CliDeterminism, ThreadCountDoesNotChangeTheBytes) {
  fs::path d = tempDir("determinism");
  std::string reference;
  std::string referenceVdb;
  for (int threads : {1, 2, 8}) {
    std::string name = "threads_";
    name += std::to_string(threads);  // (not "t" + to_string: GCC 12 warns, -Wrestrict false positive)
    std::string glb = (d / (name + ".glb")).string(), vdb = (d / (name + ".vdb")).string();
    CliRun r = prt("bake " + scene("cornell_open.gltf") + " -o " + glb + " --probes " + vdb +
                   " --probe-dims 4,4,4 --probe-samples 64 --samples 32 --bounces 2 --seed 7 -q --threads " +
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

}  // namespace
}  // namespace prt
