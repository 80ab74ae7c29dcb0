// One bake spread over processes end to end (docs/scale.md): `mpirun -n N prt bake` and
// `prt bake --shard I/N` + `prt merge` write the bytes of one process, resume together after
// one rank stops, and a rank's error stops the job with one line.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <string>
#include <vector>

#include "harness.h"

namespace prt {
namespace {

namespace fs = std::filesystem;
using Args = std::vector<std::string>;
using test::RunResult;

// A small bake with every stage: the direct pass, two bounces (cornell_open: 12.5 k vertices,
// 196 chunks per pass) and probes (8×8×8, 8 chunks of 64 points, over bounds wider than the
// room: of the 512 points 10 lie in geometry, 12 are moved out and 54 are left out in open
// air, so the ranks' shares of the placement test decide all three). Refinement stays on (its
// default): MPI ranks share its points, shards each refine the whole scene, and all must agree.
// `samples`: the bake's and refinement's directions (refinement's are at most the bake's).
Args bakeArgs(const fs::path& dir, const std::string& name, const std::string& samples = "") {
  return {"bake",
          test::sourcePath("scenes/cornell_open.gltf"),
          "-o",
          (dir / (name + ".glb")).string(),
          "--probes",
          (dir / (name + ".vdb")).string(),
          "--samples",
          samples.empty() ? "32" : samples,
          "--bands",
          "2",
          "--bounces",
          "2",
          "--probe-dims",
          "8,8,8",
          "--probe-bounds",
          "-4,-1,-4,4,4,4",
          "--probe-samples",
          "64",
          "--refine-samples",
          samples.empty() ? "16" : samples,
          "-q"};
}

bool haveMpi() {
#if PRT_TEST_MPI
  return test::onPath("mpirun");
#else
  return false;
#endif
}

// `mpirun -n N` on this machine, however many cores it has and whoever runs it. Leak detection
// is off for the ranks in a sanitizer build: Open MPI keeps its state until exit.
RunResult mpirun(int n, const Args& prtArgs, const test::RunOptions& options = {}) {
  Args a = {"--oversubscribe", "--allow-run-as-root", "-n", std::to_string(n), test::prtExe()};
  a.insert(a.end(), prtArgs.begin(), prtArgs.end());
  test::RunOptions o = options;
  o.env.push_back({"ASAN_OPTIONS", "detect_leaks=0"});
  return test::run("mpirun", a, o);
}

// The lines prt wrote (Open MPI adds its own banner when a rank aborts).
int prtLines(const std::string& err) {
  int n = 0;
  for (size_t at = 0; (at = err.find("prt: ", at)) != std::string::npos; ++at) n += at == 0 || err[at - 1] == '\n';
  return n;
}

std::vector<std::string> names(const fs::path& dir) {
  std::vector<std::string> n;
  for (const auto& e : fs::directory_iterator(dir)) n.push_back(e.path().filename().string());
  std::sort(n.begin(), n.end());
  return n;
}

class CliMpi : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!haveMpi()) GTEST_SKIP() << "no mpirun, or prt built without MPI";
  }
};

TEST_F(CliMpi, RanksWriteTheBytesOfOneProcess) {
  const test::TempDir tmp;
  const fs::path dir = tmp.path();
  // Refinement that splits edges (one round on cornell_open, 12 510 -> 12 520 vertices): the
  // ranks share its points and scores. The bounce operator: each rank makes the rows of its
  // clusters, and rank 0 stores them all.
  const Args refine = {"--refine-tolerance", "0.002", "--threads", "1", "--operator"};
  RunResult ref = test::runPrt(test::plus(bakeArgs(dir, "ref", "64"), refine));
  ASSERT_EQ(ref.status, 0) << ref.err;
  const std::string glb = test::fileBytes(dir / "ref.glb"), vdb = test::fileBytes(dir / "ref.vdb");
  for (int n : {1, 2, 3}) {
    SCOPED_TRACE(n);
    const fs::path out = dir / ("n" + std::to_string(n));
    fs::create_directories(out);
    RunResult r = mpirun(n, test::plus(bakeArgs(out, "b", "64"), refine));
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_TRUE(test::fileBytes(out / "b.glb") == glb) << "the .glb of " << n << " ranks differs from one process";
    EXPECT_TRUE(test::fileBytes(out / "b.vdb") == vdb) << "the .vdb of " << n << " ranks differs from one process";
    EXPECT_EQ(names(out), (std::vector<std::string>{"b.glb", "b.vdb"})) << "checkpoints left behind";
  }
}

// Two ranks with `common`, rank 1 interrupted after its first chunk of bounce 1 (checkpoint
// stage 2; a rank gathers the chunks whose direct pass it computed, taken as they came: about
// half of the 196, far fewer when its core is busy with something else, none when rank 0 took
// them all, and then it stops at bounce 1's end) with `rank1Extra` added to its arguments: it
// saves and stops the job, and rank 0 dies with what it had not saved.
RunResult stopRank1InBounce1(const Args& common, const Args& rank1Extra) {
  Args a = {"--oversubscribe", "--allow-run-as-root", "-n", "1", test::prtExe()};
  a.insert(a.end(), common.begin(), common.end());
  a.insert(a.end(), {":", "-n", "1", "env", "PRT_TEST_INTERRUPT_AFTER=2:1", test::prtExe()});
  a.insert(a.end(), common.begin(), common.end());
  a.insert(a.end(), rank1Extra.begin(), rank1Extra.end());
  return test::run("mpirun", a, {.env = {{"ASAN_OPTIONS", "detect_leaks=0"}}});
}

// `mpirun -n 2 ... --resume` of `common` (its outputs b.glb, b.vdb in out) writes the bytes of
// the reference bake (ref.glb, ref.vdb in dir) and leaves no checkpoint behind.
void expectResumedToTheReference(const Args& common, const fs::path& out, const fs::path& dir) {
  const RunResult resumed = mpirun(2, test::plus(common, {"--resume"}));
  ASSERT_EQ(resumed.status, 0) << resumed.err;
  EXPECT_TRUE(test::fileBytes(out / "b.glb") == test::fileBytes(dir / "ref.glb"));
  EXPECT_TRUE(test::fileBytes(out / "b.vdb") == test::fileBytes(dir / "ref.vdb"));
  EXPECT_EQ(names(out), (std::vector<std::string>{"b.glb", "b.vdb"}));
}

void expectStoppedInBounce1(const RunResult& stopped, const fs::path& out) {
  EXPECT_NE(stopped.status, 0);
  EXPECT_EQ(prtLines(stopped.err), 1) << stopped.err;
  EXPECT_NE(stopped.err.find("interrupted: checkpoints saved to " + (out / "b.glb.prt-checkpoint").string() +
                             ".rank-*-of-2 (rank 1: bounce 1 "),
            std::string::npos)
      << stopped.err;
  EXPECT_FALSE(fs::exists(out / "b.glb"));
}

// A reference bake by one process in dir, and the same bake's arguments for ranks writing to
// dir/out (b.glb, b.vdb), for the resume tests.
class CliMpiResume : public CliMpi {
 protected:
  void SetUp() override {
    CliMpi::SetUp();
    if (IsSkipped()) return;
    ASSERT_EQ(test::runPrt(bakeArgs(dir, "ref")).status, 0);
    fs::create_directories(out);
  }
  const test::TempDir tmp;
  const fs::path dir = tmp.path();
  const fs::path out = dir / "out";
  const Args common = bakeArgs(out, "b");
};

TEST_F(CliMpiResume, RankStoppedMidBakeResumesWithTheOthers) {
  // Rank 1 is interrupted in bounce 1. No rank had saved before (the checkpoint interval is
  // long), so the ranks skipped their stage-end saves: rank 0 has no file, and the ranks
  // resume together from the direct pass (rank 1 restores its direct chunks) to the bytes of
  // one process.
  const RunResult stopped = stopRank1InBounce1(common, {});
  expectStoppedInBounce1(stopped, out);
  EXPECT_EQ(names(out), (std::vector<std::string>{"b.glb.prt-checkpoint.rank-1-of-2"}))
      << "a stage-end save while no rank had saved";
  RunResult fresh = mpirun(2, common);  // a checkpoint is there: not without --resume
  EXPECT_EQ(fresh.status, 1) << fresh.err;
  EXPECT_EQ(prtLines(fresh.err), 1) << fresh.err;
  expectResumedToTheReference(common, out, dir);
  // Both ranks stopped in bounce 1: they resume there, and first trade the direct pass's
  // chunks (each rank's file holds its own, and every rank keeps the whole direct part).
  fs::remove(out / "b.glb");
  fs::remove(out / "b.vdb");
  RunResult both = mpirun(2, common, {.env = {{"PRT_TEST_INTERRUPT_AFTER", "2:1"}}});
  EXPECT_NE(both.status, 0);
  EXPECT_EQ(prtLines(both.err), 1) << both.err;
  EXPECT_NE(both.err.find(": bounce 1 "), std::string::npos) << both.err;
  expectResumedToTheReference(common, out, dir);
}

TEST_F(CliMpiResume, OnceOneRankSavedEveryRankSavesAtTheStageEnd) {
  // Rank 1 alone saves every few milliseconds: it has a file before the direct pass ends, so at
  // its end every rank saves its chunks, rank 0 too (whose own interval is long). Rank 1 is
  // interrupted in bounce 1; rank 0 dies with its bounce-1 chunks unsaved and resumes with the
  // direct chunks of its file.
  const RunResult stopped = stopRank1InBounce1(common, {"--checkpoint-interval", "0.001"});
  expectStoppedInBounce1(stopped, out);
  EXPECT_EQ(names(out),
            (std::vector<std::string>{"b.glb.prt-checkpoint.rank-0-of-2", "b.glb.prt-checkpoint.rank-1-of-2"}));
  expectResumedToTheReference(common, out, dir);
}

TEST_F(CliMpi, AFailingRankStopsEveryRankWithOneLine) {
  const test::TempDir tmp;
  const fs::path dir = tmp.path();
  const Args good = bakeArgs(dir, "b");
  Args bad = good;
  bad[1] = (dir / "missing.gltf").string();
  // Only rank 1 cannot read its scene; rank 0 would bake and wait for it.
  Args a = {"--oversubscribe", "--allow-run-as-root", "-n", "1", test::prtExe()};
  a.insert(a.end(), good.begin(), good.end());
  a.insert(a.end(), {":", "-n", "1", test::prtExe()});
  a.insert(a.end(), bad.begin(), bad.end());
  RunResult r = test::run("mpirun", a, {.env = {{"ASAN_OPTIONS", "detect_leaks=0"}}});
  EXPECT_NE(r.status, 0);
  EXPECT_EQ(prtLines(r.err), 1) << r.err;
  EXPECT_NE(r.err.find("missing.gltf"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir / "b.glb"));
  // The same error on every rank is still one line; so is a bad option.
  RunResult all = mpirun(3, bad);
  EXPECT_NE(all.status, 0);
  EXPECT_EQ(prtLines(all.err), 1) << all.err;
  RunResult usage = mpirun(2, test::plus(good, {"--bands", "99"}));
  EXPECT_EQ(prtLines(usage.err), 1) << usage.err;
  EXPECT_NE(usage.status, 0);
}

// Every rank on this one host and no layer chosen: prt asks Open MPI for ob1 over shared
// memory (its default would try the fabric layers first, about 0.2 s of MPI_Init per rank) and
// says so; a layer the user chose (OMPI_MCA_pml, which mpirun --mca pml sets) is left alone.
TEST_F(CliMpi, OneHostGetsSharedMemoryUnlessALayerWasChosen) {
  const test::TempDir tmp;
  Args quiet = {"bake", test::sourcePath("scenes/plane.gltf"), "-o", (tmp.path() / "p.glb").string(), "--samples",
                "16"};
  const std::string said = "(MPI: Open MPI's ob1 over shared memory, chosen for one host)";
  RunResult chosen = mpirun(2, quiet, {.env = {{"OMPI_MCA_pml", std::nullopt}}});
  ASSERT_EQ(chosen.status, 0) << chosen.err;
  EXPECT_NE(chosen.err.find(said), std::string::npos) << chosen.err;
  RunResult left = mpirun(2, quiet, {.env = {{"OMPI_MCA_pml", "ob1"}}});
  ASSERT_EQ(left.status, 0) << left.err;
  EXPECT_EQ(left.err.find(said), std::string::npos) << left.err;
  EXPECT_NE(left.err.find("ranks: 2 (MPI);"), std::string::npos) << left.err;
}

TEST(CliShards, ShardsAndMergeWriteTheBytesOfOneProcess) {
  const test::TempDir tmp;
  const fs::path dir = tmp.path();
  ASSERT_EQ(test::runPrt(bakeArgs(dir, "ref")).status, 0);
  const fs::path out = dir / "out";
  fs::create_directories(out);
  const Args common = bakeArgs(out, "b");
  const std::string ckpt = (out / "b.glb.prt-checkpoint").string();
  constexpr int kShards = 3;
  // The direct pass, two bounces, the probes: four stages, each baked by three shards (the
  // order of shards does not matter) and merged before the next.
  for (int stage = 0; stage < 4; ++stage) {
    SCOPED_TRACE(stage);
    for (int i : {2, 0, 1}) {
      RunResult r = test::runPrt(test::plus(common, {"--shard", std::to_string(i) + "/3", "--threads", "1"}));
      ASSERT_EQ(r.status, 0) << r.err;
    }
    if (stage == 0) {  // a shard run twice does its share once
      RunResult again = test::runPrt(test::plus(common, {"--shard", "1/3"}));
      EXPECT_EQ(again.status, 0) << again.err;
    }
    RunResult m = test::runPrt({"merge", ckpt, "--shards", std::to_string(kShards)});
    ASSERT_EQ(m.status, 0) << m.err;
    EXPECT_EQ(names(out), std::vector<std::string>{"b.glb.prt-checkpoint"});
  }
  RunResult more = test::runPrt(test::plus(common, {"--shard", "0/3"}));  // nothing left for shards
  EXPECT_EQ(more.status, 1);
  EXPECT_NE(more.err.find("--resume instead of --shard"), std::string::npos) << more.err;
  RunResult last = test::runPrt(test::plus(common, {"--resume"}));
  ASSERT_EQ(last.status, 0) << last.err;
  EXPECT_TRUE(test::fileBytes(out / "b.glb") == test::fileBytes(dir / "ref.glb"));
  EXPECT_TRUE(test::fileBytes(out / "b.vdb") == test::fileBytes(dir / "ref.vdb"));
  EXPECT_EQ(names(out), (std::vector<std::string>{"b.glb", "b.vdb"}));
}

TEST(CliShards, MergeNamesAMissingShard) {
  const test::TempDir tmp;
  const fs::path dir = tmp.path();
  const Args common = bakeArgs(dir, "b");
  ASSERT_EQ(test::runPrt(test::plus(common, {"--shard", "0/2"})).status, 0);
  const std::string ckpt = (dir / "b.glb.prt-checkpoint").string();
  RunResult m = test::runPrt({"merge", ckpt, "--shards", "2"});
  EXPECT_EQ(m.status, 1);
  EXPECT_EQ(test::lineCount(m.err), 1) << m.err;
  EXPECT_NE(m.err.find(ckpt + ".shard-1-of-2.done: no such shard"), std::string::npos) << m.err;
  EXPECT_NE(m.err.find("run prt bake --shard 1/2 first"), std::string::npos) << m.err;  // the tool's hint
  EXPECT_TRUE(fs::exists(ckpt + ".shard-0-of-2.done"));                                 // nothing merged, nothing lost
  RunResult bad = test::runPrt(test::plus(common, {"--shard", "2/2"}));
  EXPECT_EQ(bad.status, 2) << bad.err;
}

}  // namespace
}  // namespace prt
