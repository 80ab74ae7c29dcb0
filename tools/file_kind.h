// What kind of file `prt info` was given, from its first bytes.
#pragma once

#include <string>

namespace prt::tools {

enum class FileKind { Gltf, ProbeGrid, Other };

/// What a file is, from its first bytes (then its extension); for Other, `what` names the
/// kind ("a PNG image", "empty"). Throws prt::Error when the file cannot be read.
FileKind sniffFile(const std::string& path, std::string& what);

}  // namespace prt::tools
