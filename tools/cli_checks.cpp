#include "cli_checks.h"

#include <cmath>
#include <limits>

namespace prt::tools {

std::string spokenList(const std::vector<std::string>& names) {
  std::string out;
  for (size_t i = 0; i < names.size(); ++i) out += (i == 0 ? "" : i + 1 == names.size() ? " or " : ", ") + names[i];
  return out;
}

namespace {

// The number an option's text holds, or NaN when it does not parse whole.
double number(const std::string& text) {
  double v = std::numeric_limits<double>::quiet_NaN();
  return CLI::detail::lexical_cast(text, v) ? v : std::numeric_limits<double>::quiet_NaN();
}

}  // namespace

CLI::Validator finiteIn(double lo, double hi, bool open) {
  const std::string range = open ? cat("between ", lo, " and ", hi) : cat("within ", lo, "..", hi);
  return CLI::Validator(
      [lo, hi, open, range](std::string& text) {
        const double v = number(text);
        const bool inside = open ? v > lo && v < hi : v >= lo && v <= hi;
        return std::isfinite(v) && inside ? std::string() : cat(text, " is not a finite number ", range);
      },
      open ? cat("(", lo, ", ", hi, ")") : cat("[", lo, ", ", hi, "]"));
}

CLI::Validator finitePositive() {
  return CLI::Validator(
      [](std::string& text) {
        const double v = number(text);
        return std::isfinite(v) && v > 0.0 ? std::string() : cat(text, " is not a finite number > 0");
      },
      "> 0");
}

CLI::Validator finiteAtLeast(double lo) {
  return CLI::Validator(
      [lo](std::string& text) {
        const double v = number(text);
        return std::isfinite(v) && v >= lo ? std::string() : cat(text, " is not a finite number >= ", lo);
      },
      cat(">= ", lo));
}

CLI::Validator finite() {
  return CLI::Validator(
      [](std::string& text) {
        return std::isfinite(number(text)) ? std::string() : cat(text, " is not a finite number");
      },
      "");
}

}  // namespace prt::tools
