// Our APE/RPE against the evo tool's reference results shipped in
// ../shared/data/trajectories/res_files (zip: info.json + stats.json).
#include "metrics.h"

#include <gtest/gtest.h>

#include <cstdlib>
#include <map>
#include <regex>

#include "locforge/error.h"

#include "testing.h"

namespace locforge::eval {
namespace {

std::map<std::string, double> EvoStats(const fs::path& zip, const fs::path& dir) {
  const std::string cmd = "unzip -o -q '" + zip.string() + "' stats.json -d '" + dir.string() + "'";
  if (std::system(cmd.c_str()) != 0) throw Error("cannot unzip " + zip.string());
  const std::string json = ReadFile(dir / "stats.json");
  std::map<std::string, double> out;
  const std::regex field("\"(\\w+)\": ([-0-9.eE+]+)");
  for (std::sregex_iterator it(json.begin(), json.end(), field), end; it != end; ++it)
    out[(*it)[1]] = std::stod((*it)[2]);
  return out;
}

void ExpectMatchesEvo(const Statistics& s, const std::map<std::string, double>& evo) {
  const std::map<std::string, double> ours = {{"rmse", s.rmse}, {"mean", s.mean}, {"median", s.median},
                                              {"std", s.std},   {"min", s.min},   {"max", s.max},
                                              {"sse", s.sse}};
  for (const auto& [k, v] : ours) {
    ASSERT_TRUE(evo.count(k)) << k;
    EXPECT_NEAR(v, evo.at(k), 1e-6 * std::abs(evo.at(k))) << k;
  }
}

TEST(Metrics, KittiOrbApeSe3MatchesEvo) {
  LOCFORGE_SHARED_PATH_OR_SKIP(dir, "data/trajectories");
  const auto tmp = testing::MakeTempDir("evo_ape");
  Trajectory ref = ReadKitti(dir / "KITTI_00_gt.txt"), est = ReadKitti(dir / "KITTI_00_ORB.txt");
  Associate(0.01, &ref, &est);
  ASSERT_EQ(est.size(), 4541u);
  Align(Alignment::kSE3, ref, &est);
  ExpectMatchesEvo(ComputeStatistics(AbsolutePoseErrors(ref, est).translation),
                   EvoStats(dir / "res_files/orb_ape.zip", tmp));
  fs::remove_all(tmp);
}

TEST(Metrics, KittiOrbRpeTenMetresMatchesEvo) {
  LOCFORGE_SHARED_PATH_OR_SKIP(dir, "data/trajectories");
  const auto tmp = testing::MakeTempDir("evo_rpe");
  const Trajectory ref = ReadKitti(dir / "KITTI_00_gt.txt"), est = ReadKitti(dir / "KITTI_00_ORB.txt");
  const Errors e = RelativePoseErrors(ref, est, 10.0, DeltaUnit::kMeters);
  EXPECT_EQ(e.translation.size(), 353u);
  ExpectMatchesEvo(ComputeStatistics(e.translation), EvoStats(dir / "res_files/orb_rpe.zip", tmp));
  fs::remove_all(tmp);
}

// Umeyama recovers a known similarity exactly; APE is then ~0.
TEST(Metrics, UmeyamaRecoversSim3AndTumAssociation) {
  Trajectory ref, est;
  for (int i = 0; i < 50; ++i) {
    const double a = 0.1 * i;
    const Pose p(Eigen::Quaterniond(Eigen::AngleAxisd(a, Eigen::Vector3d::UnitZ())),
                 Eigen::Vector3d(std::cos(a) * 3, std::sin(a) * 2, 0.1 * i));
    ref.push_back({i * 0.1, p});
  }
  const Eigen::Quaterniond R(Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()));
  const Eigen::Vector3d t(5, -1, 2);
  for (const auto& p : ref)  // est = inverse similarity of ref, stamps shifted by 3 ms
    est.push_back({p.time + 0.003, Pose(R.conjugate() * p.T_world_device.q, R.conjugate() * (p.T_world_device.t - t) / 2.0)});
  est.erase(est.begin() + 10);
  Associate(0.01, &ref, &est);
  EXPECT_EQ(ref.size(), 49u);
  const Similarity s = Align(Alignment::kSim3, ref, &est);
  EXPECT_NEAR(s.scale, 2.0, 1e-9);
  const Statistics st = ComputeStatistics(AbsolutePoseErrors(ref, est).translation);
  EXPECT_LT(st.max, 1e-9);
  EXPECT_LT(ComputeStatistics(AbsolutePoseErrors(ref, est).rotation).max, 1e-6);
  // TUM round trip.
  const auto tmp = testing::MakeTempDir("tum");
  WriteFileAtomic(tmp / "a.tum", FormatTum(ref));
  const Trajectory back = ReadTum(tmp / "a.tum");
  ASSERT_EQ(back.size(), ref.size());
  EXPECT_LT((back[7].T_world_device.t - ref[7].T_world_device.t).norm(), 1e-12);
  WriteFileAtomic(tmp / "bad.tum", "# c\n1 2 3\n");
  EXPECT_THROW(ReadTum(tmp / "bad.tum"), InputError);
  fs::remove_all(tmp);
}

}  // namespace
}  // namespace locforge::eval
