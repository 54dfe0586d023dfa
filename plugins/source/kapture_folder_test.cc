// source/kapture_folder on a dataset as kapture's importers make it:
// records_data of symbolic links (link_absolute and link_relative), brought
// into a graph whole, filtered by an image regex, and wired from another node.
#include <gtest/gtest.h>

#include "locforge/fs.h"
#include "locforge/kapture/kapture.h"
#include "locforge/runtime/registry.h"
#include "locforge/testkit.h"
#include "testing.h"

namespace locforge {
namespace {

namespace kp = locforge::kapture;

class LinkedKapture : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = testing::MakeTempDir("kapture_folder_links");
    // The original images, somewhere else on the disk.
    WriteFileAtomic(dir_ / "originals/map_00/cam0/100.jpg", "image 100");
    WriteFileAtomic(dir_ / "originals/val_00/cam0/101.jpg", "image 101");
    root_ = dir_ / "imported";
    WriteFileAtomic(root_ / kp::layout::kSensors,
                    "# kapture format: 1.1\ncam0, cam, camera, PINHOLE, 64, 48, 50, 50, 32, 24\n");
    WriteFileAtomic(root_ / kp::layout::kTrajectories,
                    "# kapture format: 1.1\n100, cam0, 1, 0, 0, 0, 0, 0, 0\n101, cam0, 1, 0, 0, 0, 1, 0, 0\n");
    WriteFileAtomic(root_ / kp::layout::RecordsFile("camera"),
                    "# kapture format: 1.1\n100, cam0, map_00/cam0/100.jpg\n101, cam0, val_00/cam0/101.jpg\n");
    const fs::path data = root_ / kp::layout::kRecordsData;
    fs::create_directories(data / "map_00/cam0");
    fs::create_directories(data / "val_00/cam0");
    // --image_transfer link_absolute, then link_relative.
    fs::create_symlink(dir_ / "originals/map_00/cam0/100.jpg", data / "map_00/cam0/100.jpg");
    fs::create_symlink("../../../../../originals/val_00/cam0/101.jpg", data / "val_00/cam0/101.jpg");
    ASSERT_EQ(ReadFile(data / "val_00/cam0/101.jpg"), "image 101");
    ASSERT_TRUE(registry_.LoadFile(LOCFORGE_SOURCE_PLUGIN_FILE));
  }
  void TearDown() override { fs::remove_all(dir_); }

  fs::path dir_, root_;
  runtime::Registry registry_;
};

TEST_F(LinkedKapture, WholeDatasetAndImageFilterFollowTheOwnersLinks) {
  testkit::RunStage(registry_, "source/kapture_folder", {{"path", root_.string()}}, {}, dir_ / "whole");
  const kp::Kapture whole(dir_ / "whole");
  EXPECT_EQ(whole.ReadDataRecords("camera").size(), 2u);
  EXPECT_EQ(ReadFile(whole.ExistingRecordDataPath("map_00/cam0/100.jpg")), "image 100");
  EXPECT_EQ(ReadFile(whole.ExistingRecordDataPath("val_00/cam0/101.jpg")), "image 101");

  // The merge path (image regex) links or copies the files the links name:
  // a hard link to the relative link itself would dangle in its new folder.
  testkit::RunStage(registry_, "source/kapture_folder", {{"path", root_.string()}, {"images", "val_.*"}}, {},
                    dir_ / "queries");
  const kp::Kapture queries(dir_ / "queries");
  ASSERT_EQ(queries.ReadDataRecords("camera").size(), 1u);
  EXPECT_EQ(ReadFile(queries.ExistingRecordDataPath("val_00/cam0/101.jpg")), "image 101");
  EXPECT_EQ(queries.trajectories().size(), 1u);

  // The same dataset wired as the kapture input instead of the path.
  testkit::RunStage(registry_, "source/kapture_folder", {{"images", "map_.*"}},
                    {{"kapture", "kapture.dataset", root_}}, dir_ / "map");
  EXPECT_EQ(ReadFile(kp::Kapture(dir_ / "map").ExistingRecordDataPath("map_00/cam0/100.jpg")), "image 100");
}

TEST_F(LinkedKapture, LexicalEscapesAndMissingSourceAreRefused) {
  WriteFileAtomic(root_ / kp::layout::RecordsFile("camera"),
                  "# kapture format: 1.1\n100, cam0, map_00/../../../originals/map_00/cam0/100.jpg\n");
  try {
    testkit::RunStage(registry_, "source/kapture_folder", {{"path", root_.string()}}, {}, dir_ / "out");
    ADD_FAILURE() << "a record path climbing out of records_data was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("escapes the dataset root"), std::string::npos) << e.what();
  }
  try {
    testkit::RunStage(registry_, "source/kapture_folder", {}, {}, dir_ / "none");
    ADD_FAILURE() << "no path and no input accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("set the path parameter"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace locforge
