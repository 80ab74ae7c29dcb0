// Command-line options of the bench binaries: `--name value` pairs, `--help`, and one line with a
// non-zero exit for anything else (unknown option, missing value, a number that does not parse).
#pragma once

#include <cstdio>
#include <exception>
#include <functional>
#include <map>
#include <stdexcept>
#include <string>

namespace prt::bench {

/// Handlers by option name ("--width"); each parses its value and throws on a bad one.
using OptionHandlers = std::map<std::string, std::function<void(const std::string& value)>>;

/// Applies argv to `handlers`. Returns -1 to go on, or the exit code to return from main:
/// 0 after printing `usage` for --help / -h, 2 after one line on stderr for a bad command line.
inline int parseOptions(int argc, char** argv, const char* program, const char* usage,
                        const OptionHandlers& handlers) {
  for (int i = 1; i < argc; ++i) {
    const std::string k = argv[i];
    if (k == "--help" || k == "-h") {
      std::printf("%s", usage);
      return 0;
    }
    const auto it = handlers.find(k);
    if (it == handlers.end()) {
      std::fprintf(stderr, "%s: unknown option '%s' (--help lists the options)\n", program, k.c_str());
      return 2;
    }
    if (i + 1 >= argc) {
      std::fprintf(stderr, "%s: option %s needs a value\n", program, k.c_str());
      return 2;
    }
    const std::string v = argv[++i];
    try {
      it->second(v);
    } catch (const std::exception&) {
      std::fprintf(stderr, "%s: option %s: bad value '%s'\n", program, k.c_str(), v.c_str());
      return 2;
    }
  }
  return -1;
}

/// std::stoi that rejects trailing characters ("12x").
inline int toInt(const std::string& v) {
  size_t used = 0;
  const int n = std::stoi(v, &used);
  if (used != v.size()) throw std::invalid_argument(v);
  return n;
}

/// std::stod that rejects trailing characters.
inline double toDouble(const std::string& v) {
  size_t used = 0;
  const double d = std::stod(v, &used);
  if (used != v.size()) throw std::invalid_argument(v);
  return d;
}

}  // namespace prt::bench
