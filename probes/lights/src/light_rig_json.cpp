// The light rig's JSON reader (parseLightRig, loadLightRig): structure here (types, shapes,
// unknown keys, sizes), values in LightRig::validate() (light_rig.cpp). The format is in
// docs/lights.md.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "light_rig_checks.h"
#include "prt/atomic_file.h"
#include "prt/error.h"
#include "prt/image.h"
#include "prt/light_rig.h"

namespace prt {

using detail::checkFps;

namespace {

constexpr int kRigVersion = 1;

using Json = nlohmann::json;

size_t editDistance(const std::string& a, const std::string& b) {
  std::vector<size_t> row(b.size() + 1);
  for (size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (size_t i = 1; i <= a.size(); ++i) {
    size_t diag = row[0];
    row[0] = i;
    for (size_t j = 1; j <= b.size(); ++j) {
      size_t up = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diag + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diag = up;
    }
  }
  return row[b.size()];
}

std::string quoteList(const std::vector<std::string>& names) {
  std::string s;
  for (const std::string& n : names) s += (s.empty() ? "" : ", ") + n;
  return s;
}

enum class Shape { Scalar, Color, Direction, Position };

// A JSON value for a message: compact, and cut short so the message stays one readable line.
std::string shortDump(const nlohmann::json& j) { return printable(j.dump()); }

// nlohmann's message without its "[json.exception.parse_error.101] " tag, the token it quotes
// ('...', the file's bytes) cut short.
std::string jsonProblem(const Json::exception& e) {
  std::string what = e.what();
  const size_t close = what.find("] ");
  if (close != std::string::npos) what = what.substr(close + 2);
  const size_t quote = what.find('\'');
  if (quote == std::string::npos) return printable(what, 200);
  return printable(what.substr(0, quote + 1), 200) + printable(what.substr(quote + 1));
}

[[noreturn]] void failBytes(const std::string& name, const std::string& problem) {
  throw Error(cat(name, ": ", problem));
}

void checkSize(const std::string& name, uintmax_t bytes) {
  if (bytes > RigLimits::kMaxFileBytes)
    failBytes(name, cat(bytes, " bytes: larger than a rig may be (", RigLimits::kMaxFileBytes, " bytes)"));
}

// What nlohmann would trust, checked on the bytes: their number, NUL bytes (a rig is text),
// and the nesting depth. Brackets are counted outside strings; in a text that is not JSON the
// count may be off, but nlohmann then refuses the text anyway.
void checkBytes(const std::string& name, const std::string& bytes) {
  checkSize(name, bytes.size());
  if (size_t nul = bytes.find('\0'); nul != std::string::npos)
    failBytes(name, cat("NUL byte at offset ", nul, " (a rig is JSON text)"));
  int depth = 0;
  size_t line = 1;
  bool inString = false, escaped = false;
  for (char c : bytes) {
    if (c == '\n') ++line;
    if (inString) {
      if (escaped)
        escaped = false;
      else if (c == '\\')
        escaped = true;
      else if (c == '"')
        inString = false;
    } else if (c == '"') {
      inString = true;
    } else if (c == '[' || c == '{') {
      if (++depth > RigLimits::kMaxJsonDepth)
        failBytes(name, cat("JSON nested deeper than ", RigLimits::kMaxJsonDepth, " levels (line ", line, ")"));
    } else if (c == ']' || c == '}') {
      --depth;
    }
  }
}

class Reader {
 public:
  Reader(std::string name, const RigReadOptions& options)
      : name_(std::move(name)), baseDir_(options.baseDir), maps_(options.maps) {}

  [[noreturn]] void fail(const std::string& path, const std::string& problem) const {
    throw Error(path.empty() ? cat(name_, ": ", problem) : cat(name_, ": ", path, ": ", problem));
  }

  LightRig read(const std::string& bytes) {
    checkBytes(name_, bytes);
    Json root;
    try {
      root = Json::parse(bytes);
    } catch (const Json::exception& e) {
      throw Error(cat(name_, ": invalid JSON: ", jsonProblem(e)));
    }
    if (!root.is_object()) fail("", "expected a JSON object {\"version\": 1, \"lights\": [...]}");
    keys(root, "", {"version", "description", "window", "fps", "lights"});
    if (!root.contains("version")) fail("version", cat("missing (this prt reads version ", kRigVersion, ")"));
    const Json& version = root["version"];
    if (!version.is_number_integer() || version.get<long long>() != kRigVersion)
      fail("version", cat(shortDump(version), " is not supported (this prt reads version ", kRigVersion, ")"));
    if (root.contains("description") && !root["description"].is_string()) fail("description", "expected a string");

    LightRig rig;
    rig.source = name_;
    if (root.contains("window")) {
      if (!root["window"].is_string()) fail("window", "expected \"none\", \"hann\" or \"lanczos\"");
      std::string w = root["window"].get<std::string>();
      if (w != "none" && w != "hann" && w != "lanczos")
        fail("window", cat("'", printable(w), "': expected none, hann or lanczos"));
      rig.window = sh::parseWindow(w);
    }
    if (root.contains("fps")) {
      rig.fps = number(root["fps"], "fps");
      checkFps(*this, *rig.fps);
    }
    if (!root.contains("lights")) fail("lights", "missing (a list of lights)");
    const Json& lights = root["lights"];
    if (!lights.is_array()) fail("lights", "expected a list of lights");
    if (lights.empty()) fail("lights", "empty: a rig needs at least one light");
    if (lights.size() > RigLimits::kMaxLights)
      fail("lights", cat(lights.size(), " lights (at most ", RigLimits::kMaxLights, ")"));
    for (size_t i = 0; i < lights.size(); ++i) {
      const std::string path = cat("lights[", i, "]");
      if (isLocal(lights[i]))
        rig.locals.push_back(readLocal(lights[i], path));
      else
        rig.lights.push_back(readLight(rig, lights[i], path));
    }
    // Values (ranges, directions) and map files are checked by validate(), which names the
    // paths stored in each track's origin.
    rig.validate();
    return rig;
  }

 private:
  std::string name_;
  std::filesystem::path baseDir_;
  const std::map<std::string, ImageRgb>& maps_;

  // Refuses keys that are not in `allowed` (typos would otherwise be silently ignored).
  void keys(const Json& obj, const std::string& path, std::vector<std::string> allowed) const {
    for (auto it = obj.begin(); it != obj.end(); ++it) {
      if (std::find(allowed.begin(), allowed.end(), it.key()) != allowed.end()) continue;
      std::string best;
      size_t bestDistance = 3;
      for (const std::string& a : allowed) {
        size_t d = editDistance(it.key(), a);
        if (d < bestDistance) bestDistance = d, best = a;
      }
      std::string where = path.empty() ? printable(it.key()) : cat(path, ".", printable(it.key()));
      fail(where, best.empty() ? cat("unknown key (expected one of: ", quoteList(allowed), ")")
                               : cat("unknown key (did you mean '", best, "'?)"));
    }
  }

  double number(const Json& j, const std::string& path) const {
    if (!j.is_number()) fail(path, cat("expected a number, got ", shortDump(j)));
    double v = j.get<double>();
    if (!std::isfinite(v)) fail(path, "not a finite number");
    return v;
  }

  glm::dvec3 value(const Json& j, const std::string& path, Shape shape) const {
    if (j.is_number() && shape != Shape::Direction && shape != Shape::Position) return glm::dvec3(number(j, path));
    if (j.is_array() && j.size() == 3 && shape != Shape::Scalar && j[0].is_number())
      return {number(j[0], path + "[0]"), number(j[1], path + "[1]"), number(j[2], path + "[2]")};
    switch (shape) {
      case Shape::Scalar:
        fail(path, cat("expected a number, got ", shortDump(j)));
      case Shape::Color:
        fail(path, cat("expected a number or [R, G, B], got ", shortDump(j)));
      case Shape::Direction:
        fail(path, cat("expected a direction [X, Y, Z], got ", shortDump(j)));
      case Shape::Position:
        fail(path, cat("expected a position [X, Y, Z] (metres), got ", shortDump(j)));
    }
    return {};
  }

  static bool isKeyList(const Json& j) { return j.is_array() && !j.empty() && j[0].is_object(); }

  // A track: a plain value, a list of keys [{"frame": F, "value": V}, ...], or
  // {"keys": [...], "interpolation": "linear" | "step"}.
  Track track(const Json& j, const std::string& path, Shape shape) {
    Track t;
    t.origin = path;
    const Json* list = nullptr;
    std::string listPath = path;
    if (j.is_object()) {
      keys(j, path, {"keys", "interpolation"});
      if (!j.contains("keys")) fail(path, "keyframes need \"keys\": [{\"frame\": F, \"value\": V}, ...]");
      listPath = path + ".keys";
      list = &j["keys"];
      if (!list->is_array()) fail(listPath, "expected a list [{\"frame\": F, \"value\": V}, ...]");
      if (list->empty()) fail(listPath, "empty: give at least one key");
      if (j.contains("interpolation")) {
        const Json& in = j["interpolation"];
        std::string s = in.is_string() ? in.get<std::string>() : in.dump();
        if (s == "linear")
          t.interp = Track::Interp::Linear;
        else if (s == "step")
          t.interp = Track::Interp::Step;
        else
          fail(path + ".interpolation", cat("'", printable(s), "': expected linear or step"));
      }
    } else if (isKeyList(j)) {
      list = &j;
    }
    if (!list) {
      t.keys.push_back({0.0, value(j, path, shape)});
      return t;
    }
    if (list->size() > RigLimits::kMaxKeys)
      fail(listPath, cat(list->size(), " keys (at most ", RigLimits::kMaxKeys, ")"));
    for (size_t k = 0; k < list->size(); ++k) {
      const Json& key = (*list)[k];
      std::string keyPath = cat(listPath, "[", k, "]");
      if (!key.is_object()) fail(keyPath, "expected {\"frame\": F, \"value\": V}");
      keys(key, keyPath, {"frame", "value"});
      if (!key.contains("frame")) fail(keyPath + ".frame", "missing");
      if (!key.contains("value")) fail(keyPath + ".value", "missing");
      t.keys.push_back({number(key["frame"], keyPath + ".frame"), value(key["value"], keyPath + ".value", shape)});
    }
    t.origin = listPath;
    t.keyList = true;
    return t;
  }

  // The map an environment light names: one of the maps in memory (given to `rig`), else a
  // file resolved against the base folder, if there is one.
  std::string mapFile(LightRig& rig, const Json& j, const std::string& path) {
    if (!j.is_string() || j.get<std::string>().empty()) fail(path, "missing (the path of an .exr or .hdr map)");
    const std::string file = j.get<std::string>();
    if (file.size() > RigLimits::kMaxPathBytes)
      fail(path, cat(file.size(), " bytes: longer than a path may be (", RigLimits::kMaxPathBytes, ")"));
    if (std::any_of(file.begin(), file.end(), [](char c) { return static_cast<unsigned char>(c) < 0x20 || c == 0x7F; }))
      fail(path, cat("'", printable(file), "': a path without control characters (or NUL) expected"));
    if (auto it = maps_.find(file); it != maps_.end()) {
      rig.provideMap(file, it->second);
      return file;
    }
    if (baseDir_.empty()) fail(path, cat("'", printable(file), "': a rig read from memory reads no files"));
    std::filesystem::path p = file;
    return (p.is_relative() ? baseDir_ / p : p).lexically_normal().string();
  }

  static bool isLocal(const Json& j) {
    if (!j.is_object() || !j.contains("type") || !j["type"].is_string()) return false;
    const std::string type = j["type"].get<std::string>();
    return type == "point" || type == "spot" || type == "area";
  }

  // A light inside the scene: "point", "spot", or "area" with a "shape" (sphere, disk,
  // rectangle). Values are checked by validate().
  RigLocalLight readLocal(const Json& j, const std::string& path) {
    using T = LocalLight::Type;
    const std::string type = j["type"].get<std::string>();
    RigLocalLight l;
    l.label = path;
    std::vector<std::string> allowed = {"type", "name", "node", "position", "power"};
    if (type == "area") {
      if (!j.contains("shape") || !j["shape"].is_string()) fail(path + ".shape", "missing (sphere, disk or rectangle)");
      const std::string shape = j["shape"].get<std::string>();
      if (shape == "sphere")
        l.type = T::Sphere;
      else if (shape == "disk")
        l.type = T::Disk;
      else if (shape == "rectangle")
        l.type = T::Rectangle;
      else
        fail(path + ".shape", cat("'", printable(shape), "': expected sphere, disk or rectangle"));
      allowed.insert(allowed.end(), {"shape", "radiance"});
      if (l.type != T::Sphere) allowed.push_back("direction");
      if (l.type == T::Rectangle)
        allowed.insert(allowed.end(), {"up", "width", "height"});
      else
        allowed.push_back("radius");
    } else {
      l.type = type == "spot" ? T::Spot : T::Point;
      allowed.insert(allowed.end(), {"intensity", "range"});
      if (l.type == T::Spot) allowed.insert(allowed.end(), {"direction", "inner_cone", "outer_cone"});
    }
    keys(j, path, allowed);
    if (j.contains("name") && !j["name"].is_string()) fail(path + ".name", "expected a string");
    if (j.contains("node")) {
      if (!j["node"].is_string() || j["node"].get<std::string>().empty())
        fail(path + ".node", "expected the name of a node of the scene");
      l.node = j["node"].get<std::string>();
    } else if (!j.contains("position")) {
      fail(path + ".position", "missing ([X, Y, Z] in metres, or a \"node\" that places the light)");
    }
    const char* colorKey = l.type == T::Point || l.type == T::Spot ? "intensity" : "radiance";
    const bool color = j.contains(colorKey), power = j.contains("power");
    if (color == power)
      fail(path, color ? cat("give either \"", colorKey, "\" or \"power\", not both")
                       : cat("missing \"", colorKey, "\" (or \"power\" in watts)"));
    l.colorIsPower = power;
    l.color = track(j[power ? "power" : colorKey], cat(path, ".", power ? "power" : colorKey), Shape::Color);
    auto optional = [&](const char* key, Track& t, Shape shape) {
      if (j.contains(key)) t = track(j[key], cat(path, ".", key), shape);
    };
    optional("position", l.position, Shape::Position);
    optional("direction", l.direction, Shape::Direction);
    optional("up", l.up, Shape::Direction);
    optional("range", l.range, Shape::Scalar);
    optional("inner_cone", l.innerCone, Shape::Scalar);
    optional("outer_cone", l.outerCone, Shape::Scalar);
    for (const char* key : {"radius", "width", "height"})
      if (std::find(allowed.begin(), allowed.end(), key) != allowed.end() && !j.contains(key))
        fail(cat(path, ".", key), "missing (metres)");
    optional("radius", l.radius, Shape::Scalar);
    optional("width", l.width, Shape::Scalar);
    optional("height", l.height, Shape::Scalar);
    return l;
  }

  RigLight readLight(LightRig& rig, const Json& j, const std::string& path) {
    if (!j.is_object()) fail(path, "expected a light object {\"type\": ..., ...}");
    if (!j.contains("type")) fail(path + ".type", "missing (environment, sun, disk, uniform, point, spot or area)");
    if (!j["type"].is_string())
      fail(path + ".type", "expected a string (environment, sun, disk, uniform, point, spot or area)");
    const std::string type = j["type"].get<std::string>();
    RigLight light;
    light.label = path;
    if (type == "environment") {
      light.type = RigLight::Type::Environment;
      keys(j, path, {"type", "name", "file", "axis", "rotation", "intensity", "extract_sun"});
      light.file = mapFile(rig, j.contains("file") ? j["file"] : Json(), path + ".file");
      if (j.contains("extract_sun")) {
        if (!j["extract_sun"].is_boolean()) fail(path + ".extract_sun", "expected true or false");
        light.extractSun = j["extract_sun"].get<bool>();
      }
      if (j.contains("axis")) light.axis = track(j["axis"], path + ".axis", Shape::Direction);
      if (j.contains("rotation")) light.rotation = track(j["rotation"], path + ".rotation", Shape::Scalar);
      if (j.contains("intensity")) light.intensity = track(j["intensity"], path + ".intensity", Shape::Color);
    } else if (type == "sun" || type == "disk") {
      const bool sun = type == "sun";
      light.type = sun ? RigLight::Type::Sun : RigLight::Type::Disk;
      if (sun)
        keys(j, path, {"type", "name", "direction", "azimuth", "elevation", "radius", "irradiance"});
      else
        keys(j, path, {"type", "name", "direction", "azimuth", "elevation", "radius", "radiance", "irradiance"});
      const bool vec = j.contains("direction"), azel = j.contains("azimuth") || j.contains("elevation");
      if (vec == azel)
        fail(path, vec ? "give either \"direction\" or \"azimuth\" + \"elevation\", not both"
                       : "missing \"direction\" [X, Y, Z] (or \"azimuth\" + \"elevation\" in degrees)");
      if (vec) {
        light.direction = track(j["direction"], path + ".direction", Shape::Direction);
      } else {
        if (!j.contains("azimuth")) fail(path + ".azimuth", "missing (degrees; \"elevation\" needs it)");
        if (!j.contains("elevation")) fail(path + ".elevation", "missing (degrees; \"azimuth\" needs it)");
        light.useAzimuthElevation = true;
        light.azimuth = track(j["azimuth"], path + ".azimuth", Shape::Scalar);
        light.elevation = track(j["elevation"], path + ".elevation", Shape::Scalar);
      }
      if (j.contains("radius"))
        light.radius = track(j["radius"], path + ".radius", Shape::Scalar);
      else if (!sun)
        fail(path + ".radius", "missing (angular radius of the disk, degrees)");
      if (sun) {
        if (j.contains("irradiance")) light.color = track(j["irradiance"], path + ".irradiance", Shape::Color);
        light.colorIsIrradiance = true;
      } else {
        const bool radiance = j.contains("radiance"), irradiance = j.contains("irradiance");
        if (radiance == irradiance)
          fail(path, radiance ? "give either \"radiance\" or \"irradiance\", not both"
                              : "missing \"radiance\" (or \"irradiance\" on a surface facing the disk)");
        light.colorIsIrradiance = irradiance;
        light.color = track(j[radiance ? "radiance" : "irradiance"], path + (radiance ? ".radiance" : ".irradiance"),
                            Shape::Color);
      }
    } else if (type == "uniform") {
      light.type = RigLight::Type::Uniform;
      keys(j, path, {"type", "name", "radiance"});
      if (!j.contains("radiance")) fail(path + ".radiance", "missing (sky radiance, a number or [R, G, B])");
      light.color = track(j["radiance"], path + ".radiance", Shape::Color);
    } else {
      fail(path + ".type",
           cat("'", printable(type), "' is not a light type (environment, sun, disk, uniform, point, spot or area)"));
    }
    if (j.contains("name") && !j["name"].is_string()) fail(path + ".name", "expected a string");
    return light;
  }
};

}  // namespace

LightRig parseLightRigFromMemory(const std::string& bytes, const std::string& name, const RigReadOptions& options) {
  Reader reader(name, options);
  return reader.read(bytes);
}

LightRig parseLightRig(const std::string& json, const std::string& name, const std::string& baseDir) {
  return parseLightRigFromMemory(json, name, {baseDir.empty() ? "." : baseDir, {}});
}

LightRig loadLightRig(const std::string& path) {
  // Checked before reading: readFile would read a device or a FIFO forever.
  std::error_code ec;
  if (std::filesystem::exists(path, ec) && !std::filesystem::is_directory(path, ec)) {
    if (!std::filesystem::is_regular_file(path, ec)) throw Error(cat(path, ": not a regular file"));
    const uintmax_t size = std::filesystem::file_size(path, ec);
    if (!ec) checkSize(path, size);
  }
  const std::string dir = std::filesystem::path(path).parent_path().string();
  return parseLightRigFromMemory(readFile(path), path, {dir.empty() ? "." : dir, {}});
}

}  // namespace prt
