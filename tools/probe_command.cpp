#include "probe_command.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <iomanip>
#include <optional>
#include <sstream>

#include <nlohmann/json.hpp>

#include "cli_checks.h"
#include "csv_fields.h"
#include "prt/atomic_file.h"
#include "prt/bake/bounce_operator.h"
#include "prt/bake/frame_lighting.h"
#include "prt/bake/local_lights.h"
#include "prt/error.h"
#include "prt/probe_grid.h"
#include "prt/relight.h"
#include "prt/scene.h"
#include "prt/sh.h"

namespace prt::tools {

namespace {

// What prt probe reports at one point: the incident radiance SH as the renderer lights a
// receiver there (receiverRadiance: the probes, or the unoccluded light where none applies),
// and where the point lies.
// With the baked scene (`scene`), the direct lights are apart: `relit` and `light` hold the sky
// and their bounced light (relightProbes' split) and `direct` is traced at each point.
struct ProbeQuery {
  const ProbeGrid& grid;
  const std::vector<glm::vec3>& relit;
  const sh::ShRgb& light;
  const bake::PointShadows* shadowRays = nullptr;  // the baked scene, built once per command
  const std::vector<DirectLight>* direct = nullptr;
  const std::vector<LocalLight>* local = nullptr;  // the lights inside the scene
  bake::ShadowSettings shadows;
  sh::ShRgb radiance(const glm::vec3& x, const glm::vec3* n, ProbeCover& cover) const {
    return receiverRadiance(grid, relit, light, x, n, &cover);
  }
  bool tracedSuns() const { return shadowRays && direct && !direct->empty(); }
  bool tracedLocal() const { return shadowRays && local && !local->empty(); }
  bool traced() const { return tracedSuns() || tracedLocal(); }
  /// Σ_k E_k c_k(n) s_k(x) at each point, the direct lights' and the lights inside the scene's
  /// (zero without traced lights).
  std::vector<glm::vec3> directIrradiance(const std::vector<glm::vec3>& x, const std::vector<glm::vec3>& n) const {
    std::vector<glm::vec3> e(x.size(), glm::vec3(0.0f));
    if (tracedSuns()) e = shadowRays->irradiance(x, n, *direct, shadows);
    if (tracedLocal()) {
      const std::vector<glm::vec3> l = shadowRays->irradiance(x, n, *local, shadows);
      for (size_t i = 0; i < e.size(); ++i) e[i] += l[i];
    }
    return e;
  }
};

// The three values of --at or --normal (checked finite by CLI11).
glm::vec3 vec3(const std::vector<double>& v) { return glm::vec3(float(v[0]), float(v[1]), float(v[2])); }

void probeAt(const ProbeArgs& a, const ProbeQuery& q) {
  const glm::vec3 x = vec3(a.at);
  nlohmann::json j;
  j["position"] = {x.x, x.y, x.z};
  j["bands"] = q.grid.bands;
  glm::vec3 n;
  const glm::vec3* np = nullptr;
  if (!a.normal.empty()) {
    n = vec3(a.normal);
    if (glm::length(n) == 0.0f) throw UsageError("--normal: must not be zero");
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
  if (q.tracedLocal()) {  // each light inside the scene, and its light for the normal given
    nlohmann::json lights = nlohmann::json::array();
    for (const LocalLight& l : *q.local) {
      nlohmann::json one = {{"label", l.label}};
      if (np) {
        const glm::vec3 e = q.shadowRays->irradiance({x}, {n}, std::vector<LocalLight>{l}, q.shadows)[0];
        one["irradiance"] = {e.r, e.g, e.b};
      }
      lights.push_back(one);
    }
    j["scene_lights"] = lights;
  }
  if (q.tracedSuns()) {  // each direct light's visible share for a surface facing it
    nlohmann::json lights = nlohmann::json::array();
    for (const DirectLight& l : *q.direct) {
      const glm::vec3 d(l.direction);
      const glm::vec3 e = q.shadowRays->irradiance({x}, {d}, {l}, q.shadows)[0];
      const double full = std::max({l.irradiance.r, l.irradiance.g, l.irradiance.b});
      const double share = full > 0.0 ? std::max({double(e.r), double(e.g), double(e.b)}) / full : 0.0;
      lights.push_back({{"direction", {d.x, d.y, d.z}},
                        {"radius_deg", glm::degrees(l.radius)},
                        {"irradiance", {l.irradiance.r, l.irradiance.g, l.irradiance.b}},
                        {"visible_share", share}});
    }
    j["direct_lights"] = lights;
  }
  if (np) {
    const glm::vec3 direct = q.directIrradiance({x}, {n})[0];
    glm::vec3 e = sh::irradiance(c, n) + direct;
    j["normal"] = {n.x, n.y, n.z};
    j["irradiance"] = {e.r, e.g, e.b};
    if (q.traced()) j["direct_irradiance"] = {direct.r, direct.g, direct.b};
  }
  if (w.count == 0)
    std::fprintf(stderr, "prt: warning: (%g, %g, %g) is %s: reporting the unoccluded light, as the renderer does\n",
                 x.x, x.y, x.z,
                 cover == ProbeCover::Outside ? "outside the probe grid" : "in a cell with no valid probe");
  else if (cover == ProbeCover::Fade)
    std::fprintf(stderr,
                 "prt: warning: (%g, %g, %g) is beyond the probe grid's domain: reporting its nearest probes blended "
                 "with the unoccluded light (light share %.3g), as the renderer does\n",
                 x.x, x.y, x.z, w.fade);
  std::printf("%s\n", j.dump(2).c_str());
}

// Splits one CSV line at commas, RFC 4180 quoting: a field in double quotes may hold commas,
// and "" inside it is one quote; the quotes are removed. nullopt: a quoted field is not closed

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
  std::vector<std::string> rows;
  std::vector<glm::vec3> xs, ns;
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
    rows.push_back(line);
    xs.push_back(x);
    ns.push_back(glm::normalize(n));
  }
  const std::vector<glm::vec3> direct = q.directIrradiance(xs, ns);
  for (size_t i = 0; i < rows.size(); ++i) {
    ProbeCover cover;
    const glm::vec3 e = sh::irradiance(q.radiance(xs[i], &ns[i], cover), ns[i]) + direct[i];
    outside += cover == ProbeCover::Outside || cover == ProbeCover::NoValidProbe || cover == ProbeCover::Fade;
    out += cat(rows[i], ",", std::setprecision(9), e.r, ",", e.g, ",", e.b, ",", probeCoverName(cover), "\n");
  }
  if (outside)
    std::fprintf(stderr,
                 "prt: warning: %s: %d points beyond the probe grid's domain or without a valid probe got "
                 "the unoccluded light, in whole or in part (status column)\n",
                 path.c_str(), outside);
  return out;
}

// How a query with the baked scene lights it (bake::FrameLighting, as `prt render` does): the
// rig's lights with the scene's own (its directional lights as suns, its lamps and emissive
// surfaces as lights inside the scene), and the bounces of the lights SH does not carry and the
// sky detail through the bake's operator where it has rows for this grid (docs/lights.md,
// "Probes through the operator"); without such rows nothing is gathered.
bake::FrameLightingSettings probeLighting(const ProbeArgs& a, const Scene& scene, const ProbeGrid& grid) {
  bake::FrameLightingSettings s = frameLightingSettings(a.light, GatherOptions{});
  s.sceneLights = !a.noSceneLights;
  s.threads = a.threads;
  s.shadowSamples = a.shadowSamples;
  s.vertexLight = false;  // the query traces the lights at its points
  const BounceOperator* op = scene.bounceOperator.get();
  const bool rows = op && op->probeRows.present() && grid.hasDirect();
  if (rows) bake::checkProbeRows(*op, grid, cat(a.scene, " (with ", a.file, ")"));
  if (!rows) s.gatherSamples = 0;
  return s;
}

}  // namespace

void addProbe(CLI::App& cmd, ProbeArgs& a) {
  cmd.add_option("probes", a.file, "Probe grid (.vdb from prt bake --probes)")->required();
  CLI::Option* at =
      cmd.add_option("--at", a.at, "Query point X,Y,Z (prints JSON)")->delimiter(',')->expected(3)->check(finite());
  CLI::Option* normal = cmd.add_option("--normal", a.normal, "Surface normal at the point: adds irradiance")
                            ->delimiter(',')
                            ->expected(3)
                            ->check(finite());
  CLI::Option* points = cmd.add_option("--points", a.points, "CSV of points with header x,y,z,nx,ny,nz");
  CLI::Option* output = cmd.add_option("-o,--output", a.output, "Output CSV for --points (adds E_r,E_g,E_b)");
  addLightOptions(cmd, a.light);
  CLI::Option* sceneFile =
      cmd.add_option("--scene", a.scene,
                     "The baked scene (.glb) of the grid: direct lights (suns, small disks) and the scene's own lights "
                     "(lamps, emissive surfaces) are then traced at each point with their shadows and added to the "
                     "irradiance, the probes giving the sky and bounced light (through the bake's bounce operator "
                     "where it has rows for this grid); without it the direct lights go through the probes' SH, "
                     "band-limited");
  cmd.add_flag("--no-scene-lights", a.noSceneLights,
               "With --scene: leave out the scene's own point, spot and directional lights and emissive surfaces, "
               "which light it by default (traced at each point, their bounces through the bake's operator)")
      ->needs(sceneFile);
  cmd.add_option("--shadow-samples", a.shadowSamples, "With --scene: shadow rays per direct light and point")
      ->check(CLI::Range(1, 65536))
      ->capture_default_str();
  cmd.add_option("--threads", a.threads, "With --scene: threads for the shadow rays (0 = all cores)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  // --at prints JSON; --points has its own normals and writes a CSV.
  at->excludes(points);
  normal->needs(at);
  points->needs(output);
  output->needs(points);
}

int runProbe(const ProbeArgs& a) {
  // Neither of the two (CLI11 has refused both at once).
  if (a.points.empty() && a.at.empty()) throw UsageError("give either --at X,Y,Z or --points IN.csv -o OUT.csv");
  std::optional<AtomicFile> outFile;
  if (!a.output.empty()) outFile.emplace(a.output);
  const ProbeGrid grid = readProbeGrid(a.file);
  std::optional<Scene> scene;
  if (!a.scene.empty()) {
    LoadOptions load;
    load.shadingTextures = !a.noSceneLights;  // the emissive surfaces' textures: they light it
    scene = loadScene(a.scene, load);
  }
  const bool ownLights =
      scene && !a.noSceneLights && (!scene->lights.empty() || !bake::emissiveLightsOf(*scene).empty());
  const LightRig rig = buildStillRig(a.light, ownLights);
  std::optional<bake::FrameLighting> sceneLighting;
  bake::FrameLight frame;
  if (scene) {
    sceneLighting.emplace(*scene, rig, probeLighting(a, *scene, grid));
    frame = sceneLighting->at(a.light.frame);
  }
  RigLighting lighting = scene ? frame.rig : lightingAt(rig, a.light, a.light.frame, grid.bands);
  // The split (docs/lights.md, "Probes"): the probes' M·(sh + directSh) − M⁰·directSh, and the
  // direct lights traced at the point. Without the scene, or a grid without M⁰, the direct
  // lights go through the probes' SH with the rest.
  const bool split = scene && !lighting.direct.empty() && grid.hasDirect();
  const bool folded = !lighting.direct.empty() && !split;  // the direct lights are in the probes' SH
  // Said once the answer is out (an error stays the only line).
  const std::string note =
      !lighting.direct.empty() && !split
          ? cat("prt probe: note: ", lighting.direct.size(), " direct light(s) (suns, disks up to ",
                kMaxDirectRadiusDegrees,
                " deg) lit through the probes' SH, band-limited and without their own shadow: ",
                !scene ? "give --scene BAKED.glb to trace them at each point"
                       : "the grid has no direct part (baked by an older prt); bake the probes again")
          : std::string();
  if (!split) lighting.direct.clear();
  // Not split: the rig's whole light (LightRig::evaluate), as before the split existed.
  const sh::ShRgb light = sh::resize(split ? lighting.sh : rig.evaluate(a.light.frame, grid.bands), grid.bands);
  std::vector<glm::vec3> relit =
      split ? relightProbes(grid, light, sh::resize(lighting.directSh, grid.bands)) : relightProbes(grid, light);
  std::string operatorNote;
  if (scene && !folded && frame.operatorValues)
    bake::addProbeBounce(*scene->bounceOperator, grid, *frame.operatorValues, relit);
  else if (scene && !folded && scene->bounceOperator && !scene->bounceOperator->probeRows.present())
    operatorNote = cat("prt probe: note: ", a.scene,
                       " has no probe rows in its bounce operator (baked without --probes, or by an older prt): the "
                       "probes get only the bounced light their SH carries");
  std::optional<bake::PointShadows> shadowRays;
  if (split || !frame.local.empty()) {
    if (const bake::RayScene* built = sceneLighting->rays())
      shadowRays.emplace(*built);  // the frame's own shadow rays' scene
    else
      shadowRays.emplace(*scene);
  }
  ProbeQuery q{grid,         relit, light, shadowRays ? &*shadowRays : nullptr, split ? &lighting.direct : nullptr,
               &frame.local, {}};
  q.shadows.samples = a.shadowSamples;
  q.shadows.threads = a.threads;
  if (!a.at.empty())
    probeAt(a, q);
  else
    writeFileAtomic(a.output, probePointsCsv(a.points, q));
  if (!note.empty()) std::fprintf(stderr, "%s\n", note.c_str());
  if (!operatorNote.empty()) std::fprintf(stderr, "%s\n", operatorNote.c_str());
  return 0;
}

}  // namespace prt::tools
