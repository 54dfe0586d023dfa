#include "locforge/colmap/model.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>
#include <random>
#include <sstream>

#include "locforge/colmap/run.h"
#include "locforge/error.h"
#include "locforge/fs.h"
#include "testing.h"

namespace locforge::colmap {
namespace {

namespace fs = std::filesystem;

constexpr const char* kSampleModel = "data/kapture/maupertuis/colmap/reconstruction";

std::string ErrorOf(const std::function<void()>& fn) {
  try {
    fn();
  } catch (const InputError& e) {
    return e.what();
  } catch (const std::exception& e) {
    return std::string("not an InputError: ") + e.what();
  }
  return "no error";
}

void ExpectSameFiles(const fs::path& a, const fs::path& b, const std::vector<std::string>& names) {
  for (const std::string& name : names) {
    EXPECT_EQ(ReadFile(a / name), ReadFile(b / name)) << name << " differs between " << a
                                                      << " and " << b;
  }
}

const std::vector<std::string> kTextFiles = {"cameras.txt", "images.txt", "points3D.txt"};
const std::vector<std::string> kBinaryFiles = {"cameras.bin", "images.bin", "points3D.bin"};

TEST(ColmapModel, ReadsTheMaupertuisTextModel) {
  LOCFORGE_SHARED_PATH_OR_SKIP(dir, kSampleModel);
  const Reconstruction model = ReadModelText(dir);
  ASSERT_EQ(model.cameras.size(), 1u);
  EXPECT_EQ(model.cameras[0].camera_id, 1u);
  EXPECT_EQ(model.cameras[0].camera.model, CameraModelId::kSimplePinhole);
  EXPECT_EQ(model.cameras[0].camera.width, 1919);
  EXPECT_EQ(model.cameras[0].camera.height, 1079);
  EXPECT_EQ(model.cameras[0].camera.params, (std::vector<double>{1847.53, 959.5, 539.5}));
  ASSERT_EQ(model.images.size(), 4u);
  // The file lists image 4 (03.jpg) first.
  EXPECT_EQ(model.images[0].image_id, 4u);
  EXPECT_EQ(model.images[0].name, "03.jpg");
  EXPECT_EQ(model.images[0].qvec, Eigen::Vector4d(0.860298, 0.0113506, 0.344769, 0.375358));
  EXPECT_EQ(model.images[0].tvec, Eigen::Vector3d(-7.96417, -4.99505, 4.3645));
  EXPECT_EQ(model.images[0].points2d[0].xy, Eigen::Vector2d(355.968, 4.50115));
  EXPECT_FALSE(model.images[0].points2d[0].HasPoint3D());
  EXPECT_EQ(model.points3d.size(), 1039u);
  EXPECT_EQ(model.points3d[0].point3d_id, 708u);
  EXPECT_EQ(model.points3d[0].track.size(), 4u);
  EXPECT_EQ(model.NumObservations(), 3355u);  // colmap model_analyzer says 3355
  EXPECT_DOUBLE_EQ(model.MeanObservationsPerImage(), 838.75);
  EXPECT_EQ(model.Validate(), "");
}

// Text -> text, text -> binary -> binary, binary -> text: every write of the
// same model gives the same bytes.
TEST(ColmapModel, TextAndBinaryRoundTripsAreByteExact) {
  LOCFORGE_SHARED_PATH_OR_SKIP(dir, kSampleModel);
  const fs::path tmp = testing::MakeTempDir("colmap_model_rt");
  const Reconstruction sample = ReadModelText(dir);
  WriteModelText(sample, tmp / "a_txt");
  WriteModelText(ReadModelText(tmp / "a_txt"), tmp / "b_txt");
  ExpectSameFiles(tmp / "a_txt", tmp / "b_txt", kTextFiles);

  WriteModelBinary(ReadModelText(tmp / "a_txt"), tmp / "c_bin");
  WriteModelBinary(ReadModelBinary(tmp / "c_bin"), tmp / "d_bin");
  ExpectSameFiles(tmp / "c_bin", tmp / "d_bin", kBinaryFiles);

  WriteModelText(ReadModelBinary(tmp / "c_bin"), tmp / "e_txt");
  ExpectSameFiles(tmp / "a_txt", tmp / "e_txt", kTextFiles);
  // ReadModel picks binary when both exist.
  EXPECT_TRUE(HasModel(tmp / "c_bin", ModelFormat::kBinary));
  EXPECT_FALSE(HasModel(tmp / "c_bin", ModelFormat::kText));
  EXPECT_EQ(ReadModel(tmp / "c_bin").points3d.size(), 1039u);
  fs::remove_all(tmp);
}

// COLMAP's own writer (model_converter) and ours produce identical bytes.
TEST(ColmapModel, SameBytesAsColmapsOwnWriter) {
  LOCFORGE_SHARED_PATH_OR_SKIP(dir, kSampleModel);
  if (FindColmapExecutable().empty()) GTEST_SKIP() << "colmap executable not available";
  const fs::path tmp = testing::MakeTempDir("colmap_model_writer");
  RunOptions options;
  options.log_file = tmp / "colmap.log";
  options.timeout_s = 120;
  fs::create_directories(tmp / "colmap_bin");
  fs::create_directories(tmp / "colmap_txt");
  RunColmap({"model_converter", "--input_path", dir.string(), "--output_path",
             (tmp / "colmap_bin").string(), "--output_type", "BIN"},
            options);
  RunColmap({"model_converter", "--input_path", (tmp / "colmap_bin").string(), "--output_path",
             (tmp / "colmap_txt").string(), "--output_type", "TXT"},
            options);
  // COLMAP's files re-written by us: the same bytes.
  WriteModelBinary(ReadModelBinary(tmp / "colmap_bin"), tmp / "ours_bin");
  ExpectSameFiles(tmp / "colmap_bin", tmp / "ours_bin", kBinaryFiles);
  WriteModelText(ReadModelText(tmp / "colmap_txt"), tmp / "ours_txt");
  ExpectSameFiles(tmp / "colmap_txt", tmp / "ours_txt", kTextFiles);
  // Binary -> text by COLMAP and by us: the same lines. COLMAP lists records
  // in its hash-map order, which differs between its reads, so compare the
  // records as sorted sets.
  WriteModelText(ReadModelBinary(tmp / "colmap_bin"), tmp / "ours_from_bin");
  for (const std::string& name : kTextFiles) {
    auto records = [&](const fs::path& file) {
      std::istringstream in(ReadFile(file));
      std::vector<std::string> out;
      std::string line, next;
      while (std::getline(in, line)) {
        if (name == "images.txt" && !line.empty() && line[0] != '#') {
          std::getline(in, next);
          line += "\n" + next;
        }
        out.push_back(line);
      }
      std::sort(out.begin(), out.end());
      return out;
    };
    const auto theirs = records(tmp / "colmap_txt" / name);
    const auto ours = records(tmp / "ours_from_bin" / name);
    ASSERT_EQ(theirs.size(), ours.size()) << name;
    for (size_t i = 0; i < theirs.size(); ++i) ASSERT_EQ(theirs[i], ours[i]) << name;
  }
  fs::remove_all(tmp);
}

TEST(ColmapModel, PoseAccessorsFollowThePoseConvention) {
  ModelImage image;
  image.qvec = Eigen::Vector4d(0.860298, 0.0113506, 0.344769, 0.375358);
  image.tvec = Eigen::Vector3d(-7.96417, -4.99505, 4.3645);
  const Pose T = image.CameraFromWorld();
  // Camera centre: -R^T t.
  const Eigen::Vector3d c = -(T.R().transpose() * image.tvec);
  EXPECT_LT((T.Center() - c).norm(), 1e-12);
  ModelImage copy;
  copy.SetCameraFromWorld(T);
  EXPECT_LT((copy.qvec - NormalizeQvec(image.qvec)).norm(), 1e-15);
  EXPECT_EQ(NormalizeQvec(Eigen::Vector4d::Zero()), Eigen::Vector4d(1, 0, 0, 0));
}

class MalformedModel : public ::testing::Test {
 protected:
  void SetUp() override {
    tmp_ = testing::MakeTempDir("colmap_model_bad");
    Reconstruction m;
    ModelCamera c;
    c.camera_id = 1;
    c.camera.model = CameraModelId::kPinhole;
    c.camera.width = 640;
    c.camera.height = 480;
    c.camera.params = {500, 500, 320, 240};
    m.cameras.push_back(c);
    for (ImageId id : {1u, 2u}) {
      ModelImage i;
      i.image_id = id;
      i.camera_id = 1;
      i.name = "img" + std::to_string(id) + ".jpg";
      i.points2d.resize(3);
      for (int k = 0; k < 3; ++k) i.points2d[k].xy = Eigen::Vector2d(10.5 * k, 20.25 * k);
      i.points2d[1].point3d_id = 7;
      m.images.push_back(i);
    }
    ModelPoint3D p;
    p.point3d_id = 7;
    p.xyz = {1, 2, 3};
    p.color = {10, 20, 30};
    p.error = 0.5;
    p.track = {{1, 1}, {2, 1}};
    m.points3d.push_back(p);
    ASSERT_EQ(m.Validate(), "");
    model_ = m;
    WriteModelText(m, tmp_ / "txt");
    WriteModelBinary(m, tmp_ / "bin");
  }
  void TearDown() override { fs::remove_all(tmp_); }

  void ReplaceInFile(const fs::path& file, const std::string& from, const std::string& to) {
    std::string s = ReadFile(file);
    const size_t at = s.find(from);
    ASSERT_NE(at, std::string::npos) << from;
    s.replace(at, from.size(), to);
    WriteFileAtomic(file, s);
  }
  static void WriteRaw(const fs::path& file, const std::string& bytes) {
    std::ofstream(file, std::ios::binary | std::ios::trunc) << bytes;
  }
  void Truncate(const fs::path& file, size_t keep) { WriteRaw(file, ReadFile(file).substr(0, keep)); }

  fs::path tmp_;
  Reconstruction model_;
};

TEST_F(MalformedModel, SmallModelRoundTrips) {
  const Reconstruction t = ReadModelText(tmp_ / "txt");
  const Reconstruction b = ReadModelBinary(tmp_ / "bin");
  for (const Reconstruction* r : {&t, &b}) {
    ASSERT_EQ(r->images.size(), 2u);
    EXPECT_EQ(r->images[1].points2d[2].xy, Eigen::Vector2d(21, 40.5));
    EXPECT_EQ(r->images[1].points2d[1].point3d_id, 7u);
    EXPECT_EQ(r->points3d[0].track, model_.points3d[0].track);
    EXPECT_EQ(r->points3d[0].color, model_.points3d[0].color);
    EXPECT_EQ(r->Validate(), "");
  }
  // The text writer prints exactly COLMAP's layout.
  const std::string images = ReadFile(tmp_ / "txt/images.txt");
  EXPECT_NE(images.find("# Number of images: 2, mean observations per image: 1\n"
                        "1 1 0 0 0 0 0 0 1 img1.jpg\n0 0 -1 10.5 20.25 7 21 40.5 -1\n"),
            std::string::npos)
      << images;
  EXPECT_NE(ReadFile(tmp_ / "txt/points3D.txt").find("\n7 1 2 3 10 20 30 0.5 1 1 2 1\n"),
            std::string::npos);
}

TEST_F(MalformedModel, BadNumberInImagesTxtNamesFileLineAndField) {
  ReplaceInFile(tmp_ / "txt/images.txt", "1 1 0 0 0 0 0 0 1 img1.jpg", "1 1 zero 0 0 0 0 0 1 img1.jpg");
  const std::string e = ErrorOf([&] { ReadModelText(tmp_ / "txt"); });
  EXPECT_NE(e.find("images.txt:5"), std::string::npos) << e;
  EXPECT_NE(e.find("field 'QX'"), std::string::npos) << e;
  EXPECT_NE(e.find("'zero'"), std::string::npos) << e;
}

TEST_F(MalformedModel, ShortImageLineAndBrokenPointsLine) {
  ReplaceInFile(tmp_ / "txt/images.txt", "0 0 -1 10.5 20.25 7 21 40.5 -1\n2 ", "0 0 -1 10.5 20.25 7 21 40.5\n2 ");
  std::string e = ErrorOf([&] { ReadModelText(tmp_ / "txt"); });
  EXPECT_NE(e.find("images.txt:6: field 'POINTS2D'"), std::string::npos) << e;
  ReplaceInFile(tmp_ / "txt/images.txt", "0 0 -1 10.5 20.25 7 21 40.5\n2 ", "0 0 -1 10.5 20.25 7 21 40.5 -1\n2 1 0 0\n");
  e = ErrorOf([&] { ReadModelText(tmp_ / "txt"); });
  EXPECT_NE(e.find("images.txt:7"), std::string::npos) << e;
  EXPECT_NE(e.find("got 4 fields"), std::string::npos) << e;
}

TEST_F(MalformedModel, BadCamerasAndPointsTxt) {
  ReplaceInFile(tmp_ / "txt/cameras.txt", "1 PINHOLE 640 480 500 500 320 240", "1 PINHOLE 640 480 500 500 320");
  std::string e = ErrorOf([&] { ReadModelText(tmp_ / "txt"); });
  EXPECT_NE(e.find("cameras.txt:4: field 'PARAMS'"), std::string::npos) << e;
  EXPECT_NE(e.find("needs 4 parameters, got 3"), std::string::npos) << e;
  ReplaceInFile(tmp_ / "txt/cameras.txt", "PINHOLE", "PINHOLEX");
  e = ErrorOf([&] { ReadModelText(tmp_ / "txt"); });
  EXPECT_NE(e.find("field 'MODEL'"), std::string::npos) << e;

  ReplaceInFile(tmp_ / "txt/points3D.txt", "7 1 2 3 10 20 30", "7 1 2 3 10 256 30");
  e = ErrorOf([&] { ReadModelText(tmp_ / "txt"); });
  EXPECT_TRUE(e.find("cameras.txt") != std::string::npos) << e;  // cameras fail first
  WriteModelText(model_, tmp_ / "txt");
  ReplaceInFile(tmp_ / "txt/points3D.txt", "7 1 2 3 10 20 30", "7 1 2 3 10 256 30");
  e = ErrorOf([&] { ReadModelText(tmp_ / "txt"); });
  EXPECT_NE(e.find("points3D.txt:4: field 'G'"), std::string::npos) << e;
}

TEST_F(MalformedModel, TruncatedBinaryFilesNameFileFieldAndOffset) {
  const fs::path images = tmp_ / "bin/images.bin";
  const size_t size = fs::file_size(images);
  // Every cut inside the file is refused, never a crash.
  const std::string original = ReadFile(images);
  for (size_t keep = 0; keep < size; ++keep) {
    WriteRaw(images, original.substr(0, keep));
    const std::string e = ErrorOf([&] { ReadModelBinary(tmp_ / "bin"); });
    EXPECT_NE(e.find("images.bin"), std::string::npos) << keep << ": " << e;
    EXPECT_NE(e.find("field '"), std::string::npos) << keep << ": " << e;
  }
  // A count that the bytes left cannot hold is refused before reading on.
  WriteRaw(images, original.substr(0, 8 + 4 + 7 * 8 + 4 + 3));
  std::string e = ErrorOf([&] { ReadModelBinary(tmp_ / "bin"); });
  EXPECT_NE(e.find("images.bin @byte 8: field 'num_reg_images': count 2 cannot fit"),
            std::string::npos) << e;
  WriteRaw(images, original);
  Truncate(tmp_ / "bin/cameras.bin", fs::file_size(tmp_ / "bin/cameras.bin") - 4);
  e = ErrorOf([&] { ReadModelBinary(tmp_ / "bin"); });
  EXPECT_NE(e.find("cameras.bin @byte 56: field 'camera #0.params': file truncated: needs 8 bytes, 4 left"),
            std::string::npos) << e;
  WriteModelBinary(model_, tmp_ / "bin");
  Truncate(tmp_ / "bin/points3D.bin", fs::file_size(tmp_ / "bin/points3D.bin") - 4);
  e = ErrorOf([&] { ReadModelBinary(tmp_ / "bin"); });
  EXPECT_NE(e.find("points3D.bin @byte"), std::string::npos) << e;
  EXPECT_NE(e.find("field 'point3D #0.track_length'"), std::string::npos) << e;
}

TEST_F(MalformedModel, CorruptCountsAndModelIds) {
  // A huge point count must not allocate: it cannot fit in the file.
  std::string s = ReadFile(tmp_ / "bin/points3D.bin");
  s[7] = '\x7f';
  WriteFileAtomic(tmp_ / "bin/points3D.bin", s);
  std::string e = ErrorOf([&] { ReadModelBinary(tmp_ / "bin"); });
  EXPECT_NE(e.find("field 'num_points3D'"), std::string::npos) << e;
  WriteModelBinary(model_, tmp_ / "bin");
  s = ReadFile(tmp_ / "bin/cameras.bin");
  s[8 + 4] = 42;  // model id
  WriteFileAtomic(tmp_ / "bin/cameras.bin", s);
  e = ErrorOf([&] { ReadModelBinary(tmp_ / "bin"); });
  EXPECT_NE(e.find("field 'camera #0.model_id'"), std::string::npos) << e;
  EXPECT_NE(e.find("42"), std::string::npos) << e;
  // Trailing garbage.
  WriteModelBinary(model_, tmp_ / "bin");
  WriteFileAtomic(tmp_ / "bin/cameras.bin", ReadFile(tmp_ / "bin/cameras.bin") + "x");
  e = ErrorOf([&] { ReadModelBinary(tmp_ / "bin"); });
  EXPECT_NE(e.find("trailing"), std::string::npos) << e;
}

TEST_F(MalformedModel, ValidateFindsBrokenReferences) {
  Reconstruction m = model_;
  m.points3d[0].track.push_back({3, 0});
  EXPECT_NE(m.Validate().find("missing image 3"), std::string::npos);
  m = model_;
  m.points3d[0].track[0].point2d_idx = 0;
  EXPECT_NE(m.Validate().find("not linked back"), std::string::npos);
  m = model_;
  m.images[0].camera_id = 9;
  EXPECT_NE(m.Validate().find("missing camera 9"), std::string::npos);
  m = model_;
  m.images[1].points2d[0].point3d_id = 99;
  EXPECT_NE(m.Validate().find("missing point3D 99"), std::string::npos);
  EXPECT_NE(ErrorOf([&] { ReadModel(tmp_ / "nothing"); }).find("no COLMAP model"), std::string::npos);
}

}  // namespace
}  // namespace locforge::colmap

namespace locforge::colmap {
namespace {

// Random corruption of every file never crashes or over-allocates: the
// model reads, or an InputError names the file.
TEST(ColmapModelFuzz, CorruptedFilesReadOrFailCleanly) {
  LOCFORGE_SHARED_PATH_OR_SKIP(dir, kSampleModel);
  const fs::path tmp = testing::MakeTempDir("colmap_model_fuzz");
  const Reconstruction sample = ReadModelText(dir);
  Reconstruction small = sample;
  small.points3d.resize(50);
  for (ModelImage& image : small.images) {
    image.points2d.resize(200);
    for (Point2D& p : image.points2d) p.point3d_id = kInvalidPoint3DId;
  }
  for (ModelPoint3D& p : small.points3d) p.track.clear();
  WriteModelText(small, tmp / "txt");
  WriteModelBinary(small, tmp / "bin");
  std::mt19937 rng(42);
  int failures = 0, reads = 0;
  for (const auto& [sub, names] :
       {std::make_pair(std::string("txt"), kTextFiles), std::make_pair(std::string("bin"), kBinaryFiles)}) {
    for (const std::string& name : names) {
      const fs::path file = tmp / sub / name;
      const std::string original = ReadFile(file);
      for (int round = 0; round < 150; ++round) {
        std::string bytes = original;
        const int edits = 1 + static_cast<int>(rng() % 4);
        for (int e = 0; e < edits && !bytes.empty(); ++e) {
          const size_t at = rng() % bytes.size();
          switch (rng() % 3) {
            case 0: bytes[at] = static_cast<char>(rng()); break;
            case 1: bytes.erase(at, 1 + rng() % 8); break;
            default: bytes.insert(at, 1, sub == "txt" ? " -1x\n"[rng() % 5] : '\xff'); break;
          }
        }
        std::ofstream(file, std::ios::binary | std::ios::trunc) << bytes;
        try {
          const Reconstruction r = sub == "txt" ? ReadModelText(tmp / sub) : ReadModelBinary(tmp / sub);
          r.Validate();  // must not crash either
          ++reads;
        } catch (const InputError& e) {
          EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << e.what();
          ++failures;
        }
      }
      std::ofstream(file, std::ios::binary | std::ios::trunc) << original;
    }
  }
  EXPECT_GT(failures, 100);
  fs::remove_all(tmp);
}

}  // namespace
}  // namespace locforge::colmap
