// GoogleTest expectations shared by the end-to-end tests of the prt command.
#pragma once

#include <algorithm>
#include <filesystem>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "harness.h"

namespace prt::test {

/// Only the named files are in `dir`: no temporary leftovers.
inline bool dirHoldsOnly(const std::filesystem::path& dir, const std::vector<std::string>& names) {
  size_t n = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir)) {
    ++n;
    if (std::find(names.begin(), names.end(), e.path().filename().string()) == names.end()) return false;
  }
  return n == names.size();
}

/// A run that failed as prt must: exit `status` (1 bad input, 2 usage), one line on stderr that
/// mentions `mention`, and nothing left in `dir`.
inline void expectCleanFailure(const RunResult& r, const std::string& mention, const std::filesystem::path& dir,
                               int status = 1) {
  EXPECT_EQ(r.status, status) << r.err;
  EXPECT_EQ(lineCount(r.err), 1) << r.err;
  EXPECT_NE(r.err.find(mention), std::string::npos) << r.err;
  EXPECT_TRUE(dirHoldsOnly(dir, {})) << "output left behind";
}

}  // namespace prt::test
