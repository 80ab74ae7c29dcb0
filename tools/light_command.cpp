#include "light_command.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include <nlohmann/json.hpp>

#include "cli_checks.h"
#include "prt/atomic_file.h"
#include "prt/error.h"
#include "prt/light_rig.h"
#include "prt/sh.h"

namespace prt::tools {

void addLight(CLI::App& cmd, LightArgs& a) {
  cmd.add_option("-o,--output", a.output, "Output JSON")->required();
  cmd.add_option("--bands", a.bands, "SH bands (n bands = n² coefficients)")->check(kBandsRange)->capture_default_str();
  addLightOptions(cmd, a.light, /*animated=*/false, /*envPositional=*/true);
}

int runLight(const LightArgs& a) {
  AtomicFile probe(a.output);
  LightRig rig = buildStillRig(a.light);
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
  // The same light with its direct lights apart (docs/lights.md, "Direct lights"): what
  // relight, render and probe light exactly (direct) and through SH (sh, direct_sh).
  const RigLighting split = lightingAt(rig, a.light, a.light.frame, a.bands);
  auto shJson = [](const sh::ShRgb& l) {
    nlohmann::json out = nlohmann::json::array();
    for (const glm::vec3& c : l.c) out.push_back({c.r, c.g, c.b});
    return out;
  };
  nlohmann::json direct = nlohmann::json::array();
  for (size_t k = 0; k < split.direct.size(); ++k) {
    const DirectLight& d = split.direct[k];
    const RigLight& source = rig.lights[split.source[k]];
    const bool fromMap = source.type == RigLight::Type::Environment;
    direct.push_back({{"direction", {d.direction.x, d.direction.y, d.direction.z}},
                      {"elevation_deg", glm::degrees(std::asin(std::clamp(d.direction.y, -1.0, 1.0)))},
                      {"azimuth_deg", glm::degrees(std::atan2(d.direction.x, d.direction.z))},
                      {"radius_deg", glm::degrees(d.radius)},
                      {"irradiance", {d.irradiance.r, d.irradiance.g, d.irradiance.b}},
                      {"source", fromMap                              ? "map"
                                 : source.type == RigLight::Type::Sun ? "sun"
                                                                      : "disk"},
                      {"map_power_share", fromMap ? split.mapShare[k] : 0.0}});
  }
  j["direct_lights"] = direct;
  // The rig's lights inside the scene at the frame, in their own frame (a node's, if they name one).
  nlohmann::json local = nlohmann::json::array();
  for (const RigLocalLight& r : rig.locals) {
    const LocalLight l = r.at(a.light.frame);
    auto v3 = [](const glm::dvec3& v) { return nlohmann::json{v.x, v.y, v.z}; };
    nlohmann::json e = {
        {"type", localLightTypeName(l.type)}, {"label", l.label}, {"node", r.node}, {"position", v3(l.position)}};
    if (l.punctual()) {
      e["intensity_cd"] = v3(l.intensity);
      e["range"] = l.range;
    } else {
      e["radiance"] = v3(l.radiance);
    }
    if (l.type != LocalLight::Type::Point && l.type != LocalLight::Type::Sphere) e["direction"] = v3(l.direction);
    if (l.type == LocalLight::Type::Spot) {
      e["inner_cone_deg"] = glm::degrees(l.innerCone);
      e["outer_cone_deg"] = glm::degrees(l.outerCone);
    }
    if (l.type == LocalLight::Type::Sphere || l.type == LocalLight::Type::Disk) e["radius"] = l.radius;
    if (l.type == LocalLight::Type::Rectangle) {
      e["up"] = v3(l.up);
      e["width"] = l.width;
      e["height"] = l.height;
    }
    local.push_back(e);
  }
  j["local_lights"] = local;
  j["sh"] = shJson(split.sh);
  j["direct_sh"] = shJson(split.directSh);
  writeFileAtomic(a.output, j.dump(2) + "\n");
  for (const std::string& line : describeDirectLights(split, rig))
    std::fprintf(stderr, "prt light: direct light: %s\n", line.c_str());
  for (const RigLocalLight& r : rig.locals)
    std::fprintf(stderr, "prt light: light inside the scene: %s%s\n", describeLocalLight(r.at(a.light.frame)).c_str(),
                 r.node.empty() ? "" : cat(" (in node '", r.node, "')").c_str());
  return 0;
}

}  // namespace prt::tools
