#include "relight_command.h"

#include <algorithm>
#include <cstdio>
#include <fstream>

#include "prt/atomic_file.h"
#include "prt/bake/frame_lighting.h"
#include "prt/bake/local_lights.h"
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
        out << m.node << ',' << m.primitive << ',' << v << ',' << p.x << ',' << p.y << ',' << p.z << ',' << n.x << ','
            << n.y << ',' << n.z << ',' << c.r << ',' << c.g << ',' << c.b << '\n';
      }
      for (size_t v = 0; v < back[k].size(); ++v) {
        const glm::vec3 &p = m.positions[v], n = -m.normals[v], &c = back[k][v];
        out << m.node << ',' << m.primitive << ',' << v << ',' << p.x << ',' << p.y << ',' << p.z << ',' << n.x << ','
            << n.y << ',' << n.z << ',' << c.r << ',' << c.g << ',' << c.b << '\n';
      }
    }
    if (!out.flush()) throw Error(cat(path, ": cannot write"));
  }
  file.commit();
}

// The lit vertices: the transfer's light, plus the vertex light where there is one.
struct Radiance {
  std::vector<std::vector<glm::vec3>> front, back;
};

Radiance relight(const Scene& scene, const bake::FrameLight& light) {
  const RigLighting& l = light.rig;
  if (!light.vertexLight)  // directSh is zero then: every light is in sh
    return {relightVertices(scene, l.sh), relightBackVertices(scene, l.sh)};
  return {relightVerticesSplit(scene, l.sh, l.directSh, light.vertexLight->front, false),
          relightVerticesSplit(scene, l.sh, l.directSh, light.vertexLight->back, true)};
}

// The emissive surfaces' own radiance added to theirs (sides the relight has).
void addEmission(Radiance& r, const bake::VertexEmission& e) {
  auto add = [](std::vector<std::vector<glm::vec3>>& to, const std::vector<std::vector<glm::vec3>>& from) {
    for (size_t k = 0; k < to.size() && k < from.size(); ++k)
      if (to[k].size() == from[k].size())
        for (size_t v = 0; v < to[k].size(); ++v) to[k][v] += from[k][v];
  };
  add(r.front, e.front);
  add(r.back, e.back);
}

// The summary's lines on the direct lights, the sky detail and the bounces.
void printLighting(const RelightArgs& a, const Scene& scene, const LightRig& rig, const bake::FrameLight& light,
                   const bake::FrameLighting& lighting) {
  const bake::FrameLightingStats& st = lighting.stats();
  const size_t lights = light.rig.direct.size();
  if (lights) {
    std::fprintf(stderr, "  direct lights (exact, with shadows and their bounces):\n");
    for (const std::string& line : describeDirectLights(light.rig, rig)) std::fprintf(stderr, "    %s\n", line.c_str());
    std::fprintf(stderr, "  shadow rays   %llu (%d per light and vertex) in %.2f s\n",
                 (unsigned long long)st.shadowRays, a.shadowSamples, st.shadowSeconds);
  }
  if (lighting.skyDetail())
    std::fprintf(stderr, "  sky detail    the light beyond %d bands over the same rays\n", scene.transferBands);
  const int bounces = scene.bakeRecord.value_or(BakeRecord{}).bounces;
  if (light.vertexLight && (lights || !light.local.empty() || lighting.skyDetail())) {
    if (lighting.usesOperator())
      std::fprintf(stderr, "  bounces       through the bake's bounce operator (%d bounces as baked) in %.3f s\n",
                   bounces, st.gatherSeconds);
    else if (lighting.gathers())
      std::fprintf(stderr, "  gather rays   %llu (%d per vertex, %d bounces as baked) in %.2f s\n",
                   (unsigned long long)st.gatherRays, a.gather.bounceSamples, bounces,
                   st.traceSeconds + st.gatherSeconds);
    else
      std::fprintf(stderr, "  %s\n",
                   bounces > 0 ? "bounces       through the SH transfer (--bounce-samples 0)"
                               : "bounces       none (baked without bounces)");
  }
  if (!light.local.empty()) {
    std::fprintf(stderr, "  lights inside the scene (exact, with shadows%s):\n",
                 light.vertexLight && lighting.gathers() && bounces > 0 ? " and their bounces" : "");
    for (const LocalLight& l : light.local) std::fprintf(stderr, "    %s\n", describeLocalLight(l).c_str());
    if (!lights)
      std::fprintf(stderr,
                   "  shadow rays   %llu (1 per point or spot light, %d per area light, per vertex) in %.2f s\n",
                   (unsigned long long)st.shadowRays, a.shadowSamples, st.shadowSeconds);
  }
  if (!lights && a.light.noDirect)
    std::fprintf(stderr, "  direct lights: none apart (--no-direct-lights: every light through the SH transfer)\n");
}

void printSummary(const RelightArgs& a, const Scene& scene, const Radiance& r) {
  size_t vertices = 0, backSides = 0;
  glm::vec3 sum(0.0f);
  for (const auto& side : r.front)
    for (const glm::vec3& c : side) {
      sum += c;
      ++vertices;
    }
  for (const auto& side : r.back) backSides += side.size();
  glm::vec3 mean = vertices ? sum / float(vertices) : glm::vec3(0);
  std::string rigText =
      a.light.rig.empty() ? std::string() : cat(", lit by ", a.light.rig, " at frame ", a.light.frame);
  const std::string sides = backSides ? cat(" (", backSides, " of them two-sided)") : std::string();
  std::fprintf(stderr,
               "prt relight: %s -> %s%s%s\n  %zu vertices%s, %d bands%s, mean exitant radiance (%.4g, %.4g, %.4g)\n",
               a.baked.c_str(), a.output.c_str(), a.csv.empty() ? "" : " + ", a.csv.c_str(), vertices, sides.c_str(),
               scene.transferBands, rigText.c_str(), mean.r, mean.g, mean.b);
}

}  // namespace

void addRelight(CLI::App& cmd, RelightArgs& a) {
  cmd.footer(
      "The radiance written is view-independent: every surface Lambertian with its diffuse albedo "
      "(baseColor·(1 − metallic)), no highlights, no normal or occlusion maps, no emission; prt render "
      "draws the glTF material in full (docs/render.md, \"Materials\").");
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
  addGatherOptions(cmd, a.gather);
  cmd.add_option("--threads", a.threads, "Threads for the shadow and bounce rays (0 = all cores)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cmd.add_flag("--no-scene-lights", a.noSceneLights,
               "Leave the scene's own lights (KHR_lights_punctual point, spot and directional lights) dark; by "
               "default they light it, and no other light is needed (docs/lights.md, \"Lights inside the scene\")");
  cmd.add_flag("-q,--quiet", a.quiet, "No summary");
}

int runRelight(const RelightArgs& a) {
  AtomicFile probe(a.output);
  // The emissive textures are read for the scene's emissive surfaces (they light it).
  LoadOptions load;
  load.shadingTextures = !a.noSceneLights;
  Scene scene = loadScene(a.baked, load);
  printWarnings(scene, a.quiet);
  // A bake whose every instance is a receiver has bands (its record's) but nothing to relight.
  const bool anyTransfer =
      std::any_of(scene.meshes.begin(), scene.meshes.end(), [](const MeshInstance& m) { return !m.transfer.empty(); });
  if (!anyTransfer) throw Error(cat(a.baked, ": holds no baked transfer (run prt bake first)"));
  const bool ownLights = !scene.lights.empty() || !bake::emissiveLightsOf(scene).empty();
  const LightRig rig = buildStillRig(a.light, !a.noSceneLights && ownLights);
  // The direct lights exactly at the vertices, with their bounces and the sky's detail
  // gathered over the bake's own rays (not with --no-direct-lights, nor for bakes without the
  // direct part).
  bake::FrameLightingSettings settings = frameLightingSettings(a.light, a.gather);
  settings.directAtVertices = true;
  settings.shadowSamples = a.shadowSamples;
  settings.threads = a.threads;
  settings.sceneLights = !a.noSceneLights;
  bake::FrameLighting lighting(scene, rig, settings);
  const bake::FrameLight light = lighting.at(a.light.frame);
  if (light.foldedLights && !a.quiet)
    std::fprintf(stderr,
                 "prt relight: warning: %s has no direct part (baked by an older prt): its %zu direct "
                 "light(s) are lit through SH, without exact shadows; bake again for them\n",
                 a.baked.c_str(), light.foldedLights);
  Radiance radiance = relight(scene, light);
  if (!a.noSceneLights) addEmission(radiance, bake::emissionAtVertices(scene));
  if (!a.csv.empty()) AtomicFile csvProbe(a.csv);
  writeLitScene(a.baked, scene, radiance.front, a.output, &radiance.back);
  if (!a.csv.empty()) writeCsv(a.csv, scene, radiance.front, radiance.back);
  if (a.quiet) return 0;
  printSummary(a, scene, radiance);
  printLighting(a, scene, rig, light, lighting);
  return 0;
}

}  // namespace prt::tools
