#include "pose_graph.h"

#include <ceres/ceres.h>

#include <Eigen/Eigenvalues>
#include <cmath>
#include <sstream>

#include "locforge/error.h"

namespace locforge::lidar {

bool PoseGraphOptions::Check(std::string* why) const {
  if (max_iterations >= 1 && threads >= 1) return true;
  if (why) *why = "max_iterations and threads must be >= 1";
  return false;
}

Matrix6d SwapRotationTranslation(const Matrix6d& m) {
  Matrix6d out;
  out.topLeftCorner<3, 3>() = m.bottomRightCorner<3, 3>();
  out.bottomRightCorner<3, 3>() = m.topLeftCorner<3, 3>();
  out.topRightCorner<3, 3>() = m.bottomLeftCorner<3, 3>();
  out.bottomLeftCorner<3, 3>() = m.topRightCorner<3, 3>();
  return out;
}

Matrix6d RegistrationInformationToEdge(const Matrix6d& H, const Pose& T_ab) {
  const Eigen::Matrix3d R = T_ab.R();
  Eigen::Matrix3d tx;
  tx << 0, -T_ab.t.z(), T_ab.t.y(), T_ab.t.z(), 0, -T_ab.t.x(), -T_ab.t.y(), T_ab.t.x(), 0;
  Matrix6d M = Matrix6d::Zero();  // rows (w, v), columns (r_t, r_r)
  M.topRightCorner<3, 3>() = R;
  M.bottomLeftCorner<3, 3>() = Eigen::Matrix3d::Identity();
  M.bottomRightCorner<3, 3>() = tx * R;
  const Matrix6d omega = M.transpose() * H * M;
  return 0.5 * (omega + omega.transpose());
}

bool NormalizeInformation(const Matrix6d& omega, double sigma_t, double sigma_r, double max_ratio,
                          Matrix6d* out) {
  if (!omega.allFinite()) return false;
  const double lt = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(omega.topLeftCorner<3, 3>()).eigenvalues()(2);
  const double lr = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(omega.bottomRightCorner<3, 3>()).eigenvalues()(2);
  if (!(lt > 0) || !(lr > 0)) return false;
  Vector6d d;
  d << Eigen::Vector3d::Constant(1 / (sigma_t * std::sqrt(lt))), Eigen::Vector3d::Constant(1 / (sigma_r * std::sqrt(lr)));
  Matrix6d scaled = d.asDiagonal() * omega * d.asDiagonal();
  Vector6d floor;
  floor << Eigen::Vector3d::Constant(1 / std::pow(max_ratio * sigma_t, 2)),
      Eigen::Vector3d::Constant(1 / std::pow(max_ratio * sigma_r, 2));
  scaled += floor.asDiagonal().toDenseMatrix();
  *out = scaled;
  return true;
}

namespace {

// Relative-pose residual (header); parameters: t_a, q_a, t_b, q_b with
// quaternions in Eigen's (x, y, z, w) storage.
struct RelativePoseError {
  RelativePoseError(const Pose& measured, const Matrix6d& sqrt_information)
      : t_ab(measured.t), q_ab(measured.q), sqrt_info(sqrt_information) {}

  template <typename T>
  bool operator()(const T* t_a_ptr, const T* q_a_ptr, const T* t_b_ptr, const T* q_b_ptr,
                  T* residual_ptr) const {
    Eigen::Map<const Eigen::Matrix<T, 3, 1>> t_a(t_a_ptr), t_b(t_b_ptr);
    Eigen::Map<const Eigen::Quaternion<T>> q_a(q_a_ptr), q_b(q_b_ptr);
    const Eigen::Quaternion<T> q_a_inv = q_a.conjugate();
    const Eigen::Quaternion<T> q_ab_est = q_a_inv * q_b;
    const Eigen::Matrix<T, 3, 1> t_ab_est = q_a_inv * (t_b - t_a);
    const Eigen::Quaternion<T> dq = q_ab.template cast<T>().conjugate() * q_ab_est;
    Eigen::Map<Eigen::Matrix<T, 6, 1>> r(residual_ptr);
    r.template head<3>() = t_ab_est - t_ab.template cast<T>();
    r.template tail<3>() = T(2.0) * dq.vec();
    r.applyOnTheLeft(sqrt_info.template cast<T>());
    return true;
  }

  static ceres::CostFunction* Create(const PoseGraphEdge& e) {
    const Eigen::LLT<Matrix6d> llt(e.information);
    if (llt.info() != Eigen::Success)
      throw Error("pose graph edge " + std::to_string(e.from) + "-" + std::to_string(e.to) +
                  ": information matrix is not positive definite");
    const Matrix6d sqrt_info = llt.matrixL().transpose();
    return new ceres::AutoDiffCostFunction<RelativePoseError, 6, 3, 4, 3, 4>(
        new RelativePoseError(e.T_from_to, sqrt_info));
  }

  Eigen::Vector3d t_ab;
  Eigen::Quaterniond q_ab;
  Matrix6d sqrt_info;
};

// Planar prior: r = [t_z / sigma_z; (R e_z)_x / sigma_tilt; (R e_z)_y / sigma_tilt].
struct PlanarPrior {
  double sigma_z, sigma_tilt;
  template <typename T>
  bool operator()(const T* t, const T* q_ptr, T* r) const {
    Eigen::Map<const Eigen::Quaternion<T>> q(q_ptr);
    const Eigen::Matrix<T, 3, 1> up = q * Eigen::Matrix<T, 3, 1>(T(0), T(0), T(1));
    r[0] = t[2] / sigma_z;
    r[1] = up.x() / sigma_tilt;
    r[2] = up.y() / sigma_tilt;
    return true;
  }
};

ceres::LossFunction* MakeLoss(const PoseGraphEdge& e, double factor) {
  // Ceres losses take the squared norm; scale given on the norm.
  const double s = e.loss_scale * factor;
  switch (e.loss) {
    case RobustLoss::kHuber: return new ceres::HuberLoss(s);
    case RobustLoss::kCauchy: return new ceres::CauchyLoss(s);
    case RobustLoss::kNone: break;
  }
  return nullptr;
}

struct Parameters {
  std::map<int, Eigen::Vector3d> t;
  std::map<int, Eigen::Quaterniond> q;
};

// Builds the problem over `p` (which must outlive it).
void BuildProblem(const PoseGraph& graph, Parameters* p, ceres::Problem* problem, double loss_factor = 1) {
  for (const auto& [id, pose] : graph.nodes) {
    p->t[id] = pose.t;
    p->q[id] = pose.q;
  }
  for (const auto& e : graph.edges) {
    if (!graph.nodes.count(e.from) || !graph.nodes.count(e.to))
      throw Error("pose graph edge " + std::to_string(e.from) + "-" + std::to_string(e.to) +
                  " names a missing node");
    problem->AddResidualBlock(RelativePoseError::Create(e), MakeLoss(e, loss_factor), p->t[e.from].data(),
                              p->q[e.from].coeffs().data(), p->t[e.to].data(),
                              p->q[e.to].coeffs().data());
  }
  if (graph.planar_sigma_z > 0 && graph.planar_sigma_tilt > 0)
    for (auto& [id, t] : p->t)
      problem->AddResidualBlock(new ceres::AutoDiffCostFunction<PlanarPrior, 3, 3, 4>(
                                    new PlanarPrior{graph.planar_sigma_z, graph.planar_sigma_tilt}),
                                nullptr, t.data(), p->q[id].coeffs().data());
  for (auto& [id, q] : p->q)
    if (problem->HasParameterBlock(q.coeffs().data()))
      problem->SetManifold(q.coeffs().data(), new ceres::EigenQuaternionManifold);
  std::vector<int> fixed = graph.fixed;
  if (fixed.empty() && !graph.nodes.empty()) fixed.push_back(graph.nodes.begin()->first);
  for (int id : fixed) {
    if (!p->t.count(id) || !problem->HasParameterBlock(p->t[id].data())) continue;
    problem->SetParameterBlockConstant(p->t[id].data());
    problem->SetParameterBlockConstant(p->q[id].coeffs().data());
  }
}

}  // namespace

double PoseGraphCost(const PoseGraph& graph) {
  Parameters p;
  ceres::Problem problem;
  BuildProblem(graph, &p, &problem);
  double cost = 0;
  problem.Evaluate(ceres::Problem::EvaluateOptions(), &cost, nullptr, nullptr, nullptr);
  return cost;
}

PoseGraphSummary OptimizeOnce(const PoseGraphOptions& options, double loss_factor, PoseGraph* graph);

PoseGraphSummary Optimize(const PoseGraphOptions& options, PoseGraph* graph) {
  PoseGraphSummary out;
  out.initial_cost = PoseGraphCost(*graph);
  std::vector<double> factors = options.loss_continuation;
  if (factors.empty() || factors.back() != 1.0) factors.push_back(1.0);
  for (double factor : factors) {
    const PoseGraphSummary step = OptimizeOnce(options, factor, graph);
    out.iterations += step.iterations;
    out.converged = step.converged;
    out.report = step.report;
  }
  out.final_cost = PoseGraphCost(*graph);
  return out;
}

PoseGraphSummary OptimizeOnce(const PoseGraphOptions& options, double loss_factor, PoseGraph* graph) {
  Parameters p;
  ceres::Problem problem;
  BuildProblem(*graph, &p, &problem, loss_factor);
  ceres::Solver::Options solver;
  solver.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  solver.max_num_iterations = options.max_iterations;
  solver.num_threads = options.threads;
  solver.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(solver, &problem, &summary);
  for (auto& [id, pose] : graph->nodes) pose = Pose(p.q[id], p.t[id]);
  PoseGraphSummary out;
  out.initial_cost = summary.initial_cost;
  out.final_cost = summary.final_cost;
  out.iterations = static_cast<int>(summary.iterations.size());
  out.converged = summary.termination_type == ceres::CONVERGENCE;
  out.report = summary.BriefReport();
  return out;
}

// ------------------------------------------------------------------- g2o

PoseGraph ReadG2o(const fs::path& path) {
  std::istringstream in(ReadFile(path));
  PoseGraph graph;
  std::string line, tag;
  int64_t number = 0;
  const std::string file = path.string();
  while (std::getline(in, line)) {
    ++number;
    std::istringstream s(line);
    if (!(s >> tag) || tag[0] == '#') continue;
    auto fail = [&](const std::string& what) { throw InputError(file, number, tag, what); };
    double x, y, z, qx, qy, qz, qw;
    if (tag == "VERTEX_SE3:QUAT") {
      int id;
      if (!(s >> id >> x >> y >> z >> qx >> qy >> qz >> qw)) fail("expected id x y z qx qy qz qw");
      if (!graph.nodes.emplace(id, Pose(Eigen::Quaterniond(qw, qx, qy, qz), {x, y, z})).second)
        fail("duplicate vertex " + std::to_string(id));
    } else if (tag == "EDGE_SE3:QUAT") {
      PoseGraphEdge e;
      if (!(s >> e.from >> e.to >> x >> y >> z >> qx >> qy >> qz >> qw))
        fail("expected a b x y z qx qy qz qw");
      e.T_from_to = Pose(Eigen::Quaterniond(qw, qx, qy, qz), {x, y, z});
      for (int r = 0; r < 6; ++r)
        for (int c = r; c < 6; ++c) {
          if (!(s >> e.information(r, c))) fail("expected 21 information values");
          e.information(c, r) = e.information(r, c);
        }
      graph.edges.push_back(e);
    } else if (tag == "FIX") {
      int id;
      while (s >> id) graph.fixed.push_back(id);
    } else {
      fail("unsupported tag (only VERTEX_SE3:QUAT, EDGE_SE3:QUAT, FIX)");
    }
  }
  for (const auto& e : graph.edges)
    if (!graph.nodes.count(e.from) || !graph.nodes.count(e.to))
      throw InputError(file, 0, "EDGE_SE3:QUAT",
                       "edge " + std::to_string(e.from) + "-" + std::to_string(e.to) +
                           " names a missing vertex");
  return graph;
}

void WriteG2o(const fs::path& path, const PoseGraph& graph) {
  std::ostringstream o;
  o.precision(17);
  auto pose_fields = [&](const Pose& p) {
    o << p.t.x() << ' ' << p.t.y() << ' ' << p.t.z() << ' ' << p.q.x() << ' ' << p.q.y() << ' '
      << p.q.z() << ' ' << p.q.w();
  };
  for (const auto& [id, pose] : graph.nodes) {
    o << "VERTEX_SE3:QUAT " << id << ' ';
    pose_fields(pose);
    o << '\n';
  }
  for (const auto& e : graph.edges) {
    o << "EDGE_SE3:QUAT " << e.from << ' ' << e.to << ' ';
    pose_fields(e.T_from_to);
    for (int r = 0; r < 6; ++r)
      for (int c = r; c < 6; ++c) o << ' ' << e.information(r, c);
    o << '\n';
  }
  for (int id : graph.fixed) o << "FIX " << id << '\n';
  WriteFileAtomic(path, o.str());
}

}  // namespace locforge::lidar
