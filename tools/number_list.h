// Option values that are lists of numbers, "A,B,...".
#pragma once

#include <cstddef>
#include <string>
#include <vector>

namespace prt::tools {

/// Parses "A,B,..." into exactly `count` finite numbers (integers if `integers`) for option
/// `name`; anything else throws CLI::ValidationError (a usage error) naming the option, the text
/// and the expected `form`.
std::vector<double> parseNumberList(const std::string& name, const std::string& text, size_t count, bool integers,
                                    const char* form);

}  // namespace prt::tools
