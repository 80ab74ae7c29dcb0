// Rows as walks of the operator's trees (row_cuts.h).
#include "row_cuts.h"

#include <algorithm>

#include "prt/error.h"

namespace prt::cuts {

namespace {

constexpr uint32_t kNone = UINT32_MAX;

class BitWriter {
 public:
  void put(bool bit) {
    if (used_ % 8 == 0) bytes.push_back(0);
    if (bit) bytes.back() |= uint8_t(1u << (used_ % 8));
    ++used_;
  }
  std::vector<uint8_t> bytes;

 private:
  size_t used_ = 0;
};

class BitReader {
 public:
  BitReader(const std::vector<uint8_t>& bytes, const std::string& where, const char* part)
      : bytes_(bytes), where_(where), part_(part) {}
  bool get(size_t row) {
    if (at_ >= 8 * bytes_.size())
      throw Error(cat(where_, ": ", part_, ": the bits end inside row ", row, " (corrupt or truncated)"));
    const bool bit = (bytes_[at_ / 8] >> (at_ % 8)) & 1u;
    ++at_;
    return bit;
  }
  // Throws unless what is left is the last byte's zero padding.
  void finish() const {
    if ((at_ + 7) / 8 != bytes_.size() || (at_ % 8 != 0 && (bytes_.back() >> (at_ % 8)) != 0))
      throw Error(cat(where_, ": ", part_, ": ", bytes_.size(), " bytes, the rows use ", (at_ + 7) / 8, " (corrupt)"));
  }

 private:
  const std::vector<uint8_t>& bytes_;
  const std::string& where_;
  const char* part_;
  size_t at_ = 0;
};

}  // namespace

CutTrees::CutTrees(const BounceOperator& op) : op_(op), parent_(op.nodes(), kNone) {
  for (size_t i = 0; i < op.children.size(); ++i) parent_[op.children[i]] = uint32_t(op.leaves() + i / 2);
}

std::vector<uint8_t> CutTrees::encode(const std::vector<uint32_t>& start, const std::vector<uint32_t>& node) const {
  enum : uint8_t { kIn = 1, kBelow = 2 };  // the node is in the row; a node below it is
  std::vector<uint8_t> state(op_.nodes(), 0);
  std::vector<uint32_t> touched, stack;
  BitWriter w;
  for (size_t r = 0; r + 1 < start.size(); ++r) {
    if (start[r + 1] == start[r]) continue;  // an empty row: no walk
    for (uint32_t e = start[r]; e < start[r + 1]; ++e) {
      // A reader lists a row's nodes ascending and pairs its weights with them in that order.
      if (e > start[r] && node[e] <= node[e - 1])
        throw Error(cat("bounce operator: row ", r, " is not in ascending node order"));
      state[node[e]] |= kIn;
      touched.push_back(node[e]);
      for (uint32_t p = parent_[node[e]]; p != kNone && !(state[p] & kBelow); p = parent_[p]) {
        state[p] |= kBelow;
        touched.push_back(p);
      }
    }
    stack = {op_.skyRoot, op_.surfaceRoot};
    while (!stack.empty()) {
      const uint32_t n = stack.back();
      stack.pop_back();
      const uint8_t s = state[n];
      if (n < op_.leaves()) {
        w.put(s & kIn);
        continue;
      }
      if ((s & kIn) && (s & kBelow))
        throw Error(cat("bounce operator: row ", r, " holds node ", n, " and a node below it (not a cut)"));
      w.put(s & kBelow);
      if (s & kBelow) {
        const size_t i = 2 * (n - op_.leaves());
        stack.push_back(op_.children[i + 1]);
        stack.push_back(op_.children[i]);
      } else {
        w.put(s & kIn);
      }
    }
    for (uint32_t n : touched) state[n] = 0;
    touched.clear();
  }
  return std::move(w.bytes);
}

std::vector<uint32_t> CutTrees::decode(const std::vector<uint32_t>& start, const std::vector<uint8_t>& bits,
                                       const std::string& where, const char* part) const {
  std::vector<uint32_t> node(start.empty() ? 0 : start.back());
  std::vector<uint32_t> stack;
  BitReader in(bits, where, part);
  for (size_t r = 0; r + 1 < start.size(); ++r) {
    const uint32_t length = start[r + 1] - start[r];
    if (length == 0) continue;  // an empty row: no walk
    uint32_t found = 0;
    auto keep = [&](uint32_t n) {
      if (found == length)
        throw Error(cat(where, ": ", part, ": row ", r, " holds more than its ", length, " nodes (corrupt)"));
      node[start[r] + found++] = n;
    };
    stack = {op_.skyRoot, op_.surfaceRoot};
    while (!stack.empty()) {
      const uint32_t n = stack.back();
      stack.pop_back();
      if (n < op_.leaves()) {
        if (in.get(r)) keep(n);
      } else if (in.get(r)) {
        const size_t i = 2 * (n - op_.leaves());
        stack.push_back(op_.children[i + 1]);
        stack.push_back(op_.children[i]);
      } else if (in.get(r)) {
        keep(n);
      }
    }
    if (found != length)
      throw Error(
          cat(where, ": ", part, ": row ", r, " holds ", found, " nodes, its length is ", length, " (corrupt)"));
    std::sort(node.begin() + start[r], node.begin() + start[r + 1]);
  }
  in.finish();
  return node;
}

}  // namespace prt::cuts
