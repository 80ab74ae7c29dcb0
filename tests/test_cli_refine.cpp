// `prt bake`'s adaptive refinement end to end: the refined .glb read back (closed, every
// attribute interpolated, the file's own accessors), what the other commands see, determinism
// across threads, the options. The refinement itself: test_refine.cpp.
#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <map>

#include <nlohmann/json.hpp>

#include "gltf_file.h"
#include "harness.h"
#include "prt/scene.h"
#include "test_scenes.h"

namespace prt {
namespace {

namespace fs = std::filesystem;
using Json = nlohmann::json;
using test::Glb;
using test::GltfFile;

// A 2 × 2 floor of two triangles with NORMAL, TEXCOORD_0 = ((x+1)/2, (z+1)/2), COLOR_0 =
// ((x+1)/2, (z+1)/2, 0.5, 1) and TANGENT (1, 0, 0, -1), under a lid of two triangles without
// NORMAL (flat normals, facing down) that shadows part of it.
// Without `floorNormals` the floor has no NORMAL either (flat normals, which the refined file
// then holds).
std::string scene(const test::TempDir& dir, bool floorNormals = true) {
  GltfFile f;
  MeshInstance floor = test::makePlane({0, 0, 0}, 2.0f, 1);
  const int floorMesh = f.mesh(floor);
  std::vector<float> uv, color, tangent;
  for (const glm::vec3& p : floor.positions) {
    uv.insert(uv.end(), {(p.x + 1) / 2, (p.z + 1) / 2});
    color.insert(color.end(), {(p.x + 1) / 2, (p.z + 1) / 2, 0.5f, 1.0f});
    tangent.insert(tangent.end(), {1, 0, 0, -1});
  }
  Json& attrs = f.j["meshes"][size_t(floorMesh)]["primitives"][0]["attributes"];
  const int uvAccessor = f.accessor(uv, "VEC2");
  f.j["accessors"][size_t(uvAccessor)]["count"] = floor.vertexCount();  // GltfFile counts VEC2 as 4 wide
  attrs["TEXCOORD_0"] = uvAccessor;
  attrs["COLOR_0"] = f.accessor(color, "VEC4");
  attrs["TANGENT"] = f.accessor(tangent, "VEC4");
  if (!floorNormals) attrs.erase("NORMAL");
  f.node({{"name", "Floor"}, {"mesh", floorMesh}}, true);
  MeshInstance lid = test::makePlane({0.25f, 0.3f, 0.0f}, 1.0f, 1);
  for (size_t t = 0; t < lid.indices.size(); t += 3) std::swap(lid.indices[t + 1], lid.indices[t + 2]);
  const int lidMesh = f.mesh(lid);
  f.j["meshes"][size_t(lidMesh)]["primitives"][0]["attributes"].erase("NORMAL");
  f.node({{"name", "Lid"}, {"mesh", lidMesh}}, true);
  return f.write(floorNormals ? "refine" : "refine_flat", dir.path());
}

TEST(CliRefine, RefinedGlbIsClosedWithEveryAttributeInterpolated) {
  const test::TempDir dir("cli_refine");
  const std::string in = scene(dir), out = (dir.path() / "out.glb").string();
  const test::RunResult r = test::runPrt({"bake", in, "-o", out, "--samples", "256"});
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.err.find("refinement: 8 -> "), std::string::npos) << r.err;

  const Glb glb(out);
  const Json& prim = glb.primitive("Floor");
  const Json& attrs = prim["attributes"];
  const std::vector<float> pos = glb.values<float>(attrs["POSITION"], 3);
  const size_t n = pos.size() / 3;
  ASSERT_GT(n, 4u) << "the floor was not refined";
  for (const char* a : {"NORMAL", "TEXCOORD_0", "COLOR_0", "TANGENT", "_PRT_SH_00"})
    EXPECT_EQ(glb.j["accessors"][attrs[a].get<size_t>()]["count"].get<size_t>(), n) << a;
  const std::vector<float> normal = glb.values<float>(attrs["NORMAL"], 3),
                           uv = glb.values<float>(attrs["TEXCOORD_0"], 2),
                           color = glb.values<float>(attrs["COLOR_0"], 4),
                           tangent = glb.values<float>(attrs["TANGENT"], 4);
  for (size_t v = 0; v < n; ++v) {
    const float x = pos[3 * v], y = pos[3 * v + 1], z = pos[3 * v + 2];
    SCOPED_TRACE(cat("vertex ", v, " at (", x, ", ", z, ")"));
    EXPECT_EQ(y, 0.0f);
    EXPECT_NEAR(uv[2 * v], (x + 1) / 2, 1e-6);
    EXPECT_NEAR(uv[2 * v + 1], (z + 1) / 2, 1e-6);
    EXPECT_NEAR(color[4 * v], (x + 1) / 2, 1e-6);
    EXPECT_NEAR(color[4 * v + 1], (z + 1) / 2, 1e-6);
    EXPECT_NEAR(color[4 * v + 2], 0.5, 1e-6);
    EXPECT_NEAR(normal[3 * v + 1], 1.0, 1e-6);
    EXPECT_NEAR(tangent[4 * v], 1.0, 1e-6);
    EXPECT_EQ(tangent[4 * v + 3], -1.0f);
  }
  // Closed: every edge of the floor is shared by two triangles, or lies on its border.
  const std::vector<uint32_t> idx = glb.values<uint32_t>(prim["indices"], 1);
  std::map<std::pair<uint32_t, uint32_t>, int> edges;
  for (size_t t = 0; t + 2 < idx.size(); t += 3)
    for (int k = 0; k < 3; ++k) {
      const uint32_t a = idx[t + size_t(k)], b = idx[t + size_t(k + 1) % 3];
      edges[{std::min(a, b), std::max(a, b)}]++;
    }
  for (const auto& [e, count] : edges) {
    const float ax = pos[3 * e.first], az = pos[3 * e.first + 2], bx = pos[3 * e.second], bz = pos[3 * e.second + 2];
    const bool border = (std::abs(ax) == 1 && ax == bx) || (std::abs(az) == 1 && az == bz);
    EXPECT_EQ(count, border ? 1 : 2) << "edge (" << ax << ", " << az << ") - (" << bx << ", " << bz << ")";
  }
  // A floor without NORMAL: the refined file holds the flat normals of its refined triangles.
  const std::string flat = (dir.path() / "flat.glb").string();
  ASSERT_EQ(test::runPrt({"bake", scene(dir, false), "-o", flat, "--samples", "256", "-q"}).status, 0);
  const Glb flatGlb(flat);
  const Json& flatAttrs = flatGlb.primitive("Floor")["attributes"];
  ASSERT_TRUE(flatAttrs.contains("NORMAL"));
  const std::vector<float> flatNormals = flatGlb.values<float>(flatAttrs["NORMAL"], 3);
  EXPECT_GT(flatNormals.size(), 12u);
  for (size_t v = 0; v < flatNormals.size() / 3; ++v) EXPECT_EQ(flatNormals[3 * v + 1], 1.0f) << v;
  EXPECT_EQ(loadScene(flat).meshes[0].vertexCount(), flatNormals.size() / 3);

  // What the other commands read: the same vertices, their transfer, the record.
  const Scene back = loadScene(out);
  ASSERT_EQ(back.meshes[0].vertexCount(), n);
  EXPECT_EQ(back.meshes[0].transfer.size(), n * 9);
  ASSERT_TRUE(back.bakeRecord);
  EXPECT_EQ(back.bakeRecord->refinement.verticesBefore, 8u);
  EXPECT_EQ(back.bakeRecord->refinement.verticesAfter, back.meshes[0].vertexCount() + back.meshes[1].vertexCount());
  const test::RunResult info = test::runPrt({"info", out});
  EXPECT_EQ(info.status, 0) << info.err;
  EXPECT_NE(
      info.out.find(cat("; refined 8 -> ", back.bakeRecord->refinement.verticesAfter, " vertices (tolerance 0.01")),
      std::string::npos)
      << info.out;
  const test::RunResult probe =
      test::runPrt({"bake", out, "-o", (dir.path() / "again.glb").string(), "--samples", "64", "-q", "--probes",
                    (dir.path() / "p.vdb").string(), "--probe-dims", "2,2,2"});
  EXPECT_EQ(probe.status, 0) << probe.err;  // a refined bake bakes again
}

TEST(CliRefine, AnyThreadCountGivesTheSameBytes) {
  const test::TempDir dir("cli_refine_threads");
  const std::string in = scene(dir);
  std::string bytes[2];
  for (int t = 1; t <= 2; ++t) {
    const std::string out = (dir.path() / cat("t", t, ".glb")).string();
    ASSERT_EQ(test::runPrt({"bake", in, "-o", out, "--samples", "128", "--threads", std::to_string(t), "-q"}).status,
              0);
    bytes[t - 1] = test::fileBytes(out);
  }
  EXPECT_EQ(bytes[0], bytes[1]);
}

TEST(CliRefine, OffAndOptionChecks) {
  const test::TempDir dir("cli_refine_off");
  const std::string in = scene(dir);
  for (const std::vector<std::string>& off : {std::vector<std::string>{"--no-refine"}, {"--refine-tolerance", "0"}}) {
    const std::string out = (dir.path() / "off.glb").string();
    std::vector<std::string> args = {"bake", in, "-o", out, "--samples", "64", "-q"};
    args.insert(args.end(), off.begin(), off.end());
    ASSERT_EQ(test::runPrt(args).status, 0);
    const Scene s = loadScene(out);
    EXPECT_EQ(s.meshes[0].vertexCount(), 4u);
    EXPECT_EQ(s.bakeRecord->refinement.tolerance, 0.0);
  }
  const std::string out = (dir.path() / "x.glb").string();
  for (const std::vector<std::string>& bad : {std::vector<std::string>{"--refine-tolerance", "-1"},
                                              {"--refine-tolerance", "nan"},
                                              {"--no-refine", "--refine-budget", "5"},
                                              {"--unshadowed", "--refine-tolerance", "0.1"},
                                              {"--refine-samples", "0"}}) {
    std::vector<std::string> args = {"bake", in, "-o", out};
    args.insert(args.end(), bad.begin(), bad.end());
    const test::RunResult r = test::runPrt(args);
    EXPECT_EQ(r.status, 2) << bad[0] << ": " << r.err;
  }
}

}  // namespace
}  // namespace prt
