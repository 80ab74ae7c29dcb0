// prt: bake precomputed radiance transfer, relight it, inspect it.
// Thin on purpose: parse the command line, call the libraries, report. Errors are caught once,
// here: bad input prints one line and exits 1; usage errors print usage and exit 2.
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <sstream>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "light_options.h"
#include "prt/atomic_file.h"
#include "prt/bake/surface_bake.h"
#include "prt/error.h"
#include "prt/progress.h"
#include "prt/relight.h"
#include "prt/scene.h"

namespace {

using namespace prt;

void printWarnings(const Scene& scene, bool quiet) {
  if (quiet) return;
  for (const std::string& w : scene.warnings) std::fprintf(stderr, "prt: warning: %s\n", w.c_str());
}

// ---- prt bake
struct BakeArgs {
  std::string scene, output;
  bake::BakeSettings settings;
  bool unshadowed = false;
  bool quiet = false;
  LoadOptions load;
};

void runBake(const BakeArgs& a) {
  bake::BakeSettings s = a.settings;
  s.shadowed = !a.unshadowed;
  s.progress = !a.quiet && Progress::terminalDefault();
  bake::validate(s);
  AtomicFile probe(a.output);  // fail on an unwritable output before hours of work

  Scene scene = loadScene(a.scene, a.load);
  printWarnings(scene, a.quiet);
  bake::SurfaceTransfer result = bake::bakeSurface(scene, s);
  for (size_t k = 0; k < scene.meshes.size(); ++k) {
    scene.meshes[k].transfer = std::move(result.perMesh[k]);
    scene.meshes[k].transferBands = scene.meshes[k].transfer.empty() ? 0 : s.bands;
  }
  scene.transferBands = s.bands;
  auto tWrite = std::chrono::steady_clock::now();
  writeBakedScene(a.scene, scene, bake::settingsJson(s, std::filesystem::path(a.scene).filename().string()),
                  a.output);
  double writeSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - tWrite).count();

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
               "%d samples, %d bounces%s\n  %s rays (%s rays/s in the direct pass), %s hit records\n"
               "  time: %s write %.2f s; total %.2f s; peak memory %s\n",
               a.scene.c_str(), a.output.c_str(), formatCount(double(st.vertices)).c_str(),
               scene.meshes.size() - receivers, receivers, s.bands, s.samples, s.shadowed ? s.bounces : 0,
               s.shadowed ? "" : " (unshadowed)", formatCount(double(st.rays)).c_str(),
               formatCount(directSeconds > 0 ? double(st.rays) / directSeconds : 0.0).c_str(),
               formatCount(double(st.hitRecords)).c_str(), stages.str().c_str(), writeSeconds,
               st.seconds + writeSeconds, formatBytes(peakMemoryBytes()).c_str());
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
  std::fprintf(stderr, "prt relight: %s -> %s%s%s\n  %zu vertices, %d bands, mean exitant radiance (%.4g, %.4g, %.4g)\n",
               a.baked.c_str(), a.output.c_str(), a.csv.empty() ? "" : " + ", a.csv.c_str(), vertices,
               scene.transferBands, mean.r, mean.g, mean.b);
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
  sh::ShRgb light = tools::buildLight(a.light, a.bands);
  nlohmann::json j;
  j["bands"] = a.bands;
  j["convention"] = "real orthonormal SH, no Condon-Shortley phase, index l(l+1)+m, glTF axes (+Y up)";
  j["quantity"] = "radiance";
  j["window"] = a.light.window;
  j["env"] = a.light.env;
  j["env_rotate_deg"] = a.light.envRotate;
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
  bake->add_flag("-q,--quiet", bakeArgs.quiet, "No progress bar, no summary");

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

  std::vector<std::string> infoFiles;
  CLI::App* info = app.add_subcommand("info", "Describe baked or input files");
  info->add_option("files", infoFiles, "Files to describe (.gltf, .glb)")->required();

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  try {
    if (bake->parsed()) runBake(bakeArgs);
    if (relight->parsed()) runRelight(relightArgs);
    if (light->parsed()) runLight(lightArgs);
    if (info->parsed()) return runInfo(infoFiles);
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
