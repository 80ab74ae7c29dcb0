// How version 4 of the bounce operator stores its rows' nodes (docs/formats.md, "The bounce
// operator"): every row is a cut of the operator's two trees (no node of a row lies below
// another), so it is written as the walk that finds it, from the surface root and then the sky
// root, depth first, the first child before the second: at an inner node one bit, 1 to go down
// into both children, else 0 and a second bit, 1 if the node is in the row; at a leaf one bit, 1
// if it is in the row. An empty row has no walk. About 4 bits a node against 9 for delta-coded
// indices. Private to bounce_operator.cpp.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "prt/bounce_operator.h"

namespace prt::cuts {

class CutTrees {
 public:
  /// `op`'s trees, which must pass the tree checks (each node but the two roots the child of one
  /// node of larger index): the walks then end.
  explicit CutTrees(const BounceOperator& op);

  /// The bits of the rows [start[r], start[r + 1]) of `node` (each row ascending), one row after
  /// another, low bits first. Throws prt::Error if a row is not ascending or not a cut of the trees.
  std::vector<uint8_t> encode(const std::vector<uint32_t>& start, const std::vector<uint32_t>& node) const;

  /// The nodes of rows of the given starts from their bits, each row ascending. Throws
  /// prt::Error "WHERE: PART: problem" when a row's walk finds another count of nodes than its
  /// length, the bits end inside a walk, or bits are left over.
  std::vector<uint32_t> decode(const std::vector<uint32_t>& start, const std::vector<uint8_t>& bits,
                               const std::string& where, const char* part) const;

 private:
  const BounceOperator& op_;
  std::vector<uint32_t> parent_;  // per node, its parent (UINT32_MAX for a root)
};

}  // namespace prt::cuts
