// Every in-tree plugin through the SDK's conformance kit (testkit.h): it
// loads, its metadata is complete, and it refuses bad parameters.
#include <gtest/gtest.h>

#include <sstream>
#include <string>
#include <vector>

#include "locforge/testkit.h"

namespace {

std::vector<std::string> PluginFiles() {
  std::vector<std::string> out;
  std::istringstream in(LOCFORGE_PLUGIN_FILES);
  for (std::string file; std::getline(in, file, ':');) out.push_back(file);
  return out;
}

class PluginConformance : public ::testing::TestWithParam<std::string> {};

TEST_P(PluginConformance, Conforms) {
  const auto report = locforge::testkit::CheckPlugin(GetParam());
  EXPECT_TRUE(report.ok()) << GetParam() << "\n" << report.ToString();
}

INSTANTIATE_TEST_SUITE_P(InTree, PluginConformance, ::testing::ValuesIn(PluginFiles()),
                         [](const ::testing::TestParamInfo<std::string>& info) {
                           std::string name = info.param.substr(info.param.rfind('/') + 1);
                           std::string out;
                           for (char c : name)
                             if (std::isalnum(static_cast<unsigned char>(c))) out += c;
                           return out;
                         });

}  // namespace
