// The bounce operator in a baked glTF file (docs/formats.md, "The bounce operator"): its header
// as asset.extras.prt_operator, its bytes in one buffer view that header names. Read by the
// reader (loadScene), written by writeBakedScene, kept by the packing of buffers (gltf_glb.cpp).
#include <memory>
#include <string>

#include <nlohmann/json.hpp>

#include "gltf_glb.h"
#include "gltf_operator.h"
#include "prt/bounce_operator.h"
#include "prt/error.h"

namespace prt::gltf {

namespace {

using Json = nlohmann::json;
constexpr const char* kKey = "prt_operator";

const tinygltf::Value* operatorValue(const tinygltf::Model& m) {
  const tinygltf::Value& extras = m.asset.extras;
  if (!extras.IsObject() || !extras.Has(kKey)) return nullptr;
  return &extras.Get(kKey);
}

}  // namespace

int operatorBufferView(const tinygltf::Model& m) {
  const tinygltf::Value* v = operatorValue(m);
  if (!v || !v->IsObject() || !v->Has("bufferView") || !v->Get("bufferView").IsInt()) return -1;
  return v->Get("bufferView").Get<int>();
}

void setOperatorBufferView(tinygltf::Model& m, int view) {
  if (!operatorValue(m)) return;
  auto& extras = m.asset.extras.Get<tinygltf::Value::Object>();
  tinygltf::Value::Object o = extras[kKey].Get<tinygltf::Value::Object>();
  o["bufferView"] = tinygltf::Value(view);
  extras[kKey] = tinygltf::Value(std::move(o));
}

void dropOperator(tinygltf::Model& m) {
  if (!operatorValue(m)) return;
  m.asset.extras.Get<tinygltf::Value::Object>().erase(kKey);
}

void storeOperator(tinygltf::Model& m, int& staging, const BounceOperator& op) {
  const PackedOperator packed = packOperator(op);
  const int view = appendBufferView(m, stagingBuffer(m, staging), packed.bytes.data(), packed.bytes.size(), 0);
  m.bufferViews[size_t(view)].name = "prt bounce operator";
  tinygltf::Value::Object o;
  o["header"] = tinygltf::Value(packed.header);
  o["bufferView"] = tinygltf::Value(view);
  if (!m.asset.extras.IsObject()) m.asset.extras = tinygltf::Value(tinygltf::Value::Object{});
  m.asset.extras.Get<tinygltf::Value::Object>()[kKey] = tinygltf::Value(std::move(o));
}

std::shared_ptr<const BounceOperator> readOperator(const Gltf& g, const Scene& scene) {
  const tinygltf::Value* v = operatorValue(g.model);
  if (!v) return nullptr;
  const std::string where = cat(g.path, ": asset.extras.", kKey);
  if (!v->IsObject() || !v->Has("header") || !v->Get("header").IsString())
    throw Error(cat(where, ": header: missing (a JSON text under \"header\" is expected)"));
  const int view = operatorBufferView(g.model);
  const tinygltf::Model& m = g.model;
  if (view < 0 || size_t(view) >= m.bufferViews.size())
    throw Error(cat(where, ": bufferView: ", view, " does not exist (the file has ", m.bufferViews.size(), ")"));
  const tinygltf::BufferView& bv = m.bufferViews[size_t(view)];
  if (bv.buffer < 0 || size_t(bv.buffer) >= m.buffers.size())
    throw Error(cat(where, ": bufferView ", view, ": buffer ", bv.buffer, " does not exist"));
  const std::vector<unsigned char>& data = m.buffers[size_t(bv.buffer)].data;
  if (bv.byteOffset > data.size() || bv.byteLength > data.size() - bv.byteOffset)
    throw Error(cat(where, ": bufferView ", view, ": runs past the end of its buffer (the file is truncated)"));
  auto op = std::make_shared<BounceOperator>(
      unpackOperator(v->Get("header").Get<std::string>(), data.data() + bv.byteOffset, bv.byteLength, where));
  size_t sides = 0;
  for (const MeshInstance& inst : scene.meshes) {
    if (inst.receiverOnly || inst.transfer.empty()) continue;
    sides += inst.vertexCount() * (inst.hasBackTransfer() ? 2 : 1);
  }
  if (sides != op->vertexSides)
    throw Error(cat(where, ": vertex_sides: ", op->vertexSides, ", but the scene's baked primitives have ", sides,
                    " vertex sides (the operator does not belong to this scene)"));
  return op;
}

}  // namespace prt::gltf
