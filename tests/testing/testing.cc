#include "testing.h"

#include <unistd.h>

#include <cstdlib>
#include <random>

namespace locforge::testing {

std::filesystem::path SharedDir() {
  if (const char* env = std::getenv("LOCFORGE_SHARED_DIR"); env && *env) return env;
  return LOCFORGE_DEFAULT_SHARED_DIR;
}

bool SharedRequired() {
  const char* env = std::getenv("LOCFORGE_REQUIRE_SHARED");
  return env && std::string(env) == "1";
}

std::filesystem::path MakeTempDir(const std::string& prefix) {
  std::random_device rd;
  const auto dir = std::filesystem::temp_directory_path() /
                   (prefix + "-" + std::to_string(::getpid()) + "-" + std::to_string(rd()));
  std::filesystem::create_directories(dir);
  return dir;
}

}  // namespace locforge::testing
