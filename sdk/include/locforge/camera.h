// Camera models: every model name of kapture 1.1 / COLMAP 3.8, with the
// parameter order of COLMAP's src/base/camera_models.h.
//
// Pixel convention (the SDK's, kapture's and COLMAP's alike): the image's
// top-left corner is (0, 0) and the centre of the first pixel is (0.5, 0.5);
// x to the right, y down. Camera frame: x right, y down, z forward.
#ifndef LOCFORGE_CAMERA_H_
#define LOCFORGE_CAMERA_H_

#include <Eigen/Core>
#include <string>
#include <vector>

namespace locforge {

enum class CameraModelId : int {
  kUnknown = -1,  // kapture's UNKNOWN_CAMERA: parameters kept verbatim
  kSimplePinhole = 0,
  kPinhole = 1,
  kSimpleRadial = 2,
  kRadial = 3,
  kOpenCV = 4,
  kOpenCVFisheye = 5,
  kFullOpenCV = 6,
  kFOV = 7,
  kSimpleRadialFisheye = 8,
  kRadialFisheye = 9,
  kThinPrismFisheye = 10,
};

struct CameraModelInfo {
  CameraModelId id;
  const char* name;          // kapture/COLMAP spelling, e.g. "SIMPLE_RADIAL"
  int num_params;            // -1 for kUnknown (any count)
  const char* param_names;   // e.g. "f, cx, cy, k"
};

// All known models, in COLMAP id order, then UNKNOWN_CAMERA.
const std::vector<CameraModelInfo>& CameraModels();
// Lookup by name; returns nullptr when unknown.
const CameraModelInfo* FindCameraModel(const std::string& name);
const CameraModelInfo& CameraModelInfoOf(CameraModelId id);

struct Camera {
  CameraModelId model = CameraModelId::kPinhole;
  int width = 0;
  int height = 0;
  std::vector<double> params;

  // Focal lengths and principal point, whatever the model.
  double fx() const;
  double fy() const;
  double cx() const;
  double cy() const;

  // Point in the camera frame (z > 0) to pixel.
  Eigen::Vector2d Project(const Eigen::Vector3d& p_camera) const;
  // Pixel to a ray in the camera frame with z = 1 (normalised image plane).
  Eigen::Vector3d Unproject(const Eigen::Vector2d& pixel) const;
  // On the normalised image plane: apply / remove the lens distortion.
  Eigen::Vector2d Distort(const Eigen::Vector2d& undistorted) const;
  Eigen::Vector2d Undistort(const Eigen::Vector2d& distorted) const;

  // Checks the parameter count against the model. Returns "" or the reason.
  std::string Validate() const;

  // The model's entry of CameraModels().
  const CameraModelInfo& info() const { return CameraModelInfoOf(model); }
  // A camera of the model named `model_name` (kapture/COLMAP spelling); throws
  // InputError when the name is unknown. Parameters are not validated here.
  static Camera FromModelName(const std::string& model_name, int width, int height,
                              std::vector<double> params);
};

}  // namespace locforge

#endif  // LOCFORGE_CAMERA_H_
