#include "slam_part.h"

#include <cstring>
#include <fstream>
#include <type_traits>

#include "locforge/error.h"
#include "scan_context.h"

namespace locforge::lidar {

namespace {

constexpr char kMagic[] = "LFSLAMPART";
constexpr uint32_t kVersion = 1;
// Bounds a corrupt count is refused by before anything is allocated for it.
constexpr uint64_t kMaxPoints = uint64_t{1} << 32, kMaxCount = uint64_t{1} << 28;

class Writer {
 public:
  template <typename T>
  void Put(T v) {
    static_assert(std::is_arithmetic_v<T>);
    out_.append(reinterpret_cast<const char*>(&v), sizeof v);
  }
  void Str(const std::string& s) {
    Put<uint32_t>(static_cast<uint32_t>(s.size()));
    out_ += s;
  }
  void PoseOf(const Pose& p) {
    for (double v : {p.q.w(), p.q.x(), p.q.y(), p.q.z(), p.t.x(), p.t.y(), p.t.z()}) Put(v);
  }
  void CloudOf(const Cloud& c) {
    Put<uint64_t>(c.points.size());
    for (const auto& p : c.points)
      for (int k = 0; k < 3; ++k) Put(p[k]);
    Put<uint8_t>(c.has_normals());
    for (const auto& n : c.normals)
      for (int k = 0; k < 3; ++k) Put(n[k]);
  }
  std::string& bytes() { return out_; }

 private:
  std::string out_;
};

class Reader {
 public:
  Reader(const std::string& bytes, const std::string& name) : b_(bytes), name_(name) {}
  template <typename T>
  T Get(const char* field) {
    T v;
    Need(sizeof v, field);
    std::memcpy(&v, b_.data() + at_, sizeof v);
    at_ += sizeof v;
    return v;
  }
  uint64_t Count(const char* field, uint64_t max = kMaxCount) {
    const uint64_t n = Get<uint32_t>(field);
    if (n > max) Fail(field, "count " + std::to_string(n) + " out of range");
    return n;
  }
  std::string Str(const char* field) {
    const uint64_t n = Count(field);
    Need(n, field);
    std::string s = b_.substr(at_, n);
    at_ += n;
    return s;
  }
  Pose PoseOf(const char* field) {
    Pose p;
    double v[7];
    for (double& x : v) x = Get<double>(field);
    p.q = Eigen::Quaterniond(v[0], v[1], v[2], v[3]);  // as written: no renormalisation
    p.t = Eigen::Vector3d(v[4], v[5], v[6]);
    return p;
  }
  Cloud CloudOf(const char* field) {
    Cloud c;
    const uint64_t n = Get<uint64_t>(field);
    if (n > kMaxPoints) Fail(field, "point count out of range");
    Need(n * 3 * sizeof(float), field);
    c.points.resize(n);
    for (auto& p : c.points)
      for (int k = 0; k < 3; ++k) p[k] = Get<float>(field);
    if (Get<uint8_t>(field)) {
      Need(n * 3 * sizeof(float), field);
      c.normals.resize(n);
      for (auto& q : c.normals)
        for (int k = 0; k < 3; ++k) q[k] = Get<float>(field);
    }
    return c;
  }
  void Expect(const std::string& bytes, const char* field, const std::string& what) {
    Need(bytes.size(), field);
    if (b_.compare(at_, bytes.size(), bytes) != 0) Fail(field, what);
    at_ += bytes.size();
  }
  bool AtEnd() const { return at_ == b_.size(); }
  size_t at() const { return at_; }
  [[noreturn]] void Fail(const char* field, const std::string& what) const {
    throw InputError(name_, 0, field, what + " (byte " + std::to_string(at_) + ")");
  }

 private:
  void Need(uint64_t n, const char* field) const {
    if (n > b_.size() - at_) Fail(field, "truncated: the file ends inside it");
  }
  const std::string& b_;
  const std::string name_;
  size_t at_ = 0;
};

}  // namespace

std::string EncodeSlamPart(const SlamPart& part) {
  Writer w;
  w.bytes() += kMagic;
  w.Put<uint32_t>(kVersion);
  w.Str(part.sequence);
  w.Put<uint8_t>(part.manual);
  w.Put<uint32_t>(static_cast<uint32_t>(part.params.size()));
  for (const auto& [k, v] : part.params) {
    w.Str(k);
    w.Str(v);
  }
  w.Put<uint32_t>(static_cast<uint32_t>(part.keyframes.size()));
  for (const Keyframe& kf : part.keyframes) {
    w.Put<int64_t>(kf.timestamp);
    w.Put<double>(kf.travelled);
    w.CloudOf(kf.cloud);
    w.CloudOf(kf.rough);
  }
  for (const PoseGraph* g : {&part.graph, &part.before})
    for (const Keyframe& kf : part.keyframes) w.PoseOf(g->nodes.at(kf.id));
  w.Put<uint32_t>(static_cast<uint32_t>(part.graph.edges.size()));
  for (const PoseGraphEdge& e : part.graph.edges) {
    w.Put<int32_t>(e.from);
    w.Put<int32_t>(e.to);
    w.PoseOf(e.T_from_to);
    for (int i = 0; i < 36; ++i) w.Put<double>(e.information.data()[i]);
    w.Put<uint8_t>(static_cast<uint8_t>(e.loss));
    w.Put<double>(e.loss_scale);
    w.Put<uint8_t>(e.loop);
  }
  w.Put<uint32_t>(static_cast<uint32_t>(part.loops.size()));
  for (const auto& [a, b] : part.loops) {
    w.Put<int32_t>(a);
    w.Put<int32_t>(b);
  }
  const SlamStats& st = part.stats;
  for (int v : {st.sequential_fallbacks, st.information_fallbacks, st.refinements, st.refinements_rejected,
                st.sequential_reregistered})
    w.Put<int32_t>(v);
  w.Put<int64_t>(st.loop_tests);
  w.Put<uint32_t>(static_cast<uint32_t>(st.odometry_yaw_scale.size()));
  for (const auto& [sequence, k] : st.odometry_yaw_scale) {
    w.Str(sequence);
    w.Put<double>(k);
  }
  w.Put<double>(st.summary.initial_cost);
  w.Put<double>(st.summary.final_cost);
  w.Put<int32_t>(st.summary.iterations);
  w.Put<uint32_t>(static_cast<uint32_t>(st.steps.size()));
  for (const auto& [step, seconds] : st.steps) {
    w.Str(step);
    w.Put<double>(seconds);
  }
  return std::move(w.bytes());
}

SlamPart DecodeSlamPart(const std::string& bytes, const std::string& name, bool keep_clouds) {
  Reader r(bytes, name);
  r.Expect(kMagic, "magic", "not a slam/sequences part file");
  const uint32_t version = r.Get<uint32_t>("version");
  if (version != kVersion)
    r.Fail("version", "part version " + std::to_string(version) + ", this build reads " + std::to_string(kVersion) +
                          ": run slam/sequences again");
  SlamPart part;
  part.sequence = r.Str("sequence");
  part.manual = r.Get<uint8_t>("manual") != 0;
  for (uint64_t n = r.Count("params"), i = 0; i < n; ++i) {
    std::string k = r.Str("params");
    part.params.emplace_back(std::move(k), r.Str("params"));
  }
  const uint64_t keyframes = r.Count("keyframes");
  if (keyframes == 0) r.Fail("keyframes", "a part without keyframes");
  for (uint64_t i = 0; i < keyframes; ++i) {
    Keyframe kf;
    kf.id = static_cast<int>(i);
    kf.sequence = part.sequence;
    kf.timestamp = r.Get<int64_t>("keyframes.timestamp");
    kf.travelled = r.Get<double>("keyframes.travelled");
    const size_t offset = r.at();
    Cloud cloud = r.CloudOf("keyframes.cloud");
    kf.context = MakeScanContext(cloud, ScanContextOptions{});
    if (keep_clouds) {
      kf.cloud = std::move(cloud);
    } else {
      kf.cloud_file = name;
      kf.cloud_offset = offset;
    }
    kf.rough = r.CloudOf("keyframes.rough");
    part.keyframes.push_back(std::move(kf));
  }
  for (PoseGraph* g : {&part.graph, &part.before})
    for (uint64_t i = 0; i < keyframes; ++i)
      g->nodes[static_cast<int>(i)] = r.PoseOf(g == &part.graph ? "nodes" : "before");
  const auto id = [&](const char* field) {
    const int32_t v = r.Get<int32_t>(field);
    if (v < 0 || static_cast<uint64_t>(v) >= keyframes) r.Fail(field, "keyframe id " + std::to_string(v) + " out of range");
    return static_cast<int>(v);
  };
  for (uint64_t n = r.Count("edges"), i = 0; i < n; ++i) {
    PoseGraphEdge e;
    e.from = id("edges.from");
    e.to = id("edges.to");
    e.T_from_to = r.PoseOf("edges.T_from_to");
    for (int k = 0; k < 36; ++k) e.information.data()[k] = r.Get<double>("edges.information");
    const uint8_t loss = r.Get<uint8_t>("edges.loss");
    if (loss > static_cast<uint8_t>(RobustLoss::kCauchy)) r.Fail("edges.loss", "unknown loss " + std::to_string(loss));
    e.loss = static_cast<RobustLoss>(loss);
    e.loss_scale = r.Get<double>("edges.loss_scale");
    e.loop = r.Get<uint8_t>("edges.loop") != 0;
    part.graph.edges.push_back(e);
  }
  for (uint64_t n = r.Count("loops"), i = 0; i < n; ++i) {
    const int a = id("loops");
    part.loops.emplace_back(a, id("loops"));
  }
  SlamStats& st = part.stats;
  for (int* v : {&st.sequential_fallbacks, &st.information_fallbacks, &st.refinements, &st.refinements_rejected,
                 &st.sequential_reregistered})
    *v = r.Get<int32_t>("stats");
  st.loop_tests = r.Get<int64_t>("stats.loop_tests");
  for (uint64_t n = r.Count("stats.odometry_yaw_scale"), i = 0; i < n; ++i) {
    std::string sequence = r.Str("stats.odometry_yaw_scale");
    st.odometry_yaw_scale[sequence] = r.Get<double>("stats.odometry_yaw_scale");
  }
  st.summary.initial_cost = r.Get<double>("stats.initial_cost");
  st.summary.final_cost = r.Get<double>("stats.final_cost");
  st.summary.iterations = r.Get<int32_t>("stats.iterations");
  for (uint64_t n = r.Count("stats.steps"), i = 0; i < n; ++i) {
    std::string step = r.Str("stats.steps");
    st.steps.emplace_back(std::move(step), r.Get<double>("stats.steps"));
  }
  if (!r.AtEnd()) r.Fail("end", "bytes after the part");
  return part;
}

void WriteSlamPart(const fs::path& path, const SlamPart& part) { WriteFileAtomic(path, EncodeSlamPart(part)); }

SlamPart ReadSlamPart(const fs::path& path, bool keep_clouds) {
  return DecodeSlamPart(ReadFile(path), path.string(), keep_clouds);
}

Cloud ReadPartCloud(const fs::path& path, uint64_t offset) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path.string(), 0, "keyframes.cloud", "cannot open the part file");
  in.seekg(static_cast<std::streamoff>(offset));
  uint64_t n = 0;
  in.read(reinterpret_cast<char*>(&n), sizeof n);
  if (!in || n > kMaxPoints) throw InputError(path.string(), 0, "keyframes.cloud", "no cloud at byte " + std::to_string(offset));
  std::string bytes(sizeof n + n * 3 * sizeof(float) + 1, '\0');
  std::memcpy(bytes.data(), &n, sizeof n);
  in.read(bytes.data() + sizeof n, static_cast<std::streamsize>(bytes.size() - sizeof n));
  if (in && bytes.back()) {  // normals follow
    bytes.resize(bytes.size() + n * 3 * sizeof(float));
    in.read(bytes.data() + bytes.size() - n * 3 * sizeof(float), static_cast<std::streamsize>(n * 3 * sizeof(float)));
  }
  if (!in) throw InputError(path.string(), 0, "keyframes.cloud", "truncated: the file ends inside the cloud at byte " +
                                                                     std::to_string(offset));
  Reader r(bytes, path.string());
  return r.CloudOf("keyframes.cloud");
}

std::string PartFileName(const std::string& sequence) { return (sequence.empty() ? "_" : sequence) + ".part"; }

}  // namespace locforge::lidar
