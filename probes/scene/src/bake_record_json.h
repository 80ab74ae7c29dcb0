// The bake record as JSON (asset.extras.prt): the one writer and the one reader, shared by
// gltf_write.cpp and gltf_read.cpp, which convert it to and from tinygltf values.
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "prt/bake_record.h"

namespace prt::gltf {

/// The record as written: every field, the layout version, the fixed descriptions.
nlohmann::json bakeRecordToJson(const BakeRecord& record);

/// Reads and validates a record. `where` begins every message ("scene.glb: asset.extras.prt"),
/// followed by the field: "scene.glb: asset.extras.prt.bands: expected an integer 1..8, got
/// \"x\"". The layout version is checked first (a newer layout may mean other fields). Keys
/// this prt does not know are ignored: additions that keep the meaning of the others do not
/// change the layout version. Throws prt::Error.
BakeRecord bakeRecordFromJson(const nlohmann::json& j, const std::string& where);

}  // namespace prt::gltf
