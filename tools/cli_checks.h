// Option checks shared by the commands, on top of CLI11's own (CLI::Range, ->excludes, ->needs).
#pragma once

#include <string>
#include <utility>
#include <vector>

#include <CLI/CLI.hpp>

#include "prt/error.h"
#include "prt/sh.h"

namespace prt::tools {

/// A usage error found after parsing, where options conflict in a way CLI11 cannot state (one
/// of several options needed): main prints it with a usage hint and exits 2, like CLI11's own.
class UsageError : public Error {
 public:
  using Error::Error;
};

/// --bands of every command: 1 .. sh::kMaxBands.
inline const CLI::Range kBandsRange(1, sh::kMaxBands);

/// "a", "a or b", "a, b or c".
std::string spokenList(const std::vector<std::string>& names);

/// The check of an option that takes one of a few names, in any case: --help lists the names,
/// a name becomes its value (CLI::CheckedTransformer, so the option may be of the enum type),
/// anything else is refused with "'texel' is not pixel or vertex". CheckedTransformer alone
/// would also take the values' numbers ("1" for vertex), so the names are checked first.
template <typename T>
CLI::Validator choice(const std::vector<std::pair<std::string, T>>& choices) {
  std::vector<std::string> names;
  for (const auto& c : choices) names.push_back(c.first);
  const CLI::Validator known = CLI::IsMember(names, CLI::ignore_case);
  const CLI::Validator convert = CLI::CheckedTransformer(choices, CLI::ignore_case);
  std::string shown = "{";
  for (const std::string& n : names) shown += (shown.size() > 1 ? "," : "") + n;
  return CLI::Validator(
      [known, convert, spoken = spokenList(names)](std::string& value) {
        const std::string given = value;
        if (!known(value).empty()) return cat("'", given, "' is not ", spoken);
        return convert(value);
      },
      shown + "}");
}

/// A finite number within [lo, hi], or within (lo, hi) when `open`; the message says which.
CLI::Validator finiteIn(double lo, double hi, bool open = false);

/// A finite number > 0.
CLI::Validator finitePositive();

/// A finite number >= lo.
CLI::Validator finiteAtLeast(double lo);

/// A finite number.
CLI::Validator finite();

}  // namespace prt::tools
