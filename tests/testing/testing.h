// Test helpers: locating ../shared, skipping or failing when it is absent.
#ifndef LOCFORGE_TESTS_TESTING_H_
#define LOCFORGE_TESTS_TESTING_H_

#include <gtest/gtest.h>

#include <filesystem>
#include <string>
#include <vector>

namespace locforge::testing {

// The shared data folder: $LOCFORGE_SHARED_DIR, else the one CMake recorded.
std::filesystem::path SharedDir();
// True when LOCFORGE_REQUIRE_SHARED=1: absent data then fails instead of skipping.
bool SharedRequired();
// A fresh empty folder under the system temp dir, removed by the caller or left for debugging.
std::filesystem::path MakeTempDir(const std::string& prefix);

// `s` quoted for /bin/sh ('...', with ' written as '\'').
std::string ShellQuote(const std::string& s);

// Runs the host of the build in `binary_dir`: bin/locforge ARGS... with
// LOCFORGE_PLUGIN_PATH set to that build's plugins, every argument quoted (no
// shell expansion), stdout and stderr into `log`. Returns the exit status
// (0 = success); on failure, print the log.
int RunHost(const std::filesystem::path& binary_dir, const std::vector<std::string>& args,
            const std::filesystem::path& log);

// A simulated recording for end-to-end tests: writes DIR/sim.yaml with one
// `source/simulator` node whose params are `params` (a YAML flow map, e.g.
// "{preset: tiny, seed: 0, masks: false}"), runs it in workspace DIR/sim and
// returns the recording folder (canonical), or an empty path when the run
// failed (its output: DIR/sim.log).
std::filesystem::path SimulateRecording(const std::filesystem::path& binary_dir,
                                        const std::filesystem::path& dir, const std::string& params);

// Text of a file ("" when it cannot be read).
std::string ReadText(const std::filesystem::path& file);

// Rows of a CSV file (RFC 4180: quoted cells may hold commas and doubled quotes).
std::vector<std::vector<std::string>> ReadCsv(const std::filesystem::path& file);

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
