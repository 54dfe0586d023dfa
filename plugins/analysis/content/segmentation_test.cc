// Person masks from a probability map, their agreement with a reference,
// and analysis/person_segmentation end to end on a generated ONNX model
// (testdata/segmentation_model.py: probability = sigmoid(5 x red)) feeding
// analysis/image_content's crowdedness.
#include "segmentation.h"

#include <gtest/gtest.h>

#include <fstream>
#include <opencv2/imgcodecs.hpp>

#include "locforge/runtime/registry.h"
#include "locforge/testkit.h"
#include "testing.h"

namespace locforge::analysis {
namespace {

namespace fs = std::filesystem;

TEST(Segmentation, ProbabilitiesResizeAndThreshold) {
  cv::Mat p(2, 4, CV_32F, cv::Scalar(0.f));
  p.colRange(0, 2).setTo(1.f);
  const cv::Mat mask = PersonMask(p, cv::Size(40, 20), 0.5);
  ASSERT_EQ(mask.size(), cv::Size(40, 20));
  EXPECT_EQ(mask.type(), CV_8U);
  EXPECT_EQ(cv::countNonZero(mask), 20 * 20);  // the left half, split at the cells' boundary
  EXPECT_EQ(mask.at<uchar>(10, 5), 255);
  EXPECT_EQ(mask.at<uchar>(10, 35), 0);
  EXPECT_THROW(PersonMask(cv::Mat(2, 2, CV_8U), cv::Size(4, 4), 0.5), std::invalid_argument);
}

TEST(Segmentation, IouAndCrowdednessOfTwoMasks) {
  cv::Mat e(10, 10, CV_8U, cv::Scalar(0)), r(10, 10, CV_8U, cv::Scalar(0));
  e.rowRange(0, 4).setTo(255);  // 40 px
  r.rowRange(2, 6).setTo(255);  // 40 px, 20 shared
  MaskAgreement a = CompareMasks(e, r);
  EXPECT_DOUBLE_EQ(a.iou, 20.0 / 60.0);
  EXPECT_DOUBLE_EQ(a.estimated_percent, 40);
  EXPECT_DOUBLE_EQ(a.reference_percent, 40);
  a = CompareMasks(cv::Mat(10, 10, CV_8U, cv::Scalar(0)), cv::Mat(10, 10, CV_8U, cv::Scalar(0)));
  EXPECT_DOUBLE_EQ(a.iou, 1.0);  // no people in either
  EXPECT_THROW(CompareMasks(e, cv::Mat(5, 5, CV_8U)), std::invalid_argument);
}

TEST(Segmentation, StageOnAGeneratedModelAgreesWithTheTrueMaskAndFeedsCrowdedness) {
  if (std::string(LOCFORGE_ONNX_PYTHON).empty()) {
    if (locforge::testing::SharedRequired()) FAIL() << "no python3 with onnx (python3-onnx) and LOCFORGE_REQUIRE_SHARED=1";
    GTEST_SKIP() << "no python3 with onnx: install python3-onnx to generate the test model";
  }
  const fs::path dir = locforge::testing::MakeTempDir("person_segmentation");
  const std::string command = std::string(LOCFORGE_ONNX_PYTHON) + " " + LOCFORGE_SEGMENTATION_MODEL_SCRIPT + " " +
                              (dir / "segmentation.onnx").string();
  ASSERT_EQ(std::system(command.c_str()), 0) << command;
  // A recording-like folder: one 64x48 query, its left half red (a "person"),
  // and a true mask of the left 30 columns.
  const fs::path rec = dir / "recording";
  fs::create_directories(rec / "sensors/records_data/validation");
  std::ofstream(rec / "sensors/sensors.txt") << "# kapture format: 1.1\ncam, , camera, PINHOLE, 64, 48, 50, 50, 32, 24\n";
  std::ofstream(rec / "sensors/records_camera.txt") << "# kapture format: 1.1\n0, cam, validation/q.png\n";
  cv::Mat image(48, 64, CV_8UC3, cv::Scalar(255, 0, 0));             // BGR: blue
  image.colRange(0, 32).setTo(cv::Scalar(0, 0, 255));                // red
  ASSERT_TRUE(cv::imwrite((rec / "sensors/records_data/validation/q.png").string(), image));
  cv::Mat truth(48, 64, CV_8U, cv::Scalar(0));
  truth.colRange(0, 30).setTo(255);
  fs::create_directories(rec / "truth/masks/validation");
  ASSERT_TRUE(cv::imwrite((rec / "truth/masks/validation/q.png").string(), truth));

  runtime::Registry registry;
  ASSERT_TRUE(registry.LoadFile(LOCFORGE_ANALYSIS_PLUGIN_FILE));
  const runtime::InputArtifact images{"images", "kapture.dataset", rec};
  testkit::RunStage(registry, "analysis/person_segmentation",
                    {{"model", (dir / "segmentation.onnx").string()}, {"width", "64"}, {"height", "48"}},
                    {images, {"recording", "kapture.dataset", rec}}, dir / "seg");
  const auto rows = locforge::testing::ReadCsv(dir / "seg/segmentation.csv");
  ASSERT_EQ(rows.size(), 2u);
  EXPECT_NEAR(std::stod(rows[1][1]), 50.0, 2.0);               // estimated crowdedness
  EXPECT_NEAR(std::stod(rows[1][2]), 100.0 * 30 / 64, 1e-9);   // true crowdedness
  EXPECT_NEAR(std::stod(rows[1][3]), 30.0 / 32.0, 0.03);       // IoU
  EXPECT_NE(locforge::testing::ReadText(dir / "seg/segmentation.md").find("mean IoU"), std::string::npos);
  // The estimated masks as analysis/image_content's source of crowdedness.
  testkit::RunStage(registry, "analysis/image_content", {}, {images, {"masks", "person.masks", dir / "seg"}},
                    dir / "content");
  const auto content = locforge::testing::ReadCsv(dir / "content/content.csv");
  ASSERT_EQ(content.size(), 2u);
  EXPECT_NEAR(std::stod(content[1][4]), 50.0, 2.0);
  EXPECT_EQ(content[1][5], "1");  // crowded: >= 20 %
  // Two sources of masks at once are refused.
  EXPECT_THROW(testkit::RunStage(registry, "analysis/image_content", {},
                                 {images, {"masks", "person.masks", dir / "seg"}, {"recording", "kapture.dataset", rec}},
                                 dir / "both"),
               std::exception);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace locforge::analysis
