// RegistrationBackend <-> RegistrationComponent through the C table: results,
// errors and ownership cross the boundary intact.
#include "locforge/registration.h"

#include <gtest/gtest.h>

namespace locforge {
namespace {

struct ShiftOptions {
  double shift_x = 0.5;  // Added to the initial guess's x translation.
  static void Declare(ParamSchema<ShiftOptions>& s) {
    s.Add("shift_x", &ShiftOptions::shift_x, "Added to the guess's x translation");
  }
};

int g_live = 0;  // live Shift instances

// Returns the guess moved by shift_x, echoing what it received in the result.
class Shift : public RegistrationComponent<Shift, ShiftOptions> {
 public:
  static StageMeta Meta() { return {"registration", "shift", "Test back-end", {}, {}}; }
  explicit Shift(ShiftOptions o) : RegistrationComponent(std::move(o)) { ++g_live; }
  ~Shift() override { --g_live; }
  RegistrationResult Align(const PointCloud& source, const PointCloud& target, const Pose& guess,
                           int threads) const override {
    if (source.empty()) throw InputError("source", 0, "", "empty cloud");
    RegistrationResult r;
    r.converged = true;
    r.iterations = threads;
    r.num_inliers = target.size();
    r.inlier_fraction = source.has_normals() ? 1.0 : 0.5;
    r.final_error = source.has_times() ? source.times.back() : -1;
    r.T_target_source = Pose(guess.q, guess.t + Eigen::Vector3d(options().shift_x, 0, 0));
    r.information = Matrix6d::Identity() * static_cast<double>(source.size());
    return r;
  }
};

RegistrationBackend MakeShift(double shift) {
  const std::string value = FormatDouble(shift);
  const LfParam p{"shift_x", value.c_str()};
  LfError err{};
  void* inst = internal::Adapter<Shift>::Create(&p, 1, &err);
  EXPECT_NE(inst, nullptr) << err.message;
  const auto* table =
      static_cast<const LfRegistrationInterface*>(internal::Adapter<Shift>::ComponentTable(inst));
  return RegistrationBackend(table, inst, "registration/shift",
                             [inst] { internal::Adapter<Shift>::Destroy(inst); });
}

PointCloud Cloud(int n, bool normals, bool times) {
  PointCloud c;
  for (int i = 0; i < n; ++i) {
    c.points.emplace_back(i, 2 * i, 3 * i);
    if (normals) c.normals.emplace_back(0, 0, 1);
    if (times) c.times.push_back(0.1 * i);
  }
  return c;
}

TEST(Registration, ResultAndPoseCrossTheBoundary) {
  const RegistrationBackend backend = MakeShift(0.25);
  const Pose guess(Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ())),
                   Eigen::Vector3d(1, 2, 3));
  const RegistrationResult r = backend.Align(Cloud(5, true, true), Cloud(7, false, false), guess, 3);
  EXPECT_TRUE(r.converged);
  EXPECT_EQ(r.iterations, 3);
  EXPECT_EQ(r.num_inliers, 7u);
  EXPECT_EQ(r.inlier_fraction, 1.0);
  EXPECT_DOUBLE_EQ(r.final_error, 0.4);
  EXPECT_LT(RotationAngleDeg(r.T_target_source.q, guess.q), 1e-9);
  EXPECT_LT((r.T_target_source.t - Eigen::Vector3d(1.25, 2, 3)).norm(), 1e-12);
  EXPECT_EQ(r.information, Matrix6d::Identity() * 5.0);
}

TEST(Registration, PluginErrorBecomesErrorWithCode) {
  const RegistrationBackend backend = MakeShift(0);
  try {
    backend.Align(PointCloud{}, Cloud(3, false, false), Pose(), 1);
    FAIL() << "no throw";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), LF_BAD_INPUT);
    EXPECT_NE(std::string(e.what()).find("registration/shift"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("empty cloud"), std::string::npos) << e.what();
  }
}

TEST(Registration, MoveOnlyAndDestroysOnce) {
  ASSERT_EQ(g_live, 0);
  {
    RegistrationBackend a = MakeShift(1);
    EXPECT_EQ(g_live, 1);
    RegistrationBackend b = std::move(a);
    EXPECT_EQ(g_live, 1);
    b = MakeShift(2);
    EXPECT_EQ(g_live, 1);
    EXPECT_NEAR(b.Align(Cloud(2, 0, 0), Cloud(2, 0, 0), Pose(), 1).T_target_source.t.x(), 2, 1e-12);
    EXPECT_THROW(a.Align(Cloud(2, 0, 0), Cloud(2, 0, 0), Pose(), 1), Error);
  }
  EXPECT_EQ(g_live, 0);
}

TEST(Registration, CreateThroughRunContext) {
  struct Host {
    int created = 0, destroyed = 0;
  } host;
  LfRunContext c{};
  c.struct_size = sizeof(c);
  c.host = &host;
  c.create_component = [](void* h, const char* id, const LfParam* p, uint32_t n,
                          const LfStageInfo** info, LfError* err) -> void* {
    static LfStageInfo shift_info = [] {
      LfStageInfo i{};
      i.struct_size = sizeof(i);
      i.component_interface = LF_REGISTRATION_INTERFACE;
      i.component = &internal::Adapter<Shift>::ComponentTable;
      return i;
    }();
    if (std::string(id) != "registration/shift") {
      internal::WriteError(err, std::string("no stage ") + id);
      return nullptr;
    }
    ++static_cast<Host*>(h)->created;
    *info = &shift_info;
    return internal::Adapter<Shift>::Create(p, n, err);
  };
  c.destroy_component = [](void* h, const LfStageInfo*, void* inst) {
    ++static_cast<Host*>(h)->destroyed;
    internal::Adapter<Shift>::Destroy(inst);
  };
  const RunContext ctx(&c);
  {
    const auto b = RegistrationBackend::Create(ctx, "registration/shift", {{"shift_x", "3"}});
    EXPECT_NEAR(b.Align(Cloud(2, 0, 0), Cloud(2, 0, 0), Pose(), 1).T_target_source.t.x(), 3, 1e-12);
  }
  EXPECT_EQ(host.created, 1);
  EXPECT_EQ(host.destroyed, 1);
  try {
    RegistrationBackend::Create(ctx, "registration/nope");
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("no stage registration/nope"), std::string::npos);
  }
  EXPECT_THROW(RegistrationBackend::Create(ctx, "registration/shift", {{"shift_y", "1"}}), Error);
}

TEST(Registration, ViewsWithStrides) {
  // Interleaved x y z nx ny nz records, as a caller's own buffer might hold.
  const float buf[] = {1, 2, 3, 0, 0, 1, 4, 5, 6, 0, 1, 0};
  LfPointCloudView v{};
  v.struct_size = sizeof(v);
  v.num_points = 2;
  v.xyz = buf;
  v.xyz_stride = 24;
  v.normals = buf + 3;
  v.normals_stride = 24;
  const PointCloud c = CopyFromView(v);
  ASSERT_EQ(c.size(), 2u);
  EXPECT_EQ(c.points[1], Eigen::Vector3f(4, 5, 6));
  EXPECT_EQ(c.normals[1], Eigen::Vector3f(0, 1, 0));
  EXPECT_FALSE(c.has_times());
  v.xyz = nullptr;
  EXPECT_THROW(CopyFromView(v), InputError);
  PointCloud bad = Cloud(3, false, false);
  bad.times = {1.0};
  EXPECT_THROW(MakeView(bad), Error);
}

}  // namespace
}  // namespace locforge
