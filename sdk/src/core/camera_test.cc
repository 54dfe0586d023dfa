#include "locforge/camera.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <set>

#include "locforge/error.h"

namespace locforge {
namespace {

using Id = CameraModelId;

constexpr int kWidth = 640;
constexpr int kHeight = 480;

// One plausible camera of each model for a 640x480 image: distortion strong
// enough to matter (several pixels at the corners) and monotonic over the image.
std::map<Id, std::vector<double>> SampleParams() {
  return {
      {Id::kSimplePinhole, {500, 320, 240}},
      {Id::kPinhole, {500, 520, 320, 240}},
      {Id::kSimpleRadial, {500, 320, 240, -0.1}},
      {Id::kRadial, {500, 320, 240, -0.1, 0.02}},
      {Id::kOpenCV, {500, 510, 320, 240, -0.1, 0.02, 0.001, -0.002}},
      {Id::kOpenCVFisheye, {300, 305, 320, 240, 0.05, -0.01, 0.002, -0.0005}},
      {Id::kFullOpenCV,
       {500, 510, 320, 240, -0.1, 0.02, 0.001, -0.002, 0.001, 0.01, -0.005, 0.001}},
      {Id::kFOV, {500, 510, 320, 240, 0.8}},
      {Id::kSimpleRadialFisheye, {300, 320, 240, 0.05}},
      {Id::kRadialFisheye, {300, 320, 240, 0.05, -0.01}},
      {Id::kThinPrismFisheye,
       {300, 305, 320, 240, 0.05, -0.01, 0.001, -0.001, 0.002, -0.0005, 0.001, -0.001}},
  };
}

Camera MakeCamera(Id id, std::vector<double> params) {
  Camera c;
  c.model = id;
  c.width = kWidth;
  c.height = kHeight;
  c.params = std::move(params);
  return c;
}

TEST(CameraModels, TableFollowsColmap) {
  const auto& models = CameraModels();
  ASSERT_EQ(models.size(), 12u);
  const std::vector<std::pair<std::string, int>> expected = {
      {"SIMPLE_PINHOLE", 3}, {"PINHOLE", 4},        {"SIMPLE_RADIAL", 4},
      {"RADIAL", 5},         {"OPENCV", 8},         {"OPENCV_FISHEYE", 8},
      {"FULL_OPENCV", 12},   {"FOV", 5},            {"SIMPLE_RADIAL_FISHEYE", 4},
      {"RADIAL_FISHEYE", 5}, {"THIN_PRISM_FISHEYE", 12}};
  for (size_t i = 0; i < expected.size(); ++i) {
    EXPECT_EQ(static_cast<int>(models[i].id), static_cast<int>(i));  // COLMAP ids
    EXPECT_EQ(models[i].name, expected[i].first);
    EXPECT_EQ(models[i].num_params, expected[i].second);
    // param_names lists exactly num_params names.
    const std::string names = models[i].param_names;
    EXPECT_EQ(std::count(names.begin(), names.end(), ',') + 1, expected[i].second) << names;
  }
  EXPECT_STREQ(models[4].param_names, "fx, fy, cx, cy, k1, k2, p1, p2");
  EXPECT_STREQ(models[6].param_names, "fx, fy, cx, cy, k1, k2, p1, p2, k3, k4, k5, k6");
  EXPECT_STREQ(models[10].param_names, "fx, fy, cx, cy, k1, k2, p1, p2, k3, k4, sx1, sy1");
  EXPECT_EQ(models.back().id, Id::kUnknown);
  EXPECT_STREQ(models.back().name, "UNKNOWN_CAMERA");
  EXPECT_EQ(models.back().num_params, -1);
}

TEST(CameraModels, Lookup) {
  ASSERT_NE(FindCameraModel("OPENCV_FISHEYE"), nullptr);
  EXPECT_EQ(FindCameraModel("OPENCV_FISHEYE")->id, Id::kOpenCVFisheye);
  EXPECT_EQ(FindCameraModel("UNKNOWN_CAMERA")->id, Id::kUnknown);
  EXPECT_EQ(FindCameraModel("opencv"), nullptr);  // names are case-sensitive, as in kapture
  EXPECT_EQ(FindCameraModel(""), nullptr);
  EXPECT_STREQ(CameraModelInfoOf(Id::kFOV).name, "FOV");
  EXPECT_THROW(CameraModelInfoOf(static_cast<Id>(42)), Error);

  const Camera c = Camera::FromModelName("RADIAL", 10, 20, {1, 2, 3, 4, 5});
  EXPECT_EQ(c.model, Id::kRadial);
  EXPECT_EQ(c.width, 10);
  EXPECT_EQ(c.height, 20);
  EXPECT_EQ(c.params.size(), 5u);
  EXPECT_STREQ(c.info().name, "RADIAL");
  try {
    Camera::FromModelName("SIMPLE_RADAIL", 1, 1, {});
    FAIL() << "unknown model accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("SIMPLE_RADAIL"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("did you mean 'SIMPLE_RADIAL'"), std::string::npos)
        << e.what();
  }
}

TEST(Camera, FocalAndPrincipalPoint) {
  const Camera simple = MakeCamera(Id::kSimpleRadial, {500, 320, 240, 0.1});
  EXPECT_EQ(simple.fx(), 500);
  EXPECT_EQ(simple.fy(), 500);
  EXPECT_EQ(simple.cx(), 320);
  EXPECT_EQ(simple.cy(), 240);
  const Camera two = MakeCamera(Id::kOpenCV, {500, 510, 321, 241, 0, 0, 0, 0});
  EXPECT_EQ(two.fx(), 500);
  EXPECT_EQ(two.fy(), 510);
  EXPECT_EQ(two.cx(), 321);
  EXPECT_EQ(two.cy(), 241);
  for (const auto& [id, params] : SampleParams()) {
    const Camera c = MakeCamera(id, params);
    EXPECT_GT(c.fx(), 0);
    EXPECT_EQ(c.cx(), 320) << c.info().name;
    EXPECT_EQ(c.cy(), 240) << c.info().name;
  }
}

TEST(Camera, ValidateRefusesBadParameterCounts) {
  for (const auto& [id, params] : SampleParams()) {
    Camera c = MakeCamera(id, params);
    EXPECT_EQ(c.Validate(), "") << c.info().name;
    c.params.push_back(0.0);
    const std::string why = c.Validate();
    EXPECT_NE(why.find(c.info().name), std::string::npos) << why;
    EXPECT_NE(why.find("got " + std::to_string(params.size() + 1)), std::string::npos) << why;
    c.params.resize(params.size() - 1);
    EXPECT_NE(c.Validate(), "") << c.info().name;
    c.params.clear();
    EXPECT_NE(c.Validate(), "") << c.info().name;
  }
  const std::string why = MakeCamera(Id::kPinhole, {1, 2, 3}).Validate();
  EXPECT_EQ(why, "PINHOLE takes 4 parameters (fx, fy, cx, cy), got 3");
}

TEST(Camera, ValidateRefusesBadValues) {
  EXPECT_NE(MakeCamera(Id::kPinhole, {0, 500, 320, 240}).Validate(), "");
  EXPECT_NE(MakeCamera(Id::kPinhole, {500, -1, 320, 240}).Validate(), "");
  EXPECT_NE(MakeCamera(Id::kSimplePinhole, {std::nan(""), 320, 240}).Validate(), "");
  EXPECT_NE(MakeCamera(Id::kSimpleRadial, {500, 320, 240, INFINITY}).Validate(), "");
  EXPECT_NE(MakeCamera(static_cast<Id>(99), {}).Validate(), "");
  Camera negative = MakeCamera(Id::kSimplePinhole, {500, 320, 240});
  negative.width = -1;
  EXPECT_NE(negative.Validate(), "");
}

TEST(Camera, UnknownCameraKeepsAnyParameters) {
  for (size_t n : {0, 1, 7, 30}) {
    const Camera c = MakeCamera(Id::kUnknown, std::vector<double>(n, 1.5));
    EXPECT_EQ(c.Validate(), "");
    // No geometry: refused with an error, never undefined behaviour.
    EXPECT_THROW(c.fx(), Error);
    EXPECT_THROW(c.Project(Eigen::Vector3d(0, 0, 1)), Error);
    EXPECT_THROW(c.Unproject(Eigen::Vector2d(1, 1)), Error);
  }
}

TEST(Camera, GeometryWithBadParameterCountThrows) {
  const Camera c = MakeCamera(Id::kOpenCV, {500, 500, 320, 240});
  EXPECT_THROW(c.Project(Eigen::Vector3d(0, 0, 1)), Error);
  EXPECT_THROW(c.Unproject(Eigen::Vector2d(1, 1)), Error);
  EXPECT_THROW(c.Distort(Eigen::Vector2d(0.1, 0.1)), Error);
  EXPECT_THROW(c.cy(), Error);
}

// Known values, derived by hand from the model definitions.
TEST(Camera, PinholeKnownValues) {
  const Camera c = MakeCamera(Id::kPinhole, {500, 400, 320, 240});
  // (1, 2, 4) -> (u, v) = (0.25, 0.5) -> (500*0.25+320, 400*0.5+240).
  const Eigen::Vector2d px = c.Project(Eigen::Vector3d(1, 2, 4));
  EXPECT_DOUBLE_EQ(px.x(), 445.0);
  EXPECT_DOUBLE_EQ(px.y(), 440.0);
  const Eigen::Vector3d ray = c.Unproject(Eigen::Vector2d(445, 440));
  EXPECT_DOUBLE_EQ(ray.x(), 0.25);
  EXPECT_DOUBLE_EQ(ray.y(), 0.5);
  EXPECT_DOUBLE_EQ(ray.z(), 1.0);
  // The principal point is the optical axis.
  EXPECT_EQ(c.Unproject(Eigen::Vector2d(320, 240)), Eigen::Vector3d(0, 0, 1));
}

TEST(Camera, SimpleRadialKnownValues) {
  const Camera c = MakeCamera(Id::kSimpleRadial, {100, 50, 60, 0.1});
  // (u, v) = (0.3, 0.4), r^2 = 0.25, scale 1 + 0.1 * 0.25 = 1.025
  // -> (0.3075, 0.41) -> (100*0.3075+50, 100*0.41+60) = (80.75, 101).
  const Eigen::Vector2d px = c.Project(Eigen::Vector3d(0.6, 0.8, 2.0));
  EXPECT_NEAR(px.x(), 80.75, 1e-12);
  EXPECT_NEAR(px.y(), 101.0, 1e-12);
  const Eigen::Vector3d ray = c.Unproject(Eigen::Vector2d(80.75, 101.0));
  EXPECT_NEAR(ray.x(), 0.3, 1e-12);
  EXPECT_NEAR(ray.y(), 0.4, 1e-12);
}

TEST(Camera, OpenCVKnownValues) {
  const Camera c =
      MakeCamera(Id::kOpenCV, {200, 210, 100, 110, 0.1, 0.01, 0.001, 0.002});
  // (u, v) = (0.2, -0.1): r^2 = 0.05, radial = 0.1*0.05 + 0.01*0.0025 = 0.005025
  // du = 0.2*0.005025 + 2*0.001*(-0.02) + 0.002*(0.05 + 2*0.04) = 0.001225
  // dv = -0.1*0.005025 + 2*0.002*(-0.02) + 0.001*(0.05 + 2*0.01) = -0.0005125
  // pixel = (200*0.201225 + 100, 210*(-0.1005125) + 110) = (140.245, 88.892375)
  const Eigen::Vector2d px = c.Project(Eigen::Vector3d(0.4, -0.2, 2.0));
  EXPECT_NEAR(px.x(), 140.245, 1e-12);
  EXPECT_NEAR(px.y(), 88.892375, 1e-12);
  const Eigen::Vector3d ray = c.Unproject(Eigen::Vector2d(140.245, 88.892375));
  EXPECT_NEAR(ray.x(), 0.2, 1e-12);
  EXPECT_NEAR(ray.y(), -0.1, 1e-12);
}

TEST(Camera, FisheyeKnownValues) {
  // A point at 45 degrees off axis: theta = pi/4, equidistant radius = f theta.
  const Camera equidistant = MakeCamera(Id::kOpenCVFisheye, {300, 300, 320, 240, 0, 0, 0, 0});
  Eigen::Vector2d px = equidistant.Project(Eigen::Vector3d(1, 0, 1));
  EXPECT_NEAR(px.x(), 320 + 300 * M_PI / 4, 1e-12);
  EXPECT_NEAR(px.y(), 240, 1e-12);
  // With k1 = 0.1: theta_d = theta (1 + 0.1 theta^2).
  const Camera k1 = MakeCamera(Id::kOpenCVFisheye, {300, 300, 320, 240, 0.1, 0, 0, 0});
  px = k1.Project(Eigen::Vector3d(0, 1, 1));
  const double theta = M_PI / 4;
  EXPECT_NEAR(px.x(), 320, 1e-12);
  EXPECT_NEAR(px.y(), 240 + 300 * theta * (1 + 0.1 * theta * theta), 1e-12);
  // 60 degrees off axis on the diagonal, RADIAL_FISHEYE with k1, k2.
  const Camera radial = MakeCamera(Id::kRadialFisheye, {300, 320, 240, 0.05, -0.01});
  const double t60 = M_PI / 3;
  const double rd = t60 * (1 + 0.05 * t60 * t60 - 0.01 * std::pow(t60, 4));
  px = radial.Project(Eigen::Vector3d(std::tan(t60) / std::sqrt(2.0),
                                      std::tan(t60) / std::sqrt(2.0), 1));
  EXPECT_NEAR(px.x(), 320 + 300 * rd / std::sqrt(2.0), 1e-10);
  EXPECT_NEAR(px.y(), 240 + 300 * rd / std::sqrt(2.0), 1e-10);
}

TEST(Camera, FOVKnownValues) {
  // FOV: r_d = atan(2 r tan(omega/2)) / omega. With omega = pi/2, tan(omega/2) = 1,
  // so r = 0.5 gives r_d = atan(1) / (pi/2) = 0.5 (a fixed point), and r = 1
  // gives atan(2) / (pi/2).
  const Camera c = MakeCamera(Id::kFOV, {100, 100, 0, 0, M_PI / 2});
  Eigen::Vector2d px = c.Project(Eigen::Vector3d(0.5, 0, 1));
  EXPECT_NEAR(px.x(), 50, 1e-12);
  px = c.Project(Eigen::Vector3d(0, 1, 1));
  EXPECT_NEAR(px.y(), 100 * std::atan(2.0) / (M_PI / 2), 1e-12);
  EXPECT_NEAR(c.Unproject(Eigen::Vector2d(0, 100 * std::atan(2.0) / (M_PI / 2))).y(), 1.0,
              1e-12);
}

TEST(Camera, FOVSpecialCasesAreContinuous) {
  // COLMAP switches to Taylor series below omega^2 = 1e-4 and r^2 = 1e-4.
  const Eigen::Vector2d p(0.3, -0.2);
  for (double omega : {0.01, 0.5, 1.2}) {
    const Camera below = MakeCamera(Id::kFOV, {1, 1, 0, 0, omega * (1 - 1e-9)});
    const Camera above = MakeCamera(Id::kFOV, {1, 1, 0, 0, omega * (1 + 1e-9)});
    EXPECT_LT((below.Distort(p) - above.Distort(p)).norm(), 1e-9) << omega;
    EXPECT_LT((below.Undistort(p) - above.Undistort(p)).norm(), 1e-9) << omega;
    // Across r^2 = 1e-4.
    const Eigen::Vector2d in(0.01 * (1 - 1e-9), 0), out(0.01 * (1 + 1e-9), 0);
    EXPECT_NEAR(below.Distort(in).x(), below.Distort(out).x(), 1e-9) << omega;
    EXPECT_NEAR(below.Undistort(in).x(), below.Undistort(out).x(), 1e-9) << omega;
  }
  // At the centre the distortion is 2 tan(omega/2) / omega (the limit r -> 0).
  const Camera c = MakeCamera(Id::kFOV, {1, 1, 0, 0, 0.8});
  EXPECT_NEAR(c.Distort(Eigen::Vector2d(1e-8, 0)).x() / 1e-8, 2 * std::tan(0.4) / 0.8, 1e-12);
  // omega = 0 is the pinhole.
  const Camera pinhole = MakeCamera(Id::kFOV, {1, 1, 0, 0, 0.0});
  EXPECT_EQ(pinhole.Distort(p), p);
  EXPECT_EQ(pinhole.Undistort(p), p);
}

TEST(Camera, ProjectUnprojectRoundTripEveryModel) {
  for (const auto& [id, params] : SampleParams()) {
    const Camera c = MakeCamera(id, params);
    double worst = 0;
    for (double y = 0; y <= kHeight; y += 16) {
      for (double x = 0; x <= kWidth; x += 16) {
        const Eigen::Vector2d px(x, y);
        const Eigen::Vector3d ray = c.Unproject(px);
        ASSERT_DOUBLE_EQ(ray.z(), 1.0);
        // Any point on the ray projects back to the pixel.
        worst = std::max(worst, (c.Project(ray * 3.7) - px).norm());
      }
    }
    EXPECT_LT(worst, 1e-6) << c.info().name;
  }
}

TEST(Camera, UnprojectProjectRoundTripEveryModel) {
  for (const auto& [id, params] : SampleParams()) {
    const Camera c = MakeCamera(id, params);
    for (double v = -0.4; v <= 0.4; v += 0.05) {
      for (double u = -0.55; u <= 0.55; u += 0.05) {
        const Eigen::Vector3d p(u * 2, v * 2, 2);
        const Eigen::Vector3d ray = c.Unproject(c.Project(p));
        EXPECT_LT((ray - p / 2).norm(), 1e-9) << c.info().name << " " << u << " " << v;
      }
    }
  }
}

TEST(Camera, DistortUndistortRoundTripEveryModel) {
  for (const auto& [id, params] : SampleParams()) {
    const Camera c = MakeCamera(id, params);
    double worst = 0;
    for (double v = -0.5; v <= 0.5; v += 0.025) {
      for (double u = -0.65; u <= 0.65; u += 0.025) {
        const Eigen::Vector2d p(u, v);
        worst = std::max(worst, (c.Undistort(c.Distort(p)) - p).norm());
        worst = std::max(worst, (c.Distort(c.Undistort(p)) - p).norm());
      }
    }
    EXPECT_LT(worst, 1e-10) << c.info().name;
  }
}

TEST(Camera, DistortionActuallyDistorts) {
  // Guards against a model silently behaving as a pinhole: a point near the
  // corner moves by more than a pixel for every distorted sample camera.
  const std::set<Id> pinholes = {Id::kSimplePinhole, Id::kPinhole};
  for (const auto& [id, params] : SampleParams()) {
    const Camera c = MakeCamera(id, params);
    const Eigen::Vector2d p(0.5, 0.4);
    const double moved_px = (c.Distort(p) - p).norm() * c.fx();
    if (pinholes.count(id)) {
      EXPECT_EQ(moved_px, 0);
    } else {
      EXPECT_GT(moved_px, 1.0) << c.info().name;
    }
  }
}

TEST(Camera, FOVSmallOmegaRoundTrip) {
  // The series branch (omega^2 < 1e-4) still inverts to well below a pixel.
  const Camera c = MakeCamera(Id::kFOV, {500, 500, 320, 240, 0.005});
  for (double y = 0; y <= kHeight; y += 40)
    for (double x = 0; x <= kWidth; x += 40) {
      const Eigen::Vector2d px(x, y);
      EXPECT_LT((c.Project(c.Unproject(px)) - px).norm(), 1e-6) << x << " " << y;
    }
}

TEST(Camera, ThinPrismMatchesFisheyeWhenPrismTermsVanish) {
  // THIN_PRISM_FISHEYE applies its radial polynomial to the equidistant point
  // (radius theta), so with p1 = p2 = sx1 = sy1 = 0 it is OPENCV_FISHEYE with
  // the same k1..k4: two code paths (one iterative inverse on each) agreeing.
  const Camera prism = MakeCamera(Id::kThinPrismFisheye, {300, 305, 320, 240, 0.05, -0.01, 0,
                                                          0, 0.002, -0.0005, 0, 0});
  const Camera fisheye =
      MakeCamera(Id::kOpenCVFisheye, {300, 305, 320, 240, 0.05, -0.01, 0.002, -0.0005});
  for (double u = -2; u <= 2; u += 0.25) {
    const Eigen::Vector3d p(u, 0.5 * u + 0.1, 1);
    EXPECT_LT((prism.Project(p) - fisheye.Project(p)).norm(), 1e-10) << u;
    const Eigen::Vector2d px = fisheye.Project(p);
    EXPECT_LT((prism.Unproject(px) - fisheye.Unproject(px)).norm(), 1e-9) << u;
  }
}

}  // namespace
}  // namespace locforge
