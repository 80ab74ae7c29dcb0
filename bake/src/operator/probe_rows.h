// The probes' rows of the bounce operator (BounceOperator::ProbeRows): made from each probe's
// own gather rays as the operator's vertex rows are from the vertices' (build.cpp calls it with
// the trees and training lights it built), and evaluated at a light change. Private to the
// operator's build.
#pragma once

#include <vector>

#include "prt/bake/bounce_operator.h"
#include "prt/bake/ray_scene.h"
#include "prt/bake/surface_layout.h"
#include "prt/probe_grid.h"
#include "prt/scene.h"
#include "training.h"
#include "tree.h"

namespace prt::bake::op {

/// What makeProbeRows reads of the operator's build.
struct ProbeRowInputs {
  const Scene& scene;
  const Layout& lay;
  const BounceOperator& op;
  const Tree& tree;
  const std::vector<uint8_t>& sky;  // skyNodeMask(op)
  const Training& training;
  const RayScene& rays;
};

/// The rows of every probe of `grid` (empty rows for invalid probes), each from the first
/// `samples` of the probe's own rays (the probe bake's stream of it), cut to `rowLength` entries
/// unless `uncompressed`; `full` (if given) receives them with their SH in full.
BounceOperator::ProbeRows makeProbeRows(const ProbeRowInputs& in, const ProbeGrid& grid, int samples, int rowLength,
                                        bool uncompressed, ProbeShRows* full);

}  // namespace prt::bake::op
