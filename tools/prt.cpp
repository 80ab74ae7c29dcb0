// prt: bake precomputed radiance transfer, relight it, inspect it.
// Thin on purpose: parse the command line, call the libraries, report. Errors are caught once,
// here: bad input prints one line and exits 1; usage errors print usage and exit 2.
#include <unistd.h>

#include <array>
#include <cmath>
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

void runProbe(const ProbeArgs& a) {
  if (a.points.empty() == a.at.empty()) throw Error("give either --at X,Y,Z or --points IN.csv -o OUT.csv");
  if (!a.points.empty() && a.output.empty()) throw Error("--points needs -o OUT.csv");
  std::optional<AtomicFile> outFile;
  if (!a.output.empty()) outFile.emplace(a.output);
  ProbeGrid grid = readProbeGrid(a.file);
  sh::ShRgb light = tools::buildLight(a.light, grid.bands);
  std::vector<glm::vec3> relit = relightProbes(grid, light);
  auto finiteVec = [](const std::vector<double>& v, const char* what) {
    for (double x : v)
      if (!std::isfinite(x)) throw Error(cat(what, ": values must be finite"));
    return glm::vec3(float(v[0]), float(v[1]), float(v[2]));
  };
  if (!a.at.empty()) {
    glm::vec3 x = finiteVec(a.at, "--at");
    nlohmann::json j;
    j["position"] = {x.x, x.y, x.z};
    j["bands"] = grid.bands;
    glm::vec3 n;
    const glm::vec3* np = nullptr;
    if (!a.normal.empty()) {
      n = finiteVec(a.normal, "--normal");
      if (glm::length(n) == 0.0f) throw Error("--normal: must not be zero");
      n = glm::normalize(n);
      np = &n;
    }
    ProbeWeights w = probeWeights(grid, x, np);
    if (w.count == 0) throw Error(cat(a.file, ": point (", x.x, ", ", x.y, ", ", x.z, ") is outside the probe grid or has no valid probe around it"));
    sh::ShRgb c = interpolateRadiance(grid, relit, x, np);
    nlohmann::json coeffs = nlohmann::json::array();
    for (const glm::vec3& v : c.c) coeffs.push_back({v.r, v.g, v.b});
    j["radiance_sh"] = coeffs;
    nlohmann::json probes = nlohmann::json::array();
    for (int i = 0; i < w.count; ++i) {
      glm::ivec3 ijk = grid.coord[size_t(w.probe[size_t(i)])];
      probes.push_back({{"index", {ijk.x, ijk.y, ijk.z}}, {"weight", w.weight[size_t(i)]}});
    }
    j["probes"] = probes;
    if (np) {
      glm::vec3 e = sh::irradiance(c, n);
      j["normal"] = {n.x, n.y, n.z};
      j["irradiance"] = {e.r, e.g, e.b};
    }
    std::printf("%s\n", j.dump(2).c_str());
    return;
  }
  // --points IN.csv -o OUT.csv
  std::string text = readFile(a.points);
  std::istringstream in(text);
  std::string line;
  if (!std::getline(in, line)) throw Error(cat(a.points, ": empty file, expected a header x,y,z,nx,ny,nz"));
  if (!line.empty() && line.back() == '\r') line.pop_back();
  if (line != "x,y,z,nx,ny,nz") throw Error(cat(a.points, ": header is '", line, "', expected 'x,y,z,nx,ny,nz'"));
  std::ostringstream out;
  out << "x,y,z,nx,ny,nz,E_r,E_g,E_b\n";
  out.precision(9);
  for (int row = 2; std::getline(in, line); ++row) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty()) continue;
    std::array<float, 6> v{};
    std::istringstream ls(line);
    std::string cell;
    for (int k = 0; k < 6; ++k) {
      if (!std::getline(ls, cell, ',')) throw Error(cat(a.points, ": line ", row, ": expected 6 values"));
      char* end = nullptr;
      v[size_t(k)] = std::strtof(cell.c_str(), &end);
      if (end == cell.c_str() || !std::isfinite(v[size_t(k)]))
        throw Error(cat(a.points, ": line ", row, ": '", cell, "' is not a finite number"));
    }
    glm::vec3 x(v[0], v[1], v[2]), n(v[3], v[4], v[5]);
    if (glm::length(n) == 0.0f) throw Error(cat(a.points, ": line ", row, ": normal is zero"));
    n = glm::normalize(n);
    glm::vec3 e(0.0f);
    if (probeWeights(grid, x, &n).count > 0) e = sh::irradiance(interpolateRadiance(grid, relit, x, &n), n);
    out << v[0] << ',' << v[1] << ',' << v[2] << ',' << v[3] << ',' << v[4] << ',' << v[5] << ',' << e.r << ','
        << e.g << ',' << e.b << '\n';
  }
  writeFileAtomic(a.output, out.str());
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
  std::printf("  instances   %zu (%zu with transfer, %zu receivers)\n", scene.meshes.size(), baked, receivers);
  std::printf("  vertices    %zu\n  triangles   %zu\n", vertices, triangles);
  std::printf("  materials   %zu, textures %zu, cameras %zu, lights %zu\n", scene.materials.size(),
              scene.textures.size(), scene.cameras.size(), scene.lights.size());
  std::printf("  bounds      (%g, %g, %g) .. (%g, %g, %g)\n", scene.boundsMin.x, scene.boundsMin.y,
              scene.boundsMin.z, scene.boundsMax.x, scene.boundsMax.y, scene.boundsMax.z);
  if (scene.transferBands > 0) {
    std::printf("  transfer    %d bands (%d RGB coefficients per vertex)\n", scene.transferBands,
                scene.transferBands * scene.transferBands);
    if (!scene.bakeSettingsJson.empty()) std::printf("  bake        %s\n", scene.bakeSettingsJson.c_str());
  } else {
    std::printf("  transfer    none (not baked)\n");
  }
  for (const std::string& w : scene.warnings) std::printf("  warning     %s\n", w.c_str());
}

int runInfo(const std::vector<std::string>& files) {
  int status = 0;
  for (const std::string& f : files) {
    try {
      if (std::filesystem::path(f).extension() == ".vdb")
        std::printf("%s", describeProbeFile(f).c_str());
      else
        infoGlb(f);
    } catch (const Error& e) {
      std::fprintf(stderr, "prt: %s\n", e.what());
      status = 1;
    }
  }
  return status;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"prt: precomputed radiance transfer. Bake once, relight with a dot product."};
  app.require_subcommand(1);
  app.set_version_flag("--version", "prt 0.1.0");
  app.get_formatter()->column_width(34);

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
  bake->add_option("--probes", bakeArgs.probes, "Also bake a probe grid into this OpenVDB file (.vdb)");
  bake->add_option("--probe-spacing", bakeArgs.probeSpacing, "Probe spacing in world units (else --probe-dims)");
  bake->add_option("--probe-dims", bakeArgs.probeDims, "Probe counts X,Y,Z (default 16,16,16)")->delimiter(',')->expected(3);
  bake->add_option("--probe-bounds", bakeArgs.probeBounds, "Probe grid bounds MINX,MINY,MINZ,MAXX,MAXY,MAXZ (default: scene bounds)")
      ->delimiter(',')->expected(6);
  bake->add_option("--probe-samples", bakeArgs.probeSamples, "Sphere directions per probe")->capture_default_str();
  bake->add_flag("--probe-half", bakeArgs.probeHalf, "Store probe grids as 16-bit floats");
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
