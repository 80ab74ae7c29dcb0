// The bounce operator's checks and its packed form (prt/bounce_operator.h, docs/formats.md
// "The bounce operator").
#include "prt/bounce_operator.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <iomanip>
#include <optional>
#include <sstream>

#include <nlohmann/json.hpp>

#include "prt/error.h"
#include "row_cuts.h"

namespace prt {

namespace {

using Json = nlohmann::json;

// Appends arrays little-endian (every supported machine is), each starting on a 4-byte boundary.
class Packer {
 public:
  template <class T>
  void put(const std::vector<T>& v) {
    align();
    const auto* p = reinterpret_cast<const uint8_t*>(v.data());
    bytes.insert(bytes.end(), p, p + v.size() * sizeof(T));
  }
  // The node indices of every row as the walks of `trees` that find them (row_cuts.h).
  // Returns the count of bytes.
  template <class Rows>
  size_t putRowCuts(const Rows& r, const cuts::CutTrees& trees) {
    const std::vector<uint8_t> out = trees.encode(r.start, r.node);
    put(out);
    return out.size();
  }
  std::vector<uint8_t> bytes;

 private:
  void align() {
    while (bytes.size() % 4 != 0) bytes.push_back(0);
  }
};

class Unpacker {
 public:
  Unpacker(const uint8_t* bytes, size_t size, std::string where) : p_(bytes), size_(size), where_(std::move(where)) {}
  template <class T>
  std::vector<T> take(size_t count, const char* part) {
    at_ = (at_ + 3) / 4 * 4;
    if (count > (size_ - std::min(at_, size_)) / sizeof(T))
      throw Error(cat(where_, ": ", part, ": the bytes end at ", size_, ", before its ", count,
                      " values (the file is truncated)"));
    std::vector<T> v(count);
    if (count) std::memcpy(v.data(), p_ + at_, count * sizeof(T));
    at_ += count * sizeof(T);
    return v;
  }
  // Weights of `Wide` (uint16 row weights, int16 gradient weights): from version 4 on, one byte
  // each (`Code`) read through `decode`, else two bytes.
  template <class Wide, class Code, class Decode>
  std::vector<Wide> takeCoded(size_t count, int version, const char* part, Decode decode) {
    if (version < 4) return take<Wide>(count, part);
    const std::vector<Code> codes = take<Code>(count, part);
    std::vector<Wide> out(count);
    for (size_t i = 0; i < count; ++i) out[i] = decode(codes[i]);
    return out;
  }
  std::vector<uint16_t> takeWeights(size_t count, int version, const char* part) {
    return takeCoded<uint16_t, uint8_t>(count, version, part, BounceOperator::weightOfCode);
  }
  std::vector<int16_t> takeGradients(size_t count, int version, const char* part) {
    return takeCoded<int16_t, int8_t>(count, version, part, BounceOperator::gradientOfCode);
  }
  // Row nodes of the given starts: putRowCuts' walks (`trees`, version 4) or delta-coded varints
  // (versions 2, 3).
  std::vector<uint32_t> takeRowNodesOf(const std::vector<uint32_t>& start, size_t byteCount,
                                       const cuts::CutTrees* trees, const char* part) {
    if (trees) return trees->decode(start, take<uint8_t>(byteCount, part), where_, part);
    return takeRowNodes(start, byteCount, part);
  }
  // Version 2 and 3's delta-coded varints back, for rows of the given starts.
  std::vector<uint32_t> takeRowNodes(const std::vector<uint32_t>& start, size_t byteCount, const char* part) {
    const std::vector<uint8_t> in = take<uint8_t>(byteCount, part);
    std::vector<uint32_t> node(start.back());
    size_t at = 0;
    for (size_t i = 0; i + 1 < start.size(); ++i)
      for (uint32_t e = start[i]; e < start[i + 1]; ++e) {
        uint64_t x = 0;
        for (int shift = 0;; shift += 7) {
          if (at >= in.size() || shift > 28)
            throw Error(cat(where_, ": ", part, ": row ", i, " ends inside a node index (corrupt)"));
          x |= uint64_t(in[at] & 0x7f) << shift;
          if (!(in[at++] & 0x80)) break;
        }
        if (e > start[i]) x += uint64_t(node[e - 1]) + 1;
        if (x > UINT32_MAX) throw Error(cat(where_, ": ", part, ": row ", i, " names a node beyond 2^32 (corrupt)"));
        node[e] = uint32_t(x);
      }
    if (at != in.size())
      throw Error(cat(where_, ": ", part, ": ", in.size(), " bytes, the rows use ", at, " (corrupt)"));
    return node;
  }
  std::vector<uint32_t> takeNodes(size_t count, int width, const char* part) {
    if (width == 4) return take<uint32_t>(count, part);
    const std::vector<uint16_t> narrow = take<uint16_t>(count, part);
    return {narrow.begin(), narrow.end()};
  }
  size_t used() const { return at_; }

 private:
  const uint8_t* p_;
  size_t size_, at_ = 0;
  std::string where_;
};

template <class Rows>
std::vector<uint8_t> lengths(const Rows& r) {
  std::vector<uint8_t> out(r.rows());
  for (size_t i = 0; i < out.size(); ++i) out[i] = uint8_t(r.start[i + 1] - r.start[i]);
  return out;
}

std::vector<uint32_t> startsFrom(const std::vector<uint8_t>& lengths) {
  std::vector<uint32_t> start(lengths.size() + 1, 0);
  for (size_t i = 0; i < lengths.size(); ++i) start[i + 1] = start[i] + lengths[i];
  return start;
}

std::string hex(uint64_t v) {
  std::ostringstream s;
  s << std::hex << std::setw(16) << std::setfill('0') << v;
  return s.str();
}

template <class Rows>
void checkRows(const Rows& r, size_t rows, size_t nodes, const std::string& where) {
  if (r.rows() != rows || r.start.front() != 0 || r.start.back() != r.node.size() || r.weight.size() != r.node.size())
    throw Error(
        cat(where, ": ", rows, " rows expected, the arrays hold ", r.rows(), " rows of ", r.node.size(), " entries"));
  for (size_t i = 0; i < rows; ++i) {
    if (r.start[i + 1] < r.start[i] || r.start[i + 1] - r.start[i] > uint32_t(BounceOperator::kMaxRowLength))
      throw Error(cat(where, ": row ", i, " has ", int64_t(r.start[i + 1]) - int64_t(r.start[i]), " entries (at most ",
                      BounceOperator::kMaxRowLength, ")"));
  }
  for (size_t e = 0; e < r.node.size(); ++e)
    if (r.node[e] >= nodes)
      throw Error(cat(where, ": entry ", e, " names node ", r.node[e], " of ", nodes, " (corrupt or truncated)"));
}

void checkTree(const BounceOperator& op, const std::string& where) {
  const size_t leaves = op.leaves(), nodes = op.nodes();
  if (op.children.size() % 2 != 0) throw Error(cat(where, ": children: an odd count, ", op.children.size()));
  std::vector<uint8_t> parents(nodes, 0);
  for (size_t i = 0; i < op.children.size(); ++i) {
    const size_t parent = leaves + i / 2;
    const uint32_t c = op.children[i];
    if (c >= parent) throw Error(cat(where, ": children: node ", parent, " has child ", c, " (children come first)"));
    if (++parents[c] > 1) throw Error(cat(where, ": children: node ", c, " has two parents"));
  }
  if (op.surfaceRoot >= nodes || op.skyRoot >= nodes || op.surfaceRoot == op.skyRoot)
    throw Error(cat(where, ": roots: ", op.surfaceRoot, " and ", op.skyRoot, " of ", nodes, " nodes"));
  for (size_t n = 0; n < nodes; ++n) {
    const bool root = n == op.surfaceRoot || n == op.skyRoot;
    if ((parents[n] == 0) != root)
      throw Error(cat(where, ": children: node ", n, root ? " is a root but has a parent" : " has no parent"));
  }
}

void checkClusters(const BounceOperator& op, const std::string& where) {
  if (op.albedo.size() != op.clusters || op.memberStart.size() != size_t(op.clusters) + 1 ||
      op.members.size() != op.vertexSides || op.memberStart.front() != 0 || op.memberStart.back() != op.vertexSides)
    throw Error(cat(where, ": clusters: ", op.clusters, " clusters of ", op.vertexSides,
                    " vertex sides expected, the arrays disagree"));
  for (size_t c = 0; c < op.clusters; ++c) {
    if (op.memberStart[c + 1] <= op.memberStart[c])
      throw Error(cat(where, ": clusters: cluster ", c, " has no members"));
    const glm::vec3 a = op.albedo[c];
    if (!(std::isfinite(a.x) && std::isfinite(a.y) && std::isfinite(a.z)) ||
        glm::any(glm::lessThan(a, glm::vec3(0.0f))))
      throw Error(cat(where, ": albedo: cluster ", c, " has albedo (", a.x, ", ", a.y, ", ", a.z, ")"));
  }
  std::vector<uint8_t> seen(op.vertexSides, 0);
  for (uint32_t m : op.members)
    if (m >= op.vertexSides || seen[m]++)
      throw Error(
          cat(where, ": members: vertex side ", m, m >= op.vertexSides ? " does not exist" : " is listed twice"));
}

void checkProbeRowArrays(const BounceOperator& op, const std::string& where) {
  const BounceOperator::ProbeRows& p = op.probeRows;
  const std::string at = cat(where, ": probe rows");
  if (glm::any(glm::lessThan(p.dims, glm::ivec3(1))) ||
      !(p.spacing.x > 0.0 && p.spacing.y > 0.0 && p.spacing.z > 0.0) ||
      !std::isfinite(p.origin.x + p.origin.y + p.origin.z + p.spacing.x + p.spacing.y + p.spacing.z) ||
      double(p.dims.x) * p.dims.y * p.dims.z > double(UINT32_MAX) || p.samples < 1 || p.bands < 1 || p.bands > 8)
    throw Error(cat(at, ": lattice ", p.dims.x, " x ", p.dims.y, " x ", p.dims.z, ", ", p.samples, " samples, ",
                    p.bands, " bands"));
  checkRows(p.rows, p.lattice.size(), op.nodes(), at);
  const uint64_t points = uint64_t(p.dims.x) * uint64_t(p.dims.y) * uint64_t(p.dims.z);
  for (size_t i = 0; i < p.lattice.size(); ++i)
    if (p.lattice[i] >= points || (i > 0 && p.lattice[i] <= p.lattice[i - 1]))
      throw Error(cat(at, ": row ", i, " names lattice point ", p.lattice[i], " (out of range or out of order)"));
  if (p.shape.size() != p.shapeStride() * p.rows.entries())
    throw Error(cat(at, ": ", p.shape.size(), " SH values for ", p.rows.entries(), " entries of ", p.bands, " bands"));
}

}  // namespace

void checkProbeRows(const BounceOperator& op, const glm::ivec3& dims, const glm::dvec3& origin,
                    const glm::dvec3& spacing, uint64_t seed, const std::vector<uint32_t>& lattice,
                    const std::string& where) {
  const BounceOperator::ProbeRows& p = op.probeRows;
  auto differ = [](const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& scale) {
    return glm::any(glm::greaterThan(glm::abs(a - b), 1e-5 * scale));
  };
  const std::string grid = "the probe grid was baked with other settings or from another bake";
  if (p.dims != dims || differ(p.origin, origin, spacing) || differ(p.spacing, spacing, spacing) || p.seed != seed)
    throw Error(cat(where, ": probe rows: made for a ", p.dims.x, " x ", p.dims.y, " x ", p.dims.z, " lattice (seed ",
                    p.seed, "), the grid is ", dims.x, " x ", dims.y, " x ", dims.z, " (seed ", seed, "): ", grid));
  if (p.lattice != lattice)
    throw Error(cat(where, ": probe rows: made for ", p.lattice.size(), " probes, the grid has ", lattice.size(),
                    " at other lattice points: ", grid));
}

uint64_t fnv1a64(const uint8_t* bytes, size_t size) {
  uint64_t h = 1469598103934665603ull;
  for (size_t i = 0; i < size; ++i) h = (h ^ bytes[i]) * 1099511628211ull;
  return h;
}

void checkOperator(const BounceOperator& op, const std::string& where) {
  if (op.samples < 1 || op.bounces < 0 || op.bounces > 64 || op.skyWidth < 1 || op.skyHeight < 1 ||
      op.samplePoints < 1 || op.clusters == 0)
    throw Error(cat(where, ": header: samples ", op.samples, ", bounces ", op.bounces, ", sky bins ", op.skyWidth,
                    " x ", op.skyHeight, ", sample points ", op.samplePoints, ", clusters ", op.clusters));
  if (op.leafWeight.size() != op.leaves())
    throw Error(cat(where, ": leaf weights: ", op.leafWeight.size(), " for ", op.leaves(), " leaves"));
  for (size_t i = 0; i < op.leafWeight.size(); ++i)
    if (!(op.leafWeight[i] > 0.0f) || !std::isfinite(op.leafWeight[i]))
      throw Error(cat(where, ": leaf weights: leaf ", i, " weighs ", op.leafWeight[i]));
  checkTree(op, where);
  checkClusters(op, where);
  if (op.skyBin.size() != op.skyBins())
    throw Error(cat(where, ": sky bins: ", op.skyBin.size(), " for ", op.skyBins()));
  std::vector<uint8_t> seen(op.skyBins(), 0);
  for (uint32_t b : op.skyBin)
    if (b >= op.skyBins() || seen[b]++) throw Error(cat(where, ": sky bins: bin ", b, " out of range or twice"));
  checkRows(op.vertexRows, op.vertexSides, op.nodes(), cat(where, ": vertex rows"));
  checkRows(op.clusterRows, op.clusters, op.nodes(), cat(where, ": cluster rows"));
  if (!op.clusterGradients.start.empty())
    checkRows(op.clusterGradients, 2 * size_t(op.clusters), op.nodes(), cat(where, ": cluster gradients"));
  if (op.probeRows.present()) checkProbeRowArrays(op, where);
}

std::vector<uint8_t> skyNodeMask(const BounceOperator& op) {
  std::vector<uint8_t> sky(op.nodes(), 0);
  for (size_t n = op.clusters; n < op.leaves(); ++n) sky[n] = 1;
  for (size_t i = 0; i < op.children.size() / 2; ++i)
    sky[op.leaves() + i] = sky[op.children[2 * i]] | sky[op.children[2 * i + 1]];
  return sky;
}

std::vector<float> nodeWeights(const BounceOperator& op) {
  std::vector<float> w(op.nodes(), 0.0f);
  for (size_t n = 0; n < op.leaves(); ++n) w[n] = op.leafWeight[n];
  for (size_t i = 0; i < op.children.size() / 2; ++i)
    w[op.leaves() + i] = w[op.children[2 * i]] + w[op.children[2 * i + 1]];
  return w;
}

namespace {

std::vector<uint8_t> codesOf(const std::vector<uint16_t>& weights) {
  std::vector<uint8_t> out(weights.size());
  for (size_t i = 0; i < weights.size(); ++i) out[i] = BounceOperator::codeOfWeight(weights[i]);
  return out;
}

std::vector<int8_t> codesOf(const std::vector<int16_t>& weights) {
  std::vector<int8_t> out(weights.size());
  for (size_t i = 0; i < weights.size(); ++i) out[i] = BounceOperator::codeOfGradient(weights[i]);
  return out;
}

}  // namespace

PackedOperator packOperator(const BounceOperator& op) {
  checkOperator(op, "bounce operator");
  Packer p;
  std::vector<float> albedo(size_t(op.clusters) * 3);
  std::memcpy(albedo.data(), op.albedo.data(), albedo.size() * sizeof(float));
  p.put(op.leafWeight);
  p.put(op.children);
  p.put(albedo);
  p.put(op.memberStart);
  p.put(op.members);
  p.put(op.skyBin);
  BounceOperator::SignedRows none;
  none.start.assign(2 * size_t(op.clusters) + 1, 0);
  const BounceOperator::SignedRows& g = op.clusterGradients.start.empty() ? none : op.clusterGradients;
  const cuts::CutTrees trees(op);
  Json nodeBytes;
  p.put(lengths(op.vertexRows));
  nodeBytes["vertex"] = p.putRowCuts(op.vertexRows, trees);
  p.put(codesOf(op.vertexRows.weight));
  p.put(lengths(op.clusterRows));
  nodeBytes["cluster"] = p.putRowCuts(op.clusterRows, trees);
  p.put(codesOf(op.clusterRows.weight));
  p.put(lengths(g));
  nodeBytes["gradient"] = p.putRowCuts(g, trees);
  p.put(codesOf(g.weight));
  const BounceOperator::ProbeRows& pr = op.probeRows;
  Json probes;
  if (pr.present()) {
    p.put(pr.lattice);
    p.put(lengths(pr.rows));
    probes["node_bytes"] = p.putRowCuts(pr.rows, trees);
    p.put(codesOf(pr.rows.weight));
    p.put(pr.shape);
    probes["bands"] = pr.bands;
    probes["samples"] = pr.samples;
    probes["row_length"] = pr.rowLength;
    probes["dims"] = {pr.dims.x, pr.dims.y, pr.dims.z};
    probes["origin"] = {pr.origin.x, pr.origin.y, pr.origin.z};
    probes["spacing"] = {pr.spacing.x, pr.spacing.y, pr.spacing.z};
    probes["seed"] = std::to_string(pr.seed);
    probes["probes"] = pr.lattice.size();
    probes["entries"] = pr.rows.entries();
  }
  while (p.bytes.size() % 4 != 0) p.bytes.push_back(0);
  Json h;
  h["version"] = BounceOperator::kVersion;
  h["samples"] = op.samples;
  h["bounces"] = op.bounces;
  h["seed"] = std::to_string(op.seed);
  h["cluster_size"] = op.clusterSize;
  h["row_length"] = op.rowLength;
  h["cluster_row_length"] = op.clusterRowLength;
  h["gradient_row_length"] = op.gradientRowLength;
  h["vertex_sides"] = op.vertexSides;
  h["clusters"] = op.clusters;
  h["sky_bins"] = {op.skyWidth, op.skyHeight};
  h["sample_points"] = op.samplePoints;
  h["inner_nodes"] = op.children.size() / 2;
  h["roots"] = {op.surfaceRoot, op.skyRoot};
  h["row_node_bytes"] = nodeBytes;
  h["vertex_entries"] = op.vertexRows.entries();
  h["cluster_entries"] = op.clusterRows.entries();
  h["gradient_entries"] = g.entries();
  if (pr.present()) h["probe_rows"] = probes;
  h["byte_length"] = p.bytes.size();
  h["checksum"] = hex(fnv1a64(p.bytes.data(), p.bytes.size()));
  return {h.dump(), std::move(p.bytes)};
}

namespace {

template <class T>
T field(const Json& h, const char* key, const std::string& where) {
  if (!h.contains(key)) throw Error(cat(where, ": header: no \"", key, "\""));
  try {
    return h.at(key).get<T>();
  } catch (const Json::exception&) {
    throw Error(cat(where, ": header: \"", key, "\" is ", h.at(key).dump(), ", not a value of the right type"));
  }
}

BounceOperator headerOf(const Json& h, const std::string& where) {
  const int version = field<int>(h, "version", where);
  if (version < 1 || version > BounceOperator::kVersion)
    throw Error(cat(where, ": header: version ", version, "; this prt reads version ", BounceOperator::kVersion,
                    " (bake the scene again)"));
  BounceOperator op;
  op.version = version;
  op.samples = field<int>(h, "samples", where);
  op.bounces = field<int>(h, "bounces", where);
  const std::string seed = field<std::string>(h, "seed", where);
  try {
    op.seed = std::stoull(seed);
  } catch (const std::exception&) {
    throw Error(cat(where, ": header: seed \"", seed, "\" is not a number"));
  }
  op.clusterSize = field<int>(h, "cluster_size", where);
  op.rowLength = field<int>(h, "row_length", where);
  op.clusterRowLength = field<int>(h, "cluster_row_length", where);
  if (version >= 2) op.gradientRowLength = field<int>(h, "gradient_row_length", where);
  op.vertexSides = field<uint32_t>(h, "vertex_sides", where);
  op.clusters = field<uint32_t>(h, "clusters", where);
  const auto bins = field<std::vector<int>>(h, "sky_bins", where);
  const auto roots = field<std::vector<uint32_t>>(h, "roots", where);
  if (bins.size() != 2 || roots.size() != 2) throw Error(cat(where, ": header: sky_bins and roots hold two values"));
  op.skyWidth = bins[0];
  op.skyHeight = bins[1];
  op.surfaceRoot = roots[0];
  op.skyRoot = roots[1];
  op.samplePoints = field<int>(h, "sample_points", where);
  if (op.skyWidth < 1 || op.skyHeight < 1 || op.skyWidth > 4096 || op.skyHeight > 4096)
    throw Error(cat(where, ": header: sky bins ", op.skyWidth, " x ", op.skyHeight));
  return op;
}

uint64_t seedOf(const std::string& text, const std::string& where) {
  try {
    size_t used = 0;
    const uint64_t v = std::stoull(text, &used);
    if (used == text.size()) return v;
  } catch (const std::exception&) {}
  throw Error(cat(where, ": header: seed \"", text, "\" is not a number"));
}

// The probe rows' header (`h`, the header's "probe_rows") and arrays.
void takeProbeRows(BounceOperator& op, const Json& h, Unpacker& u, const cuts::CutTrees* trees,
                   const std::string& where) {
  const std::string at = cat(where, ": probe rows");
  BounceOperator::ProbeRows& p = op.probeRows;
  p.bands = field<int>(h, "bands", at);
  if (p.bands < 1 || p.bands > 8) throw Error(cat(at, ": header: ", p.bands, " bands"));
  p.samples = field<int>(h, "samples", at);
  p.rowLength = field<int>(h, "row_length", at);
  const auto dims = field<std::vector<int>>(h, "dims", at);
  const auto origin = field<std::vector<double>>(h, "origin", at);
  const auto spacing = field<std::vector<double>>(h, "spacing", at);
  if (dims.size() != 3 || origin.size() != 3 || spacing.size() != 3)
    throw Error(cat(at, ": header: dims, origin and spacing hold three values"));
  p.dims = glm::ivec3(dims[0], dims[1], dims[2]);
  p.origin = glm::dvec3(origin[0], origin[1], origin[2]);
  p.spacing = glm::dvec3(spacing[0], spacing[1], spacing[2]);
  p.seed = seedOf(field<std::string>(h, "seed", at), at);
  const size_t probes = field<size_t>(h, "probes", at), entries = field<size_t>(h, "entries", at);
  p.lattice = u.take<uint32_t>(probes, "probe row lattice points");
  p.rows.start = startsFrom(u.take<uint8_t>(probes, "probe row lengths"));
  p.rows.node = u.takeRowNodesOf(p.rows.start, field<size_t>(h, "node_bytes", at), trees, "probe row nodes");
  p.rows.weight = u.takeWeights(entries, op.version, "probe row weights");
  p.shape = u.take<int8_t>(p.shapeStride() * entries, "probe row SH");
}

}  // namespace

BounceOperator unpackOperator(const std::string& headerText, const uint8_t* bytes, size_t size,
                              const std::string& where) {
  Json h;
  try {
    h = Json::parse(headerText);
  } catch (const Json::exception& e) {
    throw Error(cat(where, ": header: not JSON (", e.what(), ")"));
  }
  if (!h.is_object()) throw Error(cat(where, ": header: not a JSON object"));
  BounceOperator op = headerOf(h, where);
  const size_t byteLength = field<size_t>(h, "byte_length", where);
  if (byteLength != size)
    throw Error(cat(where, ": bytes: ", size, " bytes, the header says ", byteLength, " (truncated or corrupt)"));
  if (field<std::string>(h, "checksum", where) != hex(fnv1a64(bytes, size)))
    throw Error(cat(where, ": bytes: their checksum is not the header's (the file is corrupt)"));
  const int version = op.version;
  const int width = version == 1 ? field<int>(h, "node_index_bytes", where) : 0;
  const Json nodeBytes = version == 1 ? Json() : field<Json>(h, "row_node_bytes", where);
  auto bytesOf = [&](const char* rows) {
    if (!nodeBytes.contains(rows) || !nodeBytes.at(rows).is_number_unsigned())
      throw Error(cat(where, ": header: row_node_bytes has no count for the ", rows, " rows"));
    return nodeBytes.at(rows).get<size_t>();
  };
  const size_t inner = field<size_t>(h, "inner_nodes", where);
  const size_t vertexEntries = field<size_t>(h, "vertex_entries", where);
  const size_t clusterEntries = field<size_t>(h, "cluster_entries", where);
  if (version == 1 && width != 2 && width != 4)
    throw Error(cat(where, ": header: node_index_bytes ", width, " (2 or 4)"));
  Unpacker u(bytes, size, where);
  op.leafWeight = u.take<float>(op.leaves(), "leaf weights");
  op.children = u.take<uint32_t>(2 * inner, "children");
  const std::vector<float> albedo = u.take<float>(size_t(op.clusters) * 3, "albedo");
  op.albedo.resize(op.clusters);
  std::memcpy(op.albedo.data(), albedo.data(), albedo.size() * sizeof(float));
  op.memberStart = u.take<uint32_t>(size_t(op.clusters) + 1, "member starts");
  op.members = u.take<uint32_t>(op.vertexSides, "members");
  op.skyBin = u.take<uint32_t>(op.skyBins(), "sky bins");
  // Version 4's rows are walks of the trees: checked first, so that every walk ends.
  std::optional<cuts::CutTrees> cutTrees;
  if (version >= 4) {
    checkTree(op, where);
    cutTrees.emplace(op);
  }
  const cuts::CutTrees* trees = cutTrees ? &*cutTrees : nullptr;
  op.vertexRows.start = startsFrom(u.take<uint8_t>(op.vertexSides, "vertex row lengths"));
  op.vertexRows.node = version == 1
                           ? u.takeNodes(vertexEntries, width, "vertex row nodes")
                           : u.takeRowNodesOf(op.vertexRows.start, bytesOf("vertex"), trees, "vertex row nodes");
  op.vertexRows.weight = u.takeWeights(vertexEntries, version, "vertex row weights");
  op.clusterRows.start = startsFrom(u.take<uint8_t>(op.clusters, "cluster row lengths"));
  op.clusterRows.node = version == 1
                            ? u.takeNodes(clusterEntries, width, "cluster row nodes")
                            : u.takeRowNodesOf(op.clusterRows.start, bytesOf("cluster"), trees, "cluster row nodes");
  op.clusterRows.weight = u.takeWeights(clusterEntries, version, "cluster row weights");
  if (version >= 2) {
    const size_t gradientEntries = field<size_t>(h, "gradient_entries", where);
    op.clusterGradients.start = startsFrom(u.take<uint8_t>(2 * size_t(op.clusters), "cluster gradient lengths"));
    op.clusterGradients.node =
        u.takeRowNodesOf(op.clusterGradients.start, bytesOf("gradient"), trees, "cluster gradient nodes");
    op.clusterGradients.weight = u.takeGradients(gradientEntries, version, "cluster gradient weights");
  }
  if (version >= 3 && h.contains("probe_rows")) takeProbeRows(op, field<Json>(h, "probe_rows", where), u, trees, where);
  if ((u.used() + 3) / 4 * 4 != size)
    throw Error(cat(where, ": bytes: ", size, " bytes, the arrays fill ", u.used(), " (corrupt)"));
  checkOperator(op, where);
  return op;
}

}  // namespace prt
