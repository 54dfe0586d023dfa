#include "scene_regression.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <opencv2/imgproc.hpp>

namespace locforge::regression {

bool PoseFromRegression(const float position[3], const float orientation[4], Pose* camera_from_world,
                        std::string* why) {
  const Eigen::Vector3d c(position[0], position[1], position[2]);
  const Eigen::Quaterniond q(orientation[0], orientation[1], orientation[2], orientation[3]);
  if (!c.allFinite() || !q.coeffs().allFinite()) return *why = "non-finite network output", false;
  if (q.norm() < 1e-6) return *why = "orientation quaternion ~ 0", false;
  const Pose world_from_camera(q.normalized(), c);
  *camera_from_world = world_from_camera.Inverse();
  return true;
}

std::vector<localization::Correspondence> SceneCoordinateCorrespondences(const cv::Mat& coordinates,
                                                                         const Camera& camera) {
  CV_Assert(coordinates.dims == 4 && coordinates.size[0] == 1 && coordinates.size[1] == 3);
  const int h = coordinates.size[2], w = coordinates.size[3];
  const float* x = coordinates.ptr<float>(0, 0);
  const float* y = coordinates.ptr<float>(0, 1);
  const float* z = coordinates.ptr<float>(0, 2);
  std::vector<localization::Correspondence> out;
  out.reserve(static_cast<size_t>(h) * w);
  for (int i = 0; i < h; ++i)
    for (int j = 0; j < w; ++j) {
      const int k = i * w + j;
      const Eigen::Vector3d world(x[k], y[k], z[k]);
      if (!world.allFinite()) continue;
      const Eigen::Vector2d pixel((j + 0.5) * camera.width / w, (i + 0.5) * camera.height / h);
      localization::Correspondence c;
      c.normalized = camera.Unproject(pixel).hnormalized();
      c.world = world;
      out.push_back(c);
    }
  return out;
}

std::vector<double> Softmax(const std::vector<float>& logits) {
  std::vector<double> p(logits.size());
  if (logits.empty()) return p;
  const double top = *std::max_element(logits.begin(), logits.end());
  double sum = 0;
  for (size_t i = 0; i < logits.size(); ++i) sum += p[i] = std::exp(double(logits[i]) - top);
  for (double& v : p) v /= sum;
  return p;
}

std::vector<int> HypothesisBudget(const std::vector<double>& probabilities, int hypotheses) {
  const size_t n = probabilities.size();
  std::vector<int> budget(n, 0);
  if (n == 0) return budget;
  const double total = std::accumulate(probabilities.begin(), probabilities.end(), 0.0);
  std::vector<double> remainder(n);
  int given = 0;
  for (size_t i = 0; i < n; ++i) {
    const double share = total > 0 ? hypotheses * probabilities[i] / total : double(hypotheses) / n;
    budget[i] = static_cast<int>(std::floor(share));
    remainder[i] = share - budget[i];
    given += budget[i];
  }
  std::vector<size_t> order(n);
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return remainder[a] > remainder[b]; });
  for (size_t k = 0; given < hypotheses; k = (k + 1) % n, ++given) ++budget[order[k]];
  return budget;
}

int BestExpert(const std::vector<ExpertResult>& results) {
  int best = -1;
  for (size_t i = 0; i < results.size(); ++i) {
    if (!results[i].pose.success) continue;
    if (best < 0) {
      best = static_cast<int>(i);
      continue;
    }
    const auto& r = results[i];
    const auto& b = results[best];
    if (r.pose.num_inliers > b.pose.num_inliers ||
        (r.pose.num_inliers == b.pose.num_inliers && r.probability > b.probability))
      best = static_cast<int>(i);
  }
  return best;
}

}  // namespace locforge::regression
