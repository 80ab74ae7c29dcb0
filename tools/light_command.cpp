#include "light_command.h"

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
  writeFileAtomic(a.output, j.dump(2) + "\n");
  return 0;
}

}  // namespace prt::tools
