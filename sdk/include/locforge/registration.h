// Point-cloud registration through LF_REGISTRATION_INTERFACE components
// (abi.h), from both sides of the boundary.
//
// Caller side (a stage using a back-end in-process):
//
//   // options().registration: a ComponentSpec parameter chosen in the graph,
//   // declared .Implements(LF_REGISTRATION_INTERFACE) (params.h)
//   auto icp = locforge::RegistrationBackend::Create(ctx, options().registration);
//   // or by id with parameters, e.g. one of them overridden:
//   auto fine = locforge::RegistrationBackend::Create(
//       ctx, options().registration.With("max_correspondence_distance", "0.3"));
//   locforge::RegistrationResult r = icp.Align(source, target, guess, ctx.threads());
//   if (r.converged) use(r.T_target_source, r.information);
//
// Back-end side (a plugin providing one):
//
//   class MyIcp : public locforge::RegistrationComponent<MyIcp, MyIcpOptions> {
//    public:
//     static locforge::StageMeta Meta() { return {"registration", "my_icp", "...", {}, {}}; }
//     using RegistrationComponent::RegistrationComponent;
//     locforge::RegistrationResult Align(const locforge::PointCloud& source,
//                                        const locforge::PointCloud& target,
//                                        const locforge::Pose& initial_T_target_source,
//                                        int threads) const override;
//   };
//   LOCFORGE_PLUGIN("my_icp", "1.0.0", "...", MyIcp)
//
// Conventions: T_target_source maps source points into the target frame
// (pose.h); the information matrix is 6x6 in tangent order (rx ry rz tx ty tz),
// i.e. for a perturbation T <- Exp(xi) * T applied on the left.
#ifndef LOCFORGE_REGISTRATION_H_
#define LOCFORGE_REGISTRATION_H_

#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "locforge/abi.h"
#include "locforge/error.h"
#include "locforge/plugin.h"
#include "locforge/pose.h"

namespace locforge {

// A point cloud. `normals` and `times` are either empty or one per point.
struct PointCloud {
  std::vector<Eigen::Vector3f> points;
  std::vector<Eigen::Vector3f> normals;  // unit normals, optional
  std::vector<double> times;             // seconds, optional (per-point capture time)

  size_t size() const { return points.size(); }
  bool empty() const { return points.empty(); }
  bool has_normals() const { return !normals.empty(); }
  bool has_times() const { return !times.empty(); }
  // Throws Error when normals/times are present with the wrong size.
  void CheckConsistent() const;
};

// A zero-copy view of `cloud` for the C boundary; valid while `cloud` lives.
LfPointCloudView MakeView(const PointCloud& cloud);
// Copies a C view (any strides) into a PointCloud. Throws InputError on a
// malformed view (NULL xyz with points, stride smaller than one element).
PointCloud CopyFromView(const LfPointCloudView& view);

struct RegistrationResult {
  bool converged = false;
  int iterations = 0;
  uint64_t num_inliers = 0;
  double inlier_fraction = 0;  // inliers / source points (overlap)
  double final_error = 0;      // mean robust residual of the inliers
  Pose T_target_source;
  Matrix6d information = Matrix6d::Zero();  // (rx ry rz tx ty tz), left perturbation
};

RegistrationResult FromC(const LfRegistrationResult& c);
LfRegistrationResult ToC(const RegistrationResult& r);

// Caller-side handle on one registration component. Move-only; destroys the
// component when it goes away. Align is const and may be called repeatedly;
// distinct backends may align concurrently (one backend per thread).
class RegistrationBackend {
 public:
  // Creates `stage_id` (e.g. "registration/gicp") through the host of `ctx`.
  // Throws Error with the host's/plugin's message when it cannot be created
  // or is not a LF_REGISTRATION_INTERFACE component.
  static RegistrationBackend Create(const RunContext& ctx, const std::string& stage_id,
                                    const std::vector<std::pair<std::string, std::string>>& params = {});
  // The component of a ComponentSpec parameter, with its parameters.
  static RegistrationBackend Create(const RunContext& ctx, const ComponentSpec& component) {
    return Create(ctx, component.stage, component.params);
  }
  // Wraps a component created by other means (e.g. runtime::StageInstance in
  // tests): `table` is its interface table, `release` destroys it (may be empty).
  RegistrationBackend(const LfRegistrationInterface* table, void* instance, std::string name,
                      std::function<void()> release);

  RegistrationBackend(RegistrationBackend&& other) noexcept;
  RegistrationBackend& operator=(RegistrationBackend&& other) noexcept;
  RegistrationBackend(const RegistrationBackend&) = delete;
  RegistrationBackend& operator=(const RegistrationBackend&) = delete;
  ~RegistrationBackend();

  // Aligns `source` to `target`, starting from `initial_T_target_source`.
  // Throws Error (with the plugin's status code and message) on failure; a
  // registration that ran but did not converge is not a failure (check
  // result.converged).
  RegistrationResult Align(const PointCloud& source, const PointCloud& target,
                           const Pose& initial_T_target_source, int threads = 1) const;
  RegistrationResult Align(const LfPointCloudView& source, const LfPointCloudView& target,
                           const Pose& initial_T_target_source, int threads = 1) const;

  const std::string& name() const { return name_; }
  // Whether the component's stage declares the parameter `name` (its
  // metadata; false for a component wrapped from a table).
  bool Declares(const std::string& param) const;

 private:
  void Release() noexcept;
  std::vector<std::string> parameters_;  // declared by the stage (Create)
  const LfRegistrationInterface* table_ = nullptr;
  void* instance_ = nullptr;
  std::string name_;
  std::function<void()> release_;
};

// Plugin-side base of a registration back-end: derive, give a static Meta(),
// and implement Align. Provides kInterface and the static function table; the
// adapter turns exceptions into LfError statuses.
template <typename Derived, typename OptionsT>
class RegistrationComponent : public Component<OptionsT> {
 public:
  static constexpr const char* kInterface = LF_REGISTRATION_INTERFACE;
  explicit RegistrationComponent(OptionsT options) : Component<OptionsT>(std::move(options)) {}

  virtual RegistrationResult Align(const PointCloud& source, const PointCloud& target,
                                   const Pose& initial_T_target_source, int threads) const = 0;

  const void* Table() {
    static const LfRegistrationInterface table = {sizeof(LfRegistrationInterface), &AlignC};
    return &table;
  }

 private:
  static int32_t AlignC(void* instance, const LfPointCloudView* source,
                        const LfPointCloudView* target, const double initial[16], int32_t threads,
                        LfRegistrationResult* result, LfError* err) {
    return internal::Guard(err, [&] {
      if (!instance || !source || !target || !initial || !result)
        throw Error("registration align: NULL argument");
      const auto* self = static_cast<const Derived*>(static_cast<Derived*>(instance));
      const Eigen::Matrix4d m =
          Eigen::Map<const Eigen::Matrix<double, 4, 4, Eigen::RowMajor>>(initial);
      const RegistrationResult r = self->Align(CopyFromView(*source), CopyFromView(*target),
                                               Pose::FromMatrix(m), threads > 0 ? threads : 1);
      *result = ToC(r);
    });
  }
};

}  // namespace locforge

#endif  // LOCFORGE_REGISTRATION_H_
