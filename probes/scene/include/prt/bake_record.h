// The bake record: what a baked .glb says about the bake that made it, stored as the JSON
// object asset.extras.prt (docs/formats.md, "The bake record"). loadScene reads and validates
// it (Scene::bakeRecord), writeBakedScene writes it; both go through one piece of code
// (scene/src/bake_record.cpp), so the keys and their checks are written once.
#pragma once

#include <cstdint>
#include <string>

namespace prt {

struct BakeRecord {
  /// The record's layout. A reader refuses any other value ("written by a newer prt"), so a
  /// record in memory is always of this layout and holds no field for it.
  static constexpr int kLayoutVersion = 1;
  /// Fixed descriptions written beside the fields, for whoever reads the file without prt.
  /// kTransfer is checked on read: it says what the _PRT_SH_ attributes hold.
  static constexpr const char* kTransfer = "irradiance";
  static constexpr const char* kShConvention = "real orthonormal, no Condon-Shortley phase, index l(l+1)+m, glTF axes";
  static constexpr const char* kUnits = "E = transfer . light (irradiance); L_o = albedo / pi * E";
  /// What the _PRT_SH_BACK_ attributes hold, written as "back_transfer" when the file has them
  /// (backTransfer); absent in a file without them, so one-sided bakes write what they did.
  static constexpr const char* kBackTransfer =
      "_PRT_SH_BACK_NN of double-sided primitives: transfer of the back side (normal -N)";

  /// What the _PRT_SH_DIRECT_ attributes hold, written as "direct_transfer" when the file has
  /// them (directTransfer).
  static constexpr const char* kDirectTransfer =
      "_PRT_SH_DIRECT_NN (_PRT_SH_BACK_DIRECT_NN): bounce-0 transfer, first-hit visibility, colourless";

  std::string scene;  // file name of the scene baked (no folder)
  int bands = 0;      // 1 .. sh::kMaxBands
  int samples = 0;    // rays per vertex, >= 1
  int bounces = 0;    // interreflection bounces, >= 0 (0 when unshadowed)
  bool shadowed = true;
  uint64_t seed = 0;
  std::string prtVersion;       // the prt that baked it; empty for files baked before it was recorded
  bool backTransfer = false;    // double-sided primitives carry the back side's transfer (_PRT_SH_BACK_)
  bool directTransfer = false;  // every baked primitive carries its direct part (_PRT_SH_DIRECT_)

  /// Adaptive refinement of the meshes before the bake (prt/bake/refine.h). tolerance 0: none
  /// (turned off, unshadowed, or a file baked before prt refined meshes).
  struct Refinement {
    double tolerance = 0.0;       // relative to the unoccluded transfer's norm
    uint64_t budget = 0;          // vertices it could add
    int samples = 0;              // directions per estimated point
    uint64_t verticesBefore = 0;  // baked vertices of the input
    uint64_t verticesAfter = 0;   // baked vertices of the refined meshes (what the file holds)
    double residual = 0.0;        // largest error left, in the tolerance's units
    bool operator==(const Refinement&) const = default;
  };
  Refinement refinement;

  bool operator==(const BakeRecord&) const = default;
};

/// One line for people, e.g. "3 bands, 1024 samples, 2 bounces, shadowed, seed 1, from
/// cornell_open.gltf, prt 0.1.0" (the prt part only when the record names it; ", both sides
/// of double-sided surfaces" when it has backTransfer), then the refinement if any:
/// "; refined 8 -> 240 vertices (tolerance 0.05, budget 10000, residual 0.031)".
std::string describeBakeRecord(const BakeRecord& record);

}  // namespace prt
