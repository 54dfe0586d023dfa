// The simulator plugin through the SDK's conformance kit: it loads, its
// metadata and parameter refusals are complete, and a run is byte-for-byte
// deterministic whatever the thread count.
#include <gtest/gtest.h>

#include "locforge/runtime/registry.h"
#include "locforge/testkit.h"

#ifndef LOCFORGE_SIM_PLUGIN_FILE
#error "LOCFORGE_SIM_PLUGIN_FILE must name the built plugin"
#endif

namespace {

TEST(SimulatorPlugin, Conforms) {
  const auto report = locforge::testkit::CheckPlugin(LOCFORGE_SIM_PLUGIN_FILE);
  EXPECT_TRUE(report.ok()) << report.ToString();
}

TEST(SimulatorPlugin, RunsDeterministically) {
  locforge::runtime::Registry registry;
  ASSERT_TRUE(locforge::testkit::CheckLoads(registry, LOCFORGE_SIM_PLUGIN_FILE).ok());
  locforge::testkit::DeterminismCase c;
  c.stage_id = "source/simulator";
  c.params = {{"preset", "tiny"}, {"seed", "4"}, {"duration_scale", "0.3"}};
  c.threads = 2;
  const auto report = locforge::testkit::CheckDeterminism(registry, c);
  EXPECT_TRUE(report.ok()) << report.ToString();
}

}  // namespace
