// Test helpers: locating ../shared, skipping or failing when it is absent.
#ifndef LOCFORGE_TESTS_TESTING_H_
#define LOCFORGE_TESTS_TESTING_H_

#include <gtest/gtest.h>

#include <filesystem>
#include <string>

namespace locforge::testing {

// The shared data folder: $LOCFORGE_SHARED_DIR, else the one CMake recorded.
std::filesystem::path SharedDir();
// True when LOCFORGE_REQUIRE_SHARED=1: absent data then fails instead of skipping.
bool SharedRequired();
// A fresh empty folder under the system temp dir, removed by the caller or left for debugging.
std::filesystem::path MakeTempDir(const std::string& prefix);

}  // namespace locforge::testing

// Sets `var` to ../shared/<relative>; skips the test (or fails it under
// LOCFORGE_REQUIRE_SHARED=1) with a clear message when it is missing.
#define LOCFORGE_SHARED_PATH_OR_SKIP(var, relative)                                     \
  const std::filesystem::path var = ::locforge::testing::SharedDir() / (relative);       \
  if (!std::filesystem::exists(var)) {                                                  \
    if (::locforge::testing::SharedRequired()) {                                         \
      FAIL() << "shared data " << var << " is missing and LOCFORGE_REQUIRE_SHARED=1";   \
    } else {                                                                            \
      GTEST_SKIP() << "shared data " << var                                             \
                   << " is absent; set LOCFORGE_SHARED_DIR to run this test";            \
    }                                                                                   \
  }

#endif  // LOCFORGE_TESTS_TESTING_H_
