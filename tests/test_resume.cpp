// Interruption, checkpoints and resume (bake/checkpoint.h), and the memory guard
// (bake/memory_estimate.h), in process through the library (through `prt bake`:
// test_cli_resume.cpp).
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

#include "harness.h"
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

std::string slurp(const fs::path& p) { return test::fileBytes(p); }

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

TEST(BakeResume, InterruptedAnywhereResumesToTheSameBits) {
  const Scene scene = resumeScene();
  const BakeSettings s = resumeSettings();
  const SurfaceTransfer ref = bakeSurface(scene, s);
  const uint64_t chunks = (2561 + 169 + 63) / 64;  // cavity + plane vertices, 64 per chunk
  const test::TempDir tmp("points");
  const fs::path dir = tmp.path();
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

TEST(BakeResume, TwoSidedSceneInterruptedAnywhereResumesToTheSameBits) {
  // The plane double-sided: its 169 back sides are vertices of the bake after the real ones
  // (chunks 43 .. 46 of the direct pass and of each bounce), and the fingerprint says so.
  Scene scene = resumeScene();
  Material two = scene.materials[0];
  two.doubleSided = true;
  scene.materials.push_back(two);
  scene.meshes[1].material = 1;
  const BakeSettings s = resumeSettings();
  const SurfaceTransfer ref = bakeSurface(scene, s);
  ASSERT_EQ(ref.perMesh[1].size(), 2u * 169 * 9);
  const uint64_t chunks = (2561 + 169 + 169 + 63) / 64;
  Fingerprint one, both;
  addSceneFingerprint(one, resumeScene());
  addSceneFingerprint(both, scene);
  EXPECT_EQ(both.entries.back(), std::make_pair(std::string("two-sided vertices"), std::string("169")));
  EXPECT_NE(one.entries.back().first, "two-sided vertices");
  const test::TempDir tmp("two-sided");
  for (uint64_t after : {chunks - 2, chunks + chunks - 1, 2 * chunks + 1}) {
    SCOPED_TRACE(::testing::Message() << "interrupt after " << after << " chunks");
    const std::string path = tmp.file("a.ckpt");
    bakeUntilInterrupted(scene, s, path, false, after, 1e-9);
    BakeSettings r = s;
    r.threads = 1;
    SurfaceTransfer t = bakeResumed(scene, r, path);
    EXPECT_TRUE(sameBits(ref.perMesh, t.perMesh));
    EXPECT_TRUE(sameBits(ref.perMeshLowerOrder, t.perMeshLowerOrder));
  }
}

TEST(BakeResume, InterruptedTwiceAndWithoutBouncesStillTheSameBits) {
  const Scene scene = resumeScene();
  for (int bounces : {0, 3}) {
    BakeSettings s = resumeSettings();
    s.bounces = bounces;
    s.keepLowerOrder = bounces > 0;
    SCOPED_TRACE(bounces);
    const SurfaceTransfer ref = bakeSurface(scene, s);
    const test::TempDir tmp("twice");
    const std::string path = tmp.file("a.ckpt");
    bakeUntilInterrupted(scene, s, path, false, 7, 1e-9);
    bakeUntilInterrupted(scene, s, path, true, 20, 0.0);  // the resumed bake interrupted again
    bakeUntilInterrupted(scene, s, path, true, 11, 1e-9);
    SurfaceTransfer t = bakeResumed(scene, s, path);
    EXPECT_TRUE(sameBits(ref.perMesh, t.perMesh));
    EXPECT_TRUE(sameBits(ref.perMeshLowerOrder, t.perMeshLowerOrder));
  }
}

TEST(BakeResume, FinishedSurfaceStageIsKeptForTheProbeStage) {
  // With keepLowerOrder (a probe bake follows) the finished surface stage is saved, so that a
  // bake interrupted in the probe stage resumes without redoing the surface.
  const Scene scene = resumeScene();
  const BakeSettings s = resumeSettings();
  const SurfaceTransfer ref = bakeSurface(scene, s);
  const test::TempDir tmp("done");
  const std::string path = tmp.file("a.ckpt");
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

TEST(BakeResume, TornTailOfTheLogIsDropped) {
  // A kill -9 or power cut in the middle of a save leaves a partial last record: resume keeps
  // what the last complete save committed and redoes the rest.
  const Scene scene = resumeScene();
  const BakeSettings s = resumeSettings();
  const SurfaceTransfer ref = bakeSurface(scene, s);
  const test::TempDir tmp("torn");
  const std::string path = tmp.file("a.ckpt");
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

TEST(BakeResume, CheckpointOfAnotherBakeIsRefusedNamingTheDifference) {
  const Scene scene = resumeScene();
  BakeSettings s = resumeSettings();
  const test::TempDir tmp("mismatch");
  const fs::path dir = tmp.path();
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
  Scene cutOut = scene;
  cutOut.materials[0].alphaMode = Material::AlphaMode::Mask;
  EXPECT_NE(messageFor(cutOut, s).find("scene materials differs"), std::string::npos);
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

TEST(BakeResume, NoCheckpointStillStopsOnInterrupt) {
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

TEST(BakeResumeProbes, InterruptedInTheProbeStageResumesToTheSameBitsAndFile) {
  const Scene scene = resumeScene();
  const BakeSettings s = resumeSettings();
  const ProbeSettings ps = resumeProbeSettings();
  const test::TempDir tmp("probes");
  const fs::path dir = tmp.path();
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

TEST(BakeResumeProbes, InterruptedTwiceInTheProbeStage) {
  const Scene scene = resumeScene();
  const BakeSettings s = resumeSettings();
  const ProbeSettings ps = resumeProbeSettings();
  const ProbeGrid ref = bakeBoth(scene, s, ps, nullptr);
  const test::TempDir tmp("probes_twice");
  const std::string path = tmp.file("a.ckpt");
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

TEST(BakeResumeProbes, CheckpointWithOtherProbeSettingsIsRefused) {
  const Scene scene = resumeScene();
  const BakeSettings s = resumeSettings();
  const ProbeSettings ps = resumeProbeSettings();
  const test::TempDir tmp("probes_mismatch");
  const std::string path = tmp.file("a.ckpt");
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

TEST(BakeResumeProbes, InterruptStopsWithinAProbe) {
  // Two probes of 2^24 rays each take seconds; the flag is polled per stream of 256 rays, so
  // the bake stops long before one probe is done, and saves no probe chunk.
  const Scene scene = resumeScene();
  ProbeSettings ps;
  ps.dims = glm::ivec3(2, 1, 1);
  ps.samples = 1 << 24;
  ps.bounces = 0;
  const test::TempDir tmp("probes_latency");
  const std::string path = tmp.file("a.ckpt");
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

TEST(BakeHasher, StreamingEqualsOneShotAndDetectsChanges) {
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
TEST(BakeMemory, ParsesSizes) {
  EXPECT_EQ(parseByteSize("8G", "--max-memory"), uint64_t(8) << 30);
  EXPECT_EQ(parseByteSize("500M", "--max-memory"), uint64_t(500) << 20);
  EXPECT_EQ(parseByteSize("1.5GiB", "--max-memory"), uint64_t(3) << 29);
  EXPECT_EQ(parseByteSize("64k", "--max-memory"), uint64_t(64) << 10);
  EXPECT_EQ(parseByteSize("12345", "--max-memory"), uint64_t(12345));
  for (const char* bad : {"", "G", "8X", "-1G", "0", "nan", "1e30T"})
    EXPECT_THROW(parseByteSize(bad, "--max-memory"), Error) << bad;
}

TEST(BakeMemory, PilotBoundsTheHitRecordsAndTheRefusalSuggestsAWayOut) {
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
    ASSERT_TRUE(std::regex_search(msg, m, std::regex("samples ([0-9]+)"))) << msg;
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

TEST(BakeMemory, APlacementCountsOnlyTheProbesTheBakeKeeps) {
  // A cavity in a lattice eight times its size: most points are open air far from its
  // surfaces, which the probe bake leaves out, so the bound that counts them all is loose.
  const Scene scene = test::makeScene({test::makeCavity(0.6, 20, 32)}, 0.7f);
  ProbeSettings p;
  p.dims = {24, 24, 24};
  p.boundsMin = glm::dvec3(-4.0);
  p.boundsMax = glm::dvec3(4.0);
  p.samples = 16;
  const ProbePlacement placed = placeProbes(scene, p);
  ProbeStats stats;
  (void)bakeProbes(scene, {}, p, &stats);
  // The placement the bake made, and bounds on what it kept.
  EXPECT_EQ(placed.points, stats.probes);
  EXPECT_EQ(placed.points - placed.baked, stats.outside);  // a cavity alone: no point deep in solid
  EXPECT_GE(placed.baked, stats.valid);
  EXPECT_GE(placed.activeBound, stats.active);
  EXPECT_GT(stats.valid, uint64_t(0));
  EXPECT_LT(placed.baked * 4, placed.points);
  EXPECT_GE(placed.leafBlocks, uint64_t(1));
  EXPECT_LE(placed.leafBlocks, uint64_t(27));  // 3³ blocks of 8³ cover 24³
  EXPECT_EQ(placed.lowerBlocks, uint64_t(1));

  BakeSettings s = resumeSettings();
  const MemoryEstimate worst = estimateBakeMemory(scene, s, &p, 1.0);
  const MemoryEstimate counted = estimateBakeMemory(scene, s, &p, 1.0, &placed);
  EXPECT_FALSE(worst.placement.has_value());
  ASSERT_TRUE(counted.placement.has_value());
  EXPECT_LT(counted.probes * 2, worst.probes);
  EXPECT_LT(counted.probePeak, worst.probePeak);
  EXPECT_EQ(counted.surfacePeak, worst.surfacePeak);
  // Every point baked and active, in every block: the bound itself.
  const ProbePlacement all{placed.points, placed.points, placed.points, 27, 1};
  const MemoryEstimate whole = estimateBakeMemory(scene, s, &p, 1.0, &all);
  EXPECT_EQ(whole.probePeak, worst.probePeak);
  EXPECT_EQ(whole.total, worst.total);
}

}  // namespace
}  // namespace prt
