// MergeCameraKaptures: union of kapture folders (the simulator's query
// splits) and the image filter that splits one ground-truth kapture into map
// and queries.
#include "kapture_merge.h"

#include <gtest/gtest.h>

#include <fstream>
#include <set>

#include "locforge/error.h"
#include "locforge/kapture/kapture.h"
#include "testing.h"

namespace locforge::colmap_stages {
namespace {

namespace kp = locforge::kapture;

void Write(const fs::path& file, const std::string& text) {
  fs::create_directories(file.parent_path());
  std::ofstream(file) << text;
}

// A kapture with one camera and one image per sequence name, each posed.
fs::path MakeKapture(const fs::path& root, const std::vector<std::string>& sequences, int64_t t0) {
  Write(root / "sensors/sensors.txt",
        "# kapture format: 1.1\ncam0, cam, camera, PINHOLE, 64, 48, 50, 50, 32, 24\n");
  std::string records = "# kapture format: 1.1\n", poses = "# kapture format: 1.1\n";
  int64_t t = t0;
  for (const auto& seq : sequences) {
    const std::string path = seq + "/cam0/" + std::to_string(t) + ".jpg";
    records += std::to_string(t) + ", cam0, " + path + "\n";
    poses += std::to_string(t) + ", cam0, 1, 0, 0, 0, " + std::to_string(t - t0) + ", 0, 0\n";
    Write(root / "sensors/records_data" / path, "jpeg bytes of " + path);
    ++t;
  }
  Write(root / "sensors/records_camera.txt", records);
  Write(root / "sensors/trajectories.txt", poses);
  return root;
}

TEST(KaptureMerge, ImageFilterKeepsMatchingImagesAndOnlyTheirPoses) {
  const fs::path dir = locforge::testing::MakeTempDir("lf_merge");
  const fs::path gt = MakeKapture(dir / "gt", {"map_00", "map_01", "val_00", "test_00"}, 100);
  const MergeReport map = MergeCameraKaptures({{gt, ""}}, dir / "map", true, {"map_.*"});
  EXPECT_EQ(map.images, 2);
  EXPECT_EQ(map.poses, 2);
  EXPECT_EQ(map.data_files, 2);
  const MergeReport query = MergeCameraKaptures({{gt, ""}}, dir / "query", true, {"(val|test)_.*"});
  EXPECT_EQ(query.images, 2);
  kp::Kapture q(dir / "query");
  const auto records = q.ReadDataRecords(kp::kSensorCamera);
  ASSERT_EQ(records.size(), 2u);
  EXPECT_EQ(records[0].path, "val_00/cam0/102.jpg");
  EXPECT_EQ(records[1].path, "test_00/cam0/103.jpg");
  // Poses of the kept images only, unchanged.
  ASSERT_NE(q.trajectories().Find(102, "cam0"), nullptr);
  EXPECT_DOUBLE_EQ(q.trajectories().Find(102, "cam0")->t.x(), 2.0);
  EXPECT_EQ(q.trajectories().Find(100, "cam0"), nullptr);
  EXPECT_TRUE(fs::exists(dir / "query/sensors/records_data/test_00/cam0/103.jpg"));
  EXPECT_FALSE(fs::exists(dir / "query/sensors/records_data/map_00"));
  // The filter sees the prefixed path of a sub-folder.
  MakeKapture(dir / "rec/validation", {"val_00"}, 500);
  MakeKapture(dir / "rec/test", {"test_00"}, 600);
  const MergeReport test_only = MergeCameraKaptures(
      {{dir / "rec/validation", "validation"}, {dir / "rec/test", "test"}}, dir / "test_only", false, {"test/.*"});
  EXPECT_EQ(test_only.images, 1);
  EXPECT_EQ(test_only.data_files, 0);
  fs::remove_all(dir);
}

// A sparse map: 1 image in 4 of each camera, and the other 3 as its queries.
TEST(KaptureMerge, SampleEveryPartitionsEachCamerasImages) {
  const fs::path dir = locforge::testing::MakeTempDir("lf_merge");
  std::vector<std::string> sequences;
  for (int i = 0; i < 10; ++i) sequences.push_back("map_0" + std::to_string(i));
  const fs::path gt = MakeKapture(dir / "gt", sequences, 100);  // images at t = 100..109
  ImageSelection sparse;
  sparse.sample_every = 4;
  const MergeReport map = MergeCameraKaptures({{gt, ""}}, dir / "map", true, sparse);
  EXPECT_EQ(map.images, 3);  // t = 100, 104, 108
  EXPECT_EQ(map.poses, 3);
  EXPECT_EQ(map.data_files, 3);
  sparse.sample_rest = true;
  const MergeReport rest = MergeCameraKaptures({{gt, ""}}, dir / "rest", true, sparse);
  EXPECT_EQ(rest.images, 7);
  EXPECT_EQ(rest.poses, 7);
  kp::Kapture m(dir / "map"), q(dir / "rest");
  std::set<int64_t> map_times, rest_times;
  for (const auto& r : m.ReadDataRecords(kp::kSensorCamera)) map_times.insert(r.timestamp);
  for (const auto& r : q.ReadDataRecords(kp::kSensorCamera)) rest_times.insert(r.timestamp);
  EXPECT_EQ(map_times, (std::set<int64_t>{100, 104, 108}));
  EXPECT_EQ(rest_times, (std::set<int64_t>{101, 102, 103, 105, 106, 107, 109}));
  ASSERT_NE(q.trajectories().Find(105, "cam0"), nullptr);
  EXPECT_EQ(q.trajectories().Find(104, "cam0"), nullptr);
  EXPECT_FALSE(fs::exists(dir / "rest/sensors/records_data/map_04"));
  EXPECT_TRUE(fs::exists(dir / "rest/sensors/records_data/map_05/cam0/105.jpg"));
  // The sampling applies to the images the regex kept.
  ImageSelection odd{"map_0[13579]/.*", 2, false};
  EXPECT_EQ(MergeCameraKaptures({{gt, ""}}, dir / "odd", false, odd).images, 3);  // 101, 105, 109
  EXPECT_THROW(MergeCameraKaptures({{gt, ""}}, dir / "bad", false, {"", 0, false}), ParamError);
  fs::remove_all(dir);
}

TEST(KaptureMerge, BadRegexIsAParamError) {
  const fs::path dir = locforge::testing::MakeTempDir("lf_merge");
  const fs::path gt = MakeKapture(dir / "gt", {"map_00"}, 100);
  EXPECT_THROW(MergeCameraKaptures({{gt, ""}}, dir / "out", false, {"(map_"}), ParamError);
  fs::remove_all(dir);
}

TEST(KaptureMerge, SameImagePathFromTwoSourcesNamesTheSource) {
  const fs::path dir = locforge::testing::MakeTempDir("lf_merge");
  const fs::path a = MakeKapture(dir / "a", {"map_00"}, 100);
  const fs::path b = MakeKapture(dir / "b", {"map_00"}, 100);
  try {
    MergeCameraKaptures({{a, ""}, {b, ""}}, dir / "out", false);
    FAIL() << "a duplicate image path was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find((b / "sensors/records_camera.txt").string()), std::string::npos) << e.what();
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace locforge::colmap_stages
