// The three registration plugins, loaded as the host loads them: conformance,
// synthetic scenes with known transforms (and outliers), the information
// matrix, and accuracy on the real small_gicp pair against its ground truth.
#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>

#include <fstream>
#include <map>
#include <memory>
#include <random>
#include <thread>

#include "locforge/pointcloud_io.h"
#include "locforge/registration.h"
#include "locforge/runtime/registry.h"
#include "locforge/testkit.h"
#include "testing.h"

namespace locforge {
namespace {

const char* const kPlugins[] = {LF_REGISTRATION_PLUGIN};
const char* const kBackends[] = {"registration/gicp", "registration/pcl_gicp",
                                 "registration/icp_plane"};
using Params = std::vector<std::pair<std::string, std::string>>;

runtime::Registry& Plugins() {
  static runtime::Registry* r = [] {
    auto* reg = new runtime::Registry;
    for (const char* f : kPlugins) EXPECT_TRUE(reg->LoadFile(f)) << f;
    return reg;
  }();
  return *r;
}

RegistrationBackend Make(const std::string& id, const Params& params = {}) {
  const runtime::StageEntry* stage = Plugins().Find(id);
  if (!stage) throw Error("no stage " + id);
  auto inst = std::make_shared<runtime::StageInstance>(*stage, runtime::CheckStageParams(*stage, params));
  return RegistrationBackend(static_cast<const LfRegistrationInterface*>(inst->Component()),
                             inst->raw(), id, [inst]() mutable { inst.reset(); });
}

Pose MakePose(double rx, double ry, double rz, double tx, double ty, double tz) {
  return Pose(ExpSO3(Eigen::Vector3d(rx, ry, rz)), Eigen::Vector3d(tx, ty, tz));
}

// A room-like scene: floor, three walls, a box and a cylinder, so every
// direction is constrained; `n` points in all.
PointCloud Scene(int n, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  PointCloud c;
  for (int i = 0; i < n; ++i) {
    const double a = u(rng), b = u(rng);
    Eigen::Vector3d p;
    switch (i % 6) {
      case 0: p = {10 * a, 8 * b, 0}; break;                 // floor
      case 1: p = {0, 8 * a, 3 * b}; break;                  // wall x = 0
      case 2: p = {10 * a, 0, 3 * b}; break;                 // wall y = 0
      case 3: p = {10 * a, 8, 3 * b}; break;                 // wall y = 8
      case 4: p = {3 + a, 3 + b, u(rng) < 0.5 ? 1.0 : 0.0}; break;  // box top/bottom
      default: {                                             // cylinder r = 0.5 at (7, 5)
        const double t = 2 * M_PI * a;
        p = {7 + 0.5 * std::cos(t), 5 + 0.5 * std::sin(t), 2 * b};
      }
    }
    c.points.push_back(p.cast<float>());
  }
  return c;
}

PointCloud Transformed(const PointCloud& c, const Pose& T, double noise, uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> g(0, noise);
  PointCloud out;
  for (const auto& p : c.points)
    out.points.push_back((T * p.cast<double>() + Eigen::Vector3d(g(rng), g(rng), g(rng))).cast<float>());
  return out;
}

double RotErrDeg(const Pose& a, const Pose& b) { return RotationAngleDeg(a.q, b.q); }
double TransErr(const Pose& a, const Pose& b) { return (a.t - b.t).norm(); }

TEST(RegistrationPlugins, Conform) {
  for (const char* f : kPlugins) {
    const auto report = testkit::CheckPlugin(f);
    EXPECT_TRUE(report.ok()) << f << "\n" << report.ToString();
  }
}

TEST(RegistrationPlugins, RecoverAKnownTransformOfASyntheticScene) {
  const PointCloud target = Scene(12000, 1);
  const Pose T_target_source = MakePose(0.03, -0.02, 0.08, 0.3, -0.2, 0.05);
  // source = T_source_target * target (resampled noise-free scene, new noise)
  const PointCloud source = Transformed(Scene(12000, 2), T_target_source.Inverse(), 0.005, 3);
  for (const char* id : kBackends) {
    SCOPED_TRACE(id);
    const auto b = Make(id, {{"max_correspondence_distance", "1.0"}});
    for (int threads : {1, 2}) {
      const RegistrationResult r = b.Align(source, target, Pose(), threads);
      EXPECT_TRUE(r.converged);
      EXPECT_LT(RotErrDeg(r.T_target_source, T_target_source), 0.05);
      EXPECT_LT(TransErr(r.T_target_source, T_target_source), 0.005);
      EXPECT_GT(r.inlier_fraction, 0.95);
      EXPECT_GT(r.iterations, 0);
    }
  }
}

TEST(RegistrationPlugins, GicpLevenbergMarquardtFromAFarGuess) {
  const PointCloud target = Scene(8000, 11);
  const Pose gt = MakePose(0.1, -0.05, 0.2, 0.6, -0.4, 0.1);
  const PointCloud source = Transformed(Scene(8000, 12), gt.Inverse(), 0.005, 13);
  const auto b = Make("registration/gicp", {{"optimizer", "levenberg_marquardt"},
                                            {"max_correspondence_distance", "2.0"}});
  const RegistrationResult r = b.Align(source, target, Pose(), 2);
  EXPECT_TRUE(r.converged);
  EXPECT_LT(RotErrDeg(r.T_target_source, gt), 0.05);
  EXPECT_LT(TransErr(r.T_target_source, gt), 0.005);
}

TEST(RegistrationPlugins, GicpRobustKernelsResistOutliers) {
  const PointCloud target = Scene(10000, 4);
  const Pose gt = MakePose(0.02, 0.01, -0.05, -0.2, 0.15, 0.03);
  PointCloud source = Transformed(Scene(10000, 5), gt.Inverse(), 0.005, 6);
  // 30 % outliers: points scattered through the room volume.
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0, 1);
  for (int i = 0; i < 3000; ++i)
    source.points.emplace_back(10 * u(rng), 8 * u(rng), 3 * u(rng));
  double err_none = 0;
  for (const char* kernel : {"none", "huber", "cauchy"}) {
    SCOPED_TRACE(kernel);
    const auto b = Make("registration/gicp", {{"robust_kernel", kernel}, {"kernel_width", "1.0"},
                                              {"max_correspondence_distance", "0.5"}});
    const RegistrationResult r = b.Align(source, target, Pose(), 2);
    const double err = TransErr(r.T_target_source, gt);
    if (std::string(kernel) == "none") err_none = err;
    if (std::string(kernel) != "none") {
      EXPECT_LT(err, 0.005);
      EXPECT_LT(RotErrDeg(r.T_target_source, gt), 0.05);
      EXPECT_LE(err, err_none + 1e-4);
    }
    EXPECT_LT(r.inlier_fraction, 0.95);  // the outliers count in the overlap
  }
}

TEST(RegistrationPlugins, InformationIsPositiveDefiniteAndGrowsWithPoints) {
  const Pose gt = MakePose(0.01, 0.0, 0.02, 0.1, 0.0, 0.0);
  for (const char* id : kBackends) {
    SCOPED_TRACE(id);
    const auto b = Make(id);
    double smallest[2];
    for (int k = 0; k < 2; ++k) {
      const int n = k == 0 ? 3000 : 12000;
      const RegistrationResult r =
          b.Align(Transformed(Scene(n, 8), gt.Inverse(), 0.003, 9), Scene(n, 10), Pose(), 2);
      const Matrix6d H = r.information;
      EXPECT_LT((H - H.transpose()).norm(), 1e-9 * H.norm());
      Eigen::SelfAdjointEigenSolver<Matrix6d> eig(H);
      EXPECT_GT(eig.eigenvalues()[0], 0) << H;
      smallest[k] = eig.eigenvalues()[0];
    }
    EXPECT_GT(smallest[1], 2.5 * smallest[0]);  // ~4x the points, ~4x the information
  }
}

TEST(RegistrationPlugins, RefuseTooSmallClouds) {
  PointCloud tiny;
  tiny.points = {{0, 0, 0}, {1, 0, 0}};
  for (const char* id : kBackends) {
    try {
      Make(id).Align(tiny, Scene(100, 1), Pose(), 1);
      ADD_FAILURE() << id;
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), LF_BAD_INPUT) << e.what();
    }
  }
}

// Results of our GICP with its cache of preprocessed clouds are bit-identical
// to those without it: on a miss, on a hit, with the clouds' roles swapped,
// at 1 and 2 threads, and from concurrent registrations on one instance.
TEST(RegistrationPlugins, GicpCacheLeavesResultsBitIdentical) {
  const PointCloud target = Scene(12000, 21);
  const Pose gt = MakePose(0.02, -0.01, 0.04, 0.2, -0.1, 0.03);
  const PointCloud source = Transformed(Scene(12000, 22), gt.Inverse(), 0.005, 23);
  const Params base = {{"voxel_size", "0.1"}, {"max_correspondence_distance", "1.0"}};
  Params off = base, on = base;
  off.emplace_back("cache_clouds", "0");
  on.emplace_back("cache_clouds", "4");
  const auto cold = Make("registration/gicp", off), warm = Make("registration/gicp", on);
  const auto same = [](const RegistrationResult& a, const RegistrationResult& b) {
    return a.converged == b.converged && a.iterations == b.iterations && a.num_inliers == b.num_inliers &&
           a.final_error == b.final_error && a.T_target_source.q.coeffs() == b.T_target_source.q.coeffs() &&
           a.T_target_source.t == b.T_target_source.t && a.information == b.information;
  };
  const std::vector<Pose> guesses = {Pose(), MakePose(0, 0, 0.03, 0.1, 0, 0), MakePose(0.01, 0, -0.02, 0, 0.1, 0)};
  std::vector<RegistrationResult> expected;
  for (const Pose& g : guesses) expected.push_back(cold.Align(source, target, g, 1));
  EXPECT_LT(RotErrDeg(expected[0].T_target_source, gt), 0.05);
  for (int threads : {1, 2})
    for (size_t k = 0; k < guesses.size(); ++k) {  // the first call misses, the others hit
      EXPECT_TRUE(same(cold.Align(source, target, guesses[k], threads), expected[k])) << threads << " " << k;
      EXPECT_TRUE(same(warm.Align(source, target, guesses[k], threads), expected[k])) << threads << " " << k;
    }
  EXPECT_TRUE(same(warm.Align(target, source, Pose(), 2), cold.Align(target, source, Pose(), 1)));
  // A source moved by 1 mm (same size) is a miss, and registers as it should.
  const PointCloud moved = Transformed(source, MakePose(0, 0, 0, 0.001, 0, 0), 0, 0);
  EXPECT_TRUE(same(warm.Align(moved, target, Pose(), 2), cold.Align(moved, target, Pose(), 2)));
  // Concurrent registrations on the one instance.
  std::vector<RegistrationResult> got(8);
  std::vector<std::thread> workers;
  for (size_t w = 0; w < got.size(); ++w)
    workers.emplace_back([&, w] { got[w] = warm.Align(source, target, guesses[w % guesses.size()], 1 + w % 2); });
  for (auto& w : workers) w.join();
  for (size_t w = 0; w < got.size(); ++w) EXPECT_TRUE(same(got[w], expected[w % guesses.size()])) << w;
}

Pose ReadMatrix(const std::filesystem::path& file) {
  std::ifstream in(file);
  Eigen::Matrix4d m;
  for (int i = 0; i < 16; ++i) in >> m(i / 4, i % 4);
  if (!in) throw Error("cannot read " + file.string());
  return Pose::FromMatrix(m);
}

// On the small_gicp pair (voxel 0.25 m), the non-robust back-ends (PCL's
// GICP and point-to-plane ICP, our GICP with robust_kernel none) agree with
// each other within ~0.15 deg / 2 cm but differ from the shipped
// T_target_source by ~0.67 deg (almost all roll) and 1-3 cm. Our GICP's
// default Cauchy kernel (width 0.25) lands within 0.25 deg / 1.1 cm of it:
// the roll was the pull of points without a counterpart (docs/results/registration.md). The
// bounds are the measured errors plus a margin; the agreement of our
// non-robust GICP with PCL's (same cost) is checked tightly.
TEST(RegistrationPlugins, SmallGicpPairMatchesGroundTruth) {
  LOCFORGE_SHARED_PATH_OR_SKIP(dir, "data/registration/small_gicp_pair");
  const PointCloud source = ReadPly(dir / "source.ply");
  const PointCloud target = ReadPly(dir / "target.ply");
  const Pose gt = ReadMatrix(dir / "T_target_source.txt");
  const Pose perturbed = MakePose(0.02, -0.02, 0.05, 0.2, -0.2, 0.1) * gt;
  struct Run {
    std::string id, label, extra_key, extra_value;
    double max_rot_deg, max_trans_m;
  };
  const std::vector<Run> runs = {{"registration/gicp", "gicp (default: cauchy)", "", "", 0.35, 0.015},
                                 {"registration/gicp", "gicp robust_kernel none", "robust_kernel", "none", 0.8, 0.04},
                                 {"registration/pcl_gicp", "pcl_gicp", "", "", 0.8, 0.04},
                                 {"registration/icp_plane", "icp_plane", "", "", 0.8, 0.04}};
  std::map<std::string, Pose> solution;
  for (const Run& run : runs) {
    std::vector<std::pair<std::string, std::string>> params = {{"voxel_size", "0.25"},
                                                               {"max_correspondence_distance", "1.0"}};
    if (!run.extra_key.empty()) params.emplace_back(run.extra_key, run.extra_value);
    const auto b = Make(run.id.c_str(), params);
    for (int k = 0; k < 2; ++k) {
      const Pose init = k == 0 ? Pose() : perturbed;
      const RegistrationResult r = b.Align(source, target, init, 2);
      const double rot = RotErrDeg(r.T_target_source, gt), tr = TransErr(r.T_target_source, gt);
      std::printf("%-24s init %-9s rot %.4f deg  trans %.4f m  iters %d  overlap %.3f\n", run.label.c_str(),
                  k ? "perturbed" : "identity", rot, tr, r.iterations, r.inlier_fraction);
      EXPECT_TRUE(r.converged) << run.label;
      EXPECT_LT(rot, run.max_rot_deg) << run.label;
      EXPECT_LT(tr, run.max_trans_m) << run.label;
      EXPECT_GT(r.inlier_fraction, 0.9) << run.label;
      if (k == 0) solution[run.label] = r.T_target_source;
    }
  }
  const Pose& ours = solution["gicp robust_kernel none"];
  const Pose& pcl = solution["pcl_gicp"];
  EXPECT_LT(RotErrDeg(ours, pcl), 0.05);
  EXPECT_LT(TransErr(ours, pcl), 0.005);
}

}  // namespace
}  // namespace locforge
