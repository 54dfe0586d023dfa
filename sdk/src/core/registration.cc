// Conversions between the C registration structs of abi.h and their C++
// forms, and the caller-side RegistrationBackend.
#include "locforge/registration.h"

#include <algorithm>
#include <cstring>

namespace locforge {

namespace {
using RowMajor4d = Eigen::Matrix<double, 4, 4, Eigen::RowMajor>;
using RowMajor6d = Eigen::Matrix<double, 6, 6, Eigen::RowMajor>;

// Reads element i of a strided float3/double array.
template <typename T>
const T* At(const T* base, uint32_t stride, uint64_t i, uint32_t min_stride) {
  const uint32_t s = stride ? stride : min_stride;
  return reinterpret_cast<const T*>(reinterpret_cast<const char*>(base) + i * s);
}
}  // namespace

void PointCloud::CheckConsistent() const {
  if (!normals.empty() && normals.size() != points.size())
    throw Error("point cloud: " + std::to_string(normals.size()) + " normals for " +
                std::to_string(points.size()) + " points");
  if (!times.empty() && times.size() != points.size())
    throw Error("point cloud: " + std::to_string(times.size()) + " times for " +
                std::to_string(points.size()) + " points");
}

LfPointCloudView MakeView(const PointCloud& cloud) {
  cloud.CheckConsistent();
  static_assert(sizeof(Eigen::Vector3f) == 3 * sizeof(float), "Vector3f must be packed");
  LfPointCloudView v{};
  v.struct_size = sizeof(LfPointCloudView);
  v.num_points = cloud.points.size();
  v.xyz = cloud.points.empty() ? nullptr : cloud.points.front().data();
  v.xyz_stride = sizeof(Eigen::Vector3f);
  v.normals = cloud.normals.empty() ? nullptr : cloud.normals.front().data();
  v.normals_stride = sizeof(Eigen::Vector3f);
  v.times = cloud.times.empty() ? nullptr : cloud.times.data();
  v.times_stride = sizeof(double);
  return v;
}

PointCloud CopyFromView(const LfPointCloudView& view) {
  if (view.struct_size < sizeof(LfPointCloudView))
    throw InputError("point cloud view: struct_size " + std::to_string(view.struct_size) +
                     " is too small");
  const uint64_t n = view.num_points;
  PointCloud out;
  if (n == 0) return out;
  if (view.xyz == nullptr) throw InputError("point cloud view: xyz is NULL with points");
  if (view.xyz_stride != 0 && view.xyz_stride < 12)
    throw InputError("point cloud view: xyz_stride below 12 bytes");
  if (view.normals && view.normals_stride != 0 && view.normals_stride < 12)
    throw InputError("point cloud view: normals_stride below 12 bytes");
  if (view.times && view.times_stride != 0 && view.times_stride < 8)
    throw InputError("point cloud view: times_stride below 8 bytes");
  out.points.resize(n);
  for (uint64_t i = 0; i < n; ++i) std::memcpy(out.points[i].data(), At(view.xyz, view.xyz_stride, i, 12), 12);
  if (view.normals) {
    out.normals.resize(n);
    for (uint64_t i = 0; i < n; ++i)
      std::memcpy(out.normals[i].data(), At(view.normals, view.normals_stride, i, 12), 12);
  }
  if (view.times) {
    out.times.resize(n);
    for (uint64_t i = 0; i < n; ++i)
      std::memcpy(&out.times[i], At(view.times, view.times_stride, i, 8), 8);
  }
  return out;
}

RegistrationResult FromC(const LfRegistrationResult& c) {
  RegistrationResult r;
  r.converged = c.converged != 0;
  r.iterations = c.iterations;
  r.num_inliers = c.num_inliers;
  r.inlier_fraction = c.inlier_fraction;
  r.final_error = c.final_error;
  r.T_target_source = Pose::FromMatrix(Eigen::Map<const RowMajor4d>(c.T_target_source));
  r.information = Eigen::Map<const RowMajor6d>(c.information);
  return r;
}

LfRegistrationResult ToC(const RegistrationResult& r) {
  LfRegistrationResult c{};
  c.struct_size = sizeof(LfRegistrationResult);
  c.converged = r.converged ? 1 : 0;
  c.iterations = r.iterations;
  c.num_inliers = r.num_inliers;
  c.inlier_fraction = r.inlier_fraction;
  c.final_error = r.final_error;
  Eigen::Map<RowMajor4d>(c.T_target_source) = r.T_target_source.Matrix();
  Eigen::Map<RowMajor6d>(c.information) = r.information;
  return c;
}

RegistrationBackend RegistrationBackend::Create(
    const RunContext& ctx, const std::string& stage_id,
    const std::vector<std::pair<std::string, std::string>>& params) {
  const LfRunContext* c = ctx.raw();
  if (c == nullptr || c->create_component == nullptr || c->destroy_component == nullptr)
    throw Error("cannot create " + stage_id + ": the host provides no components");
  std::vector<LfParam> raw;
  raw.reserve(params.size());
  for (const auto& [k, v] : params) raw.push_back({k.c_str(), v.c_str()});
  LfError err{};
  err.struct_size = sizeof(err);
  const LfStageInfo* info = nullptr;
  void* instance = c->create_component(c->host, stage_id.c_str(), raw.data(),
                                       static_cast<uint32_t>(raw.size()), &info, &err);
  if (instance == nullptr) throw Error("cannot create " + stage_id + ": " + err.message);
  auto release = [c, info, instance] { c->destroy_component(c->host, info, instance); };
  if (info == nullptr || info->component_interface == nullptr || info->component == nullptr ||
      std::string(info->component_interface) != LF_REGISTRATION_INTERFACE) {
    release();
    throw Error(stage_id + " is not a " LF_REGISTRATION_INTERFACE " component");
  }
  const auto* table = static_cast<const LfRegistrationInterface*>(info->component(instance));
  if (table == nullptr || table->struct_size < sizeof(LfRegistrationInterface) ||
      table->align == nullptr) {
    release();
    throw Error(stage_id + ": malformed registration interface table");
  }
  RegistrationBackend backend(table, instance, stage_id, release);
  for (uint32_t i = 0; info->params != nullptr && i < info->num_params; ++i)
    if (info->params[i].name != nullptr) backend.parameters_.emplace_back(info->params[i].name);
  return backend;
}

bool RegistrationBackend::Declares(const std::string& param) const {
  return std::find(parameters_.begin(), parameters_.end(), param) != parameters_.end();
}

RegistrationBackend::RegistrationBackend(const LfRegistrationInterface* table, void* instance,
                                         std::string name, std::function<void()> release)
    : table_(table), instance_(instance), name_(std::move(name)), release_(std::move(release)) {
  if (table_ == nullptr || table_->align == nullptr)
    throw Error(name_ + ": no registration interface table");
}

RegistrationBackend::RegistrationBackend(RegistrationBackend&& o) noexcept
    : parameters_(std::move(o.parameters_)), table_(o.table_), instance_(o.instance_), name_(std::move(o.name_)),
      release_(std::move(o.release_)) {
  o.table_ = nullptr;
  o.instance_ = nullptr;
  o.release_ = nullptr;
}

RegistrationBackend& RegistrationBackend::operator=(RegistrationBackend&& o) noexcept {
  if (this != &o) {
    Release();
    parameters_ = std::move(o.parameters_);
    table_ = o.table_;
    instance_ = o.instance_;
    name_ = std::move(o.name_);
    release_ = std::move(o.release_);
    o.table_ = nullptr;
    o.instance_ = nullptr;
    o.release_ = nullptr;
  }
  return *this;
}

RegistrationBackend::~RegistrationBackend() { Release(); }

void RegistrationBackend::Release() noexcept {
  if (release_) {
    try {
      release_();
    } catch (...) {
    }
  }
  release_ = nullptr;
  instance_ = nullptr;
  table_ = nullptr;
}

RegistrationResult RegistrationBackend::Align(const PointCloud& source, const PointCloud& target,
                                              const Pose& initial, int threads) const {
  return Align(MakeView(source), MakeView(target), initial, threads);
}

RegistrationResult RegistrationBackend::Align(const LfPointCloudView& source,
                                              const LfPointCloudView& target, const Pose& initial,
                                              int threads) const {
  if (table_ == nullptr) throw Error("registration backend used after move");
  double init[16];
  Eigen::Map<RowMajor4d> init_map(init);
  init_map = initial.Matrix();
  LfRegistrationResult c{};
  c.struct_size = sizeof(c);
  LfError err{};
  err.struct_size = sizeof(err);
  const int32_t rc = table_->align(instance_, &source, &target, init, threads, &c, &err);
  if (rc != LF_OK) throw Error(name_ + ": " + err.message, rc);
  return FromC(c);
}

}  // namespace locforge
