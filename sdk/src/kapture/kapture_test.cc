// The dataset facade and rig handling on the shared kapture samples.
#include "locforge/kapture/kapture.h"

#include <gtest/gtest.h>

#include <atomic>
#include <thread>

#include "locforge/error.h"
#include "locforge/kapture/rigs.h"
#include "testing.h"

namespace locforge::kapture {
namespace {

void ExpectPoseNear(const Pose& p, const Eigen::Quaterniond& q, const Eigen::Vector3d& t,
                    double tol) {
  // q and -q are the same rotation.
  const double sign = p.q.coeffs().dot(q.coeffs()) < 0 ? -1.0 : 1.0;
  EXPECT_NEAR(p.q.w(), sign * q.w(), tol);
  EXPECT_NEAR(p.q.x(), sign * q.x(), tol);
  EXPECT_NEAR(p.q.y(), sign * q.y(), tol);
  EXPECT_NEAR(p.q.z(), sign * q.z(), tol);
  EXPECT_NEAR((p.t - t).norm(), 0.0, tol * std::max(1.0, t.norm()));
}

TEST(KaptureSamples, Maupertuis) {
  LOCFORGE_SHARED_PATH_OR_SKIP(root, "data/kapture/maupertuis/kapture");
  Kapture k(root);
  ASSERT_EQ(k.sensors().size(), 2u);
  const Sensor* cam = k.sensors().Find("cam_00001");
  ASSERT_TRUE(cam && cam->camera);
  EXPECT_EQ(cam->name, "");
  EXPECT_EQ(cam->camera->model, CameraModelId::kSimplePinhole);
  EXPECT_EQ(cam->camera->width, 1919);
  EXPECT_EQ(cam->camera->height, 1079);
  EXPECT_DOUBLE_EQ(cam->camera->params[0], 1847.53);
  EXPECT_EQ(k.sensors().Find("gps_00001")->EpsgCode(), "EPSG:4326");
  EXPECT_EQ(k.trajectories().size(), 4u);
  const Pose* p = k.trajectories().Find(2, "cam_00001");
  ASSERT_TRUE(p);
  // Unit quaternion for geometry; the file's numbers kept for writing back.
  EXPECT_NEAR(p->q.norm(), 1.0, 1e-15);
  EXPECT_NEAR(p->q.w(), 0.999999, 1e-6);
  EXPECT_EQ(p->t.z(), 0.314238);
  ASSERT_EQ(k.trajectories().raw_rotations.count({2, "cam_00001"}), 1u);
  EXPECT_EQ(k.trajectories().raw_rotations.at({2, "cam_00001"})[0], 0.999999);
  EXPECT_EQ(k.trajectories().raw_rotations.at({2, "cam_00001"})[3], 8.68136e-05);
  EXPECT_EQ(k.RecordTypes(), (std::vector<std::string>{"camera", "gnss"}));
  const auto images = k.ReadDataRecords("camera");
  ASSERT_EQ(images.size(), 4u);
  EXPECT_EQ(images[3].path, "03.jpg");
  EXPECT_TRUE(std::filesystem::exists(k.ExistingRecordDataPath(images[3].path)));
  const auto gnss = ReadRecords<GnssRecord>(root / layout::RecordsFile("gnss"));
  ASSERT_EQ(gnss.size(), 4u);
  EXPECT_EQ(gnss[0].x, 5.793155);
  EXPECT_EQ(gnss[0].utc, 514850400);
  EXPECT_EQ(gnss[0].dop, 10.0);

  // Features: SIFT keypoints float32 x 6, descriptors uint8 x 128.
  const FeatureSet& kp = k.GetFeatureSet(FeatureKind::kKeypoints, "SIFT");
  EXPECT_EQ(kp.info.dtype, DType::kFloat32);
  EXPECT_EQ(kp.info.dsize, 6);
  EXPECT_EQ(k.FeatureImages(FeatureKind::kKeypoints, "SIFT"),
            (std::vector<std::string>{"00.jpg", "01.jpg", "02.jpg", "03.jpg"}));
  const FeatureArray kpt = k.ReadKeypoints("SIFT", "00.jpg");
  EXPECT_EQ(kpt.rows, 6424);  // 154176 bytes / (6 * 4)
  EXPECT_FLOAT_EQ(kpt.data<float>()[0], 1290.9084f);
  EXPECT_FLOAT_EQ(static_cast<float>(kpt.At(0, 1)), 4.1563606f);
  EXPECT_THROW(kpt.data<double>(), Error);
  const FeatureArray desc = k.ReadDescriptors("SIFT", "00.jpg");
  EXPECT_EQ(desc.rows, 6424);
  EXPECT_EQ(desc.dsize, 128);
  EXPECT_EQ(desc.data<uint8_t>()[0], 21);
  EXPECT_EQ(desc.data<uint8_t>()[3], 67);
  EXPECT_EQ(k.GetFeatureSet(FeatureKind::kDescriptors, "SIFT").info.keypoints_type, "SIFT");
  EXPECT_THROW(k.ReadKeypoints("SIFT", "99.jpg"), InputError);
  EXPECT_THROW(k.ReadKeypoints("ORB", "00.jpg"), InputError);

  // Matches: 6 pairs; either order reads, index columns follow the request.
  EXPECT_EQ(k.MatchesTypes(), (std::vector<std::string>{"SIFT"}));
  const auto pairs = k.MatchPairs("SIFT");
  ASSERT_EQ(pairs.size(), 6u);
  EXPECT_EQ(pairs[0], (std::pair<std::string, std::string>("00.jpg", "01.jpg")));
  const auto m01 = k.ReadMatches("SIFT", "00.jpg", "01.jpg");
  ASSERT_EQ(m01.size(), 2501u);
  EXPECT_EQ(m01[0].index1, 3.0);
  EXPECT_EQ(m01[0].index2, 1.0);
  EXPECT_EQ(m01.back().index1, 6419.0);
  const auto m10 = k.ReadMatches("SIFT", "01.jpg", "00.jpg");
  EXPECT_EQ(m10[0].index1, 1.0);
  EXPECT_EQ(m10[0].index2, 3.0);

  ASSERT_EQ(k.points3d().size(), 1039u);
  EXPECT_EQ(k.points3d()[0].x, -2.396749999999999936e+00);
  EXPECT_EQ(k.points3d()[0].r, 57.0);
  ASSERT_EQ(k.observations().size(), 1039u);
  EXPECT_EQ(k.observations()[0].keypoints_type, "SIFT");
  EXPECT_EQ(k.observations()[0].features.size(), 4u);
  EXPECT_EQ(k.observations()[0].features[0],
            (std::pair<std::string, int64_t>("01.jpg", 4561)));
  // The observed keypoint indices are within the keypoint files.
  for (const auto& e : k.observations())
    for (const auto& [image, id] : e.features) ASSERT_LT(id, k.ReadKeypoints("SIFT", image).rows);
}

TEST(KaptureSamples, M1xMetadataParsesCompletely) {
  LOCFORGE_SHARED_PATH_OR_SKIP(root, "data/kapture/m1x_metadata");
  Kapture k(root);
  const Sensors& s = k.sensors();
  EXPECT_EQ(s.size(), 14u);
  EXPECT_EQ(s.OfType("lidar").size(), 2u);
  EXPECT_EQ(s.OfType("camera").size(), 10u);
  EXPECT_EQ(s.OfType("wifi").size(), 1u);
  EXPECT_EQ(s.OfType("bluetooth").size(), 1u);
  EXPECT_EQ(s.Find("lidar0")->name, "vertical");
  EXPECT_EQ(s.Find("AC01324954")->camera->model, CameraModelId::kFullOpenCV);
  EXPECT_DOUBLE_EQ(s.Find("AC01324954")->camera->params[4], 0.309526634993);
  ASSERT_EQ(k.rigs().size(), 1u);
  EXPECT_EQ(k.rigs().list()[0].id, "rig");
  EXPECT_EQ(k.rigs().NumSensorEntries(), 14u);
  EXPECT_EQ(k.trajectories().size(), 9u);
  EXPECT_EQ(k.RecordTypes(),
            (std::vector<std::string>{"bluetooth", "camera", "lidar", "wifi"}));
  EXPECT_EQ(k.ReadDataRecords("camera").size(), 18u);
  const auto lidar = k.ReadDataRecords("lidar");
  ASSERT_EQ(lidar.size(), 6u);
  EXPECT_EQ(lidar[1].device_id, "lidar1");
  EXPECT_EQ(lidar[1].path, "lidar1/1555399760777612.pcd");
  const auto wifi = ReadRecords<WifiRecord>(root / layout::RecordsFile("wifi"));
  ASSERT_EQ(wifi.size(), 6u);
  EXPECT_EQ(wifi[1].ssid, "@HYUNDAI-WiFi");
  EXPECT_EQ(wifi[1].frequency, 5765);
  EXPECT_EQ(wifi[1].rssi, -49.0);
  const auto bt = ReadRecords<BluetoothRecord>(root / layout::RecordsFile("bluetooth"));
  ASSERT_EQ(bt.size(), 6u);
  EXPECT_EQ(bt[1].name, "MyPhone");
  EXPECT_EQ(bt[5].rssi, -59.0);  // last line has no final newline
  const FeatureSet& sift = k.GetFeatureSet(FeatureKind::kKeypoints, "SIFT");
  EXPECT_EQ(sift.info.dtype_name, "float");
  EXPECT_EQ(sift.info.dtype, DType::kFloat64);
  EXPECT_EQ(sift.info.dsize, 4);
  EXPECT_EQ(k.points3d().size(), 20u);

  // Composed pose of camera 22970286 at a rig timestamp, against the value
  // computed by hand (numpy): T_cam_world = T_cam_rig * T_rig_world.
  const auto pose = k.DevicePose(1555399760779869, "22970286");
  ASSERT_TRUE(pose);
  ExpectPoseNear(*pose,
                 // numpy, with both quaternions normalised as the toolbox's
                 // rotate_vectors does
                 Eigen::Quaterniond(0.5340713285651891, -0.048371930622734254,
                                    -0.8408054933830613, 0.07398712475363885),
                 Eigen::Vector3d(639.1521723323182, -40.884708278921096, -192.97095878722163),
                 1e-9);
  EXPECT_FALSE(k.DevicePose(1555399760779869, "no_such_camera"));
  EXPECT_FALSE(k.DevicePose(42, "22970286"));
  // Every camera record at a rig timestamp gets a pose after rigs_remove.
  const Trajectories per_sensor = RigsRemove(k.trajectories(), k.rigs());
  EXPECT_EQ(per_sensor.size(), 9u * 14u);
  EXPECT_EQ(per_sensor.Find(1555399760779869, "rig"), nullptr);
}

TEST(KaptureSamples, VirtualGalleryRigConventionFromData) {
  // training/ has both the rig extrinsics and per-camera poses: recovering
  // the rig from each camera must give one rig pose per timestamp, and
  // composing it back must give every camera's pose.
  LOCFORGE_SHARED_PATH_OR_SKIP(root, "data/kapture/virtual_gallery_metadata/training");
  Kapture k(root);
  EXPECT_EQ(k.sensors().size(), 6u);
  ASSERT_EQ(k.rigs().size(), 1u);
  EXPECT_EQ(k.rigs().NumSensorEntries(), 6u);
  const Trajectories& cams = k.trajectories();
  ASSERT_EQ(cams.size(), 48u);
  const Trajectories rig = RigsRecover(cams, k.rigs());
  ASSERT_EQ(rig.size(), 8u);
  for (const auto& [key, pose] : cams.poses) {
    const Rig& r = *k.rigs().RigOf(key.second);
    // The rig pose seen from this camera agrees with the one recovered.
    const Pose from_this = r.Find(key.second)->sensor_from_rig.Inverse() * pose;
    const Pose& recovered = rig.poses.at({key.first, r.id});
    EXPECT_LT(RotationAngleDeg(from_this.q, recovered.q), 1e-4) << key.second;
    EXPECT_LT((from_this.t - recovered.t).norm(), 2e-6) << key.second;
  }
  const Trajectories back = RigsRemove(rig, k.rigs());
  ASSERT_EQ(back.size(), 48u);
  for (const auto& [key, pose] : cams.poses) {
    const Pose& b = back.poses.at(key);
    EXPECT_LT(RotationAngleDeg(b.q, pose.q), 1e-4);
    EXPECT_LT((b.t - pose.t).norm(), 2e-6);
  }
  // The opposite convention (rigs.txt = T_rig_sensor) fails on this data.
  const RigSensor& c1 = *k.rigs().Find("training_rig")->Find("training_camera_1");
  const Pose rig0 = rig.poses.at({0, "training_rig"});
  const Pose wrong = c1.sensor_from_rig.Inverse() * rig0;
  EXPECT_GT((wrong.t - cams.poses.at({0, "training_camera_1"}).t).norm(), 0.1);
}

TEST(KaptureSamples, VirtualGalleryTutorialRigAndFeatures) {
  LOCFORGE_SHARED_PATH_OR_SKIP(tutorial, "data/kapture/virtual_gallery_tutorial");
  Kapture mapping(tutorial / "mapping");
  EXPECT_EQ(mapping.trajectories().size(), 6u);
  EXPECT_EQ(mapping.ReadDataRecords("camera").size(), 12u);
  // Hand-computed (numpy): camera 1 at timestamp 223.
  const auto pose = mapping.DevicePose(223, "training_camera_1");
  ASSERT_TRUE(pose);
  ExpectPoseNear(*pose, Eigen::Quaterniond(0.2561413661199806, 0.0, 0.9666393332376819, 0.0),
                 Eigen::Vector3d(-0.05613710203753941, 1.6500000000000004, -1.2714315129186973),
                 1e-12);
  // Features kept outside the kapture (kapture-localization layout).
  mapping.AttachFeatures(FeatureKind::kKeypoints, "r2d2_500",
                         tutorial / "local_features/r2d2_500/keypoints");
  mapping.AttachFeatures(FeatureKind::kDescriptors, "r2d2_500",
                         tutorial / "local_features/r2d2_500/descriptors");
  mapping.AttachFeatures(FeatureKind::kGlobalFeatures, "AP-GeM-LM18",
                         tutorial / "global_features/AP-GeM-LM18/global_features");
  const std::string image = "training/gallery_light1_loop1/frames/rgb/camera_0/rgb_00223.jpg";
  const FeatureArray kp = mapping.ReadKeypoints("r2d2_500", image);
  EXPECT_EQ(kp.rows, 500);
  EXPECT_EQ(kp.dsize, 3);
  EXPECT_FLOAT_EQ(kp.data<float>()[0], 866.02234f);
  EXPECT_FLOAT_EQ(kp.data<float>()[2], 76.10925f);
  const FeatureArray desc = mapping.ReadDescriptors("r2d2_500", image);
  EXPECT_EQ(desc.rows, 500);
  EXPECT_EQ(desc.dsize, 128);
  EXPECT_EQ(mapping.GetFeatureSet(FeatureKind::kDescriptors, "r2d2_500").info.keypoints_type,
            "r2d2_500");
  const FeatureArray g = mapping.ReadGlobalFeatures("AP-GeM-LM18", image);
  EXPECT_EQ(g.rows, 1);
  EXPECT_EQ(g.dsize, 2048);
  double norm2 = 0;
  for (int64_t i = 0; i < g.dsize; ++i) norm2 += g.At(0, i) * g.At(0, i);
  EXPECT_NEAR(norm2, 1.0, 1e-5);  // AP-GeM descriptors are L2-normalised
  EXPECT_EQ(mapping.FeatureImages(FeatureKind::kKeypoints, "r2d2_500").size(), 16u);
  mapping.ForEachDataRecord("camera", [&](const DataRecord& r) {
    EXPECT_TRUE(mapping.HasFeatureFile(FeatureKind::kKeypoints, "r2d2_500", r.path)) << r.path;
  });
}

TEST(KaptureSamples, SevenScenesDepthRecordsAndMissingImages) {
  LOCFORGE_SHARED_PATH_OR_SKIP(root, "data/kapture/7scenes_stairs/mapping");
  Kapture k(root);
  EXPECT_EQ(k.sensors().OfType("depth").size(), 2u);
  EXPECT_EQ(k.sensors().Find("kinect_depth")->camera->params[0], 585.0);
  const auto depth = k.ReadDataRecords("depth");
  EXPECT_EQ(depth.size(), 12u);
  const fs::path d = k.ExistingRecordDataPath(depth[0].path);
  EXPECT_EQ(fs::file_size(d), 640u * 480u * 4u);
  // The colour images are not shipped: a clear error names the record file.
  const auto cams = k.ReadDataRecords("camera");
  try {
    k.ExistingRecordDataPath(cams[0].path, "sensors/records_camera.txt:3");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("sensors/records_camera.txt:3: missing file "
                                         "'seq-02/frame-000000.color.jpg'"),
              std::string::npos)
        << e.what();
  }
  // Rig pose composition with a negative-w rig quaternion (same rotation).
  EXPECT_TRUE(k.DevicePose(3, "kinect_rgb"));
  EXPECT_TRUE(k.DevicePose(3, "kinect_depth"));
}

TEST(KaptureSamples, InspectReportsCountsAndProblems) {
  LOCFORGE_SHARED_PATH_OR_SKIP(root, "data/kapture/7scenes_stairs/query");
  const KaptureSummary s = InspectKapture(root);
  EXPECT_EQ(s.sensors_by_type.at("camera"), 1);
  EXPECT_EQ(s.sensors_by_type.at("depth"), 2);
  EXPECT_EQ(s.trajectory_poses, 6);
  ASSERT_EQ(s.records.size(), 2u);
  EXPECT_EQ(s.records[0].sensor_type, "camera");
  EXPECT_EQ(s.records[0].count, 6);
  EXPECT_EQ(s.records[0].missing_files, 6);  // colour images not shipped
  EXPECT_EQ(s.records[1].sensor_type, "depth");
  EXPECT_EQ(s.records[1].count, 12);
  EXPECT_EQ(s.records[1].missing_files, 6);  // the .depth files are shipped, not the .depth.reg
  bool named = false;
  for (const auto& p : s.problems)
    named |= p.find("missing file sensors/records_data/seq-01/frame-000000.color.jpg") !=
             std::string::npos;
  EXPECT_TRUE(named);
  const std::string text = FormatSummary(s);
  EXPECT_NE(text.find("records camera: 6 from 1 devices"), std::string::npos) << text;

  LOCFORGE_SHARED_PATH_OR_SKIP(tutorial_mapping, "data/kapture/virtual_gallery_tutorial/mapping");
  const KaptureSummary t = InspectKapture(tutorial_mapping);
  bool rig_problem = false;
  for (const auto& p : t.problems)
    rig_problem |= p.find("'training_camera_2' absent from sensors.txt") != std::string::npos;
  EXPECT_TRUE(rig_problem);  // the rig lists 6 cameras, sensors.txt has 2
}

}  // namespace
}  // namespace locforge::kapture

namespace locforge::kapture {
namespace {

// kapture 1.0 kept a single feature type directly in reconstruction/<kind>/
// and observations without a keypoints type column.
TEST(KaptureLegacy, Reads10LayoutAndCopyKeepsIt) {
  const fs::path root = locforge::testing::MakeTempDir("kapture_v10") / "k";
  WriteFileAtomic(root / layout::kSensors, "# kapture format: 1.0\ncam, , camera, SIMPLE_PINHOLE, 64, 48, 50, 32, 24\n");
  WriteFileAtomic(root / layout::RecordsFile("camera"), "# kapture format: 1.0\n1, cam, a.jpg\n2, cam, sub/b.jpg\n");
  WriteFileAtomic(root / "reconstruction/keypoints/keypoints.txt", "# kapture format: 1.0\nsift, float32, 2\n");
  WriteFileAtomic(root / "reconstruction/descriptors/descriptors.txt", "# kapture format: 1.0\nsift, uint8, 4\n");
  WriteFeatureFile(root / "reconstruction/keypoints/a.jpg.kpt",
                   FeatureArray::From(DType::kFloat32, 2, std::vector<float>{1, 2, 3, 4}));
  WriteFeatureFile(root / "reconstruction/keypoints/sub/b.jpg.kpt",
                   FeatureArray::From(DType::kFloat32, 2, std::vector<float>{5, 6}));
  WriteFeatureFile(root / "reconstruction/descriptors/a.jpg.desc",
                   FeatureArray::From(DType::kUint8, 4, std::vector<uint8_t>{1, 2, 3, 4, 5, 6, 7, 8}));
  WriteFeatureFile(root / "reconstruction/matches/a.jpg.overlapping/sub/b.jpg.matches",
                   MatchesToArray({{1, 0, 0.5}}));
  WriteFileAtomic(root / layout::kObservations, "# kapture format: 1.0\n0, a.jpg, 1, sub/b.jpg, 0\n");

  Kapture k(root);
  const FeatureSet& kp = k.GetFeatureSet(FeatureKind::kKeypoints, "sift");
  EXPECT_TRUE(kp.legacy_layout);
  EXPECT_EQ(k.FeatureImages(FeatureKind::kKeypoints, "sift"),
            (std::vector<std::string>{"a.jpg", "sub/b.jpg"}));
  EXPECT_EQ(k.ReadKeypoints("sift", "sub/b.jpg").At(0, 1), 6.0);
  EXPECT_EQ(k.ReadDescriptors("sift", "a.jpg").rows, 2);
  EXPECT_EQ(k.MatchesTypes(), (std::vector<std::string>{"sift"}));
  EXPECT_EQ(k.MatchPairs("sift"),
            (std::vector<std::pair<std::string, std::string>>{{"a.jpg", "sub/b.jpg"}}));
  const auto m = k.ReadMatches("sift", "sub/b.jpg", "a.jpg");
  ASSERT_EQ(m.size(), 1u);
  EXPECT_EQ(m[0].index1, 0.0);  // swapped to the requested order
  EXPECT_EQ(m[0].index2, 1.0);
  ASSERT_EQ(k.observations().size(), 1u);
  EXPECT_EQ(k.observations()[0].keypoints_type, "sift");

  const fs::path dst = root.parent_path() / "copy";
  const CopyReport r = CopyKapture(root, dst);
  EXPECT_EQ(r.binary_files, 4);
  EXPECT_EQ(r.other_files, 0);
  for (const char* rel : {"reconstruction/keypoints/a.jpg.kpt", "reconstruction/keypoints/sub/b.jpg.kpt",
                          "reconstruction/matches/a.jpg.overlapping/sub/b.jpg.matches"})
    EXPECT_EQ(ReadFile(root / rel), ReadFile(dst / rel)) << rel;
  EXPECT_EQ(ReadFile(dst / "reconstruction/descriptors/descriptors.txt"),
            "# kapture format: 1.1\n# name, dtype, dsize, keypoints_type, metric_type\nsift, uint8, 4\n");
  Kapture c(dst);
  EXPECT_EQ(c.observations()[0].keypoints_type, "sift");
  EXPECT_EQ(c.observations()[0].features, k.observations()[0].features);
  fs::remove_all(root.parent_path());
}

}  // namespace
}  // namespace locforge::kapture

namespace locforge::kapture {
namespace {

// Per-item stages share one Kapture across their threads: the first accesses,
// racing, must each see the one complete parse (before the lock, a race read a
// garbage camera model id in a clean-clone run).
TEST(KaptureThreads, FirstAccessesFromManyThreadsSeeOneCompleteParse) {
  const fs::path root = locforge::testing::MakeTempDir("kapture_threads") / "k";
  Sensors sensors;
  Camera cam;
  cam.model = CameraModelId::kPinhole;
  cam.width = 640;
  cam.height = 480;
  cam.params = {500.0, 501.0, 320.0, 240.0};
  constexpr int kCameras = 50, kPoses = 4000;
  for (int c = 0; c < kCameras; ++c) sensors.Add(MakeCameraSensor("cam" + std::to_string(c), "", cam));
  WriteSensors(root / layout::kSensors, sensors);
  Trajectories traj;  // large enough that parsing takes a while: a wide window for a race
  for (int t = 0; t < kPoses; ++t)
    traj.Set(t, "cam" + std::to_string(t % kCameras), Pose(Eigen::Quaterniond(1, 0, 0, 0), Eigen::Vector3d(t, 0, 0)));
  WriteTrajectories(root / layout::kTrajectories, traj);
  constexpr int kThreads = 6;
  for (int round = 0; round < 10; ++round) {
    const Kapture shared(root);
    std::atomic<int> ready{0};
    std::vector<size_t> sensor_counts(kThreads), pose_counts(kThreads);
    std::vector<int> models(kThreads);
    std::vector<std::thread> threads;
    for (int i = 0; i < kThreads; ++i)
      threads.emplace_back([&, i] {
        ++ready;
        while (ready < kThreads) std::this_thread::yield();  // start together
        pose_counts[i] = shared.trajectories().size();
        sensor_counts[i] = shared.sensors().size();
        models[i] = static_cast<int>(shared.sensors().Find("cam" + std::to_string(i))->camera->model);
      });
    for (auto& t : threads) t.join();
    for (int i = 0; i < kThreads; ++i) {
      EXPECT_EQ(pose_counts[i], static_cast<size_t>(kPoses)) << "round " << round << " thread " << i;
      EXPECT_EQ(sensor_counts[i], static_cast<size_t>(kCameras)) << "round " << round << " thread " << i;
      EXPECT_EQ(models[i], static_cast<int>(CameraModelId::kPinhole)) << "round " << round << " thread " << i;
    }
  }
}

TEST(KaptureWriting, BuildsA11DatasetThatReadsBack) {
  const fs::path root = locforge::testing::MakeTempDir("kapture_write") / "k";
  Sensors sensors;
  Camera cam;
  cam.model = CameraModelId::kSimpleRadial;
  cam.width = 640;
  cam.height = 480;
  cam.params = {500.0, 320.0, 240.0, -0.01};
  sensors.Add(MakeCameraSensor("cam", "sim", cam));
  WriteSensors(root / layout::kSensors, sensors);
  Rigs rigs;
  rigs.Add("rig", RigSensor{"cam", Pose(Eigen::Quaterniond(0, 0, 1, 0), Eigen::Vector3d(0, 0, 0.1)),
                            PoseParts::kComplete, std::nullopt});
  WriteRigs(root / layout::kRigs, rigs);
  Trajectories traj;
  traj.Set(10, "rig", Pose(Eigen::Quaterniond(1, 0, 0, 0), Eigen::Vector3d(1, 2, 3)));
  WriteTrajectories(root / layout::kTrajectories, traj);
  WriteRecords<DataRecord>(root / layout::RecordsFile("camera"), RecordKind::kCamera,
                           {{10, "cam", "seq/img 0.png"}, {10, "cam", "seq/img1.png"}});
  FeatureInfo info;
  info.kind = FeatureKind::kKeypoints;
  info.name = "sim";
  info.dtype_name = "float32";
  info.dtype = DType::kFloat32;
  info.dsize = 2;
  WriteFeatureSetInfo(root, "simkp", info);
  WriteImageFeatures(root, "simkp", info, "seq/img1.png",
                     FeatureArray::From(DType::kFloat32, 2, std::vector<float>{10, 20, 30, 40}));
  WriteImageFeatures(root, "simkp", info, "seq/img 0.png",
                     FeatureArray::From(DType::kFloat32, 2, std::vector<float>{1, 2}));
  EXPECT_THROW(WriteImageFeatures(root, "simkp", info, "x.png",
                                  FeatureArray::From(DType::kFloat64, 2, std::vector<double>{1, 2})),
               Error);
  EXPECT_THROW(WriteImageFeatures(root, "simkp", info, "../../x.png",
                                  FeatureArray::From(DType::kFloat32, 2, std::vector<float>{1, 2})),
               InputError);
  // Written in the other order: stored under the smaller name, columns swapped.
  WriteMatches(root, "simkp", "seq/img1.png", "seq/img 0.png", {{1, 0, 0.9}});
  EXPECT_TRUE(fs::exists(root / "reconstruction/matches/simkp/seq/img 0.png.overlapping/seq/img1.png.matches"));
  WritePoints3d(root / layout::kPoints3d, {{1, 2, 3, 255, 128, 0}});
  WriteObservations(root / layout::kObservations, {{0, "simkp", {{"seq/img1.png", 1}, {"seq/img 0.png", 0}}}});

  Kapture k(root);
  EXPECT_EQ(k.sensors().Find("cam")->params,
            (std::vector<std::string>{"SIMPLE_RADIAL", "640", "480", "500.0", "320.0", "240.0", "-0.01"}));
  const auto pose = k.DevicePose(10, "cam");
  ASSERT_TRUE(pose);
  EXPECT_NEAR((pose->t - Eigen::Vector3d(-1, 2, -2.9)).norm(), 0, 1e-12);  // R_y(180) * (1,2,3) + (0,0,0.1)
  EXPECT_EQ(k.ReadDataRecords("camera")[0].path, "seq/img 0.png");
  EXPECT_EQ(k.ReadKeypoints("simkp", "seq/img1.png").At(1, 1), 40.0);
  const auto m = k.ReadMatches("simkp", "seq/img1.png", "seq/img 0.png");
  ASSERT_EQ(m.size(), 1u);
  EXPECT_EQ(m[0].index1, 1.0);
  EXPECT_EQ(m[0].index2, 0.0);
  EXPECT_EQ(k.MatchPairs("simkp")[0].first, "seq/img 0.png");
  EXPECT_EQ(k.points3d()[0].g, 128.0);
  EXPECT_EQ(k.observations()[0].features[1].first, "seq/img 0.png");
  const KaptureSummary s = InspectKapture(root);
  EXPECT_EQ(s.features.at(0).files, 2);
  EXPECT_EQ(s.match_pairs.at("simkp"), 1);
  fs::remove_all(root.parent_path());
}

TEST(KaptureWriting, LocalFeatureInfosOfAnExtractorReadBack) {
  const fs::path root = locforge::testing::MakeTempDir("kapture_local") / "k";
  const LocalFeatureInfos infos =
      MakeLocalFeatureInfos("sift_u8", "SIFT", 4, DType::kUint8, 128, "L2", "RootSIFT");
  WriteLocalFeatureSetInfos(root, "sift_u8", infos);
  std::vector<float> kpts = {10.5f, 20.5f, 1.5f, 0.25f, 30.5f, 40.5f, 2.5f, -1.0f};
  std::vector<uint8_t> descs(2 * 128);
  for (size_t i = 0; i < descs.size(); ++i) descs[i] = static_cast<uint8_t>(i % 251);
  WriteImageLocalFeatures(root, "sift_u8", "a/b.jpg", infos, FeatureArray::From(DType::kFloat32, 4, kpts),
                          FeatureArray::From(DType::kUint8, 128, descs));
  // One keypoint short: refused before anything is written.
  EXPECT_THROW(WriteImageLocalFeatures(root, "sift_u8", "c.jpg", infos,
                                       FeatureArray::From(DType::kFloat32, 4, std::vector<float>(4)),
                                       FeatureArray::From(DType::kUint8, 128, descs)),
               Error);
  EXPECT_FALSE(fs::exists(FeatureFilePath(root, FeatureKind::kKeypoints, "sift_u8", "c.jpg")));

  EXPECT_EQ(ReadFile(root / "reconstruction/keypoints/sift_u8/keypoints.txt"),
            "# kapture format: 1.1\n# name, dtype, dsize\nSIFT, float32, 4\n");
  EXPECT_EQ(ReadFile(root / "reconstruction/descriptors/sift_u8/descriptors.txt"),
            "# kapture format: 1.1\n# name, dtype, dsize, keypoints_type, metric_type\n"
            "RootSIFT, uint8, 128, sift_u8, L2\n");
  Kapture k(root);
  const FeatureSet& d = k.GetFeatureSet(FeatureKind::kDescriptors, "sift_u8");
  EXPECT_EQ(d.info.keypoints_type, "sift_u8");
  EXPECT_EQ(d.info.dtype, DType::kUint8);
  const FeatureArray kr = k.ReadKeypoints("sift_u8", "a/b.jpg");
  ASSERT_EQ(kr.rows, 2);
  EXPECT_EQ(kr.At(1, 3), -1.0);
  const FeatureArray dr = k.ReadDescriptors("sift_u8", "a/b.jpg");
  ASSERT_EQ(dr.rows, 2);
  EXPECT_EQ(dr.bytes, std::vector<uint8_t>(descs.begin(), descs.end()));

  const LocalFeatureInfos f = MakeLocalFeatureInfos("r2d2", "r2d2", 3, DType::kFloat32, 128);
  EXPECT_EQ(f.descriptors.name, "r2d2");
  EXPECT_EQ(f.descriptors.dtype_name, "float32");
  EXPECT_EQ(f.descriptors.metric_type, "L2");
  EXPECT_EQ(f.keypoints.dsize, 3);
  EXPECT_TRUE(f.keypoints.keypoints_type.empty());
  fs::remove_all(root.parent_path());
}

}  // namespace
}  // namespace locforge::kapture
