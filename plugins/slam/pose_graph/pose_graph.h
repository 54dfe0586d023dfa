// An SE(3) pose graph (nodes T_world_node, relative-pose edges) and its
// optimisation with Ceres on the SE(3) manifold (quaternion manifold +
// Euclidean translation), the solver the SLAM stage uses. Ceres stays in
// pose_graph.cc.
//
// Edge residual (as g2o's EDGE_SE3:QUAT and Ceres' pose_graph_3d):
//   T_ab_est = T_wa^-1 T_wb,  r = [t_ab_est - t_ab ; 2 vec(q_ab^-1 q_ab_est)],
//   cost = 1/2 rho(r^T Omega r), Omega in (translation, rotation) order.
#ifndef LOCFORGE_PLUGINS_SLAM_POSE_GRAPH_POSE_GRAPH_H_
#define LOCFORGE_PLUGINS_SLAM_POSE_GRAPH_POSE_GRAPH_H_

#include <map>
#include <string>
#include <vector>

#include "locforge/fs.h"
#include "locforge/pose.h"

namespace locforge::lidar {

enum class RobustLoss { kNone, kHuber, kCauchy };

struct PoseGraphEdge {
  int from = 0, to = 0;
  Pose T_from_to;                                    // measured T_a_b
  Matrix6d information = Matrix6d::Identity();       // (tx, ty, tz, rx, ry, rz) order, as g2o
  RobustLoss loss = RobustLoss::kNone;
  double loss_scale = 1.0;                           // in units of sqrt(r^T Omega r)
  bool loop = false;                                 // a loop closure (for plots and counts)
};

struct PoseGraph {
  std::map<int, Pose> nodes;  // id -> T_world_node
  std::vector<PoseGraphEdge> edges;
  std::vector<int> fixed;     // ids held constant (at least one, else the first node)
  // Planar prior (a wheeled platform on a level floor): every node's height
  // and tilt (its z axis against the world's) held near those of the world
  // frame with these stds (m, rad); 0 disables it.
  double planar_sigma_z = 0, planar_sigma_tilt = 0;
};

// The information matrix of abi.h's registration results is in (r, t) order;
// this swaps it to the graph's (t, r) order (and back: the swap is its own inverse).
Matrix6d SwapRotationTranslation(const Matrix6d& information);

// A registration's information H (abi.h: tangent (w, v), left perturbation
// T_ab <- Exp(xi) T_ab) in the coordinates of this graph's edge residual r
// (header: r = [dt ; 2 vec(dq)] with dt in frame a, dq on the right). To first
// order xi = M r with M = [[0, R_ab], [I, [t_ab]x R_ab]], so the same quadratic
// form is r^T (M^T H M) r; returned in (t, r) order.
Matrix6d RegistrationInformationToEdge(const Matrix6d& H, const Pose& T_ab);

// Rescales an edge information Omega (t, r order) to D Omega D with
// D = diag(a I3, b I3) so that its best-constrained translation direction has
// std `sigma_t` and its best rotation direction `sigma_r` (rad), keeping its
// shape (directions the scans leave free, e.g. along a corridor, stay weak),
// then adds the floor diag(1/(ratio sigma_t)^2, 1/(ratio sigma_r)^2) so no
// direction is weaker than `max_ratio` times those stds. Returns false (and
// leaves *out alone) when Omega is not usable (non-finite or no positive
// eigenvalue in a block).
bool NormalizeInformation(const Matrix6d& omega, double sigma_t, double sigma_r, double max_ratio,
                          Matrix6d* out);

struct PoseGraphOptions {
  int max_iterations = 100;
  int threads = 1;
  // Robust-loss continuation: solved once per factor, the robust edges' scale
  // multiplied by it (wide first, so a large initial drift does not switch
  // off correct loop edges; then the nominal scale rejects outliers).
  std::vector<double> loss_continuation = {100, 10, 1};
  bool Check(std::string* why) const;
};

struct PoseGraphSummary {
  double initial_cost = 0, final_cost = 0;
  int iterations = 0;
  bool converged = false;
  std::string report;  // Ceres' brief report
};

// Total cost of the graph at its current node poses (same cost as Optimize).
double PoseGraphCost(const PoseGraph& graph);
PoseGraphSummary Optimize(const PoseGraphOptions& options, PoseGraph* graph);

// g2o text format: VERTEX_SE3:QUAT id x y z qx qy qz qw and
// EDGE_SE3:QUAT a b x y z qx qy qz qw + the upper triangle of the 6x6
// information (21 values); FIX id. Unknown tags are refused (InputError
// naming file and line).
PoseGraph ReadG2o(const fs::path& path);
void WriteG2o(const fs::path& path, const PoseGraph& graph);  // atomic

}  // namespace locforge::lidar

#endif  // LOCFORGE_PLUGINS_SLAM_POSE_GRAPH_POSE_GRAPH_H_
