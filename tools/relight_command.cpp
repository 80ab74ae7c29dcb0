#include "relight_command.h"

#include <algorithm>
#include <cstdio>
#include <fstream>

#include "prt/atomic_file.h"
#include "prt/bake/direct_light.h"
#include "prt/error.h"
#include "prt/relight.h"
#include "prt/scene.h"
#include "scene_warnings.h"

namespace prt::tools {

namespace {

// One row per vertex; a double-sided vertex has a second row for its back side, with the
// normal negated, after its instance's front rows.
void writeCsv(const std::string& path, const Scene& scene, const std::vector<std::vector<glm::vec3>>& radiance,
              const std::vector<std::vector<glm::vec3>>& back) {
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
      for (size_t v = 0; v < back[k].size(); ++v) {
        const glm::vec3 &p = m.positions[v], n = -m.normals[v], &c = back[k][v];
        out << m.node << ',' << m.primitive << ',' << v << ',' << p.x << ',' << p.y << ',' << p.z << ','
            << n.x << ',' << n.y << ',' << n.z << ',' << c.r << ',' << c.g << ',' << c.b << '\n';
      }
    }
    if (!out.flush()) throw Error(cat(path, ": cannot write"));
  }
  file.commit();
}

}  // namespace

void addRelight(CLI::App& cmd, RelightArgs& a) {
  cmd.add_option("baked", a.baked, "Baked scene (.glb from prt bake)")->required();
  cmd.add_option("-o,--output", a.output,
                 "Output lit scene (.glb, or .gltf): radiance as _RADIANCE, and clamped to 0..1 as COLOR_0 on unlit "
                 "materials for viewers")
      ->required();
  cmd.add_option("--csv", a.csv, "Also write per-vertex radiance as CSV");
  addLightOptions(cmd, a.light);
  cmd.add_option("--shadow-samples", a.shadowSamples,
                 "Shadow rays per direct light (sun, small disk) and vertex, stratified over its disk")
      ->check(CLI::Range(1, 65536))
      ->capture_default_str();
  cmd.add_option("--bounce-samples", a.bounceSamples,
                 "Rays per vertex (the bake's own first rays) that gather the direct lights' bounced light and "
                 "the sky's light beyond the SH band limit; 0: both through the SH transfer instead")
      ->check(CLI::Range(0, 16777216))
      ->capture_default_str();
  cmd.add_flag("--no-sky-detail", a.noSkyDetail,
               "Light the sky (maps, residuals, uniform skies) through the SH transfer alone, without its light "
               "beyond the band limit gathered over those rays");
  cmd.add_option("--threads", a.threads, "Threads for the shadow and bounce rays (0 = all cores)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cmd.add_flag("-q,--quiet", a.quiet, "No summary");
}

int runRelight(const RelightArgs& a) {
  AtomicFile probe(a.output);
  Scene scene = loadScene(a.baked);
  printWarnings(scene, a.quiet);
  // A bake whose every instance is a receiver has bands (its record's) but nothing to relight.
  const bool anyTransfer =
      std::any_of(scene.meshes.begin(), scene.meshes.end(), [](const MeshInstance& m) { return !m.transfer.empty(); });
  if (!anyTransfer) throw Error(cat(a.baked, ": holds no baked transfer (run prt bake first)"));
  const LightRig rig = buildStillRig(a.light);
  RigLighting lighting = lightingAt(rig, a.light, a.light.frame, scene.transferBands);
  std::vector<std::vector<glm::vec3>> radiance, back;
  bake::DirectIrradiance direct;
  std::string bounceLine, skyLine;
  if (!lighting.direct.empty() && !hasDirectTransfer(scene)) {
    // A bake from before the split: the suns go through the whole transfer, as they did then.
    if (!a.quiet)
      std::fprintf(stderr, "prt relight: warning: %s has no direct part (baked by an older prt): its %zu direct "
                           "light(s) are lit through SH, without exact shadows; bake again for them\n",
                   a.baked.c_str(), lighting.direct.size());
    lighting.sh += lighting.directSh;
    lighting.directSh = sh::ShRgb(scene.transferBands);
    lighting.direct.clear();
  }
  const BakeRecord record = scene.bakeRecord.value_or(BakeRecord{});
  // The bake's own rays, traced again: they gather the direct lights' bounces and the sky's
  // detail beyond the band limit (docs/lights.md, "Sky detail"). Not with --no-direct-lights
  // (every light through SH, the behaviour before the split) nor for bakes without the direct
  // part (relightVerticesSplit needs it).
  const bool gather = a.bounceSamples > 0 && !a.light.noDirect && hasDirectTransfer(scene);
  const bool skyDetail = gather && !a.noSkyDetail;
  if (lighting.direct.empty() && !skyDetail) {  // directSh is zero then: every light is in sh
    radiance = relightVertices(scene, lighting.sh);
    back = relightBackVertices(scene, lighting.sh);
  } else {
    bake::ShadowSettings shadows;
    shadows.samples = a.shadowSamples;
    shadows.threads = a.threads;
    direct = bake::shadowedDirectIrradiance(scene, lighting.direct, shadows);
    sh::ShRgb directSh = lighting.directSh;
    if (gather && (skyDetail || record.bounces > 0)) {
      // Their bounces gathered over the bake's rays instead of through (t − t⁰) · directSh,
      // and the sky's detail Δ added to the direct light (it bounces with it).
      bake::BounceSettings bs;
      bs.samples = a.bounceSamples;
      bs.bounces = record.bounces;
      bs.seed = record.seed;
      bs.threads = a.threads;
      const bake::DirectBounce rays(scene, bs);
      double seconds = rays.traceSeconds();
      if (skyDetail) {
        const bake::DirectIrradiance delta = rays.skyDetail(rig.shRadiance(a.light.frame), lighting.sh);
        bake::addIrradiance(direct, delta);
        seconds += delta.seconds;
        skyLine = cat("sky detail    the light beyond ", scene.transferBands, " bands over the same rays");
      }
      if (record.bounces > 0) {
        const bake::DirectIrradiance bounced = rays.bounce(direct);
        bake::addIrradiance(direct, bounced);
        seconds += bounced.seconds;
      }
      char text[32];
      std::snprintf(text, sizeof text, "%.2f", seconds);
      bounceLine = cat("gather rays   ", rays.rays(), " (", a.bounceSamples, " per vertex, ", record.bounces,
                       " bounces as baked) in ", text, " s");
      directSh = sh::ShRgb(scene.transferBands);
    } else {
      bounceLine = record.bounces > 0 ? "bounces       through the SH transfer (--bounce-samples 0)"
                                      : "bounces       none (baked without bounces)";
    }
    radiance = relightVerticesSplit(scene, lighting.sh, directSh, direct.front, false);
    back = relightVerticesSplit(scene, lighting.sh, directSh, direct.back, true);
  }
  if (!a.csv.empty()) AtomicFile csvProbe(a.csv);
  writeLitScene(a.baked, scene, radiance, a.output, &back);
  if (!a.csv.empty()) writeCsv(a.csv, scene, radiance, back);
  if (a.quiet) return 0;
  size_t vertices = 0;
  glm::vec3 sum(0.0f);
  size_t backSides = 0;
  for (const auto& r : radiance)
    for (const glm::vec3& c : r) {
      sum += c;
      ++vertices;
    }
  for (const auto& r : back) backSides += r.size();
  glm::vec3 mean = vertices ? sum / float(vertices) : glm::vec3(0);
  std::string rigText = a.light.rig.empty() ? std::string() : cat(", lit by ", a.light.rig, " at frame ", a.light.frame);
  const std::string sides = backSides ? cat(" (", backSides, " of them two-sided)") : std::string();
  std::fprintf(stderr, "prt relight: %s -> %s%s%s\n  %zu vertices%s, %d bands%s, mean exitant radiance (%.4g, %.4g, %.4g)\n",
               a.baked.c_str(), a.output.c_str(), a.csv.empty() ? "" : " + ", a.csv.c_str(), vertices, sides.c_str(),
               scene.transferBands, rigText.c_str(), mean.r, mean.g, mean.b);
  if (!lighting.direct.empty()) {
    std::fprintf(stderr, "  direct lights (exact, with shadows and their bounces):\n");
    for (const std::string& line : describeDirectLights(lighting, rig)) std::fprintf(stderr, "    %s\n", line.c_str());
    std::fprintf(stderr, "  shadow rays   %llu (%d per light and vertex) in %.2f s\n", (unsigned long long)direct.rays,
                 a.shadowSamples, direct.seconds);
  }
  if (!skyLine.empty()) std::fprintf(stderr, "  %s\n", skyLine.c_str());
  if (!bounceLine.empty() && (!lighting.direct.empty() || !skyLine.empty())) std::fprintf(stderr, "  %s\n", bounceLine.c_str());
  if (lighting.direct.empty() && a.light.noDirect) {
    std::fprintf(stderr, "  direct lights: none apart (--no-direct-lights: every light through the SH transfer)\n");
  }
  return 0;
}

}  // namespace prt::tools
