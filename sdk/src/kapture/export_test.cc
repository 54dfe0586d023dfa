// ExportKapture: partial kaptures (a dataset, features, matches, a
// reconstruction, as workspace nodes hold them) merged into one that reads
// back whole; disagreements refused without touching the destination.
#include <gtest/gtest.h>

#include "locforge/error.h"
#include "locforge/kapture/kapture.h"
#include "testing.h"

namespace locforge::kapture {
namespace {

Sensor TestCamera(double focal) {
  Camera cam;
  cam.model = CameraModelId::kSimplePinhole;
  cam.width = 64;
  cam.height = 48;
  cam.params = {focal, 32.0, 24.0};
  return MakeCameraSensor("cam", "test", cam);
}

// dataset/: sensors, trajectories, two camera records and their images;
// features/: keypoints of both; matches/: one pair; mapper/: points3d and
// observations. Each a partial kapture, like a workspace node's folder.
struct Nodes {
  fs::path root, dataset, features, matches, mapper;
};

Nodes MakeNodes(const std::string& name) {
  Nodes n;
  n.root = locforge::testing::MakeTempDir(name);
  n.dataset = n.root / "dataset";
  n.features = n.root / "features";
  n.matches = n.root / "matches";
  n.mapper = n.root / "mapper";
  Sensors sensors;
  sensors.Add(TestCamera(50));
  WriteSensors(n.dataset / layout::kSensors, sensors);
  Trajectories traj;
  traj.Set(1, "cam", Pose(Eigen::Quaterniond(1, 0, 0, 0), Eigen::Vector3d(0, 0, 0)));
  traj.Set(2, "cam", Pose(Eigen::Quaterniond(1, 0, 0, 0), Eigen::Vector3d(1, 0, 0)));
  WriteTrajectories(n.dataset / layout::kTrajectories, traj);
  WriteRecords<DataRecord>(n.dataset / layout::RecordsFile("camera"), RecordKind::kCamera,
                           {{1, "cam", "seq/a.png"}, {2, "cam", "seq/b.png"}});
  WriteFileAtomic(n.dataset / layout::kRecordsData / "seq/a.png", "image a");
  WriteFileAtomic(n.dataset / layout::kRecordsData / "seq/b.png", "image b");
  const LocalFeatureInfos infos = MakeLocalFeatureInfos("kp", "test", 2, DType::kUint8, 4);
  WriteLocalFeatureSetInfos(n.features, "kp", infos);
  WriteImageLocalFeatures(n.features, "kp", "seq/a.png", infos,
                          FeatureArray::From(DType::kFloat32, 2, std::vector<float>{1, 2, 3, 4}),
                          FeatureArray::From(DType::kUint8, 4, std::vector<uint8_t>(8, 7)));
  WriteImageLocalFeatures(n.features, "kp", "seq/b.png", infos,
                          FeatureArray::From(DType::kFloat32, 2, std::vector<float>{5, 6}),
                          FeatureArray::From(DType::kUint8, 4, std::vector<uint8_t>(4, 9)));
  WriteMatches(n.matches, "kp", "seq/a.png", "seq/b.png", {{1, 0, 0.5}});
  WritePoints3d(n.mapper / layout::kPoints3d, {{1, 2, 3, 10, 20, 30}});
  WriteObservations(n.mapper / layout::kObservations, {{0, "kp", {{"seq/a.png", 1}, {"seq/b.png", 0}}}});
  return n;
}

std::vector<ExportSource> Sources(const Nodes& n) {
  return {{"dataset", n.dataset}, {"features", n.features}, {"matches", n.matches}, {"mapper", n.mapper}};
}

TEST(ExportKapture, MergesPartialKapturesIntoOneThatReadsBackWhole) {
  const Nodes n = MakeNodes("export_merge");
  const fs::path out = n.root / "out";
  const ExportReport r = ExportKapture(Sources(n), out);
  EXPECT_EQ(r.sensors, 1);
  EXPECT_EQ(r.trajectory_poses, 2);
  EXPECT_EQ(r.records.at("camera"), 2);
  EXPECT_EQ(r.data_files, 2);
  EXPECT_EQ(r.feature_files.at("keypoints/kp"), 2);
  EXPECT_EQ(r.feature_files.at("descriptors/kp"), 2);
  EXPECT_EQ(r.match_pairs.at("kp"), 1);
  EXPECT_EQ(r.points3d, 1);

  EXPECT_EQ(ReadFile(out / layout::kSensors).rfind("# kapture format: 1.1\n", 0), 0u);
  const KaptureSummary s = InspectKapture(out);
  EXPECT_TRUE(s.problems.empty()) << FormatSummary(s);
  const Kapture k(out);
  EXPECT_EQ(k.CameraImages(), (std::vector<std::string>{"seq/a.png", "seq/b.png"}));
  EXPECT_EQ(k.FeatureImages(FeatureKind::kKeypoints, "kp").size(), 2u);
  EXPECT_EQ(k.MatchPairs("kp").size(), 1u);
  EXPECT_EQ(k.points3d().size(), 1u);
  EXPECT_EQ(k.observations().size(), 1u);
  for (const char* image : {"seq/a.png", "seq/b.png"})
    for (FeatureKind kind : {FeatureKind::kKeypoints, FeatureKind::kDescriptors})
      EXPECT_EQ(ReadFile(FeatureFilePath(out, kind, "kp", image)),
                ReadFile(FeatureFilePath(n.features, kind, "kp", image)))
          << image;
  // Record files are links to the node's files, unless copied.
  const fs::path a = out / layout::kRecordsData / "seq/a.png";
  EXPECT_TRUE(fs::is_symlink(a));
  EXPECT_EQ(fs::read_symlink(a), fs::canonical(n.dataset / layout::kRecordsData / "seq/a.png"));
  EXPECT_EQ(ReadFile(a), "image a");
  ExportOptions copy;
  copy.link_records_data = false;
  ExportKapture(Sources(n), n.root / "copied", copy);
  EXPECT_FALSE(fs::is_symlink(n.root / "copied" / layout::kRecordsData / "seq/a.png"));
  EXPECT_EQ(ReadFile(n.root / "copied" / layout::kRecordsData / "seq/a.png"), "image a");
  fs::remove_all(n.root);
}

TEST(ExportKapture, SameFilesFromTwoNodesAreKeptOnce) {
  const Nodes n = MakeNodes("export_same");
  std::vector<ExportSource> sources = Sources(n);
  fs::copy(n.features, n.root / "features2", fs::copy_options::recursive);
  sources.push_back({"features2", n.root / "features2"});
  const ExportReport r = ExportKapture(sources, n.root / "out");
  EXPECT_EQ(r.feature_files.at("keypoints/kp"), 2);
  fs::remove_all(n.root);
}

TEST(ExportKapture, RefusesNodesThatDisagreeAndLeavesNoOutput) {
  const Nodes n = MakeNodes("export_conflict");
  const fs::path other = n.root / "other";
  Sensors sensors;
  sensors.Add(TestCamera(60));
  WriteSensors(other / layout::kSensors, sensors);
  std::vector<ExportSource> sources = Sources(n);
  sources.push_back({"other", other});
  const fs::path out = n.root / "out";
  try {
    ExportKapture(sources, out);
    ADD_FAILURE() << "two cameras 'cam' accepted";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("other/sensors/sensors.txt"), std::string::npos) << what;
    EXPECT_NE(what.find("field 'cam'"), std::string::npos) << what;
    EXPECT_NE(what.find("'dataset' and 'other'"), std::string::npos) << what;
  }
  EXPECT_FALSE(fs::exists(out));
  // A keypoints file of the same image with other values.
  const fs::path features2 = n.root / "features2";
  fs::copy(n.features, features2, fs::copy_options::recursive);
  WriteFeatureFile(FeatureFilePath(features2, FeatureKind::kKeypoints, "kp", "seq/b.png"),
                   FeatureArray::From(DType::kFloat32, 2, std::vector<float>{5, 7}));
  sources.back() = {"features2", features2};
  try {
    ExportKapture(sources, out);
    ADD_FAILURE() << "two keypoints files of seq/b.png accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("reconstruction/keypoints/kp/seq/b.png.kpt"), std::string::npos)
        << e.what();
  }
  EXPECT_FALSE(fs::exists(out));
  for (const auto& entry : fs::directory_iterator(n.root))
    EXPECT_EQ(entry.path().filename().string().find("out"), std::string::npos) << entry.path();
  fs::remove_all(n.root);
}

TEST(ExportKapture, RefusesANonEmptyDestinationUnlessOverwrite) {
  const Nodes n = MakeNodes("export_dest");
  const fs::path out = n.root / "out";
  WriteFileAtomic(out / "keep.txt", "mine");
  EXPECT_THROW(ExportKapture(Sources(n), out), InputError);
  EXPECT_EQ(ReadFile(out / "keep.txt"), "mine");
  ExportOptions overwrite;
  overwrite.overwrite = true;
  ExportKapture(Sources(n), out, overwrite);
  EXPECT_FALSE(fs::exists(out / "keep.txt"));
  EXPECT_TRUE(fs::exists(out / layout::kPoints3d));
  // Inside a source: refused.
  EXPECT_THROW(ExportKapture(Sources(n), n.dataset / "out"), InputError);
  // A folder without any kapture file.
  fs::create_directories(n.root / "empty");
  std::vector<ExportSource> sources = Sources(n);
  sources.push_back({"empty", n.root / "empty"});
  EXPECT_THROW(ExportKapture(sources, n.root / "out2", overwrite), InputError);
  fs::remove_all(n.root);
}

TEST(ExportKapture, ChosenTrajectoriesOnly) {
  const Nodes n = MakeNodes("export_traj");
  const fs::path estimate = n.root / "estimate";
  Trajectories traj;
  traj.Set(2, "cam", Pose(Eigen::Quaterniond(1, 0, 0, 0), Eigen::Vector3d(1.5, 0, 0)));
  WriteTrajectories(estimate / layout::kTrajectories, traj);
  std::vector<ExportSource> sources = Sources(n);
  sources.push_back({"estimate", estimate});
  EXPECT_THROW(ExportKapture(sources, n.root / "out"), InputError);  // two poses at (2, cam)
  ExportOptions options;
  options.trajectories_from = "estimate";
  ExportKapture(sources, n.root / "out", options);
  const Kapture k(n.root / "out");
  ASSERT_EQ(k.trajectories().size(), 1u);
  EXPECT_EQ(k.trajectories().Find(2, "cam")->t.x(), 1.5);
  options.trajectories_from = "nobody";
  EXPECT_THROW(ExportKapture(sources, n.root / "out3", options), ParamError);
  fs::remove_all(n.root);
}

}  // namespace
}  // namespace locforge::kapture
