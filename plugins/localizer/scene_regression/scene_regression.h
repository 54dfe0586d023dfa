// Absolute pose regression (PoseNet, Kendall et al., ICCV 2015) and
// scene-coordinate regression with expert selection (ESAC, Brachmann and
// Rother, ICCV 2019) on ONNX networks run by OpenCV dnn. The networks' contracts
// are in README.md beside this file; the training recipes in train/.
//
// PoseNet: image -> camera centre c and rotation R_world_camera (quaternion),
// so T_camera_world = [R^T | -R^T c].
// ESAC: a gating network gives p(expert | image); M hypotheses are split over
// the experts in proportion to p (paper section 3, "ESAC"); each chosen
// expert's scene coordinates give 2D-3D correspondences (one per output cell,
// at the cell centre) for the LO-RANSAC P3P + refinement of localizer/pnp with
// its share of the hypotheses; the expert whose pose has the most inliers wins
// (the paper picks the hypothesis of highest soft inlier count over all
// experts: the same choice at the level of whole experts).
#ifndef LOCFORGE_PLUGINS_LOCALIZER_SCENE_REGRESSION_SCENE_REGRESSION_H_
#define LOCFORGE_PLUGINS_LOCALIZER_SCENE_REGRESSION_SCENE_REGRESSION_H_

#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "absolute_pose.h"
#include "image_input.h"
#include "locforge/camera.h"
#include "locforge/params.h"
#include "locforge/pose.h"

namespace locforge::regression {

using learned::DeclareInputOptions;
using learned::InputOptions;

// T_camera_world from a regressed camera centre (world, metres) and rotation
// world_from_camera as (w, x, y, z) of any norm. Returns false (and why) when
// the numbers are not finite or the quaternion is ~0.
bool PoseFromRegression(const float position[3], const float orientation[4], Pose* camera_from_world,
                        std::string* why);

// One correspondence per cell of a 1x3xhxw scene-coordinate map regressed
// from an image of image_width x image_height: the cell (i, j) stands for
// the pixel at its centre ((j + 0.5) W / w, (i + 0.5) H / h) (SDK convention:
// first pixel centre at 0.5). Non-finite coordinates are skipped.
std::vector<localization::Correspondence> SceneCoordinateCorrespondences(const cv::Mat& coordinates,
                                                                         const Camera& camera);

// Softmax of gating logits.
std::vector<double> Softmax(const std::vector<float>& logits);

// Splits `hypotheses` over the experts in proportion to `probabilities`
// (largest remainders, ties to the lower index); sums to `hypotheses`.
std::vector<int> HypothesisBudget(const std::vector<double>& probabilities, int hypotheses);

struct ExpertResult {
  int expert = -1;
  double probability = 0;  // the gating network's p(expert | image)
  int hypotheses = 0;
  int correspondences = 0;
  localization::AbsolutePoseResult pose;
};

// The ESAC choice among the experts' results: most inliers among the
// successful ones, ties to the more probable expert (two self-consistent
// scenes explain an image equally well; the gate knows which one it shows).
// Returns -1 when none succeeded.
int BestExpert(const std::vector<ExpertResult>& results);

}  // namespace locforge::regression

#endif  // LOCFORGE_PLUGINS_LOCALIZER_SCENE_REGRESSION_SCENE_REGRESSION_H_
