// URI sandboxing for the glTF reader (uri_guard.h): buffers and images are read only from
// the scene's folder unless external URIs are allowed, and the document is checked before
// tinygltf parses it.
#include "uri_guard.h"

#include <algorithm>
#include <cctype>
#include <fstream>

#include <nlohmann/json.hpp>

#include "prt/error.h"
#include "prt/scene.h"

namespace prt::gltf {

namespace {

namespace fs = std::filesystem;
using Json = nlohmann::json;

// Limits on hostile input, checked before anything that scales with them is allocated
// (docs/robustness.md). JSON nesting: tinygltf converts extras and extensions recursively,
// so a deeply nested document would overflow the stack; real files nest fewer than 20 levels.
constexpr int kMaxJsonDepth = 64;

bool isWithin(const fs::path& p, const fs::path& dir) {
  auto [d, q] = std::mismatch(dir.begin(), dir.end(), p.begin(), p.end());
  return d == dir.end();
}

int hexValue(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

/// The path a relative URI spells, its %XX escapes decoded (RFC 3986), as tinygltf reads it.
std::string percentDecoded(const std::string& uri) {
  std::string out;
  for (size_t i = 0; i < uri.size(); ++i) {
    if (uri[i] == '%' && i + 2 < uri.size() && hexValue(uri[i + 1]) >= 0 && hexValue(uri[i + 2]) >= 0) {
      out += char(hexValue(uri[i + 1]) * 16 + hexValue(uri[i + 2]));
      i += 2;
    } else {
      out += uri[i];
    }
  }
  return out;
}

/// Why `uri` (of a buffer or an image) may not be read, or "" if it may. The checks see the
/// decoded path, so that an escaped "../" is refused here, by the URI it was written as.
std::string uriProblem(const UriGuard& guard, const std::string& encoded) {
  if (encoded.rfind("data:", 0) == 0) return "";
  const std::string uri = percentDecoded(encoded);
  size_t colon = uri.find(':');
  bool scheme = colon != std::string::npos && colon > 0 && std::isalpha(static_cast<unsigned char>(uri[0])) &&
                std::all_of(uri.begin(), uri.begin() + std::ptrdiff_t(colon),
                            [](unsigned char c) { return std::isalnum(c) || c == '+' || c == '-' || c == '.'; });
  if (scheme) return cat("uses scheme '", uri.substr(0, colon), "'; only relative file paths and data: URIs are read");
  if (guard.baseDir.empty()) return "refers to a file, but the document was read from memory (no folder)";
  bool absolute = !uri.empty() && (uri[0] == '/' || uri[0] == '\\');
  if (absolute && !guard.allowExternal) return cat("is an absolute path; ", kExternalRefused);
  std::error_code ec;
  fs::path target = fs::weakly_canonical(absolute ? fs::path(uri) : guard.canonicalDir / uri, ec);
  if (!guard.allowExternal && (ec || !isWithin(target, guard.canonicalDir)))
    return cat("points outside the scene folder; ", kExternalRefused);
  if (fs::exists(target, ec) && !fs::is_regular_file(target, ec)) return "is not a regular file";
  return "";
}

/// Why tinygltf may not open `path` (a URI joined to a search folder), or "".
std::string fileProblem(const UriGuard& guard, const std::string& path) {
  if (guard.baseDir.empty()) return "refers to a file, but the document was read from memory (no folder)";
  std::error_code ec;
  if (!guard.allowExternal && !isWithin(fs::weakly_canonical(path, ec), guard.canonicalDir))
    return cat("lies outside the scene folder; ", kExternalRefused);
  if (fs::exists(path, ec) && !fs::is_regular_file(path, ec)) return "is not a regular file";
  return "";
}

}  // namespace

// tinygltf file-system callbacks: every file it opens passes the guard (tinygltf also looks
// in the working directory, and follows whatever path a URI spells).
bool guardedFileExists(const std::string& path, void* user) {
  auto& guard = *static_cast<UriGuard*>(user);
  std::error_code ec;
  if (guard.baseDir.empty() || !fs::exists(path, ec)) return false;  // tinygltf: "File not found"
  if (std::string why = fileProblem(guard, path); !why.empty()) {
    if (guard.refusal.empty()) {
      guard.refusal = cat("file '", path, "' ", why);
      guard.refusalIsExternal = why.find(kExternalRefused) != std::string::npos;
    }
    return false;
  }
  return true;
}

std::string guardedExpandFilePath(const std::string& path, void* user) {
  // tinygltf joins an absolute URI to its folder ("dir//abs"); when external files are
  // allowed, it means what it says.
  const auto& guard = *static_cast<const UriGuard*>(user);
  for (const std::string& dir : {guard.baseDir, std::string(".")})
    if (guard.allowExternal && !dir.empty() && path.rfind(dir + "//", 0) == 0) return path.substr(dir.size() + 1);
  return path;
}

bool guardedReadWholeFile(std::vector<unsigned char>* out, std::string* err, const std::string& path, void* user) {
  auto& guard = *static_cast<UriGuard*>(user);
  if (std::string why = fileProblem(guard, path); !why.empty()) {
    if (err) *err += why;
    return false;
  }
  std::error_code ec;
  uintmax_t size = fs::file_size(path, ec);
  if (ec || size > kMaxFileBytes) {
    if (err) *err += ec ? ec.message() : cat("larger than ", kMaxFileBytes, " bytes");
    return false;
  }
  std::ifstream in(path, std::ios::binary);
  out->resize(size_t(size));
  if (!in.read(reinterpret_cast<char*>(out->data()), std::streamsize(size))) {
    if (err) *err += "cannot read";
    return false;
  }
  return true;
}

bool refuseWrite(std::string* err, const std::string&, const std::vector<unsigned char>&, void*) {
  if (err) *err += "prt never writes through tinygltf's file callbacks";
  return false;
}

/// Checks what tinygltf would trust: the nesting depth of the document and the URIs of
/// buffers and images. Syntax errors are left to tinygltf, which reports them.
void checkDocument(const std::string& path, const std::string& text, const UriGuard& guard) {
  Json doc = Json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (doc.is_discarded()) return;
  std::vector<std::pair<const Json*, int>> stack{{&doc, 1}};
  while (!stack.empty()) {
    auto [j, depth] = stack.back();
    stack.pop_back();
    if (depth > kMaxJsonDepth) throw Error(cat(path, ": JSON nested deeper than ", kMaxJsonDepth, " levels"));
    if (j->is_structured())
      for (const Json& child : *j) stack.emplace_back(&child, depth + 1);
  }
  if (!doc.is_object()) return;
  for (const char* array : {"buffers", "images"}) {
    auto it = doc.find(array);
    if (it == doc.end() || !it->is_array()) continue;
    for (size_t i = 0; i < it->size(); ++i) {
      const Json& element = (*it)[i];
      if (!element.is_object() || !element.contains("uri") || !element["uri"].is_string()) continue;
      const std::string uri = element["uri"].get<std::string>();
      if (std::string why = uriProblem(guard, uri); !why.empty()) {
        std::string message = cat(path, ": ", std::string(array) == "buffers" ? "buffer " : "image ", i, ": uri '",
                                  uri.size() > 200 ? uri.substr(0, 200) + "..." : uri, "' ", why);
        if (why.find(kExternalRefused) != std::string::npos) throw ExternalUriRefused(message);
        throw Error(message);
      }
    }
  }
}

}  // namespace prt::gltf
