// Errors and checks, shared by every prt library.
//
// Two kinds of failure, two mechanisms (../docs/conventions.md):
// - Bad input (files, options): throw prt::Error (or a subclass) whose message names where it
//   happened, e.g. "scene.gltf: mesh 3 / primitive 1 / NORMAL: 12 values, expected 36".
//   Libraries never call exit(); tools catch once in main, print one line, exit 1.
// - Bugs (broken invariants): PRT_CHECK* print both operands and abort.
#pragma once

#include <cstdio>
#include <cstdlib>
#include <sstream>
#include <stdexcept>
#include <string>

namespace prt {

/// Bad input: a file, an option, a value. The message is one line, ready for the user.
class Error : public std::runtime_error {
public:
  explicit Error(const std::string& what) : std::runtime_error(what) {}
};

/// A bake or render stopped on request (SIGINT/SIGTERM).
class Interrupted : public Error {
public:
  explicit Interrupted(const std::string& what) : Error(what) {}
};

/// Builds a message from stream-able pieces: prt::cat("mesh ", i, ": ", n, " values").
template <class... Args>
std::string cat(const Args&... args) {
  std::ostringstream os;
  (os << ... << args);
  return os.str();
}

/// A string from a file for a one-line message: cut after `maxBytes` bytes ("..."), control
/// characters and bytes that are not UTF-8 written as \xNN.
std::string printable(const std::string& s, size_t maxBytes = 40);

namespace detail {
[[noreturn]] inline void checkFailed(const char* file, int line, const std::string& what) {
  std::fprintf(stderr, "prt: internal error at %s:%d: %s\n", file, line, what.c_str());
  std::abort();
}
}  // namespace detail

}  // namespace prt

#define PRT_CHECK(cond)                                                     \
  do {                                                                      \
    if (!(cond)) ::prt::detail::checkFailed(__FILE__, __LINE__, "CHECK(" #cond ") failed"); \
  } while (0)

#define PRT_CHECK_OP(a, op, b)                                                          \
  do {                                                                                  \
    auto&& prtA_ = (a);                                                                 \
    auto&& prtB_ = (b);                                                                 \
    if (!(prtA_ op prtB_))                                                              \
      ::prt::detail::checkFailed(__FILE__, __LINE__,                                    \
                                 ::prt::cat("CHECK(" #a " " #op " " #b ") failed: ", prtA_, \
                                            " vs ", prtB_));                            \
  } while (0)

#define PRT_CHECK_EQ(a, b) PRT_CHECK_OP(a, ==, b)
#define PRT_CHECK_NE(a, b) PRT_CHECK_OP(a, !=, b)
#define PRT_CHECK_LT(a, b) PRT_CHECK_OP(a, <, b)
#define PRT_CHECK_LE(a, b) PRT_CHECK_OP(a, <=, b)
#define PRT_CHECK_GT(a, b) PRT_CHECK_OP(a, >, b)
#define PRT_CHECK_GE(a, b) PRT_CHECK_OP(a, >=, b)
