// prt: bake precomputed radiance transfer, relight it, inspect it.
// Thin on purpose: parse the command line, call the libraries, report. Errors are caught once,
// here: bad input prints one line and exits 1; usage errors print usage and exit 2.
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <optional>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <sstream>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "light_options.h"
#include "render_command.h"
#include "prt/atomic_file.h"
#include "prt/bake/checkpoint.h"
#include "prt/bake/memory_estimate.h"
#include "prt/bake/probe_bake.h"
#include "prt/bake/surface_bake.h"
#include "prt/error.h"
#include "prt/light_rig.h"
#include "prt/progress.h"
#include "prt/probe_grid.h"
#include "prt/relight.h"
#include "prt/scene.h"

namespace {

using namespace prt;

void printWarnings(const Scene& scene, bool quiet) {
  if (quiet) return;
  for (const std::string& w : scene.warnings) std::fprintf(stderr, "prt: warning: %s\n", w.c_str());
}

// ---- prt bake
// Signals: the first SIGINT/SIGTERM asks the bake to stop (every stage, surface and probes,
// saves its checkpoint and unwinds to main); a second one exits at once without saving. Only
// async-signal-safe calls here.
void onSignal(int sig) {
  if (bake::interruptRequested()) {
    const char msg[] = "prt: interrupted again: stopping without saving\n";
    ssize_t ignored = ::write(STDERR_FILENO, msg, sizeof msg - 1);
    (void)ignored;
    ::_exit(128 + sig);
  }
  bake::requestInterrupt(sig);
}

// Installs the handlers for the lifetime of a bake and restores the previous ones after.
class SignalScope {
public:
  SignalScope() {
    struct sigaction sa{};
    sa.sa_handler = onSignal;
    sigemptyset(&sa.sa_mask);
    sa.sa_flags = SA_RESTART;
    sigaction(SIGINT, &sa, &oldInt_);
    sigaction(SIGTERM, &sa, &oldTerm_);
  }
  ~SignalScope() {
    sigaction(SIGINT, &oldInt_, nullptr);
    sigaction(SIGTERM, &oldTerm_, nullptr);
  }
  SignalScope(const SignalScope&) = delete;
  SignalScope& operator=(const SignalScope&) = delete;

private:
  struct sigaction oldInt_{}, oldTerm_{};
};

struct BakeArgs {
  std::string scene, output;
  std::string probes;  // optional .vdb
  double probeSpacing = 0.0;
  std::vector<int> probeDims;
  std::vector<double> probeBounds;
  int probeSamples = 1024;
  bool probeHalf = false;
  bake::BakeSettings settings;
  bool unshadowed = false;
  bool quiet = false;
  LoadOptions load;
  std::string checkpoint;          // default OUTPUT.prt-checkpoint
  double checkpointInterval = 60;  // seconds; 0 = only when interrupted
  bool resume = false;
  std::string maxMemory;
};

// What must match for a checkpoint to be resumed: the scene's content and every setting that
// changes the output bits (not --threads, not -q).
bake::Fingerprint bakeFingerprint(const Scene& scene, const BakeArgs& a, const bake::BakeSettings& s,
                                  const bake::ProbeSettings* ps) {
  bake::Fingerprint fp;
  fp.add("prt", "0.1.0");
  bake::addSceneFingerprint(fp, scene);
  fp.add("bands", std::to_string(s.bands));
  fp.add("samples", std::to_string(s.samples));
  fp.add("bounces", std::to_string(s.bounces));
  fp.add("seed", std::to_string(s.seed));
  fp.add("probes", ps ? "yes" : "no");
  if (ps) {
    bake::addProbeFingerprint(fp, *ps);
    fp.add("probe half", a.probeHalf ? "yes" : "no");  // the .vdb written from the same results
  }
  return fp;
}

// The test suite interrupts bakes at chosen points with PRT_TEST_INTERRUPT_AFTER=N (an
// interrupt once N chunks have finished in this run), as a user's Ctrl-C would.
uint64_t testInterruptAfter() {
  const char* v = std::getenv("PRT_TEST_INTERRUPT_AFTER");
  return v ? std::strtoull(v, nullptr, 10) : 0;
}

void runBake(const BakeArgs& a) {
  bake::BakeSettings s = a.settings;
  s.shadowed = !a.unshadowed;
  s.progress = !a.quiet && Progress::terminalDefault();
  bake::validate(s);
  AtomicFile probe(a.output);  // fail on an unwritable output before hours of work
  std::optional<AtomicFile> probeFile;
  bake::ProbeSettings ps;
  if (!a.probes.empty()) {
    probeFile.emplace(a.probes);
    ps.bands = s.bands;
    ps.samples = a.probeSamples;
    ps.bounces = s.shadowed ? s.bounces : 0;
    ps.seed = s.seed;
    ps.progress = s.progress;
    ps.threads = s.threads;
    ps.spacing = a.probeSpacing;
    if (!a.probeDims.empty()) ps.dims = glm::ivec3(a.probeDims[0], a.probeDims[1], a.probeDims[2]);
    if (a.probeSpacing == 0.0 && a.probeDims.empty()) ps.dims = glm::ivec3(16);
    if (!a.probeBounds.empty()) {
      ps.boundsMin = glm::dvec3(a.probeBounds[0], a.probeBounds[1], a.probeBounds[2]);
      ps.boundsMax = glm::dvec3(a.probeBounds[3], a.probeBounds[4], a.probeBounds[5]);
    }
    bake::validate(ps);
    if (!s.shadowed) throw Error("--probes needs a shadowed bake (drop --unshadowed)");
    s.keepLowerOrder = true;
  }

  if (!(a.checkpointInterval >= 0.0) || !std::isfinite(a.checkpointInterval))
    throw Error(cat("--checkpoint-interval ", a.checkpointInterval, ": must be 0 or more seconds"));
  if (a.resume && !s.shadowed) throw Error("--resume: an unshadowed bake has no checkpoint (it takes no rays)");
  std::optional<uint64_t> maxMemory;
  if (!a.maxMemory.empty()) maxMemory = bake::parseByteSize(a.maxMemory, "--max-memory");
  const bake::ProbeSettings* psp = a.probes.empty() ? nullptr : &ps;

  SignalScope signals;
  Scene scene = loadScene(a.scene, a.load);
  printWarnings(scene, a.quiet);

  // Memory guard: first without the hit records (before the BVH is built), then with the
  // bound the bake measures on a pilot of its own rays (BakeControl::checkMemory).
  std::optional<bake::MemoryLimit> limit = bake::memoryLimit(maxMemory);
  bake::MemoryEstimate estimate = bake::estimateBakeMemory(scene, s, psp, 0.0);
  if (limit) bake::checkMemory(estimate, *limit, scene, s, psp);

  std::optional<bake::Checkpoint> checkpoint;
  if (s.shadowed) {
    bake::CheckpointOptions co;
    co.path = a.checkpoint.empty() ? a.output + ".prt-checkpoint" : a.checkpoint;
    co.intervalSeconds = a.checkpointInterval;
    co.resume = a.resume;
    co.interruptAfterChunks = testInterruptAfter();
    checkpoint.emplace(co, bakeFingerprint(scene, a, s, psp));
  }
  bake::BakeControl control;
  control.checkpoint = checkpoint ? &*checkpoint : nullptr;
  control.checkMemory = [&](double share) {
    estimate = bake::estimateBakeMemory(scene, s, psp, share);
    if (limit) bake::checkMemory(estimate, *limit, scene, s, psp);
  };
  // Runs a stage; an interruption names the checkpoint and how far the bake got.
  auto runStage = [&](auto&& run) {
    try {
      return run();
    } catch (const Interrupted&) {
      if (!checkpoint) throw;
      throw Interrupted(cat("interrupted: checkpoint saved to ", checkpoint->path(), " (",
                            checkpoint->progressText(), "); rerun with --resume to continue"));
    }
  };
  bake::SurfaceTransfer result = runStage([&] { return bake::bakeSurface(scene, s, control); });
  std::string sceneName = std::filesystem::path(a.scene).filename().string();
  bake::ProbeStats probeStats;
  if (!a.probes.empty()) {
    if (result.perMeshLowerOrder.empty()) result.perMeshLowerOrder.assign(scene.meshes.size(), {});
    ProbeGrid grid = runStage([&] {
      return bake::bakeProbes(scene, result.perMeshLowerOrder, ps, &probeStats, checkpoint ? &*checkpoint : nullptr);
    });
    grid.info.scene = sceneName;
    writeProbeGrid(grid, a.probes, a.probeHalf);
  }
  for (size_t k = 0; k < scene.meshes.size(); ++k) {
    scene.meshes[k].transfer = std::move(result.perMesh[k]);
    scene.meshes[k].transferBands = scene.meshes[k].transfer.empty() ? 0 : s.bands;
  }
  scene.transferBands = s.bands;
  auto tWrite = std::chrono::steady_clock::now();
  writeBakedScene(a.scene, scene, bake::settingsJson(s, sceneName), a.output);
  double writeSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - tWrite).count();
  // The outputs are in place: the checkpoint has served.
  if (checkpoint) checkpoint->remove();

  if (a.quiet) return;
  const bake::BakeStats& st = result.stats;
  size_t receivers = 0;
  for (const MeshInstance& m : scene.meshes) receivers += m.receiverOnly;
  std::ostringstream stages;
  for (const bake::StageStats& stage : st.stages) stages << stage.name << " " << std::fixed
                                                         << std::setprecision(2) << stage.seconds << " s, ";
  double directSeconds = 0;
  for (const auto& stage : st.stages)
    if (stage.name == "direct") directSeconds = stage.seconds;
  std::fprintf(stderr,
               "prt bake: %s -> %s\n  %s vertices in %zu instances (%zu receivers skipped), %d bands, "
               "%d samples, %d bounces%s\n  %s rays (%s rays/s in the direct pass), %s hit records%s\n"
               "  time: %s write %.2f s; total %.2f s\n  memory: estimated %s, peak %s (estimated by phase: %s)\n",
               a.scene.c_str(), a.output.c_str(), formatCount(double(st.vertices)).c_str(),
               scene.meshes.size() - receivers, receivers, s.bands, s.samples, s.shadowed ? s.bounces : 0,
               s.shadowed ? "" : " (unshadowed)", formatCount(double(st.rays)).c_str(),
               formatCount(directSeconds > 0 ? double(st.rays) / directSeconds : 0.0).c_str(),
               formatCount(double(st.hitRecords)).c_str(), st.resumed ? "; resumed from the checkpoint" : "",
               stages.str().c_str(), writeSeconds, st.seconds + writeSeconds, formatBytes(estimate.total).c_str(),
               formatBytes(peakMemoryBytes()).c_str(), estimate.phases().c_str());
  for (const std::string& line : describeReceivers(scene)) std::fprintf(stderr, "  receiver %s\n", line.c_str());
  if (a.probes.empty()) return;
  const std::string restored =
      probeStats.restored ? cat("; ", formatCount(double(probeStats.restored)), " restored from the checkpoint") : "";
  std::fprintf(stderr,
               "  probes: %s lattice points, %s active, %s inside geometry, %s moved out; %s rays in %.2f s "
               "(%s probes/s, %s rays/s)%s -> %s\n",
               formatCount(double(probeStats.probes)).c_str(), formatCount(double(probeStats.active)).c_str(),
               formatCount(double(probeStats.invalid)).c_str(), formatCount(double(probeStats.moved)).c_str(),
               formatCount(double(probeStats.rays)).c_str(), probeStats.seconds,
               formatCount(double(probeStats.probes - probeStats.restored) / std::max(probeStats.seconds, 1e-9)).c_str(),
               formatCount(probeStats.rays / std::max(probeStats.seconds, 1e-9)).c_str(), restored.c_str(),
               a.probes.c_str());
}

// ---- prt probe
struct ProbeArgs {
  std::string file, points, output;
  std::vector<double> at, normal;
  tools::LightOptions light;
};

// What prt probe reports at one point: the incident radiance SH as the renderer lights a
// receiver there (receiverRadiance: the probes, or the unoccluded light where none applies),
// and where the point lies.
struct ProbeQuery {
  const ProbeGrid& grid;
  const std::vector<glm::vec3>& relit;
  const sh::ShRgb& light;
  sh::ShRgb radiance(const glm::vec3& x, const glm::vec3* n, ProbeCover& cover) const {
    return receiverRadiance(grid, relit, light, x, n, &cover);
  }
};

glm::vec3 finiteVec3(const std::vector<double>& v, const char* what) {
  for (double x : v)
    if (!std::isfinite(x)) throw Error(cat(what, ": values must be finite"));
  return glm::vec3(float(v[0]), float(v[1]), float(v[2]));
}

void probeAt(const ProbeArgs& a, const ProbeQuery& q) {
  const glm::vec3 x = finiteVec3(a.at, "--at");
  nlohmann::json j;
  j["position"] = {x.x, x.y, x.z};
  j["bands"] = q.grid.bands;
  glm::vec3 n;
  const glm::vec3* np = nullptr;
  if (!a.normal.empty()) {
    n = finiteVec3(a.normal, "--normal");
    if (glm::length(n) == 0.0f) throw Error("--normal: must not be zero");
    n = glm::normalize(n);
    np = &n;
  }
  const ProbeWeights w = probeWeights(q.grid, x, np);
  const ProbeCover cover = w.cover;
  const sh::ShRgb c = receiverRadiance(q.grid, q.relit, q.light, w);
  j["status"] = probeCoverName(cover);
  nlohmann::json coeffs = nlohmann::json::array();
  for (const glm::vec3& v : c.c) coeffs.push_back({v.r, v.g, v.b});
  j["radiance_sh"] = coeffs;
  nlohmann::json probes = nlohmann::json::array();
  for (int i = 0; i < w.count; ++i) {
    glm::ivec3 ijk = q.grid.coord[size_t(w.probe[size_t(i)])];
    probes.push_back({{"index", {ijk.x, ijk.y, ijk.z}}, {"weight", w.weight[size_t(i)]}});
  }
  j["probes"] = probes;
  // The unoccluded light's share of radiance_sh: 1 outside, 0 within the domain (docs/probes.md).
  j["light_share"] = w.count == 0 ? 1.0f : w.fade;
  if (np) {
    glm::vec3 e = sh::irradiance(c, n);
    j["normal"] = {n.x, n.y, n.z};
    j["irradiance"] = {e.r, e.g, e.b};
  }
  if (w.count == 0)
    std::fprintf(stderr, "prt: warning: (%g, %g, %g) is %s: reporting the unoccluded light, as the renderer does\n",
                 x.x, x.y, x.z, cover == ProbeCover::Outside ? "outside the probe grid" : "in a cell with no valid probe");
  else if (cover == ProbeCover::Fade)
    std::fprintf(stderr,
                 "prt: warning: (%g, %g, %g) is beyond the probe grid's domain: reporting its nearest probes blended "
                 "with the unoccluded light (light share %.3g), as the renderer does\n",
                 x.x, x.y, x.z, w.fade);
  std::printf("%s\n", j.dump(2).c_str());
}

// Splits one CSV line at commas, RFC 4180 quoting: a field in double quotes may hold commas,
// and "" inside it is one quote; the quotes are removed. nullopt: a quoted field is not closed
// on its line (fields spanning lines are not supported).
std::optional<std::vector<std::string>> csvFields(const std::string& line) {
  std::vector<std::string> out(1);
  bool quoted = false;
  for (size_t i = 0; i < line.size(); ++i) {
    const char c = line[i];
    if (quoted) {
      if (c != '"')
        out.back() += c;
      else if (i + 1 < line.size() && line[i + 1] == '"')
        out.back() += '"', ++i;
      else
        quoted = false;
    } else if (c == '"') {
      quoted = true;
    } else if (c == ',') {
      out.emplace_back();
    } else {
      out.back() += c;
    }
  }
  if (quoted) return std::nullopt;
  return out;
}

// The CSV text of --points -o: each input row repeated verbatim (its own text, not re-printed
// numbers), then E_r,E_g,E_b and the status. Throws "FILE:LINE: problem" on a malformed row.
std::string probePointsCsv(const std::string& path, const ProbeQuery& q) {
  const std::string text = readFile(path);
  std::istringstream in(text);
  std::string line;
  auto chomp = [&] {
    if (!line.empty() && line.back() == '\r') line.pop_back();
  };
  if (!std::getline(in, line)) throw Error(cat(path, ":1: empty file, expected a header x,y,z,nx,ny,nz"));
  chomp();
  const std::optional<std::vector<std::string>> headerFields = csvFields(line);
  if (!headerFields) throw Error(cat(path, ":1: a quoted field is not closed on its line"));
  const std::vector<std::string>& header = *headerFields;
  const std::vector<std::string> expected{"x", "y", "z", "nx", "ny", "nz"};
  if (header.size() < 6 || !std::equal(expected.begin(), expected.end(), header.begin()))
    throw Error(cat(path, ":1: header is '", line, "', expected it to start with x,y,z,nx,ny,nz"));
  std::string out = line + ",E_r,E_g,E_b,status\n";
  int outside = 0;
  for (int row = 2; std::getline(in, line); ++row) {
    chomp();
    if (line.empty()) continue;
    const std::optional<std::vector<std::string>> fields = csvFields(line);
    if (!fields) throw Error(cat(path, ":", row, ": a quoted field is not closed on its line"));
    const std::vector<std::string>& f = *fields;
    if (f.size() != header.size())
      throw Error(cat(path, ":", row, ": ", f.size(), " fields, the header has ", header.size()));
    std::array<float, 6> v{};
    for (size_t k = 0; k < 6; ++k) {
      char* end = nullptr;
      const char* begin = f[k].c_str();
      v[k] = std::strtof(begin, &end);
      while (end && (*end == ' ' || *end == '\t')) ++end;
      if (end == begin || *end != '\0' || !std::isfinite(v[k]))
        throw Error(cat(path, ":", row, ": ", header[k], " '", f[k], "' is not a finite number"));
    }
    const glm::vec3 x(v[0], v[1], v[2]);
    glm::vec3 n(v[3], v[4], v[5]);
    if (glm::length(n) == 0.0f) throw Error(cat(path, ":", row, ": the normal is zero"));
    n = glm::normalize(n);
    ProbeCover cover;
    const glm::vec3 e = sh::irradiance(q.radiance(x, &n, cover), n);
    outside += cover == ProbeCover::Outside || cover == ProbeCover::NoValidProbe || cover == ProbeCover::Fade;
    out += cat(line, ",", std::setprecision(9), e.r, ",", e.g, ",", e.b, ",", probeCoverName(cover), "\n");
  }
  if (outside)
    std::fprintf(stderr, "prt: warning: %s: %d points beyond the probe grid's domain or without a valid probe got "
                 "the unoccluded light, in whole or in part (status column)\n", path.c_str(), outside);
  return out;
}

void runProbe(const ProbeArgs& a) {
  if (a.points.empty() == a.at.empty()) throw Error("give either --at X,Y,Z or --points IN.csv -o OUT.csv");
  if (!a.points.empty() && a.output.empty()) throw Error("--points needs -o OUT.csv");
  if (!a.output.empty() && a.points.empty()) throw Error("-o goes with --points (--at prints JSON)");
  if (!a.normal.empty() && a.at.empty()) throw Error("--normal goes with --at (--points has its own normals)");
  std::optional<AtomicFile> outFile;
  if (!a.output.empty()) outFile.emplace(a.output);
  const ProbeGrid grid = readProbeGrid(a.file);
  const sh::ShRgb light = sh::resize(tools::buildLight(a.light, grid.bands), grid.bands);
  const std::vector<glm::vec3> relit = relightProbes(grid, light);
  const ProbeQuery q{grid, relit, light};
  if (!a.at.empty()) return probeAt(a, q);
  writeFileAtomic(a.output, probePointsCsv(a.points, q));
}

// ---- prt relight
struct RelightArgs {
  std::string baked, output, csv;
  tools::LightOptions light;
  bool quiet = false;
};

void writeCsv(const std::string& path, const Scene& scene, const std::vector<std::vector<glm::vec3>>& radiance) {
  AtomicFile file(path);
  {
    std::ofstream out(file.tempPath());
    if (!out) throw Error(cat(path, ": cannot write"));
    out << "node,primitive,vertex,px,py,pz,nx,ny,nz,r,g,b\n";
    out.precision(9);
    for (size_t k = 0; k < scene.meshes.size(); ++k) {
      const MeshInstance& m = scene.meshes[k];
      for (size_t v = 0; v < radiance[k].size(); ++v) {
        const glm::vec3 &p = m.positions[v], &n = m.normals[v], &c = radiance[k][v];
        out << m.node << ',' << m.primitive << ',' << v << ',' << p.x << ',' << p.y << ',' << p.z << ','
            << n.x << ',' << n.y << ',' << n.z << ',' << c.r << ',' << c.g << ',' << c.b << '\n';
      }
    }
    if (!out.flush()) throw Error(cat(path, ": cannot write"));
  }
  file.commit();
}

void runRelight(const RelightArgs& a) {
  AtomicFile probe(a.output);
  Scene scene = loadScene(a.baked);
  printWarnings(scene, a.quiet);
  if (scene.transferBands == 0) throw Error(cat(a.baked, ": holds no baked transfer (run prt bake first)"));
  sh::ShRgb light = tools::buildLight(a.light, scene.transferBands);
  std::vector<std::vector<glm::vec3>> radiance = relightVertices(scene, light);
  if (!a.csv.empty()) AtomicFile csvProbe(a.csv);
  writeLitScene(a.baked, scene, radiance, a.output);
  if (!a.csv.empty()) writeCsv(a.csv, scene, radiance);
  if (a.quiet) return;
  size_t vertices = 0;
  glm::vec3 sum(0.0f);
  for (const auto& r : radiance)
    for (const glm::vec3& c : r) {
      sum += c;
      ++vertices;
    }
  glm::vec3 mean = vertices ? sum / float(vertices) : glm::vec3(0);
  std::string lighting = a.light.rig.empty() ? std::string() : cat(", lit by ", a.light.rig, " at frame ", a.light.frame);
  std::fprintf(stderr, "prt relight: %s -> %s%s%s\n  %zu vertices, %d bands%s, mean exitant radiance (%.4g, %.4g, %.4g)\n",
               a.baked.c_str(), a.output.c_str(), a.csv.empty() ? "" : " + ", a.csv.c_str(), vertices,
               scene.transferBands, lighting.c_str(), mean.r, mean.g, mean.b);
}

// ---- prt light
struct LightArgs {
  std::string output;
  int bands = 3;
  tools::LightOptions light;
};

void runLight(const LightArgs& a) {
  if (a.bands < 1 || a.bands > sh::kMaxBands) throw Error(cat("--bands ", a.bands, ": must be between 1 and ", sh::kMaxBands));
  AtomicFile probe(a.output);
  LightRig rig = tools::buildStillRig(a.light);
  sh::ShRgb light = rig.evaluate(a.light.frame, a.bands);
  nlohmann::json j;
  j["bands"] = a.bands;
  j["convention"] = "real orthonormal SH, no Condon-Shortley phase, index l(l+1)+m, glTF axes (+Y up)";
  j["quantity"] = "radiance";
  j["window"] = sh::windowName(rig.window);
  j["rig"] = a.light.rig;
  j["frame"] = a.light.frame;
  j["lights"] = rig.lights.size();
  // The shortcut environment's map and rotation (for a rig, its file says).
  const bool shortcutEnv = a.light.rig.empty() && !a.light.env.empty();
  j["env"] = shortcutEnv ? a.light.env : "";
  j["env_rotate_deg"] = shortcutEnv ? rig.lights[0].rotation.scalarAt(a.light.frame) : 0.0;
  nlohmann::json coeffs = nlohmann::json::array();
  for (const glm::vec3& c : light.c) coeffs.push_back({c.r, c.g, c.b});
  j["coefficients"] = coeffs;
  writeFileAtomic(a.output, j.dump(2) + "\n");
}

// ---- prt info
void infoGlb(const std::string& path) {
  Scene scene = loadScene(path);
  size_t vertices = 0, triangles = 0, receivers = 0, baked = 0;
  for (const MeshInstance& m : scene.meshes) {
    vertices += m.vertexCount();
    triangles += m.triangleCount();
    receivers += m.receiverOnly;
    baked += m.transferBands > 0;
  }
  std::printf("%s: glTF scene\n", path.c_str());
  std::printf("  file        %s on disk\n", formatBytes(std::filesystem::file_size(path)).c_str());
  std::printf("  instances   %zu (%zu with transfer, %zu receivers)\n", scene.meshes.size(), baked, receivers);
  for (const std::string& line : describeReceivers(scene)) std::printf("  receiver    %s\n", line.c_str());
  std::printf("  vertices    %zu\n  triangles   %zu\n", vertices, triangles);
  std::printf("  materials   %zu, textures %zu, cameras %zu, lights %zu\n", scene.materials.size(),
              scene.textures.size(), scene.cameras.size(), scene.lights.size());
  for (size_t k = 0; k < scene.cameras.size(); ++k) {
    const Camera& c = scene.cameras[k];
    std::printf("  camera %zu    '%s', %s\n", k, c.name.c_str(),
                c.perspective ? cat("perspective, yfov ", c.yfov, " rad").c_str() : "orthographic");
  }
  for (const Animation& an : scene.animations) {
    double end = 0.0;
    for (const AnimationChannel& ch : an.channels) end = std::max(end, ch.times.back());
    std::printf("  animation   '%s', %zu channels, %g s\n", an.name.c_str(), an.channels.size(), end);
  }
  std::printf("  bounds      (%g, %g, %g) .. (%g, %g, %g)\n", scene.boundsMin.x, scene.boundsMin.y,
              scene.boundsMin.z, scene.boundsMax.x, scene.boundsMax.y, scene.boundsMax.z);
  // The memory figures come from the bake's own estimate (the one --max-memory checks).
  const bake::BakeSettings defaults;
  const bake::MemoryEstimate loaded = bake::estimateBakeMemory(scene, defaults, nullptr, 1.0);
  std::printf("  memory      %s when loaded (geometry, transfer, textures); baking it with the defaults "
              "(%d bands, %d samples, %d bounces) needs at most %s\n",
              formatBytes(loaded.scene).c_str(), defaults.bands, defaults.samples, defaults.bounces,
              formatBytes(loaded.total).c_str());
  if (scene.transferBands > 0) {
    std::printf("  transfer    %d bands (%d RGB coefficients per vertex)\n", scene.transferBands,
                scene.transferBands * scene.transferBands);
    if (!scene.bakeSettingsJson.empty()) std::printf("  bake        %s\n", scene.bakeSettingsJson.c_str());
  } else {
    std::printf("  transfer    none (not baked)\n");
  }
  for (const std::string& w : scene.warnings) std::printf("  warning     %s\n", w.c_str());
}

enum class FileKind { Gltf, ProbeGrid, Other };

// What a file is, from its first bytes (then its extension); `what` names other kinds.
FileKind sniffFile(const std::string& path, std::string& what) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error(cat(path, ": cannot read (", std::strerror(errno), ")"));
  char head[16] = {};
  in.read(head, sizeof head);
  const std::string h(head, size_t(in.gcount()));
  const std::string ext = std::filesystem::path(path).extension().string();
  if (h.compare(0, 8, std::string(" BDV\0\0\0\0", 8)) == 0) return FileKind::ProbeGrid;  // OpenVDB's int64 magic
  const size_t text = h.compare(0, 3, "\xEF\xBB\xBF") == 0 ? 3 : 0;    // UTF-8 byte order mark
  const size_t first = h.find_first_not_of(" \t\r\n", text);
  const bool json = first != std::string::npos && h[first] == '{';
  if (h.compare(0, 4, "glTF") == 0 || (json && ext != ".json")) return FileKind::Gltf;
  // The extension claims a kind: let its reader say what is wrong with the file.
  if (ext == ".vdb") return FileKind::ProbeGrid;
  if (ext == ".gltf" || ext == ".glb") return FileKind::Gltf;
  what = json                                  ? "JSON (a light rig or `prt light` output?)"
         : h.compare(0, 2, "#?") == 0          ? "a Radiance HDR image"
         : h.compare(0, 4, "v/1\x01") == 0     ? "an OpenEXR image"
         : h.compare(0, 4, "\x89PNG") == 0     ? "a PNG image"
         : h.compare(0, 3, "\xFF\xD8\xFF") == 0 ? "a JPEG image"
         : h.empty()                           ? "empty"
                                               : "of an unknown kind";
  return FileKind::Other;
}

int runInfo(const std::vector<std::string>& files) {
  int status = 0;
  for (const std::string& f : files) {
    try {
      std::string what;
      switch (sniffFile(f, what)) {
        case FileKind::ProbeGrid: std::printf("%s", describeProbeFile(f).c_str()); break;
        case FileKind::Gltf: infoGlb(f); break;
        case FileKind::Other:
          throw Error(cat(f, ": not a glTF scene (.gltf, .glb) or a probe grid (.vdb): the file is ", what));
      }
    } catch (const Error& e) {
      std::fprintf(stderr, "prt: %s\n", e.what());
      status = 1;
    }
  }
  return status;
}

// Parses "A,B,..." into exactly `count` finite numbers (integers if `integers`) for option
// `name`; anything else is a usage error that names the option, the text and the expected form.
std::vector<double> parseNumberList(const std::string& name, const std::string& text, size_t count, bool integers,
                                    const char* form) {
  std::vector<double> out;
  std::istringstream in(text);
  std::string item;
  bool ok = !text.empty() && text.back() != ',';
  while (ok && std::getline(in, item, ',')) {
    char* end = nullptr;
    const double v = std::strtod(item.c_str(), &end);
    ok = !item.empty() && *end == '\0' && std::isfinite(v) && (!integers || (v == std::floor(v) && std::fabs(v) < 1e9));
    out.push_back(v);
  }
  if (!ok || out.size() != count) throw CLI::ValidationError(name, cat("'", text, "' is not ", form));
  return out;
}

// The probe options of prt bake: each needs --probes (never silently ignored), --probe-dims and
// --probe-spacing exclude each other, and malformed values are one-line usage errors.
void addProbeOptions(CLI::App& bake, BakeArgs& a) {
  CLI::Option* probes = bake.add_option("--probes", a.probes, "Also bake a probe grid into this OpenVDB file (.vdb)");
  CLI::Option* spacing = bake.add_option("--probe-spacing", a.probeSpacing, "Probe spacing in world units (else --probe-dims)")
                             ->check(CLI::PositiveNumber);
  CLI::Option* dims = bake.add_option_function<std::string>(
      "--probe-dims",
      [&a](const std::string& v) {
        std::vector<double> d = parseNumberList("--probe-dims", v, 3, true, "three integer counts X,Y,Z (e.g. 16,16,8)");
        a.probeDims.clear();
        for (double x : d) a.probeDims.push_back(int(x));
      },
      "Probe counts X,Y,Z (default 16,16,16)");
  CLI::Option* bounds = bake.add_option_function<std::string>(
      "--probe-bounds",
      [&a](const std::string& v) {
        a.probeBounds = parseNumberList("--probe-bounds", v, 6, false, "six numbers MINX,MINY,MINZ,MAXX,MAXY,MAXZ");
      },
      "Probe grid bounds MINX,MINY,MINZ,MAXX,MAXY,MAXZ (default: scene bounds, flat axes padded)");
  CLI::Option* samples = bake.add_option("--probe-samples", a.probeSamples, "Sphere directions per probe")->capture_default_str();
  CLI::Option* half = bake.add_flag("--probe-half", a.probeHalf, "Store probe grids as 16-bit floats");
  dims->excludes(spacing);
  for (CLI::Option* o : {spacing, dims, bounds, samples, half}) o->needs(probes);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"prt: precomputed radiance transfer. Bake once, relight with a dot product."};
  app.require_subcommand(1);
  app.set_version_flag("--version", "prt 0.1.0");
  app.get_formatter()->column_width(34);
  // Usage errors in one line (CLI11's default adds a second).
  app.failure_message([](const CLI::App*, const CLI::Error& e) {
    return cat("prt: ", e.what(), " (see --help)\n");
  });

  BakeArgs bakeArgs;
  CLI::App* bake = app.add_subcommand("bake", "Bake per-vertex SH transfer of a glTF scene into a .glb");
  bake->add_option("scene", bakeArgs.scene, "Input scene (.gltf or .glb)")->required();
  bake->add_option("-o,--output", bakeArgs.output, "Output baked scene (.glb)")->required();
  bake->add_option("--bands", bakeArgs.settings.bands, "SH bands (1-8; n bands = n² coefficients)")->capture_default_str();
  bake->add_option("--samples", bakeArgs.settings.samples, "Hemisphere directions per vertex")->capture_default_str();
  bake->add_option("--bounces", bakeArgs.settings.bounces, "Interreflection bounces (0 = direct shadowed only)")->capture_default_str();
  bake->add_flag("--unshadowed", bakeArgs.unshadowed, "Unshadowed transfer (closed form, no rays, no bounces)");
  bake->add_option("--seed", bakeArgs.settings.seed, "Random seed (same seed, same output, any thread count)")->capture_default_str();
  bake->add_option("--threads", bakeArgs.settings.threads, "Worker threads (0 = all cores)")->capture_default_str();
  bake->add_option("--receiver", bakeArgs.load.receiverNodes, "Node (name or index) baked as receiver only; repeatable");
  bake->add_flag("--allow-degenerate", bakeArgs.load.allowDegenerate, "Drop zero-area triangles with a warning instead of refusing");
  bake->add_flag("--allow-external-uris", bakeArgs.load.allowExternalUris,
                 "Read buffers and images outside the scene's folder (absolute paths, ..)");
  bake->add_flag("-q,--quiet", bakeArgs.quiet, "No progress bar, no summary");
  addProbeOptions(*bake, bakeArgs);
  bake->add_flag("--resume", bakeArgs.resume, "Continue an interrupted bake from its checkpoint (same scene and settings)");
  bake->add_option("--checkpoint", bakeArgs.checkpoint, "Checkpoint file (default: OUTPUT.prt-checkpoint)");
  bake->add_option("--checkpoint-interval", bakeArgs.checkpointInterval,
                   "Seconds between checkpoint saves (0 = only when interrupted)")->capture_default_str();
  bake->add_option("--max-memory", bakeArgs.maxMemory, "Refuse bakes estimated above this (e.g. 8G, 500M; default: available memory)");

  RelightArgs relightArgs;
  CLI::App* relight = app.add_subcommand("relight", "Relight a baked scene: per-vertex exitant radiance as COLOR_0");
  relight->add_option("baked", relightArgs.baked, "Baked scene (.glb from prt bake)")->required();
  relight->add_option("-o,--output", relightArgs.output, "Output lit scene (.glb, unlit vertex colours)")->required();
  relight->add_option("--csv", relightArgs.csv, "Also write per-vertex radiance as CSV");
  tools::addLightOptions(*relight, relightArgs.light);
  relight->add_flag("-q,--quiet", relightArgs.quiet, "No summary");

  LightArgs lightArgs;
  CLI::App* light = app.add_subcommand("light", "Project lighting to SH and write it as JSON");
  light->add_option("env", lightArgs.light.env, "Environment map (.exr or .hdr)");
  light->add_option("-o,--output", lightArgs.output, "Output JSON")->required();
  light->add_option("--bands", lightArgs.bands, "SH bands (1-8)")->capture_default_str();
  tools::addLightOptions(*light, lightArgs.light);

  ProbeArgs probeArgs;
  CLI::App* probeCmd = app.add_subcommand("probe", "Query a probe grid: incident radiance SH and irradiance at points");
  probeCmd->add_option("probes", probeArgs.file, "Probe grid (.vdb from prt bake --probes)")->required();
  probeCmd->add_option("--at", probeArgs.at, "Query point X,Y,Z (prints JSON)")->delimiter(',')->expected(3);
  probeCmd->add_option("--normal", probeArgs.normal, "Surface normal at the point: adds irradiance")->delimiter(',')->expected(3);
  probeCmd->add_option("--points", probeArgs.points, "CSV of points with header x,y,z,nx,ny,nz");
  probeCmd->add_option("-o,--output", probeArgs.output, "Output CSV for --points (adds E_r,E_g,E_b)");
  tools::addLightOptions(*probeCmd, probeArgs.light);

  CLI::App* renderCmd = tools::addRenderCommand(app);

  std::vector<std::string> infoFiles;
  CLI::App* info = app.add_subcommand("info", "Describe baked or input files");
  info->add_option("files", infoFiles, "Files to describe (.gltf, .glb, .vdb)")->required();

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  try {
    if (bake->parsed()) runBake(bakeArgs);
    if (relight->parsed()) runRelight(relightArgs);
    if (light->parsed()) runLight(lightArgs);
    if (probeCmd->parsed()) runProbe(probeArgs);
    if (renderCmd->parsed()) tools::runRenderCommand();
    if (info->parsed()) return runInfo(infoFiles);
  } catch (const Interrupted& e) {
    std::fprintf(stderr, "prt: %s\n", e.what());
    return 128 + (bake::interruptSignal() ? bake::interruptSignal() : SIGINT);
  } catch (const Error& e) {
    std::fprintf(stderr, "prt: %s\n", e.what());
    return 1;
  } catch (const std::bad_alloc&) {
    std::fprintf(stderr, "prt: out of memory\n");
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "prt: unexpected error: %s\n", e.what());
    return 1;
  }
  return 0;
}
