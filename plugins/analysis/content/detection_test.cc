// Person detection: the cfg's geometry, the network input, decoding, NMS,
// the covered share, the persons file and the correlations on hand-made
// values; then analysis/person_detection with the real Yolo-Fastest body
// detector (../shared/models/yolo_fastest_body) on real photographs of the
// Debian package darknet (cmake/debian-packages.txt), against what we see in
// them; analysis/image_content and analysis/crowdedness_agreement on its output.
#include "detection.h"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <opencv2/imgcodecs.hpp>

#include "locforge/error.h"
#include "locforge/params.h"
#include "locforge/runtime/registry.h"
#include "locforge/testkit.h"
#include "testing.h"

namespace locforge::analysis {
namespace {

namespace fs = std::filesystem;

PersonBox Box(double x, double y, double w, double h, double score = 1) { return {x, y, w, h, score}; }

TEST(Detection, ReadsTheNetSectionOfADarknetCfg) {
  const fs::path dir = locforge::testing::MakeTempDir("darknet_cfg");
  std::ofstream(dir / "a.cfg") << "[net]\n# training\nbatch=32\nwidth = 416\nheight=288  # comment\n"
                               << "letter_box=1\n\n[convolutional]\nwidth=7\n";
  DarknetInput in = ReadDarknetInput(dir / "a.cfg");
  EXPECT_EQ(in.width, 416);
  EXPECT_EQ(in.height, 288);  // the [convolutional] section's keys are not the input's
  EXPECT_TRUE(in.letter_box);
  std::ofstream(dir / "b.cfg") << "[net]\nwidth=320\nheight=320\n[yolo]\n";
  EXPECT_FALSE(ReadDarknetInput(dir / "b.cfg").letter_box);  // Darknet's default: plain resize
  std::ofstream(dir / "c.cfg") << "[net]\nwidth=320\n";
  try {
    ReadDarknetInput(dir / "c.cfg");
    FAIL() << "no height accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("height"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("c.cfg"), std::string::npos) << e.what();
  }
  std::ofstream(dir / "d.cfg") << "[net]\nwidth=300\nheight=320\n";
  EXPECT_THROW(ReadDarknetInput(dir / "d.cfg"), InputError);  // not a multiple of 32
  std::ofstream(dir / "e.cfg") << "[convolutional]\nwidth=320\n";
  EXPECT_THROW(ReadDarknetInput(dir / "e.cfg"), InputError);
  fs::remove_all(dir);
}

TEST(Detection, BlobIsResizedOrLetterboxedRgbOver255) {
  cv::Mat rgb(50, 100, CV_8UC3, cv::Scalar(255, 0, 51));  // R=255, G=0, B=51
  DarknetInput in{64, 64, false};
  cv::Mat blob = DarknetBlob(rgb, in);
  ASSERT_EQ(blob.dims, 4);
  EXPECT_EQ(blob.size[1], 3);
  EXPECT_EQ(blob.size[2], 64);
  EXPECT_EQ(blob.size[3], 64);
  EXPECT_FLOAT_EQ(blob.ptr<float>(0, 0)[0], 1.0f);  // plain resize: the image everywhere
  EXPECT_FLOAT_EQ(blob.ptr<float>(0, 2)[0], 0.2f);
  in.letter_box = true;  // 100x50 -> 64x32, centred: rows 16..47, grey 0.5 above and below
  blob = DarknetBlob(rgb, in);
  EXPECT_FLOAT_EQ(blob.ptr<float>(0, 0)[0], 0.5f);
  EXPECT_FLOAT_EQ(blob.ptr<float>(0, 0)[15 * 64 + 10], 0.5f);
  EXPECT_FLOAT_EQ(blob.ptr<float>(0, 0)[16 * 64 + 10], 1.0f);
  EXPECT_FLOAT_EQ(blob.ptr<float>(0, 0)[47 * 64 + 10], 1.0f);
  EXPECT_FLOAT_EQ(blob.ptr<float>(0, 0)[48 * 64 + 10], 0.5f);
}

TEST(Detection, DecodesRowsToImagePixelsAboveTheThreshold) {
  // Rows: cx, cy, w, h (of the network input), objectness, person score.
  cv::Mat rows = (cv::Mat_<float>(3, 6) << 0.5f, 0.5f, 0.2f, 0.4f, 0.9f, 0.9f,  // kept
                  0.1f, 0.1f, 0.1f, 0.1f, 0.3f, 0.24f,                              // under 0.25
                  0.95f, 0.5f, 0.2f, 0.2f, 0.8f, 0.8f);                             // clipped at the right edge
  const DarknetInput resized{320, 320, false};
  std::vector<PersonBox> boxes = DecodeYoloRows({rows}, cv::Size(200, 100), resized, DetectionOptions{});
  ASSERT_EQ(boxes.size(), 2u);
  EXPECT_NEAR(boxes[0].x, 80, 1e-4);  // centre 100, width 40
  EXPECT_NEAR(boxes[0].y, 30, 1e-4);  // centre 50, height 40
  EXPECT_NEAR(boxes[0].width, 40, 1e-4);
  EXPECT_NEAR(boxes[0].height, 40, 1e-4);
  EXPECT_NEAR(boxes[0].score, 0.9, 1e-6);
  EXPECT_NEAR(boxes[1].x, 170, 1e-4);
  EXPECT_NEAR(boxes[1].width, 30, 1e-4);  // 170..210 clipped to 200
  // Letterboxed 200x100 in 320x320: the image spans rows 80..239 of the input
  // (0.25..0.75); a box at input (0.5, 0.5) of height 0.25 is the image's
  // centre, half its height.
  const DarknetInput letterboxed{320, 320, true};
  boxes = DecodeYoloRows({rows.rowRange(0, 1)}, cv::Size(200, 100), letterboxed, DetectionOptions{});
  ASSERT_EQ(boxes.size(), 1u);
  EXPECT_NEAR(boxes[0].x + boxes[0].width / 2, 100, 1e-4);
  EXPECT_NEAR(boxes[0].y + boxes[0].height / 2, 50, 1e-4);
  EXPECT_NEAR(boxes[0].height, 80, 1e-4);  // 0.4 of the input = 0.8 of the image's extent
  EXPECT_NEAR(boxes[0].width, 40, 1e-4);
  DetectionOptions other_class;
  other_class.person_class = 1;  // the rows have one class only
  EXPECT_THROW(DecodeYoloRows({rows}, cv::Size(200, 100), resized, other_class), std::invalid_argument);
}

TEST(Detection, GreedyNmsDropsOverlapsAboveTheIou) {
  // IoU of a 10x10 box and the same shifted by 2: 80 / 120 = 0.67; by 6: 40 / 160 = 0.25.
  EXPECT_NEAR(BoxIou(Box(0, 0, 10, 10), Box(2, 0, 10, 10)), 80.0 / 120.0, 1e-12);
  EXPECT_NEAR(BoxIou(Box(0, 0, 10, 10), Box(6, 0, 10, 10)), 0.25, 1e-12);
  EXPECT_EQ(BoxIou(Box(0, 0, 10, 10), Box(10, 0, 10, 10)), 0.0);
  const std::vector<PersonBox> kept =
      NonMaximumSuppression({Box(2, 0, 10, 10, 0.6), Box(0, 0, 10, 10, 0.9), Box(6, 0, 10, 10, 0.5)}, 0.45);
  ASSERT_EQ(kept.size(), 2u);  // the 0.6 box overlaps the best by 0.67 > 0.45; the 0.5 one by 0.25 only
  EXPECT_EQ(kept[0].score, 0.9);
  EXPECT_EQ(kept[1].score, 0.5);
  EXPECT_EQ(NonMaximumSuppression({Box(2, 0, 10, 10, 0.6), Box(0, 0, 10, 10, 0.9)}, 0.7).size(), 2u);
}

TEST(Detection, CoveredShareIsTheAreaOfTheUnion) {
  const cv::Size image(100, 50);  // 5000 px
  EXPECT_EQ(CoveredPercent({}, image), 0.0);
  EXPECT_NEAR(CoveredPercent({Box(0, 0, 10, 10)}, image), 2.0, 1e-12);
  // Two 10x10 boxes sharing 5x10: 150 px, not 200.
  EXPECT_NEAR(CoveredPercent({Box(0, 0, 10, 10), Box(5, 0, 10, 10)}, image), 3.0, 1e-12);
  // A box inside another counts nothing; a box half outside counts its inside half.
  EXPECT_NEAR(CoveredPercent({Box(0, 0, 20, 20), Box(5, 5, 5, 5), Box(95, 40, 10, 20)}, image),
              100.0 * (400 + 50) / 5000, 1e-12);
  EXPECT_NEAR(CoveredPercent({Box(-10, -10, 200, 200)}, image), 100.0, 1e-12);
  // Three boxes in an L and a cross: 10x30 + 30x10 sharing 10x10 = 500 px.
  EXPECT_NEAR(CoveredPercent({Box(10, 0, 10, 30), Box(0, 10, 30, 10), Box(10, 10, 10, 10)}, image), 10.0, 1e-12);
}

TEST(Detection, PersonsFileRoundTripsAndRefusesMalformedFiles) {
  Persons p;
  p.boxes = {Box(1.5, 2, 30, 60, 0.875), Box(100, 20, 10, 25, 0.5)};
  p.covered_percent = 12.25;
  const Persons back = ParsePersons(FormatPersons(p), "x.txt");
  ASSERT_EQ(back.boxes.size(), 2u);
  EXPECT_EQ(back.covered_percent, 12.25);
  EXPECT_EQ(back.boxes[0].x, 1.5);
  EXPECT_EQ(back.boxes[1].height, 25);
  EXPECT_EQ(back.boxes[0].score, 0.875);
  EXPECT_EQ(FormatPersons(Persons{}), "0 0\n");
  EXPECT_THROW(ParsePersons("", "x.txt"), InputError);
  EXPECT_THROW(ParsePersons("2 1.0\n0 0 5 5 0.9\n", "x.txt"), InputError);      // count disagrees
  EXPECT_THROW(ParsePersons("1 1.0\n0 0 5 0.9\n", "x.txt"), InputError);        // short box
  EXPECT_THROW(ParsePersons("1 101\n0 0 5 5 0.9\n", "x.txt"), InputError);      // > 100 %
  try {
    ParsePersons("1 1.0\n0 0 -5 5 0.9\n", "y.txt");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("y.txt"), std::string::npos) << e.what();
  }
}

TEST(Detection, PearsonAndSpearmanOfKnownSamples) {
  EXPECT_NEAR(PearsonCorrelation({1, 2, 3, 4}, {2, 4, 6, 8}), 1.0, 1e-12);
  EXPECT_NEAR(PearsonCorrelation({1, 2, 3, 4}, {8, 6, 4, 2}), -1.0, 1e-12);
  // x = 1..5, y = x^2: Pearson 0.981 (computed by hand: sxy 60, sxx 10, syy 374), Spearman 1.
  EXPECT_NEAR(PearsonCorrelation({1, 2, 3, 4, 5}, {1, 4, 9, 16, 25}), 60 / std::sqrt(10 * 374.0), 1e-12);
  EXPECT_NEAR(SpearmanCorrelation({1, 2, 3, 4, 5}, {1, 4, 9, 16, 25}), 1.0, 1e-12);
  // Ties share their mean rank: x ranks 1.5 1.5 3 4, y ranks 1 2 3 4.
  EXPECT_NEAR(SpearmanCorrelation({0, 0, 1, 2}, {0, 1, 2, 3}), PearsonCorrelation({1.5, 1.5, 3, 4}, {1, 2, 3, 4}), 1e-12);
  EXPECT_TRUE(std::isnan(PearsonCorrelation({1, 1, 1}, {1, 2, 3})));
  EXPECT_TRUE(std::isnan(SpearmanCorrelation({1}, {1})));
}

// A kapture of the given photographs (copied), one camera per size.
fs::path PhotoKapture(const fs::path& dir, const std::vector<fs::path>& photos) {
  const fs::path root = dir / "photos";
  fs::create_directories(root / "sensors/records_data");
  std::ofstream sensors(root / "sensors/sensors.txt"), records(root / "sensors/records_camera.txt");
  sensors << "# kapture format: 1.1\n";
  records << "# kapture format: 1.1\n";
  for (size_t i = 0; i < photos.size(); ++i) {
    const cv::Mat image = cv::imread(photos[i].string());
    const std::string cam = "cam" + std::to_string(i), name = photos[i].filename().string();
    sensors << cam << ", , camera, PINHOLE, " << image.cols << ", " << image.rows << ", 500, 500, " << image.cols / 2
            << ", " << image.rows / 2 << "\n";
    records << i << ", " << cam << ", " << name << "\n";
    fs::copy_file(photos[i], root / "sensors/records_data" / name);
  }
  return root;
}

bool Covers(const std::vector<PersonBox>& boxes, double x, double y) {
  for (const PersonBox& b : boxes)
    if (x >= b.x && x <= b.x + b.width && y >= b.y && y <= b.y + b.height) return true;
  return false;
}

// The photographs of Debian's darknet package (/usr/share/darknet/data).
#define DARKNET_PHOTO_OR_SKIP(var, name)                                                            \
  const fs::path var = fs::path("/usr/share/darknet/data") / (name);                               \
  if (!fs::exists(var)) {                                                                          \
    if (locforge::testing::SharedRequired()) FAIL() << var << " missing: apt-get install darknet"; \
    GTEST_SKIP() << var << " is absent: install the Debian package darknet (cmake/debian-packages.txt)"; \
  }

TEST(PersonDetection, FindsThePeopleOfRealPhotographs) {
  LOCFORGE_SHARED_PATH_OR_SKIP(model, "models/yolo_fastest_body");
  DARKNET_PHOTO_OR_SKIP(person_jpg, "person.jpg");
  DARKNET_PHOTO_OR_SKIP(kite_jpg, "kite.jpg");
  const fs::path dir = locforge::testing::MakeTempDir("person_detection");
  const fs::path photos = PhotoKapture(dir, {person_jpg, kite_jpg});
  runtime::Registry registry;
  ASSERT_TRUE(registry.LoadFile(LOCFORGE_ANALYSIS_PLUGIN_FILE));
  std::vector<std::pair<std::string, std::string>> params = {
      {"cfg", (model / "yolo-fastest-1.1_body.cfg").string()},
      {"weights", (model / "yolo-fastest-1.1_body.weights").string()}};
  const runtime::InputArtifact images{"images", "kapture.dataset", photos};
  // True masks of our own (as a simulator recording holds them): person.jpg's
  // man as the box drawn by eye, nobody in kite.jpg (its people are not
  // what this checks: the recording input's path).
  cv::Mat man_mask(424, 640, CV_8U, cv::Scalar(0));
  man_mask(cv::Rect(190, 100, 80, 272)).setTo(255);
  fs::create_directories(photos / "truth/masks");
  ASSERT_TRUE(cv::imwrite((photos / "truth/masks/person.png").string(), man_mask));
  ASSERT_TRUE(cv::imwrite((photos / "truth/masks/kite.png").string(), cv::Mat(900, 1352, CV_8U, cv::Scalar(0))));
  // At the cfg's input size, 320x320.
  testkit::RunStage(registry, "analysis/person_detection", params, {images, {"recording", "kapture.dataset", photos}},
                    dir / "det320");
  // person.jpg (640x424): one man standing in a field between a dog and a
  // horse; by eye he spans x 190-270, y 100-372 (hat to boots).
  const Persons man = ReadPersons(dir / "det320/persons", "person.jpg");
  ASSERT_EQ(man.boxes.size(), 1u) << "one person, not the dog nor the horse";
  EXPECT_GE(BoxIou(man.boxes[0], Box(190, 100, 80, 272)), 0.75);
  EXPECT_NEAR(man.covered_percent, 100.0 * 80 * 272 / (640 * 424), 2.5);  // 8.0 % by eye
  const std::string summary = locforge::testing::ReadText(dir / "det320/detection.md");
  EXPECT_NE(summary.find("320x320 (resized)"), std::string::npos) << summary;
  // Two images, the crowded one found more crowded: both correlations 1.
  EXPECT_NE(summary.find("covered % with the true % 1 / 1"), std::string::npos) << summary;
  const auto with_truth = locforge::testing::ReadCsv(dir / "det320/persons.csv");
  ASSERT_EQ(with_truth.size(), 3u);
  EXPECT_NEAR(std::stod(with_truth[2][3]), 100.0 * 80 * 272 / (640 * 424), 1e-9);
  EXPECT_EQ(with_truth[1][3], "0");

  // kite.jpg's people are 10-50 px of a 1352 px image: at 320 the detector
  // misses some (and takes a kite for one); at 640x640 it finds them.
  params.push_back({"width", "640"});
  params.push_back({"height", "640"});
  testkit::RunStage(registry, "analysis/person_detection", params, {images}, dir / "det");

  // kite.jpg (1352x900): a beach with kites. By eye 13 people: 8 we can place
  // (below, centres in pixels), a child beside the man in black (100, 550),
  // the surfer (352, 495), a far figure (465, 478) and two kite surfers
  // (699, 466), (1210, 457) of a few pixels each.
  const Persons beach = ReadPersons(dir / "det/persons", "kite.jpg");
  EXPECT_GE(beach.boxes.size(), 12u);
  EXPECT_LE(beach.boxes.size(), 14u);
  const std::vector<std::pair<double, double>> seen = {
      {139, 687},  // walker in the blue hood
      {243, 776},  // walker in the dark hood
      {46, 535},   // man in a white shirt
      {91, 537},   // man in black
      {30, 544},   // child in red
      {184, 556},  // girl in the water
      {526, 518},  // two people in the water
      {544, 524}};
  for (const auto& [x, y] : seen) EXPECT_TRUE(Covers(beach.boxes, x, y)) << "nobody found at " << x << ", " << y;
  // The summary tables agree with the per-image files.
  const auto rows = locforge::testing::ReadCsv(dir / "det/persons.csv");
  ASSERT_EQ(rows.size(), 3u);
  EXPECT_EQ(rows[1][0], "kite.jpg");  // the kapture's order (sorted by path)
  EXPECT_EQ(rows[1][1], std::to_string(beach.boxes.size()));
  EXPECT_EQ(rows[2][0], "person.jpg");
  EXPECT_EQ(rows[2][1], "1");
  EXPECT_EQ(rows[2][3], "");  // no recording: no true crowdedness
  EXPECT_EQ(locforge::testing::ReadCsv(dir / "det/detections.csv").size(), 1 + 1 + beach.boxes.size());

  // The detections as analysis/image_content's source of crowdedness.
  testkit::RunStage(registry, "analysis/image_content", {}, {images, {"detections", "person.detections", dir / "det320"}},
                    dir / "content");
  const auto content = locforge::testing::ReadCsv(dir / "content/content.csv");
  ASSERT_EQ(content.size(), 3u);
  EXPECT_EQ(content[2][0], "person.jpg");
  EXPECT_NEAR(std::stod(content[2][4]), man.covered_percent, 1e-9);
  EXPECT_EQ(content[2][5], "0");  // 8 % < 20 %: not crowded
  EXPECT_NEAR(std::stod(content[1][4]), ReadPersons(dir / "det320/persons", "kite.jpg").covered_percent, 1e-9);
  EXPECT_NE(locforge::testing::ReadText(dir / "content/crowdedness_source.txt").find("person_detection"),
            std::string::npos);
  fs::remove_all(dir);
}

TEST(PersonDetection, ComparedWithTrueMasksPerSetAndPooled) {
  // Hand-made persons.csv of two sets: covered = 2 x truth in set 1, and the
  // counts rank like the truth except one pair.
  const fs::path dir = locforge::testing::MakeTempDir("crowdedness_agreement");
  fs::create_directories(dir / "a");
  fs::create_directories(dir / "b");
  std::ofstream(dir / "a/persons.csv") << "image,person_count,covered_percent,true_crowdedness_percent\n"
                                       << "q0,0,0,0\nq1,1,4,2\nq2,3,8,4\n";
  std::ofstream(dir / "b/persons.csv") << "image,person_count,covered_percent,true_crowdedness_percent\n"
                                       << "q0,2,20,10\nq1,5,30,15\nq2,4,40,20\n";
  runtime::Registry registry;
  ASSERT_TRUE(registry.LoadFile(LOCFORGE_ANALYSIS_PLUGIN_FILE));
  testkit::RunStage(registry, "analysis/crowdedness_agreement", {{"densities", JoinList({"0", "24"})}},
                    {{"detections", "person.detections", dir / "a"}, {"detections", "person.detections", dir / "b"}},
                    dir / "out");
  const auto rows = locforge::testing::ReadCsv(dir / "out/agreement.csv");
  ASSERT_EQ(rows.size(), 4u);
  EXPECT_EQ(rows[1][0], "0");
  EXPECT_EQ(rows[1][1], "3");
  EXPECT_EQ(rows[1][2], "2.00");   // mean truth
  EXPECT_EQ(rows[1][3], "4.00");   // mean covered
  EXPECT_EQ(rows[1][5], "1.000");  // covered = 2 x truth
  EXPECT_EQ(rows[1][6], "1.000");
  EXPECT_EQ(rows[2][8], "0.500");  // counts 2 5 4 vs truth 10 15 20: ranks 1 3 2 vs 1 2 3
  EXPECT_EQ(rows[3][0], "all (pooled)");
  EXPECT_EQ(rows[3][1], "6");
  EXPECT_EQ(rows[3][5], "1.000");  // covered = 2 x truth in both sets
  // A persons.csv without true crowdedness is refused, naming the file.
  std::ofstream(dir / "a/persons.csv") << "image,person_count,covered_percent,true_crowdedness_percent\nq0,0,0,\n";
  try {
    testkit::RunStage(registry, "analysis/crowdedness_agreement", {},
                      {{"detections", "person.detections", dir / "a"}}, dir / "out2");
    FAIL() << "a set without true crowdedness accepted";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("persons.csv"), std::string::npos) << e.what();
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace locforge::analysis
