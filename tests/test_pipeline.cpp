// The bake pipeline (prt/bake/pipeline.h) in process: a bake with probes, interrupted and
// resumed through runPipeline, writes the bits of the uninterrupted bake (through `prt bake`:
// test_cli_resume.cpp; the stages alone: test_resume.cpp).
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "gltf_file.h"
#include "harness.h"
#include "prt/bake/interrupt.h"
#include "prt/bake/pipeline.h"
#include "test_scenes.h"

namespace prt {
namespace {

namespace fs = std::filesystem;
using namespace prt::bake;

// A cavity (2561 vertices) above a plane, as a glTF file: occlusion, bounces, two instances,
// and probes in free space, inside the cavity's wall and moved out of it.
std::string writeScene(const fs::path& dir) {
  test::GltfFile f;
  for (const MeshInstance& m : {test::makeCavity(0.6, 40, 64), test::makePlane({0, -1.2f, 0}, 4.0f, 12)})
    f.node({{"mesh", f.mesh(m)}}, true);
  return f.write("pipeline", dir);
}

// A small bake of it with refinement (a resumed bake refines again before it restores) and a
// 9 × 7 × 8 probe grid, its outputs named `name` in `dir`.
BakeJob smallJob(const std::string& scene, const fs::path& dir, const std::string& name) {
  BakeJob job;
  job.scenePath = scene;
  job.settings.samples = 64;
  job.settings.bounces = 2;
  job.refine.samples = 32;
  ProbeSettings ps;
  ps.dims = glm::ivec3(9, 7, 8);
  ps.samples = 64;
  job.probes = ps;
  OperatorSettings os;
  os.samples = 32;
  job.bounceOperator = os;  // built after the transfer: the resumed bake writes the same one
  job.outputs = {(dir / (name + ".glb")).string(), (dir / (name + ".vdb")).string(), false};
  job.checkpoint.intervalSeconds = 0.0;  // saves only when interrupted
  return job;
}

TEST(BakePipeline, ProbeBakeInterruptedThenResumedWritesTheSameBits) {
  const test::TempDir tmp("pipeline");
  const std::string scene = writeScene(tmp.path());
  const BakeJob ref = smallJob(scene, tmp.path(), "ref");
  const BakeReport done = runPipeline(ref);
  ASSERT_EQ(done.outcome, BakeReport::Outcome::Written);
  ASSERT_GT(done.probes.valid, 0u);
  ASSERT_GT(done.refined.points, 0u);  // refinement ran
  const std::string glb = test::fileBytes(ref.outputs.scene), vdb = test::fileBytes(ref.outputs.probes);
  EXPECT_FALSE(fs::exists(ref.outputs.scene + ".prt-checkpoint"));
  // In the direct pass and in the probe stage, after the stage's first chunk
  // (one thread: exactly one).
  for (uint32_t stage : {kSurfaceStageDirect, kProbeStageFirst}) {
    SCOPED_TRACE(::testing::Message() << "interrupted in stage " << stage);
    BakeJob job = smallJob(scene, tmp.path(), "b");
    job.settings.threads = 1;
    job.checkpoint.interruptInStage = stage;
    job.checkpoint.interruptAfterChunks = 1;
    try {
      runPipeline(job);
      ADD_FAILURE() << "not interrupted";
    } catch (const InterruptedAndSaved& e) {
      EXPECT_NE(
          std::string(e.what()).find("interrupted: checkpoint saved to " + job.outputs.scene + ".prt-checkpoint ("),
          std::string::npos)
          << e.what();
    }
    clearInterrupt();
    EXPECT_FALSE(fs::exists(job.outputs.scene));
    EXPECT_FALSE(fs::exists(job.outputs.probes));
    // A fresh bake does not start over the checkpoint; the resumed one (all threads) finishes it.
    try {
      runPipeline(smallJob(scene, tmp.path(), "b"));
      ADD_FAILURE() << "a fresh bake started over the checkpoint";
    } catch (const BakeRefused& e) {
      EXPECT_EQ(e.reason(), BakeRefused::Reason::CheckpointFound);
      EXPECT_EQ(e.path(), job.outputs.scene + ".prt-checkpoint");
    }
    BakeJob resumed = smallJob(scene, tmp.path(), "b");
    resumed.checkpoint.resume = true;
    const BakeReport r = runPipeline(resumed);
    EXPECT_TRUE(r.surface.resumed);
    if (stage == kProbeStageFirst) {
      EXPECT_GT(r.probes.restored, 0u);
    }
    EXPECT_TRUE(test::fileBytes(resumed.outputs.scene) == glb) << "the .glb differs";
    EXPECT_TRUE(test::fileBytes(resumed.outputs.probes) == vdb) << "the .vdb differs";
    EXPECT_FALSE(fs::exists(resumed.outputs.scene + ".prt-checkpoint"));
    fs::remove(resumed.outputs.scene);
    fs::remove(resumed.outputs.probes);
  }
}

// The bounce operator a bake writes is read back with its scene, and a file whose operator was
// changed (its checksum, or its count of vertex sides) is refused with one line naming the file
// and the part, where the rest of the file is intact.
TEST(BakePipeline, StoredOperatorIsReadBackAndCheckedAgainstItsFile) {
  const test::TempDir tmp("pipeline-operator");
  const std::string scene = writeScene(tmp.path());
  BakeJob job = smallJob(scene, tmp.path(), "op");
  job.probes.reset();
  const BakeReport r = runPipeline(job);
  ASSERT_TRUE(r.bounceOperator.built);
  const Scene back = loadScene(job.outputs.scene);
  ASSERT_NE(back.bounceOperator, nullptr);
  EXPECT_EQ(back.bounceOperator->vertexRows.node, r.scene.bounceOperator->vertexRows.node);
  EXPECT_EQ(back.bounceOperator->clusterRows.weight, r.scene.bounceOperator->clusterRows.weight);
  EXPECT_EQ(back.bounceOperator->bounces, 2);
  const std::string bytes = test::fileBytes(job.outputs.scene);
  auto refusal = [&](const std::string& from, const std::string& to) -> std::string {
    std::string edited = bytes;
    const size_t at = edited.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    if (at == std::string::npos) return "";
    EXPECT_EQ(from.size(), to.size());
    edited.replace(at, from.size(), to);
    const std::string path = (tmp.path() / "edited.glb").string();
    std::ofstream(path, std::ios::binary) << edited;
    try {
      loadScene(path);
    } catch (const Error& e) {
      return e.what();
    }
    return "accepted";
  };
  const size_t sum = bytes.find("\\\"checksum\\\":\\\"") + 15;
  std::string checksum = bytes.substr(sum, 16), other = checksum;
  other[0] = other[0] == '0' ? '1' : '0';
  const std::string corrupt = refusal(checksum, other);
  EXPECT_NE(corrupt.find("edited.glb: asset.extras.prt_operator: bytes: their checksum"), std::string::npos) << corrupt;
  const std::string sides = cat("\\\"vertex_sides\\\":", r.scene.bounceOperator->vertexSides);
  std::string fewer = sides;
  fewer.back() = fewer.back() == '0' ? '1' : char(fewer.back() - 1);
  const std::string mismatch = refusal(sides, fewer);
  EXPECT_NE(mismatch.find("edited.glb: asset.extras.prt_operator: "), std::string::npos) << mismatch;
}

}  // namespace
}  // namespace prt
