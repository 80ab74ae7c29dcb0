// A tiny glTF writer for tests: JSON with one base64 data: buffer, nodes, meshes, cameras and
// animations built in code, written to a temporary .gltf that loadScene reads like any file;
// and a .glb reader that reads what prt wrote without prt's reader.
#pragma once

#include <unistd.h>

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "harness.h"
#include "prt/error.h"
#include "prt/scene.h"

namespace prt::test {

struct GltfFile {
  using Json = nlohmann::json;
  Json j;
  std::vector<unsigned char> bin;

  GltfFile() {
    j = {{"asset", {{"version", "2.0"}}},
         {"scene", 0},
         {"scenes", Json::array({{{"nodes", Json::array()}}})},
         {"nodes", Json::array()},
         {"meshes", Json::array()},
         {"accessors", Json::array()},
         {"bufferViews", Json::array()},
         {"animations", Json::array()}};
    // One triangle mesh (mesh 0) for the nodes to carry.
    const int pos = accessor({0, 0, 0, 1, 0, 0, 0, 1, 0}, "VEC3");
    j["meshes"].push_back({{"primitives", Json::array({{{"attributes", {{"POSITION", pos}}}}})}});
  }
  /// Appends 4-byte values as a buffer view and an accessor of `type` (SCALAR, VEC2, VEC3, VEC4).
  template <typename T>
  int accessor(const std::vector<T>& data, const char* type, int componentType = 5126) {
    static_assert(sizeof(T) == 4);
    const size_t offset = bin.size();
    bin.resize(offset + data.size() * 4);
    std::memcpy(bin.data() + offset, data.data(), data.size() * 4);
    const std::string t(type);
    const int width = t == "SCALAR" ? 1 : t == "VEC2" ? 2 : t == "VEC3" ? 3 : 4;
    j["bufferViews"].push_back({{"buffer", 0}, {"byteOffset", offset}, {"byteLength", data.size() * 4}});
    j["accessors"].push_back({{"bufferView", j["bufferViews"].size() - 1},
                              {"componentType", componentType},
                              {"count", data.size() / size_t(width)},
                              {"type", type}});
    return int(j["accessors"].size() - 1);
  }
  int accessor(const std::vector<float>& data, const char* type) { return accessor<float>(data, type, 5126); }
  /// Adds an indexed triangle mesh (xyz per vertex; normals as many as positions) of material
  /// `material` (-1: the glTF default, white); returns its index.
  int mesh(const std::vector<float>& positions, const std::vector<float>& normals, const std::vector<uint32_t>& indices,
           int material = -1) {
    Json prim = {{"attributes", {{"POSITION", accessor(positions, "VEC3")}, {"NORMAL", accessor(normals, "VEC3")}}},
                 {"indices", accessor<uint32_t>(indices, "SCALAR", 5125)}};
    if (material >= 0) prim["material"] = material;
    j["meshes"].push_back({{"primitives", Json::array({prim})}});
    return int(j["meshes"].size() - 1);
  }
  /// The same from an in-memory mesh (tests/test_scenes.h builders): its positions, normals
  /// and triangles become the mesh's local coordinates.
  int mesh(const MeshInstance& m, int material = -1) {
    std::vector<float> positions, normals;
    for (size_t v = 0; v < m.vertexCount(); ++v)
      for (int c = 0; c < 3; ++c) {
        positions.push_back(m.positions[v][c]);
        normals.push_back(m.normals[v][c]);
      }
    return mesh(positions, normals, m.indices, material);
  }
  int node(Json n, bool root) {
    j["nodes"].push_back(std::move(n));
    const int index = int(j["nodes"].size() - 1);
    if (root) j["scenes"][0]["nodes"].push_back(index);
    return index;
  }
  /// Adds an animation with one sampler per channel: {node, path, times, values, interpolation}.
  struct Channel {
    int node;
    std::string path;
    std::vector<float> times;
    std::vector<float> values;
    std::string interpolation = "LINEAR";
  };
  void animation(const std::string& name, const std::vector<Channel>& channels) {
    Json a = {{"name", name}, {"channels", Json::array()}, {"samplers", Json::array()}};
    for (const Channel& c : channels) {
      const int in = accessor(c.times, "SCALAR");
      const int out = accessor(c.values, c.path == "rotation" ? "VEC4" : "VEC3");
      a["samplers"].push_back({{"input", in}, {"output", out}, {"interpolation", c.interpolation}});
      a["channels"].push_back(
          {{"sampler", a["samplers"].size() - 1}, {"target", {{"node", c.node}, {"path", c.path}}}});
    }
    j["animations"].push_back(a);
  }
  /// Writes the file as `dir`/prt_anim_PID_NAME.gltf (default: the temporary folder).
  std::string write(const std::string& name,
                    const std::filesystem::path& dir = std::filesystem::temp_directory_path()) {
    j["buffers"] =
        Json::array({{{"byteLength", bin.size()}, {"uri", "data:application/octet-stream;base64," + base64(bin)}}});
    const std::filesystem::path p = dir / cat("prt_anim_", ::getpid(), "_", name, ".gltf");
    std::ofstream(p) << j.dump();
    return p.string();
  }
};

// A .glb read by hand (JSON chunk, BIN chunk): the test checks the file, not prt's reader.
struct Glb {
  using Json = nlohmann::json;
  Json j;
  std::string bin;
  explicit Glb(const std::string& path) {
    const std::string bytes = test::fileBytes(path);
    uint32_t jsonLength = 0, binLength = 0;
    std::memcpy(&jsonLength, bytes.data() + 12, 4);
    j = Json::parse(bytes.substr(20, jsonLength));
    std::memcpy(&binLength, bytes.data() + 20 + jsonLength, 4);
    bin = bytes.substr(28 + jsonLength, binLength);
  }
  // Float or UNSIGNED_INT values of accessor `a`, `n` per element.
  template <typename T>
  std::vector<T> values(int a, int n) const {
    const Json& acc = j["accessors"][size_t(a)];
    const Json& view = j["bufferViews"][acc["bufferView"].get<size_t>()];
    const size_t stride = view.value("byteStride", size_t(n) * sizeof(T));
    const size_t offset = view.value("byteOffset", size_t(0)) + acc.value("byteOffset", size_t(0));
    std::vector<T> out(acc["count"].get<size_t>() * size_t(n));
    for (size_t i = 0; i < acc["count"].get<size_t>(); ++i)
      std::memcpy(&out[i * size_t(n)], bin.data() + offset + i * stride, size_t(n) * sizeof(T));
    return out;
  }
  const Json& primitive(const std::string& node) const {
    for (const Json& n : j["nodes"])
      if (n.value("name", "") == node) return j["meshes"][n["mesh"].get<size_t>()]["primitives"][0];
    throw Error("no node " + node);
  }
};

}  // namespace prt::test
