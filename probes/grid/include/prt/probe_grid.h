// A sparse grid of radiance-transfer probes: the data, its file format (OpenVDB) and the
// interpolation every consumer uses (the renderer, `prt probe`, the tests).
//
// Probe at index (i, j, k) sits at origin + spacing ⊙ (i, j, k) + offset (an offset moves a probe
// out of geometry within its cell). Each probe holds, per colour channel, the n²×n² matrix M
// with incident radiance SH c = M · l for distant light SH l (docs/prt-math.md):
//   M_ji = ∫ y_j(ω) [ V(p,ω) y_i(ω) + (1 − V(p,ω)) (ρ(h)/π) t_i(h(ω)) ] dω.
// File layout and the leak-prevention method: docs/probes.md.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "prt/sh.h"

namespace prt {

/// Cube faces of a probe's distance moments, in this order.
enum class Face { PosX, NegX, PosY, NegY, PosZ, NegZ };
/// The face a direction belongs to (its dominant axis and sign). Inline: the probe bake asks it
/// for every ray.
inline int faceOf(const glm::vec3& d) {
  const glm::vec3 a = glm::abs(d);
  // Ties go to the earlier axis (x, then y), so every direction has exactly one face.
  if (a.x >= a.y && a.x >= a.z) return d.x >= 0.0f ? int(Face::PosX) : int(Face::NegX);
  if (a.y >= a.z) return d.y >= 0.0f ? int(Face::PosY) : int(Face::NegY);
  return d.z >= 0.0f ? int(Face::PosZ) : int(Face::NegZ);
}

struct ProbeGridInfo {
  int bounces = 0;
  int samples = 0;
  uint64_t seed = 0;
  std::string scene;  // file name of the scene it was baked from
  /// Where probes were baked: "everywhere" outside solid geometry, or "inside" a closed
  /// level's shell only (docs/probes.md, "Where probes go"); empty in files before it.
  std::string region;
};

struct ProbeGrid {
  int bands = 0;
  glm::dvec3 origin{0.0};   // world position of index (0, 0, 0)
  glm::dvec3 spacing{1.0};  // distance between neighbouring probes along x, y, z (> 0)
  glm::ivec3 dims{0};       // indices run over [0, dims)
  ProbeGridInfo info;

  // Active probes, in any order; arrays below are parallel to `coord`.
  std::vector<glm::ivec3> coord;
  std::vector<float> transfer;  // probe p: n⁴ RGB triples, [p][j][i] -> 3 floats (r, g, b)
  /// The direct part M⁰_ji = ∫ V y_j y_i dω of each probe's M (first-hit visibility, no
  /// bounce): colourless and symmetric, so its upper triangle j ≤ i, row by row (directStride()
  /// floats per probe). Empty in files baked before prt kept it apart (prt_format_version 2).
  std::vector<float> direct;
  std::vector<float> validity;       // 1 = valid, 0 = inside geometry (never interpolated)
  std::vector<glm::vec3> offset;     // world offset from the lattice position (0 if not moved)
  std::vector<float> skyVisibility;  // fraction of all directions that escape to the sky
  // Per Face: mean and mean square of the first hits' depth along the face's axis, |t · ω_axis|
  // (ray length t, direction ω; misses count as 2 × max spacing). prt_format_version 2.
  std::vector<std::array<glm::vec2, 6>> moments;

  size_t probeCount() const { return coord.size(); }
  int coeffs() const { return bands * bands; }
  /// Floats of transfer per probe: n⁴ · 3.
  size_t transferStride() const { return size_t(coeffs()) * coeffs() * 3; }
  /// Floats of direct per probe: n²(n² + 1)/2.
  static size_t directStride(int bands) { return size_t(bands) * bands * (size_t(bands) * bands + 1) / 2; }
  size_t directStride() const { return directStride(bands); }
  bool hasDirect() const { return !direct.empty(); }
  glm::dvec3 latticePosition(const glm::ivec3& c) const { return origin + spacing * glm::dvec3(c); }
  glm::dvec3 position(size_t p) const { return latticePosition(coord[p]) + glm::dvec3(offset[p]); }

  /// Builds the index used by find() (call after filling `coord`).
  void buildIndex();
  /// Position in `coord` of probe (i, j, k), or -1 if it is inactive or outside dims.
  int find(const glm::ivec3& c) const;

 private:
  std::vector<int32_t> dense_;  // dims.x·dims.y·dims.z entries, -1 = inactive
};

/// Incident radiance SH of every probe under distant light `light` (truncated/padded to the
/// grid's bands): c_p = M_p · l, per channel. Result: probeCount() × n² RGB, probe-major.
/// This is the per-frame "light update".
std::vector<glm::vec3> relightProbes(const ProbeGrid& grid, const sh::ShRgb& light);
/// The same with direct lights split off (docs/lights.md, "Direct lights"): `light` through the
/// whole of M, `directLight` (the direct lights' SH) through the bounced part M − M⁰ only:
/// c_p = M_p · (light + directLight) − M⁰_p · directLight. The direct lights' unoccluded part is
/// added per receiver, with its shadow. Precondition: grid.hasDirect().
std::vector<glm::vec3> relightProbes(const ProbeGrid& grid, const sh::ShRgb& light, const sh::ShRgb& directLight);

/// Where a query point lies relative to the grid (docs/probes.md, "Lattice and domain").
enum class ProbeCover {
  Lattice,       // inside the lattice's box [origin, origin + spacing ⊙ (dims − 1)]: interpolated
  Shell,         // in the half-cell shell around it: clamped to the box, nearest probes
  Fade,          // beyond the domain (the box grown by half a spacing) by less than one spacing:
                 // the nearest probes blended with the unoccluded light (ProbeWeights::fade)
  Outside,       // farther: no probe
  NoValidProbe,  // inside the domain, but every probe of its cell is invalid or inactive
};
/// "lattice", "shell", "fade", "outside", "no_valid_probe" (prt probe's JSON and CSV).
const char* probeCoverName(ProbeCover c);

/// Weights of one interpolation: up to 8 probes and their normalised weights.
struct ProbeWeights {
  int count = 0;
  std::array<int, 8> probe{};
  std::array<float, 8> weight{};
  ProbeCover cover = ProbeCover::Outside;  // count > 0 exactly for Lattice, Shell and Fade
  /// The unoccluded light's share (receiverRadiance): 0 within the domain, rising linearly
  /// with the distance beyond it to 1 one spacing further (on the farthest axis).
  float fade = 0.0f;
};

/// The domain of the grid: the lattice's box grown by half a spacing on every side, i.e. the
/// union of the probes' cells. prt bake's default lattice puts the probes at the cell centres of
/// the bake bounds, so the domain covers those bounds.
void probeDomain(const ProbeGrid& grid, glm::dvec3& lo, glm::dvec3& hi);

/// Interpolation weights at world point x (with surface normal n, or none): per corner probe,
/// trilinear × validity × a Chebyshev visibility test on the depth moments of the three faces
/// x lies towards (no light through walls between probe and x) × a soft back-face weight when n
/// is given; then normalised (exact formula: docs/probes.md). Falls back to plain trilinear
/// over valid probes when every weight vanishes. A point in the half-cell shell around the
/// lattice's box has its trilinear position clamped to the box (the nearest probes light it),
/// and so does a point less than one spacing beyond the domain, with `fade` > 0. count == 0
/// when x is farther out or no valid probe surrounds it (`cover` says which).
ProbeWeights probeWeights(const ProbeGrid& grid, const glm::vec3& x, const glm::vec3* normal);

/// Interpolated incident radiance SH at x from relit probes (relightProbes()); zero where
/// probeWeights finds no probe. The probes only: receiverRadiance applies the fade.
sh::ShRgb interpolateRadiance(const ProbeGrid& grid, const std::vector<glm::vec3>& relit, const glm::vec3& x,
                              const glm::vec3* normal);

/// Incident radiance SH at x as the renderer lights a receiver there: interpolated from the
/// probes where probeWeights finds any, else the unoccluded light itself (M = I: nothing
/// around x blocks or reflects); beyond the domain (cover Fade) the two blended,
/// (1 − fade) · probes + fade · light, so the light changes continuously as x leaves the grid. `light` is the one the
/// probes were relit with. `cover` (if
/// given) receives where x lies. prt probe and the renderer's shader both follow this rule.
sh::ShRgb receiverRadiance(const ProbeGrid& grid, const std::vector<glm::vec3>& relit, const sh::ShRgb& light,
                           const glm::vec3& x, const glm::vec3* normal, ProbeCover* cover = nullptr);
/// The same from weights already found by probeWeights (for callers that report them too).
sh::ShRgb receiverRadiance(const ProbeGrid& grid, const std::vector<glm::vec3>& relit, const sh::ShRgb& light,
                           const ProbeWeights& w);

/// Writes the grid as OpenVDB (standard grid types only), atomically. `half` stores floats
/// as 16-bit. Layout: docs/probes.md.
void writeProbeGrid(const ProbeGrid& grid, const std::string& path, bool half = false);
/// Reads a file written by writeProbeGrid. Throws prt::Error naming the file and the problem
/// (missing, not VDB, truncated, missing grid, inconsistent metadata).
ProbeGrid readProbeGrid(const std::string& path);
/// A human summary of a probe file (prt info): grids, active probes, bounds, spacing, memory,
/// settings. Throws prt::Error like readProbeGrid.
std::string describeProbeFile(const std::string& path);

}  // namespace prt
