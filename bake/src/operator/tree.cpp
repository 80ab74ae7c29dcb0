// The operator's clusters and trees (tree.h).
#include "tree.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <numeric>

#include "prt/error.h"
#include "prt/light.h"
#include "prt/math.h"

namespace prt::bake::op {

namespace {

// A node while the trees grow: which list it is in, and where.
struct Ref {
  enum Kind : uint8_t { Cluster, SkyLeaf, SurfaceInner, SkyInner } kind;
  uint32_t index;
};

class Builder {
 public:
  struct Box {
    glm::vec3 plo{INFINITY}, phi{-INFINITY}, nlo{INFINITY}, nhi{-INFINITY};
    void add(const SidePoint& s) {
      plo = glm::min(plo, s.position), phi = glm::max(phi, s.position);
      nlo = glm::min(nlo, s.normal), nhi = glm::max(nhi, s.normal);
    }
    float surface() const {
      if (plo.x > phi.x) return 0.0f;
      const glm::vec3 d = phi - plo;
      return d.x * d.y + d.y * d.z + d.z * d.x;
    }
  };
  Builder(BounceOperator& op, const std::vector<SidePoint>& sides) : op_(op), sides_(sides) {
    order_.resize(sides.size());
    std::iota(order_.begin(), order_.end(), 0u);
  }

  void grow() {
    surfaceRoot_ = splitSurface(0, order_.size());
    skyRoot_ = splitSky(0, op_.skyWidth, 0, op_.skyHeight);
  }

  Tree finish() {
    const uint32_t C = uint32_t(clusterBegin_.size());
    op_.clusters = C;
    const size_t L = op_.leaves();
    auto id = [&](Ref r) -> uint32_t {
      switch (r.kind) {
        case Ref::Cluster:
          return r.index;
        case Ref::SkyLeaf:
          return C + r.index;
        case Ref::SurfaceInner:
          return uint32_t(L + r.index);
        default:
          return uint32_t(L + surfaceInner_.size() + r.index);
      }
    };
    op_.children.clear();
    for (const auto* list : {&surfaceInner_, &skyInner_})
      for (const auto& [a, b] : *list) {
        op_.children.push_back(id(a));
        op_.children.push_back(id(b));
      }
    op_.surfaceRoot = id(surfaceRoot_);
    op_.skyRoot = id(skyRoot_);
    Tree t;
    placeMembers(t);
    placeSkyBins(t);
    summarizeInnerNodes(t);
    return t;
  }

 private:
  // Splits the vertex sides order_[b, e) in two. While their normals spread over more than
  // about 30° on some axis, at the middle of that axis of the normals (the two sides of a sheet,
  // or walls facing apart, part first); then at the middle of the position axis whose halves'
  // boxes have the least surface (so that parallel walls part before either is cut). A range
  // becomes a cluster once it is small enough and its normals agree. Sides with equal keys stay
  // together; only sides equal in every key are parted by index. The same tree for any thread
  // count.
  Ref splitSurface(size_t b, size_t e) {
    const Box all = boxOf(b, e);
    const glm::vec3 nspread = all.nhi - all.nlo;
    const float coherent = std::max({nspread.x, nspread.y, nspread.z});
    if (e - b == 1 || (e - b <= size_t(op_.clusterSize) && coherent <= 0.5f && flat(b, e, all))) {
      clusterBegin_.push_back(uint32_t(b));
      return {Ref::Cluster, uint32_t(clusterBegin_.size() - 1)};
    }
    auto first = order_.begin() + ptrdiff_t(b), last = order_.begin() + ptrdiff_t(e);
    auto cut = first;
    if (coherent > 0.5f) {
      const int axis = int(std::max_element(&nspread.x, &nspread.x + 3) - &nspread.x);
      const float middle = all.nlo[axis] + 0.5f * nspread[axis];
      cut = std::stable_partition(first, last, [&](uint32_t v) { return sides_[v].normal[axis] < middle; });
    } else {
      cut = bestPositionCut(b, e, all);
    }
    if (cut == first || cut == last) {
      // Every key equal (or the middle rounds to an end): halve by index.
      std::sort(first, last);
      cut = first + (last - first) / 2;
    }
    const size_t mid = size_t(cut - order_.begin());
    const Ref left = splitSurface(b, mid);
    const Ref right = splitSurface(mid, e);
    surfaceInner_.push_back({left, right});
    return {Ref::SurfaceInner, uint32_t(surfaceInner_.size() - 1)};
  }

  // Whether the sides order_[b, e) lie on one sheet: their spread along their mean normal is at
  // most a tenth of their box's diagonal (parallel layers, a slab and the floor under it, are not).
  bool flat(size_t b, size_t e, const Box& all) const {
    glm::vec3 axis(0.0f);
    for (size_t i = b; i < e; ++i) axis += sides_[order_[i]].normal;
    if (glm::length(axis) == 0.0f) return false;
    axis = glm::normalize(axis);
    float lo = INFINITY, hi = -INFINITY;
    for (size_t i = b; i < e; ++i) {
      const float h = glm::dot(axis, sides_[order_[i]].position);
      lo = std::min(lo, h), hi = std::max(hi, h);
    }
    return hi - lo <= 0.1f * glm::length(all.phi - all.plo);
  }

  Box boxOf(size_t b, size_t e) const {
    Box box;
    for (size_t i = b; i < e; ++i) box.add(sides_[order_[i]]);
    return box;
  }

  // The middle cut of x, y or z whose two halves' boxes have the least surface (lower axis on
  // a tie), applied to order_[b, e).
  std::vector<uint32_t>::iterator bestPositionCut(size_t b, size_t e, const Box& all) {
    int best = -1;
    float bestSurface = INFINITY;
    for (int axis = 0; axis < 3; ++axis) {
      const float middle = all.plo[axis] + 0.5f * (all.phi[axis] - all.plo[axis]);
      if (!(all.phi[axis] > all.plo[axis])) continue;
      Box lo, hi;
      for (size_t i = b; i < e; ++i) {
        const SidePoint& s = sides_[order_[i]];
        (s.position[axis] < middle ? lo : hi).add(s);
      }
      const float surface = lo.surface() + hi.surface();
      if (surface < bestSurface) bestSurface = surface, best = axis;
    }
    auto first = order_.begin() + ptrdiff_t(b), last = order_.begin() + ptrdiff_t(e);
    if (best < 0) return first;
    const float middle = all.plo[best] + 0.5f * (all.phi[best] - all.plo[best]);
    return std::stable_partition(first, last, [&](uint32_t v) { return sides_[v].position[best] < middle; });
  }

  // Halves the bins [x0, x1) × [y0, y1) across their longer side (across u on a tie).
  Ref splitSky(int x0, int x1, int y0, int y1) {
    if (x1 - x0 == 1 && y1 - y0 == 1) {
      op_.skyBin.push_back(uint32_t(y0 * op_.skyWidth + x0));
      return {Ref::SkyLeaf, uint32_t(op_.skyBin.size() - 1)};
    }
    Ref a, b;
    if (x1 - x0 >= y1 - y0) {
      const int xm = (x0 + x1) / 2;
      a = splitSky(x0, xm, y0, y1), b = splitSky(xm, x1, y0, y1);
    } else {
      const int ym = (y0 + y1) / 2;
      a = splitSky(x0, x1, y0, ym), b = splitSky(x0, x1, ym, y1);
    }
    skyInner_.push_back({a, b});
    return {Ref::SkyInner, uint32_t(skyInner_.size() - 1)};
  }

  // The members of each cluster, its first samplePoints spread over it: the one nearest its
  // centroid, then each time the one farthest from those chosen (lower index on ties).
  void placeMembers(Tree& t) {
    const size_t L = op_.leaves(), N = op_.nodes();
    t.leafLo.assign(N, 0), t.leafHi.assign(N, 0), t.center.assign(N, glm::vec3(0.0f)), t.radius.assign(N, 0.0f);
    t.axis.assign(N, glm::vec3(0.0f)), t.cone.assign(N, 0.0f);
    t.clusterOf.assign(sides_.size(), 0);
    op_.leafWeight.assign(L, 0.0f);
    op_.albedo.assign(op_.clusters, glm::vec3(0.0f));
    op_.memberStart.assign(size_t(op_.clusters) + 1, 0);
    op_.members.clear();
    for (uint32_t c = 0; c < op_.clusters; ++c) {
      const size_t b = clusterBegin_[c], e = c + 1 < op_.clusters ? clusterBegin_[c + 1] : order_.size();
      std::vector<uint32_t> m(order_.begin() + ptrdiff_t(b), order_.begin() + ptrdiff_t(e));
      std::sort(m.begin(), m.end());
      double area = 0.0;
      glm::dvec3 centroid(0.0), rho(0.0), mean(0.0);
      for (uint32_t v : m) {
        area += sides_[v].area;
        centroid += double(sides_[v].area) * glm::dvec3(sides_[v].position);
        rho += double(sides_[v].area) * glm::dvec3(sides_[v].albedo);
        mean += glm::dvec3(sides_[v].position);
        t.clusterOf[v] = c;
      }
      if (area > 0.0)
        centroid /= area, rho /= area;
      else {
        centroid = mean / double(m.size());
        for (uint32_t v : m) rho += glm::dvec3(sides_[v].albedo) / double(m.size());
      }
      spreadSamples(m, glm::vec3(centroid));
      op_.members.insert(op_.members.end(), m.begin(), m.end());
      op_.memberStart[c + 1] = uint32_t(op_.members.size());
      op_.leafWeight[c] = std::max(float(area), 1e-30f);
      op_.albedo[c] = glm::vec3(rho);
      t.leafLo[c] = c, t.leafHi[c] = c + 1;
      t.center[c] = glm::vec3(centroid);
      glm::vec3 axis(0.0f);
      for (uint32_t v : m) {
        t.radius[c] = std::max(t.radius[c], glm::length(sides_[v].position - t.center[c]));
        axis += sides_[v].normal;
      }
      t.axis[c] = glm::length(axis) > 0.0f ? glm::normalize(axis) : sides_[m[0]].normal;
      float cosMin = 1.0f;
      for (uint32_t v : m) cosMin = std::min(cosMin, glm::dot(t.axis[c], sides_[v].normal));
      t.cone[c] = 1.0f - cosMin;
    }
  }

  void spreadSamples(std::vector<uint32_t>& m, const glm::vec3& centroid) const {
    const size_t P = std::min(m.size(), size_t(op_.samplePoints));
    auto dist = [&](uint32_t v, const glm::vec3& x) { return glm::length(sides_[v].position - x); };
    size_t first = 0;
    for (size_t i = 1; i < m.size(); ++i)
      if (dist(m[i], centroid) < dist(m[first], centroid)) first = i;
    std::swap(m[0], m[first]);
    for (size_t k = 1; k < P; ++k) {
      size_t best = k;
      float bestD = -1.0f;
      for (size_t i = k; i < m.size(); ++i) {
        float d = INFINITY;
        for (size_t j = 0; j < k; ++j) d = std::min(d, dist(m[i], sides_[m[j]].position));
        if (d > bestD || (d == bestD && m[i] < m[best])) bestD = d, best = i;
      }
      std::swap(m[k], m[best]);
    }
    std::sort(m.begin() + ptrdiff_t(P), m.end());
  }

  void placeSkyBins(Tree& t) {
    const int W = op_.skyWidth, H = op_.skyHeight;
    t.skyLeafOfBin.assign(op_.skyBins(), 0);
    for (size_t s = 0; s < op_.skyBins(); ++s) {
      const uint32_t n = op_.clusters + uint32_t(s), bin = op_.skyBin[s];
      const int x = int(bin) % W, y = int(bin) / W;
      t.skyLeafOfBin[bin] = n;
      op_.leafWeight[n] = float(equirectPixelSolidAngle(y, W, H));
      const glm::vec3 c(equirectDirection((x + 0.5) / W, (y + 0.5) / H));
      t.center[n] = c;
      for (int cx = 0; cx <= 1; ++cx)
        for (int cy = 0; cy <= 1; ++cy) {
          const glm::vec3 corner(equirectDirection(double(x + cx) / W, double(y + cy) / H));
          t.radius[n] = std::max(t.radius[n], std::acos(std::clamp(glm::dot(c, corner), -1.0f, 1.0f)));
        }
      t.leafLo[n] = n, t.leafHi[n] = n + 1;
    }
  }

  // Inner nodes: their leaves, weighted centre and a radius that holds their children's.
  void summarizeInnerNodes(Tree& t) {
    const std::vector<uint8_t> sky = skyNodeMask(op_);
    std::vector<double> weight(op_.nodes(), 0.0);
    for (size_t n = 0; n < op_.leaves(); ++n) weight[n] = op_.leafWeight[n];
    for (size_t i = 0; i < op_.children.size() / 2; ++i) {
      const size_t n = op_.leaves() + i;
      const uint32_t a = op_.children[2 * i], b = op_.children[2 * i + 1];
      weight[n] = weight[a] + weight[b];
      t.leafLo[n] = t.leafLo[a], t.leafHi[n] = t.leafHi[b];
      PRT_CHECK_EQ(t.leafHi[a], t.leafLo[b]);
      glm::vec3 c = glm::vec3((weight[a] * glm::dvec3(t.center[a]) + weight[b] * glm::dvec3(t.center[b])) / weight[n]);
      if (sky[n]) {
        const float len = glm::length(c);
        c = len > 0.0f ? c / len : t.center[a];
      }
      t.center[n] = c;
      if (!sky[n]) coneOf(t, n, a, b, weight);
      for (uint32_t k : {a, b}) {
        const float d =
            sky[n] ? std::acos(std::clamp(glm::dot(c, t.center[k]), -1.0f, 1.0f)) : glm::length(c - t.center[k]);
        t.radius[n] = std::max(t.radius[n], d + t.radius[k]);
      }
    }
  }

  // The normal cone of inner node n from its children's: the weighted mean axis, and the
  // largest angle to it of either child's cone.
  static void coneOf(Tree& t, size_t n, uint32_t a, uint32_t b, const std::vector<double>& weight) {
    glm::vec3 axis = float(weight[a]) * t.axis[a] + float(weight[b]) * t.axis[b];
    axis = glm::length(axis) > 1e-6f ? glm::normalize(axis) : t.axis[a];
    t.axis[n] = axis;
    float angle = 0.0f;
    for (uint32_t k : {a, b})
      angle = std::max(angle, std::acos(std::clamp(glm::dot(axis, t.axis[k]), -1.0f, 1.0f)) +
                                  std::acos(std::clamp(1.0f - t.cone[k], -1.0f, 1.0f)));
    t.cone[n] = 1.0f - std::cos(std::min(angle, float(kPi)));
  }

  BounceOperator& op_;
  const std::vector<SidePoint>& sides_;
  std::vector<uint32_t> order_;
  std::vector<uint32_t> clusterBegin_;
  std::vector<std::pair<Ref, Ref>> surfaceInner_, skyInner_;
  Ref surfaceRoot_{}, skyRoot_{};
};

}  // namespace

std::vector<float> sideAreas(const Scene& scene, const Layout& lay) {
  std::vector<float> out(lay.vertices, 0.0f);
  for (size_t k = 0; k < scene.meshes.size(); ++k) {
    if (lay.vertexOffset[k] == SIZE_MAX) continue;
    const MeshInstance& m = scene.meshes[k];
    for (size_t t = 0; t + 2 < m.indices.size(); t += 3) {
      const uint32_t* ix = &m.indices[t];
      const float a =
          glm::length(glm::cross(m.positions[ix[1]] - m.positions[ix[0]], m.positions[ix[2]] - m.positions[ix[0]])) /
          6.0f;
      for (int j = 0; j < 3; ++j) {
        out[lay.vertexOffset[k] + ix[j]] += a;
        if (lay.backVertexOffset[k] != SIZE_MAX) out[lay.backVertexOffset[k] + ix[j]] += a;
      }
    }
  }
  return out;
}

Tree buildTree(BounceOperator& op, const std::vector<SidePoint>& sides) {
  PRT_CHECK_EQ(sides.size(), size_t(op.vertexSides));
  PRT_CHECK_GT(sides.size(), size_t(0));
  op.skyBin.clear();
  Builder b(op, sides);
  b.grow();
  return b.finish();
}

}  // namespace prt::bake::op
