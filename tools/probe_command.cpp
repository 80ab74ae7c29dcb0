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
#include "prt/error.h"
#include "prt/probe_grid.h"
#include "prt/relight.h"
#include "prt/sh.h"

namespace prt::tools {

namespace {

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

}  // namespace

void addProbe(CLI::App& cmd, ProbeArgs& a) {
  cmd.add_option("probes", a.file, "Probe grid (.vdb from prt bake --probes)")->required();
  CLI::Option* at = cmd.add_option("--at", a.at, "Query point X,Y,Z (prints JSON)")
                        ->delimiter(',')
                        ->expected(3)
                        ->check(finite());
  CLI::Option* normal = cmd.add_option("--normal", a.normal, "Surface normal at the point: adds irradiance")
                            ->delimiter(',')
                            ->expected(3)
                            ->check(finite());
  CLI::Option* points = cmd.add_option("--points", a.points, "CSV of points with header x,y,z,nx,ny,nz");
  CLI::Option* output = cmd.add_option("-o,--output", a.output, "Output CSV for --points (adds E_r,E_g,E_b)");
  addLightOptions(cmd, a.light);
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
  const sh::ShRgb light = sh::resize(buildLight(a.light, grid.bands), grid.bands);
  const std::vector<glm::vec3> relit = relightProbes(grid, light);
  const ProbeQuery q{grid, relit, light};
  if (!a.at.empty()) {
    probeAt(a, q);
    return 0;
  }
  writeFileAtomic(a.output, probePointsCsv(a.points, q));
  return 0;
}

}  // namespace prt::tools
