// Interruption, checkpoints, resume and the memory guard end to end through `prt bake`, with the
// test interrupt hook, real signals and kill -9 (the library side: test_resume.cpp).
#include <gtest/gtest.h>

#include <signal.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <regex>
#include <string>
#include <thread>
#include <vector>

#include "gltf_file.h"
#include "harness.h"
#include "test_scenes.h"

namespace prt {
namespace {

namespace fs = std::filesystem;

// ---- End to end through `prt bake`
using Args = std::vector<std::string>;
using test::Process;
using test::RunResult;

std::string scenePath(const std::string& name) { return test::sourcePath("scenes/" + name); }

std::string slurp(const fs::path& p) { return test::fileBytes(p); }

// `prt ARGS...`, to its end.
RunResult prtBake(const Args& args, const test::RunOptions& options = {}) { return test::runPrt(args, options); }

// The test interrupt hook of `prt bake`: it stops as if interrupted after `chunks` chunks.
test::RunOptions interruptAfter(int chunks) { return {.env = {{"PRT_TEST_INTERRUPT_AFTER", std::to_string(chunks)}}}; }

int lines(const std::string& s) { return int(std::count(s.begin(), s.end(), '\n')); }

std::vector<std::string> dirNames(const fs::path& dir) {
  std::vector<std::string> n;
  for (const auto& e : fs::directory_iterator(dir)) n.push_back(e.path().filename().string());
  std::sort(n.begin(), n.end());
  return n;
}

// Starts `prt ARGS...` (a resumed bake), waits until it has saved to its checkpoint `ckpt`
// once more, and kills it with -9.
RunResult killAfterNextSave(const Args& args, const std::string& ckpt) {
  const uintmax_t before = fs::file_size(ckpt);
  Process child(test::prtExe(), args);
  // 20 s: a sanitizer build on a busy machine can take several seconds to its next save.
  for (int i = 0; i < 2000 && fs::file_size(ckpt) <= before; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  EXPECT_GT(fs::file_size(ckpt), before) << "the resumed bake saved nothing in 20 s";
  child.signal(SIGKILL);
  return child.wait();
}

TEST(CliResume, InterruptedBakeResumesByteIdenticalWithOtherThreads) {
  const test::TempDir tmp("cli_points");
  const fs::path dir = tmp.path();
  const std::string scene = scenePath("cornell_open.gltf");
  const std::string ref = (dir / "ref.glb").string(), out = (dir / "out" / "b.glb").string();
  fs::create_directories(dir / "out");
  std::vector<std::string> common = {"bake", scene, "--samples", "64", "--bands", "2", "-q"};
  auto with = [&](std::vector<std::string> extra) {
    std::vector<std::string> a = common;
    a.insert(a.end(), extra.begin(), extra.end());
    return a;
  };
  ASSERT_EQ(prtBake(with({"-o", ref})).status, 0);
  const std::string refBytes = slurp(ref);
  // cornell_open has 12.5 k baked vertices: 196 chunks per pass. Interrupt in the direct pass,
  // in bounce 1 and in bounce 2.
  for (int after : {20, 250, 500}) {
    SCOPED_TRACE(after);
    RunResult r = prtBake(with({"-o", out}), interruptAfter(after));
    EXPECT_EQ(r.status, 130) << r.err;
    EXPECT_EQ(lines(r.err), 1) << r.err;
    EXPECT_NE(r.err.find("interrupted: checkpoint saved to " + out + ".prt-checkpoint ("), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("rerun with --resume"), std::string::npos);
    EXPECT_EQ(dirNames(dir / "out"), std::vector<std::string>{"b.glb.prt-checkpoint"});  // no output yet
    RunResult again = prtBake(with({"-o", out}));  // forgetting --resume does not lose it
    EXPECT_EQ(again.status, 1);
    EXPECT_NE(again.err.find("add --resume"), std::string::npos) << again.err;
    RunResult resumed = prtBake(with({"-o", out, "--resume", "--threads", "1"}));
    ASSERT_EQ(resumed.status, 0) << resumed.err;
    EXPECT_TRUE(slurp(out) == refBytes) << "resumed output differs from the uninterrupted bake";
    EXPECT_EQ(dirNames(dir / "out"), std::vector<std::string>{"b.glb"});  // checkpoint removed
    fs::remove(out);
  }
}

TEST(CliResume, SignalThenKillNineThenResume) {
  // A real SIGTERM stops the bake within two seconds with a checkpoint; a resumed bake killed
  // with -9 leaves the previous output untouched; the next resume finishes byte-identically.
  const test::TempDir tmp("cli_kill");
  const fs::path dir = tmp.path();
  fs::create_directories(dir / "out");
  const std::string scene = scenePath("cornell_open.gltf");
  const std::string ref = (dir / "ref.glb").string(), out = (dir / "out" / "b.glb").string();
  const std::string ckpt = out + ".prt-checkpoint";
  // --no-refine: a resumed bake refines again before its first save (seconds on cornell_open at
  // one thread), and this test times saves; refined resumes are CliResume.RefinedBakeResumes...
  std::vector<std::string> common = {"bake",    scene,        "-o",        out, "--samples", "256",
                                     "--bands", "2",          "--bounces", "1", "-q",        "--checkpoint-interval",
                                     "0.1",     "--no-refine"};
  std::vector<std::string> refArgs = common;
  refArgs[3] = ref;
  ASSERT_EQ(prtBake(refArgs).status, 0);
  const std::string refBytes = slurp(ref);
  // The previous good output at the path: some other bake.
  ASSERT_EQ(prtBake({"bake", scenePath("plane.gltf"), "-o", out, "--samples", "16", "-q"}).status, 0);
  const std::string previous = slurp(out);

  Process child(test::prtExe(), common);
  // Wait for the first periodic save, then stop it.
  for (int i = 0; i < 200 && !fs::exists(ckpt); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(25));
  ASSERT_TRUE(fs::exists(ckpt)) << "no periodic checkpoint after 5 s";
  auto tSignal = std::chrono::steady_clock::now();
  child.signal(SIGTERM);
  RunResult r = child.wait();
  const double stopSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - tSignal).count();
  ASSERT_EQ(r.status, 143) << r.err;  // 128 + SIGTERM: it finished before the signal otherwise
  EXPECT_LT(stopSeconds, 2.0);
  EXPECT_NE(r.err.find("checkpoint saved"), std::string::npos) << r.err;
  EXPECT_EQ(slurp(out), previous);

  std::vector<std::string> resumeArgs = common;
  resumeArgs.push_back("--resume");
  resumeArgs.push_back("--threads");
  resumeArgs.push_back("1");
  RunResult killed = killAfterNextSave(resumeArgs, ckpt);
  ASSERT_EQ(killed.status, 128 + SIGKILL) << "finished before kill -9: " << killed.err;
  EXPECT_EQ(slurp(out), previous);  // never a partial output

  RunResult done = prtBake(resumeArgs);
  ASSERT_EQ(done.status, 0) << done.err;
  EXPECT_TRUE(slurp(out) == refBytes) << "output after kill -9 and resume differs";
  EXPECT_FALSE(fs::exists(ckpt));
}

// Refinement is not a checkpointed stage: it is deterministic and runs again on resume, before
// the restored stages, so a resumed refined bake has the refined mesh the restored chunks belong
// to. A coarse floor under a lid (refined from 8 to some 50 vertices), interrupted after the
// direct pass, resumed with another thread count: the same bytes.
TEST(CliResume, RefinedBakeResumesByteIdentical) {
  const test::TempDir tmp("cli_refine_resume");
  test::GltfFile f;
  f.node({{"name", "Floor"}, {"mesh", f.mesh(test::makePlane({0, 0, 0}, 2.0f, 1))}}, true);
  MeshInstance lid = test::makePlane({0.25f, 0.3f, 0.0f}, 1.0f, 1);
  for (size_t t = 0; t < lid.indices.size(); t += 3) std::swap(lid.indices[t + 1], lid.indices[t + 2]);
  for (glm::vec3& n : lid.normals) n = {0, -1, 0};
  f.node({{"name", "Lid"}, {"mesh", f.mesh(lid)}}, true);
  const std::string scene = f.write("quad", tmp.path());
  const std::string ref = (tmp.path() / "ref.glb").string(), out = (tmp.path() / "out.glb").string();
  const std::vector<std::string> common = {"bake", scene, "--samples", "256", "-q"};
  auto with = [&](std::vector<std::string> extra) {
    std::vector<std::string> a = common;
    a.insert(a.end(), extra.begin(), extra.end());
    return a;
  };
  ASSERT_EQ(prtBake(with({"-o", ref})).status, 0);
  ASSERT_GT(loadScene(ref).meshes[0].vertexCount(), 4u) << "not refined: the test would prove nothing";
  const RunResult r = prtBake(with({"-o", out}), interruptAfter(1));
  ASSERT_EQ(r.status, 130) << r.err;
  ASSERT_TRUE(fs::exists(out + ".prt-checkpoint"));
  const RunResult done = prtBake(with({"-o", out, "--resume", "--threads", "1"}));
  ASSERT_EQ(done.status, 0) << done.err;
  EXPECT_EQ(slurp(out), slurp(ref));
  // Other refinement settings are another bake: the checkpoint is refused, naming them.
  ASSERT_EQ(prtBake(with({"-o", out}), interruptAfter(1)).status, 130);
  const RunResult other = prtBake(with({"-o", out, "--resume", "--refine-tolerance", "0.1"}));
  EXPECT_EQ(other.status, 1);
  EXPECT_NE(other.err.find("refine tolerance"), std::string::npos) << other.err;
}

TEST(CliResume, MismatchingCheckpointIsRefused) {
  const test::TempDir tmp("cli_mismatch");
  const fs::path dir = tmp.path();
  // A private copy of the scene, to edit it between the runs.
  fs::copy_file(scenePath("cornell_open.gltf"), dir / "s.gltf");
  fs::copy_file(scenePath("cornell_open.bin"), dir / "cornell_open.bin");
  const std::string out = (dir / "b.glb").string();
  std::vector<std::string> args = {"bake", (dir / "s.gltf").string(), "-o", out, "--samples", "64", "-q"};
  ASSERT_EQ(prtBake(args, interruptAfter(10)).status, 130);
  std::vector<std::string> other = args;
  other[5] = "128";
  other.push_back("--resume");
  RunResult r = prtBake(other);
  EXPECT_EQ(r.status, 1);
  EXPECT_EQ(lines(r.err), 1) << r.err;
  EXPECT_NE(r.err.find("samples 64 (checkpoint) vs 128 (now)"), std::string::npos) << r.err;
  // Edit one byte of the vertex data (the buffer the .gltf references).
  {
    std::fstream f(dir / "cornell_open.bin", std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(40);
    f.put('\x7f');
  }
  args.push_back("--resume");
  r = prtBake(args);
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("scene geometry differs"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(out));
  // --resume without a checkpoint.
  fs::remove(out + ".prt-checkpoint");
  r = prtBake(args);
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("no checkpoint to resume"), std::string::npos) << r.err;
}

// ---- The probe stage through `prt bake --probes`
// cornell_open (12.5 k vertices: 196 chunks per surface pass) with a probe lattice over it.
std::vector<std::string> probeBakeArgs(const std::string& glb, const std::string& vdb, int dims, int probeSamples) {
  const std::string d = std::to_string(dims);
  return {"bake",
          scenePath("cornell_open.gltf"),
          "-o",
          glb,
          "--probes",
          vdb,
          "--samples",
          "16",
          "--bands",
          "2",
          "--bounces",
          "1",
          "--probe-dims",
          d + "," + d + "," + d,
          "--probe-samples",
          std::to_string(probeSamples),
          "-q"};
}

using test::plus;

TEST(CliResumeProbes, InterruptedInTheProbeStageResumesByteIdentical) {
  const test::TempDir tmp("cli_probes");
  const fs::path dir = tmp.path();
  fs::create_directories(dir / "out");
  const std::string out = (dir / "out" / "b.glb").string(), vdb = (dir / "out" / "b.vdb").string();
  const std::string ckpt = out + ".prt-checkpoint";
  const std::vector<std::string> args = probeBakeArgs(out, vdb, 12, 64);  // 1728 probes, 27 chunks
  ASSERT_EQ(prtBake(probeBakeArgs((dir / "ref.glb").string(), (dir / "ref.vdb").string(), 12, 64)).status, 0);
  const std::string refGlb = slurp(dir / "ref.glb"), refVdb = slurp(dir / "ref.vdb");
  constexpr int kSurfaceChunks = 2 * 196;  // direct pass and one bounce
  uintmax_t sizeAt[2] = {0, 0};
  const int probeChunks[2] = {5, 20};
  for (int run = 0; run < 2; ++run) {
    SCOPED_TRACE(probeChunks[run]);
    const int after = kSurfaceChunks + probeChunks[run];
    RunResult r = prtBake(args, interruptAfter(after));
    EXPECT_EQ(r.status, 130) << r.err;
    EXPECT_EQ(lines(r.err), 1) << r.err;
    EXPECT_NE(r.err.find("interrupted: checkpoint saved to " + ckpt + " (probe stage "), std::string::npos) << r.err;
    EXPECT_EQ(dirNames(dir / "out"), std::vector<std::string>{"b.glb.prt-checkpoint"});  // no output yet
    sizeAt[run] = fs::file_size(ckpt);
    RunResult resumed = prtBake(plus(args, {"--resume", "--threads", "1"}));
    ASSERT_EQ(resumed.status, 0) << resumed.err;
    EXPECT_TRUE(slurp(out) == refGlb) << "resumed .glb differs from the uninterrupted bake";
    EXPECT_TRUE(slurp(vdb) == refVdb) << "resumed .vdb differs from the uninterrupted bake";
    EXPECT_EQ(dirNames(dir / "out"), (std::vector<std::string>{"b.glb", "b.vdb"}));  // checkpoint removed
    fs::remove(out);
    fs::remove(vdb);
  }
  // Every probe chunk adds one record: 64 probes' slots and the transfer of the valid ones.
  std::printf("checkpoint: %.1f bytes per probe (bands 2: %zu bytes of transfer per valid probe)\n",
              double(sizeAt[1] - sizeAt[0]) / ((probeChunks[1] - probeChunks[0]) * 64.0), size_t(16 * 12));
}

TEST(CliResumeProbes, CheckpointWithOtherProbeSettingsIsRefused) {
  const test::TempDir tmp("cli_probes_mismatch");
  const fs::path dir = tmp.path();
  const std::string out = (dir / "b.glb").string(), vdb = (dir / "b.vdb").string();
  const std::vector<std::string> args = probeBakeArgs(out, vdb, 6, 64);
  ASSERT_EQ(prtBake(args, interruptAfter(394)).status, 130);
  for (const auto& [other, what] : std::vector<std::pair<std::vector<std::string>, std::string>>{
           {probeBakeArgs(out, vdb, 6, 128), "probe samples 64 (checkpoint) vs 128 (now)"},
           {probeBakeArgs(out, vdb, 7, 64), "probe dims 6,6,6 (checkpoint) vs 7,7,7 (now)"},
           {plus(args, {"--probe-half"}), "probe half no (checkpoint) vs yes (now)"},
           {plus(args, {"--seed", "2"}), "seed 1 (checkpoint) vs 2 (now)"}}) {
    RunResult r = prtBake(plus(other, {"--resume"}));
    EXPECT_EQ(r.status, 1);
    EXPECT_EQ(lines(r.err), 1) << r.err;
    EXPECT_NE(r.err.find("checkpoint is from another bake: "), std::string::npos) << r.err;
    EXPECT_NE(r.err.find(what), std::string::npos) << r.err;
  }
  EXPECT_FALSE(fs::exists(out));
  EXPECT_FALSE(fs::exists(vdb));
}

TEST(CliResumeProbes, SigintInTheProbeStageThenKillNineThenResume) {
  // A real SIGINT while the probes are baked stops the bake within a second with the
  // checkpoint saved; a resumed bake killed with -9 in the probe stage leaves the previous
  // outputs untouched; the next resume finishes byte-identically.
  const test::TempDir tmp("cli_probes_kill");
  const fs::path dir = tmp.path();
  fs::create_directories(dir / "out");
  const std::string out = (dir / "out" / "b.glb").string(), vdb = (dir / "out" / "b.vdb").string();
  const std::string ckpt = out + ".prt-checkpoint";
  // 8000 probes of 256 rays: several seconds on the 2-core development machine.
  const std::vector<std::string> args = probeBakeArgs(out, vdb, 20, 256);
  const auto tRef = std::chrono::steady_clock::now();
  ASSERT_EQ(prtBake(probeBakeArgs((dir / "ref.glb").string(), (dir / "ref.vdb").string(), 20, 256)).status, 0);
  // The signal goes a tenth of the reference bake's time into the probe stage (at most 0.3 s):
  // on a machine fast enough to bake it all in a fraction of a second it still lands.
  const double refSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - tRef).count();
  const auto waitInProbeStage = std::chrono::duration<double>(std::min(0.3, 0.1 * refSeconds));
  const std::string refGlb = slurp(dir / "ref.glb"), refVdb = slurp(dir / "ref.vdb");
  // The previous good outputs at the paths: some other bake.
  ASSERT_EQ(prtBake(probeBakeArgs(out, vdb, 3, 16)).status, 0);
  const std::string previousGlb = slurp(out), previousVdb = slurp(vdb);

  Process child(test::prtExe(), plus(args, {"--checkpoint-interval", "0"}));
  // With --checkpoint-interval 0 the first save is the finished surface stage: the probe
  // stage has begun once the file is there.
  for (int i = 0; i < 1000 && !fs::exists(ckpt); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(10));
  ASSERT_TRUE(fs::exists(ckpt)) << "the surface stage did not finish in 10 s";
  std::this_thread::sleep_for(waitInProbeStage);
  auto tSignal = std::chrono::steady_clock::now();
  child.signal(SIGINT);
  RunResult r = child.wait();
  const double stopSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - tSignal).count();
  ASSERT_EQ(r.status, 130) << r.err;  // it finished before the signal otherwise
  std::printf("SIGINT in the probe stage: exit after %.3f s, checkpoint %ju bytes\n", stopSeconds,
              uintmax_t(fs::file_size(ckpt)));
  EXPECT_LT(stopSeconds, 2.0);
  EXPECT_EQ(lines(r.err), 1) << r.err;
  EXPECT_NE(r.err.find("interrupted: checkpoint saved to " + ckpt + " (probe stage "), std::string::npos) << r.err;
  EXPECT_EQ(slurp(out), previousGlb);
  EXPECT_EQ(slurp(vdb), previousVdb);

  std::vector<std::string> resumeArgs = plus(args, {"--resume", "--threads", "1", "--checkpoint-interval", "0.1"});
  RunResult killed = killAfterNextSave(resumeArgs, ckpt);
  ASSERT_EQ(killed.status, 128 + SIGKILL) << "finished before kill -9: " << killed.err;
  EXPECT_EQ(slurp(out), previousGlb);  // never a partial output
  EXPECT_EQ(slurp(vdb), previousVdb);

  RunResult done = prtBake(resumeArgs);
  ASSERT_EQ(done.status, 0) << done.err;
  EXPECT_TRUE(slurp(out) == refGlb) << "the .glb after SIGINT, kill -9 and resume differs";
  EXPECT_TRUE(slurp(vdb) == refVdb) << "the .vdb after SIGINT, kill -9 and resume differs";
  EXPECT_FALSE(fs::exists(ckpt));
}

TEST(CliMemory, RefusalWritesNothingAndEstimateBoundsThePeak) {
  const test::TempDir tmp("cli_memory");
  const fs::path dir = tmp.path();
  fs::create_directories(dir / "out");
  const std::string out = (dir / "out" / "b.glb").string();
  RunResult r = prtBake({"bake", scenePath("cornell_open.gltf"), "-o", out, "--max-memory", "1M"});
  EXPECT_EQ(r.status, 1);
  EXPECT_EQ(lines(r.err), 1) << r.err;
  EXPECT_NE(r.err.find("not enough memory"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("--max-memory"), std::string::npos) << r.err;
  EXPECT_TRUE(dirNames(dir / "out").empty());
  r = prtBake({"bake", scenePath("cornell_open.gltf"), "-o", out, "--max-memory", "lots"});
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("--max-memory lots"), std::string::npos) << r.err;

  // A moderate bake: the estimate printed is at least the measured peak, and not far above. At
  // the default 1024 samples the surface stage (hit records, transfer buffers) is the largest
  // phase of the estimate and of the bake (estimated 214 MiB, peak 144 MiB, 2026-12-05); at 256
  // samples the refinement's estimate, a loose bound per vertex (memory_estimate.cpp), is the
  // largest, and since the hit records are copied once the bake's peak is 74 MiB against 121.
  r = prtBake({"bake", scenePath("cornell_open.gltf"), "-o", out, "--samples", "1024"});
  ASSERT_EQ(r.status, 0) << r.err;
  std::smatch m;
  ASSERT_TRUE(std::regex_search(r.err, m, std::regex("memory: estimated ([0-9.]+) MiB, peak ([0-9.]+) MiB"))) << r.err;
  const double estimated = std::stod(m[1]), peak = std::stod(m[2]);
  // AddressSanitizer's shadow memory and quarantine add to every allocation; the estimate is for
  // the uninstrumented program (the Release suite checks it).
  if (test::kAddressSanitizer) GTEST_SKIP() << "peak under ASan is not the program's peak";
  EXPECT_GE(estimated, peak);
  EXPECT_LE(estimated, 2.0 * peak);
}

TEST(CliMemory, EstimateBoundsThePeakOfAProbeBake) {
  // The probe stage is the largest phase: at bands 4 the .vdb has 264 grids, each with a
  // 512 KiB OpenVDB node whatever the lattice's size, and 16³ points hold 3 KiB of transfer
  // each in the bake, the grid, its OpenVDB trees and the file read back.
  const test::TempDir tmp("cli_memory_probes");
  const fs::path dir = tmp.path();
  RunResult r = prtBake({"bake", scenePath("cornell_open.gltf"), "-o", (dir / "b.glb").string(), "--probes",
                         (dir / "b.vdb").string(), "--samples", "16", "--bounces", "1", "--bands", "4", "--probe-dims",
                         "16,16,16", "--probe-samples", "4"});
  ASSERT_EQ(r.status, 0) << r.err;
  std::smatch m;
  ASSERT_TRUE(std::regex_search(r.err, m,
                                std::regex("memory: estimated ([0-9.]+) MiB, peak ([0-9.]+) MiB \\(estimated by "
                                           "phase: surface ([0-9.]+) MiB, probes ([0-9.]+) MiB")))
      << r.err;
  const double estimated = std::stod(m[1]), peak = std::stod(m[2]), surface = std::stod(m[3]), probes = std::stod(m[4]);
  EXPECT_EQ(estimated, probes);  // the probe stage is the largest phase
  EXPECT_GT(probes, surface);
  if (test::kAddressSanitizer) GTEST_SKIP() << "peak under ASan is not the program's peak";
  EXPECT_GE(estimated, peak);
  EXPECT_LE(estimated, 2.0 * peak);
}

TEST(CliMemory, ASparseLatticeIsCountedByItsPlacement) {
  // A cavity in a lattice 8 times its size, 40³ points: nearly all are open air far from its
  // surfaces, which the probe bake leaves out. Under a limit the bound (every point baked)
  // exceeds, the placement's count is checked instead, and the bake runs with the same bytes.
  const test::TempDir tmp("cli_memory_sparse");
  const fs::path dir = tmp.path();
  auto args = [&](const std::string& name, const std::string& limit) {
    return std::vector<std::string>{"bake",
                                    scenePath("cavity.gltf"),
                                    "-o",
                                    (dir / (name + ".glb")).string(),
                                    "--probes",
                                    (dir / (name + ".vdb")).string(),
                                    "--samples",
                                    "16",
                                    "--bounces",
                                    "1",
                                    "--probe-dims",
                                    "40,40,40",
                                    "--probe-bounds",
                                    "-8,-8,-8,8,8,8",
                                    "--probe-samples",
                                    "16",
                                    "--max-memory",
                                    limit};
  };
  const std::regex estimate("memory: estimated ([0-9.]+) MiB, peak ([0-9.]+) MiB");
  std::smatch m;
  RunResult r = prtBake(args("bound", "64G"));
  ASSERT_EQ(r.status, 0) << r.err;
  ASSERT_TRUE(std::regex_search(r.err, m, estimate)) << r.err;
  const double bound = std::stod(m[1]);
  // Just under the bound: refused before, counted now.
  const int limit = int(bound) - 1;
  r = prtBake(args("counted", cat(limit, "M")));
  ASSERT_EQ(r.status, 0) << r.err;
  ASSERT_TRUE(std::regex_search(r.err, m, estimate)) << r.err;
  const double counted = std::stod(m[1]), peak = std::stod(m[2]);
  EXPECT_LT(counted, 0.75 * bound) << r.err;
  EXPECT_EQ(slurp(dir / "counted.glb"), slurp(dir / "bound.glb"));
  EXPECT_EQ(slurp(dir / "counted.vdb"), slurp(dir / "bound.vdb"));
  // Still refused, in one line and writing nothing, where even the count does not fit.
  r = prtBake(args("refused", cat(int(counted) / 2, "M")));
  EXPECT_EQ(r.status, 1);
  EXPECT_EQ(lines(r.err), 1) << r.err;
  EXPECT_NE(r.err.find("not enough memory"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir / "refused.glb"));
  EXPECT_FALSE(fs::exists(dir / "refused.vdb"));
  if (test::kAddressSanitizer) GTEST_SKIP() << "peak under ASan is not the program's peak";
  EXPECT_GE(counted, peak);
}

}  // namespace
}  // namespace prt
