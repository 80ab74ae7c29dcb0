#include "number_list.h"

#include <cmath>
#include <cstdlib>
#include <sstream>

#include <CLI/CLI.hpp>

#include "prt/error.h"

namespace prt::tools {

std::vector<double> parseNumberList(const std::string& name, const std::string& text, size_t count, bool integers,
                                    const char* form) {
  std::vector<double> out;
  std::istringstream in(text);
  std::string item;
  bool ok = !text.empty() && text.back() != ',';
  while (ok && std::getline(in, item, ',')) {
    char* end = nullptr;
    const double v = std::strtod(item.c_str(), &end);
    ok = !item.empty() && *end == '\0' && std::isfinite(v) && (!integers || (v == std::floor(v) && std::fabs(v) < 1e9));
    out.push_back(v);
  }
  if (!ok || out.size() != count) throw CLI::ValidationError(name, cat("'", text, "' is not ", form));
  return out;
}

}  // namespace prt::tools
