#include "locforge/colmap/convert.h"

#include <gtest/gtest.h>

#include <cstring>
#include <iostream>
#include <fstream>
#include <regex>

#include "locforge/colmap/convention.h"
#include "locforge/colmap/run.h"
#include "locforge/error.h"
#include "locforge/fs.h"
#include "locforge/kapture/io.h"
#include "locforge/kapture/kapture.h"
#include "testing.h"

namespace locforge::colmap {
namespace {

namespace fs = std::filesystem;
using kapture::FeatureKind;

constexpr const char* kMaupertuis = "data/kapture/maupertuis";

double PoseDistance(const Pose& a, const Pose& b) {
  return (a.t - b.t).norm() + std::abs(std::abs(a.q.normalized().dot(b.q.normalized())) - 1.0);
}

// Cameras, images, poses, points, observations, features and matches of two
// kapture folders agree.
void ExpectSameKapture(const fs::path& expected_root, const fs::path& actual_root,
                       bool compare_matches = true) {
  const kapture::Kapture expected(expected_root), actual(actual_root);
  // Cameras.
  const auto ec = expected.sensors().OfType(kapture::kSensorCamera);
  const auto ac = actual.sensors().OfType(kapture::kSensorCamera);
  ASSERT_EQ(ec.size(), ac.size());
  for (size_t i = 0; i < ec.size(); ++i) {
    EXPECT_EQ(ec[i]->id, ac[i]->id);
    ASSERT_TRUE(ac[i]->camera.has_value());
    EXPECT_EQ(ec[i]->camera->model, ac[i]->camera->model);
    EXPECT_EQ(ec[i]->camera->width, ac[i]->camera->width);
    EXPECT_EQ(ec[i]->camera->params, ac[i]->camera->params);
  }
  // Images.
  const auto er = expected.ReadDataRecords(kapture::kSensorCamera);
  const auto ar = actual.ReadDataRecords(kapture::kSensorCamera);
  ASSERT_EQ(er.size(), ar.size());
  for (size_t i = 0; i < er.size(); ++i) {
    EXPECT_EQ(er[i].timestamp, ar[i].timestamp);
    EXPECT_EQ(er[i].device_id, ar[i].device_id);
    EXPECT_EQ(er[i].path, ar[i].path);
    const auto ep = expected.DevicePose(er[i].timestamp, er[i].device_id);
    const auto ap = actual.DevicePose(ar[i].timestamp, ar[i].device_id);
    ASSERT_EQ(ep.has_value(), ap.has_value()) << er[i].path;
    if (ep) EXPECT_LT(PoseDistance(*ep, *ap), 1e-9) << er[i].path;
  }
  // Points and tracks.
  ASSERT_EQ(expected.points3d().size(), actual.points3d().size());
  for (size_t i = 0; i < expected.points3d().size(); ++i) {
    const auto& e = expected.points3d()[i];
    const auto& a = actual.points3d()[i];
    EXPECT_EQ(Eigen::Vector3d(e.x, e.y, e.z), Eigen::Vector3d(a.x, a.y, a.z)) << i;
    EXPECT_EQ(Eigen::Vector3d(e.r, e.g, e.b), Eigen::Vector3d(a.r, a.g, a.b)) << i;
  }
  ASSERT_EQ(expected.observations().size(), actual.observations().size());
  for (size_t i = 0; i < expected.observations().size(); ++i) {
    EXPECT_EQ(expected.observations()[i].point3d_id, actual.observations()[i].point3d_id);
    EXPECT_EQ(expected.observations()[i].keypoints_type, actual.observations()[i].keypoints_type);
    EXPECT_EQ(expected.observations()[i].features, actual.observations()[i].features) << i;
  }
  // Features, byte for byte.
  for (FeatureKind kind : {FeatureKind::kKeypoints, FeatureKind::kDescriptors}) {
    for (const auto& set : expected.FeatureSets(kind)) {
      ASSERT_TRUE(actual.HasFeatureType(kind, set.type)) << set.type;
      EXPECT_EQ(actual.GetFeatureSet(kind, set.type).info.dsize, set.info.dsize);
      for (const std::string& image : expected.FeatureImages(kind, set.type)) {
        EXPECT_EQ(expected.ReadFeatures(kind, set.type, image).bytes,
                  actual.ReadFeatures(kind, set.type, image).bytes)
            << set.type << " " << image;
      }
    }
  }
  if (!compare_matches) return;
  for (const std::string& type : expected.MatchesTypes()) {
    const auto pairs = expected.MatchPairs(type);
    ASSERT_EQ(pairs, actual.MatchPairs(type));
    for (const auto& [a, b] : pairs) {
      const auto em = expected.ReadMatches(type, a, b);
      const auto am = actual.ReadMatches(type, a, b);
      ASSERT_EQ(em.size(), am.size()) << a << " " << b;
      for (size_t i = 0; i < em.size(); ++i) {
        EXPECT_EQ(em[i].index1, am[i].index1);
        EXPECT_EQ(em[i].index2, am[i].index2);
      }
    }
  }
}

class ConvertTest : public ::testing::Test {
 protected:
  void SetUp() override { tmp_ = testing::MakeTempDir("colmap_convert"); }
  void TearDown() override { fs::remove_all(tmp_); }
  fs::path tmp_;
};

// The sample's colmap/ (made by the kapture toolbox from the same scene)
// imports to the sample's kapture/.
TEST_F(ConvertTest, ImportOfTheSampleColmapMatchesItsKapture) {
  LOCFORGE_SHARED_PATH_OR_SKIP(root, kMaupertuis);
  const ImportReport r = ImportFromColmap(root / "colmap/colmap.db",
                                          root / "colmap/reconstruction", tmp_ / "kapture");
  EXPECT_EQ(r.cameras, 1);
  EXPECT_EQ(r.images, 4);
  EXPECT_EQ(r.posed_images, 4);
  EXPECT_EQ(r.keypoint_images, 4);
  EXPECT_EQ(r.descriptor_images, 4);
  EXPECT_EQ(r.match_pairs, 6);
  EXPECT_EQ(r.points3d, 1039);
  EXPECT_EQ(r.observations, 3355);
  ExpectSameKapture(root / "kapture", tmp_ / "kapture");
}

TEST_F(ConvertTest, ExportOfTheSampleKaptureMatchesItsColmap) {
  LOCFORGE_SHARED_PATH_OR_SKIP(root, kMaupertuis);
  const kapture::Kapture k(root / "kapture");
  const ExportReport r = ExportToColmap(k, tmp_ / "out.db", tmp_ / "model");
  EXPECT_EQ(r.keypoints_type, "SIFT");
  EXPECT_EQ(r.cameras, 1);
  EXPECT_EQ(r.images, 4);
  EXPECT_EQ(r.posed_images, 4);
  EXPECT_EQ(r.keypoint_images, 4);
  EXPECT_EQ(r.descriptor_images, 4);
  EXPECT_EQ(r.match_pairs, 6);
  EXPECT_EQ(r.points3d, 1039);
  EXPECT_EQ(r.observations, 3355);
  EXPECT_TRUE(r.notes.empty()) << r.notes.front();
  // The sample's own reconstruction reports 0.3426 px (colmap model_analyzer).
  EXPECT_NEAR(r.mean_reprojection_error, 0.3426, 0.01);

  const Reconstruction ours = ReadModelText(tmp_ / "model");
  const Reconstruction theirs = ReadModelText(root / "colmap/reconstruction");
  EXPECT_EQ(ours.Validate(), "");
  ASSERT_EQ(ours.images.size(), theirs.images.size());
  for (const ModelImage& t : theirs.images) {
    const ModelImage* o = ours.FindImageByName(t.name);
    ASSERT_NE(o, nullptr) << t.name;
    EXPECT_EQ(o->image_id, t.image_id);  // ids by sorted name, as the sample
    EXPECT_LT(PoseDistance(o->CameraFromWorld(), t.CameraFromWorld()), 1e-9) << t.name;
    ASSERT_EQ(o->points2d.size(), t.points2d.size());
    for (size_t i = 0; i < t.points2d.size(); ++i) {
      // images.txt prints 6 significant digits; ours are the float32
      // keypoints: equal to that rounding (no half-pixel shift).
      for (int c = 0; c < 2; ++c) {
        EXPECT_NEAR(o->points2d[i].xy(c), t.points2d[i].xy(c), 5.01e-6 * std::abs(t.points2d[i].xy(c)))
            << t.name << " " << i;
      }
      EXPECT_EQ(o->points2d[i].HasPoint3D(), t.points2d[i].HasPoint3D());
    }
  }
  // Points: same xyz and tracks, theirs with COLMAP ids, ours with kapture
  // index + 1, both in the kapture file order.
  ASSERT_EQ(ours.points3d.size(), theirs.points3d.size());
  for (size_t i = 0; i < ours.points3d.size(); ++i) {
    EXPECT_EQ(ours.points3d[i].point3d_id, i + 1);
    EXPECT_EQ(ours.points3d[i].xyz, theirs.points3d[i].xyz);
    EXPECT_EQ(ours.points3d[i].track, theirs.points3d[i].track);
  }

  // Database: the same keypoint and descriptor blobs as the sample's, and
  // its verified matches (which kapture's matches are).
  Database db(tmp_ / "out.db");
  Database sample(root / "colmap/colmap.db");
  ASSERT_EQ(db.ReadImages().size(), 4u);
  for (const DbImage& image : sample.ReadImages()) {
    EXPECT_EQ(db.ReadImages()[image.image_id - 1].name, image.name);
    EXPECT_EQ(db.ReadKeypoints(image.image_id)->data, sample.ReadKeypoints(image.image_id)->data);
    EXPECT_EQ(db.ReadDescriptors(image.image_id)->data,
              sample.ReadDescriptors(image.image_id)->data);
    ASSERT_TRUE(db.ReadImages()[image.image_id - 1].prior_qvec.has_value());
  }
  sample.ForEachTwoViewGeometry([&](ImageId a, ImageId b, const TwoViewGeometry& g) {
    EXPECT_EQ(*db.ReadMatches(a, b), g.inlier_matches) << a << " " << b;
    EXPECT_EQ(db.ReadTwoViewGeometry(a, b)->inlier_matches, g.inlier_matches);
    return true;
  });
  // Exporting again refuses to overwrite unless asked.
  EXPECT_THROW(ExportToColmap(k, tmp_ / "out.db", ""), Error);
  ExportOptions again;
  again.overwrite = true;
  again.model_format = ModelFormat::kBinary;
  ExportToColmap(k, tmp_ / "out.db", tmp_ / "model_bin", again);
  EXPECT_EQ(ReadModelBinary(tmp_ / "model_bin").points3d.size(), 1039u);
}

TEST_F(ConvertTest, ExportThenImportGivesBackTheKapture) {
  LOCFORGE_SHARED_PATH_OR_SKIP(root, kMaupertuis);
  ExportToColmap(kapture::Kapture(root / "kapture"), tmp_ / "db.db", tmp_ / "model");
  ImportFromColmap(tmp_ / "db.db", tmp_ / "model", tmp_ / "back");
  ExpectSameKapture(root / "kapture", tmp_ / "back");
  // The output folder is not overwritten silently.
  EXPECT_THROW(ImportFromColmap(tmp_ / "db.db", tmp_ / "model", tmp_ / "back"), Error);
}

TEST_F(ConvertTest, ImportOfAModelAlone) {
  LOCFORGE_SHARED_PATH_OR_SKIP(root, kMaupertuis);
  const ImportReport r = ImportFromColmap("", root / "colmap/reconstruction", tmp_ / "k");
  EXPECT_EQ(r.images, 4);
  EXPECT_EQ(r.posed_images, 4);
  EXPECT_EQ(r.keypoint_images, 0);
  EXPECT_EQ(r.points3d, 1039);
  const kapture::Kapture k(tmp_ / "k");
  EXPECT_EQ(k.trajectories().size(), 4u);
  EXPECT_EQ(k.sensors().Find("cam_00001")->camera->params, (std::vector<double>{1847.53, 959.5, 539.5}));
  EXPECT_TRUE(k.FeatureSets(FeatureKind::kKeypoints).empty());
  EXPECT_EQ(k.observations().size(), 1039u);
}

TEST_F(ConvertTest, PixelConventionIsTheIdentity) {
  const Eigen::Vector2d p(0.5, 1079.25);
  EXPECT_EQ(ConvertPixel(p, PixelDirection::kKaptureToColmap), p);
  EXPECT_EQ(ConvertPixel(ConvertPixel(p, PixelDirection::kKaptureToColmap),
                         PixelDirection::kColmapToKapture),
            p);
}

// The geometric side of convention.h: kapture's points3d projected with its
// poses and camera land on its keypoints best with no half-pixel shift.
TEST_F(ConvertTest, MaupertuisReprojectsBestWithoutPixelShift) {
  LOCFORGE_SHARED_PATH_OR_SKIP(root, kMaupertuis);
  ExportToColmap(kapture::Kapture(root / "kapture"), tmp_ / "db.db", tmp_ / "model");
  const Reconstruction model = ReadModelText(tmp_ / "model");
  const Camera& camera = model.cameras.at(0).camera;
  auto mean_error = [&](double shift) {
    double sum = 0;
    int n = 0;
    for (const ModelPoint3D& p : model.points3d) {
      for (const TrackElement& e : p.track) {
        const ModelImage& image = *model.FindImage(e.image_id);
        const Eigen::Vector2d kapture_xy = image.points2d[e.point2d_idx].xy;
        sum += (camera.Project(image.CameraFromWorld() * p.xyz) -
                (kapture_xy + Eigen::Vector2d::Constant(shift)))
                   .norm();
        ++n;
      }
    }
    return sum / n;
  };
  const double none = mean_error(0), plus = mean_error(0.5), minus = mean_error(-0.5);
  std::cout << "mean reprojection error, kapture keypoints shifted by 0 / +0.5 / -0.5 px: " << none
            << " / " << plus << " / " << minus << "\n";
  EXPECT_LT(none, 0.4);
  EXPECT_LT(none, plus);
  EXPECT_LT(none, minus);
}

// A two-camera rig: per-camera poses are T_sensor_rig * T_rig_world.
TEST_F(ConvertTest, ExportComposesRigPoses) {
  const fs::path root = tmp_ / "rig";
  kapture::Sensors sensors;
  Camera cam;
  cam.model = CameraModelId::kPinhole;
  cam.width = 640;
  cam.height = 480;
  cam.params = {500, 500, 320, 240};
  sensors.Add(kapture::MakeCameraSensor("right", "", cam));
  sensors.Add(kapture::MakeCameraSensor("left", "", cam));
  kapture::WriteSensors(root / "sensors/sensors.txt", sensors);
  kapture::Rigs rigs;
  const Pose left_from_rig(Eigen::Quaterniond(Eigen::AngleAxisd(0.1, Eigen::Vector3d::UnitY())),
                           Eigen::Vector3d(0.1, 0, 0));
  const Pose right_from_rig(Eigen::Quaterniond(Eigen::AngleAxisd(-0.1, Eigen::Vector3d::UnitY())),
                            Eigen::Vector3d(-0.1, 0, 0));
  rigs.Add("rig", {"left", left_from_rig});
  rigs.Add("rig", {"right", right_from_rig});
  kapture::WriteRigs(root / "sensors/rigs.txt", rigs);
  kapture::Trajectories traj;
  const Pose rig_from_world(Eigen::Quaterniond(Eigen::AngleAxisd(0.5, Eigen::Vector3d(1, 1, 0).normalized())),
                            Eigen::Vector3d(1, 2, 3));
  traj.Set(10, "rig", rig_from_world);
  kapture::WriteTrajectories(root / "sensors/trajectories.txt", traj);
  kapture::WriteRecords<kapture::DataRecord>(
      root / "sensors/records_camera.txt", kapture::RecordKind::kCamera,
      {{10, "left", "left/0010.jpg"}, {10, "right", "right/0010.jpg"}, {20, "left", "left/0020.jpg"}});

  const ExportReport r = ExportToColmap(kapture::Kapture(root), tmp_ / "rig.db", tmp_ / "model");
  EXPECT_EQ(r.cameras, 2);
  EXPECT_EQ(r.images, 3);
  EXPECT_EQ(r.posed_images, 2);  // left/0020.jpg has no pose
  const Reconstruction model = ReadModelText(tmp_ / "model");
  // Camera ids by sorted sensor id: left = 1, right = 2; images by name.
  const ModelImage* left = model.FindImageByName("left/0010.jpg");
  const ModelImage* right = model.FindImageByName("right/0010.jpg");
  ASSERT_TRUE(left && right);
  EXPECT_EQ(left->image_id, 1u);
  EXPECT_EQ(left->camera_id, 1u);
  EXPECT_EQ(right->image_id, 3u);
  EXPECT_EQ(right->camera_id, 2u);
  EXPECT_LT(PoseDistance(left->CameraFromWorld(), left_from_rig * rig_from_world), 1e-12);
  EXPECT_LT(PoseDistance(right->CameraFromWorld(), right_from_rig * rig_from_world), 1e-12);
  Database db(tmp_ / "rig.db");
  EXPECT_EQ(db.ReadImages()[1].name, "left/0020.jpg");
  EXPECT_FALSE(db.ReadImages()[1].prior_qvec.has_value());
}

// Real rig data with third-party features: virtual_gallery_tutorial's
// rig, R2D2 keypoints (x, y, scale: 3 columns -> COLMAP's 4 with orientation
// 0) and float32 descriptors (COLMAP has uint8 only: skipped with a note).
TEST_F(ConvertTest, ExportsTheVirtualGalleryRigWithR2d2Keypoints) {
  LOCFORGE_SHARED_PATH_OR_SKIP(root, "data/kapture/virtual_gallery_tutorial");
  kapture::Kapture k(root / "mapping");
  k.AttachFeatures(FeatureKind::kKeypoints, "r2d2_500", root / "local_features/r2d2_500/keypoints");
  k.AttachFeatures(FeatureKind::kDescriptors, "r2d2_500",
                   root / "local_features/r2d2_500/descriptors");
  const ExportReport r = ExportToColmap(k, tmp_ / "vg.db", tmp_ / "model");
  EXPECT_EQ(r.keypoints_type, "r2d2_500");
  EXPECT_EQ(r.cameras, 2);  // the tutorial ships 2 of the rig's cameras
  EXPECT_EQ(r.images, 12);
  EXPECT_EQ(r.posed_images, 12);
  EXPECT_EQ(r.keypoint_images, 12);
  EXPECT_EQ(r.descriptor_images, 0);
  ASSERT_EQ(r.notes.size(), 1u);
  EXPECT_NE(r.notes[0].find("float32, COLMAP stores uint8 only"), std::string::npos) << r.notes[0];
  Database db(tmp_ / "vg.db");
  const auto images = db.ReadImages();
  const KeypointsBlob kp = *db.ReadKeypoints(1);
  EXPECT_EQ(kp.cols, 4u);
  const kapture::FeatureArray theirs = k.ReadKeypoints("r2d2_500", images[0].name);
  ASSERT_EQ(kp.rows, theirs.rows);
  for (int64_t i = 0; i < theirs.rows; ++i) {
    EXPECT_EQ(kp.at(i, 0), theirs.At(i, 0));
    EXPECT_EQ(kp.at(i, 1), theirs.At(i, 1));
    EXPECT_EQ(kp.at(i, 2), theirs.At(i, 2));
    EXPECT_EQ(kp.at(i, 3), 0.0f);
  }
  // Each camera pose is the rig pose composed with the camera's rig extrinsics.
  const Reconstruction model = ReadModelText(tmp_ / "model");
  for (const kapture::DataRecord& rec : k.ReadDataRecords(kapture::kSensorCamera)) {
    const ModelImage* image = model.FindImageByName(rec.path);
    ASSERT_NE(image, nullptr) << rec.path;
    const Pose rig = *k.trajectories().Find(rec.timestamp, "training_rig");
    const Pose cam_from_rig = k.rigs().Find("training_rig")->Find(rec.device_id)->sensor_from_rig;
    EXPECT_LT(PoseDistance(image->CameraFromWorld(), cam_from_rig * rig), 1e-12) << rec.path;
  }
}

TEST_F(ConvertTest, RefusesBadRequests) {
  LOCFORGE_SHARED_PATH_OR_SKIP(root, kMaupertuis);
  ExportOptions options;
  options.keypoints_type = "R2D2";
  EXPECT_THROW(ExportToColmap(kapture::Kapture(root / "kapture"), tmp_ / "x.db", "", options),
               InputError);
  EXPECT_FALSE(fs::exists(tmp_ / "x.db"));
  EXPECT_THROW(ImportFromColmap("", "", tmp_ / "k"), ParamError);
  // A model whose image names disagree with the database.
  Reconstruction m = ReadModelText(root / "colmap/reconstruction");
  m.images[0].name = "renamed.jpg";
  WriteModelText(m, tmp_ / "renamed");
  try {
    ImportFromColmap(root / "colmap/colmap.db", tmp_ / "renamed", tmp_ / "k");
    ADD_FAILURE() << "accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("'renamed.jpg' in the model but '03.jpg' in the database"),
              std::string::npos)
        << e.what();
  }
}

// ---- the `colmap` executable accepts what we export

struct AnalyzerNumbers {
  int64_t cameras = -1, images = -1, registered = -1, points = -1, observations = -1;
  double reprojection_error = -1;
};

AnalyzerNumbers Analyze(const fs::path& model, const fs::path& log) {
  RunOptions options;
  options.log_file = log;
  options.timeout_s = 120;
  RunColmap({"model_analyzer", "--path", model.string()}, options);
  const std::string text = ReadFile(log);
  AnalyzerNumbers n;
  auto grab = [&](const std::string& label) -> std::string {
    const std::regex re(label + ": ([0-9.]+)");
    std::smatch m;
    return std::regex_search(text, m, re) ? m[1].str() : "-1";
  };
  n.cameras = std::stoll(grab("Cameras"));
  n.images = std::stoll(grab("\\bImages"));
  n.registered = std::stoll(grab("Registered images"));
  n.points = std::stoll(grab("Points"));
  n.observations = std::stoll(grab("Observations"));
  n.reprojection_error = std::stod(grab("Mean reprojection error"));
  return n;
}

TEST_F(ConvertTest, ColmapModelAnalyzerReadsOurExport) {
  LOCFORGE_SHARED_PATH_OR_SKIP(root, kMaupertuis);
  if (FindColmapExecutable().empty()) GTEST_SKIP() << "colmap executable not available";
  for (const ModelFormat format : {ModelFormat::kText, ModelFormat::kBinary}) {
    ExportOptions options;
    options.model_format = format;
    options.overwrite = true;
    const ExportReport r =
        ExportToColmap(kapture::Kapture(root / "kapture"), tmp_ / "db.db", tmp_ / "model", options);
    const AnalyzerNumbers n = Analyze(tmp_ / "model", tmp_ / "analyzer.log");
    EXPECT_EQ(n.cameras, r.cameras);
    EXPECT_EQ(n.images, r.posed_images);
    EXPECT_EQ(n.registered, r.posed_images);
    EXPECT_EQ(n.points, r.points3d);
    EXPECT_EQ(n.observations, r.observations);
    EXPECT_NEAR(n.reprojection_error, r.mean_reprojection_error, 1e-5);
    fs::remove_all(tmp_ / "model");
  }
}

TEST_F(ConvertTest, ColmapPointTriangulatorTriangulatesOurExport) {
  LOCFORGE_SHARED_PATH_OR_SKIP(root, kMaupertuis);
  if (FindColmapExecutable().empty()) GTEST_SKIP() << "colmap executable not available";
  ExportOptions options;
  options.export_points3d = false;
  const ExportReport r = ExportToColmap(kapture::Kapture(root / "kapture"), tmp_ / "db.db",
                                        tmp_ / "empty_model", options);
  EXPECT_EQ(r.points3d, 0);
  fs::create_directories(tmp_ / "triangulated");
  RunOptions run;
  run.log_file = tmp_ / "triangulator.log";
  run.timeout_s = 300;
  RunColmap({"point_triangulator", "--database_path", (tmp_ / "db.db").string(), "--image_path",
             (root / "kapture/sensors/records_data").string(), "--input_path",
             (tmp_ / "empty_model").string(), "--output_path", (tmp_ / "triangulated").string()},
            run);
  const AnalyzerNumbers n = Analyze(tmp_ / "triangulated", tmp_ / "analyzer.log");
  EXPECT_EQ(n.registered, 4);
  EXPECT_GT(n.points, 500);  // the sample's own model has 1039
  EXPECT_GT(n.observations, 2 * n.points);
  std::cout << "point_triangulator: " << n.points << " points, " << n.observations
            << " observations, mean reprojection error " << n.reprojection_error << " px\n";
  EXPECT_GT(n.reprojection_error, 0.0);
  EXPECT_LT(n.reprojection_error, 1.0);
  // Its output reads back with our reader, and the poses were kept.
  const Reconstruction tri = ReadModel(tmp_ / "triangulated");
  EXPECT_EQ(tri.Validate(), "");
  EXPECT_EQ(static_cast<int64_t>(tri.points3d.size()), n.points);
  const Reconstruction input = ReadModelText(tmp_ / "empty_model");
  for (const ModelImage& image : input.images) {
    EXPECT_LT(PoseDistance(tri.FindImage(image.image_id)->CameraFromWorld(), image.CameraFromWorld()),
              1e-9);
  }
}

}  // namespace
}  // namespace locforge::colmap
