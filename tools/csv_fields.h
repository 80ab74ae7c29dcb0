// The fields of one CSV line (prt probe --points).
#pragma once

#include <optional>
#include <string>
#include <vector>

namespace prt::tools {

/// Splits one CSV line at commas, RFC 4180 quoting: a field in double quotes may hold commas,
/// and "" inside it is one quote; the quotes are removed. nullopt: a quoted field is not closed
/// on its line (fields spanning lines are not supported).
std::optional<std::vector<std::string>> csvFields(const std::string& line);

}  // namespace prt::tools
