#include "file_kind.h"

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>

#include "prt/error.h"

namespace prt::tools {

FileKind sniffFile(const std::string& path, std::string& what) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error(cat(path, ": cannot read (", std::strerror(errno), ")"));
  char head[16] = {};
  in.read(head, sizeof head);
  const std::string h(head, size_t(in.gcount()));
  const std::string ext = std::filesystem::path(path).extension().string();
  if (h.compare(0, 8, std::string(" BDV\0\0\0\0", 8)) == 0) return FileKind::ProbeGrid;  // OpenVDB's int64 magic
  const size_t text = h.compare(0, 3, "\xEF\xBB\xBF") == 0 ? 3 : 0;                      // UTF-8 byte order mark
  const size_t first = h.find_first_not_of(" \t\r\n", text);
  const bool json = first != std::string::npos && h[first] == '{';
  if (h.compare(0, 4, "glTF") == 0 || (json && ext != ".json")) return FileKind::Gltf;
  // The extension claims a kind: let its reader say what is wrong with the file.
  if (ext == ".vdb") return FileKind::ProbeGrid;
  if (ext == ".gltf" || ext == ".glb") return FileKind::Gltf;
  what = json                                   ? "JSON (a light rig or `prt light` output?)"
         : h.compare(0, 2, "#?") == 0           ? "a Radiance HDR image"
         : h.compare(0, 4, "v/1\x01") == 0      ? "an OpenEXR image"
         : h.compare(0, 4, "\x89PNG") == 0      ? "a PNG image"
         : h.compare(0, 3, "\xFF\xD8\xFF") == 0 ? "a JPEG image"
         : h.empty()                            ? "empty"
                                                : "of an unknown kind";
  return FileKind::Other;
}

}  // namespace prt::tools
