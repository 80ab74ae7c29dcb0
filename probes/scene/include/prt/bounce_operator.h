// The direct-to-indirect operator a bake stores beside its transfer (docs/lights.md, "The bounce
// operator"; its bytes: docs/formats.md, "The bounce operator"). It maps the light that arrives
// directly at the baked surfaces (suns and disks with their shadows, the sky's detail beyond the
// SH band limit) to the light those surfaces send on, at every baked vertex side, after the
// bake's bounce count, as sparse rows over a tree of nodes:
//   E(row) = Σ_{entries (n, w) of the row} w · value(n).
// Its leaves are surface clusters (patches of a few vertex sides of similar position and
// normal) and sky bins (cells of an equirectangular grid of world directions); an inner node
// stands for the leaves below it, its value their area-weighted (solid-angle-weighted) mean.
// A cluster's row is its members' gather rays (the bake's first `samples` rays of each): the
// share that hits each cluster or escapes through each bin, with far or faint shares merged into
// the coarsest node that keeps the row within its length. Cluster rows carry the bounces after
// the first (cluster to cluster) and what a cluster's vertex sides receive; a vertex side whose
// view differs from its cluster's has a row of its own instead. What the values are at each
// light change, and how a vertex side shares its cluster's light, is prt::bake's
// (prt/bake/bounce_operator.h); this header says what the operator is, and checks it.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <glm/glm.hpp>

namespace prt {

struct BounceOperator {
  static constexpr int kVersion = 4;  // 1 had no cluster gradients, 2 no probe rows, 3 two-byte weights; all still read
  static constexpr int kMaxRowLength = 255;      // entries in one row (its length is stored in a byte)
  static constexpr uint32_t kWeightOne = 65535;  // a weight is held as q = w · kWeightOne, rounded
  static constexpr int kGradientOne = 16384;     // a gradient weight g (|g| < 2) as g · kGradientOne

  /// Version 4 stores a row weight q (vertex, cluster and probe rows) in one byte, its code:
  /// codes 0 … 31 are q itself, codes 32 … 255 grow by 3.5% each from 32 to 65535, rounded (every
  /// code a different q). A bake holds its rows' weights on these values (storedWeight), so what
  /// it writes is what it built.
  static uint16_t weightOfCode(uint8_t code);
  /// The code whose weight is nearest q (the lower on a tie).
  static uint8_t codeOfWeight(uint16_t q);
  /// A row's weights put on the codes' values: `scaled` holds each entry's w · kWeightOne
  /// (unrounded, in [0, kWeightOne]); each becomes the code value just below or just above it,
  /// chosen from the largest entry down so that the row's sum stays what it was (to half the
  /// step of its smallest entries: no light is gained or lost). Zeros are entries to drop.
  /// `exact`: each rounded to the nearest integer instead (an uncompressed operator, which is
  /// never stored).
  static std::vector<uint16_t> storedWeights(const std::vector<double>& scaled, bool exact = false);
  /// Version 4 stores a gradient weight g · kGradientOne in one signed byte: its sign and a
  /// magnitude code 0 … 127, codes 0 … 15 the magnitude itself, codes 16 … 127 growing by 7.1%
  /// each from 16 to 32767, rounded (−128 reads as −127).
  static int16_t gradientOfCode(int8_t code);
  /// The code whose gradient weight is nearest g (the lower magnitude on a tie).
  static int8_t codeOfGradient(int16_t g);
  /// A gradient row's weights (g · kGradientOne, unrounded, |·| ≤ 32767) on the codes' values,
  /// as storedWeights puts a row's: the row's sum kept (`exact`: rounded instead).
  static std::vector<int16_t> storedGradients(const std::vector<double>& scaled, bool exact = false);

  int version = kVersion;  // of the file it was read from

  // How it was built (informative, and checked against the bake record).
  int samples = 0;      // gather rays per vertex side: the bake's first ones
  int bounces = 0;      // the bake's bounce count
  uint64_t seed = 0;    // the bake's seed (its ray streams)
  int clusterSize = 0;  // the largest cluster asked for
  int rowLength = 0;    // the longest vertex row asked for
  int clusterRowLength = 0;
  int gradientRowLength = 0;  // the longest cluster gradient row asked for (0 in version 1)

  uint32_t vertexSides = 0;         // the bake's numbering: every baked instance's vertices, then the back sides
  uint32_t clusters = 0;            // surface leaves: nodes [0, clusters)
  int skyWidth = 0, skyHeight = 0;  // sky leaves: nodes [clusters, clusters + skyWidth · skyHeight)
  int samplePoints = 0;             // the first ones of each cluster's members stand for it under shadow rays

  /// Per leaf: its area (a cluster, m² in scene units) or solid angle (a bin, sr).
  std::vector<float> leafWeight;
  /// Two per inner node: inner node leaves() + i has children[2i] and children[2i + 1], both of
  /// smaller index (children before parents).
  std::vector<uint32_t> children;
  uint32_t surfaceRoot = 0, skyRoot = 0;
  /// Per cluster: the area-weighted mean diffuse albedo of its members (linear RGB).
  std::vector<glm::vec3> albedo;
  /// Per cluster c: its vertex sides members[memberStart[c] .. memberStart[c + 1]); every vertex
  /// side is in exactly one cluster.
  std::vector<uint32_t> memberStart;
  std::vector<uint32_t> members;
  /// Per sky leaf: its bin, y · skyWidth + x (x along u, y along v of prt/light.h's equirectUv).
  std::vector<uint32_t> skyBin;

  /// Sparse rows, CSR: row r's entries are [start[r], start[r + 1]).
  template <class Weight>
  struct RowsOf {
    std::vector<uint32_t> start;
    std::vector<uint32_t> node;
    std::vector<Weight> weight;
    size_t rows() const { return start.empty() ? 0 : start.size() - 1; }
    size_t entries() const { return node.size(); }
  };
  using Rows = RowsOf<uint16_t>;       // weights w · kWeightOne
  using SignedRows = RowsOf<int16_t>;  // weights g · kGradientOne
  Rows vertexRows;                     // one per vertex side
  Rows clusterRows;                    // one per cluster
  /// Two per cluster c, rows 2c and 2c + 1: how its members' gathers change across it, along
  /// the two axes of its plane (clusterFrame), per unit of its radius. A member at (s, t) in
  /// that frame gathers row(c) + s · gradient(2c) + t · gradient(2c + 1). Empty in version 1.
  SignedRows clusterGradients;

  /// The probes' rows (version 3; absent in older files and in bakes without probes): per probe
  /// of one probe grid, the share w of its gather rays that lands on each node and the mean SH
  /// of their directions ȳ_j, each coefficient j ≥ 1 stored as ȳ_j / b_l (b_l = √((2l + 1)/4π)
  /// bounds |y_lm| on band l), ȳ_0 being y_0. A probe's incident-radiance SH gains, per channel,
  ///   c_j += 4 Σ_{entries (n, w, ȳ)} w · ȳ_j · value(n),
  /// value(n) the node's π × radiance (OperatorLighting's node values): docs/lights.md,
  /// "Probes through the operator".
  struct ProbeRows {
    static constexpr int kShapeOne = 127;  // ȳ_j / b_l as that · kShapeOne, rounded
    int bands = 0;
    int samples = 0;    // gather rays per probe: the probe bake's first ones
    int rowLength = 0;  // the longest row asked for
    // The grid they belong to, as its .vdb records it: checked when both are read (checkProbeRows).
    glm::ivec3 dims{0};
    glm::dvec3 origin{0.0}, spacing{0.0};
    uint64_t seed = 0;  // the probe bake's
    /// Per row: its probe's lattice index x + dims.x · (y + dims.y · z), ascending.
    std::vector<uint32_t> lattice;
    Rows rows;                  // weights: the share of the probe's rays, w · kWeightOne
    std::vector<int8_t> shape;  // bands² − 1 per entry: ȳ_j / b_l · kShapeOne, j = 1 … bands² − 1
    bool present() const { return !rows.start.empty(); }
    size_t shapeStride() const { return size_t(bands) * size_t(bands) - 1; }
  };
  ProbeRows probeRows;

  size_t skyBins() const { return size_t(skyWidth) * size_t(skyHeight); }
  size_t leaves() const { return clusters + skyBins(); }
  size_t nodes() const { return leaves() + children.size() / 2; }
};

/// The operator as stored: a JSON header (text) and the bytes of its arrays, in the order and
/// widths docs/formats.md lists.
struct PackedOperator {
  std::string header;
  std::vector<uint8_t> bytes;
};

/// Packs `op` (which must pass checkOperator).
PackedOperator packOperator(const BounceOperator& op);

/// Reads a packed operator. Throws prt::Error "WHERE: PART: problem" when the header is not
/// one this prt reads (version, fields), the bytes are truncated or corrupt (their checksum),
/// or the arrays are inconsistent (checkOperator).
BounceOperator unpackOperator(const std::string& header, const uint8_t* bytes, size_t size, const std::string& where);

/// Throws prt::Error "WHERE: PART: problem" unless every array has its size and every index
/// is in range: children before parents and each node but the two roots a child once, members
/// a partition of the vertex sides, sky bins each once, rows within their length limit over
/// existing nodes, weights and albedos finite.
void checkOperator(const BounceOperator& op, const std::string& where);

/// Per node, 1 if it is a sky leaf or has sky leaves below it (the sky tree), else 0.
std::vector<uint8_t> skyNodeMask(const BounceOperator& op);

/// Per node, the area (surface tree) or solid angle (sky tree) of the leaves below it.
std::vector<float> nodeWeights(const BounceOperator& op);

/// Throws prt::Error "WHERE: probe rows: problem" unless op's probe rows (present) belong to the
/// probe grid of lattice `dims`, `origin`, `spacing` and seed `seed` whose active probes have the
/// lattice indices `lattice` (ascending).
void checkProbeRows(const BounceOperator& op, const glm::ivec3& dims, const glm::dvec3& origin,
                    const glm::dvec3& spacing, uint64_t seed, const std::vector<uint32_t>& lattice,
                    const std::string& where);

/// FNV-1a (64 bits) of `size` bytes: the checksum the header records.
uint64_t fnv1a64(const uint8_t* bytes, size_t size);

}  // namespace prt
