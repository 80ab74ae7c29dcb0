// Interruption, checkpoints and resume (bake/checkpoint.h), and the memory guard
// (bake/memory_estimate.h): in process through the library, and end to end through `prt bake`
// with the test interrupt hook, real signals and kill -9.
#include <gtest/gtest.h>

#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <thread>

#include "prt/bake/checkpoint.h"
#include "prt/bake/memory_estimate.h"
#include "prt/bake/probe_bake.h"
#include "prt/bake/surface_bake.h"
#include "prt/error.h"
#include "prt/probe_grid.h"
#include "test_scenes.h"

namespace prt {
namespace {

namespace fs = std::filesystem;
using namespace prt::bake;

fs::path freshDir(const std::string& name) {
  fs::path d = fs::path(::testing::TempDir()) / ("prt_resume_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// A cavity (2561 vertices, 41 chunks of 64) above a plane: occlusion, bounces, two instances.
Scene resumeScene() {
  return test::makeScene({test::makeCavity(0.6, 40, 64), test::makePlane({0, -1.2f, 0}, 4.0f, 12)}, 0.7f);
}

BakeSettings resumeSettings() {
  BakeSettings s;
  s.samples = 64;
  s.bounces = 2;
  s.bands = 3;
  s.keepLowerOrder = true;
  return s;
}

bool sameBits(const std::vector<std::vector<glm::vec3>>& a, const std::vector<std::vector<glm::vec3>>& b) {
  if (a.size() != b.size()) return false;
  for (size_t k = 0; k < a.size(); ++k)
    if (a[k].size() != b[k].size() ||
        (!a[k].empty() && std::memcmp(a[k].data(), b[k].data(), a[k].size() * sizeof(glm::vec3)) != 0))
      return false;
  return true;
}

Fingerprint fingerprintOf(const Scene& scene, const BakeSettings& s) {
  Fingerprint fp;
  addSceneFingerprint(fp, scene);
  fp.add("samples", std::to_string(s.samples));
  fp.add("bounces", std::to_string(s.bounces));
  return fp;
}

// Bakes with a checkpoint that raises an interrupt after `after` chunks; expects the bake to
// stop with prt::Interrupted.
void bakeUntilInterrupted(const Scene& scene, BakeSettings s, const std::string& path, bool resume, uint64_t after,
                          double interval) {
  CheckpointOptions o;
  o.path = path;
  o.resume = resume;
  o.interruptAfterChunks = after;
  o.intervalSeconds = interval;
  Checkpoint cp(o, fingerprintOf(scene, s));
  BakeControl control;
  control.checkpoint = &cp;
  EXPECT_THROW(bakeSurface(scene, s, control), Interrupted);
  clearInterrupt();
}

SurfaceTransfer bakeResumed(const Scene& scene, BakeSettings s, const std::string& path) {
  CheckpointOptions o;
  o.path = path;
  o.resume = true;
  Checkpoint cp(o, fingerprintOf(scene, s));
  BakeControl control;
  control.checkpoint = &cp;
  SurfaceTransfer t = bakeSurface(scene, s, control);
  EXPECT_TRUE(t.stats.resumed);
  cp.remove();
  return t;
}

TEST(Resume, InterruptedAnywhereResumesToTheSameBits) {
  const Scene scene = resumeScene();
  const BakeSettings s = resumeSettings();
  const SurfaceTransfer ref = bakeSurface(scene, s);
  const uint64_t chunks = (2561 + 169 + 63) / 64;  // cavity + plane vertices, 64 per chunk
  fs::path dir = freshDir("points");
  // In the direct pass (first chunk, middle), in bounce 1, in bounce 2, after the last chunk;
  // with saves only at the interrupt, and with a save after every chunk.
  for (uint64_t after : {uint64_t(1), chunks / 2, chunks + 3, 2 * chunks + chunks / 2, 3 * chunks}) {
    for (double interval : {0.0, 1e-9}) {
      SCOPED_TRACE(::testing::Message() << "interrupt after " << after << " chunks, interval " << interval);
      const std::string path = (dir / "a.ckpt").string();
      bakeUntilInterrupted(scene, s, path, false, after, interval);
      ASSERT_TRUE(fs::exists(path));
      BakeSettings r = s;
      r.threads = 1;  // another thread count on resume
      SurfaceTransfer t = bakeResumed(scene, r, path);
      EXPECT_TRUE(sameBits(ref.perMesh, t.perMesh));
      EXPECT_TRUE(sameBits(ref.perMeshLowerOrder, t.perMeshLowerOrder));
      EXPECT_EQ(ref.stats.hitRecords, t.stats.hitRecords);
      EXPECT_FALSE(fs::exists(path));
    }
  }
}

TEST(Resume, InterruptedTwiceAndWithoutBouncesStillTheSameBits) {
  const Scene scene = resumeScene();
  for (int bounces : {0, 3}) {
    BakeSettings s = resumeSettings();
    s.bounces = bounces;
    s.keepLowerOrder = bounces > 0;
    SCOPED_TRACE(bounces);
    const SurfaceTransfer ref = bakeSurface(scene, s);
    const std::string path = (freshDir("twice") / "a.ckpt").string();
    bakeUntilInterrupted(scene, s, path, false, 7, 1e-9);
    bakeUntilInterrupted(scene, s, path, true, 20, 0.0);  // the resumed bake interrupted again
    bakeUntilInterrupted(scene, s, path, true, 11, 1e-9);
    SurfaceTransfer t = bakeResumed(scene, s, path);
    EXPECT_TRUE(sameBits(ref.perMesh, t.perMesh));
    EXPECT_TRUE(sameBits(ref.perMeshLowerOrder, t.perMeshLowerOrder));
  }
}

TEST(Resume, FinishedSurfaceStageIsKeptForTheProbeStage) {
  // With keepLowerOrder (a probe bake follows) the finished surface stage is saved, so that a
  // bake interrupted in the probe stage resumes without redoing the surface.
  const Scene scene = resumeScene();
  const BakeSettings s = resumeSettings();
  const SurfaceTransfer ref = bakeSurface(scene, s);
  const std::string path = (freshDir("done") / "a.ckpt").string();
  {
    CheckpointOptions o;
    o.path = path;
    o.intervalSeconds = 0.0;
    Checkpoint cp(o, fingerprintOf(scene, s));
    BakeControl control;
    control.checkpoint = &cp;
    bakeSurface(scene, s, control);
  }
  ASSERT_TRUE(fs::exists(path));
  SurfaceTransfer t = bakeResumed(scene, s, path);
  EXPECT_EQ(t.stats.rays, 0u);  // nothing traced again
  EXPECT_TRUE(sameBits(ref.perMesh, t.perMesh));
  EXPECT_TRUE(sameBits(ref.perMeshLowerOrder, t.perMeshLowerOrder));
  EXPECT_EQ(ref.stats.hitRecords, t.stats.hitRecords);
}

TEST(Resume, TornTailOfTheLogIsDropped) {
  // A kill -9 or power cut in the middle of a save leaves a partial last record: resume keeps
  // what the last complete save committed and redoes the rest.
  const Scene scene = resumeScene();
  const BakeSettings s = resumeSettings();
  const SurfaceTransfer ref = bakeSurface(scene, s);
  const std::string path = (freshDir("torn") / "a.ckpt").string();
  bakeUntilInterrupted(scene, s, path, false, 60, 1e-9);
  // Cuts relative to the file as it is at each round: a resumed bake may leave it shorter than
  // before (its last chunks can hold fewer hit records than the ones the cut dropped).
  for (auto cutOf : {+[](uintmax_t n) { return n - 1; }, +[](uintmax_t n) { return n - 30; },
                     +[](uintmax_t n) { return n * 2 / 3; }}) {
    std::string bytes = slurp(path);
    const uintmax_t cut = cutOf(bytes.size());
    SCOPED_TRACE(cut);
    {
      std::ofstream out(path, std::ios::binary | std::ios::trunc);
      out.write(bytes.data(), std::streamsize(cut));
      out << "garbage after a torn write";
    }
    // Resume from the damaged copy, interrupt again (so the checkpoint survives), then check
    // the final result once below.
    bakeUntilInterrupted(scene, s, path, true, 1, 0.0);
  }
  SurfaceTransfer t = bakeResumed(scene, s, path);
  EXPECT_TRUE(sameBits(ref.perMesh, t.perMesh));
}

TEST(Resume, CheckpointOfAnotherBakeIsRefusedNamingTheDifference) {
  const Scene scene = resumeScene();
  BakeSettings s = resumeSettings();
  fs::path dir = freshDir("mismatch");
  const std::string path = (dir / "a.ckpt").string();
  bakeUntilInterrupted(scene, s, path, false, 5, 0.0);
  auto messageFor = [&](const Scene& sc, const BakeSettings& st) {
    CheckpointOptions o;
    o.path = path;
    o.resume = true;
    try {
      Checkpoint cp(o, fingerprintOf(sc, st));
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  BakeSettings more = s;
  more.samples = 128;
  EXPECT_NE(messageFor(scene, more).find("samples 64 (checkpoint) vs 128 (now)"), std::string::npos)
      << messageFor(scene, more);
  Scene edited = scene;
  edited.meshes[1].positions[3].y += 1e-3f;
  EXPECT_NE(messageFor(edited, s).find("scene geometry differs"), std::string::npos) << messageFor(edited, s);
  Scene recoloured = scene;
  recoloured.materials[0].baseColorFactor.r = 0.5f;
  EXPECT_NE(messageFor(recoloured, s).find("scene materials differs"), std::string::npos);
  EXPECT_EQ(messageFor(scene, s), "accepted");
  // Without --resume an existing checkpoint is not silently replaced.
  CheckpointOptions fresh;
  fresh.path = path;
  EXPECT_THROW(Checkpoint(fresh, fingerprintOf(scene, s)), Error);
  // --resume with nothing to resume, and a file that is not a checkpoint.
  CheckpointOptions none;
  none.path = (dir / "none.ckpt").string();
  none.resume = true;
  try {
    Checkpoint cp(none, fingerprintOf(scene, s));
    ADD_FAILURE() << "resumed from nothing";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("no checkpoint to resume"), std::string::npos) << e.what();
  }
  std::ofstream(dir / "bad.ckpt") << "not a checkpoint at all";
  none.path = (dir / "bad.ckpt").string();
  EXPECT_THROW(Checkpoint(none, fingerprintOf(scene, s)), Error);
}

TEST(Resume, NoCheckpointStillStopsOnInterrupt) {
  const Scene scene = resumeScene();
  requestInterrupt(SIGINT);
  EXPECT_THROW(bakeSurface(scene, resumeSettings()), Interrupted);
  clearInterrupt();
}

// ---- The probe stage
// A 9×7×8 lattice over the cavity and the plane (504 points, 8 chunks of 64, the last one
// partial): probes in free space, inside the cavity's wall, and moved out of it.
ProbeSettings resumeProbeSettings() {
  ProbeSettings ps;
  ps.dims = glm::ivec3(9, 7, 8);
  ps.samples = 64;
  ps.bands = 3;
  ps.bounces = 2;
  return ps;
}

Fingerprint fingerprintOf(const Scene& scene, const BakeSettings& s, const ProbeSettings& ps) {
  Fingerprint fp = fingerprintOf(scene, s);
  addProbeFingerprint(fp, ps);
  return fp;
}

// Surface then probes through one checkpoint, as `prt bake --probes` runs them.
ProbeGrid bakeBoth(const Scene& scene, const BakeSettings& s, const ProbeSettings& ps, Checkpoint* cp,
                   ProbeStats* stats = nullptr) {
  BakeControl control;
  control.checkpoint = cp;
  SurfaceTransfer t = bakeSurface(scene, s, control);
  return bakeProbes(scene, t.perMeshLowerOrder, ps, stats, cp);
}

void bakeBothUntilInterrupted(const Scene& scene, const BakeSettings& s, const ProbeSettings& ps,
                              const std::string& path, bool resume, uint64_t after, double interval) {
  CheckpointOptions o;
  o.path = path;
  o.resume = resume;
  o.interruptAfterChunks = after;
  o.intervalSeconds = interval;
  Checkpoint cp(o, fingerprintOf(scene, s, ps));
  EXPECT_THROW(bakeBoth(scene, s, ps, &cp), Interrupted);
  clearInterrupt();
}

std::string vdbBytes(const ProbeGrid& g, const fs::path& path) {
  writeProbeGrid(g, path.string());
  return slurp(path);
}

template <class T>
bool sameBits(const std::vector<T>& a, const std::vector<T>& b) {
  return a.size() == b.size() && (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(T)) == 0);
}

void expectSameGrid(const ProbeGrid& a, const ProbeGrid& b) {
  EXPECT_EQ(a.dims, b.dims);
  EXPECT_EQ(a.origin, b.origin);
  EXPECT_EQ(a.spacing, b.spacing);
  EXPECT_TRUE(sameBits(a.coord, b.coord));
  EXPECT_TRUE(sameBits(a.transfer, b.transfer));
  EXPECT_TRUE(sameBits(a.validity, b.validity));
  EXPECT_TRUE(sameBits(a.offset, b.offset));
  EXPECT_TRUE(sameBits(a.skyVisibility, b.skyVisibility));
  EXPECT_TRUE(sameBits(a.moments, b.moments));
}

constexpr uint64_t kResumeSurfaceChunks = 3 * ((2561 + 169 + 63) / 64);  // direct pass, 2 bounces
constexpr uint64_t kResumeProbeChunks = (9 * 7 * 8 + kProbeChunk - 1) / kProbeChunk;

// The interrupted bakes run on one thread: the chunks saved at the interrupt are then exactly
// the first k (on several threads others finish in the meantime, in any order, and are saved
// too; the result is the same, but the count is not). The resumed bakes run on all threads.
template <class Settings>
Settings oneThread(Settings s) {
  s.threads = 1;
  return s;
}

TEST(ResumeProbes, InterruptedInTheProbeStageResumesToTheSameBitsAndFile) {
  const Scene scene = resumeScene();
  const BakeSettings s = resumeSettings();
  const ProbeSettings ps = resumeProbeSettings();
  fs::path dir = freshDir("probes");
  ProbeStats refStats;
  const ProbeGrid ref = bakeBoth(scene, s, ps, nullptr, &refStats);
  // The lattice has all three kinds of probes, or the test would miss a code path.
  ASSERT_GT(refStats.invalid, 0u);
  ASSERT_GT(refStats.moved, 0u);
  ASSERT_GT(refStats.active - refStats.invalid, refStats.active / 2);
  const std::string refFile = vdbBytes(ref, dir / "ref.vdb");
  // After the first probe chunk, in the middle, and after the last one (interrupt raised by
  // the last chunk: the stage is complete but stops before assembling); saves only at the
  // interrupt, and after every chunk.
  for (uint64_t k : {uint64_t(1), kResumeProbeChunks / 2, kResumeProbeChunks}) {
    for (double interval : {0.0, 1e-9}) {
      SCOPED_TRACE(::testing::Message() << "interrupt after probe chunk " << k << ", interval " << interval);
      const std::string path = (dir / "a.ckpt").string();
      bakeBothUntilInterrupted(scene, oneThread(s), oneThread(ps), path, false, kResumeSurfaceChunks + k, interval);
      ASSERT_TRUE(fs::exists(path));
      CheckpointOptions o;
      o.path = path;
      o.resume = true;
      Checkpoint cp(o, fingerprintOf(scene, s, ps));
      ProbeStats stats;
      const ProbeGrid g = bakeBoth(scene, s, ps, &cp, &stats);  // another thread count on resume
      cp.remove();
      EXPECT_EQ(stats.restored, std::min<uint64_t>(k * kProbeChunk, stats.probes));
      EXPECT_LT(stats.rays, refStats.rays);  // only the missing chunks were traced
      expectSameGrid(ref, g);
      EXPECT_TRUE(vdbBytes(g, dir / "resumed.vdb") == refFile) << "the .vdb differs";
    }
  }
}

TEST(ResumeProbes, InterruptedTwiceInTheProbeStage) {
  const Scene scene = resumeScene();
  const BakeSettings s = resumeSettings();
  const ProbeSettings ps = resumeProbeSettings();
  const ProbeGrid ref = bakeBoth(scene, s, ps, nullptr);
  const std::string path = (freshDir("probes_twice") / "a.ckpt").string();
  bakeBothUntilInterrupted(scene, oneThread(s), oneThread(ps), path, false, kResumeSurfaceChunks + 2, 1e-9);
  // The resumed bake interrupted again.
  bakeBothUntilInterrupted(scene, oneThread(s), oneThread(ps), path, true, 3, 0.0);
  CheckpointOptions o;
  o.path = path;
  o.resume = true;
  Checkpoint cp(o, fingerprintOf(scene, s, ps));
  ProbeStats stats;
  expectSameGrid(ref, bakeBoth(scene, s, ps, &cp, &stats));
  EXPECT_EQ(stats.restored, 5 * kProbeChunk);
}

TEST(ResumeProbes, CheckpointWithOtherProbeSettingsIsRefused) {
  const Scene scene = resumeScene();
  const BakeSettings s = resumeSettings();
  const ProbeSettings ps = resumeProbeSettings();
  const std::string path = (freshDir("probes_mismatch") / "a.ckpt").string();
  bakeBothUntilInterrupted(scene, s, ps, path, false, kResumeSurfaceChunks + 2, 0.0);
  auto messageFor = [&](const ProbeSettings& other) {
    CheckpointOptions o;
    o.path = path;
    o.resume = true;
    try {
      Checkpoint cp(o, fingerprintOf(scene, s, other));
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  auto expectRefused = [&](const ProbeSettings& other, const std::string& what) {
    const std::string msg = messageFor(other);
    EXPECT_NE(msg.find("checkpoint is from another bake: " + what), std::string::npos) << msg;
    EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
  };
  ProbeSettings o = ps;
  o.samples = 128;
  expectRefused(o, "probe samples 64 (checkpoint) vs 128 (now)");
  o = ps;
  o.dims.z = 9;
  expectRefused(o, "probe dims 9,7,8 (checkpoint) vs 9,7,9 (now)");
  o = ps;
  o.spacing = 0.25;
  expectRefused(o, "probe spacing 0 (checkpoint) vs 0.25 (now)");
  o = ps;
  o.boundsMin = glm::dvec3(-1.0);
  o.boundsMax = glm::dvec3(1.0);
  expectRefused(o, "probe bounds min scene (checkpoint) vs -1,-1,-1 (now)");
  o = ps;
  o.seed = 2;
  expectRefused(o, "probe seed 1 (checkpoint) vs 2 (now)");
  o = ps;
  o.bands = 2;
  expectRefused(o, "probe bands 3 (checkpoint) vs 2 (now)");
  o = ps;
  o.bounces = 1;
  expectRefused(o, "probe bounces 2 (checkpoint) vs 1 (now)");
  o = ps;
  o.threads = 1;  // not a setting of the result
  EXPECT_EQ(messageFor(o), "accepted");
}

TEST(ResumeProbes, InterruptStopsWithinAProbe) {
  // Two probes of 2^24 rays each take seconds; the flag is polled per stream of 256 rays, so
  // the bake stops long before one probe is done, and saves no probe chunk.
  const Scene scene = resumeScene();
  ProbeSettings ps;
  ps.dims = glm::ivec3(2, 1, 1);
  ps.samples = 1 << 24;
  ps.bounces = 0;
  const std::string path = (freshDir("probes_latency") / "a.ckpt").string();
  CheckpointOptions o;
  o.path = path;
  o.intervalSeconds = 0.0;
  Checkpoint cp(o, fingerprintOf(scene, resumeSettings(), ps));
  std::thread stopper([] {
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
    requestInterrupt(SIGINT);
  });
  const auto t0 = std::chrono::steady_clock::now();
  EXPECT_THROW(bakeProbes(scene, {}, ps, nullptr, &cp), Interrupted);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  stopper.join();
  clearInterrupt();
  std::printf("probe bake of 2 x 2^24 rays interrupted after 0.2 s: stopped after %.3f s\n", seconds);
  EXPECT_LT(seconds, 1.5);
  uint64_t chunks = 0;
  CheckpointOptions r = o;
  r.resume = true;
  Checkpoint again(r, fingerprintOf(scene, resumeSettings(), ps));
  again.restoreChunks(kProbeStage, [&](uint64_t, ByteReader&) { ++chunks; });
  EXPECT_EQ(chunks, 0u);
  again.remove();
}

TEST(Hasher, StreamingEqualsOneShotAndDetectsChanges) {
  std::string data(1000, '\0');
  for (size_t i = 0; i < data.size(); ++i) data[i] = char(i * 7 + 3);
  Hasher whole;
  whole.add(data.data(), data.size());
  for (size_t split : {size_t(1), size_t(3), size_t(8), size_t(13), size_t(999)}) {
    Hasher parts;
    for (size_t at = 0; at < data.size(); at += split) parts.add(data.data() + at, std::min(split, data.size() - at));
    EXPECT_EQ(parts.digest(), whole.digest()) << split;
  }
  data[500] ^= 1;
  Hasher flipped;
  flipped.add(data.data(), data.size());
  EXPECT_NE(flipped.digest(), whole.digest());
  Hasher shorter;
  shorter.add(data.data(), data.size() - 1);
  EXPECT_NE(shorter.digest(), flipped.digest());
}

// ---- Memory guard
TEST(Memory, ParsesSizes) {
  EXPECT_EQ(parseByteSize("8G", "--max-memory"), uint64_t(8) << 30);
  EXPECT_EQ(parseByteSize("500M", "--max-memory"), uint64_t(500) << 20);
  EXPECT_EQ(parseByteSize("1.5GiB", "--max-memory"), uint64_t(3) << 29);
  EXPECT_EQ(parseByteSize("64k", "--max-memory"), uint64_t(64) << 10);
  EXPECT_EQ(parseByteSize("12345", "--max-memory"), uint64_t(12345));
  for (const char* bad : {"", "G", "8X", "-1G", "0", "nan", "1e30T"}) EXPECT_THROW(parseByteSize(bad, "--max-memory"), Error) << bad;
}

TEST(Memory, PilotBoundsTheHitRecordsAndTheRefusalSuggestsAWayOut) {
  const Scene scene = resumeScene();
  BakeSettings s = resumeSettings();
  s.samples = 256;
  double share = -1;
  BakeControl control;
  control.checkMemory = [&](double sh) { share = sh; };
  SurfaceTransfer t = bakeSurface(scene, s, control);
  ASSERT_GE(share, 0.0);
  const double actual = double(t.stats.hitRecords) / (double(t.stats.vertices) * s.samples);
  // An upper bound, and not a uselessly loose one (the pilot adds 3 standard errors + 0.02).
  EXPECT_GE(share, actual);
  EXPECT_LE(share, actual + 0.1);
  MemoryEstimate e = estimateBakeMemory(scene, s, nullptr, share);
  EXPECT_GE(e.hits, t.stats.hitRecords * 8);
  // Refused under a limit just below the estimate, with a sample count that fits.
  MemoryLimit limit{e.total - e.hits / 2, "--max-memory"};
  try {
    checkMemory(e, limit, scene, s, nullptr);
    ADD_FAILURE() << "not refused";
  } catch (const Error& err) {
    std::string msg = err.what();
    EXPECT_NE(msg.find("not enough memory"), std::string::npos) << msg;
    std::smatch m;
    ASSERT_TRUE(std::regex_search(msg, m, std::regex("--samples ([0-9]+)"))) << msg;
    BakeSettings fewer = s;
    fewer.samples = std::stoi(m[1]);
    EXPECT_LT(fewer.samples, s.samples);
    EXPECT_LE(estimateBakeMemory(scene, fewer, nullptr, share).total, limit.bytes);
  }
  EXPECT_NO_THROW(checkMemory(e, MemoryLimit{e.total, "--max-memory"}, scene, s, nullptr));
  // The system's limit is readable here (Linux) and positive.
  std::optional<MemoryLimit> sys = memoryLimit(std::nullopt);
  ASSERT_TRUE(sys.has_value());
  EXPECT_GT(sys->bytes, uint64_t(0));
}

// ---- End to end through `prt bake`
struct ChildRun {
  int status = -1;  // exit status, or 128 + signal when killed
  std::string err;
  double seconds = 0;
};

std::string scenePath(const std::string& name) { return std::string(PRT_SOURCE_DIR) + "/scenes/" + name; }

// Starts `prt ARGS...` with stderr to a file and an optional extra environment variable.
pid_t spawn(const std::vector<std::string>& args, const fs::path& errFile, const std::string& env = "") {
  pid_t pid = ::fork();
  if (pid == 0) {
    int fd = ::open(errFile.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    ::dup2(fd, STDERR_FILENO);
    int nul = ::open("/dev/null", O_WRONLY);
    ::dup2(nul, STDOUT_FILENO);
    if (!env.empty()) ::putenv(const_cast<char*>(env.c_str()));
    std::vector<char*> argv;
    argv.push_back(const_cast<char*>(PRT_EXE));
    for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    ::execv(PRT_EXE, argv.data());
    ::_exit(127);
  }
  return pid;
}

ChildRun finish(pid_t pid, const fs::path& errFile, std::chrono::steady_clock::time_point t0) {
  int st = 0;
  ::waitpid(pid, &st, 0);
  ChildRun r;
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  r.status = WIFEXITED(st) ? WEXITSTATUS(st) : 128 + WTERMSIG(st);
  r.err = slurp(errFile);
  return r;
}

ChildRun prtBake(const std::vector<std::string>& args, const fs::path& dir, const std::string& env = "") {
  fs::path errFile = dir.parent_path() / (dir.filename().string() + "_stderr.txt");
  auto t0 = std::chrono::steady_clock::now();
  return finish(spawn(args, errFile, env), errFile, t0);
}

int lines(const std::string& s) { return int(std::count(s.begin(), s.end(), '\n')); }

std::vector<std::string> dirNames(const fs::path& dir) {
  std::vector<std::string> n;
  for (const auto& e : fs::directory_iterator(dir)) n.push_back(e.path().filename().string());
  std::sort(n.begin(), n.end());
  return n;
}

// Starts `prt ARGS...` (a resumed bake), waits until it has saved to its checkpoint `ckpt`
// once more, and kills it with -9.
ChildRun killAfterNextSave(const std::vector<std::string>& args, const std::string& ckpt, const fs::path& errFile) {
  const uintmax_t before = fs::file_size(ckpt);
  auto t0 = std::chrono::steady_clock::now();
  pid_t pid = spawn(args, errFile);
  for (int i = 0; i < 400 && fs::file_size(ckpt) <= before; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(10));
  EXPECT_GT(fs::file_size(ckpt), before) << "the resumed bake saved nothing in 4 s";
  ::kill(pid, SIGKILL);
  return finish(pid, errFile, t0);
}

TEST(CliResume, InterruptedBakeResumesByteIdenticalWithOtherThreads) {
  fs::path dir = freshDir("cli_points");
  const std::string scene = scenePath("cornell_open.gltf");
  const std::string ref = (dir / "ref.glb").string(), out = (dir / "out" / "b.glb").string();
  fs::create_directories(dir / "out");
  std::vector<std::string> common = {"bake", scene, "--samples", "64", "--bands", "2", "-q"};
  auto with = [&](std::vector<std::string> extra) {
    std::vector<std::string> a = common;
    a.insert(a.end(), extra.begin(), extra.end());
    return a;
  };
  ASSERT_EQ(prtBake(with({"-o", ref}), dir).status, 0);
  const std::string refBytes = slurp(ref);
  // cornell_open has 12.5 k baked vertices: 196 chunks per pass. Interrupt in the direct pass,
  // in bounce 1 and in bounce 2.
  for (int after : {20, 250, 500}) {
    SCOPED_TRACE(after);
    ChildRun r = prtBake(with({"-o", out}), dir, "PRT_TEST_INTERRUPT_AFTER=" + std::to_string(after));
    EXPECT_EQ(r.status, 130) << r.err;
    EXPECT_EQ(lines(r.err), 1) << r.err;
    EXPECT_NE(r.err.find("interrupted: checkpoint saved to " + out + ".prt-checkpoint ("), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("rerun with --resume"), std::string::npos);
    EXPECT_EQ(dirNames(dir / "out"), std::vector<std::string>{"b.glb.prt-checkpoint"});  // no output yet
    ChildRun again = prtBake(with({"-o", out}), dir);  // forgetting --resume does not lose it
    EXPECT_EQ(again.status, 1);
    EXPECT_NE(again.err.find("add --resume"), std::string::npos) << again.err;
    ChildRun resumed = prtBake(with({"-o", out, "--resume", "--threads", "1"}), dir);
    ASSERT_EQ(resumed.status, 0) << resumed.err;
    EXPECT_TRUE(slurp(out) == refBytes) << "resumed output differs from the uninterrupted bake";
    EXPECT_EQ(dirNames(dir / "out"), std::vector<std::string>{"b.glb"});  // checkpoint removed
    fs::remove(out);
  }
}

TEST(CliResume, SignalThenKillNineThenResume) {
  // A real SIGTERM stops the bake within two seconds with a checkpoint; a resumed bake killed
  // with -9 leaves the previous output untouched; the next resume finishes byte-identically.
  fs::path dir = freshDir("cli_kill");
  fs::create_directories(dir / "out");
  const std::string scene = scenePath("cornell_open.gltf");
  const std::string ref = (dir / "ref.glb").string(), out = (dir / "out" / "b.glb").string();
  const std::string ckpt = out + ".prt-checkpoint";
  std::vector<std::string> common = {"bake", scene, "-o", out, "--samples", "256", "--bands", "2", "--bounces", "1",
                                     "-q", "--checkpoint-interval", "0.1"};
  std::vector<std::string> refArgs = common;
  refArgs[3] = ref;
  ASSERT_EQ(prtBake(refArgs, dir).status, 0);
  const std::string refBytes = slurp(ref);
  // The previous good output at the path: some other bake.
  ASSERT_EQ(prtBake({"bake", scenePath("plane.gltf"), "-o", out, "--samples", "16", "-q"}, dir).status, 0);
  const std::string previous = slurp(out);

  fs::path errFile = dir / "child_stderr.txt";
  auto t0 = std::chrono::steady_clock::now();
  pid_t pid = spawn(common, errFile);
  // Wait for the first periodic save, then stop it.
  for (int i = 0; i < 200 && !fs::exists(ckpt); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(25));
  ASSERT_TRUE(fs::exists(ckpt)) << "no periodic checkpoint after 5 s";
  auto tSignal = std::chrono::steady_clock::now();
  ::kill(pid, SIGTERM);
  ChildRun r = finish(pid, errFile, t0);
  const double stopSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - tSignal).count();
  ASSERT_EQ(r.status, 143) << r.err;  // 128 + SIGTERM: it finished before the signal otherwise
  EXPECT_LT(stopSeconds, 2.0);
  EXPECT_NE(r.err.find("checkpoint saved"), std::string::npos) << r.err;
  EXPECT_EQ(slurp(out), previous);

  std::vector<std::string> resumeArgs = common;
  resumeArgs.push_back("--resume");
  resumeArgs.push_back("--threads");
  resumeArgs.push_back("1");
  ChildRun killed = killAfterNextSave(resumeArgs, ckpt, errFile);
  ASSERT_EQ(killed.status, 128 + SIGKILL) << "finished before kill -9: " << killed.err;
  EXPECT_EQ(slurp(out), previous);  // never a partial output

  ChildRun done = prtBake(resumeArgs, dir);
  ASSERT_EQ(done.status, 0) << done.err;
  EXPECT_TRUE(slurp(out) == refBytes) << "output after kill -9 and resume differs";
  EXPECT_FALSE(fs::exists(ckpt));
}

TEST(CliResume, MismatchingCheckpointIsRefused) {
  fs::path dir = freshDir("cli_mismatch");
  // A private copy of the scene, to edit it between the runs.
  fs::copy_file(scenePath("cornell_open.gltf"), dir / "s.gltf");
  fs::copy_file(scenePath("cornell_open.bin"), dir / "cornell_open.bin");
  const std::string out = (dir / "b.glb").string();
  std::vector<std::string> args = {"bake", (dir / "s.gltf").string(), "-o", out, "--samples", "64", "-q"};
  ASSERT_EQ(prtBake(args, dir, "PRT_TEST_INTERRUPT_AFTER=10").status, 130);
  std::vector<std::string> other = args;
  other[5] = "128";
  other.push_back("--resume");
  ChildRun r = prtBake(other, dir);
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
  r = prtBake(args, dir);
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("scene geometry differs"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(out));
  // --resume without a checkpoint.
  fs::remove(out + ".prt-checkpoint");
  r = prtBake(args, dir);
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("no checkpoint to resume"), std::string::npos) << r.err;
}

// ---- The probe stage through `prt bake --probes`
// cornell_open (12.5 k vertices: 196 chunks per surface pass) with a probe lattice over it.
std::vector<std::string> probeBakeArgs(const std::string& glb, const std::string& vdb, int dims, int probeSamples) {
  const std::string d = std::to_string(dims);
  return {"bake", scenePath("cornell_open.gltf"), "-o", glb, "--probes", vdb, "--samples", "16", "--bands", "2",
          "--bounces", "1", "--probe-dims", d + "," + d + "," + d, "--probe-samples", std::to_string(probeSamples),
          "-q"};
}

std::vector<std::string> plus(std::vector<std::string> a, const std::vector<std::string>& extra) {
  a.insert(a.end(), extra.begin(), extra.end());
  return a;
}

TEST(CliResumeProbes, InterruptedInTheProbeStageResumesByteIdentical) {
  fs::path dir = freshDir("cli_probes");
  fs::create_directories(dir / "out");
  const std::string out = (dir / "out" / "b.glb").string(), vdb = (dir / "out" / "b.vdb").string();
  const std::string ckpt = out + ".prt-checkpoint";
  const std::vector<std::string> args = probeBakeArgs(out, vdb, 12, 64);  // 1728 probes, 27 chunks
  ASSERT_EQ(prtBake(probeBakeArgs((dir / "ref.glb").string(), (dir / "ref.vdb").string(), 12, 64), dir).status, 0);
  const std::string refGlb = slurp(dir / "ref.glb"), refVdb = slurp(dir / "ref.vdb");
  constexpr int kSurfaceChunks = 2 * 196;  // direct pass and one bounce
  uintmax_t sizeAt[2] = {0, 0};
  const int probeChunks[2] = {5, 20};
  for (int run = 0; run < 2; ++run) {
    SCOPED_TRACE(probeChunks[run]);
    const int after = kSurfaceChunks + probeChunks[run];
    ChildRun r = prtBake(args, dir, "PRT_TEST_INTERRUPT_AFTER=" + std::to_string(after));
    EXPECT_EQ(r.status, 130) << r.err;
    EXPECT_EQ(lines(r.err), 1) << r.err;
    EXPECT_NE(r.err.find("interrupted: checkpoint saved to " + ckpt + " (probe stage "), std::string::npos) << r.err;
    EXPECT_EQ(dirNames(dir / "out"), std::vector<std::string>{"b.glb.prt-checkpoint"});  // no output yet
    sizeAt[run] = fs::file_size(ckpt);
    ChildRun resumed = prtBake(plus(args, {"--resume", "--threads", "1"}), dir);
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
  fs::path dir = freshDir("cli_probes_mismatch");
  const std::string out = (dir / "b.glb").string(), vdb = (dir / "b.vdb").string();
  const std::vector<std::string> args = probeBakeArgs(out, vdb, 6, 64);
  ASSERT_EQ(prtBake(args, dir, "PRT_TEST_INTERRUPT_AFTER=394").status, 130);
  for (const auto& [other, what] : std::vector<std::pair<std::vector<std::string>, std::string>>{
           {probeBakeArgs(out, vdb, 6, 128), "probe samples 64 (checkpoint) vs 128 (now)"},
           {probeBakeArgs(out, vdb, 7, 64), "probe dims 6,6,6 (checkpoint) vs 7,7,7 (now)"},
           {plus(args, {"--probe-half"}), "probe half no (checkpoint) vs yes (now)"},
           {plus(args, {"--seed", "2"}), "seed 1 (checkpoint) vs 2 (now)"}}) {
    ChildRun r = prtBake(plus(other, {"--resume"}), dir);
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
  fs::path dir = freshDir("cli_probes_kill");
  fs::create_directories(dir / "out");
  const std::string out = (dir / "out" / "b.glb").string(), vdb = (dir / "out" / "b.vdb").string();
  const std::string ckpt = out + ".prt-checkpoint";
  // 8000 probes of 256 rays: several seconds on the 2-core development machine.
  const std::vector<std::string> args = probeBakeArgs(out, vdb, 20, 256);
  const auto tRef = std::chrono::steady_clock::now();
  ASSERT_EQ(prtBake(probeBakeArgs((dir / "ref.glb").string(), (dir / "ref.vdb").string(), 20, 256), dir).status, 0);
  // The signal goes a tenth of the reference bake's time into the probe stage (at most 0.3 s):
  // on a machine fast enough to bake it all in a fraction of a second it still lands.
  const double refSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - tRef).count();
  const auto waitInProbeStage = std::chrono::duration<double>(std::min(0.3, 0.1 * refSeconds));
  const std::string refGlb = slurp(dir / "ref.glb"), refVdb = slurp(dir / "ref.vdb");
  // The previous good outputs at the paths: some other bake.
  ASSERT_EQ(prtBake(probeBakeArgs(out, vdb, 3, 16), dir).status, 0);
  const std::string previousGlb = slurp(out), previousVdb = slurp(vdb);

  fs::path errFile = dir / "child_stderr.txt";
  auto t0 = std::chrono::steady_clock::now();
  pid_t pid = spawn(plus(args, {"--checkpoint-interval", "0"}), errFile);
  // With --checkpoint-interval 0 the first save is the finished surface stage: the probe
  // stage has begun once the file is there.
  for (int i = 0; i < 1000 && !fs::exists(ckpt); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(10));
  ASSERT_TRUE(fs::exists(ckpt)) << "the surface stage did not finish in 10 s";
  std::this_thread::sleep_for(waitInProbeStage);
  auto tSignal = std::chrono::steady_clock::now();
  ::kill(pid, SIGINT);
  ChildRun r = finish(pid, errFile, t0);
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
  ChildRun killed = killAfterNextSave(resumeArgs, ckpt, errFile);
  ASSERT_EQ(killed.status, 128 + SIGKILL) << "finished before kill -9: " << killed.err;
  EXPECT_EQ(slurp(out), previousGlb);  // never a partial output
  EXPECT_EQ(slurp(vdb), previousVdb);

  ChildRun done = prtBake(resumeArgs, dir);
  ASSERT_EQ(done.status, 0) << done.err;
  EXPECT_TRUE(slurp(out) == refGlb) << "the .glb after SIGINT, kill -9 and resume differs";
  EXPECT_TRUE(slurp(vdb) == refVdb) << "the .vdb after SIGINT, kill -9 and resume differs";
  EXPECT_FALSE(fs::exists(ckpt));
}

#if defined(__SANITIZE_ADDRESS__)
constexpr bool kAddressSanitizer = true;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
constexpr bool kAddressSanitizer = true;
#else
constexpr bool kAddressSanitizer = false;
#endif
#else
constexpr bool kAddressSanitizer = false;
#endif

TEST(CliMemory, RefusalWritesNothingAndEstimateBoundsThePeak) {
  fs::path dir = freshDir("cli_memory");
  fs::create_directories(dir / "out");
  const std::string out = (dir / "out" / "b.glb").string();
  ChildRun r = prtBake({"bake", scenePath("cornell_open.gltf"), "-o", out, "--max-memory", "1M"}, dir);
  EXPECT_EQ(r.status, 1);
  EXPECT_EQ(lines(r.err), 1) << r.err;
  EXPECT_NE(r.err.find("not enough memory"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("--max-memory"), std::string::npos) << r.err;
  EXPECT_TRUE(dirNames(dir / "out").empty());
  r = prtBake({"bake", scenePath("cornell_open.gltf"), "-o", out, "--max-memory", "lots"}, dir);
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("--max-memory lots"), std::string::npos) << r.err;

  // A moderate bake: the estimate printed is at least the measured peak, and not far above.
  r = prtBake({"bake", scenePath("cornell_open.gltf"), "-o", out, "--samples", "256"}, dir);
  ASSERT_EQ(r.status, 0) << r.err;
  std::smatch m;
  ASSERT_TRUE(std::regex_search(r.err, m, std::regex("memory: estimated ([0-9.]+) MiB, peak ([0-9.]+) MiB"))) << r.err;
  const double estimated = std::stod(m[1]), peak = std::stod(m[2]);
  // AddressSanitizer's shadow memory and quarantine add to every allocation; the estimate is for
  // the uninstrumented program (the Release suite checks it).
  if (kAddressSanitizer) GTEST_SKIP() << "peak under ASan is not the program's peak";
  EXPECT_GE(estimated, peak);
  EXPECT_LE(estimated, 2.0 * peak);
}

TEST(CliMemory, EstimateBoundsThePeakOfAProbeBake) {
  // The probe stage is the largest phase: at bands 4 the .vdb has 264 grids, each with a
  // 512 KiB OpenVDB node whatever the lattice's size, and 16³ points hold 3 KiB of transfer
  // each in the bake, the grid, its OpenVDB trees and the file read back.
  fs::path dir = freshDir("cli_memory_probes");
  ChildRun r = prtBake({"bake", scenePath("cornell_open.gltf"), "-o", (dir / "b.glb").string(), "--probes",
                        (dir / "b.vdb").string(), "--samples", "16", "--bounces", "1", "--bands", "4",
                        "--probe-dims", "16,16,16", "--probe-samples", "4"},
                       dir);
  ASSERT_EQ(r.status, 0) << r.err;
  std::smatch m;
  ASSERT_TRUE(std::regex_search(r.err, m,
                                std::regex("memory: estimated ([0-9.]+) MiB, peak ([0-9.]+) MiB \\(estimated by "
                                           "phase: surface ([0-9.]+) MiB, probes ([0-9.]+) MiB")))
      << r.err;
  const double estimated = std::stod(m[1]), peak = std::stod(m[2]), surface = std::stod(m[3]),
               probes = std::stod(m[4]);
  EXPECT_EQ(estimated, probes);  // the probe stage is the largest phase
  EXPECT_GT(probes, surface);
  if (kAddressSanitizer) GTEST_SKIP() << "peak under ASan is not the program's peak";
  EXPECT_GE(estimated, peak);
  EXPECT_LE(estimated, 2.0 * peak);
}

}  // namespace
}  // namespace prt
