// Errors and checks, shared by every prt library.
//
// Two kinds of failure, two mechanisms (../docs/conventions.md):
// - Bad input (files, options): throw prt::Error (or a subclass) whose message names where it
//   happened, e.g. "scene.gltf: mesh 3 / primitive 1 / NORMAL: 12 values, expected 36".
//   Libraries never call exit(); tools catch once in main, print one line, exit 1.
// - Bugs (broken invariants): PRT_CHECK* print both operands and abort. PRT_DCHECK* do the same
//   in a build without NDEBUG and are compiled out (operands not evaluated) under NDEBUG, as
//   pbrt-v4's DCHECK: for checks too costly for an inner loop. A CheckContext adds what the code
//   was doing ("instance 3, vertex 17") to the message of a check that fails while it lives.
#pragma once

#include <cstdio>
#include <cstdlib>
#include <functional>
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

/// Adds context to the message of a check (PRT_CHECK*, PRT_DCHECK*) that fails on this thread
/// while the scope lives, as pbrt-v4's CheckCallbackScope: `describe` is called only when a
/// check fails, so a scope costs nothing in a loop that passes. Scopes nest; the message lists
/// the outermost first:
///   prt::CheckContext context([&] { return prt::cat("instance ", k, ", vertex ", v); });
class CheckContext {
 public:
  explicit CheckContext(std::function<std::string()> describe);
  ~CheckContext();
  CheckContext(const CheckContext&) = delete;
  CheckContext& operator=(const CheckContext&) = delete;

 private:
  std::function<std::string()> describe_;
};

namespace detail {
/// Prints "prt: internal error at FILE:LINE: WHAT", then one line per live CheckContext, and
/// aborts.
[[noreturn]] void checkFailed(const char* file, int line, const std::string& what);
}  // namespace detail

}  // namespace prt

#define PRT_CHECK(cond)                                                                     \
  do {                                                                                      \
    if (!(cond)) ::prt::detail::checkFailed(__FILE__, __LINE__, "CHECK(" #cond ") failed"); \
  } while (0)

#define PRT_CHECK_OP(a, op, b)                                                                               \
  do {                                                                                                       \
    auto&& prtA_ = (a);                                                                                      \
    auto&& prtB_ = (b);                                                                                      \
    if (!(prtA_ op prtB_))                                                                                   \
      ::prt::detail::checkFailed(__FILE__, __LINE__,                                                         \
                                 ::prt::cat("CHECK(" #a " " #op " " #b ") failed: ", prtA_, " vs ", prtB_)); \
  } while (0)

#define PRT_CHECK_EQ(a, b) PRT_CHECK_OP(a, ==, b)
#define PRT_CHECK_NE(a, b) PRT_CHECK_OP(a, !=, b)
#define PRT_CHECK_LT(a, b) PRT_CHECK_OP(a, <, b)
#define PRT_CHECK_LE(a, b) PRT_CHECK_OP(a, <=, b)
#define PRT_CHECK_GT(a, b) PRT_CHECK_OP(a, >, b)
#define PRT_CHECK_GE(a, b) PRT_CHECK_OP(a, >=, b)

// Debug-only checks. Under NDEBUG the condition is still compiled (so a variable used only in a
// check stays used) but never evaluated.
#ifdef NDEBUG
#define PRT_DCHECK(cond)        \
  do {                          \
    if (false) PRT_CHECK(cond); \
  } while (0)
#define PRT_DCHECK_OP(a, op, b)        \
  do {                                 \
    if (false) PRT_CHECK_OP(a, op, b); \
  } while (0)
#else
#define PRT_DCHECK(cond) PRT_CHECK(cond)
#define PRT_DCHECK_OP(a, op, b) PRT_CHECK_OP(a, op, b)
#endif

#define PRT_DCHECK_EQ(a, b) PRT_DCHECK_OP(a, ==, b)
#define PRT_DCHECK_NE(a, b) PRT_DCHECK_OP(a, !=, b)
#define PRT_DCHECK_LT(a, b) PRT_DCHECK_OP(a, <, b)
#define PRT_DCHECK_LE(a, b) PRT_DCHECK_OP(a, <=, b)
#define PRT_DCHECK_GT(a, b) PRT_DCHECK_OP(a, >, b)
#define PRT_DCHECK_GE(a, b) PRT_DCHECK_OP(a, >=, b)
