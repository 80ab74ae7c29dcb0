#include "prt/bake_record.h"

#include <cmath>
#include <limits>

#include "bake_record_json.h"
#include "prt/error.h"
#include "prt/sh.h"

namespace prt {

using Json = nlohmann::json;

std::string describeBakeRecord(const BakeRecord& r) {
  std::string line = cat(r.bands, " bands, ", r.samples, " samples, ", r.bounces, " bounce", r.bounces == 1 ? "" : "s",
                         ", ", r.shadowed ? "shadowed" : "unshadowed", ", seed ", r.seed, ", from ", r.scene);
  if (!r.prtVersion.empty()) line += cat(", prt ", r.prtVersion);
  if (r.backTransfer) line += ", both sides of double-sided surfaces";
  const BakeRecord::Refinement& f = r.refinement;
  if (f.tolerance > 0.0)
    line += cat("; refined ", f.verticesBefore, " -> ", f.verticesAfter, " vertices (tolerance ", f.tolerance,
                ", budget ", f.budget, ", ", f.samples, " samples, residual ", f.residual, ")");
  return line;
}

namespace gltf {

namespace {

// Keys, as files baked by every prt so far spell them.
constexpr const char* kVersionKey = "version";
constexpr const char* kPrtVersionKey = "prt_version";
constexpr const char* kRefinementKey = "refinement";

/// A value as the message quotes it: JSON text, cut short if long.
std::string shown(const Json& v) {
  std::string s = v.dump();
  return s.size() > 40 ? s.substr(0, 37) + "..." : s;
}

class Fields {
 public:
  Fields(const Json& j, const std::string& where) : j_(j), where_(where) {}

  [[noreturn]] void fail(const char* key, const std::string& what) const {
    throw Error(cat(where_, ".", key, ": ", what));
  }
  const Json& get(const char* key) const {
    auto it = j_.find(key);
    if (it == j_.end()) fail(key, "missing");
    return *it;
  }
  int integer(const char* key, int lo, int hi, const std::string& range) const {
    const Json& v = get(key);
    const bool ok =
        v.is_number_integer() &&
        (v.is_number_unsigned() ? v.get<uint64_t>() <= uint64_t(hi) : v.get<int64_t>() >= lo && v.get<int64_t>() <= hi);
    if (!ok) fail(key, cat("expected an integer ", range, ", got ", shown(v)));
    return int(v.get<int64_t>());
  }
  /// An unsigned 64-bit integer. Above 2^31 the writer's tinygltf values hold it as a double
  /// (exact up to 2^53): an integral double is taken as it is, 2^64 (UINT64_MAX rounded) as
  /// UINT64_MAX.
  uint64_t unsigned64(const char* key) const {
    const Json& v = get(key);
    if (v.is_number_unsigned()) return v.get<uint64_t>();
    if (v.is_number_integer() && v.get<int64_t>() >= 0) return uint64_t(v.get<int64_t>());
    if (v.is_number_float()) {
      const double d = v.get<double>();
      constexpr double kTwo64 = 18446744073709551616.0;
      if (d >= 0.0 && d <= kTwo64 && std::floor(d) == d)
        return d == kTwo64 ? std::numeric_limits<uint64_t>::max() : uint64_t(d);
    }
    fail(key, cat("expected an unsigned integer, got ", shown(v)));
  }
  bool boolean(const char* key) const {
    const Json& v = get(key);
    if (!v.is_boolean()) fail(key, cat("expected true or false, got ", shown(v)));
    return v.get<bool>();
  }
  std::string string(const char* key) const {
    const Json& v = get(key);
    if (!v.is_string()) fail(key, cat("expected a string, got ", shown(v)));
    return v.get<std::string>();
  }
  /// A finite number (integer or not).
  double number(const char* key) const {
    const Json& v = get(key);
    if (!v.is_number() || !std::isfinite(v.get<double>())) fail(key, cat("expected a number, got ", shown(v)));
    return v.get<double>();
  }
  bool has(const char* key) const { return j_.contains(key); }

 private:
  const Json& j_;
  const std::string& where_;
};

}  // namespace

Json bakeRecordToJson(const BakeRecord& r) {
  Json j;
  j[kVersionKey] = BakeRecord::kLayoutVersion;
  j["scene"] = r.scene;
  j["bands"] = r.bands;
  j["samples"] = r.samples;
  j["bounces"] = r.bounces;
  j["shadowed"] = r.shadowed;
  j["seed"] = r.seed;
  j["transfer"] = BakeRecord::kTransfer;
  j["sh_convention"] = BakeRecord::kShConvention;
  j["units"] = BakeRecord::kUnits;
  if (r.backTransfer) j["back_transfer"] = BakeRecord::kBackTransfer;
  if (r.directTransfer) j["direct_transfer"] = BakeRecord::kDirectTransfer;
  if (!r.prtVersion.empty()) j[kPrtVersionKey] = r.prtVersion;
  if (r.refinement.tolerance > 0.0) {
    const BakeRecord::Refinement& f = r.refinement;
    j[kRefinementKey] = {{"tolerance", f.tolerance},
                         {"budget", f.budget},
                         {"samples", f.samples},
                         {"vertices_before", f.verticesBefore},
                         {"vertices_after", f.verticesAfter},
                         {"residual", f.residual}};
  }
  return j;
}

BakeRecord bakeRecordFromJson(const Json& j, const std::string& where) {
  if (!j.is_object()) throw Error(cat(where, ": expected an object, got ", shown(j)));
  const Fields f(j, where);
  const Json& version = f.get(kVersionKey);
  if (!version.is_number_integer()) f.fail(kVersionKey, cat("expected an integer, got ", shown(version)));
  if (version.is_number_unsigned() ? version.get<uint64_t>() > uint64_t(BakeRecord::kLayoutVersion)
                                   : version.get<int64_t>() > BakeRecord::kLayoutVersion)
    f.fail(kVersionKey,
           cat(shown(version), ": written by a newer prt (this one reads version ", BakeRecord::kLayoutVersion, ")"));
  if (version.get<int64_t>() != BakeRecord::kLayoutVersion)
    f.fail(kVersionKey, cat("expected ", BakeRecord::kLayoutVersion, ", got ", shown(version)));

  BakeRecord r;
  r.scene = f.string("scene");
  r.bands = f.integer("bands", 1, sh::kMaxBands, cat("1..", sh::kMaxBands));
  r.samples = f.integer("samples", 1, std::numeric_limits<int>::max(), ">= 1");
  r.bounces = f.integer("bounces", 0, std::numeric_limits<int>::max(), ">= 0");
  r.shadowed = f.boolean("shadowed");
  r.seed = f.unsigned64("seed");
  if (const std::string t = f.string("transfer"); t != BakeRecord::kTransfer)
    f.fail("transfer", cat("expected \"", BakeRecord::kTransfer, "\", got ", shown(Json(t))));
  f.string("sh_convention");  // descriptions: any wording, but text
  f.string("units");
  if (f.has("back_transfer")) {  // a description: any wording, but text
    f.string("back_transfer");
    r.backTransfer = true;
  }
  if (f.has("direct_transfer")) {  // a description too
    f.string("direct_transfer");
    r.directTransfer = true;
  }
  if (f.has(kPrtVersionKey)) r.prtVersion = f.string(kPrtVersionKey);
  if (f.has(kRefinementKey)) {
    const Json& sub = f.get(kRefinementKey);
    const std::string here = cat(where, ".", kRefinementKey);
    if (!sub.is_object()) f.fail(kRefinementKey, cat("expected an object, got ", shown(sub)));
    const Fields g(sub, here);
    BakeRecord::Refinement& x = r.refinement;
    x.tolerance = g.number("tolerance");
    if (!(x.tolerance > 0.0)) g.fail("tolerance", cat("expected a number > 0, got ", shown(sub["tolerance"])));
    x.budget = g.unsigned64("budget");
    x.samples = g.integer("samples", 1, std::numeric_limits<int>::max(), ">= 1");
    x.verticesBefore = g.unsigned64("vertices_before");
    x.verticesAfter = g.unsigned64("vertices_after");
    if (x.verticesAfter < x.verticesBefore)
      g.fail("vertices_after", cat(x.verticesAfter, ": fewer than vertices_before (", x.verticesBefore, ")"));
    x.residual = g.number("residual");
    if (x.residual < 0.0) g.fail("residual", cat("expected a number >= 0, got ", shown(sub["residual"])));
  }
  return r;
}

}  // namespace gltf
}  // namespace prt
