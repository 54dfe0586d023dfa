#include <gtest/gtest.h>

#include <cmath>

#include "locforge/error.h"
#include "texture.h"

namespace locforge::sim {
namespace {

// Mean absolute horizontal gradient of level 0: a proxy for "has features".
double GradientEnergy(const Texture& t) {
  const auto& l = t.levels[0];
  double sum = 0;
  for (int y = 0; y < l.size; ++y)
    for (int x = 0; x + 1 < l.size; ++x)
      sum += std::abs(l.rgb[(y * l.size + x + 1) * 3] - l.rgb[(y * l.size + x) * 3]);
  return sum / (l.size * (l.size - 1));
}

TEST(Texture, EveryKindBuildsWithAMipPyramid) {
  for (const char* key : {"noise:0", "bricks:1", "tiles:2", "ceiling:0", "poster:5", "shopfront:1",
                          "signage:3", "glossy:0", "plain:0", "clothes:4", "marker"}) {
    const Texture t = MakeTexture(key, 0, 128);
    EXPECT_EQ(t.levels[0].size, 128) << key;
    EXPECT_EQ(t.levels.back().size, 4) << key;
  }
  EXPECT_THROW(MakeTexture("lava:1", 0, 64), ParamError);
  EXPECT_THROW(MakeTexture("poster:x", 0, 64), ParamError);
}

TEST(Texture, RichKindsHaveGradientsAndTemporaryWallsDoNot) {
  EXPECT_LT(GradientEnergy(MakeTexture("plain:0", 0, 256)), 2.0);
  for (const char* key : {"noise:0", "bricks:0", "tiles:0", "poster:0", "shopfront:0"})
    EXPECT_GT(GradientEnergy(MakeTexture(key, 0, 256)), 4.0) << key;
}

TEST(Texture, SignageChangesWithTheDayPostersDoNot) {
  EXPECT_NE(MakeTexture("signage:1", 0, 64).levels[0].rgb, MakeTexture("signage:1", 1, 64).levels[0].rgb);
  EXPECT_EQ(MakeTexture("poster:1", 0, 64).levels[0].rgb, MakeTexture("poster:1", 1, 64).levels[0].rgb);
  EXPECT_EQ(MakeTexture("signage:1", 2, 64).levels[0].rgb, MakeTexture("signage:1", 2, 64).levels[0].rgb);
}

TEST(Texture, BilinearSamplingHitsTexelCentresAndWraps) {
  const Texture t = MakeTexture("poster:2", 0, 64);
  const auto& l = t.levels[0];
  const int x = 10, y = 20;
  const Eigen::Vector3f at = t.Sample((x + 0.5) / 64.0, (y + 0.5) / 64.0, 1);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(at[c], l.rgb[(y * 64 + x) * 3 + c], 1e-3);
  const Eigen::Vector3f wrapped = t.Sample((x + 0.5) / 64.0 + 3, (y + 0.5) / 64.0 - 2, 1);
  EXPECT_NEAR((at - wrapped).norm(), 0, 1e-3);
  // Marker: black centre, white corner.
  const Texture m = MakeTexture("marker", 0, 64);
  EXPECT_LT(m.Sample(0.5, 0.5, 1).x(), 1);
  EXPECT_GT(m.Sample(0.05, 0.05, 1).x(), 254);
}

}  // namespace
}  // namespace locforge::sim
