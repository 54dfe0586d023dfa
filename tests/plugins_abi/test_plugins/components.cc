// A registration component (closed-form Kabsch alignment of two clouds with
// known point-to-point correspondences) and a stage that creates it through
// the run context and aligns a cloud moved by a known transform.
#include <Eigen/Dense>
#include <Eigen/Geometry>
#include <cmath>
#include <cstdio>
#include <sstream>

#include "locforge/fs.h"
#include "locforge/plugin.h"

namespace {

using locforge::ParamSchema;
using locforge::RunContext;
using locforge::StageMeta;

struct KabschOptions {
  int min_points = 3;  // Fewest correspondences accepted.
  static void Declare(ParamSchema<KabschOptions>& s) {
    s.Add("min_points", &KabschOptions::min_points, "Fewest correspondences accepted").Min(3);
  }
};

Eigen::Vector3d PointAt(const LfPointCloudView& v, uint64_t i) {
  const auto* p = reinterpret_cast<const float*>(reinterpret_cast<const char*>(v.xyz) +
                                                 i * (v.xyz_stride ? v.xyz_stride : 12));
  return {p[0], p[1], p[2]};
}

Eigen::Matrix3d Skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return m;
}

class Kabsch : public locforge::Component<KabschOptions> {
 public:
  static constexpr const char* kInterface = LF_REGISTRATION_INTERFACE;
  static StageMeta Meta() {
    StageMeta meta{"registration", "kabsch_test",
                   "Closed-form point-to-point alignment with known correspondences (test)", {}, {}};
    meta.version = "2.0.0";
    return meta;
  }
  using Component::Component;

  const void* Table() {
    static const LfRegistrationInterface table = {sizeof(LfRegistrationInterface), &Align};
    return &table;
  }

 private:
  static int32_t Align(void* instance, const LfPointCloudView* source,
                       const LfPointCloudView* target, const double initial[16], int32_t,
                       LfRegistrationResult* result, LfError* err) {
    return locforge::internal::Guard(err, [&] {
      auto* self = static_cast<Kabsch*>(instance);
      const uint64_t n = source->num_points;
      if (n != target->num_points)
        throw locforge::Error("kabsch_test needs clouds of equal size (correspondences by index)");
      if (n < static_cast<uint64_t>(self->options().min_points))
        throw locforge::Error("kabsch_test: " + std::to_string(n) + " points, fewer than min_points");
      Eigen::Matrix4d init = Eigen::Map<const Eigen::Matrix<double, 4, 4, Eigen::RowMajor>>(initial);
      // Centroids, then the SVD of the cross-covariance (Umeyama without scale).
      Eigen::Vector3d cs = Eigen::Vector3d::Zero(), ct = Eigen::Vector3d::Zero();
      std::vector<Eigen::Vector3d> s(n), t(n);
      for (uint64_t i = 0; i < n; ++i) {
        s[i] = init.topLeftCorner<3, 3>() * PointAt(*source, i) + init.topRightCorner<3, 1>();
        t[i] = PointAt(*target, i);
        cs += s[i];
        ct += t[i];
      }
      cs /= static_cast<double>(n);
      ct /= static_cast<double>(n);
      Eigen::Matrix3d h = Eigen::Matrix3d::Zero();
      for (uint64_t i = 0; i < n; ++i) h += (s[i] - cs) * (t[i] - ct).transpose();
      Eigen::JacobiSVD<Eigen::Matrix3d> svd(h, Eigen::ComputeFullU | Eigen::ComputeFullV);
      Eigen::Matrix3d d = Eigen::Matrix3d::Identity();
      d(2, 2) = (svd.matrixV() * svd.matrixU().transpose()).determinant() < 0 ? -1 : 1;
      const Eigen::Matrix3d r = svd.matrixV() * d * svd.matrixU().transpose();
      Eigen::Matrix4d delta = Eigen::Matrix4d::Identity();
      delta.topLeftCorner<3, 3>() = r;
      delta.topRightCorner<3, 1>() = ct - r * cs;
      const Eigen::Matrix4d total = delta * init;

      double error = 0;
      Eigen::Matrix<double, 6, 6> info = Eigen::Matrix<double, 6, 6>::Zero();
      for (uint64_t i = 0; i < n; ++i) {
        const Eigen::Vector3d p = total.topLeftCorner<3, 3>() * PointAt(*source, i) +
                                  total.topRightCorner<3, 1>();
        error += (p - t[i]).norm();
        Eigen::Matrix<double, 3, 6> j;
        j << -Skew(p), Eigen::Matrix3d::Identity();
        info += j.transpose() * j;
      }
      *result = LfRegistrationResult{};
      result->struct_size = sizeof(LfRegistrationResult);
      result->converged = 1;
      result->iterations = 1;
      result->num_inliers = n;
      result->inlier_fraction = 1.0;
      result->final_error = error / static_cast<double>(n);
      Eigen::Map<Eigen::Matrix<double, 4, 4, Eigen::RowMajor>>(result->T_target_source) = total;
      Eigen::Map<Eigen::Matrix<double, 6, 6, Eigen::RowMajor>>(result->information) = info;
    });
  }
};

locforge::ComponentSpec MinPoints(const char* stage) {
  locforge::ComponentSpec spec(stage);
  spec.params = {{"min_points", "3"}};
  return spec;
}

struct AlignCheckOptions {
  // Component stage used, with its parameters.
  locforge::ComponentSpec backend = MinPoints("registration/kabsch_test");
  int points = 200;                                  // Points in the cloud.
  std::vector<double> rotation = {0.3, -0.2, 0.5};     // Euler x, y, z (radians), R = Rz Ry Rx.
  std::vector<double> translation = {1.0, -2.0, 0.5};  // Metres.
  static void Declare(ParamSchema<AlignCheckOptions>& s) {
    s.Add("backend", &AlignCheckOptions::backend, "Registration component and its parameters")
        .Implements(LF_REGISTRATION_INTERFACE);
    s.Add("points", &AlignCheckOptions::points, "Points in the synthetic cloud").Range(3, 1000000);
    s.Add("rotation", &AlignCheckOptions::rotation, "Euler angles x, y, z in radians");
    s.Add("translation", &AlignCheckOptions::translation, "Translation in metres");
  }
  bool Check(std::string* why) const {
    if (rotation.size() != 3 || translation.size() != 3) {
      *why = "parameters 'rotation' and 'translation' need 3 values each";
      return false;
    }
    return true;
  }
};

class AlignCheck : public locforge::Stage<AlignCheckOptions> {
 public:
  static StageMeta Meta() {
    return {"test", "align_check",
            "Moves a cloud by a known transform and recovers it with a registration component",
            {},
            {{"result", "report", "transform.txt: the recovered 4x4 T_target_source"}}};
  }
  using Stage::Stage;

  void Run(RunContext& ctx) override {
    const auto& o = options();
    const Eigen::Matrix3d r = (Eigen::AngleAxisd(o.rotation[2], Eigen::Vector3d::UnitZ()) *
                               Eigen::AngleAxisd(o.rotation[1], Eigen::Vector3d::UnitY()) *
                               Eigen::AngleAxisd(o.rotation[0], Eigen::Vector3d::UnitX()))
                                  .toRotationMatrix();
    const Eigen::Vector3d t(o.translation[0], o.translation[1], o.translation[2]);
    std::vector<float> source, target;
    uint64_t state = 12345;
    auto next = [&] {  // LCG in [-5, 5): deterministic everywhere
      state = state * 6364136223846793005ull + 1442695040888963407ull;
      return static_cast<float>((state >> 11) * 0x1.0p-53 * 10.0 - 5.0);
    };
    for (int i = 0; i < o.points; ++i) {
      const Eigen::Vector3f p(next(), next(), next());
      const Eigen::Vector3d q = r * p.cast<double>() + t;
      source.insert(source.end(), {p.x(), p.y(), p.z()});
      target.insert(target.end(), {static_cast<float>(q.x()), static_cast<float>(q.y()),
                                   static_cast<float>(q.z())});
    }
    const LfRunContext* c = ctx.raw();
    LfError err{};
    err.struct_size = sizeof(err);
    std::vector<LfParam> params;
    for (const auto& [name, value] : o.backend.params) params.push_back({name.c_str(), value.c_str()});
    const LfStageInfo* info = nullptr;
    void* component = c->create_component(c->host, o.backend.stage.c_str(), params.data(),
                                          static_cast<uint32_t>(params.size()), &info, &err);
    if (component == nullptr) throw locforge::Error("cannot create " + o.backend.stage + ": " + err.message);
    struct Release {  // destroys the component on every path out
      const LfRunContext* c;
      const LfStageInfo* info;
      void* instance;
      ~Release() { c->destroy_component(c->host, info, instance); }
    } release{c, info, component};
    if (info == nullptr || info->component_interface == nullptr ||
        std::string(info->component_interface) != LF_REGISTRATION_INTERFACE)
      throw locforge::Error(o.backend.stage + " is not a " LF_REGISTRATION_INTERFACE " component");
    const auto* table = static_cast<const LfRegistrationInterface*>(info->component(component));
    LfPointCloudView src{sizeof(LfPointCloudView), static_cast<uint64_t>(o.points), source.data(), 12,
                         nullptr, 0, nullptr, 0};
    LfPointCloudView tgt = src;
    tgt.xyz = target.data();
    const double identity[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
    LfRegistrationResult result{};
    result.struct_size = sizeof(result);
    if (table->align(component, &src, &tgt, identity, ctx.threads(), &result, &err) != LF_OK)
      throw locforge::Error("align failed: " + std::string(err.message));
    std::ostringstream out;
    for (int i = 0; i < 16; ++i) out << locforge::FormatDouble(result.T_target_source[i]) << (i % 4 == 3 ? "\n" : " ");
    out << "final_error " << locforge::FormatDouble(result.final_error) << "\n";
    out << "inliers " << result.num_inliers << "\n";
    locforge::WriteFileAtomic(ctx.output_dir() / "transform.txt", out.str());
  }
};

}  // namespace

LOCFORGE_PLUGIN("lftest_components", "1.0.0", "Test registration component and its user",
                Kabsch, AlignCheck)
